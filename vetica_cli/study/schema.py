"""The study table: its columns and their units, built from the registries (surface
models for the estimates, extraction methods for the method column, the simulation's
observables), and the assembly of the persisted points into one table.

One row per (point, force source): ``method``, ``force_source``, each quantity the
surface model reports with ``_theory`` and ``_err_pct``, the relative 1-sigma of
its parameters (``_sigma_pct``), ``unidentified``, ``taps``, the run observables,
``stop_reason``, ``sim_time``, ``status``, ``error``, ``wall_s``.
"""

from __future__ import annotations

import pandas as pd

from .. import surfaces
from ..extraction import METHODS, SOURCES
from ..simulation.observables import OBSERVABLE_UNITS
from .grid import EXTRACT_KEYS, Study

# row status: ok = steady record, every reported quantity estimated; no_estimate = steady record, the
# extraction returned but some quantity has no value (the reason is in 'error'); not_steady = the record
# is not proven periodic (values, if any, are not trustworthy); failed = the simulation or extraction raised
STATUSES = ("ok", "no_estimate", "not_steady", "failed")
OBSERVABLES = tuple(OBSERVABLE_UNITS)


def point_sources(force: str = "both") -> tuple:
    """Force sources extracted for a point with ``extract.force = force``, in table order."""
    return SOURCES if force == "both" else (force,)


def sigma_names(model: surfaces.SurfaceModel) -> tuple[str, ...]:
    """The model's parameters among its quantities (in quantity order): the ``_sigma_pct``
    columns and those the ``unidentified`` column may name."""
    return tuple(q for q in model.quantities if q in model.parameter_keys)


def study_models(study: Study) -> list[surfaces.SurfaceModel]:
    """The surface models of a study's points, in registry order, each specialised to its
    points' parameters (a Wiechert study's number of arms), in order of first use."""
    used: dict = {}
    for p in study.points:
        m = p.config.surface.surface_model
        used.setdefault((p.config.surface.model, m.parameter_keys), m)
    order = list(surfaces.MODELS)
    return [m for (k, _), m in sorted(used.items(), key=lambda kv: order.index(kv[0][0]))]


def result_columns(models=None) -> list[str]:
    """Columns a job fills for each (point, force source), in table order, for points of the
    surface ``models`` (default: the default model)."""
    models = models or [surfaces.get(surfaces.DEFAULT_MODEL)]
    quantities = list(dict.fromkeys(q for m in models for q in m.quantities))
    sigmas = list(dict.fromkeys(q for m in models for q in sigma_names(m)))
    cols = ["method", "force_source"]
    for name in quantities:
        cols += [name, f"{name}_theory", f"{name}_err_pct"]
    cols += [f"{name}_sigma_pct" for name in sigmas]
    cols += ["unidentified", "taps", *OBSERVABLES, "stop_reason", "sim_time", "status", "error", "wall_s"]
    return cols


def column_units(study: Study) -> dict:
    """Unit (and meaning) of every column of the study's table, for its metadata."""
    units = {"point": "hash of the resolved point config (names its part file)"}
    for k in study.keys:
        if k not in EXTRACT_KEYS:
            units[k] = "swept key (SI, as in the config schema)"
    units["method"] = "extraction method (extract.method): " + " | ".join(
        f"{k} ({m.description})" for k, m in METHODS.items()
    )
    units["force_source"] = "true = simulator f_ts; reconstructed = spectral inversion of the paddle signal"
    models = study_models(study)
    for model in models:
        for name, q in model.quantities.items():
            units[name] = f"{q.unit}: estimate of the {q.description} by the row's extraction method"
            units[f"{name}_theory"] = f"{q.unit}: {model.theory_source}"
            units[f"{name}_err_pct"] = "%: 100 (estimate - theory) / theory, signed (tables before v0.2: its magnitude)"
        for name in sigma_names(model):
            units[f"{name}_sigma_pct"] = (
                "%: relative 1-sigma of the estimate (Jacobian) for methods that report one; NaN otherwise or unbounded"
            )
    units["unidentified"] = "fitted parameters the method flags not identifiable, comma-separated ('' = none)"
    units["taps"] = "complete taps in the record"
    for name in OBSERVABLES:
        units[name] = OBSERVABLE_UNITS.get(name, "")
    units["stop_reason"] = (
        "steady | steady (transient fallback) | max_time | max_time (orbit solver failed): steady = the recorded "
        "window is proven periodic"
    )
    units["sim_time"] = "s: simulated time to steady state plus the recorded periods (or numerics.max_time)"
    units["status"] = (
        "ok (steady record, every quantity estimated) | no_estimate (steady record, some quantity has no value; "
        "why: error) | not_steady (record not proven periodic: stop_reason max_time ...) | failed (see error)"
    )
    units["error"] = "error text of a failed simulation or extraction, or why a quantity has no estimate"
    units["wall_s"] = (
        "s: wall time of the point's simulation (shared by the points of a print-step group) plus this row's extraction"
    )
    return units


def assemble(study: Study, done: dict) -> pd.DataFrame:
    """The tidy table from the points' rows (``done``: point key -> frame): points in grid
    order, 'true' before 'reconstructed', the swept keys after the point key."""
    columns = result_columns(study_models(study))
    frames = []
    for p in study.points:
        df = done[p.key].reindex(columns=columns)
        lead = pd.DataFrame({"point": [p.key] * len(df)})
        for k in study.keys:
            if k not in EXTRACT_KEYS:  # extract.method is the 'method' column
                lead[k] = [p.values[k]] * len(df)
        frames.append(pd.concat([lead, df.reset_index(drop=True)], axis=1))
    table = pd.concat(frames, ignore_index=True)
    order = {s: i for i, s in enumerate(SOURCES)}
    idx = {p.key: p.index for p in study.points}
    table = (
        table.assign(_i=table["point"].map(idx), _s=table["force_source"].map(order))
        .sort_values(["_i", "_s"], kind="mergesort")
        .drop(columns=["_i", "_s"])
        .reset_index(drop=True)
    )
    table["error"] = table["error"].fillna("").astype(str)
    table["unidentified"] = table["unidentified"].fillna("").astype(str)
    table["method"] = table["method"].astype(str)
    table["stop_reason"] = table["stop_reason"].fillna("").astype(str)
    table["taps"] = table["taps"].astype("int64")
    return table
