"""Compiled stage 2 of VETICA and of VETICA with pre-stress: the Boltzmann superposition of
one tap's sampled indentation and the one-dimensional least squares for ``Kr`` (numba).

Plain SI floats and arrays in and out.  The indentation ``delta_k = Zc - z_tip(u_k)`` is
taken as linear between the samples (``u_k = k h``, a constant step ``h``), so the
superposition integral against the exponential kernel is exact on it, by the recursion::

    y(u) = int_0^u exp(-(u - s)/tau) delta'(s) ds
    y_{k+1} = E y_k + (delta_{k+1} - delta_k) tau (1 - E)/h,   E = exp(-h/tau),  y_0 = 0

and its ``tau``-derivative (``dE/dtau = E h/tau^2``)::

    dy_{k+1} = E dy_k + y_k E h/tau^2 + (delta_{k+1} - delta_k) ((1 - E)/h - E/tau)

The model force of a tap (thesis eqs. 75-78; the pre-stress term of
:mod:`vetica_cli.extraction.vetica_prestress`, 0 for VETICA)::

    F(u) = Fc + Kr delta + (Kg - Kr) y(tau_r) + sigma0 (1 - exp(-u/tau_r)),   tau_r = tau_c Kr/Kg

with ``sigma0 = sa + sb Kr`` (a known pre-stress law) or, with ``fit_sigma``, the value
that minimises the cost at each ``Kr`` (linear least squares: variable projection).  The
cost ``S(Kr) = sum r^2``, ``r = (model - F)/scale``; ``Kr`` is the root of ``S'(Kr)``
(by the envelope theorem, the partial derivative at the projected ``sigma0``) found as
:func:`vetica_cli.extraction.vetica.stage2_kr` finds it: the lowest ``S`` on a
log-spaced scan of ``(lo, hi)`` plus the guess brackets the root, Brent's method solves
it to ``rtol``; a minimum on a bound returns the bound; where ``S'`` does not change sign
across the bracket, a golden-section search on ``S``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def superpose(delta, h, tau, y, dy):
    """Fill ``y`` (the superposition integral, [m]) and ``dy`` (its ``tau``-derivative, [m/s])."""
    e = math.exp(-h / tau)
    c = tau * (1.0 - e) / h
    de = e * h / (tau * tau)
    dc = (1.0 - e) / h - e / tau
    y[0] = 0.0
    dy[0] = 0.0
    for k in range(len(delta) - 1):
        step = delta[k + 1] - delta[k]
        dy[k + 1] = e * dy[k] + y[k] * de + step * dc
        y[k + 1] = e * y[k] + step * c


@njit(cache=True)
def _cost(delta, f, h, kg, kr, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out):
    """``out = (S, S'/2, sigma0)`` at ``kr``."""
    tau = tau_c * kr / kg
    superpose(delta, h, tau, y, dy)
    n = len(delta)
    e = math.exp(-h / tau)
    sigma = sa + sb * kr
    if fit_sigma:  # sigma0 minimising S at this Kr: r = r0 + sigma g, g = (1 - p)/scale
        num = 0.0
        den = 0.0
        p = 1.0
        for k in range(n):
            r0 = (fc + kr * delta[k] + (kg - kr) * y[k] - f[k]) / scale
            g = (1.0 - p) / scale
            num += r0 * g
            den += g * g
            p *= e
        sigma = -num / den if den > 0.0 else 0.0
    s = 0.0
    slope = 0.0
    p = 1.0
    dtau = tau_c / kg
    for k in range(n):
        u = k * h
        r = (fc + kr * delta[k] + (kg - kr) * y[k] + sigma * (1.0 - p) - f[k]) / scale
        dsig = 0.0 if fit_sigma else sb
        dr = (delta[k] - y[k] + (kg - kr) * dy[k] * dtau + dsig * (1.0 - p) - sigma * u / (tau * tau) * p * dtau) / scale
        s += r * r
        slope += r * dr
        p *= e
    out[0] = s
    out[1] = slope
    out[2] = sigma


@njit(cache=True)
def _brent_root(delta, f, h, kg, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out, a, b, fa, fb, rtol):
    """Root of ``S'`` in ``[a, b]`` (``fa < 0 < fb``) by Brent's method; returns ``(root, evaluations)``."""
    calls = 0
    c, fcc = a, fa
    d = b - a
    e = d
    for _ in range(200):
        if (fb > 0.0) == (fcc > 0.0):
            c, fcc = a, fa
            d = b - a
            e = d
        if abs(fcc) < abs(fb):
            a, b, c = b, c, b
            fa, fb, fcc = fb, fcc, fb
        tol = 2.0 * 2.220446049250313e-16 * abs(b) + 0.5 * rtol * abs(b)
        m = 0.5 * (c - b)
        if abs(m) <= tol or fb == 0.0:
            return b, calls
        if abs(e) >= tol and abs(fa) > abs(fb):
            s = fb / fa
            if a == c:
                p = 2.0 * m * s
                q = 1.0 - s
            else:
                q = fa / fcc
                r = fb / fcc
                p = s * (2.0 * m * q * (q - r) - (b - a) * (r - 1.0))
                q = (q - 1.0) * (r - 1.0) * (s - 1.0)
            if p > 0.0:
                q = -q
            else:
                p = -p
            if 2.0 * p < min(3.0 * m * q - abs(tol * q), abs(e * q)):
                e = d
                d = p / q
            else:
                d = m
                e = d
        else:
            d = m
            e = d
        a, fa = b, fb
        b = b + d if abs(d) > tol else b + (tol if m > 0 else -tol)
        _cost(delta, f, h, kg, b, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out)
        calls += 1
        fb = out[1]
    return b, calls


@njit(cache=True)
def _golden(delta, f, h, kg, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out, a, b, rtol):
    """Minimum of ``S`` on ``[a, b]`` by golden-section search; returns ``(x, evaluations)``."""
    g = 0.5 * (math.sqrt(5.0) - 1.0)
    x1 = b - g * (b - a)
    x2 = a + g * (b - a)
    _cost(delta, f, h, kg, x1, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out)
    f1 = out[0]
    _cost(delta, f, h, kg, x2, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out)
    f2 = out[0]
    calls = 2
    while b - a > rtol * b and calls < 300:
        if f1 < f2:
            b, x2, f2 = x2, x1, f1
            x1 = b - g * (b - a)
            _cost(delta, f, h, kg, x1, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out)
            f1 = out[0]
        else:
            a, x1, f1 = x1, x2, f2
            x2 = a + g * (b - a)
            _cost(delta, f, h, kg, x2, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out)
            f2 = out[0]
        calls += 1
    return 0.5 * (a + b), calls


@njit(cache=True)
def solve_kr(delta, f, h, kg, tau_c, fc, kr_guess, sa, sb, fit_sigma, n_scan, rtol):
    """Least-squares ``Kr`` of one tap on ``(1e-12 Kg, Kg (1 - 1e-9))`` (module docstring).
    ``kr_guess <= 0``: none.  Returns ``(Kr, sigma0 [N], residual RMS [N], cost evaluations)``."""
    n = len(delta)
    y = np.empty(n)
    dy = np.empty(n)
    out = np.zeros(3)
    scale = 0.0
    for k in range(n):
        scale = max(scale, abs(f[k]))
    if scale == 0.0:
        scale = 1.0
    lo = 1e-12 * kg
    hi = kg * (1.0 - 1e-9)
    xs = np.exp(np.linspace(math.log(lo), math.log(hi), n_scan))
    if lo < kr_guess < hi:
        xs = np.unique(np.append(xs, kr_guess))
    m = len(xs)
    best = 0
    sbest = np.inf
    calls = 0
    for i in range(m):
        _cost(delta, f, h, kg, xs[i], tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out)
        calls += 1
        if out[0] < sbest:
            sbest = out[0]
            best = i
    _cost(delta, f, h, kg, xs[best], tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out)
    calls += 1
    gi = out[1]
    kr = -1.0
    if gi == 0.0:
        kr = xs[best]
    elif gi > 0.0:  # the minimum is below xs[best]
        if best == 0:
            kr = lo
        else:
            _cost(delta, f, h, kg, xs[best - 1], tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out)
            calls += 1
            if out[1] == 0.0:
                kr = xs[best - 1]
            elif out[1] < 0.0:
                kr, c = _brent_root(delta, f, h, kg, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out,
                                    xs[best - 1], xs[best], out[1], gi, rtol)  # fmt: skip
                calls += c
    else:  # above xs[best]
        if best == m - 1:
            kr = hi
        else:
            _cost(delta, f, h, kg, xs[best + 1], tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out)
            calls += 1
            if out[1] == 0.0:
                kr = xs[best + 1]
            elif out[1] > 0.0:
                kr, c = _brent_root(delta, f, h, kg, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out,
                                    xs[best], xs[best + 1], gi, out[1], rtol)  # fmt: skip
                calls += c
    if kr < 0.0:  # S' does not change sign across the neighbour: minimise S itself there
        kr, c = _golden(delta, f, h, kg, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out,
                        xs[max(best - 1, 0)], xs[min(best + 1, m - 1)], rtol)  # fmt: skip
        calls += c
    _cost(delta, f, h, kg, kr, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out)
    calls += 1
    return kr, out[2], scale * math.sqrt(out[0] / n), calls
