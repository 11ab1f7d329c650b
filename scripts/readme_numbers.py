"""Measure every timing the README quotes, with the machine's load noted, and print them.

    python scripts/readme_numbers.py            # a few minutes: main job cold and warm, simulate, stage 2, dry run
    python scripts/readme_numbers.py --tests    # also time the whole test suite (minutes to tens of minutes)
    python scripts/readme_numbers.py --repeat 5 # more repeats of the short measurements
    python scripts/readme_numbers.py --goals    # also the performance goals: goal, before, after per row
    python scripts/readme_numbers.py --goals --slow-goals   # with the seven studies and the map (~20 min)

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

With ``--goals`` a second table: each performance goal, what was measured when it was set (the
"before" column, CPU time on this machine, kept in :data:`GOALS`) and what this code measures now:
the extraction of a scan pixel's record per method (CPU ms, in this process, medians), the
worked example to its proven periodic state and a hertz point to its state and record (the
kernel's time, ``Run.timing_s``), the ``vetica simulate`` process (wall and CPU, from the runs
above); with ``--slow-goals`` also the seven thesis studies (``vetica sweep`` each, 2 workers:
summed wall and CPU) and the 128 x 128 map (CPU per pixel of the blend scanned with VETICA and the
whole-cycle fit at 2 ms pixels: an 8 x 8 scan less an 8 x 2 one, so the scan's start-up is left
out and added once; times 16384 pixels over 2 cores).

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


CPU: list[float] = []  # CPU seconds (user + system) of each finished command, in order (run())


def children_cpu() -> float:
    """CPU seconds (user + system) of this process's finished children so far."""
    import resource

    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def run(cmd: list[str], env: dict | None = None, timeout: float | None = None) -> tuple[float, float, str, bool]:
    """``(wall s, load before, stdout, finished)`` of one command in a fresh process group (all of
    it is stopped at ``timeout``); its CPU time is appended to :data:`CPU`."""
    load = os.getloadavg()[0]
    c0 = children_cpu()
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
    wall = time.perf_counter() - t0
    CPU.append(children_cpu() - c0)
    return wall, load, stdout, True


def loads(values: list[float]) -> str:
    return f"{min(values):.2f}" if len(values) == 1 else f"{min(values):.2f}–{max(values):.2f}"


# the performance goals, and what was measured when they were set (2026-11-26, on this 2-core
# machine, shared; CPU time, medians): (key, what, goal, before)
GOALS = [
    ("vetica", "VETICA `extract()` per pixel record (4 periods at 1 ns, reconstructed force, error bars and checks)",
     "1 ms", "9.6–12.7 ms"),
    ("vetica-prestress", "vetica-prestress `extract()` per pixel record", "2 ms", "10.5–15.4 ms"),
    ("full", "whole-cycle fit `extract()` per pixel record", "15 ms", "49–54 ms"),
    ("point", "worked-example point to its proven periodic state (kernel: approach + orbit)", "10 ms",
     "29.5 ms (approach 14 + orbit 15)"),
    ("hertz", "hertz point (defaults) to its state and record (kernel)", "0.5 s", "2.35–2.40 s"),
    ("simulate", "`vetica simulate` whole process", "0.6 s wall", "≥ 1.22 CPU-s"),
    ("studies", "seven thesis studies, 2 cores", "30 s", "146.5 CPU-s (≥ 73 s)"),
    ("map", "128 × 128 map, VETICA + full, 2 ms pixels, 2 cores", "10 min", "0.134 CPU-s a pixel (≥ 18 min)"),
]
THESIS_STUDIES = ["dashpot", "dashpot_vdw_off", "stiffness_ratio", "setpoint", "frequency", "print_step",
                  "paddle_stiffness"]  # fmt: skip  (scripts/regenerate_results.py: THESIS)


def spread(values: list[float], unit: str, scale: float = 1.0, fmt: str = ".1f") -> str:
    lo, hi = scale * min(values), scale * max(values)
    return f"{lo:{fmt}} {unit}" if f"{lo:{fmt}}" == f"{hi:{fmt}}" else f"{lo:{fmt}}–{hi:{fmt}} {unit}"


def goal_measurements(repeat: int, simulate_row: tuple[float, float], slow: bool, tmp: Path) -> dict:
    """``{goal key: measured text}`` (module docstring, ``--goals``)."""
    sys.path.insert(0, str(ROOT))
    from vetica_cli.batch.launch import one_thread
    from vetica_cli.bench import extraction_plan
    from vetica_cli.extraction import extract
    from vetica_cli.simulation.config import load
    from vetica_cli.simulation.simulate import simulate

    out: dict = {}
    per_method: dict = {}
    with one_thread():  # as the command and its workers compute
        for _, cfg, methods in extraction_plan(None, ("vetica", "vetica-prestress", "full")):
            run_ = simulate(cfg)
            df, meta = run_.frame(), run_.metadata()
            for key in methods:
                for _ in range(2):  # compilation, caches
                    extract(df, meta, force="reconstructed", method=key)
                cpu = []
                for _ in range(max(5, 5 * repeat) if key != "full" else max(3, repeat)):
                    c0 = time.process_time()
                    extract(df, meta, force="reconstructed", method=key)
                    cpu.append(time.process_time() - c0)
                per_method.setdefault(key, []).append(statistics.median(cpu))
        for key, values in per_method.items():
            out[key] = spread(values, "ms", 1e3) + " (stiff, soft)"
        cfg = load(None, {})
        simulate(cfg)
        t = [simulate(cfg).timing_s for _ in range(max(3, repeat))]
        ap, orb = (statistics.median(x[k] for x in t) for k in ("approach", "steady"))
        out["point"] = f"{1e3 * (ap + orb):.1f} ms (approach {1e3 * ap:.1f} + orbit {1e3 * orb:.1f}), wall"
        cfg = load(None, {"surface.model": "hertz"})
        simulate(cfg)
        out["hertz"] = f"{statistics.median(simulate(cfg).timing_s['total'] for _ in range(repeat)):.2f} s, wall"
    wall, cpu = simulate_row
    out["simulate"] = f"{wall:.2f} s wall, {cpu:.2f} CPU-s"
    if not slow:
        out["studies"] = out["map"] = "not measured (pass --slow-goals)"
        return out
    walls, cpus = [], []
    for name in THESIS_STUDIES:
        w, _, _, _ = run([*VETICA, "sweep", f"configs/{name}.yaml", "-o", str(tmp / f"{name}.parquet"), "--no-resume",
                          "--jobs", "2", "-q"])  # fmt: skip
        walls.append(w)
        cpus.append(CPU[-1])
    out["studies"] = f"{sum(walls):.1f} s wall, {sum(cpus):.1f} CPU-s"
    cpu = {}
    for lines in (2, 8):  # the difference of two scans: a pixel's CPU without the scan's start-up (workers, orbit)
        run([*VETICA, "scan", "configs/scan_blend.yaml", "--set", f"scan.pixels=[8,{lines}]", "--set",
             "scan.pixel_time=2.0e-3", "--set", "scan.steady=transient", "--jobs", "2", "-q", "-o",
             str(tmp / f"map{lines}.parquet")])  # fmt: skip
        cpu[lines] = CPU[-1]
    per_pixel = (cpu[8] - cpu[2]) / (8 * 6)
    fixed = cpu[2] - 16 * per_pixel
    out["map"] = (f"{per_pixel:.3f} CPU-s a pixel (8 × 8 scan less 8 × 2; {fixed:.1f} CPU-s to start a scan): "
                  f"{(per_pixel * 128 * 128 + fixed) / 2 / 60:.0f} min on 2 cores")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="runs of each short measurement (median)")
    ap.add_argument("--tests", action="store_true", help="also time the whole test suite")
    ap.add_argument("--dry-run-timeout", type=float, default=420.0, help="stop the 1e6-value dry run after this [s]")
    ap.add_argument("--goals", action="store_true", help="also the performance goals: goal, before, after per row")
    ap.add_argument("--slow-goals", action="store_true", help="with --goals: also the seven studies and the map")
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
        walls, lds, cpus = [], [], []
        for _ in range(args.repeat):
            wall, load, _, _ = run([*VETICA, "simulate", "-q", "-o", str(run_file)], cache)
            walls.append(wall)
            lds.append(load)
            cpus.append(CPU[-1])
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

        goals = None
        if args.goals:
            goals = goal_measurements(args.repeat, (statistics.median(walls), statistics.median(cpus)),
                                      args.slow_goals, tmp)  # fmt: skip

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
    if goals is not None:
        print("\n| what | goal | before (when the goal was set) | now |")
        print("|---|---|---|---|")
        for key, what, goal, before in GOALS:
            print(f"| {what} | {goal} | {before} | {goals[key]} |")
        print("\nThe tap methods' `extract()` includes their checks, among them the whole-cycle fit that referees "
              "them (docs/noise.md); the kernel times are wall times of this process.")


if __name__ == "__main__":
    main()
