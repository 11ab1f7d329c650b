"""The forward model of the whole-cycle fit: the prescribed-trajectory surface over one
record (:class:`SurfaceFit`), its periodic dashpot state and its Jacobian.

The measured tip trajectory drives the simulator's own surface update
(:mod:`vetica_cli.core.prescribed`: the massless Zener SLS, or the Wiechert surface
with N Maxwell arms) once per sample, with exact tangent-linear
derivatives; see :mod:`vetica_cli.extraction.fullfit` for the choices (sub-steps
near the surface, far-field blocks, periodic state, surface height).

Parameter vector ``theta = (k_inf, k_1, cd_1, ..., k_N, cd_N, H R/6)`` [SI] (one arm:
``k_inf, k0, cd, H R/6``).  Jacobian columns (:meth:`SurfaceFit.evaluate`):
``d/d ln theta`` (2 N + 2), ``d/d s0``, ``d/d Xd0_i`` (N).
"""

from __future__ import annotations

import math

import numpy as np


def kernels():
    """:mod:`vetica_cli.core.prescribed`, imported at the first pass: importing the method loads no numba."""
    from ...core import prescribed

    return prescribed


NEAR_GAP = 5e-9  # [m] residuals densely (and fine steps) where the measured tip is within this of Z1
FAR_GAP = 5e-9  # [m] model gap above which blocks are advanced in one exact step
FROZEN = 1e-12  # 1 - dXd_end/dXd0 below which the dashpot counts as frozen over the window
APPROACH_MEMO = 2  # approach passes a record's models keep (SurfaceFit._approach_pass)
LINEAR_XD0 = 1e-4  # periodic-state Newton steps worth less than this of the peak force: applied to first order


def n_directions(n_arms: int) -> int:
    """Directions of the kernel for ``n_arms`` arms: ``Xd0_i``, ``s0``, ``ln theta``."""
    return 3 * n_arms + 3


JUMP_RATIO = 5.0  # a force step this many times both neighbouring steps ...
JUMP_SIZE = 0.01  # ... and above this fraction of the peak force is a jump (the snap to contact)
SNAP_GAIN_FORCE = 2.0 ** (-2.0 / 3.0)  # Fa(d)/Fa(d*) where the pull's gain 2 Fa/(d Kg) is 1/2 (d = 2^(1/3) d*)


def jump_samples(f) -> np.ndarray:
    """Samples at a jump of the measured force (a surface snapping to the tip under its pull),
    left out of the residuals: the samples it falls between and one more each side, and the
    approach to it where the pull's feedback gain ``2 Fa(d)/(d Kg)`` exceeds 1/2 (the attraction
    within ``2^(-2/3)`` of its value before the jump, ``Fa ~ 1/d^2``).  Where in its sample
    interval the jump falls is not in the record, and a model that puts it one sample early or
    late misses by the whole jump (2 nN at Kg = 10.5 N/m against 0.1 nN of noise); before it the
    force's sensitivity to the surface grows as ``1/(1 - gain)``, and those few samples ruled the
    linearised error bars: the tap-robust 1-sigma read 40-950 % on answers within 1 % of the
    truth (stripped 300 K records of a 5:1 surface, Kg 10.5 N/m).

    A jump is one step ``JUMP_RATIO`` times both neighbouring steps and above ``JUMP_SIZE`` of the
    peak, or two such steps of one sign in a row held together against the steps either side: the
    surface's runaway under the pull takes a fraction of a nanosecond, and a sample taken during it
    reads part of the jump.  Missed, such a straddled jump left one sample a tap a whole jump off
    the model wherever the model's jump moved by a sample, and the least squares rugged: on a 1:2
    surface (k0 2, k_inf 4 N/m, cd 1e-3 kg/s, 0.5 ns, true force) the noise-free fit's cd sat -4.1 %
    off the truth (0.000 % with the pair), and with 1 pm of detector noise 20 seeds' cd spread over
    -18 ... +10 % at error bars of 1-4 % (-3.3 ... +1.1 % with it, RMS residuals all at the noise)."""
    f = np.asarray(f, dtype=float)
    out = np.zeros(len(f), bool)
    if len(f) < 4:
        return out
    step = np.diff(f)
    d = np.abs(step)
    size = JUMP_SIZE * float(np.max(np.abs(f)))
    # the size test first: it leaves a handful of steps, and only they are held against their neighbours
    big = np.flatnonzero(d > size)
    done = -1
    for i in big:
        if i <= done:
            continue
        before = d[i - 1] if i > 0 else 0.0
        pair = i + 1 < len(d) and d[i + 1] > size and step[i + 1] * step[i] > 0.0
        if pair and abs(f[i + 2] - f[i]) > JUMP_RATIO * max(before, d[i + 2] if i + 2 < len(d) else 0.0):
            last = i + 1
        elif d[i] > JUMP_RATIO * max(before, d[i + 1] if i + 1 < len(d) else 0.0):
            last = i
        else:
            continue
        done = last
        lo = i
        if f[i] < 0.0:  # the pull's gain above 1/2 before the snap: the attraction within 2^(-2/3) of its last
            while lo > 0 and f[lo - 1] <= SNAP_GAIN_FORCE * f[i]:
                lo -= 1
        out[max(lo - 1, 0) : last + 3] = True
    return out


class SampledRecord:
    """One record laid out for the kernel: tip positions, the samples whose force
    enters the residuals, the blocks that may be stepped coarsely, and the
    measured force at the wanted samples."""

    def __init__(self, z, f, z_ref, near_stride, far_stride, block, near_gap, ndir):
        self.z = np.ascontiguousarray(z, dtype=float)
        n = len(self.z)
        near = (self.z - z_ref) < near_gap
        every_near, every_far = np.zeros(n, bool), np.zeros(n, bool)  # sample i % stride == 0 (far: (i+1) % stride)
        every_near[::near_stride] = True
        every_far[far_stride - 1 :: far_stride] = True
        want = np.where(near, every_near, every_far) & ~jump_samples(f)
        nblock = n // block
        near_blocks = near[: nblock * block].reshape(nblock, block).any(axis=1)
        self.coarse_ok = (~near_blocks).astype(np.uint8)
        self.want = want.astype(np.uint8)
        self._f_all = np.asarray(f, dtype=float)
        self.near = int(np.count_nonzero(near))
        self._layout(ndir)

    def _layout(self, ndir):
        self.idx = np.flatnonzero(self.want)
        self.f = self._f_all[self.idx]
        self.out_f = np.empty(len(self.idx))
        self.out_j = np.empty((len(self.idx), ndir))

    def drop(self, rows) -> np.ndarray:
        """Leave the residual rows ``rows`` (and the wanted samples next to them) out; returns the
        record's sample indices left out."""
        i = self.idx[np.asarray(rows, int)]
        gone = np.unique(np.clip(np.concatenate([i - 1, i, i + 1]), 0, len(self.want) - 1))
        self.want[gone] = 0
        self._layout(self.out_j.shape[1])
        return i


class SurfaceFit:
    """The forward model of one record and its least-squares residuals.

    ``z, f`` (N,) steady tip positions [m] and measured force [N] every ``h``
    [s], spanning whole drive periods; ``z1`` [m] (the tip position at the first
    force minimum of the approach; None when unknown); ``approach`` = ``(za, fa,
    i1)`` the approach record's tip positions, force and first-contact index, or
    None; ``n_arms`` Maxwell arms (1 = the SLS).  The surface height ``s0`` is a fit
    parameter when ``fit_offset`` (with an approach record its samples -- the first
    tap, on a surface undeformed at the record's start -- join the residuals) or
    when ``z1`` is unknown; otherwise it follows from ``Z1`` (:meth:`z1_offset`).
    ``z_ref`` [m]: the tip height near the surface that decides which samples are
    near (default ``z1``; a record without Z1 gives the tip position at its steady
    contacts).  ``height`` [m]: the undeformed surface's position when the record says it
    (``z_tip`` measured from it, eq. 84's premise: 0); the height then follows from it rather
    than from ``Z1`` where it is not fitted, and starts there where it is.
    """

    def __init__(self, z, f, h, z1, approach, a0, tip_radius, vdw_on_surface, fit_offset=True,
                 near_stride=4, far_stride=256, block=16, near_gap=NEAR_GAP, substeps=1, n_arms=1,
                 z_ref=None, shared=None, height=None):  # fmt: skip
        self.h = float(h)
        self.height = None if height is None else float(height)
        self.substeps = max(1, int(substeps))
        self.z1 = None if z1 is None else float(z1)
        self.z_ref = float(z_ref if z_ref is not None else z1)
        self.a0 = float(a0)
        self.radius = float(tip_radius)
        self.vdw = bool(vdw_on_surface)
        self.block = int(block)
        self.n_arms = int(n_arms)
        self.n_params = 2 * self.n_arms + 1  # k_inf and (k_i, cd_i) per arm
        self.ndir = n_directions(self.n_arms)
        nd = self.ndir
        self.steady = SampledRecord(z, f, self.z_ref, near_stride, far_stride, block, near_gap, nd)
        self.approach = None
        self.za1 = None  # approach tip positions before the first-contact minimum
        fit_offset = bool(fit_offset) or self.z1 is None
        # what the approach's passes depend on besides (theta, s0, directions): a model of the same
        # record with the same key (another stage's) shares its approach and its passes (_approach_pass)
        self._approach_key = (id(approach), self.z1, self.z_ref, near_stride, far_stride, self.block, near_gap,
                              self.n_arms, fit_offset, self.h, self.substeps, self.a0, self.vdw)  # fmt: skip
        self._approach_memo = {}
        if shared is not None and shared._approach_key == self._approach_key:
            self.za1, self.approach = shared.za1, shared.approach
            if self.za1 is not None:
                self._za1_want, self._za1_ok = shared._za1_want, shared._za1_ok
            self._approach_memo = shared._approach_memo
        elif approach is not None and self.z1 is not None:
            za, fa, i1 = approach
            self.za1 = np.ascontiguousarray(za[:i1], dtype=float)
            self._za1_want = np.zeros(len(self.za1), np.uint8)
            self._za1_ok = np.ones(len(self.za1) // self.block, np.uint8)
            if fit_offset:
                self.approach = SampledRecord(za, fa, self.z_ref, near_stride, far_stride, block, near_gap, nd)
        self.fit_offset = fit_offset
        self.offset_source = (
            "fitted (approach tap + steady window)" if self.approach is not None
            else "fitted (steady window)" if fit_offset
            else "the undeformed surface (z_tip measured from it: thesis eq. 84's premise)" if self.height is not None
            else "from Z1"
        )  # fmt: skip
        self._gather_f()
        self.scale = float(np.max(f)) or 1.0
        self.near_samples = self.steady.near
        self._state = (np.zeros(self.n_arms), False)  # periodic (Xd0, contact0) of the last evaluation: warm start
        self._last = None
        self._s0 = None
        self._coef = {}
        self.passes = 0
        self.frozen = 0
        self.periodic_residual = math.nan

    # ---- parameters

    def split(self, theta):
        """``(k_inf, k (N,), cd (N,), hr6)`` of a parameter vector."""
        theta = np.asarray(theta, float)
        return float(theta[0]), theta[1 : self.n_params : 2], theta[2 : self.n_params : 2], float(theta[self.n_params])

    def _stiffness_tangents(self, theta):
        """``k``, ``1/Kg``, ``Fa_sep`` and their derivatives along the kernel's directions
        (``d k_i/d ln k_i = k_i``, ``d(1/Kg) = -dKg/Kg^2``, ``d Fa_sep/d ln(HR/6) = Fa_sep``)."""
        k_inf, k, _, hr6 = self.split(theta)
        n, nd = self.n_arms, self.ndir
        kg = k_inf + float(np.sum(k))
        inv = 1.0 / kg
        fa_sep = hr6 / self.a0**2 if self.vdw else 0.0
        dk = np.zeros((n, nd))
        dkg = np.zeros(nd)
        dkg[n + 1] = k_inf
        for i in range(n):
            dk[i, n + 2 + 2 * i] = k[i]
            dkg[n + 2 + 2 * i] = k[i]
        dfa = np.zeros(nd)
        dfa[nd - 1] = fa_sep
        return k, inv, fa_sep, dk, -dkg * inv * inv, dfa

    def pinned_offset(self, theta) -> float:
        """The surface height [m] an evaluation without a fitted one uses (:meth:`evaluate`): the
        undeformed surface's where the record says it (``height``), else from Z1 (:meth:`z1_offset`).
        (The fit once reported the latter on an eq.-84 record, whose evaluations used the former: its
        forward model then stood 68 pm off the fit on a 300 K record of a snapping surface.)"""
        if self.height is not None:
            return self.height
        return self.z1_offset(theta, tangents=False)[0]

    def initial_offset(self, theta) -> float:
        """Starting surface height [m]: from Z1 (:meth:`z1_offset`) when known, else the
        reference tip height at contact less the relaxed surface's lift (:meth:`_contact_lift`)."""
        if self.height is not None:
            return self.height
        if self.z1 is not None:
            return self.z1_offset(theta, tangents=False)[0]
        _, inv, fa_sep, _, dinv, dfasep = self._stiffness_tangents(theta)
        return self.z_ref - self._contact_lift(inv, fa_sep, dinv, dfasep)[0]

    def _contact_lift(self, inv, fa_sep, dinv, dfasep):
        """Tip height above the surface's rest position at the first contact, less the arms'
        share: ``d_c + Fa(d_c)/Kg`` [m] and its derivatives.  The pulled surface meets the
        tip at the gap ``d_c = a0`` (``a0 + Fa(a0)/Kg``, eq. 84's lift) unless the pull's
        feedback gain ``2 Fa(d)/(d Kg)`` reaches 1 first: then no equilibrium is left below
        ``d* = (2 H R/(6 Kg))^(1/3)`` and the surface snaps to the tip from there,
        ``d* + Fa(d*)/Kg = 1.5 d*`` (the simulator's rule: contact when the gap to the
        surface, pulled at the last step's gap, reaches a0)."""
        if fa_sep <= 0.0 or 2.0 * fa_sep * inv <= self.a0:
            return self.a0 + fa_sep * inv, dfasep * inv + fa_sep * dinv
        d_star = (2.0 * fa_sep * self.a0**2 * inv) ** (1.0 / 3.0)
        # d ln d* = (d ln(HR/6) + d ln(1/Kg))/3; d ln(HR/6) = dFa_sep/Fa_sep
        return 1.5 * d_star, 0.5 * d_star * (dfasep / fa_sep + dinv / inv)

    def z1_offset(self, theta, tangents=True):
        """Surface height from Z1: ``s0 = Z1 - a0 - X1`` [m] and ``ds0/d(direction)``.

        ``X1 = (sum k_i Xd1_i + fa_sep)/Kg`` is the pulled-up surface at the first
        contact, ``Xd1`` from the approach record (0 without one); solved with
        Newton's method since ``Xd1`` depends (weakly) on ``s0``.  Exact up to the
        tip's travel in one sample at the first contact (the force minimum is the
        last sample out of contact or the first in it).
        """
        n = self.n_arms
        k, inv, fa_sep, dk, dinv, dfasep = self._stiffness_tangents(theta)
        lift, dlift = self._contact_lift(inv, fa_sep, dinv, dfasep)
        s0 = self.z1 - lift
        xd1 = np.zeros(n)
        dxd1 = np.zeros((n, self.ndir))
        if self.za1 is not None and len(self.za1) > 1 and self.vdw:
            if self._s0 is not None:
                s0 = self._s0  # warm start: the last evaluation's surface height
            empty_f, empty_j = np.empty(0), np.empty((0, self.ndir))
            for _ in range(6):
                xd1, _, _, dxd1, *_ = self._kernel(self.za1, self._za1_ok, self._za1_want, empty_f, empty_j, s0,
                                                   theta, np.zeros(n), False, self.ndir if tangents else n + 1,
                                                   known_start=True)  # fmt: skip
                g = self.z1 - lift - (k @ xd1) * inv - s0  # Newton on s0 = z1 - a0 - X1(s0)
                s0 -= g / (-(k @ dxd1[:, n]) * inv - 1.0)
                if abs(g) < 1e-17:
                    break
            self._s0 = s0
        # dX1 along each direction at fixed s0, then ds0 = -dX1/(1 + dX1/ds0)
        dx1 = (xd1 @ dk + k @ dxd1) * inv + (k @ xd1) * dinv + dlift
        ds0 = -dx1 / (1.0 + dx1[n])
        ds0[: n + 1] = 0.0
        return s0, ds0

    # ---- the kernel

    def _kernel(self, z, coarse_ok, want, out_f, out_j, s0, theta, xd0, contact0, ndir, known_start=False):
        """One pass of the prescribed-trajectory kernel (the SLS's scalar kernel for one arm,
        the N-arm kernel otherwise).  Returns ``(xd (N,), x, contact, dxd (N, D), written, ...)``.
        ``known_start``: the caller reads no derivative along the start state ``Xd0`` (the SLS
        kernel then skips that direction; its columns are left unwritten)."""
        k_inf, k, cd, hr6 = self.split(theta)
        sub_gap = self._sub_gap(k_inf + float(np.sum(k)), hr6)
        if self.n_arms == 1:
            xd, x, contact, dxd, *rest = kernels().surface_force(
                z, s0, k_inf, float(k[0]), float(cd[0]), hr6, self.a0, self.vdw, self.h,
                self.block, coarse_ok, want, FAR_GAP, self.substeps, sub_gap,
                float(xd0[0]), contact0, ndir, out_f, out_j, 1 if known_start else 0,
            )  # fmt: skip
            return np.array([xd]), x, contact, dxd[None, :], *rest
        co = self._coefficients(theta, ndir > self.n_arms + 1)
        return kernels().arms_force(
            z, s0, self.a0, self.block, coarse_ok, want, FAR_GAP, self.substeps, sub_gap,
            np.asarray(xd0, float), contact0, ndir, *co, out_f, out_j,
        )  # fmt: skip

    def _coefficients(self, theta, tangents):
        key = (tuple(float(v) for v in theta), tangents)
        if key not in self._coef:
            if len(self._coef) > 8:
                self._coef.clear()
            k_inf, k, cd, hr6 = self.split(theta)
            steps = (self.h, self.h * self.block, self.h / self.substeps)
            self._coef[key] = kernels().arm_coefficients(k_inf, k, cd, hr6, self.a0, self.vdw, steps, tangents)
        return self._coef[key]

    def _pass(self, rec, s0, theta, xd0, contact0, ndir, known_start=False):
        self.passes += 1
        return self._kernel(rec.z, rec.coarse_ok, rec.want, rec.out_f, rec.out_j, s0, theta, xd0, contact0, ndir,
                            known_start)  # fmt: skip

    def _sub_gap(self, kg, hr6):
        """Gap [m] below which the surface is updated ``substeps`` times per sample: where
        the attraction's feedback gain ``2 Fa(d)/(d Kg) = 2 H R/(6 d^3 Kg)`` exceeds 1 %."""
        return max(2.0 * self.a0, (200.0 * hr6 / kg) ** (1.0 / 3.0))

    def force_everywhere(self, theta, s0, xd0, contact0, z, start=True):
        """Model force [N] at every sample of the tip positions ``z`` (no coarse blocks), from
        the dashpot positions ``xd0`` [m] and contact state ``contact0`` at its first sample
        (``start=False``: ``z`` is an approach record, the surface undeformed at its start):
        the fitted surface's force through the whole band, for what the record's low-pass
        does to a method's answer (:func:`vetica_cli.extraction.uncertainty.band_term`)."""
        z = np.ascontiguousarray(z, dtype=float)
        n = len(z)
        out_f, out_j = np.empty(n), np.empty((n, 1))
        xd = np.asarray(xd0, float) if start else np.zeros(self.n_arms)
        self._kernel(z, np.zeros(max(n // self.block, 1), np.uint8), np.ones(n, np.uint8), out_f, out_j,
                     float(s0), np.asarray(theta, float), xd, bool(contact0) if start else False, 0)  # fmt: skip
        return out_f

    # ---- the periodic state

    def _regularised_inverse(self, b):
        """``(I - B)^-1`` of the window's state map ``Xd_end = B Xd0 + ...``; a dashpot
        that relaxes by less than ``FROZEN`` over the window has no periodic state to
        speak of: its direction is limited to ``1/FROZEN`` (counted in ``frozen``)."""
        n = self.n_arms
        if n == 1:
            gap = 1.0 - b[0, 0]
            if not gap > FROZEN:
                self.frozen += 1
                gap = FROZEN
            return np.array([[1.0 / gap]])
        u, sv, vt = np.linalg.svd(np.eye(n) - b)
        if not np.all(sv > FROZEN):
            self.frozen += 1
        return (vt.T / np.maximum(sv, FROZEN)) @ u.T

    def _predict_xd0(self, theta, s0):
        """Periodic Xd0 [m] extrapolated from the last evaluation with its derivatives."""
        if self._last is None:
            return self._state[0].copy()
        lnth, s0_last, xd0, dln, ds, s0_free = self._last
        pred = xd0 + dln @ (np.log(theta) - lnth)
        if s0_free:
            pred = pred + ds * (s0 - s0_last)
        return pred if np.all(np.isfinite(pred)) else self._state[0].copy()

    def drop_rows(self, rows) -> np.ndarray:
        """Leave the steady window's residual rows ``rows`` out of the fit (an approach row is kept:
        the approach tap pins the height, as a group); returns the sample indices left out."""
        rows = np.asarray(rows, int)
        rows = rows[rows < len(self.steady.idx)]
        if not len(rows):
            return rows
        out = self.steady.drop(rows)
        self._gather_f()
        return out

    def _gather_f(self):
        """The measured force of the residual rows: the steady window's, then the approach's."""
        self.f = self.steady.f if self.approach is None else np.concatenate([self.steady.f, self.approach.f])

    def reset(self):
        """Forget the warm start (periodic state of the last evaluation)."""
        self._state = (np.zeros(self.n_arms), False)
        self._last = None

    def warm_start_from(self, other: SurfaceFit) -> None:
        """Start the periodic-state search where ``other`` (a fit of this record's first
        periods, with as many arms) ended."""
        if other.n_arms == self.n_arms:
            self._state, self._last = other._state, other._last

    @property
    def window_start_xd(self) -> np.ndarray:
        """Dashpot positions at the window start of the last evaluation [m] (the periodic
        state, or the fitted one), one per arm."""
        return np.array(self._state[0], dtype=float)

    def evaluate(self, theta, s0=None, ndir=None, xd0=None):
        """Model force at the wanted samples [N] (steady, then approach) for ``theta``
        (module docstring) and surface height ``s0`` [m] (None: from Z1), with the
        steady window in its periodic state, and the total derivatives (N_out, D):
        ``dF/d ln theta``, ``dF/ds0`` (through the periodic ``Xd0``; with ``s0`` from
        Z1 this column is zero and the others include ``ds0/d ln theta``) and
        ``dF/dXd0_i`` at fixed parameters.  ``ndir``: kernel directions (default all;
        one fewer leaves out ``H R/6``; 0 = no Jacobian).  ``xd0``: the dashpot
        positions at the window start [m], None = the periodic state."""
        theta = np.asarray(theta, float)
        n = self.n_arms
        ndir = self.ndir if ndir is None else ndir
        ds0 = None
        if s0 is None and self.height is not None:  # the record says where the undeformed surface is
            s0, ds0 = self.height, np.zeros(self.ndir)
        elif s0 is None:
            s0, ds0 = self.z1_offset(theta, tangents=ndir > 0)
        periodic = xd0 is None
        nd = max(ndir, n + 1)
        if periodic:
            f, xd0, contact0, dxd, k = self._periodic_window(theta, s0, nd)
            inv = self._regularised_inverse(dxd[:, :n])
        else:  # the state at the window start is a fit parameter
            xd0 = np.atleast_1d(np.asarray(xd0, float))
            contact0 = self._state[1]
            xd_end, _, _, dxd, k, *_ = self._pass(self.steady, s0, theta, xd0, contact0, nd)
            f = self.steady.out_f[:k].copy()
            self.periodic_residual = float(np.max(np.abs(xd_end - xd0)))
            inv = np.zeros((n, n))
        self._state = (np.array(xd0, float), contact0)
        # derivatives of the periodic Xd0 along (ln theta, s0), for the next evaluation's start
        self._last = (np.log(theta), s0, self._state[0].copy(), inv @ dxd[:, n + 1 :], inv @ dxd[:, n], ds0 is None)
        jac = self._steady_jacobian(k, dxd, inv, ds0, nd) if ndir > 0 else None
        if self.approach is not None:
            f, jac = self._with_approach(f, jac, theta, s0, ds0, ndir)
        return f, jac

    def _periodic_window(self, theta, s0, nd):
        """The steady window in its periodic state: Newton on the dashpot states
        ``Xd_end(Xd0) = Xd0`` (affine for a fixed contact schedule); the last step, when
        small, is applied to the outputs to first order.  Returns ``(force, Xd0,
        contact state at the start, dXd_end, samples)``."""
        rec = self.steady
        n = self.n_arms
        contact0 = self._state[1]
        xd0 = self._predict_xd0(theta, s0)
        small = LINEAR_XD0 * self.scale / float(np.max(self.split(theta)[1]))  # [m]
        step = np.zeros(n)
        for _ in range(12):
            xd0 = xd0 + step
            xd_end, _, contact_end, dxd, k, *_ = self._pass(rec, s0, theta, xd0, contact0, nd)
            last = step
            step = self._regularised_inverse(dxd[:, :n]) @ (xd_end - xd0)
            same = contact_end == contact0
            contact0 = contact_end
            # small enough, or no longer contracting (round-off when nothing relaxes in the window)
            big, big_last = float(np.max(np.abs(step))), float(np.max(np.abs(last)))
            if same and (big <= small or (big_last and big > 0.5 * big_last)):
                break
        f = rec.out_f[:k] + rec.out_j[:k, :n] @ step
        xd0 = xd0 + step
        self.periodic_residual = float(np.max(np.abs(xd_end - xd0 + dxd[:, :n] @ step)))
        return f, xd0, contact0, dxd, k

    def _steady_jacobian(self, k, dxd, inv, ds0, nd):
        """Total derivatives (k, D) of the steady window's force (:meth:`evaluate`); the
        kernel computed its first ``nd`` directions (the others are zero)."""
        n, p = self.n_arms, self.n_params
        jd = self.steady.out_j[:k]
        jac = np.zeros((k, self.ndir))
        jac[:, p + 2 :] = jd[:, :n]  # dF/dXd0 at fixed parameters (periodic: for the conservative covariance)
        nth = min(p + 1, nd - n - 1)  # parameter columns the kernel computed
        if ds0 is None:  # s0 a parameter: dXd0/d(direction) from periodicity
            jac[:, :nth] = jd[:, n + 1 : n + 1 + nth] + jd[:, :n] @ (inv @ dxd[:, n + 1 : n + 1 + nth])
            jac[:, p + 1] = jd[:, n] + jd[:, :n] @ (inv @ dxd[:, n])
        else:  # s0 from Z1: through s0 too
            dth = dxd[:, n + 1 : n + 1 + nth] + np.outer(dxd[:, n], ds0[n + 1 : n + 1 + nth])
            jac[:, :nth] = (
                jd[:, n + 1 : n + 1 + nth] + np.outer(jd[:, n], ds0[n + 1 : n + 1 + nth]) + jd[:, :n] @ (inv @ dth)
            )
        return jac

    def _with_approach(self, f, jac, theta, s0, ds0, ndir):
        """Append the approach record's force (surface undeformed at its start) and derivatives."""
        n, p = self.n_arms, self.n_params
        fa, out_j = self._approach_pass(theta, s0, ndir)
        ka = len(fa)
        f = np.concatenate([f, fa])
        if ndir > 0:
            nth = min(p + 1, ndir - n - 1)
            ja = np.zeros((ka, self.ndir))
            ja[:, :nth] = out_j[:, n + 1 : n + 1 + nth]
            if ds0 is None:
                ja[:, p + 1] = out_j[:, n]
            else:
                ja[:, :nth] += np.outer(out_j[:, n], ds0[n + 1 : n + 1 + nth])
            jac = np.vstack([jac, ja])
        return f, jac

    def _approach_pass(self, theta, s0, ndir):
        """The approach record's force and kernel derivatives (surface undeformed at its start,
        so they depend on ``theta, s0`` alone): the last few are kept, shared by the models of
        one record (a stage starts where the one before ended: the same approach pass)."""
        key = (np.asarray(theta, float).tobytes(), float(s0), ndir)
        hit = self._approach_memo.get(key)
        if hit is None:
            a = self.approach
            _, _, _, _, ka, *_ = self._pass(a, s0, theta, np.zeros(self.n_arms), False, ndir, known_start=True)
            hit = (a.out_f[:ka].copy(), a.out_j[:ka, :ndir].copy())
            if len(self._approach_memo) >= APPROACH_MEMO:
                self._approach_memo.pop(next(iter(self._approach_memo)))
            self._approach_memo[key] = hit
        return hit
