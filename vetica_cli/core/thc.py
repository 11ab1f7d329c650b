"""Time loop of the Torsional Harmonic Cantilever tapping a Zener SLS surface.

Plain SI floats in, plain arrays out: no dicts, no dataclasses, no I/O.

Probe (thesis eqs. 15-16, decoupled THC point-mass model)::

    m1 zc'' = -k1 zc - c1 zc' + F0 cos(w t) + Fts        flexural cantilever  [N]
    m2 zp'' = -k2 zp - c2 zp' + Fts                       torsional paddle+tip [N]
    z_tip   = Zb + zc + zp                                                     [m]

Integrator: velocity Verlet (thesis appendix B).  The linear damping force is
treated implicitly inside the velocity half-step (``v_new (1 + dt c/2m) = ...``)
so the scheme stays explicit in position and second order.

The loop-carried dependency force -> position -> force is kept short by
splitting every velocity/acceleration into a part that does not depend on the
current ``Fts`` and a constant multiple of ``Fts``: the next tip position is
``(sum of Fts-free parts) + B * Fts``, one fused multiply-add on the chain.

Surface (``sls.py``): massless Zener SLS, contact / non-contact regimes,
exact exponential dashpot step.
"""

import math

import numpy as np
from numba import njit

from .sls import contact_update, noncontact_update, released_position, sls_coefficients


# Column order of the recorded sample arrays.
COLUMNS = ("t", "z_tip", "z_cantilever", "z_paddle", "z_base", "f_ts", "x_surface", "x_dashpot")
NCOL = 8

# Stop codes.
STOP_STEADY = 0
STOP_BUDGET = 1

# Indices into the ``info`` vector returned by :func:`integrate`.
INFO_NAMES = (
    "steps",  # integration steps taken
    "t_end",  # [s] simulated time
    "t_first_contact",  # [s] time of the first approach contact (nan if none)
    "z_first_contact",  # [m] tip position at the first approach contact
    "t_record_start",  # [s] start of the steady recording window
    "w_drive",  # [J] drive work on the cantilever over the recording window
    "d_cantilever",  # [J] energy lost to cantilever damping c1 over the window
    "d_paddle",  # [J] energy lost to paddle damping c2 over the window
    "w_ts",  # [J] -sum Fts dz_tip over the window (energy taken from the tip)
    "d_dashpot",  # [J] energy dissipated in the dashpot over the window
    "e_mech_start",  # [J] probe mechanical energy at the window start
    "e_mech_end",  # [J] probe mechanical energy at the window end
    "contact_steps",  # steps spent in contact during the window
    "n_contacts",  # contact events during the window
    "n_separations",  # separation events during the window
    "zb_final",  # [m] base height during the window
    "amp_last",  # [m] last running amplitude measured by the controller
    "periods",  # controller periods simulated
    "settled_periods",  # consecutive settled periods when recording started
    "approach_written",  # samples written into the approach ring buffer
    "z_contact_last",  # [m] tip position at the last contact event before recording
    "max_contacts_per_period",  # largest number of contact events in one recorded period
)
NINFO = len(INFO_NAMES)


@njit(cache=True)
def _verlet_step(z, vp, fts, drv0, drv1, dt, w2, g, im, bv, inv):
    """One velocity-Verlet step of ``m z'' = -k z - c z' + drive + Fts``.

    ``vp`` is the velocity without its share of the current ``fts``
    (``v = vp + bv fts``); the linear damping is implicit in the velocity
    half step.  Returns ``(z_next, vp_next)``.  The step is linear in its
    inputs: :func:`_step_matrix` evaluates it on unit vectors.
    """
    v = vp + bv * fts
    a = -w2 * z - g * v + (drv0 + fts) * im
    z1 = z + dt * v + 0.5 * dt * dt * a
    vp1 = (v + 0.5 * dt * a + 0.5 * dt * (-w2 * z1 + drv1 * im)) * inv
    return z1, vp1


@njit(cache=True)
def _step_matrix(dt, w2, g, im, bv, inv):
    """Coefficients of the linear Verlet map (z, vp, fts, drive_n, drive_n+1) -> (z', vp')."""
    m = np.zeros((2, 5))
    for j in range(5):
        u = np.zeros(5)
        u[j] = 1.0
        z1, v1 = _verlet_step(u[0], u[1], u[2], u[3], u[4], dt, w2, g, im, bv, inv)
        m[0, j] = z1
        m[1, j] = v1
    return m


@njit(cache=True)
def _two_step_row(m):
    """Coefficients of z_{n+2} on (z_n, vp_n, Fts_n, drive_n, drive_{n+1}) with Fts_{n+1} = 0.

    ``m`` is the one-step map of :func:`_step_matrix` (drive columns unscaled).
    """
    r = np.zeros(5)
    for j in range(5):
        r[j] = m[0, 0] * m[0, j] + m[0, 1] * m[1, j]
    r[4] += m[0, 3]  # drive_{n+1} also enters z_{n+2} directly
    return r[0], r[1], r[2], r[3], r[4]


@njit(cache=True, fastmath={"contract"}, error_model="numpy")
def integrate(
    m1, k1, c1, m2, k2, c2, omega, f0,
    k_inf, k0, cd, hr6, a0, vdw_on_surface,
    a_sp, zb0, zc0, vc0, zp0, vp0, controller_on, kp, ki, approach_rate,
    dt, stride, samples_per_period, max_steps, tol_amp, tol_z, settle_cycles,
    n_ring, n_steady,
):
    """Integrate the THC + SLS system until steady state, then record.

    Parameters are SI floats (masses kg, stiffness N/m, damping kg/s, omega
    rad/s, f0 N, hr6 = H R / 6 in J m, lengths m, dt s, approach_rate m/s).
    ``stride`` is print_step/dt, ``samples_per_period`` the controller period in
    print steps (one drive period, rounded to the print step), ``n_ring`` the approach ring-buffer length and ``n_steady`` the
    number of steady samples to record.

    The Verlet step is linear in the probe state, so it is applied as a
    precomputed 2x5 matrix per oscillator; the gap for the next step is
    ``d = (Zb + u - xbase) + kappa Fts`` (one FMA after the force), where
    ``u`` is the force-free part of the next tip deflection and ``xbase`` the
    force-free part of the surface position (``X = xbase - beta Fts``).

    Returns ``(ring, steady, info, stop_code)``: ``ring`` (n_ring, 8) holds the
    print-step samples around the first approach contact (unrolled by the
    caller with ``info['approach_written']``), ``steady`` (n_steady, 8) the
    samples of the recorded steady window, ``info`` see ``INFO_NAMES``.
    """
    hdt = 0.5 * dt
    w21 = k1 / m1
    w22 = k2 / m2
    g1 = c1 / m1
    g2 = c2 / m2
    inv1 = 1.0 / (1.0 + hdt * g1)
    inv2 = 1.0 / (1.0 + hdt * g2)
    im1 = 1.0 / m1
    im2 = 1.0 / m2
    bv1 = hdt * inv1 * im1  # share of Fts_n in v_n (implicit half step)
    bv2 = hdt * inv2 * im2
    mc = _step_matrix(dt, w21, g1, im1, bv1, inv1)
    mp = _step_matrix(dt, w22, g2, im2, bv2, inv2)
    czz, czv, czf, czd = mc[0, 0], mc[0, 1], mc[0, 2], mc[0, 3] * f0
    cvz, cvv, cvf, cvd0, cvd1 = mc[1, 0], mc[1, 1], mc[1, 2], mc[1, 3] * f0, mc[1, 4] * f0
    pzz, pzv, pzf = mp[0, 0], mp[0, 1], mp[0, 2]
    pvz, pvv, pvf = mp[1, 0], mp[1, 1], mp[1, 2]
    ef = czf + pzf  # d(z_tip next)/d(Fts)
    # two steps composed, Fts_{n+1} = 0: z_{n+2} = r . (z_n, vp_n, Fts_n, c_n, c_{n+1})
    rcz, rcv, rcf, rc0, rc1 = _two_step_row(mc)
    rpz, rpv, rpf, _, _ = _two_step_row(mp)
    rc0 *= f0
    rc1 *= f0
    rho = rcf + rpf

    (ec, er, alpha, beta, gamma, kc, k0er, fa0, sep_thr, fa_sep, fa_c, inv_kg) = sls_coefficients(
        k_inf, k0, cd, dt, hr6, a0, vdw_on_surface
    )
    kappa = ef + beta
    ihr6 = 1.0 / hr6 if hr6 > 0.0 else 0.0
    cr = math.cos(omega * dt)
    sr = math.sin(omega * dt)

    ring = np.zeros((n_ring, 8))
    steady = np.zeros((n_steady, 8))
    info = np.full(NINFO, np.nan)

    # --- initial state
    zc = zc0
    zp = zp0
    zb = zb0
    xd = 0.0
    in_contact = False
    z_tip = zb + zc + zp
    d = z_tip
    fa = hr6 / (d * d)
    fts = -fa
    x = (fa if vdw_on_surface else 0.0) * inv_kg  # surface pulled by the initial Fa
    xbase = x + beta * fts
    vcp = vc0 - bv1 * fts
    vpp = vp0 - bv2 * fts
    # force-free part of the first step's tip deflection: z_1 = u1 + ef Fts_0
    u1 = (czz * zc + czv * vcp + czd * math.cos(0.0)) + (pzz * zp + pzv * vpp)

    n = 0  # global step index, t = n dt
    vb_dt = -approach_rate * dt  # base increment per step before first contact
    first_contact = False
    ring_written = 0
    ring_left = n_ring // 2  # samples still to write after the first repulsive contact
    repulsive_seen = False  # a first contact can be a graze that never turns repulsive
    ring_active = n_ring > 0
    e_prev = 0.0
    amp_prev = -1.0
    zcont_prev = np.nan
    settled = 0
    recording = False
    rec_i = 0
    stop_code = STOP_STEADY
    period = 0
    w_drive = 0.0
    d1 = 0.0
    d2 = 0.0
    w_ts = 0.0
    d_dash = 0.0
    contact_steps = 0
    n_cont = 0
    n_sep = 0
    max_cpp = 0
    z_contact_last = np.nan
    rec_steps = (n_steady - 1) * stride + 1
    steps_per_period = samples_per_period * stride
    budget_start = max_steps - rec_steps - steps_per_period
    amp = 0.0
    ztip_old = z_tip

    while True:
        # drive phase at the start of this controller period, exact
        t0 = n * dt
        cw = math.cos(omega * t0)
        sw = math.sin(omega * t0)
        qmax = -1e300
        qmin = 1e300
        zcont = np.nan
        cont_this = 0
        for _ in range(samples_per_period):
            for _k in range(stride):
                fts_old = fts
                vcp_old = vcp
                vpp_old = vpp
                cw_old = cw
                cw, sw = cw * cr - sw * sr, sw * cr + cw * sr
                zb += vb_dt
                # tip deflection two steps ahead, without Fts_{n+1}: from y_n, Fts_n
                # (off the critical path; enters the next gap with one add)
                u2 = ((rcz * zc + rcv * vcp) + (rpz * zp + rpv * vpp)) + (rc0 * cw_old + rc1 * cw) + rho * fts
                # probe state y_{n+1} (linear Verlet map); late operand Fts_n last
                zc, vcp = (
                    (czz * zc + czv * vcp) + (czd * cw_old + czf * fts),
                    (cvz * zc + cvv * vcp) + ((cvd0 * cw_old + cvd1 * cw) + cvf * fts),
                )
                zp, vpp = (pzz * zp + pzv * vpp) + pzf * fts, (pvz * zp + pvv * vpp) + pvf * fts
                base = zb + u1  # z_tip_{n+1} = base + ef * Fts_n
                u1 = u2
                n += 1
                xd_prev = xd
                if not in_contact:
                    # gap on the critical path: one FMA after the previous force
                    d = (base - xbase) + kappa * fts
                    if d > a0:
                        xbase = alpha * xd  # force-free part of X (off the critical path)
                        fa, _x, xd = noncontact_update(d, xd, fa, hr6, ihr6, alpha, beta, gamma, ec)
                        fts = -fa
                    else:
                        in_contact = True
                        z_tip = base + ef * fts_old
                        cont_this += 1
                        if cont_this == 1:
                            zcont = z_tip
                        z_contact_last = z_tip
                        if recording:
                            n_cont += 1
                        if not first_contact:
                            first_contact = True
                            info[2] = n * dt
                            info[3] = z_tip
                if in_contact:
                    # X = z_tip - a0; exact dashpot relaxation; F_sls = Kg X - k0 Xd
                    x = (base - a0) + ef * fts
                    f_sls, xd = contact_update(x, xd, kc, k0er, er)
                    if f_sls > sep_thr:
                        # separation: surface released, held only by the adhesion
                        in_contact = False
                        x = released_position(xd, fa_sep, k0, inv_kg)
                        fts = -fa0
                        if recording:
                            n_sep += 1
                    else:
                        fts = -f_sls - fa_c
                    xbase = x + beta * fts
                if recording:
                    z_tip = base + ef * fts_old
                    x = xbase - beta * fts
                    vc_old = vcp_old + bv1 * fts_old
                    vp_old = vpp_old + bv2 * fts_old
                    vc_new = vcp + bv1 * fts
                    vp_new = vpp + bv2 * fts
                    # trapezoidal energy integrals over the step
                    w_drive += hdt * f0 * (cw_old * vc_old + cw * vc_new)
                    d1 += hdt * c1 * (vc_old * vc_old + vc_new * vc_new)
                    d2 += hdt * c2 * (vp_old * vp_old + vp_new * vp_new)
                    w_ts -= 0.5 * (fts_old + fts) * (z_tip - ztip_old)
                    ztip_old = z_tip
                    # dashpot: force k0 (X - Xd) times the dashpot displacement
                    d_dash += k0 * (x - 0.5 * (xd + xd_prev)) * (xd - xd_prev)
                    if in_contact:
                        contact_steps += 1
            z_tip = base + ef * fts_old
            q = z_tip - zb
            if q > qmax:
                qmax = q
            if q < qmin:
                qmin = q
            if recording:
                _store(steady, rec_i, n * dt, z_tip, zc, zp, zb, fts, xbase - beta * fts, xd)
                rec_i += 1
                if rec_i == n_steady:
                    break
            elif ring_active:
                _store(ring, ring_written % n_ring, n * dt, z_tip, zc, zp, zb, fts, xbase - beta * fts, xd)
                ring_written += 1
                if first_contact and not repulsive_seen and fts > 0.0:
                    repulsive_seen = True
                if repulsive_seen:
                    ring_left -= 1
                    if ring_left <= 0:
                        ring_active = False
        period += 1
        if cont_this > max_cpp and recording:
            max_cpp = cont_this
        if recording and rec_i == n_steady:
            break
        amp = 0.5 * (qmax - qmin)
        if recording:
            continue
        # ---- controller and steady-state check, once per period
        e = amp - a_sp
        if controller_on:
            if first_contact:
                dzb = -(kp * (e - e_prev) + ki * e)
                vb_dt = dzb / steps_per_period
            e_prev = e
            amp_ok = abs(e) <= tol_amp * a_sp
        else:
            vb_dt = 0.0
            amp_ok = amp_prev > 0.0 and abs(amp - amp_prev) <= tol_amp * amp
        amp_prev = amp
        if first_contact:
            z_ok = cont_this > 0 and (not np.isnan(zcont_prev)) and abs(zcont - zcont_prev) <= tol_z
            zcont_prev = zcont if cont_this > 0 else np.nan
        else:
            z_ok = not controller_on  # free oscillation: no surface to settle
        if amp_ok and z_ok and (first_contact or not controller_on):
            settled += 1
        else:
            settled = 0
        start = False
        if settled >= settle_cycles:
            start = True
            stop_code = STOP_STEADY
        elif n >= budget_start:
            start = True
            stop_code = STOP_BUDGET
        if start:
            recording = True
            vb_dt = 0.0  # controller holds the base during the recorded window
            info[4] = n * dt
            info[10] = _mech_energy(m1, k1, m2, k2, zc, vcp + bv1 * fts, zp, vpp + bv2 * fts)
            info[18] = settled
            info[20] = z_contact_last
            info[16] = amp
            ztip_old = zb + zc + zp
    info[0] = n
    info[1] = n * dt
    info[5] = w_drive
    info[6] = d1
    info[7] = d2
    info[8] = w_ts
    info[9] = d_dash
    info[11] = _mech_energy(m1, k1, m2, k2, zc, vcp + bv1 * fts, zp, vpp + bv2 * fts)
    info[12] = contact_steps
    info[13] = n_cont
    info[14] = n_sep
    info[15] = zb
    info[17] = period
    info[19] = ring_written
    info[21] = max_cpp
    return ring, steady, info, stop_code


@njit(cache=True, inline="always")
def _store(buf, i, t, z_tip, zc, zp, zb, fts, x, xd):
    """Write one print-step sample (columns as ``COLUMNS``)."""
    buf[i, 0] = t
    buf[i, 1] = z_tip
    buf[i, 2] = zc
    buf[i, 3] = zp
    buf[i, 4] = zb
    buf[i, 5] = fts
    buf[i, 6] = x
    buf[i, 7] = xd


@njit(cache=True)
def _mech_energy(m1, k1, m2, k2, zc, vc, zp, vp):
    """Kinetic + elastic energy of both probe oscillators [J]."""
    return 0.5 * (m1 * vc * vc + k1 * zc * zc + m2 * vp * vp + k2 * zp * zp)
