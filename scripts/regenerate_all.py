"""Regenerate every result folder after a change to the simulation or the extraction, in one run
(``scripts/regenerate_results.py`` does the sweep studies only; the lab studies, the noise
tables, the scans and the advise example each had their own command, and went stale when one
was forgotten).

    python scripts/regenerate_all.py --list            # the steps, their commands and what cites them
    python scripts/regenerate_all.py                   # every step (~1.5 h on 2 cores)
    python scripts/regenerate_all.py --only lab noise  # some steps

Each step runs its commands in order from the repository's root, each in its own process, and
stops the run at the first failure (a table half regenerated is worse than a stale one: rerun the
step).  It then prints the wall time of every step and the documents that quote its numbers,
which are written by hand and must be brought in line (``scripts/compare_tables.py`` says which
sweep tables moved, ``--identical`` which tables moved nothing but their wall times, to keep the
committed files; ``scripts/table_trust.py`` re-counts the silently wrong results).  PNGs are
re-saved with a 256-colour palette, as ``regenerate_results.py`` does.  The held-out coverage
check (``scripts/trust.py``) is not a step: it runs once per version on a fresh draw seed (its
docstring), by hand.
"""

from __future__ import annotations

import argparse
import glob
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LAB = ("dashpot", "stiffness_ratio", "setpoint", "frequency", "print_step", "paddle_stiffness", "surface_position")
PY = [sys.executable]
VETICA = [sys.executable, "-m", "vetica_cli"]

# name -> (commands, documents quoting its numbers)
STEPS: dict[str, tuple[list[list[str]], list[str]]] = {
    "studies": ([PY + ["scripts/regenerate_results.py"]],
                ["results/thesis/comparison.md", "results/methods/README.md", "docs/performance.md (the seven studies)"]),
    "lab": ([VETICA + ["sweep", f"configs/lab_{s}.yaml", "-o", f"results/lab/lab_{s}.parquet", "--no-resume",
                       "--jobs", "2", "-q"] for s in LAB]
            + [PY + ["scripts/lab_summary.py", "--tables", "results/lab", "--out", "results/lab/summary.md"]],
            ["results/lab/README.md", "README.md (the lab row)"]),
    "noise": ([PY + ["scripts/noise_study.py", "--dashpots", "3e-5", "1e-3", "--out", "results/noise/thermal_methods.parquet"],
               PY + ["scripts/stripped_records.py", "--out", "results/noise/stripped_records.parquet"],
               PY + ["scripts/thermal_coverage.py", "--replicas", "50", "--temperatures", "300", "1200"],
               PY + ["scripts/thermal_coverage.py", "--replicas", "50", "--temperatures", "300", "--force",
                     "reconstructed"],
               PY + ["-m", "pytest", "tests/test_coverage.py", "-m", "slow", "-s", "-q"]],
              ["results/noise/README.md (its tables are the printed output)", "docs/noise.md"]),
    "scans": ([VETICA + ["scan", "configs/scan_edge.yaml", "-o", "results/scans/scan_edge.parquet", "-q", "--no-resume"],
               VETICA + ["scan", "configs/scan_blend.yaml", "-o", "results/scans/scan_blend.parquet", "-q", "--no-resume",
                         "--yes"],
               VETICA + ["plot", "results/scans/scan_edge.parquet", "-o", "results/scans/figures"],
               VETICA + ["plot", "results/scans/scan_blend.parquet", "-o", "results/scans/figures"]],
              ["results/scans/README.md", "docs/performance.md (the blend map's wall time)"]),
    "advise": ([VETICA + ["advise", "--k-inf", "4", "--k0", "64", "--cd", "3e-3", "-q", "-o",
                          "results/advise/advise_example.png", ">", "results/advise/advise_example.txt"],
                VETICA + ["advise", "--k-inf", "4", "--k0", "64", "--cd", "3e-3", "-q", "--json", "-o",
                          "results/advise/advise_example.png", ">", "results/advise/advise_example.json"]],
               ["results/advise/README.md (the count of settings recovered; the JSON's figure path)"]),
    # the tables only: results/methods/method_comparison.md has a written introduction above them
    "comparison": ([PY + ["scripts/method_comparison.py", "-o", "/tmp/method_comparison_tables.md"]],
                   ["results/methods/method_comparison.md (its tables: from /tmp/method_comparison_tables.md)",
                    "README.md (the methods row)"]),
}


def quantize(folder: Path) -> None:
    """Re-save the PNGs of ``folder``'s figure folders (``*/figures/``, as ``regenerate_results.py``
    keeps them) with a 256-colour palette (no dithering); one already re-saved is left as it is."""
    try:
        from PIL import Image
    except ImportError:  # the figures stay full colour
        return
    for name in glob.glob(str(folder / "*" / "figures" / "*.png")):
        img = Image.open(name)
        if img.mode != "P":  # one already re-saved is left as it is (its file unchanged)
            img.convert("RGB").quantize(colors=256, dither=Image.Dither.NONE).save(name, optimize=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", choices=list(STEPS), help="run these steps only (default: all)")
    ap.add_argument("--list", action="store_true", help="print the steps and their commands, run nothing")
    args = ap.parse_args(argv)
    names = args.only or list(STEPS)
    if args.list:
        for n in names:
            cmds, docs = STEPS[n]
            print(f"{n}:")
            for c in cmds:
                print("    " + " ".join(["python" if c[0] == sys.executable else c[0], *c[1:]]))
            print("  quoted in: " + "; ".join(docs))
        return 0
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    times = {}
    for n in names:
        t0 = time.perf_counter()
        for c in STEPS[n][0]:
            print(f"[{n}] {' '.join(c[1:])}", flush=True)
            if ">" in c:  # its standard output is the file after ">"
                with open(ROOT / c[c.index(">") + 1], "w") as sink:
                    done = subprocess.run(c[: c.index(">")], cwd=ROOT, env=env, stdout=sink)
            else:
                done = subprocess.run(c, cwd=ROOT, env=env)
            if done.returncode != 0:
                print(f"[{n}] failed: the step's tables may be half regenerated; rerun it", file=sys.stderr)
                return 1
        quantize(ROOT / "results")
        times[n] = time.perf_counter() - t0
    for n, s in times.items():
        print(f"{n}: {s:.0f} s; now bring in line: {'; '.join(STEPS[n][1])}")
    print("the tables that moved nothing but their wall times, and their figures: "
          "python scripts/compare_tables.py --identical")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
