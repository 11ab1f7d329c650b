"""Coverage of the standard errors under thermal noise (results/noise/README.md).

The worked-example surface, 6 recorded periods at a 1 ns print step (dt 0.05 ns) with the
approach segment, at ``numerics.temperature`` T: the noise-free orbit is solved once and
``--replicas`` noisy recordings are made from it (``simulate.replicas``, one noise seed
each); every method on each (true force, optionally with white detector noise added on
z_tip and f_ts).  Per method and quantity: the fraction of replicas whose reference lies
within +-2 sigma, the replica spread against the median reported sigma, the mean shift
against the spread, and the fraction flagged ``unidentified``; for the whole-cycle fit also
with its white-residual error alone (``full, white error``).  References: the method's
answer on the noise-free record made by the same recording path (T = 1e-9 K: the thermal
kernel with no noise to speak of) and on the 0 K record (the fine kernel).

    PYTHONPATH=. python scripts/thermal_coverage.py --replicas 50 --temperatures 300 1200
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time

import numpy as np

from vetica_cli.errors import InputError
from vetica_cli.extraction import extract_many
from vetica_cli.extraction.result import Estimate
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import replicas, simulate

METHODS = ("vetica", "vetica-prestress", "full")
QUANTITIES = ("tau_c", "k_g", "k0", "k_inf", "cd")
BASE = {"numerics.record_cycles": 6, "numerics.dt": 0.05e-9, "numerics.print_step": 1e-9}
COLUMNS = ["t", "z_tip", "f_ts", "segment"]
DETECTOR = (1e-12, 1e-10)  # white detector noise of the second level: z_tip [m], f_ts [N] (z_paddle [m]: the first)


def answers(df, meta, force="true"):
    """Every method's estimates, and the whole-cycle fit's with its white-residual error alone
    (``full, white error``: the standard error it reported before the tap-robust one)."""
    out = {}
    for m in METHODS:
        try:
            res = extract_many(df if force != "true" else df[COLUMNS], meta, force, {m: {}})[m]
        except InputError:  # the record refused (e.g. no Z1 under the noise): no estimate, counted as flagged
            res = None
        for q in QUANTITIES:
            out[(m, q)] = res.estimates[q] if res is not None else Estimate(value=None, unit="", identifiable=False)
        if m == "full":
            white = res.info["fit"]["uncertainty"]["white"] if res is not None else {}
            for q in QUANTITIES:
                out[("full, white error", q)] = dataclasses.replace(out[(m, q)], sigma=white.get(q))
    return out


def study(temperature: float, n: int, seed0: int = 1, force: str = "true"):
    """``{level: {(method, quantity): row}}`` for one temperature (module docstring)."""
    t0 = time.perf_counter()
    cold = simulate(load(None, BASE))
    ref0 = answers(cold.frame(), cold.metadata(), force)
    faint = replicas(load(None, {**BASE, "numerics.temperature": 1e-9}), [0])[0]
    ref1 = answers(faint.frame(), faint.metadata(), force)
    runs = replicas(load(None, {**BASE, "numerics.temperature": temperature}), range(seed0, seed0 + n))
    rng = np.random.default_rng([seed0, int(temperature)])
    name = f"{temperature:g} K" + ("" if force == "true" else f", {force} force")
    detector = f"{name} + " + ("1 pm/0.1 nN" if force == "true" else "1 pm on z_tip and z_paddle")
    levels = {name: [], detector: []}
    for run in runs:
        df, meta = run.frame(), run.metadata()
        levels[name].append(answers(df, meta, force))
        df = df.copy()
        df["z_tip"] += rng.normal(0.0, DETECTOR[0], len(df))
        if force == "true":
            df["f_ts"] += rng.normal(0.0, DETECTOR[1], len(df))
        else:  # the force comes from the paddle: its detector noise as a force, k2 x 1 pm = 0.7 nN
            df["z_paddle"] += rng.normal(0.0, DETECTOR[0], len(df))
        levels[detector].append(answers(df, meta, force))
    out = {}
    for level, reps in levels.items():
        rows = {}
        for key in ref1:
            v = np.array([r[key].value if r[key].value is not None else math.nan for r in reps], float)
            s = np.array([r[key].sigma if r[key].sigma is not None else math.inf for r in reps], float)
            flagged = np.mean([r[key].identifiable is False for r in reps])
            row = {"flagged": float(flagged)}
            for name, ref in (("rec", ref1[key].value), ("0K", ref0[key].value)):
                rel = (v - ref) / abs(ref)
                row[f"cover_{name}"] = float(np.mean(np.abs(rel) <= 2.0 * s))
                row[f"shift_{name}"] = float(np.nanmean(rel))
            rel = (v - ref1[key].value) / abs(ref1[key].value)
            row["spread"] = float(np.nanstd(rel, ddof=1))
            row["sigma"] = float(np.median(s))
            rows[key] = row
        out[level] = rows
    print(f"T {temperature:g} K: {n} replicas in {time.perf_counter() - t0:.0f} s", flush=True)
    return out


def table(results) -> str:
    lines = ["| level | method | quantity | within 2 sigma (ref: same recording, T -> 0) | "
             "within 2 sigma (ref: 0 K record) | replica spread % | median sigma % | spread / sigma | "
             "mean shift / spread | mean shift from the 0 K answer % | flagged |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for level, rows in results.items():
        for (m, q), r in rows.items():
            ratio = r["spread"] / r["sigma"] if r["sigma"] > 0 else math.inf
            lines.append(f"| {level} | {m} | {q} | {r['cover_rec']:.2f} | {r['cover_0K']:.2f} | "
                         f"{100 * r['spread']:.3g} | {100 * r['sigma']:.3g} | {ratio:.2f} | "
                         f"{r['shift_rec'] / r['spread']:+.2f} | "
                         f"{100 * r['shift_0K']:+.3g} | {r['flagged']:.2f} |")  # fmt: skip
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--replicas", type=int, default=50)
    ap.add_argument("--temperatures", type=float, nargs="*", default=[300.0])
    ap.add_argument("--force", default="true", choices=("true", "reconstructed"))
    args = ap.parse_args(argv)
    results = {}
    for temp in args.temperatures:
        results.update(study(temp, args.replicas, force=args.force))
    print(table(results))
    return results


if __name__ == "__main__":
    main()
