"""VETICA against the whole-cycle inversion
(``extract.method full``), without and with detector position noise.

Reads the tables of four sweeps (run them first, ~15 min on 2 cores):

    vetica sweep configs/method_dashpot.yaml              # cd x print step x noise x method, 16:1
    vetica sweep configs/method_stiffness_ratio.yaml      # ratio x cd x noise x method, PS 0.5 ns
    vetica sweep configs/method_noise_reconstructed.yaml  # noisy reconstructed force, a few points
    vetica sweep configs/method_low_cd.yaml               # cd below the thesis range, 0.125 ns
    vetica sweep configs/method_pull.yaml                 # cd x surface pull on/off x method

and prints the Markdown tables of ``results/methods/method_comparison.md``, writing the
summary tables they are built from (``results/methods/method_comparison_summary.parquet``, one row per setting, noise
level, force source and method; ``results/methods/method_comparison_noisy_reconstructed.parquet``):

    python scripts/method_comparison.py [--measure-reconstruction]

``--measure-reconstruction`` also simulates one point (cd = 1e-3 kg/s, 16:1,
PS 0.125 ns; ~5 s) and measures the RMS error of the reconstructed force for
0, 1 and 10 pm of position noise.

Definitions (per setting, noise level, force source and method; cd grid of the sweep):

* ``W_tau``: acceptance regime of thesis fig. 52, the longest run of
  consecutive cd grid points with status 'ok' and tau_c error < 30 %, in
  decades (log10 of last/first cd of the run; one point = 0 decades);
* ``W_cd``: the same with the cd error < 30 %;
* ``W_cd_all``: as ``W_cd`` but points that hit numerics.max_time
  ('not_steady') count too: the extraction is judged on the record it got;
* medians of the k0, k_inf and cd error magnitudes over the points of the ``W_cd`` run
  (the run of ``W_tau`` for the ``*_tau`` columns).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pandas as pd

from table_units import stamp  # scripts/table_units.py
from vetica_cli.io import read_table, write_table
from vetica_cli.study.acceptance import ACCEPT_ERR_PCT

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results" / "methods"
LIMIT = ACCEPT_ERR_PCT  # % (thesis fig. 52)
CD = "surface.cd"
NOISE = "numerics.position_noise"
STUDIES = {  # table -> (setting column, label)
    "method_dashpot": ("numerics.print_step", "print step"),
    "method_stiffness_ratio": ("surface.stiffness_ratio", "k0:k_inf"),
    "method_pull": ("surface.vdw_on_surface", "surface pull"),
}


def longest_run(g: pd.DataFrame, err_col: str, statuses=("ok",)) -> pd.DataFrame:
    """Rows of the longest run of consecutive cd grid points with status in
    ``statuses`` and ``err_col`` < 30 % (the lower-cd run wins a tie)."""
    g = g.sort_values(CD)
    ok = (g["status"].isin(statuses) & (g[err_col].abs() < LIMIT)).to_numpy()
    best, start = (0, 0), None
    for i, flag in enumerate([*ok, False]):
        if flag and start is None:
            start = i
        elif not flag and start is not None:
            if i - start > best[1] - best[0]:
                best = (start, i)
            start = None
    return g.iloc[best[0] : best[1]]


def decades(run: pd.DataFrame) -> float:
    if run.empty:
        return math.nan
    cd = run[CD].to_numpy(float)
    return float(np.log10(cd.max() / cd.min()))


def summarize(df: pd.DataFrame, setting: str) -> pd.DataFrame:
    rows = []
    keys = [setting, NOISE, "force_source", "method"]
    for combo, g in df.groupby(keys, sort=True):
        r = dict(zip(keys, combo))
        r_tau = longest_run(g, "tau_c_err_pct")
        r_cd = longest_run(g, "cd_err_pct")
        r_all = longest_run(g, "cd_err_pct", ("ok", "not_steady"))
        r.update(
            n_points=len(g),
            n_ok=int((g["status"] == "ok").sum()),
            n_failed=int((g["status"] == "failed").sum()),
            W_tau=decades(r_tau),
            W_cd=decades(r_cd),
            W_cd_all=decades(r_all),
            cd_lo=float(r_cd[CD].min()) if len(r_cd) else math.nan,
            cd_hi=float(r_cd[CD].max()) if len(r_cd) else math.nan,
        )
        for q in ("k0", "k_inf", "cd"):
            r[f"med_{q}"] = float(r_cd[f"{q}_err_pct"].abs().median()) if len(r_cd) else math.nan
            r[f"med_{q}_tau"] = float(r_tau[f"{q}_err_pct"].abs().median()) if len(r_tau) else math.nan
        r["flagged"] = int((g["unidentified"] != "").sum())
        r["extract_s_median"] = float(g["wall_s"].median())
        rows.append(r)
    out = pd.DataFrame(rows)
    rank = {"true": 0, "reconstructed": 1, "vetica": 0, "vetica-prestress": 1, "full": 2}
    out["_f"], out["_m"] = out["force_source"].map(rank), out["method"].map(rank)
    return out.sort_values([setting, NOISE, "_f", "_m"]).drop(columns=["_f", "_m"]).reset_index(drop=True)


def _f(v, nd=2) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    return f"{v:.{nd}f}"


def _e(v) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    return f"{v:.2g}" if v < 100 else f"{v:.3g}"


def _setting(setting: str, v) -> str:
    if setting == "numerics.print_step":
        return f"{v * 1e9:g} ns"
    if setting == "surface.vdw_on_surface":
        return "on" if v else "off"
    r = float(v)
    return f"1:{1 / r:g}" if r < 1 else f"{r:g}:1"


def _noise(v) -> str:
    return "none" if v == 0 else f"{v * 1e12:g} pm"


def markdown_table(s: pd.DataFrame, setting: str, label: str) -> str:
    head = (
        f"| {label} | noise | force | method | W_tau [dec] | W_cd [dec] | cd range of W_cd [kg/s] | "
        "med. k0 err [%] | med. k_inf err [%] | med. cd err [%] | W_cd incl. not steady [dec] | ok/points |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|---|\n"
    )
    lines = []
    for _, r in s.iterrows():
        rng = "–" if math.isnan(r["cd_lo"]) else f"{r['cd_lo']:.3g} .. {r['cd_hi']:.3g}"
        lines.append(
            f"| {_setting(setting, r[setting])} | {_noise(r[NOISE])} | {r['force_source']} | {r['method']} | "
            f"{_f(r['W_tau'], 1)} | {_f(r['W_cd'], 1)} | {rng} | {_e(r['med_k0'])} | {_e(r['med_k_inf'])} | "
            f"{_e(r['med_cd'])} | {_f(r['W_cd_all'], 1)} | {r['n_ok']}/{r['n_points']} |"
        )
    return head + "\n".join(lines) + "\n"


def noisy_reconstructed(df: pd.DataFrame) -> str:
    head = (
        "| cd [kg/s] | noise | method | tau_c err [%] | k0 err [%] | k_inf err [%] | cd err [%] | flagged | "
        "wall [s] |\n|---|---|---|---|---|---|---|---|---|\n"
    )
    lines = []
    for _, r in df.sort_values([CD, NOISE, "method"]).iterrows():
        lines.append(
            f"| {r[CD]:g} | {_noise(r[NOISE])} | {r['method']} | {_e(r['tau_c_err_pct'])} | {_e(r['k0_err_pct'])} | "
            f"{_e(r['k_inf_err_pct'])} | {_e(r['cd_err_pct'])} | {r['unidentified'] or '–'} | {r['wall_s']:.1f} |"
        )
    return head + "\n".join(lines) + "\n"


def measure_reconstruction() -> str:
    """RMS error of the reconstructed force (Nyquist cut-off) against f_ts for 0, 1, 10 pm."""
    from vetica_cli.signals.spectral import reconstruct_force, reconstruction_error
    from vetica_cli.simulation.config import load
    from vetica_cli.simulation.simulate import simulate
    from vetica_cli.rows.plan import point_run

    base = {"surface.k_inf": 4.0, "surface.k0": 64.0, "surface.cd": 1e-3, "numerics.dt": 0.025e-9,
            "numerics.print_step": 0.125e-9, "numerics.kp": 0.05, "numerics.ki": 0.03,
            "numerics.max_time": 0.012}  # fmt: skip
    clean = load(None, base)
    shared = simulate(clean)
    f_true = shared.steady[:, 5]
    out = ["| position noise | RMS error of the reconstructed force [% of peak] | max error [% of peak] |",
           "|---|---|---|"]  # fmt: skip
    for noise in (0.0, 1e-12, 1e-11):
        cfg = load(None, {**base, "numerics.position_noise": noise})
        run = point_run(shared, clean, cfg)
        p = cfg.probe
        rec = reconstruct_force(run.steady[:, 0], run.steady[:, 3], p.k2, p.f2, p.q2)
        e = reconstruction_error(rec.f, f_true)
        out.append(f"| {_noise(noise)} | {e['rms_pct']:.3g} | {e['max_pct']:.3g} |")
    return "\n".join(out) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--measure-reconstruction", action="store_true", help="simulate one point (~5 s) for the RMS")
    ap.add_argument("-o", "--output", type=Path, default=None, help="also write the Markdown tables here")
    args = ap.parse_args()
    parts, summaries = [], []
    for name, (setting, label) in STUDIES.items():
        path = RESULTS / f"{name}.parquet"
        if not path.is_file():
            parts.append(f"## {name}\n\n(missing: run `vetica sweep configs/{name}.yaml`)\n")
            continue
        df, meta = read_table(path)
        s = summarize(df, setting)
        s.insert(0, "study", name)
        summaries.append(s)
        parts.append(f"## {name} ({meta.get('description', '')})\n\n" + markdown_table(s, setting, label))
    low, dash = RESULTS / "method_low_cd.parquet", RESULTS / "method_dashpot.parquet"
    if low.is_file() and dash.is_file():
        # the dashpot grid at 0.125 ns without noise, extended below cd = 1e-5 kg/s
        d, _ = read_table(dash)
        d = d[(d["numerics.print_step"] == 0.125e-9) & (d[NOISE] == 0.0)]
        lo, _ = read_table(low)
        lo = lo.assign(**{"numerics.print_step": 0.125e-9, NOISE: 0.0})
        s = summarize(pd.concat([lo, d], ignore_index=True), "numerics.print_step")
        s.insert(0, "study", "method_dashpot+method_low_cd")
        summaries.append(s)
        parts.append(
            "## cd grid extended down to 1e-7 kg/s (16:1, 0.125 ns, no noise; method_low_cd + method_dashpot)\n\n"
            + markdown_table(s, "numerics.print_step", "print step")
        )
    if summaries:
        summ = pd.concat(summaries, ignore_index=True)
        write_table(summ, RESULTS / "method_comparison_summary.parquet", {"source": "scripts/method_comparison.py"})
        stamp(RESULTS / "method_comparison_summary.parquet")  # units and descriptions in the metadata
    nr = RESULTS / "method_noise_reconstructed.parquet"
    if nr.is_file():
        df, _ = read_table(nr)
        cols = [CD, NOISE, "method", "force_source", "status", "tau_c_err_pct", "k0_err_pct", "k_inf_err_pct",
                "cd_err_pct", "unidentified", "wall_s"]  # fmt: skip
        write_table(df[cols].reset_index(drop=True), RESULTS / "method_comparison_noisy_reconstructed.parquet",
                    {"source": "scripts/method_comparison.py"})  # fmt: skip
        stamp(RESULTS / "method_comparison_noisy_reconstructed.parquet")
        parts.append("## Reconstructed force with detector noise (16:1, PS 0.125 ns)\n\n" + noisy_reconstructed(df))
    if args.measure_reconstruction:
        parts.append(
            "## Reconstruction error against the position noise (cd = 1e-3 kg/s)\n\n" + measure_reconstruction()
        )
    text = "\n".join(parts)
    print(text)
    if args.output is not None:
        args.output.write_text(text)


if __name__ == "__main__":
    main()
