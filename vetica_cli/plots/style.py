"""Display conventions shared by every figure: units, line styles of the force sources, axis
labels of the swept keys (surface keys from their model), figure and legend helpers, and
the atomic PNG writer.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .. import surfaces
from ..io import atomic_path
from ..study.acceptance import ACCEPT_ERR_PCT

PCT = f"{ACCEPT_ERR_PCT:g} %"  # the acceptance threshold as the figures write it


ERR_FLOOR = 1e-3  # errors below this (%) are drawn at it on log axes


SOURCE_LABEL = {"true": "true force $F_{ts}$", "reconstructed": "reconstructed force (spectral inversion)"}


SOURCE_LS = {"true": "-", "reconstructed": "--"}


SOURCE_FILLED = {"true": True, "reconstructed": False}


def quantities(model: str | None = None) -> dict:
    """The quantities the study figures draw (those the surface model marks ``plotted``):
    name -> (matplotlib label, display unit, SI->display factor)."""
    qs = surfaces.get(model or surfaces.DEFAULT_MODEL).quantities
    return {k: (q.tex, q.shown_unit, q.display_scale) for k, q in qs.items() if q.plotted}


def quantity_style(q: str, i: int = 0) -> tuple[str, str]:
    """(colour, marker) of a quantity: thesis fig. 46's, else one of a cycle."""
    return Q_STYLE.get(q) or (f"C{i % 10}", "ovs^<>pPhX"[i % 10])


Q_STYLE = {  # thesis fig. 46: tau_c green crosses, Kg magenta stars, k0 black circles, k_inf blue diamonds, cd red squares
    "tau_c": ("tab:green", "P"),
    "k_g": ("m", "*"),
    "k0": ("k", "o"),
    "k_inf": ("tab:blue", "D"),
    "cd": ("tab:red", "s"),
}


OBSERVABLES = {
    "e_diss_ev": (r"$E_{diss}$", "eV per cycle", 1.0),
    "peak_force": ("peak force", "nN", 1e9),
    "max_penetration": ("max. surface penetration", "nm", 1e9),
    "contact_time": ("contact time", "µs per cycle", 1e6),
    "noncontact_time": ("non-contact time", "µs per cycle", 1e6),
    "paddle_amplitude": ("paddle amplitude", "nm", 1e9),
    "ss_zero_depth": ("steady-state zero reference depth", "nm", 1e9),
    "contact_pos_dev": ("contact position: measured - true", "pm", 1e12),
    "separation_pos_dev": ("separation position: measured - true", "pm", 1e12),
    "contact_time_dev": ("contact time: measured - true", "ns", 1e9),
    "separation_time_dev": ("separation time: measured - true", "ns", 1e9),
}


# swept keys we know: key -> (label, unit, SI->display factor, scale)
CD, RATIO, SETPOINT, F1, PS, K2 = (
    "surface.cd",
    "surface.stiffness_ratio",
    "operation.setpoint",
    "probe.f1",
    "numerics.print_step",
    "probe.k2",
)


AXES = {  # (surface keys: from their model, surface_axis())
    SETPOINT: ("amplitude set point", r"% of $A_0$", 100.0, "linear"),
    F1: ("cantilever resonance $f_1$", "kHz", 1e-3, "linear"),
    PS: ("print step PS", "ns", 1e9, "log2"),
    K2: ("paddle stiffness $k_2$", "N/m", 1.0, "linear"),
    "probe.f2": ("paddle resonance $f_2$", "kHz", 1e-3, "linear"),
    "probe.k1": ("cantilever stiffness $k_1$", "N/m", 1.0, "linear"),
    "operation.free_amplitude": ("free amplitude $A_0$", "nm", 1e9, "linear"),
}


SHORT = {SETPOINT: "set point", F1: "$f_1$", PS: "PS", K2: "$k_2$"}  # (surface keys: from their model)


def save_png(fig: Figure, target: Path) -> Path:
    with atomic_path(target) as tmp:
        FigureCanvasAgg(fig)
        _lean_log_axes(fig)
        legends_off_data(fig)
        fig.savefig(tmp, format="png", dpi=130)
    return target


def covered_points(ax, legend) -> int:
    """How many data points of ``ax`` lie inside ``legend``'s box on the canvas: the vertices of
    its lines (densified along each segment), their markers, and scatter points.  Lines drawn
    across the axes in axes coordinates (``axhline``, ``axvline``: reference lines) do not count;
    markers placed in axes coordinates (the no-value rows along the top edge) do."""
    from matplotlib.collections import PathCollection

    box = legend.get_window_extent()
    n = 0
    for art in ax.lines:
        drawn_line = art.get_linestyle() not in ("None", "none", " ", "")
        if not art.get_visible() or (drawn_line and art.get_transform() != ax.transData):
            continue
        xy = np.asarray(art.get_xydata(), float)
        if drawn_line and len(xy) > 1:
            t = np.linspace(0.0, 1.0, 9)[:-1]
            seg = xy[:-1, None, :] + (xy[1:, None, :] - xy[:-1, None, :]) * t[None, :, None]
            xy = np.concatenate([seg.reshape(-1, 2), xy[-1:]])
        n += _inside(art.get_transform(), xy, box)
    for art in ax.collections:
        if isinstance(art, PathCollection) and art.get_visible():
            n += _inside(art.get_offset_transform(), np.asarray(art.get_offsets(), float), box)
    return n


def _inside(transform, xy: np.ndarray, box) -> int:
    xy = xy[np.all(np.isfinite(xy), axis=1)] if len(xy) else xy
    if not len(xy):
        return 0
    px = transform.transform(xy)
    return int(((px[:, 0] >= box.x0) & (px[:, 0] <= box.x1) & (px[:, 1] >= box.y0) & (px[:, 1] <= box.y1)).sum())


def legends_off_data(fig: Figure) -> None:
    """A legend placed inside the axes that covers data points is moved to the right of its axes
    (where the layout makes room for it); nothing else moves."""
    fig.canvas.draw()
    moved = False
    for ax in fig.axes:
        leg = ax.get_legend()
        if leg is None or not ax.get_visible() or not ax.axison:
            continue
        if covered_points(ax, leg):
            handles, labels = leg.legend_handles, [t.get_text() for t in leg.get_texts()]
            title = leg.get_title().get_text() or None
            ax.legend(handles, labels, title=title, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                      borderaxespad=0.0)  # fmt: skip
            moved = True
    if moved:
        fig.canvas.draw()


def _lean_log_axes(fig: Figure) -> None:
    """No minor ticks on log axes spanning more than three decades: a tick per decade reads
    better there, and the minor tick artists were most of the drawing time."""
    from matplotlib.ticker import NullLocator

    for ax in fig.axes:
        for axis, lim, scale in ((ax.xaxis, ax.get_xlim, ax.get_xscale), (ax.yaxis, ax.get_ylim, ax.get_yscale)):
            if scale() != "log":
                continue
            lo, hi = sorted(lim())
            if lo > 0 and hi / lo > 1e3:
                axis.set_minor_locator(NullLocator())


def new_figure(w: float, h: float) -> Figure:
    fig = Figure(figsize=(w, h), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def axis_label(name: str, unit: str) -> str:
    return f"{name} [{unit}]" if unit else name


def add_note(fig: Figure, text: str) -> None:
    """A grey note under the axes (excluded points, how a curve was averaged); space is reserved for it."""
    if not text:
        return
    lines = max(1, math.ceil(len(text) / (fig.get_figwidth() * 15)))
    h = (0.06 + 0.14 * lines) / fig.get_figheight()
    fig.get_layout_engine().set(rect=(0, h, 1, 1 - h))
    fig.text(0.005, 0.004, text, fontsize=7.5, color="0.3", ha="left", va="bottom", wrap=True)


def axis_meta(key: str):
    """(label, unit, SI->display factor, scale) of a swept key."""
    return AXES.get(key) or _surface_axis(key) or (key, "", 1.0, "linear")


def _surface_keys(key: str):
    """(parameter or derived-key name, the model declaring it) of a ``surface.*`` key, or None."""
    sec, _, name = key.partition(".")
    if sec != "surface":
        return None
    for model in surfaces.MODELS.values():
        found = model.key_parameter(name)  # a parameter, a derived key, or an item such as arms.2.cd
        if found is not None:
            return found
    return None


def _surface_axis(key: str):
    """Axis of a swept surface key from its model: a parameter on a log axis, a derived ratio on log2."""
    found = _surface_keys(key)
    if found is None:
        return None
    name, model = found
    if name in model.derived_keys:
        return (model.derived_keys[name].label, "", 1.0, "log2")
    return (
        model.parameter_axis_labels.get(name, model.parameter_labels[name]),
        model.parameter_units[name],
        1.0,
        "log",
    )


def _short(key: str) -> str:
    """Short name of a swept key for legends."""
    found = _surface_keys(key)
    if found is None:
        return SHORT.get(key, key)
    name, model = found
    return model.derived_keys[name].short if name in model.derived_keys else model.parameter_labels[name]


def _value_text(key: str, v: float) -> str | None:
    """How a derived surface key's value is written (e.g. a ratio as 16:1), or None."""
    found = _surface_keys(key)
    if found is None or found[0] not in found[1].derived_keys:
        return None
    fmt = found[1].derived_keys[found[0]].fmt
    return fmt(v) if fmt else None


def disp(key: str, values) -> np.ndarray:
    return np.asarray(values, float) * axis_meta(key)[2]


def _fmt_value(key: str, v: float | str | bool) -> str:
    if isinstance(v, (str, bool, np.bool_)):  # text and switch keys (numerics.steady, surface.vdw_on_surface)
        return str(v)
    text = _value_text(key, v)
    if text is not None:
        return text
    _name, unit, scale, _ = axis_meta(key)
    return f"{v * scale:.3g}{' ' + unit if unit else ''}"


def set_axis(ax, key: str, which: str = "x", values=None) -> None:
    name, unit, scale, kind = axis_meta(key)
    set_label = ax.set_xlabel if which == "x" else ax.set_ylabel
    set_scale = ax.set_xscale if which == "x" else ax.set_yscale
    set_label(axis_label(name, unit))
    if kind == "log":
        set_scale("log")
    elif kind == "log2":
        set_scale("log", base=2)
        if values is not None:
            ticks = np.unique(np.asarray(values, float) * scale)
            axis = ax.xaxis if which == "x" else ax.yaxis
            if len(ticks) <= 12:
                axis.set_ticks(ticks)
                axis.set_ticks([], minor=True)
                labels = [_value_text(key, v) or f"{v:g}" for v in ticks]
                axis.set_ticklabels(labels)


def group_label(keys: list, vals: tuple) -> str:
    return ", ".join(f"{_short(k)} {_fmt_value(k, v)}" for k, v in zip(keys, vals))


def colors_for(n: int):
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    return [cmap(0.05 + 0.85 * i / max(1, n - 1)) for i in range(n)]


def series(ax, x, y, status, color, ls, marker, filled, label, floor=None, show_missing=False, missing_row=0) -> set:
    """Line through the usable points; not-steady points get a grey cross over the marker.

    With ``show_missing``, points that ran (not failed) but have no value
    (the extraction returned none, e.g. no measurable creep for tau_c) are
    drawn in the series' own colour and marker in a row along the top edge of
    the axes (row ``missing_row`` from the top, so that the rows of several
    quantities do not hide each other).  Returns the set of special markers
    drawn ({'not_steady', 'no_value'}) for the legend.
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    ran = (status != "failed") & np.isfinite(x)
    ok = ran & np.isfinite(y)
    if floor is not None:
        y = np.where(ok, np.maximum(y, floor), y)
    order = np.argsort(x[ok])
    xs, ys = x[ok][order], y[ok][order]
    ax.plot(
        xs,
        ys,
        ls=ls,
        color=color,
        marker=marker,
        ms=6,
        lw=1.4,
        mfc=color if filled else "white",
        mec=color,
        label=label,
    )
    flags = set()
    ns = ok & (status == "not_steady")
    if ns.any():
        ax.plot(x[ns], y[ns], "x", color="0.35", ms=11, mew=1.6, ls="none")
        flags.add("not_steady")
    missing = ran & ~np.isfinite(y)
    if show_missing and missing.any():
        ax.plot(
            x[missing],
            np.full(missing.sum(), 1.0 - MISSING_ROW * (missing_row + 0.5)),
            marker,
            transform=ax.get_xaxis_transform(),
            color=color,
            mfc=color if filled else "white",
            ms=6,
            ls="none",
            clip_on=False,
        )
        flags.add("no_value")
    return flags


MISSING_ROW = 0.045  # height of one row of no-value markers [fraction of the axes]


def reserve_missing_rows(axes, flags: set, rows: int) -> None:
    """Raise the top of the y axis of ``axes`` (one axes or several sharing y) so that ``rows``
    rows of no-value markers (:func:`series`) sit above every data point, in a band separated
    by a thin line; nothing when none was drawn."""
    if "no_value" not in flags or rows < 1:
        return
    axes = list(np.atleast_1d(axes))
    frac = MISSING_ROW * rows + 0.01
    lo, hi = axes[0].get_ylim()
    if axes[0].get_yscale() == "log" and lo > 0:
        top = math.exp(math.log(lo) + (math.log(hi) - math.log(lo)) / (1.0 - frac))
    else:
        top = lo + (hi - lo) / (1.0 - frac)
    for ax in axes:
        ticks = [t for t in ax.get_yticks() if lo <= t <= hi * (1 + 1e-9)]  # no tick inside the band
        minor = [t for t in ax.get_yticks(minor=True) if lo <= t <= hi * (1 + 1e-9)]
        ax.set_yticks(ticks)
        ax.set_yticks(minor, minor=True)
        ax.set_ylim(lo, top)
        ax.axhline(hi, color="0.6", lw=0.6)
        ax.text(0.005, 1.0 - frac / 2, "no value", transform=ax.transAxes, fontsize=6, color="0.4", va="center")


def extra_handles(flags: set) -> list:
    """Legend entries for the special markers of :func:`series`."""
    from matplotlib.lines import Line2D

    h = []
    if "not_steady" in flags:
        h.append(Line2D([], [], marker="x", color="0.35", ms=9, mew=1.6, ls="none", label="not steady (hit max_time)"))
    if "no_value" in flags:
        h.append(Line2D([], [], marker="^", color="0.35", ms=8, ls="none",
                        label="no value extracted: the quantity's marker\nin the band along the top edge"))  # fmt: skip
    return h


def err_axes(ax) -> None:
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(axis_label("dashpot $c_d$", "kg/s"))
    ax.grid(alpha=0.3, which="major")
    plain_log_labels(ax)


def plain_log_labels(ax) -> None:
    """On a log y axis spanning less than three decades, label ticks 0.3, 1, 3, 10 instead of 3x10^-1 ...;
    below a factor 4, switch to a linear axis."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    lo, hi = ax.get_ylim() if ax.get_yscale() == "log" else (1.0, 1e9)
    if lo > 0 and hi / lo < 4:  # less than about half a decade: a linear axis reads better
        ax.set_yscale("linear")
        ax.relim()
        ax.autoscale_view()
        return
    if lo > 0 and hi / lo < 1e3:
        fmt = FuncFormatter(lambda v, _: f"{v:g}")
        subs = np.arange(1.0, 10.0) if hi / lo < 30 else (1.0, 2.0, 3.0, 5.0)
        ax.yaxis.set_major_locator(LogLocator(base=10, subs=subs))
        ax.yaxis.set_major_formatter(fmt)
        ax.yaxis.set_minor_formatter(NullFormatter())


def outside_legend(ax, handles) -> None:
    """Legend to the right of the axes when it lists several settings (inside it would hide data)."""
    if len(handles) <= 3:
        ax.legend(handles=handles, fontsize=8, loc="best")
        return
    ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)


def legend_panel(ax, groups, colors, sources, flags, title=None) -> None:
    """Use an empty axes as the legend: colours = settings, line styles = force source."""
    from matplotlib.lines import Line2D

    ax.axis("off")
    h = [Line2D([], [], color=c, lw=3, label=lab) for (lab, _, _), c in zip(groups, colors)]
    h += [
        Line2D(
            [],
            [],
            color="0.2",
            ls=SOURCE_LS[s],
            marker="o",
            mfc="0.2" if SOURCE_FILLED[s] else "white",
            label=SOURCE_LABEL[s],
        )
        for s in sources
    ]
    h += extra_handles(flags)
    ax.legend(handles=h, loc="center", fontsize=9, title=title, ncol=2 if len(h) > 14 else 1)
