"""Study figures of the extraction errors and values (thesis figs. 43-47, 55)."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from ..study.acceptance import ACCEPT_ERR_PCT, regime
from .acceptance import regime_text, shade_regime
from .data import SweepData, groups_of, set_title, status_note, statuses
from .style import (
    CD,
    ERR_FLOOR,
    PCT,
    RATIO,
    SOURCE_FILLED,
    SOURCE_LABEL,
    SOURCE_LS,
    add_note,
    axis_label,
    axis_meta,
    colors_for,
    disp,
    err_axes,
    extra_handles,
    legend_panel,
    new_figure,
    outside_legend,
    plain_log_labels,
    quantity_style,
    reserve_missing_rows,
    series,
    set_axis,
)


def fig_errors_vs_cd(sw: SweepData) -> Figure | None:
    """Errors of tau_c, Kg, k0, k_inf, cd against cd, log axes, acceptance regime shaded (thesis figs. 43-46).

    Error = 100 |extracted - theory| / theory.  With cd the only
    axis, one panel per force source holds the five quantities (fig. 46
    layout); with more axes, one panel per quantity holds a line per
    setting of the other keys.
    """
    others = sw.others
    fig = _errors_per_source(sw) if not others else _errors_per_quantity(sw)
    add_note(
        fig,
        status_note(
            sw.df,
            sw.swept,
            f"errors below {ERR_FLOOR:g} % drawn at {ERR_FLOOR:g} %; "
            f"dotted line: {PCT} (acceptance regime: τc error < {PCT})",
            regime=True,
        ),
    )
    how = (
        f"acceptance regime (τc error < {PCT}) shaded"
        if not others
        else f"dotted: the {PCT} acceptance threshold on τc"
    )
    set_title(fig, sw, f"VETICA errors against the dashpot; {how} (cf. thesis figs. 43-46)")
    return fig


def _errors_per_source(sw: SweepData) -> Figure:
    """cd the only axis: one panel per force source holding every quantity (thesis fig. 46 layout)."""
    sources = sw.sources()
    flags = set()
    fig = new_figure(6.2 * len(sources) + 0.6, 5.6)
    axes = np.atleast_1d(fig.subplots(1, len(sources), sharey=True))
    ran = sw.df[sw.df["status"].astype(str) != "failed"]
    missing = [q for q in sw.quantities if ran[q].isna().any()]  # one row of no-value markers each
    for ax, src in zip(axes, sources):
        d = sw.rows(src)
        rng = regime(d)
        shade_regime(ax, rng, d[CD], label=f"acceptance regime (τc error < {PCT})")
        for i, (q, (qlab, _, _)) in enumerate(sw.quantities.items()):
            col, mk = quantity_style(q, i)
            flags |= series(
                ax,
                d[CD],
                d[f"{q}_err_pct"],
                statuses(d),
                col,
                SOURCE_LS[src],
                mk,
                SOURCE_FILLED[src],
                qlab,
                floor=ERR_FLOOR,
                show_missing=True,
                missing_row=missing.index(q) if q in missing else 0,
            )
        ax.axhline(ACCEPT_ERR_PCT, color="k", ls=":", lw=1)
        ax.set_title(f"{SOURCE_LABEL[src]} ({'solid' if src == 'true' else 'dashed'})\n{regime_text(rng)}", fontsize=10)
    for ax in axes:
        err_axes(ax)
    reserve_missing_rows(axes, flags, len(missing))
    axes[0].set_ylabel(axis_label("error |extracted - theory| / theory", "%"))
    handles, _labels = axes[-1].get_legend_handles_labels()
    handles += extra_handles(flags)
    axes[-1].legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    return fig


def _errors_per_quantity(sw: SweepData) -> Figure:
    """More axes than cd: one panel per quantity holding a line per setting of the other keys."""
    sources = sw.sources()
    flags = set()
    groups = groups_of(sw.df, sw.others)
    colors = colors_for(len(groups))
    fig = new_figure(15, 8.5)
    axes = fig.subplots(2, 3).ravel()
    for ax, (q, (qlab, _, _)) in zip(axes, sw.quantities.items()):
        for (glab, _, g), color in zip(groups, colors):
            for src in sources:
                d = g[g["force_source"].astype(str) == src]
                flags |= series(
                    ax,
                    d[CD],
                    d[f"{q}_err_pct"],
                    statuses(d),
                    color,
                    SOURCE_LS[src],
                    "o",
                    SOURCE_FILLED[src],
                    None,
                    floor=ERR_FLOOR,
                    show_missing=True,
                    missing_row=sources.index(src),
                )
        if q == "tau_c":
            ax.axhline(ACCEPT_ERR_PCT, color="k", ls=":", lw=1.2)
            ax.text(0.01, ACCEPT_ERR_PCT, f" {PCT} (acceptance)", transform=ax.get_yaxis_transform(), va="bottom",
                    fontsize=8)  # fmt: skip
        ax.set_title(f"error of {qlab}", fontsize=10)
        ax.set_ylabel(axis_label("error", "%"))
        err_axes(ax)
        reserve_missing_rows(ax, flags, len(sources))
    legend_panel(axes[-1], groups, colors, sources, flags)
    return fig


def fig_values_vs_cd(sw: SweepData) -> Figure | None:
    """Extracted against theory for tau_c, Kg, k0, k_inf, cd over cd (thesis figs. 43 A-B, 45 A-C)."""
    fig = new_figure(15, 8.5)
    axes = fig.subplots(2, 3).ravel()
    flags = set()
    t = sw.rows(sw.sources()[0])
    rng = regime(sw.rows("true")) if "true" in sw.sources() else None
    for ax, (q, (qlab, unit, scale)) in zip(axes, sw.quantities.items()):
        shade_regime(ax, rng, t[CD], label="acceptance regime (true force)")
        th = t.sort_values(CD)
        ax.plot(th[CD], th[f"{q}_theory"] * scale, color="k", lw=1.6, label="theory")
        for src, mk, col in (("true", "x", "tab:red"), ("reconstructed", "o", "tab:blue")):
            if src not in sw.sources():
                continue
            d = sw.rows(src)
            flags |= series(
                ax,
                d[CD],
                d[q] * scale,
                statuses(d),
                col,
                SOURCE_LS[src],
                mk,
                SOURCE_FILLED[src],
                "VETICA, " + SOURCE_LABEL[src],
                show_missing=True,
                missing_row=0 if src == "true" else 1,
            )
        ax.set_xscale("log")
        vals = np.concatenate([th[f"{q}_theory"].to_numpy(float), t[q].to_numpy(float)]) * scale
        vals = vals[np.isfinite(vals) & (vals > 0)]
        if len(vals) and vals.max() / vals.min() > 30:
            ax.set_yscale("log")
        reserve_missing_rows(ax, flags, 2)
        ax.set_xlabel(axis_label("dashpot $c_d$", "kg/s"))
        ax.set_ylabel(axis_label(qlab, unit))
        ax.set_title(qlab, fontsize=10)
        ax.grid(alpha=0.3)
    handles, _labels = axes[0].get_legend_handles_labels()
    handles += extra_handles(flags)
    axes[-1].axis("off")
    axes[-1].legend(handles=handles, loc="center", fontsize=9)
    add_note(fig, status_note(sw.df, sw.swept))
    set_title(fig, sw, "VETICA extracted values against theory over the dashpot (cf. thesis figs. 43 and 45)")
    return fig


def fig_errors_vs(sw: SweepData, key: str, thesis: str | None) -> Figure | None:
    """Errors of the five VETICA quantities against ``key`` (thesis fig. 47: ratio; fig. 55: set point).

    With cd swept too, each point is the mean error over the cd values inside
    that setting's acceptance regime (as the thesis averages), computed per
    force source; otherwise the mean over the other keys.
    """
    sources = sw.sources()
    fig = new_figure(10, 6.3)
    ax = fig.subplots()
    cd_swept = CD in sw.swept
    rest = [k for k in sw.others if k != key]
    plotted = False
    for src in sources:
        m = _mean_errors(sw.rows(src), key, rest, cd_swept, list(sw.quantities))
        for i, (q, (qlab, _, _)) in enumerate(sw.quantities.items()):
            col, mk = quantity_style(q, i)
            y = np.maximum(m[q].to_numpy(float), ERR_FLOOR)
            if np.isfinite(y).any():
                plotted = True
            ax.plot(
                disp(key, m[key]),
                y,
                ls=SOURCE_LS[src],
                marker=mk,
                color=col,
                ms=7,
                lw=1.4,
                mfc=col if SOURCE_FILLED[src] else "white",
                label=f"{qlab}, {'true' if src == 'true' else 'reconstructed'}",
            )
    if not plotted:
        return None
    ax.set_yscale("log")
    ax.axhline(ACCEPT_ERR_PCT, color="k", ls=":", lw=1)
    plain_log_labels(ax)
    set_axis(ax, key, "x", sw.df[key])
    ax.set_ylabel(axis_label("mean error" + (" within the acceptance regime" if cd_swept else ""), "%"))
    ax.grid(alpha=0.3)
    outside_legend(ax, ax.get_legend_handles_labels()[0])
    name = "stiffness ratio" if key == RATIO else axis_meta(key)[0]
    ref = f" (cf. thesis fig. {thesis})" if thesis else " (no thesis counterpart)"
    extra = (
        (
            "mean over the ok cd points inside each setting's own acceptance regime; "
            "settings without a regime are left out"
        )
        if cd_swept
        else "mean over the other swept keys"
    )
    add_note(fig, status_note(sw.df, sw.swept, extra + "; solid: true force, dashed: reconstructed", marked=False))
    set_title(fig, sw, f"VETICA errors against {name}{ref}")
    return fig


def _mean_errors(d: pd.DataFrame, key: str, rest: list, cd_swept: bool, quantities: list) -> pd.DataFrame:
    """Mean error of each quantity at each value of ``key`` over the ok points: with cd swept,
    only those inside their setting's (of ``rest``) own acceptance regime."""
    rows = []
    d = d[d["status"].astype(str) == "ok"]
    for kv, g in d.groupby(key):
        sel = []
        for _, _, gg in groups_of(g, rest):
            if cd_swept:
                rng = regime(gg)
                if rng is None:
                    continue
                gg = gg[(gg[CD] >= rng.lo) & (gg[CD] <= rng.hi)]
            sel.append(gg[gg["status"].astype(str) == "ok"])
        sel = pd.concat(sel) if sel else g.iloc[:0]
        rows.append({key: kv, **{q: sel[f"{q}_err_pct"].mean() if len(sel) else np.nan for q in quantities}})
    return pd.DataFrame(rows)
