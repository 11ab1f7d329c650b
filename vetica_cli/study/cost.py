"""The ``--dry-run`` estimate: points, simulations and a bound on the cost."""

from __future__ import annotations

from pathlib import Path

from ..extraction import METHODS, get
from .grid import Study
from .plan import plan
from .schema import point_sources
from .store import parts_dir

# measured on the project machine (2 cores): `vetica bench` gives 14 ns per integration step on one
# core (worked example, dt = 0.025 ns).  Each extraction method states its own seconds per point
# (ExtractionMethod.seconds_per_point, both force sources).  Used only for the --dry-run estimate.
NS_PER_STEP = 14.0


def dry_run_text(study: Study, output: Path, jobs: int, share_print_step: bool = True) -> str:
    """Points, jobs and a cost bound: kernel time if every simulation runs to
    numerics.max_time, plus the extraction of every point."""
    tasks = plan(study, share_print_step)
    kernel = sum(t.points[0].config.numerics.max_time / t.points[0].config.numerics.dt for t in tasks)
    kernel *= NS_PER_STEP * 1e-9
    extract = sum(get(p.method).seconds_per_point * len(point_sources(p.force)) / 2 for p in study.points)
    total = kernel + extract
    per_method = ", ".join(f"{m.seconds_per_point:g} s a {k} point" for k, m in METHODS.items())
    lines = [
        (
            f"study {study.name}: {len(study.points)} points over {', '.join(study.keys)}; "
            f"{len(tasks)} simulations ({'print-step groups shared' if share_print_step else 'no print-step sharing'})"
        ),
        (
            f"cost at most {total:.0f} core-s = {total / max(jobs, 1) / 60:.1f} min wall on {jobs} workers: "
            f"kernel {kernel:.0f} core-s if every simulation runs to numerics.max_time ({NS_PER_STEP:g} ns/step), "
            f"extraction ~{extract:.0f} core-s ({per_method}); steady points cost less"
        ),
        f"output: {output} (parts in {parts_dir(output)}/)",
    ]
    for p in study.points[:5]:
        lines.append(f"  point {p.index}: {p.label()}")
    if len(study.points) > 5:
        lines.append(f"  ... {len(study.points) - 5} more")
    return "\n".join(lines)
