"""Time loop of the Torsional Harmonic Cantilever tapping a massless viscoelastic surface.

Plain SI floats and arrays in and out (coefficients from :mod:`.coefficients`).

Probe (thesis eqs. 13-16, decoupled THC point-mass model)::

    m1 zc'' = -k1 zc - c1 zc' + F0 cos(w t) + Fts        flexural cantilever  [N]
    m2 zp'' = -k2 zp - c2 zp' + Fts                       torsional paddle+tip [N]
    z_tip   = Zb + zc + zp                                                     [m]

Surface (thesis 3.2): ``k_inf`` in parallel with N Maxwell
arms ``(k_i, cd_i)`` (one arm = the Zener SLS), van der Waals attraction
``Fa(d) = H R/(6 d^2)`` (thesis eq. 3) at gap ``d = z_tip - X``.  Contact when
``d <= a0``: ``X = z_tip - a0``, every arm relaxes towards ``X`` (exact
exponential), ``Fts = -(k_inf X + sum k_i (X - Xd_i)) - fa_c``.  Separation
when the surface would have to hold the tip with more than the adhesion.
Out of contact the arms creep, coupled through ``X = (sum k_i Xd_i + Fa)/Kg``
(``Fa`` only with the surface pull on), and ``Fts = -Fa``.

Two integrators share the physics:

* **fine** -- velocity Verlet at ``dt`` (thesis appendix B) with the damping
  implicit in the velocity half step; the surface updates once per step
  with the gap of the previous surface position.  Applied as a precomputed
  linear map so that the chain force -> next gap is one fused multiply-add.
  This is the whole integration when the far ladder is empty
  (``numerics.integrator: verlet``) and, in the hybrid, everywhere the tip is in
  contact or within ``d_switch`` of the surface;
* **far** (hybrid only) -- out of contact and farther than ``d_switch``, both
  oscillators are advanced by their *exact* linear flow over long steps
  ``H = n dt`` (the drive enters exactly through its particular solution),
  the van der Waals force acts as two half kicks ``H Fts/2`` (Strang
  splitting: second order in the slowly varying attraction, the linear part
  exact), and the arms creep by their exact exponential with the mean
  attraction of the step.  A step is accepted only if the gap stays above
  ``d_switch`` at its end and at the lowest point of the cubic Hermite
  interpolant of the tip position inside it; otherwise a shorter one is tried
  and, below the shortest, fine steps resume.  The amplitude measurement
  takes the extremum of that interpolant, so the top of the swing is not
  missed.

State vector ``S``: ``zc, vc, zp, vp, Zb, global step index, contact flag,
Xd_1..N`` with velocities synchronised with positions (the physical state).
Each call of :func:`advance` starts from it and writes it back.
"""

import math

import numpy as np
from numba import njit

from . import probe as PR
from .probe import (  # noqa: F401 - the layout is re-exported: tapping.S_ZC ... as before
    NO_BASE, NR, O_CSTEPS, O_D1, O_D2, O_DDASH, O_FAR, O_FINE, O_FMAX, O_FMIN, O_HC, O_HS, O_MAXCPP, O_NCONT,
    O_NSEP, O_QMAX, O_QMIN, O_REJECT, O_T_FC, O_TCONT_LAST, O_TSEP_LAST, O_WDRIVE, O_WTS, O_XM, O_Z_FC, O_ZCONT,
    O_ZCONT_LAST, O_ZSEP_LAST, R_ACTIVE, R_FC, R_LEFT, R_ORIGIN, R_POS, R_REP, R_RING, R_STRIDE, S_CONTACT,
    S_IDX, S_VC, S_VP, S_XD, S_ZB, S_ZC, S_ZP, far_extrema, hermite_extrema, project_harmonic,
)
from .sls import NEWTON_TOL, vdw_force  # noqa: F401 - NEWTON_TOL: re-exported
from .coefficients import (
    A_ALPHA, A_G, A_K, A_KER, A_LIN, A_OMER,
    L_C00, L_C01, L_C10, L_C11, L_COS, L_H, L_K1BI, L_K1BR, L_K1I, L_K1R, L_K2BI, L_K2BR, L_K2I, L_K2R,
    L_KPI, L_KPR, L_N, L_P00, L_P01, L_P10, L_P11, L_SIN,
    P_A0, P_BETA, P_BV1, P_BV2, P_C1, P_C2, P_COSDT, P_CVD0, P_CVD1, P_CVF, P_CVV, P_CVZ, P_CZD, P_CZF,
    P_CZV, P_CZZ, P_DSW, P_DSW_EXIT, P_DT, P_EF, P_F0, P_FA0, P_FAC, P_FASEP, P_HR6, P_IHR6, P_INVKG,
    P_K1, P_K2, P_KAPPA, P_KC, P_KINF, P_M1, P_M2, P_NT, P_OMEGA, P_PVF, P_PVV, P_PVZ, P_PZF, P_PZV,
    P_PZZ, P_RC0, P_RC1, P_RCV, P_RCZ, P_RHO, P_RPV, P_RPZ, P_SEPTHR, P_SINDT, P_VDW, P_ZI, P_ZR,
)  # fmt: skip

# ---- state vector, recorder and outputs: the probe's (one layout for every kernel, .probe)

# ---- recorded sample columns (then x_dashpot of arms 2..N)
COLUMNS = ("t", "z_tip", "z_cantilever", "z_paddle", "z_base", "f_ts", "x_surface", "x_dashpot")
C_T, C_ZTIP, C_ZC, C_ZP, C_ZB, C_F, C_X, C_XD = range(8)


# the van der Waals force and its Newton tolerance are the surface module's (one definition: .sls)


@njit(cache=True)
def surface_position(z_tip, xd, p, a, contact):
    """Surface position and attraction consistent with the tip at ``z_tip`` [m].

    In contact ``X = z_tip - a0`` and ``Fa = 0``.  Out of contact, with the
    surface pull on, ``X = (sum k_i Xd_i + Fa(z_tip - X))/Kg`` solved by
    fixed-point iteration (gain ``2 Fa/(d Kg)`` < 1 away from the instability).
    Returns ``(X, Fa)``.
    """
    if contact:
        return z_tip - p[P_A0], 0.0
    xs = 0.0
    for i in range(len(xd)):
        xs += a[A_K, i] * xd[i]
    x = xs * p[P_INVKG]
    d = z_tip - x
    fa = p[P_HR6] / (d * d)
    if p[P_VDW] > 0.0:
        for _ in range(4):
            x = (xs + fa) * p[P_INVKG]
            d = z_tip - x
            if d <= p[P_A0]:
                break
            fa = p[P_HR6] / (d * d)
    return x, fa


@njit(cache=True)
def contact_force(x, xd, p, a):
    """``F_sls = k_inf X + sum k_i (X - Xd_i)`` [N] (force the surface exerts)."""
    f = p[P_KINF] * x
    for i in range(len(xd)):
        f += a[A_K, i] * (x - xd[i])
    return f


@njit(cache=True)
def tip_force(s, p, a):
    """Tip-sample force ``Fts`` [N] and surface position at the state ``s``."""
    xd = s[S_XD:]
    z_tip = s[S_ZB] + s[S_ZC] + s[S_ZP]
    if s[S_CONTACT] > 0.5:
        x = z_tip - p[P_A0]
        return -contact_force(x, xd, p, a) - p[P_FAC], x
    x, fa = surface_position(z_tip, xd, p, a, False)
    return -fa, x


@njit(cache=True, inline="always")
def _store(buf, r, t, z_tip, zc, zp, zb, fts, x, xd):
    """Write one sample at the recorder's position (ring: modulo the buffer)."""
    n = buf.shape[0]
    i = r[R_POS] % n if r[R_RING] else r[R_POS]
    if i < n:
        buf[i, 0] = t
        buf[i, 1] = z_tip
        buf[i, 2] = zc
        buf[i, 3] = zp
        buf[i, 4] = zb
        buf[i, 5] = fts
        buf[i, 6] = x
        for j in range(len(xd)):
            buf[i, 7 + j] = xd[j]
    r[R_POS] += 1
    if r[R_RING]:
        if r[R_FC] and not r[R_REP] and fts > 0.0:
            r[R_REP] = 1
            r[R_LEFT] = n // 2
        if r[R_REP]:
            r[R_LEFT] -= 1
            if r[R_LEFT] <= 0:
                r[R_ACTIVE] = 0
    elif r[R_POS] >= n:
        r[R_ACTIVE] = 0


@njit(cache=True, inline="always")
def _free_dissipation(o, k_arm, kinf, x0, x1, xd0, xd1, work):
    """Dashpot dissipation over an out-of-contact step from the surface's energy balance
    (exact for the step's held attraction): the massless surface stays in equilibrium, so
    ``Fa dX = dU + sum cd Xd'^2`` with ``U = k_inf X^2/2 + sum k_i (X - Xd_i)^2/2``:
    ``D = work - dU`` (``work`` = the attraction's work on the surface, 0 without the pull).
    Split over the arms in proportion to their midpoint estimates."""
    n = len(k_arm)
    u0 = 0.5 * kinf * x0 * x0
    u1 = 0.5 * kinf * x1 * x1
    wsum = 0.0
    for i in range(n):
        u0 += 0.5 * k_arm[i] * (x0 - xd0[i]) ** 2
        u1 += 0.5 * k_arm[i] * (x1 - xd1[i]) ** 2
        wsum += k_arm[i] * (0.5 * (x0 + x1) - 0.5 * (xd0[i] + xd1[i])) * (xd1[i] - xd0[i])
    total = work - (u1 - u0)
    o[O_DDASH] += total
    for i in range(n):
        wi = k_arm[i] * (0.5 * (x0 + x1) - 0.5 * (xd0[i] + xd1[i])) * (xd1[i] - xd0[i])
        o[O_XM + n + i] += total * (wi / wsum if wsum != 0.0 else 1.0 / n)


@njit(cache=True, fastmath={"contract"}, error_model="numpy")
def fine_steps(s, n_end, zb_step, p, a, emi, buf, r, o, energy, far_ok):
    """Fine Verlet steps from the state ``s`` until step index ``n_end``, or until
    the tip is out of contact beyond the exit distance (when ``far_ok``, at a
    recording sample point).  Updates ``s``, the recorder and the outputs.  The probe's
    step, lock-in, energy and recorder bookkeeping are :mod:`.probe`'s."""
    n_arms = len(s) - S_XD
    dt = p[P_DT]
    c = PR.fine_map(p)
    ef = p[P_EF]
    hr6, ihr6, a0 = p[P_HR6], p[P_IHR6], p[P_A0]
    beta, kappa, kc = p[P_BETA], p[P_KAPPA], p[P_KC]
    fa0, sep_thr, fa_sep, fa_c = p[P_FA0], p[P_SEPTHR], p[P_FASEP], p[P_FAC]
    invkg = p[P_INVKG]
    kinf = p[P_KINF]
    d_exit = p[P_DSW_EXIT]
    vdw = p[P_VDW] > 0.0
    # dashpot positions as base + increments accumulated in this call: a slow dashpot moves by
    # ~1e-22 m per step, far below one ulp of its position, and rounding every update into the
    # position itself would bias its drift over a period (the orbit's mean-stretch residual)
    xd0 = s[S_XD:].copy()
    dxd = np.zeros(n_arms)
    xd = xd0.copy()
    xd_prev = xd.copy()
    k_arm = a[A_K].copy()
    alpha = a[A_ALPHA].copy()
    ker = a[A_KER].copy()
    omer = a[A_OMER].copy()
    lin = a[A_LIN].copy()
    g = a[A_G].copy()
    tmp = np.empty(n_arms)

    n, zc, vc, zp, vp, zb, contact, th = PR.load(s, p)
    cw, sw = math.cos(th), math.sin(th)
    z_tip = zb + zc + zp
    if contact:
        x = z_tip - a0
        fts = -contact_force(x, xd, p, a) - fa_c
        fa = fa0
    else:
        x, fa = surface_position(z_tip, xd, p, a, False)
        fts = -fa
    vcp, vpp, u1 = PR.fine_start(c, zc, vc, zp, vp, cw, fts)
    xbase = x + beta * fts
    x_last = x  # surface position after the previous step (the dashpot's linear target starts there)
    ztip_old, q_old, hc, hs, stride, to_grid, qmax, qmin, fmax, fmin = PR.fine_begin(o, r, n, z_tip, zb)
    steps = 0
    while n < n_end:
        fts_old, vcp_old, vpp_old, cw_old, sw_old = fts, vcp, vpp, cw, sw
        zc, vcp, zp, vpp, u1, base, zb, cw, sw = PR.fine_step(c, zc, vcp, zp, vpp, u1, cw, sw, zb, zb_step, fts)
        n += 1
        steps += 1
        if energy:
            for i in range(n_arms):
                xd_prev[i] = xd[i]
        free_step = False
        fa_old = fa
        if not contact:
            d = (base - xbase) + kappa * fts
            if d > a0:
                free_step = True
                # X_(n+1) = alpha . Xd_n + beta Fa_(n+1)  (force-free part before the update)
                xs = 0.0
                for i in range(n_arms):
                    xs += alpha[i] * xd[i]
                xbase = xs
                fa = vdw_force(d, fa, hr6, ihr6)
                for i in range(n_arms):
                    acc = g[i] * fa
                    for j in range(n_arms):
                        acc += emi[i, j] * xd[j]
                    tmp[i] = acc
                for i in range(n_arms):
                    dxd[i] += tmp[i]
                    xd[i] = xd0[i] + dxd[i]
                fts = -fa
            else:
                contact = True
                z_tip = base + ef * fts_old
                PR.first_contact(o, r, z_tip, n * dt)
        if contact:
            x = (base - a0) + ef * fts
            sk = 0.0
            for i in range(n_arms):
                sk += ker[i] * xd[i] + k_arm[i] * lin[i] * x_last
            f_sls = kc * x - sk
            for i in range(n_arms):
                dxd[i] += omer[i] * (x - xd[i]) - lin[i] * (x - x_last)
                xd[i] = xd0[i] + dxd[i]
            if f_sls > sep_thr:
                contact = False
                PR.separation(o, base + ef * fts_old, n * dt)  # tip position at the separation
                xs = 0.0
                for i in range(n_arms):
                    xs += k_arm[i] * xd[i]
                x = (xs + fa_sep) * invkg
                fts = -fa0
                fa = fa0
            else:
                fts = -f_sls - fa_c
            xbase = x + beta * fts
            o[O_CSTEPS] += 1.0
        z_tip = base + ef * fts_old
        q = z_tip - zb
        hc, hs = PR.lock_in(c, hc, hs, q_old, q, cw_old, cw, sw_old, sw)
        q_old = q
        qmax, qmin, fmax, fmin = PR.extrema(q, fts, qmax, qmin, fmax, fmin)
        if energy:
            x_now = xbase - beta * fts
            PR.fine_work(o, c, vcp_old, vpp_old, fts_old, vcp, vpp, fts, cw_old, cw, z_tip, ztip_old)
            ztip_old = z_tip
            if free_step:
                work = 0.5 * (fa_old + fa) * (x_now - x_last) if vdw else 0.0
                _free_dissipation(o, k_arm, kinf, x_last, x_now, xd_prev, xd, work)
            else:  # in contact: midpoint rule with the dashpot's linear target
                for i in range(n_arms):
                    dd = k_arm[i] * (0.5 * (x_now + x_last) - 0.5 * (xd[i] + xd_prev[i])) * (xd[i] - xd_prev[i])
                    o[O_DDASH] += dd
                    o[O_XM + n_arms + i] += dd
            for i in range(n_arms):
                o[O_XM + i] += (x_now - xd[i]) * dt
        x_last = xbase - beta * fts
        to_grid, on_grid = PR.grid_tick(to_grid, stride)
        if r[R_ACTIVE] and on_grid:
            _store(buf, r, n * dt, z_tip, zc, zp, zb, fts, xbase - beta * fts, xd)
        if far_ok and not contact and on_grid:
            if z_tip - (xbase - beta * fts) > d_exit:
                break
    PR.fine_save(s, o, c, zc, vcp, zp, vpp, zb, n, contact, fts, hc, hs, qmax, qmin, fmax, fmin, steps)
    for i in range(n_arms):
        s[S_XD + i] = xd0[i] + dxd[i]
    _ = kinf


@njit(cache=True, fastmath={"contract"}, error_model="numpy")
def fine_steps_one_arm(s, n_end, zb_step, p, a, emi, buf, r, o, energy, far_ok):
    """:func:`fine_steps` for one Maxwell arm (the SLS), on scalars: the same operations in
    the same order, so the same numbers bit for bit (tested), but the arm's dashpot lives
    in registers instead of length-1 arrays -- 28 % less time per fine step (measured on
    the worked example's steady orbit, all-fine Verlet: 7.35 against 10.3 ns, medians of
    7).  The SLS keeps this fast path because the general N-arm loop alone is slower."""
    dt = p[P_DT]
    c = PR.fine_map(p)
    ef = p[P_EF]
    hr6, ihr6, a0 = p[P_HR6], p[P_IHR6], p[P_A0]
    beta, kappa, kc = p[P_BETA], p[P_KAPPA], p[P_KC]
    fa0, sep_thr, fa_sep, fa_c = p[P_FA0], p[P_SEPTHR], p[P_FASEP], p[P_FAC]
    invkg = p[P_INVKG]
    kinf = p[P_KINF]
    d_exit = p[P_DSW_EXIT]
    vdw = p[P_VDW] > 0.0

    # dashpot positions as base + increments accumulated in this call: a slow dashpot moves by
    # ~1e-22 m per step, far below one ulp of its position, and rounding every update into the
    # position itself would bias its drift over a period (the orbit's mean-stretch residual)
    xd0 = s[S_XD]
    dxd = 0.0
    xd = xd0
    xd_prev = xd
    k_arm = a[A_K, 0]
    alpha = a[A_ALPHA, 0]
    ker = a[A_KER, 0]
    omer = a[A_OMER, 0]
    lin = a[A_LIN, 0]
    g = a[A_G, 0]
    e00 = emi[0, 0]
    karr = a[A_K]
    xdv = np.empty(1)
    xdpv = np.empty(1)

    n, zc, vc, zp, vp, zb, contact, th = PR.load(s, p)
    cw, sw = math.cos(th), math.sin(th)
    z_tip = zb + zc + zp
    xdv[0] = xd
    if contact:
        x = z_tip - a0
        fts = -contact_force(x, xdv, p, a) - fa_c
        fa = fa0
    else:
        x, fa = surface_position(z_tip, xdv, p, a, False)
        fts = -fa
    vcp, vpp, u1 = PR.fine_start(c, zc, vc, zp, vp, cw, fts)
    xbase = x + beta * fts
    x_last = x  # surface position after the previous step (the dashpot's linear target starts there)
    ztip_old, q_old, hc, hs, stride, to_grid, qmax, qmin, fmax, fmin = PR.fine_begin(o, r, n, z_tip, zb)
    steps = 0
    while n < n_end:
        fts_old, vcp_old, vpp_old, cw_old, sw_old = fts, vcp, vpp, cw, sw
        zc, vcp, zp, vpp, u1, base, zb, cw, sw = PR.fine_step(c, zc, vcp, zp, vpp, u1, cw, sw, zb, zb_step, fts)
        n += 1
        steps += 1
        xd_prev = xd
        free_step = False
        fa_old = fa
        if not contact:
            d = (base - xbase) + kappa * fts
            if d > a0:
                free_step = True
                # X_(n+1) = alpha . Xd_n + beta Fa_(n+1)  (force-free part before the update)
                xbase = alpha * xd
                fa = vdw_force(d, fa, hr6, ihr6)
                dxd += g * fa + e00 * xd
                xd = xd0 + dxd
                fts = -fa
            else:
                contact = True
                z_tip = base + ef * fts_old
                PR.first_contact(o, r, z_tip, n * dt)
        if contact:
            x = (base - a0) + ef * fts
            f_sls = kc * x - (ker * xd + k_arm * lin * x_last)
            dxd += omer * (x - xd) - lin * (x - x_last)
            xd = xd0 + dxd
            if f_sls > sep_thr:
                contact = False
                PR.separation(o, base + ef * fts_old, n * dt)  # tip position at the separation
                x = (k_arm * xd + fa_sep) * invkg
                fts = -fa0
                fa = fa0
            else:
                fts = -f_sls - fa_c
            xbase = x + beta * fts
            o[O_CSTEPS] += 1.0
        z_tip = base + ef * fts_old
        q = z_tip - zb
        hc, hs = PR.lock_in(c, hc, hs, q_old, q, cw_old, cw, sw_old, sw)
        q_old = q
        qmax, qmin, fmax, fmin = PR.extrema(q, fts, qmax, qmin, fmax, fmin)
        if energy:
            x_now = xbase - beta * fts
            PR.fine_work(o, c, vcp_old, vpp_old, fts_old, vcp, vpp, fts, cw_old, cw, z_tip, ztip_old)
            ztip_old = z_tip
            if free_step:
                work = 0.5 * (fa_old + fa) * (x_now - x_last) if vdw else 0.0
                xdv[0] = xd
                xdpv[0] = xd_prev
                _free_dissipation(o, karr, kinf, x_last, x_now, xdpv, xdv, work)
            else:  # in contact: midpoint rule with the dashpot's linear target
                dd = k_arm * (0.5 * (x_now + x_last) - 0.5 * (xd + xd_prev)) * (xd - xd_prev)
                o[O_DDASH] += dd
                o[O_XM + 1] += dd
            o[O_XM] += (x_now - xd) * dt
        x_last = xbase - beta * fts
        to_grid, on_grid = PR.grid_tick(to_grid, stride)
        if r[R_ACTIVE] and on_grid:
            xdv[0] = xd
            _store(buf, r, n * dt, z_tip, zc, zp, zb, fts, xbase - beta * fts, xdv)
        if far_ok and not contact and on_grid:
            if z_tip - (xbase - beta * fts) > d_exit:
                break
    PR.fine_save(s, o, c, zc, vcp, zp, vpp, zb, n, contact, fts, hc, hs, qmax, qmin, fmax, fmin, steps)
    s[S_XD] = xd0 + dxd
    _ = kinf


@njit(inline="always")
def end_attraction(z1, x1, fa1, xs, hr6, ihr6, invkg, vdw):
    """``(Fa, X)`` at a far step's end (:func:`far_steps`, :func:`.thermal.brownian_hybrid`): the
    attraction consistent with the surface it pulls, at most four fixed-point iterations from ``fa1``
    (``xs`` the arms' pull ``sum k_i Xd_i``; without the pull one evaluation is exact)."""
    for _ in range(4):
        d1 = z1 - x1
        if d1 <= 0.0:
            break
        fa_new = vdw_force(d1, fa1, hr6, ihr6)
        converged = abs(fa_new - fa1) <= 1e-12 * fa_new
        fa1 = fa_new
        if not vdw:
            break
        x1 = (xs + fa1) * invkg
        if converged:
            break
    return fa1, x1


EPS_STEP = 0.05  # far step <= EPS_STEP * gap / |tip speed|: the attraction changes < 5 % over a step


@njit(cache=True, fastmath={"contract"}, error_model="numpy")
def far_steps(s, n_end, zb_step, p, a, lad, lemi, lg, buf, r, o, energy, rec_mode):
    """Long exact steps from ``s`` while the gap stays above ``d_switch``.

    The step length is the longest ladder entry not above
    ``EPS_STEP * gap/|tip speed|`` (and not past ``n_end``); a step whose gap
    would fall below ``d_switch`` -- at its end or at the lowest point of the
    exact trajectory inside it -- is retried one ladder entry shorter.  Returns
    False when not even the shortest step can be taken (fine steps must
    resume).  In ``rec_mode`` (the one-entry recording ladder) it also stops
    when the recorder closes, and, with the surface pull on, the fixed point for the
    attraction at a step's end starts from the cubic extrapolation of the attraction over the
    last four steps instead of the attraction at the step's start, wherever the iteration
    from the start converges well within its four iterations (its first change times the
    gain cubed, ``|dFa| (2 Fa/(d Kg))^3``, below ``1e-14 Fa``): the same fixed point in 1.03
    instead of 3.03 iterations a step (the worked example's recorded window), so the chain
    of dependent operations a recorded sample waits on is shorter.  Without the pull
    the one Newton step keeps the start attraction as its guess (its result depends on it).
    """
    n_arms = len(s) - S_XD
    f = PR.far_constants(p)
    hr6, dsw, dt, invkg = p[P_HR6], p[P_DSW], p[P_DT], p[P_INVKG]
    ihr6 = p[P_IHR6]
    vdw = p[P_VDW] > 0.0
    k_arm = a[A_K]
    xd0 = s[S_XD:].copy()  # base + accumulated increments, as in fine_steps
    dxd = np.zeros(n_arms)
    xd = xd0.copy()
    xd_new = np.empty(n_arms)
    dxd_new = np.empty(n_arms)
    n, zc, vc, zp, vp, zb, _, th = PR.load(s, p)
    cw, sw = math.cos(th), math.sin(th)
    z_tip = zb + zc + zp
    x, fa = surface_position(z_tip, xd, p, a, False)
    fa_p1 = fa_p2 = fa_p3 = fa  # the attraction one, two and three steps back (recording: its extrapolation)
    n_hist = 0
    extrapolate = rec_mode and vdw
    stride = r[R_STRIDE]
    origin = r[R_ORIGIN]
    moved = True
    while n < n_end:
        # the longest step within the attraction's time scale and before n_end
        lev = PR.far_level(lad, EPS_STEP, vc, vp, z_tip - x, n, n_end)
        if lev < 0:
            break
        accepted = False
        while lev >= 0:
            h = lad[lev, L_H]
            hh = 0.5 * h
            # half kick, exact flow (drive through its particular solution), creep, half kick
            vc1, vp1, zpart0, vpart0, cw1, sw1, zc1, vc2, zp1, vp2, zb1, z1 = PR.far_flow(
                f, lad, lev, hh, fa, zc, vc, zp, vp, zb, zb_step, cw, sw)
            # creep predictor with the start attraction, then the consistent end attraction
            xs = 0.0
            for i in range(n_arms):
                acc = lg[lev, i] * fa
                for j in range(n_arms):
                    acc += lemi[lev, i, j] * xd[j]
                xd_new[i] = xd[i] + acc
                xs += k_arm[i] * xd_new[i]
            fa1 = fa
            if extrapolate and n_hist >= 3:
                dfa = fa - fa_p1
                gd = 2.0 * fa * invkg  # the fixed point's gain times the gap
                gap = z_tip - x
                if abs(dfa) * (gd * gd * gd) <= 1e-14 * fa * (gap * gap * gap):
                    fa1 = fa + (3.0 * (dfa - (fa_p1 - fa_p2)) + (fa_p2 - fa_p3))  # cubic through the last four
            x1 = (xs + (fa1 if vdw else 0.0)) * invkg
            # the attraction at the end, consistent with the surface it pulls (fixed point; the
            # gain 2 Fa/(d Kg) is small this far out; without the pull one evaluation is exact)
            fa1, x1 = end_attraction(z1, x1, fa1, xs, hr6, ihr6, invkg, vdw)
            d1 = z1 - x1
            vc3, vp3 = PR.far_close(f, hh, fa1, vc2, vp2)
            # extrema of q = zc + zp inside the step where they could matter
            ok, qmn, qmx = PR.far_accept(o, f, p, rec_mode, h, dsw, zc, zc1, zp, vc1, vp1, vc2, vp2, cw, sw, z_tip, zb,
                                         z1, zb1, x, x1, d1)  # fmt: skip
            if ok:
                accepted = True
                break
            o[O_REJECT] += 1.0
            lev -= 1
        if not accepted:
            moved = False
            break
        # accepted: first harmonic of q over the step
        PR.far_harmonic(o, f, rec_mode, lad, lev, hh, h, z_tip, zb, z1, zb1, zc, zpart0, vc1, vpart0, zp, vp1, cw, sw,
                        cw1, sw1)  # fmt: skip
        # exact creep with the mean attraction of the step
        fm = 0.5 * (fa + fa1)
        xs = 0.0
        for i in range(n_arms):
            acc = lg[lev, i] * fm
            for j in range(n_arms):
                acc += lemi[lev, i, j] * xd[j]
            dxd_new[i] = dxd[i] + acc
            xd_new[i] = xd0[i] + dxd_new[i]
            xs += k_arm[i] * xd_new[i]
        x1 = (xs + (fa1 if vdw else 0.0)) * invkg
        PR.far_bounds(o, qmn, qmx, fa1)
        if energy:
            PR.far_work(o, f, hh, fa, fa1, hr6, z_tip, x, z1, x1, cw, cw1, vc, vp, vc3, vp3)
            _free_dissipation(o, k_arm, p[P_KINF], x, x1, xd, xd_new, fm * (x1 - x) if vdw else 0.0)
            for i in range(n_arms):
                o[O_XM + i] += 0.5 * ((x - xd[i]) + (x1 - xd_new[i])) * h
        zc, vc, zp, vp, zb = zc1, vc3, zp1, vp3, zb1
        fa_p3, fa_p2, fa_p1 = fa_p2, fa_p1, fa
        n_hist += 1
        z_tip, x, fa = z1, x1, fa1
        cw, sw = cw1, sw1
        for i in range(n_arms):
            xd[i] = xd_new[i]
            dxd[i] = dxd_new[i]
        n += int(lad[lev, L_N])
        o[O_FAR] += 1.0
        if r[R_ACTIVE] and (n - origin) % stride == 0:
            _store(buf, r, n * dt, z_tip, zc, zp, zb, -fa, x, xd)
            if rec_mode and not r[R_ACTIVE]:
                break
    PR.far_save(s, zc, vc, zp, vp, zb, n)
    for i in range(n_arms):
        s[S_XD + i] = xd0[i] + dxd[i]
    return moved


@njit(cache=True)
def advance(s, n_steps, zb_step, p, a, emi, lad, lemi, lg, lad_rec, lemi_rec, lg_rec, buf, r, energy, o):
    """Advance the state ``s`` by ``n_steps`` fine steps (any mix of fine and far steps).

    ``zb_step`` [m]: base change per fine step (controller ramp or approach);
    ``lad, lemi, lg``: the far-step ladder (empty = all-fine Verlet);
    ``lad_rec, ...``: the far step used while recording (one print step);
    ``buf, r``: recorder (see ``R_*``); ``energy``: accumulate the energy
    integrals and the mean arm stretch ``<X - Xd_i>`` (``O_XM``); ``o``: outputs
    (reset by the caller), accumulated over the call.
    """
    n_end = int(s[S_IDX]) + n_steps
    hybrid = lad.shape[0] > 0
    while int(s[S_IDX]) < n_end:
        recording = r[R_ACTIVE] == 1
        use_far = hybrid and s[S_CONTACT] < 0.5
        if use_far and recording:
            use_far = lad_rec.shape[0] > 0 and (int(s[S_IDX]) - r[R_ORIGIN]) % r[R_STRIDE] == 0
        if use_far:
            z_tip = s[S_ZB] + s[S_ZC] + s[S_ZP]
            x, _fa = surface_position(z_tip, s[S_XD:], p, a, False)
            use_far = z_tip - x > p[P_DSW]
        if use_far:
            if recording:
                moved = far_steps(s, n_end, zb_step, p, a, lad_rec, lemi_rec, lg_rec, buf, r, o, energy, True)
            else:
                moved = far_steps(s, n_end, zb_step, p, a, lad, lemi, lg, buf, r, o, energy, False)
            if int(s[S_IDX]) >= n_end:
                break
            if moved and recording and r[R_ACTIVE] == 0:
                continue  # the recorder closed inside: re-plan on the free ladder
        far_ok = hybrid and (lad_rec.shape[0] > 0 or r[R_ACTIVE] == 0)
        if len(s) == S_XD + 1:
            fine_steps_one_arm(s, n_end, zb_step, p, a, emi, buf, r, o, energy, far_ok)
        else:
            fine_steps(s, n_end, zb_step, p, a, emi, buf, r, o, energy, far_ok)


def new_outputs(n_arms: int) -> np.ndarray:
    """A fresh output vector (extrema at +-inf, first-contact entries nan)."""
    o = np.zeros(NO_BASE + 2 * n_arms)
    o[O_QMAX], o[O_QMIN] = -np.inf, np.inf
    o[O_FMAX], o[O_FMIN] = -np.inf, np.inf
    o[O_ZCONT] = o[O_T_FC] = o[O_Z_FC] = o[O_ZCONT_LAST] = o[O_ZSEP_LAST] = np.nan
    o[O_TCONT_LAST] = o[O_TSEP_LAST] = np.nan
    return o


def new_recorder(stride: int = 1, origin: int = 0, ring: bool = False, active: bool = False) -> np.ndarray:
    r = np.zeros(NR, dtype=np.int64)
    r[R_STRIDE] = stride
    r[R_ORIGIN] = origin
    r[R_RING] = int(ring)
    r[R_ACTIVE] = int(active)
    r[R_LEFT] = -1
    return r


# public names of the helpers the MDR surface kernel (core.mdr) shares with this one (the probe's are .probe's)
store_sample = _store
