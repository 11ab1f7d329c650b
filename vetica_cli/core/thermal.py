"""Fine Verlet steps with a Brownian force on each probe mode (fluctuation-dissipation).

The same probe and surface physics as :func:`.tapping.fine_steps` (and its
coefficient arrays ``p, a, emi``), written as plain velocity Verlet so that a
random force can enter each mode at every step:

    m1 zc'' = -k1 zc - c1 zc' + F0 cos(w t) + Fts + F_B1(t)
    m2 zp'' = -k2 zp - c2 zp' + Fts + F_B2(t)

``F_B1, F_B2`` are held constant over a step; their per-step values are passed in
(drawn by the caller: Gaussian of variance ``S_F/(2 dt)``, one-sided PSD
``S_F = 4 kB T m w0/Q``, fluctuation-dissipation), so the kernel stays
deterministic and the noise reproducible from a seed.  The damping enters the
second velocity half step implicitly (as in the fine kernel).  Surface: out of
contact the attraction is taken at the gap to the last step's surface, the arms
creep by the exact coupled step (``Xd += emi Xd + g Fa``) and the surface follows,
``X = (sum k_i Xd_i + Fa)/Kg`` -- the fine kernel's rule, so a surface soft enough
to snap to the tip (the pull's gain ``2 Fa/(d Kg)`` reaching 1 above ``a0``) snaps
where the noise-free record has it (a 4-iteration fixed point from the unpulled
surface, the rule before, snapped 45 pm lower at Kg = 10.5 N/m); in contact
``X = z_tip - a0`` and each arm relaxes exactly towards the linearly moving
target; contact when the gap reaches ``a0``, separation when the surface would
have to hold the tip with more than the adhesion -- the rules of the SLS and Wiechert models.

Only for the recorded periods of a run at ``numerics.temperature > 0``.  Two integrators, as
for the noise-free record: :func:`brownian_steps` (and its batch twin) takes fine steps all the
way (``numerics.integrator: verlet``); :func:`brownian_hybrid` (the default) takes them only in
contact and within ``d_switch`` of the surface, and farther out one exact step of a print step:
the noise-free far step (each mode's exact linear flow, the attraction as two half kicks, the
arms' exact creep) plus each free mode's sampled Ornstein-Uhlenbeck increment over the step,
``(dz, dv) = L (e1, e2)``, ``L L^T`` the increment's covariance (Van Loan's block exponential,
:func:`vetica_cli.simulation.thermal.sampled_flow`): exact for the linear modes by
superposition, since the random force enters additively.
"""

import math

import numpy as np
from numba import njit

from .coefficients import (
    A_G, A_K, A_LIN, A_OMER, L_H, L_N, P_A0, P_C1, P_C2, P_COSDT, P_DSW, P_DT, P_F0, P_FA0, P_FAC, P_FASEP,
    P_INVKG, P_K1, P_K2, P_KINF, P_M1, P_HR6, P_IHR6, P_VDW, P_M2, P_NT, P_OMEGA, P_SEPTHR, P_SINDT,
)  # fmt: skip
from . import probe as PR
from .probe import S_CONTACT, S_IDX, S_VC, S_VP, S_XD, S_ZB, S_ZC, S_ZP
from .sls import vdw_force
from .tapping import contact_force, end_attraction, surface_position


# :func:`.tapping.surface_position`'s own body, compiled into the recording kernel (the start state's surface; a call no
# more: the replicas' steps sit closer together in the instruction stream); same arithmetic
_surface_position = njit(inline="always")(surface_position.py_func)


@njit(cache=True)
def brownian_steps(s, fb1, fb2, p, a, emi, buf, stride, origin, pos, sig1=1.0, sig2=1.0, scaled=False):
    """``len(fb1)`` Verlet steps from the state ``s`` (updated in place) with the
    Brownian forces ``fb1[j], fb2[j]`` [N] on the cantilever and the paddle during
    step ``j``.  A sample (``t, z_tip, zc, zp, zb, Fts, X, Xd_1..N``) is written to
    ``buf[pos]`` after every step whose global index is ``origin`` + a multiple of ``stride``
    (``pos`` < 0 or beyond the buffer: nothing written).  Returns the next ``pos``.  With
    ``scaled``, ``fb1, fb2`` are standard normal and the forces ``0.0 + sig1 * fb1[j]``, ``0.0 +
    sig2 * fb2[j]`` (the numbers ``Generator.normal(0, sig, n)`` gives from the same stream).
    The one-replica twin of :func:`brownian_steps_batch` (the same arithmetic, the state in
    registers; tests/test_thermal_batch.py holds the two to the same records bit for bit)."""
    n_arms = len(s) - S_XD
    dt = p[P_DT]
    hdt = 0.5 * dt
    m1, m2, k1, k2, c1, c2 = p[P_M1], p[P_M2], p[P_K1], p[P_K2], p[P_C1], p[P_C2]
    f0 = p[P_F0]
    a0, fa0, fa_c, sep_thr, fa_sep, invkg = p[P_A0], p[P_FA0], p[P_FAC], p[P_SEPTHR], p[P_FASEP], p[P_INVKG]
    kinf = p[P_KINF]
    hr6, ihr6, vdw = p[P_HR6], p[P_IHR6], p[P_VDW] > 0.0
    cr, sr = p[P_COSDT], p[P_SINDT]
    den1 = 1.0 + hdt * c1 / m1
    den2 = 1.0 + hdt * c2 / m2
    k_arm = a[A_K]
    omer = a[A_OMER]
    lin = a[A_LIN]
    g = a[A_G]
    xd = s[S_XD:].copy()
    tmp = np.empty(n_arms)
    n, zc, vc, zp, vp, zb, contact, th = PR.load(s, p)
    cw, sw = math.cos(th), math.sin(th)
    z_tip = zb + zc + zp
    fa = fa0
    if contact:
        x = z_tip - a0
        fts = -contact_force(x, xd, p, a) - fa_c
    else:
        x, fa = _surface_position(z_tip, xd, p, a, False)
        fts = -fa
    n_buf = buf.shape[0]
    for j in range(len(fb1)):
        if scaled:
            f1 = 0.0 + sig1 * fb1[j]
            f2 = 0.0 + sig2 * fb2[j]
        else:
            f1 = fb1[j]
            f2 = fb2[j]
        # first half kick with the forces at the start of the step
        vc += hdt * (-k1 * zc - c1 * vc + f0 * cw + fts + f1) / m1
        vp += hdt * (-k2 * zp - c2 * vp + fts + f2) / m2
        zc += dt * vc
        zp += dt * vp
        cw, sw = cw * cr - sw * sr, sw * cr + cw * sr
        n += 1
        z_tip = zb + zc + zp
        x_last = x
        if not contact:
            # the fine kernel's rule (tapping.fine_steps): the attraction at the gap to the last
            # step's surface, then the arms and the surface with it
            d = z_tip - x
            if d > a0:
                fa = vdw_force(d, fa, hr6, ihr6)
                for i in range(n_arms):
                    acc = g[i] * fa
                    for k in range(n_arms):
                        acc += emi[i, k] * xd[k]
                    tmp[i] = acc
                xs = 0.0
                for i in range(n_arms):
                    xd[i] += tmp[i]
                    xs += k_arm[i] * xd[i]
                x = (xs + fa) * invkg if vdw else xs * invkg
                fts = -fa
            else:
                contact = True
        if contact:
            x = z_tip - a0
            for i in range(n_arms):
                xd[i] += omer[i] * (x - xd[i]) - lin[i] * (x - x_last)
            f_sls = kinf * x
            for i in range(n_arms):
                f_sls += k_arm[i] * (x - xd[i])
            if f_sls > sep_thr:
                contact = False
                xs = 0.0
                for i in range(n_arms):
                    xs += k_arm[i] * xd[i]
                x = (xs + fa_sep) * invkg
                fts = -fa0
                fa = fa0
            else:
                fts = -f_sls - fa_c
        # second half kick, damping implicit
        vc = (vc + hdt * (-k1 * zc + f0 * cw + fts + f1) / m1) / den1
        vp = (vp + hdt * (-k2 * zp + fts + f2) / m2) / den2
        if (n - origin) % stride == 0 and 0 <= pos < n_buf:
            buf[pos, 0] = n * dt
            buf[pos, 1] = z_tip
            buf[pos, 2] = zc
            buf[pos, 3] = zp
            buf[pos, 4] = zb
            buf[pos, 5] = fts
            buf[pos, 6] = x
            for i in range(n_arms):
                buf[pos, 7 + i] = xd[i]
            pos += 1
    s[S_ZC], s[S_VC], s[S_ZP], s[S_VP] = zc, vc, zp, vp
    s[S_IDX] = n
    s[S_CONTACT] = 1.0 if contact else 0.0
    for i in range(n_arms):
        s[S_XD + i] = xd[i]
    return pos


@njit(cache=True)
def brownian_steps_batch(s, z1, z2, sig, p, a, emi, buf, stride, origin, pos):
    """``z1.shape[1]`` Verlet steps of ``R = s.shape[0]`` independent replicas (one state
    ``s[r]`` each, updated in place; the same coefficients ``p, a, emi``), the replica loop
    inside the step loop, so that the replicas' serial chains (the kicks, the attraction's
    Newton step, the creep) overlap in the CPU.  Replica ``r``'s
    Brownian forces during step ``j``: ``0.0 + sig[r, 0] * z1[r, j]`` and ``0.0 + sig[r, 1] *
    z2[r, j]`` (``z`` standard normal: the numbers ``Generator.normal(0, sig, n)`` gives from the
    same stream).  Its samples go to
    ``buf[r, pos[r]]`` on the recording grid ``origin[r]`` + multiples of ``stride`` (``pos[r]``
    < 0 or beyond the buffer: nothing written; ``pos`` updated in place).  Each replica's
    arithmetic is :func:`brownian_steps`'s, operation for operation (no fastmath), so its record
    is bit for bit the one it gets alone (its state lives in arrays between its steps here: R = 1
    is :func:`brownian_steps`'s job)."""
    n_rep = s.shape[0]
    n_arms = s.shape[1] - S_XD
    dt = p[P_DT]
    hdt = 0.5 * dt
    m1, m2, k1, k2, c1, c2 = p[P_M1], p[P_M2], p[P_K1], p[P_K2], p[P_C1], p[P_C2]
    f0 = p[P_F0]
    a0, fa0, fa_c, sep_thr, fa_sep, invkg = p[P_A0], p[P_FA0], p[P_FAC], p[P_SEPTHR], p[P_FASEP], p[P_INVKG]
    kinf = p[P_KINF]
    hr6, ihr6, vdw = p[P_HR6], p[P_IHR6], p[P_VDW] > 0.0
    cr, sr = p[P_COSDT], p[P_SINDT]
    den1 = 1.0 + hdt * c1 / m1
    den2 = 1.0 + hdt * c2 / m2
    k_arm = a[A_K]
    omer = a[A_OMER]
    lin = a[A_LIN]
    g = a[A_G]
    xd = s[:, S_XD:].copy()
    tmp = np.empty((n_rep, n_arms))
    # each replica's probe, drive phase, surface and force (its registers, kept in arrays between steps)
    nn = np.empty(n_rep, np.int64)
    zc_r, vc_r, zp_r, vp_r, zb_r = np.empty(n_rep), np.empty(n_rep), np.empty(n_rep), np.empty(n_rep), np.empty(n_rep)
    cw_r, sw_r, x_r, fts_r = np.empty(n_rep), np.empty(n_rep), np.empty(n_rep), np.empty(n_rep)
    fa_r = np.empty(n_rep)
    contact_r = np.empty(n_rep, np.bool_)
    left = np.empty(n_rep, np.int64)  # steps to the replica's next grid point (1..stride): no division a step
    for r in range(n_rep):
        n, zc, vc, zp, vp, zb, contact, th = PR.load(s[r], p)
        z_tip = zb + zc + zp
        fa = fa0
        if contact:
            x = z_tip - a0
            fts = -contact_force(x, xd[r], p, a) - fa_c
        else:
            x, fa = _surface_position(z_tip, xd[r], p, a, False)
            fts = -fa
        fa_r[r] = fa
        nn[r], zc_r[r], vc_r[r], zp_r[r], vp_r[r], zb_r[r], contact_r[r] = n, zc, vc, zp, vp, zb, contact
        cw_r[r], sw_r[r], x_r[r], fts_r[r] = math.cos(th), math.sin(th), x, fts
        left[r] = stride - (n - origin[r]) % stride
    n_buf = buf.shape[1]
    for j in range(z1.shape[1]):
        for r in range(n_rep):
            f1 = 0.0 + sig[r, 0] * z1[r, j]
            f2 = 0.0 + sig[r, 1] * z2[r, j]
            n, zc, vc, zp, vp, zb, contact = nn[r], zc_r[r], vc_r[r], zp_r[r], vp_r[r], zb_r[r], contact_r[r]
            cw, sw, x, fts, fa = cw_r[r], sw_r[r], x_r[r], fts_r[r], fa_r[r]
            xr = xd[r]
            # first half kick with the forces at the start of the step
            vc += hdt * (-k1 * zc - c1 * vc + f0 * cw + fts + f1) / m1
            vp += hdt * (-k2 * zp - c2 * vp + fts + f2) / m2
            zc += dt * vc
            zp += dt * vp
            cw, sw = cw * cr - sw * sr, sw * cr + cw * sr
            n += 1
            z_tip = zb + zc + zp
            x_last = x
            if not contact:  # the fine kernel's rule, as in brownian_steps
                d = z_tip - x
                if d > a0:
                    fa = vdw_force(d, fa, hr6, ihr6)
                    for i in range(n_arms):
                        acc = g[i] * fa
                        for k in range(n_arms):
                            acc += emi[i, k] * xr[k]
                        tmp[r, i] = acc
                    xs = 0.0
                    for i in range(n_arms):
                        xr[i] += tmp[r, i]
                        xs += k_arm[i] * xr[i]
                    x = (xs + fa) * invkg if vdw else xs * invkg
                    fts = -fa
                else:
                    contact = True
            if contact:
                x = z_tip - a0
                for i in range(n_arms):
                    xr[i] += omer[i] * (x - xr[i]) - lin[i] * (x - x_last)
                f_sls = kinf * x
                for i in range(n_arms):
                    f_sls += k_arm[i] * (x - xr[i])
                if f_sls > sep_thr:
                    contact = False
                    xs = 0.0
                    for i in range(n_arms):
                        xs += k_arm[i] * xr[i]
                    x = (xs + fa_sep) * invkg
                    fts = -fa0
                    fa = fa0
                else:
                    fts = -f_sls - fa_c
            # second half kick, damping implicit
            vc = (vc + hdt * (-k1 * zc + f0 * cw + fts + f1) / m1) / den1
            vp = (vp + hdt * (-k2 * zp + fts + f2) / m2) / den2
            left[r] -= 1
            if left[r] == 0:  # (n - origin) a multiple of stride
                left[r] = stride
                ps = pos[r]
                if 0 <= ps < n_buf:
                    buf[r, ps, 0] = n * dt
                    buf[r, ps, 1] = z_tip
                    buf[r, ps, 2] = zc
                    buf[r, ps, 3] = zp
                    buf[r, ps, 4] = zb
                    buf[r, ps, 5] = fts
                    buf[r, ps, 6] = x
                    for i in range(n_arms):
                        buf[r, ps, 7 + i] = xr[i]
                    pos[r] = ps + 1
            nn[r], zc_r[r], vc_r[r], zp_r[r], vp_r[r], contact_r[r] = n, zc, vc, zp, vp, contact
            cw_r[r], sw_r[r], x_r[r], fts_r[r], fa_r[r] = cw, sw, x, fts, fa
    for r in range(n_rep):
        s[r, S_ZC], s[r, S_VC], s[r, S_ZP], s[r, S_VP] = zc_r[r], vc_r[r], zp_r[r], vp_r[r]
        s[r, S_IDX] = nn[r]
        s[r, S_CONTACT] = 1.0 if contact_r[r] else 0.0
        for i in range(n_arms):
            s[r, S_XD + i] = xd[r, i]


@njit(cache=True)
def brownian_hybrid(s, rng, sig1, sig2, lc, p, a, emi, lad, lemi, lg, buf, stride, origin, pos, n_steps):
    """``n_steps`` fine steps' worth of time from the state ``s`` (updated in place) with the
    Brownian forces drawn from the generator ``rng`` (module docstring): fine Verlet steps with
    the forces ``0.0 + sig1 * e``, ``0.0 + sig2 * e`` [N] (``e`` standard normal, the cantilever's
    then the paddle's) in contact and within ``d_switch`` of the surface; farther out, from a
    point of the recording grid (``origin`` + multiples of ``stride``), one far step of the
    recording ladder ``lad[0]`` (one print step) where the noise-free far step accepts it (gap
    above ``d_switch`` at its end and its ends' tip heights: decided on the noise-free flow, so
    the decision does not select draws), with each mode's thermal increment ``lc[mode] @ (e1,
    e2)`` added to its end state.  Samples as :func:`brownian_steps` writes them (``buf[pos]``
    on the grid; ``pos`` < 0 or beyond the buffer: nothing).  Returns the next ``pos``."""
    n_arms = len(s) - S_XD
    dt = p[P_DT]
    hdt = 0.5 * dt
    m1, m2, k1, k2, c1, c2 = p[P_M1], p[P_M2], p[P_K1], p[P_K2], p[P_C1], p[P_C2]
    f0 = p[P_F0]
    a0, fa0, fa_c, sep_thr, fa_sep, invkg = p[P_A0], p[P_FA0], p[P_FAC], p[P_SEPTHR], p[P_FASEP], p[P_INVKG]
    kinf = p[P_KINF]
    hr6, ihr6, vdw = p[P_HR6], p[P_IHR6], p[P_VDW] > 0.0
    cr, sr = p[P_COSDT], p[P_SINDT]
    dsw = p[P_DSW]
    den1 = 1.0 + hdt * c1 / m1
    den2 = 1.0 + hdt * c2 / m2
    k_arm = a[A_K]
    omer = a[A_OMER]
    lin = a[A_LIN]
    g = a[A_G]
    f = PR.far_constants(p)
    far = lad.shape[0] > 0
    h_far = lad[0, L_H] if far else 0.0
    hh = 0.5 * h_far
    n_far = int(lad[0, L_N]) if far else 0
    o = np.zeros(64)  # far_accept reads no output in recording mode
    xd = s[S_XD:].copy()
    tmp = np.empty(n_arms)
    xd_new = np.empty(n_arms)
    n, zc, vc, zp, vp, zb, contact, th = PR.load(s, p)
    cw, sw = math.cos(th), math.sin(th)
    z_tip = zb + zc + zp
    fa = fa0
    if contact:
        x = z_tip - a0
        fts = -contact_force(x, xd, p, a) - fa_c
    else:
        x, fa = _surface_position(z_tip, xd, p, a, False)
        fts = -fa
    n_buf = buf.shape[0]
    n_end = n + n_steps
    while n < n_end:
        if far and not contact and (n - origin) % stride == 0 and n + n_far <= n_end and z_tip - x > dsw:
            # the noise-free far step (tapping.far_steps in recording mode) decides
            vc1, vp1, zpart0, vpart0, cw1, sw1, zc1, vc2, zp1, vp2, zb1, z1 = PR.far_flow(
                f, lad, 0, hh, fa, zc, vc, zp, vp, zb, 0.0, cw, sw)
            xs = 0.0
            for i in range(n_arms):
                acc = lg[0, i] * fa
                for k in range(n_arms):
                    acc += lemi[0, i, k] * xd[k]
                xs += k_arm[i] * (xd[i] + acc)
            fa1 = fa
            x1 = (xs + (fa1 if vdw else 0.0)) * invkg
            fa1, x1 = end_attraction(z1, x1, fa1, xs, hr6, ihr6, invkg, vdw)
            d1 = z1 - x1
            ok, _qmn, _qmx = PR.far_accept(o, f, p, True, h_far, dsw, zc, zc1, zp, vc1, vp1, vc2, vp2, cw, sw, z_tip,
                                           zb, z1, zb1, x, x1, d1)  # fmt: skip
            if ok:
                # each free mode's thermal increment over the step (exact: the linear flow superposes it)
                e1 = rng.standard_normal()
                e2 = rng.standard_normal()
                e3 = rng.standard_normal()
                e4 = rng.standard_normal()
                zc1 += lc[0, 0, 0] * e1 + lc[0, 0, 1] * e2
                vc2 += lc[0, 1, 0] * e1 + lc[0, 1, 1] * e2
                zp1 += lc[1, 0, 0] * e3 + lc[1, 0, 1] * e4
                vp2 += lc[1, 1, 0] * e3 + lc[1, 1, 1] * e4
                z1 = zb1 + zc1 + zp1
                fa1, x1 = end_attraction(z1, x1, fa1, xs, hr6, ihr6, invkg, vdw)  # at the moved tip
                vc3, vp3 = PR.far_close(f, hh, fa1, vc2, vp2)
                fm = 0.5 * (fa + fa1)  # exact creep with the mean attraction of the step
                xs = 0.0
                for i in range(n_arms):
                    acc = lg[0, i] * fm
                    for k in range(n_arms):
                        acc += lemi[0, i, k] * xd[k]
                    xd_new[i] = xd[i] + acc
                    xs += k_arm[i] * xd_new[i]
                for i in range(n_arms):
                    xd[i] = xd_new[i]
                x = (xs + (fa1 if vdw else 0.0)) * invkg
                zc, vc, zp, vp, zb = zc1, vc3, zp1, vp3, zb1
                z_tip, fa, fts = z1, fa1, -fa1
                cw, sw = cw1, sw1
                n += n_far
                if 0 <= pos < n_buf:
                    buf[pos, 0] = n * dt
                    buf[pos, 1] = z_tip
                    buf[pos, 2] = zc
                    buf[pos, 3] = zp
                    buf[pos, 4] = zb
                    buf[pos, 5] = fts
                    buf[pos, 6] = x
                    for i in range(n_arms):
                        buf[pos, 7 + i] = xd[i]
                    pos += 1
                continue
        # fine steps to the next grid point (brownian_steps' step, its forces drawn here)
        m = stride - (n - origin) % stride
        if m > n_end - n:
            m = n_end - n
        for _j in range(m):
            f1 = 0.0 + sig1 * rng.standard_normal()
            f2 = 0.0 + sig2 * rng.standard_normal()
            vc += hdt * (-k1 * zc - c1 * vc + f0 * cw + fts + f1) / m1
            vp += hdt * (-k2 * zp - c2 * vp + fts + f2) / m2
            zc += dt * vc
            zp += dt * vp
            cw, sw = cw * cr - sw * sr, sw * cr + cw * sr
            n += 1
            z_tip = zb + zc + zp
            x_last = x
            if not contact:
                d = z_tip - x
                if d > a0:
                    fa = vdw_force(d, fa, hr6, ihr6)
                    for i in range(n_arms):
                        acc = g[i] * fa
                        for k in range(n_arms):
                            acc += emi[i, k] * xd[k]
                        tmp[i] = acc
                    xs = 0.0
                    for i in range(n_arms):
                        xd[i] += tmp[i]
                        xs += k_arm[i] * xd[i]
                    x = (xs + fa) * invkg if vdw else xs * invkg
                    fts = -fa
                else:
                    contact = True
            if contact:
                x = z_tip - a0
                for i in range(n_arms):
                    xd[i] += omer[i] * (x - xd[i]) - lin[i] * (x - x_last)
                f_sls = kinf * x
                for i in range(n_arms):
                    f_sls += k_arm[i] * (x - xd[i])
                if f_sls > sep_thr:
                    contact = False
                    xs = 0.0
                    for i in range(n_arms):
                        xs += k_arm[i] * xd[i]
                    x = (xs + fa_sep) * invkg
                    fts = -fa0
                    fa = fa0
                else:
                    fts = -f_sls - fa_c
            vc = (vc + hdt * (-k1 * zc + f0 * cw + fts + f1) / m1) / den1
            vp = (vp + hdt * (-k2 * zp + fts + f2) / m2) / den2
            if (n - origin) % stride == 0 and 0 <= pos < n_buf:
                buf[pos, 0] = n * dt
                buf[pos, 1] = z_tip
                buf[pos, 2] = zc
                buf[pos, 3] = zp
                buf[pos, 4] = zb
                buf[pos, 5] = fts
                buf[pos, 6] = x
                for i in range(n_arms):
                    buf[pos, 7 + i] = xd[i]
                pos += 1
    s[S_ZC], s[S_VC], s[S_ZP], s[S_VP] = zc, vc, zp, vp
    s[S_IDX] = n
    s[S_CONTACT] = 1.0 if contact else 0.0
    for i in range(n_arms):
        s[S_XD + i] = xd[i]
    return pos


@njit(cache=True)
def linear_flow(phi, w, x0):
    """``x_(j+1) = phi x_j + w_j`` for a two-component state (``w``: (n, 2)); returns the
    first components ``x_1 .. x_n`` (the exact sampled Ornstein-Uhlenbeck oscillator)."""
    n = w.shape[0]
    out = np.empty(n)
    z, v = x0[0], x0[1]
    for j in range(n):
        z, v = phi[0, 0] * z + phi[0, 1] * v + w[j, 0], phi[1, 0] * z + phi[1, 1] * v + w[j, 1]
        out[j] = z
    return out
