"""The cost of one simulation before it runs: a rough upper estimate of its kernel time,
from the config alone, for the dry runs, the progress bars' first estimate and the guard that
asks for ``--yes`` before a long command (:func:`vetica_cli.checks.confirm_cost`)."""

from __future__ import annotations

# Measured on the project machine (2 cores, `vetica bench` and whole points of the print-step
# study, worked example): a hybrid drive period costs ~0.10 of the fine steps of a period at
# NS_PER_STEP each (the tip is within the switch gap of the surface for ~10 % of it), a recorded
# one RECORD_NS per print-step sample more (the kernel's recording, the table and its
# observables: 0.35 s for 1.86 M samples); an orbit solve with its approach takes ORBIT_PERIODS
# periods (p90 over the study grid), a transient up to numerics.max_time.  Each extraction
# method states its own seconds per point (ExtractionMethod.seconds_per_point, both force
# sources, scaled by extraction.base.record_cost_scale).  Used only for estimates.
NS_PER_STEP = 18.0
NEAR_FRACTION = 0.10
RECORD_NS = 190.0
ORBIT_PERIODS = 60
SIMULATE_START_S = 1.5  # [s] one simulation's fixed cost besides the kernel (imports, the record, its table)


def kernel_seconds_of(f1, dt, print_step, record_cycles, integrator, steady, max_time) -> float:
    """Rough upper estimate of one simulation's kernel time [s] (module comment)."""
    steps = round(1.0 / f1 / dt)
    fraction = NEAR_FRACTION if integrator == "hybrid" else 1.0
    period = steps * fraction * NS_PER_STEP * 1e-9
    periods = ORBIT_PERIODS if steady == "orbit" else max_time * f1
    record = record_cycles * steps / max(1, round(print_step / dt)) * RECORD_NS * 1e-9
    return periods * period + record


def kernel_seconds(cfg) -> float:
    """:func:`kernel_seconds_of` a resolved config."""
    n = cfg.numerics
    return kernel_seconds_of(cfg.probe.f1, n.dt, n.print_step, n.record_cycles, n.integrator, n.steady, n.max_time)


def simulation_seconds(cfg) -> float:
    """Rough upper estimate of one ``vetica simulate`` of ``cfg`` [s]: its kernel and its fixed cost."""
    return SIMULATE_START_S + kernel_seconds(cfg)
