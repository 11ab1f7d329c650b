"""The whole-cycle fit's band term from its linearisation against the four re-fits it replaces.

On a low-passed force the fit's answer is biased by the low-pass; :func:`vetica_cli.extraction.
uncertainty.model_band` reads that bias on noise-free records of the fit's own surface and its error
from the record's step to ``fc/sqrt(2)`` against the model's.  It did so by fitting those records
(four fits); now it solves the fit's linearisation at its optimum (``BandLinearisation``).  This
script extracts the same noisy records both ways and prints, per record and quantity, the two
biases, the two sigmas, the change of the corrected value in units of its sigma, and the CPU time of
each extraction.  Materials come from ``trust.draw_materials`` (``--draw-seed``, a development draw),
records from ``trust.condition_overrides`` (300 K reconstructed force, or ``lab``).

    PYTHONPATH=. python scripts/band_linear.py --draw-seed 19 --materials 4 --replicas 3
"""

from __future__ import annotations

import argparse
import sys
import time
from functools import partial
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from trust import condition_overrides, draw_materials  # noqa: E402

from vetica_cli.extraction import extract_many, uncertainty  # noqa: E402
from vetica_cli.simulation.config import load  # noqa: E402
from vetica_cli.simulation.simulate import replicas  # noqa: E402

QUANTITIES = ("k_g", "k0", "k_inf", "cd", "tau_c")


def extract(run, linear: bool):
    original = uncertainty.model_band
    uncertainty.model_band = partial(original, linear=linear)
    try:
        t = time.process_time()
        res = extract_many(run.frame(), run.metadata(), "reconstructed", {"full": {}})["full"]
        return res, time.process_time() - t
    finally:
        uncertainty.model_band = original


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draw-seed", type=int, default=19)
    ap.add_argument("--materials", type=int, default=4)
    ap.add_argument("--replicas", type=int, default=3)
    ap.add_argument("--condition", default="thermal", choices=("thermal", "lab"))
    ap.add_argument("--print-step", type=float, default=1e-9)
    ap.add_argument("--cycles", type=int, default=4)
    args = ap.parse_args(argv)
    worst, times = {}, {True: [], False: []}
    for i, mat in enumerate(draw_materials(args.materials, args.draw_seed)):
        ov = {**condition_overrides(args.condition, args.print_step, args.cycles),
              **{f"surface.{k}": v for k, v in mat.items()}}  # fmt: skip
        seeds = [int(s) for s in np.random.default_rng([args.draw_seed, i, 99]).integers(1, 2**31, args.replicas)]
        for r, run in enumerate(replicas(load(None, ov), seeds)):
            got = {}
            for lin in (False, True):
                got[lin], dt = extract(run, lin)
                times[lin].append(dt)
            bands = {lin: (got[lin].info.get("uncertainty") or {}).get("band") or {} for lin in got}
            if not bands[False] or not bands[True]:
                print(f"material {i} {mat} replica {r}: band term {bands[False].get('source')} / "
                      f"{bands[True].get('source')}")  # fmt: skip
                continue
            line = []
            for q in QUANTITIES:
                a, b = got[False].estimates.get(q), got[True].estimates.get(q)
                if a is None or b is None or a.value is None or b.value is None:
                    continue
                ba, bb = bands[False]["bias"].get(q, np.nan), bands[True]["bias"].get(q, np.nan)
                sa, sb = bands[False]["sigma"].get(q, np.nan), bands[True]["sigma"].get(q, np.nan)
                shift = abs(b.value - a.value) / (abs(a.value) * a.sigma) if a.sigma else np.nan
                worst[q] = max(worst.get(q, 0.0), shift)
                line.append(f"{q} bias {100 * ba:+.3f}/{100 * bb:+.3f} % band-sigma {100 * sa:.3f}/{100 * sb:.3f} % "
                            f"value moved {shift:.2f} sigma")  # fmt: skip
            print(f"material {i} {mat} replica {r} (refit/linear):\n   " + "\n   ".join(line), flush=True)
    print("largest move of a corrected value, in its sigma: " + ", ".join(f"{q} {v:.3f}" for q, v in worst.items()))
    med = {k: 1e3 * float(np.median(v)) for k, v in times.items() if v}
    print(f"CPU ms per extraction, median: refit {med.get(False, np.nan):.0f}, linearised {med.get(True, np.nan):.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
