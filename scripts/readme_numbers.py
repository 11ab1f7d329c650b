"""Measure every timing the README quotes, with the machine's load noted, and print them.

    python scripts/readme_numbers.py            # a few minutes: main job cold and warm, simulate, stage 2, dry run
    python scripts/readme_numbers.py --tests    # also time the whole test suite (minutes to tens of minutes)
    python scripts/readme_numbers.py --repeat 5 # more repeats of the short measurements

What it runs, each in a fresh process exactly as a user types it (``python -m vetica_cli``
is the ``vetica`` command):

* **main job, cold**: ``vetica sweep configs/dashpot.yaml`` with an empty numba cache (a new
  ``NUMBA_CACHE_DIR``), so the kernels compile as on a fresh clone;
* **main job, warm**: the same with that cache filled (``--no-resume``: every point computed);
* **simulate**: ``vetica simulate -o run.parquet`` (the worked example), and the size of the file
  it writes;
* **stage 2**: VETICA's stage 2 on that run, from ``vetica extract run.parquet --json``
  (``info.timing_s.stage2``: the sum-of-sines fits and the Kr fits of every tap);
* **dry run of a 1e6-value key**: ``vetica sweep --dry-run`` on the dashpot study with
  ``surface.cd: {logspace: [-5, 3, 1000000]}``, its wall time and peak memory (stopped at
  ``--dry-run-timeout`` seconds, and said so);
* **tests** (``--tests`` only): ``python -m pytest -q``.

Each short measurement is the median of ``--repeat`` runs; the load average (1 min) is read
before each run and the range printed, with the core count, so a reader can judge the numbers.
Everything is written under a temporary folder that is removed at the end.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VETICA = [sys.executable, "-m", "vetica_cli"]
# runs a command and prints its peak resident memory [kB] (of that command alone)
PEAK = ("import resource, subprocess, sys; subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL); "
        "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")


def run(cmd: list[str], env: dict | None = None, timeout: float | None = None) -> tuple[float, float, str, bool]:
    """``(wall s, load before, stdout, finished)`` of one command in a fresh process group (all of
    it is stopped at ``timeout``)."""
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=ROOT, env={**os.environ, **(env or {})}, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)  # fmt: skip
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        return time.perf_counter() - t0, load, "", False
    if proc.returncode != 0:
        sys.exit(f"error: {' '.join(cmd)} exited with {proc.returncode}: {stderr.strip()[-300:]}")
    return time.perf_counter() - t0, load, stdout, True


def loads(values: list[float]) -> str:
    return f"{min(values):.2f}" if len(values) == 1 else f"{min(values):.2f}–{max(values):.2f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="runs of each short measurement (median)")
    ap.add_argument("--tests", action="store_true", help="also time the whole test suite")
    ap.add_argument("--dry-run-timeout", type=float, default=420.0, help="stop the 1e6-value dry run after this [s]")
    args = ap.parse_args()
    rows = []  # (what, value, load, command)
    with tempfile.TemporaryDirectory(prefix="vetica_numbers_") as tmp:
        tmp = Path(tmp)
        cache = {"NUMBA_CACHE_DIR": str(tmp / "numba_cache")}
        out = tmp / "dashpot.parquet"
        sweep = [*VETICA, "sweep", "configs/dashpot.yaml", "-o", str(out), "--no-resume", "-q"]
        wall, load, _, _ = run(sweep, cache)
        rows.append(("main job, cold (empty numba cache: compiles the kernels)", f"{wall:.1f} s", f"{load:.2f}",
                     "vetica sweep configs/dashpot.yaml"))  # fmt: skip
        walls, lds = [], []
        for _ in range(args.repeat):
            wall, load, _, _ = run(sweep, cache)
            walls.append(wall)
            lds.append(load)
        rows.append(("main job, warm (33 points, 2 workers)", f"{statistics.median(walls):.1f} s", loads(lds),
                     "vetica sweep configs/dashpot.yaml"))  # fmt: skip

        run_file = tmp / "run.parquet"
        walls, lds = [], []
        for _ in range(args.repeat):
            wall, load, _, _ = run([*VETICA, "simulate", "-q", "-o", str(run_file)], cache)
            walls.append(wall)
            lds.append(load)
        size_mb = run_file.stat().st_size / 1e6
        rows.append(("simulate (worked example, 10 recorded periods; whole process)",
                     f"{statistics.median(walls):.2f} s, writes {size_mb:.0f} MB", loads(lds),
                     "vetica simulate -o run.parquet"))  # fmt: skip

        stage2, per_tap, lds = [], [], []
        for _ in range(args.repeat):
            _, load, stdout, _ = run([*VETICA, "extract", str(run_file), "--json"], cache)
            info = json.loads(stdout)["info"]
            stage2.append(info["timing_s"]["stage2"])
            per_tap.append(info["timing_s"]["stage2_per_tap"])
            lds.append(load)
        rows.append(("VETICA stage 2 (reconstructed force, every tap of the record)",
                     f"{statistics.median(stage2):.3f} s per record, {1e3 * statistics.median(per_tap):.0f} ms per tap",
                     loads(lds), "vetica extract run.parquet --json (info.timing_s)"))  # fmt: skip

        big = tmp / "million.yaml"
        text = (ROOT / "configs" / "dashpot.yaml").read_text()
        big.write_text(text.replace("{logspace: [-5, 3, 33]}", "{logspace: [-5, 3, 1000000]}"))
        dry = [*VETICA, "sweep", str(big), "--dry-run", "-o", str(tmp / "m.parquet")]
        wall, load, stdout, done = run([sys.executable, "-c", PEAK, *dry], cache, timeout=args.dry_run_timeout)
        mem = f", peak memory {int(stdout.split()[-1]) / 1e6:.2f} GB" if done else ""  # ru_maxrss: kB on Linux
        value = f"{wall:.1f} s{mem}" if done else f"stopped after {wall:.0f} s (did not finish)"
        rows.append(("dry run of one key with 1e6 values", value, f"{load:.2f}",
                     "vetica sweep CONFIG --dry-run (surface.cd: {logspace: [-5, 3, 1000000]})"))  # fmt: skip

        if args.tests:
            wall, load, _, _ = run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"])
            rows.append(("tests (the whole suite)", f"{wall / 60:.1f} min", f"{load:.2f}", "python -m pytest"))
        else:
            rows.append(("tests (the whole suite)", "not measured (pass --tests)", "", "python -m pytest"))

    print(f"measured {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} on {os.cpu_count()} cores "
          f"({'shared machine: ' if max(os.getloadavg()) > 1 else ''}load average at each start below); "
          f"medians of {args.repeat} runs where repeated\n")  # fmt: skip
    print("| what | measured | load (1 min) | command |")
    print("|---|---|---|---|")
    for what, value, load, cmd in rows:
        print(f"| {what} | {value} | {load} | `{cmd}` |")


if __name__ == "__main__":
    main()
