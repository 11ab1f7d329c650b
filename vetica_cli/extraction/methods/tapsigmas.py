"""The tap methods' error bars (VETICA, VETICA with the pre-stress): their
:meth:`~vetica_cli.extraction.base.ExtractionMethod.sigmas` hook, :func:`tap_method_sigmas`.
What each term is, and why, is in :mod:`vetica_cli.extraction.uncertainty`'s docstring:
the spread over taps (standard error of the tap means, t-scaled), the Z1 term by reruns with
Z1 moved by +-2 sigma (:func:`z1_sigma`), the Kg term by reruns with stage 1b's slopes scaled,
and the stages propagated through :func:`~vetica_cli.extraction.result.sls_elements`
(:func:`log_gradients`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...signals.taps import find_taps
from ..result import ExtractionResult, sls_elements, t_factor
from ..uncertainty import approach_jitter

STAGES = ("tau_c", "k_g", "k_r")  # per-tap measurements the tap methods average
KG_STEP_MAX = 0.2  # the Kg term's re-runs move stage 1b's slopes by their relative 1-sigma, at most this


def z1_sigma(record, taps, kr: float | None = None) -> float:
    """1-sigma of Z1 [m] (module docstring); 0 for a Z1 the user gave.  For eq. 84 with
    the pull, the lift's model uncertainty too: the surface meets the tip between its
    glassy lift ``Fa/Kg`` and its rubbery lift ``Fa/Kr`` (``kr``: stage 2's Kr), so half
    that bracket is added in quadrature (unbounded without a Kr)."""
    source = str(record.info.get("z1_source", ""))
    if source == "given" or record.z1 is None:
        return 0.0
    zc = record.z[taps.contact]
    scatter = float(np.std(zc, ddof=1)) if len(zc) > 1 else math.inf
    if source.startswith("thesis eq. 84") and "Fa(a0)/Kg" in source:
        fc = record.f[taps.contact]
        fa = -float(np.median(fc))
        kg = (record.z1 - record.a0) and fa / (record.z1 - record.a0)
        s_fa = float(np.std(fc, ddof=1)) / math.sqrt(len(fc)) if len(fc) > 1 else math.inf
        from ...signals.taps import contact_slopes

        kgi = contact_slopes(record.z, record.f, taps, 10)
        kgi = kgi[np.isfinite(kgi)]
        s_kg = float(np.std(kgi, ddof=1)) / math.sqrt(len(kgi)) if len(kgi) > 1 else math.inf
        if not kg > 0:
            return math.inf
        # the noise of eq. 84's inputs only: which lift holds (glassy Fa/Kg or rubbery Fa/Kr) is a model
        # question the replicas of a record cannot show, judged by the flags (sanity: the lift bracket)
        return math.sqrt(scatter**2 + (s_fa / kg) ** 2 + (fa * s_kg / kg**2) ** 2)
    if record.approach is not None and source.startswith("approach"):
        scatter = math.hypot(scatter, approach_jitter(*record.approach))
    return scatter


def log_gradients(values: dict, rel: float = 1e-6) -> dict:
    """``d ln q / d ln s`` of every quantity ``q`` of ``sls_elements`` against each stage
    ``s`` of :data:`STAGES` (central differences)."""

    base = [values[s] for s in STAGES]
    out = {}
    for j, _ in enumerate(STAGES):
        up, dn = list(base), list(base)
        up[j] *= 1 + rel
        dn[j] *= 1 - rel
        qu, qd = sls_elements(*up), sls_elements(*dn)
        for q in qu:
            g = (math.log(abs(qu[q])) - math.log(abs(qd[q]))) / (2 * rel) if qu[q] and qd[q] else math.nan
            out.setdefault(q, [0.0] * len(STAGES))[j] = g
    return out


def rerun(record, method, options, z1: float | None = None, kg_scale: float | None = None) -> dict:
    """The method's estimates with the record's Z1 at ``z1`` and/or the option ``kg_scale`` at
    ``kg_scale``: by the method's :meth:`moved` (the tap methods re-run only the stages that move,
    from the record's taps measured once) when it has one, else by a whole run; ``{}`` when the
    method refuses them."""
    try:
        if hasattr(method, "moved"):
            return method.moved(record, options, z1=z1, kg_scale=kg_scale)
        rec = record if z1 is None else dataclasses.replace(record, z1=z1)
        return method.run(rec, options if kg_scale is None else {**options, "kg_scale": kg_scale}).estimates
    except Exception:  # noqa: BLE001 - moved inputs the method refuses: no term from that side
        return {}


def with_z1_moved(record, method, options, h: float) -> list[dict]:
    """The method's estimates with the record's Z1 moved by ``+h`` and ``-h`` (in that order);
    a side the method refuses gives ``{}`` (no term from it)."""
    return [rerun(record, method, options, z1=record.z1 + sign * h) for sign in (1.0, -1.0)]


def sampling_term(record, taps) -> float:
    """Relative 1-sigma of stage 1a's tau_c from locating the contact and separation minima on
    the sample grid (:func:`tap_sigmas`): the median over creep intervals of ``|d ln tau_c / d Z|``
    at ``Z'i`` and ``Z(i+1)`` (thesis eq. 73: ``tau_c = -dt / ln r``, ``r = (Z(i+1) - Z1)/(Z'i -
    Z1)``) times ``|dz/dt| h / sqrt(12)`` there, in quadrature.  0 without Z1."""
    if record.z1 is None or len(taps.contact) < 2:
        return 0.0
    z, z1 = record.z, record.z1
    out = []
    for i in range(len(taps.contact) - 1):
        js, jc = int(taps.separation[i]), int(taps.contact[i + 1])
        zs, zc = z[js] - z1, z[jc] - z1
        if not (zs != 0 and 0.0 < zc / zs < 1.0) or not (0 < js < len(z) - 1 and 0 < jc < len(z) - 1):
            continue
        lr = math.log(zc / zs)
        vs, vc = abs(z[js + 1] - z[js - 1]) / 2.0, abs(z[jc + 1] - z[jc - 1]) / 2.0  # [m per sample]
        # d ln tau_c = -d ln(-ln r) = -(d ln r)/ln r,  d ln r = dZc/zc - dZs/zs
        out.append(math.hypot(vc / zc, vs / zs) / math.sqrt(12.0) / abs(lr))
    return float(np.median(out)) if out else 0.0


def contact_location_term(record, method, options, kg: float) -> float:
    """Relative 1-sigma of Kg from where stage 1b's grown window reads the slope: the larger of the
    slope's difference between the thesis's reading point (5.5 samples after each tap's force
    minimum) and the window's, read by the same fits (the mean over taps), and its change per
    sample the window moves (:func:`vetica_cli.signals.slopes._per_sample`) times
    :data:`~vetica_cli.signals.slopes.LOCATION_SAMPLES`.  The thesis's reading on the noise-free
    record is what the noisy record's Kg is compared with, and the two readings of the contact
    differ alike in every tap, so the term does not average over taps and is not in their spread
    (a 10:1 surface that snaps to the tip, stripped at 0.5 ns with 1 pm and 0.1 nN of noise: the
    break 7-8 samples after the minimum, Kg 1.1 % low at a 0.6 % sigma).  0 where the thesis's
    window was kept (noise-free records) or the method keeps no stage-1b windows
    (``method.kg_windows``)."""
    from ...signals.slopes import LOCATION_SAMPLES

    if not hasattr(method, "kg_windows") or "kg_points" not in options or "kg_window" not in options or not kg:
        return 0.0
    try:
        windows = method.kg_windows(record, options)
    except Exception:  # noqa: BLE001 - the record's taps refused: the method has said so
        return 0.0
    per = [x for x in windows.get("per_sample_of_contact") or () if math.isfinite(x)]
    at_thesis = [x for x in windows.get("at_thesis_reading") or () if math.isfinite(x)]
    step = LOCATION_SAMPLES * abs(float(np.mean(per))) if per else 0.0
    return max(step, abs(float(np.mean(at_thesis))) if at_thesis else 0.0) / abs(kg)


def tap_sigmas(res: ExtractionResult, record, method, options) -> tuple[dict, dict]:
    """Relative sigmas of a tap method's quantities and the bookkeeping (module docstring)."""
    est = res.estimates
    values = {s: est[s].value for s in STAGES if s in est}
    if len(values) < len(STAGES) or any(v is None or v == 0 for v in values.values()):
        return {}, {"source": "spread over taps", "note": "a stage gave no value"}
    rel = {}
    for s in STAGES:
        sp = est[s].spread
        n = sp.n if sp else 0
        rel[s] = (sp.std / math.sqrt(n) * t_factor(n) / abs(values[s])) if n >= 2 and sp.std is not None else math.inf
    loc = contact_location_term(record, method, options, values["k_g"])
    if loc:
        rel["k_g"] = math.hypot(rel["k_g"], loc)
    taps = find_taps(record.f)
    s_z1 = z1_sigma(record, taps, values["k_r"]) if record.z1 is not None else 0.0
    # the print step: every force minimum is located on the sample grid, to within half a step in
    # time, so each position of stage 1a (Z'i, Z(i+1), and Z1 when read on the approach) is off by
    # up to half the tip's travel in a step -- the same for every tap when the period is a whole
    # number of samples, so it does not average over taps: uniform, v h / sqrt(12), through eq. 73
    rel["tau_c"] = math.hypot(rel["tau_c"], sampling_term(record, taps))
    # the method twice more with Z1 moved by +-2 sigma: how every quantity follows Z1 (a secant
    # over the 95 % range, so a quantity that depends on Z1 non-linearly, e.g. cd when tau_c and
    # Kr move in opposite directions, gets the larger of the two changes), and through it tau_c
    grad_z1 = {}
    if record.z1 is not None and math.isfinite(s_z1):
        h = 2.0 * s_z1 if s_z1 > 0 else 1e-13
        kr = est["k_r"].value if "k_r" in est else None
        warm = {**options, "kr_guess": kr} if "kr_guess" in options and kr and kr > 0 else options  # start at this Kr
        moved = with_z1_moved(record, method, warm, h)
        for q, e in est.items():
            changes = [m[q].value - e.value for m in moved if q in m and m[q].value and e.value]
            if changes:
                grad_z1[q] = max(changes, key=abs) / (h * abs(e.value))  # d ln q / d Z1 [1/m]
    # the method twice more with stage 1b's slopes scaled by 1 +- sigma_Kg: how every quantity follows Kg,
    # stage 2's refit of Kr at the moved Kg included (sls_elements alone holds Kr fixed).  A central difference
    # over the noise's own scale, not the larger secant over +-2 sigma: where k_inf << k0, stage 2's Kr turns
    # steep a few % below Kg (a 32:1 surface at 300 K: Kr 2.5 -> 3.6 -> 23 -> Kg at 0.99, 0.97, 0.89 Kg) and the
    # secant over the collapsed side made k0's sigma 50 % where its replicas scattered 3 % (dev draw 27); a
    # replica whose Kg is that far off collapses and is flagged, the others follow the local slope
    grad_kg = {}
    if "kg_scale" in options and math.isfinite(rel["k_g"]) and rel["k_g"] > 0:
        hk = min(rel["k_g"], KG_STEP_MAX)
        moved = [rerun(record, method, options, kg_scale=1.0 + sign * hk) for sign in (1.0, -1.0)]
        for q, e in est.items():
            if not e.value:
                continue
            up, dn = (m[q].value if q in m and m[q].value else None for m in moved)
            if up is not None and dn is not None:
                grad_kg[q] = (up - dn) / (2.0 * hk * abs(e.value))  # d ln q / d ln Kg
            elif up is not None or dn is not None:  # one side refused: its secant
                side, v = (1.0, up) if up is not None else (-1.0, dn)
                grad_kg[q] = (v - e.value) / (side * hk * abs(e.value))
    g_tau, g_kg = grad_z1.get("tau_c"), grad_kg.get("k_g")
    sls = log_gradients(values)
    sig, parts = {}, {}
    for q, e in est.items():
        if e.value is None or q not in sls:
            continue
        gz = grad_z1.get(q)
        # the taps' tau_c scatter (and its sampling term) reaches q as Z1 does, or through the SLS relations at
        # the stage-2 fit's Kr, whichever is larger: a Z1 shift moves tau_c and stage 2's data together (cd
        # follows at -0.13 of tau_c there), while a minimum misplaced on the sample grid moves tau_c alone
        # (at 100 kHz and 8 ns, tau_c -84 % at a 65 % sigma left cd -83 % at a sigma of 8 %)
        via_tau = abs(sls[q][0] * rel["tau_c"])
        if gz is not None and g_tau:
            via_tau = max(via_tau, abs(gz / g_tau * rel["tau_c"]))
        via_kg = (grad_kg[q] if q in grad_kg else sls[q][1]) * rel["k_g"]
        terms = [via_tau, via_kg, sls[q][2] * rel["k_r"], (gz or 0.0) * s_z1]
        parts[q] = dict(zip(("tau_c", "k_g", "k_r", "z1"), (abs(x) if math.isfinite(x) else None for x in terms)))
        terms = [x for x in terms if x]
        sig[q] = math.sqrt(sum(x * x for x in terms)) if all(math.isfinite(x) for x in terms) else math.inf
        if not math.isfinite(s_z1):
            sig[q] = math.inf
    info = {"source": "spread over taps (standard error of the tap means, t-scaled), Z1 term by reruns with Z1 "
                      "moved by +-2 sigma", "z1_sigma_m": s_z1, "kg_contact_location": loc,
            # d ln q / d ln tau_c (through Z1, Kr's refit included) and d ln q / d ln Kg (through the slopes'
            # scale, per the reported Kg's own change: on a 300 K lab record vetica-prestress's Kg moved by 0.036 of
            # the scale, and k0 = Kg - Kr, +314 % off with Kg flagged +264 %, read a reach of 0.036 x 2.64 < 10 %):
            # how far a stage's error reaches the quantities computed from it (tapchecks.stage_dependents)
            "parts": parts,  # each quantity's relative sigma by where it comes from (the taps' tau_c, Kg, Kr; Z1)
            "gradient": {"tau_c": {q: gz / g_tau for q, gz in grad_z1.items() if g_tau and math.isfinite(gz / g_tau)},
                         "k_g": {q: g / g_kg for q, g in grad_kg.items() if g_kg and math.isfinite(g / g_kg)}}}  # fmt: skip
    return sig, info


def tap_method_sigmas(res: ExtractionResult, record, method, options) -> tuple[dict, dict]:
    """The tap methods' :meth:`~vetica_cli.extraction.base.ExtractionMethod.sigmas` hook:
    :func:`tap_sigmas`, and where a stage failed Kg keeps its taps' standard error and the rest is
    unbounded."""
    sig, info = tap_sigmas(res, record, method, options)
    for k, e in res.estimates.items():
        if e.value is not None and k not in sig:
            sp = e.spread
            ok = k == "k_g" and sp is not None and sp.n >= 2 and sp.std is not None
            sig[k] = sp.std / math.sqrt(sp.n) * t_factor(sp.n) / abs(e.value) if ok else math.inf
    return sig, info


