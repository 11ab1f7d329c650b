"""The initial contact slope (VETICA's stage 1b, the glassy stiffness Kg) on a noisy record,
with the fitting window chosen from the record's noise.

The thesis fits ``F`` against ``z_tip`` over the 10 samples after each contact minimum
(eq. 86).  At the print steps of its studies the tip moves ~1 pm a sample at contact
(0.86 pm at 0.125 ns on the worked example's 16:1 surface), so 10 samples span ~9 pm and
~0.6 nN: a detector's 1 pm and 0.1 nN per sample leave the slope uncertain by tens of
percent, and the force minimum that marks the contact wanders by several samples in the
flat adhesion well (seen: Kg -120 ... +27 % at 1 pm + 1 nN).  Two changes, both driven by
the noise the record itself shows (second differences, :func:`noise_floor`):

* **the window grows with the noise**: the slope is read from quadratic fits of ``F`` and
  of ``z_tip`` against time over ``n`` samples from the contact, at the sample where the
  thesis's straight line over samples 1..10 reads it -- its centre, 5.5 samples after the
  contact -- so both windows estimate the same slope (``Kg = -F'(t)/z'(t)`` there;
  the quadratic term absorbs the contact's curvature -- the relaxing arm, the decelerating
  tip -- that a longer straight line would average into the slope).  ``n`` is the
  shortest window whose predicted relative standard error of ``Kg`` is at most
  :data:`TARGET` (the endpoint derivative of a quadratic least-squares fit has variance
  ``192 sigma^2/n^3`` in sample units), capped at an eighth of the contact (:data:`WINDOW_SPAN`);
* **the contact is located by a hinge fit**: within a window's length of the force
  minimum (which wanders by hundreds of samples in a flat adhesion well under 1 nN of
  noise), the break of the continuous broken line that explains the force best over
  one fixed stretch of samples; contact and window are refined together.

A force low-passed below the Nyquist frequency (the reconstruction's cut-off ``fc`` chosen from a
noisy record, :mod:`vetica_cli.signals.noise`) smears the kink over ``f_nyquist/fc`` samples; its
slope is read :data:`SMEAR_SKIP` smear lengths past the contact, over at least
:data:`SMEAR_WINDOW` of them (the brick-wall low-pass's ripple averages out), and the thesis's
window is never kept (measured on the noise-free worked example with the pull off, low-passed:
Kg -2.9 % at 300 MHz, -5.3 % at 30 MHz against +0.12 % at the whole band; read on the kink, -74 %
at 100 MHz).

The switch is made per record: while the thesis's window has a predicted relative error
(median over taps) of at most :data:`KEEP` -- the simulator's noise-free records of the thesis
studies --
nothing changes and the thesis's 10-sample fit is returned as before.  Both windows read
the slope at the same sample, so they agree where both are precise (reading the grown
window's slope at the contact instead moved VETICA's Kg from +1.8 % to +3.7 % on the
worked example with the pull, 1 ns, 0.3 nN: the pre-stressed arm steepens the first
samples, a model error of VETICA's that its pre-stress variant removes).
"""

from __future__ import annotations

import math

import numpy as np

from .memo import ArrayMemo
from .noise import declared

TARGET = 0.02  # relative standard error of a tap's Kg the window is grown to
KEEP = TARGET  # the thesis's window is kept while its predicted relative error (median over taps) is at most this
HINGE_REACH = 1.0  # the contact searched within +- this many windows around the current estimate
HINGE_MAX = 4096  # samples of the window the break is located on (at most)


WINDOW_SPAN = 0.125  # the longest window, a fraction of the contact: a quarter of the way to the peak, where the force
# is still close to linear in the tip position (half the contact, the window's reach before, read slopes of -40 N/m
# off a true 131 N/m on 300 K records, whose noise grows the window that far: quadratics over a curving contact)
SMEAR_WINDOW = 4  # ... over a window of at least this many smear lengths
SMEAR_SKIP = 1.0  # a low-passed force's slope is read this many smear lengths (f_nyquist / fc samples) past the kink
NOISE_SAMPLES = 8192  # second differences the noise floor's median is taken over (evenly spread)


_FLOORS = ArrayMemo(4)  # the floors of the last few arrays (a record's force and position, ...)


def noise_floor(x: np.ndarray, samples: int = NOISE_SAMPLES) -> float:
    """RMS of the noise on the samples of ``x``: the floor measured on the record's spectrum
    when one was declared for this array (:func:`vetica_cli.signals.noise.declare`: any
    colour, e.g. a low-passed force), else :func:`white_noise_floor`; the answer of one of the
    last four calls is reused when the same array comes back unchanged
    (:class:`~vetica_cli.signals.memo.ArrayMemo`: an extraction asks for a record's force and
    position floors in every stage-1b run, standard error and check)."""
    d = declared(x)
    if d is not None:
        return d[0]
    return _FLOORS(white_noise_floor, x, samples)


def white_equivalent(x: np.ndarray) -> float:
    """The per-sample white noise a least-squares fit of many samples of ``x`` sees: for a
    declared floor its white equivalent (the same power per hertz over the whole sampled
    band), else :func:`noise_floor`."""
    d = declared(x)
    return d[1] if d is not None else noise_floor(x)


def white_noise_floor(x: np.ndarray, samples: int = NOISE_SAMPLES, order: int = 2) -> float:
    """RMS of the white noise on a sampled signal, from its second differences
    (``var(x[i+1] - 2x[i] + x[i-1]) = 6 sigma^2`` for white noise; median absolute
    deviation for robustness against the contact kinks).  Longer records use ``samples``
    second differences evenly spread over the record (each one of three consecutive
    samples): the median's relative standard error is then ~1.4 %, and its cost no
    longer grows with the record.  ``order=4``: from the fourth differences
    (``var = 70 sigma^2``), which see a smooth signal as ``(omega h)^4`` of it where the second
    see ``(omega h)^2``: on a noise-free tip record at an 8 ns print step the second differences
    of its 20 us swing read 2.9e-13 m of noise, the fourth 1.4e-16 m."""
    if order not in (2, 4):
        raise ValueError(f"order {order!r}: 2 or 4")
    x = np.asarray(x, float)
    n = len(x)
    half = order // 2
    if n < order + 3:
        return 0.0
    step = max(1, (n - order) // samples)
    i = np.arange(half, n - half, step)
    if order == 4:
        d = x[i - 2] - 4.0 * x[i - 1] + 6.0 * x[i] - 4.0 * x[i + 1] + x[i + 2]
    else:
        d = x[i + 1] - 2.0 * x[i] + x[i - 1]
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(70.0 if order == 4 else 6.0))


def quad_fit(y: np.ndarray) -> tuple[np.ndarray, float]:
    """``(coefficients of 1, k, k^2, residual RMS)`` of a quadratic least-squares fit of ``y``
    against the sample index ``k``; its slope at sample ``at`` is ``c[1] + 2 c[2] at``."""
    n = len(y)
    k = np.arange(n, dtype=float)
    x = np.column_stack([np.ones(n), k, k * k])
    coef, res, *_ = np.linalg.lstsq(x, y, rcond=None)
    return coef, math.sqrt(float(res[0]) / n) if len(res) else 0.0


def quad_slope(y: np.ndarray, at: float = 0.0) -> tuple[float, float]:
    """``(slope at sample ``at``, residual RMS)`` of a quadratic least-squares fit of ``y``
    against the sample index (:func:`quad_fit`)."""
    coef, rms = quad_fit(y)
    return float(coef[1] + 2.0 * coef[2] * at), rms


def _hinge(f: np.ndarray, ic: int, n: int, lo: int, hi: int) -> int:
    """The break ``c`` in ``[ic - h, ic + h]`` (``h = HINGE_REACH n``) of the continuous broken
    line ``a + b k + d max(k - c, 0)`` that fits ``f`` best over one fixed window (from
    ``n // 2`` samples before the first candidate to ``n`` after the last: every candidate
    judged on the same samples; ``n`` at most :data:`HINGE_MAX`).  With ``r0`` the residual
    of a straight line and ``q_c`` that of the hinge column, the sum of squares falls by
    ``(q_c . r0)^2 / |q_c|^2``; candidates every ``h // 32`` samples, then around the best
    in steps an eighth as long, down to one sample (memory: ~33 candidates x the stretch)."""
    n = min(n, HINGE_MAX)  # the break is local: a longer stretch adds cost, not information
    h = max(1, int(HINGE_REACH * n))
    half = max(3, n // 2)
    w0, w1 = max(lo, ic - h - half), min(hi, ic + h + n)
    if w1 - w0 < 8:
        return ic
    y = f[w0:w1]
    k = np.arange(w1 - w0, dtype=float)
    x0 = np.column_stack([np.ones_like(k), k])
    pinv = np.linalg.pinv(x0)
    r0 = y - x0 @ (pinv @ y)

    def gain(cands: np.ndarray) -> np.ndarray:
        p = np.maximum(k[None, :] - (cands - w0)[:, None], 0.0)
        q = p - (p @ pinv.T) @ x0.T
        den = np.einsum("ij,ij->i", q, q)
        return np.where(den > 0, (q @ r0) ** 2 / np.where(den > 0, den, 1.0), -np.inf)

    first, last = max(w0 + 2, ic - h), min(w1 - 2, ic + h)
    if last < first:
        return ic
    step = max(1, h // 32)
    cands = np.arange(first, last + 1, step)
    best = int(cands[int(np.argmax(gain(cands)))])
    while step > 1:  # refine around the best, at most ~17 candidates a level
        fine_step = max(1, step // 8)
        cands = np.arange(max(first, best - step), min(last, best + step) + 1, fine_step)
        best = int(cands[int(np.argmax(gain(cands)))])
        step = fine_step
    return best


def _window(rel2: float, points: int, span: int) -> int:
    """Samples of the grown window: the fewest for a predicted relative error of :data:`TARGET`
    (``192 rel2 / n^3``), at least ``points``, at most half the contact's ``span``."""
    return int(min(max(points, math.ceil((192.0 * rel2 / TARGET**2) ** (1.0 / 3.0))), int(span * WINDOW_SPAN)))


def contact_slopes_thesis(z, f, contact, separation, points: int = 10) -> np.ndarray:
    """The thesis's stage 1b (eq. 86): ``-dF/dz_tip`` from a straight line over the ``points``
    samples after each contact minimum; nan for a contact shorter than that."""
    out = []
    for ic, isep in zip(contact, separation):
        a, b = int(ic) + 1, int(ic) + 1 + points
        out.append(np.nan if b > isep else -np.polyfit(z[a:b], f[a:b], 1)[0])
    return np.array(out, dtype=float)


def noise_aware_slopes(z: np.ndarray, f: np.ndarray, contact, separation, points: int = 10,
                       sigma_f: float | None = None, sigma_z: float | None = None) -> tuple[np.ndarray, dict]:  # fmt: skip
    """Initial contact slope ``-dF/dz_tip`` [N/m] of each tap (module docstring) and the
    bookkeeping ``{"window": [n per tap], "noise_force_n", "noise_position_m", "thesis":
    [True where the thesis's window was kept], "start": [first sample of each window], "at":
    [where the quadratic reads the slope, in samples from the start; None: the thesis's
    straight line]}``.  ``sigma_f``/``sigma_z``: the white noise
    of force and position (default: :func:`noise_floor` of the record)."""
    z = np.asarray(z, float)
    f = np.asarray(f, float)
    sf = white_equivalent(f) if sigma_f is None else float(sigma_f)
    sz = white_equivalent(z) if sigma_z is None else float(sigma_z)
    # a low-passed force (the reconstruction's cut-off fc below the Nyquist frequency) smears the
    # contact's kink over ~f_nyquist/fc samples: the slope is read from there on, never on the kink
    d = declared(f)
    offset = int(math.ceil(SMEAR_SKIP * d[2])) if d is not None and d[2] > 1.5 else 0
    thesis_fit = contact_slopes_thesis(z, f, contact, separation, points)
    # the thesis window's predicted relative error (straight line: 12 sigma^2/n^3) on each tap's
    # mean slopes from contact to peak (no steeper than the initial ones, and blind to the noise)
    rel2s = []
    for ic, isep in zip(contact, separation):
        ic, isep = int(ic), int(isep)
        pk = ic + int(np.argmax(f[ic:isep])) if isep > ic else ic
        bf = (f[pk] - f[ic]) / max(pk - ic, 1)
        bz = (z[pk] - z[ic]) / max(pk - ic, 1)
        ok = bf > 0 and bz != 0 and isep - ic >= 4 * points
        rel2s.append((sf / bf) ** 2 + (sz / bz) ** 2 if ok else math.nan)
    predicted = [math.sqrt(12.0 * r / points**3) for r in rel2s if math.isfinite(r)]
    if not offset and (not predicted or float(np.median(predicted)) <= KEEP):  # the noise allows the thesis's window
        info = {"window": [points] * len(thesis_fit), "noise_force_n": sf, "noise_position_m": sz,
                "thesis": [True] * len(thesis_fit), "thesis_predicted_sigma": predicted,
                "start": [int(c) + 1 for c in contact], "at": [None] * len(thesis_fit)}  # fmt: skip
        return thesis_fit, info
    out, windows, thesis, starts, ats, located, at_thesis = [], [], [], [], [], [], []
    thesis_at = 1.0 + 0.5 * (points - 1)  # the thesis's straight line over samples 1..points reads at its centre
    prev_sep = 0
    for ic, isep, rel2, kg0 in zip(contact, separation, rel2s, thesis_fit):
        ic, isep = int(ic), int(isep)
        span = isep - ic
        if not math.isfinite(rel2):
            out.append(kg0), windows.append(points), thesis.append(True), starts.append(ic + 1), ats.append(None)
            located.append(math.nan), at_thesis.append(math.nan)
            prev_sep = isep
            continue
        if span - offset < 2 * points:  # the contact is shorter than the smear: no slope to read
            out.append(np.nan), windows.append(0), thesis.append(False), starts.append(ic), ats.append(0.0)
            located.append(math.nan), at_thesis.append(math.nan)
            prev_sep = isep
            continue
        lo_n = max(points, SMEAR_WINDOW * offset)  # the window spans several smears: the low-pass's ripple averages out
        n, c = max(lo_n, _window(rel2, points, span - offset)), ic
        if offset:  # a low-passed force: the window is the smear's, whatever the noise (the low-pass has averaged
            n = min(lo_n, max(int((span - offset) * WINDOW_SPAN), points))  # it), so the reading does not move with it
        for _ in range(2 if offset else 4):  # contact and window together: the hinge on the current window, then the window
            c = _hinge(f, c, n, prev_sep, isep)  # for TARGET from the slopes read at that contact
            a = c + offset
            bf, _ = quad_slope(f[a : a + n])
            bz, _ = quad_slope(z[a : a + n])
            if bf == 0 or bz == 0:
                break
            rel2 = (sf / bf) ** 2 + (sz / bz) ** 2
            m = min(max(lo_n, _window(rel2, points, span - offset)), max(int((span - offset) * WINDOW_SPAN), points))
            if offset or m == n:
                break
            n = m
        a = c + offset
        # where the thesis's straight line reads the slope (its window's centre), or past the smear; and, on a force
        # at its whole band, the same fits read at the thesis's reading point (a low-passed force: the band term, read
        # on the whole-cycle fit's surface with the thesis's window at the whole band, holds the smear's reading)
        at = -float(offset) if offset else thesis_at
        read = _slopes_at(z, f, a, n, (at,) if offset else (at, ic + thesis_at - a))
        out.append(read[0]), windows.append(n), thesis.append(False), starts.append(int(a)), ats.append(at)
        located.append(_per_sample(z, f, a, n, at, lo=prev_sep, hi=isep))
        moved = read[1] - read[0] if len(read) > 1 else math.nan
        at_thesis.append(moved if math.isfinite(moved) else math.nan)
        prev_sep = isep
    info = {"window": windows, "noise_force_n": sf, "noise_position_m": sz, "thesis": thesis,
            "thesis_predicted_sigma": predicted, "start": starts, "at": ats,
            "per_sample_of_contact": located, "at_thesis_reading": at_thesis}  # fmt: skip
    return np.array(out, dtype=float), info


LOCATION_SAMPLES = 1.0  # the least distance (samples) the error bars allow between the grown window's reading and the thesis's


def _per_sample(z, f, a: int, n: int, at: float, lo: int, hi: int) -> float:
    """How the grown window's slope moves per sample the contact is located later [N/m]: half the
    difference of the slopes read with the window one sample later and one earlier (the same
    ``n`` and ``at``); nan at the tap's ends.  The broken line's break and the force minimum the
    thesis's window starts after are different readings of the contact (``at_thesis_reading``: the
    same fits' slope at the thesis's reading point, 5.5 samples after the minimum, less theirs): on
    noisy records of the same orbit the break sat 0-2 samples before the noise-free minimum on a
    55:1 surface at 0.5 ns (the slope 1.6 % low), 0 on the worked example at 1 ns, and 7-8 samples
    after it on a 10:1 surface that snaps to the tip (0.5 ns: the slope 1.1 % low; its force
    minimum is the snap).  A parabolic contact branch for the break moved it onto the stiff surface's
    kink but a sample late on the worked example: not kept.  The error bars carry the difference
    as a systematic term (:mod:`vetica_cli.extraction.methods.tapsigmas`)."""
    if a - 1 < lo or a + 1 + n > hi:
        return math.nan
    later, earlier = (_slopes_at(z, f, b, n, (at,))[0] for b in (a + 1, a - 1))
    return 0.5 * (later - earlier)


def _slopes_at(z, f, a: int, n: int, ats) -> list[float]:
    """``-dF/dz_tip`` read at each sample ``at`` of ``ats`` (from ``a``) from quadratic least-squares
    fits of ``f`` and ``z`` over the ``n`` samples from ``a``, each fitted once (:func:`quad_fit`:
    the numbers of :func:`quad_slope` at every ``at``); nan where z's slope is 0."""
    (cf, _), (cz, _) = quad_fit(f[a : a + n]), quad_fit(z[a : a + n])
    out = []
    for at in ats:
        bf, bz = float(cf[1] + 2.0 * cf[2] * at), float(cz[1] + 2.0 * cz[2] * at)
        out.append(-bf / bz if bz != 0 else math.nan)
    return out
