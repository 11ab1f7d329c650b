"""JPK text exports: what JPK's data-processing software writes when a user exports force curves.

The format (JPK Data Processing, "Export ... as text"): a file of segment blocks separated by
blank lines.  Each block is a header of ``# key: value`` lines followed by one whitespace-separated
row of numbers per sample.  The keys read here:

* ``segment``: ``extend`` (approach), ``retract``, ``pause``; ``segmentIndex``;
* ``columns``: the channel names (``vDeflection``, ``strainGaugeHeight`` or ``measuredHeight``
  (the closed-loop height sensor), ``height`` (the piezo's), ``capacitiveSensorHeight``,
  ``seriesTime``, ``time`` (segment time), ...), ``units`` (one per column);
* ``calibrationSlots`` (the deflection's calibration: ``force`` [N], ``distance`` [m],
  ``volts`` [V]), ``springConstant`` [N/m], ``sensitivity`` [m/V];
* ``xPosition``, ``yPosition`` [m] (``----`` when not recorded), ``index``.

A file holds one curve: its extend and retract segments (a pause before the extend or after
the retract is left out).  The deflection becomes a force with the spring constant (and the
sensitivity for volts), which ``--meta spring_constant=... sensitivity=...`` may give or
override.  The result is afmformats' force-distance data object, so the rest of ``vetica fit``
reads it as any instrument file.  :func:`is_text_export` tells such a file from the other
``.txt`` formats afmformats reads (NT-MDT).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

HEIGHTS = {"measured": ("strainGaugeHeight", "measuredHeight", "capacitiveSensorHeight", "headHeight"),
           "piezo": ("height",)}  # fmt: skip
SIGNATURE = ("# TEXT EXPORT", "# segmentIndex:", "# springConstant:", "# columns:")


class TextExportError(ValueError):
    """A JPK text export that cannot be read: one line saying why."""


def is_text_export(path: Path) -> bool:
    """True for a file whose first 64 kB hold JPK text-export header lines."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(65536).decode("latin-1")
    except OSError:
        return False
    return head.startswith("# TEXT EXPORT") or ("# columns:" in head and "# segment:" in head)


def _blocks(text: str) -> list[tuple[dict, list[str]]]:
    blocks, header, rows = [], {}, []
    for line in text.splitlines():
        s = line.strip()
        if not s:
            if rows:
                blocks.append((header, rows))
                header, rows = {}, []
            continue
        if s.startswith("#"):
            if rows:  # a header after data without a blank line: a new block
                blocks.append((header, rows))
                header, rows = {}, []
            key, sep, value = s[1:].partition(":")
            if sep:
                header[key.strip()] = value.strip()
            continue
        rows.append(s)
    if rows:
        blocks.append((header, rows))
    return blocks


def _number(header: dict, key: str, override: dict, okey: str) -> float | None:
    if okey in override:
        return float(override[okey])
    raw = header.get(key)
    try:
        v = float(raw) if raw is not None else None
    except ValueError:
        return None
    return v if v is not None and np.isfinite(v) and v > 0 else None


def load_text_export(path: Path, meta_override: dict | None = None) -> list:
    """afmformats' force-distance data object(s) of one JPK text export (module docstring);
    :class:`TextExportError` (one line) for a file that cannot be read as one."""
    from afmformats.mod_force_distance import AFMForceDistance

    override = dict(meta_override or {})
    try:
        text = Path(path).read_text(encoding="latin-1")
    except OSError as exc:
        raise TextExportError(f"cannot be read ({exc.strerror or exc})") from None
    segs = {}
    for header, rows in _blocks(text):
        kind = header.get("segment")
        if kind not in ("extend", "retract"):
            continue
        if kind in segs:
            raise TextExportError(f"two {kind} segments: one curve per text export is read")
        cols = header.get("columns", "").split()
        if not cols:
            raise TextExportError(f"the {kind} segment has no '# columns:' line")
        try:
            data = np.array([[float(v) for v in r.split()] for r in rows], float)
        except ValueError:
            raise TextExportError(f"the {kind} segment holds a value that is not a number") from None
        if data.ndim != 2 or data.shape[1] != len(cols):
            raise TextExportError(f"the {kind} segment's rows do not have the {len(cols)} columns its header names")
        segs[kind] = (header, cols, data)
    if "extend" not in segs or "retract" not in segs:
        raise TextExportError("no extend and retract segments (a JPK force-curve text export has both)")
    out = {"force": [], "height (measured)": [], "height (piezo)": [], "time": [], "segment": []}
    meta: dict = {}
    t_prev = 0.0
    for code, kind in enumerate(("extend", "retract")):
        header, cols, data = segs[kind]
        units = header.get("units", "").split()
        slots = header.get("calibrationSlots", "").split()
        k = _number(header, "springConstant", override, "spring constant")
        sens = _number(header, "sensitivity", override, "sensitivity")
        if "vDeflection" not in cols:
            raise TextExportError(f"the {kind} segment has no vDeflection column")
        i = cols.index("vDeflection")
        slot = slots[i] if i < len(slots) else ""
        unit = units[i] if i < len(units) else ""
        if slot == "force" or unit == "N":
            force = data[:, i]
        elif slot == "distance" or unit == "m":
            if k is None:
                raise TextExportError("no springConstant for a deflection in m; give --meta spring_constant=N/m")
            force = data[:, i] * k
        elif slot == "volts" or unit == "V":
            if k is None or sens is None:
                raise TextExportError("a deflection in V needs springConstant and sensitivity; give --meta "
                                      "spring_constant=N/m sensitivity=m/V")  # fmt: skip
            force = data[:, i] * sens * k
        else:
            raise TextExportError(f"the vDeflection column's unit {unit or slot or 'is missing'}: expected N, m or V")
        if k is None:
            raise TextExportError("no springConstant in the file; give --meta spring_constant=N/m")
        n = data.shape[0]
        for name, keys in HEIGHTS.items():
            found = next((c for c in keys if c in cols), None)
            out[f"height ({name})"].append(data[:, cols.index(found)] if found else np.full(n, np.nan))
        if "seriesTime" in cols:
            t = data[:, cols.index("seriesTime")]
        elif "time" in cols:
            t = data[:, cols.index("time")] + t_prev
        else:
            raise TextExportError("no seriesTime or time column")
        t_prev = float(t[-1]) if n else t_prev
        out["force"].append(force)
        out["time"].append(t)
        out["segment"].append(np.full(n, code, np.uint8))
        meta["spring constant"] = k
        if sens is not None:
            meta["sensitivity"] = sens
        for key, mk in (("xPosition", "position x"), ("yPosition", "position y")):
            try:
                meta[mk] = float(header.get(key, "nan"))
            except ValueError:
                pass
    data = {c: np.concatenate(v) for c, v in out.items()}
    for c in ("height (measured)", "height (piezo)"):
        if not np.all(np.isfinite(data[c])):
            del data[c]
    if not any(c.startswith("height") for c in data):
        raise TextExportError("no height channel (strainGaugeHeight, measuredHeight or height)")
    meta.update({"path": Path(path), "enum": 0, "imaging mode": "force-distance", "feedback mode": "contact",
                 "format": "JPK text export"})  # fmt: skip
    meta = {k: v for k, v in meta.items() if not (isinstance(v, float) and not np.isfinite(v))}
    return [AFMForceDistance(data, meta)]
