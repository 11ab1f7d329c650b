"""How far the real-time extraction (compiled stage 2, force rebuilt in the tap windows) moves
the committed results: re-run a few points of each study with this code into a temporary
folder and compare their estimates with the rows of results/<study>.parquet (or results/<sub-folder>/<study>.parquet).

For each study (default: the seven thesis studies), ``--points`` points spread evenly over
its grid are simulated again (``vetica_cli.study``'s own point configs) and extracted with
every method and force source their rows name; each estimate is compared with the committed
row of the same point, method and force source: ``|new - committed| / |committed|``.  For
VETICA and VETICA with pre-stress the thesis's sum-of-sines stage 2 (``stage2=sines``) is
run on the same record too, which separates what the solver changes from what the
simulation or the tap windows change.  Rows whose committed status is not ok/no_estimate
are skipped (their values are not claims).

Scan studies: ``--scan`` re-runs one line of configs/scan_edge.yaml (2 ms pixels, the
transient pass, VETICA only) into the temporary folder with ``vetica scan`` and compares
every pixel with results/scan_edge.parquet.

Nothing under results/ is written.  Prints one line per study and method: points compared,
the largest relative difference per quantity.

    python scripts/realtime_accuracy.py [--points 3] [--studies dashpot,setpoint] [--scan]
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))

from regenerate_results import THESIS  # noqa: E402

from vetica_cli.extraction import extract  # noqa: E402
from vetica_cli.simulation.simulate import simulate  # noqa: E402
from vetica_cli.study.acceptance import ACCEPT_ERR_PCT  # noqa: E402
from vetica_cli.study.grid import load_study  # noqa: E402

QUANTITIES = ("tau_c", "k_g", "k_r", "k0", "k_inf", "cd")
GOOD = ("ok", "no_estimate")
SOURCES = {"both": ("true", "reconstructed"), "true": ("true",), "reconstructed": ("reconstructed",)}


def rel(a: float, b: float) -> float:
    if a is None or b is None or not (math.isfinite(a) and math.isfinite(b)) or b == 0:
        return math.nan
    return abs(a - b) / abs(b)


def committed_table(name: str) -> Path:
    """results/<name>.parquet, or in a sub-folder of results/ (results/thesis/, results/scans/, ...)."""
    found = sorted((ROOT / "results").rglob(f"{name}.parquet"))
    if not found:
        raise SystemExit(f"no committed table {name}.parquet under results/")
    return found[0]


def accepted_row(row) -> bool:
    """In the thesis's acceptance regime (vetica_cli.study.acceptance): status ok and |tau_c error| < 30 %."""
    err = row.get("tau_c_err_pct")
    return row.get("status") == "ok" and err is not None and math.isfinite(err) and abs(err) < ACCEPT_ERR_PCT


def pick(n_points: int, k: int) -> list[int]:
    return sorted({int(round(i)) for i in np.linspace(0, n_points - 1, min(k, n_points))})


def study_rows(name: str, k: int) -> list[dict]:
    study = load_study(ROOT / "configs" / f"{name}.yaml")
    table = pd.read_parquet(committed_table(name))
    out = []
    for idx in pick(len(study.points), k):
        point = study.points[idx]
        committed = table[table["point"] == point.key]
        if committed.empty:
            continue
        run = simulate(point.config)
        df, meta = run.frame(), run.metadata()
        for _, row in committed.iterrows():
            if row["status"] not in GOOD:
                continue
            method, source = row["method"], row["force_source"]
            try:
                new = extract(df, meta, force=source, method=method)
            except Exception as exc:  # noqa: BLE001 - reported, not fatal
                out.append({"study": name, "point": idx, "method": method, "force": source, "error": str(exc)})
                continue
            rec = {"study": name, "point": idx, "method": method, "force": source, "accepted": accepted_row(row)}
            for q in QUANTITIES:
                rec[q] = rel(new.value(q), row.get(q))
            if method in ("vetica", "vetica-prestress"):
                thesis = extract(df, meta, force=source, method=method, stage2="sines")
                rec["vs_sines"] = max((rel(new.value(q), thesis.value(q)) for q in QUANTITIES), default=math.nan)
            out.append(rec)
    return out


def scan_rows(tmp: Path) -> list[dict]:
    out_path = tmp / "scan_edge.parquet"
    subprocess.run([sys.executable, "-m", "vetica_cli", "scan", str(ROOT / "configs" / "scan_edge.yaml"),
                    "--set", "scan.pixel_time=2.0e-3", "--set", "scan.steady=transient", "--set",
                    "scan.methods=[vetica]", "-j", "1", "-o", str(out_path)], check=True, cwd=ROOT,
                   stdout=subprocess.DEVNULL)  # fmt: skip
    new = pd.read_parquet(out_path)
    old = pd.read_parquet(committed_table("scan_edge"))
    old = old[(old["method"] == "vetica") & (old["steady"] == "transient") & np.isclose(old["pixel_time"], 2e-3)]
    merged = new.merge(old, on=["ix", "iy", "method", "force_source"], suffixes=("", "_old"))
    out = []
    for _, r in merged.iterrows():
        if r["status_old"] not in GOOD:
            continue
        rec = {"study": "scan_edge (2 ms, transient)", "point": int(r["ix"]), "method": "vetica",
               "force": r["force_source"], "accepted": accepted_row({"status": r["status_old"],
                                                                      "tau_c_err_pct": r["tau_c_err_pct_old"]})}  # fmt: skip
        for q in QUANTITIES:
            rec[q] = rel(r[q], r[f"{q}_old"])
        out.append(rec)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=3, help="points per study (spread over its grid)")
    ap.add_argument("--studies", default=",".join(THESIS), help="comma-separated study names (configs/<name>.yaml)")
    ap.add_argument("--scan", action="store_true", help="also one line of scan_edge (2 ms pixels, transient)")
    args = ap.parse_args()
    rows = []
    for name in [s for s in args.studies.split(",") if s]:
        rows += study_rows(name, args.points)
        print(f"{name}: done", file=sys.stderr)
    if args.scan:
        with tempfile.TemporaryDirectory() as tmp:
            rows += scan_rows(Path(tmp))
    res = pd.DataFrame(rows)
    if "error" in res:
        for _, r in res[res["error"].notna()].iterrows():
            print(f"FAILED {r['study']} point {r['point']} {r['method']} {r['force']}: {r['error']}")
        res = res[res["error"].isna()]
    cols = [q for q in QUANTITIES if q in res]
    pd.set_option("display.width", 200)
    for title, part in (("rows in the acceptance regime (status ok, |tau_c error| < 30 %)", res[res["accepted"]]),
                        ("all rows (ok and no_estimate)", res)):  # fmt: skip
        grouped = part.groupby(["study", "method", "force"], sort=False)
        summary = grouped[cols + (["vs_sines"] if "vs_sines" in part else [])].max()
        summary.insert(0, "rows", grouped.size())
        print(f"\n{title}: largest relative difference from the committed tables (vs_sines: from the thesis's "
              "stage 2 on the same record)")  # fmt: skip
        print(summary.to_string(float_format=lambda v: f"{v:.2e}"))
        print(f"largest relative difference: {part[cols].max().max():.2e} over {len(part)} rows")


if __name__ == "__main__":
    main()
