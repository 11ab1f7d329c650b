"""Runs of the ``hertz`` surface (:mod:`vetica_cli.core.mdr`), the kernel factory of
:class:`vetica_cli.surfaces.hertz.Hertz`: the element grid and its check.

The grid must reach beyond the deepest tap's contact radius and resolve it, but the
deepest tap is an outcome of the run.  So the controlled approach is first run on a
provisional grid (``PROVISIONAL`` elements over ``[0, R]``) and its last tap's depth
``d`` is the estimate: ``elements: auto`` builds the fewest elements over ``MARGIN``
contact radii of ``1.1 d`` whose elastic force is within 0.1 % of Hertz at every depth in
``[0.6, 1.1] d`` (:func:`vetica_cli.core.mdr.auto_elements`); an integer spreads that many
over the same reach.  The run is then checked at its measured deepest tap ``delta_max`` (reach of
``REACH`` contact radii, and for auto the 0.1 %), and repeated once on a grid built for
``delta_max`` if it fails.  The metadata
(``kernel.mdr``) states the grid, the depth and the grid's elastic accuracy there.
"""

from __future__ import annotations

import math

import numpy as np

from ..core import engine, mdr, session
from ..core import tapping as T

PROVISIONAL = 24  # elements of the provisional grid over [0, R] (the depth estimate)
REACH = 1.15  # the grid must reach this many contact radii of the deepest tap
MARGIN = 1.3  # the grid is built over this many contact radii of the target depth
DEPTH_MARGIN = 1.05  # a second grid: accurate over [0.9, 1.05] of the measured depth
# the first grid: accurate over this range of the approach's depth (which overshoots the steady
# depth by up to ~30 %, measured on the surface with tau 1e-8 .. 2e-3 s)
ESTIMATE_RANGE = (0.6, 1.1)


def grid_accuracy(radius: float, g: np.ndarray, w: np.ndarray, delta_max: float) -> float:
    """Largest relative error of the grid's elastic force against Hertz over ``[0.9, 1] delta_max``."""
    return mdr.grid_error(radius, g, w, 0.9 * delta_max, delta_max)


def deepest(rr: engine.RunResult, a0: float) -> float:
    """Deepest indentation of the apex in the recorded periods [m]: ``-(z_tip - a0)``."""
    return float(max(-(np.min(rr.steady[:, 1]) - a0), 0.0))


def estimate_depth(st: engine.KernelSetup, spec: engine.RunSpec, radius: float) -> float:
    """The deepest indentation [m] of the controlled approach's last period on a provisional grid
    (``PROVISIONAL`` elements over ``[0, R]``): the approach ends with the amplitude within 1 % of
    the set point, a few percent from the steady taps."""
    x, g, w = mdr.element_grid(radius, radius, PROVISIONAL)
    kern = mdr.MDRKernel(st, x, g, w)
    s = engine.new_state(spec.zc0, spec.vc0, 0.0, 0.0, spec.zb0, kern.n_state)
    ctrl = engine.Controller(st.a_sp, spec.kp, spec.ki, kern.nt, st.dt, spec.approach_rate, spec.controller_on)
    q1 = math.sqrt(st.k1 * st.m1) / st.c1
    ap = engine.approach(kern, s, ctrl, spec.n_ring, min(spec.max_periods, 200),
                         no_contact_max=None if spec.controller_on else int(10 * q1))  # fmt: skip
    if ap.last is None:
        return 0.0
    return float(max(-(ap.last[T.O_QMIN] + session.base(s) - st.a0), 0.0))


def line_kernel(cfg, st: engine.KernelSetup, spec: engine.RunSpec):
    """The MDR kernel of a scan's ``hertz`` pixels, ``(kernel, grid info)``: the grid built as
    :func:`run_hertz`'s first pass (the controlled approach's depth on the provisional grid,
    ``elements: auto`` over its ``ESTIMATE_RANGE``), once per material and line; a scan's
    pixels have no second pass (their depth differs from pixel to pixel), so the grid's elastic
    accuracy at each pixel's deepest tap is in its row's metadata (``mdr``) instead."""
    radius = cfg.probe.tip_radius
    est = estimate_depth(st, spec, radius)
    x, g, w, xm = grid(radius, cfg.surface.params["elements"], ESTIMATE_RANGE[0] * est, ESTIMATE_RANGE[1] * est)
    info = {"elements": len(g), "x_max_m": xm, "dx_m": xm / len(g), "delta_estimate_m": est, "passes": 1}
    return mdr.MDRKernel(st, x, g, w), info


def grid(radius: float, elements, lo: float, hi: float):
    """``(x, g, w, x_max)``: the element grid for depths ``[lo, hi]`` (module docstring):
    ``elements: auto`` -- the fewest elements over ``MARGIN`` contact radii of ``hi`` within
    0.1 % of Hertz over the range; an integer -- that many over the same reach."""
    if elements == "auto":
        m, xm = mdr.auto_elements(radius, hi, margin=MARGIN, delta_lo=lo)
    else:
        m, xm = int(elements), MARGIN * math.sqrt(radius * hi)
    return (*mdr.element_grid(radius, xm, m), xm)


def run_hertz(cfg, st: engine.KernelSetup, spec: engine.RunSpec):
    """Run the hertz surface to its steady state (engine.run) on a grid checked as the module
    docstring says.  Returns ``(RunResult, grid info)``."""
    radius = cfg.probe.tip_radius
    elements = cfg.surface.params["elements"]
    est = estimate_depth(st, spec, radius)
    lo, hi = ESTIMATE_RANGE[0] * est, ESTIMATE_RANGE[1] * est
    passes = 0
    while True:
        passes += 1
        x, g, w, xm = grid(radius, elements, lo, hi)
        rr = engine.run(mdr.MDRKernel(st, x, g, w), spec)
        dmax = deepest(rr, st.a0)
        a_max = math.sqrt(radius * dmax)
        acc = grid_accuracy(radius, g, w, dmax) if dmax > 0 else math.nan
        reach = xm >= REACH * a_max
        if (reach and (elements != "auto" or acc <= 1e-3)) or passes >= 2 or dmax <= 0:
            break
        lo, hi = 0.9 * dmax, DEPTH_MARGIN * dmax
    info = {
        "elements": len(g),
        "x_max_m": xm,
        "dx_m": xm / len(g),
        "delta_max_m": dmax,
        "delta_estimate_m": est,
        "contact_radius_hertz_m": a_max,
        "elastic_force_error_at_delta_max": acc,
        "reach_ok": bool(reach),
        "passes": passes,
    }
    if not reach or (elements == "auto" and not acc <= 1e-3):
        rr.warnings.append(
            f"hertz: the element grid ({len(g)} over {xm:.3g} m) does not meet its target at the deepest tap "
            f"(reach {xm / max(a_max, 1e-300):.2f} contact radii, elastic force error {acc:.2g}) after {passes} runs"
        )
    return rr, info


def kernel_of_run(cfg, st: engine.KernelSetup, run) -> mdr.MDRKernel:
    """The MDR kernel on the element grid a hertz run used (its metadata ``kernel.mdr``)."""
    info = run.info["mdr"]
    x, g, w = mdr.element_grid(cfg.probe.tip_radius, info["x_max_m"], int(info["elements"]))
    return mdr.MDRKernel(st, x, g, w)
