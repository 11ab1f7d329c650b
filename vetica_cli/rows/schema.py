"""The rows of every batch table (sweep, scan): their columns and their units, built from
the registries (surface models for the estimates, extraction methods for the method
column, the simulation's observables), and the material columns computed from them.

One row per (point, force source): ``method``, ``force_source``, each quantity the
surface model reports with ``_theory`` and ``_err_pct``, the relative 1-sigma of
its parameters (``_sigma_pct``), ``unidentified``, ``taps``, the run observables,
the record's peak force and penetration below Z1 (``tap_peak_force``,
``tap_depth``), the material units computed from them when the table is assembled
(:func:`material_columns`: ``E_dmt``, ``E_glassy``, ``E_rubbery``, ``viscosity``, the
last three also as ``_theory``; thesis 4.6.2, eqs. 90-92, with the table's contact
model), ``stop_reason``, ``sim_time``, ``status``, ``error``, ``wall_s``.

Each column's unit is written to a table's metadata as a unit a unit library parses
(``units``: ``"N/m"``, ``"kg/s"``, ``"percent"``, ``""`` for a column without one) and,
apart, what the column means (``descriptions``): :func:`column_meta`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .. import surfaces
from ..extraction import METHODS
from ..extraction.material import CONTACT_UNITS, MATERIAL_UNITS, contact_metadata, contact_model, moduli
from ..simulation.observables import OBSERVABLE_UNITS
from .replicas import replica_columns, replica_meta

if TYPE_CHECKING:  # pandas is imported where the table is built: a dry run starts without it
    import pandas as pd

ACCEPT_ERR_PCT = 30.0  # [%] tau_c error below which a point is accepted (thesis fig. 52; study.acceptance)
# row status: ok = steady record, every reported quantity estimated; no_estimate = steady record, the
# extraction returned but some quantity has no value (the reason is in 'error'); not_steady = the record
# is not proven periodic (values, if any, are not trustworthy); failed = the simulation or extraction raised
STATUSES = ("ok", "no_estimate", "not_steady", "failed")
OBSERVABLES = tuple(OBSERVABLE_UNITS)
# column -> entry of the extraction's material object: the record's contact, the material columns' inputs
MATERIAL_INPUTS = {"tap_peak_force": "peak_force", "tap_depth": "penetration"}
# material columns computed when the table is assembled (the moduli from Kg, Kr also from their theory values);
# E_dmt always, the others when a surface model of the table declares them (SurfaceModel.material_columns)
MATERIAL_COLUMNS = ("E_dmt", "E_glassy", "E_glassy_theory", "E_rubbery", "E_rubbery_theory", "viscosity",
                    "viscosity_theory")  # fmt: skip


def material_columns_of(models=None) -> tuple[str, ...]:
    """The material columns of a table of points of the surface ``models`` (default: the
    default model): ``E_dmt`` and each column (with its ``_theory``) a model declares."""
    models = models or [surfaces.get(surfaces.DEFAULT_MODEL)]
    declared = {c for m in models for c in m.material_columns}
    return tuple(c for c in MATERIAL_COLUMNS if c == "E_dmt" or c.removesuffix("_theory") in declared)


def sigma_names(model: surfaces.SurfaceModel) -> tuple[str, ...]:
    """Every quantity of the model (in quantity order; its parameters and the quantities derived
    from them, e.g. the SLS's tau_c, Kg, Kr and tau_r beside k0, k_inf and cd): the ``_sigma_pct``
    columns and those the ``unidentified`` column may name.  A table that gives a quantity's
    error gives its flag and its error bar too: a row whose tau_c is off and flagged says so."""
    return tuple(model.quantities)


def models_of(configs) -> list[surfaces.SurfaceModel]:
    """The surface models of resolved point configs, in registry order, each specialised to
    its points' parameters (a Wiechert table's number of arms)."""
    used: dict = {}
    for cfg in configs:
        m = cfg.surface.surface_model
        used.setdefault((cfg.surface.model, m.parameter_keys), m)
    order = list(surfaces.MODELS)
    return [m for (k, _), m in sorted(used.items(), key=lambda kv: order.index(kv[0][0]))]


def method_quantities(models, methods) -> tuple[list[str], list[str]]:
    """``(estimates, references)``: the quantities the ``methods`` (keys) report for points of
    the surface ``models`` beyond the models' own (e.g. ``tan_delta_am`` of ``observables``),
    and their theory-only references (``<name>_theory`` columns), in order of first use."""
    own = {q for m in models for q in m.quantities}
    est, refs = {}, {}
    for key in methods or ():
        for m in models:
            est.update(dict.fromkeys(q for q in METHODS[key].quantities(m) if q not in own))
            refs.update(dict.fromkeys(METHODS[key].reference_quantities(m)))
    return list(est), [r for r in refs if r not in est and r not in own]


def result_columns(models=None, methods=None, replicas: int = 1) -> list[str]:
    """Columns a job fills for each (point, force source), in table order, for points of the
    surface ``models`` (default: the default model) extracted by ``methods`` (keys; their own
    quantities and references after the models'); with ``replicas`` > 1 the replicas' summary
    (:mod:`.replicas`) after the sigma columns."""
    models = models or [surfaces.get(surfaces.DEFAULT_MODEL)]
    extra, refs = method_quantities(models, methods)
    quantities = list(dict.fromkeys([*(q for m in models for q in m.quantities), *extra]))
    sigmas = list(dict.fromkeys(q for m in models for q in sigma_names(m)))
    cols = ["method", "force_source"]
    for name in quantities:
        cols += [name, f"{name}_theory", f"{name}_err_pct"]
    cols += [f"{name}_theory" for name in refs]
    cols += [f"{name}_sigma_pct" for name in sigmas]
    if replicas > 1:
        cols += replica_columns(sigmas)
    cols += ["unidentified", "taps", *OBSERVABLES, *MATERIAL_INPUTS, "stop_reason", "sim_time", "status", "error",
             "wall_s"]  # fmt: skip
    return cols


# unit texts of the observables that a unit library does not read as written, and the units
# a "unit: meaning" text may start with
_UNIT_WORDS = {"eV per drive cycle": "eV", "s per drive cycle": "s", "deg": "degree"}
_UNITS = {"s", "m", "N", "N/m", "kg/s", "Pa", "Pa s", "eV", "J", "Hz", "J m"}


def split_unit(text: str) -> tuple[str, str]:
    """``'N/m: what it is'`` -> ``('N/m', 'what it is')``; ``'s per drive cycle in contact'``
    -> ``('s', the whole text)``; a text that starts with no unit -> ``('', text)``: the
    unit a unit library parses, and the meaning."""
    head, sep, desc = text.partition(": ")
    if sep and head in _UNITS:
        return head, desc
    if sep and head in _UNIT_WORDS:
        return _UNIT_WORDS[head], f"{desc} ({head})"
    for words, unit in _UNIT_WORDS.items():
        if text.startswith(words + " "):
            return unit, text
    return "", text


def column_meta(models, methods=None, replicas: int = 1) -> dict:
    """``column -> (unit, description)`` of every row column for points of the surface
    ``models`` extracted by ``methods`` (keys) (module docstring: the unit parses with a unit
    library, ``''`` for none)."""
    meta = {
        "method": ("", "extraction method (extract.method): "
                   + " | ".join(f"{k} ({m.description})" for k, m in METHODS.items())),
        "force_source": ("", "true = simulator f_ts; reconstructed = spectral inversion of the paddle signal"),
    }  # fmt: skip
    for model in models:
        for name, q in model.quantities.items():
            meta[name] = (q.unit, f"estimate of the {q.description} by the row's extraction method")
            meta[f"{name}_theory"] = (q.unit, f"{q.description}: {model.theory_source}")
            meta[f"{name}_err_pct"] = ("percent", "100 (estimate - theory) / theory, signed")
        for name in sigma_names(model):
            meta[f"{name}_sigma_pct"] = (
                "percent", "relative 1-sigma of the estimate (Jacobian) for methods that report one; NaN otherwise "
                "or unbounded")  # fmt: skip
        for key in methods or ():
            meth = METHODS[key]
            for name, q in {**meth.quantities(model), **meth.reference_quantities(model)}.items():
                if name in model.quantities:
                    continue
                unit = _UNIT_WORDS.get(q.unit, q.unit)
                if name in meth.quantities(model):
                    meta[name] = (unit, f"{q.description} ({key})")
                    meta[f"{name}_err_pct"] = ("percent", "100 (estimate - theory) / theory, signed")
                    meta[f"{name}_theory"] = (unit, getattr(meth, "theory_sources", {}).get(name, "theory value"))
                else:
                    meta[f"{name}_theory"] = (unit, f"the surface's {q.description} (theory only)")
    if replicas > 1:
        meta.update(replica_meta(list(dict.fromkeys(q for m in models for q in sigma_names(m)))))
    meta["unidentified"] = ("", "quantities the method flags not identifiable, comma-separated ('' = none)")
    meta["taps"] = ("", "complete taps in the record")
    for name in OBSERVABLES:
        meta[name] = split_unit(OBSERVABLE_UNITS.get(name, ""))
    for col, entry in MATERIAL_INPUTS.items():
        unit, desc = CONTACT_UNITS[entry]
        meta[col] = (unit, f"the record's {desc}, as the row's extraction saw it")
    for col in material_columns_of(models):
        name = col.removesuffix("_theory")
        unit, desc = MATERIAL_UNITS[name]
        src = "the theory values of" if col.endswith("_theory") else "the row's estimates of"
        needs = {"E_dmt": "", "E_glassy": f", tap_depth and {src} Kg", "E_rubbery": f", tap_depth and {src} Kr",
                 "viscosity": f", tap_depth and {src} tau_r"}[name]  # fmt: skip
        meta[col] = (unit, f"{desc}; from tap_peak_force{needs or ' and tap_depth'} (contact model: metadata "
                     "'material')")  # fmt: skip
    meta["stop_reason"] = ("", "steady | steady (transient fallback) | max_time | max_time (orbit solver failed): "
                           "steady = the recorded window is proven periodic")  # fmt: skip
    meta["sim_time"] = ("s", "simulated time to steady state plus the recorded periods (or numerics.max_time)")
    meta["status"] = ("", "ok (steady record, every quantity estimated) | no_estimate (steady record, some quantity "
                      "has no value; why: error) | not_steady (record not proven periodic: stop_reason max_time ...) "
                      "| failed (see error)")  # fmt: skip
    meta["error"] = ("", "error text of a failed simulation or extraction, or why a quantity has no estimate")
    meta["wall_s"] = ("s", "wall time of the point's simulation (shared by the points that share it) plus this row's "
                      "extraction")  # fmt: skip
    return meta


def units_metadata(meta: dict) -> dict:
    """``{'units': {column: unit}, 'descriptions': {column: text}}`` from ``column -> (unit,
    description)``: what a table's metadata holds."""
    return {"units": {c: u for c, (u, _) in meta.items()}, "descriptions": {c: d for c, (_, d) in meta.items()}}


def material_columns(table: pd.DataFrame, cms: dict, models=None) -> pd.DataFrame:
    """The table with its material columns (:func:`material_columns_of` the surface ``models``)
    inserted after ``tap_depth`` (thesis 4.6.2, eqs. 90-92;
    :func:`vetica_cli.extraction.material.moduli`): from the record's peak force and penetration
    and the row's ``k_g, k_r, tau_r`` (estimates and theory values).  ``cms``: point key (the
    ``point`` column) -> its contact model."""
    import pandas as pd

    out = {c: np.full(len(table), np.nan) for c in material_columns_of(models)}

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


def material_metadata(over: dict | None, radii) -> dict:
    """The contact model of the material columns, for the table's metadata: thesis table 6
    with the table's ``material:`` section ``over`` it (the tip radius: the points' probe
    radii ``radii`` unless the section sets it)."""
    over = over or {}
    radii = sorted(set(radii))
    cm = contact_model(over, radii[0], where="material")
    source = "material section" if "tip_radius" in over else "probe.tip_radius of each point"
    meta = contact_metadata(cm, source)
    if len(radii) > 1 and "tip_radius" not in over:
        meta["tip_radius"] = {"value": radii, "unit": "m"}
    return meta
