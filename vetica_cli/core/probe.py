"""The probe's half of every contact kernel, once: compiled inline helpers that the flat-punch
kernel (:mod:`.tapping`), the MDR kernel (:mod:`.mdr`) and the Brownian recorder
(:mod:`.thermal`) call, so that each surface kernel holds only its surface.

Probe (thesis eqs. 13-16, decoupled THC point-mass model)::

    m1 zc'' = -k1 zc - c1 zc' + F0 cos(w t) + Fts        flexural cantilever  [N]
    m2 zp'' = -k2 zp - c2 zp' + Fts                       torsional paddle+tip [N]

* **fine step** (:func:`fine_step`) -- velocity Verlet at ``dt`` (thesis appendix B) with the
  damping implicit in the velocity half step, applied as the precomputed linear map of
  :mod:`.coefficients` (``P_CZZ`` ...): positions and pre-kick velocities ``vcp = vc - bv1
  Fts`` advance by one fused multiply-add per term, and ``u1`` carries the next step's tip
  position less the force's share (``z_tip = Zb + u1 + ef Fts``);
* **exact flow** (:func:`far_flow`) -- a far step of length ``h`` of the hybrid integrator:
  half kick ``h Fa/2``, both oscillators by their exact linear flow (the drive through its
  particular solution ``zr cos - zi sin``), then the closing half kick (:func:`far_close`);
* **controller and recorder bookkeeping** -- the drive phase at a step index, the lock-in of
  the first harmonic of ``q = z_tip - Zb`` (trapezoid), the extrema of ``q`` and ``Fts``, the
  energy integrals (drive work, both dampings, ``-int Fts dz_tip``), the first contact, the
  recording grid, and writing the probe back into the state vector.

Every helper is ``inline="always"``: numba compiles it into each caller, with the caller's
``fastmath={"contract"}``, so the numbers are those of the kernels that held these lines
before (bit for bit: tests/test_simulator.py's reference runs).  Not ``cache=True``: they are
cached inside their callers.
"""

import math

from numba import njit

from .coefficients import (
    L_C00, L_C01, L_C10, L_C11, L_COS, L_H, L_K1BI, L_K1BR, L_K1I, L_K1R, L_K2BI, L_K2BR, L_K2I, L_K2R, L_KPI, L_KPR,
    L_N, L_P00, L_P01, L_P10, L_P11, L_SIN,
    P_BV1, P_BV2, P_C1, P_C2, P_COSDT, P_CVD0, P_CVD1, P_CVF, P_CVV, P_CVZ, P_CZD, P_CZF, P_CZV, P_CZZ,
    P_DT, P_F0, P_K1, P_K2, P_M1, P_M2, P_NT, P_OMEGA, P_PVF, P_PVV, P_PVZ, P_PZF, P_PZV, P_PZZ, P_RC0,
    P_RC1, P_RCV, P_RCZ, P_RHO, P_RPV, P_RPZ, P_SINDT, P_ZI, P_ZR,
)  # fmt: skip

# ---- state vector (shared by every kernel; :mod:`.session` reads and writes it from above the core)
S_ZC, S_VC, S_ZP, S_VP, S_ZB, S_IDX, S_CONTACT, S_XD = range(8)

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

# ---- the fine map's coefficients, as :func:`fine_map` packs them (one tuple: registers in the loop)
(M_CZZ, M_CZV, M_CZF, M_CZD, M_CVZ, M_CVV, M_CVF, M_CVD0, M_CVD1, M_PZZ, M_PZV, M_PZF, M_PVZ, M_PVV, M_PVF,
 M_RCZ, M_RCV, M_RC0, M_RC1, M_RPZ, M_RPV, M_RHO, M_COS, M_SIN, M_BV1, M_BV2, M_HDT, M_F0, M_C1, M_C2) = range(30)  # fmt: skip


@njit(inline="always")
def fine_map(p):
    """The fine step's coefficients from the parameter vector ``p`` (:mod:`.coefficients`), one
    tuple indexed by ``M_*``: the linear map, the drive's rotation by ``w dt``, the velocity
    offsets ``bv1, bv2``, ``dt/2`` and the drive and damping constants of the energy integrals."""
    return (p[P_CZZ], p[P_CZV], p[P_CZF], p[P_CZD], p[P_CVZ], p[P_CVV], p[P_CVF], p[P_CVD0], p[P_CVD1],
            p[P_PZZ], p[P_PZV], p[P_PZF], p[P_PVZ], p[P_PVV], p[P_PVF], p[P_RCZ], p[P_RCV], p[P_RC0], p[P_RC1],
            p[P_RPZ], p[P_RPV], p[P_RHO], p[P_COSDT], p[P_SINDT], p[P_BV1], p[P_BV2], 0.5 * p[P_DT], p[P_F0],
            p[P_C1], p[P_C2])  # fmt: skip


@njit(inline="always")
def load(s, p):
    """The probe of state ``s`` at its step: ``(n, zc, vc, zp, vp, Zb, contact, th)`` with the
    drive's phase ``th = w (n mod nt) dt`` (the drive is periodic in ``nt`` steps; the caller takes
    its cosine and sine)."""
    n = int(s[S_IDX])
    th = p[P_OMEGA] * (n % int(p[P_NT])) * p[P_DT]
    return n, s[S_ZC], s[S_VC], s[S_ZP], s[S_VP], s[S_ZB], s[S_CONTACT] > 0.5, th


@njit(inline="always")
def fine_start(c, zc, vc, zp, vp, cw, fts):
    """The fine map's variables at a step: ``(vcp, vpp, u1)`` from the probe and the force ``fts``."""
    vcp = vc - c[M_BV1] * fts
    vpp = vp - c[M_BV2] * fts
    u1 = (c[M_CZZ] * zc + c[M_CZV] * vcp + c[M_CZD] * cw) + (c[M_PZZ] * zp + c[M_PZV] * vpp)
    return vcp, vpp, u1


@njit(inline="always")
def fine_begin(o, r, n, z_tip, zb):
    """The bookkeeping a call of fine steps carries: ``(z_tip before, q before, hc, hs, stride,
    steps to the next recording-grid point (1..stride), qmax, qmin, fmax, fmin)``."""
    stride = r[R_STRIDE]
    return (z_tip, z_tip - zb, o[O_HC], o[O_HS], stride, stride - (n - r[R_ORIGIN]) % stride, o[O_QMAX], o[O_QMIN],
            o[O_FMAX], o[O_FMIN])  # fmt: skip


@njit(inline="always")
def fine_step(c, zc, vcp, zp, vpp, u1, cw, sw, zb, zb_step, fts):
    """One fine step of the probe under the force ``fts`` of the step before: returns ``(zc, vcp,
    zp, vpp, u1, base, Zb, cos, sin)`` after it; the tip is at ``base + ef Fts`` with the new force."""
    cw_old = cw
    cw, sw = cw * c[M_COS] - sw * c[M_SIN], sw * c[M_COS] + cw * c[M_SIN]
    zb += zb_step
    u2 = (((c[M_RCZ] * zc + c[M_RCV] * vcp) + (c[M_RPZ] * zp + c[M_RPV] * vpp)) + (c[M_RC0] * cw_old + c[M_RC1] * cw)
          + c[M_RHO] * fts)  # fmt: skip
    zc, vcp = (
        (c[M_CZZ] * zc + c[M_CZV] * vcp) + (c[M_CZD] * cw_old + c[M_CZF] * fts),
        (c[M_CVZ] * zc + c[M_CVV] * vcp) + ((c[M_CVD0] * cw_old + c[M_CVD1] * cw) + c[M_CVF] * fts),
    )
    zp, vpp = (c[M_PZZ] * zp + c[M_PZV] * vpp) + c[M_PZF] * fts, (c[M_PVZ] * zp + c[M_PVV] * vpp) + c[M_PVF] * fts
    return zc, vcp, zp, vpp, u2, zb + u1, zb, cw, sw


@njit(inline="always")
def lock_in(c, hc, hs, q_old, q, cw_old, cw, sw_old, sw):
    """The first harmonic of ``q`` (lock-in): one trapezoid of ``q exp(-i w t)`` added to ``(hc, hs)``."""
    hc += c[M_HDT] * (q_old * cw_old + q * cw)
    hs -= c[M_HDT] * (q_old * sw_old + q * sw)
    return hc, hs


@njit(inline="always")
def extrema(q, fts, qmax, qmin, fmax, fmin):
    """The running extrema of the deflection ``q`` and the force ``fts``."""
    if q > qmax:
        qmax = q
    if q < qmin:
        qmin = q
    if fts > fmax:
        fmax = fts
    if fts < fmin:
        fmin = fts
    return qmax, qmin, fmax, fmin


@njit(inline="always")
def fine_work(o, c, vcp_old, vpp_old, fts_old, vcp, vpp, fts, cw_old, cw, z_tip, ztip_old):
    """The energy integrals over a fine step (trapezoid): the drive's work, both dampings and
    ``-int Fts dz_tip``, added to the outputs ``o``."""
    vc_old = vcp_old + c[M_BV1] * fts_old
    vp_old = vpp_old + c[M_BV2] * fts_old
    vc_new = vcp + c[M_BV1] * fts
    vp_new = vpp + c[M_BV2] * fts
    hdt = c[M_HDT]
    o[O_WDRIVE] += hdt * c[M_F0] * (cw_old * vc_old + cw * vc_new)
    o[O_D1] += hdt * c[M_C1] * (vc_old * vc_old + vc_new * vc_new)
    o[O_D2] += hdt * c[M_C2] * (vp_old * vp_old + vp_new * vp_new)
    o[O_WTS] -= 0.5 * (fts_old + fts) * (z_tip - ztip_old)


@njit(inline="always")
def first_contact(o, r, z_tip, t):
    """Count a contact at tip position ``z_tip`` [m], time ``t`` [s]; the first of the call and
    the first of the recorder (the approach's first contact, Z1) are kept."""
    o[O_NCONT] += 1.0
    o[O_ZCONT_LAST] = z_tip
    o[O_TCONT_LAST] = t
    if math.isnan(o[O_ZCONT]):
        o[O_ZCONT] = z_tip
    if r[R_FC] == 0:
        r[R_FC] = 1
        o[O_T_FC] = t
        o[O_Z_FC] = z_tip


@njit(inline="always")
def separation(o, z_tip, t):
    """Count a separation at tip position ``z_tip`` [m], time ``t`` [s]."""
    o[O_NSEP] += 1.0
    o[O_ZSEP_LAST] = z_tip
    o[O_TSEP_LAST] = t


@njit(inline="always")
def grid_tick(to_grid, stride):
    """One step towards the next recording-grid point: ``(steps left, on the grid now)``."""
    to_grid -= 1
    on_grid = to_grid <= 0
    if on_grid:
        to_grid = stride
    return to_grid, on_grid


@njit(inline="always")
def fine_save(s, o, c, zc, vcp, zp, vpp, zb, n, contact, fts, hc, hs, qmax, qmin, fmax, fmin, steps):
    """The probe back into the state ``s`` (velocities synchronised with the positions) and the
    call's lock-in, extrema and step count into the outputs ``o``."""
    o[O_QMAX], o[O_QMIN], o[O_FMAX], o[O_FMIN] = qmax, qmin, fmax, fmin
    o[O_HC], o[O_HS] = hc, hs
    o[O_FINE] += steps
    s[S_ZC] = zc
    s[S_VC] = vcp + c[M_BV1] * fts
    s[S_ZP] = zp
    s[S_VP] = vpp + c[M_BV2] * fts
    s[S_ZB] = zb
    s[S_IDX] = n
    s[S_CONTACT] = 1.0 if contact else 0.0


# ---------------------------------------------------------------------------- far steps (exact flow)


@njit(inline="always")
def osc(z0, v0, lam, wd, w02, s):
    """Exact free damped oscillator ``z'' = -w0^2 z + 2 lam z'`` from ``(z0, v0)``:
    ``(z, v, a)`` after ``s`` [s] (``lam = -c/2m``, ``wd`` the damped frequency)."""
    e = math.exp(lam * s)
    c = math.cos(wd * s)
    sn = math.sin(wd * s)
    b = (v0 - lam * z0) / wd
    z = e * (z0 * c + b * sn)
    v = e * (v0 * c + (lam * b - wd * z0) * sn)
    return z, v, -w02 * z + 2.0 * lam * v


@njit
def q_at(s, zc0, vc0, zp0, vp0, cw, sw, p):
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
    hz, hv, ha = osc(zc0 - zpart0, vc0 - vpart0, lam1, wd1, w01, s)
    pz, pv, pa = osc(zp0, vp0, lam2, wd2, w02, s)
    return hz + zpart + pz, hv + vpart + pv, ha - omega * omega * zpart + pa


@njit(inline="always")
def hermite_extrema(q0, v0, q1, v1, h):
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


@njit
def far_extrema(h, zc0, vc0, zp0, vp0, cw, sw, p, q0, q1):
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
    _, v_prev, _ = q_at(0.0, zc0, vc0, zp0, vp0, cw, sw, p)
    for j in range(1, m + 1):
        s_j = h * j / m
        q_j, v_j, _ = q_at(s_j, zc0, vc0, zp0, vp0, cw, sw, p)
        if j < m:
            qmin = min(qmin, q_j)
            qmax = max(qmax, q_j)
        if v_prev * v_j < 0.0:
            lo, hi = s_prev, s_j
            v_lo = v_prev
            s = 0.5 * (lo + hi)
            for _ in range(30):
                q, v, acc = q_at(s, zc0, vc0, zp0, vp0, cw, sw, p)
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
            q, _, _ = q_at(s, zc0, vc0, zp0, vp0, cw, sw, p)
            qmin = min(qmin, q)
            qmax = max(qmax, q)
        s_prev, v_prev = s_j, v_j
    return qmin, qmax


@njit(inline="always")
def project_harmonic(o, row, zc, dz, dv, zp, vp1, cw, sw, h, zdrive, lam1, wd1, lam2, wd2):
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


(F_M1, F_M2, F_C1, F_C2, F_F0, F_ZR, F_ZI, F_OMEGA, F_W2, F_CURV, F_LAM1, F_WD1, F_LAM2, F_WD2) = range(14)


@njit(inline="always")
def far_constants(p):
    """The far step's constants, one tuple indexed by ``F_*``: masses, dampings, drive, the
    drive's particular solution ``(zr, zi)``, the paddle's angular frequency, the cantilever's
    curvature bound ``w1^2`` and both modes' decay rates and damped frequencies."""
    m1, m2, c1, c2 = p[P_M1], p[P_M2], p[P_C1], p[P_C2]
    lam1 = -0.5 * c1 / m1
    lam2 = -0.5 * c2 / m2
    return (m1, m2, c1, c2, p[P_F0], p[P_ZR], p[P_ZI], p[P_OMEGA], math.sqrt(p[P_K2] / m2), p[P_K1] / m1, lam1,
            math.sqrt(p[P_K1] / m1 - lam1 * lam1), lam2, math.sqrt(p[P_K2] / m2 - lam2 * lam2))  # fmt: skip


@njit(inline="always")
def far_level(lad, eps, vc, vp, gap, n, n_end):
    """The longest ladder entry within ``eps * gap / |tip speed|`` and not past ``n_end``; -1 when
    even the shortest passes ``n_end``."""
    speed = abs(vc) + abs(vp) + 1e-30
    hmax = eps * gap / speed
    lev = lad.shape[0] - 1
    while lev > 0 and (lad[lev, L_H] > hmax or n + int(lad[lev, L_N]) > n_end):
        lev -= 1
    if n + int(lad[lev, L_N]) > n_end:
        return -1
    return lev


@njit(inline="always")
def far_flow(f, lad, lev, hh, fa, zc, vc, zp, vp, zb, zb_step, cw, sw):
    """The opening half kick ``hh Fa`` and the exact flow of both modes over the ladder entry
    ``lad[lev]`` (indexed in place: a row view would cost a reference count per step):
    ``(vc1, vp1, zpart0, vpart0, cos1, sin1, zc1, vc2, zp1, vp2, Zb1, z_tip1)``
    (``vc1, vp1`` after the kick, ``vc2, vp2`` before the closing one)."""
    zr, zi, omega = f[F_ZR], f[F_ZI], f[F_OMEGA]
    vc1 = vc - hh * fa / f[F_M1]
    vp1 = vp - hh * fa / f[F_M2]
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
    return vc1, vp1, zpart0, vpart0, cw1, sw1, zc1, vc2, zp1, vp2, zb1, zb1 + zc1 + zp1


@njit(inline="always")
def far_close(f, hh, fa1, vc2, vp2):
    """The closing half kick ``hh Fa1`` of a far step: ``(vc3, vp3)``."""
    return vc2 - hh * fa1 / f[F_M1], vp2 - hh * fa1 / f[F_M2]


@njit(inline="always")
def far_bounds(o, qmn, qmx, fa1):
    """An accepted far step's extrema of ``q`` and of ``Fts = -Fa`` into the outputs."""
    if qmx > o[O_QMAX]:
        o[O_QMAX] = qmx
    if qmn < o[O_QMIN]:
        o[O_QMIN] = qmn
    if -fa1 > o[O_FMAX]:
        o[O_FMAX] = -fa1
    if -fa1 < o[O_FMIN]:
        o[O_FMIN] = -fa1


@njit(inline="always")
def far_work(o, f, hh, fa, fa1, hr6, z_tip, x, z1, x1, cw, cw1, vc, vp, vc3, vp3):
    """An accepted far step's energy integrals: the drive's work and both dampings by the
    trapezoid, ``-int Fts dz_tip`` exact along the gap (the attraction's potential ``hr6 (1/d1 -
    1/d0)``) and by the trapezoid along the surface's small motion.  The trapezoid on ``dz_tip``
    alone erred by ``(1/12) Fts'' dz^3`` a step, which near the switch gap and over long recording
    steps summed to ~1e-3 eV a cycle: the whole E_diss of a frozen dashpot under the pull
    (scripts/hybrid_vs_verlet.py).  Called inside the caller's ``if energy`` (a branch inside the
    helper cost the recording window 15 %, measured with ``vetica bench``)."""
    o[O_WDRIVE] += hh * f[F_F0] * (cw * vc + cw1 * vc3)
    o[O_D1] += hh * f[F_C1] * (vc * vc + vc3 * vc3)
    o[O_D2] += hh * f[F_C2] * (vp * vp + vp3 * vp3)
    o[O_WTS] -= hr6 * (1.0 / (z1 - x1) - 1.0 / (z_tip - x)) + 0.5 * (-fa - fa1) * (x1 - x)


@njit(inline="always")
def far_save(s, zc, vc, zp, vp, zb, n):
    """The probe after far steps back into the state ``s`` (out of contact)."""
    s[S_ZC], s[S_VC], s[S_ZP], s[S_VP], s[S_ZB] = zc, vc, zp, vp, zb
    s[S_IDX] = n
    s[S_CONTACT] = 0.0


@njit(inline="always")
def far_accept(o, f, p, rec_mode, h, dsw, zc, zc1, zp, vc1, vp1, vc2, vp2, cw, sw, z_tip, zb, z1, zb1, x, x1, d1):
    """Whether a far step of length ``h`` keeps the gap above ``dsw`` -- at its end (``d1``) and at
    the lowest point of the tip inside it -- and ``(ok, qmin, qmax)`` of ``q = z_tip - Zb`` over it.
    The extrema are searched only where they could matter (bound: the paddle's ringing amplitude
    and the cantilever's curvature over the step); a recording step (``rec_mode``, one print step,
    far below the time the attraction takes to change) is bounded by its ends."""
    q0 = z_tip - zb
    q1 = z1 - zb1
    qmn, qmx = min(q0, q1), max(q0, q1)
    floor = dsw + max(x, x1) - min(zb, zb1)  # q below which the gap is below d_switch
    w2 = f[F_W2]
    ring = 0.0 if rec_mode else 2.0 * math.sqrt(zp * zp + (vp1 / w2) ** 2) + f[F_CURV] * (abs(zc) + abs(zc1)) * h * h / 8.0
    if not rec_mode and (qmx + ring >= o[O_QMAX] or qmn - ring <= o[O_QMIN] or qmn - ring <= floor):
        if h * w2 < 0.1:  # a step far below the paddle period: the cubic is exact enough
            qmn, qmx = hermite_extrema(q0, vc1 + vp1, q1, vc2 + vp2, h)
        else:
            qmn, qmx = far_extrema(h, zc, vc1, zp, vp1, cw, sw, p, q0, q1)
    return d1 > dsw and qmn > floor, qmn, qmx


@njit(inline="always")
def far_harmonic(o, f, rec_mode, lad, lev, hh, h, z_tip, zb, z1, zb1, zc, zpart0, vc1, vpart0, zp, vp1, cw, sw, cw1, sw1):
    """The first harmonic of ``q`` over an accepted far step: a recording step by the trapezoid rule
    (print-step samples, error ``(w h)^2/12``), a long step exactly (damped exponentials,
    :func:`project_harmonic`)."""
    if rec_mode:
        o[O_HC] += hh * ((z_tip - zb) * cw + (z1 - zb1) * cw1)
        o[O_HS] -= hh * ((z_tip - zb) * sw + (z1 - zb1) * sw1)
    else:
        project_harmonic(o, lad[lev], zc, zc - zpart0, vc1 - vpart0, zp, vp1, cw, sw, h, complex(f[F_ZR], f[F_ZI]),
                         f[F_LAM1], f[F_WD1], f[F_LAM2], f[F_WD2])  # fmt: skip
