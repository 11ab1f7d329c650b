"""Force curves read from instrument files through afmformats (optional extra), and JPK text exports.

afmformats (MIT) reads JPK ``.jpk-force``/``.jpk-force-map``/``.jpk-qi-data``/``.jpk-qi-series``,
Igor ``.ibw``, AFM Workshop ``.csv``, NT-MDT ``.txt`` and its own HDF5/tab files, and knows three
modalities: force-distance (approach and retract), stress-relaxation (height held during a
dwell) and creep-compliance (force held).  JPK's own text export is read by :mod:`.jpktxt`.
From the file: the segments on their own, possibly different, sampling rates; the spring
constant; the force (afmformats converts the photodiode signal with the file's sensitivity and
spring constant, which ``--meta`` may give or override: afmformats' ``meta_override``); the
height channels; the time axis (or, when a file has none, one built from its sampling rates).
The height channel is chosen (``measured``: the closed-loop height sensor, or ``piezo``: the
piezo's drive converted to height; they differ by several percent) and recorded in the table.

Every file given is read or refused in one line (:func:`read_inputs`): a file afmformats
cannot read -- whatever it raises, its errors derive from ``BaseException`` -- or that holds no
curve vetica fits becomes a :class:`Refusal` (a row of the table with ``status`` and ``error``);
only Ctrl-C and the like pass through.  The readers' own tracebacks (afmformats and igor2 log
them) are kept off the terminal.  A file given twice is read once (with a note); each file gets
a ``label``, the shortest tail of its path that tells it apart from the others.
"""

from __future__ import annotations

import contextlib
import importlib
import io
import logging
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..checks import LIMITS, within
from ..errors import InputError
from .jpktxt import TextExportError, is_text_export, load_text_export

DWELL = ("stress-relaxation", "creep-compliance")
MODALITIES = ("force-distance", *DWELL)
HEIGHTS = ("measured", "piezo")
EXTRA_HINT = 'pip install -e ".[formats]"'
# --meta KEY=VALUE: afmformats' metadata key, unit and range (the spring constant is the flexural
# cantilever's stiffness, checks.LIMITS' probe.k1)
META = {
    "spring_constant": ("spring constant", "N/m", LIMITS["probe.k1"][:2], LIMITS["probe.k1"][3]),
    "sensitivity": ("sensitivity", "m/V", LIMITS["probe.sensitivity"][:2], LIMITS["probe.sensitivity"][3]),
    "rate": ("rate", "Hz", LIMITS["record.rate"][:2], LIMITS["record.rate"][3]),
}
QUIET_LOGGERS = ("afmformats", "igor2")
PASS_THROUGH = (KeyboardInterrupt, SystemExit, GeneratorExit)  # never swallowed


def afmformats():
    """The afmformats module, or InputError naming the extra to install."""
    try:
        return importlib.import_module("afmformats")
    except ImportError:
        raise InputError(f"reading instrument files needs afmformats: {EXTRA_HINT}") from None


@dataclass
class Curve:
    """One force curve: its segments' samples in time order, SI units, baseline not removed.

    ``height`` increases away from the sample; ``segment`` is 0 on the approach, 1 on a dwell,
    2 on the retract."""

    source: str
    index: int
    modality: str
    height_channel: str
    spring_constant: float  # [N/m]
    t: np.ndarray  # [s]
    force: np.ndarray  # [N]
    height: np.ndarray  # [m]
    segment: np.ndarray  # 0 approach, 1 dwell, 2 retract
    meta: dict = field(default_factory=dict)  # position x/y [m], grid index x/y
    prep_force: np.ndarray | None = None  # [N] force of a pause segment before the approach, if recorded
    label: str = ""  # the shortest tail of the path that tells the file apart from the others read with it

    @property
    def name(self) -> str:
        return f"{self.label or Path(self.source).name}#{self.index}"


@dataclass
class Refusal:
    """A file (or one curve of it) that gives no curve to fit: a table row with status and error."""

    source: str
    label: str
    status: str  # unreadable | unsuited
    error: str
    index: int = -1
    modality: str = ""


class Unsuited(ValueError):
    """A curve that was read but does not suit the fit (one line)."""


def parse_meta(items) -> dict:
    """``--meta KEY=VALUE`` items as afmformats' ``meta_override`` (``rate`` sets both segments'
    sampling rates); InputError (one line) naming the item and what is allowed."""
    out: dict = {}
    for item in items or ():
        key, sep, raw = str(item).partition("=")
        key = key.strip()
        if not sep or key not in META:
            raise InputError(f"--meta {item!r} is not allowed; expected KEY=VALUE with KEY one of {', '.join(META)}")
        name, unit, (lo, hi), why = META[key]
        try:
            v = float(raw)
        except ValueError:
            v = float("nan")
        pred, allowed = within(lo, hi, f"a {key.replace('_', ' ')}", unit, why)
        if not (np.isfinite(v) and pred(v)):
            raise InputError(f"--meta {key}={raw!r} is not allowed; expected {allowed}")
        if key == "rate":
            out["rate approach"] = out["rate retract"] = v
        else:
            out[name] = v
    return out


def supported_suffixes() -> list[str]:
    return list(afmformats().supported_extensions)


def labels(paths: list[Path]) -> dict:
    """``path -> label``: the shortest tail of each path (file name, then parent/name, ...)
    that no other path shares."""
    parts = {p: Path(os.path.abspath(p)).parts for p in paths}
    out = {}
    for p, ps in parts.items():
        for n in range(1, len(ps) + 1):
            tail = ps[-n:]
            if all(q is p or qs[-n:] != tail for q, qs in parts.items()):
                out[p] = "/".join(tail)
                break
        else:
            out[p] = str(p)
    return out


def expand_paths(paths) -> tuple[list[Path], list[Refusal], list[str]]:
    """``(files, refusals, notes)``: the files given and the supported files inside folders given
    (sorted), each once.  A folder without a supported file and a file of an unsupported format
    are refusals; a missing path is an InputError (a typing error: nothing is read)."""
    suffixes = supported_suffixes()
    files: list[Path] = []
    refused: list[Refusal] = []
    notes: list[str] = []
    seen: dict = {}
    for raw in paths:
        p = Path(raw)
        if p.is_dir():
            found = sorted(f for f in p.iterdir() if f.is_file() and f.suffix in suffixes)
            if not found:
                refused.append(Refusal(str(p), str(p), "unreadable",
                                       f"a folder without a file vetica reads (expected {', '.join(suffixes)})"))  # fmt: skip
            batch = found
        elif p.is_file():
            batch = [p]
        elif p.exists():
            raise InputError(f"{p}: not a regular file or folder")
        else:
            raise InputError(f"{p}: no such file or folder")
        for f in batch:
            key = os.path.realpath(f)
            if key in seen:
                notes.append(f"{f} is {seen[key]} given again: read once")
                continue
            seen[key] = str(f)
            files.append(f)
    if not files and not refused:
        raise InputError("no curve files given")
    return files, refused, notes


@contextlib.contextmanager
def quiet_readers():
    """The readers' log records (afmformats logs a traceback for every file it fails on, igor2
    its own errors) and anything they print on stderr are kept off the terminal."""
    saved = []
    for name in QUIET_LOGGERS:
        lg = logging.getLogger(name)
        saved.append((lg, lg.propagate, lg.level))
        lg.propagate = False
        lg.setLevel(logging.CRITICAL + 1)
    try:
        with contextlib.redirect_stderr(io.StringIO()):
            yield
    finally:
        for lg, prop, level in saved:
            lg.propagate = prop
            lg.setLevel(level)


def _why(exc: BaseException) -> str:
    text = " ".join(str(exc).split())[:160]
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def load_file(path: Path, meta: dict | None = None) -> list:
    """The data objects of one file (afmformats', or a JPK text export's); :class:`Unsuited`
    (one line) when it cannot be read, whatever the reader raised (Ctrl-C passes)."""
    meta = dict(meta or {})
    try:
        if path.stat().st_size == 0:
            raise Unsuited("an empty file")
    except OSError as exc:
        raise Unsuited(f"cannot be read ({exc.strerror or exc})") from None
    if path.suffix.lower() == ".txt" and is_text_export(path):
        try:
            return load_text_export(path, meta)
        except TextExportError as exc:
            raise Unsuited(f"a JPK text export that cannot be read: {exc}") from None
    af = afmformats()
    if path.suffix not in af.supported_extensions:
        raise Unsuited(f"not a format vetica reads (expected one of {', '.join(af.supported_extensions)})")
    af_meta = {k: v for k, v in meta.items() if k in ("spring constant", "sensitivity", "rate approach", "rate retract")}
    try:
        with quiet_readers():
            data = list(af.load_data(path, meta_override=af_meta))
    except PASS_THROUGH:
        raise
    except BaseException as exc:  # noqa: BLE001 - afmformats' errors derive from BaseException; any reader error is a refusal
        hint = "; give --meta spring_constant=N/m sensitivity=m/V" if type(exc).__name__ == "MissingMetaDataError" else ""
        raise Unsuited(f"cannot be read ({_why(exc)}){hint}") from None
    if not data:
        raise Unsuited("holds no curve")
    return data


def _time_axis(data, n: list[int]) -> np.ndarray | None:
    """The curve's times [s], or ones built from the sampling rates (segments back to back);
    None when the file has neither."""
    md = data.metadata
    rates = []
    for key in ("rate approach", "rate intermediate", "rate retract"):
        try:
            rates.append(float(md.get(key)) if md.get(key) is not None else None)
        except (TypeError, ValueError, KeyError):
            rates.append(None)
    rates = [r if r is not None and np.isfinite(r) and r > 0 else None for r in rates]
    parts, t0 = [], 0.0
    for count, rate in zip(n, (rates[0], rates[1] or rates[0], rates[2] or rates[0])):
        if count == 0:
            continue
        if rate is None:
            return None
        parts.append(t0 + np.arange(count) / rate)
        t0 = parts[-1][-1] + 1.0 / rate
    return np.concatenate(parts)


def to_curve(data, path: Path, index: int, height: str = "measured", label: str = "") -> Curve:
    """A :class:`Curve` from one data object; :class:`Unsuited` (one line) for another modality, a
    curve without the segments its fit needs, a missing height channel or spring constant.  A
    dwell curve keeps its approach and dwell (its fit does not model the retract); a
    force-distance curve its approach and retract."""
    modality = getattr(data, "modality", "?")
    if modality not in MODALITIES:
        raise Unsuited(f"a {modality} curve; vetica fit reads {', '.join(MODALITIES)}")
    if height not in HEIGHTS:
        raise InputError(f"--height {height!r} is not allowed; expected one of {', '.join(HEIGHTS)}")
    col = f"height ({height})"
    if col not in data.columns:
        have = [c[len("height ("):-1] for c in data.columns if c.startswith("height (")]
        raise Unsuited(f"curve {index} has no {col!r} channel; this file has --height {' or '.join(have) or 'none'}")
    k = data.metadata.get("spring constant")
    if not k or not np.isfinite(k) or k <= 0:
        raise Unsuited("no spring constant in the file; give --meta spring_constant=N/m")
    appr = data.appr
    if modality in DWELL:
        second, code = data.intr, 1
        if _length(second) < 10:
            raise Unsuited(f"curve {index} has no dwell (no intermediate segment); expected a stress-relaxation "
                           "or creep-compliance curve with a dwell")  # fmt: skip
    else:
        second, code = data.retr, 2
        if _length(second) < 10:
            raise Unsuited(f"curve {index} has no retract segment (10 samples at least)")
    n_a, n_2 = _length(appr), _length(second)
    if n_a < 10:
        raise Unsuited(f"curve {index} has no approach segment (10 samples at least)")
    have_time = "time" in data.columns
    if have_time:
        t = np.concatenate([appr["time"], second["time"]]).astype(float)
    else:
        t = _time_axis(data, [n_a, n_2 if code == 1 else 0, n_2 if code == 2 else 0])
    if t is None:
        raise Unsuited(f"curve {index} has no time axis (no time column, no sampling rate): a viscoelastic fit needs "
                       "one; give --meta rate=HZ")  # fmt: skip
    f = np.concatenate([appr["force"], second["force"]]).astype(float)
    h = np.concatenate([appr[col], second[col]]).astype(float)
    seg = np.concatenate([np.zeros(n_a, np.int8), np.full(n_2, code, np.int8)])
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(f)) and np.all(np.isfinite(h))):
        raise Unsuited(f"curve {index} holds non-finite samples")
    meta = {key: data.metadata.get(key) for key in ("position x", "position y", "grid index x", "grid index y")
            if data.metadata.get(key) is not None}  # fmt: skip
    prep = None
    if modality == "stress-relaxation":  # afmformats: segment 0 is the pause at constant height before the approach
        try:
            pf = np.asarray(data.prep["force"], float)
            prep = pf if pf.size >= 10 and np.all(np.isfinite(pf)) else None
        except (KeyError, IndexError, ValueError, AttributeError):
            prep = None
    return Curve(str(path), index, modality, height, float(k), t, f, h, seg, meta, prep, label)


def _length(segment) -> int:
    try:
        return len(segment["force"])
    except (KeyError, IndexError, ValueError, AttributeError):
        return 0


def read_inputs(paths, height: str = "measured", meta: dict | None = None) -> tuple[list[Curve], list[Refusal], list[str]]:
    """``(curves, refusals, notes)`` of every file of ``paths`` (folders expanded, each file
    once): each file is read or refused in one line (module docstring)."""
    files, refused, notes = expand_paths(paths)
    names = labels([*files, *(Path(r.source) for r in refused)])
    for r in refused:
        r.label = names.get(Path(r.source), r.label)
    curves: list[Curve] = []
    for path in files:
        label = names[path]
        try:
            data = load_file(path, meta)
        except Unsuited as exc:
            refused.append(Refusal(str(path), label, "unreadable", str(exc)))
            continue
        for i, d in enumerate(data):
            try:
                curves.append(to_curve(d, path, i, height, label))
            except Unsuited as exc:
                refused.append(Refusal(str(path), label, "unsuited", str(exc), i, str(getattr(d, "modality", ""))))
            except PASS_THROUGH:
                raise
            except InputError:
                raise
            except BaseException as exc:  # noqa: BLE001 - a reader's data object that fails on access
                refused.append(Refusal(str(path), label, "unreadable", f"curve {i} cannot be read ({_why(exc)})", i))
    return curves, refused, notes


def read_curves(paths, height: str = "measured", meta: dict | None = None) -> list[Curve]:
    """Every curve of every file; InputError at the first file that is refused (for scripts
    and tests that expect only good files)."""
    curves, refused, _ = read_inputs(paths, height, meta)
    if refused:
        r = refused[0]
        raise InputError(f"{r.source}: {r.error}")
    return curves
