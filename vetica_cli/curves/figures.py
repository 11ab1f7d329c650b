"""Figures of a ``vetica fit`` batch: each curve's data against its fits, histograms of the
selected rows' parameters, and, for every file that is a force map, a map of every parameter.

The model curves are computed again from the table's rows and the curves (one evaluation of
the forward model each), so a batch resumed from persisted parts draws every curve.  File
names come from the file's label (the shortest tail of its path that tells it apart from the
others), so two curves of the same name in two folders do not overwrite each other.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..io import atomic_path

PARAMS = ("e_hertz", "e0", "beta", "e_inf", "e_1", "e_2", "e_3", "tau_1", "tau_2", "tau_3")
UNITS = {"beta": "", "tau_1": "s", "tau_2": "s", "tau_3": "s"}


def safe(name: str) -> str:
    """A file-name fragment of a label: path separators and odd characters to '_'."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("_")


def _save(fig, path: Path) -> Path:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=path.suffix[1:], dpi=110)
    return path


def unit(p: str) -> str:
    return UNITS.get(p, "Pa")


def _fd_axes(ax, curve, rows, tip_radius, nu, points):
    from .fd import FDProblem, model_force

    prob = FDProblem(curve, tip_radius, nu, points)
    ax.plot(prob.t, prob.f * 1e9, color="k", lw=2.2, label="data (binned)")
    for r in rows:
        lab = ("power law: e0 = %.3g Pa, beta = %.3f" % (r["e0"], r["beta"]) if r["modulus"] == "power-law"
               else f"{int(r['arms'])} arm{'s' * (r['arms'] > 1)}: e_inf = {r['e_inf']:.3g} Pa")  # fmt: skip
        mark = " (selected)" if r["selected"] else ""
        ax.plot(prob.t, model_force(prob, r) * 1e9, lw=1.2, label=f"Ting, {lab}{mark} [{r['status']}]")
    r = rows[0]
    app = prob.approach
    ax.plot(prob.t[app], prob.hertz(r["contact_hertz"], r["e_hertz"])[app] * 1e9, ls="--", lw=1,
            color="0.5", label=f"Hertz on the approach: {r['e_hertz']:.3g} Pa")  # fmt: skip
    ax.set_title(f"{curve.name}: Ting fits (approach and retract)", fontsize=9)


def _dwell_axes(ax, curve, rows, tip_radius, nu, window):
    from .fit import Problem

    r0 = rows[0]
    prob = Problem(curve, tip_radius, nu, r0["contact"], window)
    ax.plot(prob.t, prob.f * 1e9, color="k", lw=2.2, label="data")
    for r in rows:
        n = int(r["arms"])
        taus = [r[f"tau_{k}"] for k in range(1, n + 1)]
        f = prob.model(r["contact"], r["e_inf"], [r[f"e_{k}"] for k in range(1, n + 1)], taus)
        mark = " (selected)" if r["selected"] else ""
        ax.plot(prob.t, f * 1e9, lw=1, label=f"{n} arm{'s' * (n > 1)}: tau = "
                + ", ".join(f"{x:.3g}" for x in taus) + f" s{mark} [{r['status']}]")  # fmt: skip
    ax.set_title(f"{curve.name}: Lee-Radok fits", fontsize=9)


def write_figures(df, curves, folder, points: int = 400) -> list[Path]:
    """``fit_<file>_<curve>.png`` per fitted curve, ``parameters.png`` and, for each file that
    is a force map, ``map_<file>_<param>.png`` of every parameter; returns the paths written."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return [_save(fig, folder / f"{name}.png") for name, fig in build_figures(df, curves, points)]


def build_figures(df, curves, points: int = 400):
    """``(name, figure)`` of :func:`write_figures`, one at a time (matplotlib Agg; the caller
    saves and closes each); ``curves`` may be empty (a table drawn without its files:
    histograms and maps only)."""
    from matplotlib.figure import Figure

    tip_radius, nu = float(df["tip_radius"].iloc[0]), float(df["nu"].iloc[0])
    fitted = df[~df["status"].isin(("unreadable", "unsuited", "failed"))]
    by_curve = {key: g for key, g in fitted.groupby(["path", "curve"])}
    for c in curves:
        g = by_curve.get((c.source, c.index))
        if g is None:
            continue
        rows = g.to_dict("records")
        fig = Figure(figsize=(6.4, 3.8))
        ax = fig.subplots()
        try:
            if rows[0]["model"] == "ting":
                _fd_axes(ax, c, rows, tip_radius, nu, points)
            else:
                _dwell_axes(ax, c, rows, tip_radius, nu, rows[0].get("window", "dwell"))
        except Exception as exc:  # noqa: BLE001 - a figure that cannot be drawn must not lose the batch
            ax.text(0.5, 0.5, f"cannot draw: {exc}", ha="center", transform=ax.transAxes, fontsize=8)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("force [nN]")
        ax.legend(fontsize=6)
        fig.tight_layout()
        yield f"fit_{safe(c.label)}_{c.index}", fig
    sel = fitted[fitted["selected"] & (fitted["status"] == "ok")]
    params = [p for p in PARAMS if p in sel and sel[p].notna().any()]
    if params:
        fig = Figure(figsize=(2.3 * len(params), 2.6))
        axes = fig.subplots(1, len(params))
        for ax, p in zip(np.atleast_1d(axes), params):
            v = sel[p].dropna()
            ax.hist(v, bins=max(5, int(np.sqrt(len(v)))), color="0.4")
            ax.set_xlabel(f"{p} [{unit(p)}]" if unit(p) else p)
        np.atleast_1d(axes)[0].set_ylabel("curves (selected, ok)")
        fig.tight_layout()
        yield "parameters", fig
    yield from map_figures(df)


def map_figures(df):
    """``(name, figure)`` per force-map file and parameter: the selected row of each grid point
    (grey: flagged; blank: not measured)."""
    from matplotlib.figure import Figure

    sel = df[df["selected"] & (df["grid_x"] >= 0) & (df["grid_y"] >= 0)]
    for label, g in sel.groupby("file"):
        if len(g) < 2:
            continue
        nx, ny = int(g["grid_x"].max()) + 1, int(g["grid_y"].max()) + 1
        for p in [p for p in PARAMS if p in g and g[p].notna().any()]:
            img = np.full((ny, nx), np.nan)
            ok = g[g["status"] == "ok"]
            img[ok["grid_y"].astype(int), ok["grid_x"].astype(int)] = ok[p]
            flagged = np.zeros((ny, nx), bool)
            bad = g[g["status"] != "ok"]
            flagged[bad["grid_y"].astype(int), bad["grid_x"].astype(int)] = True
            fig = Figure(figsize=(4.2, 3.5))
            ax = fig.subplots()
            ax.imshow(np.where(flagged, 1.0, np.nan), origin="lower", cmap="Greys", vmin=0, vmax=2)
            im = ax.imshow(img, origin="lower")
            fig.colorbar(im, ax=ax, label=f"{p} [{unit(p)}]" if unit(p) else p)
            ax.set_xlabel("grid x")
            ax.set_ylabel("grid y")
            ax.set_title(f"{label}: {p} (grey: flagged)", fontsize=8)
            fig.tight_layout()
            yield f"map_{safe(label)}_{p}", fig
