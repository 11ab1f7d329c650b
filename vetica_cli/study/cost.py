"""The ``--dry-run`` estimate: points, simulations and a bound on the cost."""

from __future__ import annotations

from pathlib import Path

from ..extraction import METHODS, get
from .grid import Study
from .plan import plan
from .schema import point_sources
from .store import parts_dir

# Measured on the project machine (2 cores, `vetica bench`, worked example): a hybrid drive period
# costs ~0.09 of the fine steps of a period at NS_PER_STEP each (the tip is within the switch gap of
# the surface for ~9 % of it), a recorded one RECORD_NS per print-step sample more; an orbit solve
# with its approach takes ORBIT_PERIODS periods (p90 over the study grid), a transient up to
# numerics.max_time.  Each extraction method states its own seconds per point
# (ExtractionMethod.seconds_per_point, both force sources).  Used only for the --dry-run estimate.
NS_PER_STEP = 11.0
NEAR_FRACTION = 0.09
RECORD_NS = 50.0
ORBIT_PERIODS = 60


def kernel_seconds(cfg) -> float:
    """Rough upper estimate of one simulation's kernel time [s] (module comment)."""
    n = cfg.numerics
    steps = round(1.0 / cfg.probe.f1 / n.dt)
    fraction = NEAR_FRACTION if n.integrator == "hybrid" else 1.0
    period = steps * fraction * NS_PER_STEP * 1e-9
    periods = ORBIT_PERIODS if n.steady == "orbit" else n.max_time * cfg.probe.f1
    record = n.record_cycles * steps / round(n.print_step / n.dt) * RECORD_NS * 1e-9
    return periods * period + record


def dry_run_text(study: Study, output: Path, jobs: int) -> str:
    """Points, jobs and a cost estimate: the kernel (:func:`kernel_seconds`) plus the
    extraction of every point."""
    tasks = plan(study)
    kernel = sum(kernel_seconds(t.points[0].config) for t in tasks)
    extract = sum(get(p.method).seconds_per_point * len(point_sources(p.force)) / 2 for p in study.points)
    total = kernel + extract
    per_method = ", ".join(f"{m.seconds_per_point:g} s a {k} point" for k, m in METHODS.items())
    lines = [
        f"study {study.name}: {len(study.points)} points over {', '.join(study.keys)}; {len(tasks)} simulations",
        (
            f"cost ~{total:.0f} core-s = {total / max(jobs, 1) / 60:.1f} min wall on {jobs} workers: "
            f"kernel ~{kernel:.0f} core-s, extraction ~{extract:.0f} core-s ({per_method})"
        ),
        f"output: {output} (parts in {parts_dir(output)}/)",
    ]
    for p in study.points[:5]:
        lines.append(f"  point {p.index}: {p.label()}")
    if len(study.points) > 5:
        lines.append(f"  ... {len(study.points) - 5} more")
    return "\n".join(lines)
