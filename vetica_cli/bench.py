"""Benchmark of the simulation kernel (not a test: numbers are reported, not asserted).

Reports, for the given config (default: thesis worked example at dt = 0.025 ns),
the integration cost in ns per step and the wall time to steady state on one core.
"""

from __future__ import annotations

import os
import platform
import statistics

from .simulation.config import load
from .simulation.simulate import simulate


def run_bench(overrides: dict | None = None, repeat: int = 3) -> str:
    """Time ``repeat`` runs of the worked example (with dotted ``overrides``) after one warm-up run."""
    cfg = load(None, overrides)
    simulate(cfg)  # compile / load the numba cache
    walls, ns = [], []
    for _ in range(repeat):
        run = simulate(cfg)
        walls.append(run.wall_s)
        ns.append(run.wall_s / run.info["steps"] * 1e9)
    steps = int(run.info["steps"])
    return "\n".join(
        [
            f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, one core used",
            f"config: dt = {cfg.numerics.dt:g} s, print_step = {cfg.numerics.print_step:g} s, cd = {cfg.surface.cd:g} kg/s",
            f"steps to steady state + {cfg.numerics.record_cycles} recorded periods: {steps:,} "
            f"({run.info['t_end'] * 1e3:.3f} ms simulated, stop_reason {run.stop_reason})",
            f"ns per step: median {statistics.median(ns):.2f} (min {min(ns):.2f}, max {max(ns):.2f}) over {repeat} runs",
            f"wall seconds to steady state and recording: median {statistics.median(walls):.3f} "
            f"(min {min(walls):.3f}, max {max(walls):.3f})",
        ]
    )
