"""Parametric sweeps: ``run_sweep(study, output)`` (``vetica sweep CONFIG``).

One *point* of a study (:mod:`.grid`) is simulated once and then extracted with
the simulator's true force and with the force reconstructed from the paddle
signal (SPEC 6-7; ``extract.force`` restricts this), by the point's
``extract.method`` (a registered method of :mod:`vetica_cli.extraction`),
giving one row per force source of a tidy table (:mod:`.schema`).  The path of
a study, one way through:

1. :func:`.plan.plan` groups the points into tasks that share one simulation;
2. :mod:`.store` gives back the points persisted by an earlier run (resume);
3. a :mod:`.launch` launcher runs the task function (:class:`.task.PointTask`,
   passed in) over the missing tasks, serially, on loky workers or on Dask;
4. each finished point is written at once to ``<output>.parts/`` (:mod:`.store`);
5. :func:`.schema.assemble` builds the table, :mod:`.acceptance` its acceptance
   regime, and the table is written atomically with the units, the resolved
   study config and the regime in its metadata; the config is also saved as
   ``<output stem>.config.yaml``.

Nothing is lost: a point whose simulation or extraction raises becomes a row
with ``status = 'failed'`` and the error text (the simulation's columns are
kept when only the extraction failed); the other points run on, and a killed
sweep run again computes only the missing points.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd
import yaml

from .. import __version__
from ..errors import InputError
from ..io import write_table, write_text
from .acceptance import ACCEPT_ERR_PCT, acceptance_regime, format_acceptance
from .cost import dry_run_text
from .grid import Study, load_study
from .launch import Launcher, make_launcher
from .plan import Task, plan
from .progress import Progress
from .schema import STATUSES, assemble, column_units, material_metadata
from .store import code_fingerprint, part_path, parts_dir, read_part, rows_frame, write_part
from .task import PointTask


@dataclass
class SweepResult:
    table: pd.DataFrame
    output: Path
    config_path: Path
    computed: list = field(default_factory=list)  # point keys computed in this call
    reused: list = field(default_factory=list)  # point keys taken from persisted parts
    acceptance: list = field(default_factory=list)
    wall_s: float = 0.0


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
) -> SweepResult:
    """Run every missing point of ``study``, then assemble and write the table.

    ``task``: the function each task runs (default :class:`.task.PointTask`: the real
    simulation and extraction); ``launcher``: where (default from ``backend``,
    ``jobs`` and ``scheduler``, :func:`.launch.make_launcher`; a given launcher is
    not closed here).
    """
    t_start = time.perf_counter()
    output = Path(output)
    if output.suffix.lower() != ".parquet":
        raise InputError(f"-o {str(output)!r}: the table is written as Parquet; expected a .parquet path")
    own = launcher is None
    launcher = make_launcher(backend, jobs, scheduler) if own else launcher
    try:
        done, computed, reused = _run_tasks(study, output, launcher, task or PointTask(), resume, progress, console)
    finally:
        if own:
            launcher.close()
    res = _write_table(study, output, done)
    res.computed, res.reused, res.wall_s = computed, reused, time.perf_counter() - t_start
    return res


def _resumed(tasks: list[Task], pdir: Path, resume: bool) -> tuple[dict, list[Task]]:
    """The points persisted by an earlier run (key -> rows) and the tasks still to run."""
    done: dict[str, pd.DataFrame] = {}
    todo = []
    for t in tasks:
        if resume:
            got = {p.key: read_part(part_path(pdir, p.key), p, t.sim_print_step) for p in t.points}
            done.update({k: df for k, df in got.items() if df is not None})
            if all(df is not None for df in got.values()):
                continue
        todo.append(t)
    return done, todo


def _run_tasks(study, output, launcher, task, resume, progress, console):
    """Run the missing tasks, persisting each point as it finishes.  Returns
    ``(done: point key -> rows frame, keys computed now, keys read from parts)``."""
    pdir = parts_dir(output)
    done, todo = _resumed(plan(study), pdir, resume)
    reused = list(done)
    pdir.mkdir(parents=True, exist_ok=True)
    for stale in pdir.glob(".*.tmp"):  # temporaries of a killed write
        stale.unlink(missing_ok=True)
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
    config_path = output.with_name(output.stem + ".config.yaml")
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
    lines = [
        f"{len(study.points)} points ({len(res.computed)} computed, {len(res.reused)} reused from "
        f"{parts_dir(res.output).name}/), {len(t)} rows: " + ", ".join(f"{by_status.get(s, 0)} {s}" for s in STATUSES),
        format_acceptance(res.acceptance, study.keys),
        f"wrote {res.output} and {res.config_path} in {res.wall_s:.1f} s",
    ]
    return "\n".join(lines)


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C during a sweep; the message says what is persisted and how to go on."""


def sweep_command(
    config: str | Path,
    output: str | Path | None = None,
    overrides: dict | None = None,
    dry_run: bool = False,
    jobs: int = 2,
    **run_kw,
) -> str:
    """``vetica sweep CONFIG``: load the study (``overrides`` on its base), then print its
    points and cost (``dry_run``) or run it (:func:`run_sweep` keywords in ``run_kw``).
    Returns the text to print; the table goes to ``output`` (default
    ``results/<config stem>.parquet``).  Raises :class:`SweepInterrupted` on Ctrl-C."""
    study = load_study(config, overrides)
    out = Path(output) if output is not None else Path("results") / f"{Path(config).stem}.parquet"
    if dry_run:
        return dry_run_text(study, out, jobs)
    try:
        res = run_sweep(study, out, jobs=jobs, **run_kw)
    except KeyboardInterrupt:
        n = len(list(parts_dir(out).glob("*.parquet")))
        raise SweepInterrupted(
            f"interrupted: {n} of {len(study.points)} points are persisted in {parts_dir(out)}/; "
            "run the same command again to compute the rest"
        ) from None
    return summary(res, study)
