"""The whole-cycle fit of the ``hertz`` surface (MDR, Popov & Hess 2015): ``vetica extract REC --method full``
on a record of a sphere on a generalized-Maxwell half-space (the record's metadata names the
model, ``--fit-model hertz`` names it for a record without one).

The measured tip trajectory drives the MDR surface of :mod:`vetica_cli.core.mdr` (the
simulator's own element update, once per sample: ``mdr.prescribed``) and bounded least
squares finds the Prony series ``e_inf, e_1, tau_1, ..., e_N, tau_N`` (Pa, s) for which the
predicted force matches the measured one::

    minimise  sum_i (Fts_model(t_i) - F_i)^2 / F_peak^2
    over      ln e_inf, ln e_i, ln tau_i, the surface height s0 [, ln H R]

Stated inputs: the tip radius ``R`` and the sample's Poisson ratio ``nu`` (options, else the
metadata, else the thesis's 10 nm and 0.5, said as assumed), ``a0`` and ``H`` as the SLS fit
takes them (``H R`` fitted when unknown).  The attraction acts on the tip only (DMT):
``Fts = -sum f_i - H R/(6 a0^2)`` in contact, ``-H R/(6 d^2)`` with ``d`` the gap to the centre
element out of contact.

* **Window**: the first ``FIT_PERIODS`` drive periods of the steady record (a whole number of
  periods with the base held: its periodic state is the record's), the model stepped every
  ``k``-th sample (``k h <= FORWARD_STEP``, 1 ns).  **Periodic state**: the elements' dashpots at
  the window start solve ``ud_end(ud0) = ud0``, by the fixed-point iteration
  ``ud0 <- ud0 + (ud_end - ud0)/(1 - exp(-T/tau_a))`` per arm (exact for an error that decays with
  the arm's own time; Anderson-mixed), to ``PERIODIC_TOL`` = 1e-12 of the indentation: the
  Jacobian is a finite difference of ``DIFF_STEP`` in the log-parameters, and a state converged to
  1e-7 (before) put ~10 % noise into it -- two-arm fits stalled far from the optimum.
* **Grid**: ``mdr.auto_elements`` at ``GRID_REL`` (1e-4) of Hertz for depths ``[0.6, 1.2]`` of
  the start's deepest indentation (``R`` and the record's tip positions only), fixed during the
  fit.  The model error limits what a slow arm can show: a record simulated on the simulator's
  auto grid (0.1 % of Hertz) differs from the fit's model by ~0.02 % of the peak force RMS, more
  than a second arm's signature at tau f1 >= 0.1 (docs/hertz.md).
* **Surface height** ``s0``: fitted within 2 nm of its start ``Z1 - a0`` (``Z1`` the record's
  first force minimum of the approach), else the steady contacts.  Not pinned to ``Z1``: the
  record's approach window does not hold the first contact (its ``Z1`` is a graze's separation
  on a surface already dented: 0.12 nm low on the two-arm record at tau f1 = 0.1).  With the
  periodic state converged the height is fitted to a few pm (a 2 pm error costs 0.05 % of the
  peak RMS, 20 times the model error).
* **Start**: the glassy modulus from the peak force and depth by Hertz; then a scan of ``tau_1``
  over 1e-9 .. 1e-2 s (one decade apart, below the bound) with a split of the modulus, the best
  fitted; arms added one at a time (``tau`` 1e-2 .. 1e2 times the present arms', the best
  ``ARM_TRIES`` candidates fitted briefly), and the best continued to convergence
  (``FINAL_NFEV``).  ``tau`` is bounded by ``TAU_MAX_WINDOWS`` windows: a slower arm is a spring
  and an offset of the height.
* **Uncertainty**: ``cov = s^2 (J^T J)^-1`` in log-parameters (relative 1-sigma), as the SLS fit.
  **Identifiability**: a parameter at a bound or with a relative 1-sigma above ``REL_LIMIT``
  (10 %) is ``unidentified``; when an arm is, every parameter is (the record resolves fewer arms
  than fitted, and the others take the lost arm's share: measured at tau f1 = 1, where the fit
  merges both arms into one and lets the other vanish).
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.optimize import least_squares

from ...core import mdr
from ...core import tapping as T
from ...errors import InputError
from ...signals.taps import find_taps
from ... import surfaces
from ..result import ExtractionResult, estimates

FIT_PERIODS = 1  # drive periods of the window fitted (its periodic state is the record's)
NEAR_STRIDE = 1  # residual every NEAR_STRIDE-th model step within NEAR_GAP of the surface
FAR_STRIDE = 8
# the model steps every k-th sample, k the largest divisor of the window's samples with k h <= FORWARD_STEP:
# the element update is exact for a tip moving linearly between steps (measured on a two-arm record of
# the simulator's grid, 125 ps samples: force RMS error 1.16e-7 of the peak stepping every sample,
# 1.26e-7 every 8th, 1 ns)
FORWARD_STEP = 1e-9  # [s]
GRID_REL = 1e-4  # the fit grid's elastic force accuracy (mdr.auto_elements)
NEAR_GAP = 3e-9  # [m]
TAU_SCAN = 10.0 ** np.arange(-9, -1)  # [s] start scan of tau_1
ARM_STEPS = (1e-2, 1e-1, 10.0, 100.0)  # a new arm's tau relative to the present arms'
ARM_TRIES = 4  # candidates fitted (ARM_NFEV evaluations at most each)
ARM_NFEV = 30  # (the last fit continues the best to FINAL_NFEV)
OFFSET_UNIT = 1e-9  # [m] the surface height's fit unit
HEIGHT_BAND = 2e-9  # [m] the height's freedom around its start
# the periodic state to 1e-12 of the indentation: the Jacobian is taken by finite differences of
# DIFF_STEP in the log-parameters, and a state converged to only 1e-7 put ~10 % noise into it
# (measured while developing: a two-arm fit with the height pinned stalled at tau_2 +18 % after 100 evaluations
# with 1e-7 and 1e-6; 1e-12 and 1e-5 reached 0.3 % in 62)
PERIODIC_TOL = 1e-12
PERIODIC_PASSES = 60
DIFF_STEP = 1e-5
TAU_MAX_WINDOWS = 100.0  # a relaxation time's upper bound in fit windows (slower: a spring and an offset)
FINAL_NFEV = 200  # evaluations of the last fit (all arms, from the best candidate)
MODEL_REL = 1e-3  # the hertz model's stated accuracy (elements: auto): the model-error term of the 1-sigma
REL_LIMIT = 0.3  # relative 1-sigma (with the model-accuracy term) above which a parameter is unidentified
DEFAULT_NU = 0.5
DEFAULT_RADIUS = 10e-9


class HertzForward:
    """The MDR surface driven by the record's tip positions: force at every sample (module docstring)."""

    def __init__(self, z, h, radius, nu, a0, period_samples, z_ref, rel=None):
        self.z, self.h = np.asarray(z, float), float(h)
        self.radius, self.nu, self.a0 = radius, nu, a0
        self.period_samples = period_samples
        depth = max(z_ref - a0 - float(np.min(z)), 0.05e-9)
        rel = GRID_REL if rel is None else rel
        m, xm = mdr.auto_elements(radius, 1.2 * depth, rel=rel, margin=1.3, delta_lo=0.6 * depth)
        self.x, self.g, self.w = mdr.element_grid(radius, xm, m)
        self.ud = None  # periodic state of the last evaluation (warm start)
        self.passes = 0
        self.periodic_residual = math.nan

    def run(self, e_inf, e, tau, s0, hr6):
        s = 1.0 - self.nu**2
        e_s = np.asarray(e, float) / s
        q, arm, vec, vi, lam, urow, sm = mdr.surface_tables(e_inf / s, e_s, e_s * np.asarray(tau, float), self.h)
        m_el, n_arms = len(self.g), len(e_s)
        zs = self.z - s0 - self.a0
        ud = np.zeros((m_el, n_arms)) if self.ud is None or self.ud.shape != (m_el, n_arms) else self.ud.copy()
        o = mdr.new_outputs(m_el, n_arms)
        t_win = (len(zs) - 1) * self.h
        weight = 1.0 / -np.expm1(-t_win / np.asarray(tau, float))
        scale = max(float(np.max(-zs)), 1e-10)
        hist_x, hist_g = [], []
        for _ in range(PERIODIC_PASSES):
            u0 = ud.copy()
            f, hi, uc = mdr.prescribed_centre(zs, self.h, ud, self.g, self.w, q, arm, vec, vi, lam, sm, urow, o)
            self.passes += 1
            step = (ud - u0) * weight[None, :]
            err = float(np.max(np.abs(ud - u0))) / scale
            if err <= PERIODIC_TOL:
                break
            gx = (u0 + step).ravel()
            hist_x.append(u0.ravel())
            hist_g.append(gx)
            if len(hist_x) > 4:
                hist_x.pop(0)
                hist_g.pop(0)
            if len(hist_x) >= 2:
                fs = np.array([b - a for a, b in zip(hist_x, hist_g)])
                df = np.diff(fs, axis=0).T
                dg = np.diff(np.array(hist_g), axis=0).T
                gamma = np.linalg.lstsq(df, gx - u0.ravel(), rcond=None)[0]
                gx = gx - dg @ gamma
            ud = gx.reshape(m_el, n_arms)
        self.ud = u0
        self.periodic_residual = err * scale
        fa0 = hr6 / self.a0**2
        d = self.z - s0 + self.g[0] - uc  # the tip's surface over the centre element to that element
        out = np.where(hi > 0, f - fa0, -hr6 / np.maximum(d, 0.5 * self.a0) ** 2)
        return out


def _theta_values(theta, n_arms, fit_hr):
    e_inf = math.exp(theta[0])
    e = np.exp(theta[1 : 1 + 2 * n_arms : 2])
    tau = np.exp(theta[2 : 2 + 2 * n_arms : 2])
    s0 = theta[1 + 2 * n_arms] * OFFSET_UNIT
    return e_inf, e, tau, s0


def run_hertz_fit(record, opts: dict, consts: dict, method_key: str) -> ExtractionResult:
    """Fit the hertz surface to ``record`` (module docstring)."""
    t0 = time.perf_counter()
    t, z, f = record.t, record.z, record.f
    h = (t[-1] - t[0]) / (len(t) - 1)
    a0 = float(consts["a0"][0])
    radius = float(consts["tip_radius"][0])
    nu_src = "given" if opts.get("nu") is not None else None
    nu = opts.get("nu")
    if nu is None:
        nu = record.surface.get("nu") if record.model.key == "hertz" else None
        nu_src = "metadata" if nu is not None else "assumed: 0.5 (incompressible)"
        nu = DEFAULT_NU if nu is None else nu
    hamaker = consts["hamaker"][0]
    fit_hr = opts["fit_hamaker"] if opts["fit_hamaker"] is not None else hamaker is None
    taps = find_taps(f)
    if len(taps.contact) < 1:
        raise InputError("too few taps: no complete tap in the record")
    period = int(round(taps.spacing)) if taps.spacing > 0 else len(z)
    n = min(len(z), FIT_PERIODS * period + 1) if taps.spacing > 0 else len(z)
    k_dec = next(k for k in range(max(1, int(FORWARD_STEP / h)), 0, -1) if (n - 1) % k == 0)
    zw, fw = z[:n:k_dec], f[:n:k_dec]
    h_fit = h * k_dec
    z1 = record.z1 if record.z1 is not None and math.isfinite(record.z1) else None
    z_ref = z1 if z1 is not None else float(np.median(z[taps.contact]))
    s0_start = z_ref - a0
    hr6 = float(hamaker) * radius / 6.0 if hamaker is not None else max(-float(np.min(f)), 1e-12) * a0 * a0
    n_arms = opts["arms"] or (len(record.surface.get("arms") or [1]) if record.model.key == "hertz" else 1)
    fwd = HertzForward(zw, h_fit, radius, nu, a0, period // k_dec, z_ref)
    fpeak = float(np.max(fw))
    near = (zw - s0_start) < NEAR_GAP
    idx = np.arange(len(zw))
    sel = (near & (idx % NEAR_STRIDE == 0)) | (idx % FAR_STRIDE == 0)
    sel[0] = False  # the first sample is the window start (no force computed there)

    def residual(theta, k_arms, hr_free):
        e_inf, e, tau, s0 = _theta_values(theta, k_arms, hr_free)
        hr = math.exp(theta[-1]) if hr_free else hr6
        return (fwd.run(e_inf, e, tau, s0, hr)[sel] - fw[sel]) / fpeak

    # start: the glassy modulus from the peak force and depth by Hertz (E = 3 F (1 - nu^2)/(4 sqrt(R) d^1.5))
    depth = max(s0_start + a0 - float(np.min(zw)), 0.05e-9)
    e_g = 3.0 * fpeak * (1.0 - nu**2) / (4.0 * math.sqrt(radius) * depth**1.5)
    s0u = s0_start / OFFSET_UNIT
    # the height: free within HEIGHT_BAND of the start.  (Pinned to Z1 - a0 it failed: the record's Z1
    # is the minimum before the first repulsive sample, and on a soft sphere the first taps are
    # attractive only and leave the surface dented -- measured Z1 0.25 nm low on the record.)
    band = HEIGHT_BAND / OFFSET_UNIT
    bounds_lo = {"e": math.log(1e3), "tau": math.log(1e-12), "s0": s0u - band, "hr": -200.0}
    tau_max = TAU_MAX_WINDOWS * (n - 1) * h
    bounds_hi = {"e": math.log(1e13), "tau": math.log(tau_max), "s0": s0u + band, "hr": 200.0}

    def vec(e_inf, arms, s0=s0u, hr=None):
        v = [math.log(e_inf)] + [x for a in arms for x in (math.log(a[0]), math.log(a[1]))] + [s0]
        if fit_hr:
            v.append(math.log(hr if hr is not None else 6 * hr6) - math.log(6))
        return np.array(v)

    def bounds(k_arms):
        lo = [bounds_lo["e"]] + [b for _ in range(k_arms) for b in (bounds_lo["e"], bounds_lo["tau"])] + [bounds_lo["s0"]]
        hi = [bounds_hi["e"]] + [b for _ in range(k_arms) for b in (bounds_hi["e"], bounds_hi["tau"])] + [bounds_hi["s0"]]
        if fit_hr:
            lo.append(bounds_lo["hr"])
            hi.append(bounds_hi["hr"])
        return np.array(lo), np.array(hi)

    def solve(x0, k_arms, nfev):
        lo, hi = bounds(k_arms)
        x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
        return least_squares(residual, x0, args=(k_arms, fit_hr), bounds=(lo, hi), method="trf", x_scale="jac",
                             diff_step=DIFF_STEP, xtol=1e-10, ftol=1e-12, gtol=1e-12, max_nfev=nfev)  # fmt: skip

    scan = []
    for tau in TAU_SCAN[TAU_SCAN < tau_max]:
        for frac in (0.3, 0.7):
            x = vec(e_g * (1 - frac), [(e_g * frac, tau)])
            fwd.ud = None
            scan.append((float(np.sum(residual(x, 1, fit_hr) ** 2)), x))
    scan.sort(key=lambda c: c[0])
    best = None
    for _, x in scan[:2]:
        fwd.ud = None
        fit = solve(x, 1, 30)
        if best is None or fit.cost < best.cost:
            best = fit
    k = 1
    while k < n_arms:
        k += 1
        ev = best.x
        e_inf, e, tau, _ = _theta_values(ev, k - 1, fit_hr)
        tail = list(ev[1 + 2 * (k - 1) :])
        cands = []
        for j in range(k - 1):
            for step in ARM_STEPS:
                for source in ("arms", "e_inf"):  # the new arm's modulus taken from the arms or from e_inf
                    if source == "arms":
                        ei0, kept, new = e_inf, e * 0.7, 0.3 * float(np.sum(e))
                    else:
                        ei0, kept, new = 0.5 * e_inf, e, 0.5 * e_inf
                    arms = [(a, b) for a, b in zip(kept, tau)] + [(new, tau[j] * step)]
                    arms.sort(key=lambda a: a[1])
                    x = np.array([math.log(ei0)] + [v for a in arms for v in (math.log(a[0]), math.log(a[1]))] + tail)
                    fwd.ud = None
                    cands.append((float(np.sum(residual(x, k, fit_hr) ** 2)), x))
        cands.sort(key=lambda c: c[0])
        tried = []
        for _, x in cands[:ARM_TRIES]:  # the best few fitted, the best fit kept (the landscape has several basins)
            fwd.ud = None
            tried.append(solve(x, k, ARM_NFEV))
        best = min(tried, key=lambda r: r.cost)
    fwd.ud = None
    fit = solve(best.x, n_arms, FINAL_NFEV)  # the last fit to convergence
    res, jac = fit.fun, fit.jac
    e_inf, e, tau, s0 = _theta_values(fit.x, n_arms, fit_hr)
    order = np.argsort(tau)
    e, tau = e[order], tau[order]
    dof = max(len(res) - len(fit.x), 1)
    s2 = float(res @ res) / dof
    try:
        cov = s2 * np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        cov = np.full((len(fit.x), len(fit.x)), np.inf)
    # the model's own accuracy: the hertz model is defined to MODEL_REL of Hertz (elements: auto), so a
    # record of it may differ from the fit's model by as much as a grid of that accuracy does; the
    # parameters' shift that difference causes (linearised) is added to the 1-sigma in quadrature
    alt = HertzForward(zw, h_fit, radius, nu, a0, period // k_dec, z_ref, rel=MODEL_REL)
    e_u, tau_u = _theta_values(fit.x, n_arms, fit_hr)[1:3]
    hr_fit = math.exp(fit.x[-1]) if fit_hr else hr6
    d_model = alt.run(e_inf, e_u, tau_u, s0, hr_fit)[sel] / fpeak - (res + fw[sel] / fpeak)
    shift = np.linalg.lstsq(jac, d_model, rcond=None)[0]
    cov = cov + np.outer(shift, shift)
    rel = np.sqrt(np.abs(np.diag(cov)))
    col = [0] + [c for i in order for c in (1 + 2 * i, 2 + 2 * i)]
    model = surfaces.get("hertz").with_arms(n_arms)
    params = {"e_inf": e_inf, "arms": [{"e": float(a), "tau": float(b)} for a, b in zip(e, tau)], "nu": nu,
              "elements": "auto"}  # fmt: skip
    values = model.theory(params)
    grads = model.log_gradients(params)
    cov_p = cov[np.ix_(col, col)]
    sigma = {q: float(math.sqrt(max(float(np.asarray(g) @ cov_p @ np.asarray(g)), 0.0))) for q, g in grads.items()}
    units = {q: v.unit for q, v in model.quantities.items()}
    own = record.model.for_params(record.surface) if record.truth else None
    truth = dict(record.truth) if own is not None and own.key == "hertz" and own.n_arms == n_arms else None
    est = estimates(values, units, truth, sigmas=sigma)
    rms = 100.0 * math.sqrt(float(np.mean(res**2)))
    info = dict(record.info)
    info["fit"] = {
        "model": "hertz",
        "parameters": list(model.parameter_keys) + ["s0"] + (["hamaker_radius"] if fit_hr else []),
        "arms": n_arms,
        "residual_rms_pct": rms,
        "residuals": int(len(res)),
        "nfev": int(fit.nfev),
        "status": int(fit.status),
        "message": fit.message,
        "elements": int(len(fwd.g)),
        "x_max_m": float(fwd.x[-1] + 0.5 * (fwd.x[1] - fwd.x[0])) if len(fwd.x) > 1 else None,
        "window_periods": FIT_PERIODS,
        "surface_height_m": float(s0),
        "surface_height_start_m": float(s0_start),
        "periodic_residual_m": float(fwd.periodic_residual),
        "model_passes": int(fwd.passes),
    }
    info["constants"] = {
        "tip_radius": {"value": radius, "source": consts["tip_radius"][1]},
        "nu": {"value": nu, "source": nu_src},
        "a0": {"value": a0, "source": consts["a0"][1]},
        "hamaker_radius": {"value": 6.0 * (math.exp(fit.x[-1]) if fit_hr else hr6),
                           "source": "fitted" if fit_hr else consts["hamaker"][1]},  # fmt: skip
        "surface_height": {"value": float(s0), "source": "fitted (start: Z1 - a0)" if z1 is not None else "fitted"},
    }
    warnings = list(record.meta_warnings)
    if rms > 1.0:
        warnings.append(f"the hertz model does not reproduce the measured force (RMS residual {rms:.2g} % of the peak)")
    if fit.status <= 0:
        warnings.append(f"least squares did not converge: {fit.message}")
    lo, hi = bounds(n_arms)
    names = ["e_inf"] + [f"{p}_{i}" for i in range(1, n_arms + 1) for p in ("e", "tau")]
    at_bound = {nm for nm, j in zip(names, col) if fit.x[j] - lo[j] < 1e-6 or hi[j] - fit.x[j] < 1e-6}
    verdict = {}
    for name, j in zip(names, range(len(col))):
        if name in at_bound:
            verdict[name] = (False, "at the bound of the fit range")
        elif not math.isfinite(rel[col[j]]) or rel[col[j]] > REL_LIMIT:
            verdict[name] = (False, f"relative 1-sigma uncertainty {rel[col[j]]:.3g} > {REL_LIMIT:g} (Jacobian)")
        else:
            verdict[name] = (True, f"relative 1-sigma uncertainty {rel[col[j]]:.2g}")
    # an arm lost: its modulus not determined, or the arm at a bound (vanished, instant or frozen)
    lost = [i for i in range(1, n_arms + 1)
            if not verdict[f"e_{i}"][0] or f"e_{i}" in at_bound or f"tau_{i}" in at_bound]  # fmt: skip
    if n_arms > 1 and lost:
        # an arm the record does not resolve: the others are then the values of a fit with fewer arms
        # (measured: a two-arm record with tau f1 = 1 fitted as one arm of e_1 + e_2 and a vanishing arm)
        why = (f"arm {', '.join(map(str, lost))} not resolved by the record: the record supports fewer than "
               f"{n_arms} arms, and the other arms and e_inf take the lost arm's share")  # fmt: skip
        for name in names:
            ok, reason = verdict[name]
            verdict[name] = (False, why if ok else reason + "; " + why)
    from dataclasses import replace

    for name, (ok, reason) in verdict.items():
        est[name] = replace(est[name], identifiable=ok, reason=reason)
    info["fit"]["identifiability"] = {k: v[1] for k, v in verdict.items()}
    info["fit"]["model_accuracy"] = MODEL_REL
    info["fit"]["model_shift_rel"] = {nm: float(shift[j]) for nm, j in zip(names, col)}  # in the 1-sigma
    res_obj = ExtractionResult(method=method_key, force=record.force, taps=len(taps.contact), estimates=est,
                               model="hertz", fitted=tuple(model.parameter_keys), info=info, warnings=warnings)  # fmt: skip
    res_obj.timing_s = {"fit": time.perf_counter() - t0, "total": time.perf_counter() - record.t_start}
    _ = T
    return res_obj
