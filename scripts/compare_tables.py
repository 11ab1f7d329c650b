"""How far regenerated study tables moved from the committed ones: for every study table of
results/ changed in the working tree, against the same file at a git revision (default HEAD),
the largest relative difference of each estimate over the rows both tables have (matched by
point, method and force source), separately for rows in the acceptance regime (status ok,
|tau_c error| < 30 % in the old table) and the rest, and the rows whose status or flags changed.

    python scripts/compare_tables.py                     # every changed results/**/*.parquet vs HEAD
    python scripts/compare_tables.py --rev 4ba8667 results/thesis/dashpot.parquet

Prints a Markdown table (one row per study) to paste into the notes or results/README.md.

    python scripts/compare_tables.py --identical         # which changed tables are the committed ones

``--identical``: every changed Parquet table under results/ (not only the sweep studies) whose every
column but the timings (:data:`TIMING`) equals the committed one, cell for cell, and the figures
drawn from it (``figures/<table>_*.png`` beside it), with the ``git checkout`` that keeps the
committed files: a regeneration that moved nothing leaves no diff but its wall times.
"""

from __future__ import annotations

import argparse
import io
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parent.parent
QUANTITIES = ("tau_c", "k_g", "k_r", "k0", "k_inf", "cd")
KEY = ("point", "method", "force_source")
ACCEPT = 30.0
TIMING = ("wall_s", "extract_s_median")  # columns that hold how long a row took, not what it found


def old_table(path: Path, rev: str) -> pd.DataFrame | None:
    rel = path.resolve().relative_to(ROOT)
    try:
        blob = subprocess.run(["git", "show", f"{rev}:{rel}"], cwd=ROOT, check=True, capture_output=True).stdout
    except subprocess.CalledProcessError:
        return None
    return pd.read_parquet(io.BytesIO(blob))


def changed_files(rev: str) -> list[Path]:
    """The files under results/ that differ from ``rev`` in the working tree."""
    out = subprocess.run(["git", "diff", "--name-only", rev, "--", "results"], cwd=ROOT, check=True,
                         capture_output=True, text=True).stdout.split()  # fmt: skip
    return [ROOT / p for p in out]


def changed_tables(rev: str) -> list[Path]:
    return [p for p in changed_files(rev) if p.suffix == ".parquet" and p.is_file()]


def compare(old: pd.DataFrame, new: pd.DataFrame) -> dict:
    key = [k for k in KEY if k in old.columns and k in new.columns]
    m = old.merge(new, on=key, suffixes=("_old", "_new"))
    out = {"rows": len(m), "rows_old": len(old), "rows_new": len(new)}
    ok = (m.get("status_old") == "ok") & (m.get("tau_c_err_pct_old", pd.Series(np.nan, index=m.index)).abs() < ACCEPT)
    for part, mask in (("accepted", ok), ("other", ~ok)):
        worst, where = 0.0, ""
        for q in QUANTITIES:
            a, b = f"{q}_old", f"{q}_new"
            if a not in m.columns or b not in m.columns:
                continue
            x, y = m.loc[mask, a].astype(float), m.loc[mask, b].astype(float)
            both = np.isfinite(x) & np.isfinite(y) & (x != 0)
            if not both.any():
                continue
            rel = ((y[both] - x[both]) / x[both].abs()).abs()
            if rel.max() > worst:
                worst, where = float(rel.max()), q
        out[f"{part}_max_rel"], out[f"{part}_quantity"], out[f"{part}_rows"] = worst, where, int(mask.sum())
    changed = 0
    for col in ("status", "unidentified"):
        if f"{col}_old" in m.columns and f"{col}_new" in m.columns:
            changed += int((m[f"{col}_old"].astype(str) != m[f"{col}_new"].astype(str)).sum())
    out["status_or_flags_changed"] = changed
    return out


def same_but_timings(old: pd.DataFrame, new: pd.DataFrame) -> bool:
    """Whether two tables hold the same rows and columns and equal cells in every column but
    :data:`TIMING` (NaN equal to NaN)."""
    a, b = (t.drop(columns=[c for c in TIMING if c in t.columns]) for t in (old, new))
    if list(a.columns) != list(b.columns) or len(a) != len(b):
        return False
    for c in a.columns:
        x, y = a[c].reset_index(drop=True), b[c].reset_index(drop=True)
        if x.dtype.kind in "fc" or y.dtype.kind in "fc":
            xa, ya = x.to_numpy(float), y.to_numpy(float)
            if not np.array_equal(xa, ya, equal_nan=True):
                return False
        elif not x.astype(str).equals(y.astype(str)):
            return False
    return True


def figures_of(table: Path, figures: list[Path]) -> list[Path]:
    """The figures ``figures/<stem>_*.png`` beside ``table`` that no other table of its folder
    with a longer stem claims (``dashpot_*`` is not ``dashpot_vdw_off_*``)."""
    stems = sorted({p.stem for p in table.parent.glob("*.parquet")}, key=len, reverse=True)
    out = []
    for f in figures:
        if f.parent != table.parent / "figures":
            continue
        owner = next((s for s in stems if f.name.startswith(s + "_")), None)
        if owner == table.stem:
            out.append(f)
    return out


def identical(rev: str) -> tuple[list[Path], list[Path]]:
    """``(tables, figures)``: the changed results tables equal to ``rev``'s but for their timings,
    and the changed figures drawn from them."""
    pngs = [p for p in changed_files(rev) if p.suffix == ".png"]
    tables, figures = [], []
    for p in changed_tables(rev):
        old = old_table(p, rev)
        if old is not None and same_but_timings(old, pd.read_parquet(p)):
            tables.append(p)
            figures += figures_of(p, pngs)
    return tables, figures


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("tables", nargs="*", type=Path)
    ap.add_argument("--rev", default="HEAD")
    ap.add_argument("--identical", action="store_true",
                    help="list the changed tables equal to --rev's but for their timings, and their figures")
    args = ap.parse_args(argv)
    if args.identical:
        tables, figures = identical(args.rev)
        for p in tables:
            print(f"identical but for its timings: {p.relative_to(ROOT)}")
        if tables:
            paths = " ".join(str(p.relative_to(ROOT)) for p in tables + figures)
            print(f"keep the committed files: git checkout {args.rev} -- {paths}")
        else:
            print("no changed table is identical to the committed one")
        return
    tables = args.tables or changed_tables(args.rev)
    print("| table | rows matched | accepted rows: largest relative difference | other rows: largest | "
          "status or flags changed |")  # fmt: skip
    print("|---|---|---|---|---|")
    for p in tables:
        old = old_table(p, args.rev)
        if old is None or "point" not in old.columns:
            continue
        c = compare(old, pd.read_parquet(p))
        print(f"| {p.resolve().relative_to(ROOT)} | {c['rows']} of {c['rows_old']}/{c['rows_new']} | "
              f"{c['accepted_max_rel']:.2g} ({c['accepted_quantity'] or '-'}, {c['accepted_rows']} rows) | "
              f"{c['other_max_rel']:.2g} ({c['other_quantity'] or '-'}, {c['other_rows']} rows) | "
              f"{c['status_or_flags_changed']} |")  # fmt: skip
    sys.stdout.flush()


if __name__ == "__main__":
    main()
