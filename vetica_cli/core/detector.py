"""The position detector's one-pole (RC) low-pass, compiled (numba; plain SI floats and arrays).

``y_n = (1 - a) x_n + a y_(n-1)``: the recurrence, operation for operation, that
``scipy.signal.lfilter([1 - a], [1, -a], x, zi=[a y_(-1)])`` evaluates (the same numbers, bit for
bit), without importing scipy.signal, which imports scipy.stats (about half a second of imports
in every process that records through a detector of finite bandwidth).
"""

from __future__ import annotations

from numba import njit


@njit(cache=True)
def one_pole(x, a, y_prev, out):
    """Fill ``out`` with the low-pass of ``x`` (``a`` = exp(-2 pi fc ts)) from the filter's
    previous output ``y_prev``; returns the last output (the state to continue from)."""
    b0 = 1.0 - a
    y = y_prev
    for n in range(len(x)):
        y = b0 * x[n] + a * y
        out[n] = y
    return y
