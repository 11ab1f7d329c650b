"""VETICA: the SLS surface's k0, k_inf, cd from time, tip position and force
(thesis 3.3 and 4.3).  Registered as extraction method ``vetica``.

Inputs are plain arrays of one record of consecutive taps: ``t`` [s],
``z_tip`` [m] (up positive, undeformed surface at ``z_tip = a0``), ``f``
[N] the tip-sample force (repulsive positive), and ``Z1`` [m], the tip
position at the first force minimum of the initial approach.

It measures the characteristic constants of a Zener SLS
(:class:`vetica_cli.surfaces.sls.SLS`, thesis eqs. 43-44, 68, 75-76:
``Kg = k0 + k_inf``, ``Kr = k_inf``, ``tau_r = cd/k0``, ``tau_c = cd Kg/(k0 k_inf)``)
and inverts them for the elements.

Stage 1a (thesis eq. 73): creep between the separation of tap i (tip at
``Z'i``) and the contact of tap i+1 (tip at ``Z(i+1)``, ``dt`` later)::

    tau_c = -dt / ln((Z(i+1) - Z1) / (Z'i - Z1))

Stage 1b (thesis 4.3.2, eq. 86): ``Kg = -dF/dz_tip``, a straight-line fit
over the first ``kg_points`` samples after the contact minimum (10 in the
thesis).

Stage 2 (thesis eqs. 75-83): the contact trajectory is fitted by a 3-term
sum of sines (thesis eq. 88) and the SLS force is the Boltzmann
superposition of the indentation ``delta(t) = Zc - z_tip(t)`` from the
contact instant::

    F_SLS(t) = Fc + int_0^t Erel(t - s) d delta/ds ds
    Erel(t)  = Kr + (Kg - Kr) exp(-t / tau_r),   tau_r = tau_c Kr / Kg

``Fc`` is the force measured at the contact minimum (-F_vdW(a0)); the
thesis does not say how it handled this offset, and fitting without it
biases Kr by the adhesion force over the indentation.  ``Kr`` is the
least-squares fit of ``F_SLS - F`` over the contact samples, bounded to
``0 < Kr < Kg`` (the thesis's MATLAB ``lsqnonlin``), solved as the root of the
cost's derivative so that rounding does not move it (:func:`stage2_kr`).  Then
``k_inf = Kr``, ``k0 = Kg - Kr``, ``cd = tau_r k0`` (thesis eqs. 81-83).

The superposition integral of a sum of sines against the exponential kernel
has a closed form (:func:`exp_conv_cos`), so stage 2 costs a few
milliseconds per tap.

That is the thesis's path, kept as the option ``stage2='sines'``.  The default,
``stage2='closed'`` (:func:`stage2_tap_closed`), skips the sum-of-sines fit: the
indentation is taken as linear between the recorded samples, on which the same
superposition integral is exact by a recursion, and the same cost is solved for Kr
the same way (log scan, Brent on ``S'``), compiled
(:mod:`vetica_cli.core.superposition`): ~0.3 ms a tap of 1400 samples instead of
~20 ms, no scipy.  On the thesis studies the two differ by <= 1.1e-3 relative in Kr
(k_inf, cd) in the acceptance regime and 8e-5 on scan pixels (docs/realtime.md);
``tau_c`` and ``Kg`` do not depend on it.

One pass per record: the taps, stage 1b's slopes and the contacts as plain arrays
(:class:`Stage1`, :class:`Contacts`) are measured once and kept on the record
(:func:`record_stage1`); stage 2 runs over every tap in one compiled call
(:func:`vetica_cli.core.superposition.solve_taps`, its bounds' scan one pass over the samples
for every scanned Kr); the error bars' re-runs at a moved Z1 or Kg and the checks' comparison
with the pre-stress variant re-run only the stages that move, values only
(:meth:`TapMethod.moved`, :meth:`TapMethod.values_at`), each stage solved as a whole run solves
it (tests/test_tap_pass.py).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ...checks import one_of
from ...errors import InputError
from ...signals.taps import Taps, contact_slopes, find_taps
from ..base import KG_SCALE, KG_POINTS, KG_WINDOW, ExtractionMethod, Option, register
from ..record import Record
from ..result import ExtractionResult, Spread, estimates, sls_elements  # noqa: F401  (sls_elements re-exported)

MIN_CONTACT_SAMPLES = 20  # stage 2 needs the contact resolved: 3 sines + constant = 10 parameters




# ----------------------------------------------------------------------------- stage 1


def stage1a_tau_c(t: np.ndarray, z: np.ndarray, taps: Taps, z1: float) -> np.ndarray:
    """Retardation time of each creep interval (thesis eq. 73) [s].

    One value per pair (separation of tap i, contact of tap i+1); nan where
    the two positions are not both on the same side of Z1 with the surface
    recovering (ratio outside (0, 1)).
    """
    out = []
    for i in range(len(taps.contact) - 1):
        js, jc = taps.separation[i], taps.contact[i + 1]
        ratio = (z[jc] - z1) / (z[js] - z1)
        dt = t[jc] - t[js]
        out.append(-dt / math.log(ratio) if 0.0 < ratio < 1.0 and dt > 0 else math.nan)
    return np.array(out)


def stage1b_kg(z: np.ndarray, f: np.ndarray, taps: Taps, points: int = 10, window: str = "noise",
               details: bool = False):  # fmt: skip
    """Glassy stiffness of each tap: ``-dF/dz_tip`` fitted over ``points``
    samples after the contact minimum (thesis 4.3.2, eq. 86) [N/m], over a window grown
    from the record's noise where the thesis's is too short for it (``window``,
    :func:`vetica_cli.signals.taps.contact_slopes`; ``details``: with the windows)."""
    return contact_slopes(z, f, taps, points, window, details)


# ----------------------------------------------------------------------------- stage 2


@dataclass
class SineFit:
    """``z(u) = sum_j p_j sin(b_j u) + q_j cos(b_j u)``, u = t - t_contact [s]."""

    b: np.ndarray  # [rad/s]
    p: np.ndarray  # [m]
    q: np.ndarray  # [m]
    rms: float  # [m] residual RMS

    def __call__(self, u):
        u = np.asarray(u)[:, None]
        return np.sum(self.p * np.sin(self.b * u) + self.q * np.cos(self.b * u), axis=1)


STARTS = ((0.5, 1.5, 3.0), (0.3, 2.0, 4.0), (0.1, 1.0, 2.0), (1.0, 2.0, 3.0))
SCOUT_NFEV = 15  # per starting set
NFEV = 100  # for the best start (residual ~0.05 pm on the worked example)


def _sines_model(params: np.ndarray, x: np.ndarray, terms: int) -> tuple[np.ndarray, np.ndarray]:
    """Value and Jacobian of ``c0 + sum_j a_j sin(b_j x + c_j)``; params = (a, b, c, c0)."""
    a, b, c = params[:terms], params[terms : 2 * terms], params[2 * terms : 3 * terms]
    ph = np.outer(x, b) + c
    sn, cs = np.sin(ph), np.cos(ph)
    value = sn @ a + params[-1]
    jac = np.hstack([sn, cs * a * x[:, None], cs * a, np.ones((len(x), 1))])
    return value, jac


def fit_sum_of_sines(u: np.ndarray, z: np.ndarray, terms: int = 3, max_points: int = 250) -> SineFit:
    """Least-squares sum of ``terms`` sines plus a constant (thesis eq. 88).

    ``z(u) ~ c0 + sum_j a_j sin(b_j u + c_j)``: MATLAB's ``sin3`` plus a
    constant offset, which the superposition integral does not see (it uses
    only ``dz/du``) but which frees the sines to fit the shape.  Levenberg-
    Marquardt with the analytic Jacobian on at most ``max_points`` evenly
    spaced samples (the trajectory is smooth), time scaled to the contact
    duration; a few starting frequency sets (amplitudes and phases from a
    linear fit at those frequencies) are tried and the lowest residual kept.
    ``rms`` is over all samples.

    The Jacobian carries one trailing zero column (a parameter the residuals do not
    depend on, held at 0).  scipy's MINPACK port behind ``method="lm"`` (scipy 1.17)
    reads one element past the end of its Jacobian array when its pivoting QR re-norms
    the last column (valgrind: an invalid read of 8 bytes just after the m x n block
    that ``qrfac`` factors), so the fit's last bits depended on whatever lay in memory
    there: reruns of the same record differed by ~1e-14 in Kr, and the first call of a
    process often differed from the later ones.  A zero column is never pivoted and
    never re-normed, so nothing outside the array is read and the fit is a function of
    its inputs alone.
    """
    from scipy.optimize import least_squares  # lazy: the CLI starts without scipy.optimize

    u = np.asarray(u, dtype=float)
    z = np.asarray(z, dtype=float)
    span = float(u[-1] - u[0]) or 1.0
    step = max(1, len(u) // max_points)
    x = (u[::step] - u[0]) / span
    zs = float(np.std(z)) or 1.0
    zm = float(np.mean(z))
    y = (z[::step] - zm) / zs

    cache = {}
    zero = np.zeros((len(x), 1))  # the trailing zero column (docstring)

    def _eval(params):  # MINPACK asks for value and Jacobian at the same point: compute once
        key = params.tobytes()
        if key not in cache:
            cache.clear()
            value, jac = _sines_model(params[:-1], x, terms)
            cache[key] = value, np.hstack([jac, zero])
        return cache[key]

    def resid(params):
        return _eval(params)[0] - y

    def jac(params):
        return _eval(params)[1]

    best = None
    for freqs in STARTS:
        p0 = np.append(_linear_start(x, y, np.pi * np.array(freqs[:terms])), 0.0)
        try:  # short run from each start, then the best one to convergence
            sol = least_squares(resid, p0, jac=jac, method="lm", max_nfev=SCOUT_NFEV)
        except (ValueError, np.linalg.LinAlgError):  # pragma: no cover - degenerate start
            continue
        if best is None or sol.cost < best.cost:
            best = sol
    if best is None:
        raise InputError(f"sum-of-sines fit failed on a contact of {len(u)} samples")
    best = least_squares(resid, best.x, jac=jac, method="lm", max_nfev=NFEV)
    fit = _physical(best.x[:-1], terms, u[0], span, zm, zs)
    fit.rms = float(np.sqrt(np.mean((fit(u) - z) ** 2)))
    return fit


def _linear_start(x: np.ndarray, y: np.ndarray, b0: np.ndarray) -> np.ndarray:
    """Starting ``(a, b, c, c0)`` at the frequencies ``b0``: amplitudes and phases from a
    linear least-squares fit of sines and cosines at those frequencies."""
    terms = len(b0)
    design = np.hstack([np.sin(np.outer(x, b0)), np.cos(np.outer(x, b0)), np.ones((len(x), 1))])
    lin, *_ = np.linalg.lstsq(design, y, rcond=None)
    amp = np.hypot(lin[:terms], lin[terms : 2 * terms])
    phase = np.arctan2(lin[terms : 2 * terms], lin[:terms])  # p sin + q cos = A sin(. + atan2(q, p))
    return np.concatenate([amp, b0, phase, [lin[-1]]])


def _physical(params: np.ndarray, terms: int, u0: float, span: float, zm: float, zs: float) -> SineFit:
    """The scaled fit back in physical units: ``z = zm + zs (c0 + sum a sin(b (u - u0)/span + c))``
    as a :class:`SineFit` (rms not yet set)."""
    a, b, c = params[:terms], params[terms : 2 * terms], params[2 * terms : 3 * terms]
    bu = b / span
    ph = c - bu * u0
    return SineFit(
        b=np.append(bu, 0.0),
        p=np.append(zs * a * np.cos(ph), 0.0),
        q=np.append(zs * a * np.sin(ph), zm + zs * params[-1]),
        rms=0.0,
    )


def exp_conv_cos(u: np.ndarray, b: np.ndarray, c: np.ndarray, tau: float) -> np.ndarray:
    """``int_0^u exp(-(u-s)/tau) cos(b s + c) ds`` for each (b, c) column.

    Closed form: ``tau/(1+(b tau)^2) [cos(bu+c) + b tau sin(bu+c)
    - exp(-u/tau) (cos c + b tau sin c)]``.
    """
    u = np.asarray(u)[:, None]
    bt = b * tau
    ph = b * u + c
    return tau / (1.0 + bt * bt) * (np.cos(ph) + bt * np.sin(ph) - np.exp(-u / tau) * (np.cos(c) + bt * np.sin(c)))


class Superposition:
    """Parts of the Boltzmann integral of one tap that do not depend on Kr.

    ``delta(u) = z(0) - z(u)`` and ``delta'(u) = -sum_j b_j (p_j cos(b_j u) -
    q_j sin(b_j u))`` from the sum-of-sines fit; the convolution with
    ``exp(-u/tau)`` of each cosine column has the closed form of
    :func:`exp_conv_cos`, whose trigonometric parts are computed once here.
    """

    def __init__(self, u: np.ndarray, fit: SineFit):
        self.u = np.asarray(u, dtype=float)
        self.delta = fit(np.array([0.0]))[0] - fit(self.u)
        b = fit.b
        self.b = np.concatenate([b, b])
        c = np.concatenate([np.zeros_like(b), np.full_like(b, 0.5 * np.pi)])
        self.w = -np.concatenate([b * fit.p, b * fit.q])  # delta' = sum w cos(b u + c)
        ph = np.outer(self.u, self.b) + c
        self.cos, self.sin = np.cos(ph), np.sin(ph)
        self.cos0, self.sin0 = np.cos(c), np.sin(c)

    def conv(self, tau: float) -> np.ndarray:
        """``int_0^u exp(-(u-s)/tau) delta'(s) ds`` [m]."""
        bt = self.b * tau
        a = tau / (1.0 + bt * bt) * self.w
        decay = np.exp(-self.u / tau)
        return (self.cos @ a) + (self.sin @ (bt * a)) - decay * np.dot(a, self.cos0 + bt * self.sin0)

    def conv_dtau(self, tau: float) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`conv` and its derivative with respect to ``tau`` [m, m/s], from the complex
        form of each column: with ``lam = 1/tau``, ``int_0^u exp(-lam (u-s)) exp(i(b s + c)) ds
        = exp(ic) (exp(ibu) - exp(-lam u)) / (lam + ib)``, whose ``lam``-derivative is
        ``exp(ic) (u exp(-lam u) (lam + ib) - (exp(ibu) - exp(-lam u))) / (lam + ib)^2``;
        ``d/dtau = -d/dlam / tau^2``."""
        lam = 1.0 / tau
        den = lam + 1j * self.b
        e_c = self.cos0 + 1j * self.sin0
        tail = e_c * np.exp(-lam * self.u)[:, None]  # exp(ic) exp(-lam u)
        diff = (self.cos + 1j * self.sin) - tail  # exp(i(bu + c)) - exp(ic) exp(-lam u)
        conv = (diff / den).real @ self.w
        dlam = ((self.u[:, None] * tail * den - diff) / den**2).real @ self.w
        return conv, -dlam / tau**2

    def force(self, kg: float, kr: float, tau_r: float, fc: float = 0.0) -> np.ndarray:
        """``Fc + Kr delta + (Kg - Kr) conv(tau_r)`` [N] (thesis eqs. 75-78)."""
        return fc + kr * self.delta + (kg - kr) * self.conv(tau_r)


def boltzmann_force(u: np.ndarray, fit: SineFit, kg: float, kr: float, tau_r: float, fc: float = 0.0) -> np.ndarray:
    """SLS force of the fitted contact trajectory (thesis eqs. 75-78) [N].

    ``F = Fc + Kr delta(u) + (Kg - Kr) int_0^u exp(-(u-s)/tau_r) delta'(s) ds``
    with ``delta(u) = z(0) - z(u)`` from the sum-of-sines fit, ``u`` [s] from
    the contact instant.
    """
    return Superposition(u, fit).force(kg, kr, tau_r, fc)


KR_SCAN = 16  # log-spaced Kr values over the bounds (12 decades) on which stage 2 looks for the lowest cost
KR_RTOL = 4 * np.finfo(float).eps  # Brent's relative tolerance on the root of the cost's derivative


def stage2_kr(
    u, f, fit: SineFit, kg: float, tau_c: float, fc: float, kr_guess: float | None = None, max_points: int = 1000
):
    """Rubbery stiffness of one tap: least squares of ``F_SLS - F`` (thesis eqs. 79-80),
    ``0 < Kr < Kg``, over at most ``max_points`` evenly spaced contact samples.  Returns
    ``(Kr, residual RMS [N], cost evaluations)``.

    The cost ``S(Kr) = sum r^2`` (residuals in units of the peak force) is flat near its
    minimum: its value fixes Kr only to ~1e-8 relative, so a solver that stops on the
    change of Kr or S (the thesis's ``lsqnonlin``; scipy's trust-region least squares at
    ``xtol`` 1e-10) returns Kr to ~1e-10, and a last-bit change of the input -- another
    CPU's ``exp`` -- moves the answer by that much.  Kr is instead the root of the analytic
    derivative ``S'(Kr) = 2 sum r dr/dKr`` (``dr/dKr = (delta - conv + (Kg - Kr) dconv/dtau
    tau_c/Kg)/scale``, :meth:`Superposition.conv_dtau`), a simple root (``S'' > 0``), which
    rounding fixes to ~1e-15 relative: the lowest ``S`` on a log-spaced scan of the bounds
    (:data:`KR_SCAN` values, plus ``kr_guess``) brackets it, Brent's method solves it to
    :data:`KR_RTOL`.  A minimum on a bound returns the bound.
    """
    from scipy.optimize import minimize_scalar

    step = max(1, len(u) // max_points)
    sup = Superposition(np.asarray(u)[::step], fit)
    f = np.asarray(f)[::step]
    lo, hi = 1e-12 * kg, kg * (1.0 - 1e-9)
    scale = float(np.max(np.abs(f))) or 1.0  # residuals in units of the peak force
    calls = [0]

    def resid(kr: float) -> np.ndarray:
        calls[0] += 1
        return (sup.force(kg, kr, tau_c * kr / kg, fc) - f) / scale

    def slope(kr: float) -> float:  # S'(Kr) / 2
        calls[0] += 1
        conv, dconv = sup.conv_dtau(tau_c * kr / kg)
        r = (fc + kr * sup.delta + (kg - kr) * conv - f) / scale
        return float(r @ ((sup.delta - conv + (kg - kr) * dconv * tau_c / kg) / scale))

    xs = np.geomspace(lo, hi, KR_SCAN)
    if kr_guess is not None and lo < kr_guess < hi:
        xs = np.unique(np.append(xs, kr_guess))
    i = int(np.argmin([float(np.sum(resid(x) ** 2)) for x in xs]))
    gi = slope(xs[i])
    if gi == 0.0:
        kr = float(xs[i])
    elif gi > 0:  # the minimum is below xs[i]
        kr = lo if i == 0 else _root(slope, xs[i - 1], xs[i], gi_right=gi)
    else:  # above xs[i]
        kr = hi if i == len(xs) - 1 else _root(slope, xs[i], xs[i + 1], gi_left=gi)
    if kr is None:  # S' does not change sign across the neighbour: minimise S itself there
        a, b = xs[max(i - 1, 0)], xs[min(i + 1, len(xs) - 1)]
        kr = float(minimize_scalar(lambda x: float(np.sum(resid(x) ** 2)), bounds=(a, b), method="bounded",
                                   options={"xatol": KR_RTOL * b}).x)  # fmt: skip
    return float(kr), float(scale * np.sqrt(np.mean(resid(kr) ** 2))), calls[0]


def _root(slope, a: float, b: float, gi_left: float | None = None, gi_right: float | None = None) -> float | None:
    """The root of ``slope`` in ``[a, b]`` by Brent's method when it goes from negative to
    positive there; None otherwise."""
    from scipy.optimize import brentq

    ga = slope(a) if gi_left is None else gi_left
    gb = slope(b) if gi_right is None else gi_right
    if ga == 0.0:
        return float(a)
    if gb == 0.0:
        return float(b)
    if not (ga < 0.0 < gb):
        return None
    return float(brentq(slope, a, b, xtol=1e-300, rtol=KR_RTOL))


# ----------------------------------------------------------------------------- driver


@dataclass
class VeticaResult:
    """VETICA on one record: values (means over taps), per-tap values and diagnostics."""

    values: dict  # tau_c, k_g, k_r, tau_r, k0, k_inf, cd -> float (nan if not measured)
    per_tap: dict  # the same -> array (tau_c: one per creep interval)
    taps: int
    z1: float
    timing_s: dict
    diagnostics: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)

    def spread(self) -> dict:
        return {k: Spread.of(v) for k, v in self.per_tap.items()}


def _mean(values: np.ndarray) -> float:
    """Mean of the finite ``values`` (nan for none), as ``np.nanmean``; a few values (a pixel's
    taps) summed in a plain loop, which is numpy's own order below eight values."""
    if len(values) < 8:
        total, n = 0.0, 0
        for v in np.asarray(values, dtype=float).tolist():
            if math.isfinite(v):
                total += v
                n += 1
        return total / n if n else math.nan
    return float(np.nanmean(values)) if np.any(np.isfinite(values)) else math.nan


@dataclass
class Contacts:
    """Every complete tap's contact, from its contact minimum to its separation minimum (both
    included), as plain arrays for the compiled stages (:mod:`vetica_cli.core.superposition`):
    the samples of all taps end to end, tap ``j``'s in ``[start[j], stop[j])``."""

    delta: np.ndarray  # [m] indentation from the contact minimum, z_tip(contact) - z_tip
    z: np.ndarray  # [m] tip position
    f: np.ndarray  # [N] force
    u: np.ndarray  # [s] time from the contact minimum
    start: np.ndarray  # first sample of each tap
    stop: np.ndarray  # one past its last
    h: np.ndarray  # [s] each tap's constant sample step (:func:`uniform_step`), nan where it has none
    fc: np.ndarray  # [N] force at each contact minimum
    zc: np.ndarray  # [m] tip position there

    @property
    def samples(self) -> np.ndarray:
        """Samples of each contact."""
        return self.stop - self.start


def contacts_of(t, z, f, taps: Taps) -> Contacts:
    """The taps' contacts as :class:`Contacts`."""
    parts, start, stop, h = [], [], [], []
    at = 0
    for ic, isep in zip(taps.contact, taps.separation):
        sl = slice(int(ic), int(isep) + 1)
        u = t[sl] - t[ic]
        parts.append((float(z[ic]) - z[sl], z[sl], f[sl], u))
        step = uniform_step(u)
        start.append(at)
        at += len(u)
        stop.append(at)
        h.append(math.nan if step is None else step)
    cat = [np.concatenate([p[k] for p in parts]) if parts else np.empty(0) for k in range(4)]
    return Contacts(delta=cat[0], z=cat[1], f=cat[2], u=cat[3], start=np.array(start, dtype=np.int64),
                    stop=np.array(stop, dtype=np.int64), h=np.array(h, dtype=float),
                    fc=np.array([float(f[i]) for i in taps.contact]), zc=np.array([float(z[i]) for i in taps.contact]))  # fmt: skip


@dataclass
class Stage1:
    """What stages 1a and 1b read of a record that depends neither on Z1 nor on the Kg scale
    of the error bars: the taps, stage 1b's slopes as measured (:func:`stage1b_kg`) and its
    windows' bookkeeping.  Measured once per record and window (:func:`record_stage1`); the
    error bars' and checks' re-runs at a moved Z1 or Kg start from it."""

    taps: Taps
    kg: np.ndarray  # [N/m] stage 1b per tap, unscaled
    windows: dict | None  # stage 1b's windows (None: the thesis's)
    kg_points: int
    kg_window: str
    contacts: Contacts | None = None  # the contacts for the compiled stage 2 (None: measured without the times)


def measure_stage1(z, f, kg_points: int, taps: Taps | None = None, kg_window: str = "noise", t=None) -> Stage1:
    """The taps (located on ``f`` unless given), stage 1b's slopes and, with the times ``t``, the
    contacts; InputError for fewer than two complete taps."""
    taps = find_taps(f) if taps is None else taps
    n_taps = len(taps.contact)
    if n_taps < 2:
        raise InputError(
            f"too few taps: {n_taps} complete tap(s) in the record ({taps.incomplete} cut by its ends), need at least 2"
        )
    kg, windows = stage1b_kg(z, f, taps, kg_points, kg_window, details=True)
    contacts = None if t is None else contacts_of(t, z, f, taps)
    return Stage1(taps=taps, kg=kg, windows=windows, kg_points=kg_points, kg_window=kg_window, contacts=contacts)


def record_stage1(record: Record, kg_points: int, kg_window: str) -> Stage1:
    """:func:`measure_stage1` of ``record``, kept on it (``record.memo``, shared by the records
    :func:`dataclasses.replace` makes of it with another Z1) for the same force, position and
    taps: every re-run of a tap method on the record (error bars, checks) reads it once."""
    key = ("tap-stage1", id(record.f), kg_points, kg_window)  # a record low-passed once more (error bars) has its own
    memo = getattr(record, "memo", None)  # None: a record-like object without one (measured every time)
    held = None if memo is None else memo.get(key)
    if held is not None and held[0] is record.f and held[1] is record.z and held[2] is record.taps:
        return held[3]
    stage1 = measure_stage1(record.z, record.f, kg_points, record.taps, kg_window, record.t)
    if memo is not None:
        memo[key] = (record.f, record.z, record.taps, stage1)  # the arrays held: their ids cannot be reused
    return stage1


def _stage1(t, z, f, z1, kg_points, taps: Taps | None = None, kg_window: str = "noise", stage1: Stage1 | None = None):
    """Taps, then stages 1a and 1b: ``(taps, tau_c per interval, Kg per tap, warnings)``;
    ``stage1``: the record's taps and slopes when already measured (:func:`record_stage1`)."""
    if stage1 is None:
        stage1 = measure_stage1(z, f, kg_points, taps, kg_window, t)
    taps = stage1.taps
    longest = int(np.max(taps.separation - taps.contact)) - 1  # samples after the contact minimum, before separation
    if kg_points > longest:
        raise InputError(
            f"kg_points {kg_points} is not allowed for this record; expected an integer in [2, {max(longest, 2)}] "
            "(samples after the contact minimum in its longest contact)"
        )
    warnings = []
    pk = np.diff(taps.peak)
    if len(pk) and np.ptp(pk) > 0.1 * np.median(pk):
        warnings.append("irregular tap spacing (chatter or several contacts per drive period?)")
    return taps, stage1a_tau_c(t, z, taps, z1), stage1.kg, warnings


def _stage1_warnings(tau_c: float, kg: float, z1: float, kg_points: int) -> list[str]:
    out = []
    if math.isnan(tau_c):
        out.append(
            "stage 1a: no creep interval gives a retardation time (positions at separation and next contact "
            f"not both below Z1 = {z1:.4g} m with the surface recovering); tau_c and stage 2 skipped"
        )
    if math.isnan(kg):
        out.append(f"stage 1b: contacts shorter than kg_points = {kg_points} samples; Kg and stage 2 skipped")
    elif kg <= 0:
        out.append(f"stage 1b: the initial contact slope gives Kg = {kg:.4g} N/m <= 0; stage 2 skipped")
    return out


STAGE2 = ("closed", "sines")  # stage-2 solvers: compiled superposition of the samples | the thesis's sine fit


def uniform_step(u: np.ndarray) -> float | None:
    """The constant sample step of ``u`` [s], or None when the steps differ by more than 1e-3 of it."""
    if len(u) < 2:
        return None
    h = (u[-1] - u[0]) / (len(u) - 1)
    return h if h > 0 and np.max(np.abs(np.diff(u) - h)) <= 1e-3 * h else None


def stage2_tap_closed(u, z, f, kg: float, tau_c: float, fc: float, kr_guess: float | None = None,
                      sigma: tuple = (0.0, 0.0), fit_sigma: bool = False, warm: bool = False):  # fmt: skip
    """Stage 2 of one tap without the sum-of-sines fit (``stage2='closed'``): ``(Kr, sigma0 [N],
    residual RMS [N], cost evaluations)``, or None when the contact is not sampled at a
    constant step (the caller then uses the thesis's path).

    The indentation ``Zc - z_tip`` is taken as linear between the samples, on which the
    superposition integral against ``exp(-u/tau_r)`` is exact by recursion, and the same
    cost as :func:`stage2_kr` (over every contact sample) is solved for Kr the same way,
    compiled (:func:`vetica_cli.core.superposition.solve_kr`).  The thesis's sine fit
    smooths the trajectory first; on noise-free records of 1 ns samples the two agree to
    ~1e-4 relative in Kr (tests/test_realtime.py).  ``sigma = (sa, sb)``: the pre-stress
    ``sa + sb Kr`` (:mod:`.vetica_prestress`; 0 for VETICA), or with ``fit_sigma`` a
    parameter fitted with Kr.  ``warm``: ``kr_guess`` is the previous iteration's Kr (the
    root is bracketed near it instead of scanning the bounds; same root).
    """
    from ...core.superposition import solve_kr  # lazy: numba only when a record is extracted

    u = np.asarray(u, dtype=float)
    h = uniform_step(u)
    if h is None:
        return None
    delta = float(z[0]) - np.asarray(z, dtype=float)
    guess = -1.0 if kr_guess is None else float(kr_guess)
    kr, s0, rms, calls = solve_kr(delta, np.asarray(f, dtype=float), h, float(kg), float(tau_c), float(fc), guess,
                                  float(sigma[0]), float(sigma[1]), bool(fit_sigma), 0 if warm else KR_SCAN,
                                  KR_RTOL)  # fmt: skip
    return float(kr), float(s0), float(rms), int(calls)


def stage2_tap(u, z, f, kg: float, tau_c: float, fc: float, kr_guess=None, solver: str = "closed"):
    """Kr of one tap from its contact samples (``u`` [s] from the contact minimum, ``z_tip``,
    force): ``(Kr, sine-fit RMS [m] or nan, force residual RMS [N], cost evaluations)``."""
    if solver == "closed":
        out = stage2_tap_closed(u, z, f, kg, tau_c, fc, kr_guess)
        if out is not None:
            return out[0], math.nan, out[2], out[3]
    fit = fit_sum_of_sines(u, z)
    kr, rms, nf = stage2_kr(u, f, fit, kg, tau_c, fc, kr_guess)
    return kr, fit.rms, rms, nf


def _stage2_compiled(c: Contacts, kg: float, tau_c: float, kr_guess):
    """:func:`_stage2` with ``solver='closed'`` in one compiled call over the taps
    (:func:`vetica_cli.core.superposition.solve_taps`); None when a contact has no constant step."""
    from ...core.superposition import solve_taps

    long = c.samples >= MIN_CONTACT_SAMPLES + 1  # isep - ic >= MIN_CONTACT_SAMPLES
    if not np.all(np.isfinite(c.h[long])):
        return None
    n = len(c.start)
    start = np.where(long, c.start, -1)
    guess = np.full(n, -1.0 if kr_guess is None else float(kr_guess))
    warm = np.zeros(n, dtype=bool)
    kr, s0, rms = np.full(n, math.nan), np.zeros(n), np.zeros(n)
    calls = np.zeros(n, dtype=np.int64)
    zeros = np.zeros(n)
    solve_taps(c.delta, c.f, start, c.stop, c.h, float(kg), float(tau_c), c.fc, guess, warm, zeros, zeros, False,
               KR_SCAN, KR_RTOL, kr, s0, rms, calls)  # fmt: skip
    return (list(kr), [math.nan] * int(np.sum(long)), [float(x) for x in rms[long]],
            [int(x) for x in calls[long]])  # fmt: skip


def _stage2(t, z, f, taps: Taps, kg: float, tau_c: float, kr_guess, solver: str = "closed",
            contacts: Contacts | None = None):  # fmt: skip
    """Kr of every tap long enough (nan otherwise) and the fit residuals of those fitted; with
    the ``contacts`` (and ``solver='closed'``) in one compiled call (:func:`_stage2_compiled`)."""
    if solver == "closed" and contacts is not None:
        out = _stage2_compiled(contacts, kg, tau_c, kr_guess)
        if out is not None:
            return out
    kr_i, fit_rms, f_rms, nfev = [], [], [], []
    for ic, isep in zip(taps.contact, taps.separation):
        if isep - ic < MIN_CONTACT_SAMPLES:
            kr_i.append(math.nan)
            continue
        sl = slice(ic, isep + 1)
        kr, zrms, rms, nf = stage2_tap(t[sl] - t[ic], z[sl], f[sl], kg, tau_c, float(f[ic]), kr_guess, solver)
        kr_i.append(kr)
        fit_rms.append(zrms)
        f_rms.append(rms)
        nfev.append(nf)
    return kr_i, fit_rms, f_rms, nfev


def vetica(
    t: np.ndarray,
    z: np.ndarray,
    f: np.ndarray,
    z1: float,
    kg_points: int = 10,
    kr_guess: float | None = None,
    stage2: str = "closed",
    taps: Taps | None = None,
    kg_window: str = "noise",
    kg_scale: float = 1.0,
    stage1: Stage1 | None = None,
    lean: bool = False,
) -> VeticaResult:
    """Run VETICA stages 1a, 1b and 2 on a record of consecutive taps.

    Values are the means over taps (``tau_c`` over creep intervals); stage 2
    fits each tap with the mean ``tau_c`` and ``Kg``, and the derived
    ``k0, k_inf, tau_r, cd`` use the mean ``Kr``.  Per-tap arrays give the
    spread.  A stage that cannot produce a value (no creep interval with
    the surface recovering below Z1, or contacts shorter than ``kg_points``)
    gives nan for it and for what depends on it, with a warning.  Raises
    InputError for no contact or fewer than two complete taps.  ``stage2``: 'closed'
    (:func:`stage2_tap_closed`, compiled, the default) or 'sines' (the thesis's sum-of-sines
    fit, :func:`fit_sum_of_sines` and :func:`stage2_kr`).  ``taps``: the record's taps when
    already located (else :func:`~vetica_cli.signals.taps.find_taps` on ``f``).  ``stage1``:
    the record's taps and stage 1b's slopes when already measured (:func:`record_stage1`);
    ``lean``: the values and the per-tap Kr only (no other
    per-tap values, diagnostics or warnings: the error bars' re-runs on a record already checked).
    """
    if stage2 not in STAGE2:
        raise InputError(f"stage2 {stage2!r} not allowed; choose one of: {', '.join(STAGE2)}")
    t = np.asarray(t, dtype=float)
    z = np.asarray(z, dtype=float)
    f = np.asarray(f, dtype=float)
    if kg_points < 2:
        raise InputError(f"kg_points {kg_points} not allowed; expected an integer >= 2")
    t0 = time.perf_counter()
    if stage1 is None:
        stage1 = measure_stage1(z, f, kg_points, taps, kg_window, t)
    if lean:
        taps, tau_c_i, kg_i, warnings = stage1.taps, stage1a_tau_c(t, z, stage1.taps, z1), stage1.kg, []
    else:
        taps, tau_c_i, kg_i, warnings = _stage1(t, z, f, z1, kg_points, taps, kg_window, stage1)
    kg_i = kg_i * kg_scale  # the error bars move Kg to see how stage 2 follows it
    n_taps = len(taps.contact)
    t1 = time.perf_counter()
    tau_c, kg = _mean(tau_c_i), _mean(kg_i)
    warnings += _stage1_warnings(tau_c, kg, z1, kg_points)
    run2 = not (math.isnan(tau_c) or math.isnan(kg)) and kg > 0
    contacts = stage1.contacts
    kr_i, fit_rms, f_rms, nfev = (_stage2(t, z, f, taps, kg, tau_c, kr_guess, stage2, contacts) if run2
                                  else ([], [], [], []))  # fmt: skip
    t2 = time.perf_counter()
    kr_i = np.array(kr_i) if kr_i else np.full(n_taps, math.nan)
    if lean:
        return VeticaResult(values=sls_elements(tau_c, kg, _mean(kr_i)), per_tap={"k_r": kr_i}, taps=n_taps,
                            z1=float(z1), timing_s={})  # fmt: skip
    if run2 and not fit_rms:
        warnings.append(f"stage 2: every contact is shorter than {MIN_CONTACT_SAMPLES} samples; Kr skipped")
    per = [sls_elements(tau_c, kg, k) for k in kr_i]
    per_tap = {
        "tau_c": tau_c_i,
        "k_g": kg_i,
        "k_r": kr_i,
        **{k: np.array([p[k] for p in per]) for k in ("tau_r", "k0", "k_inf", "cd")},
    }
    diagnostics = {"contact_samples": int(np.median(taps.separation - taps.contact))}
    if fit_rms:
        diagnostics.update(force_fit_rms_n=float(np.max(f_rms)), kr_nfev_max=int(np.max(nfev)))
        if np.any(np.isfinite(fit_rms)):
            diagnostics["sine_fit_rms_m"] = float(np.nanmax(fit_rms))
        diagnostics["stage2"] = "sines" if np.all(np.isfinite(fit_rms)) else stage2
    return VeticaResult(
        values=sls_elements(tau_c, kg, _mean(kr_i)),
        per_tap=per_tap,
        taps=n_taps,
        z1=float(z1),
        timing_s={"stage1": t1 - t0, "stage2": t2 - t1, "stage2_per_tap": (t2 - t1) / n_taps},
        diagnostics=diagnostics,
        warnings=warnings,
    )


class TapMethod(ExtractionMethod):
    """The tap family (VETICA and its pre-stress variant): the stages read tap by tap, their
    error bars (:mod:`.tapsigmas`) and checks (:mod:`.tapchecks`), refereed by the whole-cycle fit."""

    referee = "full"  # the whole-cycle fit on the same record judges the stages (tapchecks.referee)

    def sigmas(self, res: ExtractionResult, record: Record, options: dict) -> tuple[dict, dict]:
        """Spread over taps with the Z1 and Kg terms (:func:`.tapsigmas.tap_method_sigmas`)."""
        from .tapsigmas import tap_method_sigmas

        return tap_method_sigmas(res, record, self, options)

    def checks(self, res: ExtractionResult, record: Record, options: dict, info: dict) -> None:
        """The tap family's stage checks (:func:`.tapchecks.stage_checks`)."""
        from .tapchecks import stage_checks

        stage_checks(self, res, record, options, info)

    def flag_dependents(self, res: ExtractionResult) -> None:
        """Stage 2 and the elements follow a flagged tau_c or Kg (:func:`.tapchecks.stage_dependents`)."""
        from .tapchecks import stage_dependents

        stage_dependents(res)

    def moved(self, record: Record, options: dict, z1: float | None = None, kg_scale: float | None = None) -> dict:
        """The estimates (values only) of the method re-run on ``record`` with Z1 at ``z1`` and/or the
        option ``kg_scale`` at ``kg_scale`` (the error bars' re-runs): only the stages that move, from
        the taps, slopes and contacts measured once (:func:`record_stage1`), with each stage solved
        exactly as a whole run solves it (the same roots)."""
        opts = options if kg_scale is None else {**options, "kg_scale": kg_scale}
        return self.values_at(record, opts, record.z1 if z1 is None else z1)

    def kg_windows(self, record: Record, options: dict) -> dict:
        """Stage 1b's window bookkeeping on ``record`` (:func:`record_stage1`, measured once; ``{}``
        for the thesis's windows): the error bars' contact-location term reads it."""
        return record_stage1(record, options["kg_points"], options["kg_window"]).windows or {}

    def values_at(self, record: Record, options: dict, z1: float | None = None) -> dict:
        """The estimates (values only: no spread, sigma or checks) of the method on ``record`` at
        ``z1`` (default the record's): the checks' comparison of the two VETICA variants and the
        error bars' re-runs (:meth:`moved`)."""
        ex = self.tap_pass(record, options, record.z1 if z1 is None else z1, lean=True)
        units = {k: q.unit for k, q in self.quantities(record.model).items()}
        return estimates(ex.values, units)

    def tap_pass(self, record: Record, options: dict, z1: float, lean: bool = False):
        """The method's stages on ``record`` at ``z1`` (its own result type) from the record's taps,
        slopes and contacts measured once; ``lean``: its values only."""
        raise NotImplementedError  # pragma: no cover - each tap method has its own


@register
class Vetica(TapMethod):
    """VETICA (thesis 3.3): Z1 from the approach, then stages 1a, 1b and 2 on the steady taps."""

    key = "vetica"
    description = "VETICA (thesis 3.3): creep between taps, initial contact slope, superposition fit"
    title = "VETICA"
    surface_models = ("sls",)
    tap_windows = True  # the force is read only around the contacts (and the approach's first contact)
    kernel_modules = ("superposition",)  # stage 2, closed (measured: simulation.jit)
    surface_note = "VETICA assumes one relaxation time (thesis 3.3)"
    option_specs = (KG_POINTS, Option("kr_guess", "float", None, "N/m", "start of the rubbery stiffness Kr in the "
                                      "superposition fit (default: from the creep)", (lambda v: v > 0, "a stiffness > 0 N/m")),
                    Option("stage2", "str", "closed", "", "closed (compiled superposition of the samples) or sines (the "
                           "thesis's sum-of-sines fit)", one_of(*STAGE2), flag="--stage2"), KG_WINDOW, KG_SCALE)  # fmt: skip
    references = ("thesis 3.3 (stages 1a, 1b, 2; eqs. 73-84)",)
    scan_maps = ("tau_c",)  # drawn in a scan's instrument figure
    seconds_per_point = 0.45  # both forces, 10 periods at 0.125 ns: 0.44 CPU s measured with standard errors and checks

    compared_with = "vetica-prestress"  # the thesis's stages against the pre-stress at contact (tapchecks)

    def tap_pass(self, record: Record, options: dict, z1: float, lean: bool = False) -> VeticaResult:
        """:func:`vetica` on the record's taps and slopes measured once (:func:`record_stage1`)."""
        stage1 = record_stage1(record, options["kg_points"], options["kg_window"])
        return vetica(record.t, record.z, record.f, z1, kg_points=options["kg_points"],
                      kr_guess=options["kr_guess"], stage2=options["stage2"], taps=record.taps,
                      kg_window=options["kg_window"], kg_scale=options.get("kg_scale", 1.0), stage1=stage1,
                      lean=lean)  # fmt: skip

    def run(self, record: Record, options: dict) -> ExtractionResult:
        if options["stage2"] not in STAGE2:
            raise InputError(f"stage2 {options['stage2']!r} not allowed; choose one of: {', '.join(STAGE2)}")
        if options["kg_points"] < 2:
            raise InputError(f"kg_points {options['kg_points']} not allowed; expected an integer >= 2")
        ex = self.tap_pass(record, options, record.z1)
        units = {k: q.unit for k, q in self.quantities(record.model).items()}
        timing = {"reconstruction": record.reconstruction_s, **ex.timing_s,
                  "total": time.perf_counter() - record.t_start}  # fmt: skip
        res = ExtractionResult(
            method=self.key,
            force=record.force,
            taps=ex.taps,
            estimates=estimates(ex.values, units, record.truth, spreads=ex.spread()),
            model=record.model.key,
            info=record.info,
            diagnostics=ex.diagnostics,
            warnings=ex.warnings + record.meta_warnings,
            timing_s=timing,
        )
        return res

    def timing_line(self, timing_s: dict) -> str:
        tm = timing_s
        return (
            f"time: reconstruction {tm.get('reconstruction', 0):.4f} s, stage 1 {tm.get('stage1', 0):.4f} s, "
            f"stage 2 {tm.get('stage2', 0):.4f} s ({tm.get('stage2_per_tap', 0) * 1e3:.2f} ms per tap)"
        )
