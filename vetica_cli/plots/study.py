"""Which study figures a sweep table calls for (from its swept keys) and drawing them,
one titled set per extraction method.
"""

from __future__ import annotations

import pandas as pd

from .. import surfaces
from ..errors import InputError
from ..extraction import DEFAULT_METHOD, METHODS, SOURCES
from .acceptance import fig_acceptance_vs
from .data import AXIS_PRIORITY, SweepData, base_config, swept_keys
from .errors import fig_errors_vs, fig_errors_vs_cd, fig_values_vs_cd
from .maps import fig_depth_error_map, fig_ediss_map
from .observables import (
    fig_contact_times_vs,
    fig_force_penetration_vs,
    fig_observable_vs,
    fig_observable_vs_cd,
    fig_quantities_vs,
    fig_surface_position_vs_ps,
)
from .style import CD, F1, K2, PS, RATIO, SETPOINT


def select_sweep_figures(swept: list[str]) -> list[tuple[str, str, tuple]]:
    """Figures for a sweep, chosen from the swept keys: [(file name, builder, args)].

    Thesis figures (ch. 4) and the keys that call for them:
    cd -> errors (43-46), extracted values when cd is the only axis (43, 45),
    E_diss against cd (41, one ratio), steady-state zero depth (57);
    cd x ratio -> E_diss map coloured by tau_c error (41, 50), paddle amplitude (49);
    cd x set point -> tau_c error map with zero-depth contours (58);
    cd x f1 / cd x print step -> acceptance regime (52 / 61);
    ratio -> peak force and penetration (48), errors within the regime (47);
    set point -> peak force and penetration (56), contact times (54), errors (55);
    f1 -> contact times (51); print step -> surface position deviation (59-60); k2 -> E_diss (30);
    any other swept key -> errors against it (no thesis figure).
    """
    s = set(swept)
    others = [k for k in swept if k != CD]
    out: list[tuple[str, str, tuple]] = []
    if CD in s:
        out.append(("fig43-46_errors_vs_cd", "errors_vs_cd", ()))
        if not others:
            out.append(("fig43-45_values_vs_cd", "values_vs_cd", ()))
        if RATIO in s:
            out.append(("fig41-50_ediss_map_cd_ratio", "ediss_map", ()))
            out.append(("fig49_paddle_amplitude_vs_cd", "observable_vs_cd", ("paddle_amplitude", "49")))
        else:
            out.append(("fig41_ediss_vs_cd", "observable_vs_cd", ("e_diss_ev", "41")))
        out.append(("fig57_ss_zero_depth_vs_cd", "observable_vs_cd", ("ss_zero_depth", "57")))
        if SETPOINT in s:
            out.append(("fig58_tau_c_error_map_cd_setpoint", "depth_error_map", ()))
        if F1 in s:
            out.append(("fig52_acceptance_vs_f1", "acceptance_vs", (F1, "52")))
        if PS in s:
            out.append(("fig61_acceptance_vs_print_step", "acceptance_vs", (PS, "61")))
    if RATIO in s:
        out.append(("fig48_force_penetration_vs_ratio", "force_penetration_vs", (RATIO, "48")))
        out.append(("fig47_errors_vs_ratio", "errors_vs", (RATIO, "47")))
    if SETPOINT in s:
        out.append(("fig56_force_penetration_vs_setpoint", "force_penetration_vs", (SETPOINT, "56")))
        out.append(("fig54_contact_times_vs_setpoint", "contact_times_vs", (SETPOINT, "54")))
        out.append(("fig55_errors_vs_setpoint", "errors_vs", (SETPOINT, "55")))
    if F1 in s:
        out.append(("fig51_contact_times_vs_f1", "contact_times_vs", (F1, "51")))
    if PS in s:
        out.append(("fig59-60_surface_position_vs_print_step", "surface_position_vs_ps", ("59-60",)))
    if K2 in s:
        out.append(("fig30_ediss_vs_k2", "observable_vs", (K2, "e_diss_ev", "30")))
    for k in others:
        if k not in AXIS_PRIORITY:
            out.append((f"errors_vs_{k.replace('.', '_')}", "errors_vs", (k, None)))
    return out


def sweep_figures(df: pd.DataFrame, meta: dict) -> tuple[list, list]:
    """[(name, Figure)], [notes] for a sweep table."""
    bad = sorted(set(df["force_source"].astype(str)) - set(SOURCES))
    if bad:
        raise InputError(f"force_source has {bad[0]!r}; allowed: {', '.join(SOURCES)}")
    if df.empty:
        raise InputError("the sweep table has no rows")
    swept = swept_keys(df, meta)
    if not swept:
        raise InputError("the sweep table varies no key: nothing to plot against")
    # tables comparing extraction methods (sweep key extract.method): one set of figures per method
    methods = sorted(set(df["method"].astype(str))) if "method" in df.columns else [DEFAULT_METHOD]
    text_keys = {k for k in swept if k in df.columns and not pd.api.types.is_numeric_dtype(df[k])}
    figs, notes = [], []
    model_cols = [q for m in surfaces.MODELS.values() for q in m.quantities if q in df.columns]
    for method in methods:
        dm = df[df["method"].astype(str) == method] if len(methods) > 1 else df
        sw = SweepData(df=dm, swept=swept, base=base_config(meta), method=method)
        # a method that reports its own numbers, not the model's (observables, dmt-fit): no figures of the model's
        own = bool(model_cols) and not dm[model_cols].notna().to_numpy().any() and not dm.empty
        for name, builder, args in select_sweep_figures(swept):
            label = name if len(methods) == 1 else f"{name}_{method}"
            if own and builder in MODEL_QUANTITY_FIGURES:
                notes.append(f"{label} skipped: {method} reports no estimate of the surface model's quantities")
                continue
            if builder == "errors_vs" and args[0] in text_keys:
                notes.append(f"{label} skipped: {args[0]} takes text values, which are series, not an axis")
                continue
            try:
                fig = BUILDERS[builder](sw, *args)
            except KeyError as exc:  # e.g. no 'ok' point for one force source
                notes.append(f"{label} skipped: no usable points ({exc})")
                continue
            if fig is None:
                notes.append(f"{label} skipped: no usable points")
                continue
            figs.append((label, fig))
        if own and method in METHODS:  # its own numbers against each swept key instead
            qs = METHODS[method].quantities(surfaces.get(surfaces.DEFAULT_MODEL))
            for key in (k for k in swept if k not in text_keys):
                label = f"{method}_values_vs_{key.replace('.', '_')}"
                fig = fig_quantities_vs(sw, key, qs)
                if fig is None:
                    notes.append(f"{label} skipped: no usable points")
                else:
                    figs.append((label, fig))
    notes.append(f"swept keys: {', '.join(swept)}" + (f"; methods: {', '.join(methods)}" if len(methods) > 1 else ""))
    return figs, notes


MODEL_QUANTITY_FIGURES = ("errors_vs_cd", "values_vs_cd", "errors_vs", "acceptance_vs", "depth_error_map")
BUILDERS = {
    "errors_vs_cd": fig_errors_vs_cd,
    "values_vs_cd": fig_values_vs_cd,
    "observable_vs_cd": fig_observable_vs_cd,
    "ediss_map": fig_ediss_map,
    "depth_error_map": fig_depth_error_map,
    "acceptance_vs": fig_acceptance_vs,
    "force_penetration_vs": fig_force_penetration_vs,
    "contact_times_vs": fig_contact_times_vs,
    "errors_vs": fig_errors_vs,
    "observable_vs": fig_observable_vs,
    "surface_position_vs_ps": fig_surface_position_vs_ps,
}
