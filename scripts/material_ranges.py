"""The thesis's material ranges (4.6.2) from our study tables: DMT modulus 32 MPa .. 9 GPa
and viscosity 700 Pa s .. 70 GPa s over its study, 700 Pa s .. 70 MPa s over the
acceptance regime.

    python scripts/material_ranges.py [FOLDER_OR_TABLES ...] [--all]     # default: every table under results/

For every study table (``*.parquet`` with ``status`` and ``force_source``) it prints the
range of ``E_dmt`` (the DMT modulus from each point's peak force and penetration, thesis
eqs. 90-92) and of ``viscosity_theory`` (``E_dmt`` times the point's theory relaxation
time ``tau_r``, the thesis's "modulus times relaxation time") over the points with
status 'ok' (true-force rows, one per point and method), and the viscosity range over
the acceptance regime (status 'ok' and tau_c error < 30 %, the one definition of
:mod:`vetica_cli.study.acceptance`, per method), then the union over the tables.

Only points inside the thesis's study ranges count (table 1: ``cd`` 1e-5 .. 1e3 kg/s,
``k0:k_inf`` 1:8 .. 32:1); ``--all`` takes every point (e.g. ``method_low_cd``'s cd down to
1e-7 kg/s).

Tables written before the material columns existed (version 0.2 and earlier) have no
``E_dmt``: the script then uses the simulation's observables ``peak_force`` and
``max_penetration`` (the surface's own depth, not the record's depth below Z1) with the
contact model of thesis table 6 and says so.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pandas as pd

from vetica_cli.extraction.material import ContactModel, moduli
from vetica_cli.io import read_table
from vetica_cli.study.acceptance import ACCEPT_ERR_PCT, accepted

ROOT = Path(__file__).resolve().parents[1]
THESIS = {"E_dmt": (32e6, 9e9), "viscosity": (700.0, 70e9), "viscosity_accepted": (700.0, 70e6)}
CD_RANGE = (1e-5, 1e3)  # [kg/s] thesis table 1
RATIO_RANGE = (1 / 8, 32.0)  # k0:k_inf, thesis table 1


def in_thesis_ranges(df: pd.DataFrame) -> pd.Series:
    """Rows whose surface lies in the thesis's study ranges (theory columns of the table)."""
    ok = pd.Series(True, index=df.index)
    if "cd_theory" in df.columns:
        ok &= df["cd_theory"].between(CD_RANGE[0] * (1 - 1e-9), CD_RANGE[1] * (1 + 1e-9))
    if "k0_theory" in df.columns and "k_inf_theory" in df.columns:
        r = df["k0_theory"] / df["k_inf_theory"]
        ok &= r.between(RATIO_RANGE[0] * (1 - 1e-9), RATIO_RANGE[1] * (1 + 1e-9))
    return ok


def si(v: float, unit: str) -> str:
    if not math.isfinite(v):
        return "-"
    for scale, prefix in ((1e12, "T"), (1e9, "G"), (1e6, "M"), (1e3, "k"), (1.0, ""), (1e-3, "m")):
        if abs(v) >= scale * (1 - 1e-12):
            return f"{v / scale:.3g} {prefix}{unit}"
    return f"{v:.3g} {unit}"


def span(values, unit: str) -> str:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v) & (v > 0)]
    return "-" if not len(v) else f"{si(v.min(), unit)} .. {si(v.max(), unit)} ({len(v)} points)"


def material_frame(df: pd.DataFrame) -> tuple[pd.DataFrame, str]:
    """``df`` with ``E_dmt`` and ``viscosity_theory``: its own columns, else from the
    observables (older tables) with table 6's contact."""
    if "E_dmt" in df.columns and "viscosity_theory" in df.columns:
        return df, "material columns"
    need = ("peak_force", "max_penetration", "tau_r_theory")
    if not all(c in df.columns for c in need):
        return df.iloc[:0], "no material columns and no observables to compute them"
    m = moduli(df["peak_force"], df["max_penetration"], np.nan, np.nan, df["tau_r_theory"], ContactModel())
    return df.assign(E_dmt=m["E_dmt"], viscosity_theory=m["viscosity"]), (
        "computed from the observables peak_force, max_penetration (table without material columns)"
    )


def tables(args: list[str]) -> list[Path]:
    paths = []
    for a in args or [str(ROOT / "results")]:
        p = Path(a)
        paths += sorted(p.rglob("*.parquet")) if p.is_dir() else [p]
    return paths


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="*", help="study tables or folders, searched recursively (default: results/)")
    ap.add_argument("--all", action="store_true", help="every point, not only those in the thesis's ranges")
    args = ap.parse_args(argv)
    every, every_acc = [], []
    print(f"thesis 4.6.2: E_dmt {si(THESIS['E_dmt'][0], 'Pa')} .. {si(THESIS['E_dmt'][1], 'Pa')}, viscosity "
          f"{si(THESIS['viscosity'][0], 'Pa s')} .. {si(THESIS['viscosity'][1], 'Pa s')} (acceptance regime "
          f"{si(THESIS['viscosity_accepted'][0], 'Pa s')} .. {si(THESIS['viscosity_accepted'][1], 'Pa s')})\n")  # fmt: skip
    for path in tables(args.paths):
        df, _ = read_table(path)
        if not {"status", "force_source"} <= set(df.columns):
            continue
        df, how = material_frame(df)
        if df.empty:
            print(f"{path.name}: {how}")
            continue
        rows = df[(df["status"] == "ok") & (df["force_source"] == "true")]
        if not args.all:
            rows = rows[in_thesis_ranges(rows)]
        every.append(rows)
        print(f"{path.name} ({how}):")
        print(f"  E_dmt      {span(rows['E_dmt'], 'Pa')}")
        print(f"  viscosity  {span(rows['viscosity_theory'], 'Pa s')}")
        methods = sorted(rows["method"].unique()) if "method" in rows.columns else [None]
        for m in methods:
            g = rows if m is None else rows[rows["method"] == m]
            acc = g[accepted(g)] if "tau_c_err_pct" in g.columns else g.iloc[:0]
            every_acc.append(acc.assign(method=m))
            label = f" ({m})" if m is not None else ""
            print(
                f"  viscosity, accepted (tau_c error < {ACCEPT_ERR_PCT:g} %){label}: {span(acc['viscosity_theory'], 'Pa s')}"
            )
    if every:
        allr = pd.concat(every)
        acc = pd.concat(every_acc) if every_acc else allr.iloc[:0]
        print("\nall tables:")
        print(f"  E_dmt      {span(allr['E_dmt'], 'Pa')}")
        print(f"  viscosity  {span(allr['viscosity_theory'], 'Pa s')}")
        for m in sorted(acc["method"].dropna().unique()) or [None]:
            g = acc if m is None else acc[acc["method"] == m]
            print(f"  viscosity, accepted ({m}): {span(g['viscosity_theory'], 'Pa s')}")


if __name__ == "__main__":
    main()
