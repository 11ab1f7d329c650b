"""Lee–Radok force of a sphere on a generalized-Maxwell half-space, one state per arm.

A sphere of radius ``R`` [m] indents a half-space whose Young's relaxation modulus is the Prony
series ``E(t) = e_inf + Σ e_i exp(-t/tau_i)`` [Pa, s], Poisson ratio ``nu``.  While the contact
grows, Lee & Radok (1960) give

    F(t) = C ∫ E(t - s) dp/ds ds,    p = δ^{3/2},    C = 4 √R / (3 (1 - nu²))

(elastic limit: Hertz, ``F = (4/3) E/(1-nu²) √R δ^{3/2}``).  For a Prony series the
integral is one state per arm: ``F = C [e_inf p + Σ e_i q_i]`` with ``q_i = p - p_i`` and
``dq_i/dt = dp/dt - q_i/tau_i``.  Over a step ``h`` on which ``p`` is linear in time the
update is exact,

    q_i(t + h) = a_i q_i(t) + b_i [p(t + h) - p(t)],   a_i = exp(-h/tau_i),
    b_i = tau_i (1 - a_i) / h,

so the recursion runs on the instrument's own (non-uniform) time axis.  A record that starts
in contact (``p[0] > 0``) is taken as a step at ``t[0]`` (every arm fully strained, ``q_i = p[0]``).

The same recursion solved for ``p`` gives the creep (the indentation under a given force
history) and, with the cantilever in series (``δ = s - F/k``), a height-controlled record
(stress relaxation at constant height: the tip sinks as the force relaxes).

Valid while the contact radius does not shrink (approach and dwell); unloading needs Ting's
solution and is not modelled here.  Kernels: plain floats and arrays (numba).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


def hertz_constant(tip_radius: float, nu: float) -> float:
    """``C = 4 √R / (3 (1 - nu²))`` [m^0.5]: ``F = C E p`` for an elastic half-space."""
    return 4.0 * math.sqrt(tip_radius) / (3.0 * (1.0 - nu * nu))


@njit(cache=True)
def force_from_p(t, p, e_inf, e, tau, c):  # pragma: no cover - numba
    """Force [N] for the history ``p = δ^{3/2}`` [m^1.5] sampled at ``t`` [s] (module docstring)."""
    n = t.size
    m = e.size
    out = np.empty(n)
    q = np.empty(m)
    for i in range(m):
        q[i] = p[0]
    s = 0.0
    for i in range(m):
        s += e[i] * q[i]
    out[0] = c * (e_inf * p[0] + s)
    a = np.ones(m)
    b = np.ones(m)
    h_last = -1.0
    for k in range(1, n):
        h = t[k] - t[k - 1]
        if h != h_last:  # a record's segments are uniformly sampled: the factors change rarely
            for i in range(m):
                if h > 0.0:
                    x = h / tau[i]
                    a[i] = math.exp(-x)
                    b[i] = -math.expm1(-x) / x
                else:
                    a[i] = 1.0
                    b[i] = 1.0
            h_last = h
        dp = p[k] - p[k - 1]
        s = 0.0
        for i in range(m):
            q[i] = a[i] * q[i] + b[i] * dp
            s += e[i] * q[i]
        out[k] = c * (e_inf * p[k] + s)
    return out


@njit(cache=True)
def p_from_force(t, f, e_inf, e, tau, c):  # pragma: no cover - numba
    """``p = δ^{3/2}`` [m^1.5] under the force history ``f`` [N] (creep; the recursion of
    :func:`force_from_p` solved for ``p`` at each step, which is linear in it)."""
    n = t.size
    m = e.size
    out = np.empty(n)
    e0 = e_inf
    for i in range(m):
        e0 += e[i]
    out[0] = f[0] / (c * e0)
    q = np.empty(m)
    for i in range(m):
        q[i] = out[0]
    a = np.empty(m)
    b = np.empty(m)
    for k in range(1, n):
        h = t[k] - t[k - 1]
        num = f[k] / c
        den = e_inf
        for i in range(m):
            if h > 0.0:
                x = h / tau[i]
                a[i] = math.exp(-x)
                b[i] = -math.expm1(-x) / x
            else:
                a[i] = 1.0
                b[i] = 1.0
            num -= e[i] * (a[i] * q[i] - b[i] * out[k - 1])
            den += e[i] * b[i]
        pk = num / den
        for i in range(m):
            q[i] = a[i] * q[i] + b[i] * (pk - out[k - 1])
        out[k] = pk
    return out


@njit(cache=True)
def height_controlled(t, s, k_spring, e_inf, e, tau, c):  # pragma: no cover - numba
    """Force [N] and indentation [m] when the cantilever's base is driven so that the
    undeflected tip would sit ``s(t)`` [m] below the surface's contact height; the
    cantilever (spring ``k_spring`` [N/m]) is in series: ``δ = s - F/k_spring``.  Each step
    solves ``p^{2/3} + C (A p + B)/k - s = 0`` (increasing in p) by safeguarded Newton.
    Out of contact (``s <= 0``) the force is 0.  For simulated records (tests)."""
    n = t.size
    m = e.size
    f = np.zeros(n)
    d = np.zeros(n)
    q = np.zeros(m)
    a = np.empty(m)
    b = np.empty(m)
    p_prev = 0.0
    for k in range(n):
        h = t[k] - t[k - 1] if k > 0 else 0.0
        A = e_inf
        B = 0.0
        for i in range(m):
            if h > 0.0:
                x = h / tau[i]
                a[i] = math.exp(-x)
                b[i] = -math.expm1(-x) / x
            else:
                a[i] = 1.0
                b[i] = 1.0
            A += e[i] * b[i]
            B += e[i] * (a[i] * q[i] - b[i] * p_prev)
        sk = s[k]
        if sk <= 0.0 and B <= 0.0:
            pk = 0.0
        else:
            lo = 0.0
            hi = max(sk, 0.0) ** 1.5 + 1e-30
            pk = hi
            for _ in range(200):  # bisection on [lo, hi]: g increasing, g(lo) <= 0 <= g(hi) enough here
                mid = 0.5 * (lo + hi)
                g = mid ** (2.0 / 3.0) + c * (A * mid + B) / k_spring - sk
                if g > 0.0:
                    hi = mid
                else:
                    lo = mid
                if hi - lo <= 1e-15 * hi:
                    break
            pk = 0.5 * (lo + hi)
        for i in range(m):
            q[i] = a[i] * q[i] + b[i] * (pk - p_prev)
        fk = e_inf * pk
        for i in range(m):
            fk += e[i] * q[i]
        f[k] = c * fk
        d[k] = pk ** (2.0 / 3.0)
        p_prev = pk
    return f, d


def relaxation_modulus(t, e_inf: float, e, tau):
    """``E(t) = e_inf + Σ e_i exp(-t/tau_i)`` [Pa]."""
    t = np.asarray(t, float)
    return e_inf + sum(ei * np.exp(-t / ti) for ei, ti in zip(e, tau))


def force(t, indentation, tip_radius: float, nu: float, e_inf: float, e, tau) -> np.ndarray:
    """Lee–Radok force [N] for the indentation history ``indentation`` [m] at times ``t`` [s]
    (negative indentation: out of contact, p = 0)."""
    t = np.ascontiguousarray(t, float)
    p = np.clip(np.asarray(indentation, float), 0.0, None) ** 1.5
    return force_from_p(t, p, float(e_inf), np.asarray(e, float), np.asarray(tau, float),
                        hertz_constant(tip_radius, nu))  # fmt: skip


def creep(t, force_history, tip_radius: float, nu: float, e_inf: float, e, tau) -> np.ndarray:
    """Indentation [m] under the force history [N] at times ``t`` [s] (Lee–Radok solved for δ)."""
    p = p_from_force(np.ascontiguousarray(t, float), np.ascontiguousarray(force_history, float), float(e_inf),
                     np.asarray(e, float), np.asarray(tau, float), hertz_constant(tip_radius, nu))  # fmt: skip
    return np.clip(p, 0.0, None) ** (2.0 / 3.0)


@njit(cache=True)
def force_and_gradient(t, p, dp, e_inf, e, tau, c):  # pragma: no cover - numba
    """Force [N] as :func:`force_from_p` and its derivatives, columns ``[∂F/∂contact,
    ∂F/∂e_inf, ∂F/∂e_i..., ∂F/∂tau_i...]``; ``dp = ∂p/∂contact`` (the force is linear in the
    p history, so its contact derivative is the same recursion run on ``dp``; the tau
    derivatives follow the recursion's own derivative, ``∂a/∂tau = a h/tau²``,
    ``∂b/∂tau = (1 - a)/h - a/tau``)."""
    n = t.size
    m = e.size
    out = np.empty(n)
    jac = np.zeros((n, 2 + 2 * m))
    q = np.empty(m)
    r = np.empty(m)  # the same recursion on dp
    g = np.zeros(m)  # dq_i/dtau_i
    for i in range(m):
        q[i] = p[0]
        r[i] = dp[0]
    a = np.ones(m)
    b = np.ones(m)
    da = np.zeros(m)
    db = np.zeros(m)
    h_last = -1.0
    for k in range(n):
        if k > 0:
            h = t[k] - t[k - 1]
            if h != h_last:
                for i in range(m):
                    if h > 0.0:
                        x = h / tau[i]
                        a[i] = math.exp(-x)
                        b[i] = -math.expm1(-x) / x
                        da[i] = a[i] * h / (tau[i] * tau[i])
                        db[i] = (1.0 - a[i]) / h - a[i] / tau[i]
                    else:
                        a[i] = 1.0
                        b[i] = 1.0
                        da[i] = 0.0
                        db[i] = 0.0
                h_last = h
            step = p[k] - p[k - 1]
            dstep = dp[k] - dp[k - 1]
            for i in range(m):
                g[i] = a[i] * g[i] + da[i] * q[i] + db[i] * step
                q[i] = a[i] * q[i] + b[i] * step
                r[i] = a[i] * r[i] + b[i] * dstep
        s = e_inf * p[k]
        sc = e_inf * dp[k]
        for i in range(m):
            s += e[i] * q[i]
            sc += e[i] * r[i]
            jac[k, 2 + i] = c * q[i]
            jac[k, 2 + m + i] = c * e[i] * g[i]
        out[k] = c * s
        jac[k, 0] = c * sc
        jac[k, 1] = c * p[k]
    return out, jac
