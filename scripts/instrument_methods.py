"""Evidence: the instrument's numbers (``observables``: tan d_AM, E_diss, virial
from amplitude and phase; ``dmt-fit``: per-tap DMT modulus, unloading stiffness, adhesion,
loop dissipation, deformation) beside VETICA, VETICA with pre-stress and the whole-cycle fit.

Reads the study table (run it first, ~3 min on 2 cores)::

    vetica sweep configs/instrument_methods.yaml -o results/instrument_methods/instrument_methods.parquet

and writes ``results/instrument_methods/summary.md`` (ranking and bias, one row per method,
quantity and force source) and ``results/instrument_methods/tan_delta.png`` (tan d_AM, the
surface's tan delta at the drive frequency and at pi / contact time, and VETICA's tau_c,
against cd)::

    python scripts/instrument_methods.py

Definitions, per (stiffness ratio, set point) and cd grid of the study (9 points, 1e-6 .. 1e2):

* **ranks** (and **of the pairs both estimated**, the same among the pairs where the method gave
  both numbers): of the pairs of cd points whose truth differs by more than 5 % (a material pair a
  user could tell apart), the fraction whose estimates order the two materials as their truths
  do (1 = every such pair ranked correctly; estimates that differ by less than 1 % count as a
  wrong order: the method cannot tell them apart); pooled over the four (ratio, set point);
* **monotonic**: whether the estimate rises (or falls) with cd as its truth does over every
  neighbouring pair, counted in the four (ratio, set point) series;
* **bias**: median and range of the signed error ``100 (estimate - truth)/truth`` [%] over the
  points with an estimate.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pandas as pd

from vetica_cli.io import read_table
from vetica_cli.plots.style import new_figure, save_png

OUT = Path(__file__).resolve().parents[1] / "results" / "instrument_methods"
TABLE = OUT / "instrument_methods.parquet"
# (method, estimate column, truth column, what the truth is)
COMPARISONS = (
    ("vetica", "tau_c", "tau_c_theory", "tau_c"),
    ("vetica", "cd", "cd_theory", "cd"),
    ("vetica-prestress", "tau_c", "tau_c_theory", "tau_c"),
    ("vetica-prestress", "cd", "cd_theory", "cd"),
    ("full", "tau_c", "tau_c_theory", "tau_c"),
    ("full", "cd", "cd_theory", "cd"),
    ("observables", "tan_delta_am", "tan_delta_drive_theory", "tan delta at f1"),
    ("observables", "tan_delta_am", "tan_delta_contact_theory", "tan delta at pi/t_c"),
    ("observables", "e_diss_obs", "e_diss_obs_theory", "sample E_diss"),
    ("observables", "virial_obs", "virial_obs_theory", "virial"),
    ("dmt-fit", "e_dmt", "k_storage_contact_theory", "k' at pi/t_c (ranking only)"),
    ("dmt-fit", "k_dmt", "k_storage_contact_theory", "k' at pi/t_c"),
    ("dmt-fit", "adhesion", "adhesion_theory", "Fa(a0)"),
    ("dmt-fit", "e_diss_tap", "e_diss_tap_theory", "sample E_diss"),
    ("dmt-fit", "deformation", "deformation_theory", "max penetration"),
)
GROUP = ["surface.stiffness_ratio", "operation.setpoint"]
TRUTH_STEP = 0.05  # truths closer than this (relative) are not a pair to rank
SAME = 0.01  # estimates closer than this (relative) do not rank the pair


def _rel(a: float, b: float) -> float:
    return abs(a - b) / max(abs(a), abs(b), 1e-300)


def ranking(g: pd.DataFrame, est: str, truth: str) -> tuple[int, int, int, bool]:
    """``(correct, pairs, pairs both estimated, monotonic)`` over one cd series (module docstring)."""
    g = g.sort_values("surface.cd")
    v, t = g[est].to_numpy(float), g[truth].to_numpy(float)
    ok = n = both = 0
    for i, j in itertools.combinations(range(len(g)), 2):
        if not (np.isfinite(t[i]) and np.isfinite(t[j])) or _rel(t[i], t[j]) < TRUTH_STEP:
            continue
        n += 1
        if np.isfinite(v[i]) and np.isfinite(v[j]):
            both += 1
            if _rel(v[i], v[j]) >= SAME:
                ok += int(np.sign(v[j] - v[i]) == np.sign(t[j] - t[i]))
    steps = [(np.sign(v[k + 1] - v[k]), np.sign(t[k + 1] - t[k])) for k in range(len(g) - 1)
             if np.isfinite(t[k]) and np.isfinite(t[k + 1]) and _rel(t[k], t[k + 1]) >= TRUTH_STEP]  # fmt: skip
    mono = bool(steps) and all(a == b for a, b in steps)
    return ok, n, both, mono


def summary(df: pd.DataFrame) -> pd.DataFrame:
    rows = []
    for (method, est, truth, what), source in itertools.product(COMPARISONS, ("true", "reconstructed")):
        d = df[(df["method"] == method) & (df["force_source"] == source)]
        if d.empty or truth not in d:
            continue
        ok = n = both = mono = 0
        for _, g in d.groupby(GROUP):
            a, b, c, m = ranking(g, est, truth)
            ok, n, both, mono = ok + a, n + b, both + c, mono + int(m)
        v, t = d[est].to_numpy(float), d[truth].to_numpy(float)
        has = np.isfinite(v) & np.isfinite(t) & (t != 0)
        err = 100 * (v[has] - t[has]) / t[has]
        rows.append({
            "method": method, "quantity": est, "truth": what, "force": source,
            "ranks": ok / n if n else math.nan, "pairs": n, "ranks_estimated": ok / both if both else math.nan,
            "pairs_estimated": both, "monotonic_series": mono,
            "estimated": int(np.isfinite(v).sum()), "points": len(d),
            "bias_median_pct": float(np.median(err)) if len(err) else math.nan,
            "bias_min_pct": float(np.min(err)) if len(err) else math.nan,
            "bias_max_pct": float(np.max(err)) if len(err) else math.nan,
        })  # fmt: skip
    return pd.DataFrame(rows)


def _pct(v: float) -> str:
    if not math.isfinite(v):
        return "-"
    return f"{v:+.3g}" if abs(v) < 1e4 else f"{v:+.2e}"


def markdown(s: pd.DataFrame) -> str:
    lines = ["| method | estimate | truth | force | pairs ranked right | of the pairs both estimated | "
             "monotonic series (of 4) | estimated | bias median % | bias range % |",
             "|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for _, r in s.iterrows():
        ranks = f"{r['ranks']:.2f} of {r['pairs']}" if r["pairs"] else "- (truth flat)"
        est = f"{r['ranks_estimated']:.2f} of {r['pairs_estimated']}" if r["pairs_estimated"] else "-"
        lines.append(f"| {r['method']} | {r['quantity']} | {r['truth']} | {r['force']} | {ranks} | {est} | "
                     f"{r['monotonic_series']} | {r['estimated']}/{r['points']} | {_pct(r['bias_median_pct'])} | "
                     f"{_pct(r['bias_min_pct'])} .. {_pct(r['bias_max_pct'])} |")  # fmt: skip
    return "\n".join(lines)


def figure(df: pd.DataFrame, path: Path) -> Path:
    groups = list(df.groupby(GROUP))
    fig = new_figure(4.0 * len(groups), 7.0)
    axes = fig.subplots(2, len(groups), sharex=True, squeeze=False)
    for j, ((ratio, sp), g) in enumerate(groups):
        ax, bx = axes[0, j], axes[1, j]
        o = g[(g["method"] == "observables") & (g["force_source"] == "true")].sort_values("surface.cd")
        cd = o["surface.cd"].to_numpy(float)
        ax.plot(cd, o["tan_delta_am"], "o-", color="C0", label=r"$\tan\delta_{AM}$ (amplitude, phase)")
        ax.plot(cd, o["tan_delta_drive_theory"], "k-", lw=1.2, label=r"true $\tan\delta(f_1)$")
        ax.plot(cd, o["tan_delta_contact_theory"], "k--", lw=1.0, label=r"true $\tan\delta(\pi/t_c)$")
        ax.set_yscale("log")
        ax.set_title(f"k0:k_inf {ratio:g}:1, set point {sp:g}", fontsize=10)
        for k, (source, mk) in enumerate((("true", "s"), ("reconstructed", "^"))):
            v = g[(g["method"] == "vetica") & (g["force_source"] == source)].sort_values("surface.cd")
            bx.plot(v["surface.cd"], v["tau_c"] * 1e6, mk, ls="-" if k == 0 else ":", color=f"C{k + 1}",
                    label=f"VETICA $\\tau_c$ ({source} force)")  # fmt: skip
        bx.plot(v["surface.cd"], v["tau_c_theory"] * 1e6, "k-", lw=1.2, label=r"true $\tau_c$")
        bx.set_yscale("log")
        bx.set_xscale("log")
        bx.set_xlabel(r"dashpot $c_d$ [kg/s]")
        if j == 0:
            ax.set_ylabel(r"loss tangent")
            bx.set_ylabel(r"$\tau_c$ [µs]")
            ax.legend(fontsize=7)
            bx.legend(fontsize=7)
    fig.suptitle("tan d_AM from amplitude and phase vs the surface's own tan delta, and VETICA's tau_c "
                 "(missing points: no estimate)", fontsize=10)  # fmt: skip
    return save_png(fig, path)


def main() -> None:
    df, _ = read_table(TABLE)
    s = summary(df)
    (OUT / "summary.md").write_text(
        "# instrument_methods: ranking and bias (scripts/instrument_methods.py)\n\n" + markdown(s) + "\n"
    )
    print(markdown(s))
    print(figure(df, OUT / "tan_delta.png"))


if __name__ == "__main__":
    main()
