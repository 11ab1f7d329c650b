"""The ``full`` extraction method: coarse-to-fine whole-cycle fit of one record
(the choices are in :mod:`vetica_cli.extraction.fullfit`)."""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from ... import surfaces
from ...constants import TIP_RADIUS
from ...checks import MAX_ARMS, limit, one_of
from ...errors import InputError
from ...signals.slopes import noise_floor
from ...signals.taps import find_taps
from ...surfaces import COMMON_KEYS
from ..base import KG_POINTS, ExtractionMethod, Option, register
from ..record import Record
from ..referee import memo_key
from ..result import ExtractionResult, estimates, finite_or_none
from ..uncertainty import t_factor
from .eiv import correct_z_noise
from .fit import CD_SCAN, HAMAKER_BOUNDS, OFFSET_UNIT, FitVector, fit_surface, solve
from .model import SurfaceFit
from .start import generic_start, starting_point
from .uncertainty import (
    band_noise_meat, covariance, gn_gain, height_sensitivity, identifiability, misfit_term, own_sigma,
    drive_period, propagate, release_significant, sandwich, systematic_misfit, tap_covariance, tap_groups,
)

STATES = ("auto", "periodic", "free")  # dashpot state at the window start
FREE_NFEV = 25  # evaluation budget of the free-start-state stage (whole window)
RELEASE_P = 1e-3  # 'auto' also frees the start state where the linearised step's gain is this unlikely as noise
SUB_PERIODS = 1  # drive periods of the first (coarse) fit stage
PINNED_NFEV = 30  # whole-window evaluations once the height, pinned to Z1 on the first periods, is freed
ARM_TAU_STEPS = (1e-3, 1e-2, 1e-1, 10.0, 100.0, 1000.0)  # a new arm's tau relative to the nearest arm's
ARM_TRY_NFEV = 5  # evaluations per candidate arm
ARM_NFEV = 40  # evaluations of the best candidate on the first period
# first-period evaluations when no approach tap pins the surface height: the height and the split of Kg
# between k_inf and a slow dashpot form a long curved valley (on the periodic orbit the arms sit at the
# surface's mean position <X> = -<Fts>/k_inf), which least squares follows slowly but surely; measured
# (cd = 3e-4 kg/s, 16:1, stripped record): 25 evaluations stop at k_inf +375 %, 100 at +64 %, 300 at 1e-5
FREE_HEIGHT_NFEV = 400
# the first stage is fitted twice, the better kept, where the cd scan's best start is the grid's frozen end after a
# poor start (fit.scan_cd: also from the best cd below it; a stripped noise-free record of a snapping surface, H R
# fitted, stopped on the plateau at cd 42 kg/s, every quantity flagged, where the truth is 8.4e-4), or where
# a first-stage fit whose RMS residual exceeds POOR_FIT x the force's noise floor and POOR_FIT_MIN of the peak,
# after a scan that only looked near a good start, scans the whole cd grid and fits again (the better kept): on a
# 300 K record (k_inf 5.04, k0 26.1 N/m, cd 4.3e-4 kg/s; draw 20) the generic start's Gauss-Newton step swapped
# k_inf and k0 (22.8, 6.9 N/m) at an RMS of 3.5 % ("good"), and the fit stopped at k_inf +53 %, cd -21 %
# (unflagged, sigma 10 %) with 2.4 % RMS on its first period against 0.7 % in the right valley (noise 0.45 %)
POOR_FIT, POOR_FIT_MIN = 3.0, 0.01
# a first stage still poor after that is fitted again from the scan's other points, in the order of their cost,
# up to this many, until one is not poor (the best kept): a draw-21 300 K record (k_inf 3.67, k0 37.9 N/m, cd
# 5.1e-4 kg/s) whose whole scan chose the frozen plateau converged to k_inf +18 % with the surface 148 pm under
# its Z1, RMS 1.9 % on the first period (noise 0.36 %); the scan's points at cd 1e-6 and 1e-4 reach the right
# valley (RMS 0.46 %, 18x lower cost)
POOR_STARTS = 7
# still poor after those: every start so far split Kg as the first (VETICA's) did; the first stage is fitted once more
# from the generic split (start.generic_start: k0 = 0.9 Kg of the loading slope), over the whole cd grid, the better
# kept: on a 300 K replica of a stiff surface (k_inf 9.2, k0 238 N/m, cd 3.8e-5 kg/s; draw 30) VETICA's first taps
# gave k_inf 39.5, k0 0.12 N/m, the scan's one Gauss-Newton step per cd reached k0 <= 0.9 N/m, and every start stayed
# at an RMS of 16 % of the peak; the fit ended at k_g 1e6 N/m, flagged, and left the tap methods without the band
# term its surface measures.  From the generic split: 0.3 %, every parameter within 0.2 % of the truth
GENERIC_RETRY = True
# a first stage that ends on the frozen plateau (cd beyond the grid's frozen end) is fitted again from the scan's best
# point below it, the better kept: the plateau has no gradient in cd and a fit started below it may walk onto it. With
# the simulator's own contact step, a 16:1 record (cd 1e-3 kg/s, 0.125 ns, 1 pm of detector noise, the force
# reconstructed and low-passed at 5.5 MHz) went from its scan's start to cd 4.5e4 kg/s at an RMS of 1.96 % of the peak
# (every quantity flagged) where the right valley is at 1.43 %; from below: cd -1.7 %, k0 -0.27 %
FROZEN_RETRY = True
# still poor after those: the loading slope was read as Kg (VETICA's start, the generic split), which it is when the arm
# relaxes slower than a tap loads; an arm faster than the loading has relaxed while the tip pushes in, and the slope
# is k_inf.  The first stage is fitted again from k_inf = the slope and k0 = FAST_ARM_RATIOS x it in turn (cd from the
# whole grid), until one is not poor, the best kept: a record of the worked example's SLS with tau = 20 ns (k_inf 4,
# k0 128 N/m, cd 2.56e-6 kg/s; tau f1 = 1e-3, the cross-model study, reconstructed force) started from Kg = 1.5 N/m and
# every start ended with k0 at its bound (a Kelvin-Voigt surface) at an RMS of 4.2 % of the peak, tau -99.7 %, flagged;
# from k0 = 64 x the slope: 0.49 %, k0 -1.2 %, tau +1.3 %.  The ratios span the thesis's stiffness ratios (1:2 .. 32:1)
FAST_ARM_RETRY = True
FAST_ARM_RATIOS = (4.0, 16.0, 64.0)
# still poor after those, from ARM_PROFILE_MIN of the peak (with POOR_FIT x the noise): the first stage is fitted once
# more from the best of the arm's spring and the surface height profiled at the best fit's dashpot (fit.scan_arm), the
# better kept: an arm that relaxes within a few samples shows its spring only in the impact, a valley narrow in both
# that the cd scan's two-decade grid steps over.  A noise-free 16:1 record at cd 1e-7 kg/s (tau 1.6 ns at 0.125 ns,
# method_low_cd; first stage 0.77-0.80 % of the peak, under POOR_FIT_MIN) was fitted with cd within 4 %, k0 -97 % and
# the height 17 pm off at 0.54 % (true force) and 0.73 % (reconstructed), unflagged; from the profile's best: every
# parameter within 0.15 % (both forces), ~1 CPU-s more.  Over the noise-free method-study points (5 stiffness ratios
# x 9 cd at 0.5 ns, 16:1 at 0.125 and 2 ns, both forces) first stages that ended right reached at most 0.28 % but one
# (0.54 %, 16:1 at cd 3.2e-6 kg/s, whose other retries had found the valley); the set-point study's 25 % point (0.33 %
# at the end, right) runs it and keeps its answer (within 1e-5)
ARM_PROFILE_RETRY = True
ARM_PROFILE_MIN = 0.004
HEIGHT_READ_MIN = 0.25  # the height term counts a steady group as a tap's reading when its rows feel the height this
# much of the median group (its column's squared norm): a group below it is a window's end, not a tap (_height_term)
MIN_GROUPS = 3  # taps (with the approach tap) below which the tap-robust error is not estimated
SUBSTEP_DT = 0.025e-9  # [s] surface sub-step near the surface when the record does not say its dt (thesis dt)


# ------------------------------------------------------------------------- known and unknown constants


def surface_constants(record: Record, opts: dict) -> dict:
    """The constants of the attraction and their sources, ``name -> (value, source)``:
    ``a0`` [m], ``tip_radius`` [m], ``hamaker`` [J] (None = unknown: fitted as ``H R``),
    ``vdw_on_surface`` (None = unknown: both tried).  An option (``--a0``,
    ``--tip-radius``, ``--hamaker``, ``--vdw-on-surface``) beats the file's metadata,
    which beats the thesis's default (then 'assumed')."""
    surface, probe = record.surface, record.probe
    out = {}
    for name, given, meta, default in (
        ("a0", opts["a0"], surface.get("a0"), COMMON_KEYS["a0"].default),
        ("tip_radius", opts["tip_radius"], probe.get("tip_radius"), TIP_RADIUS),
        ("hamaker", opts["hamaker"], surface.get("hamaker"), None),
        ("vdw_on_surface", opts["vdw_on_surface"], surface.get("vdw_on_surface"), None),
    ):
        if given is not None:
            out[name] = (given, "given")
        elif meta is not None:
            out[name] = (meta, "metadata")
        else:
            out[name] = (default, "assumed: thesis default" if default is not None else "unknown")
    return out


def fit_model(record: Record, arms: int | None) -> surfaces.SurfaceModel:
    """The surface model fitted: ``arms`` Maxwell arms (1 = the SLS, unless the record's
    surface is a Wiechert), default the record's own surface (the SLS for measured data)."""
    own = record.model.for_params(record.surface) if record.truth else record.model
    if arms is None:
        return own
    if arms == 1 and record.model.key != "wiechert":
        return surfaces.get("sls")
    return surfaces.get("wiechert").with_arms(arms)


def truth_for(record: Record, model: surfaces.SurfaceModel) -> dict | None:
    """The record's theory values the fitted ``model`` can be compared with: all of them for
    the same surface (model and arms), else those of the same name outside the arms."""
    if not record.truth:
        return None
    own = record.model.for_params(record.surface)
    if own.key == model.key and own.parameter_keys == model.parameter_keys:
        return dict(record.truth)
    return {k: v for k, v in record.truth.items() if k in ("k_g", "k_r", "k_inf")}


# ------------------------------------------------------------------------- stages


def _poor(fit: dict, noise: float, floor: float | None = None) -> bool:
    """Whether a first-stage fit is poor enough to scan the whole cd grid again (``POOR_FIT``; ``floor``: the
    fraction of the peak up to which a fit is not poor, default ``POOR_FIT_MIN``)."""
    rms = math.sqrt(fit["cost"] / max(len(fit["residual"]), 1))
    return rms > max(POOR_FIT * noise, POOR_FIT_MIN if floor is None else floor)


def _stages(make, n, taps, theta0, opts, bounds, n_arms, pin=False, noise=0.0, alt_start=None, generic_first=False):
    """Coarse to fine: scan and fit on the first ``SUB_PERIODS`` drive periods (the periodic
    state of a whole number of periods is the window's), then refine on the whole window;
    then, per ``state``, release the periodic state (module docstring).  Several arms are
    added one at a time on the first periods (:func:`_add_arms`).  ``pin``: the first
    periods are fitted with the surface height pinned to Z1 (a record with Z1 but no
    approach tap; the window then frees it): the height and the split of Kg between k_inf
    and a slow dashpot form a long valley that a fit with a free height may not leave
    (FREE_HEIGHT_NFEV).  ``alt_start``: a callable giving the generic start (GENERIC_RETRY, not tried again
    where it was the first start: ``generic_first``; FAST_ARM_RETRY reads the loading slope from it).
    Returns the whole-window model, the fits of every stage and the free-state gain."""
    fit_hamaker, scan = opts["fit_hamaker"], opts["scan"]
    model = make(n, n_arms)
    cycles = round(n / taps.spacing) if taps.spacing > 0 else 0
    n_sub = round(n * SUB_PERIODS / cycles) if cycles >= 2 * SUB_PERIODS else n
    stages = []
    given = opts["start"] is not None and len(theta0) == model.n_params + 1
    if n_arms > 1 and not given:
        stages = _add_arms(make, n_sub, theta0, bounds, fit_hamaker, scan, n_arms, pin)
    elif n_sub < n:
        sub = make(n_sub, n_arms, pin)
        nfev = FREE_HEIGHT_NFEV if sub.fit_offset and sub.approach is None else 25
        xtol = 1e-10 if sub.fit_offset and sub.approach is None else 1e-6
        stages.append(fit_surface(sub, theta0, bounds, fit_hamaker=fit_hamaker, scan=scan, xtol=xtol, max_nfev=nfev))
        stages[-1]["model"] = sub

        def keep_better(theta, marks=None, **kw):  # the first stage fitted again, the better of the two kept
            again = make(n_sub, n_arms, pin)
            fit = fit_surface(again, theta, bounds, fit_hamaker=fit_hamaker, xtol=xtol, max_nfev=nfev, **kw)
            fit.update(model=again, rescanned=True, **(marks or {}))
            if fit["cost"] < stages[-1]["cost"]:
                stages[-1] = fit

        if scan and stages[-1]["plateau_start"]:
            # the scan's best start is the frozen plateau, which a fit may not leave: also from the best cd below it
            keep_better(theta0, scan=True, off_plateau=True)
        elif scan and len(stages[-1]["scan"]) < len(CD_SCAN) + 1 and _poor(stages[-1], noise):
            # a start good enough to scan only near it, and a poor fit from it: the whole grid
            keep_better(theta0, scan=True, whole_scan=True)
        if scan and _poor(stages[-1], noise):
            # still poor: a local minimum of another split of Kg and surface height; fit from the scan's other
            # points in the order of their cost until one is not poor, the best kept (POOR_STARTS)
            tried = [stages[-1]["start_x"]]
            for _, x in sorted(stages[-1]["scan"], key=lambda p: p[0]):
                if len(tried) > POOR_STARTS or not _poor(stages[-1], noise):
                    break
                if any(np.array_equal(x, t) for t in tried):
                    continue
                tried.append(x)
                keep_better(theta0, {"scan": stages[-1]["scan"]}, start=x)
        if scan and GENERIC_RETRY and alt_start is not None and not generic_first and _poor(stages[-1], noise):
            # still poor: every start so far split Kg as the first one did; the generic split, its whole cd grid
            keep_better(alt_start(), {"generic_start": True}, scan=True, whole_scan=True)
        if scan and FAST_ARM_RETRY and alt_start is not None and _poor(stages[-1], noise):
            # still poor: the loading slope read as k_inf under an arm faster than the loading (FAST_ARM_RATIOS)
            g = alt_start()
            kg = g[0] + g[1]
            for ratio in FAST_ARM_RATIOS:
                keep_better([kg, ratio * kg, g[2], *g[3:]], {"fast_arm_start": ratio}, scan=True, whole_scan=True)
                if not _poor(stages[-1], noise):
                    break
        if scan and ARM_PROFILE_RETRY and _poor(stages[-1], noise, ARM_PROFILE_MIN):
            # still poor: the dashpot may be right with the wrong spring and height; both profiled at its cd
            keep_better(theta0, {"arm_profile": True}, start=stages[-1]["x"], arm_profile=True)
        if scan and FROZEN_RETRY and stages[-1]["theta"][2] >= CD_SCAN[-1]:
            # ended on the frozen plateau, which a fit started below it may walk onto: also from the scan's best
            # point below the plateau, the better kept (FROZEN_RETRY)
            tried, frozen = stages[-1]["start_x"], math.log(CD_SCAN[-1])
            below = [(c, x) for c, x in stages[-1]["scan"] if x[2] < frozen and not np.array_equal(x, tried)]
            if below:
                keep_better(theta0, {"scan": stages[-1]["scan"], "frozen_retry": True},
                            start=min(below, key=lambda p: p[0])[1])  # fmt: skip
    if stages:
        theta0 = stages[-1]["theta"]
        model.warm_start_from(stages[-1]["model"])
    s0_start = stages[-1]["s0"] if stages else None
    s0_ref = stages[0]["s0_ref"] if stages else None
    coarse = bool(stages)
    nfev = (PINNED_NFEV if pin and model.fit_offset else 8) if coarse else 60
    stages.append(fit_surface(model, theta0, bounds, fit_hamaker=fit_hamaker, scan=scan and not coarse, s0=s0_start,
                              s0_ref=s0_ref, xtol=1e-8 if coarse else 1e-10, max_nfev=nfev))  # fmt: skip
    stages[-1]["model"] = model
    # the periodic state is an assumption (a record taken before the surface settled breaks it, and
    # thermal motion does on every record): 'auto' releases it -- fits the dashpot positions at the
    # window start too -- when the linearised model says that would remove more than half the
    # residual, or more than the noise could (an F test); 'free' always does
    last = stages[-1]
    gain = gn_gain(last["residual"], last["jac_free"])
    significant = release_significant(last["jac"], last["jac_free"], gain, RELEASE_P)
    if opts["state"] == "free" or (opts["state"] == "auto" and (gain > 0.5 or significant)):
        # on the whole window: one period holds too little of a slow dashpot's creep
        stages.append(fit_surface(model, last["theta"], bounds, fit_hamaker=fit_hamaker, scan=False, s0=last["s0"],
                                  s0_ref=s0_ref, xd0=last["xd0"], xtol=1e-8, max_nfev=FREE_NFEV))  # fmt: skip
        stages[-1]["model"] = model
    return model, stages, gain


def _add_arms(make, n_sub, theta0, bounds, fit_hamaker, scan, n_arms, pin=False):
    """Several arms, on the first period: fit one arm (the SLS, with its cd scan), then add
    an arm at a time -- its relaxation time ``ARM_TAU_STEPS`` times each present arm's, its
    spring taken from the arms' springs or from ``k_inf`` -- try every candidate briefly,
    and fit the best.  (A sum of exponentials is fitted term by term, as a Prony series
    is: the fit of N - 1 arms is the start of N.)"""
    stages = []
    sub = make(n_sub, 1, pin)
    sls_bounds = {k: bounds[k] for k in ("k_inf", "k_1", "cd_1", "hamaker")}
    free_height = sub.fit_offset and sub.approach is None
    first = fit_surface(sub, theta0, sls_bounds, fit_hamaker=fit_hamaker, scan=scan, xtol=1e-10 if free_height else 1e-6,
                        max_nfev=FREE_HEIGHT_NFEV if free_height else 25)  # fmt: skip
    first["model"] = sub
    stages.append(first)
    theta = first["theta"]
    s0, s0_ref = first["s0"], first["s0_ref"]
    for m in range(2, n_arms + 1):
        sub = make(n_sub, m, pin)
        keys = list(bounds)[: 2 * m + 1] + ["hamaker"]
        mb = {k: bounds[k] for k in keys}
        tried = []
        for cand in _arm_candidates(theta, m - 1):
            sub.reset()
            vec = FitVector(sub, cand, mb, fit_hamaker, s0, None, s0_ref)
            try:
                trial = solve(vec, vec.x0, max_nfev=ARM_TRY_NFEV, xtol=1e-6)
            except (ValueError, FloatingPointError, np.linalg.LinAlgError):
                continue
            if math.isfinite(trial["cost"]):
                tried.append((trial["cost"], cand, trial))
        if not tried:
            raise InputError(f"the fit of {m} arms found no starting point")
        _, _, best = min(tried, key=lambda c: c[0])
        sub.reset()
        vec = FitVector(sub, best["theta"], mb, fit_hamaker, best["s0"], None, s0_ref)
        fit = solve(
            vec, vec.x0, max_nfev=FREE_HEIGHT_NFEV if free_height else ARM_NFEV, xtol=1e-10 if free_height else 1e-7
        )
        fit["model"] = sub
        fit["candidates"] = len(tried)
        stages.append(fit)
        theta, s0 = fit["theta"], fit["s0"]
    return stages


def _arm_candidates(theta, n_arms):
    """Starting vectors of ``n_arms + 1`` arms from a fit of ``n_arms`` (:func:`_add_arms`)."""
    k_inf, k, cd, hr6 = theta[0], np.array(theta[1:-1:2]), np.array(theta[2:-1:2]), theta[-1]
    tau = cd / k
    out = []
    for j in range(n_arms):
        for step in ARM_TAU_STEPS:
            for source in ("arms", "k_inf"):
                if source == "arms":
                    kk, kn, ki = k * 0.7, 0.3 * float(np.sum(k)), k_inf
                else:
                    kk, kn, ki = k, 0.5 * k_inf, 0.5 * k_inf
                tn = tau[j] * step
                arms = sorted([*zip(kk, kk * tau), (kn, kn * tn)], key=lambda a: a[1] / a[0])
                out.append(np.array([ki, *[v for a in arms for v in a], hr6]))
    return out


def order_arms(theta, n_arms: int, truth_taus: list | None):
    """Arms are exchangeable: order the fitted arms by their relaxation time ``cd/k``, rank
    for rank onto the record's own arms when they are known (``truth_taus`` in config order),
    else fastest first.  Returns the permuted parameter vector and the permutation."""
    k = np.asarray(theta[1 : 2 * n_arms + 1 : 2])
    cd = np.asarray(theta[2 : 2 * n_arms + 1 : 2])
    by_tau = np.argsort(cd / k, kind="stable")
    if truth_taus is not None and len(truth_taus) == n_arms:
        slots = np.argsort(np.asarray(truth_taus), kind="stable")  # slot of rank r
        perm = np.empty(n_arms, int)
        perm[slots] = by_tau
    else:
        perm = by_tau
    out = np.array(theta, float)
    out[1 : 2 * n_arms + 1 : 2] = k[perm]
    out[2 : 2 * n_arms + 1 : 2] = cd[perm]
    return out, perm


# ------------------------------------------------------------------------- the method


@register
class FullFit(ExtractionMethod):
    """Whole-cycle inversion: the SLS, Wiechert or Hertzian surface driven by the measured
    tip trajectory, fitted to every sample of the record (:mod:`vetica_cli.extraction.fullfit`)."""

    key = "full"
    # the band term of a low-passed force read on its own fitted surface (uncertainty.model_band), as the tap methods
    # read theirs on it: Richardson's re-runs on the noisy record itself left a -0.2 % bias of k_g and k0 on soft
    # surfaces at 300 K (cut-off 23-31 MHz) under a band sigma that swung 1e-4 .. 9e-3 with the noise (draw 19);
    # read from the fit's linearisation at its optimum (BandLinearisation), not by re-fitting the model's records
    band_model = "full"
    # a quantity whose 1-sigma exceeds half its value (its +-2 sigma reaching zero) is not determined by the record
    # (sanity.check; 1 for the other methods): the fit's error bars are calibrated (held-out widths 0.6-1.6), the tap
    # methods' conservative (up to 2.8), and at 0.5 they would flag 23 right results of draw 29; the fit's k_g on a
    # lab record, 6x the truth at a 1-sigma of 0.88, was the draw's one silently wrong result. No status-ok fit result
    # of any committed table had a 1-sigma between 0.5 and 1 (results/*: only failed lab replicas)
    rel_limit = 0.5
    description = (
        "whole-cycle model inversion (SLS, Wiechert or Hertzian surface): the surface driven by the measured tip, "
        "fitted to every sample"
    )
    title = "whole-cycle fit"
    surface_models = ("sls", "wiechert", "hertz")
    option_specs = (
        KG_POINTS,
        Option("start", "any", None, "", "starting values of the fit ({parameter: value}; default: VETICA's stages on "
               "the record)", settable=False),
        Option("fit_hamaker", "bool", None, "", "fit H R (default: when neither H nor R is known)"),
        Option("near_stride", "int", 4, "", "kernel steps per evaluation near the surface", (lambda v: 1 <= v <= 4096,
               "an integer in 1..4096")),
        Option("far_stride", "int", 256, "", "kernel steps per evaluation far from the surface",
               (lambda v: 1 <= v <= 65536, "an integer in 1..65536")),
        Option("scan", "bool", True, "", "scan cd on a grid before the fit"),
        Option("fit_offset", "bool", None, "", "fit the surface height offset (default: fitted, except where the "
               "record's z_tip is measured from the undeformed surface: Z1 from thesis eq. 84 and no approach "
               "segment, whose premise puts the height at 0)"),
        Option("state", "str", "auto", "", "dashpot state at the window start", one_of(*STATES)),
        Option("substeps", "int", None, "", "kernel substeps per print step (default: from the record's sampling)",
               (lambda v: v >= 1, "an integer >= 1"), settable=False),
        Option("arms", "int", None, "", "Maxwell arms to fit (1 = SLS, 2+ = Wiechert); default: the record's surface, "
               "else 1", (lambda v: 1 <= v <= MAX_ARMS, f"an integer in 1..{MAX_ARMS}"), flag="--arms"),
        Option("hamaker", "float", None, "J", "Hamaker constant H (fixes H R; default: metadata, else H R fitted)",
               limit("surface.hamaker", "a Hamaker constant"), flag="--hamaker"),
        Option("tip_radius", "float", None, "m", "tip radius R (default: metadata, else 10 nm assumed)",
               limit("probe.tip_radius", "a radius"), flag="--tip-radius"),
        Option("a0", "float", None, "m", "intermolecular distance a0 (the record's --a0; default: metadata, else "
               "0.2 nm assumed)", (lambda v: v > 0, "a number > 0 m"), settable=False),
        Option("vdw_on_surface", "bool", None, "", "whether the surface feels the pull (the record's "
               "--vdw-on-surface; unknown: both fitted, the better kept)", settable=False),
        Option("fit_model", "str", None, "", "the surface model fitted (sls, wiechert, hertz); default: the record's "
               "surface, else sls", one_of("sls", "wiechert", "hertz"), flag="--fit-model"),
        Option("nu", "float", None, "", "with hertz: the sample's Poisson ratio (default: metadata, else 0.5 assumed)",
               (lambda v: -1.0 < v <= 0.5, "a Poisson ratio > -1 and <= 0.5"), flag="--nu"),
    )  # fmt: skip
    references = ("thesis 3.2 and appendix C (the surface driven by the tip)", "MDR, Popov & Hess 2015 (hertz)")
    needs_approach = True
    needs_z1 = False
    uniform_sampling = True
    kernel_modules = ("prescribed", "sls", "superposition")  # the forward model and the checks (measured: simulation.jit)
    # both force sources, 10 periods at PS 0.125 ns, cd = 1e-3 kg/s at 16:1: 1.2 s (true) + 1.8 s
    # (reconstructed), measured while the other core was busy
    seconds_per_point = 1.8  # both forces, 10 periods at 0.125 ns: 1.76 CPU s measured

    def continuation(self, res: ExtractionResult) -> dict:
        """Start from the fitted surface, without the cd scan: a snapping surface's samples at
        the jump to contact make the least squares rugged, and a narrower band's fit from
        VETICA's start could land in another valley and read as a band bias of 100s of %."""
        keys = ("k_inf", "k0", "cd")
        values = {k: res.estimates[k].value for k in keys if k in res.estimates}
        if len(values) < len(keys) or any(v is None or not v > 0 for v in values.values()):
            return {}
        fit = res.info.get("fit") or {}
        if list(fit.get("parameters") or [])[:3] != list(keys):  # the SLS's fit only (one arm, not the sphere's)
            return {}
        return {"start": values, "scan": False}

    def sigmas(self, res: ExtractionResult, record: Record, options: dict) -> tuple[dict, dict]:
        """The fit's own sigma, computed in :meth:`run`; where the fit freed the surface height
        from an eq.-84 Z1 (a record without an approach tap), plus in quadrature **the height
        term**: each quantity's change when the height is pinned at that Z1 (:func:`.checks.
        pinned_fit`).  The height and ``k_inf`` and a slow dashpot form a long valley that the
        linearised covariance does not follow: on stripped 300 K records of a 18:1 surface the free
        height sat 100-125 pm from eq. 84's, cd -3 % off the noise-free answer at a sigma of
        0.06 %; the pinned fit was within 1 %.  Beyond 10 % and 3 of the fit's own sigmas the
        check flags the quantity (:func:`.checks.height_freedom`).

        On a force low-passed below the Nyquist frequency the misfit term is left out: the part of the
        residual that repeats every period is then the band's smear of the contact (the model's force is
        not low-passed), which the band term measures on the fitted surface and divides out
        (:func:`..uncertainty.band_term`); counted twice it made the fit's cd and tau_r sigmas 3.0-3.7
        times the replicas' scatter at 300 K (held-out draw 16)."""
        from ..uncertainty import band_limited
        from .checks import pinned_fit

        info = {"source": "the larger of the fit's Jacobian-and-residual error and the tap-robust sandwich"}
        own = {q: e.sigma for q, e in res.estimates.items() if e.value is not None and e.sigma is not None}
        unc = (res.info.get("fit") or {}).get("uncertainty") or {}
        if unc.get("misfit") and band_limited(record):
            white, taps, height = (unc.get(k) or {} for k in ("white", "taps", "height"))
            white = unc.get("noise") or white  # the band's noise through the fit, where it was read
            for q in list(own):
                if q in unc["misfit"] and white.get(q) is not None and taps.get(q) is not None:
                    own[q] = own_sigma(white[q], taps[q], height.get(q) or 0.0)
            info["misfit_term"] = "left out: the band term holds the repeating misfit of a low-passed force"
        alt = pinned_fit(self, res, record, options)
        if alt is None:
            return own, info
        out, rel = dict(own), {}
        for q, e in res.estimates.items():
            a = alt.get(q)
            if q not in own or a is None or a.value is None or not a.value:
                continue
            rel[q] = (e.value - a.value) / abs(a.value)
            out[q] = math.hypot(own[q], rel[q])
        res.__dict__["_pinned"] = (alt, {q: own[q] for q in rel})  # for the check (not a field)
        info["height"] = {"source": "the fit with the height pinned at the undeformed surface (eq. 84's premise): "
                                    "each quantity's change, in quadrature", "change": rel}  # fmt: skip
        return out, info

    def checks(self, res: ExtractionResult, record: Record, options: dict, info: dict) -> None:
        """The fit's residual, a fitted height against the creep, the pinned height and eq. 84's
        bracket (:func:`.checks.fit_checks`)."""
        from .checks import fit_checks

        fit_checks(self, res, record, options, info)

    def flag_dependents(self, res: ExtractionResult) -> None:
        """The SLS's derived quantities carry their parameters' flags where they are the same
        number or scale with it: ``k_r`` is ``k_inf``; ``tau_c`` and ``tau_r`` scale with ``cd``
        (a dashpot with only a bound gives its times only a bound).  A `lab` record's k_r was
        -98 % off at a 26 % sigma, unflagged, while k_inf, the same value, was flagged."""
        from ..sanity import flag

        est = res.estimates
        for q, p in (("k_r", "k_inf"), ("k_inf", "k_r"), ("tau_c", "cd"), ("tau_r", "cd")):
            a, b = est.get(q), est.get(p)
            if a is None or b is None or a.identifiable is False or b.identifiable is not False:
                continue
            if q in ("k_r", "k_inf") and a.value != b.value:  # not the SLS (another model's k_r)
                continue
            flag(res, [q], f"computed from {p}, which is flagged: {str(b.reason or '')[:120]}")

    def run(self, record: Record, options: dict) -> ExtractionResult:
        """Fit the surface's parameters (and what the record does not say: the surface height,
        ``H R``, the surface pull) to the record (:mod:`vetica_cli.extraction.fullfit`)."""
        opts = dict(options)
        if opts.get("fit_offset", True) is None:
            opts["fit_offset"] = not premise_height(record)
        consts = surface_constants(record, opts)
        target = opts["fit_model"] or (record.model.key if record.model.key in self.surface_models else "sls")
        if target == "hertz":  # the sphere on a generalized-Maxwell half-space (fullfit.hertz)
            from .hertz import run_hertz_fit

            return run_hertz_fit(record, opts, consts, self.key)
        if opts["fit_model"] is not None and opts["arms"] is None and record.model.key != opts["fit_model"]:
            opts["arms"] = 1 if opts["fit_model"] == "sls" else 2  # the linear fit of another model's record
        vdw_known = consts["vdw_on_surface"][0]
        choices = [bool(vdw_known)] if vdw_known is not None else [True, False]
        results = [self._run_one(record, opts, consts, vdw) for vdw in choices]
        best = min(results, key=lambda r: r.info["fit"]["residual_rms_pct"])
        forward = best.__dict__.pop("forward", None)
        for r in results:
            r.__dict__.pop("forward", None)
        if forward is not None and hasattr(record, "memo") and dict(options) == self.options({}):
            record.memo[memo_key("forward", self.key, record)] = forward  # (uncertainty.band_term)
        if len(results) > 1:  # the surface pull was unknown: both fitted, the better one kept
            rms = {("on" if r.info["fit"]["vdw_on_surface"] else "off"): r.info["fit"]["residual_rms_pct"]
                   for r in results}  # fmt: skip
            best.info["constants"]["vdw_on_surface"] = {
                "value": best.info["fit"]["vdw_on_surface"],
                "source": "fitted: both tried, the smaller residual kept (RMS % of the peak: "
                + ", ".join(f"{k} {v:.3g}" for k, v in rms.items()) + ")",
            }  # fmt: skip
        correct_z_noise(self, record, opts, consts, best, fit_model(record, opts["arms"]))  # z_tip's white noise
        best.timing_s["total"] = time.perf_counter() - record.t_start
        return best

    def _run_one(self, record: Record, opts: dict, consts: dict, vdw: bool) -> ExtractionResult:
        t, z, f = record.t, record.z, record.f
        h = (t[-1] - t[0]) / (len(t) - 1)
        surface = fit_model(record, opts["arms"])
        n_arms = 1 if surface.key == "sls" else surface.n_arms
        a0, radius = float(consts["a0"][0]), float(consts["tip_radius"][0])
        hamaker = consts["hamaker"][0]
        fit_hamaker = opts["fit_hamaker"] if opts["fit_hamaker"] is not None else hamaker is None
        taps = find_taps(f)
        if len(taps.contact) < 1:
            raise InputError("too few taps: no complete tap in the record")
        if hamaker is not None:
            hr6 = float(hamaker) * radius / 6.0
        else:  # start from the adhesion: the force minimum is -Fa(a0) = -H R/(6 a0^2)
            hr6 = max(-float(np.min(f)), 1e-12) * a0 * a0
        substeps, substeps_source = opts["substeps"], "given"
        if substeps is None:  # the simulator's surface step: dt of the metadata, else the thesis dt
            dt_sim = (record.params.get("numerics") or {}).get("dt")
            substeps = max(1, round(h / (dt_sim or SUBSTEP_DT)))
            substeps_source = "metadata dt" if dt_sim else f"{SUBSTEP_DT * 1e9:g} ns near the surface"
        z1 = record.z1 if record.z1 is not None and math.isfinite(record.z1) else None
        z_ref = z1 if z1 is not None else float(np.median(z[taps.contact]))
        if z1 is not None and record.approach is not None:
            z_ref = max(z_ref, first_touch_top(record.approach))
        info, warnings = dict(record.info), []
        if z1 is None and record.approach is None and opts["fit_offset"]:
            warnings.append(
                "no Z1 (no approach segment, no metadata, no --z1): the surface height is fitted from the steady taps "
                "alone, and for a dashpot that creeps little between taps (e.g. cd >= 1e-3 kg/s at 16:1, 50 kHz) the "
                "fit may split Kg wrongly between k_inf and that dashpot; pass --z1 (the tip position at the first "
                "approach contact) to pin the height"
            )
        start_sls, source = starting_point(t, z, f, z_ref, taps, opts["kg_points"], _sls_start(opts["start"]))
        t_start_done = time.perf_counter()

        made = []  # the models share the approach record and its passes where they can (SurfaceFit's shared)

        # a Z1 from eq. 84 is a record whose z_tip is measured from the undeformed surface (its premise): the
        # height is that surface's, 0, rather than Z1 less a lift measured on the prestressed steady taps
        # (56 pm off on a 5:1 surface that snaps to the tip, and the pinned first stage then sat in k_inf +67 %)
        height = 0.0 if premise_height(record) else None

        def make(n, arms, pinned=False):
            made.append(SurfaceFit(z[:n], f[:n], h, z1, record.approach, a0, radius, vdw,
                                   fit_offset=opts["fit_offset"] and not pinned, near_stride=opts["near_stride"],
                                   far_stride=opts["far_stride"], substeps=substeps, n_arms=arms, z_ref=z_ref,
                                   shared=next((m for m in made if m.n_arms == arms), None), height=height))  # fmt: skip
            return made[-1]

        bounds = {**surface.fit_bounds, "hamaker": HAMAKER_BOUNDS}
        given = opts["start"]
        if n_arms > 1 and given is not None and all(k in given for k in surface.parameter_keys):
            theta0 = [float(given[k]) for k in surface.parameter_keys] + [hr6]
            # stiffnesses rescaled onto the loading slope as the SLS start is (start.starting_point)
            factor = (start_sls["k_inf"] + start_sls["k0"]) / (float(given["k_inf"]) + float(given["k_1"]))
            theta0 = [v * factor if i % 2 == 1 or i == 0 else v for i, v in enumerate(theta0[:-1])] + [hr6]
        else:
            theta0 = [start_sls["k_inf"], start_sls["k0"], start_sls["cd"], hr6]
        opts_run = {**opts, "fit_hamaker": fit_hamaker}
        pin = z1 is not None and record.approach is None and opts["fit_offset"]
        noise = noise_floor(f) / (float(np.max(f)) or 1.0)  # relative to the peak, as the residuals are
        generic = None
        if n_arms == 1 and not source.startswith("given"):

            def generic():  # the generic split (GENERIC_RETRY, FAST_ARM_RETRY), read only where a first stage stays poor
                g = generic_start(z, f, taps)
                return [g["k_inf"], g["k0"], g["cd"], hr6]

        model, stages, info["free_state_gain"] = _stages(make, len(z), taps, theta0, opts_run, bounds, n_arms, pin,
                                                         noise, generic, source.startswith("generic"))  # fmt: skip
        t_fit = time.perf_counter()
        last = stages[-1]
        forward = ForwardForce(model, last["theta"], last["s0"], last["xd0"], model._state[1])
        info["start"] = {"source": source, **start_sls}
        result = self._result(record, surface, model, stages, taps, h, radius, opts_run, info, warnings, consts, vdw,
                              forward)  # fmt: skip
        forward.linear = BandLinearisation(model, last, result.__dict__.pop("_band_gradients"))
        result.forward = forward  # taken off the result by run() and kept on the record
        result.info["fit"]["substeps_source"] = substeps_source
        result.timing_s = {"reconstruction": record.reconstruction_s, "start": t_start_done - record.t_force,
                           "fit": t_fit - t_start_done, "total": time.perf_counter() - record.t_start}  # fmt: skip
        return result

    def _result(self, record, surface, model, stages, taps, h, radius, opts, info, warnings, consts, vdw, forward=None):
        """Values, uncertainties, identifiability and diagnostics of the final stage."""
        fit = stages[-1]
        names, res = list(fit["names"]), fit["residual"]
        n_arms = model.n_arms
        p = model.n_params
        truth = truth_for(record, surface)
        truth_taus = [truth[f"tau_{i}"] for i in range(1, n_arms + 1)] if truth and "tau_1" in truth else None
        theta, perm = order_arms(fit["theta"], n_arms, truth_taus)
        # covariance with the window's start state as unknowns too (conservative: does not lean
        # on the periodic state, which a record taken before the surface settled does not have)
        cov, cov_model = covariance(res, fit["jac_free"]), covariance(res, fit["jac"])
        # the same with correlated noise allowed within a tap (thermal motion, a misfit that repeats
        # with the tap): the spread of the taps' pulls on the estimate, t-scaled for the taps counted
        cov_taps, n_groups = self._tap_covariance(model, taps, res, fit["jac_free"])
        order = [0] + [c for i in perm for c in (1 + 2 * i, 2 + 2 * i)]  # parameter columns after ordering
        idx = order + list(range(p, len(cov)))
        idm = idx[: len(cov_model)]
        cov, cov_model = cov[np.ix_(idx, idx)], cov_model[np.ix_(idm, idm)]
        cov_taps = cov_taps[np.ix_(idx, idx)]
        x = np.asarray(fit["x"])[idx[: len(fit["x"])]]
        lo, hi = np.asarray(fit["lo"])[idx[: len(fit["x"])]], np.asarray(fit["hi"])[idx[: len(fit["x"])]]
        rel = np.maximum(np.sqrt(np.diag(cov))[: len(names)], np.sqrt(np.diag(cov_taps))[: len(names)])
        at_bound = (x - lo < 1e-6) | (hi - x < 1e-6)
        k_inf, k, cd = float(theta[0]), theta[1:p:2], theta[2:p:2]
        params = surface.from_arms(k_inf, k, cd)
        values = surface.theory(params)
        grads = surface.log_gradients(params)
        # d ln q / d x over the fit vector's own columns (arms in the fit's order): the band term's linearisation
        band_g = {}
        for q, g in grads.items():
            v = np.zeros(len(fit["x"]))
            v[order[: len(g)]] = g
            band_g[q] = v
        if opts["fit_hamaker"]:
            band_g["hamaker_radius"] = band_g["hamaker"] = np.eye(len(fit["x"]))[p]
        sigma_white, sigma_taps = propagate(cov, grads), propagate(cov_taps, grads)
        # a force low-passed below the Nyquist frequency: its noise is the band's (rows closer than the band's
        # correlation length share it), not white residuals (_band_noise_cov)
        cov_noise = self._band_noise_cov(record, fit, model, res)
        sigma_noise = propagate(cov_noise[np.ix_(idx, idx)], grads) if cov_noise is not None else None
        # the height's reading error: the approach tap pins the height alone, and reads it as one steady tap does
        s_h, sigma_h = self._height_term(model, taps, res, fit["jac_free"], names, cov, grads)
        contact_s = float(np.median(taps.separation - taps.contact)) * h
        free_s = float(taps.spacing) * h - contact_s
        # the residual's part the record's noise does not explain (the model's misfit) is what a dashpot's
        # signature is held against; the noise's part is in the error bars (relative to the peak force, as res)
        rms = math.sqrt(float(np.mean(res**2)))
        floor = noise_floor(record.f) / model.scale
        # a low-passed force's residual holds the band's smear of the contact (the model's force is not low-passed):
        # the fitted surface's own smear is taken off before the misfit is measured (the band term holds it)
        smear = band_smear(record, model, forward, h)
        rms_model = math.sqrt(float(np.mean((res[: len(smear)] + smear) ** 2))) if smear is not None else rms
        misfit = math.sqrt(max(rms_model**2 - floor**2, 0.0))
        # the misfit term where the residual is more the model's own error (it repeats every period) than
        # noise (a noise-free record: there the Jacobian's error, scaled by that residual, holds none of it);
        # on a noisy record the tap-robust error holds a misfit that repeats with the tap: left out
        period = drive_period(record.z, model.steady.idx, round(taps.spacing))
        repeats, rest = systematic_misfit(res, model.steady.idx, period, floor)
        sigma_misfit = misfit_term(repeats, k_inf, list(zip(k, cd)), contact_s, free_s, grads, len(cov)) \
            if repeats > rest else {}
        sigma = {q: own_sigma(v, sigma_taps[q], sigma_h.get(q, 0.0), sigma_misfit.get(q, 0.0))
                 for q, v in (sigma_noise or sigma_white).items()}  # fmt: skip
        sigma_model = propagate(cov_model, grads)
        units = {q: v.unit for q, v in self.quantities(surface).items()}
        hr = 6.0 * float(theta[p])  # H R [J m]
        if opts["fit_hamaker"]:
            j = names.index("hamaker")
            units["hamaker_radius"] = "J m"
            values["hamaker_radius"] = hr
            sigma["hamaker_radius"], sigma_model["hamaker_radius"] = float(rel[j]), float(math.sqrt(cov_model[j, j]))
            if record.surface.get("hamaker") is not None and record.probe.get("tip_radius") is not None:
                truth = {**(truth or {}), "hamaker_radius": record.surface["hamaker"] * record.probe["tip_radius"]}
            if consts["tip_radius"][1] in ("given", "metadata"):  # H itself only with a known tip radius
                units["hamaker"] = "J"
                values["hamaker"] = hr / radius
                sigma["hamaker"], sigma_model["hamaker"] = sigma["hamaker_radius"], sigma_model["hamaker_radius"]
                if record.surface.get("hamaker") is not None:
                    truth = {**(truth or {}), "hamaker": record.surface["hamaker"]}
        est = estimates(values, units, truth, sigmas=sigma)
        fitted = [n for n in names if n in (*surface.parameter_keys, "hamaker")]  # not s0, xd0: nuisance
        arm_names = [(surface.parameter_keys[1 + 2 * i], surface.parameter_keys[2 + 2 * i]) for i in range(n_arms)]
        ident = identifiability(fitted, rel, at_bound, k_inf, list(zip(k, cd)), arm_names, contact_s, free_s, h,
                                sigma["k_g"], misfit)  # fmt: skip
        if "hamaker" in ident:  # reported as H R (and H when the tip radius is known)
            ok, why = ident.pop("hamaker")
            ident["hamaker_radius"] = (ok, why)
            fitted = [("hamaker_radius" if n == "hamaker" else n) for n in fitted]
        unconverged = gn_gain(res, fit["jac"]) if fit["status"] == 0 else 0.0
        if unconverged > 0.5:  # stopped by the evaluation budget far from the optimum
            why = (f"the fit stopped before converging (one more Gauss-Newton step would remove "
                   f"{100 * unconverged:.0f} % of the residual)")  # fmt: skip
            ident = {k: (False, why + ("; " + v[1] if not v[0] else "")) for k, v in ident.items()}
        for name, (ok, reason) in ident.items():
            est[name] = replace(est[name], identifiable=bool(ok), reason=reason)
        if "hamaker" in est and "hamaker_radius" in ident:
            ok, reason = ident["hamaker_radius"]
            est["hamaker"] = replace(est["hamaker"], identifiable=bool(ok), reason=reason)
        info["fit"] = _fit_info(model, stages, cov, sigma_model, opts, perm)
        info["fit"]["uncertainty"] = {
            "source": "the larger of the Jacobian-and-residual error (white residuals; on a low-passed force the "
                      "band's noise through the fit, 'noise') and the tap-robust sandwich (delete-one-tap jackknife of "
                      "the linearised fit, the approach tap bias-reduced; t-scaled), and in quadrature the height's "
                      "reading error (one steady tap's, the approach tap's) and, where the residual's part "
                      "that repeats every drive period exceeds the rest, the misfit term (that part over each "
                      "dashpot's force signature)",
            "groups": n_groups,
            "white": {k: finite_or_none(v) for k, v in sigma_white.items()},
            "noise": {k: finite_or_none(v) for k, v in sigma_noise.items()} if sigma_noise is not None else None,
            "taps": {k: finite_or_none(v) for k, v in sigma_taps.items()},
            "height": {k: finite_or_none(v) for k, v in sigma_h.items()},
            "height_sigma_m": finite_or_none(s_h),
            "misfit": {k: finite_or_none(v) for k, v in sigma_misfit.items()},
        }  # fmt: skip
        info["fit"]["vdw_on_surface"] = vdw
        info["constants"] = _constants_info(consts, opts, model, fit, vdw, hr)
        rms_pct = info["fit"]["residual_rms_pct"]
        if rms_pct > 1.0:
            warnings.append(
                f"the {surface.name} model does not reproduce the measured force (RMS residual {rms_pct:.2g} % of "
                "the peak): a record taken before the surface settled, chatter, noise, or a surface that is not "
                f"{surface.describe(params)}"
            )
        if fit["status"] <= 0:
            warnings.append(f"least squares did not converge: {fit['message']}")
        out = ExtractionResult(method=self.key, force=record.force, taps=len(taps.contact), estimates=est,
                               model=surface.key, fitted=tuple(ident), info=info,
                               warnings=warnings + record.meta_warnings)  # fmt: skip
        out.__dict__["_band_gradients"] = band_g  # for the forward model's linearisation (not a field)
        return out

    @staticmethod
    def _tap_covariance(model, taps, res, jac):
        """Tap-robust covariance (:func:`.uncertainty.tap_covariance`) of the fit vector,
        scaled by ``t_factor(G)^2`` (G groups: the steady taps and the approach tap), and G.
        Fewer than ``MIN_GROUPS`` groups (the spread of two is no estimate): zero, the white
        error alone."""
        n_app = len(model.approach.idx) if model.approach is not None else 0
        zero = np.zeros((jac.shape[1],) * 2)
        if len(res) != len(model.steady.idx) + n_app or len(taps.contact) < 1:
            return zero, 0
        groups = tap_groups(model.steady.idx, taps.contact, taps.spacing, n_app)
        cov, g = tap_covariance(res, jac, groups)
        return (cov * t_factor(g) ** 2, g) if g >= MIN_GROUPS else (zero, g)

    @staticmethod
    def _band_noise_cov(record, fit, model, res):
        """Covariance of the fit vector (with the window's start state, as ``jac_free``) under the noise
        of a force low-passed below the Nyquist frequency, ``M^-1 J^T Sigma J M^-1`` (``M = J^T J``):
        ``Sigma`` the record's declared noise, white within the band (:func:`.uncertainty.band_noise_meat`;
        a 300 K record's reconstruction error is that: white and stationary within the band, its RMS
        within 7 % of the declared one).  None for a whole-band force or a record without declared noise.

        Measured on 300 K records (dev draws 21-22 of ``scripts/trust.py``, 12 replicas of 6 surfaces):
        the white residual error (:func:`.uncertainty.covariance`) was 2.1-2.3 times short of this term
        (medians per quantity), and refits of the records with that noise added scattered 0.90-0.99 of this
        term (medians per quantity over dev draw 22's 72 records, 8 refits each)."""
        from ...signals import noise as nz
        from ..uncertainty import band_limited

        declared = nz.declared(record.f)
        if not band_limited(record) or declared is None or not declared[1] > 0:
            return None
        jac = fit["jac_free"]
        ns = len(model.steady.idx)
        segments = [(slice(0, ns), model.steady.idx, len(model.steady.want))]
        if model.approach is not None and len(res) > ns:
            segments.append((slice(ns, len(res)), model.approach.idx, len(model.approach.want)))
        fc = float(record.info["cutoff_hz"])
        meat = band_noise_meat(jac, segments, declared[1] / model.scale, float(model.h), fc)
        return sandwich(jac.T @ jac, meat)

    @staticmethod
    def _height_term(model, taps, res, jac, names, cov, grads):
        """``(sigma_h [m], {quantity: relative sigma})``: the approach tap pins the surface height
        almost alone, and one tap reads the height no better than the steady taps' own readings
        scatter.  Each steady tap's reading is its Gauss-Newton step on the height alone (its residual
        rows, every other parameter held); their standard deviation is one tap's height error, the
        approach tap's, and each quantity follows the height as the fit's covariance says
        (:func:`.uncertainty.height_sensitivity`).  On 300 K records the approach's first tap is not
        read as independent noise would be (``scripts/approach_noise.py``: the cantilever's thermal
        motion takes it from no repulsion to twice its noise-free depth) and the residuals' error
        leaves that out; the steady taps go through the same.  Measured on dev draws 21-22 of
        ``scripts/trust.py`` (12 replicas of 6 surfaces): one tap's reading 0.24-1.46 pm where the
        fitted height scattered 0.28-1.32 pm from replica to replica (Z1's jitter, the term this
        replaces, assumed 3-8 pm: tau_c, k_inf, k_r covered 1.00 at widths 3-5).  Nothing without an
        approach tap in the fit, or with fewer than three steady taps."""
        if model.approach is None or "s0" not in names:
            return None, {}
        j = names.index("s0")
        ns = len(model.steady.idx)
        groups = tap_groups(model.steady.idx, taps.contact, taps.spacing)
        cols = [(jac[:ns][groups == g, j], res[:ns][groups == g]) for g in np.unique(groups)]
        norms = np.array([float(c @ c) for c, _ in cols])
        # a group whose rows hardly feel the height is no tap's reading: past the last complete tap the window's
        # end can leave a few rows out of contact (a transient scan pixel: 3 rows of norm 6e-19 read the height
        # 32 nm off, and its fit's sigmas read 9-58 for values within 0.02 % of the truth)
        floor = HEIGHT_READ_MIN * float(np.median(norms)) if len(norms) else 0.0
        reads = [-float(c @ r) / n for (c, r), n in zip(cols, norms) if n > 0.0 and n >= floor]
        if len(reads) < 3:
            return None, {}
        s_h = float(np.std(reads, ddof=1)) * OFFSET_UNIT
        per_m = height_sensitivity(cov, j, grads)
        return s_h, {q: abs(g) * s_h / OFFSET_UNIT if math.isfinite(g) else math.inf for q, g in per_m.items()}

    def detail_lines(self, res: ExtractionResult) -> list[str]:
        """What was fitted and what known or assumed (the constants of the attraction, the
        surface pull, the surface height): the record's metadata, an option or the thesis."""
        c = res.info.get("constants") or {}
        if not c:
            return []
        fitted = [("H R" if n == "hamaker_radius" else n) for n in res.fitted]
        height = c.get("surface_height")
        if height and height["source"].startswith("fitted"):
            fitted.append("surface height")
        pull = c.get("vdw_on_surface")
        if pull and pull["source"].startswith("fitted"):
            fitted.append("surface pull")
        lines = ["fitted: " + ", ".join(fitted)]
        known = []
        for name, text, unit, scale in (("a0", "a0", "nm", 1e9), ("tip_radius", "tip radius", "nm", 1e9),
                                        ("hamaker", "H", "J", 1.0), ("vdw_on_surface", "surface pull", "", 1.0),
                                        ("nu", "nu", "", 1.0)):  # fmt: skip
            e = c.get(name)
            if not e or e["source"].startswith("fitted") or e["value"] is None:
                continue
            v = e["value"]
            shown = ("on" if v else "off") if isinstance(v, bool) else f"{v * scale:.4g} {unit}"
            known.append(f"{text} {shown} ({e['source']})")
        if known:
            lines.append("known or assumed: " + "; ".join(known))
        if pull and pull["source"].startswith("fitted"):
            lines.append(f"surface pull (vdw_on_surface): {'on' if pull['value'] else 'off'}, {pull['source']}")
        if height:
            lines.append(f"surface height: {height['value'] * 1e9:.4f} nm in the record's z_tip ({height['source']})")
        zn = (res.info.get("fit") or {}).get("z_noise") or {}
        if zn.get("applied"):
            moved = ", ".join(f"{q} {100 * v:+.2g} %" for q, v in (zn.get("shift") or {}).items() if v is not None)
            lines.append(f"z_tip's white noise ({zn['sigma_z_m'] * 1e12:.2g} pm) biases the fit by {moved}: taken "
                         "off its values (errors in variables; two refits with the noise doubled)")  # fmt: skip
        return lines


class ForwardForce:
    """The fitted surface's force through the whole band at every sample of the record it was
    fitted to (:meth:`.model.SurfaceFit.force_everywhere`): what a record's low-pass does to
    another method's answer is read on it (:func:`vetica_cli.extraction.uncertainty.band_term`)."""

    def __init__(self, model, theta, s0, xd0, contact0):
        self.model, self.theta, self.s0 = model, np.asarray(theta, float), float(s0)
        self.xd0, self.contact0 = np.atleast_1d(np.asarray(xd0, float)), bool(contact0)
        self.linear = None  # the answer's linear dependence on the fitted force (BandLinearisation)
        self._steady, self._spectrum = None, None

    def steady(self, z) -> np.ndarray:
        """Force [N] at the tip positions ``z`` of the steady window (in its fitted start state); the last
        ``z`` asked for is remembered (the misfit and the band term read the same)."""
        if self._steady is None or self._steady[0] is not z:
            self._steady = (z, self.model.force_everywhere(self.theta, self.s0, self.xd0, self.contact0, z))
            self._spectrum = None
        return self._steady[1]

    def steady_spectrum(self, z):
        """The transform of :meth:`steady`'s force (``uncertainty.Spectrum``), taken once for every
        low-pass of it: the misfit's band smear and the band term's cut-offs."""
        from ..uncertainty import Spectrum

        fs = self.steady(z)
        if self._spectrum is None:
            self._spectrum = Spectrum(fs)
        return self._spectrum

    def approach(self, z) -> np.ndarray:
        """Force [N] at the tip positions ``z`` of the approach (the surface undeformed at its start)."""
        return self.model.force_everywhere(self.theta, self.s0, None, False, z, start=False)


def band_smear(record, model, forward, h: float) -> np.ndarray | None:
    """``(L f - f)/scale`` at the steady residual rows: what the record's low-pass ``L`` (its declared
    cut-off) does to the fitted surface's force ``f`` (``forward``), relative to the peak as the
    residuals are; None for a force not low-passed below the Nyquist frequency."""
    from ..uncertainty import band_limited, lowpass

    if forward is None or not band_limited(record):
        return None
    fs = forward.steady(record.z)
    low = lowpass(fs, h, float(record.info["cutoff_hz"]), spectrum=forward.steady_spectrum(record.z))
    return (low - fs)[model.steady.idx] / model.scale


class BandLinearisation:
    """The fit's answer as a linear function of the force it was fitted to, at its optimum: a change
    ``d`` of the force at the residual rows moves the fit vector by ``J^+ d / scale`` (the least
    squares' normal equations, ``J^T r = 0``, linearised), and each quantity by ``exp(g . dx) - 1``
    (``g = d ln q / dx``).  What a low-pass does to the answer (``uncertainty.model_band``) is then
    a linear solve, not a re-fit: the fit's model of its own fitted surface low-passed moves it by
    ``J^+ (L f - f)``.  Parameters at a bound are held there (a re-fit keeps them).  Where a quantity
    would move by more than ``uncertainty.LINEAR_BAND_MAX`` the linearisation is not trusted and the
    model's records are fitted (a column of J near zero: a dashpot that hardly acts, on a 300 K
    worked-example record, moved cd by e^700)."""

    def __init__(self, model, fit: dict, gradients: dict):
        x, lo, hi = (np.asarray(fit[k], float) for k in ("x", "lo", "hi"))
        self.free = ~((x - lo < 1e-6) | (hi - x < 1e-6))
        self.steady_rows = model.steady.idx.copy()
        self.approach_rows = model.approach.idx.copy() if model.approach is not None else None
        self.scale = float(model.scale)
        self.gradients = {q: np.asarray(g, float)[self.free] for q, g in gradients.items()}
        self._jac, self._qr = np.asarray(fit["jac"], float), None  # factorised when first asked (a band-limited force)

    @property
    def ok(self) -> bool:
        """Whether the linearisation holds: every residual row has its Jacobian row, and the free
        columns are of full rank."""
        if self._qr is None:
            n_rows = len(self.steady_rows) + (len(self.approach_rows) if self.approach_rows is not None else 0)
            good = self._jac.shape[0] == n_rows and bool(self.free.any()) and bool(np.all(np.isfinite(self._jac)))
            q, r = np.linalg.qr(self._jac[:, self.free]) if good else (None, None)
            good = good and np.linalg.matrix_rank(r) == r.shape[1]
            self._qr = (q, r) if good else False
        return self._qr is not False

    def shift(self, d_steady, d_approach=None) -> dict:
        """``{quantity: change of its logarithm}`` of the answer when the force changes by ``d_steady`` at
        every sample of the steady window and ``d_approach`` at every sample of the approach (None:
        unchanged) [N]; the caller judges whether a change is small enough for the linearisation to hold."""
        if not self.ok:
            raise ValueError("the fit's linearisation does not hold")
        d = np.asarray(d_steady, float)[self.steady_rows]
        if self.approach_rows is not None:
            da = np.zeros(len(self.approach_rows)) if d_approach is None else np.asarray(d_approach)[self.approach_rows]
            d = np.concatenate([d, da])
        q, r = self._qr
        dx = np.linalg.solve(r, q.T @ (d / self.scale))
        with np.errstate(all="ignore"):
            return {q: float(g @ dx) for q, g in self.gradients.items()}


def _sls_start(start: dict | None) -> dict | None:
    """The SLS part of a given start (``k_inf, k0, cd``; ``k_1, cd_1`` of a Wiechert start)."""
    if start is None:
        return None
    if all(k in start for k in ("k_inf", "k0", "cd")):
        return start
    if all(k in start for k in ("k_inf", "k_1", "cd_1")):
        return {"k_inf": start["k_inf"], "k0": start["k_1"], "cd": start["cd_1"]}
    raise InputError(f"start {start!r} not allowed; expected k_inf, k0, cd (or k_inf, k_1, cd_1, ...)")


def _constants_info(consts: dict, opts: dict, model: SurfaceFit, fit: dict, vdw: bool, hr: float) -> dict:
    """``info['constants']``: each constant of the attraction and the surface height with its
    value and source (given, metadata, assumed, fitted)."""
    out = {name: {"value": v, "source": src} for name, (v, src) in consts.items()}
    out["vdw_on_surface"] = {"value": vdw, "source": consts["vdw_on_surface"][1]}
    if opts["fit_hamaker"]:
        out["hamaker_radius"] = {"value": hr, "source": "fitted"}
        out["hamaker"] = {"value": consts["hamaker"][0], "source": "fitted as H R"}
        if consts["tip_radius"][1].startswith("assumed"):  # it would only convert H R to H
            out["tip_radius"] = {"value": None, "source": "unknown, not needed: H R fitted"}
    elif consts["hamaker"][0] is None:
        out["hamaker"] = {"value": COMMON_KEYS["hamaker"].default, "source": "assumed: thesis default"}
    out["surface_height"] = {"value": float(fit["s0"]), "source": model.offset_source}
    return out


def first_touch_top(approach) -> float:
    """The tip position at the approach's first deep well read from the force alone
    (:func:`~vetica_cli.signals.taps.first_contact_minimum` without the tip position): on a surface the
    tip's pull drags up, the first contact's pull-off well, where the tip leaves the surface, above Z1
    (read on the way in).  The fit's near band (``NEAR_GAP`` above it) and its start's creep reference
    stay where they were before Z1 was read on the way in: referred to Z1 there (0.87 nm lower on a
    1:2 surface, Kg 6 N/m), the near band no longer covered the approach's snap, the fit's misfit rose
    from 8e-9 to 9e-4 of the peak and k0 went -4.9 % (flagged)."""
    from ...signals.taps import first_contact_minimum

    za, fa, i1 = approach
    try:
        return float(za[first_contact_minimum(fa)])
    except InputError:
        return float(za[i1])


def premise_height(record) -> bool:
    """Whether the record's z_tip is measured from the undeformed surface: a Z1 from thesis eq. 84
    (``a0 + Fa/Kg``, what the user's ``a0`` and surface pull give) and no approach segment.  The
    surface height is then that premise's, 0, and the fit holds it there by default (option
    ``fit_offset``): the tap methods' Z1 stands on the same premise.  Freed, the height wandered
    along the valley it forms with k_inf and a slow dashpot under 0.1 nN of white force noise
    (70-200 pm below the surface, k_inf +11 ... +42 % at a 20 % 1-sigma on a 9:1 surface whose
    pinned fit was within 0.2 %), and the free fit is no test of the premise there."""
    return record.approach is None and str(record.info.get("z1_source", "")).startswith("thesis eq. 84")


def _fit_info(model, stages, cov, unc_periodic, opts, perm) -> dict:
    """What the fit did, for ``info['fit']``."""
    fit = stages[-1]
    names, res = fit["names"], fit["residual"]
    s0_sigma = math.sqrt(cov[names.index("s0"), names.index("s0")]) * OFFSET_UNIT if "s0" in names else None
    xd0 = np.asarray(fit["xd0"], float)[perm]
    n = model.n_arms
    xd0_sigma = [finite_or_none(math.sqrt(cov[-n + i, -n + i]) * OFFSET_UNIT) for i in perm]
    return {
        "parameters": names,
        "arms": n,
        "nfev": [s["nfev"] for s in stages],
        "njev": [s["njev"] for s in stages],
        "status": fit["status"],
        "message": fit["message"],
        "residual_rms_pct": 100.0 * math.sqrt(float(np.mean(res**2))),
        "residuals": len(res),
        "near_samples": model.near_samples,
        "decimation": {"near_stride": opts["near_stride"], "far_stride": opts["far_stride"], "block": model.block},
        "substeps": model.substeps,
        "surface_height_m": float(fit["s0"]),
        "surface_height_sigma_m": finite_or_none(s0_sigma),
        "uncertainty_periodic_state": {k: finite_or_none(v) for k, v in unc_periodic.items()},
        "state": "free" if any(nm.startswith("xd0") for nm in names) else "periodic",
        # the height eq. 84 gives at the fitted parameters (Newton over the approach: the final stage only)
        "surface_height_from_z1_m": finite_or_none(model.z1_offset(fit["theta"], tangents=False)[0])
        if model.z1 is not None else None,
        "surface_height_source": model.offset_source,
        "xd0_m": float(xd0[0]) if n == 1 else [float(v) for v in xd0],
        "xd0_sigma_m": xd0_sigma[0] if n == 1 else xd0_sigma,
        "periodic_residual_m": fit["periodic_residual"],
        "model_passes": int(sum(s["model"].passes for s in stages if "model" in s and s["model"] is not model))
        + int(model.passes),
        "stages": len(stages),
        # the first stage fitted again after a scan of the whole cd grid (POOR_FIT), the better kept
        "rescanned": any(bool(s.get("rescanned")) for s in stages),
        # ... from the generic split of Kg, every start from the first split having stayed poor (GENERIC_RETRY)
        "generic_start": any(bool(s.get("generic_start")) for s in stages),
        "frozen_retry": any(bool(s.get("frozen_retry")) for s in stages),
        # ... from k_inf = the loading slope and k0 this many times it, every earlier start having stayed poor
        "fast_arm_start": next((s["fast_arm_start"] for s in stages if s.get("fast_arm_start")), None),
        # ... from the best of the arm's spring and the height profiled at the best fit's dashpot (ARM_PROFILE_RETRY)
        "arm_profile": any(bool(s.get("arm_profile")) for s in stages),
        "arm_candidates": [s["candidates"] for s in stages if "candidates" in s],
        # samples where the force's sensitivity to the surface diverges (a snap), left out (fit.solve)
        "high_leverage_samples_left_out": sorted({i for s in stages for d in s.get("dropped", ()) for i in d}),
    }
