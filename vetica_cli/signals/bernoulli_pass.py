"""The Bernoulli end correction of a long window in one compiled pass (:mod:`.spectral`).

:func:`.spectral.bernoulli_correction` builds ``b``, ``b'`` and ``b''`` from the polynomials
``B_m(k/n)`` on the window's grid, each a numpy array: on a window of 1.6 M samples (the worked
example's 10 periods at 0.125 ns) that is ~15 array passes and 50 ms.  :func:`terms` does the same
scalar operations in the same order for each sample (Horner's rule from the highest power, the
terms accumulated in the order of the jumps, no fused multiply-add), so its arrays are the same bits;
:func:`combine` adds the paddle operator on ``b`` to the inverted force as
``f + ((m2 b'' + c2 b') + k2 b)``, numpy's order.  Compiled on first use (numba's cache)."""

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
