"""Ting's viscoelastic Hertz contact through loading and unloading, for any relaxation modulus.

A paraboloid (sphere for δ ≪ R) of radius ``R`` [m] indents a linear viscoelastic half-space
with Young's relaxation modulus ``E(t)`` [Pa] and Poisson ratio ``nu``.  While the contact grows
(Lee & Radok 1960)

    F(t) = C ∫_0^t E(t - ξ) dp/dξ dξ,    p = δ^{3/2},    C = 4 √R / (3 (1 - nu²)),

and after the indentation's maximum, while the contact shrinks (Ting 1966), the contact radius
goes back through the values it had at ``t1(t) ≤ t_m`` found from

    ∫_{t1}^{t} E(t - ξ) dδ/dξ dξ = 0,    then    F(t) = C ∫_0^{t1} E(t - ξ) dp/dξ dξ

(``F = 0`` once ``t1`` reaches the contact's start: the tip has left the surface, which has not
yet recovered).  Both rules are one: ``t1`` is the latest time ``≤ t`` at which the integral
``G(s) = ∫_s^t E(t - ξ) dδ/dξ dξ`` vanishes, and ``t1 = t`` while ``G`` is positive just
before ``t`` (the contact grows).

**Discretization** (:func:`ting_force`): a uniform time grid of step ``h``, ``δ`` and ``p``
linear within each step (only the contact's part, ``δ⁺ = max(δ, 0)``, enters), and the
step-averaged modulus ``u_m = (1/h) ∫_{mh}^{(m+1)h} E(τ) dτ``; then ``G(t_j) = Σ_{i>j} Δδ_i
u_{k-i}`` at ``t = t_k`` and ``F(t_k) = C Σ_{i≤j1} Δp_i u_{k-i}`` plus the fraction of the step
holding ``t1``.  The modulus enters only through ``u``, so one kernel serves every modulus:

* power law ``E(t) = e0 (t/t0)^(-beta)``, ``0 ≤ beta < 1``, ``t0 = 1 s``:
  ``u_m = e0 (h/t0)^(-beta) [(m+1)^(1-beta) - m^(1-beta)] / (1 - beta)``
  (:func:`powerlaw_weights`);
* generalized Maxwell (Prony) ``E(t) = e_inf + Σ e_i exp(-t/tau_i)``:
  ``u_m = e_inf + Σ e_i (tau_i/h) (1 - a_i) a_i^m``, ``a_i = exp(-h/tau_i)``
  (:func:`prony_weights`).

The cost is ``O(N²)`` multiply-adds for ``N`` grid points (a few hundred for a fit: binned).
Closed forms for tests and documentation: the power law on a constant-velocity ramp
(:func:`powerlaw_ramp_force`) and on a triangle, loading and Ting's unloading
(:func:`powerlaw_triangle_force`).  Kernels: plain floats and arrays (numba).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.special import beta as beta_fn
from scipy.special import betainc

T0 = 1.0  # [s] the power law's reference time: E(t0) = e0


def hertz_constant(tip_radius: float, nu: float) -> float:
    """``C = 4 √R / (3 (1 - nu²))`` [m^0.5]: ``F = C E δ^{3/2}`` for an elastic half-space (Hertz)."""
    return 4.0 * math.sqrt(tip_radius) / (3.0 * (1.0 - nu * nu))


@njit(cache=True)
def powerlaw_weights(n, h, e0, beta, t0):  # pragma: no cover - numba
    """``u_m`` [Pa], ``m = 0..n-1``: the power-law modulus averaged over step ``m`` of width ``h`` [s]."""
    u = np.empty(n)
    scale = e0 * (h / t0) ** (-beta) / (1.0 - beta)
    prev = 0.0
    for m in range(n):
        nxt = (m + 1.0) ** (1.0 - beta)
        u[m] = scale * (nxt - prev)
        prev = nxt
    return u


@njit(cache=True)
def prony_weights(n, h, e_inf, e, tau):  # pragma: no cover - numba
    """``u_m`` [Pa], ``m = 0..n-1``: the Prony-series modulus averaged over step ``m`` of width ``h`` [s]."""
    u = np.full(n, e_inf)
    for i in range(e.size):
        a = math.exp(-h / tau[i])
        b = e[i] * tau[i] / h * (1.0 - a)
        for m in range(n):
            u[m] += b
            b *= a
    return u


@njit(cache=True)
def ting_force(delta, u, c):  # pragma: no cover - numba
    """Force [N] and the contact's reference time index ``t1/h`` (fractional) at every grid point.

    ``delta`` [m]: the indentation at the grid points (uniform in time; negative = out of
    contact; the first point should be out of contact), ``u`` [Pa]: the step-averaged modulus
    (at least ``delta.size`` values), ``c`` the Hertz constant :func:`hertz_constant`."""
    n = delta.size
    dd = np.zeros(n)
    dp = np.zeros(n)
    prev_d = max(delta[0], 0.0)
    prev_p = prev_d**1.5
    for k in range(1, n):
        d = max(delta[k], 0.0)
        p = d**1.5
        dd[k] = d - prev_d
        dp[k] = p - prev_p
        prev_d = d
        prev_p = p
    f = np.zeros(n)
    t1 = np.zeros(n)
    d0 = max(delta[0], 0.0)
    for k in range(n):
        # t1: going back from t_k, the first point where G(s) = sum over the later steps of
        # dd_i u_{k-i} turns positive (G(t_k) = 0; at once for a growing contact: Lee-Radok)
        g = 0.0
        j = k
        frac = -1.0
        while j >= 1:
            g_next = g + dd[j] * u[k - j]  # G(t_{j-1})
            if g_next > 0.0:
                frac = g_next / (g_next - g)  # G linear within step j: t1 = t_{j-1} + frac h
                break
            g = g_next
            j -= 1
        if frac < 0.0:  # no zero after the grid's start
            if d0 > 0.0 and g + d0 * u[k] > 0.0:  # a record that starts in contact: within the step at t_0
                theta = (g + d0 * u[k]) / (d0 * u[k])
                f[k] = c * (theta * d0) ** 1.5 * u[k]
            continue  # else the tip has left the surface: F = 0, t1 = 0
        s = d0**1.5 * u[k]
        for i in range(1, j):
            s += dp[i] * u[k - i]
        s += frac * dp[j] * u[k - j]
        f[k] = c * s
        t1[k] = j - 1 + frac
    return f, t1


def powerlaw_force(t, delta, tip_radius: float, nu: float, e0: float, beta: float, t0: float = T0):
    """Ting's force [N] for the indentation ``delta`` [m] at uniform times ``t`` [s], power law."""
    t = np.asarray(t, float)
    h = float(t[1] - t[0])
    u = powerlaw_weights(t.size, h, float(e0), float(beta), float(t0))
    return ting_force(np.ascontiguousarray(delta, float), u, hertz_constant(tip_radius, nu))[0]


def prony_force(t, delta, tip_radius: float, nu: float, e_inf: float, e, tau):
    """Ting's force [N] for the indentation ``delta`` [m] at uniform times ``t`` [s], Prony series."""
    t = np.asarray(t, float)
    h = float(t[1] - t[0])
    u = prony_weights(t.size, h, float(e_inf), np.asarray(e, float), np.asarray(tau, float))
    return ting_force(np.ascontiguousarray(delta, float), u, hertz_constant(tip_radius, nu))[0]


def powerlaw_ramp_force(t, v: float, tip_radius: float, nu: float, e0: float, beta: float, t0: float = T0):
    """Closed form on a constant-velocity ramp ``δ = v t``: Lee–Radok's integral done by hand,

        F(t) = 2 √R e0 t0^β v^{3/2} B(3/2, 1 - β) t^{3/2 - β} / (1 - ν²)

    (B the Beta function; β = 0 is Hertz, ``4 √R e0 δ^{3/2} / (3 (1 - ν²))``)."""
    t = np.asarray(t, float)
    return (2.0 * math.sqrt(tip_radius) * e0 * t0**beta * v**1.5 * beta_fn(1.5, 1.0 - beta)
            * np.clip(t, 0.0, None) ** (1.5 - beta) / (1.0 - nu * nu))  # fmt: skip


def powerlaw_triangle_force(t, v: float, t_m: float, tip_radius: float, nu: float, e0: float, beta: float,
                            t0: float = T0):  # fmt: skip
    """Closed form on a triangle ``δ = v t`` up to ``t_m``, then ``δ = v (2 t_m - t)``.

    Loading: :func:`powerlaw_ramp_force`.  Unloading (Ting): ``∫_{t1}^{t_m} (t-ξ)^{-β} dξ =
    ∫_{t_m}^{t} (t-ξ)^{-β} dξ`` gives ``t1 = t - 2^{1/(1-β)} (t - t_m)``, and
    ``F = (3/2) C e0 t0^β v^{3/2} ∫_0^{t1} (t-ξ)^{-β} ξ^{1/2} dξ = (3/2) C e0 t0^β v^{3/2}
    t^{3/2-β} B(t1/t; 3/2, 1-β)`` (incomplete Beta function); the tip leaves when ``t1 = 0``,
    at ``t = t_m 2^{1/(1-β)} / (2^{1/(1-β)} - 1)`` (``2 t_m`` for an elastic sample)."""
    t = np.asarray(t, float)
    out = powerlaw_ramp_force(np.minimum(t, t_m), v, tip_radius, nu, e0, beta, t0)
    after = t > t_m
    ta = t[after]
    t1 = np.clip(ta - 2.0 ** (1.0 / (1.0 - beta)) * (ta - t_m), 0.0, None)
    pref = 1.5 * hertz_constant(tip_radius, nu) * e0 * t0**beta * v**1.5
    out = np.array(out, float)
    out[after] = pref * ta ** (1.5 - beta) * betainc(1.5, 1.0 - beta, t1 / ta) * beta_fn(1.5, 1.0 - beta)
    return out
