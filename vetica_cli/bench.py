"""``vetica bench``: what the simulation costs (a benchmark, not a test: numbers are reported,
not asserted).  Medians of repeated runs, because the machine may be shared.

For each integrator (``verlet``: all fine steps; ``hybrid``: exact propagation away from the
surface) on the given config (default: the thesis's worked example, dt = 0.025 ns):

* ns per fine step: one drive period of the all-fine integrator from the solved orbit,
  divided by its steps;
* ms per drive period: one period (not recorded) from the solved orbit;
* s per point: ``simulate()``'s kernel time -- approach, steady state (orbit or transient),
  recorded window -- and its split.
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
    from .core import engine, tapping
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
    s[tapping.S_ZC], s[tapping.S_ZP], s[tapping.S_ZB] = last[2], last[3], last[4]
    s[tapping.S_VC] = d.a_sp * d.omega1
    kern.advance(s)
    walls, fine = [], 0
    for _ in range(5):
        t0 = time.perf_counter()
        o = kern.advance(s)
        walls.append(time.perf_counter() - t0)
        fine = o[tapping.O_FINE]
    return 1e3 * statistics.median(walls), float(fine)


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
