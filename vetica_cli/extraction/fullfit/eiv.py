"""The whole-cycle fit's correction for white noise on the measured tip position (errors in variables).

The fit drives its surface with the record's ``z_tip`` as if it were exact.  A detector's white
noise on ``z_tip`` (``sigma_z`` a sample) reaches the model's force through the surface's
instantaneous stiffness, but not the measured force: the least squares then pays
``sigma_z^2 sum_i (dF_i/dz_i)^2`` more for a stiffer model and settles on a softer one (the
attenuation bias of a regression on a noisy regressor), large on stiff surfaces whose taps
are shallow.  Measured on stripped records (1 pm of white noise on z_tip, 0.1 nN on f_ts; a 63:1
surface, k0 474 N/m, cd 1.1e-5 kg/s): k0 -6.7 and tau_r +6.5 of the fit's own sigmas off the
noise-free answer, on average over 8 replicas; without the z_tip noise -0.3 and +0.2.

**The correction** (simulation-extrapolation, SIMEX, with antithetic draws): the bias is, to first
order, proportional to ``sigma_z^2``; the record is fitted again twice with ``+n`` and ``-n`` added
to ``z_tip`` (``n`` white, of the RMS measured on the record: its fourth-difference floor,
:func:`~vetica_cli.signals.slopes.white_noise_floor` with ``order=4``), which doubles the noise's variance; the
mean of the two refits less the fit is the bias at ``sigma_z^2``, and is taken off each of the
surface's parameters (and ``H R``) the fit determines, every other quantity computed from them (a
parameter it reports unidentified is left as it is: the refits wander along its flat direction;
one the correction would move by more than :data:`SHIFT_MAX` is left as it is and flagged).
The antithetic pair cancels the refits' part linear in ``n`` (their random scatter), so the
correction carries little noise of its own.  The refits start from the fit's answer with the fit's
arms (no cd scan).  Only where the z_tip noise is a sizeable part of the model force's noise
(``k_top sigma_z >= GATE sigma_f``, ``k_top`` the instantaneous stiffness, ``sigma_f`` the force's
noise floor): a simulator's record without detector noise has a floor of rounding (``sigma_z``
~1e-15 m), an instrument's record at 300 K a force noise far above ``k_top sigma_z``, and the
correction costs two fits; nor where ``k_top sigma_z`` is below :data:`NEGLIGIBLE` of the peak
force (a noise-free record, whose force's floor is rounding too).  Not for the sphere's fit
(``fit_model: hertz``).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ...signals.slopes import noise_floor, white_noise_floor
from ..result import error_pct, finite_or_none

GATE = 0.5  # the z_tip noise through the instantaneous stiffness, against the force noise, from which it is corrected
NEGLIGIBLE = 1e-4  # nor where it is below this fraction of the peak force (a noise-free record's rounding)
SHIFT_MAX = 0.1  # a correction larger than this (relative) is beyond first order in sigma_z^2: not made, flagged
SEED = 0x7A1E  # the refits' noise: drawn from the record's length and this, the same record gives the same answer


def instantaneous_stiffness(res) -> float | None:
    """The surface's stiffness to a sudden push [N/m]: the largest stiffness among the values."""
    ks = [e.value for e in res.estimates.values() if e.unit == "N/m" and e.value is not None and math.isfinite(e.value)]
    return max(ks) if ks else None


def correct_z_noise(method, record, opts: dict, consts: dict, res, surface) -> None:
    """Take the z_tip noise's bias off ``res``'s values where it matters (module docstring);
    what was measured and done goes to ``res.info['fit']['z_noise']``.  ``surface``: the surface
    model fitted (:func:`.method.fit_model`), whose parameters are corrected."""
    fit = res.info.get("fit") or {}
    sigma_z, k_top = white_noise_floor(record.z, order=4), instantaneous_stiffness(res)
    sigma_f = noise_floor(record.f)
    ratio = k_top * sigma_z / sigma_f if k_top and sigma_f > 0 else 0.0
    info = {"sigma_z_m": finite_or_none(sigma_z), "sigma_f_N": finite_or_none(sigma_f), "k_top_N_m": k_top,
            "ratio": finite_or_none(ratio), "gate": GATE, "applied": False}  # fmt: skip
    fit["z_noise"] = info
    peak = float(np.max(np.abs(record.f))) if len(record.f) else 0.0
    info["relative_to_peak"] = finite_or_none(k_top * sigma_z / peak) if k_top and peak > 0 else None
    if not (ratio >= GATE and (info["relative_to_peak"] or 0.0) >= NEGLIGIBLE):
        return
    rng = np.random.default_rng([len(record.z), SEED])
    noise = rng.normal(0.0, sigma_z, len(record.z))
    noise_a = rng.normal(0.0, sigma_z, len(record.approach[0])) if record.approach is not None else None
    opts_probe = {**opts, "arms": fit.get("arms") or opts.get("arms"), **method.continuation(res)}
    vdw = bool(fit.get("vdw_on_surface", True))
    probes = []
    for sign in (1.0, -1.0):
        approach = record.approach
        if approach is not None:
            approach = (np.asarray(approach[0], float) + sign * noise_a, *approach[1:])
        rec = replace(record, z=record.z + sign * noise, approach=approach, memo={})
        try:
            out = method._run_one(rec, opts_probe, consts, vdw)
        except Exception as exc:  # noqa: BLE001 - a refit that fails leaves the fit as it was, and says so
            info["reason"] = f"a refit with the noise doubled failed: {str(exc).splitlines()[0][:120]}"
            return
        out.__dict__.pop("forward", None)
        probes.append(out.estimates)
    # the surface's parameters (and H R) corrected, every other quantity computed from them: a quantity keeps its
    # parameters' flags (k_r is k_inf, the times scale with cd), as the fit's own values do
    est = res.estimates
    if any(k not in est or est[k].value is None for k in surface.parameter_keys):
        info["reason"] = "the fit reports no value for one of the surface's parameters: not corrected"
        return
    params = {k: est[k].value for k in surface.parameter_keys}
    shifts, kept = {}, []
    for q in (*surface.parameter_keys, "hamaker_radius"):
        e = est.get(q)
        vals = [p.get(q).value if p.get(q) is not None else None for p in probes]
        if e is None or e.value is None or e.identifiable is False or any(v is None or not math.isfinite(v) for v in vals):
            continue  # a direction the record does not determine: the refits wander along it, not the bias
        shift = 0.5 * (vals[0] + vals[1]) - e.value
        shifts[q] = shift / abs(e.value) if e.value else None
        if abs(shift) > SHIFT_MAX * abs(e.value):  # beyond first order: the value kept, and flagged
            kept.append(q)
        elif q in params:
            params[q] = e.value - shift
        else:
            hr = e.value - shift
            ratio_h = hr / e.value
            for name in ("hamaker_radius", "hamaker"):  # H itself scales with H R (a known tip radius)
                if name in est and est[name].value is not None:
                    v = est[name].value * ratio_h
                    est[name] = replace(est[name], value=v, error_pct=error_pct(v, est[name].theory))
    keys = surface.parameter_keys  # k_inf, then (k_i, cd_i) per arm: the fit's own order (method._result)
    n_arms = (len(keys) - 1) // 2
    arms = surface.from_arms(params[keys[0]], [params[keys[1 + 2 * i]] for i in range(n_arms)],
                             [params[keys[2 + 2 * i]] for i in range(n_arms)])  # fmt: skip
    for q, v in surface.theory(arms).items():
        if q in est and est[q].value is not None:
            est[q] = replace(est[q], value=v, error_pct=error_pct(v, est[q].theory))
    info["applied"] = True
    info["shift"] = {q: finite_or_none(v) for q, v in shifts.items()}
    if kept:
        from ..sanity import flag

        info["not_corrected"] = kept
        flag(res, kept, f"z_tip's noise ({sigma_z * 1e12:.2g} pm) would move it by more than {SHIFT_MAX:.0%}, beyond "
                        "the first-order correction: not corrected")  # fmt: skip
