"""A standard error for every method's estimates (:func:`calibrate`, applied to each
result by :func:`vetica_cli.extraction.extract_many` after the method ran).

* the tap methods (VETICA and VETICA with the pre-stress; their hook in
  :mod:`vetica_cli.extraction.methods.tapsigmas`) -- **spread over taps**.  Each tap (creep interval)
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
* the whole-cycle fit -- the larger of **the fit's Jacobian and residual** (``s^2 (J^T J)^-1``) and
  the **tap-robust sandwich** (delete-one-tap jackknife of the linearised fit, for
  residuals correlated within a tap, e.g. thermal noise; :mod:`.fullfit.uncertainty`),
  kept as the method computes it (with the approach's Z1 reading error); a record's Z1 from
  thesis eq. 84 (no approach segment) only starts the fit's surface height, which is then
  fitted free (the height against eq. 84's lift bracket is a check, :mod:`.sanity`).

* every other method -- the base's default hook: the standard error of its per-tap (or
  per-period) values (:meth:`~vetica_cli.extraction.base.ExtractionMethod.sigmas`).

Each is the method's :meth:`~vetica_cli.extraction.base.ExtractionMethod.sigmas` hook; this
module adds the band term of a low-passed force to all of them.  Relative sigmas (fractions), as :class:`~vetica_cli.extraction.result.Estimate` holds
them; ``info['uncertainty']`` says which source and the Z1 term.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .result import ExtractionResult, t_factor  # noqa: F401  (t_factor re-exported)





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
        from ..signals.spectral import irfft, rfft  # numpy's, or scipy's for an awkward length

        spec = rfft(x)
        spec[np.fft.rfftfreq(len(x), h) > fc2] = 0.0
        return irfft(spec, len(x))

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
