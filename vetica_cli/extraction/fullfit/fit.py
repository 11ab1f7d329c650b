"""Bounded least squares of the force residuals of a :class:`~.model.SurfaceFit`
(trust-region reflective over the log-parameters), with the starting-cd scan of one
arm and the arm-by-arm start of several."""

from __future__ import annotations

import math

import numpy as np

from .model import SurfaceFit
from .uncertainty import LEVERAGE_MAX, leverage

CD_SCAN = np.logspace(-10, 2, 7)  # [kg/s] starting-cd scan, every two decades
# a start whose RMS residual after its Gauss-Newton step is below this fraction of the peak force
# has its dashpot's regime right: the scan then tries only the grid's cd within two decades of it
# (measured over the test records and the bench pixels, stiff, soft and 300 K, true and reconstructed
# force: every start this good either won the whole scan or lost to such a neighbour, by 1.4x at
# cd = 1e-3 kg/s, 16:1; the next-best far candidate cost >= 3.3x the start's)
GOOD_START_RMS = 0.05
HAMAKER_BOUNDS = (1e-24, 1e-14)  # [J] fit range of the Hamaker constant (fit_hamaker)
OFFSET_UNIT = 1e-10  # [m] unit of the surface height in the fit vector
OFFSET_RANGE = 5e-9  # [m] the fitted surface height stays within this of its reference (Z1 or the start)
XD0_RANGE = 1e-6  # [m] bound of a fitted dashpot start position
LEVERAGE_ROUNDS = 3  # times a fit leaves out rows of leverage above LEVERAGE_MAX and resumes (solve)


class FitVector:
    """The fit vector ``ln k_inf, ln k_1, ln cd_1, ... [, ln(H R/6)] [, s0/OFFSET_UNIT]
    [, xd0_i/OFFSET_UNIT]`` of one model: its names, bounds and start, and the scaled
    residuals and Jacobian at a point (each point evaluated once: least squares asks
    for both).  ``names`` are the surface model's ``parameter_keys`` then ``hamaker``
    (fitted as ``H R/6``), ``s0``, ``xd0`` (one arm) or ``xd0_1..N``."""

    def __init__(self, model: SurfaceFit, theta0, bounds: dict, fit_hamaker: bool, s0, xd0, s0_ref=None):
        self.model = model
        p = model.n_params
        self.fit_idx = list(range(p)) + ([p] if fit_hamaker else [])
        self.ndir = model.ndir if fit_hamaker else model.ndir - 1
        self.base = np.array(theta0, dtype=float)
        names = [list(bounds)[i] for i in self.fit_idx]
        r = model.radius
        lo = list(np.log([bounds[n][0] * (r / 6 if n == "hamaker" else 1.0) for n in names]))
        hi = list(np.log([bounds[n][1] * (r / 6 if n == "hamaker" else 1.0) for n in names]))
        x0 = list(np.log(self.base[self.fit_idx]))
        self.s0_ref = model.initial_offset(self.base) if s0_ref is None else float(s0_ref)
        if model.fit_offset:
            s0 = self.s0_ref if s0 is None else s0
            names.append("s0")
            x0.append(s0 / OFFSET_UNIT)
            lo.append((self.s0_ref - OFFSET_RANGE) / OFFSET_UNIT)
            hi.append((self.s0_ref + OFFSET_RANGE) / OFFSET_UNIT)
        n = model.n_arms
        self.free = xd0 is not None
        if self.free:
            xd0 = np.broadcast_to(np.asarray(xd0, float), (n,))
            names += ["xd0"] if n == 1 else [f"xd0_{i}" for i in range(1, n + 1)]
            x0 += list(xd0 / OFFSET_UNIT)
            lo += [-XD0_RANGE / OFFSET_UNIT] * n
            hi += [XD0_RANGE / OFFSET_UNIT] * n
        self.names = names
        self.lo, self.hi = np.array(lo), np.array(hi)
        self.x0 = np.clip(np.array(x0), self.lo + 1e-9, self.hi - 1e-9)
        self.state_cols = list(range(p + 2, p + 2 + n))
        self.cols = self.fit_idx + ([p + 1] if model.fit_offset else []) + (self.state_cols if self.free else [])
        self.scale = np.ones(len(self.cols))
        self.scale[len(self.fit_idx) :] = OFFSET_UNIT
        self._cache = {}

    def unpack(self, x):
        """``(theta, s0 or None, xd0 (N,) or None)`` [SI] of a fit vector."""
        theta = self.base.copy()
        nf = len(self.fit_idx)
        theta[self.fit_idx] = np.exp(x[:nf])
        n = self.model.n_arms
        return (
            theta,
            x[nf] * OFFSET_UNIT if self.model.fit_offset else None,
            np.asarray(x[len(x) - n :]) * OFFSET_UNIT if self.free else None,
        )

    def evaluate(self, x):
        """Scaled residuals, their Jacobian, and the columns of the window's start state."""
        key = x.tobytes()
        if key not in self._cache:
            self._cache.clear()
            model = self.model
            theta, s0x, xd0x = self.unpack(x)
            f, jac = model.evaluate(theta, s0x, ndir=self.ndir, xd0=xd0x)
            self._cache[key] = (
                (f - model.f) / model.scale,
                jac[:, self.cols] * self.scale / model.scale,
                jac[:, self.state_cols] * OFFSET_UNIT / model.scale,
            )
        return self._cache[key]

    def cost(self, x) -> float:
        """Sum of squared scaled residuals, without derivatives."""
        theta, s0x, xd0x = self.unpack(x)
        f, _ = self.model.evaluate(theta, s0x, ndir=0, xd0=xd0x)
        return float(np.sum(((f - self.model.f) / self.model.scale) ** 2))

    def gn_step(self, x, fixed=(), clip=2.0):
        """``x`` after one Gauss-Newton step on every component but ``fixed``, each clipped
        to ``+-clip`` and kept inside the bounds."""
        others = [i for i in range(len(x)) if i not in fixed]
        res, jac, _ = self.evaluate(x)
        step = np.clip(np.linalg.lstsq(jac[:, others], -res, rcond=None)[0], -clip, clip)
        x = x.copy()
        x[others] = np.clip(x[others] + step, self.lo[others] + 1e-9, self.hi[others] - 1e-9)
        return x


def scan_cd(vec: FitVector, whole: bool = False, off_plateau: bool = False) -> tuple[np.ndarray, list, bool]:
    """Starting cd of one arm: scan ``CD_SCAN`` (and the start) with one Gauss-Newton step on
    the other parameters at each cd (a cheap profile: a wrong starting k_inf must not make
    the glassy plateau of large cd look best); after a good start (``GOOD_START_RMS``) only the
    grid's cd within two decades of it (``whole``: the whole grid, whatever the start).
    Returns the best point, ``[(cost, x)]`` and whether the best is the grid's frozen end after a
    start that was not good -- a plateau where cd has no gradient, which a fit may not leave
    (``off_plateau``: the best point below it instead; :func:`fit_surface`'s caller then fits
    from both and keeps the better)."""
    lo, hi = vec.lo, vec.hi
    scanned = []
    cd0 = math.exp(vec.x0[2])
    good = False
    for cd in [cd0] + list(CD_SCAN):
        good = bool(scanned) and not whole and scanned[0][0] <= GOOD_START_RMS**2 * len(vec.model.f)
        if good and abs(math.log10(cd / cd0)) > 2.0:
            continue  # a good start: its regime is right, a cd decades away is not tried (GOOD_START_RMS)
        x = vec.x0.copy()
        x[2] = np.clip(math.log(cd), lo[2] + 1e-9, hi[2] - 1e-9)
        vec.model.reset()
        x = vec.gn_step(x, fixed=(2,))
        scanned.append((vec.cost(x), x))
    vec.model.reset()
    frozen = min(math.log(CD_SCAN[-1]), hi[2] - 1e-9) - 1e-9
    best = min(scanned, key=lambda c: c[0])[1]
    plateau = not good and best[2] >= frozen
    if plateau and off_plateau:
        below = [c for c in scanned if c[1][2] < frozen]
        best = min(below, key=lambda c: c[0])[1] if below else best
    return best, scanned, plateau


# the arm's spring over this grid of k_1 / k_inf (8 a decade), each with the surface height moved by each of
# HEIGHT_PROFILE [OFFSET_UNIT], at a fitted dashpot (scan_arm): an arm that relaxes within a few samples shows its spring
# only in the impact, and the right valley is as narrow in the height as in the spring.  On a noise-free 16:1 record
# (k_inf 4, k0 64 N/m, cd 1e-7 kg/s: tau 1.6 ns, 13 samples of 0.125 ns) the fit found cd within 4 % with k0 1.8 N/m
# and the height 17 pm off (RMS 0.54 % of the peak); at the truth the model fits to 3e-6 with the height within 1 pm,
# to 0.4 % with it 17 pm off; a profile of k0 alone, with Gauss-Newton steps on the height at each point, stayed at the
# fit's height
ARM_PROFILE = np.logspace(-1.0, 3.0, 33)
HEIGHT_PROFILE = np.linspace(-0.6, 0.6, 13)
ARM_PROFILE_REFINE = 3  # the profile's best points each given Gauss-Newton steps on k_inf and the height, the best kept


def scan_arm(vec: FitVector, x) -> tuple[np.ndarray, list]:
    """The best of :data:`ARM_PROFILE` x :data:`HEIGHT_PROFILE` for one arm's spring ``k_1`` and the surface height
    (where fitted) about the fit vector ``x``, its dashpot held: the profile the cd scan (:func:`scan_cd`) does not
    take.  The :data:`ARM_PROFILE_REFINE` best points get three Gauss-Newton steps on the other parameters (``k_1``
    and ``cd_1`` held); the best of those is returned, with ``[(cost, x)]`` of the grid."""
    lo, hi = vec.lo, vec.hi
    x = np.asarray(x, float)
    j = vec.names.index("s0") if "s0" in vec.names else None
    scanned = []
    for ratio in ARM_PROFILE:
        for ds in HEIGHT_PROFILE if j is not None else (0.0,):
            y = x.copy()
            y[1] = np.clip(x[0] + math.log(ratio), lo[1] + 1e-9, hi[1] - 1e-9)
            if j is not None:
                y[j] = np.clip(x[j] + ds, lo[j] + 1e-9, hi[j] - 1e-9)
            vec.model.reset()
            scanned.append((vec.cost(y), y))
    best = []
    for _, y in sorted(scanned, key=lambda c: c[0])[:ARM_PROFILE_REFINE]:
        vec.model.reset()
        for _ in range(3):
            y = vec.gn_step(y, fixed=(1, 2))
        best.append((vec.cost(y), y))
    vec.model.reset()
    return min(best, key=lambda c: c[0])[1], scanned


def fit_surface(
    model: SurfaceFit, theta0, bounds: dict, fit_hamaker=False, scan=True, max_nfev=60, xtol=1e-10, s0=None, xd0=None,
    s0_ref=None, whole_scan=False, off_plateau=False, start=None, arm_profile=False,
) -> dict:  # fmt: skip
    """Bounded least squares of the force residuals (trust-region reflective).

    Fit vector: :class:`FitVector`.  ``theta0`` = starting ``(k_inf, k_1, cd_1, ...,
    H R/6)`` [SI; H R/6 in J m, held fixed unless ``fit_hamaker``]; ``bounds`` = fit
    range [SI] of each parameter and ``hamaker``, in that order; ``s0`` the starting
    surface height (default: from Z1 or the contacts, :meth:`SurfaceFit.initial_offset`)
    and ``s0_ref`` the centre of its range (default the same).  ``xd0``: None =
    periodic state at the window start, else the starting dashpot positions [m] of a
    fitted start state (``state='free'``).  ``scan`` (one arm): first replace the
    starting cd by the best of ``CD_SCAN`` (and itself) at the starting stiffnesses
    (:func:`scan_cd`; ``whole_scan``: the whole grid however good the start; ``off_plateau``: the
    best cd below the grid's frozen end where the frozen end is best after a poor start).  ``start``: a fit
    vector to start from instead (no scan; e.g. another of a scan's points, ``out['scan']``, on a model built
    from the same ``theta0`` and ``bounds``, so the same height range; ``arm_profile``: from the best of the arm's
    spring and the height profiled about that start at its dashpot instead, :func:`scan_arm`).  Returns the fit (parameters,
    residuals, Jacobian, counts; ``scan`` the scan's ``[(cost, x)]``, ``start_x`` the vector it started from).
    """
    vec = FitVector(model, theta0, bounds, fit_hamaker, s0, xd0, s0_ref)
    if start is not None:
        x0, scanned, plateau = np.clip(np.asarray(start, float), vec.lo + 1e-9, vec.hi - 1e-9), [], False
        if arm_profile and model.n_arms == 1:
            x0, scanned = scan_arm(vec, x0)
    elif scan and model.n_arms == 1:
        x0, scanned, plateau = scan_cd(vec, whole_scan, off_plateau)
    else:
        x0, scanned, plateau = vec.x0, [], False
    out = solve(vec, x0, max_nfev, xtol, scanned)
    out["plateau_start"] = plateau
    out["start_x"] = x0
    return out


def solve(vec: FitVector, x0, max_nfev=60, xtol=1e-10, scanned=()) -> dict:
    """Least squares from ``x0`` on the fit vector ``vec`` (:func:`fit_surface`).  A steady
    residual row whose leverage exceeds :data:`LEVERAGE_MAX` (with the window's start state
    among the unknowns) is left out with its neighbours and the fit resumed, up to
    :data:`LEVERAGE_ROUNDS` times: one sample that decides a direction of the fit is one where
    the force's sensitivity to the surface diverges -- the pull's gain reaching 1 as a soft
    surface snaps to the tip or springs back from it -- where a linear error bar means nothing
    (on stripped 300 K records of a 5:1 surface, Kg 10.5 N/m, such rows had leverage 0.93-1.00
    and the tap-robust 1-sigma read 36-165 % on answers within 0.5 % of the truth; a surface
    that does not snap: at most 0.18, on the 1,554 rows of one period)."""
    from scipy.optimize import least_squares  # lazy: the CLI starts without scipy.optimize

    model = vec.model
    dropped = []
    for _ in range(LEVERAGE_ROUNDS + 1):
        sol = least_squares(
            lambda x: vec.evaluate(x)[0], x0, jac=lambda x: vec.evaluate(x)[1], bounds=(vec.lo, vec.hi),
            method="trf", x_scale="jac", xtol=xtol, ftol=1e-12, gtol=1e-12, max_nfev=max_nfev,
        )  # fmt: skip
        res, jac, jac_xd0 = vec.evaluate(sol.x)
        # Jacobian with the window's start state as unknowns too (already so when it is fitted)
        jac_free = jac if vec.free else np.column_stack([jac, jac_xd0])
        rows = np.flatnonzero(leverage(jac_free) > LEVERAGE_MAX)
        if not len(rows) or len(dropped) >= LEVERAGE_ROUNDS:
            break
        gone = model.drop_rows(rows)
        if not len(gone):
            break
        dropped.append([int(i) for i in gone])
        vec._cache.clear()
        x0 = sol.x
    theta, s0_fit, _ = vec.unpack(sol.x)
    return {
        "names": vec.names,
        "x": sol.x,
        "theta": theta,
        "s0": s0_fit if s0_fit is not None else model.pinned_offset(theta),
        "s0_ref": vec.s0_ref,
        "residual": res,
        "cost": float(res @ res),
        "xd0": model.window_start_xd,
        "periodic_residual": float(model.periodic_residual),
        "jac": jac,
        "jac_free": jac_free,
        "lo": vec.lo,
        "hi": vec.hi,
        "nfev": int(sol.nfev),
        "njev": int(sol.njev or 0),
        "status": int(sol.status),
        "message": str(sol.message),
        "scan": list(scanned),
        "dropped": dropped,
    }
