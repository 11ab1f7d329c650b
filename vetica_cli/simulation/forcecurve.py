"""The ``hertz`` surface (a sphere on a generalized-Maxwell half-space, by the method of
dimensionality reduction: :mod:`vetica_cli.core.mdr`) driven as an approach–retract force curve.

The tip's indentation follows a prescribed ramp: out of contact for ``pre`` of the loading
time, then down at a constant rate to ``depth``, back up at the same rate, and on until the
record's end (``post`` of the loading time after the indentation is back at zero).  The MDR
kernel gives the force (Lee–Radok while the contact grows, Ting's solution while it shrinks,
the surface recovering element by element; no adhesion, no van der Waals).  A cantilever of
stiffness ``k`` in series bends by ``F/k``, so the record's height (increasing away from the
sample) is ``h = contact_height - δ - F/k`` -- what ``vetica fit`` reads from a file, where the
indentation is recovered as ``(contact - h) - F/k``.  (An instrument drives the base at a
constant rate instead and the tip lags; the record is self-consistent either way, and a fit
uses the recorded ``h`` and ``F`` only.)

The element grid reaches 1.5 contact radii of ``depth`` with ``elements`` elements (default:
the fewest within 0.1 % of Hertz's elastic force over the deepest tenth,
:func:`vetica_cli.core.mdr.auto_elements`); the kernel runs ``substeps`` steps per sample.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core import mdr


@dataclass
class ForceCurveRecord:
    """A simulated force curve, SI units: ``segment`` 0 approach, 2 retract (afmformats' order)."""

    t: np.ndarray  # [s]
    force: np.ndarray  # [N], repulsive > 0
    height: np.ndarray  # [m], increasing away from the sample
    indentation: np.ndarray  # [m], the prescribed tip indentation (negative: out of contact)
    segment: np.ndarray
    contact_height: float  # [m]
    spring_constant: float  # [N/m]
    elements: int


def triangle(t: np.ndarray, t_contact: float, t_turn: float, depth: float) -> np.ndarray:
    """The indentation [m] of a ramp that reaches the surface at ``t_contact``, ``depth`` at
    ``t_turn`` and goes back at the same rate (negative before the contact and after the tip has
    left)."""
    v = depth / (t_turn - t_contact)
    return np.where(t <= t_turn, v * (t - t_contact), depth - v * (t - t_turn))


def hertz_force_curve(tip_radius: float, nu: float, e_inf: float, e, tau, depth: float = 1e-6,
                      t_load: float = 0.5, rate: float = 2000.0, spring_constant: float = 0.05,
                      pre: float = 0.5, post: float = 0.3, contact_height: float = 10e-6,
                      elements: int | None = None, substeps: int = 4) -> ForceCurveRecord:  # fmt: skip
    """A force curve of the ``hertz`` surface (moduli [Pa], times [s], module docstring):
    loading over ``t_load`` [s] to ``depth`` [m], sampled at ``rate`` [Hz]."""
    t_contact = pre * t_load
    t_turn = t_contact + t_load
    t_end = t_turn + t_load + post * t_load
    n = int(round(t_end * rate)) + 1
    t = np.arange(n) / rate
    n_fine = (n - 1) * substeps + 1
    t_fine = np.arange(n_fine) / (rate * substeps)
    delta_fine = triangle(t_fine, t_contact, t_turn, depth)
    s = 1.0 - nu * nu
    e_s = np.asarray(e, float) / s
    tau = np.asarray(tau, float)
    if elements is None:
        m, x_max = mdr.auto_elements(tip_radius, depth)
    else:
        m, x_max = int(elements), 1.5 * math.sqrt(tip_radius * depth)
    x, g, w = mdr.element_grid(tip_radius, x_max, m)
    f_fine, _, _, _ = mdr.run_prescribed(x, g, w, e_inf / s, e_s, e_s * tau, -delta_fine, t_fine[1], energy=False)
    force = f_fine[::substeps].copy()
    delta = delta_fine[::substeps].copy()
    height = contact_height - delta - force / spring_constant
    segment = np.where(t <= t_turn + 0.5 / rate, 0, 2).astype(np.int8)
    return ForceCurveRecord(t, force, height, delta, segment, contact_height, spring_constant, m)
