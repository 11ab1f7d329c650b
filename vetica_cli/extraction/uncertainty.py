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
  by +-2 ``sigma_Z1`` (only the stages that move with Z1, from the record's taps measured once:
  :meth:`~vetica_cli.extraction.methods.vetica.TapMethod.moved`) and half the larger change of
  each quantity is its Z1 term
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
  kept as the method computes it (with the approach's Z1 reading error); on a record whose Z1
  is from thesis eq. 84 (no approach segment) the fit holds the surface height at the undeformed
  surface, eq. 84's premise (:func:`.fullfit.method.premise_height`; freed on request, with the
  height term of :meth:`.fullfit.method.FullFit.sigmas`).

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
from .sanity import BAND_FACTOR_MAX, correctable  # noqa: F401  (re-exported: the band term's limit)





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


# the largest change of ln(quantity) the fit's linearised band term is trusted with (model_band falls back to fitting
# the model's records beyond it); the low-pass's biases of the fit measured 1e-4 .. 5e-3 (worked example, draws 19-20)
LINEAR_BAND_MAX = 0.1
BAND_STEPS = (math.sqrt(2.0), 2.0)  # the band term re-reads the record low-passed once more at fc / each


def lowpass(x, h: float, fc: float, periodic: bool = True, spectrum=None) -> np.ndarray:
    """``x`` (sampled every ``h`` [s]) without its content above ``fc`` [Hz].  ``periodic=False``
    (an approach segment, whose ends differ): filtered with its mirror image appended, so the
    segment's end does not wrap onto its start (it made the start look in contact).
    ``spectrum``: a :class:`Spectrum` of this ``x`` (its transform shared by the low-passes of
    ``x`` at several cut-offs: the same bits as without it)."""
    from ..signals.spectral import irfft

    x = np.asarray(x, float)
    if spectrum is None or spectrum.x is not x or spectrum.periodic != bool(periodic):
        spectrum = Spectrum(x, periodic)
    if periodic:
        spec = spectrum.spec.copy()  # the shared transform stays whole
        spec[np.fft.rfftfreq(len(x), h) > fc] = 0.0
        return irfft(spec, len(x))
    # x and its mirror image, 2n samples: their transform is exp(i pi k/2n) times x's DCT-II, and the
    # low-passed first n samples are the inverse DCT-II of the cut coefficients (half the length)
    import scipy.fft

    coef = spectrum.spec.copy()
    coef[np.fft.rfftfreq(2 * len(x), h)[: len(x)] > fc] = 0.0
    return scipy.fft.idct(coef, 2)


WELL_SMEARS = 10  # the narrower band's first-contact well is looked for within this many smears of the record's


def well_in_band(fa2: np.ndarray, i1: int, h: float, fc: float) -> int:
    """Index of the approach's first-contact well in its force ``fa2`` low-passed at ``fc``: the
    minimum within :data:`WELL_SMEARS` smears (``1/(2 fc)``) of the record's own well ``i1``.  A
    low-pass moves the well by about a smear; looked for afresh over the whole approach, a
    narrower band's noise or its edge put it 127 nm above the surface on a 300 K record (the fit
    on that band then failed, and read as a band bias of 230 %)."""
    half = max(16, int(math.ceil(WELL_SMEARS / (2.0 * fc * h))))
    lo, hi = max(int(i1) - half, 0), min(int(i1) + half + 1, len(fa2))
    return lo + int(np.argmin(fa2[lo:hi]))


class Spectrum:
    """The transform :func:`lowpass` takes of ``x`` (its DCT-II when not ``periodic``, which is
    the transform of ``x`` with its mirror image appended), taken when first asked for and kept for
    the low-passes at other cut-offs."""

    def __init__(self, x, periodic: bool = True):
        self.x, self.periodic, self._spec = np.asarray(x, float), bool(periodic), None

    @property
    def spec(self) -> np.ndarray:
        from ..signals.spectral import rfft  # numpy's, or scipy's for an awkward length

        if self._spec is None:
            if self.periodic:
                self._spec = rfft(self.x)
            else:
                import scipy.fft

                self._spec = scipy.fft.dct(self.x, 2)
        return self._spec


def band_record(record, step: float, spectra: dict | None = None):
    """The record with its force low-passed once more, at ``fc / step`` (and its approach,
    and Z1 when it came from the approach, re-read on the approach's force low-passed the same
    way: its well looked for near the record's, :func:`well_in_band`); None when the force is not
    band-limited (no declared low-pass below the Nyquist frequency).  ``spectra``: the
    transforms of the record's force and approach force (:class:`Spectrum`, by ``"f"`` and
    ``"approach"``), shared by the steps (filled here when empty)."""
    from ..signals import noise as nz

    d = nz.declared(record.f)
    fc = record.info.get("cutoff_hz")
    if d is None or d[2] <= 1.5 or not fc:
        return None
    fc2 = fc / step
    h = (record.t[-1] - record.t[0]) / (len(record.t) - 1)

    spectra = {} if spectra is None else spectra
    f2 = lowpass(record.f, h, fc2, spectrum=spectra.setdefault("f", Spectrum(record.f)))
    # the record's noise through the narrower band (white within the band: its RMS by sqrt(fc2/fc), its white
    # equivalent kept, the smear by step); measured afresh on the low-passed force it read ~1e-25 N (the bands
    # above fc2 are empty and cap the floor), and the narrower band's thresholds took noise for contacts
    nz.declare(f2, d[0] / math.sqrt(step), d[1], d[2] * step)
    changes = {"f": f2, "taps": None, "info": {**record.info, "cutoff_hz": fc2}}
    if record.approach is not None and str(record.info.get("z1_source", "")).startswith("approach"):
        za, fa, i0 = record.approach
        fa2 = lowpass(fa, h, fc2, periodic=False, spectrum=spectra.setdefault("approach", Spectrum(fa, False)))
        i1 = well_in_band(fa2, i0, h, fc2)
        changes.update(approach=(za, fa2, i1), z1=float(za[i1]))
    return dataclasses.replace(record, **changes)


def _relative(a: dict, b: dict) -> dict:
    """``{q: a[q]/b[q] - 1}`` where both have a value."""
    out = {}
    for q, e in b.items():
        v = a.get(q)
        if e.value and v is not None and v.value is not None:
            out[q] = (v.value - e.value) / abs(e.value)
    return out


def _narrower_runs(record, method, options, res=None):
    """``run(step)``: ``(the record low-passed once more at fc/step, the method's estimates on
    it)``, or None when the force is not band-limited or the method refuses that band;
    each step computed once, started from ``res`` where the method has a start
    (:meth:`~vetica_cli.extraction.base.ExtractionMethod.continuation`)."""
    done, spectra = {}, {}
    more = method.continuation(res) if res is not None else {}
    if more:
        options = method.options({**options, **more})

    def run(step):
        if step not in done:
            rec2 = band_record(record, step, spectra)
            try:
                done[step] = None if rec2 is None else (rec2, method.run(rec2, options).estimates)
            except Exception:  # noqa: BLE001 - the narrower band is refused
                done[step] = None
        return done[step]

    return run


def model_band(res: ExtractionResult, record, method, options, narrower=None, linear=True) -> dict | None:
    """The band term read on the referee's fitted surface (:mod:`.referee`): its force through
    the whole band at every sample of the record (and of the approach), and the same low-passed
    as the record's force was (``fc``) and once more (``fc/sqrt(2)``); the method on each.  The
    record's answer is biased by the low-pass as the model's is: ``bias = m(fc)/m(whole) - 1``,
    which the caller divides out.  How well the model's band response is the record's is
    measured on the record: the change of the method's answer from ``fc`` to ``fc/sqrt(2)`` on
    the record against the same change on the model; their difference, extrapolated to the whole
    band as a bias growing as ``1/fc`` would (``/(sqrt(2) - 1)``), is the correction's standard
    error, less the noise the narrower band removes (:func:`step_sigma`; without the record's step,
    the whole bias).  None
    when the method has no referee, the fit kept no forward model, its ``k_g`` is flagged (a
    model that does not reproduce the record predicts nothing), or a band loses the approach's
    first contact.  ``narrower``: :func:`band_term`'s runs of the method on the record low-passed
    once more (each computed once for both terms)."""
    from ..signals import noise as nz
    from ..signals.taps import first_contact_minimum
    from .referee import fit_on, forward_on

    narrower = narrower or _narrower_runs(record, method, options)

    key = method.band_model or method.referee
    own = key == method.key
    if own:  # the fit on its own surface: its answer and forward model, no second fit
        est, fwd = res.estimates, forward_on(record, method.key)
        more = method.continuation(res)  # the model's records fitted from the answer, as the narrower bands are
        if more:
            options = method.options({**options, **more})
    else:
        est, fwd = fit_on(record, key)
    kg = est.get("k_g") if est else None
    if fwd is None or kg is None or kg.identifiable is False:
        return None
    fc = float(record.info["cutoff_hz"])
    h = (record.t[-1] - record.t[0]) / (len(record.t) - 1)
    declared = nz.declared(record.f)
    fs = fwd.steady(record.z)
    from_approach = record.approach is not None and str(record.info.get("z1_source", "")).startswith("approach")
    fa = fwd.approach(record.approach[0]) if from_approach else None
    # each transformed once for the bands fc and fc/sqrt(2) (the fit's forward model keeps its own, which its misfit used)
    spec_s = fwd.steady_spectrum(record.z) if hasattr(fwd, "steady_spectrum") else Spectrum(fs)
    spec_a = Spectrum(fa, False) if from_approach else None
    lin = getattr(fwd, "linear", None) if own and linear else None
    if lin is not None and lin.ok and (not from_approach or lin.approach_rows is not None):
        out = _linear_band(record, lin, fs, fa, spec_s, spec_a, h, fc, res)
        if out is not None:
            return out

    def model_record(cut, noise):  # the whole band without noise (as the answer it is compared with), or a band
        f2 = fs.copy() if cut is None else lowpass(fs, h, cut, spectrum=spec_s)
        if noise is not None:  # the record's noise at that band: the method's thresholds as on the record
            nz.declare(f2, *noise)
        changes = {"f": f2, "taps": None, "memo": {}, "info": {**record.info, "cutoff_hz": cut}}
        if from_approach:
            za, _, i0 = record.approach
            fa2 = fa.copy() if cut is None else lowpass(fa, h, cut, periodic=False, spectrum=spec_a)
            i1 = first_contact_minimum(fa2, z=za) if cut is None else well_in_band(fa2, i0, h, cut)
            changes.update(approach=(za, fa2, i1), z1=float(za[i1]))
        return dataclasses.replace(record, **changes)

    try:
        whole, low = (method.run(model_record(c, n), options).estimates for c, n in ((None, None), (fc, declared)))
    except Exception:  # noqa: BLE001 - the model's records are refused (or lose the first contact): no model term
        return None
    bias, d_model, d_rec = _relative(low, whole), {}, {}
    step = narrower(BAND_STEPS[0])
    if step is not None:
        rec2, alt = step
        try:
            lower = method.run(model_record(rec2.info["cutoff_hz"], nz.declared(rec2.f)), options).estimates
            d_rec, d_model = _relative(alt, res.estimates), _relative(lower, low)
        except Exception:  # noqa: BLE001 - the narrower band is refused: the correction's error unmeasured
            d_rec, d_model = {}, {}
    removed = removed_by_quantity(res, step[1], removed_noise(record, step[0])) if step is not None else 0.0
    sigma = beyond_factor(bias, step_sigma(bias, d_rec, d_model, res, removed))
    return {"source": "model", "bias": bias, "sigma": sigma, "model_step": d_model, "record_step": d_rec}


def beyond_factor(bias: dict, sigma: dict) -> dict:
    """``sigma`` with each quantity whose band correction exceeds :data:`BAND_FACTOR_MAX` either way (or
    whose bias is -100 % or less: nothing of it left in the band) raised to its bias's size; such a
    bias is not divided out (:func:`calibrate`)."""
    out = dict(sigma)
    for q, b in bias.items():
        if q in out and not correctable(b):
            out[q] = max(out[q], abs(b)) if math.isfinite(b) else math.inf
    return out


# where the step's noise is measured on the taps (:func:`removed_by_quantity`), the steps' disagreement counts beyond
# this many times that noise's variance (its 2-sigma level; the 95 % point of a 1-dof chi-square is 3.84)
STEP_TEST = 4.0


def step_sigma(bias: dict, d_rec: dict, d_model: dict, res: ExtractionResult, removed: float | dict = 0.0) -> dict:
    """The band correction's standard error from the step to ``fc/sqrt(2)``: the record's change
    ``d_rec`` against the model's ``d_model``, their difference extrapolated to the whole band as
    Richardson's slowest bias growth (p = 1) would (``/(sqrt(2) - 1)``); without a step, the whole
    bias.  The record's step also holds the noise the narrower band removes, the fraction ``removed``
    of the noise power (:func:`removed_noise`; per quantity, ``{quantity: factor, None: default}``, where
    :func:`removed_by_quantity` measured it) of which the answer's own sigma (``res``, before the
    band term) is the whole: ``removed`` times that sigma squared is taken out of the difference's
    square, so only a disagreement the noise cannot explain is the model's.  Counted in full (and
    extrapolated, x2.4) it made VETICA's k_g sigma twice the replicas' scatter at 300 K (dev draw 21:
    the record's step scattered 0.7-0.95x the answer's sigma over replicas of one material, the
    model's within 0.1-1.6 %); the whole sigma taken out instead left dmt-fit's adhesion short on a
    snapping surface whose band correction missed by 4 % (held-out draw 22, coverage 0.84)."""
    out = {}
    for q, b in bias.items():
        if q not in d_rec or q not in d_model:
            out[q] = abs(b)
            continue
        e = res.estimates.get(q) if res is not None else None
        s = e.sigma if e is not None and e.sigma is not None and math.isfinite(e.sigma) else 0.0
        diff = d_rec[q] - d_model[q]
        r = removed.get(q, removed.get(None, 0.0)) if isinstance(removed, dict) else removed
        out[q] = math.sqrt(max(diff * diff - r * s * s, 0.0)) / (math.sqrt(2.0) - 1.0)
    return out


def removed_by_quantity(res: ExtractionResult, narrower: dict, default: float) -> float | dict:
    """The fraction of each quantity's noise variance (its sigma squared, before the band term) that the
    step to the narrower band removes, measured on the record where the method's sigma is built from
    per-tap stages (``res.info["uncertainty"]["parts"]``, :mod:`.methods.tapsigmas`): for a stage
    averaged over taps, ``1 - (se_narrow / se)^2`` of the standard errors of its tap means on the two
    bands (a linear reading of a brick-wall-filtered record splits its noise between the two bands'
    parts, which are independent: var(step) = var(whole) - var(narrower)), and each quantity's parts
    weighted by their variance; the Z1 part keeps ``default`` (:func:`removed_noise`: the noise power's
    share).  A slope reads the band's top: the record's step over Kg's sigma scattered 1.03 over
    replicas (dev draw 23, 6 surfaces x 12 at 300 K), where the power's share says 0.54, and the
    step's noise was read as a band disagreement in half the replicas (the tap methods' ±2 sigma
    covered 1.00, z-spread 0.57).  The measured variance is that of a standard error of ~10 taps,
    itself uncertain, and the step is a test of the model's band response, not a measurement of it:
    what is returned is :data:`STEP_TEST` times the fraction, so a disagreement counts where the
    noise would explain it in fewer than 5 % of records (dev draw 23: Kg covered 0.986, z-spread
    0.76; with the fraction alone 1.00 and 0.63).  ``default`` (subtracted once) for every quantity
    where the method has no such parts (dmt-fit: its adhesion covered 0.85 with the test against 0.89
    without).  ``{None: default, quantity: variance factor, ...}``."""
    parts = ((res.info.get("uncertainty") or {}).get("parts") if res is not None else None) or {}
    if not parts:
        return default
    stage = {}
    for s in ("tau_c", "k_g", "k_r"):
        a, b = res.estimates.get(s), narrower.get(s)
        sa, sb = (a.spread if a is not None else None), (b.spread if b is not None else None)
        if sa is None or sb is None or not (sa.n >= 2 and sb.n >= 2) or not a.value or not b.value:
            continue
        if sa.std is None or sb.std is None or not sa.std > 0:
            continue
        se_a = sa.std / math.sqrt(sa.n) / abs(a.value)
        se_b = sb.std / math.sqrt(sb.n) / abs(b.value)
        stage[s] = min(max(1.0 - (se_b / se_a) ** 2, 0.0), 1.0)
    out = {None: default}
    for q, p in parts.items():
        w = {k: v * v for k, v in p.items() if v and math.isfinite(v)}
        total = sum(w.values())
        if total > 0:
            out[q] = STEP_TEST * sum(v * stage.get(k, default) for k, v in w.items()) / total
    return out


def removed_noise(record, narrower) -> float:
    """The fraction of the record's force-noise power that its copy low-passed once more
    (``narrower``, :func:`band_record`) no longer holds, ``1 - (rms_narrow / rms)^2`` from the noise
    each declares (:func:`vetica_cli.signals.noise.declared`: white within the band, so 1 - 1/sqrt(2)
    for the step to fc/sqrt(2)); 0 where either is unknown."""
    from ..signals import noise as nz

    a = nz.declared(record.f)
    b = nz.declared(narrower.f) if narrower is not None else None
    if not a or not b or not a[0] > 0:
        return 0.0
    return min(max(1.0 - (b[0] / a[0]) ** 2, 0.0), 1.0)


def _linear_band(record, lin, fs, fa, spec_s, spec_a, h: float, fc: float, res=None) -> dict:
    """:func:`model_band` of the whole-cycle fit on its own surface, from its linearisation
    (:class:`~.fullfit.method.BandLinearisation`) rather than four re-fits (None where a quantity would
    move by more than :data:`LINEAR_BAND_MAX` in its logarithm: then the re-fits): the fitted surface's
    force ``fs`` (approach ``fa``, None when Z1 is not the approach's) low-passed at ``fc`` moves the
    answer by the bias; the record's step to ``fc/sqrt(2)`` (:func:`band_record`) against the
    model's is the correction's error, as there (:func:`step_sigma`, ``res`` the answer with its own
    sigma).  A re-fit's answer differs from the linear one by
    the second order of the band's change (measured: ``scripts/band_linear.py``)."""
    app = fa is not None

    def cut(c):
        return lowpass(fs, h, c, spectrum=spec_s), (lowpass(fa, h, c, periodic=False, spectrum=spec_a) if app else None)

    def relative(log_change):  # None where a change is too large for the linearisation
        ok = all(math.isfinite(v) and abs(v) <= LINEAR_BAND_MAX for v in log_change.values())
        return {q: math.expm1(v) for q, v in log_change.items()} if ok else None

    low_s, low_a = cut(fc)
    bias = relative(lin.shift(low_s - fs, low_a - fa if app else None))
    if bias is None:
        return None
    d_model, d_rec = {}, {}
    rec2 = band_record(record, BAND_STEPS[0])
    if rec2 is not None:
        low2_s, low2_a = cut(rec2.info["cutoff_hz"])
        d_model = relative(lin.shift(low2_s - low_s, low2_a - low_a if app else None))
        d_rec = relative(lin.shift(rec2.f - record.f, rec2.approach[1] - record.approach[1] if app else None))
        if d_model is None or d_rec is None:
            return None
    # the correction is trusted to no better than its own size: the steps can agree while the whole band does not
    # (noise-free records of dev draws 21-22, reconstructed at 23-31 MHz: the fit's linearised correction left
    # 36-180 % of itself, k_inf and tau_c, where the record's and the model's steps agreed within 20 %)
    steps = step_sigma(bias, d_rec, d_model, res, removed_noise(record, rec2))
    sigma = {q: max(v, abs(bias[q])) for q, v in steps.items()}
    return {"source": "model", "how": "linearised", "bias": bias, "sigma": sigma, "model_step": d_model,
            "record_step": d_rec}  # fmt: skip


def band_limited(record) -> bool:
    """Whether the record's force is low-passed below the Nyquist frequency (a cut-off chosen from its
    noise, declared with the force): where :func:`band_term` applies."""
    from ..signals import noise as nz

    d = nz.declared(record.f)
    return d is not None and d[2] > 1.5 and bool(record.info.get("cutoff_hz"))


def band_term(res: ExtractionResult, record, method, options) -> dict:
    """The **band term** of a force low-passed below the Nyquist frequency (the cut-off chosen
    from a noisy record's noise, :mod:`vetica_cli.signals.noise`): ``{"source", "bias": {quantity:
    relative bias}, "sigma": {quantity: relative error of the band term}}``, empty for a
    whole-band force.  A low-pass smears the contact's kinks over ~1/(2 fc): the force minima that
    mark contact, separation and Z1 move (into the contact, where the force is less steep), and
    the initial slope is read later; these biases do not average over taps and are not in the
    answer at the whole band.

    * ``model`` (a method with a referee whose fit reproduces the record, or the whole-cycle fit on
      its own fitted surface, :func:`model_band`):
      the bias read on the fitted surface's force, divided out of the answer by
      :func:`calibrate`; its sigma is the measured disagreement of the model's band response with
      the record's.  On the 300 K worked-example family (k0:k_inf 47, cd 2.9e-4 kg/s, 31 MHz) the
      record's k_inf and cd were -12 % and -16 % off the whole-band answer, the model said -11.8 %
      and -15.7 %, and the corrected answers were within 1 %.  The fit on its own surface reads it
      from its linearisation (:func:`_linear_band`: a linear solve, no re-fit): four re-fits of the
      model's records a record made its band sigma swing with the re-fits' convergence (on soft 300 K
      surfaces 0.36-5.8 % where the linear reading gives 0.02-0.4 %, widths 1.0-3.4 against 0.57-1.8
      on dev draw 19: ``scripts/band_linear.py``, ``scripts/trust.py``) and cost 60 % of the extraction.
    * ``richardson`` (any other method or record, e.g. where the fitted surface's k_g is flagged or its
      model records are refused): measured on the record itself by Richardson's
      extrapolation: the method re-run on its own force low-passed once more at ``fc/sqrt(2)`` and
      ``fc/2`` (no more noise), the changes ``D1``, ``D2`` fitted by a bias growing as ``fc^-p``
      (``D2/D1 = 2^(p/2) + 1``, ``p`` clamped to 1..4), and the bias at ``fc`` is
      ``D1/(2^(p/2) - 1)``, its magnitude the sigma (not corrected: its sign is not known).  It
      under-estimated the bias of the case above about twofold (the bias saturates below ~30 MHz:
      not a power law).  A quantity the method gives at neither ``fc/sqrt(2)`` nor a
      model's record is not measured: :func:`calibrate` lists it (``unmeasured``) and the flags say
      so.  Where the band collapses the contact at ``fc/2`` the steps are no power law either: on a
      300 K replica of a 238 N/m surface VETICA's Kg moved -0.47 % and -27 %, read at the clamped
      p = 4 as a 0.16 % bias, where the fit's surface reads +5.6 % on its other replicas (+8.4 % off
      the truth at a 0.8 % sigma; not changed).

    Added to sigma in quadrature (an error bar of the record's answer against the noise-free one
    at the whole band), and compared with the tolerance by the flags (:mod:`.sanity`)."""
    if not band_limited(record):
        return {}
    narrower = _narrower_runs(record, method, options, res)
    if getattr(method, "band_model", None) or getattr(method, "referee", None):
        out = model_band(res, record, method, options, narrower)
        if out is not None:
            return out
    alts = []
    for step in BAND_STEPS:
        got = narrower(step)
        if got is None:  # the method refuses the narrower band: the steps before stand
            break
        alts.append(got[1])
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
    return {"source": "richardson", "bias": out, "sigma": dict(out)} if out else {}


def calibrate(res: ExtractionResult, record, method=None, options=None) -> ExtractionResult:
    """Give every estimate of ``res`` its standard error (module docstring): the method's own
    ``sigmas`` hook (:meth:`~vetica_cli.extraction.base.ExtractionMethod.sigmas`), then the band
    term of a low-passed force; in place."""
    info = {}
    if method is not None:
        sig, info = method.sigmas(res, record, options or {})
        res.estimates = {k: dataclasses.replace(e, sigma=sig[k]) if k in sig and e.value is not None else e
                         for k, e in res.estimates.items()}  # fmt: skip
    # set before the band term, which reads the sigma's parts (removed_by_quantity); its own entry is added to
    # this same dict below
    res.info = {**res.info, "uncertainty": info}
    if method is not None:  # a band-limited force: the bias of its low-pass (corrected where a model measures it)
        band = band_term(res, record, method, options or {})
        # a quantity with an error bar the band term could not read (the method gives no value for it on the record
        # low-passed once more, and no model measured it): its low-pass bias is unknown, which the flags say
        unmeasured = sorted(k for k, e in res.estimates.items() if e.value is not None and e.sigma is not None
                            and k not in band.get("sigma", {})) if band_limited(record) else []  # fmt: skip
        if unmeasured:
            band = {"source": "none", "bias": {}, "sigma": {}, **band, "unmeasured": unmeasured}
        if band:
            info["band"] = {"cutoff_hz": record.info.get("cutoff_hz"), **band}
            corrected = band["source"] == "model"
            out = {}
            for k, e in res.estimates.items():
                if k in band["sigma"] and e.value is not None and e.sigma is not None:
                    value = e.value / (1.0 + band["bias"][k]) if corrected and correctable(band["bias"][k]) else e.value
                    err = 100.0 * (value - e.theory) / e.theory if e.theory else e.error_pct
                    e = dataclasses.replace(e, value=value, error_pct=err, sigma=math.hypot(e.sigma, band["sigma"][k]))
                out[k] = e
            res.estimates = out
    return res
