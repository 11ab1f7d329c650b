"""The force of a record rebuilt only where an extraction reads it: each tap's window.

VETICA reads the force at and around the contacts (the contact and separation minima,
the initial contact slope, the contact for stage 2) and at the first contact of the
approach (Z1); between taps it reads only the tip position.  So instead of the spectral
inversion of the whole record (:func:`vetica_cli.signals.spectral.reconstruct_force`,
whose cost on a 4-period record of 1 ns samples is the FFT of 80 000 samples and the
end correction over all of them), :func:`reconstruct_taps`:

1. estimates the force everywhere with the paddle operator in the time domain (central
   differences, compiled: :func:`vetica_cli.core.paddle.paddle_force_fd`) and locates the
   taps on it (:func:`vetica_cli.signals.taps.find_taps`);
2. rebuilds each tap's window -- the contact plus :data:`MARGIN` samples either side,
   rounded up to an FFT-friendly length (:func:`fft_length`) -- by the same spectral
   inversion with the same Bernoulli end correction (the window's ends lie in free
   flight, where the paddle signal is smooth, so the correction is exact to its order);
3. moves each contact and separation minimum and peak to the rebuilt force's (within
   :data:`REFINE` samples of the estimate's).

Outside the windows the returned force is the time-domain estimate.  Measured on records
of 4 periods at 1 ns (worked example and a soft surface): from the contact to the
separation the windows' force equals the whole-record inversion's to 1e-7 of the peak
force, for windows of 2048 to 8192 samples; the last few samples at a window's ends ring
(up to 0.4 % of the peak), which the margin keeps away from the taps
(tests/test_realtime.py checks half a margin either side on a record).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .spectral import reconstruct_force
from .taps import Taps, find_taps, first_contact_minimum

MARGIN = 256  # samples of free flight either side of a contact in its window
REFINE = 32  # samples around the estimate's minimum searched in the rebuilt force
APPROACH_HALF = 512  # samples either side of the approach's first contact minimum rebuilt


def fft_length(n: int) -> int:
    """The smallest ``2^a 3^b 5^c >= n`` (a length numpy's FFT transforms fast)."""
    best = 1 << max(int(n - 1).bit_length(), 0)
    p5 = 1
    while p5 < 2 * n:
        p35 = p5
        while p35 < 2 * n:
            m = p35
            while m < n:
                m *= 2
            best = min(best, m)
            p35 *= 3
        p5 *= 5
    return best


@dataclass
class TapForce:
    """The force of a record rebuilt in its tap windows."""

    f: np.ndarray  # [N] on every sample: spectral inversion in the windows, time-domain estimate elsewhere
    taps: Taps  # the taps, located on the rebuilt force
    windows: list  # (start, stop) sample ranges rebuilt spectrally
    cutoff_hz: float  # [Hz] low-pass cut-off used in the windows


def paddle_estimate(t: np.ndarray, zp: np.ndarray, k2: float, f2: float, q2: float) -> np.ndarray:
    """The time-domain paddle operator of ``zp`` (:func:`vetica_cli.core.paddle.paddle_force_fd`) [N]."""
    from ..core.paddle import paddle_force_fd

    h = (t[-1] - t[0]) / (len(t) - 1)
    w2 = 2.0 * math.pi * f2
    m2 = k2 / w2**2
    out = np.empty(len(zp))
    paddle_force_fd(np.ascontiguousarray(zp, dtype=float), h, m2, m2 * w2 / q2, k2, out)
    return out


def _window(lo: int, hi: int, n: int) -> tuple[int, int]:
    """An FFT-friendly window around samples ``[lo, hi]`` with :data:`MARGIN` either side, inside ``[0, n)``."""
    need = hi - lo + 1 + 2 * MARGIN
    length = min(fft_length(need), n)
    a = max(0, (lo + hi + 1) // 2 - length // 2)
    a = min(a, n - length)
    return a, a + length


def _argmin_near(f: np.ndarray, i: int, a: int, b: int) -> int | None:
    """The rebuilt force's minimum within :data:`REFINE` samples of ``i``; None when it lies on
    the edge of that range (no clean contact kink there: noise, or a low-pass cut-off)."""
    lo, hi = max(a, i - REFINE), min(b, i + REFINE + 1)
    j = lo + int(np.argmin(f[lo:hi]))
    return None if j in (lo, hi - 1) else j


def reconstruct_taps(t, zp, k2: float, f2: float, q2: float, cutoff_hz: float | None = None,
                     taper: float = 0.0) -> TapForce | None:  # fmt: skip
    """The force rebuilt in the tap windows of a record (module docstring); input checks as
    :func:`~vetica_cli.signals.spectral.reconstruct_force`.  None -- rebuild the whole record
    instead -- when the windows would not find what the whole record's inversion finds: a
    low-pass cut-off below the Nyquist frequency (the time-domain estimate has none), no two
    taps in the estimate, or a contact or separation minimum of the rebuilt force that is not
    a clean minimum within :data:`REFINE` samples of the estimate's (a noisy paddle signal)."""
    t = np.asarray(t, dtype=float)
    zp = np.asarray(zp, dtype=float)
    n = len(t)
    if n < 2 or (cutoff_hz is not None and cutoff_hz < 0.5 * (n - 1) / (t[-1] - t[0])):
        return None
    est = paddle_estimate(t, zp, k2, f2, q2)
    try:
        coarse = find_taps(est)
    except InputError:
        return None
    f = est
    windows, cutoff = [], None
    contact, separation, peak = [], [], []
    for ic, isep in zip(coarse.contact, coarse.separation):
        a, b = _window(int(ic), int(isep), n)
        rec = reconstruct_force(t[a:b], zp[a:b], k2, f2, q2, cutoff_hz=cutoff_hz, taper=taper)
        f[a:b] = rec.f
        cutoff = rec.cutoff_hz
        windows.append((a, b))
        c = _argmin_near(f, int(ic), a, b)
        s = _argmin_near(f, int(isep), a, b)
        if c is None or s is None or s - c < 2:
            return None
        contact.append(c)
        separation.append(s)
        peak.append(c + int(np.argmax(f[c : s + 1])))
    taps = Taps(np.array(contact, int), np.array(separation, int), np.array(peak, int), coarse.spacing,
                coarse.incomplete)  # fmt: skip
    if cutoff is None:  # no complete tap: the whole record's inversion says what is wrong
        return None
    return TapForce(f=f, taps=taps, windows=windows, cutoff_hz=float(cutoff))


def approach_force(t, zp, k2: float, f2: float, q2: float, cutoff_hz: float | None = None,
                   taper: float = 0.0, z=None) -> tuple[np.ndarray, int] | None:  # fmt: skip
    """The approach segment's force rebuilt around its first contact minimum, and that
    minimum's index (:func:`~vetica_cli.signals.taps.first_contact_minimum`, located on the
    time-domain estimate, then moved to the rebuilt force's minimum nearby; ``z``: the tip
    position, for the contact's approach side); None as
    :func:`reconstruct_taps` says (then the whole segment is rebuilt)."""
    t = np.asarray(t, dtype=float)
    zp = np.asarray(zp, dtype=float)
    n = len(t)
    if n < 4 * MARGIN or (cutoff_hz is not None and cutoff_hz < 0.5 * (n - 1) / (t[-1] - t[0])):
        return None
    f = paddle_estimate(t, zp, k2, f2, q2)
    try:
        i1 = first_contact_minimum(f, z=z)
    except InputError:
        return None
    a, b = _window(i1 - APPROACH_HALF + MARGIN, i1 + APPROACH_HALF - MARGIN, n)
    f[a:b] = reconstruct_force(t[a:b], zp[a:b], k2, f2, q2, cutoff_hz=cutoff_hz, taper=taper).f
    j = _argmin_near(f, i1, a, b)
    return None if j is None else (f, j)
