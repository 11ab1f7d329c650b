"""The scan table: one row per pixel, method and force source, tidy.

Columns: the pixel's place and truth (:data:`PIXEL_COLUMNS`), then the columns of a
sweep row (:func:`vetica_cli.study.schema.result_columns`: ``method``,
``force_source``, every quantity of the surface model with ``_theory`` and
``_err_pct`` (signed), the 1-sigma of fitted parameters, ``unidentified``, ``taps``,
the run observables -- ``amplitude``, ``phase_deg``, ``e_diss_ev``, ``peak_force``,
``max_penetration``, ... --, ``stop_reason``, ``sim_time``, ``status``, ``error``,
``wall_s``).  The units go into the Parquet metadata (:func:`column_units`).
"""

from __future__ import annotations

import pandas as pd

from .. import surfaces
from ..study.grid import Point, Study
from ..study.schema import column_units as study_units
from ..study.schema import result_columns
from .config import ScanConfig

PIXEL_COLUMNS = ("steady", "pixel_time", "ix", "iy", "x", "y", "domain", "height_true", "topography")
PIXEL_UNITS = {
    "steady": "the pass: transient (the last record_cycles periods of pixel_time) | orbit (the pixel's periodic orbit)",
    "pixel_time": "s: time the tip taps each pixel (scan.pixel_time, whole drive periods); NaN for an orbit pass",
    "ix": "pixel index along x, the fast axis (scan order)",
    "iy": "line index along y, the slow axis",
    "x": "m: pixel centre, fast axis",
    "y": "m: pixel centre, slow axis",
    "domain": "0 = background, k = feature k of sample.features (the one covering the pixel centre)",
    "height_true": "m: true height of the pixel's surface",
    "topography": "m: measured height, B - Zb_ref: the absolute base height B the controller holds during the "
    "pixel's recorded periods minus Zb_ref (metadata 'zb_ref'), the base height of the background's periodic "
    "orbit, so a settled background pixel reads its true height",
}
STOP_REASONS = ("steady = the recorded periods are proven periodic; pixel_time = a transient pixel whose record is "
                "not (what the instrument records in pixel_time); orbit passes: steady (transient fallback) | "
                "max_time (orbit solver failed)")  # fmt: skip


def scan_models(cfg: ScanConfig) -> list[surfaces.SurfaceModel]:
    """The surface models of the sample's surfaces, in registry order."""
    used = {s.get("model", surfaces.DEFAULT_MODEL) for s in cfg.sample.surfaces()}
    return [m for k, m in surfaces.MODELS.items() if k in used]


def columns(cfg: ScanConfig) -> list[str]:
    """The table's columns in order."""
    return list(PIXEL_COLUMNS) + result_columns(scan_models(cfg), cfg.scan.methods)


def column_units(cfg: ScanConfig) -> dict:
    """Unit (and meaning) of every column: the pixel columns', then the sweep table's for the
    sample's surfaces (:func:`vetica_cli.study.schema.column_units`), worded for a scan."""
    points = tuple(Point(index=i, values={}, config=cfg.material_config(s, "orbit"), key="")
                   for i, s in enumerate(cfg.sample.surfaces()))  # fmt: skip
    units = dict(PIXEL_UNITS)
    units.update(study_units(Study(name=cfg.name, description="", keys=(), points=points, base={}, sweep={})))
    units.pop("point", None)
    units["stop_reason"] = STOP_REASONS
    units["status"] = (
        "ok (extracted; record proven periodic) | not_steady (extracted; record not proven periodic) | failed (see error)"
    )
    units["sim_time"] = "s: simulated time since the line's start at the end of the pixel's record"
    units["wall_s"] = "s: wall time of the pixel's simulation plus this row's extraction"
    return units


def assemble(cfg: ScanConfig, frames: list[pd.DataFrame]) -> pd.DataFrame:
    """One table from the lines' rows (``frames`` in pass order, then line order): typed columns,
    rows by pass, line, pixel along x, then method and force source as the lines wrote them."""
    cols = columns(cfg)
    table = pd.concat([f.reindex(columns=cols) for f in frames], ignore_index=True)
    for c in ("ix", "iy", "domain", "taps"):
        table[c] = table[c].astype("int64")
    for c in ("steady", "method", "force_source", "stop_reason", "status", "error", "unidentified"):
        table[c] = table[c].fillna("").astype(str)
    return table
