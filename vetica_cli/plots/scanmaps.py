"""Scan figures (``vetica plot MAP``): images of a scan table -- true height,
measured topography, phase and E_diss; each extracted property beside its truth and its
signed error, per method (and force source) -- with the domain outlines of the sample
and colour bars in physical units; a line profile across a domain edge; and, for a
table of several passes, how the per-domain errors, the apparent heights and the
edge-artefact widths change with the pixel time (:mod:`vetica_cli.scan.analysis`).

Pixels are drawn as the squares they stand for (``imshow`` over the scan area, x the
fast axis to the right, y up); failed pixels are grey.  A table of fewer than
:data:`MIN_IMAGE_LINES` lines gets the profile only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from matplotlib import colormaps, patheffects
from matplotlib.colors import LogNorm, Normalize
from matplotlib.figure import Figure
from matplotlib.ticker import FixedLocator, FuncFormatter, MaxNLocator, NullLocator

from .. import surfaces
from ..errors import InputError
from ..extraction import METHODS
from ..extraction.base import ModelFreeMethod
from ..scan.analysis import (
    apparent_heights,
    domain_stats,
    estimate_names,
    edge_widths,
    grid,
    one_per_pixel,
    pass_label,
    pass_rows,
    passes,
    summary_names,
)
from ..scan.config import Pass
from ..scan.sample import feature_from_dict
from .style import add_note, axis_label, new_figure

MIN_IMAGE_LINES = 4
ERR_CAP = 100.0  # [%] the error colour scale never spans more than +-this
PIXEL_IMAGES = {  # column -> (title, display unit, SI -> display, colour map)
    "height_true": ("true height", "nm", 1e9, "copper"),
    "topography": ("topography (measured)", "nm", 1e9, "copper"),
    "phase_deg": ("phase", "deg", 1.0, "viridis"),
    "e_diss_ev": (r"$E_{diss}$", "eV per cycle", 1.0, "magma"),
}
METHOD_STYLE = [("-", "o"), ("--", "s"), (":", "^"), ("-.", "D")]


@dataclass
class ScanGeometry:
    """The raster and the sample's outlines from a scan table's metadata."""

    nx: int
    ny: int
    size: tuple
    features: list  # of vetica_cli.scan.sample.Feature
    domains: list  # names

    @classmethod
    def of(cls, df: pd.DataFrame, meta: dict) -> ScanGeometry:
        sc = meta.get("scan") or {}
        try:
            nx, ny = (int(v) for v in sc["pixels"])
            size = tuple(float(v) for v in sc["size"])
            feats = [feature_from_dict(f) for f in sc.get("features") or []]
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"scan table metadata lacks the sample's geometry ({type(exc).__name__}: {exc})") from None
        if df.empty:
            raise InputError("the scan table has no rows")
        return cls(nx, ny, size, feats, list(sc.get("domains") or []))

    @property
    def extent(self) -> list:
        return [0.0, self.size[0] * 1e6, 0.0, self.size[1] * 1e6]

    @property
    def aspect(self) -> float:
        """Width over height of the scan area."""
        return self.size[0] / self.size[1]

    def layout(self, panels: int, across: int) -> tuple[int, int, float, float]:
        """``(rows, columns, width, height)`` of a figure of ``panels`` maps, normally ``across``
        to a row: a wide area (more than 1.6 times as wide as high) gets one map per row at
        the full width, so that no map is a sliver; the height follows the area's shape."""
        if self.aspect > 1.6:
            rows, cols, width = panels, 1, 11.0
            panel_h = max(1.1, (width - 2.5) / self.aspect) + 0.9
        else:
            rows, cols = math.ceil(panels / across), across
            width = 4.3 * cols + 0.5
            panel_w = 4.3 - 1.6
            panel_h = min(9.0, panel_w / self.aspect) + 1.0
        return rows, cols, width, panel_h * rows + 0.8

    def true_line(self, y: float, n: int = 2001) -> tuple[np.ndarray, np.ndarray]:
        """``(x [m], domain)`` along the line at ``y`` on a fine grid: where each feature truly
        begins and ends, painted in order as the scan paints its pixel centres."""
        xs = np.linspace(0.0, self.size[0], n)
        dom = np.zeros(n, dtype=int)
        for k, f in enumerate(self.features, 1):
            dom[f.contains(xs, np.full(n, y))] = k
        return xs, dom

    def domain_name(self, d: int) -> str:
        return self.domains[d] if d < len(self.domains) else f"domain {d}"


def quantity_info(name: str) -> tuple[str, str, float]:
    """(matplotlib label, display unit, SI -> display) of a quantity from the model or the
    extraction method declaring it."""
    default = surfaces.get(surfaces.DEFAULT_MODEL)
    for q in (*(m.quantities.get(name) for m in surfaces.MODELS.values()),
              *(me.quantities(default).get(name) for me in METHODS.values())):  # fmt: skip
        if q is not None:
            return q.tex, q.shown_unit, q.display_scale
    return name, "", 1.0


def own_quantities(g: pd.DataFrame) -> list[str]:
    """Quantities with values in ``g`` that no surface model declares: what a method reports
    of its own instead of the model's (``observables``: ``tan_delta_am``, ...)."""
    models = {q for m in surfaces.MODELS.values() for q in m.quantities}
    return [q for q in estimate_names(g) if q not in models and g[q].notna().any()]


# the instrument's maps beside VETICA's: (method, quantity) drawn when the table has them (each method's scan_maps)
INSTRUMENT_MAPS = tuple((key, q) for key, m in METHODS.items() for q in m.scan_maps)
TRUTH_TITLES = {"tan_delta_am": r"truth: the surface's $\tan\delta$ at $f_{drive}$",
                "k_dmt": r"truth: the surface's $k'$ at $\pi/t_c$"}  # fmt: skip


def _outline(ax, geo: ScanGeometry) -> None:
    halo = [patheffects.withStroke(linewidth=2.0, foreground="k")]
    for f in geo.features:
        x, y = f.outline()
        ax.plot(x * 1e6, y * 1e6, color="w", lw=0.9, path_effects=halo)
    ax.set_xlim(geo.extent[:2])
    ax.set_ylim(geo.extent[2:])


def _image(ax, fig, geo, arr, title, unit, cmap, norm=None, extend="neither"):
    cm = fig.get_figure() if hasattr(fig, "get_figure") else fig
    cmap = colormaps[cmap].with_extremes(bad="0.75")  # failed pixels grey
    im = ax.imshow(np.ma.masked_invalid(arr), origin="lower", extent=geo.extent, cmap=cmap, norm=norm,
                   interpolation="nearest", aspect="equal")  # fmt: skip
    _outline(ax, geo)
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("x (fast axis) [µm]")
    ax.set_ylabel("y [µm]")
    ax.xaxis.set_major_locator(MaxNLocator(nbins=5))
    ax.yaxis.set_major_locator(MaxNLocator(nbins=5 if geo.aspect < 3 else 3))
    cm.colorbar(im, ax=ax, label=f"[{unit}]" if unit else "", extend=extend, shrink=0.85)


def _value_norm(*arrays) -> Normalize:
    """Log scale for values spanning more than a factor 3 (domains decades apart), else linear;
    limits from the truth and the 2-98 % range of the values."""
    v = np.concatenate([a[np.isfinite(a)].ravel() for a in arrays])
    if not len(v):
        return Normalize(0, 1)
    lo, hi = np.percentile(v, [2, 98])
    if np.isfinite(arrays[-1]).any():
        lo, hi = min(lo, np.nanmin(arrays[-1])), max(hi, np.nanmax(arrays[-1]))
    if lo > 0 and hi / lo > 3.0:
        return LogNorm(lo, hi)
    if hi <= lo:
        lo, hi = lo - abs(lo) * 0.05 - 1e-30, hi + abs(hi) * 0.05 + 1e-30
    return Normalize(lo, hi)


def fig_images(geo: ScanGeometry, rows: pd.DataFrame, title: str) -> Figure:
    """True height, topography, phase and E_diss of one pass."""
    px = one_per_pixel(rows)
    nrow, ncol, w, h = geo.layout(len(PIXEL_IMAGES), 2)
    fig = new_figure(w, h)
    axes = np.atleast_1d(fig.subplots(nrow, ncol))
    for ax, (col, (name, unit, scale, cmap)) in zip(axes.ravel(), PIXEL_IMAGES.items()):
        arr = grid(px, col, (geo.ny, geo.nx)) * scale
        norm = None
        if col in ("height_true", "topography"):  # one scale for both heights
            both = np.concatenate([px["height_true"].to_numpy(float), px["topography"].to_numpy(float)]) * scale
            both = both[np.isfinite(both)]
            norm = Normalize(float(np.min(both)), float(np.max(both)) + 1e-12) if len(both) else None
        _image(ax, fig, geo, arr, name, unit, cmap, norm)
    fig.suptitle(title, fontsize=11)
    return fig


def fig_properties(geo: ScanGeometry, g: pd.DataFrame, title: str) -> Figure:
    """Each extracted property of one pass, method and force source: value, truth, signed error."""
    qs = own_quantities(g) or [q for q in summary_names(g) if g[q].notna().any() or g[f"{q}_theory"].notna().any()]
    nrow, ncol, w, h = geo.layout(3 * len(qs), 3)
    fig = new_figure(w, h)
    axes = np.asarray(fig.subplots(nrow, ncol)).reshape(len(qs), 3)
    ok = g[g["status"] != "failed"]
    shape = (geo.ny, geo.nx)
    for row, q in zip(axes, qs):
        tex, unit, scale = quantity_info(q)
        val = grid(ok, q, shape) * scale
        truth = grid(g, f"{q}_theory", shape) * scale
        err = grid(ok, f"{q}_err_pct", shape)
        norm = _value_norm(val, truth)
        _image(row[0], fig, geo, val, f"{tex} extracted", unit, "viridis", norm)
        _image(row[1], fig, geo, truth, f"{tex} truth", unit, "viridis", _value_norm(val, truth))
        e = np.abs(err[np.isfinite(err)])
        lim = min(ERR_CAP, max(1.0, float(np.percentile(e, 98)) if len(e) else 1.0))
        over = len(e) and float(np.max(e)) > lim
        _image(row[2], fig, geo, err, f"{tex} error (signed)", "%", "RdBu_r", Normalize(-lim, lim),
               "both" if over else "neither")  # fmt: skip
    fig.suptitle(title, fontsize=11)
    failed = int((g["status"] == "failed").sum())
    add_note(fig, f"{failed} failed pixel(s) drawn grey" if failed else "")
    return fig


def fig_instrument(geo: ScanGeometry, rows: pd.DataFrame, title: str) -> Figure | None:
    """The instrument's maps beside VETICA's for one pass: VETICA's tau_c, the loss
    tangent tan d_AM from amplitude and phase, the per-tap DMT modulus and unloading stiffness
    (top: extracted, first force source; bottom: the truth -- tau_c, the surface's tan delta at
    the drive frequency, k' at pi / contact time; none for E* of a spring surface).  None when
    the table has no instrument method."""
    have = [(m, q) for m, q in INSTRUMENT_MAPS if q in rows.columns and (rows["method"] == m).any()]
    if not any(isinstance(METHODS[m], ModelFreeMethod) for m, _ in have):  # an instrument method's map
        return None
    source = rows["force_source"].iloc[0]
    fig = new_figure(4.4 * len(have), 7.0)
    axes = np.atleast_2d(fig.subplots(2, len(have))).reshape(2, len(have))
    shape = (geo.ny, geo.nx)
    for j, (m, q) in enumerate(have):
        g = rows[(rows["method"] == m) & (rows["force_source"] == source)]
        ok = g[g["status"] != "failed"]
        tex, unit, scale = quantity_info(q)
        val, truth = grid(ok, q, shape) * scale, grid(g, f"{q}_theory", shape) * scale
        norm = _value_norm(val, truth) if np.isfinite(truth).any() else _value_norm(val, val)
        _image(axes[0, j], fig, geo, val, f"{tex} ({m})", unit, "viridis", norm)
        if np.isfinite(truth).any():
            _image(axes[1, j], fig, geo, truth, TRUTH_TITLES.get(q, f"{tex} truth"), unit, "viridis", norm)
        else:
            axes[1, j].set_axis_off()
            axes[1, j].text(0.5, 0.5, f"no truth for {tex}\n(spring surfaces have no modulus)", ha="center",
                            va="center", transform=axes[1, j].transAxes, fontsize=9)  # fmt: skip
    fig.suptitle(f"{title}, {source} force: the instrument's numbers beside VETICA's", fontsize=11)
    return fig


def profile_line(geo: ScanGeometry) -> int:
    """The line through the first feature's centre (a domain edge to cross), else the middle one."""
    if not geo.features:
        return geo.ny // 2
    f = geo.features[0]
    yc = f.center[1] if f.shape == "disk" else f.corner[1] + 0.5 * f.size[1]
    return int(min(max(math.floor(yc / geo.size[1] * geo.ny), 0), geo.ny - 1))


def _shade_domains(ax, xs_um, dom) -> None:
    """Grey bands where the line truly crosses a feature (:meth:`ScanGeometry.true_line`)."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], (dom != 0).astype(int), [0]])))
    for a, b in zip(edges[::2], edges[1::2]):
        ax.axvspan(xs_um[a], xs_um[b - 1], color="0.9", zorder=0)


def _truth_along(xs_um, dom, rows: pd.DataFrame, col: str, scale: float):
    """The true ``col`` along the fine line: each domain's value (median over its pixels of the
    table) wherever the line crosses it, so the steps sit at the true edges."""
    per = rows.groupby("domain")[col].median()
    return xs_um, per.reindex(dom).to_numpy(float) * scale


def _pass_colors(ps) -> dict:
    cmap = colormaps["viridis"]
    trans = [p for p in ps if p[0] != "orbit"]
    out = {p: cmap(0.85 * i / max(1, len(trans) - 1)) for i, p in enumerate(trans)}
    out.update({p: "tab:red" for p in ps if p[0] == "orbit"})
    return out


def fig_profile(geo: ScanGeometry, df: pd.DataFrame, iy: int) -> Figure:
    """Along line ``iy``: true height and topography, and each property against its truth, for
    every pass (colour) and method (line style)."""
    line = df[df["iy"] == iy]
    qs = summary_names(df)
    ps = passes(df)
    colors = _pass_colors(ps)
    methods = list(dict.fromkeys(line["method"]))
    fig = new_figure(9.5, 2.3 * (len(qs) + 1) + 0.8)
    axes = fig.subplots(len(qs) + 1, 1, sharex=True)
    ref = one_per_pixel(line).sort_values("ix")
    every = one_per_pixel(df)
    y_line = geo.size[1] * (iy + 0.5) / geo.ny
    xs, dom = geo.true_line(y_line)
    xs_um = xs * 1e6
    for ax in axes:
        _shade_domains(ax, xs_um, dom)
    axes[0].plot(*_truth_along(xs_um, dom, every, "height_true", 1e9), color="k", lw=1.2, label="true height")
    for p in ps:
        px = one_per_pixel(pass_rows(line, p)).sort_values("ix")
        axes[0].plot(px["x"] * 1e6, px["topography"] * 1e9, "o-", ms=3, lw=1, color=colors[p], label=pass_label(p))
    axes[0].set_ylabel(axis_label("height", "nm"))
    axes[0].legend(fontsize=7, ncol=min(4, len(ps) + 1), loc="best", title="topography", title_fontsize=7)
    for ax, q in zip(axes[1:], qs):
        tex, unit, scale = quantity_info(q)
        ax.plot(*_truth_along(xs_um, dom, every, f"{q}_theory", scale), color="k", lw=1.2, label="truth")
        for p in ps:
            pr = pass_rows(line, p)
            for j, m in enumerate(methods):
                s = pr[(pr["method"] == m) & (pr["status"] != "failed")].drop_duplicates("ix").sort_values("ix")
                ls, mk = METHOD_STYLE[j % len(METHOD_STYLE)]
                ax.plot(s["x"] * 1e6, s[q] * scale, ls=ls, marker=mk, ms=3, lw=1, color=colors[p],
                        label=m if p == ps[0] else None)  # fmt: skip
        v = np.concatenate([ref[f"{q}_theory"].to_numpy(float), line[q].to_numpy(float)])
        v = v[np.isfinite(v) & (v > 0)]
        if len(v) and v.max() / v.min() > 10:
            ax.set_yscale("log")
        ax.set_ylabel(axis_label(tex, unit))
        ax.legend(fontsize=7, ncol=len(methods) + 1, loc="best")
    axes[-1].set_xlabel("x (fast axis, scan direction →) [µm]")
    fig.suptitle(f"Profile along line {iy} (y = {y_line * 1e6:.3g} µm): true values (black) against the measured "
                 "(colours: passes; line style: method);\ngrey bands: where the line crosses a feature (true edges)",
                 fontsize=10)  # fmt: skip
    return fig


def fig_pixel_time(geo: ScanGeometry, df: pd.DataFrame) -> Figure:
    """Per-domain median error of each property, apparent height difference and edge-artefact
    width against the pixel time (orbit passes as horizontal reference lines)."""
    st, ah, ew = domain_stats(df), apparent_heights(df), edge_widths(df)
    qs = summary_names(df)
    n = len(qs) + 2
    ncol = 3
    fig = new_figure(13.0, 3.2 * math.ceil(n / ncol) + 0.5)
    axes = fig.subplots(math.ceil(n / ncol), ncol, squeeze=False).ravel()
    for ax in axes[n:]:
        ax.set_visible(False)
    methods = list(dict.fromkeys(df["method"]))
    doms = sorted(set(st["domain"])) if len(st) else []
    for ax, q in zip(axes, qs):
        tex = quantity_info(q)[0]
        for d in doms:
            for j, m in enumerate(methods):
                s = st[(st["quantity"] == q) & (st["domain"] == d) & (st["method"] == m)]
                _vs_time(ax, s, "median_err_pct", f"C{d}", METHOD_STYLE[j % 4], f"{geo.domain_name(d)}, {m}")
        ax.axhline(0.0, color="0.5", lw=0.6)
        ax.set_yscale("symlog", linthresh=1.0)
        ax.set_ylabel(f"{tex}: median error [%]")
    ax = axes[len(qs)]
    for d in sorted(set(ah["domain"]) - {0}) if len(ah) else []:
        s = ah[ah["domain"] == d].assign(v=lambda t: t["apparent_dh"] * 1e9)
        _vs_time(ax, s, "v", f"C{d}", METHOD_STYLE[0], f"{geo.domain_name(d)} apparent")
        ax.axhline(float(s["true_dh"].iloc[0]) * 1e9, color=f"C{d}", lw=0.8, ls=(0, (1, 3)))
    ax.set_ylabel(r"apparent $\Delta h$ [nm] (dotted: true)")
    ax = axes[len(qs) + 1]
    first = methods[0] if methods else ""
    for i, q in enumerate(["topography", *qs]):
        s = ew[(ew["quantity"] == q) & ((ew["method"] == first) | (q == "topography"))]
        label = "topography" if q == "topography" else quantity_info(q)[0]
        _vs_time(ax, s, "median_px", f"C{i}", METHOD_STYLE[0], label)
    ax.set_ylabel(f"edge artefact width [px] ({first})")
    times = sorted({float(t) * 1e3 for st_, t in passes(df) if st_ == "transient"})
    for ax in axes[:n]:
        ax.set_xscale("log")
        ax.xaxis.set_major_locator(FixedLocator(times))
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.xaxis.set_minor_locator(NullLocator())
        ax.set_xlabel("pixel time [ms] (dash-dot: orbit)")
        ax.legend(fontsize=6)
    fig.suptitle("against the pixel time (interior pixels; medians)", fontsize=11)
    return fig


def _vs_time(ax, s: pd.DataFrame, col: str, color, style, label) -> None:
    """``col`` against the pixel time of the transient passes; an orbit pass as a horizontal line."""
    if s.empty:
        return
    tr = s[s["steady"] == "transient"].sort_values("pixel_time")
    ls, mk = style
    ax.plot(tr["pixel_time"] * 1e3, tr[col], ls=ls, marker=mk, ms=4, color=color, label=label)
    for v in s.loc[s["steady"] == "orbit", col]:
        ax.axhline(v, color=color, ls="-.", lw=0.8)


def scan_figures(df: pd.DataFrame, meta: dict) -> tuple[list, list]:
    """[(name, Figure)], [notes] for a scan table (module docstring)."""
    geo = ScanGeometry.of(df, meta)
    ps = passes(df)
    figs, notes = [], []
    name = (meta.get("scan") or {}).get("name", "scan")
    for p in ps:
        rows = pass_rows(df, p)
        slug = "" if len(ps) == 1 else Pass(p[0], p[1]).slug() + "_"
        if geo.ny < MIN_IMAGE_LINES:
            continue
        figs.append((f"{slug}images", fig_images(geo, rows, f"{name}: {Pass(*p).label()}")))
        inst = fig_instrument(geo, rows, f"{name}: {Pass(*p).label()}")
        if inst is not None:
            figs.append((f"{slug}instrument", inst))
        groups = list(rows.groupby(["method", "force_source"], sort=False))
        for (method, source), g in groups:
            tag = method if len(set(rows["force_source"])) == 1 else f"{method}_{source}"
            figs.append(
                (f"{slug}{tag}", fig_properties(geo, g, f"{name}: {Pass(*p).label()}, {method}, {source} force"))
            )
    if geo.ny < MIN_IMAGE_LINES:
        notes.append(f"{geo.ny} line(s): no images (fewer than {MIN_IMAGE_LINES}), the profile only")
    figs.append(("profile", fig_profile(geo, df, profile_line(geo))))
    if len(ps) > 1:
        figs.append(("pixel_time", fig_pixel_time(geo, df)))
    return figs, notes
