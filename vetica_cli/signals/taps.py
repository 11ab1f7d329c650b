"""Taps of a force record: contact and separation at the force minima (thesis 3.3.1,
4.3.1, fig. 32).

In the massless Zener SLS (thesis 3.2) the tip-sample force ``Fts`` is continuous at
contact and at separation and smallest there (``-Fa(a0)``, the adhesion), so the
force minima either side of each repulsive peak mark the tap's contact and
separation, and the first adhesion well of the approach gives ``Z1``, the
undeformed-surface reference (thesis eq. 84).  Used by VETICA, the whole-cycle
fit, the simulation's ``z1`` observable and the run figures.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .memo import ArrayMemo
from .slopes import contact_slopes_thesis, noise_aware_slopes, white_noise_floor


@dataclass
class Taps:
    """Sample indices of the complete taps of a record (one row per tap)."""

    contact: np.ndarray  # force minimum at contact
    separation: np.ndarray  # force minimum at separation
    peak: np.ndarray  # largest repulsive force
    spacing: float  # median number of samples between peaks
    incomplete: int = 0  # taps cut by the record's ends (dropped)


_TAPS = ArrayMemo(1)  # the last record's taps


def find_taps(f: np.ndarray) -> Taps:
    """The taps of ``f`` (:func:`locate_taps`); the last call's answer is reused when the
    same array comes back unchanged (:class:`~vetica_cli.signals.memo.ArrayMemo`), as a copy
    the caller may change."""
    t = _TAPS(locate_taps, f)
    return Taps(t.contact.copy(), t.separation.copy(), t.peak.copy(), t.spacing, t.incomplete)


_CYCLES = ArrayMemo(2)  # the last records' cycles (the record's check and the tap methods' checks ask)


def oscillation_cycles(z: np.ndarray) -> int:
    """Whole oscillation cycles of the tip in ``z`` (the drive's periods as the record shows
    them, from the position alone): upward crossings of the middle of its range, with a
    hysteresis of a quarter of the range either side, so detector noise far below the
    amplitude cannot add a crossing.  The answer for one of the last two arrays is reused while
    it comes back unchanged (:class:`~vetica_cli.signals.memo.ArrayMemo`)."""
    return _CYCLES(_oscillation_cycles, z)


def _oscillation_cycles(z: np.ndarray) -> int:
    z = np.asarray(z, dtype=float)
    if len(z) < 3:
        return 0
    lo, hi = float(np.min(z)), float(np.max(z))
    mid, band = 0.5 * (lo + hi), 0.25 * (hi - lo)
    above, below = z > mid + band, z < mid - band
    side = above[above | below]  # outside the band, in order: True above, False below
    return int(np.count_nonzero(side[1:] & ~side[:-1]))


def locate_taps(f: np.ndarray) -> Taps:
    """Locate every tap's contact and separation force minimum (thesis 4.3.1, fig. 32).

    A tap is a run of samples above half the peak repulsive force (runs
    split by ringing inside one contact are merged); its contact minimum is the smallest force in the half tap-spacing
    before its peak, its separation minimum the smallest in the half spacing
    after.  Taps whose search range is cut by the record's ends are dropped.
    Raises InputError when the force has no repulsive peak or fewer than two taps.
    """
    f = np.asarray(f, dtype=float)
    peaks = [a + int(np.argmax(f[a:b])) for a, b in _contact_runs(f)]
    if len(peaks) < 2:
        raise InputError(f"too few taps: found {len(peaks)} contact(s) in the record, need at least 2")
    spacing = float(np.median(np.diff(peaks)))
    half = int(0.5 * spacing)
    n = len(f)
    contact, separation, peak = [], [], []
    incomplete = 0
    for p in peaks:
        lo, hi = p - half, p + half
        if lo < 0 or hi >= n:
            incomplete += 1
            continue
        ic = lo + int(np.argmin(f[lo : p + 1]))
        isep = p + int(np.argmin(f[p : hi + 1]))
        if ic == lo or isep == hi:  # minimum at the search edge: not a clean tap
            incomplete += 1
            continue
        contact.append(ic)
        separation.append(isep)
        peak.append(p)
    return Taps(np.array(contact, int), np.array(separation, int), np.array(peak, int), spacing, incomplete)


def _contact_runs(f: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) of each run of samples above half the peak repulsive force, runs split
    by paddle ringing inside one contact merged (gaps much shorter than the longest one)."""
    n = len(f)
    above = _repulsive(f, "the record")
    edges = np.flatnonzero(np.diff(above.astype(np.int8)))
    starts = list(edges[~above[edges]] + 1)
    ends = list(edges[above[edges]] + 1)
    if above[0]:
        starts.insert(0, 0)
    if above[-1]:
        ends.append(n)
    runs = list(zip(starts, ends))
    if len(runs) >= 2:
        gaps = np.array([a - b for (_, b), (a, _) in itertools.pairwise(runs)])
        merged = [runs[0]]
        for (a, b), gap in zip(runs[1:], gaps):
            if gap < 0.25 * gaps.max():
                merged[-1] = (merged[-1][0], b)
            else:
                merged.append((a, b))
        runs = merged
    return runs


def _repulsive(f: np.ndarray, where: str) -> np.ndarray:
    """Samples above half the peak repulsive force; InputError if there is no
    repulsive peak of at least a tenth of the deepest attraction."""
    fmax, fmin = float(np.max(f)), float(np.min(f))
    if not (fmax > 0 and fmax > 0.1 * max(-fmin, 0.0)):
        raise InputError(f"no contact found in {where}: the force has no repulsive peak")
    return f > 0.5 * fmax


def first_contact_minimum(f: np.ndarray, noise: float = 0.0, z: np.ndarray | None = None) -> int:
    """Index of the force minimum at the first contact of an approach record.

    Z1 is the tip position at the very first adhesion well (thesis 3.3.1,
    eq. 84).  Before the first sample above half the peak repulsive force,
    the first run of samples within 10 % of the deepest attraction is the first
    well (a first contact can be a graze that never turns repulsive, and then
    the next tap's well is as deep); its smallest sample is the minimum.
    ``noise``: the force's noise RMS [N]; a tap counts only where the force stands more than
    :data:`SNR_CONTACT` noise RMS above zero (and above half the peak).
    ``z``: the tip position at each sample; with it, a well read on the way out of a contact (the
    pull-off) is moved to that contact's approach-side well (:func:`approach_side_well`), where
    every steady tap's contact is read.
    Raises InputError when no contact is found, or none stands above the noise.
    """
    f = np.asarray(f, dtype=float)
    fmax = float(np.max(f)) if len(f) else 0.0
    if noise > 0 and not fmax > SNR_CONTACT * noise:
        raise InputError(f"no contact of the approach stands above its force noise ({fmax:.3g} N peak, "
                         f"{noise:.3g} N RMS noise): cannot measure Z1")  # fmt: skip
    above = _repulsive(f, "the approach segment") & (f > SNR_CONTACT * noise)
    first = int(np.argmax(above))
    if first == 0:
        raise InputError("the approach segment starts in contact: cannot measure Z1")
    before = f[:first]
    deep = before <= before.min() + 0.10 * abs(before.min())
    start = int(np.argmax(deep))
    stop = start + (int(np.argmin(deep[start:])) if not deep[start:].all() else len(deep) - start)
    i = start + int(np.argmin(before[start:stop]))
    return i if z is None else approach_side_well(np.asarray(z, dtype=float), f, i)


APPROACH_SIDE_DEPTH = 0.25  # the approach-side well replaces a pull-off well at least this fraction as deep


def approach_side_well(z: np.ndarray, f: np.ndarray, i: int) -> int:
    """The approach-side force minimum of the contact whose well ``i`` is, read on the tip position
    ``z``: ``i`` itself unless the tip went down into the surface before it (a bottom of ``z`` lower
    than ``z[i]`` by more than three times its noise floor, with no free flight between), i.e. ``i``
    is the pull-off well of a contact; then the force minimum on the way down, among the samples
    within one such depth of ``z[i]`` above it, where it is at least :data:`APPROACH_SIDE_DEPTH`
    of ``f[i]``.

    Why: Z1 is the surface's zero before any tap (thesis 3.3, fig. 25), read as every steady
    contact is (the force minimum before each repulsive peak, :func:`locate_taps`).  On a surface
    under the tip's pull the first contact's snap-in well is shallower than its pull-off well,
    which the surface follows up while the adhesion holds it; when the snap-in well missed
    :func:`first_contact_minimum`'s 10 % of the deepest, the pull-off well was read instead.  On
    soft pulled surfaces (k_inf 1.5-2.6, k0 12-42 N/m, noise-free, the record's band) that put Z1
    26-295 pm above the snap-in, and at 300 K, where the snap-in's depth scatters about that
    threshold, a material's replicas read either well (two groups 18 pm apart, std 9 pm, where
    each group's scatter was 2-4 pm).  Reading the approach side on both, the replicas' Z1 fell
    within 1.7-5.1 pm (std) of the noise-free record's at the same band (dev draw 33, six surfaces,
    7-10 replicas each)."""
    tol = 3.0 * white_noise_floor(z) if len(z) > 8 else 0.0
    out = np.flatnonzero(z[:i] >= z[i] + 2.0 * tol)  # where the tip was last above the well, on its way down
    if len(out) == 0:
        return i
    ks = int(out[-1])
    kb = ks + int(np.argmin(z[ks : i + 1]))  # the bottom of the tip's path between
    if not z[kb] < z[i] - tol:  # no contact before the well: it is on the way down already (or a graze)
        return i
    up = np.flatnonzero(z[:kb] >= z[i] + (z[i] - z[kb]))
    kx = int(up[-1]) if len(up) else 0
    j = kx + int(np.argmin(f[kx : kb + 1]))
    return j if f[j] <= APPROACH_SIDE_DEPTH * f[i] else i


SNR_CONTACT = 5.0  # a first contact counts where its force stands this many noise RMS above zero
KG_WINDOWS = ("noise", "thesis")  # stage 1b's window: chosen from the record's noise, or the thesis's


def contact_slopes(z: np.ndarray, f: np.ndarray, taps: Taps, points: int = 10, window: str = "noise",
                   details: bool = False):  # fmt: skip
    """Initial contact slope of each tap, ``-dF/dz_tip`` [N/m] (thesis 4.3.2, eq. 86: VETICA's
    stage 1b, the glassy stiffness Kg).  ``window='thesis'``: a straight-line fit of the
    force against the tip position over the ``points`` samples after the contact minimum;
    ``'noise'`` (default): the same wherever the record's noise allows it, a window grown
    from the noise otherwise (:mod:`vetica_cli.signals.slopes`).  nan for a tap whose
    contact is shorter than ``points`` samples.  ``details``: ``(slopes, the windows' bookkeeping
    or None for the thesis's)``."""
    if window == "noise":
        slopes, info = noise_aware_slopes(z, f, taps.contact, taps.separation, points)
        return (slopes, info) if details else slopes
    slopes = contact_slopes_thesis(z, f, taps.contact, taps.separation, points)
    return (slopes, None) if details else slopes
