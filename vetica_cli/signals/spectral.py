"""Spectral operations on a recorded window: the tip-sample force from the paddle
signal by spectral inversion and the spectral derivative (thesis 5.3.1),
both with one Bernoulli end correction.

The torsional paddle is driven only by the tip-sample force (thesis eq. 16),
so in the frequency domain (thesis eqs. 17-20)::

    Zp(w) = T(w) Fts(w),   T(w) = (1/k2) / (1 - (w/w2)^2 + i w/(Q2 w2))    [m/N]
    Fts(w) = Zp(w) / T(w) = k2 (1 - (w/w2)^2 + i w/(Q2 w2)) Zp(w)           [N]

``1/T`` grows as ``w^2``: it is the paddle operator ``m2 d2/dt2 + c2 d/dt + k2``
with ``m2 = k2/w2^2``, ``c2 = m2 w2/Q2``.  A discrete Fourier transform treats
the window as one period of a periodic signal, so any mismatch between its two
ends (a window that is not an exact number of drive periods, or a signal that
is still drifting by picometres from period to period, which the simulator's
steady-state tolerance allows) becomes a step whose second derivative rings
over the whole window.  On the worked example a plain FFT of the 10 recorded
periods is off by more than the peak force because ``z_paddle`` drifts by
~2 pm per period (7.8 pm between the window's ends).

Leakage is removed exactly, without assuming periodicity, by an end
correction with Bernoulli polynomials (the Eckhoff / Lanczos method)::

    zp(t) = r(t) + b(t),   b(t) = sum_{j=0..K} J_j L^j/(j+1)! B_{j+1}((t - t0)/L)

``J_j`` is the jump of the j-th derivative across the wrap of the window of
length ``L = n h`` (derivative just after the last sample minus derivative at
the first, each from a local polynomial fit of the end samples; a jump not
resolved above the noise of that fit is left out).  The
periodic extension of ``r`` is then ``C^K`` (K = 2: value, velocity and
acceleration continuous), so ``r`` inverts spectrally without ringing, and
the paddle operator is applied to the polynomial ``b`` analytically.  The same
code handles windows that are not a whole number of drive periods (e.g.
f1 = 75 kHz, where T / print_step is not an integer): no resampling and no
assumption on the drive period is needed.

Low-pass: the inverted spectrum is multiplied by a raised-cosine taper that is
1 below ``(1 - taper) fc`` and 0 above ``fc``.  The default ``fc`` is the
Nyquist frequency ``1/(2 h)`` with no taper (the whole band the sampling
holds): the simulated paddle signal is noise-free, and the force has slope
discontinuities at contact and separation (its spectrum falls only as
``1/w^2``), which VETICA's stages 1a and 1b read at the nanosecond scale.
Any lower cut-off smears those kinks over ~``1/fc``; see
results/thesis/worked_example.md for the reconstruction and VETICA errors against
``fc``.  For measured (noisy) data choose ``fc`` from the detector noise
floor: noise is amplified by ``(w/w2)^2``.

The spectral derivative ``dz/dt = F^-1[i w Z(w)]`` (thesis eqs. 93-94, the tip
velocity of the "4-D" force curve) needs the same end correction for the same
reason, to first order (value and slope jumps): :func:`spectral_derivative`.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from ..errors import InputError


@dataclass
class Reconstruction:
    """Force rebuilt from the paddle signal on the input time grid."""

    f: np.ndarray  # [N] reconstructed tip-sample force
    cutoff_hz: float  # [Hz] low-pass cut-off fc actually used
    taper: float  # raised-cosine taper width as a fraction of fc
    end_jumps: np.ndarray  # [m, m/s, m/s^2, ...] derivative jumps corrected (0 = below the noise)
    noise: object = None  # the noise measured and the cut-off chosen (signals.noise.CutoffChoice) with cutoff 'auto'


def paddle_inverse_transfer(omega: np.ndarray, k2: float, f2: float, q2: float) -> np.ndarray:
    """``1/T(w) = k2 (1 - (w/w2)^2 + i w/(Q2 w2))`` [N/m] (thesis eqs. 17-19)."""
    w2 = 2.0 * math.pi * f2
    return k2 * (1.0 - (omega / w2) ** 2 + 1j * omega / (q2 * w2))


_BERNOULLI = (  # coefficients of B_m(s), highest power first (B_1 = s - 1/2 convention)
    (1.0,),
    (1.0, -0.5),
    (1.0, -1.0, 1.0 / 6.0),
    (1.0, -1.5, 0.5, 0.0),
    (1.0, -2.0, 1.0, 0.0, -1.0 / 30.0),
    (1.0, -2.5, 5.0 / 3.0, 0.0, -1.0 / 6.0, 0.0),
)


def _bernoulli_poly(m: int, s: np.ndarray) -> np.ndarray:
    """Bernoulli polynomial ``B_m(s)`` (B_1 = s - 1/2 convention); a table up to m = 5 (Horner), scipy beyond."""
    if m < len(_BERNOULLI):
        coeffs = _BERNOULLI[m]
        out = np.full_like(s, coeffs[0], dtype=float)
        for c in coeffs[1:]:
            out *= s
            out += c
        return out
    from scipy.special import bernoulli, comb

    b = bernoulli(m)
    coeffs = [comb(m, k, exact=True) * b[k] for k in range(m + 1)]  # of s^(m-k)
    return np.polyval(coeffs, s)


def bernoulli_correction(jumps: np.ndarray, n: int, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The end-correction polynomial and its first two time derivatives on ``n`` samples
    ``h`` apart (module docstring)::

        b(t) = sum_j J_j L^j/(j+1)! B_{j+1}(s),   s = (t - t0)/L,   L = n h

    ``jumps`` = ``J_0, J_1, ...`` (:func:`end_jumps`, units [y]/s^j).  Returns
    ``(b, db/dt, d2b/dt2)`` in [y], [y]/s, [y]/s^2: ``y - b`` has a periodic
    extension continuous up to derivative ``len(jumps) - 1``.
    """
    length = n * h
    if n > CACHE_SAMPLES and all(j + 1 < len(_BERNOULLI) for j, jump in enumerate(jumps) if jump != 0.0):
        return _bernoulli_compiled(jumps, n, length)
    b = np.zeros(n)
    b1 = np.zeros(n)
    b2 = np.zeros(n)
    grids = {}  # B_m(k/n) by m: each polynomial evaluated once for b, b' and b''

    def grid(m):
        if m not in grids:
            grids[m] = _bernoulli_on_grid(m, n)
        return grids[m]

    for j, jump in enumerate(jumps):
        if jump == 0.0:  # a jump left out (below the noise) adds nothing
            continue
        m = j + 1
        a = jump * length**j / math.factorial(m)
        b += a * grid(m)
        b1 += a * m * grid(m - 1) / length
        if m >= 2:
            b2 += a * m * (m - 1) * grid(m - 2) / length**2
    return b, b1, b2


def _bernoulli_compiled(jumps: np.ndarray, n: int, length: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`bernoulli_correction` of a long window in one compiled pass, the same bits
    (:mod:`.passes`: the same scalar operations in the same order)."""
    from .passes import terms

    used = [(j, jump) for j, jump in enumerate(jumps) if jump != 0.0]
    width = len(_BERNOULLI)  # six coefficients a row, leading zeros below degree 5 (passes._horner)
    coeffs = np.zeros((3 * max(len(used), 1), width))
    a, am, amm = np.zeros(len(used)), np.zeros(len(used)), np.zeros(len(used))
    for i, (j, jump) in enumerate(used):
        m = j + 1
        a[i] = jump * length**j / math.factorial(m)  # as bernoulli_correction: (a m) g / L, (a m (m - 1)) g / L^2
        am[i] = a[i] * m
        amm[i] = a[i] * m * (m - 1)
        for r, mm in enumerate((m, m - 1, m - 2)):
            if mm >= 0:
                row = _BERNOULLI[mm]
                coeffs[3 * i + r, width - len(row) :] = row
    return terms(coeffs, a, am, amm, float(length), float(length**2), int(n))


# windows up to this length keep their Bernoulli polynomials and paddle gain (a scan pixel's 4 periods at 1 ns: 80000)
CACHE_SAMPLES = 1 << 17
FFT_RADICES = (2, 3, 5, 7, 11)  # prime factors numpy's FFT has fast passes for
SCIPY_FFT_MIN = 1024  # awkward lengths from which scipy's FFT is faster (below, its call costs more than it saves)


def _smooth(n: int) -> bool:
    """Whether ``n`` has no prime factor beyond :data:`FFT_RADICES` (numpy's FFT is fast on it)."""
    for p in FFT_RADICES:
        while n > 1 and n % p == 0:
            n //= p
    return n == 1


def fast_length(n: int, keep: float = 0.97) -> int:
    """The largest length ``m <= n`` whose FFT is fast (no prime factor beyond :data:`FFT_RADICES`)
    with ``m >= keep n``; ``n`` itself when it is fast, short, or no such ``m`` exists.  An approach
    segment of 3 x 10813 samples costs 3.3 ms a DCT against 0.15 ms at 32400 (measured), and the
    extraction of a 300 K pixel record transforms its approach several times over."""
    if n < SCIPY_FFT_MIN or _smooth(n):
        return n
    for m in range(n - 1, int(math.ceil(keep * n)) - 1, -1):
        if _smooth(m):
            return m
    return n


def rfft(x: np.ndarray) -> np.ndarray:
    """``numpy.fft.rfft(x)``; a length of ``SCIPY_FFT_MIN`` or more with a large prime factor (an
    approach segment of 3 x 10813 samples: 8 ms against 0.3 ms at a nearby length) goes to
    ``scipy.fft``, the same transform (the same pocketfft: equal bits on 407 lengths tried) 2-4x
    faster there (imported only then)."""
    if len(x) < SCIPY_FFT_MIN or _smooth(len(x)):
        return np.fft.rfft(x)
    import scipy.fft

    return scipy.fft.rfft(x)


def irfft(spec: np.ndarray, n: int) -> np.ndarray:
    """``numpy.fft.irfft(spec, n)`` (:func:`rfft`: scipy's for a long awkward ``n``)."""
    if n < SCIPY_FFT_MIN or _smooth(n):
        return np.fft.irfft(spec, n)
    import scipy.fft

    return scipy.fft.irfft(spec, n)


def _bernoulli_on_grid(m: int, n: int) -> np.ndarray:
    """``B_m(k/n)``, k = 0..n-1 (cached, read-only, for tap windows of up to CACHE_SAMPLES)."""
    return _bernoulli_cached(m, n) if n <= CACHE_SAMPLES else _bernoulli_poly(m, np.arange(n) / n)


@functools.lru_cache(maxsize=64)
def _bernoulli_cached(m: int, n: int) -> np.ndarray:
    out = _bernoulli_poly(m, np.arange(n) / n)
    out.setflags(write=False)
    return out


def _paddle_gain(n: int, h: float, k2: float, f2: float, q2: float) -> tuple[np.ndarray, np.ndarray]:
    """``(rfftfreq(n, h), 1/T(2 pi freq))`` (cached for windows of up to CACHE_SAMPLES)."""
    if n <= CACHE_SAMPLES:
        return _paddle_gain_cached(n, h, k2, f2, q2)
    from .passes import paddle_gain  # one compiled pass, the same bits

    return paddle_gain(int(n), float(h), float(k2), 2.0 * math.pi * f2, float(q2))


@functools.lru_cache(maxsize=64)
def _paddle_gain_cached(n: int, h: float, k2: float, f2: float, q2: float) -> tuple[np.ndarray, np.ndarray]:
    freq = np.fft.rfftfreq(n, h)
    gain = paddle_inverse_transfer(2.0 * math.pi * freq, k2, f2, q2)
    freq.setflags(write=False)
    gain.setflags(write=False)
    return freq, gain


@functools.lru_cache(maxsize=None)
def end_fit_weights(points: int, degree: int) -> tuple:
    """The least-squares polynomial fit of ``degree`` through ``points`` equally spaced
    samples as fixed linear weights, for the samples at ``x = 0..points-1`` (first end) and
    ``x = -points..-1`` (last end, extrapolated to ``x = 0`` one step past it).  For each end:
    ``(W, G, A)`` with ``coef = W y`` (``W = (A^T A)^-1 A^T``), ``G = (A^T A)^-1`` (the
    coefficients' covariance per unit residual variance) and ``A`` the Vandermonde matrix.
    Computed in exact rational arithmetic and rounded once, so the weights are the same
    bits on every machine."""
    n = degree + 1
    out = []
    for offset in (0, -points):
        a = [[Fraction(i + offset) ** k for k in range(n)] for i in range(points)]
        gram = [[sum(row[i] * row[j] for row in a) for j in range(n)] for i in range(n)]
        ginv = _exact_inverse(gram)
        w = [[sum(ginv[i][k] * a[r][k] for k in range(n)) for r in range(points)] for i in range(n)]
        out.append(tuple(tuple(tuple(float(v) for v in row) for row in m) for m in (w, ginv, a)))
    return tuple(out)


def _exact_inverse(m: list) -> list:
    """Inverse of a nonsingular square matrix of Fractions (Gauss-Jordan, exact)."""
    n = len(m)
    aug = [list(row) + [Fraction(int(i == j)) for j in range(n)] for i, row in enumerate(m)]
    for c in range(n):
        p = next(r for r in range(c, n) if aug[r][c] != 0)
        aug[c], aug[p] = aug[p], aug[c]
        aug[c] = [v / aug[c][c] for v in aug[c]]
        for r in range(n):
            if r != c and aug[r][c] != 0:
                aug[r] = [x - aug[r][c] * y for x, y in zip(aug[r], aug[c])]
    return [row[n:] for row in aug]


def end_jumps(
    y: np.ndarray, h: float, order: int = 2, points: int = 12, degree: int = 4
) -> tuple[np.ndarray, np.ndarray]:
    """Jumps of the derivatives 0..order of ``y`` across the periodic wrap.

    ``J_j = y^(j)(t_last + h) - y^(j)(t_first)``, each derivative from a
    least-squares polynomial of ``degree`` through ``points`` samples at that
    end (extrapolated one step past the last sample).  Returns ``(J, se)``:
    the jumps and their standard errors from the fits' residuals (noise).
    Units: [y] / s^j.

    The fits are fixed weights (:func:`end_fit_weights`) summed with ``math.fsum``
    (correctly rounded), not LAPACK: the jumps of a noise-free record are resolved only
    to rounding (``J_2`` to ~10 standard errors on the worked example), and the spectral
    inversion amplifies the correction, so a BLAS kernel of another CPU moved the
    reconstructed force's Kg by 5e-7 relative; this way the result is the same bits on
    every machine.
    """
    jumps = np.zeros(order + 1)
    var = np.zeros(order + 1)
    ends = ((y[:points], -1.0), (y[-points:], 1.0))
    for (w, ginv, a), (ys, sign) in zip(end_fit_weights(points, degree), ends):
        ys = [float(v) for v in ys]
        coef = [math.fsum(wi * v for wi, v in zip(row, ys)) for row in w]
        resid = [v - math.fsum(ai * c for ai, c in zip(row, coef)) for v, row in zip(ys, a)]
        s2 = math.fsum(r * r for r in resid) / max(points - degree - 1, 1)
        for j in range(order + 1):
            scale = math.factorial(j) / h**j
            jumps[j] += sign * scale * coef[j]
            var[j] += scale**2 * s2 * ginv[j][j]
    return jumps, np.sqrt(var)


def reconstruct_force(
    t: np.ndarray,
    z_paddle: np.ndarray,
    k2: float,
    f2: float,
    q2: float,
    cutoff_hz: float | str | None = None,
    taper: float = 0.0,
    order: int = 2,
    drive_hz: float | None = None,
) -> Reconstruction:
    """Tip-sample force from the paddle deflection (thesis eqs. 17-20).

    Parameters: ``t`` [s] uniformly spaced, ``z_paddle`` [m], paddle
    stiffness ``k2`` [N/m], resonance ``f2`` [Hz], quality factor ``q2``;
    ``cutoff_hz`` the low-pass cut-off fc (None = Nyquist, 1/(2 h); 'auto' = where the
    inverted noise meets the signal's harmonics, :mod:`vetica_cli.signals.noise`, on the comb
    of the drive frequency ``drive_hz`` -- Nyquist when it cannot be read);
    ``taper`` the raised-cosine roll-off width as a fraction of fc (0 = brick
    wall); ``order`` the highest derivative made continuous across the
    window's wrap by the Bernoulli end correction (module docstring).
    Returns the force [N] on the same samples.
    """
    t = np.asarray(t, dtype=float)
    zp = np.asarray(z_paddle, dtype=float)
    n = len(t)
    points = 12
    if n < 4 * points:
        raise InputError(f"spectral inversion needs at least {4 * points} samples, got {n}")
    if not (k2 > 0 and f2 > 0 and q2 > 0):
        raise InputError(f"probe k2, f2, q2 must be > 0 for the force reconstruction (got {k2}, {f2}, {q2})")
    h = (t[-1] - t[0]) / (n - 1)
    if np.max(np.abs(np.diff(t) - h)) > 1e-3 * h:
        raise InputError("spectral inversion needs uniformly sampled t (constant time step)")
    if not 0.0 <= taper < 1.0:
        raise InputError(f"taper {taper} not allowed; expected a fraction in [0, 1)")
    nyquist = 0.5 / h
    auto = isinstance(cutoff_hz, str)
    if auto and cutoff_hz != "auto":
        raise InputError(f"cut-off {cutoff_hz!r} not allowed; expected a frequency > 0 Hz or 'auto'")
    fc = nyquist if cutoff_hz is None or auto else float(cutoff_hz)
    if not fc > 0:
        raise InputError(f"cut-off {cutoff_hz} Hz not allowed; expected > 0")
    w2 = 2.0 * math.pi * f2
    m2 = k2 / w2**2
    c2 = m2 * w2 / q2

    # Bernoulli end correction: b has the same derivative jumps as zp across the wrap.
    # A jump not resolved above the noise (|J| < 3 standard errors) is left out: a wrong
    # J_2 would bias the force over the whole window (by m2 J_2 (s - 1/2)), an omitted
    # one only rings near the window's ends.
    jumps, se = end_jumps(zp, h, order=order, points=points)
    jumps = np.where(np.abs(jumps) > 3.0 * se, jumps, 0.0)
    b, b1, b2 = bernoulli_correction(jumps, n, h)

    spec = rfft(zp - b)
    freq, gain = _paddle_gain(n, h, k2, f2, q2)
    choice = None
    if auto:  # the low-pass chosen from the record's own noise (signals.noise)
        from .noise import measure

        inverted = spec * gain
        periods = n * h * (drive_hz or 0.0)
        if abs(periods - round(periods)) <= 0.01:  # whole periods: the spectrum as it is
            choice = measure(None, h, drive_hz, spectrum=inverted, n=n, notch_hz=f2)
        else:  # the unfiltered force, read over its longest whole-period stretch
            choice = measure(irfft(inverted, n) + (m2 * b2 + c2 * b1 + k2 * b), h, drive_hz, notch_hz=f2)
        if choice is not None:
            fc = choice.cutoff_hz
    if taper > 0:
        f_pass = fc * (1.0 - taper)
        roll = np.clip((freq - f_pass) / (fc - f_pass), 0.0, 1.0)
        gain = gain * 0.5 * (1.0 + np.cos(math.pi * roll))
    elif fc < nyquist:
        gain = gain * (freq <= fc)
    f = irfft(spec * gain, n)
    if n > CACHE_SAMPLES:  # one compiled pass, the same bits (passes.combine)
        from .passes import combine

        f = combine(f, b, b1, b2, m2, c2, k2)
    else:
        f = f + (m2 * b2 + c2 * b1 + k2 * b)
    return Reconstruction(f=f, cutoff_hz=min(fc, nyquist), taper=taper, end_jumps=jumps, noise=choice)


def reconstruction_error(f_rec: np.ndarray, f_true: np.ndarray) -> dict:
    """Errors of a reconstructed force against the true one, in % of the peak force.

    ``rms_pct`` = RMS of the difference; ``max_pct`` = largest absolute
    difference (at the contact/separation kinks); ``peak_pct`` = signed
    error of the reconstructed peak (max) force; all relative to max(f_true).
    """
    f_rec = np.asarray(f_rec, dtype=float)
    f_true = np.asarray(f_true, dtype=float)
    peak = float(np.max(f_true))
    e = f_rec - f_true
    return {
        "rms_pct": float(100.0 * np.sqrt(np.mean(e * e)) / peak),
        "max_pct": float(100.0 * np.max(np.abs(e)) / peak),
        "peak_pct": float(100.0 * (np.max(f_rec) - peak) / peak),
    }


def spectral_derivative(z: np.ndarray, h: float, cutoff_hz: float | None = None, points: int = 12) -> np.ndarray:
    """Time derivative by the spectral derivative ``dz/dt = F^-1[i w Z(w)]`` (thesis eqs. 93-94, 5.3.1).

    ``z`` sampled every ``h`` [s] over a window that need not be periodic: a
    run steady to the simulator's tolerance still drifts by picometres per
    period, and the DFT's periodic extension turns that mismatch into a step
    whose derivative rings over the window.  The value and slope jumps across
    the wrap (:func:`end_jumps`, order 1, every jump kept) are removed first by
    the Bernoulli end correction (:func:`bernoulli_correction`: ``b(t) = J0
    B1(s) + J1 L B2(s)/2``) and ``b'`` is added back analytically; windows
    shorter than ``2 points`` samples are transformed as they are.  The Nyquist
    bin of an even-length signal is dropped (its derivative is not real).
    ``cutoff_hz``: bins above it are dropped (brick wall; None keeps the whole
    band), which noisy records need, since differentiation multiplies noise by
    ``w``.  Units: [z]/s.
    """
    z = np.asarray(z, float)
    n = len(z)
    jumps = end_jumps(z, h, order=1, points=points)[0] if n >= 2 * points else np.zeros(2)
    b, db, _ = bernoulli_correction(jumps, n, h)
    spec = np.fft.rfft(z - b)
    w = 2 * np.pi * np.fft.rfftfreq(n, h)
    deriv = 1j * w * spec
    if n % 2 == 0:
        deriv[-1] = 0.0
    if cutoff_hz is not None:
        deriv[w > 2 * np.pi * cutoff_hz] = 0.0
    return np.fft.irfft(deriv, n) + db
