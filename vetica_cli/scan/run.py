"""``vetica scan CONFIG``: plan the lines, run the missing ones, write the table.

The path of a scan, one way through:

1. the config is validated (:mod:`.config`) and the sample painted on the raster
   (:mod:`.sample`);
2. the zero of the measured topography is the base height of the background's own
   periodic orbit (:func:`.pixel.reference_base`, one solve in this process);
3. every line of every pass is a job (:class:`.line.LineItem`) named by a hash of what
   it computes (:func:`line_key`);
4. the batch layer (:func:`vetica_cli.batch.run.run_batch`, as a sweep's) checks every
   output path first, locks the output, reuses the lines persisted in ``<output>.parts/``
   by an earlier run with the same code (a killed scan resumes by line), runs the task
   (:class:`.line.LineTask`, passed in) over the missing lines on a launcher (serial,
   loky, dask), writes each finished line at once as a part, and handles Ctrl-C,
   SIGTERM and SIGHUP as a sweep does;
5. the table (:mod:`.table`) is written atomically with the units, the resolved config,
   the sample's geometry and the topography's zero in its metadata, the config as
   ``<output stem>.config.yaml`` and the measures (:mod:`.analysis`) as
   ``<output stem>.summary.md``; the parts folder is then removed.

Without ``-o`` the table goes to the git-ignored ``sweeps/`` folder, never over a
committed table.
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from .. import __version__
from ..batch.launch import Launcher, check_launcher_options
from ..batch.parts import code_fingerprint, parts_dir
from ..batch.run import Bar, BatchInterrupted, Job, check_batch_output, default_output, run_batch, sidecar
from ..batch.run import signals_as_interrupt
from ..checks import confirm_cost
from ..io import write_table, write_text
from ..rows.schema import STATUSES
from ..simulation.jit import compile_notice, simulation_modules
from ..batch.progress import duration
from ..extraction import extraction_modules
from ..extraction import get as get_method
from ..extraction.base import record_cost_scale
from .config import ScanConfig, dump, load_scan
from .sample import paint, surface_key
from .table import assemble, column_units, columns

if TYPE_CHECKING:  # pandas and the lines' simulation (numba) are imported by the scan itself: a dry run starts without them
    import pandas as pd

    from .line import LineItem, LineTask

SCAN_ROOTS = ("scan/line.py", "scan/table.py")  # the code that computes a line's rows (its import closure)
# The dry run's costs, measured on the committed scans (results/scans: blend 64 x 64 and edge, 2 workers on
# 2 cores, PS 1 ns, 4 periods, vetica + full; per-row wall_s = the pixel's simulation + that row's extraction):
# a drive period of a transient pixel 0.65 ms (the rows' median wall between the 0.5 and 2 ms passes; 1.3 ms
# two versions before); the orbit pass as ~20 such periods; a pixel's record and both extractions 0.070 s
# (0.12 s before), which with the period's cost puts the blend map at 632 s against 632.5 measured and the
# edge at 24 s against 22.8; a scan's start-up (process, workers, kernels, summary, figures) 6.7-8.4 s for a
# 2-pixel scan.
SECONDS_PER_PERIOD = 0.65e-3
ORBIT_PERIODS = 20
SCAN_START_S = 7.0
# a pixel's record (observables, table, force) at the methods' reference size, 10 periods at 0.125 ns, one
# force source; a record costs in proportion to its samples, as each method's seconds_per_point / 2, plus a
# fixed part smaller than a sweep point's (no task or part file of its own).  Re-measured on the committed blend
# map of 2026-11-28 (928.8 s alone, where the constants of the version before, 0.003 and a 0.070 s pixel record,
# estimated 630 s: the fit's band term, referee and checks had grown the part that does not grow with the record):
# its rows' medians (VETICA and the fit, each with the pixel's simulation) give a drive period 0.61 ms and a pixel's
# record with both extractions 0.105 s (the orbit pass) to 0.136 s (the transient passes); 0.039 puts it at 0.115 s
SECONDS_PER_RECORD = 0.2
PIXEL_FIXED_COST = 0.039


@dataclass
class ScanResult:
    table: pd.DataFrame
    meta: dict
    output: Path
    config_path: Path
    summary_path: Path
    computed: list = field(default_factory=list)  # line keys computed in this call
    reused: list = field(default_factory=list)  # line keys read from parts
    wall_s: float = 0.0
    parts_kept: bool = False
    notes: list = field(default_factory=list)


def line_key(cfg: ScanConfig, smap, steady: str, pixel_time: float, iy: int, zb_ref: float) -> str:
    """16-hex hash of everything a line's rows depend on: the point config, the pass, the
    methods and force, the line's pixels (surface, height, domain, place), the topography's
    zero and the package version (so adding a pixel time or a line keeps the others' parts)."""
    x, y = cfg.scan.raster.centres()
    point = cfg.point.to_dict()
    point["numerics"].pop("steady")
    pixels = [[surface_key(smap.materials[int(m)]), float(h), int(d)]
              for m, h, d in zip(smap.material[iy], smap.height[iy], smap.domain[iy])]  # fmt: skip
    blob = {"version": __version__, "point": point, "steady": steady,
            "pixel_time": None if math.isnan(pixel_time) else pixel_time, "methods": list(cfg.scan.methods),
            "force": cfg.force, "x": [float(v) for v in x], "y": float(y[iy]), "pixels": pixels, "zb_ref": zb_ref}  # fmt: skip
    return hashlib.sha256(json.dumps(blob, sort_keys=True).encode()).hexdigest()[:16]


def _items(cfg: ScanConfig, smap, zb_ref: float) -> list[LineItem]:
    from .line import LineItem

    return [LineItem(line_key(cfg, smap, p.steady, p.pixel_time, iy, zb_ref), cfg.resolved, p.steady, p.pixel_time,
                     iy, zb_ref)
            for p in cfg.scan.passes() for iy in range(cfg.scan.raster.ny)]  # fmt: skip


def failed_pixels(df: pd.DataFrame) -> int:
    """Pixels of a line with a failed row."""
    return int(df.loc[df["status"] == "failed", "ix"].nunique()) if len(df) else 0


SIDECARS = (".config.yaml", ".summary.md")  # written beside the table


def check_scan_output(output: str | Path) -> Path:
    """Every path a scan on ``output`` writes, checked before any work (InputError, one line)."""
    return check_batch_output(output, SIDECARS)


def run_scan(cfg: ScanConfig, output: str | Path, jobs: int = 2, backend: str = "loky", scheduler: str | None = None,
             resume: bool = True, progress: bool = True, console=None, task: LineTask | None = None,
             launcher: Launcher | None = None, keep_parts: bool = False, log=None,
             notice: str | None = None) -> ScanResult:  # fmt: skip
    """Scan every missing line of ``cfg`` (module docstring), then write the table.

    ``task``: the job function (default :class:`.line.LineTask`: the real simulation and
    extraction); ``launcher``: where (default from ``backend``, ``jobs``, ``scheduler``;
    a given launcher is not closed here); ``keep_parts`` keeps ``<output>.parts/`` after
    success; ``log(line)`` receives notes.  Raises :class:`ScanInterrupted` on Ctrl-C,
    SIGTERM or SIGHUP (under :func:`vetica_cli.batch.run.signals_as_interrupt`)."""
    from .analysis import summary_markdown
    from .line import LineTask
    from .pixel import reference_base

    t_start = time.perf_counter()
    output = check_scan_output(output)
    smap = paint(cfg.sample, cfg.scan.raster)
    zb_ref, zb_stop = reference_base(cfg.material_config(cfg.sample.background, "orbit"))
    items = _items(cfg, smap, zb_ref)
    nx = cfg.scan.raster.nx
    fp = code_fingerprint(SCAN_ROOTS)

    def split(job: Job, res) -> list:
        import pandas as pd

        it = job.arg
        meta = {"iy": it.iy, "steady": it.steady, "pixel_time": None if math.isnan(it.pixel_time) else it.pixel_time,
                "wall_s": res.wall_s}  # fmt: skip
        return [(it.key, pd.DataFrame(res.rows), meta)]

    def finish(done: dict) -> ScanResult:
        table = assemble(cfg, [done[it.key] for it in items])
        meta = scan_meta(cfg, smap, zb_ref, zb_stop)
        meta["wall_s"] = time.perf_counter() - t_start
        meta["lines"] = {"total": len(items)}
        write_table(table, output, meta)
        config_path = sidecar(output, ".config.yaml")
        write_text(config_path, dump(cfg))
        summary_path = sidecar(output, ".summary.md")
        write_text(summary_path, f"# {cfg.name}: scan summary\n\n" + summary_markdown(table, meta) + "\n")
        return ScanResult(table, meta, output, config_path, summary_path)

    jobs_ = [Job(it, {it.key: it}) for it in items]
    bar = Bar(name="scan", unit="pixels", count=lambda df: (nx, failed_pixels(df)), groups="lines",
              total=len(items) * nx, estimate_s=scan_seconds(cfg) / max(1, jobs), notice=notice)  # fmt: skip
    res, run = run_batch(output, jobs_, task or LineTask(), split, fingerprint=fp, finish=finish, bar=bar,
                         backend=backend, n_jobs=jobs, scheduler=scheduler, launcher=launcher, resume=resume,
                         progress=progress, console=console, keep_parts=keep_parts, log=log, what="lines")  # fmt: skip
    res.computed, res.reused, res.wall_s = run.computed, run.reused, time.perf_counter() - t_start
    res.meta["lines"].update(computed=len(run.computed), reused=len(run.reused))
    res.parts_kept, res.notes = run.parts_kept, run.notes
    return res


def scan_meta(cfg: ScanConfig, smap, zb_ref: float, zb_stop: str) -> dict:
    """The table's metadata: kind, geometry of the sample, passes, units, resolved config."""
    r = cfg.scan.raster
    return {
        "table": "scan",
        "scan": {
            "name": cfg.name,
            "description": cfg.description,
            "pixels": [r.nx, r.ny],
            "size": [r.size_x, r.size_y],
            "pitch": list(r.pitch),
            "passes": [
                {
                    "steady": p.steady,
                    "pixel_time": None if math.isnan(p.pixel_time) else p.pixel_time,
                    "label": p.label(),
                }
                for p in cfg.scan.passes()
            ],
            "methods": list(cfg.scan.methods),
            "force": cfg.force,
            "domains": cfg.sample.domain_names(),
            "domain_pixels": smap.covered,
            "background": {"height": cfg.sample.height, "surface": cfg.sample.background},
            "features": [f.to_dict() for f in cfg.sample.features],
            "zb_ref": zb_ref,
            "zb_ref_stop_reason": zb_stop,
        },
        "config": cfg.resolved,
        **column_units(cfg),
        "columns": columns(cfg),
        "version": __version__,
        "code": code_fingerprint(SCAN_ROOTS),
    }


def summary(res: ScanResult) -> str:
    """What the scan did, and its measures."""
    from .analysis import summary_markdown

    t = res.table
    px = t.drop_duplicates(subset=["steady", "pixel_time", "iy", "ix"])
    by_status = t["status"].value_counts().to_dict()
    lines = [
        f"{res.meta['lines']['total']} lines ({len(res.computed)} computed, {len(res.reused)} reused from "
        f"{parts_dir(res.output).name}/), {len(px)} pixels, {len(t)} rows: "
        + ", ".join(f"{by_status.get(s, 0)} {s}" for s in STATUSES),
        summary_markdown(t, res.meta),
        f"wrote {res.output}, {res.config_path.name} and {res.summary_path.name} in {res.wall_s:.1f} s",
    ]
    return "\n".join(lines)


def dry_run_text(cfg: ScanConfig, output: Path, jobs: int) -> str:
    """Lines, pixels, domains and a cost estimate; runs nothing."""
    r = cfg.scan.raster
    smap = paint(cfg.sample, r)
    head = (f"scan {cfg.name}: {r.nx} x {r.ny} pixels over {r.size_x * 1e6:g} x {r.size_y * 1e6:g} um "
            f"(pitch {r.pitch[0] * 1e9:.4g} x {r.pitch[1] * 1e9:.4g} nm), methods {', '.join(cfg.scan.methods)}, "
            f"force {cfg.force}")  # fmt: skip
    lines = [head]
    for name, n in zip(cfg.sample.domain_names(), smap.covered):
        lines.append(f"  {name}: {n} pixels" + ("  (covers no pixel centre)" if n == 0 else ""))
    n = cfg.point.numerics
    per_record = pixel_record_seconds(cfg)
    for p in cfg.scan.passes():
        lines.append(f"  pass {p.label()}: {r.ny} lines, ~{pass_pixel_seconds(cfg, p):.2f} s a pixel")
    lines.append(f"~{duration(SCAN_START_S + scan_seconds(cfg) / jobs)} on {jobs} worker(s) (measured costs: "
                 f"{SECONDS_PER_PERIOD * 1e3:g} ms a drive period, {per_record:.3g} s a pixel's record and its "
                 f"extraction at PS {n.print_step * 1e9:g} ns and {n.record_cycles} periods, "
                 f"{SCAN_START_S:g} s to start); would write {output}")  # fmt: skip
    return "\n".join(lines)


ScanInterrupted = BatchInterrupted  # Ctrl-C, SIGTERM or SIGHUP during a scan (message and exit code)
DEFAULT_FOLDER = Path("sweeps")  # where `vetica scan CONFIG` writes without -o (git-ignored, as a sweep)


def pixel_record_seconds(cfg: ScanConfig) -> float:
    """Estimated core-seconds of one pixel's record and its extractions (every method)."""
    n = cfg.point.numerics
    scale = record_cost_scale(n.record_cycles, n.print_step, PIXEL_FIXED_COST)
    return scale * (SECONDS_PER_RECORD + sum(get_method(m).seconds_per_point / 2 for m in cfg.scan.methods))


def pass_pixel_seconds(cfg: ScanConfig, p) -> float:
    """Estimated core-seconds of one pixel of pass ``p``: its drive periods and its record."""
    periods = round(p.pixel_time * cfg.point.probe.f1) if p.steady == "transient" else ORBIT_PERIODS
    return periods * SECONDS_PER_PERIOD + pixel_record_seconds(cfg)


def scan_seconds(cfg: ScanConfig) -> float:
    """Estimated core-seconds of the whole scan's pixels (the dry run's measured costs)."""
    r = cfg.scan.raster
    return sum(pass_pixel_seconds(cfg, p) for p in cfg.scan.passes()) * r.nx * r.ny


def scan_modules(cfg: ScanConfig) -> set[str]:
    """The cached core modules a scan compiles: its surfaces' simulations and its methods."""
    mods = extraction_modules(cfg.scan.methods, ("true", "reconstructed") if cfg.force == "both" else (cfg.force,))
    for surface in [cfg.sample.background, *(f.surface for f in cfg.sample.features)]:
        for steady in cfg.scan.steady:
            mods |= simulation_modules(cfg.material_config(surface, steady))
    return mods


def scan_command(config: str | Path, output: str | Path | None = None, overrides: dict | None = None,
                 dry_run: bool = False, jobs: int = 2, log=None, yes: bool = False, **run_kw) -> str:  # fmt: skip
    """``vetica scan CONFIG``: load the scan (``overrides`` as dotted keys) and check every
    output path, then print its plan and cost (``dry_run``) or run it (:func:`run_scan`
    keywords in ``run_kw``).  The table goes to ``output`` (default
    ``sweeps/<config stem>.parquet``, git-ignored).  Raises :class:`ScanInterrupted` on
    Ctrl-C, SIGTERM or SIGHUP.  A scan estimated over the threshold every command shares
    (:func:`vetica_cli.checks.confirm_cost`) needs ``yes``."""
    cfg = load_scan(config, overrides)
    out = check_scan_output(Path(output) if output is not None else default_output(config, DEFAULT_FOLDER))
    check_launcher_options(run_kw.get("backend", "loky"), jobs, run_kw.get("scheduler"))
    if dry_run:
        return dry_run_text(cfg, out, jobs)
    r, passes = cfg.scan.raster, len(cfg.scan.passes())
    confirm_cost(f"this scan ({r.nx} x {r.ny} pixels, {passes} pass{'es' if passes > 1 else ''}, {jobs} worker(s))",
                 SCAN_START_S + scan_seconds(cfg) / jobs, yes, r.nx * r.ny * passes, "pixel records")  # fmt: skip
    with signals_as_interrupt():
        res = run_scan(cfg, out, jobs=jobs, log=log, notice=compile_notice(scan_modules(cfg)), **run_kw)
    return summary(res)
