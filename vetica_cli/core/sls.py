"""Massless Zener Standard Linear Solid surface with van der Waals attraction.

Spring ``k_inf`` in parallel with a Maxwell arm (spring ``k0`` in series with
dashpot ``cd``).  ``X`` is the surface position, ``Xd`` the dashpot position,
both 0 when undeformed (thesis 3.2, figs. 22-24).  All SI.

Force balance of the massless surface::

    F_sls = k_inf X + k0 (X - Xd)              [N]  (force the surface exerts)
    cd Xd' = k0 (X - Xd)                            (dashpot, thesis eq. 51)

Non-contact, ``d = z_tip - X > a0`` (thesis eqs. 59-65, appendix C): the tip
pulls the surface with ``Fa(d) = H R / (6 d^2)`` (thesis eq. 3) when
``vdw_on_surface``; then ``X = (k0 Xd + Fa)/(k0 + k_inf)`` and ``Xd`` creeps
towards ``Fa/k_inf`` with the retardation time ``tau_c = cd (k0+k_inf)/(k0 k_inf)``.
``Fts = -Fa(d)``.

Contact (thesis eqs. 52-58): ``X = z_tip - a0``; ``Xd`` relaxes towards ``X``
with the relaxation time ``tau_r = cd/k0``; ``Fts = -F_sls`` (vdW on the
surface) or ``-F_sls - Fa(a0)`` (vdW only on the tip).  Separation when the
surface would have to hold the tip with more than the adhesion ``Fa(a0)``
(resp. when ``F_sls`` changes sign).  ``Fts`` is continuous at both transitions.

The dashpot is advanced with the exact exponential step
``Xd <- Xt + (Xd - Xt) exp(-dt/tau)``: it never overshoots its target, so the
thesis's clamp "the dashpot may not pass the surface" holds by construction,
and it is stable for any ``tau`` vs ``dt``.  ``decay = exp(-dt/tau)`` is passed
in precomputed.
"""

from numba import njit


@njit(cache=True, inline="always", fastmath={"contract"})
def noncontact_step(z_tip, x, xd, decay_c, hr6, a0, k0, inv_kg, inv_kinf, vdw_on_surface):
    """Advance the surface one step out of contact.

    ``x`` is the surface position of the previous step (the gap is evaluated
    with it: an explicit one-step lag of at most ~1e-13 m at dt = 0.025 ns).
    Returns ``(x, fts, xd, contact)``; when ``contact`` is True the caller must
    redo the step with :func:`contact_step` (``x, fts, xd`` are then unused).
    """
    d = z_tip - x
    if d <= a0:
        return x, 0.0, xd, True
    fa = hr6 / (d * d)
    if vdw_on_surface:
        xt = fa * inv_kinf
        xd = xt + (xd - xt) * decay_c
        x = (k0 * xd + fa) * inv_kg
    else:
        xd = xd * decay_c
        x = k0 * xd * inv_kg
    return x, -fa, xd, False


@njit(cache=True, inline="always", fastmath={"contract"})
def contact_step(z_tip, xd, decay_r, a0, k0, kg, sep_thr, fa0, inv_kg, vdw_on_surface):
    """Advance the surface one step in contact.

    Returns ``(x, fts, xd, contact, separated)``.  On separation the surface
    is released at the same instant and ``Fts = -Fa(a0)`` (continuous).
    """
    x = z_tip - a0
    xd = x + (xd - x) * decay_r
    f_sls = kg * x - k0 * xd
    if f_sls > sep_thr:
        # separation: surface released, held only by the adhesion (if vdW on it)
        if vdw_on_surface:
            x = (k0 * xd + fa0) * inv_kg
        else:
            x = k0 * xd * inv_kg
        return x, -fa0, xd, False, True
    if vdw_on_surface:
        return x, -f_sls, xd, True, False
    return x, -f_sls - fa0, xd, True, False
