"""``vetica bench``: what the simulation costs (a benchmark, not a test: numbers are reported,
not asserted).  Medians of repeated runs, because the machine may be shared.

For each integrator (``verlet``: all fine steps; ``hybrid``: exact propagation away from the
surface) on the given config (default: the thesis's worked example, dt = 0.025 ns):

* ns per fine step: one drive period of the all-fine integrator from the solved orbit,
  divided by its steps;
* ms per drive period: one period (not recorded) from the solved orbit;
* s per point: ``simulate()``'s kernel time -- approach, steady state (orbit or transient),
  recorded window -- and its split.

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
from .simulation.simulate import simulate


def _period_ms(run, cfg) -> tuple[float, float]:
    """Wall time of one unrecorded drive period from the run's last recorded state [ms],
    and the fine steps it took."""
    from .core import engine, session, tapping
    from .simulation.simulate import derive, kernel_setup

    d = derive(cfg)
    if cfg.surface.model == "hertz":  # the MDR kernel on the run's element grid
        from .simulation.hertz import kernel_of_run

        kern = kernel_of_run(cfg, kernel_setup(cfg, d), run)
    else:
        kern = engine.Kernel(kernel_setup(cfg, d))
    s = engine.new_state(0, 0, 0, 0, 0, kern.n_state)
    last = run.steady[-1]
    # the orbit's state at the end of the window: positions from the record, velocities by one
    # period of warm-up (any state near the orbit costs the same)
    session.place_probe(s, zc=last[2], vc=d.a_sp * d.omega1, zp=last[3], zb=last[4])
    kern.advance(s)
    walls, fine = [], 0
    for _ in range(5):
        t0 = time.perf_counter()
        o = kern.advance(s)
        walls.append(time.perf_counter() - t0)
        fine = o[tapping.O_FINE]
    return 1e3 * statistics.median(walls), float(fine)


PIXEL = {"numerics.print_step": 1e-9, "numerics.record_cycles": 4}  # a scan pixel's record (configs/scan_blend.yaml)
SURFACES = {"stiff": {}, "soft": {"surface.k_inf": 2.0, "surface.k0": 32.0, "surface.cd": 3e-4}}


def _cpu_ms(fn, repeat: int) -> float:
    """Median CPU time of ``fn()`` over ``repeat`` calls [ms]."""
    out = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        out.append(time.process_time() - t0)
    return 1e3 * statistics.median(out)


def run_extraction_bench(methods: tuple = ("vetica", "vetica-prestress", "full"), repeat: int = 20,
                         overrides: dict | None = None) -> str:  # fmt: skip
    """CPU ms per pixel record of each extraction method (module docstring); ``repeat`` timed
    calls after two warm-up calls (compilation, caches), fewer for the whole-cycle fit."""
    from .extraction import extract, get
    from .extraction.record import build_record

    lines = [f"extraction per pixel record (4 periods at 1 ns, reconstructed force), CPU ms, medians of {repeat} "
             f"calls (the whole-cycle fit: {max(3, repeat // 5)}), one core"]  # fmt: skip
    lines.append(f"{'surface':<6} {'method':<17} {'extract':>8} {'record':>8} {'method':>8}   "
                 "stage2 thesis fit (sines) for comparison")  # fmt: skip
    for name, surf in SURFACES.items():
        run = simulate(load(None, {**PIXEL, **surf, **(overrides or {})}))
        df, meta = run.frame(), run.metadata()
        for key in methods:
            m = get(key)
            n = max(3, repeat // 5) if key == "full" else repeat
            opts = m.options({})
            for _ in range(2):
                extract(df, meta, force="reconstructed", method=key)
            total = _cpu_ms(lambda: extract(df, meta, force="reconstructed", method=key), n)
            kw = {"need_approach": m.needs_approach, "need_z1": m.needs_z1, "tap_windows": m.tap_windows,
                  "uniform": key if m.uniform_sampling else None}  # fmt: skip
            record = build_record(df, meta, "reconstructed", **kw)
            rec_ms = _cpu_ms(lambda: build_record(df, meta, "reconstructed", **kw), n)
            meth_ms = _cpu_ms(lambda: m.run(record, opts), n)
            extra = ""
            if "stage2" in opts:
                o2 = {**opts, "stage2": "sines"}
                m.run(record, o2)
                extra = f"{_cpu_ms(lambda: m.run(record, o2), max(3, repeat // 5)):8.1f}"
            lines.append(f"{name:<6} {key:<17} {total:8.2f} {rec_ms:8.2f} {meth_ms:8.2f}   {extra}")
    return "\n".join(lines)


def run_bench(overrides: dict | None = None, repeat: int = 3) -> str:
    """Time ``repeat`` runs per integrator of the worked example (with dotted ``overrides``)
    after one warm-up run each (compilation / cache loading)."""
    lines = [f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, one core used"]
    rows = []
    for integ in ("verlet", "hybrid"):
        cfg = load(None, {**(overrides or {}), "numerics.integrator": integ})
        run = simulate(cfg)
        timings = [simulate(cfg).timing_s for _ in range(repeat)]
        ms, fine = _period_ms(run, cfg)
        med = {k: statistics.median(t[k] for t in timings) for k in timings[0]}
        rows.append((integ, ms, fine, med, run))
    cfg0 = load(None, overrides)
    n = cfg0.numerics
    lines.append(
        f"config: f1 = {cfg0.probe.f1:g} Hz, dt = {n.dt:g} s, print_step = {n.print_step:g} s, "
        f"steady = {n.steady}, record_cycles = {n.record_cycles}; medians of {repeat} runs"
    )
    steps = rows[0][2]
    lines.append(f"{'integrator':<10} {'ns/fine step':>13} {'ms/period':>10} {'s/point':>9}   split (approach / steady / record)")
    for integ, ms, fine, med, run in rows:
        ns = ms * 1e6 / steps if integ == "verlet" else ms * 1e6 / max(fine, 1)
        lines.append(
            f"{integ:<10} {ns:>13.2f} {ms:>10.3f} {med['total']:>9.3f}   "
            f"{med['approach']:.3f} / {med['steady']:.3f} / {med['record']:.3f} s; "
            f"{run.info['periods_evaluated']} periods evaluated, stop_reason {run.stop_reason}"
        )
    v, h = rows[0], rows[1]
    lines.append(f"hybrid vs verlet: {v[1] / h[1]:.1f}x per drive period, {v[3]['total'] / h[3]['total']:.1f}x per point "
                 f"({np.round(h[2] / steps * 100, 1)} % of a period in fine steps)")  # fmt: skip
    return "\n".join(lines)
