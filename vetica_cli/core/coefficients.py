"""Coefficient arrays of the tapping kernel (:mod:`.tapping`), built once per run.

Plain numpy/scipy on SI floats; the kernel only reads the arrays.  Three
families:

* **fine step** (velocity Verlet at ``dt``, thesis appendix B): the linear
  Verlet map of each oscillator ``m z'' = -k z - c z' + drive + Fts`` with
  the damping implicit in the velocity half step, folded so that the next
  tip position is one fused multiply-add after the force (see
  :func:`verlet_row`);
* **surface at step h** (thesis 3.2): the massless surface of
  ``k_inf`` in parallel with N Maxwell arms ``(k_i, cd_i)``.  In contact every
  arm relaxes towards ``X`` with ``tau_i = cd_i/k_i``, integrated exactly for
  ``X`` moving linearly over the step (from ``X0`` to ``X1``)::

      Xd1 = Xd0 + (1 - e)(X1 - Xd0) - (phi - e)(X1 - X0),
      e = exp(-h/tau),  phi = (tau/h)(1 - e)

  so a dashpot faster than the step lags the surface by ``tau dX/dt`` and
  dissipates ``cd (dX/dt)^2`` (holding ``X`` at its end value instead would
  add a numerical dashpot of ``k h/2``).  Out of contact the arms are coupled through the
  massless surface, ``X = (sum k_i Xd_i + Fa)/Kg``::

      Xd' = M Xd + b Fa,   M = diag(1/tau) (1 k^T/Kg - I),   b = diag(1/tau) 1/Kg

  advanced exactly over ``h`` for ``Fa`` held: ``Xd <- Xd + (E - I) Xd + G Fa``
  with ``E = exp(M h)`` and ``G = int_0^h exp(M s) ds b`` from one augmented
  matrix exponential (no cancellation when ``h << tau``).  One arm gives the
  SLS: ``E = exp(-h/tau_c)``, ``G = (1 - E)/k_inf``;
* **far step** (exact linear propagation): the exact flow of each
  damped oscillator over ``H`` (the drive enters through its particular
  solution), for a ladder of step lengths ``H = n dt``.
"""

from __future__ import annotations

import math

import numpy as np

from .expm import expm_small

# ---- layout of the scalar parameter vector P (fine step, probe, surface scalars)
(
    P_CZZ, P_CZV, P_CZF, P_CZD, P_CVZ, P_CVV, P_CVF, P_CVD0, P_CVD1,
    P_PZZ, P_PZV, P_PZF, P_PVZ, P_PVV, P_PVF,
    P_EF, P_RCZ, P_RCV, P_RC0, P_RC1, P_RPZ, P_RPV, P_RHO,
    P_BV1, P_BV2, P_COSDT, P_SINDT,
    P_M1, P_M2, P_C1, P_C2, P_K1, P_K2, P_F0, P_OMEGA, P_DT, P_NT,
    P_ZR, P_ZI,
    P_HR6, P_IHR6, P_A0, P_DSW, P_DSW_EXIT,
    P_KINF, P_KG, P_INVKG, P_BETA, P_KAPPA, P_KC, P_FA0, P_SEPTHR, P_FASEP, P_FAC, P_VDW,
    NP,
) = range(56)  # fmt: skip

# ---- rows of the per-arm table A (N columns)
A_K, A_ALPHA, A_KER, A_OMER, A_G, A_LIN, NA = range(7)

# ---- layout of one ladder entry (far step of n fine steps); the K* pairs are the real and
# imaginary parts of the first-harmonic projection factors of harmonic_factors()
(
    L_N, L_C00, L_C01, L_C10, L_C11, L_P00, L_P01, L_P10, L_P11, L_COS, L_SIN, L_H,
    L_K1R, L_K1I, L_K1BR, L_K1BI, L_K2R, L_K2I, L_K2BR, L_K2BI, L_KPR, L_KPI,
    NL,
) = range(23)  # fmt: skip


def verlet_matrix(dt: float, m: float, k: float, c: float) -> np.ndarray:
    """Coefficients of the linear Verlet map ``(z, vp, F, drive_n, drive_n+1) -> (z', vp')``.

    ``vp`` is the velocity without its share of the current force
    (``v = vp + bv F``, ``bv = (dt/2)/(m (1 + dt c/2m))``); the damping is
    implicit in the velocity half step.  Returns a (2, 5) array.
    """
    w2, g, im = k / m, c / m, 1.0 / m
    inv = 1.0 / (1.0 + 0.5 * dt * g)
    bv = 0.5 * dt * inv * im
    out = np.zeros((2, 5))
    for j in range(5):
        u = np.zeros(5)
        u[j] = 1.0
        z, vp, f, d0, d1 = u
        v = vp + bv * f
        a = -w2 * z - g * v + (d0 + f) * im
        z1 = z + dt * v + 0.5 * dt * dt * a
        out[0, j] = z1
        out[1, j] = (v + 0.5 * dt * a + 0.5 * dt * (-w2 * z1 + d1 * im)) * inv
    return out


def verlet_row(m: np.ndarray) -> np.ndarray:
    """Coefficients of ``z_(n+2)`` on ``(z_n, vp_n, F_n, drive_n, drive_n+1)`` with ``F_(n+1) = 0``."""
    r = m[0, 0] * m[0] + m[0, 1] * m[1]
    r[4] += m[0, 3]
    return r


def oscillator_flow(m: float, k: float, c: float, h: float) -> np.ndarray:
    """Exact flow ``(z, v) -> (z, v)`` of ``m z'' + c z' + k z = 0`` over ``h`` (2x2), in
    closed form for the underdamped oscillator (``Q > 1/2``, checked by the config):
    ``exp(-g h) [[C + g S / wd, S / wd], [-w0^2 S / wd, C - g S / wd]]`` with
    ``g = c / 2m``, ``wd = sqrt(k/m - g^2)``, ``C, S = cos, sin(wd h)`` -- exact to rounding
    (3.6e-16 elementwise against 40-digit mpmath, as scipy's expm)."""
    g = c / (2.0 * m)
    w02 = k / m
    wd = math.sqrt(w02 - g * g)
    e, cw, sw = math.exp(-g * h), math.cos(wd * h), math.sin(wd * h)
    return e * np.array([[cw + g * sw / wd, sw / wd], [-w02 * sw / wd, cw - g * sw / wd]])


def exp_phi(mat: np.ndarray, b: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """``(exp(M h) - I, int_0^h exp(M s) ds b)`` from one augmented exponential.

    ``E - I = M int_0^h exp(M s) ds``: the integral comes out of the
    exponential of ``[[M h, h I], [0, 0]]`` without the cancellation of
    ``exp(M h) - I`` when ``h`` is far below every time constant.
    """
    n = len(mat)
    aug = np.zeros((2 * n, 2 * n))
    aug[:n, :n] = mat * h
    aug[:n, n:] = np.eye(n) * h
    big = expm_small(aug)
    phi = big[:n, n:]  # int_0^h exp(M s) ds
    return mat @ phi, phi @ b


def arm_matrices(k_inf: float, k: np.ndarray, cd: np.ndarray, vdw_on_surface: bool):
    """``(M, b)`` of the out-of-contact arm dynamics ``Xd' = M Xd + b Fa`` (module docstring)."""
    kg = k_inf + float(np.sum(k))
    rate = k / cd  # 1/tau_i
    mat = np.outer(rate, k) / kg - np.diag(rate)
    b = rate / kg if vdw_on_surface else np.zeros(len(k))
    return mat, b


def surface_step(k_inf: float, k: np.ndarray, cd: np.ndarray, h: float, vdw_on_surface: bool):
    """Per-arm table (NA, N), the coupled creep ``E - I`` (N, N) and scalars at step ``h``."""
    k = np.asarray(k, float)
    cd = np.asarray(cd, float)
    kg = k_inf + float(np.sum(k))
    tau = cd / k
    er = np.exp(-h / tau)
    omer = -np.expm1(-h / tau)
    mat, b = arm_matrices(k_inf, k, cd, vdw_on_surface)
    emi, g = exp_phi(mat, b, h)
    table = np.zeros((NA, len(k)))
    table[A_K] = k
    table[A_ALPHA] = (k + emi.T @ k) / kg
    table[A_KER] = k * er
    table[A_OMER] = omer
    table[A_G] = g
    table[A_LIN] = lin_lag(h / tau)
    beta = (1.0 + float(k @ g)) / kg if vdw_on_surface else 0.0
    kc = k_inf + float(np.sum(k * (er + table[A_LIN])))  # k_inf + sum k phi
    return table, emi, beta, kc


def lin_lag(x: np.ndarray) -> np.ndarray:
    """``phi - e`` of the linear-target dashpot step for ``x = h/tau`` (module docstring):
    ``(1 - e)/x - e`` with ``e = exp(-x)``; its series ``x/2 - x^2/3 + x^3/8`` below 1e-4
    (the closed form cancels there)."""
    x = np.asarray(x, float)
    small = x < 1e-4
    xs = np.where(small, 1.0, x)
    closed = -np.expm1(-xs) / xs - np.exp(-xs)
    series = x / 2 - x * x / 3 + x**3 / 8
    return np.where(small, series, closed)


def modes(m: float, k: float, c: float) -> complex:
    """Characteristic exponent ``mu = lam + i wd`` of ``m z'' + c z' + k z = 0`` (underdamped)."""
    lam = -0.5 * c / m
    return complex(lam, math.sqrt(k / m - lam * lam))


def _int_exp(x: complex, h: float) -> complex:
    """``int_0^h exp(x s) ds`` without cancellation for small ``|x h|``."""
    xh = x * h
    if abs(xh) < 1e-3:
        return h * (1 + xh / 2 + xh * xh / 6 + xh**3 / 24)
    return (np.exp(xh) - 1) / x


def harmonic_factors(mu1: complex, mu2: complex, omega: float, h: float) -> list[complex]:
    """Factors of the exact first-harmonic projection ``int_0^h q(s) exp(-i w (t0 + s)) ds``
    over a far step: ``[K1, K1b, K2, K2b, Kp]`` with ``K = int_0^h exp((mu - i w) s) ds``,
    ``Kb`` the same for the conjugate mode and ``Kp = int_0^h exp(-2 i w s) ds``."""
    iw = 1j * omega
    return [
        _int_exp(mu1 - iw, h),
        _int_exp(mu1.conjugate() - iw, h),
        _int_exp(mu2 - iw, h),
        _int_exp(mu2.conjugate() - iw, h),
        _int_exp(-2 * iw, h),
    ]


def drive_particular(m: float, k: float, c: float, omega: float, f0: float) -> complex:
    """Complex amplitude ``Z`` of the driven solution ``z = Re(Z exp(i omega t))`` [m]."""
    return f0 / complex(k - m * omega * omega, c * omega)


def build(
    m1, k1, c1, m2, k2, c2, omega, f0,
    k_inf, k, cd, hr6, a0, vdw_on_surface,
    dt, steps_per_period, d_switch, ladder,
):  # fmt: skip
    """All kernel coefficients.  Returns ``(P, A, EMI, LAD, LEMI, LG)``.

    ``ladder``: far-step lengths in fine steps (empty = all-fine Verlet);
    ``d_switch`` [m]: gap below which only fine steps are taken.
    """
    k = np.asarray(k, float)
    cd = np.asarray(cd, float)
    mc = verlet_matrix(dt, m1, k1, c1)
    mp = verlet_matrix(dt, m2, k2, c2)
    rc = verlet_row(mc)
    rp = verlet_row(mp)
    p = np.zeros(NP)
    p[P_CZZ], p[P_CZV], p[P_CZF], p[P_CZD] = mc[0, 0], mc[0, 1], mc[0, 2], mc[0, 3] * f0
    p[P_CVZ], p[P_CVV], p[P_CVF], p[P_CVD0], p[P_CVD1] = mc[1, 0], mc[1, 1], mc[1, 2], mc[1, 3] * f0, mc[1, 4] * f0
    p[P_PZZ], p[P_PZV], p[P_PZF] = mp[0, 0], mp[0, 1], mp[0, 2]
    p[P_PVZ], p[P_PVV], p[P_PVF] = mp[1, 0], mp[1, 1], mp[1, 2]
    p[P_EF] = mc[0, 2] + mp[0, 2]
    p[P_RCZ], p[P_RCV], p[P_RC0], p[P_RC1] = rc[0], rc[1], rc[3] * f0, rc[4] * f0
    p[P_RPZ], p[P_RPV] = rp[0], rp[1]
    p[P_RHO] = rc[2] + rp[2]
    p[P_BV1] = 0.5 * dt / (1.0 + 0.5 * dt * c1 / m1) / m1
    p[P_BV2] = 0.5 * dt / (1.0 + 0.5 * dt * c2 / m2) / m2
    p[P_COSDT], p[P_SINDT] = math.cos(omega * dt), math.sin(omega * dt)
    p[P_M1], p[P_M2], p[P_C1], p[P_C2], p[P_K1], p[P_K2] = m1, m2, c1, c2, k1, k2
    p[P_F0], p[P_OMEGA], p[P_DT], p[P_NT] = f0, omega, dt, steps_per_period
    z = drive_particular(m1, k1, c1, omega, f0)
    p[P_ZR], p[P_ZI] = z.real, z.imag
    p[P_HR6] = hr6
    p[P_IHR6] = 1.0 / hr6 if hr6 > 0 else 0.0
    p[P_A0] = a0
    p[P_DSW] = d_switch
    p[P_DSW_EXIT] = 1.25 * d_switch
    kg = k_inf + float(np.sum(k))
    table, emi, beta, kc = surface_step(k_inf, k, cd, dt, vdw_on_surface)
    fa0 = hr6 / (a0 * a0)
    p[P_KINF], p[P_KG], p[P_INVKG], p[P_BETA] = k_inf, kg, 1.0 / kg, beta
    p[P_KAPPA] = p[P_EF] + beta
    p[P_KC] = kc
    p[P_FA0] = fa0
    p[P_SEPTHR] = fa0 if vdw_on_surface else 0.0
    p[P_FASEP] = fa0 if vdw_on_surface else 0.0
    p[P_FAC] = 0.0 if vdw_on_surface else fa0
    p[P_VDW] = 1.0 if vdw_on_surface else 0.0
    lad, lemi, lg = ladder_tables(m1, k1, c1, m2, k2, c2, omega, k_inf, k, cd, vdw_on_surface, dt, ladder)
    return p, table, emi, lad, lemi, lg


def ladder_tables(m1, k1, c1, m2, k2, c2, omega, k_inf, k, cd, vdw_on_surface, dt, ladder):
    """Far-step tables for step lengths ``ladder`` (in fine steps): ``(LAD (n, NL), LEMI (n, N, N), LG (n, N))``."""
    n_arms = len(k)
    lad = np.zeros((len(ladder), NL))
    lemi = np.zeros((len(ladder), n_arms, n_arms))
    lg = np.zeros((len(ladder), n_arms))
    mat, b = arm_matrices(k_inf, np.asarray(k, float), np.asarray(cd, float), vdw_on_surface)
    mu1, mu2 = modes(m1, k1, c1), modes(m2, k2, c2)
    for i, n in enumerate(ladder):
        h = n * dt
        fc = oscillator_flow(m1, k1, c1, h)
        fp = oscillator_flow(m2, k2, c2, h)
        lad[i, L_N] = n
        lad[i, L_C00], lad[i, L_C01], lad[i, L_C10], lad[i, L_C11] = fc.ravel()
        lad[i, L_P00], lad[i, L_P01], lad[i, L_P10], lad[i, L_P11] = fp.ravel()
        lad[i, L_COS], lad[i, L_SIN] = math.cos(omega * h), math.sin(omega * h)
        lad[i, L_H] = h
        for col, val in zip((L_K1R, L_K1BR, L_K2R, L_K2BR, L_KPR), harmonic_factors(mu1, mu2, omega, h)):
            lad[i, col], lad[i, col + 1] = val.real, val.imag
        lemi[i], lg[i] = exp_phi(mat, b, h)
    return lad, lemi, lg
