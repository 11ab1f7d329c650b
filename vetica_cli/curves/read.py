"""Force curves with a dwell read from instrument files through afmformats (optional extra).

afmformats (MIT) reads JPK ``.jpk-force``/``.jpk-force-map``, Igor ``.ibw``, AFM Workshop,
NT-MDT text and its own HDF5/tab files, and knows three modalities: force-distance,
stress-relaxation (height held during the dwell) and creep-compliance (force held).  Only the
two with a dwell are fitted.  From the file: the segments (approach, dwell) on their own,
possibly different, sampling rates; the spring constant; the force (afmformats converts the
photodiode signal with the file's sensitivity and spring constant); the height channels.
The height channel is chosen (``measured``: the closed-loop height sensor, or ``piezo``: the
piezo's drive converted to height; they differ by several percent) and recorded in the table.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError

MODALITIES = ("stress-relaxation", "creep-compliance")
HEIGHTS = ("measured", "piezo")
EXTRA_HINT = 'pip install -e ".[formats]"'


def afmformats():
    """The afmformats module, or InputError naming the extra to install."""
    try:
        return importlib.import_module("afmformats")
    except ImportError:
        raise InputError(f"reading instrument files needs afmformats: {EXTRA_HINT}") from None


@dataclass
class Curve:
    """One force curve with a dwell: approach then dwell samples, SI units, baseline not removed.

    ``height`` increases away from the sample; ``segment`` is 0 on the approach, 1 on the dwell."""

    source: str
    index: int
    modality: str
    height_channel: str
    spring_constant: float  # [N/m]
    t: np.ndarray  # [s]
    force: np.ndarray  # [N]
    height: np.ndarray  # [m]
    segment: np.ndarray  # 0 approach, 1 dwell
    meta: dict = field(default_factory=dict)  # position x/y [m], grid index x/y
    prep_force: np.ndarray | None = None  # [N] force of a pause segment before the approach, if recorded

    @property
    def name(self) -> str:
        return f"{Path(self.source).name}#{self.index}"


def supported_suffixes() -> list[str]:
    return list(afmformats().supported_extensions)


def expand_paths(paths) -> list[Path]:
    """Files given, and the supported files inside folders given (sorted); InputError for a
    missing path or a folder without a supported file."""
    suffixes = supported_suffixes()
    out: list[Path] = []
    for raw in paths:
        p = Path(raw)
        if p.is_dir():
            found = sorted(f for f in p.iterdir() if f.is_file() and f.suffix in suffixes)
            if not found:
                raise InputError(f"{p}: no file afmformats reads in this folder; expected one of {', '.join(suffixes)}")
            out += found
        elif p.is_file():
            if p.suffix not in suffixes:
                raise InputError(f"{p}: not a format afmformats reads; expected one of {', '.join(suffixes)}")
            out.append(p)
        else:
            raise InputError(f"{p}: no such file or folder")
    if not out:
        raise InputError("no curve files given")
    return out


def load_file(path: Path) -> list:
    """afmformats' data objects of one file; InputError (one line) when it cannot read it."""
    af = afmformats()
    try:
        return list(af.load_data(path))
    except Exception as exc:  # afmformats raises many types for foreign or corrupt files
        raise InputError(f"{path}: afmformats cannot read it ({type(exc).__name__}: {' '.join(str(exc).split())[:120]})") from None


def to_curve(data, path: Path, index: int, height: str = "measured") -> Curve:
    """A :class:`Curve` from one afmformats data object; InputError (one line) for another
    modality, a curve without a dwell, a missing height channel or spring constant."""
    modality = getattr(data, "modality", "?")
    if modality not in MODALITIES:
        raise InputError(f"{path}: a {modality} curve; vetica fit needs a curve with a dwell "
                         f"({' or '.join(MODALITIES)})")  # fmt: skip
    if height not in HEIGHTS:
        raise InputError(f"--height {height!r} is not allowed; expected one of {', '.join(HEIGHTS)}")
    col = f"height ({height})"
    if col not in data.columns:
        have = [c[len("height ("):-1] for c in data.columns if c.startswith("height (")]
        raise InputError(f"{path}: no {col!r} channel; this file has --height {' or '.join(have) or 'none'}")
    appr, dwell = data.appr, data.intr
    n_a, n_d = _length(appr), _length(dwell)
    if n_d < 10:
        raise InputError(f"{path}: curve {index} has no dwell (no intermediate segment); "
                         "expected a stress-relaxation or creep-compliance curve with a dwell")  # fmt: skip
    if n_a < 10:
        raise InputError(f"{path}: curve {index} has no approach segment")
    k = data.metadata.get("spring constant")
    if not k or not np.isfinite(k) or k <= 0:
        raise InputError(f"{path}: no spring constant in the file")
    t = np.concatenate([appr["time"], dwell["time"]]).astype(float)
    f = np.concatenate([appr["force"], dwell["force"]]).astype(float)
    h = np.concatenate([appr[col], dwell[col]]).astype(float)
    seg = np.concatenate([np.zeros(n_a, np.int8), np.ones(n_d, np.int8)])
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(f)) and np.all(np.isfinite(h))):
        raise InputError(f"{path}: curve {index} holds non-finite samples")
    meta = {key: data.metadata.get(key) for key in ("position x", "position y", "grid index x", "grid index y")
            if data.metadata.get(key) is not None}  # fmt: skip
    prep = None
    if modality == "stress-relaxation":  # afmformats: segment 0 is the pause at constant height before the approach
        try:
            pf = np.asarray(data.prep["force"], float)
            prep = pf if pf.size >= 10 and np.all(np.isfinite(pf)) else None
        except (KeyError, IndexError, ValueError, AttributeError):
            prep = None
    return Curve(str(path), index, modality, height, float(k), t, f, h, seg, meta, prep)


def _length(segment) -> int:
    try:
        return len(segment["time"])
    except (KeyError, IndexError, ValueError):
        return 0


def read_curves(paths, height: str = "measured") -> list[Curve]:
    """Every curve of every file (folders expanded); InputError at the first file that is
    not a curve with a dwell (checked before any fitting starts)."""
    out = []
    for path in expand_paths(paths):
        for i, data in enumerate(load_file(path)):
            out.append(to_curve(data, path, i, height))
    return out
