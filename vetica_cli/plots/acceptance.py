"""Study figures of the acceptance regime (thesis figs. 52, 61) and the regime shading
the error figures share; the regime itself is :mod:`vetica_cli.study.acceptance`.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from ..study.acceptance import ACCEPT_ERR_PCT, Regime, regime
from .data import SweepData, groups_of, set_title, status_note, statuses
from .style import (
    CD,
    ERR_FLOOR,
    PCT,
    SOURCE_FILLED,
    SOURCE_LABEL,
    SOURCE_LS,
    add_note,
    axis_label,
    axis_meta,
    colors_for,
    err_axes,
    extra_handles,
    new_figure,
    reserve_missing_rows,
    series,
)


def _half_step(cd: np.ndarray) -> float:
    u = np.unique(cd)
    return float(np.sqrt(np.median(u[1:] / u[:-1]))) if len(u) > 1 else 1.5


def shade_regime(ax, rng, cd_values, color="tab:green", label=None):
    """The regime exactly as stated, from its lowest to its highest accepted cd (a single
    accepted point: a line at it)."""
    if rng is None:
        return
    if rng.hi > rng.lo:
        ax.axvspan(rng.lo, rng.hi, color=color, alpha=0.12, lw=0, label=label)
    else:
        ax.axvline(rng.lo, color=color, alpha=0.5, lw=3, label=label)


def regime_text(rng: Regime | None) -> str:
    if rng is None:
        return f"no acceptance regime (no ok point with τc error < {PCT})"
    broken = "" if rng.contiguous else ", not contiguous"
    return f"acceptance regime {rng.lo:.2g} to {rng.hi:.2g} kg/s ({len(rng.accepted)} points{broken})"


def fig_acceptance_vs(sw: SweepData, key: str, thesis: str) -> Figure | None:
    """Acceptance regime (cd range with tau_c error < 30 %) against ``key`` (thesis fig. 52: f1; fig. 61: PS).

    (a) tau_c error against cd, one line per setting; (b) the regime's cd
    interval per setting, for each force source.
    """
    groups = groups_of(sw.df, sw.others)
    colors = colors_for(len(groups))
    fig = new_figure(15, 6.3)
    ax_e, ax_r = fig.subplots(1, 2, width_ratios=[1.15, 1])
    _error_panel(ax_e, sw, groups, colors)
    _interval_panel(ax_r, sw, groups, colors)
    name = axis_meta(key)[0]
    add_note(
        fig,
        status_note(
            sw.df,
            sw.swept,
            "bars: lowest to highest accepted cd, ticks: the accepted points; pale bar: the accepted points are not "
            "one unbroken run of the grid",
            regime=True,
        ),
    )
    set_title(fig, sw, f"Acceptance regime against {name} (cf. thesis fig. {thesis})")
    return fig


def _error_panel(ax_e, sw: SweepData, groups, colors) -> None:
    """(a) the tau_c error against cd, one line per setting and force source, the threshold dotted."""
    sources = sw.sources()
    flags = set()
    for (glab, _, g), color in zip(groups, colors):
        for src in sources:
            d = g[g["force_source"].astype(str) == src]
            flags |= series(
                ax_e,
                d[CD],
                d["tau_c_err_pct"],
                statuses(d),
                color,
                SOURCE_LS[src],
                "o",
                SOURCE_FILLED[src],
                glab if src == sources[0] else None,
                floor=ERR_FLOOR,
                show_missing=True,
                missing_row=sources.index(src),
            )
    ax_e.axhline(ACCEPT_ERR_PCT, color="k", ls=":", lw=1.2)
    ax_e.text(0.01, ACCEPT_ERR_PCT, f" {PCT}", transform=ax_e.get_yaxis_transform(), va="bottom", fontsize=8)
    err_axes(ax_e)
    reserve_missing_rows(ax_e, flags, len(sources))
    ax_e.set_ylabel(axis_label("τc error", "%"))
    ax_e.set_title("(a) τc error (solid: true force, dashed: reconstructed)", fontsize=10, loc="left")
    h, _ = ax_e.get_legend_handles_labels()
    h += extra_handles(flags)
    ax_e.legend(handles=h, fontsize=8, loc="best")


def _interval_panel(ax_r, sw: SweepData, groups, colors) -> None:
    """(b) the regime's cd interval per setting (bars), its accepted points (ticks), per force source."""
    sources = sw.sources()
    off = {"true": -0.17, "reconstructed": 0.17} if len(sources) > 1 else {sources[0]: 0.0}
    hs = {}
    cd_all = sw.df[CD].to_numpy(float)
    h2 = _half_step(cd_all)
    his = []
    for i, ((glab, _, g), color) in enumerate(zip(groups, colors)):
        for src in sources:
            rng = regime(g[g["force_source"].astype(str) == src])
            yv = i + off[src]
            if rng is None:
                ax_r.text(
                    np.sqrt(cd_all.min() * cd_all.max()), yv, "none", ha="center", va="center", fontsize=8, color="0.3"
                )
                continue
            his.append(rng.hi)
            # exactly the stated range; a single accepted point: a sliver around it
            lo, hi = (rng.lo, rng.hi) if rng.hi > rng.lo else (rng.lo / h2**0.25, rng.hi * h2**0.25)
            hs[src] = ax_r.barh(
                yv,
                hi - lo,
                left=lo,
                height=0.3,
                color=color if src == "true" else "white",
                alpha=1.0 if rng.contiguous else 0.45,
                edgecolor=color,
                hatch=None if src == "true" else "///",
                lw=1.5,
                label=SOURCE_LABEL[src],
            )
            ax_r.plot(rng.accepted, np.full(len(rng.accepted), yv), "|", color="k", ms=9, mew=1.5)
            span = f"{rng.lo:.2g} only" if rng.lo == rng.hi else f"{rng.lo:.2g} to {rng.hi:.2g}"
            broken = "" if rng.contiguous else " (broken)"
            ax_r.text(hi * 1.15, yv, span + broken, va="center", fontsize=7.5)
    ax_r.set_xscale("log")
    ax_r.set_xlim(cd_all.min() / h2 / 1.5, max([cd_all.max() * h2 * 1.5] + [h * h2 * 150 for h in his]))
    ax_r.set_yticks(range(len(groups)))
    ax_r.set_yticklabels([lab for lab, _, _ in groups], fontsize=8)
    ax_r.set_ylim(-0.7, len(groups) - 0.3)
    ax_r.set_xlabel(axis_label("dashpot $c_d$ inside the acceptance regime", "kg/s"))
    ax_r.set_title(f"(b) acceptance regime (τc error < {PCT}): cd from ... to ... [kg/s]", fontsize=10, loc="left")
    ax_r.grid(alpha=0.3, axis="x")
    if hs:
        ax_r.legend(handles=list(hs.values()), fontsize=8, loc="lower right")
