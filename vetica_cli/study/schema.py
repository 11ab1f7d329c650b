"""The study table: its columns and their units, built from the registries (surface
models for the estimates, extraction methods for the method column, the simulation's
observables), and the assembly of the persisted points into one table.

One row per (point, force source): ``method``, ``force_source``, each quantity the
surface model reports with ``_theory`` and ``_err_pct``, the relative 1-sigma of
its parameters (``_sigma_pct``), ``unidentified``, ``taps``, the run observables,
the record's peak force and penetration below Z1 (``tap_peak_force``,
``tap_depth``), the material units computed from them when the table is assembled
(:func:`material_columns`: ``E_dmt``, ``E_glassy``, ``E_rubbery``, ``viscosity``, the
last three also as ``_theory``; thesis 4.6.2, eqs. 90-92, with the study's contact
model), ``stop_reason``, ``sim_time``, ``status``, ``error``, ``wall_s``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .. import surfaces
from ..extraction import METHODS, SOURCES
from ..extraction.material import CONTACT_UNITS, MATERIAL_UNITS, contact_metadata, contact_model, moduli
from ..simulation.observables import OBSERVABLE_UNITS
from .grid import EXTRACT_KEYS, Study

# row status: ok = steady record, every reported quantity estimated; no_estimate = steady record, the
# extraction returned but some quantity has no value (the reason is in 'error'); not_steady = the record
# is not proven periodic (values, if any, are not trustworthy); failed = the simulation or extraction raised
STATUSES = ("ok", "no_estimate", "not_steady", "failed")
OBSERVABLES = tuple(OBSERVABLE_UNITS)
# column -> entry of the extraction's material object: the record's contact, the material columns' inputs
MATERIAL_INPUTS = {"tap_peak_force": "peak_force", "tap_depth": "penetration"}
# material columns computed when the table is assembled (the moduli from Kg, Kr also from their theory values)
MATERIAL_COLUMNS = ("E_dmt", "E_glassy", "E_glassy_theory", "E_rubbery", "E_rubbery_theory", "viscosity",
                    "viscosity_theory")  # fmt: skip


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


def study_methods(study: Study) -> list[str]:
    """The extraction methods of a study's points, in order of first use."""
    return list(dict.fromkeys(p.method for p in study.points))


def method_quantities(models, methods) -> tuple[list[str], list[str]]:
    """``(estimates, references)``: the quantities the ``methods`` (keys) report for points of
    the surface ``models`` beyond the models' own (e.g. ``tan_delta_am`` of ``observables``),
    and their theory-only references (``<name>_theory`` columns), in order of first use."""
    own = {q for m in models for q in m.quantities}
    est, refs = {}, {}
    for key in methods or ():
        for m in models:
            est.update(dict.fromkeys(q for q in METHODS[key].quantities(m) if q not in own))
            refs.update(dict.fromkeys(METHODS[key].references(m)))
    return list(est), [r for r in refs if r not in est and r not in own]


def result_columns(models=None, methods=None) -> list[str]:
    """Columns a job fills for each (point, force source), in table order, for points of the
    surface ``models`` (default: the default model) extracted by ``methods`` (keys; their own
    quantities and references after the models')."""
    models = models or [surfaces.get(surfaces.DEFAULT_MODEL)]
    extra, refs = method_quantities(models, methods)
    quantities = list(dict.fromkeys([*(q for m in models for q in m.quantities), *extra]))
    sigmas = list(dict.fromkeys(q for m in models for q in sigma_names(m)))
    cols = ["method", "force_source"]
    for name in quantities:
        cols += [name, f"{name}_theory", f"{name}_err_pct"]
    cols += [f"{name}_theory" for name in refs]
    cols += [f"{name}_sigma_pct" for name in sigmas]
    cols += ["unidentified", "taps", *OBSERVABLES, *MATERIAL_INPUTS, "stop_reason", "sim_time", "status", "error",
             "wall_s"]  # fmt: skip
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
        for key in study_methods(study):
            meth = METHODS[key]
            for name, q in {**meth.quantities(model), **meth.references(model)}.items():
                if name in model.quantities:
                    continue
                unit = q.unit or "1"
                if name in meth.quantities(model):
                    units[name] = f"{unit}: {q.description} ({key})"
                    units[f"{name}_err_pct"] = "%: 100 (estimate - theory) / theory, signed"
                    units[f"{name}_theory"] = f"{unit}: " + getattr(meth, "theory_sources", {}).get(name, "theory value")
                else:
                    units[f"{name}_theory"] = f"{unit}: the surface's {q.description} (SPEC 14; theory only)"
        for name in sigma_names(model):
            units[f"{name}_sigma_pct"] = (
                "%: relative 1-sigma of the estimate (Jacobian) for methods that report one; NaN otherwise or unbounded"
            )
    units["unidentified"] = "fitted parameters the method flags not identifiable, comma-separated ('' = none)"
    units["taps"] = "complete taps in the record"
    for name in OBSERVABLES:
        units[name] = OBSERVABLE_UNITS.get(name, "")
    for col, entry in MATERIAL_INPUTS.items():
        unit, desc = CONTACT_UNITS[entry]
        units[col] = f"{unit}: the record's {desc}, as the row's extraction saw it"
    for col in MATERIAL_COLUMNS:
        name = col.removesuffix("_theory")
        unit, desc = MATERIAL_UNITS[name]
        src = "the theory values of" if col.endswith("_theory") else "the row's estimates of"
        needs = {"E_dmt": "", "E_glassy": f", tap_depth and {src} Kg", "E_rubbery": f", tap_depth and {src} Kr",
                 "viscosity": f", tap_depth and {src} tau_r"}[name]  # fmt: skip
        units[col] = (
            f"{unit}: {desc}; from tap_peak_force{needs or ' and tap_depth'} (contact model: metadata 'material')"
        )
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
    columns = result_columns(study_models(study), study_methods(study))
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
    return material_columns(table, study)


def point_contact(study: Study) -> dict:
    """Point key -> the contact model of its material columns: the study's ``material:``
    section over thesis table 6, the tip radius defaulting to the point's probe."""
    over = study.material or {}
    return {p.key: contact_model(over, p.config.probe.tip_radius, where="material") for p in study.points}


def material_columns(table: pd.DataFrame, study: Study) -> pd.DataFrame:
    """The table with :data:`MATERIAL_COLUMNS` inserted after ``tap_depth`` (thesis 4.6.2,
    eqs. 90-92; :func:`vetica_cli.extraction.material.moduli`): from the record's peak force
    and penetration and the row's ``k_g, k_r, tau_r`` (estimates and theory values)."""
    cms = point_contact(study)
    out = {c: np.full(len(table), np.nan) for c in MATERIAL_COLUMNS}

    def col(name):
        return table[name].to_numpy(float) if name in table.columns else np.full(len(table), np.nan)

    keys = table["point"].to_numpy()
    for cm in set(cms.values()):
        rows = np.isin(keys, [k for k, v in cms.items() if v == cm])
        if not rows.any():
            continue
        peak, depth = col("tap_peak_force")[rows], col("tap_depth")[rows]
        for suffix in ("", "_theory"):
            m = moduli(
                peak, depth, col("k_g" + suffix)[rows], col("k_r" + suffix)[rows], col("tau_r" + suffix)[rows], cm
            )
            for name, values in m.items():
                if name + suffix in out:
                    out[name + suffix][rows] = values
    at = table.columns.get_loc("tap_depth") + 1 if "tap_depth" in table.columns else len(table.columns)
    left, right = table.iloc[:, :at], table.iloc[:, at:]
    return pd.concat([left, pd.DataFrame(out, index=table.index), right], axis=1)


def material_metadata(study: Study) -> dict:
    """The contact model of the material columns, for the table's metadata: thesis table 6
    with the study's ``material:`` section over it (the tip radius: the points' probe
    unless the section sets it)."""
    over = study.material or {}
    radii = sorted({p.config.probe.tip_radius for p in study.points})
    cm = contact_model(over, radii[0], where="material")
    source = "study material section" if "tip_radius" in over else "probe.tip_radius of each point"
    meta = contact_metadata(cm, source)
    if len(radii) > 1 and "tip_radius" not in over:
        meta["tip_radius"] = {"value": radii, "unit": "m"}
    return meta
