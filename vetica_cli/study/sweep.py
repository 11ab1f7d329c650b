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
1. :func:`.plan.plan` groups the points into tasks that share one simulation;
2. :mod:`.lock` locks the output against a second sweep; :mod:`.store` gives back
   the points persisted by an earlier run (resume) and removes corrupt, stale and
   foreign parts, saying how many and why;
3. a :mod:`.launch` launcher runs the task function (:class:`.task.PointTask`,
   passed in) over the missing tasks, serially, on loky workers or on Dask;
4. each finished point is written at once to ``<output>.parts/`` (:mod:`.store`);
5. :func:`.schema.assemble` builds the table, :mod:`.acceptance` its acceptance
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

import os
import signal
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd
import yaml

from .. import __version__
from ..errors import InputError
from ..io import check_output_file, write_table, write_text
from .acceptance import ACCEPT_ERR_PCT, acceptance_regime, format_acceptance
from .cost import Cost, dry_run_text, duration, grid_cost, study_core_seconds
from .grid import Study, load_grid
from .launch import (
    Launcher,
    LokyLauncher,
    SerialLauncher,
    check_launcher_options,
    make_launcher,
    remove_orphaned_shm,
)
from .lock import lock_path, output_lock
from .plan import plan
from .progress import Progress
from .schema import STATUSES, assemble, column_units, material_metadata
from .store import code_fingerprint, parts_dir, remove_parts, rows_frame, scan_parts, write_part
from .task import PointTask


DEFAULT_FOLDER = Path("sweeps")  # where `vetica sweep CONFIG` writes without -o (git-ignored)
CONFIRM_POINTS = 5000  # a study with more points needs --yes
# Below this estimate of core-seconds a sweep runs in its own process: each worker costs ~1.5
# CPU-seconds to start (imports, numba's target and cache), and measured on the project machine
# a 4-point sweep took 3.0 s in one process against 5.3 s with two workers
SERIAL_BELOW_S = 8.0
CONFIRM_WALL_S = 2 * 3600.0  # [s] ... as does one estimated to take longer on the given workers


class SweepInterrupted(KeyboardInterrupt):
    """A sweep stopped by Ctrl-C, SIGTERM or SIGHUP; the message says what is persisted and
    how to go on, ``exit_code`` is the shell's 128 + signal number."""

    def __init__(self, message: str, exit_code: int = 130):
        super().__init__(message)
        self.exit_code = exit_code


class Terminated(KeyboardInterrupt):
    """Raised in the main thread by SIGTERM or SIGHUP during a sweep (handled like Ctrl-C)."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@contextmanager
def signals_as_interrupt(signums=(signal.SIGTERM, signal.SIGHUP)):
    """While the block runs, SIGTERM and SIGHUP raise :class:`Terminated` in the main thread,
    so a terminated sweep stops its workers and reports like Ctrl-C; a repeated signal
    during that shutdown is ignored.  Outside the main thread: no change."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        for s in signums:  # one shutdown: later signals must not interrupt it
            signal.signal(s, signal.SIG_IGN)
        raise Terminated(signum)

    old = {s: signal.signal(s, handler) for s in signums}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)


def default_output(config: str | Path) -> Path:
    """``sweeps/<config stem>.parquet``: outside the tracked results/, so running a study
    config never rewrites a committed table."""
    return DEFAULT_FOLDER / f"{Path(config).stem}.parquet"


def config_copy_path(output: Path) -> Path:
    return output.with_name(output.stem + ".config.yaml")


def check_sweep_output(output: str | Path) -> Path:
    """Every path a sweep on ``output`` writes, checked before any work (InputError, one line):
    the table (a .parquet path in a writable place), the config copy, the parts folder and
    the lock file."""
    out = check_output_file(output, "-o", ".parquet")
    check_output_file(config_copy_path(out), "-o (its config copy)", ".yaml")
    pdir = parts_dir(out)
    if pdir.exists() and not pdir.is_dir():
        raise InputError(f"-o {str(out)!r}: {pdir} (its parts folder) is an existing file")
    if lock_path(out).is_dir():
        raise InputError(f"-o {str(out)!r}: {lock_path(out)} (its lock file) is an existing folder")
    return out


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
) -> SweepResult:
    """Run every missing point of ``study``, then assemble and write the table.

    ``task``: the function each task runs (default :class:`.task.PointTask`: the real
    simulation and extraction); ``launcher``: where (default from ``backend``,
    ``jobs`` and ``scheduler``, :func:`.launch.make_launcher`; a given launcher is
    not closed here).  The output is locked while the sweep runs (:mod:`.lock`;
    InputError when another sweep holds it).  ``keep_parts`` keeps ``<output>.parts/``
    after success; ``log(line)`` receives notes as they arise (they are also in the
    result's ``notes``); ``auto_serial``: run a study estimated under
    :data:`SERIAL_BELOW_S` core-seconds in this process instead of starting workers.  Ctrl-C (or :class:`Terminated`) raises :class:`SweepInterrupted`.
    """
    t_start = time.perf_counter()
    output = check_sweep_output(output)
    notes: list[str] = []

    def note(line: str) -> None:
        notes.append(line)
        if log is not None:
            log(line)

    own = launcher is None
    launcher = make_launcher(backend, jobs, scheduler) if own else launcher
    if own and auto_serial and isinstance(launcher, LokyLauncher):
        est = study_core_seconds(study)
        if est < SERIAL_BELOW_S:
            launcher.close()
            launcher = SerialLauncher()
            note(f"ran in this process: the {len(study.points)} points are estimated at {est:.1f} core-seconds, "
                 f"less than starting {jobs} workers costs")  # fmt: skip
    if own and isinstance(launcher, LokyLauncher):
        stale = remove_orphaned_shm()
        if stale:
            note(f"removed {stale} semaphore(s) and memory folder(s) left in /dev/shm by killed sweeps")
    pdir = parts_dir(output)
    try:
        with output_lock(output):
            done, computed, reused = _run_tasks(study, output, launcher, task or PointTask(), resume, progress,
                                                console, note)  # fmt: skip
            res = _write_table(study, output, done)
            res.parts_kept = keep_parts or not remove_parts(pdir)
            if res.parts_kept and not keep_parts:
                note(f"{pdir}/ holds other files; left in place")
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM/SIGHUP as Terminated
        signum = getattr(exc, "signum", signal.SIGINT)
        keys = {p.key for p in study.points}
        n = sum(1 for f in pdir.glob("*.parquet") if f.stem in keys) if pdir.is_dir() else 0
        raise SweepInterrupted(
            f"interrupted ({signal.Signals(signum).name}): {n} of {len(study.points)} points are persisted "
            f"in {pdir}/; run the same command again to compute the rest",
            128 + int(signum),
        ) from None
    finally:
        if own:
            launcher.close()
    res.computed, res.reused, res.wall_s, res.notes = computed, reused, time.perf_counter() - t_start, notes
    return res


def _run_tasks(study, output, launcher, task, resume, progress, console, note):
    """Run the missing tasks, persisting each point as it finishes.  Returns
    ``(done: point key -> rows frame, keys computed now, keys read from parts)``."""
    pdir = parts_dir(output)
    tasks = plan(study)
    expected = {p.key: (p, t.sim_print_step) for t in tasks for p in t.points}
    done, report = scan_parts(pdir, expected, resume)
    if report.note():
        note(report.note())
    todo = [t for t in tasks if not all(p.key in done for p in t.points)]
    reused = list(done)
    pdir.mkdir(parents=True, exist_ok=True)
    computed: list[str] = []
    failed = sum(int((df["status"] == "failed").any()) for df in done.values())
    bar = Progress(len(study.points), len(done), failed, enabled=progress, console=console)

    def on_result(i: int, res) -> None:
        nonlocal failed
        by_key = {p.key: p for p in todo[i].points}
        for key, rows, sim_ps in res:
            point = by_key[key]
            write_part(pdir, point, rows, sim_ps)
            done[key] = rows_frame(point, rows)
            computed.append(key)
            failed += int(any(r["status"] == "failed" for r in rows))
            bar.advance(1, failed)

    items = [[(p.key, p.config.to_dict(), p.method, p.force) for p in t.points] for t in todo]
    with bar:
        launcher.launch(task, items, on_result)
    return done, computed, reused


def _write_table(study, output, done) -> SweepResult:
    """Assemble the table, take its acceptance regime, write it and the resolved config."""
    table = assemble(study, done)
    acceptance = acceptance_regime(table, study.keys)
    config_path = config_copy_path(output)
    meta = {
        "study": study.name,
        "description": study.description,
        "config": study.resolved(),
        "swept_keys": list(study.keys),
        "units": column_units(study),
        "material": material_metadata(study),
        "version": __version__,
        "code": code_fingerprint(),
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
        format_acceptance(res.acceptance, study.keys),
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


def cores() -> int:
    """CPU cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return os.cpu_count() or 1


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
    g.check_values()
    log = log or (lambda line: None)
    if run_kw.get("backend", "loky") == "loky" and jobs > cores():
        log(f"warning: --jobs {jobs} is more than the {cores()} cores here; the workers will share them")
    if dry_run:
        return dry_run_text(g, out, jobs)
    cost = grid_cost(g)
    size_guard(cost, jobs, yes)
    if cost.points > 2000:
        log(f"checking the {cost.points} points of {g.name} ...")
    study = g.study()
    with signals_as_interrupt():
        res = run_sweep(study, out, jobs=jobs, log=log, auto_serial=auto, **run_kw)
    return summary(res, study)
