"""An SLS tapping record made without vetica's simulator: the tip moves on a prescribed
cosine, the surface is the massless Zener SLS (thesis 3.2) with the van der Waals pull acting
on the tip only (``vdw_on_surface: false``), and every segment of the surface's motion is
integrated in closed form (no time step):

* out of contact the surface follows ``X = k0 Xd / Kg`` and the dashpot creeps back,
  ``Xd(t) = Xd(ts) exp(-(t - ts)/tau_c)``; the force on the tip is ``-H R / (6 d^2)``
  with ``d = z_tip - X``;
* contact starts when ``d = a0``; in contact ``X = z_tip - a0`` and the dashpot relaxes
  toward it, ``tau_r Xd' = X - Xd``, solved exactly for the cosine ``X(t)``; the force is
  ``-(k_inf X + k0 (X - Xd)) - Fa(a0)``;
* separation when the SLS force ``k_inf X + k0 (X - Xd)`` falls back to zero.

Contact and separation instants are found by root finding to 1e-15 s, the periodic
state by iterating whole periods until the dashpot repeats.  A record "from a simulator
other than ours" for the measured-data tests: it shares no code with
``vetica_cli`` and has no probe dynamics.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq


def tapping_record(k_inf=4.0, k0=128.0, cd=3e-5, a0=0.2e-9, hamaker=0.2e-18, radius=10e-9, f1=50e3, amp=70e-9,
                   depth=2.0e-9, h=0.125e-9, periods=10, start=0.0):  # fmt: skip
    """``(t, z_tip, f_ts)`` of ``periods`` drive periods of the periodic state, sampled every
    ``h`` from ``start`` (in periods; a fraction starts the window inside a period).  The
    tip: ``z = a0 - depth + amp (1 + cos(w t))``, lowest ``depth`` below the undeformed
    contact point."""
    w = 2 * math.pi * f1
    T = 1.0 / f1
    kg = k0 + k_inf
    tau_c = cd * kg / (k0 * k_inf)
    tau_r = cd / k0
    hr6 = hamaker * radius / 6.0
    fa0 = hr6 / a0**2
    c = a0 - depth + amp  # z(t) = c + amp cos(w t)

    def z(t):
        return c + amp * np.cos(w * t)

    def period(xd0):
        """Event times and the dashpot's closed form over one period from ``Xd(0) = xd0``."""

        # out of contact from the top: contact when z - a0 = k0 Xd / Kg
        def gap(t):
            return z(t) - a0 - k0 * xd0 * math.exp(-t / tau_c) / kg

        tc = brentq(gap, 0.0, 0.5 * T, xtol=1e-16)
        xdc = xd0 * math.exp(-tc / tau_c)
        # in contact: tau_r Xd' = X - Xd, X = (c - a0) + amp cos(w t): particular + homogeneous
        wt = w * tau_r

        def part(t):
            return (c - a0) + amp * (np.cos(w * t) + wt * np.sin(w * t)) / (1 + wt * wt)

        cc = xdc - part(tc)

        def xd_in(t):
            return part(t) + cc * np.exp(-(t - tc) / tau_r)

        def f_sls(t):
            x = z(t) - a0
            return k_inf * x + k0 * (x - xd_in(t))

        tb = 0.5 * T  # the bottom; F_sls > 0 there, falls to zero on the way up
        ts = brentq(f_sls, tb, T, xtol=1e-16)
        xds = float(xd_in(ts))
        return tc, ts, xd_in, xds

    xd0 = 0.0
    for _ in range(2000):  # whole periods until the dashpot repeats
        tc, ts, xd_in, xds = period(xd0)
        xd_next = xds * math.exp(-(T - ts) / tau_c)
        if abs(xd_next - xd0) < 1e-22:
            xd0 = xd_next
            break
        xd0 = xd_next
    else:  # pragma: no cover
        raise RuntimeError("no periodic state")
    tc, ts, xd_in, xds = period(xd0)
    n = round(periods * T / h)
    t = start * T + h * np.arange(n)
    u = np.mod(t, T)
    u = np.where(np.isclose(u, T, rtol=0, atol=1e-18), 0.0, u)
    zt = z(u)
    f = np.empty(n)
    before, during, after = u < tc, (u >= tc) & (u <= ts), u > ts
    x_b = k0 * xd0 * np.exp(-u[before] / tau_c) / kg
    f[before] = -hr6 / (zt[before] - x_b) ** 2
    x_c = zt[during] - a0
    f[during] = -(k_inf * x_c + k0 * (x_c - xd_in(u[during]))) - fa0
    x_a = k0 * xds * np.exp(-(u[after] - ts) / tau_c) / kg
    f[after] = -hr6 / (zt[after] - x_a) ** 2
    return t, zt, f
