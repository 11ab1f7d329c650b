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

# ---- state vector
S_ZC, S_VC, S_ZP, S_VP, S_ZB, S_IDX, S_CONTACT, S_XD = range(8)

# ---- recorded sample columns (then x_dashpot of arms 2..N)
COLUMNS = ("t", "z_tip", "z_cantilever", "z_paddle", "z_base", "f_ts", "x_surface", "x_dashpot")
C_T, C_ZTIP, C_ZC, C_ZP, C_ZB, C_F, C_X, C_XD = range(8)

# ---- recorder control (int64 vector R)
R_POS, R_RING, R_LEFT, R_FC, R_ACTIVE, R_STRIDE, R_ORIGIN, R_REP = range(8)
NR = 8

# ---- outputs of one call (float vector O; then, per arm, the mean stretch integral
# int (X - Xd_i) dt [m s] (O_XM + i) and the dashpot dissipation [J] (O_XM + N + i))
(
    O_QMAX, O_QMIN, O_ZCONT, O_NCONT, O_NSEP, O_CSTEPS, O_FMAX, O_FMIN,
    O_WDRIVE, O_D1, O_D2, O_WTS, O_DDASH, O_FINE, O_FAR, O_REJECT,
    O_T_FC, O_Z_FC, O_ZCONT_LAST, O_MAXCPP, O_HC, O_HS, O_ZSEP_LAST, O_TCONT_LAST, O_TSEP_LAST, O_XM,
) = range(26)  # fmt: skip
NO_BASE = O_XM

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
    recording sample point).  Updates ``s``, the recorder and the outputs."""
    n_arms = len(s) - S_XD
    hdt = 0.5 * p[P_DT]
    dt = p[P_DT]
    czz, czv, czf, czd = p[P_CZZ], p[P_CZV], p[P_CZF], p[P_CZD]
    cvz, cvv, cvf, cvd0, cvd1 = p[P_CVZ], p[P_CVV], p[P_CVF], p[P_CVD0], p[P_CVD1]
    pzz, pzv, pzf = p[P_PZZ], p[P_PZV], p[P_PZF]
    pvz, pvv, pvf = p[P_PVZ], p[P_PVV], p[P_PVF]
    ef, rcz, rcv, rc0, rc1 = p[P_EF], p[P_RCZ], p[P_RCV], p[P_RC0], p[P_RC1]
    rpz, rpv, rho = p[P_RPZ], p[P_RPV], p[P_RHO]
    bv1, bv2 = p[P_BV1], p[P_BV2]
    cr, sr = p[P_COSDT], p[P_SINDT]
    hr6, ihr6, a0 = p[P_HR6], p[P_IHR6], p[P_A0]
    beta, kappa, kc = p[P_BETA], p[P_KAPPA], p[P_KC]
    fa0, sep_thr, fa_sep, fa_c = p[P_FA0], p[P_SEPTHR], p[P_FASEP], p[P_FAC]
    invkg = p[P_INVKG]
    f0, c1, c2 = p[P_F0], p[P_C1], p[P_C2]
    kinf = p[P_KINF]
    d_exit = p[P_DSW_EXIT]
    nt = int(p[P_NT])
    omega = p[P_OMEGA]
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

    n = int(s[S_IDX])
    zc, vc, zp, vp, zb = s[S_ZC], s[S_VC], s[S_ZP], s[S_VP], s[S_ZB]
    contact = s[S_CONTACT] > 0.5
    th = omega * (n % nt) * dt
    cw, sw = math.cos(th), math.sin(th)
    z_tip = zb + zc + zp
    if contact:
        x = z_tip - a0
        fts = -contact_force(x, xd, p, a) - fa_c
        fa = fa0
    else:
        x, fa = surface_position(z_tip, xd, p, a, False)
        fts = -fa
    vcp = vc - bv1 * fts
    vpp = vp - bv2 * fts
    u1 = (czz * zc + czv * vcp + czd * cw) + (pzz * zp + pzv * vpp)
    xbase = x + beta * fts
    x_last = x  # surface position after the previous step (the dashpot's linear target starts there)
    ztip_old = z_tip
    q_old = z_tip - zb
    hc, hs = o[O_HC], o[O_HS]
    stride = r[R_STRIDE]
    origin = r[R_ORIGIN]
    to_grid = stride - (n - origin) % stride  # steps to the next recording-grid point (1..stride)
    qmax, qmin = o[O_QMAX], o[O_QMIN]
    fmax, fmin = o[O_FMAX], o[O_FMIN]
    steps = 0
    while n < n_end:
        fts_old = fts
        vcp_old = vcp
        vpp_old = vpp
        cw_old = cw
        sw_old = sw
        cw, sw = cw * cr - sw * sr, sw * cr + cw * sr
        zb += zb_step
        u2 = ((rcz * zc + rcv * vcp) + (rpz * zp + rpv * vpp)) + (rc0 * cw_old + rc1 * cw) + rho * fts
        zc, vcp = (
            (czz * zc + czv * vcp) + (czd * cw_old + czf * fts),
            (cvz * zc + cvv * vcp) + ((cvd0 * cw_old + cvd1 * cw) + cvf * fts),
        )
        zp, vpp = (pzz * zp + pzv * vpp) + pzf * fts, (pvz * zp + pvv * vpp) + pvf * fts
        base = zb + u1
        u1 = u2
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
                o[O_NCONT] += 1.0
                o[O_ZCONT_LAST] = z_tip
                o[O_TCONT_LAST] = n * dt
                if math.isnan(o[O_ZCONT]):
                    o[O_ZCONT] = z_tip
                if r[R_FC] == 0:
                    r[R_FC] = 1
                    o[O_T_FC] = n * dt
                    o[O_Z_FC] = z_tip
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
                o[O_ZSEP_LAST] = base + ef * fts_old  # tip position at the separation
                o[O_TSEP_LAST] = n * dt
                xs = 0.0
                for i in range(n_arms):
                    xs += k_arm[i] * xd[i]
                x = (xs + fa_sep) * invkg
                fts = -fa0
                fa = fa0
                o[O_NSEP] += 1.0
            else:
                fts = -f_sls - fa_c
            xbase = x + beta * fts
            o[O_CSTEPS] += 1.0
        z_tip = base + ef * fts_old
        q = z_tip - zb
        # first harmonic of q (lock-in): trapezoid of q exp(-i w t)
        hc += hdt * (q_old * cw_old + q * cw)
        hs -= hdt * (q_old * sw_old + q * sw)
        q_old = q
        if q > qmax:
            qmax = q
        if q < qmin:
            qmin = q
        if fts > fmax:
            fmax = fts
        if fts < fmin:
            fmin = fts
        if energy:
            x_now = xbase - beta * fts
            vc_old = vcp_old + bv1 * fts_old
            vp_old = vpp_old + bv2 * fts_old
            vc_new = vcp + bv1 * fts
            vp_new = vpp + bv2 * fts
            o[O_WDRIVE] += hdt * f0 * (cw_old * vc_old + cw * vc_new)
            o[O_D1] += hdt * c1 * (vc_old * vc_old + vc_new * vc_new)
            o[O_D2] += hdt * c2 * (vp_old * vp_old + vp_new * vp_new)
            o[O_WTS] -= 0.5 * (fts_old + fts) * (z_tip - ztip_old)
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
        to_grid -= 1
        on_grid = to_grid <= 0
        if on_grid:
            to_grid = stride
        if r[R_ACTIVE] and on_grid:
            _store(buf, r, n * dt, z_tip, zc, zp, zb, fts, xbase - beta * fts, xd)
        if far_ok and not contact and on_grid:
            if z_tip - (xbase - beta * fts) > d_exit:
                break
    o[O_QMAX], o[O_QMIN], o[O_FMAX], o[O_FMIN] = qmax, qmin, fmax, fmin
    o[O_HC], o[O_HS] = hc, hs
    o[O_FINE] += steps
    s[S_ZC] = zc
    s[S_VC] = vcp + bv1 * fts
    s[S_ZP] = zp
    s[S_VP] = vpp + bv2 * fts
    s[S_ZB] = zb
    s[S_IDX] = n
    s[S_CONTACT] = 1.0 if contact else 0.0
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
    hdt = 0.5 * p[P_DT]
    dt = p[P_DT]
    czz, czv, czf, czd = p[P_CZZ], p[P_CZV], p[P_CZF], p[P_CZD]
    cvz, cvv, cvf, cvd0, cvd1 = p[P_CVZ], p[P_CVV], p[P_CVF], p[P_CVD0], p[P_CVD1]
    pzz, pzv, pzf = p[P_PZZ], p[P_PZV], p[P_PZF]
    pvz, pvv, pvf = p[P_PVZ], p[P_PVV], p[P_PVF]
    ef, rcz, rcv, rc0, rc1 = p[P_EF], p[P_RCZ], p[P_RCV], p[P_RC0], p[P_RC1]
    rpz, rpv, rho = p[P_RPZ], p[P_RPV], p[P_RHO]
    bv1, bv2 = p[P_BV1], p[P_BV2]
    cr, sr = p[P_COSDT], p[P_SINDT]
    hr6, ihr6, a0 = p[P_HR6], p[P_IHR6], p[P_A0]
    beta, kappa, kc = p[P_BETA], p[P_KAPPA], p[P_KC]
    fa0, sep_thr, fa_sep, fa_c = p[P_FA0], p[P_SEPTHR], p[P_FASEP], p[P_FAC]
    invkg = p[P_INVKG]
    f0, c1, c2 = p[P_F0], p[P_C1], p[P_C2]
    kinf = p[P_KINF]
    d_exit = p[P_DSW_EXIT]
    nt = int(p[P_NT])
    omega = p[P_OMEGA]
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

    n = int(s[S_IDX])
    zc, vc, zp, vp, zb = s[S_ZC], s[S_VC], s[S_ZP], s[S_VP], s[S_ZB]
    contact = s[S_CONTACT] > 0.5
    th = omega * (n % nt) * dt
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
    vcp = vc - bv1 * fts
    vpp = vp - bv2 * fts
    u1 = (czz * zc + czv * vcp + czd * cw) + (pzz * zp + pzv * vpp)
    xbase = x + beta * fts
    x_last = x  # surface position after the previous step (the dashpot's linear target starts there)
    ztip_old = z_tip
    q_old = z_tip - zb
    hc, hs = o[O_HC], o[O_HS]
    stride = r[R_STRIDE]
    origin = r[R_ORIGIN]
    to_grid = stride - (n - origin) % stride  # steps to the next recording-grid point (1..stride)
    qmax, qmin = o[O_QMAX], o[O_QMIN]
    fmax, fmin = o[O_FMAX], o[O_FMIN]
    steps = 0
    while n < n_end:
        fts_old = fts
        vcp_old = vcp
        vpp_old = vpp
        cw_old = cw
        sw_old = sw
        cw, sw = cw * cr - sw * sr, sw * cr + cw * sr
        zb += zb_step
        u2 = ((rcz * zc + rcv * vcp) + (rpz * zp + rpv * vpp)) + (rc0 * cw_old + rc1 * cw) + rho * fts
        zc, vcp = (
            (czz * zc + czv * vcp) + (czd * cw_old + czf * fts),
            (cvz * zc + cvv * vcp) + ((cvd0 * cw_old + cvd1 * cw) + cvf * fts),
        )
        zp, vpp = (pzz * zp + pzv * vpp) + pzf * fts, (pvz * zp + pvv * vpp) + pvf * fts
        base = zb + u1
        u1 = u2
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
                o[O_NCONT] += 1.0
                o[O_ZCONT_LAST] = z_tip
                o[O_TCONT_LAST] = n * dt
                if math.isnan(o[O_ZCONT]):
                    o[O_ZCONT] = z_tip
                if r[R_FC] == 0:
                    r[R_FC] = 1
                    o[O_T_FC] = n * dt
                    o[O_Z_FC] = z_tip
        if contact:
            x = (base - a0) + ef * fts
            f_sls = kc * x - (ker * xd + k_arm * lin * x_last)
            dxd += omer * (x - xd) - lin * (x - x_last)
            xd = xd0 + dxd
            if f_sls > sep_thr:
                contact = False
                o[O_ZSEP_LAST] = base + ef * fts_old  # tip position at the separation
                o[O_TSEP_LAST] = n * dt
                x = (k_arm * xd + fa_sep) * invkg
                fts = -fa0
                fa = fa0
                o[O_NSEP] += 1.0
            else:
                fts = -f_sls - fa_c
            xbase = x + beta * fts
            o[O_CSTEPS] += 1.0
        z_tip = base + ef * fts_old
        q = z_tip - zb
        # first harmonic of q (lock-in): trapezoid of q exp(-i w t)
        hc += hdt * (q_old * cw_old + q * cw)
        hs -= hdt * (q_old * sw_old + q * sw)
        q_old = q
        if q > qmax:
            qmax = q
        if q < qmin:
            qmin = q
        if fts > fmax:
            fmax = fts
        if fts < fmin:
            fmin = fts
        if energy:
            x_now = xbase - beta * fts
            vc_old = vcp_old + bv1 * fts_old
            vp_old = vpp_old + bv2 * fts_old
            vc_new = vcp + bv1 * fts
            vp_new = vpp + bv2 * fts
            o[O_WDRIVE] += hdt * f0 * (cw_old * vc_old + cw * vc_new)
            o[O_D1] += hdt * c1 * (vc_old * vc_old + vc_new * vc_new)
            o[O_D2] += hdt * c2 * (vp_old * vp_old + vp_new * vp_new)
            o[O_WTS] -= 0.5 * (fts_old + fts) * (z_tip - ztip_old)
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
        to_grid -= 1
        on_grid = to_grid <= 0
        if on_grid:
            to_grid = stride
        if r[R_ACTIVE] and on_grid:
            xdv[0] = xd
            _store(buf, r, n * dt, z_tip, zc, zp, zb, fts, xbase - beta * fts, xdv)
        if far_ok and not contact and on_grid:
            if z_tip - (xbase - beta * fts) > d_exit:
                break
    o[O_QMAX], o[O_QMIN], o[O_FMAX], o[O_FMIN] = qmax, qmin, fmax, fmin
    o[O_HC], o[O_HS] = hc, hs
    o[O_FINE] += steps
    s[S_ZC] = zc
    s[S_VC] = vcp + bv1 * fts
    s[S_ZP] = zp
    s[S_VP] = vpp + bv2 * fts
    s[S_ZB] = zb
    s[S_IDX] = n
    s[S_CONTACT] = 1.0 if contact else 0.0
    s[S_XD] = xd0 + dxd
    _ = kinf


@njit(cache=True, inline="always")
def _osc(z0, v0, lam, wd, w02, s):
    """Exact free damped oscillator ``z'' = -w0^2 z + 2 lam z'`` from ``(z0, v0)``:
    ``(z, v, a)`` after ``s`` [s] (``lam = -c/2m``, ``wd`` the damped frequency)."""
    e = math.exp(lam * s)
    c = math.cos(wd * s)
    sn = math.sin(wd * s)
    b = (v0 - lam * z0) / wd
    z = e * (z0 * c + b * sn)
    v = e * (v0 * c + (lam * b - wd * z0) * sn)
    return z, v, -w02 * z + 2.0 * lam * v


@njit(cache=True)
def _q_at(s, zc0, vc0, zp0, vp0, cw, sw, p):
    """``q = zc + zp`` (tip deflection), its velocity and acceleration a time ``s``
    into a far step that starts (after its opening half kick) from
    ``(zc0, vc0, zp0, vp0)`` at drive phase ``(cos, sin) = (cw, sw)``."""
    omega, zr, zi = p[P_OMEGA], p[P_ZR], p[P_ZI]
    lam1 = -0.5 * p[P_C1] / p[P_M1]
    w01 = p[P_K1] / p[P_M1]
    lam2 = -0.5 * p[P_C2] / p[P_M2]
    w02 = p[P_K2] / p[P_M2]
    wd1 = math.sqrt(w01 - lam1 * lam1)
    wd2 = math.sqrt(w02 - lam2 * lam2)
    zpart0 = zr * cw - zi * sw
    vpart0 = -omega * (zr * sw + zi * cw)
    c = math.cos(omega * s)
    sn = math.sin(omega * s)
    cw1 = cw * c - sw * sn
    sw1 = sw * c + cw * sn
    zpart = zr * cw1 - zi * sw1
    vpart = -omega * (zr * sw1 + zi * cw1)
    hz, hv, ha = _osc(zc0 - zpart0, vc0 - vpart0, lam1, wd1, w01, s)
    pz, pv, pa = _osc(zp0, vp0, lam2, wd2, w02, s)
    return hz + zpart + pz, hv + vpart + pv, ha - omega * omega * zpart + pa


@njit(cache=True, inline="always")
def _hermite_extrema(q0, v0, q1, v1, h):
    """Smallest and largest value of the cubic Hermite interpolant of ``q`` on ``[0, h]``
    (end values and slopes): accurate to ``h^4 q^(4)/384``, for steps far shorter
    than the paddle period."""
    qmin, qmax = min(q0, q1), max(q0, q1)
    c2 = (3.0 * (q1 - q0) / h - 2.0 * v0 - v1) / h
    c3 = (v0 + v1 - 2.0 * (q1 - q0) / h) / (h * h)
    aa, bb, cc = 3.0 * c3, 2.0 * c2, v0
    disc = bb * bb - 4.0 * aa * cc
    if aa == 0.0 or disc < 0.0:
        return qmin, qmax
    sq = math.sqrt(disc)
    for r in ((-bb - sq) / (2.0 * aa), (-bb + sq) / (2.0 * aa)):
        if 0.0 < r < h:
            q = q0 + r * (v0 + r * (c2 + r * c3))
            qmin = min(qmin, q)
            qmax = max(qmax, q)
    return qmin, qmax


@njit(cache=True)
def _extrema(h, zc0, vc0, zp0, vp0, cw, sw, p, q0, q1):
    """Smallest and largest ``q`` over a far step of length ``h`` [s].

    The exact solution is sampled every ~0.5/w2 (so that the paddle's ringing
    cannot hide an extremum between samples); in every interval where the
    velocity changes sign, the extremum is polished by safeguarded Newton on
    ``q' = 0``.  ``q0, q1``: ``q`` at the ends.
    """
    w2 = math.sqrt(p[P_K2] / p[P_M2])
    m = max(2, int(math.ceil(h * w2 / 0.5)))
    qmin, qmax = min(q0, q1), max(q0, q1)
    s_prev = 0.0
    _, v_prev, _ = _q_at(0.0, zc0, vc0, zp0, vp0, cw, sw, p)
    for j in range(1, m + 1):
        s_j = h * j / m
        q_j, v_j, _ = _q_at(s_j, zc0, vc0, zp0, vp0, cw, sw, p)
        if j < m:
            qmin = min(qmin, q_j)
            qmax = max(qmax, q_j)
        if v_prev * v_j < 0.0:
            lo, hi = s_prev, s_j
            v_lo = v_prev
            s = 0.5 * (lo + hi)
            for _ in range(30):
                q, v, acc = _q_at(s, zc0, vc0, zp0, vp0, cw, sw, p)
                if (v > 0.0) == (v_lo > 0.0):
                    lo = s
                else:
                    hi = s
                s_new = s - v / acc if acc != 0.0 else 0.5 * (lo + hi)
                if not (lo < s_new < hi):
                    s_new = 0.5 * (lo + hi)
                if abs(s_new - s) <= 1e-15 * h:
                    s = s_new
                    break
                s = s_new
            q, _, _ = _q_at(s, zc0, vc0, zp0, vp0, cw, sw, p)
            qmin = min(qmin, q)
            qmax = max(qmax, q)
        s_prev, v_prev = s_j, v_j
    return qmin, qmax


@njit(cache=True, inline="always")
def _project(o, row, zc, dz, dv, zp, vp1, cw, sw, h, zdrive, lam1, wd1, lam2, wd2):
    """Add the exact first-harmonic projection ``int_0^h q(s) exp(-i w (t0 + s)) ds`` of a far
    step to ``o[O_HC], o[O_HS]``: ``q`` is the drive's particular solution plus the free
    cantilever and paddle modes from ``(dz, dv)`` and ``(zp, vp1)`` (after the opening kick);
    ``row``: the step's ladder entry with the factors of :func:`.coefficients.harmonic_factors`."""
    e0 = complex(cw, -sw)  # exp(-i w t0)
    ca = complex(dz, -(dv - lam1 * dz) / wd1)
    cp = complex(zp, -(vp1 - lam2 * zp) / wd2)
    k1 = complex(row[L_K1R], row[L_K1I])
    k1b = complex(row[L_K1BR], row[L_K1BI])
    k2 = complex(row[L_K2R], row[L_K2I])
    k2b = complex(row[L_K2BR], row[L_K2BI])
    kp = complex(row[L_KPR], row[L_KPI])
    proj = 0.5 * e0 * (ca * k1 + ca.conjugate() * k1b + cp * k2 + cp.conjugate() * k2b)
    proj += 0.5 * zdrive * h + 0.5 * zdrive.conjugate() * (e0 * e0) * kp
    o[O_HC] += proj.real
    o[O_HS] += proj.imag


EPS_STEP = 0.05  # far step <= EPS_STEP * gap / |tip speed|: the attraction changes < 5 % over a step


@njit(cache=True, fastmath={"contract"}, error_model="numpy")
def _far(s, n_end, zb_step, p, a, lad, lemi, lg, buf, r, o, energy, rec_mode):
    """Long exact steps from ``s`` while the gap stays above ``d_switch``.

    The step length is the longest ladder entry not above
    ``EPS_STEP * gap/|tip speed|`` (and not past ``n_end``); a step whose gap
    would fall below ``d_switch`` -- at its end or at the lowest point of the
    exact trajectory inside it -- is retried one ladder entry shorter.  Returns
    False when not even the shortest step can be taken (fine steps must
    resume).  In ``rec_mode`` (the one-entry recording ladder) it also stops
    when the recorder closes.
    """
    n_arms = len(s) - S_XD
    nlev = lad.shape[0]
    m1, m2, c1, c2, f0 = p[P_M1], p[P_M2], p[P_C1], p[P_C2], p[P_F0]
    zr, zi, omega = p[P_ZR], p[P_ZI], p[P_OMEGA]
    hr6, dsw, dt, invkg = p[P_HR6], p[P_DSW], p[P_DT], p[P_INVKG]
    ihr6 = p[P_IHR6]
    w2 = math.sqrt(p[P_K2] / m2)
    curv = p[P_K1] / m1  # omega1^2: bound on the cantilever's curvature per unit deflection
    lam1 = -0.5 * c1 / m1
    wd1 = math.sqrt(p[P_K1] / m1 - lam1 * lam1)
    lam2 = -0.5 * c2 / m2
    wd2 = math.sqrt(p[P_K2] / m2 - lam2 * lam2)
    zdrive = complex(zr, zi)
    vdw = p[P_VDW] > 0.0
    nt = int(p[P_NT])
    k_arm = a[A_K]
    xd0 = s[S_XD:].copy()  # base + accumulated increments, as in fine_steps
    dxd = np.zeros(n_arms)
    xd = xd0.copy()
    xd_new = np.empty(n_arms)
    dxd_new = np.empty(n_arms)
    n = int(s[S_IDX])
    zc, vc, zp, vp, zb = s[S_ZC], s[S_VC], s[S_ZP], s[S_VP], s[S_ZB]
    z_tip = zb + zc + zp
    x, fa = surface_position(z_tip, xd, p, a, False)
    th = omega * (n % nt) * dt
    cw, sw = math.cos(th), math.sin(th)
    stride = r[R_STRIDE]
    origin = r[R_ORIGIN]
    moved = True
    while n < n_end:
        # the longest step within the attraction's time scale and before n_end
        speed = abs(vc) + abs(vp) + 1e-30
        hmax = EPS_STEP * (z_tip - x) / speed
        lev = nlev - 1
        while lev > 0 and (lad[lev, L_H] > hmax or n + int(lad[lev, L_N]) > n_end):
            lev -= 1
        if n + int(lad[lev, L_N]) > n_end:
            break
        accepted = False
        while lev >= 0:
            h = lad[lev, L_H]
            hh = 0.5 * h
            # half kick, exact flow (drive through its particular solution), creep, half kick
            vc1 = vc - hh * fa / m1
            vp1 = vp - hh * fa / m2
            zpart0 = zr * cw - zi * sw
            vpart0 = -omega * (zr * sw + zi * cw)
            cw1 = cw * lad[lev, L_COS] - sw * lad[lev, L_SIN]
            sw1 = sw * lad[lev, L_COS] + cw * lad[lev, L_SIN]
            zpart1 = zr * cw1 - zi * sw1
            vpart1 = -omega * (zr * sw1 + zi * cw1)
            dz, dv = zc - zpart0, vc1 - vpart0
            zc1 = lad[lev, L_C00] * dz + lad[lev, L_C01] * dv + zpart1
            vc2 = lad[lev, L_C10] * dz + lad[lev, L_C11] * dv + vpart1
            zp1 = lad[lev, L_P00] * zp + lad[lev, L_P01] * vp1
            vp2 = lad[lev, L_P10] * zp + lad[lev, L_P11] * vp1
            zb1 = zb + zb_step * lad[lev, L_N]
            z1 = zb1 + zc1 + zp1
            # creep predictor with the start attraction, then the consistent end attraction
            xs = 0.0
            for i in range(n_arms):
                acc = lg[lev, i] * fa
                for j in range(n_arms):
                    acc += lemi[lev, i, j] * xd[j]
                xd_new[i] = xd[i] + acc
                xs += k_arm[i] * xd_new[i]
            fa1 = fa
            x1 = (xs + (fa1 if vdw else 0.0)) * invkg
            # the attraction at the end, consistent with the surface it pulls (fixed point; the
            # gain 2 Fa/(d Kg) is small this far out; without the pull one evaluation is exact)
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
            d1 = z1 - x1
            vc3 = vc2 - hh * fa1 / m1
            vp3 = vp2 - hh * fa1 / m2
            # extrema of q = zc + zp inside the step where they could matter (bound: the
            # paddle's ringing amplitude and the cantilever's curvature over the step)
            q0 = z_tip - zb
            q1 = z1 - zb1
            qmn, qmx = min(q0, q1), max(q0, q1)
            floor = dsw + max(x, x1) - min(zb, zb1)  # q below which the gap is below d_switch
            # a recording step is one print step (<= 1/20 of a period, far below the time the
            # attraction takes to change): its ends bound it; a long step is searched
            ring = 0.0 if rec_mode else 2.0 * math.sqrt(zp * zp + (vp1 / w2) ** 2) + curv * (abs(zc) + abs(zc1)) * h * h / 8.0
            if not rec_mode and (qmx + ring >= o[O_QMAX] or qmn - ring <= o[O_QMIN] or qmn - ring <= floor):
                if h * w2 < 0.1:  # a step far below the paddle period: the cubic is exact enough
                    qmn, qmx = _hermite_extrema(q0, vc1 + vp1, q1, vc2 + vp2, h)
                else:
                    qmn, qmx = _extrema(h, zc, vc1, zp, vp1, cw, sw, p, q0, q1)
            if d1 > dsw and qmn > floor:
                accepted = True
                break
            o[O_REJECT] += 1.0
            lev -= 1
        if not accepted:
            moved = False
            break
        # accepted: first harmonic of q over the step -- a recording step by the trapezoid
        # rule (print-step samples, error (w h)^2/12), a long step exactly (damped exponentials)
        if rec_mode:
            o[O_HC] += hh * ((z_tip - zb) * cw + (z1 - zb1) * cw1)
            o[O_HS] -= hh * ((z_tip - zb) * sw + (z1 - zb1) * sw1)
        else:
            _project(o, lad[lev], zc, zc - zpart0, vc1 - vpart0, zp, vp1, cw, sw, h, zdrive, lam1, wd1, lam2, wd2)
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
        if qmx > o[O_QMAX]:
            o[O_QMAX] = qmx
        if qmn < o[O_QMIN]:
            o[O_QMIN] = qmn
        if -fa1 > o[O_FMAX]:
            o[O_FMAX] = -fa1
        if -fa1 < o[O_FMIN]:
            o[O_FMIN] = -fa1
        if energy:
            o[O_WDRIVE] += hh * f0 * (cw * vc + cw1 * vc3)
            o[O_D1] += hh * c1 * (vc * vc + vc3 * vc3)
            o[O_D2] += hh * c2 * (vp * vp + vp3 * vp3)
            # -(integral of Fts dz_tip) with Fts = -H R/(6 d^2), d = z_tip - X: exact along d (the
            # attraction's potential, hr6 (1/d1 - 1/d0)), trapezoid along the surface's small motion.
            # The trapezoid on dz_tip alone erred by (1/12) Fts'' dz^3 a step, which near the switch gap
            # and over long recording steps summed to ~1e-3 eV a cycle: the whole E_diss of a frozen
            # dashpot under the pull (scripts/hybrid_vs_verlet.py)
            o[O_WTS] -= hr6 * (1.0 / (z1 - x1) - 1.0 / (z_tip - x)) + 0.5 * (-fa - fa1) * (x1 - x)
            _free_dissipation(o, k_arm, p[P_KINF], x, x1, xd, xd_new, fm * (x1 - x) if vdw else 0.0)
            for i in range(n_arms):
                o[O_XM + i] += 0.5 * ((x - xd[i]) + (x1 - xd_new[i])) * h
        zc, vc, zp, vp, zb = zc1, vc3, zp1, vp3, zb1
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
    s[S_ZC], s[S_VC], s[S_ZP], s[S_VP], s[S_ZB] = zc, vc, zp, vp, zb
    s[S_IDX] = n
    s[S_CONTACT] = 0.0
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
                moved = _far(s, n_end, zb_step, p, a, lad_rec, lemi_rec, lg_rec, buf, r, o, energy, True)
            else:
                moved = _far(s, n_end, zb_step, p, a, lad, lemi, lg, buf, r, o, energy, False)
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


# public names of the helpers the MDR surface kernel (core.mdr) shares with this one
store_sample = _store
hermite_extrema = _hermite_extrema
far_extrema = _extrema
project_harmonic = _project
