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
surface, the rule before, snapped 45 pm lower at Kg = 10 N/m); in contact
``X = z_tip - a0`` and each arm relaxes exactly towards the linearly moving
target; contact when the gap reaches ``a0``, separation when the surface would
have to hold the tip with more than the adhesion -- the rules of the SLS and Wiechert models.

Only for the recorded periods of a run at ``numerics.temperature > 0``: one
period costs ``steps_per_period`` fine steps (no far-field propagation, whose
exact flow has no room for a random force).
"""

import math

import numpy as np
from numba import njit

from .coefficients import (
    A_G, A_K, A_LIN, A_OMER, P_A0, P_C1, P_C2, P_COSDT, P_DT, P_F0, P_FA0, P_FAC, P_FASEP, P_INVKG, P_K1,
    P_K2, P_KINF, P_M1, P_HR6, P_IHR6, P_VDW, P_M2, P_NT, P_OMEGA, P_SEPTHR, P_SINDT,
)  # fmt: skip
from . import probe as PR
from .probe import S_CONTACT, S_IDX, S_VC, S_VP, S_XD, S_ZB, S_ZC, S_ZP
from .sls import vdw_force
from .tapping import contact_force, surface_position


@njit(cache=True)
def brownian_steps(s, fb1, fb2, p, a, emi, buf, stride, origin, pos):
    """``len(fb1)`` Verlet steps from the state ``s`` (updated in place) with the
    Brownian forces ``fb1[j], fb2[j]`` [N] on the cantilever and the paddle during
    step ``j``.  A sample (``t, z_tip, zc, zp, zb, Fts, X, Xd_1..N``) is written to
    ``buf[pos]`` after every step whose global index is ``origin`` + a multiple of ``stride``
    (``pos`` < 0 or beyond the buffer: nothing written).  Returns the next ``pos``."""
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
        x, fa = surface_position(z_tip, xd, p, a, False)
        fts = -fa
    n_buf = buf.shape[0]
    for j in range(len(fb1)):
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
