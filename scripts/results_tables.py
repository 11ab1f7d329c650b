"""Summary tables quoted in results/thesis/comparison.md, computed from the study tables.

    python scripts/results_tables.py            # markdown on stdout, ~5 s

Reads results/<kind>/<study>.parquet (regenerate_results.table; written by `vetica sweep configs/<study>.yaml`).
Errors are summarised by their magnitude (tables from v0.2 on store them signed).
The acceptance regime is the one `vetica sweep` and `vetica plot` use
(vetica_cli.study.acceptance.regime: status ok and |tau_c error| < 30 %, thesis fig. 52).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from vetica_cli.plots.observables import common_steady
from vetica_cli.study.acceptance import regime

RES = Path(__file__).resolve().parent.parent / "results"
STUDIES = [
    "dashpot",
    "dashpot_vdw_off",
    "print_step",
    "paddle_stiffness",
    "setpoint",
    "stiffness_ratio",
    "stiffness_ratio_vdw_off",
    "frequency",
]
from regenerate_results import THESIS as THESIS7  # noqa: E402  (the seven thesis study configs)
from regenerate_results import table  # noqa: E402  (where each study's table lives)
CD = "surface.cd"
Q = ["tau_c", "k_g", "k0", "k_inf", "cd"]
QL = {"tau_c": "τc", "k_g": "Kg", "k0": "k0", "k_inf": "k_inf", "cd": "cd"}


def load(name: str) -> pd.DataFrame:
    df = pd.read_parquet(table(name))
    df["force_source"] = df["force_source"].astype(str)
    df["status"] = df["status"].astype(str)
    return df


def md(df: pd.DataFrame, floatfmt: str = ".3g") -> str:
    cols = list(df.columns)
    out = ["| " + " | ".join(str(c) for c in cols) + " |", "|" + "---|" * len(cols)]
    for _, r in df.iterrows():
        cells = []
        for c in cols:
            v = r[c]
            if isinstance(v, (float, np.floating)):
                cells.append("–" if not np.isfinite(v) else format(v, floatfmt))
            else:
                cells.append(str(v))
        out.append("| " + " | ".join(cells) + " |")
    return "\n".join(out)


def regime_str(d: pd.DataFrame) -> tuple[str, float]:
    r = regime(d)
    if r is None:
        return "none", np.nan
    dec = np.log10(r.hi / r.lo)
    return f"{r.lo:.2g} – {r.hi:.2g}{'' if r.contiguous else ' (broken)'}", dec


def overview() -> str:
    tpath = RES / "timings.json"
    timings = json.loads(tpath.read_text()) if tpath.is_file() else {}
    rows = []
    for n in STUDIES:
        df = load(n)
        pts = df[df.force_source == "true"]
        st = pts["status"].value_counts()
        w = timings.get(n, {}).get("wall_s", np.nan)
        rows.append(
            {
                "study": n,
                "points": len(pts),
                "ok": int(st.get("ok", 0)),
                "no_estimate": int(st.get("no_estimate", 0)),
                "not_steady": int(st.get("not_steady", 0)),
                "failed": int(st.get("failed", 0)),
                "simulated time [ms]": float(pts["sim_time"].sum()) * 1e3,
                "wall time [s]": w,
            }
        )
    out = md(pd.DataFrame(rows))
    t7 = [timings[s]["wall_s"] for s in THESIS7 if s in timings]
    if len(t7) == len(THESIS7):
        loads = [timings[s].get("load_at_start", np.nan) for s in THESIS7]
        out += (
            f"\n\nThe seven thesis study configs ({', '.join(THESIS7)}): {sum(t7):.1f} s wall together "
            f"(2 workers; load average at their starts {min(loads):.2f} – {max(loads):.2f}; results/timings.json)."
        )
    return out


def no_estimate_table() -> str:
    """Where the extraction gave no value although the record is steady, and why (first reason)."""
    rows = []
    for n in STUDIES:
        df = load(n)
        d = df[(df.force_source == "true") & (df.status == "no_estimate")]
        if not len(d):
            continue
        reason = d["error"].astype(str).str.extract(r"^(no estimate of [^:]+: stage \w+: [^(;]+)")[0].value_counts()
        rows.append(
            {
                "study": n,
                "no_estimate points": len(d),
                "cd range [kg/s]": f"{d[CD].min():.2g} – {d[CD].max():.2g}" if CD in d else "–",
                "τc theory range [ms]": f"{d['tau_c_theory'].min() * 1e3:.2g} – {d['tau_c_theory'].max() * 1e3:.2g}",
                "most common reason": f"{reason.index[0].strip()} ({reason.iloc[0]} of {len(d)})" if len(reason) else "–",
            }
        )
    return md(pd.DataFrame(rows)) if rows else "none"


def dashpot_tables() -> str:
    parts = []
    on, off = load("dashpot"), load("dashpot_vdw_off")
    rows = []
    for lab, df in (("vdW on (default)", on), ("vdW off", off)):
        for src in ("true", "reconstructed"):
            d = df[df.force_source == src]
            s, dec = regime_str(d)
            r = regime(d)
            inside = d[(d[CD] >= r.lo) & (d[CD] <= r.hi) & (d.status == "ok")] if r else d.iloc[:0]
            row = {"surface": lab, "force": src, "acceptance regime cd [kg/s]": s, "decades": dec}
            for q in Q:
                row[f"{QL[q]} err %: mean / max"] = (
                    f"{inside[f'{q}_err_pct'].abs().mean():.3g} / {inside[f'{q}_err_pct'].abs().max():.3g}"
                )
            rows.append(row)
    parts.append(
        "Acceptance regime and the mean / largest errors inside it (f1 50 kHz, 16:1, PS 0.5 ns):\n\n"
        + md(pd.DataFrame(rows))
    )
    # per-cd table, true force, both surfaces
    a = on[on.force_source == "true"].set_index(CD)
    b = off[off.force_source == "true"].set_index(CD)
    t = pd.DataFrame(
        {
            "cd [kg/s]": a.index,
            "τc theory [µs]": a["tau_c_theory"].to_numpy() * 1e6,
            "status on": a["status"].to_numpy(),
            "τc err % on": a["tau_c_err_pct"].to_numpy(),
            "Kg err % on": a["k_g_err_pct"].to_numpy(),
            "k0 err % on": a["k0_err_pct"].to_numpy(),
            "k_inf err % on": a["k_inf_err_pct"].to_numpy(),
            "cd err % on": a["cd_err_pct"].to_numpy(),
            "status off": b.reindex(a.index)["status"].to_numpy(),
            "τc err % off": b.reindex(a.index)["tau_c_err_pct"].to_numpy(),
            "k_inf err % off": b.reindex(a.index)["k_inf_err_pct"].to_numpy(),
            "cd err % off": b.reindex(a.index)["cd_err_pct"].to_numpy(),
        }
    )
    parts.append("Per point, true force (`on` = dashpot.parquet, `off` = dashpot_vdw_off.parquet):\n\n" + md(t))
    # absolute stiffness deviations across all ok points (thesis: k0 within ±4 N/m, k_inf within ±2 N/m)
    rows = []
    for lab, df in (("vdW on", on), ("vdW off", off)):
        for src in ("true", "reconstructed"):
            d = df[(df.force_source == src) & (df.status == "ok")]
            r = regime(d)
            ins = d[(d[CD] >= r.lo) & (d[CD] <= r.hi)] if r else d.iloc[:0]
            rows.append(
                {
                    "surface": lab,
                    "force": src,
                    "max Δk0 in regime [N/m]": (ins["k0"] - ins["k0_theory"]).abs().max(),
                    "max Δk_inf in regime [N/m]": (ins["k_inf"] - ins["k_inf_theory"]).abs().max(),
                    "max Δk0, all ok [N/m]": (d["k0"] - d["k0_theory"]).abs().max(),
                    "max Δk_inf, all ok [N/m]": (d["k_inf"] - d["k_inf_theory"]).abs().max(),
                    "max Kg err % all ok": d["k_g_err_pct"].abs().max(),
                    "ok points without τc": int(d["tau_c"].isna().sum()),
                }
            )
    parts.append(
        "Absolute stiffness deviations Δ = abs(extracted − theory) (thesis fig. 45: k0 within ±4 N/m, k_inf within ±2 N/m):\n\n"
        + md(pd.DataFrame(rows))
    )
    # E_diss and zero depth
    t = a[["e_diss_ev", "ss_zero_depth", "max_penetration", "peak_force"]].copy()
    t = pd.DataFrame(
        {
            "cd [kg/s]": a.index,
            "status on": a["status"].to_numpy(),
            "status off": b.reindex(a.index)["status"].to_numpy(),
            "E_diss on [eV]": a["e_diss_ev"].to_numpy(),
            "E_diss off [eV]": b.reindex(a.index)["e_diss_ev"].to_numpy(),
            "zero depth on [nm]": a["ss_zero_depth"].to_numpy() * 1e9,
            "zero depth off [nm]": b.reindex(a.index)["ss_zero_depth"].to_numpy() * 1e9,
        }
    )
    parts.append("Dissipation and steady-state zero reference depth against cd (figs. 41, 57):\n\n" + md(t.iloc[::2]))
    return "\n\n".join(parts)


def regime_by(name: str, key: str, scale: float, unit: str) -> str:
    df = load(name)
    rows = []
    for kv, g in df.groupby(key):
        row = {f"{key} [{unit}]": kv * scale}
        for src in ("true", "reconstructed"):
            s, dec = regime_str(g[g.force_source == src])
            row[f"regime, {src}"] = s
            row[f"decades, {src}"] = dec
        gt = g[g.force_source == "true"]
        row["no_estimate"] = int((gt.status == "no_estimate").sum())
        row["not_steady"] = int((gt.status == "not_steady").sum())
        row["failed"] = int((gt.status == "failed").sum())
        row["min τc err % (true)"] = gt.loc[gt.status == "ok", "tau_c_err_pct"].abs().min()
        rows.append(row)
    return md(pd.DataFrame(rows))


def frequency_tables() -> str:
    df = load("frequency")
    parts = [regime_by("frequency", "probe.f1", 1e-3, "kHz")]
    pts = common_steady(df[df.force_source == "true"], "probe.f1", [CD])[0]
    g = pts.groupby("probe.f1")
    t = pd.DataFrame(
        {
            "f1 [kHz]": g.size().index * 1e-3,
            "period [µs]": 1e6 / g.size().index,
            "contact [µs]": g["contact_time"].mean().to_numpy() * 1e6,
            "non-contact [µs]": g["noncontact_time"].mean().to_numpy() * 1e6,
            "contact fraction %": (
                g["contact_time"].mean() / (g["contact_time"].mean() + g["noncontact_time"].mean())
            ).to_numpy()
            * 100,
        }
    )
    parts.append(
        "Contact and non-contact time per cycle (mean over the cd values that are steady at every f1, as the figure averages, fig. 51):\n\n"
        + md(t)
    )
    return "\n\n".join(parts)


def mean_err_in_regime(df: pd.DataFrame, key: str, src: str = "true") -> pd.DataFrame:
    rows = []
    for kv, g in df[df.force_source == src].groupby(key):
        r = regime(g)
        row = {key: kv, "n in regime": 0}
        if r is not None:
            ins = g[(g[CD] >= r.lo) & (g[CD] <= r.hi) & (g.status == "ok")]
            row["n in regime"] = len(ins)
            for q in Q:
                row[f"{QL[q]} %"] = ins[f"{q}_err_pct"].abs().mean()
        else:
            for q in Q:
                row[f"{QL[q]} %"] = np.nan
        rows.append(row)
    return pd.DataFrame(rows)


def ratio_tables() -> str:
    df = load("stiffness_ratio")
    parts = [regime_by("stiffness_ratio", "surface.stiffness_ratio", 1.0, "k0:k_inf")]
    for src in ("true", "reconstructed"):
        parts.append(
            f"Mean error within each ratio's acceptance regime, {src} force (fig. 47):\n\n"
            + md(mean_err_in_regime(df, "surface.stiffness_ratio", src))
        )
    pts = common_steady(df[df.force_source == "true"], "surface.stiffness_ratio", [CD])[0]
    g = pts.groupby("surface.stiffness_ratio")
    lo_cd, hi_cd = df[CD].min(), df[CD].max()
    t = pd.DataFrame(
        {
            "k0:k_inf": g.size().index,
            "peak force [nN]": g["peak_force"].mean().to_numpy() * 1e9,
            "max penetration [nm]": g["max_penetration"].mean().to_numpy() * 1e9,
            "paddle amplitude [nm]": g["paddle_amplitude"].mean().to_numpy() * 1e9,
        }
    )
    ed = df[df.force_source == "true"].pivot_table(index="surface.stiffness_ratio", columns=CD, values="e_diss_ev")
    t[f"E_diss at cd {lo_cd:g} [eV]"] = ed[lo_cd].to_numpy()
    t[f"E_diss at cd {hi_cd:g} [eV]"] = ed[hi_cd].to_numpy()
    parts.append(
        "Means over the cd values that are steady at every ratio (figs. 48, 49) and E_diss at the ends of the cd range (fig. 41):\n\n"
        + md(t)
    )
    return "\n\n".join(parts)


def ratio_vdw_off_tables() -> str:
    df = load("stiffness_ratio_vdw_off")
    parts = [regime_by("stiffness_ratio_vdw_off", "surface.stiffness_ratio", 1.0, "k0:k_inf")]
    for src in ("true", "reconstructed"):
        parts.append(
            f"Mean error within each ratio's acceptance regime, vdW off, {src} force (fig. 47):\n\n"
            + md(mean_err_in_regime(df, "surface.stiffness_ratio", src))
        )
    return "\n\n".join(parts)


def setpoint_tables() -> str:
    df = load("setpoint")
    parts = [regime_by("setpoint", "operation.setpoint", 100, "% of A0")]
    for src in ("true",):
        parts.append(
            f"Mean error within each set point's acceptance regime, {src} force (fig. 55):\n\n"
            + md(mean_err_in_regime(df, "operation.setpoint", src))
        )
    pts = df[(df.force_source == "true") & (df.status != "failed")]
    g = common_steady(pts, "operation.setpoint", [CD])[0].groupby("operation.setpoint")
    t = pd.DataFrame(
        {
            "set point %": g.size().index * 100,
            "contact [µs]": g["contact_time"].mean().to_numpy() * 1e6,
            "non-contact [µs]": g["noncontact_time"].mean().to_numpy() * 1e6,
            "peak force [nN]": g["peak_force"].mean().to_numpy() * 1e9,
            "max penetration [nm]": g["max_penetration"].mean().to_numpy() * 1e9,
        }
    )
    depth = []
    for sp, gg in pts.groupby("operation.setpoint"):
        gg = gg.dropna(subset=["ss_zero_depth"])
        if len(gg):
            i = gg["ss_zero_depth"].idxmax()
            depth.append((gg.loc[i, "ss_zero_depth"] * 1e9, gg.loc[i, CD]))
        else:
            depth.append((np.nan, np.nan))
    t["deepest zero depth [nm]"] = [d[0] for d in depth]
    t["at cd [kg/s]"] = [d[1] for d in depth]
    parts.append(
        "Means over the cd values that are steady at every set point (figs. 54, 56, as the figures average) and the deepest steady-state zero reference over all simulated points (fig. 57):\n\n"
        + md(t)
    )
    fails = df[(df.force_source == "true") & (df.status == "failed")]
    if len(fails):
        ft = fails.groupby("operation.setpoint").agg(n=("status", "size"), error=("error", "first")).reset_index()
        parts.append("Failed points:\n\n" + md(ft))
    return "\n\n".join(parts)


def print_step_tables() -> str:
    return regime_by("print_step", "numerics.print_step", 1e9, "ns")


def paddle_tables() -> str:
    df = load("paddle_stiffness")
    d = df[df.force_source == "true"].sort_values("probe.k2")
    t = pd.DataFrame(
        {
            "k2 [N/m]": d["probe.k2"].to_numpy(),
            "E_diss [eV]": d["e_diss_ev"].to_numpy(),
            "peak force [nN]": d["peak_force"].to_numpy() * 1e9,
            "paddle amplitude [nm]": d["paddle_amplitude"].to_numpy() * 1e9,
            "status": d["status"].to_numpy(),
        }
    )
    return md(t, ".4g")


def not_steady_table() -> str:
    rows = []
    for n in STUDIES:
        df = load(n)
        d = df[(df.force_source == "true") & (df.status == "not_steady")]
        if not len(d):
            continue
        rows.append(
            {
                "study": n,
                "not_steady points": len(d),
                "cd range [kg/s]": f"{d[CD].min():.2g} – {d[CD].max():.2g}" if CD in d else "–",
                "τc theory range [ms]": f"{d['tau_c_theory'].min() * 1e3:.2g} – {d['tau_c_theory'].max() * 1e3:.2g}",
                "max_time [ms]": ", ".join(f"{v * 1e3:g}" for v in sorted(d["sim_time"].unique())),
            }
        )
    return md(pd.DataFrame(rows)) if rows else "none"


def findings_tables() -> str:
    """The measurements behind results/thesis/comparison.md's "Thesis findings: causes" (configs/findings_*.yaml)."""
    parts = []
    t = load("findings_table5")
    t = t[t.force_source == "true"]
    cols = ["surface.vdw_on_surface", "numerics.steady", "numerics.print_step", "status", "sim_time",
            "tau_c_err_pct", "k_g_err_pct", "k0_err_pct", "k_inf_err_pct", "cd_err_pct"]  # fmt: skip
    d = t[cols].copy()
    d["numerics.print_step"] *= 1e9
    d["sim_time"] *= 1e3
    d = d.rename(columns={"numerics.print_step": "PS [ns]", "sim_time": "simulated [ms]"})
    parts.append("Table 5 point (30 kHz, cd 8e-2 kg/s, 16:1), true force, errors signed % (findings_table5):\n\n" + md(d))
    t = load("findings_tau_c_edge")
    t = t[t.force_source == "true"]
    pv = t.pivot_table(index=CD, columns="numerics.print_step", values="tau_c_err_pct", dropna=False)
    pv.columns = [f"τc err % at PS {c * 1e9:g} ns" for c in pv.columns]
    parts.append("τc error against cd and print step, 50 kHz, 16:1, pull off (findings_tau_c_edge; – = no estimate):\n\n"
                 + md(pv.reset_index().rename(columns={CD: "cd [kg/s]"})))  # fmt: skip
    t = load("findings_setpoint")
    t = t[t.force_source == "true"]
    rows = []
    for (vdw, cd), g in t.groupby(["surface.vdw_on_surface", CD]):
        g = g.sort_values("operation.setpoint")
        x, y = g["operation.setpoint"].to_numpy(), g["contact_time"].to_numpy() * 1e6
        m = x >= 0.4 - 1e-9
        p = np.polyfit(x[m], y[m], 1)
        r = y[m] - np.polyval(p, x[m])
        ok = g[(g.status == "ok")]
        lo, hi = ok.iloc[0], ok.iloc[-1]
        rows.append({"pull": "on" if vdw else "off", "cd [kg/s]": cd,
                     "contact 25 / 40 / 80 % [µs]": f"{y[0]:.3f} / {y[x.searchsorted(0.4 - 1e-9)]:.3f} / {y[-1]:.3f}",
                     "linear fit ≥ 40 %: R²": 1 - np.sum(r**2) / np.sum((y[m] - y[m].mean()) ** 2),
                     "max residual [ns]": np.abs(r).max() * 1e3,
                     "k_inf err % 25 → 80 %": f"{lo['k_inf_err_pct']:.3g} → {hi['k_inf_err_pct']:.3g}",
                     "cd err % 25 → 80 %": f"{lo['cd_err_pct']:.3g} → {hi['cd_err_pct']:.3g}",
                     "k0 err % 25 → 80 %": f"{lo['k0_err_pct']:.3g} → {hi['k0_err_pct']:.3g}"})  # fmt: skip
    parts.append("Set point 25 … 80 % in 5 % steps, true force (findings_setpoint):\n\n" + md(pd.DataFrame(rows), ".4g"))
    t = load("findings_ediss_pull")
    t = t[t.force_source == "true"]
    ref = {(750e3, 700.0): ("fig. 28", 45.9), (1.5e6, 2800.0): ("fig. 29A", 61.4), (1.5e6, 700.0): ("fig. 29B", 59.2)}
    rows = []
    for (f2, k2), g in t.groupby(["probe.f2", "probe.k2"]):
        lab, th = ref.get((f2, k2), ("–", np.nan))
        on = float(g.loc[g["surface.vdw_on_surface"].astype(bool), "e_diss_ev"].iloc[0])
        off = float(g.loc[~g["surface.vdw_on_surface"].astype(bool), "e_diss_ev"].iloc[0])
        rows.append({"f2 [kHz]": f2 * 1e-3, "k2 [N/m]": k2, "thesis": lab, "thesis E_diss [eV]": th,
                     "pull on [eV]": on, "vs thesis %": 100 * (on - th) / th,
                     "pull off [eV]": off, "vs thesis % ": 100 * (off - th) / th})  # fmt: skip
    parts.append("E_diss of the system of figs. 28–29 (findings_ediss_pull):\n\n" + md(pd.DataFrame(rows), ".4g"))
    return "\n\n".join(parts)


def surface_position_tables() -> str:
    """Figs. 59-60: deviation of the recorded contact / separation from the true events (surface_position)."""
    t = load("surface_position")
    t = t[t.force_source == "true"].sort_values("numerics.print_step")
    d = pd.DataFrame({"PS [ns]": t["numerics.print_step"].to_numpy() * 1e9,
                      "contact position dev [pm]": t["contact_pos_dev"].to_numpy() * 1e12,
                      "separation position dev [pm]": t["separation_pos_dev"].to_numpy() * 1e12,
                      "contact time dev [ns]": t["contact_time_dev"].to_numpy() * 1e9,
                      "separation time dev [ns]": t["separation_time_dev"].to_numpy() * 1e9})  # fmt: skip
    keep = np.unique(np.r_[0:len(d):6, len(d) - 1])
    return "Every 6th print step of the 60 (surface_position, true force):\n\n" + md(d.iloc[keep], ".3g")


def main(argv: list[str]) -> int:
    sections = {
        "overview": overview,
        "not_steady": not_steady_table,
        "no_estimate": no_estimate_table,
        "dashpot": dashpot_tables,
        "frequency": frequency_tables,
        "print_step": print_step_tables,
        "stiffness_ratio": ratio_tables,
        "stiffness_ratio_vdw_off": ratio_vdw_off_tables,
        "setpoint": setpoint_tables,
        "paddle_stiffness": paddle_tables,
        "surface_position": surface_position_tables,
        "findings": findings_tables,
    }
    want = argv or list(sections)
    for s in want:
        print(f"### {s}\n\n{sections[s]()}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
