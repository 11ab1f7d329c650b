"""The ``full`` extraction method: coarse-to-fine whole-cycle fit of one record
(the choices are in :mod:`vetica_cli.extraction.fullfit`)."""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any, ClassVar

import numpy as np

from ...constants import TIP_RADIUS
from ...errors import InputError
from ...signals.taps import find_taps
from ...surfaces import COMMON_KEYS
from ..base import ExtractionMethod, register
from ..record import Record
from ..result import ExtractionResult, estimates, finite_or_none
from .fit import HAMAKER_BOUNDS, OFFSET_UNIT, fit_surface
from .model import SurfaceFit
from .start import starting_point
from .uncertainty import covariance, gn_gain, identifiability, propagate

STATES = ("auto", "periodic", "free")  # dashpot state at the window start
FREE_NFEV = 25  # evaluation budget of the free-start-state stage (whole window)
SUB_PERIODS = 1  # drive periods of the first (coarse) fit stage


def _surface_constants(record: Record) -> tuple[float, float, float, bool]:
    """``(a0, H R/6, tip radius, vdw_on_surface)`` from the metadata, else the thesis defaults."""
    surface, probe = record.surface, record.probe
    a0 = float(surface.get("a0", COMMON_KEYS["a0"].default))
    hamaker = float(surface.get("hamaker", COMMON_KEYS["hamaker"].default))
    radius = float(probe.get("tip_radius", TIP_RADIUS))
    vdw = bool(surface.get("vdw_on_surface", COMMON_KEYS["vdw_on_surface"].default))
    return a0, hamaker * radius / 6.0, radius, vdw


def _stages(make, n, taps, theta0, opts, bounds):
    """Coarse to fine: scan and fit on the first ``SUB_PERIODS`` drive periods (the periodic
    state of a whole number of periods is the window's), then refine on the whole window;
    then, per ``state``, release the periodic state (module docstring).  Returns the
    whole-window model, the fits of every stage and the free-state gain."""
    fit_hamaker, scan = opts["fit_hamaker"], opts["scan"]
    model = make(n)
    cycles = round(n / taps.spacing) if taps.spacing > 0 else 0
    stages = []
    if cycles >= 2 * SUB_PERIODS:
        sub = make(round(n * SUB_PERIODS / cycles))
        stages.append(fit_surface(sub, theta0, bounds, fit_hamaker=fit_hamaker, scan=scan, xtol=1e-6, max_nfev=25))
        theta0 = stages[-1]["theta"]
        model.warm_start_from(sub)
    s0_start = stages[-1]["s0"] if stages else None
    stages.append(fit_surface(model, theta0, bounds, fit_hamaker=fit_hamaker, scan=scan and not stages, s0=s0_start,
                              xtol=1e-8 if stages else 1e-10, max_nfev=8 if stages else 60))  # fmt: skip
    # the periodic state is an assumption (a record taken before the surface settled breaks it):
    # 'auto' releases it -- fits the dashpot position at the window start too -- when the
    # linearised model says that would remove more than half the residual; 'free' always does
    gain = gn_gain(stages[-1]["residual"], stages[-1]["jac_free"])
    if opts["state"] == "free" or (opts["state"] == "auto" and gain > 0.5):
        # on the whole window: one period holds too little of a slow dashpot's creep
        last = stages[-1]
        stages.append(fit_surface(model, last["theta"], bounds, fit_hamaker=fit_hamaker, scan=False, s0=last["s0"],
                                  xd0=last["xd0"], xtol=1e-8, max_nfev=FREE_NFEV))  # fmt: skip
    return model, stages, gain


def _fit_info(model, stages, cov, unc_periodic, opts) -> dict:
    """What the fit did, for ``info['fit']``."""
    fit = stages[-1]
    names, res = fit["names"], fit["residual"]
    s0_sigma = math.sqrt(cov[names.index("s0"), names.index("s0")]) * OFFSET_UNIT if "s0" in names else None
    return {
        "parameters": names,
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
        "state": "free" if "xd0" in names else "periodic",
        "surface_height_from_z1_m": float(fit["s0_z1"]),
        "surface_height_source": "fit (approach tap + steady window)" if model.fit_offset else "Z1",
        "xd0_m": fit["xd0"],
        "xd0_sigma_m": finite_or_none(math.sqrt(cov[-1, -1]) * OFFSET_UNIT),
        "periodic_residual_m": fit["periodic_residual"],
        "model_passes": int(model.passes),
        "stages": len(stages),
    }


@register
class FullFit(ExtractionMethod):
    """Whole-cycle inversion (issue 6): the SLS surface driven by the measured tip
    trajectory, fitted to every sample of the record (:mod:`vetica_cli.extraction.fullfit`)."""

    key = "full"
    description = "whole-cycle SLS model inversion: the surface driven by the measured tip, fitted to every sample"
    title = "whole-cycle fit"
    surface_models = ("sls",)
    options_default: ClassVar[dict[str, Any]] = {"kg_points": 10, "start": None, "fit_hamaker": False, "near_stride": 4, "far_stride": 256,
                       "scan": True, "fit_offset": True, "state": "auto", "substeps": None}  # fmt: skip
    needs_approach = True
    uniform_sampling = True
    # both force sources, 10 periods at PS 0.125 ns, cd = 1e-3 kg/s at 16:1: 1.2 s (true) + 1.8 s
    # (reconstructed), measured while the other core was busy
    seconds_per_point = 3.0

    def options(self, given: dict) -> dict:
        opts = super().options(given)
        if opts["state"] not in STATES:
            raise InputError(f"state {opts['state']!r} not allowed; choose one of: {', '.join(STATES)}")
        return opts

    def run(self, record: Record, options: dict) -> ExtractionResult:
        """Fit ``k_inf, k0, cd`` (optionally ``H``) to the record (module docstring)."""
        opts = options
        t, z, f, surface = record.t, record.z, record.f, record.model
        h = (t[-1] - t[0]) / (len(t) - 1)
        a0, hr6, radius, vdw = _surface_constants(record)
        substeps = opts["substeps"]
        if substeps is None:  # the simulator's surface step: dt of the metadata, else one update per sample
            dt_sim = (record.params.get("numerics") or {}).get("dt")
            substeps = max(1, round(h / dt_sim)) if dt_sim else 1
        info, warnings = dict(record.info), []
        if record.approach is None:
            warnings.append("no approach record: the dashpot is assumed undeformed at the first contact (Xd1 = 0)")
        taps = find_taps(f)
        if len(taps.contact) < 1:
            raise InputError("too few taps: no complete tap in the record")
        start, source = starting_point(t, z, f, record.z1, taps, opts["kg_points"], opts["start"])
        t_start_done = time.perf_counter()

        def make(n):
            return SurfaceFit(z[:n], f[:n], h, record.z1, record.approach, a0, radius, vdw,
                              fit_offset=opts["fit_offset"], near_stride=opts["near_stride"],
                              far_stride=opts["far_stride"], substeps=substeps)  # fmt: skip

        bounds = {**surface.fit_bounds, "hamaker": HAMAKER_BOUNDS}
        theta0 = [start["k_inf"], start["k0"], start["cd"], hr6]
        model, stages, info["free_state_gain"] = _stages(make, len(z), taps, theta0, opts, bounds)
        t_fit = time.perf_counter()
        info["start"] = {"source": source, **start}
        result = self._result(record, model, stages, taps, h, radius, opts, info, warnings)
        result.timing_s = {"reconstruction": record.reconstruction_s, "start": t_start_done - record.t_force,
                           "fit": t_fit - t_start_done, "total": time.perf_counter() - record.t_start}  # fmt: skip
        return result

    def _result(self, record, model, stages, taps, h, radius, opts, info, warnings) -> ExtractionResult:
        """Values, uncertainties, identifiability and diagnostics of the final stage."""
        surface, fit = record.model, stages[-1]
        names, res = fit["names"], fit["residual"]
        # covariance with the window's start state as an unknown too (conservative: does not lean
        # on the periodic state, which a record taken before the surface settled does not have)
        cov, cov_model = covariance(res, fit["jac_free"]), covariance(res, fit["jac"])
        rel = np.sqrt(np.diag(cov))[: len(names)]
        at_bound = (fit["x"] - fit["lo"] < 1e-6) | (fit["hi"] - fit["x"] < 1e-6)
        params = dict(zip(surface.parameter_keys, (float(v) for v in fit["theta"][:3])))
        values = surface.theory(params)
        grads = surface.log_gradients(params)
        sigma, sigma_model = propagate(cov, grads), propagate(cov_model, grads)
        units = {k: q.unit for k, q in self.quantities(surface).items()}
        truth = dict(record.truth) if record.truth else None
        if opts["fit_hamaker"]:
            units["hamaker"] = "J"
            values["hamaker"] = 6.0 * float(fit["theta"][3]) / radius
            sigma["hamaker"], sigma_model["hamaker"] = float(rel[3]), float(math.sqrt(cov_model[3, 3]))
            if record.surface.get("hamaker") is not None:
                truth = {**(truth or {}), "hamaker": record.surface["hamaker"]}
        est = estimates(values, units, truth, sigmas=sigma)
        fitted = tuple(n for n in names if n in (*surface.parameter_keys, "hamaker"))  # not s0, xd0: nuisance
        contact_s = float(np.median(taps.separation - taps.contact)) * h
        ident = identifiability(fitted, rel, at_bound, params, values, contact_s, float(taps.spacing) * h - contact_s,
                                h, sigma["k_g"], math.sqrt(float(np.mean(res**2))))  # fmt: skip
        unconverged = gn_gain(res, fit["jac"]) if fit["status"] == 0 else 0.0
        if unconverged > 0.5:  # stopped by the evaluation budget far from the optimum
            why = (f"the fit stopped before converging (one more Gauss-Newton step would remove "
                   f"{100 * unconverged:.0f} % of the residual)")  # fmt: skip
            ident = {k: (False, why + ("; " + v[1] if not v[0] else "")) for k, v in ident.items()}
        for k, (ok, reason) in ident.items():
            est[k] = replace(est[k], identifiable=bool(ok), reason=reason)
        info["fit"] = _fit_info(model, stages, cov, sigma_model, opts)
        rms_pct = info["fit"]["residual_rms_pct"]
        if rms_pct > 1.0:
            warnings.append(
                f"the SLS model does not reproduce the measured force (RMS residual {rms_pct:.2g} % of the peak): "
                "a record taken before the surface settled, chatter, noise, or a surface that is not a Zener SLS"
            )
        if fit["status"] <= 0:
            warnings.append(f"least squares did not converge: {fit['message']}")
        return ExtractionResult(method=self.key, force=record.force, taps=len(taps.contact), estimates=est,
                                model=surface.key, fitted=tuple(ident), info=info,
                                warnings=warnings + record.meta_warnings)  # fmt: skip
