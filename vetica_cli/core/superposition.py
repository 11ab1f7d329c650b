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
    """``out = (S, S'/2, sigma0, kr)`` at ``kr``; the superposition (:func:`superpose`) fused
    into the pass over the samples (``y``, ``dy`` are filled only with ``fit_sigma``)."""
    tau = tau_c * kr / kg
    n = len(delta)
    e = math.exp(-h / tau)
    c = tau * (1.0 - e) / h
    de = e * h / (tau * tau)
    dc = (1.0 - e) / h - e / tau
    inv = 1.0 / scale
    dtau = tau_c / kg
    sigma = sa + sb * kr
    dsig = sb
    if fit_sigma:  # sigma0 minimising S at this Kr: r = r0 + sigma g, g = (1 - p)/scale
        superpose(delta, h, tau, y, dy)
        num = 0.0
        den = 0.0
        p = 1.0
        for k in range(n):
            r0 = (fc + kr * delta[k] + (kg - kr) * y[k] - f[k]) * inv
            g = (1.0 - p) * inv
            num += r0 * g
            den += g * g
            p *= e
        sigma = -num / den if den > 0.0 else 0.0
        dsig = 0.0
    s = 0.0
    slope = 0.0
    p = 1.0
    yk = 0.0
    dyk = 0.0
    kgr = kg - kr
    sp = sigma * h * dtau / (tau * tau)  # d(1 - p_k)/dKr = -(k h) p_k dtau/tau^2, times sigma
    for k in range(n):
        if k > 0:
            step = delta[k] - delta[k - 1]
            dyk = e * dyk + yk * de + step * dc
            yk = e * yk + step * c
        q = 1.0 - p
        r = (fc + kr * delta[k] + kgr * yk + sigma * q - f[k]) * inv
        dr = (delta[k] - yk + kgr * dyk * dtau + dsig * q - sp * k * p) * inv
        s += r * r
        slope += r * dr
        p *= e
    out[0] = s
    out[1] = slope
    out[2] = sigma
    out[3] = kr  # where out was evaluated: a solver whose last evaluation was at its answer does not repeat it


@njit(cache=True)
def _scan_costs(delta, f, h, kg, krs, tau_c, fc, scale, sa, sb, costs):
    """``costs[i]`` = the cost ``S`` of :func:`_cost` at ``krs[i]`` (a known pre-stress law), every
    ``Kr`` advanced together through one pass over the samples (independent recursions side by
    side: the processor overlaps them), with the same arithmetic as :func:`_cost`, so the same
    values to the last bit."""
    m = len(krs)
    n = len(delta)
    e = np.empty(m)
    c = np.empty(m)
    sig = np.empty(m)
    kgr = np.empty(m)
    p = np.ones(m)
    yk = np.zeros(m)
    inv = 1.0 / scale
    for i in range(m):
        tau = tau_c * krs[i] / kg
        e[i] = math.exp(-h / tau)
        c[i] = tau * (1.0 - e[i]) / h
        sig[i] = sa + sb * krs[i]
        kgr[i] = kg - krs[i]
        costs[i] = 0.0
    for k in range(n):
        dk = delta[k]
        fk = f[k]
        step = dk - delta[k - 1] if k > 0 else 0.0
        for i in range(m):
            if k > 0:
                yk[i] = e[i] * yk[i] + step * c[i]
            q = 1.0 - p[i]
            r = (fc + krs[i] * dk + kgr[i] * yk[i] + sig[i] * q - fk) * inv
            costs[i] += r * r
            p[i] *= e[i]


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
    ``kr_guess <= 0``: none.  ``n_scan = 0`` with a guess: a warm start (a fixed-point
    iteration's previous Kr) -- the root of ``S'`` is bracketed by steps growing from 1e-3
    of the guess (the scan when that finds none).  Returns ``(Kr, sigma0 [N], residual RMS [N], cost evaluations)``."""
    n = len(delta)
    y = np.empty(n)
    dy = np.empty(n)
    out = np.zeros(4)
    scale = 0.0
    for k in range(n):
        scale = max(scale, abs(f[k]))
    if scale == 0.0:
        scale = 1.0
    lo = 1e-12 * kg
    hi = kg * (1.0 - 1e-9)
    calls = 0
    if n_scan == 0 and lo < kr_guess < hi:  # warm start: bracket the root of S' around the guess
        _cost(delta, f, h, kg, kr_guess, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out)
        calls += 1
        g0 = out[1]
        step = 1e-3
        g1 = g0
        other = kr_guess
        for _ in range(12):
            other = kr_guess * (1.0 - step) if g0 > 0.0 else min(kr_guess * (1.0 + step), hi)
            other = max(other, lo)
            _cost(delta, f, h, kg, other, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out)
            calls += 1
            g1 = out[1]
            if g0 == 0.0 or g1 == 0.0 or (g0 > 0.0) != (g1 > 0.0):
                break
            kr_guess, g0 = other, g1
            step *= 4.0
        if g0 == 0.0:
            kr = kr_guess
        elif g1 == 0.0:
            kr = other
        elif (g0 > 0.0) != (g1 > 0.0):
            a, b, ga, gb = (other, kr_guess, g1, g0) if g0 > 0.0 else (kr_guess, other, g0, g1)
            kr, c = _brent_root(delta, f, h, kg, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out, a, b, ga, gb, rtol)
            calls += c
        else:
            kr = -1.0
        if kr > 0.0:
            if out[3] != kr:
                _cost(delta, f, h, kg, kr, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out)
                calls += 1
            return kr, out[2], scale * math.sqrt(out[0] / n), calls
        n_scan = 16  # no bracket near the guess: scan the bounds
    if n_scan < 2:  # a warm start whose guess lies outside the bounds (Kg moved below it): scan them
        n_scan = 16
    xs = np.exp(np.linspace(math.log(lo), math.log(hi), n_scan))
    if lo < kr_guess < hi:
        xs = np.unique(np.append(xs, kr_guess))
    m = len(xs)
    best = 0
    sbest = np.inf
    if fit_sigma:
        for i in range(m):
            _cost(delta, f, h, kg, xs[i], tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out)
            calls += 1
            if out[0] < sbest:
                sbest = out[0]
                best = i
    else:  # every scanned Kr in one pass over the samples
        costs = np.empty(m)
        _scan_costs(delta, f, h, kg, xs, tau_c, fc, scale, sa, sb, costs)
        calls += m
        for i in range(m):
            if costs[i] < sbest:
                sbest = costs[i]
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
    if out[3] != kr:
        _cost(delta, f, h, kg, kr, tau_c, fc, scale, sa, sb, fit_sigma, y, dy, out)
        calls += 1
    return kr, out[2], scale * math.sqrt(out[0] / n), calls


@njit(cache=True)
def solve_taps(delta, f, start, stop, h, kg, tau_c, fc, guess, warm, sa, sb, fit_sigma, n_scan, rtol,
               kr, s0, rms, calls):  # fmt: skip
    """:func:`solve_kr` on every tap of a record in one call: tap ``j``'s samples are
    ``delta[start[j]:stop[j]]``, ``f[start[j]:stop[j]]`` at the step ``h[j]``, force ``fc[j]`` at
    its contact minimum and pre-stress law ``sa[j] + sb[j] Kr``; ``guess[j]`` (<= 0: none) is a
    warm start where ``warm[j]``.  Taps with ``start[j] < 0`` are skipped (their outputs left as
    they are).  Fills ``kr, s0, rms, calls``."""
    for j in range(len(start)):
        a = start[j]
        if a < 0:
            continue
        b = stop[j]
        out = solve_kr(delta[a:b], f[a:b], h[j], kg, tau_c, fc[j], guess[j], sa[j], sb[j], fit_sigma,
                       0 if warm[j] else n_scan, rtol)  # fmt: skip
        kr[j] = out[0]
        s0[j] = out[1]
        rms[j] = out[2]
        calls[j] = out[3]


@njit(cache=True)
def _line_slope(x, y):
    """Least-squares slope of ``y`` against ``x``."""
    n = len(x)
    mx = 0.0
    my = 0.0
    for k in range(n):
        mx += x[k]
        my += y[k]
    mx /= n
    my /= n
    num = 0.0
    den = 0.0
    for k in range(n):
        xc = x[k] - mx
        num += xc * (y[k] - my)
        den += xc * xc
    return num / den


@njit(cache=True)
def _nanmean(v):
    s = 0.0
    n = 0
    for x in v:
        if math.isfinite(x):
            s += x
            n += 1
    return s / n if n else np.nan


@njit(cache=True)
def prestress_fixed_point(delta, z, f, u, start, stop, h, fc, zc, kg_points, mode, z1, kg, tau_c, kr, kr_i, s0_i,
                          warm0, kg_scale, max_iter, rtol_fp, n_scan, rtol, kg_i, rms_i):  # fmt: skip
    """Stages 2 and 1b of VETICA with the pre-stress to their fixed point, compiled (the thesis's
    stage-1b window of ``kg_points`` samples; :func:`vetica_cli.extraction.vetica_prestress._stages`
    is the same loop in Python).  ``mode``: 0 adhesion, 1 creep, 2 fit.  Per tap ``j`` the contact
    samples ``[start[j], stop[j])`` (``start[j] < 0``: skipped) of the indentation ``delta``, the tip
    position ``z``, the force ``f`` and the time ``u`` from the contact minimum, the step ``h[j]``,
    the force ``fc[j]`` and position ``zc[j]`` at the contact minimum.  ``kg``, ``kr``: where the
    iterations start (``kr_i``, ``s0_i``: the per-tap start, nan where none; ``warm0``: stage 2
    warm from the first iteration).  Fills ``kr_i, s0_i, kg_i, rms_i``; returns ``(Kg,
    iterations, converged)``."""
    n = len(start)
    guess = np.empty(n)
    warm = np.zeros(n, dtype=np.bool_)
    sa = np.zeros(n)
    sb = np.zeros(n)
    calls = np.zeros(n, dtype=np.int64)
    fit_sigma = mode == 2
    m = kg_points + 1
    y = np.empty(m)
    dy = np.empty(m)
    corr_f = np.empty(m - 1)
    for it in range(1, max_iter + 1):
        for j in range(n):
            if start[j] < 0:
                continue
            guess[j] = kr_i[j] if math.isfinite(kr_i[j]) else kr
            warm[j] = it > 1 or warm0
            if mode == 2:
                sa[j] = 0.0
                sb[j] = 0.0
            else:
                sa[j] = 0.0 if mode == 1 else -fc[j]
                sb[j] = -(zc[j] - z1) + (fc[j] / kg if mode == 0 else 0.0)
        solve_taps(delta, f, start, stop, h, kg, tau_c, fc, guess, warm, sa, sb, fit_sigma, n_scan, rtol,
                   kr_i, s0_i, rms_i, calls)  # fmt: skip
        kr_new = _nanmean(kr_i)
        tau_r = tau_c * kr_new / kg
        for j in range(n):
            a = start[j]
            if a < 0:
                continue
            if mode == 2:
                sig = s0_i[j]
            else:
                creep = -kr_new * (zc[j] - z1)
                sig = creep - fc[j] * (1.0 - kr_new / kg) if mode == 0 else creep
            dj = delta[a : a + m]
            superpose(dj, u[a + 1] - u[a], tau_r, y, dy)
            for k in range(1, m):
                corr_f[k - 1] = f[a + k] - (sig * -math.expm1(-u[a + k] / tau_r) + (kg - kr_new) * (y[k] - dj[k]))
            kg_i[j] = -_line_slope(z[a + 1 : a + m], corr_f) * kg_scale
        kg_new = _nanmean(kg_i)
        done = abs(kg_new - kg) <= rtol_fp * kg and abs(kr_new - kr) <= rtol_fp * abs(kr)
        kg = kg_new
        kr = kr_new
        if done or not (math.isfinite(kg) and kg > 0 and math.isfinite(kr)):
            return kg, it, done
    return kg, max_iter, False
