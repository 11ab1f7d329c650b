"""Starting point of the whole-cycle fit: VETICA on the first taps when it gives a
plausible answer, else a generic split of the loading slope; rescaled onto that
slope when its glassy stiffness is off by more than a decade."""

from __future__ import annotations

import math

import numpy as np

from ...errors import InputError
from ..methods.vetica import vetica

START_TAPS = 3  # taps of the record VETICA sees for the starting point


def loading_slope(z: np.ndarray, f: np.ndarray, taps) -> float:
    """Contact stiffness of the first tap [N/m]: ``-dF/dz`` fitted between 20 % and
    80 % of its peak force on loading (between Kr and Kg of an SLS)."""
    ic, ip = int(taps.contact[0]), int(taps.peak[0])
    seg = slice(ic, ip + 1)
    fp = f[ip]
    sel = np.flatnonzero((f[seg] > 0.2 * fp) & (f[seg] < 0.8 * fp))
    kg = math.nan
    if len(sel) >= 3:
        kg = -float(np.polyfit(z[seg][sel], f[seg][sel], 1)[0])
    if not (math.isfinite(kg) and kg > 0):
        depth = float(z[ic] - np.min(z[seg]))
        kg = fp / depth if depth > 0 else 1.0
    return kg


def generic_start(z: np.ndarray, f: np.ndarray, taps) -> dict:
    """``k0 = 0.9 Kg``, ``k_inf = 0.1 Kg`` with Kg from the loading slope; cd from the scan."""
    kg = loading_slope(z, f, taps)
    return {"k_inf": 0.1 * kg, "k0": 0.9 * kg, "cd": 1e-5}


def vetica_start(t, z, f, z1, taps, kg_points):
    """VETICA (thesis 3.3) on the first ``START_TAPS`` taps: a starting point only."""
    stop = len(t)
    if len(taps.peak) > START_TAPS + 1:
        stop = int(taps.peak[START_TAPS + 1] + 0.5 * taps.spacing)
    ex = vetica(t[:stop], z[:stop], f[:stop], z1, kg_points=kg_points)
    v = {k: ex.values.get(k) for k in ("k_inf", "k0", "cd")}
    if not all(x is not None and math.isfinite(x) and x > 0 for x in v.values()):
        return None
    split = v["k0"] / (v["k0"] + v["k_inf"])
    if not 1e-3 < split < 1.0 - 1e-4:  # VETICA's Kr fit ran into a bound: no start
        return None
    return {k: float(x) for k, x in v.items()}


def starting_point(t, z, f, z1, taps, kg_points, start: dict | None = None) -> tuple[dict, str]:
    """``({k_inf, k0, cd}, source)``: ``start`` if given, else VETICA's, else the generic one;
    a start whose glassy stiffness is off the loading slope by more than a decade is
    rescaled onto it (ratio k0/k_inf kept: the contact force scales with the stiffnesses)."""
    if start is not None:
        values, source = {k: float(start[k]) for k in ("k_inf", "k0", "cd")}, "given"
    else:
        try:
            values, source = vetica_start(t, z, f, z1, taps, kg_points), "vetica"
        except (InputError, ValueError, FloatingPointError, np.linalg.LinAlgError):
            values = None
        if values is None:
            values, source = generic_start(z, f, taps), "generic"
    slope = loading_slope(z, f, taps)
    kg_start = values["k0"] + values["k_inf"]
    if not 0.1 <= kg_start / slope <= 10.0:
        factor = slope / kg_start
        values = {**values, "k_inf": values["k_inf"] * factor, "k0": values["k0"] * factor}
        source += f", stiffnesses rescaled x{factor:.3g} onto the loading slope {slope:.4g} N/m"
    return values, source
