"""The paddle operator in the time domain, compiled: a first estimate of the tip-sample force
from the paddle signal, good enough to locate the taps (numba; plain SI floats and arrays).

``F = m2 zp'' + c2 zp' + k2 zp`` (thesis eqs. 16-20) with second-order central differences on
a constant step ``h``; the two end samples copy their neighbours.  Its error is
``~h^2/12 m2 zp''''``: negligible in free flight, a sample or two of smearing at the contact
and separation kinks -- so it locates the taps, and the force that is analysed is the
spectral inversion of each tap's window (:mod:`vetica_cli.signals.tapforce`).
"""

from __future__ import annotations

from numba import njit


@njit(cache=True)
def paddle_force_fd(zp, h, m2, c2, k2, out):
    """Fill ``out`` [N] with the central-difference paddle operator of ``zp`` [m]."""
    n = len(zp)
    a = m2 / (h * h)
    b = c2 / (2.0 * h)
    for k in range(1, n - 1):
        out[k] = a * (zp[k + 1] - 2.0 * zp[k] + zp[k - 1]) + b * (zp[k + 1] - zp[k - 1]) + k2 * zp[k]
    if n >= 3:
        out[0] = out[1]
        out[n - 1] = out[n - 2]
