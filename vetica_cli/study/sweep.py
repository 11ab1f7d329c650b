"""Parametric sweeps: ``run_sweep(study, output)`` and ``sweep_command`` (``vetica sweep CONFIG``).

One *point* of a study (:mod:`.grid`) is simulated once and then extracted with
the simulator's true force and with the force reconstructed from the paddle
signal (``extract.force`` restricts this), by the point's
``extract.method`` (a registered method of :mod:`vetica_cli.extraction`),
giving one row per force source of a tidy table (:mod:`.schema`).  The path of
a study, one way through:

0. before any work (:func:`sweep_command`): the config and every swept value are
   checked, the output paths are checked (:func:`check_sweep_output`), the cost is
   estimated from the grid alone (:mod:`.cost`; ``--dry-run`` stops here), and a
   study over :data:`CONFIRM_POINTS` points or :data:`CONFIRM_WALL_S` of estimated
   wall time needs ``--yes``;
1. :func:`vetica_cli.rows.plan.group` groups the points into tasks that share one
   simulation (the print-step policy every batch follows);
2. the batch layer (:func:`vetica_cli.batch.run.run_batch`) locks the output against
   a second sweep, gives back the points persisted by an earlier run (resume) and
   removes corrupt, stale and foreign parts, saying how many and why;
3. its launcher runs the task function (:class:`vetica_cli.rows.task.PointTask`,
   passed in) over the missing tasks, serially, on loky workers or on Dask;
4. each finished point is written at once to ``<output>.parts/``;
5. :func:`.table.assemble` builds the table, :mod:`.acceptance` its acceptance
   regime, and the table is written atomically with the units, the resolved
   study config and the regime in its metadata; the config is also saved as
   ``<output stem>.config.yaml``; the parts folder is removed (``keep_parts``
   keeps it).

Nothing is lost: a point whose simulation or extraction raises becomes a row
with ``status = 'failed'`` and the error text (the simulation's columns are
kept when only the extraction failed); the other points run on.  Ctrl-C,
SIGTERM and SIGHUP stop the workers and say how many points are persisted; a
killed sweep run again computes only the missing points.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import yaml

from .. import __version__
from ..batch.launch import Launcher, check_launcher_options, cores, jobs_warning  # noqa: F401 - cores: the tests'
from ..batch.parts import CORRUPT, STALE, code_fingerprint, parts_dir
from ..batch.run import (
    DEFAULT_FOLDER,
    Bar,
    BatchInterrupted,
    Job,
    check_batch_output,
    run_batch,
    sidecar,
    signals_as_interrupt,
)
from ..batch.run import Terminated  # noqa: F401 - raised by SIGTERM/SIGHUP during a sweep
from ..batch.run import default_output as batch_output
from ..checks import CONFIRM_ITEMS, CONFIRM_WALL_S
from ..errors import InputError
from ..io import write_table, write_text
from ..rows.extract import point_sources
from ..rows.plan import group
from ..rows.schema import STATUSES, units_metadata
from ..rows.task import PointTask
from ..extraction import extraction_modules
from ..simulation.jit import compile_notice, simulation_modules
from .acceptance import ACCEPT_ERR_PCT, acceptance_regime, format_acceptance
from .cost import Cost, dry_run_text, duration, grid_cost, study_core_seconds, wall_estimate
from .grid import Study, load_grid
from .table import assemble, column_meta_of, rows_frame, study_material_metadata

if TYPE_CHECKING:  # pandas is imported where a table is built: a dry run starts without it
    import pandas as pd

# the modules whose import closure computes a point's rows: the point task (simulation and
# extraction), the print-step policy that shares simulations, and the points and their keys
SWEEP_ROOTS = ("rows/task.py", "rows/plan.py", "study/grid.py", "study/table.py")
CONFIRM_POINTS = CONFIRM_ITEMS  # a study with more points needs --yes (the threshold every command asks past)
# Below this estimate of core-seconds a sweep runs in its own process: each worker costs ~1.5
# CPU-seconds to start (imports, numba's target and cache), and measured on the project machine
# a 4-point sweep took 3.0 s in one process against 5.3 s with two workers
SERIAL_BELOW_S = 8.0
SweepInterrupted = BatchInterrupted  # Ctrl-C, SIGTERM or SIGHUP during a sweep (message and exit code)


def default_output(config: str | Path) -> Path:
    """``sweeps/<config stem>.parquet``: outside the tracked results/, so running a study
    config never rewrites a committed table."""
    return batch_output(config, DEFAULT_FOLDER)


def config_copy_path(output: Path) -> Path:
    return sidecar(output, ".config.yaml")


def check_sweep_output(output: str | Path) -> Path:
    """Every path a sweep on ``output`` writes, checked before any work (InputError, one line):
    the table, the config copy, the parts folder and the lock file."""
    return check_batch_output(output, (".config.yaml",))


@dataclass
class SweepResult:
    table: pd.DataFrame
    output: Path
    config_path: Path
    computed: list = field(default_factory=list)  # point keys computed in this call
    reused: list = field(default_factory=list)  # point keys taken from persisted parts
    acceptance: list = field(default_factory=list)
    wall_s: float = 0.0
    notes: list = field(default_factory=list)  # what the user should know (parts removed, ...)
    parts_kept: bool = False  # the parts folder is still there


def run_sweep(
    study: Study,
    output: str | Path,
    jobs: int = 2,
    backend: str = "loky",
    scheduler: str | None = None,
    resume: bool = True,
    progress: bool = True,
    console=None,
    task: PointTask | None = None,
    launcher: Launcher | None = None,
    keep_parts: bool = False,
    log=None,
    auto_serial: bool = False,
    notice: str | None = None,
) -> SweepResult:
    """Run every missing point of ``study``, then assemble and write the table.

    ``task``: the function each task runs (default :class:`vetica_cli.rows.task.PointTask`:
    the real simulation and extraction); ``launcher``: where (default from ``backend``,
    ``jobs`` and ``scheduler``, :func:`vetica_cli.batch.launch.make_launcher`; a given
    launcher is not closed here).  The output is locked while the sweep runs (InputError
    when another sweep holds it).  ``keep_parts`` keeps ``<output>.parts/`` after success;
    ``log(line)`` receives notes as they arise (they are also in the result's ``notes``);
    ``auto_serial``: run a study estimated under :data:`SERIAL_BELOW_S` core-seconds in this
    process instead of starting workers; ``notice``: a line shown as the bar starts.
    Ctrl-C (or :class:`Terminated`) raises :class:`SweepInterrupted`."""
    t_start = time.perf_counter()
    output = check_sweep_output(output)
    tasks = group(study.points)
    jobs_ = [Job([(p.key, p.config.to_dict(), p.method, p.force) for p in t.points], {p.key: p for p in t.points})
             for t in tasks]  # fmt: skip
    by_key = {p.key: p for p in study.points}

    def split(job: Job, res) -> list:
        return [(key, rows_frame(by_key[key], rows), part_meta(by_key[key])) for key, rows in res]

    def finish(done: dict) -> SweepResult:
        return _write_table(study, output, {k: done[k] for k in by_key})

    core_s = study_core_seconds(study)
    bar = Bar(name="sweep", unit="points", estimate_s=wall_estimate(core_s, 1 if jobs == 1 else jobs), notice=notice)
    res, run = run_batch(output, jobs_, task or PointTask(replicas=study.replicas), split, fingerprint=code_fingerprint(SWEEP_ROOTS),
                         finish=finish, check=check_point_part, bar=bar, backend=backend, n_jobs=jobs,
                         scheduler=scheduler, launcher=launcher, serial_estimate=core_s if auto_serial else None,
                         serial_below_s=SERIAL_BELOW_S, resume=resume, progress=progress, console=console,
                         keep_parts=keep_parts, log=log, what="points")  # fmt: skip
    res.parts_kept = run.parts_kept
    res.computed, res.reused, res.wall_s, res.notes = run.computed, run.reused, time.perf_counter() - t_start, run.notes
    return res


def part_meta(point) -> dict:
    """What a point's part records beside its key and code: where it is in the grid, its config."""
    return {"index": point.index, "values": point.values, "params": point.config.to_dict(), "method": point.method,
            "force": point.force, "version": __version__}  # fmt: skip


def check_point_part(df: pd.DataFrame, meta: dict, point) -> str:
    """Why a persisted part of ``point`` is not usable ('' when it is): its rows must be of
    the point's method and force sources."""
    want = list(point_sources(point.force))
    if not {"force_source", "method", "status"} <= set(df.columns):
        return CORRUPT
    if set(df["method"]) != {point.method}:
        return STALE
    if list(df["force_source"]) != want:
        return CORRUPT if set(df["force_source"]) < set(want) else STALE
    return ""


def _write_table(study, output, done) -> SweepResult:
    """Assemble the table, take its acceptance regime, write it and the resolved config."""
    table = assemble(study, done)
    acceptance = acceptance_regime(table, study.keys, model=study.points[0].config.surface.surface_model)
    config_path = config_copy_path(output)
    meta = {
        "study": study.name,
        "description": study.description,
        "config": study.resolved(),
        "swept_keys": list(study.keys),
        **units_metadata(column_meta_of(study)),
        "material": study_material_metadata(study),
        "version": __version__,
        "code": code_fingerprint(SWEEP_ROOTS),
        "points": len(study.points),
        "acceptance_err_pct": ACCEPT_ERR_PCT,
        "acceptance": acceptance,
        "config_file": config_path.name,
    }
    write_table(table, output, meta)
    write_text(config_path, yaml.safe_dump(study.resolved(), sort_keys=False))
    return SweepResult(table=table, output=output, config_path=config_path, acceptance=acceptance)


def summary(res: SweepResult, study: Study) -> str:
    """What the sweep did: points computed and reused, rows by status, the acceptance regime."""
    t = res.table
    by_status = t["status"].value_counts().to_dict()
    pdir = parts_dir(res.output)
    where = f"{pdir}/" if res.parts_kept else "persisted parts"
    lines = [
        f"{len(study.points)} points ({len(res.computed)} computed, {len(res.reused)} reused from {where}), "
        f"{len(t)} rows: " + ", ".join(f"{by_status.get(s, 0)} {s}" for s in STATUSES),
        format_acceptance(res.acceptance, study.keys, study.points[0].config.surface.surface_model),
        f"wrote {res.output} and {res.config_path} in {res.wall_s:.1f} s"
        + (f"; kept {pdir}/" if res.parts_kept else ""),
    ]
    return "\n".join(lines)


def size_guard(cost: Cost, jobs: int, yes: bool) -> None:
    """InputError (one line, how to go on) for a study over :data:`CONFIRM_POINTS` points or
    :data:`CONFIRM_WALL_S` of estimated wall time, unless ``yes``."""
    wall = cost.wall_s(jobs)
    if yes or (cost.points <= CONFIRM_POINTS and wall <= CONFIRM_WALL_S):
        return
    raise InputError(
        f"this study has {cost.points} points ({cost.simulations} simulations), estimated {duration(wall)} on "
        f"{jobs} workers (over {CONFIRM_POINTS} points or {duration(CONFIRM_WALL_S)}): add --yes to start it, "
        "or --dry-run to see the plan"
    )


def study_modules(study: Study) -> set[str]:
    """The cached core modules the study's points compile (simulations and extractions)."""
    mods: set[str] = set()
    for kind in {(p.config.surface.model, p.config.numerics.temperature > 0, p.method, p.force) for p in study.points}:
        p = next(q for q in study.points if (q.config.surface.model, q.config.numerics.temperature > 0, q.method,
                                               q.force) == kind)  # fmt: skip
        mods |= simulation_modules(p.config) | extraction_modules((p.method,), point_sources(p.force))
    return mods


def sweep_command(
    config: str | Path,
    output: str | Path | None = None,
    overrides: dict | None = None,
    dry_run: bool = False,
    jobs: int | None = None,
    yes: bool = False,
    log=None,
    **run_kw,
) -> str:
    """``vetica sweep CONFIG``: check the study (``overrides`` on its base), its output and
    its size, then print its points and cost (``dry_run``) or run it (:func:`run_sweep`
    keywords in ``run_kw``).  Returns the text to print; the table goes to ``output``
    (default :func:`default_output`).  ``log(line)``: notes and warnings as they arise.
    ``jobs`` None: 2 workers, or none for a study estimated under :data:`SERIAL_BELOW_S`.
    Raises :class:`SweepInterrupted` on Ctrl-C, SIGTERM or SIGHUP."""
    auto = jobs is None
    jobs = 2 if auto else jobs
    g = load_grid(config, overrides)
    out = check_sweep_output(Path(output) if output is not None else default_output(config))
    check_launcher_options(run_kw.get("backend", "loky"), jobs, run_kw.get("scheduler"))
    checked = g.check_values()
    log = log or (lambda line: None)
    if run_kw.get("backend", "loky") == "loky" and jobs_warning(jobs):
        log(jobs_warning(jobs))
    if dry_run:
        return dry_run_text(g, out, jobs, checked)
    cost = grid_cost(g)
    size_guard(cost, jobs, yes)
    if cost.points > 2000:
        log(f"checking the {cost.points} points of {g.name} ...")
    study = g.study()
    with signals_as_interrupt():
        res = run_sweep(study, out, jobs=jobs, log=log, auto_serial=auto, notice=compile_notice(study_modules(study)),
                        **run_kw)  # fmt: skip
    return summary(res, study)
