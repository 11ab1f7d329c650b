"""One record ready for any extraction method: the input checks every method shares.

Input: a table with at least ``t`` [s], ``z_tip`` [m] and ``f_ts`` [N] (the
true force) or ``z_paddle`` [m] (from which the force is reconstructed by
spectral inversion), optionally a ``segment`` column ('approach' =
the window around the first contact, 'steady' = the taps to analyse), and the
``vetica`` metadata dict written by ``vetica simulate`` ({} for measured
data: then the probe's ``k2, f2, q2`` and ``Z1`` come as keyword arguments).

A record as an instrument gives it -- ``t``, ``z_tip`` and ``f_ts`` (or
``z_paddle`` with the paddle's constants), any whole number of drive periods,
starting anywhere in a tap, no segment column, no metadata -- is analysed as it
is: every row is the steady record, taps cut by its ends are dropped, and
``Z1`` (the undeformed-surface reference of thesis eq. 84) comes from, in this
order: the ``z1`` keyword; the first force minimum of an 'approach' segment; the
metadata's ``z1`` observable; else thesis eq. 84 on the record (:func:`z1_estimate`):
``Z1 = a0`` with ``z_tip`` measured from the undeformed surface and the surface not
feeling the pull (the thesis's assumption), or ``Z1 = a0 + |Fc|/Kg`` when it does
(the surface jumps up by the adhesion over its glassy stiffness as contact starts),
with ``a0`` and the pull from the keywords or the metadata -- never a silent
default (an InputError says what to pass).  The choice is recorded in
``info['z1_source']`` and printed by the formatter.

:func:`build_record` checks the columns, picks the segments, builds the force
(true or reconstructed), finds ``Z1`` and the surface's theory values, and
raises :class:`~vetica_cli.errors.InputError` (one line) for whatever is missing.
"""

from __future__ import annotations

import math
import time
from dataclasses import astuple, dataclass, field, fields, replace
from typing import TYPE_CHECKING

import numpy as np

from .. import surfaces
from ..checks import check, coerce
from ..errors import ConfigError, InputError
from ..ranges import check_range, range_of
from ..signals.spectral import reconstruct_force, reconstruction_error
from ..signals.tapforce import TapForce, approach_force, reconstruct_taps
from ..signals.taps import Taps, contact_slopes, find_taps, first_contact_minimum, oscillation_cycles

if TYPE_CHECKING:
    import pandas as pd

SOURCES = ("true", "reconstructed")  # force sources: the f_ts column, or rebuilt from the paddle signal
FORCES = ("auto", *SOURCES)  # auto = reconstructed when z_paddle is present


@dataclass
class Record:
    """The steady record of one run (or measurement) and what is known about it."""

    t: np.ndarray  # [s] steady record
    z: np.ndarray  # [m] tip position
    f: np.ndarray  # [N] force analysed (true or reconstructed)
    force: str  # 'true' | 'reconstructed'
    z1: float | None  # [m] tip position at the first force minimum of the approach (thesis eq. 84); None = unknown
    approach: tuple | None  # (z_tip, force, index of Z1) of the approach segment when it was analysed
    model: surfaces.SurfaceModel  # the surface the metadata describes (default: the SLS)
    truth: dict | None  # theory values of the model's quantities, when the metadata holds its parameters
    params: dict = field(default_factory=dict)  # resolved parameters of the metadata ({} for measured data)
    info: dict = field(default_factory=dict)  # cutoff_hz, reconstruction_error, cutoff_harmonic, z1, z1_source, periods
    meta_warnings: list = field(default_factory=list)  # warnings the simulation recorded, then the record's own
    a0: float | None = None  # [m] intermolecular distance: the keyword, else the metadata, else unknown
    vdw_on_surface: bool | None = None  # does the surface feel the pull: the keyword, else the metadata, else unknown
    observables: dict = field(default_factory=dict)  # the simulator's own per-run observables (metadata; {} if measured)
    energy: dict = field(default_factory=dict)  # the simulator's energy balance per cycle [eV] (metadata; {} if measured)
    t_start: float = 0.0  # perf_counter when the record was started
    t_force: float = 0.0  # perf_counter when the force was ready
    taps: Taps | None = None  # the steady record's taps when the force was built around them (tap windows)
    memo: dict = field(default_factory=dict, repr=False)  # results computed on this record, shared by the checks

    @property
    def probe(self) -> dict:
        return self.params.get("probe") or {}

    @property
    def surface(self) -> dict:
        return self.params.get("surface") or {}

    @property
    def reconstruction_s(self) -> float:
        """Wall seconds spent reconstructing the force (0 for the true force)."""
        return (self.t_force - self.t_start) if self.force == "reconstructed" else 0.0


def _fast_approach(approach: pd.DataFrame | None) -> pd.DataFrame | None:
    """The approach segment without its first few samples (at most 3 %, where the tip is farthest
    from the surface) when that makes its length one the FFT is fast on
    (:func:`~vetica_cli.signals.spectral.fast_length`): its force is transformed several times
    over (reconstruction, the band term's low-passes), and an awkward length cost 20x a nearby one."""
    from ..signals.spectral import fast_length

    if approach is None:
        return None
    m = fast_length(len(approach))
    return approach if m == len(approach) else approach.iloc[len(approach) - m :]


def segment(df: pd.DataFrame, name: str) -> pd.DataFrame | None:
    """Rows of one segment, or None if the table has no such rows.  A categorical column
    is compared by its codes, not through a string copy of the whole column."""
    if "segment" not in df.columns:
        return None
    seg = df["segment"]
    if hasattr(seg, "cat"):
        if name not in seg.cat.categories:
            return None
        mask = seg.cat.codes.to_numpy() == seg.cat.categories.get_loc(name)  # integer codes, no string compare
    else:
        mask = (seg == name).to_numpy()
    first = int(np.argmax(mask))
    if not mask[first]:
        return None
    last = len(mask) - 1 - int(np.argmax(mask[::-1]))
    if np.count_nonzero(mask) == last - first + 1:  # one contiguous block (a run table): a view, no copy
        return df.iloc[first : last + 1]
    return df[mask]


def column(df: pd.DataFrame, name: str, where: str) -> np.ndarray:
    """A column as floats; InputError for missing or non-finite values."""
    try:
        a = df[name].to_numpy(dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"column {name!r} holds values that are not numbers in {where}") from None
    if not np.all(np.isfinite(a)):
        raise InputError(f"column {name!r} has missing or non-finite values in {where}")
    return a


def check_time(t: np.ndarray, where: str) -> None:
    if len(t) < 2 or not np.all(np.diff(t) > 0):
        raise InputError(f"time column 't' is not strictly increasing in {where}")


# Plausible ranges of a tapping record in SI units: anything beyond is a record in other units
# (nm, nN, us) or not a tapping record, refused with one line before any work
MAX_TIME_STEP = 1e-4  # [s] a record sampled more coarsely (< 10 kHz) cannot resolve a tap (us at 50 kHz)
MAX_POSITION = 1e-3  # [m] |z_tip|: tapping amplitudes and heights are nm to um
MAX_FORCE = 1e-3  # [N] |f_ts|: tap forces are pN to uN
JITTER = 1e-3  # relative deviation of a time step from the mean above which a record is not uniform


def check_record(t: np.ndarray, z: np.ndarray, f: np.ndarray | None, meta: dict, where: str) -> None:
    """InputError (one line) for a record that is not what an instrument in SI units records:
    negative times, a time step over :data:`MAX_TIME_STEP`, a non-uniform time step (more than
    :data:`JITTER` off the mean) unless the metadata declares ``time_sampling: nonuniform``,
    positions beyond :data:`MAX_POSITION` or forces beyond :data:`MAX_FORCE` (lengths in nm,
    forces in nN), a tip that oscillates (:func:`~vetica_cli.signals.taps.oscillation_cycles`)
    at a frequency no cantilever has or more than a factor 2 off the drive frequency ``f1``
    the metadata states (its probe section, or the key ``f1``): a time in ms or us."""
    h = (t[-1] - t[0]) / (len(t) - 1)
    if t[0] < 0:
        raise InputError(f"time column 't' starts at {t[0]:.4g} s in {where}; expected times >= 0 s")
    if h > MAX_TIME_STEP:
        raise InputError(f"time column 't' steps {h:.4g} s in {where}; expected seconds with a step <= "
                         f"{MAX_TIME_STEP:g} s (a tapping record samples at ns to us: is t in another unit?)")  # fmt: skip
    if meta.get("time_sampling") != "nonuniform" and np.max(np.abs(np.diff(t) - h)) > JITTER * h:
        raise InputError(f"time column 't' is not uniformly sampled in {where} (steps vary by more than {JITTER:g} of "
                         "the mean); expected a constant step, or metadata time_sampling: nonuniform")  # fmt: skip
    cycles = oscillation_cycles(z)
    if cycles >= 3:  # the drive frequency the record shows: a cantilever's, and the stated one when there is one
        f_rec = cycles / (t[-1] - t[0])
        fr = range_of("flexural_frequency")
        if not fr.ok(f_rec):
            raise InputError(f"time column 't' makes the tip oscillate at {f_rec:.4g} Hz ({cycles} cycles in "
                             f"{t[-1] - t[0]:.4g} s) in {where}; expected a drive frequency in [{fr.lo:g}, {fr.hi:g}] Hz "
                             "(cantilever resonances): is t in seconds?")  # fmt: skip
        f1 = meta.get("f1") or ((meta.get("params") or {}).get("probe") or {}).get("f1")
        if f1 and not 0.5 <= f_rec / f1 <= 2.0:
            raise InputError(f"time column 't' makes the tip oscillate at {f_rec:.4g} Hz in {where}, {f_rec / f1:.3g} "
                             f"times the drive frequency f1 {f1:g} Hz; expected within a factor 2 of it: is t in "
                             "seconds, or f1 the probe's?")  # fmt: skip
    zmax = float(np.max(np.abs(z)))
    if zmax > MAX_POSITION:
        raise InputError(f"column 'z_tip' reaches {zmax:.4g} m in {where}; expected metres, |z_tip| <= "
                         f"{MAX_POSITION:g} m (tapping records span nm to um: is it in nm?)")  # fmt: skip
    if f is not None and len(f):
        fmax = float(np.max(np.abs(f)))
        if fmax > MAX_FORCE:
            raise InputError(f"column 'f_ts' reaches {fmax:.4g} N in {where}; expected newtons, |f_ts| <= "
                             f"{MAX_FORCE:g} N (tap forces are pN to uN: is it in nN?)")  # fmt: skip


def resolve_force(df: pd.DataFrame, force: str) -> str:
    """Check the columns an extraction needs and resolve ``force='auto'`` (reconstructed
    when ``z_paddle`` is present); InputError names what is missing."""
    if force not in FORCES:
        raise InputError(f"force {force!r} not allowed; choose one of: {', '.join(FORCES)}")
    cols = set(df.columns)
    missing = [c for c in ("t", "z_tip") if c not in cols]
    if missing or not ({"f_ts", "z_paddle"} & cols):
        need = missing + ([] if {"f_ts", "z_paddle"} & cols else ["f_ts or z_paddle"])
        raise InputError(f"missing column(s): {', '.join(need)} (need t, z_tip and f_ts or z_paddle)")
    if force == "auto":
        force = "reconstructed" if "z_paddle" in cols else "true"
    fcol = "f_ts" if force == "true" else "z_paddle"
    if fcol not in cols:
        raise InputError(f"--force {force} needs the column {fcol!r}, which the table does not have")
    return force


@dataclass
class _ForceSource:
    """The force of a segment: the ``f_ts`` column ('true'), or the spectral inversion of
    ``z_paddle`` ('reconstructed', thesis eqs. 17-20) with the probe's ``k2, f2, q2`` from
    the keywords or else the metadata's probe section."""

    force: str
    probe: dict
    info: dict
    k2: float | None = None
    f2: float | None = None
    q2: float | None = None
    cutoff_hz: float | None = None
    taper: float = 0.0

    windows: bool = False  # rebuild the force only in the tap windows (signals.tapforce)
    noise: object = None  # the noise measured on the steady record (signals.noise.CutoffChoice)

    drive_hz: float | None = None  # [Hz] the drive frequency whose harmonics the automatic cut-off reads

    def __call__(self, seg: pd.DataFrame, where: str) -> np.ndarray:
        if self.force == "true":
            return column(seg, "f_ts", where)
        p = self._probe()
        cutoff = "auto" if self.cutoff_hz is None else self.cutoff_hz
        rec = reconstruct_force(seg["t"].to_numpy(float), column(seg, "z_paddle", where), p["k2"], p["f2"],
                                p["q2"], cutoff_hz=cutoff, taper=self.taper, drive_hz=self.drive_hz)  # fmt: skip
        if rec.noise is not None:  # the steady record's choice: the approach segment is rebuilt with the same low-pass
            self.cutoff_hz = rec.cutoff_hz if rec.cutoff_hz < rec.noise.spectrum.nyquist else math.inf
            self.info["cutoff_rule"] = rec.noise.rule
            self.noise = rec.noise
        elif cutoff == "auto":
            self.cutoff_hz = math.inf
            self.info["cutoff_rule"] = "no drive harmonics to read the noise between (fewer than 2 periods): Nyquist"
        self.info["cutoff_hz"] = rec.cutoff_hz
        return rec.f

    def tap_force(self, seg: pd.DataFrame, where: str) -> TapForce | None:
        """The reconstructed force of a steady record in its tap windows (:mod:`~vetica_cli.signals.tapforce`);
        None when the windows cannot stand in for the whole record's inversion."""
        p = self._probe()
        tf = reconstruct_taps(seg["t"].to_numpy(float), column(seg, "z_paddle", where), p["k2"], p["f2"], p["q2"],
                              cutoff_hz=self.cutoff_hz, taper=self.taper)  # fmt: skip
        if tf is None:  # and the approach segment is rebuilt whole too
            self.windows = False
            return None
        self.info["cutoff_hz"] = tf.cutoff_hz
        self.info["force_windows"] = len(tf.windows)
        return tf

    def approach(self, seg: pd.DataFrame, where: str) -> tuple[np.ndarray, int]:
        """The approach segment's force and its first contact minimum (thesis eq. 84)."""
        z = column(seg, "z_tip", where)  # the contact's approach side is read on the tip position
        if self.force == "reconstructed" and self.windows:
            p = self._probe()
            out = approach_force(seg["t"].to_numpy(float), column(seg, "z_paddle", where), p["k2"], p["f2"],
                                 p["q2"], cutoff_hz=self.cutoff_hz, taper=self.taper, z=z)  # fmt: skip
            if out is not None:
                return out
        f = self(seg, where)
        return f, first_contact_minimum(f, self.noise.noise_rms if self.noise is not None else 0.0, z=z)

    def _probe(self) -> dict:
        p = {
            k: v if v is not None else self.probe.get(k) for k, v in (("k2", self.k2), ("f2", self.f2), ("q2", self.q2))
        }
        absent = [k for k, v in p.items() if v is None]
        if absent:
            raise InputError(
                f"the force reconstruction needs the probe's {', '.join(absent)} (not in the file's metadata): "
                f"pass {' '.join('--' + k for k in absent)}, or use --force true"
            )
        return p


def _steady_segment(df: pd.DataFrame) -> pd.DataFrame:
    """The 'steady' segment; for measured data every row not labelled 'approach'."""
    steady = segment(df, "steady")
    if steady is None:
        steady = df if "segment" not in df.columns else df[(df["segment"] != "approach").to_numpy()]
        if not len(steady):
            raise InputError("the table has no rows outside the 'approach' segment to analyse")
    return steady


def _steady_force(steady, force_of: _ForceSource, f1: float | None) -> tuple[np.ndarray, Taps | None]:
    """The force of the steady record and its taps when they were located on the way (tap
    windows); for a reconstructed force also its error against ``f_ts`` (when present; over
    the tap windows when only they were rebuilt) and the cut-off in drive harmonics, in
    ``force_of.info``."""
    info = force_of.info
    taps = None
    # the tap windows need the low-pass known first: with the automatic cut-off the whole record is inverted
    windows = force_of.force == "reconstructed" and force_of.windows and force_of.cutoff_hz is not None
    tf = force_of.tap_force(steady, "the steady record") if windows else None
    if tf is not None:
        f, taps = tf.f, tf.taps
        if "f_ts" in steady.columns and tf.windows:
            idx = np.concatenate([np.arange(a, b) for a, b in tf.windows])
            info["reconstruction_error"] = reconstruction_error(f[idx], steady["f_ts"].to_numpy(float)[idx])
    else:
        f = force_of(steady, "the steady record")
    if force_of.force == "reconstructed" and "f_ts" in steady.columns and taps is None:
        info["reconstruction_error"] = reconstruction_error(f, column(steady, "f_ts", "the steady record"))
    drive = f1 if f1 is not None else force_of.probe.get("f1")
    if "cutoff_hz" in info and drive:
        info["cutoff_harmonic"] = info["cutoff_hz"] / drive
    return f, taps


def _drive(f1: float | None, params: dict, t: np.ndarray, z: np.ndarray, info: dict) -> float | None:
    """The drive frequency [Hz] whose harmonics the noise is read between: ``--f1``, else the
    metadata's probe f1 (the drive is at the flexural resonance), else measured on the tip
    position (:func:`vetica_cli.signals.noise.drive_frequency`)."""
    from ..signals.noise import drive_frequency

    if f1 is not None:
        return float(f1)
    meta_f1 = (params.get("probe") or {}).get("f1")
    if meta_f1:
        return float(meta_f1)
    h = (t[-1] - t[0]) / (len(t) - 1)
    drive = drive_frequency(z, h)
    if drive is not None:
        info["drive_hz_measured"] = drive
    return drive


def _declare_noise(f: np.ndarray, t: np.ndarray, force_of: _ForceSource, info: dict) -> None:
    """Measure the analysed force's noise floor on the record (:mod:`vetica_cli.signals.noise`:
    the bins between the drive's harmonics, up to the force's low-pass) and attach it to the
    array, so every stage and check reads the record's measured noise; in ``info['noise']``."""
    from ..signals import noise as nz

    choice = force_of.noise
    if choice is None and force_of.drive_hz:
        h = (t[-1] - t[0]) / (len(t) - 1)
        fc = info.get("cutoff_hz")
        choice = nz.measure(f, h, force_of.drive_hz, cutoff_hz=fc if fc else None)
        if choice is not None and fc is None:  # the true force: no low-pass, the noise over the whole band
            choice = nz.measure(f, h, force_of.drive_hz, cutoff_hz=0.5 / h)
    if choice is None:
        return
    nz.declare(f, choice.noise_rms, choice.white_equivalent, choice.spectrum.nyquist / choice.cutoff_hz)
    info["noise"] = {"force_rms_n": choice.noise_rms, "force_white_equivalent_n": choice.white_equivalent,
                     "cutoff_hz": choice.cutoff_hz, "drive_hz": choice.spectrum.drive_hz,
                     "periods": choice.spectrum.periods}  # fmt: skip


def z1_estimate(z: np.ndarray, f: np.ndarray, a0: float, pull: bool, kg_points: int = 10) -> tuple[float, str]:
    """Z1 from a steady record alone, with ``z_tip`` measured from the undeformed surface
    (thesis eq. 84) [m], and the text saying how.

    Without the surface pull the tip meets the undeformed surface at ``Z1 = a0``
    (eq. 84, the thesis's assumption).  When the surface feels the pull it is lifted
    by the adhesion ``Fa(a0)`` as contact starts, against its glassy (instantaneous)
    stiffness: ``Z1 = a0 + Fa(a0)/Kg``, with ``Fa(a0) = -Fc`` the force at the contact
    minima of the record and ``Kg`` their initial contact slope (stage 1b, eq. 86,
    ``kg_points`` samples), medians over the taps.  A surface soft enough to snap to the tip
    (the pull's gain ``2 Fa(d)/(d Kg)`` reaching 1 at a gap ``d* > a0``) is stretched to the tip
    at contact, ``-Fc = Kg (Z1 - a0)``: the same formula holds with the measured ``-Fc``
    (which is then not ``Fa(a0)``).  The creep of the surface during a
    slow first approach (which a recorded approach includes) is not in this estimate.
    """
    if not pull:
        return float(a0), f"thesis eq. 84: Z1 = a0 = {a0 * 1e9:.4g} nm (surface not pulled)"
    taps = find_taps(f)
    if len(taps.contact) == 0:
        raise InputError("Z1 unknown: no complete tap in the record to measure the adhesion and Kg; pass --z1")
    fa = -float(np.median(f[taps.contact]))
    slopes = contact_slopes(z, f, taps, kg_points)
    kg = float(np.nanmedian(slopes)) if np.any(np.isfinite(slopes)) else math.nan
    if not (fa > 0 and math.isfinite(kg) and kg > 0):
        raise InputError(
            f"Z1 unknown: the record shows no adhesion at contact ({-fa:.3g} N) or no positive initial contact "
            f"slope ({kg:.3g} N/m) for Z1 = a0 + Fa(a0)/Kg; pass --z1"
        )
    z1 = a0 + fa / kg
    return z1, (f"thesis eq. 84 with the surface pull: Z1 = a0 + Fa(a0)/Kg = {a0 * 1e9:.4g} nm + "
                f"{fa * 1e9:.4g} nN / {kg:.4g} N/m")  # fmt: skip


def _known(value, meta_value, name: str, info: dict):
    """A constant from the keyword, else the metadata, else None; its source in ``info``."""
    if value is not None:
        info[f"{name}_source"] = "given"
        return value
    if meta_value is not None:
        info[f"{name}_source"] = "metadata"
        return meta_value
    return None


def _z1_reference(approach, z1, meta, force_of: _ForceSource, need_approach: bool, steady, a0, pull,
                  need_z1: bool = True):  # fmt: skip
    """Z1, the undeformed-surface reference (thesis eq. 84): ``z1`` if given, else the tip
    position at the first force minimum of the approach segment, else the metadata's
    observable, else :func:`z1_estimate` on the steady record ``steady = (z, f)`` when
    ``a0`` and the pull are known.  Returns ``(z1, approach_record)`` with
    ``approach_record = (z_tip, force, index of Z1)`` when the approach segment was
    analysed (always with ``need_approach``, else only when Z1 comes from it); without
    ``need_z1`` a record with no way to Z1 gets None.  Records the value and its source in
    the info."""
    rec = None
    unresolved = None  # why the approach's first contact could not be read (noise), if so
    if approach is not None and (z1 is None or need_approach):
        ta = column(approach, "t", "the approach segment")
        check_time(ta, "the approach segment")
        try:
            fa, i1 = force_of.approach(approach, "the approach segment")
            rec = (column(approach, "z_tip", "the approach segment"), fa, i1)
        except InputError as exc:
            if force_of.noise is None or "noise" not in str(exc) and "starts in contact" not in str(exc):
                raise
            unresolved = str(exc)  # a noisy approach: Z1 as if there were none (eq. 84), said in the source
    if z1 is not None:
        value, source = float(z1), "given"
    elif rec is not None:
        value, source = float(rec[0][rec[2]]), "approach segment"
    elif unresolved is not None and a0 is not None and pull is not None:
        value, source = z1_estimate(steady[0], steady[1], a0, bool(pull))
        force_of.info["z1_approach_unresolved"] = unresolved
    elif unresolved is not None:
        if need_z1:
            raise InputError(f"{unresolved}; pass --z1, or --a0 with --vdw-on-surface/--no-vdw-on-surface "
                             "(thesis eq. 84)")  # fmt: skip
        value, source = None, "unknown: the approach's first contact is not resolved above the noise"
    elif (meta.get("observables") or {}).get("z1") is not None:
        value, source = float(meta["observables"]["z1"]), "metadata"
    elif a0 is not None and pull is not None:
        try:
            value, source = z1_estimate(steady[0], steady[1], a0, bool(pull))
        except InputError:
            if need_z1:
                raise
            value, source = None, "unknown: no tap in the record to estimate it from"  # e.g. a free cantilever
    elif not need_z1:  # the method works without it (e.g. the whole-cycle fit fits the surface height)
        value, source = None, "unknown: no approach segment, no metadata"
    elif a0 is not None:
        raise InputError(
            "Z1 unknown: the table has no 'approach' segment and no metadata, and Z1 = a0 (thesis eq. 84) needs to know "
            "whether the surface feels the tip's pull: pass --vdw-on-surface or --no-vdw-on-surface, or --z1"
        )
    else:
        raise InputError(
            "Z1 unknown: the table has no 'approach' segment and no metadata; pass --z1 (tip position at the first "
            "approach force minimum), or --a0 when z_tip is measured from the undeformed surface (thesis eq. 84)"
        )
    force_of.info["z1"] = value
    force_of.info["z1_source"] = source
    return value, rec


def drive_periods(f: np.ndarray) -> float | None:
    """Drive periods the record spans [periods]: its length over the median tap spacing
    (one tap per period in tapping mode); None when the force shows fewer than two taps."""
    try:
        taps = find_taps(f)
    except InputError:
        return None
    return len(f) / taps.spacing if taps.spacing > 0 else None


NAMED_KEYS = ("steady", "integrator", "instrument")  # numerics keys whose values are names


def check_params(params: dict) -> None:
    """InputError (one line) for a metadata ``params`` a method cannot use: a probe, operation or
    numerics value that is not a number (a name where the key takes one), or a surface key its
    model refuses (each model's own parser and ranges).  Unknown keys pass (other versions)."""
    for sec in ("probe", "operation", "numerics"):
        for key, value in (params.get(sec) or {}).items():
            named = sec == "numerics" and key in NAMED_KEYS
            if value is not None and not named and (isinstance(value, str) or not isinstance(value, (int, float))):
                raise InputError(f"the file's metadata: params.{sec}.{key} is {value!r}; expected a number")
    surface = params.get("surface") or {}
    try:
        model = surfaces.get(surface.get("model", surfaces.DEFAULT_MODEL))
        for key, value in surface.items():
            if key in model.config_keys:
                model.parse_key(key, value)
            elif key in surfaces.COMMON_KEYS:
                spec = surfaces.COMMON_KEYS[key]
                check(f"surface.{key}", value, coerce(f"surface.{key}", value, spec.type), spec.rule)
    except ConfigError as exc:
        raise InputError(f"the file's metadata: {exc}") from None


def surface_of(params: dict) -> tuple[surfaces.SurfaceModel, dict | None]:
    """The surface model of a run's resolved parameters (the default for measured data) and
    its theory values, or None when the parameters do not hold every key of the model."""
    surface = params.get("surface") or {}
    try:
        model = surfaces.get(surface.get("model", surfaces.DEFAULT_MODEL))
    except ConfigError as exc:
        raise InputError(f"the file's metadata: {exc}") from None
    if not all(surface.get(k) is not None for k in model.config_keys):
        return model, None
    return model, model.theory(surface)


@dataclass(frozen=True)
class RecordInputs:
    """What a user states about a record beside the table (the record keywords, spelled here
    once): the probe's paddle for data without metadata, Z1, the drive frequency, the force
    reconstruction's low-pass, and the attraction constants for Z1 without an approach."""

    k2: float | None = None  # [N/m] paddle stiffness
    f2: float | None = None  # [Hz] paddle resonance
    q2: float | None = None  # paddle quality factor
    z1: float | None = None  # [m] undeformed-surface reference (tip position)
    f1: float | None = None  # [Hz] drive frequency (labels the cut-off in harmonics)
    cutoff_hz: float | None = None  # [Hz] low-pass of the force reconstruction (None: Nyquist)
    taper: float = 0.0  # raised-cosine taper of the low-pass (fraction of the cut-off)
    a0: float | None = None  # [m] intermolecular distance (Z1 = a0, thesis eq. 84)
    vdw_on_surface: bool | None = None  # whether the surface feels the tip's pull

    @classmethod
    def of(cls, values: dict, aliases: dict | None = None) -> "RecordInputs":
        """The record inputs among ``values`` (e.g. a command's options; ``aliases``: field ->
        the name it has there, as the CLI's ``cutoff`` for ``cutoff_hz``)."""
        aliases = aliases or {}
        return cls(**{f.name: values[aliases.get(f.name, f.name)] for f in fields(cls)
                      if aliases.get(f.name, f.name) in values and values[aliases.get(f.name, f.name)] is not None})  # fmt: skip


RECORD_KEYS = tuple(f.name for f in fields(RecordInputs))  # the record keywords


def build_record(
    df: pd.DataFrame,
    meta: dict | None = None,
    force: str = "auto",
    *,
    need_approach: bool = False,
    need_z1: bool = True,
    uniform: str | None = None,
    tap_windows: bool = False,
    inputs: RecordInputs | None = None,
    **keywords,
) -> Record:
    """Check a run table and prepare its steady record (module docstring).

    ``force``: 'true' uses the ``f_ts`` column, 'reconstructed' rebuilds the force
    from ``z_paddle`` (probe ``k2, f2, q2`` from the metadata or the keywords;
    low-pass ``cutoff_hz``, default the Nyquist frequency, with a raised-cosine
    ``taper``); 'auto' = reconstructed when ``z_paddle`` is present.  ``Z1`` comes
    from ``z1`` if given, else from the first force minimum of the 'approach'
    segment (with the chosen force), else from the metadata, else thesis eq. 84 from ``a0``
    and ``vdw_on_surface`` (the keywords, else the metadata's); ``need_approach``
    analyses the approach segment even when ``z1`` is given; without ``need_z1`` a record
    with no way to Z1 gets ``z1 = None`` instead of an error.  ``uniform``: the name
    of a method that needs a constant time step (checked before the force is
    built).  ``f1`` (drive frequency, Hz) only labels the cut-off in harmonics.  The
    record keywords come as ``inputs`` (:class:`RecordInputs`) or as keywords.
    ``tap_windows``: a reconstructed force is rebuilt only in the taps' windows
    (:mod:`vetica_cli.signals.tapforce`; for methods that read the force only there) and
    the record carries the taps located on it.
    """
    inputs = replace(inputs or RecordInputs(), **keywords)  # TypeError for an unknown keyword, as before
    k2, f2, q2, z1, f1, cutoff_hz, taper, a0, vdw_on_surface = astuple(inputs)
    for flag, value in (("--k2", k2), ("--f2", f2), ("--q2", q2), ("--f1", f1), ("--a0", a0)):
        if value is not None:  # a stated constant within its quantity's one range (vetica_cli.ranges)
            check_range(flag, value, flag)
    meta = meta or {}
    check_params(meta.get("params") or {})
    force = resolve_force(df, force)
    t_start = time.perf_counter()
    steady = _steady_segment(df)
    approach = _fast_approach(segment(df, "approach"))
    t = column(steady, "t", "the steady record")
    check_time(t, "the steady record")
    z = column(steady, "z_tip", "the steady record")
    check_record(t, z, column(steady, "f_ts", "the steady record") if force == "true" else None,
                 {**meta, "f1": f1} if f1 is not None else meta, "the steady record")
    if z1 is not None and not (math.isfinite(z1) and z.min() <= z1 <= z.max()):
        raise InputError(
            f"--z1 {z1!r} is not allowed for this record; expected a tip position within its z_tip range "
            f"[{z.min():.4g}, {z.max():.4g}] m"
        )
    if uniform:
        h = (t[-1] - t[0]) / (len(t) - 1)
        if np.max(np.abs(np.diff(t) - h)) > 1e-3 * h:
            raise InputError(f"--method {uniform} needs uniformly sampled t (constant time step) in the steady record")
    params = meta.get("params") or {}
    info: dict = {}
    force_of = _ForceSource(force, params.get("probe") or {}, info, k2, f2, q2, cutoff_hz, taper, tap_windows)
    force_of.drive_hz = _drive(f1, params, t, z, info)
    f, taps = _steady_force(steady, force_of, f1)
    _declare_noise(f, t, force_of, info)
    t_force = time.perf_counter()
    surface = params.get("surface") or {}
    a0 = _known(a0, surface.get("a0"), "a0", info)
    pull = _known(vdw_on_surface, surface.get("vdw_on_surface"), "vdw_on_surface", info)
    if a0 is not None and not (math.isfinite(a0) and a0 > 0):
        raise InputError(f"a0 {a0!r} not allowed; expected a distance > 0 m")
    z1_value, approach_rec = _z1_reference(approach, z1, meta, force_of, need_approach, (z, f), a0, pull, need_z1)
    if z1_value is not None and not math.isfinite(z1_value):
        raise InputError(f"z1 {z1_value!r} not allowed; expected a finite tip position in m")
    warnings = list(meta.get("warnings") or [])
    periods = drive_periods(f) if taps is None else (len(f) / taps.spacing if taps.spacing > 0 else None)
    if periods is not None:
        info["periods"] = periods
        if force == "reconstructed" and abs(periods - round(periods)) > 0.05:
            warnings.append(
                f"the record spans {periods:.2f} drive periods: the spectral inversion assumes a whole number "
                "(the window's ends leak into the reconstructed force)"
            )
    model, truth = surface_of(params)
    return Record(t=t, z=z, f=f, force=force, z1=z1_value, approach=approach_rec, model=model, truth=truth,
                  params=params, info=info, meta_warnings=warnings, t_start=t_start, t_force=t_force,
                  a0=None if a0 is None else float(a0), vdw_on_surface=None if pull is None else bool(pull),
                  observables=dict(meta.get("observables") or {}),
                  energy=dict(meta.get("energy_ev_per_cycle") or {}), taps=taps)  # fmt: skip
