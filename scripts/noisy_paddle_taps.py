"""Silent wrong answers on a force reconstructed from a noisy paddle (results/noise/README.md).

Thermal records of the coverage study (scripts/thermal_coverage.py: the worked-example surface,
6 periods at 1 ns, 300 K, seeds 1..N) with 1 pm of white detector noise on z_tip and z_paddle;
every method on the reconstructed force.  Prints, per replica, the vetica-prestress k_g (value
error against the method's answer on the T -> 0 record, 1-sigma, flag) and every result that is
*silently wrong*: unflagged and off by more than 10 % and 3 sigma.

    PYTHONPATH=. python scripts/noisy_paddle_taps.py --replicas 12
"""

from __future__ import annotations

import argparse

import numpy as np

from thermal_coverage import BASE, DETECTOR, answers
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import replicas


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--replicas", type=int, default=12)
    ap.add_argument("--seed", type=int, default=5, help="seed of the detector noise")
    args = ap.parse_args(argv)
    faint = replicas(load(None, {**BASE, "numerics.temperature": 1e-9}), [0])[0]
    ref = answers(faint.frame(), faint.metadata(), "reconstructed")
    runs = replicas(load(None, {**BASE, "numerics.temperature": 300.0}), range(1, args.replicas + 1))
    rng = np.random.default_rng(args.seed)
    silent = 0
    for i, run in enumerate(runs):
        df, meta = run.frame().copy(), run.metadata()
        df["z_tip"] += rng.normal(0, DETECTOR[0], len(df))
        df["z_paddle"] += rng.normal(0, DETECTOR[0], len(df))
        for (m, q), e in answers(df, meta, "reconstructed").items():
            if m == "full, white error" or e.value is None:
                continue
            err = 100 * (e.value - ref[(m, q)].value) / abs(ref[(m, q)].value)
            sig = None if e.sigma is None else 100 * e.sigma
            wrong = e.identifiable is not False and abs(err) > 10 and (sig is None or abs(err) > 3 * sig)
            silent += wrong
            if (m, q) == ("vetica-prestress", "k_g") or wrong:
                print(f"replica {i + 1}: {m} {q} error {err:+.4g} %, 1-sigma "
                      f"{'-' if sig is None else f'{sig:.3g} %'}, flagged {e.identifiable is False}"
                      + ("  SILENTLY WRONG" if wrong else ""))  # fmt: skip
    print(f"silently wrong results: {silent}")


if __name__ == "__main__":
    main()
