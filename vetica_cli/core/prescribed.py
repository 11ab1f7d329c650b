"""Massless Zener SLS surface driven by a prescribed (measured) tip trajectory.

The inverse problem of ``vetica extract --method full`` (issue 6): the tip
positions ``z_tip`` of a record are given, the surface of SPEC section 3
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

from .sls import contact_update, noncontact_update, released_position, sls_coefficients

DIRECTIONS = ("xd0", "s0", "ln_k_inf", "ln_k0", "ln_cd", "ln_hr6")
NDIR = len(DIRECTIONS)

# rows of the coefficient table of coefficient_tangents()
C_EC, C_ER, C_ALPHA, C_BETA, C_GAMMA, C_KC, C_K0ER, C_FA0, C_SEP, C_FASEP, C_FAC, C_INVKG, C_K0 = range(13)
NCOEF = 13


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
        dc[C_KC, j] = dkg - dk0 * one_m_er + k0 * der
        dc[C_K0ER, j] = dk0 * er + k0 * der
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


@njit(cache=True, inline="always", fastmath={"contract"}, error_model="numpy")
def _noncontact(d, xd, fa, hr6, ihr6, c, dc, ndir, dxd, dx, dfa, ds0, dlnhr6):
    """One non-contact update (:func:`.sls.noncontact_update`) at gap ``d`` with the
    coefficients ``c`` of its step, and its tangent: ``dfa``, ``dx``, ``dxd`` updated
    in place (``dx`` enters as the derivative of the previous surface position)."""
    alpha, beta, gamma, ec = c[C_ALPHA], c[C_BETA], c[C_GAMMA], c[C_EC]
    fa, x, xd_new = noncontact_update(d, xd, fa, hr6, ihr6, alpha, beta, gamma, ec)
    for j in range(ndir):
        dfa[j] = fa * dlnhr6[j] + 2.0 * fa / d * (ds0[j] + dx[j])  # d = z - s0 - X_prev
        dx[j] = dc[C_ALPHA, j] * xd + alpha * dxd[j] + dc[C_BETA, j] * fa + beta * dfa[j]
        dxd[j] = dc[C_GAMMA, j] * fa + gamma * dfa[j] + dc[C_EC, j] * xd + ec * dxd[j]
    return fa, x, xd_new


@njit(cache=True, inline="always", fastmath={"contract"}, error_model="numpy")
def _contact(xc, xd, c, dc, ndir, dxd, dx, dfa, ds0):
    """One contact update (:func:`.sls.contact_update`) with the surface at ``xc``
    and its tangent; ``dfa`` receives ``d(F_sls + fa_c)``.  On separation
    (``F_sls > sep_thr``) the surface is released (:func:`.sls.released_position`)
    and ``dfa`` becomes ``d Fa(a0)``.  Returns ``(fts, f_sls, x, xd, separated)``."""
    kc, k0er, er = c[C_KC], c[C_K0ER], c[C_ER]
    f_sls, xd_new = contact_update(xc, xd, kc, k0er, er)
    for j in range(ndir):
        dfa[j] = dc[C_KC, j] * xc - kc * ds0[j] - dc[C_K0ER, j] * xd - k0er * dxd[j] + dc[C_FAC, j]
        dxd[j] = -dc[C_ER, j] * xc - (1.0 - er) * ds0[j] + dc[C_ER, j] * xd + er * dxd[j]
        dx[j] = -ds0[j]
    if f_sls > c[C_SEP]:
        k0, fa_sep, inv_kg = c[C_K0], c[C_FASEP], c[C_INVKG]
        x = released_position(xd_new, fa_sep, k0, inv_kg)
        for j in range(ndir):
            dx[j] = (dc[C_K0, j] * xd_new + k0 * dxd[j] + dc[C_FASEP, j]) * inv_kg + (k0 * xd_new + fa_sep) * dc[
                C_INVKG, j
            ]
            dfa[j] = dc[C_FA0, j]
        return -c[C_FA0], f_sls, x, xd_new, True
    return -f_sls - c[C_FAC], f_sls, xc, xd_new, False


@njit(cache=True, fastmath={"contract"}, error_model="numpy")
def surface_force(
    z, s0, k_inf, k0, cd, hr6, a0, vdw_on_surface, h,
    block, coarse_ok, want, far_gap, substeps, sub_gap,
    xd0, contact0, ndir, out_f, out_jac,
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
    ``DIRECTIONS`` to differentiate along (0 = value only).

    Writes ``out_f[k]`` = Fts [N] at the k-th wanted sample and
    ``out_jac[k, j]`` = dFts/d(direction j), j < ndir.  Returns ``(xd, x,
    contact, dxd, n_written, contacts, separations, coarse_steps)``: the state
    after the last sample (dashpot and surface positions [m], contact flag),
    ``dxd`` (NDIR,) the derivatives of that dashpot position, and counts.
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
            for j in range(ndir):
                if abs(dxd[j]) < 1e-250:
                    dxd[j] = 0.0
                if abs(dx[j]) < 1e-250:
                    dx[j] = 0.0
        # ---- one exact step over a whole far block
        if (not contact) and i % block == 0 and b < nblock and coarse_ok[b]:
            i_end = i + block - 1
            d = z[i_end] - s0 - x
            if z[i] - s0 - x > far_gap and d > far_gap:
                fa, x, xd = _noncontact(d, xd, fa, hr6, ihr6, cb, dcb, ndir, dxd, dx, dfa, ds0, dlnhr6)
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
                sub = cf[C_KC] * (zz - a0) - cf[C_K0ER] * xd > cf[C_SEP]
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
                        fa, x, xd = _noncontact(d, xd, fa, hr6, ihr6, cs, dcs, ndir, dxd, dx, dfa, ds0, dlnhr6)
                        fts = -fa
                        continue
                    contact = True
                    contacts += 1
                fts, _, x, xd, sep = _contact(zm - a0, xd, cs, dcs, ndir, dxd, dx, dfa, ds0)
                if sep:
                    contact = False
                    separations += 1
                    fa = cs[C_FA0]
        elif not contact and zz - x > a0:
            fa, x, xd = _noncontact(zz - x, xd, fa, hr6, ihr6, cf, dcf, ndir, dxd, dx, dfa, ds0, dlnhr6)
            fts = -fa
        else:
            if not contact:
                contact = True
                contacts += 1
            fts, _, x, xd, sep = _contact(zz - a0, xd, cf, dcf, ndir, dxd, dx, dfa, ds0)
            if sep:
                contact = False
                separations += 1
                fa = cf[C_FA0]
        if want[i]:
            out_f[k] = fts
            for j in range(ndir):
                out_jac[k, j] = -dfa[j]
            k += 1
        i += 1
    return xd, x, contact, dxd, k, contacts, separations, coarse_steps
