"""Figures a reader understands without the documentation: every figure kind, drawn for a
non-square scan, a one-point sweep, a sweep with missing values and a cheap run, has a title,
axis labels with units, a legend (or colour bars for maps) that covers no data point, and the
specific promises: a no-value marker says which quantity is missing, the shaded acceptance
regime is exactly the stated range, figures of the run's observables do not mention missing
estimates, and a scan profile draws the features' true edges.

The tables are synthetic (the schema ``vetica sweep`` / ``vetica scan`` write, physics-free
numbers); what is checked is what a reader sees, on the figures as ``vetica plot`` saves them
(``save_png``, which also moves a legend that would cover data).  Geometry is checked on the
canvas: a legend's box against the display positions of the line vertices and markers."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest
from matplotlib.colorbar import Colorbar  # noqa: F401  (colour bars are axes with a colorbar attribute)

from vetica_cli.plots.run import run_figures
from vetica_cli.plots.scanmaps import ScanGeometry, scan_figures
from vetica_cli.plots.study import sweep_figures
from vetica_cli.plots.style import save_png
from vetica_cli.study.acceptance import regime

QUANTITIES = ("tau_c", "k_g", "k_r", "tau_r", "k0", "k_inf", "cd")
BASE = {
    "probe": {"f1": 50e3, "f2": 750e3, "k1": 10.0, "k2": 700.0, "q1": 100.0, "q2": 1000.0, "tip_radius": 10e-9},
    "operation": {"free_amplitude": 100e-9, "setpoint": 0.7},
    "surface": {"k_inf": 4.0, "stiffness_ratio": 16.0, "hamaker": 0.2e-18, "a0": 0.2e-9, "vdw_on_surface": True},
    "numerics": {"dt": 0.025e-9, "print_step": 0.5e-9},
}
UNIT = re.compile(r"\[[^\]]+\]")


def theory(cd: float) -> dict:
    k_inf, k0 = 4.0, 64.0
    kg = k0 + k_inf
    return {"tau_c": cd * kg / (k0 * k_inf), "k_g": kg, "k_r": k_inf, "tau_r": cd / k0, "k0": k0, "k_inf": k_inf,
            "cd": cd}  # fmt: skip


def sweep_table(cds, missing_from: float | None = None) -> tuple[pd.DataFrame, dict]:
    """A cd sweep; from ``missing_from`` on, VETICA gives no tau_c (and so no k0, k_inf, cd) while
    Kg stays (status no_estimate), as at the slow end of the thesis's dashpot study."""
    rows = []
    for i, cd in enumerate(cds):
        th = theory(cd)
        for src, scale in (("true", 1.0), ("reconstructed", 1.5)):
            row = {"surface.cd": cd, "force_source": src, "method": "vetica"}
            gone = missing_from is not None and cd >= missing_from
            for q, v in th.items():
                err = scale * (1.0 + 5.0 * abs(np.log10(cd) + 3.5)) * (1 + 0.1 * (i % 3))
                lost = gone and q not in ("k_g",)
                row[q] = np.nan if lost else v * (1 + err / 100)
                row[f"{q}_theory"] = v
                row[f"{q}_err_pct"] = np.nan if lost else err
            row.update(e_diss_ev=50.0 / (1 + cd * 1e3), peak_force=5e-9, max_penetration=2e-9, contact_time=1.5e-6,
                       noncontact_time=18.5e-6, paddle_amplitude=0.6e-9, ss_zero_depth=1e-9 * (1 + cd),
                       amplitude=70e-9, phase_deg=50.0, stop_reason="steady",
                       status="no_estimate" if gone else "ok", error="stage 1a: no creep interval" if gone else "",
                       wall_s=1.0)  # fmt: skip
            rows.append(row)
    sweep = {"surface.cd": [float(c) for c in cds]}
    return pd.DataFrame(rows), {"config": dict(BASE, sweep=sweep), "units": {"tau_c": "s"}}


SOFT = {"k_inf": 2.0, "k0": 32.0, "cd": 3e-4}
HARD = {"k_inf": 4.0, "k0": 128.0, "cd": 3e-5}


def scan_table() -> tuple[pd.DataFrame, dict]:
    """A 12 x 4 scan over 1.2 x 0.4 um (three times as wide as high), a disk whose edges fall
    between pixel centres, two passes (0.5 ms and the orbit), VETICA and the whole-cycle fit."""
    nx, ny, size = 12, 4, (1.2e-6, 0.4e-6)
    disk = {"shape": "disk", "center": [0.63e-6, 0.2e-6], "radius": 0.27e-6, "height": 3e-9,
            "surface": dict(SOFT, hamaker=0.2e-18, a0=0.2e-9, vdw_on_surface=True)}  # fmt: skip
    geo_meta = {"name": "wide", "pixels": [nx, ny], "size": list(size), "features": [disk],
                "domains": ["background", "feature 1 (disk)"]}  # fmt: skip
    geo = ScanGeometry.of(pd.DataFrame({"x": [0.0]}), {"scan": geo_meta})
    rows = []
    for steady, pt in (("transient", 0.5e-3), ("orbit", np.nan)):
        for iy in range(ny):
            for ix in range(nx):
                x, y = (ix + 0.5) * size[0] / nx, (iy + 0.5) * size[1] / ny
                dom = int(geo.features[0].contains(np.array([x]), np.array([y]))[0])
                mat = SOFT if dom else HARD
                kg = mat["k0"] + mat["k_inf"]
                th = {"k_inf": mat["k_inf"], "k0": mat["k0"], "cd": mat["cd"],
                      "tau_c": mat["cd"] * kg / (mat["k0"] * mat["k_inf"])}  # fmt: skip
                for j, method in enumerate(("vetica", "full")):
                    row = {"steady": steady, "pixel_time": pt, "ix": ix, "iy": iy, "x": x, "y": y, "domain": dom,
                           "height_true": 3e-9 * dom, "topography": 3e-9 * dom * 0.8, "method": method,
                           "force_source": "reconstructed", "phase_deg": 50.0 + 3 * dom, "e_diss_ev": 40.0 + 60 * dom,
                           "status": "ok", "error": "", "stop_reason": "steady", "wall_s": 0.1}  # fmt: skip
                    for q, v in th.items():
                        e = (2.0 + ix % 3) * (1 + j) * (1 if steady == "transient" else 0.3)
                        row.update({q: v * (1 + e / 100), f"{q}_theory": v, f"{q}_err_pct": e})
                    rows.append(row)
    return pd.DataFrame(rows), {"table": "scan", "scan": geo_meta}


# ----------------------------------------------------------------------------- what a reader needs


def data_points_under(ax, legend) -> int:
    """Line vertices (and segment midpoints) drawn in data coordinates, and markers in any
    coordinates, that lie inside the legend's box on the canvas."""
    box = legend.get_window_extent()
    n = 0
    for line in ax.lines:
        has_line = line.get_linestyle() not in ("None", "none", "", " ")
        if not line.get_visible() or (has_line and line.get_transform() != ax.transData):
            continue  # reference lines across the axes (axhline, axvline)
        xy = np.asarray(line.get_xydata(), float)
        if has_line and len(xy) > 1:
            xy = np.concatenate([xy, 0.5 * (xy[1:] + xy[:-1])])
        xy = xy[np.isfinite(xy).all(axis=1)]
        if len(xy):
            px = line.get_transform().transform(xy)
            n += int(((px[:, 0] > box.x0) & (px[:, 0] < box.x1) & (px[:, 1] > box.y0) & (px[:, 1] < box.y1)).sum())
    return n


def x_range(patch) -> tuple[float, float]:
    """The x extent of an axvspan (a Rectangle, or a Polygon in older matplotlib)."""
    if hasattr(patch, "get_width"):
        return patch.get_x(), patch.get_x() + patch.get_width()
    xs = np.asarray(patch.get_xy())[:, 0]
    return float(xs.min()), float(xs.max())


def check_readable(name: str, fig, tmp_path) -> None:
    save_png(fig, tmp_path / f"{name}.png")  # as vetica plot saves it (the layout is final)
    title = fig._suptitle.get_text() if fig._suptitle is not None else ""
    axes = [ax for ax in fig.axes if ax.get_visible() and ax.axison]
    assert title or any(ax.get_title() or ax.get_title(loc="left") for ax in axes), f"{name}: no title"
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None] + list(fig.legends)
    bars = [ax for ax in axes if ax.get_label() == "<colorbar>"]
    images = [ax for ax in axes if ax.images]
    if images:
        assert len(bars) == len(images), f"{name}: a map without its colour bar"
    series = max((sum(ln.get_transform() == ax.transData and len(ln.get_xdata()) > 1 for ln in ax.lines)
                  for ax in axes), default=0)  # fmt: skip
    assert legends or series < 2, f"{name}: several series and no legend"
    for ax in axes:
        if ax in bars:
            assert UNIT.search(ax.get_ylabel() + ax.get_xlabel()), f"{name}: colour bar without a unit"
            continue
        if not (ax.lines or ax.images or ax.collections or ax.patches):
            continue
        for which, label, axis in (("x", ax.get_xlabel(), ax.xaxis), ("y", ax.get_ylabel(), ax.yaxis)):
            categorical = type(axis.get_major_formatter()).__name__ == "FixedFormatter"
            group = ax.get_shared_x_axes() if which == "x" else ax.get_shared_y_axes()
            get = (lambda a: a.get_xlabel()) if which == "x" else (lambda a: a.get_ylabel())  # noqa: E731
            shared = not label and any(o is not ax and get(o) and group.joined(ax, o) for o in axes)
            if categorical or shared:  # a shared axis is labelled once
                continue
            assert UNIT.search(label), f"{name}: {which} label {label!r} has no unit in brackets"
    for ax in fig.axes:
        leg = ax.get_legend()
        if leg is not None:
            assert data_points_under(ax, leg) == 0, f"{name}: the legend of {ax.get_title()!r} covers data"


# ----------------------------------------------------------------------------- sweeps


CDS = np.logspace(-5, -1, 9)


def test_every_sweep_figure_with_missing_values_reads_on_its_own(tmp_path):
    df, meta = sweep_table(CDS, missing_from=3e-3)
    figs, _notes = sweep_figures(df, meta)
    assert {n for n, _ in figs} >= {"fig43-46_errors_vs_cd", "fig43-45_values_vs_cd", "fig41_ediss_vs_cd"}
    for name, fig in figs:
        check_readable(name, fig, tmp_path)


def test_no_value_markers_say_which_quantity_is_missing():
    """Each quantity without a value is drawn in its own colour and marker in its own row of the
    band above the data; a quantity with every value (Kg) has no such marker."""
    df, meta = sweep_table(CDS, missing_from=3e-3)
    fig = dict(sweep_figures(df, meta)[0])["fig43-46_errors_vs_cd"]
    ax = fig.axes[0]
    top = [ln for ln in ax.lines if ln.get_transform() != ax.transData and ln.get_linestyle() in ("None", "none")]
    rows = {(ln.get_marker(), round(float(ln.get_ydata()[0]), 3)) for ln in top}
    plotted = {"tau_c", "k_g", "k0", "k_inf", "cd"}  # the quantities drawn (Kr, tau_r are not)
    missing = plotted - {"k_g"}
    assert len(rows) == len(missing)  # one row each, none shared
    assert len({m for m, _ in rows}) == len(missing)  # each with its quantity's own marker
    lo, _ = ax.get_ylim()
    data_top = max(np.nanmax(ln.get_ydata()) for ln in ax.lines if ln.get_transform() == ax.transData
                   and len(ln.get_ydata()) > 1)  # fmt: skip
    assert all(y > ax.transAxes.inverted().transform(ax.transData.transform((1.0, data_top)))[1] for _, y in rows)


def test_shaded_regime_is_exactly_the_stated_range():
    df, meta = sweep_table(CDS, missing_from=3e-3)
    fig = dict(sweep_figures(df, meta)[0])["fig43-46_errors_vs_cd"]
    for ax, src in zip(fig.axes, ("true", "reconstructed")):
        rng = regime(df[df["force_source"] == src])
        spans = [p for p in ax.patches if p.get_label().startswith("acceptance regime")]
        assert rng is not None and len(spans) == 1
        x0, x1 = x_range(spans[0])
        assert x0 == pytest.approx(rng.lo, rel=1e-12, abs=0.0) and x1 == pytest.approx(rng.hi, rel=1e-12, abs=0.0)
        assert f"{rng.lo:.2g} to {rng.hi:.2g}" in ax.get_title()


def test_observable_figures_do_not_mention_missing_estimates():
    df, meta = sweep_table(CDS, missing_from=3e-3)
    figs = dict(sweep_figures(df, meta)[0])
    notes = lambda fig: " ".join(t.get_text() for t in fig.texts)  # noqa: E731
    assert "without an estimate" in notes(figs["fig43-46_errors_vs_cd"])
    for name in ("fig41_ediss_vs_cd", "fig57_ss_zero_depth_vs_cd"):
        assert "estimate" not in notes(figs[name]), name


def test_a_one_point_sweep_draws_readable_figures_or_says_why_not(tmp_path):
    df, meta = sweep_table([3e-5])
    try:
        figs, notes = sweep_figures(df, meta)
    except Exception as exc:  # a one-line refusal is a readable answer too
        assert type(exc).__name__ == "InputError" and "\n" not in str(exc)
        return
    assert figs or notes
    for name, fig in figs:
        check_readable(name, fig, tmp_path)


# ----------------------------------------------------------------------------- scans and runs


def test_every_figure_of_a_non_square_scan_reads_on_its_own(tmp_path):
    df, meta = scan_table()
    figs, _notes = scan_figures(df, meta)
    names = {n for n, _ in figs}
    assert {"profile", "pixel_time"} <= names and any(n.endswith("images") for n in names)
    for name, fig in figs:
        check_readable(name, fig, tmp_path)
        for ax in fig.axes:
            if ax.images:  # a map keeps the area's shape and is not a sliver
                bb = ax.get_window_extent()
                assert bb.width / bb.height == pytest.approx(3.0, rel=0.05), name
                assert bb.height > 60, name


def test_scan_profile_draws_the_true_feature_edges(tmp_path):
    """The disk (centre 0.63 um, radius 0.27 um) crosses the profile line at y = 0.25 um, between
    pixel centres: the grey band and the truth's step sit at the chord's true ends (0.36 .. 0.90 um
    at y = 0.2 um minus the offset of the line), not at pixel boundaries."""
    df, meta = scan_table()
    fig = dict(scan_figures(df, meta)[0])["profile"]
    geo = ScanGeometry.of(df, meta)
    y = geo.size[1] * (2 + 0.5) / geo.ny  # the profile line through the disk's centre: iy = 2
    half = np.sqrt(0.27e-6**2 - (y - 0.2e-6) ** 2)
    want = ((0.63e-6 - half) * 1e6, (0.63e-6 + half) * 1e6)
    ax = fig.axes[0]
    bands = [p for p in ax.patches if p.get_facecolor()[:3] == pytest.approx((0.9, 0.9, 0.9))]
    assert len(bands) == 1
    xs = x_range(bands[0])
    step = geo.size[0] * 1e6 / 2000  # the fine line's spacing
    assert min(xs) == pytest.approx(want[0], abs=step) and max(xs) == pytest.approx(want[1], abs=step)
    pitch = geo.size[0] * 1e6 / geo.nx
    assert abs(min(xs) / pitch - round(min(xs) / pitch)) > 0.05  # not a pixel boundary


@pytest.mark.slow
def test_every_run_figure_reads_on_its_own(tmp_path):
    """The run figures (trajectories, force loop, reconstruction, 4-D curve) of a cheap worked example."""
    from vetica_cli.io import read_table, write_run
    from vetica_cli.simulation.config import load
    from vetica_cli.simulation.simulate import simulate

    path = tmp_path / "run.parquet"
    cheap = {"numerics.dt": 0.05e-9, "numerics.print_step": 0.5e-9, "numerics.record_cycles": 3}
    write_run(simulate(load(None, cheap)), path)
    df, meta = read_table(path)
    figs, _notes = run_figures(df, meta, None)
    assert len(figs) >= 3
    for name, fig in figs:
        check_readable(name, fig, tmp_path)
