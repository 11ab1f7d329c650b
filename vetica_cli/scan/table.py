"""The scan table: one row per pixel, method and force source, tidy.

Columns: the pixel's place and truth (:data:`PIXEL_COLUMNS`), then the columns of a
batch row (:func:`vetica_cli.rows.schema.result_columns`: ``method``,
``force_source``, every quantity of the surface model with ``_theory`` and
``_err_pct`` (signed), the 1-sigma and flag (``unidentified``) of every quantity, ``taps``,
the run observables -- ``amplitude``, ``phase_deg``, ``e_diss_ev``, ``peak_force``,
``max_penetration``, ... --, ``stop_reason``, ``sim_time``, ``status``, ``error``,
``wall_s``).  The units and meanings go into the Parquet metadata (:func:`column_meta_of`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .. import surfaces
from ..rows.schema import column_meta, result_columns, split_unit, units_metadata
from .config import ScanConfig

if TYPE_CHECKING:  # pandas is imported where the table is assembled: a dry run starts without it
    import pandas as pd

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


def column_meta_of(cfg: ScanConfig) -> dict:
    """``column -> (unit, description)``: the pixel columns', then the batch rows' for the
    sample's surfaces (:func:`vetica_cli.rows.schema.column_meta`), worded for a scan."""
    meta = {c: split_unit(text) for c, text in PIXEL_UNITS.items()}
    meta.update(column_meta(scan_models(cfg), cfg.scan.methods))
    meta["stop_reason"] = ("", STOP_REASONS)
    meta["status"] = ("", "ok (extracted; record proven periodic) | not_steady (extracted; record not proven "
                      "periodic) | failed (see error)")  # fmt: skip
    meta["sim_time"] = ("s", "simulated time since the line's start at the end of the pixel's record")
    meta["wall_s"] = ("s", "wall time of the pixel's simulation plus this row's extraction")
    return meta


def column_units(cfg: ScanConfig) -> dict:
    """``{'units': ..., 'descriptions': ...}`` of the table's columns (:func:`column_meta_of`)."""
    return units_metadata(column_meta_of(cfg))


def assemble(cfg: ScanConfig, frames: list[pd.DataFrame]) -> pd.DataFrame:
    """One table from the lines' rows (``frames`` in pass order, then line order): typed columns,
    rows by pass, line, pixel along x, then method and force source as the lines wrote them."""
    import pandas as pd

    cols = columns(cfg)
    table = pd.concat([f.reindex(columns=cols) for f in frames], ignore_index=True)
    for c in ("ix", "iy", "domain", "taps"):
        table[c] = table[c].astype("int64")
    for c in ("steady", "method", "force_source", "stop_reason", "status", "error", "unidentified"):
        table[c] = table[c].fillna("").astype(str)
    return table
