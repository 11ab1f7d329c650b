"""Regenerate every table and figure in results/ with the current code, timing each study.

    python scripts/regenerate_results.py                 # everything (~15 min on 2 cores)
    python scripts/regenerate_results.py dashpot setpoint   # some studies only
    python scripts/regenerate_results.py --list          # what it would run

Each study runs as its own process, ``vetica sweep configs/<study>.yaml -o
results/<kind>/<study>.parquet --no-resume --jobs 2`` (a fresh start, two worker processes, as the
docs' wall times are quoted), then ``vetica plot`` draws its figures into
``results/<kind>/figures/``; :func:`folder` says which kind a study is (thesis studies, method
comparisons, findings, wiechert).  The wall time of every sweep goes to ``results/timings.json`` (with
the machine's core count and load average at the start, so a reader can judge the figure).
The committed PNGs are re-saved with a 256-colour palette (Pillow, no dithering) to keep the
repository small; ``vetica plot`` writes the full-colour originals.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RES = ROOT / "results"

# the thesis's chapter-4 studies (the "seven thesis studies" whose total wall time the docs quote)
THESIS = ["dashpot", "dashpot_vdw_off", "stiffness_ratio", "setpoint", "frequency", "print_step", "paddle_stiffness"]
EXTRA = ["stiffness_ratio_vdw_off", "surface_position", "wiechert_arm2_cd"]
METHODS = ["method_dashpot", "method_stiffness_ratio", "method_noise_reconstructed", "method_low_cd", "method_pull"]
# measurements behind results/thesis/comparison.md's "Thesis findings: causes"
FINDINGS = ["findings_table5", "findings_tau_c_edge", "findings_setpoint", "findings_ediss_pull"]
STUDIES = THESIS + EXTRA + METHODS + FINDINGS


def folder(name: str) -> Path:
    """The folder of results/ that holds a study's table, config and (under figures/) its figures."""
    if name in METHODS:
        return RES / "methods"
    if name in FINDINGS:
        return RES / "findings"
    if name.startswith("wiechert"):
        return RES / "wiechert"
    return RES / "thesis"


def table(name: str) -> Path:
    """A study's committed table, ``results/<kind>/<name>.parquet``."""
    return folder(name) / f"{name}.parquet"


def vetica(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "vetica_cli", *args], check=True, cwd=ROOT)


def run_study(name: str) -> float:
    out = table(name)
    t0 = time.perf_counter()
    vetica("sweep", f"configs/{name}.yaml", "-o", str(out), "--no-resume", "--jobs", "2", "-q")
    wall = time.perf_counter() - t0
    vetica("plot", str(out), "-o", str(folder(name) / "figures"))
    return wall


def worked_example() -> None:
    """The per-run figures of the worked example (thesis figs. 33, 28, 62), three periods."""
    out = Path("/tmp/worked_example.parquet")
    vetica("simulate", "-o", str(out), "--set", "numerics.record_cycles=3")
    vetica("plot", str(out), "-o", str(RES / "thesis" / "figures"))


def quantize() -> None:
    from PIL import Image

    for p in glob.glob(str(RES / "*" / "figures" / "*.png")):
        Image.open(p).convert("RGB").quantize(256, dither=0).save(p, optimize=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("studies", nargs="*", help=f"studies to run (default: all of {', '.join(STUDIES)})")
    ap.add_argument("--list", action="store_true", help="print the studies and exit")
    args = ap.parse_args()
    todo = args.studies or STUDIES
    unknown = [s for s in todo if s not in STUDIES]
    if unknown:
        sys.exit(f"error: unknown study {unknown[0]!r}; allowed: {', '.join(STUDIES)}")
    if args.list:
        print("\n".join(todo))
        return
    path = RES / "timings.json"
    timings = json.loads(path.read_text()) if path.is_file() else {}
    for name in todo:
        load = os.getloadavg()[0]
        wall = run_study(name)
        timings[name] = {"wall_s": round(wall, 1), "jobs": 2, "cores": os.cpu_count(), "load_at_start": round(load, 2)}
        print(f"{name}: {wall:.1f} s (load {load:.2f} at start)", flush=True)
        path.write_text(json.dumps(timings, indent=1) + "\n")
    if not args.studies:
        worked_example()
    thesis = [timings[s]["wall_s"] for s in THESIS if s in timings]
    if len(thesis) == len(THESIS):
        print(f"the seven thesis studies together: {sum(thesis):.1f} s")
    quantize()


if __name__ == "__main__":
    main()
