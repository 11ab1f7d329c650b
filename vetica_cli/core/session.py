"""The kernel's state seen from above :mod:`vetica_cli.core`: enter a surface at a base
height, read the base, the step index and the probe's energy, place the probe, without
the state layout (:data:`.tapping.S_ZC` ...) leaving the core.

A run (:func:`vetica_cli.simulation.simulate.simulate`) and a scan line
(:mod:`vetica_cli.scan.pixel`) drive the kernel with :mod:`.engine` (``new_state``,
``approach``, ``solve_steady``, ``record_window``, ``transient``: the run and the window)
and read or change its state only through these functions.
"""

from __future__ import annotations

import numpy as np

from . import tapping as T


def enter(s: np.ndarray, n_arms: int, zb: float) -> np.ndarray:
    """A new state over a fresh surface of ``n_arms`` dashpots at base height ``zb`` [m] (the
    base relative to the new surface): the probe's state (cantilever and paddle positions
    and velocities) and the step index carry over from ``s``; the surface is undeformed
    (every dashpot at rest) and out of contact."""
    out = np.zeros(T.S_XD + n_arms)
    out[: T.S_XD] = s[: T.S_XD]
    out[T.S_ZB] = zb
    out[T.S_CONTACT] = 0.0
    return out


def base(s: np.ndarray) -> float:
    """The base height Zb [m] of a state (relative to its surface)."""
    return float(s[T.S_ZB])


def step_index(s: np.ndarray) -> int:
    """The integration step a state is at (time = step index x dt)."""
    return int(s[T.S_IDX])


def probe_energy(s: np.ndarray, m1: float, k1: float, m2: float, k2: float) -> float:
    """Kinetic plus elastic energy of both probe oscillators [J] (cantilever m1, k1; paddle m2, k2)."""
    return 0.5 * (m1 * s[T.S_VC] ** 2 + k1 * s[T.S_ZC] ** 2 + m2 * s[T.S_VP] ** 2 + k2 * s[T.S_ZP] ** 2)


def kick_probe(s: np.ndarray, dzc: float, dvc: float, dzp: float, dvp: float) -> None:
    """Add offsets to the cantilever's and the paddle's positions [m] and velocities [m/s] of
    ``s`` (the thermal recording's equipartition draw at the window's start)."""
    s[T.S_ZC] += dzc
    s[T.S_VC] += dvc
    s[T.S_ZP] += dzp
    s[T.S_VP] += dvp


def place_probe(s: np.ndarray, zc: float, vc: float, zp: float, zb: float) -> None:
    """Set the cantilever position and velocity, the paddle position and the base height of ``s``."""
    s[T.S_ZC], s[T.S_VC], s[T.S_ZP], s[T.S_ZB] = zc, vc, zp, zb
