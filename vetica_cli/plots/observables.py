"""Study figures of the run observables: against cd (thesis figs. 41, 49, 57), twin-axis
means against a setting (figs. 48, 51, 54, 56), against any key (fig. 30), the surface
position as the record places it against the print step (figs. 59-60).
"""

from __future__ import annotations

import matplotlib.colors
import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from .data import SweepData, groups_of, set_title, status_note, statuses
from .style import (
    CD,
    OBSERVABLES,
    PS,
    RATIO,
    add_note,
    axis_label,
    axis_meta,
    colors_for,
    disp,
    extra_handles,
    new_figure,
    outside_legend,
    series,
    set_axis,
)


def fig_observable_vs_cd(sw: SweepData, obs: str, thesis: str) -> Figure | None:
    """An observable against cd, one line per setting of the other keys (thesis figs. 41, 49, 57).

    A key that does not change the observable (the print step, when the
    sweep shares one simulation between print steps) gets no lines of its
    own: they would lie on top of each other.
    """
    pts = sw.points()
    keep = [k for k in sw.others if not _no_effect(pts, obs, k, [CD] + [o for o in sw.others if o != k])]
    dropped = [k for k in sw.others if k not in keep]
    if dropped:
        pts = pts.drop_duplicates(subset=[CD] + keep)
    groups = groups_of(pts, keep)
    colors = colors_for(len(groups))
    name, unit, scale = OBSERVABLES[obs]
    fig = new_figure(9.5, 6)
    ax = fig.subplots()
    flags = set()
    for (glab, _, g), color in zip(groups, colors):
        flags |= series(ax, g[CD], g[obs] * scale, statuses(g), color, "-", "o", True, glab or None)
    ax.set_xscale("log")
    vals = (pts[obs] * scale).to_numpy(float)
    vals = vals[np.isfinite(vals)]
    if len(vals) and np.all(vals > 0) and vals.max() / vals.min() > 100:
        ax.set_yscale("log")
    elif len(vals) and np.any(vals < 0) and np.any(vals > 0):
        big = np.max(np.abs(vals))
        small = np.min(np.abs(vals[vals != 0]))
        if big / small > 100:  # both signs over decades (a depth above and below Z1): symmetric log
            ax.set_yscale("symlog", linthresh=max(small, 1e-3 * big))
            ax.axhline(0, color="0.5", lw=0.6)
    ax.set_xlabel(axis_label("dashpot $c_d$", "kg/s"))
    ylabel = {"ss_zero_depth": r"steady-state zero reference depth below $Z_1$"}.get(obs, name)
    ax.set_ylabel(axis_label(ylabel, unit))
    ax.grid(alpha=0.3)
    handles, _ = ax.get_legend_handles_labels()
    handles += extra_handles(flags)
    if handles:
        outside_legend(ax, handles)
    what = {
        "e_diss_ev": "Energy dissipated per cycle against the dashpot",
        "paddle_amplitude": "Paddle amplitude against the dashpot for each stiffness ratio",
        "ss_zero_depth": "Steady-state zero reference depth against the dashpot",
    }[obs]
    same = ", ".join(axis_meta(k)[0] for k in dropped)
    extra = f"identical for every {same} (one line drawn)" if dropped else ""
    add_note(fig, status_note(pts, [CD] + keep, extra, estimates=False))
    set_title(fig, sw, f"{what} (cf. thesis fig. {thesis})")
    return fig


def _no_effect(pts: pd.DataFrame, col: str, key: str, others: list) -> bool:
    """True when ``col`` is the same (to 1e-9) at every value of ``key`` for each setting of ``others``."""
    d = pts[pts["status"].astype(str) != "failed"]
    if d[key].nunique() < 2:
        return False
    spread = d.groupby(others)[col].agg(lambda v: np.nanmax(v) - np.nanmin(v) if v.notna().any() else 0.0)
    scale = np.nanmax(np.abs(d[col].to_numpy(float))) if d[col].notna().any() else 0.0
    return bool(np.all(spread.to_numpy(float) <= 1e-9 * scale))


def common_steady(pts: pd.DataFrame, key: str, rest: list) -> tuple[pd.DataFrame, bool]:
    """The steady points (``ok`` or ``no_estimate``: the record is proven periodic, so its
    observables hold whatever the extraction gave) whose values of the other keys ``rest`` are
    steady at every value of ``key``.

    Averaging over a different set of cd values at each setting would draw the change of
    sample, not the effect of ``key``; (steady points, False) when no such common set exists.
    """
    steady = pts[pts["status"].astype(str).isin(("ok", "no_estimate"))]
    if not rest:
        return steady, True
    n_key = pts[key].nunique()
    counts = steady.groupby(rest)[key].nunique()
    common = counts[counts == n_key].index
    if len(common) == 0:
        return steady, False
    sel = steady.set_index(rest).index.isin(common)
    return steady[sel], True


def mean_band(pts: pd.DataFrame, key: str, col: str, rest: list | None = None):
    """Mean, min and max of ``col`` at each value of ``key`` over the steady points of the other
    keys ``rest`` that are steady at every value of ``key`` (all steady points if there are none)."""
    steady, _ = common_steady(pts, key, rest or [])
    g = steady.groupby(key)[col]
    return g.mean(), g.min(), g.max(), g.count()


def _twin_plot(sw: SweepData, key: str, left: str, right: str, styles, title: str) -> Figure | None:
    pts = sw.points()
    averaged = len(sw.swept) > 1
    fig = new_figure(9.5, 6)
    ax_l = fig.subplots()
    ax_r = ax_l.twinx()
    lines = []
    for ax, col, (color, ls, mk) in ((ax_l, left, styles[0]), (ax_r, right, styles[1])):
        name, unit, scale = OBSERVABLES[col]
        if averaged:
            mean, lo, hi, _n = mean_band(pts, key, col, [k for k in sw.swept if k != key])
            x = disp(key, mean.index)
            ax.fill_between(x, lo * scale, hi * scale, color=color, alpha=0.15, lw=0)
            (ln,) = ax.plot(x, mean * scale, ls=ls, marker=mk, color=color, lw=1.6, ms=7, label=f"{name} (mean)")
        else:
            d = pts[pts["status"].astype(str) != "failed"].sort_values(key)
            (ln,) = ax.plot(disp(key, d[key]), d[col] * scale, ls=ls, marker=mk, color=color, lw=1.6, ms=7, label=name)
            ns = (d["status"].astype(str) == "not_steady").to_numpy()
            if ns.any():
                ax.plot(disp(key, d[key])[ns], (d[col] * scale).to_numpy()[ns], "x", color="0.35", ms=11, mew=1.6)
        lines.append(ln)
        ax.set_ylabel(axis_label(name, unit), color=color)
        ax.tick_params(axis="y", colors=color)
    set_axis(ax_l, key, "x", pts[key])
    ax_l.grid(alpha=0.3)
    ax_l.legend(handles=lines, fontsize=9, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=2, frameon=False)
    extra = ""
    if averaged:
        rest = [k for k in sw.swept if k != key]
        over = ", ".join(rest)
        sub, common = common_steady(pts, key, rest)
        n = len(sub.drop_duplicates(subset=rest))
        which = (
            f"the {n} values of {over} that are steady at every {axis_meta(key)[0]}"
            if common
            else f"the steady points of {over}"
        )
        extra = f"lines: mean over {which}; bands: their min-max range"
    add_note(fig, status_note(pts, sw.swept, extra, marked=not averaged, estimates=False))
    set_title(fig, sw, title)
    return fig


def fig_force_penetration_vs(sw: SweepData, key: str, thesis: str) -> Figure | None:
    """Maximum surface penetration (left, blue triangles) and peak force (right, green dashed circles)
    against the stiffness ratio (thesis fig. 48) or the set point (fig. 56)."""
    what = "stiffness ratio" if key == RATIO else axis_meta(key)[0]
    return _twin_plot(
        sw,
        key,
        "max_penetration",
        "peak_force",
        (("tab:blue", "-", "^"), ("tab:green", "--", "o")),
        f"Maximum surface penetration and peak force against {what} (cf. thesis fig. {thesis})",
    )


def fig_contact_times_vs(sw: SweepData, key: str, thesis: str) -> Figure | None:
    """Contact (left) and non-contact (right) time per cycle against f1 (thesis fig. 51) or set point (fig. 54)."""
    what = axis_meta(key)[0]
    return _twin_plot(
        sw,
        key,
        "contact_time",
        "noncontact_time",
        (("tab:blue", "-", "^"), ("tab:red", "--", "o")),
        f"Time per drive cycle in contact and out of contact against {what} (cf. thesis fig. {thesis})",
    )


def fig_observable_vs(sw: SweepData, key: str, obs: str, thesis: str) -> Figure | None:
    """An observable against a swept key, one line per setting of the rest (thesis fig. 30: E_diss vs k2)."""
    pts = sw.points()
    rest = [k for k in sw.swept if k != key]
    groups = groups_of(pts, rest)
    colors = colors_for(len(groups)) if rest else ["tab:purple"]
    name, unit, scale = OBSERVABLES[obs]
    fig = new_figure(9, 6)
    ax = fig.subplots()
    flags = set()
    for (glab, _, g), color in zip(groups, colors):
        flags |= series(ax, disp(key, g[key]), g[obs] * scale, statuses(g), color, "-", "o", True, glab or None)
    set_axis(ax, key, "x", pts[key])
    ax.set_ylabel(axis_label(name, unit))
    ax.grid(alpha=0.3)
    h, _ = ax.get_legend_handles_labels()
    h += extra_handles(flags)
    if h:
        outside_legend(ax, h)
    add_note(fig, status_note(pts, sw.swept, estimates=False))
    set_title(fig, sw, f"{name} against {axis_meta(key)[0]} (cf. thesis fig. {thesis})")
    return fig


def fig_quantities_vs(sw: SweepData, key: str, quantities: dict) -> Figure | None:
    """A method's own quantities (``{column: Quantity}``, e.g. the per-tap peak force and tap
    duration of a model-free method) against a swept key, one panel each, one line per
    setting of the other keys (no thesis figure)."""
    pts = sw.points()
    cols = [q for q in quantities if q in pts.columns and np.isfinite(pts[q].to_numpy(float)).any()]
    if not cols:
        return None
    rest = [k for k in sw.swept if k != key]
    groups = groups_of(pts, rest)
    colors = colors_for(len(groups)) if rest else ["tab:purple"]
    fig = new_figure(9, 1.5 + 3.2 * len(cols))
    axes = np.atleast_1d(fig.subplots(len(cols), 1, sharex=True))
    flags = set()
    for ax, q in zip(axes, cols):
        spec = quantities[q]
        for (glab, _, g), color in zip(groups, colors):
            flags |= series(ax, disp(key, g[key]), g[q] * spec.display_scale, statuses(g), color, "-", "o", True,
                            glab or None)  # fmt: skip
        ax.set_ylabel(axis_label(spec.label, spec.shown_unit))
        ax.grid(alpha=0.3)
    set_axis(axes[-1], key, "x", pts[key])
    h, _ = axes[0].get_legend_handles_labels()
    h += extra_handles(flags)
    if h:
        outside_legend(axes[0], h)
    add_note(fig, status_note(pts, sw.swept, estimates=False))
    set_title(fig, sw, f"{', '.join(quantities[q].label for q in cols)} against {axis_meta(key)[0]}")
    return fig


def fig_surface_position_vs_ps(sw: SweepData, thesis: str) -> Figure | None:
    """Where the record puts the surface against where it was, by print step (thesis figs.
    59-60): top, each point's contact (A, approach) and separation (B, retract) as measured
    (force minimum at the print step) relative to the true event (black star at the origin),
    time against position, coloured by the print step; bottom, the absolute position
    deviation against the print step with its running mean over five print steps (the
    deviation oscillates as the sampling grid slides past the event)."""
    pts = sw.points()
    pts = pts[pts["status"].astype(str) != "failed"]
    cols = ("contact_pos_dev", "separation_pos_dev", "contact_time_dev", "separation_time_dev")
    if not all(c in pts.columns for c in cols) or not np.isfinite(pts[list(cols)].to_numpy(float)).any():
        return None
    ps = disp(PS, pts[PS])
    fig = new_figure(12, 8.5)
    axes = fig.subplots(2, 2)
    norm = matplotlib.colors.LogNorm(vmin=float(np.min(ps)), vmax=float(np.max(ps)))
    for j, (edge, label) in enumerate((("contact", "A) approach: contact"), ("separation", "B) retract: separation"))):
        pos = pts[f"{edge}_pos_dev"].to_numpy(float) * 1e12
        lag = pts[f"{edge}_time_dev"].to_numpy(float) * 1e9
        ax = axes[0, j]
        sc = ax.scatter(lag, pos, c=ps, cmap="viridis", norm=norm, s=28, edgecolor="0.2", lw=0.4, label="measured")
        ax.plot([0], [0], marker="*", color="k", ms=16, ls="none", label="true surface (time, position)")
        ax.set_xlabel(axis_label("time: measured - true", "ns"))
        ax.set_ylabel(axis_label("position: measured - true", "pm"))
        ax.set_title(label, fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="best")
        fig.colorbar(sc, ax=ax, label=axis_label("print step PS", "ns"))
        ax = axes[1, j]
        order = np.argsort(ps, kind="stable")
        x, y = ps[order], np.abs(pos[order])
        ax.plot(x, y, "o", color="tab:blue", ms=5, label="|measured - true|")
        if len(x) >= 5:
            frame = pd.DataFrame({"x": x, "y": y}).groupby("x")["y"].mean()
            run = frame.rolling(5, center=True, min_periods=3).mean()
            ax.plot(run.index, run.to_numpy(), "-", color="k", lw=1.8, label="running mean (5 print steps)")
        ax.set_xlabel(axis_label("print step PS", "ns"))
        ax.set_ylabel(axis_label(f"|{edge} position deviation|", "pm"))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper left")
    add_note(fig, status_note(sw.points(), sw.swept, "true event: the integration step at which the tip met or "
                              "left the surface; measured: the force minimum of each recorded tap (mean over taps)",
                              marked=False, estimates=False))  # fmt: skip
    set_title(fig, sw, f"Surface position as the record places it, against the print step (cf. thesis figs. {thesis})")
    return fig
