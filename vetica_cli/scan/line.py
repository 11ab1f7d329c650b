"""One scan line as a job: drive the kernel along the line (:mod:`.pixel`) and extract every
pixel with every method, giving the line's rows of the scan table (:mod:`.table`).

:class:`LineTask` is what a launcher runs (:mod:`vetica_cli.batch.launch`): a module-level,
picklable callable; its extraction function is injected (``LineTask(extract=fake)``) as
the sweep's :class:`~vetica_cli.rows.task.PointTask`'s is, whose row building it reuses
(the estimates, their theory values and signed errors, the observables, ``status`` and
``error``; and whatever columns that row building grows).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

from ..simulation.config import Config
from ..rows.task import PointTask, extract_point, failed_rows
from .config import Pass, ScanConfig, build
from .pixel import LineDriver
from .sample import paint

Rows = list  # of dicts: the pixel columns (table.PIXEL_COLUMNS) then the sweep's result columns


@dataclass(frozen=True)
class LineItem:
    """The arguments of one line job (picklable, plain data)."""

    key: str  # names the line's part file (:func:`vetica_cli.scan.run.line_key`)
    config: dict  # the resolved scan config (ScanConfig.resolved)
    steady: str  # the pass
    pixel_time: float  # [s]; nan for an orbit pass
    iy: int  # line index (slow axis)
    zb_ref: float  # [m] zero of the measured topography (:func:`.pixel.reference_base`)


@dataclass
class LineResult:
    key: str
    rows: Rows
    wall_s: float
    pixels: int


def pixel_columns(cfg: ScanConfig, p: Pass, iy: int, ix: int, domain: int, height: float) -> dict:
    """The columns that place a row on the map (:data:`vetica_cli.scan.table.PIXEL_COLUMNS`)."""
    x, y = cfg.scan.raster.centres()
    return {"steady": p.steady, "pixel_time": p.pixel_time, "ix": ix, "iy": iy, "x": float(x[ix]),
            "y": float(y[iy]), "domain": domain, "height_true": height, "topography": math.nan}  # fmt: skip


@dataclass(frozen=True)
class LineTask:
    """Scan one line and extract its pixels (module docstring).  ``extract(df, meta, force,
    method) -> ExtractionResult`` defaults to the sweep's (:func:`vetica_cli.rows.task.extract_point`)."""

    extract: Callable = extract_point

    def __call__(self, item: LineItem) -> LineResult:
        t0 = time.perf_counter()
        cfg = build(item.config)
        p = Pass(item.steady, item.pixel_time)
        smap = paint(cfg.sample, cfg.scan.raster)
        configs = [cfg.material_config(s, p.steady) for s in smap.materials]
        rows: Rows = []
        try:
            self.scan_line(cfg, p, item.iy, smap, configs, item.zb_ref, rows)
        except Exception as exc:  # noqa: BLE001 - a broken line becomes failed rows, the others run on
            done = {r["ix"] for r in rows}
            rows += self.failed_pixels(cfg, p, item.iy, smap, configs, exc, done)
        return LineResult(item.key, rows, time.perf_counter() - t0, cfg.scan.raster.nx)

    def scan_line(self, cfg: ScanConfig, p: Pass, iy: int, smap, configs: list[Config], zb_ref: float,
                  rows: Rows) -> None:  # fmt: skip
        """Every pixel of line ``iy`` in scan order, each extracted by every method, appended to ``rows``."""
        driver = LineDriver(configs)
        line = smap.line(iy)
        period = 1.0 / cfg.point.probe.f1
        n_periods = round(p.pixel_time / period) if p.steady == "transient" else 0
        lead = n_periods if n_periods else configs[0].numerics.settle_cycles
        m0, h0 = line[0]
        driver.start(m0, h0, lead)
        task = PointTask(extract=self.extract)
        for ix, (m, h) in enumerate(line):
            rec = driver.transient(m, h, n_periods) if p.steady == "transient" else driver.orbit(m, h)
            run = driver.to_run(m, rec, configs[m])
            place = pixel_columns(cfg, p, iy, ix, int(smap.domain[iy, ix]), h)
            place["topography"] = rec.base - zb_ref
            for method in cfg.scan.methods:
                for row in task.rows_for_run(configs[m], run, rec.wall_s, method, cfg.force):
                    rows.append({**place, **row})

    def failed_pixels(self, cfg, p, iy, smap, configs, exc, done: set) -> Rows:
        """Rows with status 'failed' for the pixels of a line that broke, from the first not done."""
        rows = []
        for ix in range(cfg.scan.raster.nx):
            if ix in done:
                continue
            m = int(smap.material[iy, ix])
            place = pixel_columns(cfg, p, iy, ix, int(smap.domain[iy, ix]), float(smap.height[iy, ix]))
            for method in cfg.scan.methods:
                for row in failed_rows(configs[m], exc, f"line {iy}", 0.0, method, cfg.force):
                    rows.append({**place, **row})
        return rows
