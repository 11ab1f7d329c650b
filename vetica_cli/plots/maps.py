"""Study maps over cd x a second key: E_diss and the tau_c error over cd x stiffness
ratio (thesis figs. 41, 50), the tau_c error over cd x set point (fig. 58).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure

from ..study.acceptance import ACCEPT_ERR_PCT
from .data import SweepData, groups_of, set_title, status_note, statuses
from .style import (
    CD,
    PCT,
    RATIO,
    SETPOINT,
    SOURCE_LABEL,
    add_note,
    axis_label,
    axis_meta,
    colors_for,
    extra_handles,
    new_figure,
    series,
    set_axis,
)


def _edges(values: np.ndarray, log: bool) -> np.ndarray:
    v = np.log(values) if log else np.asarray(values, float)
    if len(v) == 1:
        e = np.array([v[0] - 0.5, v[0] + 0.5])
    else:
        mid = 0.5 * (v[1:] + v[:-1])
        e = np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])
    return np.exp(e) if log else e


def _grid(d: pd.DataFrame, ykey: str, col: str):
    """(cd values, y values, 2-D array [y, cd]) of ``col`` with failed points as NaN, and the not-steady mask."""
    d = d.copy()
    d.loc[d["status"].astype(str) == "failed", col] = np.nan
    piv = d.pivot_table(index=ykey, columns=CD, values=col, aggfunc="mean", dropna=False)
    ns = d.assign(_ns=(d["status"].astype(str) == "not_steady").astype(float))
    nsp = ns.pivot_table(index=ykey, columns=CD, values="_ns", aggfunc="max").reindex_like(piv).fillna(0) > 0
    return piv.columns.to_numpy(float), piv.index.to_numpy(float), piv.to_numpy(float), nsp.to_numpy()


def _heat(ax, fig, x, y, z, ykey, ns, norm, cmap, clabel):
    ax.set_facecolor("0.85")
    xe = _edges(x, True)
    ye = _edges(y * axis_meta(ykey)[2], axis_meta(ykey)[3] != "linear")
    m = ax.pcolormesh(xe, ye, np.ma.masked_invalid(z), norm=norm, cmap=cmap, shading="flat")
    over = norm is not None and np.nanmax(z) > norm.vmax if np.isfinite(z).any() else False
    cb = fig.colorbar(m, ax=ax, extend="max" if over else "neither")
    if isinstance(norm, LogNorm) and norm.vmax / norm.vmin < 1e3:
        from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

        cb.ax.yaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 3.0, 5.0)))
        cb.ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        cb.ax.yaxis.set_minor_formatter(NullFormatter())
    cb.set_label(clabel)
    yy, xx = np.meshgrid(y * axis_meta(ykey)[2], x, indexing="ij")
    if ns.any():
        ax.plot(xx[ns], yy[ns], "X", color="w", mec="k", mew=0.8, ms=9, ls="none")
    ax.set_xscale("log")
    ax.set_xlabel(axis_label("dashpot $c_d$", "kg/s"))
    set_axis(ax, ykey, "y", y)
    ax.set_xlim(xe[0], xe[-1])
    ax.set_ylim(ye[0], ye[-1])
    return xx, yy


def _lognorm(*arrays, cap: float | None = None):
    v = np.concatenate([np.ravel(a) for a in arrays])
    v = v[np.isfinite(v) & (v > 0)]
    if not len(v):
        return None
    hi = max(v.max(), v.min() * 10)
    if cap is not None:
        hi = max(min(hi, cap), v.min() * 10)
    return LogNorm(vmin=v.min(), vmax=hi)


def _contours(ax, xx, yy, z, fmt: str, log: bool, color="k"):
    """Labelled contour lines of ``z`` (masked where not finite); decade levels when ``log``."""
    zm = np.ma.masked_invalid(z)
    if zm.count() < 4 or z.shape[0] < 2 or z.shape[1] < 2:
        return
    if log:
        zl = np.ma.log10(np.ma.masked_less_equal(zm, 0))
        if zl.count() < 4:
            return
        lo, hi = math.floor(zl.min()), math.ceil(zl.max())
        step = max(1, (hi - lo) // 6)
        levels = np.arange(lo, hi + 1, step)
        cs = ax.contour(xx, yy, zl, levels=levels, colors=color, linewidths=0.9, negative_linestyles="solid")
        ax.clabel(cs, fontsize=7.5, fmt=lambda v: fmt % (10**v))
    else:
        cs = ax.contour(xx, yy, zm, levels=6, colors=color, linewidths=0.9, negative_linestyles="solid")
        ax.clabel(cs, fontsize=7.5, fmt=fmt)


def _accept_contour(ax, xx, yy, err):
    """The 30 % line of the tau_c error (the acceptance regime's edge), bright green."""
    zm = np.ma.masked_invalid(err)
    if zm.count() >= 4 and err.shape[0] > 1 and err.shape[1] > 1 and zm.min() < ACCEPT_ERR_PCT < zm.max():
        ax.contour(xx, yy, zm, levels=[ACCEPT_ERR_PCT], colors="lime", linewidths=2.4)


ERR_CAP = 1e3  # colour scales of tau_c error stop here (the interesting part is below 30 %)


def fig_ediss_map(sw: SweepData) -> Figure | None:
    """E_diss over cd x stiffness ratio (thesis fig. 41) and the tau_c error over the same plane with
    E_diss contours (thesis fig. 50), for each force source."""
    pts = sw.points()
    x, y, e, ns = _grid(pts, RATIO, "e_diss_ev")
    sources = sw.sources()
    fig = new_figure(14, 11)
    axes = fig.subplots(2, 2).ravel()
    vpos = e[np.isfinite(e)]
    logscale = bool(len(vpos) and np.all(vpos > 0) and vpos.max() / vpos.min() > 30)
    norm = _lognorm(e) if logscale else None
    xx, yy = _heat(axes[0], fig, x, y, e, RATIO, ns, norm, "magma", axis_label("$E_{diss}$", "eV per cycle"))
    _contours(axes[0], xx, yy, e, "%.3g eV", logscale, color="w")
    axes[0].set_title("(a) $E_{diss}$ per cycle (cf. fig. 41); white: contours [eV]", fontsize=10, loc="left")
    # (b) the same as lines against cd, one per ratio
    ax = axes[1]
    groups = groups_of(pts, [RATIO])
    flags = set()
    for (glab, _, g), color in zip(groups, colors_for(len(groups))):
        flags |= series(ax, g[CD], g["e_diss_ev"], statuses(g), color, "-", "o", True, glab)
    ax.set_xscale("log")
    if logscale:
        ax.set_yscale("log")
    ax.set_xlabel(axis_label("dashpot $c_d$", "kg/s"))
    ax.set_ylabel(axis_label("$E_{diss}$", "eV per cycle"))
    ax.grid(alpha=0.3)
    h, _ = ax.get_legend_handles_labels()
    h += extra_handles(flags)
    ax.legend(handles=h, fontsize=8)
    ax.set_title("(b) $E_{diss}$ against $c_d$, one line per stiffness ratio", fontsize=10, loc="left")
    errs = [_grid(sw.rows(src), RATIO, "tau_c_err_pct") for src in sources]
    enorm = _lognorm(*[g[2] for g in errs], cap=ERR_CAP) or LogNorm(1, 100)
    for i, (ax, src, (_, _, err, ns_s)) in enumerate(zip(axes[2:], sources, errs)):
        _heat(ax, fig, x, y, err, RATIO, ns_s, enorm, "RdYlBu_r", axis_label("τc error", "%"))
        _contours(ax, xx, yy, e, "%.3g eV", logscale)
        _accept_contour(ax, xx, yy, err)
        ax.set_title(
            f"({'cd'[i]}) τc error, {SOURCE_LABEL[src]} (cf. fig. 50)\n"
            f"black: $E_{{diss}}$ contours [eV]; green: {PCT} (acceptance edge)",
            fontsize=10,
            loc="left",
        )
    for ax in axes[2 + len(sources) :]:
        ax.axis("off")
    add_note(fig, _map_note(pts, sw, "cross (white X on maps)"))
    set_title(
        fig,
        sw,
        "Energy dissipated per cycle over dashpot × stiffness ratio, and the τc error on the same "
        "plane (cf. thesis figs. 41 and 50)",
    )
    return fig


def _map_note(pts, sw: SweepData, cross: str) -> str:
    """The status note of a τc-error map: grey cells, the colour cap, and how a not-steady point
    is marked (``cross`` replaces the line figures' "grey cross")."""
    text = f"grey cells: no value (failed point, or VETICA found no τc); τc error colours stop at {ERR_CAP:g} %"
    return status_note(pts, sw.swept, text, regime=True).replace("grey cross", cross)


def fig_depth_error_map(sw: SweepData) -> Figure | None:
    """tau_c error over cd x set point with contours of the steady-state zero reference depth (thesis fig. 58)."""
    pts = sw.points()
    x, y, depth, _ = _grid(pts, SETPOINT, "ss_zero_depth")
    sources = sw.sources()
    errs = [_grid(sw.rows(src), SETPOINT, "tau_c_err_pct") for src in sources]
    enorm = _lognorm(*[g[2] for g in errs], cap=ERR_CAP) or LogNorm(1, 100)
    fig = new_figure(7 * len(sources), 6)
    axes = np.atleast_1d(fig.subplots(1, len(sources)))
    d_nm = depth * 1e9
    dpos = d_nm[np.isfinite(d_nm)]
    dlog = bool(len(dpos) and np.all(dpos > 0) and dpos.max() / dpos.min() > 30)
    for ax, src, (_, _, err, ns) in zip(axes, sources, errs):
        xx, yy = _heat(ax, fig, x, y, err, SETPOINT, ns, enorm, "RdYlBu_r", axis_label("τc error", "%"))
        _contours(ax, xx, yy, d_nm, "%.2g nm", dlog)
        _accept_contour(ax, xx, yy, err)
        ax.set_title(
            f"τc error, {SOURCE_LABEL[src]}\nblack: steady-state zero reference depth [nm]; green: {PCT}",
            fontsize=9.5,
            loc="left",
        )
    add_note(fig, _map_note(pts, sw, "white X"))
    set_title(
        fig,
        sw,
        "τc error against dashpot and set point, with the steady-state zero reference depth (cf. thesis fig. 58)",
    )
    return fig
