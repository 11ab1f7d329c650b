"""Method comparison with thermal noise at the instrument's real level (results/noise/).

The thesis's worked-example probe (k1 10 N/m, k2 700 N/m, f1 50 kHz, Q 100/1000) on SLS
surfaces at 32:1 (k_inf 4 N/m) and cd = 1e-5, 3e-5, 1e-3, 1e-1 kg/s, print steps 0.125,
0.5 and 2 ns (dt 0.025 ns), at 0 K and 300 K (``numerics.temperature``: Brownian force on
both modes, 20 pm RMS on the cantilever, 2.4 pm on the paddle), 9 recorded periods.
Every method on the true force ``f_ts`` (which at 300 K carries the thermal motion's
effect on the contact) and on the force an instrument has, reconstructed from the
noisy paddle deflection (spectral inversion, default cut-off).  Z1 from the approach
segment (which carries the free probe's thermal motion).  One row per (point,
force, method, quantity): value, theory, error %, 1-sigma %, flag.

    PYTHONPATH=. python scripts/noise_study.py --out results/noise/thermal_methods.parquet
"""

from __future__ import annotations

import argparse
import math
import time

import pandas as pd

from table_units import stamp  # scripts/table_units.py
from vetica_cli.extraction import extract_many
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import simulate

DASHPOTS = (1e-5, 3e-5, 1e-3, 1e-1)
PRINT_STEPS = (0.125e-9, 0.5e-9, 2e-9)
TEMPERATURES = (0.0, 300.0)
METHODS = ("vetica", "vetica-prestress", "full")
QUANTITIES = ("tau_c", "k_g", "k0", "k_inf", "cd")


def rows_for(run, point):
    meta = run.metadata()
    df = run.frame()
    out = []
    for force in ("true", "reconstructed"):
        for m in METHODS:
            t0 = time.perf_counter()
            try:
                res = extract_many(df, meta, force, {m: {}})[m]
                status, error = "ok", ""
            except Exception as exc:  # noqa: BLE001 - a refused record is a row, as in a sweep
                res, status, error = None, "no_estimate", str(exc).splitlines()[0]
            wall = time.perf_counter() - t0
            for q in QUANTITIES:
                e = res.estimates.get(q) if res is not None else None
                sig = e.sigma if e is not None else None
                out.append({
                    **point, "force": force, "method": m, "quantity": q,
                    "value": math.nan if e is None or e.value is None else e.value,
                    "theory": math.nan if e is None or e.theory is None else e.theory,
                    "err_pct": math.nan if e is None or e.error_pct is None else e.error_pct,
                    "sigma_pct": math.nan if sig is None or not math.isfinite(sig) else 100.0 * sig,
                    "status": status if e is None or e.value is not None else "no_estimate",
                    "unidentified": bool(e is not None and e.identifiable is False),
                    "reason": (e.reason or "") if e is not None and e.identifiable is False else error,
                    "wall_s": wall,
                })  # fmt: skip
    return out


def summary(table: pd.DataFrame) -> pd.DataFrame:
    t = table[table["status"] == "ok"].copy()
    t["abs_err"] = t["err_pct"].abs()
    t["covered"] = t["abs_err"] <= 2.0 * t["sigma_pct"]
    t["clean"] = ~t["unidentified"]
    return t.groupby(["temperature", "force", "method", "quantity"]).agg(
        numbers=("value", "size"), unflagged=("clean", "sum"), median_abs_err_pct=("abs_err", "median"),
        median_sigma_pct=("sigma_pct", "median"), truth_within_2sigma=("covered", "mean"),
    )  # fmt: skip


def readme_table(table: pd.DataFrame) -> str:
    """The results/noise/README.md table: per temperature, force, method and print step (5
    quantities x the dashpots per row); 'truth within 2 sigma' against the theory."""
    t = table.copy()
    t["abs_err"] = t["err_pct"].abs()
    t["ok"] = t["status"] == "ok"
    t["covered"] = t["ok"] & (t["abs_err"] <= 2.0 * t["sigma_pct"])
    t["clean"] = t["ok"] & ~t["unidentified"]
    t["silent"] = t["clean"] & (t["abs_err"] > 10.0) & (t["abs_err"] > 3.0 * t["sigma_pct"])
    lines = ["| T [K] | force | method | PS [ns] | numbers | unflagged | median abs err % | median 1-sigma % | "
             "truth within 2 sigma | unflagged off >10 % and >3 sigma |", "|---|---|---|---|---|---|---|---|---|---|"]
    for (temp, force, m, ps), g in t.groupby(["temperature", "force", "method", "print_step"]):
        ok = g[g["ok"]]
        lines.append(f"| {temp:g} | {force} | {m} | {ps * 1e9:g} | {len(ok)}/{len(g)} | {int(g['clean'].sum())} | "
                     f"{ok['abs_err'].median():.3g} | {ok['sigma_pct'].median():.3g} | {g['covered'].mean():.2f} | "
                     f"{int(g['silent'].sum())} |")  # fmt: skip
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="thermal_methods.parquet")
    ap.add_argument("--dashpots", type=float, nargs="*", default=DASHPOTS)
    ap.add_argument("--print-steps", type=float, nargs="*", default=PRINT_STEPS)
    ap.add_argument("--temperatures", type=float, nargs="*", default=TEMPERATURES)
    ap.add_argument("--table-only", metavar="PARQUET", help="print the README table of a table written before")
    args = ap.parse_args(argv)
    if args.table_only:
        print(readme_table(pd.read_parquet(args.table_only)))
        return None
    rows = []
    for cd in args.dashpots:
        for ps in args.print_steps:
            for temp in args.temperatures:
                ov = {"surface.cd": cd, "numerics.print_step": ps, "numerics.record_cycles": 9,
                      "numerics.temperature": temp, "numerics.noise_seed": 1}  # fmt: skip
                t0 = time.perf_counter()
                run = simulate(load(None, ov))
                point = {"cd": cd, "print_step": ps, "temperature": temp, "stop_reason": run.stop_reason}
                rows += rows_for(run, point)
                print(f"cd {cd:g} PS {ps * 1e9:g} ns T {temp:g} K: {time.perf_counter() - t0:.1f} s", flush=True)
    table = pd.DataFrame(rows)
    table.to_parquet(args.out)
    stamp(args.out)  # units and descriptions in the metadata
    with pd.option_context("display.width", 200, "display.max_rows", 200):
        print(summary(table))
    print(readme_table(table))
    return table


if __name__ == "__main__":
    main()
