"""Fit of Ting's viscoelastic Hertz contact to one approach–retract (force-distance) curve.

Steps (one curve):

1. **Baseline and contact estimate** as for the dwell curves (:func:`.fit.baseline`: the force
   far from contact is a line in height fitted on the approach before contact and removed).
2. **Window**: from before the contact (half the loading time again) through the approach
   (and a dwell, if the curve has one) and the retract until the corrected force first
   falls to zero (beyond, adhesion pulls the tip, which the model does not hold).
3. **Binning** onto a uniform time grid of about ``points`` samples (400 by default; never a
   step shorter than the record's) with a grid point at the turnaround (the retract's start;
   Ting's kink in ``δ(t)``): each grid point holds the mean force and height of the samples
   within half a step of it.  The fit
   costs ``O(points²)`` per evaluation whatever the sampling rate; the noise averages down.
4. **Indentation** ``δ = (contact - h) - F/k`` (``h`` increases away from the sample), the
   contact height ``contact`` a fit parameter.
5. **Models**, fitted by least squares (scipy, trust-region reflective, finite-difference
   Jacobian) in ``(contact, ln modulus..., shape...)``:

   * ``hertz``: the approach alone, elastic ``F = C E δ^{3/2}`` (``e_hertz``, the apparent
     modulus users know and compare with; it lies between ``E(∞)`` and ``E(0)``);
   * ``power-law``: Ting through loading and unloading with ``E(t) = e0 (t/t0)^(-beta)``,
     ``t0 = 1 s``, ``0 ≤ beta < 1`` (started from the Hertz fit);
   * ``maxwell``: Ting with ``E(t) = e_inf + Σ e_i exp(-t/tau_i)`` (the ``hertz`` surface
     model's arms), 1 to 3 arms, the criterion selecting.

6. **Standard errors** from the Jacobian at the optimum, ``cov = s² (JᵀJ)⁻¹``,
   ``s² = RSS/(N - P)``, mapped from log parameters; independent residuals assumed (lower
   bounds when residuals are correlated).  Each row is then judged
   (:func:`.status.judge`): not converged, a relaxation time beyond the fitted window, or a
   standard error larger than its value make the row's ``status`` other than ``ok``.
"""

from __future__ import annotations

import math

import numpy as np

from .fit import CurveError, baseline, tau_starts


def kernels():
    """:mod:`.ting` (numba, scipy.special), imported at the first fit: a refused input loads neither."""
    from . import ting

    return ting


MODULI = ("power-law", "maxwell")
DEFAULT_POINTS = 400  # grid points of a fit (binned): 0.3 ms per model evaluation, within 1e-4 of the closed form
MIN_POINTS, MAX_POINTS = 50, 5000
BETA_MAX = 0.99
MAXWELL_ARMS = (1, 2, 3)
PRE_CONTACT = 0.5  # the window starts this fraction of the loading time before the contact


class FDProblem:
    """The binned data of one approach–retract curve and its models (module docstring)."""

    def __init__(self, curve, tip_radius: float, nu: float, points: int = DEFAULT_POINTS):
        if not np.any(curve.segment == 2):
            raise CurveError("no retract segment: Ting's fit needs the approach and the retract")
        f, i_c, noise = baseline(curve)
        seg, t, h = curve.segment, curve.t, curve.height
        i_turn = int(np.nonzero(seg == 2)[0][0]) - 1  # the last sample before the retract
        if not np.all(np.diff(t) > 0):
            raise CurveError("the time axis does not increase")
        retract = np.nonzero((seg == 2) & (np.arange(t.size) > i_turn))[0]
        low = retract[f[retract] <= 0.0]
        i_end = int(low[0]) if low.size else int(retract[-1])
        t_load = t[i_turn] - t[i_c]
        if t_load <= 0 or i_end - i_turn < 5:
            raise CurveError("no loading or no unloading in contact (contact at the turnaround or retract too short)")
        t_start = max(t[0], t[i_c] - PRE_CONTACT * t_load)
        t_turn, t_end = t[i_turn], t[i_end]
        k_load = max(int(round(points * (t_turn - t_start) / (t_end - t_start))), 20)
        inside = t[(t >= t_start) & (t <= t_end)]
        dt_sample = float(np.median(np.diff(inside))) if inside.size > 2 else 0.0
        if dt_sample > 0 and (t_turn - t_start) / k_load < dt_sample:  # no more grid points than samples
            k_load = max(int((t_turn - t_start) / dt_sample), 20)
        step = (t_turn - t_start) / k_load
        m = int(math.ceil((t_end - t_turn) / step - 1e-9)) + k_load
        grid = t_turn + step * (np.arange(m + 1) - k_load)
        sel = (t >= grid[0] - 0.5 * step) & (t <= grid[-1] + 0.5 * step)
        b = np.clip(np.rint((t[sel] - grid[0]) / step).astype(np.int64), 0, m)
        count = np.bincount(b, minlength=m + 1)
        fb = np.bincount(b, f[sel], minlength=m + 1)
        hb = np.bincount(b, h[sel], minlength=m + 1)
        have = count > 0
        self.f = np.where(have, fb / np.maximum(count, 1), np.interp(grid, t, f))
        self.h = np.where(have, hb / np.maximum(count, 1), np.interp(grid, t, h))
        self.t = grid
        self.step = float(step)
        self.k_turn = k_load  # grid index of the turnaround
        self.approach = np.arange(m + 1) <= k_load
        if np.any(seg == 1):  # a dwell: the elastic fit takes the approach segment only
            self.approach &= grid <= t[int(np.nonzero(seg == 0)[0][-1])] + 0.5 * step
        self.k = curve.spring_constant
        self.c = kernels().hertz_constant(tip_radius, nu)
        self.noise = noise
        self.contact0 = float(h[i_c])
        self.window = float(t_end - t_start)
        self.samples = int(np.count_nonzero(sel))
        d = self.indentation(self.contact0)
        self.depth = float(max(np.max(d), 1e-12))
        if d[self.k_turn] <= 0:
            raise CurveError("no indentation at the turnaround (contact height above the record)")
        self.noise_scale = max(noise, 1e-3 * float(np.max(np.abs(self.f))), 1e-300)

    def indentation(self, contact: float) -> np.ndarray:
        return (contact - self.h) - self.f / self.k

    def contact_of(self, x0: float) -> float:
        return self.contact0 + self.depth * x0

    # ------------------------------------------------------------------ models
    def hertz(self, contact: float, e: float) -> np.ndarray:
        return self.c * e * np.clip(self.indentation(contact), 0.0, None) ** 1.5

    def powerlaw(self, contact: float, e0: float, beta: float) -> np.ndarray:
        u = kernels().powerlaw_weights(self.t.size, self.step, e0, beta, kernels().T0)
        return kernels().ting_force(self.indentation(contact), u, self.c)[0]

    def maxwell(self, contact: float, e_inf: float, e, tau) -> np.ndarray:
        u = kernels().prony_weights(self.t.size, self.step, e_inf, np.ascontiguousarray(e, float),
                          np.ascontiguousarray(tau, float))  # fmt: skip
        return kernels().ting_force(self.indentation(contact), u, self.c)[0]


def _solve(resid, x0, lo, hi, max_nfev: int):
    from scipy.optimize import least_squares  # here: a refused input loads no scipy.optimize

    x0 = np.clip(np.asarray(x0, float), lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
    return least_squares(resid, x0, bounds=(lo, hi), method="trf", x_scale="jac", max_nfev=max_nfev)


def _stats(prob: FDProblem, res, mask) -> dict:
    """Residual, information criteria and the covariance of ``res.x`` (scaled to N)."""
    r = res.fun * prob.noise_scale
    npts, npar = r.size, res.x.size
    rss = float(r @ r)
    dof = max(npts - npar, 1)
    jac = res.jac * prob.noise_scale
    try:
        cov = np.linalg.pinv(jac.T @ jac) * (rss / dof)
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        se = np.full(npar, np.nan)
    rss_n = max(rss / npts, 1e-300)
    return {"se": se, "residual_rms": math.sqrt(rss / npts), "n_points": npts, "n_params": npar, "rss": rss,
            "aic": npts * math.log(rss_n) + 2 * npar, "bic": npts * math.log(rss_n) + npar * math.log(npts),
            "converged": bool(res.success), "nfev": int(res.nfev)}  # fmt: skip


def fit_hertz(prob: FDProblem) -> dict:
    """Elastic Hertz on the approach: ``e_hertz`` [Pa] and its contact, with standard errors."""
    mask = prob.approach
    d0 = prob.indentation(prob.contact0)
    e_start = prob.f[prob.k_turn] / (prob.c * max(d0[prob.k_turn], 1e-12) ** 1.5)
    e_start = max(e_start, 1e-300)

    def resid(x):
        return (prob.hertz(prob.contact_of(x[0]), e_start * math.exp(x[1])) - prob.f)[mask] / prob.noise_scale

    res = _solve(resid, [0.0, 0.0], np.array([-5.0, -30.0]), np.array([5.0, 30.0]), 200)
    st = _stats(prob, res, mask)
    e = e_start * math.exp(res.x[1])
    return {"e_hertz": e, "se_e_hertz": e * st["se"][1], "contact_hertz": prob.contact_of(res.x[0]),
            "se_contact_hertz": prob.depth * st["se"][0], "converged_hertz": st["converged"],
            "residual_rms_hertz": st["residual_rms"]}  # fmt: skip


def _row(prob: FDProblem, st: dict, contact: float, se_contact: float) -> dict:
    d = prob.indentation(contact)
    return {"contact": contact, "se_contact": se_contact, "indentation_max": float(np.max(d)),
            "force_max": float(np.max(prob.f)), "residual_rms": st["residual_rms"], "n_points": st["n_points"],
            "n_params": st["n_params"], "rss": st["rss"], "aic": st["aic"], "bic": st["bic"],
            "converged": st["converged"], "nfev": st["nfev"], "window_s": prob.window, "step_s": prob.step,
            "samples": prob.samples}  # fmt: skip


def fit_powerlaw(prob: FDProblem, hertz: dict) -> dict:
    """Ting with ``E(t) = e0 (t/t0)^(-beta)`` over the window; started from the Hertz fit."""
    t_load = prob.step * prob.k_turn
    x_c0 = (hertz["contact_hertz"] - prob.contact0) / prob.depth
    scale = max(hertz["e_hertz"], 1e-300)
    lo, hi = np.array([x_c0 - 2.0, -30.0, 0.0]), np.array([x_c0 + 2.0, 30.0, BETA_MAX])

    def resid(x):
        return (prob.powerlaw(prob.contact_of(x[0]), scale * math.exp(x[1]), x[2]) - prob.f) / prob.noise_scale

    best = None
    for beta0 in (0.1, 0.5):
        e0 = math.log(max(t_load / kernels().T0, 1e-12) ** beta0)  # E(t_load) ~ e_hertz
        res = _solve(resid, [x_c0, e0, beta0], lo, hi, 200)
        if best is None or res.cost < best.cost:
            best = res
        if best.success and best.x[2] < 0.3:  # a start near the solution: no second start needed
            break
    st = _stats(prob, best, None)
    e0 = scale * math.exp(best.x[1])
    row = {"modulus": "power-law", "arms": 0, "e0": e0, "se_e0": e0 * st["se"][1], "beta": float(best.x[2]),
           "se_beta": float(st["se"][2])}  # fmt: skip
    row.update(_row(prob, st, prob.contact_of(best.x[0]), prob.depth * st["se"][0]))
    row["at_bound"] = "beta" if best.x[2] >= BETA_MAX - 1e-2 else ""
    return row


def fit_maxwell(prob: FDProblem, hertz: dict, n: int, previous=None) -> dict:
    """Ting with ``E(t) = e_inf + Σ_{i≤n} e_i exp(-t/tau_i)`` over the window (several starts)."""
    x_c0 = (hertz["contact_hertz"] - prob.contact0) / prob.depth
    scale = max(hertz["e_hertz"], 1e-300)
    lo_tau, hi_tau = math.log(0.5 * prob.step), math.log(20.0 * prob.window)
    lo = np.array([x_c0 - 2.0] + [math.log(1e-6)] * (1 + n) + [lo_tau] * n)
    hi = np.array([x_c0 + 2.0] + [math.log(1e3)] * (1 + n) + [hi_tau] * n)

    def unpack(x):
        return prob.contact_of(x[0]), scale * math.exp(x[1]), scale * np.exp(x[2 : 2 + n]), np.exp(x[2 + n :])

    def resid(x):
        return (prob.maxwell(*unpack(x)) - prob.f) / prob.noise_scale

    best = None
    t_load = prob.step * prob.k_turn
    for taus in tau_starts(n, t_load, previous):
        x0 = [x_c0, math.log(0.5)] + [math.log(1.0 / n)] * n + [math.log(max(tt, 1e-300)) for tt in taus]
        try:
            res = _solve(resid, x0, lo, hi, 100 * (n + 2))
        except (ValueError, FloatingPointError):
            continue
        if np.isfinite(res.cost) and (best is None or res.cost < best.cost):
            best = res
    if best is None:
        raise CurveError(f"the {n}-arm fit did not converge from any start")
    st = _stats(prob, best, None)
    contact, e_inf, e, tau = unpack(best.x)
    se = st["se"]
    row = {"modulus": "maxwell", "arms": n, "e_inf": e_inf, "se_e_inf": e_inf * se[1]}
    for k, i in enumerate(np.argsort(tau), start=1):
        row[f"e_{k}"], row[f"se_e_{k}"] = float(e[i]), float(e[i] * se[2 + i])
        row[f"tau_{k}"], row[f"se_tau_{k}"] = float(tau[i]), float(tau[i] * se[2 + n + i])
    row["e_0"] = e_inf + float(np.sum(e))
    row.update(_row(prob, st, contact, prob.depth * se[0]))
    names = ["contact", "e_inf"] + [f"e_{k}" for k in np.argsort(np.argsort(tau)) + 1] + \
        [f"tau_{k}" for k in np.argsort(np.argsort(tau)) + 1]
    hit = [names[i] for i in range(1, len(names)) if best.x[i] <= lo[i] + 1e-2 or best.x[i] >= hi[i] - 1e-2]
    row["at_bound"] = ", ".join(hit)  # log parameters within 1 % of a bound
    return row


def model_force(prob: FDProblem, row: dict) -> np.ndarray:
    """The fitted model's force [N] on the problem's grid for a row of :func:`fit_fd_curve`."""
    if row["modulus"] == "power-law":
        return prob.powerlaw(row["contact"], row["e0"], row["beta"])
    n = int(row["arms"])
    return prob.maxwell(row["contact"], row["e_inf"], [row[f"e_{k}"] for k in range(1, n + 1)],
                        [row[f"tau_{k}"] for k in range(1, n + 1)])  # fmt: skip


def fit_fd_curve(curve, tip_radius: float, nu: float = 0.5, modulus: str = "power-law", arms=MAXWELL_ARMS,
                 points: int = DEFAULT_POINTS) -> list[dict]:  # fmt: skip
    """Rows of one force-distance curve: one for the power law, or one per arm count for the
    Maxwell modulus; each carries the approach's elastic Hertz modulus ``e_hertz`` beside it.
    Not yet judged (:func:`.status.judge`).  CurveError when the curve cannot be fitted."""
    prob = FDProblem(curve, tip_radius, nu, points)
    hertz = fit_hertz(prob)
    rows = []
    if modulus == "power-law":
        rows.append(fit_powerlaw(prob, hertz))
    else:
        previous = None
        for n in sorted(arms):
            row = fit_maxwell(prob, hertz, n, previous)
            previous = [row[f"tau_{k}"] for k in range(1, n + 1)]
            rows.append(row)
    for row in rows:
        row.update(hertz)
        row["model"] = "ting"
    return rows
