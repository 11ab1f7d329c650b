"""Whole-cycle model inversion: ``vetica extract RUN --method full`` (issue 6).

VETICA (thesis 3.3) reads a few samples of each tap.  This method uses every
sample of the recorded steady periods: the measured tip trajectory
``z_tip(t)`` drives the massless Zener SLS surface of SPEC section 3 (thesis
3.2, appendix C: contact when the gap is <= a0, creep out of contact,
separation when the surface would have to hold the tip with more than the
adhesion), and bounded least squares finds ``k_inf, k0, cd`` (optionally
the Hamaker constant ``H``) for which the predicted force matches the
measured one::

    minimise  sum_i ( Fts_model(t_i; k_inf, k0, cd[, H]) - F_i )^2 / F_peak^2
    over      ln k_inf, ln k0, ln cd [, ln H]       (scipy least_squares, 'trf')

Choices (see the module functions for details):

* **Forward model** (:mod:`.core.prescribed`): the simulator's own surface
  updates (:mod:`.core.sls`), once per sample of the record, with their
  exact tangent-linear derivatives (the Jacobian of the fit comes out of the
  same pass).  Where the simulator's lagged gap -> attraction -> surface
  feedback matters (out of contact within ~1 nm, and across a separation)
  the sample interval is split into the simulator's own steps
  (``substeps = print_step/dt`` from the metadata, else 1), the tip
  interpolated linearly: without this the snap-off transients differ by up
  to 2.6 % of the peak force over a few samples and bias cd by ~6 % at
  cd = 1e-2 kg/s.  Elsewhere in contact the dashpot is updated once per
  sample, so its relaxation leads the simulator's by ``(h - dt)/2`` (a
  ~4 pN offset on the worked example, 5e-5 of the peak force).
* **Surface height** ``s0`` (the undeformed surface in the record's tip
  coordinate, which for an instrument has an unknown offset).  Start value
  from ``Z1``, the tip position at the first force minimum of the approach
  (thesis eq. 84): there the gap is ``a0`` and the surface is pulled up to
  ``X1 = (k0 Xd1 + Fa(a0))/Kg`` (``vdw_on_surface``; ``k0 Xd1/Kg`` without
  the pull), so ``s0 = Z1 - a0 - X1``, with ``Xd1`` (the dashpot's creep
  under the attraction during the approach, ~15 pm on the worked example)
  from the same model run over the approach record (surface undeformed at
  its start).  ``Z1`` is only known to within the tip's travel in one
  sample (the minimum is the last sample out of contact or the first in
  it): 2.8 pm at cd = 1e-2, which alone gives a 0.1 % RMS force misfit.
  So, when the record has its approach segment, ``s0`` is fitted too, with
  the approach samples (the first tap, on an undeformed surface) added to
  the residuals; without one it stays at the ``Z1`` value.
* **State at the window start.**  The steady window spans whole drive
  periods with the base fixed, so the surface state at its start equals the
  state at its end.  The dashpot position ``Xd0`` there is solved for with
  Newton's method on ``Xd_end(Xd0) = Xd0`` (``dXd_end/dXd0`` from the
  tangent-linear kernel; the map is affine for a fixed contact schedule, so
  one or two passes do even when nothing relaxes within the window, where
  iterating the window would need ~tau/window repetitions); the periodicity
  residual is reported.  A record taken before the surface settled (tau_c
  comparable to the run's 3-30 ms) is not periodic: ``state='auto'`` (the
  default) then frees ``Xd0`` as one more fit parameter when a linearised
  step says that removes more than half the residual; ``'periodic'`` and
  ``'free'`` force either.
* **Decimation.**  The forward model runs over every sample; far from the
  surface (gap > 5 nm, attraction < 0.2 % of Fa(a0)) it advances in exact
  steps of ``block`` samples.  Residuals are taken at every
  ``near_stride``-th sample (4) where the measured tip is within 5 nm of Z1
  (contact and the van der Waals range) and every ``far_stride``-th (256)
  elsewhere: ~66 000 residuals for 1.6e6 samples.  Coarse to fine: the
  start scan and a first fit use the first drive period only (its periodic
  state is the window's), then the whole window refines it.
* **Start.**  VETICA's answer on the first 3 taps when it has a plausible
  one, else ``k0 = 0.9 Kg``, ``k_inf = 0.1 Kg`` from the loading slope; a
  start whose Kg is more than a decade off that slope is rescaled onto it.
  Then a scan of cd over 1e-10 .. 1e2 kg/s (every two decades) with one
  Gauss-Newton step on the other parameters at each cd picks the start.
* **Uncertainty.**  ``cov = s^2 (J^T J)^-1`` with ``s^2`` the residual
  variance, J in log-parameters (square roots of the diagonal = relative
  1-sigma), with ``Xd0`` counted as unknown (conservative: it does not lean
  on the periodic state; the periodic-state values are in ``info``).  For
  noise-free simulations ``s`` is systematic model mismatch, and the actual
  errors exceed the 1-sigma values by ~10x (cd = 1e-2 kg/s; 1 pm position
  noise) up to ~5000x (worked example: 1-sigma 4e-8, error 2e-4 from the
  contact-step lead above).  A parameter is flagged not identifiable when
  its 1-sigma exceeds 100 %, when it sits at a bound, when the fit stopped
  far from converged, or when the fitted dashpot does not act within the
  record (its force signature within a tap is below 10x the RMS residual:
  cd has only a lower bound and only Kg = k0 + k_inf is determined; or it
  relaxes within one sample: cd has only an upper bound).
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.optimize import least_squares

from .constants import TIP_RADIUS
from .core.prescribed import C_FASEP, C_INVKG, C_K0, NDIR, coefficient_tangents, surface_force
from .errors import InputError
from .extract import (
    FORCES,
    _check_time,
    _column,
    _finite_or_none,
    force_column,
    resolve_force,
    steady_force,
    z1_reference,
)
from .surfaces import COMMON_KEYS
from .vetica import NAMES, theory

PARAMS = ("k_inf", "k0", "cd", "hamaker")
STATES = ("auto", "periodic", "free")  # dashpot state at the window start
# fit bounds (SI)
BOUNDS = {"k_inf": (1e-4, 1e6), "k0": (1e-4, 1e6), "cd": (1e-13, 1e6), "hamaker": (1e-24, 1e-14)}
NEAR_GAP = 5e-9  # [m] residuals densely (and fine steps) where the measured tip is within this of Z1
FAR_GAP = 5e-9  # [m] model gap above which blocks are advanced in one exact step
CD_SCAN = np.logspace(-10, 2, 7)  # [kg/s] starting-cd scan, every two decades
REL_LIMIT = 1.0  # relative 1-sigma above which a parameter is not identifiable
FREE_NFEV = 25  # evaluation budget of the free-start-state stage (whole window)
SIGNATURE = 10.0  # dashpot force signature / RMS residual below which cd is not identifiable
START_TAPS = 3  # taps of the record VETICA sees for the starting point
SUB_PERIODS = 1  # drive periods of the first (coarse) fit stage
FROZEN = 1e-12  # 1 - dXd_end/dXd0 below which the dashpot counts as frozen over the window
LINEAR_XD0 = 1e-4  # periodic-state Newton steps worth less than this of the peak force: applied to first order


def _segment(df, name):
    """Rows of one segment (None if absent).  Compares the column directly: casting a
    categorical column of 1.8e6 rows to str, as extract's helper does, takes ~0.4 s."""
    if "segment" not in df.columns:
        return None
    sel = df[(df["segment"] == name).to_numpy()]
    return sel if len(sel) else None


class _Record:
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
        self.steady = _Record(z, f, z1, near_stride, far_stride, block, near_gap)
        self.approach = None
        self.za1 = None  # approach tip positions before the first-contact minimum
        if approach is not None:
            za, fa, i1 = approach
            self.za1 = np.ascontiguousarray(za[:i1], dtype=float)
            self._za1_want = np.zeros(len(self.za1), np.uint8)
            self._za1_ok = np.ones(len(self.za1) // self.block, np.uint8)
            if fit_offset:
                self.approach = _Record(za, fa, z1, near_stride, far_stride, block, near_gap)
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

    def evaluate(self, theta, s0=None, ndir=NDIR, xd0=None):
        """Model force at the wanted samples [N] (steady, then approach) for
        ``theta = (k_inf, k0, cd, hr6)`` [SI] and surface height ``s0`` [m] (None:
        from Z1), with the steady window in its periodic state, and the total
        derivatives (N_out, 6): ``dF/d ln theta``, ``dF/ds0`` (through the
        periodic ``Xd0``; with ``s0`` from Z1 this column is zero and the
        others include ``ds0/d ln theta``) and ``dF/dXd0`` at fixed parameters.
        ``xd0``: the dashpot position at the window start [m], None = the
        periodic state.  Jacobian None when ``ndir`` = 0."""
        if s0 is None:
            s0, ds0 = self.z1_offset(*theta, tangents=ndir > 0)
        else:
            ds0 = None
        rec = self.steady
        periodic = xd0 is None
        nd = max(ndir, 1)
        if periodic:
            contact0 = self._state[1]
            xd0 = self._predict_xd0(theta, s0)
            # Newton on the periodic dashpot state Xd_end(Xd0) = Xd0 (affine for a fixed contact
            # schedule); the last step, when small, is applied to the outputs to first order
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
        else:  # the state at the window start is a fit parameter
            contact0 = self._state[1]
            xd_end, _, contact_end, dxd, k, *_ = self._pass(rec, s0, theta, xd0, contact0, nd)
            f = rec.out_f[:k].copy()
            self.periodic_residual = xd_end - xd0
        self._state = (xd0, contact0)
        jac = None
        inv = 1.0 / max(1.0 - dxd[0], FROZEN) if periodic else 0.0
        # derivatives of the periodic Xd0 along (ln theta, s0), for the next evaluation's start
        self._last = (np.log(theta), s0, xd0, dxd[2:] * inv, dxd[1] * inv, ds0 is None)
        if ndir > 0:
            jd = rec.out_j[:k]
            jac = np.zeros((k, 6))
            jac[:, 5] = jd[:, 0]  # dF/dXd0 at fixed parameters (periodic: for the conservative covariance)
            if ds0 is None:  # s0 a parameter: dXd0/d(direction) from periodicity
                jac[:, :4] = jd[:, 2:] + np.outer(jd[:, 0], dxd[2:] * inv)
                jac[:, 4] = jd[:, 1] + jd[:, 0] * (dxd[1] * inv)
            else:  # s0 from Z1: through s0 too
                dxd0 = (dxd[2:] + dxd[1] * ds0[2:]) * inv
                jac[:, :4] = jd[:, 2:] + np.outer(jd[:, 1], ds0[2:]) + np.outer(jd[:, 0], dxd0)
        if self.approach is not None:
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


OFFSET_UNIT = 1e-10  # [m] unit of the surface height in the fit vector
OFFSET_RANGE = 5e-9  # [m] the fitted surface height stays within this of the Z1 value
XD0_RANGE = 1e-6  # [m] bound of a fitted dashpot start position


def fit_surface(
    model: SurfaceFit, theta0, fit_hamaker=False, scan=True, max_nfev=60, xtol=1e-10, s0=None, xd0=None
) -> dict:
    """Bounded least squares of the force residuals (trust-region reflective).

    Fit vector: ``ln k_inf, ln k0, ln cd [, ln(H R/6)] [, s0/OFFSET_UNIT]``.
    ``theta0`` = starting ``(k_inf, k0, cd, hr6)`` [SI; hr6 = H R/6 in J m,
    held fixed unless ``fit_hamaker``]; ``s0`` the starting surface height
    (default: from Z1; fitted when the model has an approach record).
    ``xd0``: None = periodic state at the window start, else the starting
    dashpot position [m] of a fitted start state (``state='free'``).
    ``scan``: first replace the starting cd by the best of ``CD_SCAN`` (and
    itself) at the starting stiffnesses.  Returns the fit (parameters,
    residuals, Jacobian, counts).
    """
    fit_idx = [0, 1, 2] + ([3] if fit_hamaker else [])
    base = np.array(theta0, dtype=float)
    names = [PARAMS[i] for i in fit_idx]
    r = model.radius
    lo = list(np.log([BOUNDS[n][0] * (r / 6 if n == "hamaker" else 1.0) for n in names]))
    hi = list(np.log([BOUNDS[n][1] * (r / 6 if n == "hamaker" else 1.0) for n in names]))
    x0 = list(np.log(base[fit_idx]))
    s0_z1 = model.z1_offset(*base, tangents=False)[0]
    if model.fit_offset:
        s0 = s0_z1 if s0 is None else s0
        names.append("s0")
        x0.append(s0 / OFFSET_UNIT)
        lo.append((s0_z1 - OFFSET_RANGE) / OFFSET_UNIT)
        hi.append((s0_z1 + OFFSET_RANGE) / OFFSET_UNIT)
    free = xd0 is not None
    if free:
        names.append("xd0")
        x0.append(xd0 / OFFSET_UNIT)
        lo.append(-XD0_RANGE / OFFSET_UNIT)
        hi.append(XD0_RANGE / OFFSET_UNIT)
    lo, hi = np.array(lo), np.array(hi)
    x0 = np.clip(np.array(x0), lo + 1e-9, hi - 1e-9)
    cols = fit_idx + ([4] if model.fit_offset else []) + ([5] if free else [])
    scale = np.ones(len(cols))
    scale[len(fit_idx) :] = OFFSET_UNIT
    i_s0 = len(fit_idx)

    def unpack(x):
        theta = base.copy()
        theta[fit_idx] = np.exp(x[: len(fit_idx)])
        return (
            theta,
            x[i_s0] * OFFSET_UNIT if model.fit_offset else None,
            x[-1] * OFFSET_UNIT if free else None,
        )

    cache = {}

    def evaluate(x):
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            theta, s0x, xd0x = unpack(x)
            f, jac = model.evaluate(theta, s0x, ndir=NDIR if fit_hamaker else NDIR - 1, xd0=xd0x)
            cache[key] = (
                (f - model.f) / model.scale,
                jac[:, cols] * scale / model.scale,
                jac[:, 5] * OFFSET_UNIT / model.scale,
            )
        return cache[key]

    scanned = []
    if scan:
        # starting cd: scan CD_SCAN (and the start) with one Gauss-Newton step on the other
        # parameters at each cd (a cheap profile: a wrong starting k_inf must not make the
        # glassy plateau of large cd look best), then start from the best point
        n_fit = len(x0)
        others = [i for i in range(n_fit) if i != 2]
        for cd in [math.exp(x0[2])] + list(CD_SCAN):
            x = x0.copy()
            x[2] = np.clip(math.log(cd), lo[2] + 1e-9, hi[2] - 1e-9)
            model.reset()
            res, jac, _ = evaluate(x)
            a = jac[:, others]
            step = np.linalg.lstsq(a, -res, rcond=None)[0]
            step = np.clip(step, -2.0, 2.0)
            x[others] = np.clip(x[others] + step, lo[others] + 1e-9, hi[others] - 1e-9)
            theta, s0x, xd0x = unpack(x)
            f, _ = model.evaluate(theta, s0x, ndir=0, xd0=xd0x)
            scanned.append((float(np.sum(((f - model.f) / model.scale) ** 2)), x))
        x0 = min(scanned, key=lambda c: c[0])[1]
        model.reset()
    sol = least_squares(
        lambda x: evaluate(x)[0], x0, jac=lambda x: evaluate(x)[1], bounds=(lo, hi), method="trf",
        x_scale="jac", xtol=xtol, ftol=1e-12, gtol=1e-12, max_nfev=max_nfev,
    )  # fmt: skip
    res, jac, jac_xd0 = evaluate(sol.x)
    theta, s0_fit, _ = unpack(sol.x)
    # Jacobian with the window's start state as one more unknown (already so when it is fitted)
    jac_free = jac if free else np.column_stack([jac, jac_xd0])
    return {
        "names": names,
        "x": sol.x,
        "theta": theta,
        "s0": s0_fit if s0_fit is not None else model.z1_offset(*theta, tangents=False)[0],
        "s0_z1": model.z1_offset(*theta, tangents=False)[0],
        "residual": res,
        "xd0": float(model._state[0]),
        "periodic_residual": float(model.periodic_residual),
        "jac": jac,
        "jac_free": jac_free,
        "lo": lo,
        "hi": hi,
        "nfev": int(sol.nfev),
        "njev": int(sol.njev or 0),
        "status": int(sol.status),
        "message": str(sol.message),
        "scan": [(c, float(math.exp(x[2]))) for c, x in scanned],
    }


# ----------------------------------------------------------------------------- driver


def _spread_none() -> dict:
    """A whole-record fit has no per-tap spread (same keys as VETICA's)."""
    return {"n": 0, "mean": None, "std": None, "min": None, "max": None}


def _loading_slope(z: np.ndarray, f: np.ndarray, taps) -> float:
    """Contact stiffness of the first tap [N/m]: ``-dF/dz`` fitted between 20 % and
    80 % of its peak force on loading (between Kr and Kg of an SLS)."""
    ic, ip = int(taps.contact[0]), int(taps.peak[0])
    seg = slice(ic, ip + 1)
    fp = f[ip]
    sel = np.flatnonzero((f[seg] > 0.2 * fp) & (f[seg] < 0.8 * fp))
    kg = math.nan
    if len(sel) >= 3:
        kg = -float(np.polyfit(z[seg][sel], f[seg][sel], 1)[0])
    if not (math.isfinite(kg) and kg > 0):
        depth = float(z[ic] - np.min(z[seg]))
        kg = fp / depth if depth > 0 else 1.0
    return kg


def _generic_start(z: np.ndarray, f: np.ndarray, taps) -> dict:
    """``k0 = 0.9 Kg``, ``k_inf = 0.1 Kg`` with Kg from the loading slope; cd from the scan."""
    kg = _loading_slope(z, f, taps)
    return {"k_inf": 0.1 * kg, "k0": 0.9 * kg, "cd": 1e-5}


def _vetica_start(t, z, f, z1, taps, kg_points):
    """VETICA (thesis 3.3) on the first ``START_TAPS`` taps: a starting point only."""
    from .vetica import vetica

    stop = len(t)
    if len(taps.peak) > START_TAPS + 1:
        stop = int(taps.peak[START_TAPS + 1] + 0.5 * taps.spacing)
    ex = vetica(t[:stop], z[:stop], f[:stop], z1, kg_points=kg_points)
    v = {k: ex.values.get(k) for k in ("k_inf", "k0", "cd")}
    if not all(x is not None and math.isfinite(x) and x > 0 for x in v.values()):
        return None
    split = v["k0"] / (v["k0"] + v["k_inf"])
    if not 1e-3 < split < 1.0 - 1e-4:  # VETICA's Kr fit ran into a bound: no start
        return None
    return {k: float(x) for k, x in v.items()}


def _gn_gain(res, jac) -> float:
    """Fraction of the squared residual that one more Gauss-Newton step of the
    linearised model would remove (at a periodic fit with the window's start state
    as a free column: what releasing the periodic state could gain)."""
    step = np.linalg.lstsq(jac, -res, rcond=None)[0]
    r0 = float(res @ res)
    return 1.0 - float(np.sum((res + jac @ step) ** 2)) / r0 if r0 > 0 else 0.0


def _covariance(res, jac):
    """``s^2 (J^T J)^-1`` with ``s^2 = |r|^2/(n - p)``, by SVD without truncation
    (a degenerate direction gives an infinite variance, not a truncated one)."""
    n, p = jac.shape
    s2 = float(np.sum(res**2)) / max(n - p, 1)
    norm = np.sqrt(np.sum(jac**2, axis=0))
    norm[norm == 0] = 1.0
    _, sv, vt = np.linalg.svd(jac / norm, full_matrices=False)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_sv2 = np.where(sv > 0, 1.0 / sv**2, np.inf)
        cov = (vt.T * inv_sv2) @ vt
    cov = cov / np.outer(norm, norm) * s2
    return np.where(np.isfinite(cov), cov, np.inf)


def _identifiability(names, rel, at_bound, theta, t_contact, t_free, h, sigma_kg, rms):
    """Per fitted parameter: (identifiable, reason).

    Not identifiable: relative 1-sigma (Jacobian, start state unknown) above
    ``REL_LIMIT``, or at a bound of the fit range, or when the fitted dashpot
    does not act within the record: its signature in the force within a tap,
    ``(k0/Kg) max(relaxation in a contact, creep between taps)`` relative to
    the peak force, is below ``SIGNATURE`` times the relative RMS residual
    (cd then has only a lower bound and the surface shows only its glassy
    stiffness ``Kg = k0 + k_inf``), or it relaxes within one sample (cd has
    only an upper bound).
    """
    k_inf, k0, cd = theta[:3]
    th = theory(k0, k_inf, cd)
    relax = -math.expm1(-t_contact / th["tau_r"])  # fraction the dashpot relaxes in one contact
    creep = -math.expm1(-t_free / th["tau_c"])  # fraction it creeps between taps
    signature = k0 / th["k_g"] * max(relax, creep)
    frozen = signature < SIGNATURE * rms
    why_frozen = (
        f"the dashpot hardly moves within a tap (relaxes {100 * relax:.2g} % in contact, creeps "
        f"{100 * creep:.2g} % between taps; force signature {signature:.2g} of the peak < "
        f"{SIGNATURE:g} x RMS residual {rms:.2g})"
    )
    out = {}
    for i, name in enumerate(names):
        if name == "cd":
            extra = f"; {why_frozen}: cd has only a lower bound" if frozen else ""
        elif name in ("k0", "k_inf"):
            extra = f"; {why_frozen}: only k_g = k0 + k_inf is determined (1-sigma {sigma_kg:.2g})" if frozen else ""
        else:
            extra = ""
        if at_bound[i]:
            out[name] = (False, "at the bound of the fit range" + extra)
        elif not math.isfinite(rel[i]) or rel[i] > REL_LIMIT:
            out[name] = (False, f"relative 1-sigma uncertainty {rel[i]:.3g} > {REL_LIMIT:g} (Jacobian)" + extra)
        elif extra:
            out[name] = (False, extra[2:])
        elif name == "cd" and th["tau_r"] < h and th["tau_c"] < h:
            out[name] = (False, "the dashpot relaxes within one sample: cd has only an upper bound")
        else:
            out[name] = (True, f"relative 1-sigma uncertainty {rel[i]:.2g}")
    return out


def extract_full(
    df,
    meta: dict | None = None,
    force: str = "auto",
    start: dict | None = None,
    fit_hamaker: bool = False,
    *,
    kg_points: int = 10,
    k2: float | None = None,
    f2: float | None = None,
    q2: float | None = None,
    z1: float | None = None,
    f1: float | None = None,
    cutoff_hz: float | None = None,
    taper: float = 0.0,
    near_stride: int = 4,
    far_stride: int = 256,
    scan: bool = True,
    fit_offset: bool = True,
    state: str = "auto",
    substeps: int | None = None,
    **_unused,
) -> dict:
    """Whole-cycle inversion of a run table for ``k_inf, k0, cd`` (module docstring).

    Input handling, ``force``, ``Z1`` and the probe keywords are those of
    :func:`vetica_cli.extract.extract`.  ``start``: starting ``k_inf, k0, cd``
    (default: VETICA on the first taps, else a generic start); ``fit_hamaker``
    also fits ``H``; ``near_stride, far_stride``: residual decimation.
    Surface constants ``a0, H, vdw_on_surface`` and the tip radius come from
    the metadata (else the thesis defaults).

    Returns the dict of :func:`extract` (``{name: {value, theory, error_pct,
    spread}}`` for ``tau_c, k_g, k_r, tau_r, k0, k_inf, cd``, ``force``,
    ``taps``, ``method`` = 'full', ``info``) plus ``uncertainty`` (relative
    1-sigma of every quantity, from the Jacobian), ``identifiable``
    ({fitted parameter: bool}) and ``identifiable_reason``; with
    ``fit_hamaker`` also a ``hamaker`` entry.
    """
    from .signals.taps import find_taps

    meta = meta or {}
    if force not in FORCES:
        raise InputError(f"force {force!r} not allowed; choose one of: {', '.join(FORCES)}")
    if state not in STATES:
        raise InputError(f"state {state!r} not allowed; choose one of: {', '.join(STATES)}")
    force, cols = resolve_force(df, force)
    t_start = time.perf_counter()

    steady = _segment(df, "steady")
    if steady is None:
        steady = df if "segment" not in cols else df[(df["segment"] != "approach").to_numpy()]
        if not len(steady):
            raise InputError("the table has no rows outside the 'approach' segment to analyse")
    approach = _segment(df, "approach")
    t = _column(steady, "t", "the steady record")
    _check_time(t, "the steady record")
    z = _column(steady, "z_tip", "the steady record")
    h = (t[-1] - t[0]) / (len(t) - 1)
    if np.max(np.abs(np.diff(t) - h)) > 1e-3 * h:
        raise InputError("--method full needs uniformly sampled t (constant time step) in the steady record")

    params = meta.get("params") or {}
    probe = params.get("probe") or {}
    surface = params.get("surface") or {}
    a0 = float(surface.get("a0", COMMON_KEYS["a0"].default))
    hamaker = float(surface.get("hamaker", COMMON_KEYS["hamaker"].default))
    radius = float(probe.get("tip_radius", TIP_RADIUS))
    vdw = bool(surface.get("vdw_on_surface", COMMON_KEYS["vdw_on_surface"].default))
    hr6 = hamaker * radius / 6.0
    if substeps is None:  # the simulator's surface step: dt of the metadata, else one update per sample
        dt_sim = (params.get("numerics") or {}).get("dt")
        substeps = max(1, round(h / dt_sim)) if dt_sim else 1
    info: dict = {}
    warnings: list = []

    def force_of(seg, where):
        return force_column(seg, where, force, probe, info, k2=k2, f2=f2, q2=q2, cutoff_hz=cutoff_hz, taper=taper)

    f = steady_force(steady, force, cols, force_of, probe, f1, info)
    t_rec = time.perf_counter()
    z1_value, approach_rec = z1_reference(approach, z1, meta, force_of, info, need_approach=True)
    if approach_rec is None:
        warnings.append("no approach record: the dashpot is assumed undeformed at the first contact (Xd1 = 0)")

    taps = find_taps(f)
    n_taps = len(taps.contact)
    if n_taps < 1:
        raise InputError("too few taps: no complete tap in the record")
    if start is not None:
        start_values, start_source = {k: float(start[k]) for k in ("k_inf", "k0", "cd")}, "given"
    else:
        try:
            start_values, start_source = _vetica_start(t, z, f, z1_value, taps, kg_points), "vetica"
        except (InputError, ValueError, FloatingPointError, np.linalg.LinAlgError):
            start_values = None
        if start_values is None:
            start_values, start_source = _generic_start(z, f, taps), "generic"
    # the contact force scales with the stiffnesses: a start whose glassy stiffness is off the
    # loading slope by more than a decade is rescaled onto it (ratio k0/k_inf kept)
    slope = _loading_slope(z, f, taps)
    kg_start = start_values["k0"] + start_values["k_inf"]
    if not 0.1 <= kg_start / slope <= 10.0:
        factor = slope / kg_start
        start_values = {**start_values, "k_inf": start_values["k_inf"] * factor, "k0": start_values["k0"] * factor}
        start_source += f", stiffnesses rescaled x{factor:.3g} onto the loading slope {slope:.4g} N/m"
    t_start_done = time.perf_counter()

    def surface_fit(n):
        return SurfaceFit(z[:n], f[:n], h, z1_value, approach_rec, a0, radius, vdw, fit_offset=fit_offset,
                          near_stride=near_stride, far_stride=far_stride, substeps=substeps)  # fmt: skip

    theta0 = [start_values["k_inf"], start_values["k0"], start_values["cd"], hr6]
    model = surface_fit(len(z))
    # coarse to fine: scan and fit on the first SUB_PERIODS drive periods (the periodic state of
    # a whole number of periods is the window's), then refine on the whole window
    cycles = round(len(z) / taps.spacing) if taps.spacing > 0 else 0
    stages = []
    if cycles >= 2 * SUB_PERIODS:
        sub = surface_fit(round(len(z) * SUB_PERIODS / cycles))
        stages.append(fit_surface(sub, theta0, fit_hamaker=fit_hamaker, scan=scan, xtol=1e-6, max_nfev=25))
        theta0 = stages[-1]["theta"]
        model._state, model._last = sub._state, sub._last
    s0_start = stages[-1]["s0"] if stages else None
    stages.append(
        fit_surface(
            model,
            theta0,
            fit_hamaker=fit_hamaker,
            scan=scan and not stages,
            s0=s0_start,
            xtol=1e-8 if stages else 1e-10,
            max_nfev=8 if stages else 60,
        )
    )
    # the periodic state is an assumption (a record taken before the surface settled breaks it):
    # 'auto' releases it -- fits the dashpot position at the window start too -- when the
    # linearised model says that would remove more than half the residual; 'free' always does
    gain = _gn_gain(stages[-1]["residual"], stages[-1]["jac_free"])
    info["free_state_gain"] = gain
    if state == "free" or (state == "auto" and gain > 0.5):
        # on the whole window: one period holds too little of a slow dashpot's creep
        stages.append(
            fit_surface(
                model,
                stages[-1]["theta"],
                fit_hamaker=fit_hamaker,
                scan=False,
                s0=stages[-1]["s0"],
                xd0=stages[-1]["xd0"],
                xtol=1e-8,
                max_nfev=FREE_NFEV,
            )
        )
    fit = stages[-1]
    state_used = "free" if "xd0" in fit["names"] else "periodic"
    t_fit = time.perf_counter()

    theta = fit["theta"]
    names = fit["names"]
    res = fit["residual"]
    n_res = len(res)
    # covariance with the window's start state as an unknown too (conservative: does not lean
    # on the periodic state, which a record taken before the surface settled does not have)
    cov = _covariance(res, fit["jac_free"])
    cov_model = _covariance(res, fit["jac"])
    n_par = len(names)
    rel = np.sqrt(np.diag(cov))[:n_par]
    at_bound = (fit["x"] - fit["lo"] < 1e-6) | (fit["hi"] - fit["x"] < 1e-6)

    k_inf, k0, cd, hr6_fit = (float(v) for v in theta)
    values = theory(k0, k_inf, cd)
    # d ln(quantity) / d ln(k_inf, k0, cd): propagate the covariance to the derived constants
    kg = k0 + k_inf
    grads = {
        "k_inf": (1.0, 0.0, 0.0),
        "k0": (0.0, 1.0, 0.0),
        "cd": (0.0, 0.0, 1.0),
        "k_r": (1.0, 0.0, 0.0),
        "k_g": (k_inf / kg, k0 / kg, 0.0),
        "tau_r": (0.0, -1.0, 1.0),
        "tau_c": (k_inf / kg - 1.0, k0 / kg - 1.0, 1.0),
    }
    uncertainty = {}
    uncertainty_model = {}
    for name, g in grads.items():
        for c, dest in ((cov, uncertainty), (cov_model, uncertainty_model)):
            gv = np.zeros(len(c))
            gv[:3] = g
            dest[name] = float(math.sqrt(max(gv @ c @ gv, 0.0)))
    if fit_hamaker:
        uncertainty["hamaker"] = float(rel[3])
        uncertainty_model["hamaker"] = float(math.sqrt(cov_model[3, 3]))

    contact_s = float(np.median(taps.separation - taps.contact)) * h
    free_s = float(taps.spacing) * h - contact_s
    n_phys = sum(n in PARAMS for n in names)  # s0 and xd0 are nuisance parameters, fitted last
    rms_rel = math.sqrt(float(np.mean(res**2)))
    unconverged = _gn_gain(res, fit["jac"]) if fit["status"] == 0 else 0.0
    ident = _identifiability(names[:n_phys], rel, at_bound, theta, contact_s, free_s, h, uncertainty["k_g"], rms_rel)

    truth = None
    if all(surface.get(k) is not None for k in ("k0", "k_inf", "cd")):
        truth = theory(surface["k0"], surface["k_inf"], surface["cd"])
    out: dict = {}
    for name in NAMES:
        v = _finite_or_none(values[name])
        th = _finite_or_none(truth[name]) if truth else None
        err = 100.0 * abs(v - th) / abs(th) if (v is not None and th) else None
        out[name] = {"value": v, "theory": th, "error_pct": err, "spread": _spread_none()}
    if fit_hamaker:
        h_fit = 6.0 * hr6_fit / radius
        th = surface.get("hamaker")
        out["hamaker"] = {
            "value": h_fit,
            "theory": th,
            "error_pct": 100.0 * abs(h_fit - th) / th if th else None,
            "spread": _spread_none(),
        }
    out["force"] = force
    out["taps"] = n_taps
    out["method"] = "full"
    out["uncertainty"] = {k: _finite_or_none(v) for k, v in uncertainty.items()}  # None = unbounded
    if unconverged > 0.5:  # stopped by the evaluation budget far from the optimum
        why = f"the fit stopped before converging (one more Gauss-Newton step would remove {100 * unconverged:.0f} % of the residual)"
        ident = {k: (False, why + ("; " + v[1] if not v[0] else "")) for k, v in ident.items()}
    out["identifiable"] = {k: bool(v[0]) for k, v in ident.items()}
    out["identifiable_reason"] = {k: v[1] for k, v in ident.items()}

    rms_pct = 100.0 * math.sqrt(float(np.mean(res**2)))
    info["start"] = {"source": start_source, **start_values}
    info["fit"] = {
        "parameters": names,
        "nfev": [s["nfev"] for s in stages],
        "njev": [s["njev"] for s in stages],
        "status": fit["status"],
        "message": fit["message"],
        "residual_rms_pct": rms_pct,
        "residuals": int(n_res),
        "near_samples": model.near_samples,
        "decimation": {"near_stride": near_stride, "far_stride": far_stride, "block": model.block},
        "substeps": model.substeps,
        "surface_height_m": float(fit["s0"]),
        "surface_height_sigma_m": _finite_or_none(math.sqrt(cov[names.index("s0"), names.index("s0")]) * OFFSET_UNIT)
        if "s0" in names
        else None,
        "uncertainty_periodic_state": {k: _finite_or_none(v) for k, v in uncertainty_model.items()},
        "state": state_used,
        "surface_height_from_z1_m": float(fit["s0_z1"]),
        "surface_height_source": "fit (approach tap + steady window)" if model.fit_offset else "Z1",
        "xd0_m": fit["xd0"],
        "xd0_sigma_m": _finite_or_none(math.sqrt(cov[-1, -1]) * OFFSET_UNIT),
        "periodic_residual_m": fit["periodic_residual"],
        "model_passes": int(model.passes),
        "stages": len(stages),
    }
    if rms_pct > 1.0:
        warnings.append(
            f"the SLS model does not reproduce the measured force (RMS residual {rms_pct:.2g} % of the peak): "
            "a record taken before the surface settled, chatter, noise, or a surface that is not a Zener SLS"
        )
    if fit["status"] <= 0:
        warnings.append(f"least squares did not converge: {fit['message']}")
    info["timing_s"] = {
        "reconstruction": (t_rec - t_start) if force == "reconstructed" else 0.0,
        "start": t_start_done - t_rec,
        "fit": t_fit - t_start_done,
        "total": time.perf_counter() - t_start,
    }
    info["warnings"] = warnings + list(meta.get("warnings") or [])
    out["info"] = info
    return out
