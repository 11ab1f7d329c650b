"""Runs of the ``hertz`` surface (:mod:`vetica_cli.core.mdr`): the element grid and its check.

The grid must reach beyond the deepest tap's contact radius and resolve it, but the
deepest tap is an outcome of the run.  So a run is made on a provisional grid
(``PROVISIONAL`` elements over ``[0, R]``, a contact radius up to the tip radius), the
deepest indentation ``delta_max`` is measured on its recorded periods, and the grid the
config asks for is built for it (``elements: auto``: :func:`vetica_cli.core.mdr.auto_elements`,
0.1 % of Hertz's force at ``delta_max``; an integer: that many over ``1.5 sqrt(R delta_max)``).
If the provisional grid already meets that accuracy and reach, its run stands; otherwise
the run is repeated on the new grid and the check repeated on it.  The metadata
(``kernel.mdr``) states the grid, the depth and the grid's elastic accuracy there.
"""

from __future__ import annotations

import math

import numpy as np

from ..core import engine, mdr

PROVISIONAL = 40  # elements of the provisional grid over [0, R]
REACH = 1.2  # the grid must reach this many contact radii of the deepest tap


def grid_accuracy(radius: float, g: np.ndarray, w: np.ndarray, delta_max: float) -> float:
    """Largest relative error of the grid's elastic force against Hertz over ``[0.9, 1] delta_max``."""
    deltas = np.linspace(0.9, 1.0, 41) * delta_max
    exact = 4.0 / 3.0 * math.sqrt(radius) * deltas**1.5
    return float(np.max(np.abs(mdr.hertz_force_grid(g, w, 1.0, deltas) / exact - 1.0)))


def deepest(rr: engine.RunResult, a0: float) -> float:
    """Deepest indentation of the apex in the recorded periods [m]: ``-(z_tip - a0)``."""
    return float(max(-(np.min(rr.steady[:, 1]) - a0), 0.0))


def run_hertz(cfg, st: engine.KernelSetup, spec: engine.RunSpec):
    """Run the hertz surface to its steady state (engine.run) on a grid checked as the module
    docstring says.  Returns ``(RunResult, grid info)``."""
    radius = cfg.probe.tip_radius
    elements = cfg.surface.params["elements"]
    x, g, w = mdr.element_grid(radius, radius, PROVISIONAL)
    passes = 0
    while True:
        passes += 1
        rr = engine.run(mdr.MDRKernel(st, x, g, w), spec)
        dmax = deepest(rr, st.a0)
        x_max = x[-1] + 0.5 * (x[1] - x[0] if len(x) > 1 else 2 * x[0])
        a_max = math.sqrt(radius * dmax)
        acc = grid_accuracy(radius, g, w, dmax) if dmax > 0 else math.nan
        ok_auto = elements == "auto" and x_max >= REACH * a_max and acc <= 1e-3
        ok_int = elements != "auto" and len(g) == elements and passes > 1
        if ok_auto or ok_int or passes >= 3 or dmax <= 0:
            break
        if elements == "auto":
            m, xm = mdr.auto_elements(radius, dmax * 1.02)  # 2 % deeper: the refined run taps a little differently
        else:
            m, xm = int(elements), 1.5 * a_max
        x, g, w = mdr.element_grid(radius, xm, m)
    info = {
        "elements": len(g),
        "x_max_m": x_max,
        "dx_m": x_max / len(g),
        "delta_max_m": dmax,
        "contact_radius_hertz_m": a_max,
        "elastic_force_error_at_delta_max": acc,
        "reach_ok": bool(x_max >= REACH * a_max),
        "passes": passes,
    }
    if elements == "auto" and not (x_max >= REACH * a_max and acc <= 1e-3):
        rr.warnings.append(
            f"hertz: the element grid ({len(g)} over {x_max:.3g} m) is not within 0.1 % of Hertz at the deepest "
            f"tap ({acc:.2g}) after {passes} runs"
        )
    return rr, info


def kernel_of_run(cfg, st: engine.KernelSetup, run) -> mdr.MDRKernel:
    """The MDR kernel on the element grid a hertz run used (its metadata ``kernel.mdr``)."""
    info = run.info["mdr"]
    x, g, w = mdr.element_grid(cfg.probe.tip_radius, info["x_max_m"], int(info["elements"]))
    return mdr.MDRKernel(st, x, g, w)
