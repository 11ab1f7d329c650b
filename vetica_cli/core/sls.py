"""Massless Zener Standard Linear Solid surface with van der Waals attraction.

Spring ``k_inf`` in parallel with a Maxwell arm (spring ``k0`` in series with
dashpot ``cd``).  ``X`` is the surface position, ``Xd`` the dashpot position,
both 0 when undeformed (thesis 3.2, figs. 22-24).  All SI.

Force balance of the massless surface::

    F_sls = k_inf X + k0 (X - Xd)              [N]  (force the surface exerts)
    cd Xd' = k0 (X - Xd)                            (dashpot, thesis eq. 51)

Non-contact, gap ``d = z_tip - X > a0`` (thesis eqs. 59-65, appendix C): the
tip pulls the surface with ``Fa(d) = H R / (6 d^2)`` (thesis eq. 3) when
``vdw_on_surface``; then ``X = (k0 Xd + Fa)/(k0 + k_inf)`` and ``Xd`` creeps
towards ``Fa/k_inf`` with the retardation time
``tau_c = cd (k0 + k_inf)/(k0 k_inf)``; ``Fts = -Fa(d)``.  Without the surface
pull, ``X = k0 Xd/(k0 + k_inf)`` and ``Xd`` creeps towards 0.

Contact (thesis eqs. 52-58): ``X = z_tip - a0``; ``Xd`` relaxes towards ``X``
with the relaxation time ``tau_r = cd/k0``; ``Fts = -F_sls`` (vdW on the
surface) or ``-F_sls - Fa(a0)`` (vdW only on the tip).  Separation when the
surface would have to hold the tip with more than the adhesion ``Fa(a0)``
(resp. when ``F_sls`` changes sign).  ``Fts`` is continuous at both transitions.

The dashpot is advanced with the exact exponential step
``Xd <- Xt + (Xd - Xt) exp(-dt/tau)`` for a target ``Xt`` held over the step:
it never overshoots, so the thesis's clamp "the dashpot may not pass the
surface" holds by construction, and it is stable for any ``tau`` against
``dt``.  Under a constant load or a constant indentation the discrete updates
below reproduce the closed-form creep and relaxation exactly at ``t = n dt``.

The coefficients are folded so that each update is one or two fused
multiply-adds (the kernel's critical path):

    non-contact: X_n = alpha Xd_{n-1} + beta Fa_n,   Xd_n = gamma Fa_n + ec Xd_{n-1}
    contact:     F_sls,n = kc X_n - k0er Xd_{n-1},    Xd_n = (1 - er) X_n + er Xd_{n-1}
"""

import math

from numba import njit


@njit(cache=True)
def sls_coefficients(k_inf, k0, cd, dt, hr6, a0, vdw_on_surface):
    """Precomputed constants of the surface updates.

    Returns ``(ec, er, alpha, beta, gamma, kc, k0er, fa0, sep_thr, fa_sep, fa_c, inv_kg)``:
    ``ec = exp(-dt/tau_c)``, ``er = exp(-dt/tau_r)``; ``fa0 = Fa(a0)`` [N];
    ``sep_thr`` the F_sls at which the tip separates [N]; ``fa_sep`` the pull
    on a released surface [N]; ``fa_c`` the vdW force added to Fts in contact
    in the tip-only model [N].
    """
    kg = k0 + k_inf
    inv_kg = 1.0 / kg
    tau_c = cd * kg / (k0 * k_inf)  # retardation time [s]
    tau_r = cd / k0  # relaxation time [s]
    ec = math.exp(-dt / tau_c)
    er = math.exp(-dt / tau_r)
    alpha = k0 * inv_kg * ec
    gamma = (1.0 - ec) / k_inf if vdw_on_surface else 0.0
    beta = inv_kg * (1.0 + k0 * gamma) if vdw_on_surface else 0.0
    kc = kg - k0 * (1.0 - er)
    k0er = k0 * er
    fa0 = hr6 / (a0 * a0)
    sep_thr = fa0 if vdw_on_surface else 0.0
    fa_sep = fa0 if vdw_on_surface else 0.0
    fa_c = 0.0 if vdw_on_surface else fa0
    return ec, er, alpha, beta, gamma, kc, k0er, fa0, sep_thr, fa_sep, fa_c, inv_kg


NEWTON_TOL = 1e-4  # |guess error| above which vdw_force divides exactly


@njit(cache=True, inline="always", fastmath={"contract"}, error_model="numpy")
def vdw_force(d, fa_guess, hr6, ihr6):
    """Van der Waals attraction ``Fa(d) = H R / (6 d^2)`` [N] (thesis eq. 3).

    The gap changes by < 1e-3 relative per step, so one Newton step for the
    reciprocal from the previous step's force (``fa <- fa (2 - d^2 fa/(H R/6))``)
    is accurate to the square of the guess error: a relative error <= 1e-8 when
    the guess is within NEWTON_TOL; otherwise the exact division is taken.
    This keeps a ~14-cycle division off the kernel's critical path.
    ``ihr6 = 6/(H R)``.
    """
    dd = d * d
    tn = 2.0 - dd * (fa_guess * ihr6)
    fa = fa_guess * tn
    if abs(tn - 1.0) > NEWTON_TOL:
        fa = hr6 / dd
    return fa


@njit(cache=True, inline="always", fastmath={"contract"}, error_model="numpy")
def noncontact_update(d, xd, fa_guess, hr6, ihr6, alpha, beta, gamma, ec):
    """One step out of contact at gap ``d`` [m] (> a0).

    ``fa_guess`` is the previous step's attraction (see :func:`vdw_force`).
    Returns ``(fa, x, xd)``: the attraction ``Fa(d)`` [N] (``Fts = -fa``), the
    surface position and the dashpot position after the step.
    """
    fa = vdw_force(d, fa_guess, hr6, ihr6)
    x = alpha * xd + beta * fa
    xd = gamma * fa + ec * xd
    return fa, x, xd


@njit(cache=True, inline="always", fastmath={"contract"}, error_model="numpy")
def contact_update(x, xd, kc, k0er, er):
    """One step in contact with the surface at ``x`` [m] (= z_tip - a0).

    Returns ``(f_sls, xd)``: the force the surface exerts, ``k_inf X + k0 (X - Xd)``
    with ``Xd`` after the step [N], and the dashpot position after the step.
    """
    f_sls = kc * x - k0er * xd
    xd = (1.0 - er) * x + er * xd
    return f_sls, xd


@njit(cache=True, inline="always")
def released_position(xd, fa_sep, k0, inv_kg):
    """Surface position the instant the tip separates: ``(k0 Xd + Fa_sep)/Kg``."""
    return (k0 * xd + fa_sep) * inv_kg
