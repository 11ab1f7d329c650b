"""``vetica bench``: what the simulation costs (a benchmark, not a test: numbers are reported,
not asserted).  Medians of repeated runs, because the machine may be shared.

For each integrator (``verlet``: all fine steps; ``hybrid``: exact propagation away from the
surface) on the given config (default: the thesis's worked example, dt = 0.025 ns):

* ns per fine step: one drive period of the all-fine integrator from the solved orbit,
  divided by its steps;
* ms per drive period: one period (not recorded) from the solved orbit;
* s per point: a whole ``simulate()`` call, and the split of its kernel time -- approach,
  steady state (orbit or transient), recorded window.

Each as wall time (``time.perf_counter``) and CPU time (``time.process_time``) of the same
runs: on a shared machine the wall time carries the other processes' load, the CPU time much
less of it.

And what a process pays before it simulates (:func:`startup_line`, in fresh interpreters): the
CPU time of importing numpy, the command line, numba, numba's first-call initialisation (its
registries, which import scipy.linalg for BLAS) and the simulation's kernel modules.

Extraction (:func:`run_extraction_bench`): a scan pixel's record -- 4 drive periods at 1 ns,
the force reconstructed from the paddle signal -- of the worked example (stiff) and of the
blend's soft domains (k_inf 2, k0 32, cd 3e-4 kg/s); per method, CPU milliseconds per
pixel (``time.process_time``, medians) of ``extract()`` from the table and its parts: the
record (force in the tap windows, Z1) and the method.
"""

from __future__ import annotations

import os
import platform
import statistics
import time

import numpy as np

from .simulation.config import load


def simulate(cfg):
    """:func:`vetica_cli.simulation.simulate.simulate`, imported when the bench runs (its checks
    load no numba)."""
    from .simulation.simulate import simulate as run

    return run(cfg)


def _period_ms(run, cfg) -> tuple[float, float, float]:
    """Wall and CPU time of one unrecorded drive period from the run's last recorded state [ms]
    (medians of 5), and the fine steps it took."""
    from .core import engine, session, tapping
    from .simulation.simulate import derive, kernel_setup

    d = derive(cfg)
    kern = cfg.surface.surface_model.kernel_of_run(cfg, kernel_setup(cfg, d), run)  # the model's (hertz: its grid)
    s = engine.new_state(0, 0, 0, 0, 0, kern.n_state)
    last = run.steady[-1]
    # the orbit's state at the end of the window: positions from the record, velocities by one
    # period of warm-up (any state near the orbit costs the same)
    session.place_probe(s, zc=last[2], vc=d.a_sp * d.omega1, zp=last[3], zb=last[4])
    kern.advance(s)
    walls, cpus, fine = [], [], 0
    for _ in range(5):
        t0, c0 = time.perf_counter(), time.process_time()
        o = kern.advance(s)
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
        fine = o[tapping.O_FINE]
    return 1e3 * statistics.median(walls), 1e3 * statistics.median(cpus), float(fine)


PIXEL = {"numerics.print_step": 1e-9, "numerics.record_cycles": 4}  # a scan pixel's record (configs/scan_blend.yaml)
SURFACES = {"stiff": {}, "soft": {"surface.k_inf": 2.0, "surface.k0": 32.0, "surface.cd": 3e-4}}
def bench_methods() -> tuple[str, ...]:
    """The extraction bench's methods: the registered ones that model the surface (not the
    instrument's model-free numbers), in registry order."""
    from .extraction import METHODS as REGISTERED
    from .extraction.base import ModelFreeMethod

    return tuple(k for k, m in REGISTERED.items() if not isinstance(m, ModelFreeMethod))
PARTS = ("all", "simulation", "extraction")


def extraction_plan(overrides: dict | None = None, methods: tuple | None = None) -> list[tuple[str, object, tuple]]:
    """``(surface name, config, methods)`` of the extraction bench: the stiff and soft SLS
    pixels, or, when ``overrides`` choose another surface model (``--set surface.model=hertz``),
    that one surface ('given'); each with the methods of ``methods`` that extract its model.
    Every config is checked here (ConfigError before any work)."""
    from .extraction import get

    methods = bench_methods() if methods is None else methods
    surfaces_ = SURFACES if "surface.model" not in (overrides or {}) else {"given": {}}
    out = []
    for name, surf in surfaces_.items():
        cfg = load(None, {**PIXEL, **surf, **(overrides or {})})
        out.append((name, cfg, tuple(m for m in methods if cfg.surface.model in get(m).surface_models)))
    return out


def check_bench(overrides: dict | None, repeat: int, part: str = "all", yes: bool = False) -> None:
    """Every config the bench of ``part`` runs, checked, and its cost estimated before any work:
    ConfigError for a bad ``--set``, InputError past the threshold every command asks past
    (:func:`vetica_cli.checks.confirm_cost`) without ``yes``."""
    from .checks import confirm_cost
    from .simulation.cost import simulation_seconds

    seconds = 0.0
    if part in ("all", "simulation"):
        seconds += sum((repeat + 1) * simulation_seconds(load(None, {**(overrides or {}), "numerics.integrator": i}))
                       for i in ("verlet", "hybrid"))  # fmt: skip
    if part in ("all", "extraction"):
        seconds += sum(simulation_seconds(cfg) for _, cfg, _ in extraction_plan(overrides))
    confirm_cost(f"this bench ({repeat} timed runs after a warm-up)", seconds, yes)


def cpu_ms(fn, repeat: int) -> float:
    """Median CPU time of ``fn()`` over ``repeat`` calls [ms]."""
    out = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        out.append(time.process_time() - t0)
    return 1e3 * statistics.median(out)


SLOW_METHOD_S = 1.0  # a method estimated at this many seconds a point or more is timed fewer times (the whole-cycle fit)


def run_extraction_bench(methods: tuple | None = None, repeat: int = 20, overrides: dict | None = None) -> str:
    """CPU ms per pixel record of each extraction method (module docstring); ``repeat`` timed
    calls after two warm-up calls (compilation, caches), fewer for the whole-cycle fit."""
    from .extraction import extract, get
    from .extraction.record import build_record

    lines = [f"extraction per pixel record (4 periods at 1 ns, reconstructed force), CPU ms, medians of {repeat} "
             f"calls (the whole-cycle fit: {max(3, repeat // 5)}), one core"]  # fmt: skip
    lines.append(f"{'surface':<6} {'method':<17} {'extract':>8} {'record':>8} {'method':>8}   "
                 "stage2 thesis fit (sines) for comparison")  # fmt: skip
    for name, cfg, supported in extraction_plan(overrides, methods):
        run = simulate(cfg)
        df, meta = run.frame(), run.metadata()
        for key in supported:
            m = get(key)
            n = max(3, repeat // 5) if m.seconds_per_point >= SLOW_METHOD_S else repeat
            opts = m.options({})
            for _ in range(2):
                extract(df, meta, force="reconstructed", method=key)
            total = cpu_ms(lambda: extract(df, meta, force="reconstructed", method=key), n)
            kw = {"need_approach": m.needs_approach, "need_z1": m.needs_z1, "tap_windows": m.tap_windows,
                  "uniform": key if m.uniform_sampling else None}  # fmt: skip
            record = build_record(df, meta, "reconstructed", **kw)
            rec_ms = cpu_ms(lambda: build_record(df, meta, "reconstructed", **kw), n)
            meth_ms = cpu_ms(lambda: m.run(record, opts), n)
            extra = ""
            if "stage2" in opts:
                o2 = {**opts, "stage2": "sines"}
                m.run(record, o2)
                extra = f"{cpu_ms(lambda: m.run(record, o2), max(3, repeat // 5)):8.1f}"
            lines.append(f"{name:<6} {key:<17} {total:8.2f} {rec_ms:8.2f} {meth_ms:8.2f}   {extra}")
    return "\n".join(lines)


# times each stage of a fresh process's start-up (CPU s), as the console script meets them; prints JSON
STARTUP_CODE = """
import json, time
from vetica_cli.batch.launch import cap_blas_threads
cap_blas_threads()
out, c = {}, time.process_time()
def lap(name):
    global c
    out[name] = time.process_time() - c
    c = time.process_time()
import numpy
lap("numpy")
import vetica_cli.cli
lap("command line")
import numba
lap("numba import")
from numba.core.registry import cpu_target
cpu_target.target_context.refresh()
lap("numba initialisation")
import vetica_cli.simulation.simulate
lap("simulation modules")
print(json.dumps(out))
"""


def startup_line(repeat: int = 3) -> str:
    """One line: the CPU seconds of a fresh process's start-up stages (:data:`STARTUP_CODE`),
    medians of ``repeat`` interpreters."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    root = str(Path(__file__).resolve().parent.parent)  # this package, whatever the interpreter's path says
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p)}
    runs = []
    for _ in range(repeat):
        res = subprocess.run([sys.executable, "-c", STARTUP_CODE], capture_output=True, text=True, env=env)
        if res.returncode != 0:
            return f"start-up of a process: not measured ({(res.stderr.strip().splitlines() or ['?'])[-1][:200]})"
        runs.append(json.loads(res.stdout.strip().splitlines()[-1]))
    med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    return (f"start-up of a process, CPU s (medians of {repeat} fresh interpreters): "
            + ", ".join(f"{k} {v:.3f}" for k, v in med.items()) + f"; total {sum(med.values()):.3f}")  # fmt: skip


def _timed_simulate(cfg) -> tuple[float, float, dict]:
    """``(wall s, CPU s, kernel timing_s)`` of one ``simulate(cfg)`` call."""
    t0, c0 = time.perf_counter(), time.process_time()
    run = simulate(cfg)
    return time.perf_counter() - t0, time.process_time() - c0, run.timing_s


def run_bench(overrides: dict | None = None, repeat: int = 3) -> str:
    """Time ``repeat`` runs per integrator of the worked example (with dotted ``overrides``)
    after one warm-up run each (compilation / cache loading): wall and CPU time."""
    lines = [f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, one core used"]
    rows = []
    for integ in ("verlet", "hybrid"):
        cfg = load(None, {**(overrides or {}), "numerics.integrator": integ})
        run = simulate(cfg)
        timed = [_timed_simulate(cfg) for _ in range(repeat)]
        ms, cpu_ms, fine = _period_ms(run, cfg)
        wall_s, cpu_s = statistics.median(t[0] for t in timed), statistics.median(t[1] for t in timed)
        med = {k: statistics.median(t[2][k] for t in timed) for k in timed[0][2]}
        rows.append((integ, ms, cpu_ms, fine, wall_s, cpu_s, med, run))
    cfg0 = load(None, overrides)
    n = cfg0.numerics
    lines.append(
        f"config: f1 = {cfg0.probe.f1:g} Hz, dt = {n.dt:g} s, print_step = {n.print_step:g} s, "
        f"steady = {n.steady}, record_cycles = {n.record_cycles}; medians of {repeat} runs; wall / CPU"
    )
    steps = rows[0][3]
    lines.append(f"{'integrator':<10} {'ns/fine step':>15} {'ms/period':>15} {'s/point':>15}   "
                 "of which the kernel, wall: total = approach + steady + record")  # fmt: skip
    for integ, ms, cpu_ms, fine, wall_s, cpu_s, med, run in rows:
        per = steps if integ == "verlet" else max(fine, 1)
        ns = f"{ms * 1e6 / per:.2f} / {cpu_ms * 1e6 / per:.2f}"
        lines.append(
            f"{integ:<10} {ns:>15} {f'{ms:.3f} / {cpu_ms:.3f}':>15} {f'{wall_s:.3f} / {cpu_s:.3f}':>15}   "
            f"{med['total']:.3f} = {med['approach']:.3f} + {med['steady']:.3f} + {med['record']:.3f} s; "
            f"{run.info['periods_evaluated']} periods evaluated, stop_reason {run.stop_reason}"
        )
    v, h = rows[0], rows[1]
    lines.append(f"hybrid vs verlet: {v[1] / h[1]:.1f}x per drive period, {v[4] / h[4]:.1f}x per point in wall time; "
                 f"{v[2] / h[2]:.1f}x, {v[5] / h[5]:.1f}x in CPU time ({np.round(h[3] / steps * 100, 1)} % of a period "
                 "in fine steps)")  # fmt: skip
    lines.append(startup_line(min(repeat, 3)))
    return "\n".join(lines)
