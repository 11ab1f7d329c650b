"""Compiled passes over a long window's samples and spectrum, each the same bits as the numpy code
it replaces (the same scalar operations in the same order, no fused multiply-add), for windows
where numpy's temporaries cost more than the arithmetic (the worked example's 10 periods at
0.125 ns: 1.6 M samples, 0.8 M bins).

* :func:`terms`, :func:`combine`: the Bernoulli end correction of :mod:`.spectral` --
  :func:`.spectral.bernoulli_correction` builds ``b``, ``b'`` and ``b''`` from the polynomials
  ``B_m(k/n)`` on the window's grid, ~15 array passes (50 ms on 1.6 M samples); :func:`terms` does
  it per sample (Horner's rule from the highest power, the terms accumulated in the order of the
  jumps); :func:`combine` adds the paddle operator on ``b`` to the inverted force as
  ``f + ((m2 b'' + c2 b') + k2 b)``, numpy's order;
* :func:`paddle_gain`: the frequencies and the paddle's inverse transfer of a long window
  (:func:`.spectral.paddle_inverse_transfer`);
* :func:`hann_power`, :func:`harmonic_bins`: the powers and the harmonic comb of
  :func:`.noise.measure` and :func:`.noise.harmonic_spectrum`.

Compiled on first use (numba's cache).
"""

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _horner(c, r, s):
    """Row ``r`` of ``c`` (six coefficients, highest power first, leading zeros for a lower degree:
    ``0 s + c = c`` exactly for ``s >= 0``, so the padding changes no bit) at ``s``."""
    g = c[r, 0]
    g = g * s + c[r, 1]
    g = g * s + c[r, 2]
    g = g * s + c[r, 3]
    g = g * s + c[r, 4]
    return g * s + c[r, 5]


@njit(cache=True)
def terms(coeffs, a, am, amm, length, length2, n):
    """``(b, b1, b2)`` on ``n`` samples: term ``i`` has the Horner rows of ``B_m``, ``B_(m-1)`` and
    ``B_(m-2)`` in ``coeffs[3 i .. 3 i + 2]`` (six coefficients each, :func:`_horner`) and the weights
    ``a[i]``, ``am[i] = a m`` and ``amm[i] = a m (m - 1)`` (``b''`` left alone where ``amm[i]`` is 0: a
    term with m = 1); ``length`` and ``length2 = length**2`` [s, s^2].  The terms are added one after
    the other to every sample, as the numpy code adds its arrays."""
    b = np.zeros(n)
    b1 = np.zeros(n)
    b2 = np.zeros(n)
    for i in range(len(a)):
        r = 3 * i
        ai, ami, ammi = a[i], am[i], amm[i]
        for k in range(n):
            s = k / n
            b[k] = b[k] + ai * _horner(coeffs, r, s)
            b1[k] = b1[k] + (ami * _horner(coeffs, r + 1, s)) / length
        if ammi != 0.0:
            for k in range(n):
                s = k / n
                b2[k] = b2[k] + (ammi * _horner(coeffs, r + 2, s)) / length2
    return b, b1, b2


@njit(cache=True)
def combine(f, b, b1, b2, m2, c2, k2):
    """``f + ((m2 b2 + c2 b1) + k2 b)`` in place of ``f`` (numpy's order of the same expression)."""
    for k in range(len(f)):
        f[k] = f[k] + ((m2 * b2[k] + c2 * b1[k]) + k2 * b[k])
    return f


@njit(cache=True)
def hann_power(re, im):
    """``(power, rect)`` of :func:`.noise.measure`: the Hann-windowed power ``|X_k/2 - (X_(k-1) +
    X_(k+1))/4|^2 / 0.375`` (the window at the two ends left at ``X_k/2``) and the raw power
    ``|X_k|^2`` of the spectrum ``re + i im``."""
    n = len(re)
    power = np.empty(n)
    rect = np.empty(n)
    for k in range(n):
        hr = 0.5 * re[k]
        hi = 0.5 * im[k]
        if 0 < k < n - 1:
            hr = hr - 0.25 * (re[k - 1] + re[k + 1])
            hi = hi - 0.25 * (im[k - 1] + im[k + 1])
        power[k] = (hr * hr + hi * hi) / 0.375
        rect[k] = re[k] * re[k] + im[k] * im[k]
    return power, rect


@njit(cache=True)
def harmonic_bins(nb, periods, guard):
    """``(frac, noise_mask)`` of :func:`.noise.harmonic_spectrum` over ``nb`` bins: each bin's position
    in harmonics (``k / periods``) and whether it is ``guard`` bins or more from the nearest harmonic
    (``|frac - round(frac)| periods >= guard``; round half to even, as numpy's)."""
    frac = np.empty(nb)
    mask = np.empty(nb, dtype=np.bool_)
    for k in range(nb):
        x = float(k) / periods
        frac[k] = x
        mask[k] = abs(x - np.rint(x)) * periods >= guard
    return frac, mask


@njit(cache=True)
def paddle_gain(n, h, k2, w2, q2):
    """``(rfftfreq(n, h), 1/T(2 pi freq))`` of :func:`.spectral.paddle_inverse_transfer` as numpy computes
    them: ``freq = k (1/(n h))``; ``k2 (1 - (w/w2)^2 + i w/(q2 w2))`` with the imaginary part divided as
    numpy divides a complex number by a real one (times the reciprocal ``1/(q2 w2)``)."""
    nb = n // 2 + 1
    val = 1.0 / (n * h)
    tp = 2.0 * np.pi
    scl = 1.0 / (q2 * w2)
    freq = np.empty(nb)
    gain = np.empty(nb, dtype=np.complex128)
    for k in range(nb):
        fr = k * val
        om = tp * fr
        t1 = om / w2
        re = k2 * (1.0 - t1 * t1)
        im = k2 * (om * scl)
        freq[k] = fr
        gain[k] = complex(re, im)
    return freq, gain
