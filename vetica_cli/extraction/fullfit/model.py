"""The forward model of the whole-cycle fit: the prescribed-trajectory surface over one
record (:class:`SurfaceFit`), its periodic dashpot state and its Jacobian.

The measured tip trajectory drives the simulator's own surface update
(:mod:`vetica_cli.core.prescribed`, the SLS of SPEC 3) once per sample, with
exact tangent-linear derivatives; see :mod:`vetica_cli.extraction.fullfit` for
the choices (sub-steps near the surface, far-field blocks, periodic state).
"""

from __future__ import annotations

import math

import numpy as np

from ...core.prescribed import C_FASEP, C_INVKG, C_K0, NDIR, coefficient_tangents, surface_force

NEAR_GAP = 5e-9  # [m] residuals densely (and fine steps) where the measured tip is within this of Z1
FAR_GAP = 5e-9  # [m] model gap above which blocks are advanced in one exact step
FROZEN = 1e-12  # 1 - dXd_end/dXd0 below which the dashpot counts as frozen over the window
LINEAR_XD0 = 1e-4  # periodic-state Newton steps worth less than this of the peak force: applied to first order


class SampledRecord:
    """One record laid out for the kernel: tip positions, the samples whose force
    enters the residuals, the blocks that may be stepped coarsely, and the
    measured force at the wanted samples."""

    def __init__(self, z, f, z1, near_stride, far_stride, block, near_gap):
        self.z = np.ascontiguousarray(z, dtype=float)
        n = len(self.z)
        idx = np.arange(n)
        near = (self.z - z1) < near_gap
        want = np.where(near, idx % near_stride == 0, (idx + 1) % far_stride == 0)
        nblock = n // block
        near_blocks = near[: nblock * block].reshape(nblock, block).any(axis=1)
        self.coarse_ok = (~near_blocks).astype(np.uint8)
        self.want = want.astype(np.uint8)
        self.idx = np.flatnonzero(want)
        self.f = np.asarray(f, dtype=float)[self.idx]
        self.near = int(np.count_nonzero(near))
        self.out_f = np.empty(len(self.idx))
        self.out_j = np.empty((len(self.idx), NDIR))


class SurfaceFit:
    """The forward model of one record and its least-squares residuals.

    ``z, f`` (N,) steady tip positions [m] and measured force [N] every ``h``
    [s], spanning whole drive periods; ``z1`` [m]; ``approach`` = ``(za, fa,
    i1)`` the approach record's tip positions, force and first-contact index,
    or None.  With an approach record and ``fit_offset`` the surface height
    ``s0`` is a fit parameter and the approach samples (the first tap, on a
    surface undeformed at the record's start) join the residuals; otherwise
    ``s0`` follows from ``Z1`` (:meth:`z1_offset`).
    """

    def __init__(self, z, f, h, z1, approach, a0, tip_radius, vdw_on_surface, fit_offset=True,
                 near_stride=4, far_stride=256, block=16, near_gap=NEAR_GAP, substeps=1):  # fmt: skip
        self.h = float(h)
        self.substeps = max(1, int(substeps))
        self.z1 = float(z1)
        self.a0 = float(a0)
        self.radius = float(tip_radius)
        self.vdw = bool(vdw_on_surface)
        self.block = int(block)
        self.steady = SampledRecord(z, f, z1, near_stride, far_stride, block, near_gap)
        self.approach = None
        self.za1 = None  # approach tip positions before the first-contact minimum
        if approach is not None:
            za, fa, i1 = approach
            self.za1 = np.ascontiguousarray(za[:i1], dtype=float)
            self._za1_want = np.zeros(len(self.za1), np.uint8)
            self._za1_ok = np.ones(len(self.za1) // self.block, np.uint8)
            if fit_offset:
                self.approach = SampledRecord(za, fa, z1, near_stride, far_stride, block, near_gap)
        self.fit_offset = self.approach is not None
        self.f = self.steady.f if self.approach is None else np.concatenate([self.steady.f, self.approach.f])
        self.scale = float(np.max(f)) or 1.0
        self.near_samples = self.steady.near
        self._state = (0.0, False)  # periodic (Xd0, contact0) of the last evaluation: warm start
        self._last = None
        self._s0 = None
        self.passes = 0
        self.frozen = 0
        self.periodic_residual = math.nan

    def z1_offset(self, k_inf, k0, cd, hr6, tangents=True):
        """Surface height from Z1: ``s0 = Z1 - a0 - X1`` [m] and ``ds0/d(DIRECTIONS)``.

        ``X1 = (k0 Xd1 + fa_sep)/Kg`` is the pulled-up surface at the first
        contact, ``Xd1`` from the approach record (0 without one); solved
        with Newton's method since ``Xd1`` depends (weakly) on ``s0``.  Exact
        up to the tip's travel in one sample at the first contact (the force
        minimum is the last sample out of contact or the first in it).
        """
        c, dc = coefficient_tangents(k_inf, k0, cd, hr6, self.a0, self.vdw, self.h)
        kg_inv, fa_sep = c[C_INVKG], c[C_FASEP]
        s0 = self.z1 - self.a0 - fa_sep * kg_inv
        dxd1 = np.zeros(NDIR)
        xd1 = 0.0
        if self.za1 is not None and len(self.za1) > 1 and self.vdw:
            if self._s0 is not None:
                s0 = self._s0  # warm start: the last evaluation's surface height
            empty_f, empty_j = np.empty(0), np.empty((0, NDIR))
            for _ in range(6):
                xd1, _, _, dxd1, *_ = surface_force(
                    self.za1, s0, k_inf, k0, cd, hr6, self.a0, self.vdw, self.h, self.block, self._za1_ok,
                    self._za1_want, FAR_GAP, self.substeps, self._sub_gap(k_inf, k0, hr6),
                    0.0, False, NDIR if tangents else 2, empty_f, empty_j,
                )  # fmt: skip
                g = self.z1 - self.a0 - (k0 * xd1 + fa_sep) * kg_inv - s0  # Newton on s0 = z1 - a0 - X1(s0)
                s0 -= g / (-k0 * kg_inv * dxd1[1] - 1.0)
                if abs(g) < 1e-17:
                    break
            self._s0 = s0
        # dX1 along each direction at fixed s0, then ds0 = -dX1/(1 + dX1/ds0)
        dx1 = (dc[C_K0] * xd1 + k0 * dxd1 + dc[C_FASEP]) * kg_inv + (k0 * xd1 + fa_sep) * dc[C_INVKG]
        ds0 = -dx1 / (1.0 + dx1[1])
        ds0[0] = ds0[1] = 0.0
        return s0, ds0

    def _pass(self, rec, s0, theta, xd0, contact0, ndir):
        self.passes += 1
        return surface_force(
            rec.z, s0, theta[0], theta[1], theta[2], theta[3], self.a0, self.vdw, self.h,
            self.block, rec.coarse_ok, rec.want, FAR_GAP, self.substeps, self._sub_gap(theta[0], theta[1], theta[3]),
            xd0, contact0, ndir, rec.out_f, rec.out_j,
        )  # fmt: skip

    def _sub_gap(self, k_inf, k0, hr6):
        """Gap [m] below which the surface is updated ``substeps`` times per sample: where
        the attraction's feedback gain ``2 Fa(d)/(d Kg) = 2 H R/(6 d^3 Kg)`` exceeds 1 %."""
        return max(2.0 * self.a0, (200.0 * hr6 / (k_inf + k0)) ** (1.0 / 3.0))

    def _newton_step(self, res, b):
        """Newton step of ``Xd_end(Xd0) - Xd0 = res`` with slope ``b = dXd_end/dXd0``.
        A dashpot that relaxes by less than ``FROZEN`` over the window has no
        periodic state to speak of: the step is then limited (counted in ``frozen``)."""
        gap = 1.0 - b
        if not gap > FROZEN:
            self.frozen += 1
            gap = FROZEN
        return res / gap

    def _predict_xd0(self, theta, s0):
        """Periodic Xd0 [m] extrapolated from the last evaluation with its derivatives."""
        if self._last is None:
            return self._state[0]
        lnth, s0_last, xd0, dln, ds, s0_free = self._last
        pred = xd0 + float(np.dot(dln[: NDIR - 2], np.log(theta) - lnth))
        if s0_free:
            pred += ds * (s0 - s0_last)
        return pred if math.isfinite(pred) else self._state[0]

    def reset(self):
        """Forget the warm start (periodic state of the last evaluation)."""
        self._state = (0.0, False)
        self._last = None

    def warm_start_from(self, other: SurfaceFit) -> None:
        """Start the periodic-state search where ``other`` (a fit of this record's first
        periods) ended."""
        self._state, self._last = other._state, other._last

    @property
    def window_start_xd(self) -> float:
        """Dashpot position at the window start of the last evaluation [m] (the periodic
        state, or the fitted one)."""
        return self._state[0]

    def evaluate(self, theta, s0=None, ndir=NDIR, xd0=None):
        """Model force at the wanted samples [N] (steady, then approach) for
        ``theta = (k_inf, k0, cd, hr6)`` [SI] and surface height ``s0`` [m] (None:
        from Z1), with the steady window in its periodic state, and the total
        derivatives (N_out, 6): ``dF/d ln theta``, ``dF/ds0`` (through the
        periodic ``Xd0``; with ``s0`` from Z1 this column is zero and the
        others include ``ds0/d ln theta``) and ``dF/dXd0`` at fixed parameters.
        ``xd0``: the dashpot position at the window start [m], None = the
        periodic state.  Jacobian None when ``ndir`` = 0."""
        ds0 = None
        if s0 is None:
            s0, ds0 = self.z1_offset(*theta, tangents=ndir > 0)
        periodic = xd0 is None
        if periodic:
            f, xd0, contact0, dxd, k = self._periodic_window(theta, s0, max(ndir, 1))
        else:  # the state at the window start is a fit parameter
            contact0 = self._state[1]
            xd_end, _, _, dxd, k, *_ = self._pass(self.steady, s0, theta, xd0, contact0, max(ndir, 1))
            f = self.steady.out_f[:k].copy()
            self.periodic_residual = xd_end - xd0
        self._state = (xd0, contact0)
        inv = 1.0 / max(1.0 - dxd[0], FROZEN) if periodic else 0.0
        # derivatives of the periodic Xd0 along (ln theta, s0), for the next evaluation's start
        self._last = (np.log(theta), s0, xd0, dxd[2:] * inv, dxd[1] * inv, ds0 is None)
        jac = self._steady_jacobian(k, dxd, inv, ds0) if ndir > 0 else None
        if self.approach is not None:
            f, jac = self._with_approach(f, jac, theta, s0, ds0, ndir)
        return f, jac

    def _periodic_window(self, theta, s0, nd):
        """The steady window in its periodic state: Newton on the dashpot state
        ``Xd_end(Xd0) = Xd0`` (affine for a fixed contact schedule); the last step, when
        small, is applied to the outputs to first order.  Returns ``(force, Xd0,
        contact state at the start, dXd_end, samples)``."""
        rec = self.steady
        contact0 = self._state[1]
        xd0 = self._predict_xd0(theta, s0)
        small = LINEAR_XD0 * self.scale / theta[1]  # [m]
        step = 0.0
        for _ in range(12):
            xd0 += step
            xd_end, _, contact_end, dxd, k, *_ = self._pass(rec, s0, theta, xd0, contact0, nd)
            last, step = step, self._newton_step(xd_end - xd0, dxd[0])
            same = contact_end == contact0
            contact0 = contact_end
            # small enough, or no longer contracting (round-off when nothing relaxes in the window)
            if same and (abs(step) <= small or (last and abs(step) > 0.5 * abs(last))):
                break
        f = rec.out_f[:k] + rec.out_j[:k, 0] * step
        xd0 += step
        self.periodic_residual = xd_end - xd0 + dxd[0] * step
        return f, xd0, contact0, dxd, k

    def _steady_jacobian(self, k, dxd, inv, ds0):
        """Total derivatives (k, 6) of the steady window's force (:meth:`evaluate`)."""
        jd = self.steady.out_j[:k]
        jac = np.zeros((k, 6))
        jac[:, 5] = jd[:, 0]  # dF/dXd0 at fixed parameters (periodic: for the conservative covariance)
        if ds0 is None:  # s0 a parameter: dXd0/d(direction) from periodicity
            jac[:, :4] = jd[:, 2:] + np.outer(jd[:, 0], dxd[2:] * inv)
            jac[:, 4] = jd[:, 1] + jd[:, 0] * (dxd[1] * inv)
        else:  # s0 from Z1: through s0 too
            dxd0 = (dxd[2:] + dxd[1] * ds0[2:]) * inv
            jac[:, :4] = jd[:, 2:] + np.outer(jd[:, 1], ds0[2:]) + np.outer(jd[:, 0], dxd0)
        return jac

    def _with_approach(self, f, jac, theta, s0, ds0, ndir):
        """Append the approach record's force (surface undeformed at its start) and derivatives."""
        a = self.approach
        _, _, _, _, ka, *_ = self._pass(a, s0, theta, 0.0, False, ndir)
        f = np.concatenate([f, a.out_f[:ka]])
        if ndir > 0:
            ja = np.zeros((ka, 6))
            ja[:, :4] = a.out_j[:ka, 2:]
            if ds0 is None:
                ja[:, 4] = a.out_j[:ka, 1]
            else:
                ja[:, :4] += np.outer(a.out_j[:ka, 1], ds0[2:])
            jac = np.vstack([jac, ja])
        return f, jac
