"""A standard error for every method's estimates (:func:`calibrate`, applied to each
result by :func:`vetica_cli.extraction.extract_many` after the method ran).

* ``vetica``, ``vetica-prestress`` -- **spread over taps**.  Each tap (creep interval)
  is one measurement of ``tau_c`` (stage 1a), ``Kg`` (stage 1b) and ``Kr`` (stage 2);
  the method's value is their mean, so its standard error is ``s/sqrt(n)`` (``s`` the
  per-tap standard deviation, ``n`` the taps with a value), scaled by
  ``t(0.975, n-1)/1.96`` so that +-2 sigma is the 95 % interval of a mean of ``n``
  values (1.18 for nine taps).  ``Z1`` enters every creep interval alike, so its
  error does not average out over taps: the method is run twice more with Z1 moved
  by +-2 ``sigma_Z1`` and half the larger change of each quantity is its Z1 term
  (a secant, so non-linear dependences are not linearised away); ``sigma_Z1``
  = the scatter of the steady taps' contact positions (Z1 is one more contact
  position, read the same way, so it scatters as they do: detector noise, the
  force minimum's jitter, the cantilever's thermal drift), for Z1 from the approach
  also the jitter of its gentler first minimum (:func:`approach_jitter`), and, for Z1 from thesis
  eq. 84 (``a0 + Fa/Kg``), the standard errors of the adhesion and of Kg.  Which lift of the
  pulled surface holds (the glassy ``Fa/Kg`` eq. 84 assumes, or up to the rubbery ``Fa/Kr``)
  is a model question no replica of the record shows: a systematic error, which the flags
  judge (:mod:`.sanity`, the lift bracket), not a standard error (it made the error bars of
  stripped records ~50x wider than the replicas' scatter).  The taps'
  scatter of tau_c reaches every quantity the way Z1 does (Z1 acts through tau_c,
  so the same rerun gives ``d q/d tau_c``, Kr's refit included); those of Kg and Kr
  are propagated through :func:`~vetica_cli.extraction.vetica.sls_elements`
  (log-gradients; Kr's dependence on the Kg it was fitted with is not included).
  Stages independent.  A quantity measured on fewer than two taps has an unbounded sigma.
* ``full`` -- the larger of **the fit's Jacobian and residual** (``s^2 (J^T J)^-1``) and
  the **tap-robust sandwich** (delete-one-tap jackknife of the linearised fit, for
  residuals correlated within a tap, e.g. thermal noise; :mod:`.fullfit.uncertainty`),
  kept as the method computes it (with the approach's Z1 reading error); a record's Z1 from
  thesis eq. 84 (no approach segment) only starts the fit's surface height, which is then
  fitted free (the height against eq. 84's lift bracket is a check, :mod:`.sanity`).

Relative sigmas (fractions), as :class:`~vetica_cli.extraction.result.Estimate` holds
them; ``info['uncertainty']`` says which source and the Z1 term.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..signals.taps import find_taps
from .result import ExtractionResult, sls_elements, t_factor  # noqa: F401  (t_factor re-exported)

STAGES = ("tau_c", "k_g", "k_r")  # per-tap measurements the tap methods average




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
        from ..signals.taps import contact_slopes

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


JITTER_WINDOW = 200  # samples each side of the approach's force minimum searched for rivals


def approach_jitter(z, f, i, sf: float | None = None) -> float:
    """1-sigma of the approach's first force minimum's position under force noise [m]:
    the samples near it (``JITTER_WINDOW`` each side) whose force is within 2 noise floors
    of the minimum could equally have been the minimum; their z range as a uniform
    distribution, ``range/sqrt(12)``.  ``sf``: the force noise [N] (default: the white
    noise floor of the samples before the minimum)."""
    from ..signals.slopes import noise_floor

    z, f = np.asarray(z, float), np.asarray(f, float)
    lo, hi = max(0, int(i) - JITTER_WINDOW), min(len(f), int(i) + JITTER_WINDOW + 1)
    if sf is None:
        sf = noise_floor(f[max(0, int(i) - 5 * JITTER_WINDOW) : hi])
    rivals = z[lo:hi][f[lo:hi] <= f[int(i)] + 2.0 * sf]
    return float(np.ptp(rivals)) / math.sqrt(12.0) if len(rivals) > 1 else 0.0


def sampling_term(record, taps) -> float:
    """Relative 1-sigma of stage 1a's tau_c from locating the contact and separation minima on
    the sample grid (:func:`tap_sigmas`): the median over creep intervals of ``|d ln tau_c / d Z|``
    at ``Z'i`` and ``Z(i+1)`` (thesis eq. 73: ``tau_c = -dt / ln r``, ``r = (Z(i+1) - Z1)/(Z'i -
    Z1)``) times ``|dz/dt| h / sqrt(12)`` there, in quadrature.  0 without Z1."""
    if record.z1 is None or len(taps.contact) < 2:
        return 0.0
    z, z1 = record.z, record.z1
    h = (record.t[-1] - record.t[0]) / (len(record.t) - 1)
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


def with_z1_moved(record, method, options, h: float) -> list[dict]:
    """The method's estimates with the record's Z1 moved by ``+h`` and ``-h`` (in that order);
    a side the method refuses gives ``{}`` (no term from it)."""
    moved = []
    for sign in (1.0, -1.0):
        try:
            moved.append(method.run(dataclasses.replace(record, z1=record.z1 + sign * h), options).estimates)
        except Exception:  # noqa: BLE001 - a moved Z1 the method refuses: that side gives no term
            moved.append({})
    return moved


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
    # the method twice more with stage 1b's slopes scaled by 1 +- 2 sigma_Kg: how every quantity follows Kg,
    # stage 2's refit of Kr at the moved Kg included (sls_elements alone holds Kr fixed)
    grad_kg = {}
    if "kg_scale" in options and math.isfinite(rel["k_g"]) and rel["k_g"] > 0:
        hk = min(2.0 * rel["k_g"], 0.4)
        moved = []
        for sign in (1.0, -1.0):
            try:
                moved.append(method.run(record, {**options, "kg_scale": 1.0 + sign * hk}).estimates)
            except Exception:  # noqa: BLE001 - a moved Kg the method refuses: that side gives no term
                moved.append({})
        for q, e in est.items():
            changes = [m[q].value - e.value for m in moved if q in m and m[q].value and e.value]
            if changes:
                grad_kg[q] = max(changes, key=abs) / (hk * abs(e.value))  # d ln q / d ln Kg
    g_tau = grad_z1.get("tau_c")
    sls = log_gradients(values)
    sig = {}
    for q, e in est.items():
        if e.value is None or q not in sls:
            continue
        gz = grad_z1.get(q)
        if gz is not None and g_tau:
            via_tau = gz / g_tau * rel["tau_c"]  # the taps' tau_c scatter reaches q as Z1 does
        else:
            via_tau = sls[q][0] * rel["tau_c"]
        via_kg = (grad_kg[q] if q in grad_kg else sls[q][1]) * rel["k_g"]
        terms = [via_tau, via_kg, sls[q][2] * rel["k_r"], (gz or 0.0) * s_z1]
        terms = [x for x in terms if x]
        sig[q] = math.sqrt(sum(x * x for x in terms)) if all(math.isfinite(x) for x in terms) else math.inf
        if not math.isfinite(s_z1):
            sig[q] = math.inf
    info = {"source": "spread over taps (standard error of the tap means, t-scaled), Z1 term by reruns with Z1 "
                      "moved by +-2 sigma", "z1_sigma_m": s_z1}  # fmt: skip
    return sig, info


BAND_STEPS = (math.sqrt(2.0), 2.0)  # the band term re-reads the record low-passed once more at fc / each


def band_record(record, step: float):
    """The record with its force low-passed once more, at ``fc / step`` (and its approach,
    and Z1 when it came from the approach, re-read on the approach's force low-passed the same
    way); None when the force is not band-limited (no declared low-pass below the Nyquist
    frequency) or the narrower band loses the approach's first contact."""
    from ..signals import noise as nz
    from ..signals.taps import first_contact_minimum

    d = nz.declared(record.f)
    fc = record.info.get("cutoff_hz")
    if d is None or d[2] <= 1.5 or not fc:
        return None
    fc2 = fc / step
    h = (record.t[-1] - record.t[0]) / (len(record.t) - 1)

    def lowpass(x):
        spec = np.fft.rfft(x)
        spec[np.fft.rfftfreq(len(x), h) > fc2] = 0.0
        return np.fft.irfft(spec, len(x))

    f2 = lowpass(record.f)
    drive = (record.info.get("noise") or {}).get("drive_hz")
    choice = nz.measure(f2, h, drive, cutoff_hz=fc2) if drive else None
    if choice is not None:
        nz.declare(f2, choice.noise_rms, choice.white_equivalent, choice.spectrum.nyquist / fc2)
    changes = {"f": f2, "taps": None, "info": {**record.info, "cutoff_hz": fc2}}
    if record.approach is not None and str(record.info.get("z1_source", "")).startswith("approach"):
        za, fa, _ = record.approach
        fa2 = lowpass(fa)
        try:
            i1 = first_contact_minimum(fa2, choice.noise_rms if choice is not None else 0.0)
        except Exception:  # noqa: BLE001 - the narrower band loses the first contact: no band term
            return None
        changes.update(approach=(za, fa2, i1), z1=float(za[i1]))
    return dataclasses.replace(record, **changes)


def band_term(res: ExtractionResult, record, method, options) -> dict:
    """``{quantity: relative bias}``: the **band term** of a force low-passed below the Nyquist
    frequency (the cut-off chosen from a noisy record's noise, :mod:`vetica_cli.signals.noise`).
    A low-pass smears the contact's kinks over ~1/(2 fc): the force minima that mark contact,
    separation and Z1 move (into the contact, where the force is less steep), and the initial
    slope is read later; these biases do not average over taps and are not in the answer at
    the whole band.  Their size is measured on the record itself by Richardson's extrapolation:
    the method re-run on its own force low-passed once more at ``fc/sqrt(2)`` and ``fc/2`` (no
    more noise), the changes ``D1``, ``D2`` fitted by a bias growing as ``fc^-p`` (``D2/D1 =
    2^(p/2) + 1``, ``p`` clamped to 1..4), and the bias at ``fc`` is ``D1/(2^(p/2) - 1)``
    (measured on the worked example's 16:1 surface with the pull off, noise-free, low-passed:
    tau_c -1.8 % at 30 MHz, -8.5 % at 15 MHz).  A systematic error of the band: added to sigma in
    quadrature (an error bar of the record's answer against the noise-free one at the whole band),
    and compared with the tolerance by the flags (:mod:`.sanity`)."""
    alts = []
    for step in BAND_STEPS:
        rec2 = band_record(record, step)
        if rec2 is None:
            break
        try:
            alts.append(method.run(rec2, options).estimates)
        except Exception:  # noqa: BLE001 - the narrower band is refused: the steps before it stand
            break
    if not alts:
        return {}
    out = {}
    for q, e in res.estimates.items():
        d = []
        for a in alts:
            v = a.get(q)
            d.append((v.value - e.value) / abs(e.value) if e.value and v is not None and v.value is not None else math.nan)
        if not math.isfinite(d[0]):
            continue
        if len(d) < 2 or not math.isfinite(d[1]):  # one step: the bias growing as 1/fc^2 (the minima's shift)
            out[q] = abs(d[0])
        elif d[0] * d[1] > 0 and abs(d[1]) > abs(d[0]):  # monotonic: extrapolate with the fitted order
            r = min(max(d[1] / d[0] - 1.0, math.sqrt(2.0)), 4.0)  # 2^(p/2), p in 1..4
            out[q] = abs(d[0]) / (r - 1.0)
        else:  # not monotonic in the band: the larger change, as for p = 1
            out[q] = max(abs(d[0]), abs(d[1])) / (math.sqrt(2.0) - 1.0)
    return out


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


def calibrate(res: ExtractionResult, record, method=None, options=None) -> ExtractionResult:
    """Give every estimate of ``res`` its standard error (module docstring): the method's own
    ``sigmas`` hook (:meth:`~vetica_cli.extraction.base.ExtractionMethod.sigmas`), then the band
    term of a low-passed force; in place."""
    info = {}
    if method is not None:
        sig, info = method.sigmas(res, record, options or {})
        res.estimates = {k: dataclasses.replace(e, sigma=sig[k]) if k in sig and e.value is not None else e
                         for k, e in res.estimates.items()}  # fmt: skip
    if method is not None:  # a band-limited force: the bias of its low-pass, in quadrature (and judged by the flags)
        band = band_term(res, record, method, options or {})
        if band:
            info["band"] = {"cutoff_hz": record.info.get("cutoff_hz"), "bias": band}
            res.estimates = {k: dataclasses.replace(e, sigma=math.hypot(e.sigma, band[k]))
                             if k in band and e.value is not None and e.sigma is not None else e
                             for k, e in res.estimates.items()}  # fmt: skip
    res.info = {**res.info, "uncertainty": info}
    return res
