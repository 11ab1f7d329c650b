"""One batch, one way through, for every command that runs many jobs (a sweep's point
tasks, a scan's lines): the machinery around the task function, knowing no physics.

0. before any work: every path the batch writes is checked (:func:`check_batch_output`:
   the table, its sidecar files, the parts folder and the lock file);
1. the launcher is opened (:mod:`.launch`; an unreachable scheduler exits with one line),
   a cheap batch may run in this process (``serial_estimate``), and what ``kill -9`` of an
   earlier batch left in /dev/shm is removed;
2. the output is locked against a second batch (:mod:`.lock`); the parts of an earlier run
   are reused or removed, saying how many and why (:mod:`.parts`);
3. the launcher runs the task function over the missing jobs; each result's parts are
   written at once, and the bar (:mod:`.progress`) advances;
4. ``finish(done)`` (the caller: assemble and write its table) runs under the lock; the
   parts folder is then removed (``keep_parts`` keeps it).

Ctrl-C, SIGTERM and SIGHUP (:func:`signals_as_interrupt`) stop the workers and raise
:class:`BatchInterrupted` saying how many jobs are persisted, with the shell's exit code;
a batch run again computes only the missing jobs.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import InputError
from ..io import check_output_file
from .launch import Launcher, LokyLauncher, SerialLauncher, make_launcher, remove_orphaned_shm
from .lock import lock_path, output_lock
from .parts import Check, parts_dir, remove_parts, scan_parts, write_part
from .progress import Progress

if TYPE_CHECKING:  # pandas is imported with the first part: a dry run starts without it
    import pandas as pd

DEFAULT_FOLDER = Path("sweeps")  # where a batch writes without -o (git-ignored: never a committed table)


class BatchInterrupted(KeyboardInterrupt):
    """A batch stopped by Ctrl-C, SIGTERM or SIGHUP; the message says what is persisted and
    how to go on, ``exit_code`` is the shell's 128 + signal number."""

    def __init__(self, message: str, exit_code: int = 130):
        super().__init__(message)
        self.exit_code = exit_code


class Terminated(KeyboardInterrupt):
    """Raised in the main thread by SIGTERM or SIGHUP during a batch (handled like Ctrl-C)."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@contextmanager
def signals_as_interrupt(signums=(signal.SIGTERM, signal.SIGHUP)):
    """While the block runs, SIGTERM and SIGHUP raise :class:`Terminated` in the main thread,
    so a terminated batch stops its workers and reports like Ctrl-C; a repeated signal
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


def default_output(config: str | Path, folder: Path = DEFAULT_FOLDER) -> Path:
    """``<folder>/<config stem>.parquet``: outside the tracked results/, so running a
    config never rewrites a committed table."""
    return folder / f"{Path(config).stem}.parquet"


def sidecar(output: Path, suffix: str) -> Path:
    """``<output stem><suffix>`` beside the table (e.g. ``.config.yaml``)."""
    return output.with_name(output.stem + suffix)


def check_batch_output(output: str | Path, sidecars: tuple[str, ...] = (".config.yaml",)) -> Path:
    """Every path a batch on ``output`` writes, checked before any work (InputError, one
    line): the table (a .parquet path in a writable place), each sidecar
    (``<stem><suffix>``), the parts folder and the lock file."""
    out = check_output_file(output, "-o", ".parquet")
    for suffix in sidecars:
        check_output_file(sidecar(out, suffix), f"-o (its {suffix.lstrip('.')} file)", None)
    pdir = parts_dir(out)
    if pdir.exists() and not pdir.is_dir():
        raise InputError(f"-o {str(out)!r}: {pdir} (its parts folder) is an existing file")
    if lock_path(out).is_dir():
        raise InputError(f"-o {str(out)!r}: {lock_path(out)} (its lock file) is an existing folder")
    return out


@dataclass
class Job:
    """One call of the task function: its argument and the keys of the parts it yields,
    each with what the batch's part check compares a persisted part with."""

    arg: Any
    parts: dict  # part key -> expected (for the check)


@dataclass
class BatchRun:
    """What a batch did."""

    done: dict  # part key -> frame, every part of the batch
    computed: list = field(default_factory=list)  # part keys computed in this call
    reused: list = field(default_factory=list)  # part keys read from an earlier run's parts
    notes: list = field(default_factory=list)  # what the user should know (parts removed, ...)
    parts_kept: bool = False


@dataclass
class Bar:
    """How the progress bar counts: ``count(frame) -> (items, failed items)`` of one part;
    ``groups``: the unit jobs are counted in beside the items (a scan: lines), or None."""

    name: str = "batch"
    unit: str = "points"
    count: Callable[[pd.DataFrame], tuple[int, int]] = lambda df: (1, int((df["status"] == "failed").any()))
    groups: str | None = None
    total: int | None = None  # items in the whole batch (default: one per part)
    estimate_s: float | None = None  # the cost model's wall seconds for the missing jobs
    notice: str | None = None  # a line printed as the bar starts (e.g. numba compiling on a first run)


def open_launcher(backend: str, jobs: int, scheduler: str | None, launcher: Launcher | None,
                  serial_estimate: float | None, serial_below_s: float, note,
                  what: str = "the jobs") -> tuple[Launcher, bool]:  # fmt: skip
    """``(launcher, own)``: the given one, or one made from the options (run in this process
    when ``serial_estimate`` core-seconds are below ``serial_below_s``); a loky batch first
    removes what killed batches left in /dev/shm."""
    own = launcher is None
    launcher = make_launcher(backend, jobs, scheduler) if own else launcher
    if own and serial_estimate is not None and isinstance(launcher, LokyLauncher) and serial_estimate < serial_below_s:
        launcher.close()
        launcher = SerialLauncher()
        note(f"ran in this process: {what} are estimated at {serial_estimate:.1f} core-seconds, "
             f"less than starting {jobs} workers costs")  # fmt: skip
    if own and isinstance(launcher, LokyLauncher):
        stale = remove_orphaned_shm()
        if stale:
            note(f"removed {stale} semaphore(s) and memory folder(s) left in /dev/shm by killed batches")
    return launcher, own


def run_batch(output: Path, jobs: list[Job], task: Callable, split: Callable[[Job, Any], list], *,
              fingerprint: str, finish: Callable[[dict], Any], check: Check | None = None, bar: Bar | None = None,
              backend: str = "loky", n_jobs: int = 2, scheduler: str | None = None, launcher: Launcher | None = None,
              serial_estimate: float | None = None, serial_below_s: float = 0.0, resume: bool = True,
              progress: bool = True, console=None, keep_parts: bool = False, log=None,
              what: str = "jobs") -> tuple[Any, BatchRun]:  # fmt: skip
    """Run the missing jobs of a batch on ``output`` (module docstring) and ``finish`` it.

    ``task(job.arg)`` is what a launcher runs; ``split(job, result) -> [(part key, frame,
    part metadata), ...]`` turns a job's result into its parts; ``finish(done)``
    (``done``: part key -> frame, every part) writes the caller's outputs under the lock and
    returns what :func:`run_batch` returns first.  ``check(frame, meta, expected)``: why a
    persisted part is stale, beyond its key and ``fingerprint``.  ``what``: the parts'
    name in the interruption message.  Raises :class:`BatchInterrupted` on Ctrl-C or
    :class:`Terminated`; InputError when another batch holds the output."""
    output = Path(output)
    notes: list[str] = []

    def note(line: str) -> None:
        notes.append(line)
        if log is not None:
            log(line)

    bar = bar or Bar()
    expected = {k: v for j in jobs for k, v in j.parts.items()}
    pdir = parts_dir(output)
    own = False
    try:
        with output_lock(output, bar.name):  # before any note or worker: a second batch on the output says only that
            launcher, own = open_launcher(backend, n_jobs, scheduler, launcher, serial_estimate, serial_below_s, note,
                                          f"the {len(expected)} {what}")  # fmt: skip
            done, report = scan_parts(pdir, expected, resume, fingerprint, check)
            if report.note():
                note(report.note())
            reused = list(done)
            todo = [j for j in jobs if not all(k in done for k in j.parts)]
            pdir.mkdir(parents=True, exist_ok=True)
            computed: list[str] = []
            counts = [bar.count(df) for df in done.values()]
            failed = sum(f for _, f in counts)
            total = bar.total if bar.total is not None else len(expected)
            groups = (len(jobs) - len(todo), len(jobs), bar.groups) if bar.groups else None
            meter = Progress(total, sum(n for n, _ in counts), failed, enabled=progress, console=console,
                             name=bar.name, unit=bar.unit, groups=groups, estimate_s=bar.estimate_s,
                             notice=bar.notice)  # fmt: skip

            def on_result(i: int, res) -> None:
                nonlocal failed
                n = 0
                for key, frame, meta in split(todo[i], res):
                    write_part(pdir, key, frame, fingerprint, meta)
                    done[key] = frame
                    computed.append(key)
                    items, bad = bar.count(frame)
                    n += items
                    failed += bad
                meter.advance(n, failed, 1)

            with meter:
                launcher.launch(task, [j.arg for j in todo], on_result)
            result = finish(done)
            kept = keep_parts or not remove_parts(pdir)
            if kept and not keep_parts:
                note(f"{pdir}/ holds other files; left in place")
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM/SIGHUP as Terminated
        signum = getattr(exc, "signum", signal.SIGINT)
        n = sum(1 for f in pdir.glob("*.parquet") if f.stem in expected) if pdir.is_dir() else 0
        raise BatchInterrupted(
            f"interrupted ({signal.Signals(signum).name}): {n} of {len(expected)} {what} are persisted "
            f"in {pdir}/; run the same command again to compute the rest",
            128 + int(signum),
        ) from None
    finally:
        if own:
            launcher.close()
    return result, BatchRun(done, computed, reused, notes, kept)
