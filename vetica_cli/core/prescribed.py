"""Massless Zener SLS surface driven by a prescribed (measured) tip trajectory.

The inverse problem of ``vetica extract --method full``: the tip
positions ``z_tip`` of a record are given, the massless SLS surface
(thesis 3.2, appendix C) responds, and the tip-sample force follows.  The
updates are the simulator's own (:mod:`.sls`), applied once per sample of
the record (time step ``h`` = the print step) instead of once per
integration step: for every sample ``n``::

    gap          d_n = (z_n - s0) - X_(n-1)                                   [m]
    non-contact  (d_n > a0):  Fa = H R / (6 d_n^2),  X_n = alpha Xd + beta Fa,
                 Xd <- gamma Fa + ec Xd,             Fts_n = -Fa             (thesis eqs. 3, 59-65)
    contact      X_n = z_n - s0 - a0,  F_sls = kc X_n - k0er Xd,
                 Xd <- (1 - er) X_n + er Xd,         Fts_n = -F_sls - fa_c   (thesis eqs. 51-58)
    separation   F_sls > sep_thr:  X_n = (k0 Xd + fa_sep)/Kg,  Fts_n = -Fa(a0)

``s0`` is the height of the undeformed surface in the record's tip
coordinates (0 for the simulator's own ``z_tip``); ``ec = exp(-h/tau_c)``,
``er = exp(-h/tau_r)`` and the other coefficients are those of
:func:`.sls.sls_coefficients` at step ``h``.

Far from the surface the attraction is a tiny, slowly varying load, and the
surface only creeps: there a whole block of ``block`` samples is advanced by
one exact-exponential step of length ``block h`` (the same
:func:`.sls.noncontact_update` with the coefficients at ``block h``) when the
gap at both ends of the block exceeds ``far_gap`` and the caller allows it
(``coarse_ok``, from which samples it wants the force at).

Tangent-linear model: alongside the state the kernel propagates its exact
derivatives (for a fixed contact/separation schedule) with respect to
``ndir`` of the directions ``DIRECTIONS`` = (initial dashpot position
``Xd0`` [m], surface height ``s0`` [m], ``ln k_inf``, ``ln k0``, ``ln cd``,
``ln(H R/6)``), and writes ``dFts/d(direction)`` at every wanted sample: the
Jacobian of a least-squares fit in log-parameters in one pass.  The
coefficient derivatives are in closed form (:func:`coefficient_tangents`).
"""

import math

import numpy as np
from numba import njit

from .expm import expm_small
from .sls import contact_update, noncontact_update, released_position, sls_coefficients, vdw_force

DIRECTIONS = ("xd0", "s0", "ln_k_inf", "ln_k0", "ln_cd", "ln_hr6")
NDIR = len(DIRECTIONS)

# rows of the coefficient table of coefficient_tangents()
C_EC, C_ER, C_ALPHA, C_BETA, C_GAMMA, C_KC, C_K0ER, C_FA0, C_SEP, C_FASEP, C_FAC, C_INVKG, C_K0, C_LIN, C_K0LIN = range(15)
NCOEF = 15


@njit(cache=True)
def coefficient_tangents(k_inf, k0, cd, hr6, a0, vdw_on_surface, dt):
    """Coefficients of the surface updates at step ``dt`` and their derivatives.

    Returns ``(c, dc)``: ``c`` (NCOEF,) the values of
    :func:`.sls.sls_coefficients` (rows ``C_*``; ``C_K0`` = k0) and ``dc``
    (NCOEF, NDIR) their derivatives along ``DIRECTIONS`` (columns 0, 1, the
    state directions, are zero).  With ``u = dt/tau_c``, ``v = dt/tau_r``::

        d ln tau_c = d ln cd - (k0 d ln k_inf + k_inf d ln k0)/Kg
        d ln tau_r = d ln cd - d ln k0
        d ec = ec u d ln tau_c,    d er = er v d ln tau_r
    """
    ec, er, alpha, beta, gamma, kc, k0er, fa0, sep_thr, fa_sep, fa_c, inv_kg = sls_coefficients(
        k_inf, k0, cd, dt, hr6, a0, vdw_on_surface
    )
    c = np.empty(NCOEF)
    c[C_EC] = ec
    c[C_ER] = er
    c[C_ALPHA] = alpha
    c[C_BETA] = beta
    c[C_GAMMA] = gamma
    c[C_KC] = kc
    c[C_K0ER] = k0er
    c[C_FA0] = fa0
    c[C_SEP] = sep_thr
    c[C_FASEP] = fa_sep
    c[C_FAC] = fa_c
    c[C_INVKG] = inv_kg
    c[C_K0] = k0
    # the linear-target step (core/coefficients.py): the surface moves linearly across the step, from the last
    # sample's position; lin = phi - er, phi = (tau_r/h)(1 - er); kc becomes k_inf + k0 (er + lin)
    v0 = dt * k0 / cd
    lin = v0 / 2.0 - v0 * v0 / 3.0 + v0 ** 3 / 8.0 if v0 < 1e-4 else -math.expm1(-v0) / v0 - er
    c[C_LIN] = lin
    c[C_K0LIN] = k0 * lin
    c[C_KC] = kc + k0 * lin
    dc = np.zeros((NCOEF, NDIR))
    kg = k0 + k_inf
    tau_c = cd * kg / (k0 * k_inf)
    tau_r = cd / k0
    u = dt / tau_c
    v = dt / tau_r
    one_m_ec = -math.expm1(-u)  # 1 - ec without cancellation
    one_m_er = -math.expm1(-v)
    for j in range(2, NDIR):
        dk_inf = k_inf if j == 2 else 0.0  # d k_inf / d direction
        dk0 = k0 if j == 3 else 0.0
        dlncd = 1.0 if j == 4 else 0.0
        dlnhr6 = 1.0 if j == 5 else 0.0
        dkg = dk_inf + dk0
        dln_tc = dlncd - (k0 * (dk_inf / k_inf) + k_inf * (dk0 / k0)) / kg
        dln_tr = dlncd - dk0 / k0
        dec = ec * u * dln_tc
        der = er * v * dln_tr
        dinv = -dkg * inv_kg * inv_kg
        dc[C_EC, j] = dec
        dc[C_ER, j] = der
        dc[C_ALPHA, j] = dk0 * inv_kg * ec + k0 * dinv * ec + k0 * inv_kg * dec
        if vdw_on_surface:
            g = one_m_ec / k_inf
            dg = -dec / k_inf - g * dk_inf / k_inf
            dc[C_GAMMA, j] = dg
            dc[C_BETA, j] = dinv * (1.0 + k0 * g) + inv_kg * (dk0 * g + k0 * dg)
        dlin = (lin - er * v) * dln_tr  # d(phi - er): d phi = lin d ln tau_r, d er = er v d ln tau_r
        dc[C_KC, j] = dkg - dk0 * one_m_er + k0 * der + dk0 * lin + k0 * dlin
        dc[C_K0ER, j] = dk0 * er + k0 * der
        dc[C_LIN, j] = dlin
        dc[C_K0LIN, j] = dk0 * lin + k0 * dlin
        dfa0 = fa0 * dlnhr6
        dc[C_FA0, j] = dfa0
        if vdw_on_surface:
            dc[C_SEP, j] = dfa0
            dc[C_FASEP, j] = dfa0
        else:
            dc[C_FAC, j] = dfa0
        dc[C_INVKG, j] = dinv
        dc[C_K0, j] = dk0
    return c, dc


@njit(cache=True, inline="always", error_model="numpy")
def _noncontact(d, xd, fa, hr6, ihr6, c, dc, dir0, ndir, dxd, dx, dfa, ds0, dlnhr6):
    """One non-contact update (:func:`.sls.noncontact_update`) at gap ``d`` with the
    coefficients ``c`` of its step, and its tangent: ``dfa``, ``dx``, ``dxd`` updated
    in place (``dx`` enters as the derivative of the previous surface position)."""
    alpha, beta, gamma, ec = c[C_ALPHA], c[C_BETA], c[C_GAMMA], c[C_EC]
    fa, x, xd_new = noncontact_update(d, xd, fa, hr6, ihr6, alpha, beta, gamma, ec)
    for j in range(dir0, ndir):
        dfa[j] = fa * dlnhr6[j] + 2.0 * fa / d * (ds0[j] + dx[j])  # d = z - s0 - X_prev
        dx[j] = dc[C_ALPHA, j] * xd + alpha * dxd[j] + dc[C_BETA, j] * fa + beta * dfa[j]
        dxd[j] = dc[C_GAMMA, j] * fa + gamma * dfa[j] + dc[C_EC, j] * xd + ec * dxd[j]
    return fa, x, xd_new


@njit(cache=True, inline="always", error_model="numpy")
def _contact(xc, xp, xd, c, dc, dir0, ndir, dxd, dx, dfa, ds0):
    """One contact update with the surface at ``xc``, moving linearly from ``xp`` (the last
    sample's position) across the step (the simulator's linear-target step), and its tangent;
    ``dfa`` receives ``d(F_sls + fa_c)`` (``dx`` enters as the derivative of ``xp``).  On
    separation (``F_sls > sep_thr``) the surface is released (:func:`.sls.released_position`)
    and ``dfa`` becomes ``d Fa(a0)``.  Returns ``(fts, f_sls, x, xd, separated)``."""
    kc, k0er, er, lin, k0lin = c[C_KC], c[C_K0ER], c[C_ER], c[C_LIN], c[C_K0LIN]
    f_sls = kc * xc - k0er * xd - k0lin * xp
    xd_new = er * xd + (1.0 - er - lin) * xc + lin * xp
    for j in range(dir0, ndir):
        dfa[j] = (dc[C_KC, j] * xc - kc * ds0[j] - dc[C_K0ER, j] * xd - k0er * dxd[j] - dc[C_K0LIN, j] * xp
                  - k0lin * dx[j] + dc[C_FAC, j])  # fmt: skip
        dxd[j] = (dc[C_ER, j] * xd + er * dxd[j] - (dc[C_ER, j] + dc[C_LIN, j]) * xc - (1.0 - er - lin) * ds0[j]
                  + dc[C_LIN, j] * xp + lin * dx[j])  # fmt: skip
        dx[j] = -ds0[j]
    if f_sls > c[C_SEP]:
        k0, fa_sep, inv_kg = c[C_K0], c[C_FASEP], c[C_INVKG]
        x = released_position(xd_new, fa_sep, k0, inv_kg)
        for j in range(dir0, ndir):
            dx[j] = (dc[C_K0, j] * xd_new + k0 * dxd[j] + dc[C_FASEP, j]) * inv_kg + (k0 * xd_new + fa_sep) * dc[
                C_INVKG, j
            ]
            dfa[j] = dc[C_FA0, j]
        return -c[C_FA0], f_sls, x, xd_new, True
    return -f_sls - c[C_FAC], f_sls, xc, xd_new, False


@njit(cache=True, error_model="numpy")
def surface_force(
    z, s0, k_inf, k0, cd, hr6, a0, vdw_on_surface, h,
    block, coarse_ok, want, far_gap, substeps, sub_gap,
    xd0, contact0, ndir, out_f, out_jac, dir0=0,
):  # fmt: skip
    """Tip-sample force of the SLS surface under the prescribed tip positions ``z``.

    Parameters (SI): ``z`` (N,) tip positions [m] sampled every ``h`` [s];
    ``s0`` undeformed-surface height in those coordinates [m]; surface
    ``k_inf, k0`` [N/m], ``cd`` [kg/s], ``hr6 = H R/6`` [J m], ``a0`` [m];
    ``block`` samples per coarse step; ``coarse_ok`` (N // block,) uint8,
    1 where a block may be advanced in one step (if also the gap at both its
    ends exceeds ``far_gap`` [m]); ``want`` (N,) uint8, 1 at the samples whose
    force is written (a coarse block may only want its last sample);
    ``substeps``: surface updates per sample interval (tip position
    interpolated linearly) where the tip is out of contact within ``sub_gap``
    [m] of the surface or separates during the interval: there the lagged
    gap -> attraction -> surface feedback of the simulator (gain
    ``2 Fa/(d Kg)``, above 1 near a0) evolves per update, not per second,
    so the simulator's own step ``dt = h/substeps`` reproduces it;
    ``xd0`` the dashpot position before the first sample [m] and ``contact0``
    whether the tip is then in contact; ``ndir`` the number of leading
    ``DIRECTIONS`` to differentiate along (0 = value only), from ``dir0`` on (a record
    whose start state is known, e.g. the approach from an undeformed surface, needs no
    ``Xd0`` direction: ``dir0 = 1``; the columns below ``dir0`` are not written).

    Writes ``out_f[k]`` = Fts [N] at the k-th wanted sample and
    ``out_jac[k, j]`` = dFts/d(direction j), j < ndir.  Returns ``(xd, x,
    contact, dxd, n_written, contacts, separations, coarse_steps)``: the state
    after the last sample (dashpot and surface positions [m], contact flag),
    ``dxd`` (NDIR,) the derivatives of that dashpot position, and counts.

    Why an SLS kernel beside :func:`arms_force` with one arm: it is 3-6x faster for the
    value and 1.7-4.7x with the six-direction Jacobian, for the same forces (relative
    difference 1e-13): on the worked example's 4-period record at 0.125 ns (640000
    samples, far blocks of 256), median of 7 passes, 0.7 ms against 2.2-4.4 ms and
    2-6 ms against 9-11 ms, three runs of ``scripts/measure_prescribed_sls.py`` on the
    shared 2-core machine at load 7.5.
    """
    n = len(z)
    cf, dcf = coefficient_tangents(k_inf, k0, cd, hr6, a0, vdw_on_surface, h)
    cb, dcb = coefficient_tangents(k_inf, k0, cd, hr6, a0, vdw_on_surface, h * block)
    cs, dcs = coefficient_tangents(k_inf, k0, cd, hr6, a0, vdw_on_surface, h / substeps)
    inv_kg = cf[C_INVKG]
    ihr6 = 1.0 / hr6 if hr6 > 0.0 else 0.0

    dxd = np.zeros(NDIR)  # derivatives of Xd
    dx = np.zeros(NDIR)  # derivatives of X (surface position after the previous sample)
    ds0 = np.zeros(NDIR)
    ds0[1] = 1.0
    dlnhr6 = np.zeros(NDIR)
    dlnhr6[5] = 1.0
    dfa = np.zeros(NDIR)  # derivatives of -Fts

    xd = xd0
    dxd[0] = 1.0
    contact = contact0
    # surface position before the first sample: relaxed onto the dashpot, pulled by the tip
    x = k0 * xd * inv_kg
    fa = 0.0
    if not contact:
        d = z[0] - s0 - x
        if d > a0:
            fa = hr6 / (d * d)
            x += cf[C_BETA] * fa
    dx[0] = k0 * inv_kg
    if contact:  # in contact at the start: the surface at the tip's first position (the linear target's start)
        x = z[0] - s0 - a0
        for j in range(NDIR):
            dx[j] = -ds0[j]

    k = 0  # next output row
    contacts = 0
    separations = 0
    coarse_steps = 0
    nblock = n // block
    fts = 0.0
    i = 0
    while i < n:
        b = i // block
        if i % block == 0:  # flush decayed derivatives before they turn subnormal (slow arithmetic)
            for j in range(dir0, ndir):
                if abs(dxd[j]) < 1e-250:
                    dxd[j] = 0.0
                if abs(dx[j]) < 1e-250:
                    dx[j] = 0.0
        # ---- one exact step over a whole far block
        if (not contact) and i % block == 0 and b < nblock and coarse_ok[b]:
            i_end = i + block - 1
            d = z[i_end] - s0 - x
            if z[i] - s0 - x > far_gap and d > far_gap:
                fa, x, xd = _noncontact(d, xd, fa, hr6, ihr6, cb, dcb, dir0, ndir, dxd, dx, dfa, ds0, dlnhr6)
                coarse_steps += 1
                if want[i_end]:
                    out_f[k] = -fa
                    for j in range(dir0, ndir):
                        out_jac[k, j] = -dfa[j]
                    k += 1
                i = i_end + 1
                continue
        # ---- one sample
        zz = z[i] - s0
        sub = False
        if substeps > 1:
            if contact:  # does the tip separate during this interval?
                sub = cf[C_KC] * (zz - a0) - cf[C_K0ER] * xd - cf[C_K0LIN] * x > cf[C_SEP]
            else:
                sub = zz - x < sub_gap
        if sub:
            # the simulator's own steps across the interval, tip interpolated linearly
            zp = (z[i - 1] if i > 0 else z[0]) - s0
            for m in range(1, substeps + 1):
                zm = zp + (zz - zp) * (m / substeps)
                if not contact:
                    d = zm - x
                    if d > a0:
                        fa, x, xd = _noncontact(d, xd, fa, hr6, ihr6, cs, dcs, dir0, ndir, dxd, dx, dfa, ds0, dlnhr6)
                        fts = -fa
                        continue
                    contact = True
                    contacts += 1
                fts, _, x, xd, sep = _contact(zm - a0, x, xd, cs, dcs, dir0, ndir, dxd, dx, dfa, ds0)
                if sep:
                    contact = False
                    separations += 1
                    fa = cs[C_FA0]
        elif not contact and zz - x > a0:
            fa, x, xd = _noncontact(zz - x, xd, fa, hr6, ihr6, cf, dcf, dir0, ndir, dxd, dx, dfa, ds0, dlnhr6)
            fts = -fa
        else:
            if not contact:
                contact = True
                contacts += 1
            fts, _, x, xd, sep = _contact(zz - a0, x, xd, cf, dcf, dir0, ndir, dxd, dx, dfa, ds0)
            if sep:
                contact = False
                separations += 1
                fa = cf[C_FA0]
        if want[i]:
            out_f[k] = fts
            for j in range(dir0, ndir):
                out_jac[k, j] = -dfa[j]
            k += 1
        i += 1
    return xd, x, contact, dxd, k, contacts, separations, coarse_steps


# =====================================================================================
# N Maxwell arms (Wiechert surface): the same updates with the arms coupled
# through the massless surface out of contact.
# =====================================================================================
#
# Directions of the N-arm kernel (``arm_directions``): the dashpot positions at the start
# ``Xd0_1..Xd0_N`` [m], the surface height ``s0`` [m], ``ln k_inf``, ``ln k_i``, ``ln cd_i``
# for each arm, ``ln(H R/6)``: ``3 N + 3`` in all; one arm gives ``DIRECTIONS``.

# rows of the per-arm coefficient table (AR_*, N columns) and the scalars (SC_*)
AR_K, AR_ER, AR_KER, AR_OMER, AR_ALPHA, AR_G, AR_LIN, AR_KLIN, NAR = range(9)
SC_KC, SC_BETA, SC_FA0, SC_SEP, SC_FASEP, SC_FAC, SC_INVKG, SC_HR6, NSC = range(9)
CSTEP = 1e-20  # complex step of the coefficient derivatives (exact to rounding: no subtraction)


def arm_directions(n_arms: int) -> tuple[str, ...]:
    """Names of the N-arm kernel's directions (module section comment)."""
    arms = [f"ln_{f}_{i}" for i in range(1, n_arms + 1) for f in ("k", "cd")]
    return (*(f"xd0_{i}" for i in range(1, n_arms + 1)), "s0", "ln_k_inf", *arms, "ln_hr6")


def arm_table(k_inf, k, cd, hr6, a0, vdw_on_surface, h):
    """Coefficients of the N-arm surface updates at step ``h`` [s] (real or complex inputs).

    Returns ``(arm (NAR, N), emi (N, N), sc (NSC,))``.  Contact, each arm relaxing towards
    ``X`` with ``er_i = exp(-h/tau_i)``, ``tau_i = cd_i/k_i``::

        F_n = kc X_n - sum_i ker_i Xd_i,    Xd_i <- Xd_i + omer_i (X_n - Xd_i)
        kc = k_inf + sum_i k_i er_i,  ker_i = k_i er_i,  omer_i = 1 - er_i

    Out of contact ``Xd' = M Xd + b Fa`` with ``M = diag(k/cd) (1 k^T/Kg - I)`` and
    ``b = (k/cd)/Kg`` (pull on; 0 off), exact over ``h`` for ``Fa`` held
    (as :func:`vetica_cli.core.coefficients.exp_phi`, here by :func:`expm_small`)::

        Xd <- Xd + emi Xd + g Fa,   X_n = alpha . Xd_(n-1) + beta Fa_n
        emi = exp(M h) - I,  g = int_0^h exp(M s) ds b,  alpha = (k + emi^T k)/Kg,  beta = (1 + k.g)/Kg

    One arm: ``emi = ec - 1``, the coefficients of :func:`.sls.sls_coefficients`.
    """
    k = np.asarray(k)
    cd = np.asarray(cd)
    n = len(k)
    dtype = np.result_type(k, cd, k_inf, hr6, float)
    kg = k_inf + np.sum(k)
    rate = k / cd  # 1/tau_i
    er = np.exp(-h * rate)
    omer = -np.expm1(-h * rate)
    mat = np.outer(rate, k) / kg - np.diag(rate)
    b = rate / kg if vdw_on_surface else np.zeros(n, dtype)
    aug = np.zeros((2 * n, 2 * n), dtype)
    aug[:n, :n] = mat * h
    aug[:n, n:] = np.eye(n) * h
    phi = expm_small(aug)[:n, n:]  # int_0^h exp(M s) ds
    emi = mat @ phi
    g = phi @ b
    arm = np.zeros((NAR, n), dtype)
    arm[AR_K] = k
    arm[AR_ER] = er
    arm[AR_KER] = k * er
    arm[AR_OMER] = omer
    arm[AR_ALPHA] = (k + emi.T @ k) / kg
    arm[AR_G] = g
    x = h * rate  # the linear-target step's lag phi - er (core/coefficients.lin_lag), complex-step safe
    small = np.abs(x.real) < 1e-4
    xs = np.where(small, 1.0, x)
    lin = np.where(small, x / 2 - x * x / 3 + x**3 / 8, -np.expm1(-xs) / xs - np.exp(-xs))
    arm[AR_LIN] = lin
    arm[AR_KLIN] = k * lin
    fa0 = hr6 / (a0 * a0)
    sc = np.zeros(NSC, dtype)
    sc[SC_KC] = k_inf + np.sum(k * (er + lin))
    sc[SC_BETA] = (1.0 + k @ g) / kg if vdw_on_surface else 0.0
    sc[SC_FA0] = fa0
    sc[SC_SEP] = fa0 if vdw_on_surface else 0.0
    sc[SC_FASEP] = fa0 if vdw_on_surface else 0.0
    sc[SC_FAC] = 0.0 if vdw_on_surface else fa0
    sc[SC_INVKG] = 1.0 / kg
    sc[SC_HR6] = hr6
    return arm, emi, sc


def arm_coefficients(k_inf, k, cd, hr6, a0, vdw_on_surface, steps, tangents=True):
    """Coefficient tables of the N-arm kernel at the step lengths ``steps`` [s] (three: the
    sample interval, a far block, a sub-step) and their derivatives along the kernel's
    parameter directions.

    Returns ``(arm (3, NAR, N), emi (3, N, N), sc (3, NSC), darm (3, NAR, N, D), demi
    (3, N, N, D), dsc (3, NSC, D))`` with ``D = 3 N + 3`` (:func:`arm_directions`; the
    state and ``s0`` columns are zero).  The derivatives along ``ln p`` come from one
    complex step ``p -> p (1 + i CSTEP)`` of :func:`arm_table` each: no subtraction, so
    exact to rounding, and no hand-derived derivative of the matrix exponential.
    """
    k = np.asarray(k, float)
    cd = np.asarray(cd, float)
    n = len(k)
    nd = 3 * n + 3
    p0 = np.concatenate([[k_inf], np.column_stack([k, cd]).ravel(), [hr6]])  # ln-parameter directions
    arm = np.zeros((3, NAR, n))
    emi = np.zeros((3, n, n))
    sc = np.zeros((3, NSC))
    darm = np.zeros((3, NAR, n, nd))
    demi = np.zeros((3, n, n, nd))
    dsc = np.zeros((3, NSC, nd))
    for s, h in enumerate(steps):
        arm[s], emi[s], sc[s] = arm_table(k_inf, k, cd, hr6, a0, vdw_on_surface, h)
        if not tangents:
            continue
        for j in range(len(p0)):
            p = p0.astype(complex)
            p[j] *= 1.0 + 1j * CSTEP
            ca, ce, cs = arm_table(p[0], p[1:-1:2], p[2:-1:2], p[-1], a0, vdw_on_surface, h)
            col = n + 1 + j
            darm[s, :, :, col] = ca.imag / CSTEP
            demi[s, :, :, col] = ce.imag / CSTEP
            dsc[s, :, col] = cs.imag / CSTEP
    return arm, emi, sc, darm, demi, dsc


@njit(cache=True, error_model="numpy")
def arms_force(
    z, s0, a0, block, coarse_ok, want, far_gap, substeps, sub_gap,
    xd0, contact0, ndir, arm3, emi3, sc3, darm3, demi3, dsc3, out_f, out_jac,
):  # fmt: skip
    """Tip-sample force of the N-arm surface under the prescribed tip positions ``z``.

    As :func:`surface_force` (same sampling, far blocks, sub-steps and outputs) for the
    Wiechert surface (N Maxwell arms); coefficients from :func:`arm_coefficients` (index 0:
    the sample interval, 1: a far block, 2: a sub-step); ``xd0`` (N,) the dashpot
    positions before the first sample [m].  Differentiates along the first ``ndir`` of
    :func:`arm_directions`.  Returns ``(xd (N,), x, contact, dxd (N, D), n_written,
    contacts, separations, coarse_steps)``.
    """
    n = len(z)
    na = len(xd0)
    nd = darm3.shape[3]
    hr6 = sc3[0, SC_HR6]
    ihr6 = 1.0 / hr6 if hr6 > 0.0 else 0.0
    i_s0 = na
    i_hr6 = nd - 1
    xd = xd0.copy()
    dxd = np.zeros((na, nd))
    for i in range(na):
        if i < ndir:
            dxd[i, i] = 1.0
    dx = np.zeros(nd)
    dfa = np.zeros(nd)
    xd_new = np.empty(na)
    dxd_new = np.empty((na, nd))
    ds0 = np.zeros(nd)
    ds0[i_s0] = 1.0
    dlnhr6 = np.zeros(nd)
    dlnhr6[i_hr6] = 1.0
    contact = contact0
    # surface position before the first sample: relaxed onto the dashpots, pulled by the tip
    c0 = 0
    inv_kg = sc3[c0, SC_INVKG]
    xs = 0.0
    for i in range(na):
        xs += arm3[c0, AR_K, i] * xd[i]
    x = xs * inv_kg
    for j in range(ndir):
        acc = 0.0
        for i in range(na):
            acc += darm3[c0, AR_K, i, j] * xd[i] + arm3[c0, AR_K, i] * dxd[i, j]
        dx[j] = acc * inv_kg + xs * dsc3[c0, SC_INVKG, j]
    fa = 0.0
    if not contact:
        d = z[0] - s0 - x
        if d > a0:
            fa = hr6 / (d * d)
            beta = sc3[c0, SC_BETA]
            for j in range(ndir):
                dfa_j = fa * dlnhr6[j] + 2.0 * fa / d * (ds0[j] + dx[j])
                dx[j] += dsc3[c0, SC_BETA, j] * fa + beta * dfa_j
            x += beta * fa
    else:  # in contact at the start: the surface at the tip's first position (the linear target's start)
        x = z[0] - s0 - a0
        for j in range(nd):
            dx[j] = -ds0[j]

    k = 0
    contacts = 0
    separations = 0
    coarse_steps = 0
    nblock = n // block
    fts = 0.0
    i = 0
    while i < n:
        b = i // block
        if i % block == 0:  # flush decayed derivatives before they turn subnormal (slow arithmetic)
            for j in range(ndir):
                if abs(dx[j]) < 1e-250:
                    dx[j] = 0.0
                for a in range(na):
                    if abs(dxd[a, j]) < 1e-250:
                        dxd[a, j] = 0.0
        # ---- one exact step over a whole far block
        if (not contact) and i % block == 0 and b < nblock and coarse_ok[b]:
            i_end = i + block - 1
            d = z[i_end] - s0 - x
            if z[i] - s0 - x > far_gap and d > far_gap:
                fa, x = _arms_noncontact(d, xd, fa, hr6, ihr6, 1, arm3, emi3, sc3, darm3, demi3, dsc3, ndir,
                                         dxd, dx, dfa, ds0, dlnhr6, xd_new, dxd_new)  # fmt: skip
                coarse_steps += 1
                if want[i_end]:
                    out_f[k] = -fa
                    for j in range(ndir):
                        out_jac[k, j] = -dfa[j]
                    k += 1
                i = i_end + 1
                continue
        # ---- one sample
        zz = z[i] - s0
        sub = False
        if substeps > 1:
            if contact:  # does the tip separate during this interval?
                f_try = sc3[0, SC_KC] * (zz - a0)
                for a in range(na):
                    f_try -= arm3[0, AR_KER, a] * xd[a] + arm3[0, AR_KLIN, a] * x
                sub = f_try > sc3[0, SC_SEP]
            else:
                sub = zz - x < sub_gap
        if sub:
            zp = (z[i - 1] if i > 0 else z[0]) - s0
            for m in range(1, substeps + 1):
                zm = zp + (zz - zp) * (m / substeps)
                if not contact:
                    d = zm - x
                    if d > a0:
                        fa, x = _arms_noncontact(d, xd, fa, hr6, ihr6, 2, arm3, emi3, sc3, darm3, demi3, dsc3,
                                                 ndir, dxd, dx, dfa, ds0, dlnhr6, xd_new, dxd_new)  # fmt: skip
                        fts = -fa
                        continue
                    contact = True
                    contacts += 1
                fts, x, sep = _arms_contact(zm - a0, x, xd, 2, arm3, sc3, darm3, dsc3, ndir, dxd, dx, dfa, ds0,
                                            xd_new, dxd_new)  # fmt: skip
                if sep:
                    contact = False
                    separations += 1
                    fa = sc3[2, SC_FA0]
        elif not contact and zz - x > a0:
            fa, x = _arms_noncontact(zz - x, xd, fa, hr6, ihr6, 0, arm3, emi3, sc3, darm3, demi3, dsc3, ndir,
                                     dxd, dx, dfa, ds0, dlnhr6, xd_new, dxd_new)  # fmt: skip
            fts = -fa
        else:
            if not contact:
                contact = True
                contacts += 1
            fts, x, sep = _arms_contact(zz - a0, x, xd, 0, arm3, sc3, darm3, dsc3, ndir, dxd, dx, dfa, ds0,
                                        xd_new, dxd_new)  # fmt: skip
            if sep:
                contact = False
                separations += 1
                fa = sc3[0, SC_FA0]
        if want[i]:
            out_f[k] = fts
            for j in range(ndir):
                out_jac[k, j] = -dfa[j]
            k += 1
        i += 1
    return xd, x, contact, dxd, k, contacts, separations, coarse_steps


@njit(cache=True, inline="always", error_model="numpy")
def _arms_noncontact(d, xd, fa, hr6, ihr6, c, arm3, emi3, sc3, darm3, demi3, dsc3, ndir, dxd, dx, dfa, ds0, dlnhr6,
                     xd_new, dxd_new):  # fmt: skip
    """One non-contact update at gap ``d`` with the coefficients of step ``c`` (see
    :func:`arm_table`) and its tangent; ``xd``, ``dxd``, ``dx``, ``dfa`` updated in
    place (``dx`` enters as the derivative of the previous surface position).
    Returns ``(fa, x)``."""
    na = len(xd)
    fa = vdw_force(d, fa, hr6, ihr6)
    beta = sc3[c, SC_BETA]
    x = beta * fa
    for a in range(na):
        x += arm3[c, AR_ALPHA, a] * xd[a]
        acc = arm3[c, AR_G, a] * fa
        for m in range(na):
            acc += emi3[c, a, m] * xd[m]
        xd_new[a] = xd[a] + acc
    for j in range(ndir):
        dfa_j = fa * dlnhr6[j] + 2.0 * fa / d * (ds0[j] + dx[j])  # d = z - s0 - X_prev
        dfa[j] = dfa_j
        acc = dsc3[c, SC_BETA, j] * fa + beta * dfa_j
        for a in range(na):
            acc += darm3[c, AR_ALPHA, a, j] * xd[a] + arm3[c, AR_ALPHA, a] * dxd[a, j]
        dx[j] = acc
        for a in range(na):
            acc = dxd[a, j] + darm3[c, AR_G, a, j] * fa + arm3[c, AR_G, a] * dfa_j
            for m in range(na):
                acc += demi3[c, a, m, j] * xd[m] + emi3[c, a, m] * dxd[m, j]
            dxd_new[a, j] = acc
    for a in range(na):
        xd[a] = xd_new[a]
        for j in range(ndir):
            dxd[a, j] = dxd_new[a, j]
    return fa, x


@njit(cache=True, inline="always", error_model="numpy")
def _arms_contact(xc, xp, xd, c, arm3, sc3, darm3, dsc3, ndir, dxd, dx, dfa, ds0, xd_new, dxd_new):
    """One contact update with the surface at ``xc`` (coefficients of step ``c``) and its
    tangent; ``dfa`` receives ``d(F_sls + fa_c)``.  On separation (``F_sls > sep_thr``) the
    surface is released to ``(sum k_i Xd_i + Fa_sep)/Kg`` and ``dfa`` becomes ``d Fa(a0)``.
    Returns ``(fts, x, separated)``."""
    na = len(xd)
    kc = sc3[c, SC_KC]
    f_sls = kc * xc
    for a in range(na):  # the linear-target step: the surface moves from xp (the last sample's) to xc
        f_sls -= arm3[c, AR_KER, a] * xd[a] + arm3[c, AR_KLIN, a] * xp
        xd_new[a] = xd[a] + arm3[c, AR_OMER, a] * (xc - xd[a]) - arm3[c, AR_LIN, a] * (xc - xp)
    for j in range(ndir):
        dxc = -ds0[j]
        dxp = dx[j]
        acc = dsc3[c, SC_KC, j] * xc + kc * dxc + dsc3[c, SC_FAC, j]
        for a in range(na):
            acc -= darm3[c, AR_KER, a, j] * xd[a] + arm3[c, AR_KER, a] * dxd[a, j]
            acc -= darm3[c, AR_KLIN, a, j] * xp + arm3[c, AR_KLIN, a] * dxp
            dxd_new[a, j] = (dxd[a, j] + darm3[c, AR_OMER, a, j] * (xc - xd[a]) + arm3[c, AR_OMER, a] * (dxc - dxd[a, j])
                             - darm3[c, AR_LIN, a, j] * (xc - xp) - arm3[c, AR_LIN, a] * (dxc - dxp))  # fmt: skip
        dfa[j] = acc
        dx[j] = dxc
    for a in range(na):
        xd[a] = xd_new[a]
        for j in range(ndir):
            dxd[a, j] = dxd_new[a, j]
    if f_sls > sc3[c, SC_SEP]:
        inv_kg = sc3[c, SC_INVKG]
        fa_sep = sc3[c, SC_FASEP]
        xs = fa_sep
        for a in range(na):
            xs += arm3[c, AR_K, a] * xd[a]
        for j in range(ndir):
            acc = dsc3[c, SC_FASEP, j]
            for a in range(na):
                acc += darm3[c, AR_K, a, j] * xd[a] + arm3[c, AR_K, a] * dxd[a, j]
            dx[j] = acc * inv_kg + xs * dsc3[c, SC_INVKG, j]
            dfa[j] = dsc3[c, SC_FA0, j]
        return -sc3[c, SC_FA0], xs * inv_kg, True
    return -f_sls - sc3[c, SC_FAC], xc, False
