"""Fit of the viscoelastic Hertz (Lee–Radok, Prony series) model to one force curve with a dwell.

Steps (one curve):

1. **Baseline** from the first segment: the force far from contact is a straight line in height
   (offset and the interference tilt), fitted on the approach before contact and removed
   everywhere (in the dwell the height hardly moves, so the removed line is nearly constant).
2. **Contact**: a first estimate is the last approach sample, going back from the end of the
   approach, whose corrected force is below zero; the contact height ``contact`` [m] is then a
   fit parameter (or given).
3. **Indentation** from the record: ``δ = (contact - h) - F/k`` (the tip sits above its
   undeflected place by the deflection ``F/k``; ``h`` increases away from the sample).
4. **Model**: Lee–Radok's force for that indentation history on the record's own time axis
   (:mod:`.leeradok`), run from as far before the contact as the contact is before the end of
   the approach, fitted by least squares in ``(contact, ln e_inf, ln e_i, ln tau_i)`` (several
   starts per arm count) to the measured force over approach and dwell (window ``all``), or
   over the dwell only with the approach as loading history (window ``dwell``, the default:
   the contact is then the one of the selected ``all`` fit, held fixed; the dwell alone hardly
   constrains it).
   A stress-relaxation curve (height held) and a creep curve (force held, depth grows) go
   through the same model and the same residual: the force the model predicts for the
   measured indentation history.
5. **Arm counts** 1 (the standard linear solid), 2, 3; AIC and BIC of each; the model
   ``selected`` is the one with the lowest criterion (BIC by default).
6. **Standard errors** from the Jacobian at the optimum, ``cov = s² (JᵀJ)⁻¹`` with
   ``s² = RSS/(N - P)``, mapped from the log parameters (``se(x) = x se(ln x)``).  They assume
   independent residuals; a measured curve's residuals are correlated (drift, the cell's own
   motion), so they are lower bounds.
"""

from __future__ import annotations

import math

import numpy as np


def kernels():
    """:mod:`.leeradok` (numba), imported at the first fit: a refused input loads no numba."""
    from . import leeradok

    return leeradok


ARM_COUNTS = (1, 2, 3)
WINDOWS = ("all", "dwell")  # residuals over approach and dwell, or over the dwell only (the approach as loading history)
CRITERIA = ("bic", "aic")
MODEL = "leeradok"


class CurveError(RuntimeError):
    """A curve that cannot be fitted (fit failed): a row with status failed."""


class NoContact(CurveError):
    """A curve whose approach shows no contact: it does not suit a contact fit (status unsuited)."""


def baseline(curve):
    """``(force corrected, contact index, noise)``.  The baseline comes from the first segment:
    a pause before the approach when the file has one (its mean force; its spread is the
    noise), else a line in height fitted on the approach before contact (two passes).  The
    contact index is the last approach sample at or below zero going back from the
    approach's end (0 when the approach starts in contact).  CurveError when the approach
    shows no contact."""
    f, h, seg = curve.force, curve.height, curve.segment
    n_a = int(np.count_nonzero(seg == 0))
    fa, ha = f[:n_a], h[:n_a]
    if curve.prep_force is not None:
        line = (0.0, float(np.mean(curve.prep_force)))
        noise = float(np.std(curve.prep_force))
        i_c = _last_below(fa - line[1])
    else:
        head = max(n_a // 4, 5)
        i_c = _last_below(fa - np.median(fa[:head]))
        for _ in range(2):
            stop = max(int(0.8 * i_c), 5)
            line = np.polyfit(ha[:stop], fa[:stop], 1) if np.ptp(ha[:stop]) > 0 else (0.0, float(np.median(fa[:stop])))
            base_a = np.polyval(line, ha)
            noise = float(np.std(fa[:stop] - base_a[:stop]))
            i_c = _last_below(fa - base_a)
    corrected = f - np.polyval(line, h)
    if corrected[n_a - 1] < 10 * max(noise, 1e-300) or i_c >= n_a - 5:
        raise NoContact("no contact in the approach (the force at its end is within 10 noise levels of the baseline)")
    return corrected, i_c, noise


def _last_below(g) -> int:
    below = np.nonzero(g <= 0)[0]
    return int(below[-1]) if below.size else 0


class Problem:
    """The least-squares problem of one curve: data over the fit window and the model."""

    def __init__(self, curve, tip_radius: float, nu: float, contact: float | None = None, window: str = "all"):
        f, i_c, noise = baseline(curve)
        n_a = int(np.count_nonzero(curve.segment == 0))
        i0 = max(0, i_c - (n_a - i_c))
        self.t = np.ascontiguousarray(curve.t[i0:])
        self.f = np.ascontiguousarray(f[i0:])
        self.h = np.ascontiguousarray(curve.height[i0:])
        self.segment = curve.segment[i0:]
        self.mask = np.ones(self.t.size, bool) if window == "all" else self.segment == 1
        self.k = curve.spring_constant
        self.c = kernels().hertz_constant(tip_radius, nu)
        self.noise = noise
        self.contact_fixed = contact
        self.contact0 = float(curve.height[i_c]) if contact is None else float(contact)
        self.dwell = float(self.t[-1] - self.t[self.segment == 1][0])
        self.dt_min = float(np.min(np.diff(self.t)[np.diff(self.t) > 0]))
        d = self.indentation(self.contact0)
        i_peak = int(np.nonzero(self.segment == 0)[0][-1])
        if d[i_peak] <= 0 or d[-1] <= 0:
            raise CurveError("no indentation at the end of the approach (contact height above the record)")
        self.e_app = self.f[i_peak] / (self.c * d[i_peak] ** 1.5)  # apparent modulus at the end of loading
        self.e_end = max(self.f[-1], 1e-3 * self.f[i_peak]) / (self.c * d[-1] ** 1.5)  # at the end of the dwell
        self.scale = float(self.e_app)
        self.noise_scale = max(self.noise, 1e-3 * float(np.max(np.abs(self.f))), 1e-300)  # residual unit [N]

    def indentation(self, contact: float) -> np.ndarray:
        return (contact - self.h) - self.f / self.k

    # parameter vector x = [dh (um, when the contact is fitted), ln(e_inf/scale), ln(e_i/scale)..., ln(tau_i/s)...]
    def unpack(self, x, n: int):
        j = 0
        if self.contact_fixed is None:
            contact = self.contact0 + 1e-6 * x[0]
            j = 1
        else:
            contact = self.contact0
        e_inf = self.scale * math.exp(x[j])
        e = self.scale * np.exp(x[j + 1 : j + 1 + n])
        tau = np.exp(x[j + 1 + n : j + 1 + 2 * n])
        return contact, e_inf, e, tau

    def model(self, contact, e_inf, e, tau) -> np.ndarray:
        p = np.clip(self.indentation(contact), 0.0, None) ** 1.5
        e, tau = np.ascontiguousarray(e, float), np.ascontiguousarray(tau, float)
        return kernels().force_from_p(self.t, p, e_inf, e, tau, self.c)

    def jacobian(self, x, n: int) -> np.ndarray:
        """∂residual/∂x from the kernel's exact derivatives (chain rule to the log parameters)."""
        contact, e_inf, e, tau = self.unpack(x, n)
        d = np.clip(self.indentation(contact), 0.0, None)
        _, g = kernels().force_and_gradient(self.t, d**1.5, 1.5 * np.sqrt(d), e_inf, np.ascontiguousarray(e, float),
                                  np.ascontiguousarray(tau, float), self.c)  # fmt: skip
        g = g[self.mask]
        cols = ([g[:, :1] * 1e-6] if self.contact_fixed is None else []) + [
            g[:, 1:2] * e_inf, g[:, 2 : 2 + n] * e, g[:, 2 + n :] * tau]
        return np.hstack(cols) / self.noise_scale

    def residual(self, x, n: int) -> np.ndarray:
        return (self.model(*self.unpack(x, n)) - self.f)[self.mask] / self.noise_scale


    def start(self, n: int, taus) -> np.ndarray:
        e_inf0 = min(max(self.e_end, 1e-3 * self.e_app), self.e_app)
        arms = max(1.5 * self.e_app - e_inf0, 0.3 * self.e_app) / n
        x = [0.0] if self.contact_fixed is None else []
        x += [math.log(e_inf0 / self.scale)] + [math.log(arms / self.scale)] * n + [math.log(t) for t in taus]
        return np.array(x, float)

    def bounds(self, n: int):
        lo_tau, hi_tau = math.log(0.5 * self.dt_min), math.log(20.0 * max(self.dwell, self.dt_min))
        lo = ([-50.0] if self.contact_fixed is None else []) + [math.log(1e-6)] * (1 + n) + [lo_tau] * n
        hi = ([50.0] if self.contact_fixed is None else []) + [math.log(1e3)] * (1 + n) + [hi_tau] * n
        return np.array(lo), np.array(hi)


def tau_starts(n: int, dwell: float, previous=None) -> list:
    """Starting relaxation times for ``n`` arms: log-spaced sets over the dwell, and the
    previous arm count's solution with one arm added below, between and above its times."""
    grids = {1: [(dwell / 10,), (dwell / 30,)],
             2: [(dwell / 30, dwell / 3), (dwell / 100, dwell / 10)],
             3: [(dwell / 100, dwell / 10, dwell)]}.get(n, [])  # fmt: skip
    starts = [tuple(g) for g in grids] or [tuple(dwell * 10.0 ** (-2 + 3 * i / max(n - 1, 1)) for i in range(n))]
    if previous is not None:
        prev = sorted(previous)
        for new in (prev[0] / 10, prev[-1] * 3) + tuple(math.sqrt(a * b) for a, b in zip(prev, prev[1:])):
            starts.append(tuple(sorted(prev + [new])))
    return starts


def fit_arms(prob: Problem, n: int, previous=None) -> dict:
    """Best least-squares fit with ``n`` arms over several starts (CurveError if none converges)."""
    from scipy.optimize import least_squares  # here: a refused input loads no scipy.optimize

    lo, hi = prob.bounds(n)
    best = None
    for taus in tau_starts(n, prob.dwell, previous):
        x0 = np.clip(prob.start(n, taus), lo + 1e-9, hi - 1e-9)
        try:
            res = least_squares(prob.residual, x0, jac=prob.jacobian, args=(n,), bounds=(lo, hi), method="trf",
                                x_scale="jac", max_nfev=100)  # fmt: skip
        except (ValueError, FloatingPointError):
            continue
        if np.isfinite(res.cost) and (best is None or res.cost < best.cost):
            best = res
    if best is None:
        raise CurveError(f"the {n}-arm fit did not converge from any start")
    return summarize(prob, best, n)


def summarize(prob: Problem, res, n: int) -> dict:
    """Parameters (arms sorted by tau), standard errors, residual and information criteria."""
    contact, e_inf, e, tau = prob.unpack(res.x, n)
    r = res.fun * prob.noise_scale  # [N]
    npts, npar = r.size, res.x.size
    rss = float(r @ r)
    dof = max(npts - npar, 1)
    jac = res.jac * prob.noise_scale
    try:
        cov = np.linalg.pinv(jac.T @ jac) * (rss / dof)
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        se = np.full(npar, np.nan)
    j = 0
    row = {"model": MODEL, "arms": n, "window": "all" if prob.mask.all() else "dwell"}
    if prob.contact_fixed is None:
        row["contact"], row["se_contact"] = contact, 1e-6 * se[0]
        j = 1
    else:
        row["contact"], row["se_contact"] = contact, 0.0
    row["e_inf"], row["se_e_inf"] = e_inf, e_inf * se[j]
    order = np.argsort(tau)
    for k, i in enumerate(order, start=1):
        row[f"e_{k}"], row[f"se_e_{k}"] = float(e[i]), float(e[i] * se[j + 1 + i])
        row[f"tau_{k}"], row[f"se_tau_{k}"] = float(tau[i]), float(tau[i] * se[j + 1 + n + i])
    d = prob.indentation(contact)
    row.update(
        indentation_max=float(np.max(d)),
        force_max=float(np.max(prob.f)),
        residual_rms=math.sqrt(rss / npts),
        n_points=npts,
        n_params=npar,
        rss=rss,
        aic=npts * math.log(rss / npts) + 2 * npar,
        bic=npts * math.log(rss / npts) + npar * math.log(npts),
        converged=bool(res.success),
        window_s=float(prob.t[prob.mask][-1] - prob.t[prob.mask][0]),
    )
    row["e_0"] = e_inf + float(np.sum(e))
    return row


def fit_curve(curve, tip_radius: float, nu: float = 0.5, arms=ARM_COUNTS, criterion: str = "bic",
              contact: float | None = None, window: str = "dwell", with_traces: bool = False):  # fmt: skip
    """One row per arm count (module docstring) with ``selected`` set on the lowest
    ``criterion``; with ``with_traces`` also ``{"t", "force", arms: model force}`` over the fit
    window for figures.  CurveError when the curve cannot be fitted."""
    se_contact = 0.0
    if window == "dwell" and contact is None:  # the contact from the approach: the selected fit of approach and dwell
        first = fit_curve(curve, tip_radius, nu, arms, criterion, None, "all")
        chosen = next(r for r in first if r["selected"])
        contact, se_contact = chosen["contact"], chosen["se_contact"]
    prob = Problem(curve, tip_radius, nu, contact, window)
    rows, traces, previous = [], {"t": prob.t, "force": prob.f, "segment": prob.segment}, None
    for n in sorted(arms):
        row = fit_arms(prob, n, previous)
        if prob.contact_fixed is not None and window == "dwell":
            row["se_contact"] = se_contact
        previous = [row[f"tau_{k}"] for k in range(1, n + 1)]
        rows.append(row)
        if with_traces:
            traces[n] = prob.model(row["contact"], row["e_inf"], [row[f"e_{k}"] for k in range(1, n + 1)], previous)
    best = min(range(len(rows)), key=lambda i: rows[i][criterion])
    for i, row in enumerate(rows):
        row["selected"] = i == best
        row["d_" + criterion] = row[criterion] - rows[best][criterion]
    return (rows, traces) if with_traces else rows
