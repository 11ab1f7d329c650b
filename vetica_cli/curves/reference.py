"""The afmformats example's own analysis of a stress-relaxation dwell, for comparison.

afmformats 0.18.7 ``examples/stress_relaxation.py`` (MIT) fits, with lmfit, the force on the
dwell segment against the instrument's time axis with ``c + A1 exp(-t/d1) + A2 exp(-t/d2)``
(``d1`` from 1 s, bounded below by 0.1 s; ``d2`` from 8 s, bounded below by 2 s; ``c`` from the
smallest force; both amplitudes from lmfit's exponential guess, a straight line through
``ln F``).  This is the same least-squares problem solved with scipy (no lmfit dependency).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares


def double_exponential(t, force) -> dict:
    """``{"c", "a1", "d1", "a2", "d2"}`` [N, N, s, N, s] of the example's fit on one dwell."""
    t = np.asarray(t, float)
    y = np.asarray(force, float) * 1e9  # the example fits nN
    pos = y > 0
    slope, icpt = np.polyfit(t[pos], np.log(y[pos]), 1)  # lmfit ExponentialModel.guess
    amp = float(np.exp(icpt))
    x0 = np.array([float(np.min(y)), amp, 1.0, amp, 8.0])

    def resid(x):
        c, a1, d1, a2, d2 = x
        return c + a1 * np.exp(-t / d1) + a2 * np.exp(-t / d2) - y

    lo = [-np.inf, -np.inf, 0.1, -np.inf, 2.0]
    res = least_squares(resid, x0, bounds=(lo, np.inf), method="trf", x_scale="jac", max_nfev=20000)
    c, a1, d1, a2, d2 = res.x
    return {"c": c * 1e-9, "a1": a1 * 1e-9, "d1": d1, "a2": a2 * 1e-9, "d2": d2}
