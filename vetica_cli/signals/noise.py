"""The noise a record carries, measured from the record itself, and the low-pass of the
force reconstruction chosen from it: the inverted paddle noise grows as ``(f/f2)^2`` above
the paddle's resonance, so the low-pass must come from the record's noise, not the Nyquist frequency.

A steady tapping record repeats with the drive: its signal lives at the drive's harmonics
``k f1`` and nowhere else, so in the spectrum of ``P`` whole drive periods the signal sits in
every ``P``-th bin and **the bins between the harmonics hold only noise** (the cantilever's
thermal motion, the paddle's Brownian force, detector noise, the ADC's rounding).  That gives
both numbers an extraction needs, with no model of the instrument:

* **the noise spectrum**: in bands of harmonics (an eighth of a decade wide, at least
  :data:`MIN_NOISE_BINS` noise bins each), the mean power of the inter-harmonic bins
  (their median over ``ln 2``: the power of a bin of Gaussian noise is exponential, so the
  median is robust against the leakage of a strong harmonic);
* **the signal spectrum**: in the same bands, the mean power of the harmonic bins minus the
  noise.

**The cut-off rule** (what :func:`choose_cutoff` does): the reconstruction keeps the
harmonics that stand above the measurement noise.  Walking up the bands, the cut-off is the
upper edge of the last band whose harmonics carry more power than the noise floor beside them
(signal-to-noise per bin >= 1, the Wiener filter's own cross-over) before the first run of
:data:`DROP_RUN` bands where they carry less.  (A low-pass only where the noise is worth removing: when the noise over the whole sampled
band is at most :data:`NEGLIGIBLE` of the signal's RMS, the whole band is kept -- a
noise-free record whose taps drift, e.g. a scan pixel's transient, moves its sidebands above
a rounding-level floor at high harmonics.)  The floor, not the raw power, because a record
whose taps change from period to period -- a scan pixel's transient creep, the
cantilever's thermal amplitude -- has sidebands beside every harmonic, up to ``(k dphi)^2`` of
it for a timing that drifts by ``dphi`` (they outgrew the harmonics from ~350 f1 on a noise-free
transient pixel); they are signal, and fall with the harmonics, where the floor does not.  The inverted paddle noise grows as
``(f/f2)^2`` above the paddle's resonance while a tap's harmonics fall as ``1/f^2`` (its kinks
at contact and separation), so the two meet once; a noise-free simulated record never
meets it and keeps the whole band to the Nyquist frequency (as before this rule).

**The noise floor** of the force analysed: the noise power of the bands below the cut-off,
summed (Parseval) -- the RMS of the noise on the samples, whatever its colour -- and its
*white equivalent*: the per-sample white noise with the same power per hertz, spread over the
whole sampled band (``rms * sqrt(f_nyquist / fc)``).  A least-squares fit over many
correlation lengths (a slope, a quadratic) sees band-limited noise as that white noise; the
second-difference floor (:func:`vetica_cli.signals.slopes.white_noise_floor`) sees only the
noise near the Nyquist frequency and reads a low-passed force as noise-free (2.8e-14 N on a
300 K record whose force noise is ~1 nN).

:func:`declare` attaches the measured floors to the arrays analysed, so every later reader of
:func:`vetica_cli.signals.slopes.noise_floor` gets the record's measured noise.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

BANDS_PER_DECADE = 8  # width of a band of harmonics: an eighth of a decade
MIN_NOISE_BINS = 12  # a band holds at least this many inter-harmonic bins (merged with the next otherwise)
DROP_RUN = 3  # bands in a row with the harmonics below the noise end the pass band
MIN_PERIODS = 2.0  # fewer drive periods: no harmonic comb to read the noise between
NEGLIGIBLE = 1e-3  # noise over the whole band below this fraction of the signal's RMS: no low-pass needed
LONG_BINS = 1 << 16  # spectra longer than this are read in compiled passes (signals.passes), the same bits
WHOLE = 0.01  # [periods] a window this close to a whole number of periods is read as it is; else cropped to one


@dataclass(frozen=True)
class NoiseSpectrum:
    """Signal and noise of a record's spectrum in bands of drive harmonics."""

    f_lo: np.ndarray  # [Hz] band lower edges
    f_hi: np.ndarray  # [Hz] band upper edges
    noise: np.ndarray  # [unit^2/Hz] one-sided noise PSD of each band (inter-harmonic bins)
    signal: np.ndarray  # [unit^2/Hz] harmonic power per bin above the noise, as a PSD (can be < 0: noise only)
    drive_hz: float  # [Hz] the drive frequency the comb was laid on
    periods: float  # drive periods in the window
    nyquist: float  # [Hz]
    notch_guard: float = 0.0  # [Hz] bands from here up bound the floor below them (1.5 f2 for an inverted paddle signal)

    def floor(self) -> np.ndarray:
        """The measurement noise's PSD per band [unit^2/Hz]: the inter-harmonic level, capped by
        the lowest level of the bands above it (counted from :attr:`notch_guard` up).  Between
        strong harmonics the bins hold the sidebands of the taps' slow change from period to
        period -- the cantilever's thermal motion at 300 K (up to 1e4 times the measurement
        noise beside the fundamental), a transient record's creep -- a fixed fraction of the
        harmonic power that falls with it; the measurement noise does not fall with frequency
        (the paddle's Brownian force is white, the inverted detector noise rises as ``(f/f2)^2``
        above the paddle's resonance), so the level where the harmonics have faded bounds it.
        The inverted detector noise dips at the paddle's resonance (``1/T`` is smallest there):
        bands below ``notch_guard`` (1.5 f2) never bound the others."""
        out = self.noise.copy()
        if len(out) > 1:  # the first band always holds the fundamental
            out[0] = out[1]
        caps = np.where(self.f_lo >= self.notch_guard, out, np.inf)
        cap = np.minimum.accumulate(caps[::-1])[::-1]  # the lowest level at or above each band
        return np.minimum(out, cap)

    def signal_rms(self) -> float:
        """RMS of the periodic signal about its mean [unit]: the harmonics' power above the noise,
        integrated over the bands."""
        return math.sqrt(float(np.sum(np.clip(self.signal, 0.0, None) * (self.f_hi - self.f_lo))))

    def rms(self, fc: float) -> float:
        """RMS of the measurement noise below ``fc`` [unit] (:meth:`floor` integrated to ``fc``)."""
        width = np.clip(np.minimum(self.f_hi, fc) - np.minimum(self.f_lo, fc), 0.0, None)
        width[0] += min(self.f_lo[0], fc)  # the band from DC to the first edge, at the first band's level
        return math.sqrt(float(np.sum(self.floor() * width)))


@dataclass(frozen=True)
class CutoffChoice:
    """The low-pass chosen for a record and the noise it leaves."""

    cutoff_hz: float  # [Hz]
    harmonics: float  # cut-off in drive harmonics
    noise_rms: float  # [unit] RMS of the noise below the cut-off
    white_equivalent: float  # [unit] per-sample white noise of the same PSD over the whole sampled band
    rule: str  # one line: how the cut-off was chosen
    spectrum: NoiseSpectrum | None = None


def drive_frequency(z: np.ndarray, h: float) -> float | None:
    """The drive frequency [Hz] of a tapping record from the tip position alone: the mean
    period between its first and last upward crossings of the middle of its range (linear
    interpolation between samples, a quarter-range hysteresis against noise: the crossings
    of :func:`vetica_cli.signals.taps.oscillation_cycles`); None for fewer than two crossings.
    Over ``N`` cycles the period's error is the crossing's timing jitter over ``N`` (~1e-6
    relative on a 10-period record), so the ``k``-th harmonic lands on its bin up to ``k`` in
    the thousands."""
    z = np.asarray(z, float)
    if len(z) < 8:
        return None
    lo, hi = float(np.min(z)), float(np.max(z))
    mid, band = 0.5 * (lo + hi), 0.25 * (hi - lo)
    if not hi > lo:
        return None
    times = []
    armed = False
    # vectorised: indices where z crosses mid upwards, accepted only after a visit below mid - band
    below = z < mid - band
    up = np.flatnonzero((z[:-1] < mid) & (z[1:] >= mid))
    last_below = np.maximum.accumulate(np.where(below, np.arange(len(z)), -1))
    prev = -1
    for i in up:
        armed = last_below[i] > prev
        if armed:
            frac = (mid - z[i]) / (z[i + 1] - z[i])
            times.append((i + frac) * h)
            prev = i
    if len(times) < 2:
        return None
    return (len(times) - 1) / (times[-1] - times[0])


def harmonic_spectrum(power: np.ndarray, n: int, h: float, drive_hz: float,
                      harmonic_power: np.ndarray | None = None) -> NoiseSpectrum | None:
    """Signal and noise in bands of harmonics (module docstring) from the one-sided power
    ``power = |rfft(x)|^2`` of ``n`` samples ``h`` apart; None when the window holds fewer
    than :data:`MIN_PERIODS` drive periods or no band with enough noise bins."""
    periods = n * h * drive_hz
    if not (periods >= MIN_PERIODS and math.isfinite(periods)):
        return None
    nb = len(power)
    guard = max(1.5, 0.3 * periods)  # bins from the nearest harmonic for a bin to count as noise
    if nb > LONG_BINS:  # one compiled pass, the same bits (signals.passes)
        from .passes import harmonic_bins

        frac, noise_mask = harmonic_bins(nb, float(periods), float(guard))
    else:
        frac = np.arange(nb, dtype=float) / periods  # position in harmonics
        noise_mask = np.abs(frac - np.round(frac)) * periods >= guard  # bins to the nearest harmonic
    harm_idx = np.round(np.arange(1, int(frac[-1]) + 1) * periods).astype(int)
    harm_idx = harm_idx[(harm_idx > 0) & (harm_idx < nb)]
    df = 1.0 / (n * h)
    to_psd = 2.0 / (n * n) / df  # |X|^2 -> one-sided PSD [unit^2/Hz] (Parseval)
    # bands of harmonics: edges at 10^(j/8) harmonics, merged until each holds MIN_NOISE_BINS noise bins
    top = frac[-1]
    edges = [0.5]
    x = 1.0
    while x < top:
        x = max(x * 10 ** (1.0 / BANDS_PER_DECADE), edges[-1] + 1.0)
        edges.append(min(x, top + 1e-9))
    if edges[-1] < top:
        edges.append(top + 1e-9)
    f_lo, f_hi, noise, signal = [], [], [], []
    # frac (and frac at the harmonics) increases with the bin: a band lo <= frac < hi is a slice of the bins
    frac_h = frac[harm_idx]
    lo = edges[0]
    for hi in edges[1:]:
        a, b = np.searchsorted(frac, (lo, hi))
        in_band = noise_mask[a:b]
        if np.count_nonzero(in_band) < MIN_NOISE_BINS and hi < edges[-1]:
            continue  # merge with the next band
        if np.count_nonzero(in_band) < 2:
            break
        nmean = float(np.median(power[a:b][in_band])) / math.log(2.0)
        ha, hb = np.searchsorted(frac_h, (lo, hi))
        hsel = harm_idx[ha:hb]
        hp = power if harmonic_power is None else harmonic_power
        hmean = float(np.mean(hp[hsel])) if len(hsel) else 0.0
        f_lo.append(lo * drive_hz)
        f_hi.append(min(hi, top) * drive_hz)
        noise.append(nmean * to_psd)
        signal.append((hmean - nmean) * to_psd)
        lo = hi
    if not f_lo:
        return None
    return NoiseSpectrum(np.array(f_lo), np.array(f_hi), np.array(noise), np.array(signal), float(drive_hz),
                         float(periods), 0.5 / h)  # fmt: skip


def choose_cutoff(spectrum: NoiseSpectrum) -> tuple[float, str]:
    """The cut-off rule of the module docstring: ``(cutoff_hz, rule text)``."""
    floor = spectrum.floor()
    above = spectrum.signal > floor
    run, last_ok = 0, -1
    for j, ok in enumerate(above):
        if ok:
            run, last_ok = 0, j
        else:
            run += 1
            if run >= DROP_RUN:
                break
    else:
        if run < DROP_RUN:  # the harmonics stand above the noise to the top: the whole band
            return spectrum.nyquist, "harmonics above the noise up to the Nyquist frequency: no low-pass"
    if last_ok < 0:
        fc = float(spectrum.f_hi[0])
        return fc, "no harmonic stands above the noise: the lowest band kept"
    fc = float(spectrum.f_hi[last_ok])
    return fc, (f"the harmonics meet the noise at {fc / spectrum.drive_hz:.3g} f1 "
                f"(noise {math.sqrt(floor[min(last_ok + 1, len(floor) - 1)]):.2g} /sqrt(Hz) there)")  # fmt: skip


def measure(x: np.ndarray | None, h: float, drive_hz: float | None, cutoff_hz: float | None = None,
            spectrum: np.ndarray | None = None, n: int | None = None,
            notch_hz: float | None = None) -> CutoffChoice | None:  # fmt: skip
    """The noise of the signal ``x`` (``n`` samples every ``h`` [s]): its spectrum in bands of
    the drive's harmonics, the cut-off the rule chooses (or ``cutoff_hz`` when given) and the
    noise left below it.  ``spectrum``: ``rfft`` of the ``n`` samples when the caller has it
    (e.g. the inverted paddle spectrum of a whole number of periods; then ``x`` is None).  A
    signal ``x`` that does not span a whole number of drive periods is read over its longest
    stretch that does (from its start): the harmonics then fall on bins, not between them.  The powers are read through a
    Hann window (applied in the frequency domain, ``X_k/2 - (X_(k-1) + X_(k+1))/4``): the taps
    change slowly from period to period (the cantilever's thermal motion), and through the
    record's rectangular window that modulation leaks between the harmonics as ``1/d`` of the
    distance; through a Hann window as ``1/d^3``, within the harmonic's own bins.  None when
    the record has no harmonic comb to read (fewer than two periods, no drive frequency)."""
    if drive_hz is None or not drive_hz > 0:
        return None
    if x is not None:
        x = np.asarray(x, float)
        n = len(x)
        periods = n * h * drive_hz
        if periods >= MIN_PERIODS and abs(periods - round(periods)) > WHOLE:  # the harmonics between bins would
            n = int(round(math.floor(periods) / (h * drive_hz)))  # leak everywhere: the longest whole-period stretch
            x = x[:n]
        spectrum = np.fft.rfft(x - float(np.mean(x)))
    elif spectrum is None:
        return None
    spectrum = np.asarray(spectrum)
    if len(spectrum) > LONG_BINS:  # one compiled pass, the same bits (signals.passes)
        from .passes import hann_power

        power, rect = hann_power(np.ascontiguousarray(spectrum.real), np.ascontiguousarray(spectrum.imag))
    else:
        hann = 0.5 * spectrum
        hann[1:-1] -= 0.25 * (spectrum[:-2] + spectrum[2:])
        power = (hann.real**2 + hann.imag**2) / 0.375  # the window's mean square: white noise keeps its level
        rect = spectrum.real**2 + spectrum.imag**2  # the harmonics' own bins (a whole number of periods: no leakage)
    spec = harmonic_spectrum(power, int(n), h, drive_hz, harmonic_power=rect)
    if spec is None:
        return None
    if notch_hz:
        spec = dataclasses.replace(spec, notch_guard=1.5 * float(notch_hz))
    if cutoff_hz is None:
        fc, rule = choose_cutoff(spec)
        signal = spec.signal_rms()
        whole = spec.rms(spec.nyquist)
        if fc < spec.nyquist and whole <= NEGLIGIBLE * signal:
            fc, rule = spec.nyquist, (f"noise over the whole band {whole:.2g} (<= {NEGLIGIBLE:g} of the signal's RMS "
                                      f"{signal:.2g}): no low-pass")  # fmt: skip
    else:
        fc, rule = min(float(cutoff_hz), spec.nyquist), "given"
    rms = spec.rms(fc)
    white = rms * math.sqrt(spec.nyquist / fc) if fc > 0 else rms
    return CutoffChoice(fc, fc / drive_hz, rms, white, rule, spec)


# the measured floors of the arrays an extraction reads (their identity and fingerprint; see declare)
_DECLARED: list = []
_DECLARED_MAX = 8


def declare(x: np.ndarray, rms: float, white: float, smear: float = 1.0) -> None:
    """Attach the measured noise of the array ``x`` (RMS on its samples, its white equivalent,
    and the samples a kink is smeared over by the signal's low-pass, ``f_nyquist / fc``, 1 for
    the whole band): :func:`declared` returns them while ``x`` is the same, unchanged array."""
    from .memo import fingerprint

    key = fingerprint(x)
    if key is None:
        return
    _DECLARED.insert(0, (x, key, (float(rms), float(white), float(smear))))
    del _DECLARED[_DECLARED_MAX:]


def declared(x) -> tuple[float, float, float] | None:
    """``(rms, white equivalent, smear in samples)`` declared for ``x`` (:func:`declare`), or None."""
    from .memo import fingerprint

    if not any(arr is x for arr, _, _ in _DECLARED):  # never declared: no fingerprint to take (a sum of the array)
        return None
    key = fingerprint(x)
    for arr, k, value in _DECLARED:
        if arr is x and k == key:
            return value
    return None
