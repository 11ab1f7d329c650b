"""A rigid sphere on a generalized-Maxwell half-space by the method of dimensionality
reduction (MDR; Popov & Hess 2015): the ``hertz`` surface's kernel.

The 3-D half-space becomes a row of ``M`` independent elements at lateral positions
``x_i``.  Every element is the massless node of the ``sls``/``wiechert``
surface with stiffnesses per unit length (the plane-strain moduli
``E* = E/(1 - nu^2)``) times its weight ``w_i`` (``2 dx``: both sides of ``x = 0``)::

    f_i = w_i [E_inf* u_i + sum_a E_a* (u_i - ud_ia)]      (force the element exerts) [N]
    eta_a* ud_ia' = E_a* (u_i - ud_ia),  eta_a* = E_a* tau_a

The sphere is the 1-D profile ``g(x) = x^2/R``; the tip's surface over element ``i`` is
``zs + g_i`` with ``zs = z_tip - a0``.  An element is in contact when ``zs + g_i`` is at or
below its free position ``u_free = sum_a E_a* ud_ia / Kg`` (``Kg = E_inf* + sum E_a*``);
then ``u_i = zs + g_i`` and its dashpots follow the imposed motion (the linear-target
exact step of :mod:`.coefficients`).  It leaves when its force would turn tensile
(``f_i > 0``; no adhesion per element).  Out of contact its force is zero and its
dashpots creep coupled through ``u_free`` (``C ud' = -A ud`` with ``C = diag(eta*)``,
``A = diag(E*) - E* E*^T/Kg``, symmetric): solved exactly in the modes of ``(A, C)``
(real, negative rates) -- lazily, only when the element is looked at again, so an
element far outside the contact costs nothing per step and its recovery between taps
is the exact closed form.  One element at ``x = 0`` with ``g = 0`` and ``w = 1`` is the
flat punch: the ``sls``/``wiechert`` node itself.

``Fts = -sum f_i - Fa(a0)`` while any element touches, ``-Fa(d)`` with
``d = z_tip - u_free,0`` (the apex over the centre element) otherwise: the van der
Waals pull acts on the tip only (DMT), ``Fa(d) = H R/(6 d^2)`` (thesis eq. 3).

State vector ``S`` (as :mod:`.tapping`): ``zc, vc, zp, vp, Zb, step index, contact flag,
ud`` with ``ud`` the ``M x N`` dashpot positions (element-major).  Which elements touch is
not stored: at a step boundary element ``i`` touches iff the flag is set and
``zs + g_i <= u_free,i``.

Outputs: the :mod:`.tapping` vector (``T.NO_BASE + 2 N``: per arm the mean stretch -- here
the largest over the elements -- and the dissipation, summed over the elements) followed
by ``M N`` per-element mean stretches ``int (u_i - ud_ia) dt`` (O_EL).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
from numba import njit

from . import probe as PR
from . import tapping as T
from .coefficients import (
    L_C00, L_C01, L_C10, L_C11, L_COS, L_H, L_N, L_P00, L_P01, L_P10, L_P11, L_SIN,
    P_A0, P_BV1, P_BV2, P_C1, P_C2, P_COSDT, P_CVD0, P_CVD1, P_CVF, P_CVV, P_CVZ, P_CZD, P_CZF,
    P_CZV, P_CZZ, P_DSW, P_DSW_EXIT, P_DT, P_EF, P_F0, P_FA0, P_HR6, P_IHR6, P_K1, P_K2, P_M1, P_M2,
    P_NT, P_OMEGA, P_PVF, P_PVV, P_PVZ, P_PZF, P_PZV, P_PZZ, P_RC0, P_RC1, P_RCV, P_RCZ, P_RHO, P_RPV,
    P_RPZ, P_SINDT, P_ZI, P_ZR, lin_lag,
)  # fmt: skip
from .tapping import (
    EPS_STEP, O_CSTEPS, O_D1, O_D2, O_DDASH, O_FAR, O_FINE, O_FMAX, O_FMIN, O_HC, O_HS, O_NCONT, O_NSEP,
    O_QMAX, O_QMIN, O_REJECT, O_T_FC, O_TCONT_LAST, O_TSEP_LAST, O_WDRIVE, O_WTS, O_XM, O_Z_FC, O_ZCONT,
    O_ZCONT_LAST, O_ZSEP_LAST, R_ACTIVE, R_FC, R_ORIGIN, R_STRIDE, S_CONTACT, S_IDX, S_VC, S_VP, S_XD, S_ZB,
    S_ZC, S_ZP, far_extrema, hermite_extrema, project_harmonic, store_sample, vdw_force,
)  # fmt: skip

# rows of the per-arm table ARM (N columns): modulus E_a* [Pa], E_a* er, 1 - er, phi - er, eta_a* [Pa s]
A_K, A_KER, A_OMER, A_LIN, A_ETA, NA = range(6)
# scalar surface vector Q
Q_KINF, Q_KG, Q_KC, NQ = range(4)


def element_grid(radius: float, x_max: float, m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``m`` elements at the midpoints of ``[0, x_max]`` (spacing ``dx = x_max/m``):
    positions ``x_i``, the sphere's 1-D profile ``g_i = x_i^2/R`` and weights ``2 dx``."""
    dx = x_max / m
    x = (np.arange(m) + 0.5) * dx
    return x, x * x / radius, np.full(m, 2.0 * dx)


def hertz_force_grid(g: np.ndarray, w: np.ndarray, e_star: float, delta) -> np.ndarray:
    """Elastic MDR force of the grid at indentations ``delta`` [N]: ``E* sum w_i (delta - g_i)+``."""
    d = np.atleast_1d(np.asarray(delta, float))
    return e_star * np.sum(w[None, :] * np.clip(d[:, None] - g[None, :], 0.0, None), axis=1)


def grid_error(radius: float, g: np.ndarray, w: np.ndarray, lo: float, hi: float) -> float:
    """Largest relative error of the grid's elastic force against Hertz's ``4/3 E* sqrt(R) delta^1.5``
    for ``delta`` in ``[lo, hi]`` (independent of E*).  Between two elements' touch-down depths
    ``g_i`` the grid's force is linear in ``delta`` and Hertz's convex: the error's extremes are
    at the ``g_i`` and inside the intervals, so 801 depths and every ``g_i`` in the range are
    evaluated."""
    deltas = np.concatenate([np.linspace(lo, hi, 801), g[(g > lo) & (g < hi)]])
    exact = 4.0 / 3.0 * math.sqrt(radius) * deltas**1.5
    return float(np.max(np.abs(hertz_force_grid(g, w, 1.0, deltas) / exact - 1.0)))


def auto_elements(radius: float, delta_hi: float, rel: float = 1e-3, margin: float = 1.5,
                  delta_lo: float | None = None) -> tuple[int, float]:  # fmt: skip
    """``(M, x_max)`` for ``elements: auto``: the grid reaches ``margin`` times the contact
    radius ``sqrt(R delta_hi)``, and ``M`` is the smallest count whose elastic force is within
    ``rel`` of Hertz at every depth in ``[delta_lo, delta_hi]`` (default ``delta_lo = 0.9
    delta_hi``: the deepest tenth of the deepest tap; :func:`grid_error`)."""
    lo = 0.9 * delta_hi if delta_lo is None else delta_lo
    x_max = margin * math.sqrt(radius * delta_hi)
    for m in range(4, 4000):
        _, g, w = element_grid(radius, x_max, m)
        if grid_error(radius, g, w, lo, delta_hi) <= rel:
            return m, x_max
    raise ValueError("no element count up to 4000 reaches the requested accuracy")


def surface_tables(e_inf_s: float, e_s, eta_s, h: float):
    """Tables of the element node at step ``h`` from the plane-strain moduli (per unit
    length) ``E_inf*``, ``E_a*`` [Pa] and ``eta_a* = E_a* tau_a`` [Pa s]:
    ``(Q, ARM, V, VI, LAM, UROW, SM)`` -- scalars, per-arm table, the free creep's modes
    ``ud = V c``, ``c = VI ud``, ``c_j' = LAM_j c_j``, ``u_free = UROW . c`` and the stretch
    ``u_free - ud_a = SM[a] . c``."""
    k = np.asarray(e_s, float)
    eta = np.asarray(eta_s, float)
    n = len(k)
    tau = eta / k
    kg = e_inf_s + float(k.sum())
    er = np.exp(-h / tau)
    lin = lin_lag(h / tau)
    arm = np.zeros((NA, n))
    arm[A_K] = k
    arm[A_KER] = k * er
    arm[A_OMER] = -np.expm1(-h / tau)
    arm[A_LIN] = lin
    arm[A_ETA] = eta
    q = np.zeros(NQ)
    q[Q_KINF], q[Q_KG] = e_inf_s, kg
    q[Q_KC] = e_inf_s + float(np.sum(k * (er + lin)))
    a_mat = np.diag(k) - np.outer(k, k) / kg  # C ud' = -A ud  (symmetric, positive definite)
    lam, vec = scipy.linalg.eigh(a_mat, np.diag(eta))
    lam = -lam  # rates of the modes (negative)
    vi = np.linalg.inv(vec)
    urow = (k @ vec) / kg
    sm = urow[None, :] - vec
    return q, arm, np.ascontiguousarray(vec), np.ascontiguousarray(vi), lam, urow, np.ascontiguousarray(sm)


@njit(cache=True, inline="always")
def free_advance(ud, i, h, w_i, arm, vec, vi, lam, sm, o, energy, el_off, c):
    """Element ``i`` out of contact over ``h`` [s], exactly: ``ud_i <- V exp(LAM h) VI ud_i``.
    With ``energy``: the per-arm dashpot dissipation ``w_i eta_a int ud_a'^2`` and the
    element's stretch integrals ``int (u - ud_a) dt`` in closed form."""
    n = ud.shape[1]
    if h <= 0.0:
        return
    for j in range(n):
        acc = 0.0
        for a in range(n):
            acc += vi[j, a] * ud[i, a]
        c[j] = acc
    if energy:
        for a in range(n):
            st = 0.0
            for j in range(n):
                st += sm[a, j] * c[j] * (math.expm1(lam[j] * h) / lam[j])
            o[el_off + i * n + a] += st
            dis = 0.0
            for j in range(n):
                for m in range(n):
                    s2 = lam[j] + lam[m]
                    dis += vec[a, j] * lam[j] * c[j] * vec[a, m] * lam[m] * c[m] * (math.expm1(s2 * h) / s2)
            dis *= w_i * arm[A_ETA, a]
            o[O_DDASH] += dis
            o[O_XM + n + a] += dis
    for j in range(n):
        c[j] *= math.exp(lam[j] * h)
    for a in range(n):
        acc = 0.0
        for j in range(n):
            acc += vec[a, j] * c[j]
        ud[i, a] = acc


@njit(cache=True, inline="always")
def _u_free(ud, i, arm, kg):
    s = 0.0
    for a in range(ud.shape[1]):
        s += arm[A_K, a] * ud[i, a]
    return s / kg


@njit(cache=True, inline="always")
def surface_step(zs, n, dt, ud, inc, ulast, tlast, hi_prev, g, w, q, arm, vec, vi, lam, sm, o, energy, el_off, tmp):
    """The elements at step ``n`` with the tip's surface at ``zs`` (= z_tip - a0) over the
    centre [m]: contact tests (against the free position after step ``n - 1``), imposed
    displacements, dashpot steps over step ``n``, releases (module docstring).  Elements beyond the geometric reach (``g_i > -zs``) that were not in
    contact are not touched (they catch up lazily).  Returns ``(sum of f_i [N], 1 + index
    of the outermost element in contact, 0 if none)``."""
    n_arms = ud.shape[1]
    m = len(g)
    dgeo = -zs
    kinf, kg, kc = q[Q_KINF], q[Q_KG], q[Q_KC]
    if n_arms == 1:
        return _surface_step_one_arm(zs, n, dt, ud, inc, ulast, tlast, hi_prev, g, w, arm, vec, vi, lam, sm, o, energy,
                                     el_off, tmp, kg, kc)  # fmt: skip
    fsum = 0.0
    hi = 0
    i = 0
    while i < m and (g[i] <= dgeo or i < hi_prev):
        ut = zs + g[i]
        if inc[i] == 0:
            if g[i] > dgeo:
                i += 1
                continue
            # the contact test against the element's position after the previous step (as the
            # sls kernel's gap), from which the contact step then starts
            if tlast[i] < n - 1:
                free_advance(ud, i, (n - 1 - tlast[i]) * dt, w[i], arm, vec, vi, lam, sm, o, energy, el_off, tmp)
                tlast[i] = n - 1
            uf = _u_free(ud, i, arm, kg)
            if ut > uf:
                i += 1
                continue
            inc[i] = 1
            ulast[i] = uf
        ul = ulast[i]
        f = kc * ut
        for a in range(n_arms):
            f -= arm[A_KER, a] * ud[i, a] + arm[A_K, a] * arm[A_LIN, a] * ul
        for a in range(n_arms):
            old = ud[i, a]
            new = old + arm[A_OMER, a] * (ut - old) - arm[A_LIN, a] * (ut - ul)
            ud[i, a] = new
            if energy:
                dd = w[i] * arm[A_K, a] * (0.5 * (ut + ul) - 0.5 * (new + old)) * (new - old)
                o[O_DDASH] += dd
                o[O_XM + n_arms + a] += dd
                o[el_off + i * n_arms + a] += (ut - new) * dt
        ulast[i] = ut
        tlast[i] = n
        if f > 0.0:
            inc[i] = 0
        else:
            fsum += w[i] * f
            hi = i + 1
        i += 1
    _ = kinf
    return fsum, hi


@njit(cache=True, inline="always")
def _surface_step_one_arm(zs, n, dt, ud, inc, ulast, tlast, hi_prev, g, w, arm, vec, vi, lam, sm, o, energy, el_off, tmp,
                          kg, kc):  # fmt: skip
    """:func:`surface_step` for one arm (the SLS's sphere): the same updates, the arm's constants held
    in registers and the dissipation summed over the elements before it is added to the outputs
    (each output written in the loop made the compiled loop reload every constant after it)."""
    m = len(g)
    dgeo = -zs
    k, ker, omer, lin = arm[A_K, 0], arm[A_KER, 0], arm[A_OMER, 0], arm[A_LIN, 0]
    klin = k * lin
    one_ok = False
    e1 = q1 = q2 = 0.0
    fsum = 0.0
    diss = 0.0
    hi = 0
    i = 0
    while i < m and (g[i] <= dgeo or i < hi_prev):
        gi = g[i]
        ut = zs + gi
        if inc[i] == 0:
            if gi > dgeo:
                i += 1
                continue
            if tlast[i] == n - 2:  # one step out of contact since it was looked at: the exact step, its factors once
                if not one_ok:
                    e1 = math.exp(lam[0] * dt)
                    q1 = math.expm1(lam[0] * dt) / lam[0]
                    s2 = lam[0] + lam[0]
                    q2 = math.expm1(s2 * dt) / s2
                    one_ok = True
                c0 = vi[0, 0] * ud[i, 0]
                if energy:
                    o[el_off + i] += sm[0, 0] * c0 * q1
                    dis = vec[0, 0] * lam[0] * c0 * vec[0, 0] * lam[0] * c0 * q2
                    dis *= w[i] * arm[A_ETA, 0]
                    o[O_DDASH] += dis
                    o[O_XM + 1] += dis
                ud[i, 0] = vec[0, 0] * (c0 * e1)
                tlast[i] = n - 1
            elif tlast[i] < n - 1:
                free_advance(ud, i, (n - 1 - tlast[i]) * dt, w[i], arm, vec, vi, lam, sm, o, energy, el_off, tmp)
                tlast[i] = n - 1
            uf = k * ud[i, 0] / kg
            if ut > uf:
                i += 1
                continue
            inc[i] = 1
            ulast[i] = uf
        ul = ulast[i]
        old = ud[i, 0]
        f = kc * ut - (ker * old + klin * ul)
        new = old + omer * (ut - old) - lin * (ut - ul)
        ud[i, 0] = new
        wi = w[i]
        if energy:
            diss += wi * k * (0.5 * (ut + ul) - 0.5 * (new + old)) * (new - old)
            o[el_off + i] += (ut - new) * dt
        ulast[i] = ut
        tlast[i] = n
        if f > 0.0:
            inc[i] = 0
        else:
            fsum += wi * f
            hi = i + 1
        i += 1
    if energy:
        o[O_DDASH] += diss
        o[O_XM + 1] += diss
    return fsum, hi


@njit(cache=True)
def _catch_up(ud, inc, tlast, n, dt, w, arm, vec, vi, lam, sm, o, energy, el_off, tmp):
    """Every element out of contact advanced (exactly) to step ``n``."""
    for i in range(ud.shape[0]):
        if inc[i] == 0 and tlast[i] < n:
            free_advance(ud, i, (n - tlast[i]) * dt, w[i], arm, vec, vi, lam, sm, o, energy, el_off, tmp)
            tlast[i] = n


@njit(cache=True)
def _contacts_at(s, ud, g, arm, kg, a0):
    """Which elements touch at the state ``s`` (module docstring), their imposed positions."""
    m = ud.shape[0]
    inc = np.zeros(m, np.int64)
    ulast = np.zeros(m)
    hi = 0
    if s[S_CONTACT] > 0.5:
        zs = s[S_ZB] + s[S_ZC] + s[S_ZP] - a0
        for i in range(m):
            if g[i] > -zs:
                break
            if zs + g[i] <= _u_free(ud, i, arm, kg):
                inc[i] = 1
                ulast[i] = zs + g[i]
                hi = i + 1
    return inc, ulast, hi


@njit(cache=True, fastmath={"contract"}, error_model="numpy")
def fine_steps(s, n_end, zb_step, p, g, w, xpos, q, arm, vec, vi, lam, sm, urow, buf, r, o, energy, far_ok, el_off):
    """Fine Verlet steps (the probe map of :func:`.tapping.fine_steps`) with the MDR surface,
    until ``n_end`` or, when ``far_ok``, until the tip is out of contact beyond the exit gap
    at a recording-grid point."""
    n_arms = arm.shape[1]
    m_el = len(g)
    ud = s[S_XD:].reshape((m_el, n_arms))  # a view: the state is updated in place
    dt = p[P_DT]
    c = PR.fine_map(p)
    ef = p[P_EF]
    hr6, ihr6, a0 = p[P_HR6], p[P_IHR6], p[P_A0]
    fa0 = p[P_FA0]
    d_exit = p[P_DSW_EXIT]
    kg = q[Q_KG]
    rec = np.empty(n_arms + 1)
    tmp = np.empty(n_arms)
    # out of contact the centre element's free position (the attraction's gap) comes from its
    # modal coordinates advanced by exp(LAM dt) a step; the element itself is left to catch up
    # exactly when it is next looked at
    e1 = np.exp(lam * dt)
    cx = np.zeros(n_arms)
    cx_ok = False

    n, zc, vc, zp, vp, zb, _, th = PR.load(s, p)
    cw, sw = math.cos(th), math.sin(th)
    inc, ulast, hi = _contacts_at(s, ud, g, arm, kg, a0)
    tlast = np.full(m_el, n, np.int64)
    contact = hi > 0
    z_tip = zb + zc + zp
    if contact:
        fsum = 0.0
        for i in range(hi):
            if inc[i]:
                uf = zs_u = z_tip - a0 + g[i]
                f = q[Q_KINF] * zs_u
                for a in range(n_arms):
                    f += arm[A_K, a] * (uf - ud[i, a])
                fsum += w[i] * f
        fts = -fsum - fa0
        fa = fa0
        x = z_tip - a0 + g[0]
    else:
        x = _u_free(ud, 0, arm, kg)
        fa = hr6 / ((z_tip + g[0] - x) * (z_tip + g[0] - x))
        fts = -fa
    vcp, vpp, u1 = PR.fine_start(c, zc, vc, zp, vp, cw, fts)
    ztip_old, q_old, hc, hs, stride, to_grid, qmax, qmin, fmax, fmin = PR.fine_begin(o, r, n, z_tip, zb)
    steps = 0
    while n < n_end:
        fts_old, vcp_old, vpp_old, cw_old, sw_old = fts, vcp, vpp, cw, sw
        zc, vcp, zp, vpp, u1, base, zb, cw, sw = PR.fine_step(c, zc, vcp, zp, vpp, u1, cw, sw, zb, zb_step, fts)
        n += 1
        steps += 1
        z_tip = base + ef * fts_old
        zs = z_tip - a0
        was = contact
        if hi > 0 or g[0] <= -zs:  # an element within reach (else none can touch: skip the loop)
            fsum, hi = surface_step(zs, n, dt, ud, inc, ulast, tlast, hi, g, w, q, arm, vec, vi, lam, sm, o, energy,
                                    el_off, tmp)  # fmt: skip
        else:
            fsum = 0.0
        contact = hi > 0
        if contact:
            fts = -fsum - fa0
            fa = fa0
            x = zs + g[0]  # the centre element, held by the tip
            cx_ok = False
            o[O_CSTEPS] += 1.0
            if not was:
                PR.first_contact(o, r, z_tip, n * dt)
        else:
            if was:
                PR.separation(o, z_tip, n * dt)
            # the gap between the tip's surface over the centre element and that element after the
            # previous step (as the sls kernel's gap; the contact test's own measure, so the
            # attraction is Fa(a0) exactly at contact and release), then the surface now
            d = z_tip + g[0] - x
            fa = vdw_force(d, fa, hr6, ihr6)
            fts = -fa
            if cx_ok:
                for j in range(n_arms):
                    cx[j] *= e1[j]
            else:
                for j in range(n_arms):
                    acc = 0.0
                    for a in range(n_arms):
                        acc += vi[j, a] * ud[0, a]
                    cx[j] = acc * math.exp(lam[j] * (n - tlast[0]) * dt)
                cx_ok = True
            x = 0.0
            for j in range(n_arms):
                x += urow[j] * cx[j]
        q_now = z_tip - zb
        hc, hs = PR.lock_in(c, hc, hs, q_old, q_now, cw_old, cw, sw_old, sw)
        q_old = q_now
        qmax, qmin, fmax, fmin = PR.extrema(q_now, fts, qmax, qmin, fmax, fmin)
        if energy:
            PR.fine_work(o, c, vcp_old, vpp_old, fts_old, vcp, vpp, fts, cw_old, cw, z_tip, ztip_old)
            ztip_old = z_tip
        to_grid, on_grid = PR.grid_tick(to_grid, stride)
        if r[R_ACTIVE] and on_grid:
            for a in range(n_arms):
                if contact or not cx_ok:
                    rec[a] = ud[0, a]
                else:
                    acc = 0.0
                    for j in range(n_arms):
                        acc += vec[a, j] * cx[j]
                    rec[a] = acc
            rec[n_arms] = xpos[hi - 1] if hi > 0 else 0.0
            store_sample(buf, r, n * dt, z_tip, zc, zp, zb, fts, x, rec)
        if far_ok and not contact and on_grid:
            if z_tip + g[0] - x > d_exit:
                break
    _catch_up(ud, inc, tlast, n, dt, w, arm, vec, vi, lam, sm, o, energy, el_off, tmp)
    PR.fine_save(s, o, c, zc, vcp, zp, vpp, zb, n, contact, fts, hc, hs, qmax, qmin, fmax, fmin, steps)
    _ = m_el


@njit(cache=True)
def _centre_modes(ud, vi):
    n = ud.shape[1]
    c = np.empty(n)
    for j in range(n):
        acc = 0.0
        for a in range(n):
            acc += vi[j, a] * ud[0, a]
        c[j] = acc
    return c


@njit(cache=True, inline="always")
def _centre_u(c, urow, lam, h):
    u = 0.0
    for j in range(len(c)):
        u += urow[j] * c[j] * math.exp(lam[j] * h)
    return u


@njit(cache=True, fastmath={"contract"}, error_model="numpy")
def _far(s, n_end, zb_step, p, g, w, xpos, q, arm, vec, vi, lam, sm, urow, lad, buf, r, o, energy, rec_mode, el_off):
    """:func:`.tapping.far_steps` with the MDR surface: every element is free, so nothing of the
    surface is stepped (the elements catch up exactly at the end); the gap is to the
    centre element's free position, known in closed form at any time."""
    n_arms = arm.shape[1]
    m_el = len(g)
    ud = s[S_XD:].reshape((m_el, n_arms))
    f = PR.far_constants(p)
    hr6, dsw, dt = p[P_HR6], p[P_DSW], p[P_DT]
    ihr6 = p[P_IHR6]
    rec = np.empty(n_arms + 1)
    tmp = np.empty(n_arms)
    n0, zc, vc, zp, vp, zb, _, th = PR.load(s, p)
    c0 = _centre_modes(ud, vi)
    n = n0
    z_tip = zb + zc + zp
    g0 = g[0]
    x = _centre_u(c0, urow, lam, 0.0) - g0  # the centre element's surface less g0: the gap is z_tip - x
    fa = hr6 / ((z_tip - x) * (z_tip - x))
    cw, sw = math.cos(th), math.sin(th)
    stride = r[R_STRIDE]
    origin = r[R_ORIGIN]
    moved = True
    while n < n_end:
        lev = PR.far_level(lad, EPS_STEP, vc, vp, z_tip - x, n, n_end)
        if lev < 0:
            break
        accepted = False
        while lev >= 0:
            h = lad[lev, L_H]
            hh = 0.5 * h
            vc1, vp1, zpart0, vpart0, cw1, sw1, zc1, vc2, zp1, vp2, zb1, z1 = PR.far_flow(
                f, lad, lev, hh, fa, zc, vc, zp, vp, zb, zb_step, cw, sw)
            x1 = _centre_u(c0, urow, lam, (n + int(lad[lev, L_N]) - n0) * dt) - g0
            d1 = z1 - x1
            fa1 = vdw_force(d1, fa, hr6, ihr6) if d1 > 0.0 else fa
            vc3, vp3 = PR.far_close(f, hh, fa1, vc2, vp2)
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
        PR.far_harmonic(o, f, rec_mode, lad, lev, hh, h, z_tip, zb, z1, zb1, zc, zpart0, vc1, vpart0, zp, vp1, cw, sw,
                        cw1, sw1)  # fmt: skip
        PR.far_bounds(o, qmn, qmx, fa1)
        if energy:
            PR.far_work(o, f, hh, fa, fa1, hr6, z_tip, x, z1, x1, cw, cw1, vc, vp, vc3, vp3)
        zc, vc, zp, vp, zb = zc1, vc3, zp1, vp3, zb1
        z_tip, x, fa = z1, x1, fa1
        cw, sw = cw1, sw1
        n += int(lad[lev, L_N])
        o[O_FAR] += 1.0
        if r[R_ACTIVE] and (n - origin) % stride == 0:
            hrel = (n - n0) * dt
            for a in range(n_arms):
                acc = 0.0
                for j in range(n_arms):
                    acc += vec[a, j] * c0[j] * math.exp(lam[j] * hrel)
                rec[a] = acc
            rec[n_arms] = 0.0
            store_sample(buf, r, n * dt, z_tip, zc, zp, zb, -fa, x + g0, rec)
            if rec_mode and not r[R_ACTIVE]:
                break
    # the elements (all free) catch up exactly
    for i in range(m_el):
        free_advance(ud, i, (n - n0) * dt, w[i], arm, vec, vi, lam, sm, o, energy, el_off, tmp)
    PR.far_save(s, zc, vc, zp, vp, zb, n)
    return moved


@njit(cache=True)
def _gap(s, ud, arm, kg, a0, g):
    """Gap of the apex to the centre element's free position (the contact flag off)."""
    z_tip = s[S_ZB] + s[S_ZC] + s[S_ZP]
    return z_tip + g[0] - _u_free(ud, 0, arm, kg)


@njit(cache=True)
def advance(s, n_steps, zb_step, p, g, w, xpos, q, arm, vec, vi, lam, sm, urow, lad, lad_rec, buf, r, energy, o, el_off):
    """:func:`.tapping.advance` for the MDR surface (same recorder, outputs and hybrid logic)."""
    n_arms = arm.shape[1]
    m_el = len(g)
    n_end = int(s[S_IDX]) + n_steps
    hybrid = lad.shape[0] > 0
    while int(s[S_IDX]) < n_end:
        recording = r[R_ACTIVE] == 1
        use_far = hybrid and s[S_CONTACT] < 0.5
        if use_far and recording:
            use_far = lad_rec.shape[0] > 0 and (int(s[S_IDX]) - r[R_ORIGIN]) % r[R_STRIDE] == 0
        if use_far:
            ud = s[S_XD:].reshape((m_el, n_arms))
            use_far = _gap(s, ud, arm, q[Q_KG], p[P_A0], g) > p[P_DSW]
        if use_far:
            if recording:
                moved = _far(s, n_end, zb_step, p, g, w, xpos, q, arm, vec, vi, lam, sm, urow, lad_rec, buf, r, o,
                             energy, True, el_off)  # fmt: skip
            else:
                moved = _far(s, n_end, zb_step, p, g, w, xpos, q, arm, vec, vi, lam, sm, urow, lad, buf, r, o,
                             energy, False, el_off)  # fmt: skip
            if int(s[S_IDX]) >= n_end:
                break
            if moved and recording and r[R_ACTIVE] == 0:
                continue
        far_ok = hybrid and (lad_rec.shape[0] > 0 or r[R_ACTIVE] == 0)
        fine_steps(s, n_end, zb_step, p, g, w, xpos, q, arm, vec, vi, lam, sm, urow, buf, r, o, energy, far_ok, el_off)


@njit(cache=True)
def prescribed(zs, dt, ud, g, w, q, arm, vec, vi, lam, sm, o, energy, el_off):
    """The elements under a prescribed tip motion: ``zs[n]`` = the tip's surface over the
    centre (``z_tip - a0``) at step ``n`` (``n = 0`` the start; the dashpots ``ud``
    (M, N) are the state there, updated in place).  Returns the force the elements
    exert on the tip, ``-sum f_i`` [N] (positive = repulsive), and the index + 1 of the
    outermost element in contact, at every step (0 at ``n = 0``)."""
    m_el = ud.shape[0]
    inc = np.zeros(m_el, np.int64)
    ulast = np.zeros(m_el)
    tlast = np.zeros(m_el, np.int64)
    f_out = np.zeros(len(zs))
    hi_out = np.zeros(len(zs), np.int64)
    tmp = np.empty(ud.shape[1])
    hi = 0
    for n in range(1, len(zs)):
        fsum, hi = surface_step(zs[n], n, dt, ud, inc, ulast, tlast, hi, g, w, q, arm, vec, vi, lam, sm, o, energy,
                                el_off, tmp)  # fmt: skip
        f_out[n] = -fsum
        hi_out[n] = hi
    _catch_up(ud, inc, tlast, len(zs) - 1, dt, w, arm, vec, vi, lam, sm, o, energy, el_off, tmp)
    return f_out, hi_out


@njit(cache=True)
def prescribed_centre(zs, dt, ud, g, w, q, arm, vec, vi, lam, sm, urow, o):
    """:func:`prescribed` (no energy bookkeeping) that also returns the centre element's position
    at every step (imposed in contact, free out of it): the gap of the attraction is
    ``z_tip - s0 - u_centre``.  Returns ``(force, 1 + outermost element in contact, u_centre)``."""
    m_el, n_arms = ud.shape
    el_off = T.NO_BASE + 2 * n_arms
    inc = np.zeros(m_el, np.int64)
    ulast = np.zeros(m_el)
    tlast = np.zeros(m_el, np.int64)
    f_out = np.zeros(len(zs))
    hi_out = np.zeros(len(zs), np.int64)
    uc = np.zeros(len(zs))
    tmp = np.empty(n_arms)
    kg = q[Q_KG]
    uc[0] = _u_free(ud, 0, arm, kg)
    hi = 0
    for n in range(1, len(zs)):
        if hi > 0 or g[0] <= -zs[n]:
            fsum, hi = surface_step(zs[n], n, dt, ud, inc, ulast, tlast, hi, g, w, q, arm, vec, vi, lam, sm, o, False,
                                    el_off, tmp)  # fmt: skip
        else:
            fsum = 0.0
        f_out[n] = -fsum
        hi_out[n] = hi
        if inc[0]:
            uc[n] = zs[n] + g[0]
        else:
            if tlast[0] < n:
                free_advance(ud, 0, (n - tlast[0]) * dt, w[0], arm, vec, vi, lam, sm, o, False, el_off, tmp)
                tlast[0] = n
            uc[n] = _u_free(ud, 0, arm, kg)
    _catch_up(ud, inc, tlast, len(zs) - 1, dt, w, arm, vec, vi, lam, sm, o, False, el_off, tmp)
    _ = urow
    return f_out, hi_out, uc


# ----------------------------------------------------------------------------- Python side


def n_outputs(m_el: int, n_arms: int) -> int:
    """Length of an output vector of the MDR kernel (module docstring)."""
    return T.NO_BASE + 2 * n_arms + m_el * n_arms


def new_outputs(m_el: int, n_arms: int) -> np.ndarray:
    o = np.zeros(n_outputs(m_el, n_arms))
    base = T.new_outputs(n_arms)
    o[: len(base)] = base
    return o


def run_prescribed(x, g, w, e_inf_s, e_s, eta_s, zs, dt, ud0=None, energy=True):
    """The MDR surface under the prescribed tip-surface positions ``zs`` (``z_tip - a0``,
    one per step of ``dt``; ``zs[0]`` the start, with dashpots ``ud0`` (M, N), default
    undeformed).  Returns ``(force [N] (repulsive > 0), contact radius [m], outputs, ud)``."""
    q, arm, vec, vi, lam, urow, sm = surface_tables(e_inf_s, e_s, eta_s, dt)
    m_el, n_arms = len(g), arm.shape[1]
    ud = np.zeros((m_el, n_arms)) if ud0 is None else np.array(ud0, float).reshape(m_el, n_arms)
    o = new_outputs(m_el, n_arms)
    f, hi = prescribed(np.asarray(zs, float), dt, ud, np.asarray(g, float), np.asarray(w, float), q, arm, vec, vi,
                       lam, sm, o, energy, T.NO_BASE + 2 * n_arms)  # fmt: skip
    x = np.asarray(x, float)
    radius = np.where(hi > 0, x[np.maximum(hi - 1, 0)], 0.0)
    return f, radius, o, ud


class MDRKernel:
    """The MDR kernel with its coefficients, in the interface of :class:`.engine.Kernel`
    (the engine's approach, orbit solver, proof and recording use it unchanged).

    ``setup`` is an :class:`.engine.KernelSetup` whose surface is the element node per
    unit length: ``k_inf = E_inf*``, ``k = E_a*`` [Pa], ``cd = eta_a* = E_a* tau_a`` [Pa s];
    ``x, g, w`` the element grid (:func:`element_grid`).  The state holds every element's
    dashpots (``n_state = M N``); the record holds the centre element's dashpots and the
    contact radius (``n_rec = N + 1``)."""

    def __init__(self, setup, x, g, w):
        from . import engine

        self.setup = setup
        self.x, self.g, self.w = (np.ascontiguousarray(v, dtype=float) for v in (x, g, w))
        self.m_el = len(self.g)
        p, _a, _emi, lad, _lemi, _lg, lad_rec, _lemi_r, _lg_r = setup.build()
        q, arm, vec, vi, lam, urow, sm = surface_tables(setup.k_inf, setup.k, setup.cd, setup.dt)
        p = p.copy()
        fa0 = setup.hr6 / setup.a0**2
        p[P_FA0] = fa0
        self.coef = (p, self.g, self.w, self.x, q, arm, vec, vi, lam, sm, urow, lad, lad_rec)
        self.n_arms = len(setup.k)
        self.n_state = self.m_el * self.n_arms
        self.n_rec = self.n_arms + 1
        self.state_tau = np.tile(np.asarray(setup.cd) / np.asarray(setup.k), self.m_el)
        self.el_off = T.NO_BASE + 2 * self.n_arms
        self.nt = setup.steps_per_period
        self.period_s = setup.steps_per_period * setup.dt
        self.periods = 0
        self._nobuf = engine.record_buffer(2, self.n_rec)

    def new_outputs(self) -> np.ndarray:
        return new_outputs(self.m_el, self.n_arms)

    def advance_raw(self, s, n_steps, zb_step, buf, rec, energy, o) -> None:
        p, g, w, x, q, arm, vec, vi, lam, sm, urow, lad, lad_rec = self.coef
        advance(s, n_steps, zb_step, p, g, w, x, q, arm, vec, vi, lam, sm, urow, lad, lad_rec, buf, rec, energy, o,
                self.el_off)  # fmt: skip

    def stretch(self, o) -> np.ndarray:
        """Per arm the element's mean-stretch integral of largest magnitude [m s] (the proof's
        claim: no element's dashpot carries a mean force)."""
        el = o[self.el_off : self.el_off + self.n_state].reshape(self.m_el, self.n_arms)
        idx = np.argmax(np.abs(el), axis=0)
        return el[idx, np.arange(self.n_arms)]

    def advance(self, s, n_steps=None, zb_step=0.0, buf=None, rec=None, energy=False):
        o = self.new_outputs()
        if rec is None:
            rec = T.new_recorder()
        self.advance_raw(s, self.nt if n_steps is None else n_steps, zb_step, self._nobuf if buf is None else buf,
                         rec, energy, o)  # fmt: skip
        self.periods += 1
        return o
