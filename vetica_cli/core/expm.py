"""Matrix exponential of a small matrix, compiled (numba) and without BLAS.

The far-step tables of the hybrid kernel (:mod:`.coefficients`: the arms'
augmented ``2N x 2N`` exponential for each step of the ladder) and the
prescribed-trajectory kernel (:mod:`.prescribed`, complex-step derivatives) take
dozens of exponentials of matrices of order 2 to 8.  scipy's ``expm`` does each by a
Pade approximant through BLAS; inside the ``vetica`` process its 46 calls for the
worked example took 0.31 s (OpenBLAS threads on the shared machine) -- more than the
kernel needs to reach the steady state.  On the arms' matrices this series agrees
with 50-digit mpmath as well as scipy does (1e-14); ``tests/test_steady.py`` checks it
against ``scipy.linalg.expm``.  (The probe oscillators' flows are in closed form,
:func:`.coefficients.oscillator_flow`: scaling and squaring loses 1e-10 there, the
matrix being badly balanced.)
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def expm_small(a):
    """``exp(a)`` of a small square matrix (real or complex) by scaling and squaring of its
    Taylor series: scaled to a 1-norm <= 1/2, summed to 18 terms (truncation below
    1e-21 relative), squared back.  Only arithmetic -- analytic in the entries, so a
    complex step through it gives exact derivatives -- and no BLAS call for a 4x4."""
    n = a.shape[0]
    norm = 0.0
    for j in range(n):
        col = 0.0
        for i in range(n):
            col += abs(a[i, j])
        norm = max(norm, col)
    s = 0
    while norm > 0.5:
        norm *= 0.5
        s += 1
    b = a * (0.5**s)
    out = np.eye(n, dtype=a.dtype)
    term = np.eye(n, dtype=a.dtype)
    tmp = np.empty_like(out)
    for k in range(1, 19):
        for i in range(n):
            for j in range(n):
                acc = term[i, 0] * b[0, j]
                for m in range(1, n):
                    acc += term[i, m] * b[m, j]
                tmp[i, j] = acc / k
        term[:, :] = tmp
        out += term
    for _ in range(s):
        for i in range(n):
            for j in range(n):
                acc = out[i, 0] * out[0, j]
                for m in range(1, n):
                    acc += out[i, m] * out[m, j]
                tmp[i, j] = acc
        out[:, :] = tmp
    return out
