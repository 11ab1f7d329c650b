"""A scan config: the single-point sections (``probe``, ``operation``, ``numerics``,
``extract``) plus ``scan`` and ``sample`` (the schema is a contract)::

    scan:
      pixels: [64, 64]          # nx, ny
      size: [2.0e-6, 2.0e-6]    # scan area [m]; x is the fast axis
      pixel_time: 2.0e-3        # time the tip taps each pixel [s]; a list runs one pass each
      steady: transient         # transient | orbit, or a list of both
      methods: [vetica, full]   # extraction methods run on every pixel
    sample:
      background:               # any surface section plus its height [m]
        height: 0.0
        k_inf: 4.0
        k0: 64.0
        cd: 3.0e-5
      features:                 # painted over the background in order (scan.sample)
        - shape: disk           # disk | rectangle
          center: [1.0e-6, 1.0e-6]
          radius: 4.0e-7
          height: 5.0e-9
          surface: {k_inf: 4.0, k0: 16.0, cd: 1.0e-3}
        - shape: rectangle
          corner: [0.0, 0.0]
          size: [5.0e-7, 2.0e-6]
          height: 0.0
          surface: {k0: 128.0}  # keys not given are the background's

Extensions of the contract (a plain scalar still means what it meant):
``scan.pixel_time`` and ``scan.steady`` may be lists: a *pass* is one scan of the
whole raster at one (steady, pixel time); ``orbit`` passes take no pixel time.
``extract.force`` is ``reconstructed`` by default (the force an instrument has,
spectral inversion of the paddle signal), ``true`` or ``both``.  A feature whose
surface names another ``model`` than the background's starts from the
background's common keys (``hamaker``, ``a0``, ``vdw_on_surface``) only.

Every problem raises :class:`~vetica_cli.errors.ConfigError` with one line naming
the key, the value and what is allowed, before any work starts.
"""

from __future__ import annotations

import copy
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from ..checks import MAX_LIST, finite, limit
from ..errors import ConfigError
from ..extraction import DEFAULT_METHOD, METHODS
from ..simulation.config import Config, from_dict, read_yaml
from ..rows.extract import EXTRACT_SECTION, META_KEYS, extract_section
from ..surfaces import COMMON_KEYS, DEFAULT_MODEL
from .sample import SHAPES, Feature, Raster, Sample

STEADY = ("transient", "orbit")  # scan.steady: what each pixel's record is
SCAN_DEFAULTS = {"pixels": [64, 64], "size": [2.0e-6, 2.0e-6], "pixel_time": 2.0e-3, "steady": "transient",
                 "methods": [DEFAULT_METHOD]}  # fmt: skip
FORCES = ("reconstructed", "true", "both")  # extract.force of a scan (first = default)
DEFAULT_FORCE = "reconstructed"  # what an instrument has
POINT_SECTIONS = ("probe", "operation", "numerics")  # single-point sections a scan takes as they are
TOP_KEYS = (*POINT_SECTIONS, EXTRACT_SECTION, "scan", "sample", *META_KEYS)
MAX_PIXELS = 4096  # per axis
MIN_PIXEL_PERIODS = 2  # drive periods a pixel needs besides its recorded ones (the first-contact window)


@dataclass(frozen=True)
class Pass:
    """One scan of the whole raster: each pixel's record is the last ``record_cycles``
    periods of ``pixel_time`` (``transient``) or the pixel's periodic orbit (``orbit``,
    ``pixel_time`` nan)."""

    steady: str
    pixel_time: float

    def label(self) -> str:
        return "orbit" if self.steady == "orbit" else f"transient {self.pixel_time * 1e3:g} ms"

    def slug(self) -> str:
        """File-name part: ``orbit`` or ``t2ms``."""
        return "orbit" if self.steady == "orbit" else f"t{self.pixel_time * 1e3:g}ms".replace(".", "p")


@dataclass(frozen=True)
class ScanSpec:
    raster: Raster
    pixel_times: tuple  # [s], transient passes
    steady: tuple  # of STEADY
    methods: tuple  # registered extraction methods, in order

    def passes(self) -> list[Pass]:
        """Transient passes in the order of the pixel times, then the orbit pass."""
        out = []
        for st in self.steady:
            out += [Pass("transient", t) for t in self.pixel_times] if st == "transient" else [Pass("orbit", math.nan)]
        return out


@dataclass(frozen=True)
class ScanConfig:
    """A validated scan: the point config (surface = background), the scan, the sample."""

    name: str
    description: str
    point: Config
    scan: ScanSpec
    sample: Sample
    force: str  # extract.force: reconstructed | true | both
    resolved: dict  # re-runnable config (every key resolved), as saved next to the table

    def material_config(self, surface: dict, steady: str) -> Config:
        """The single-point config of a pixel of ``surface`` (a resolved surface section);
        ``numerics.steady`` names the pass's kind."""
        d = self.point.to_dict()
        d["surface"] = copy.deepcopy(surface)
        d["numerics"]["steady"] = steady
        return from_dict(d)


# ----------------------------------------------------------------------------- helpers


def _num(key: str, v: Any, rule=None, allowed: str = "a finite number") -> float:
    return finite(key, v, (rule, allowed) if rule else None, allowed)


def _pair(key: str, v: Any, rule=None, allowed: str = "finite numbers") -> tuple[float, float]:
    if not isinstance(v, (list, tuple)) or len(v) != 2:
        raise ConfigError(f"{key}: {v!r} is not allowed; expected a list of two numbers [x, y]")
    return tuple(_num(key, x, rule, allowed) for x in v)


def _mapping(key: str, v: Any) -> dict:
    if v is None:
        return {}
    if not isinstance(v, dict):
        raise ConfigError(f"{key}: {v!r} is not allowed; expected a mapping")
    return v


def _unknown(key: str, given: dict, allowed) -> None:
    extra = [k for k in given if k not in allowed]
    if extra:
        raise ConfigError(f"unknown key '{key}.{extra[0]}'; allowed in {key}: {', '.join(allowed)}")


def _as_list(key: str, v: Any) -> list:
    out = v if isinstance(v, list) else [v]
    if not out:
        raise ConfigError(f"{key}: an empty list is not allowed; expected at least one value")
    if len(out) > MAX_LIST:
        raise ConfigError(f"{key}: a list of {len(out)} values is not allowed; expected at most {MAX_LIST}")
    return out


# ----------------------------------------------------------------------------- sections


def parse_scan(raw: Any, extract: dict) -> ScanSpec:
    """The ``scan:`` section (module docstring)."""
    raw = _mapping("scan", raw)
    _unknown("scan", raw, SCAN_DEFAULTS)
    if "method" in extract:
        raise ConfigError(
            f"extract.method: {extract['method']!r} is not used by a scan; list the methods in scan.methods"
        )
    d = {**SCAN_DEFAULTS, **raw}
    px = d["pixels"]
    if not isinstance(px, (list, tuple)) or len(px) != 2:
        raise ConfigError(f"scan.pixels: {px!r} is not allowed; expected [nx, ny], two integers in 1..{MAX_PIXELS}")
    for v in px:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or v != int(v) or not 1 <= v <= MAX_PIXELS:
            raise ConfigError(f"scan.pixels: {px!r} is not allowed; expected [nx, ny], two integers in 1..{MAX_PIXELS}")
    sx, sy = _pair("scan.size", d["size"], *limit("scan.size"))
    steady = []
    for st in _as_list("scan.steady", d["steady"]):
        if st not in STEADY:
            raise ConfigError(f"scan.steady: {st!r} is not allowed; expected one of: {', '.join(STEADY)} (or a list)")
        if st in steady:
            raise ConfigError(f"scan.steady: {st!r} appears twice")
        steady.append(st)
    times = []
    for t in _as_list("scan.pixel_time", d["pixel_time"]):
        t = _num("scan.pixel_time", t, *limit("scan.pixel_time"))
        if t in times:
            raise ConfigError(f"scan.pixel_time: {t!r} appears twice")
        times.append(t)
    methods = []
    for m in _as_list("scan.methods", d["methods"]):
        if not isinstance(m, str) or m not in METHODS:
            raise ConfigError(f"scan.methods: {m!r} is not allowed; expected a list of: {', '.join(METHODS)}")
        if m in methods:
            raise ConfigError(f"scan.methods: {m!r} appears twice")
        methods.append(m)
    raster = Raster(int(px[0]), int(px[1]), sx, sy)
    return ScanSpec(raster, tuple(times), tuple(steady), tuple(methods))


def _surface(key: str, raw: dict) -> dict:
    """A surface section validated by its model (:func:`vetica_cli.simulation.config.from_dict`),
    resolved; errors name ``key`` instead of ``surface``."""
    try:
        return from_dict({"surface": raw}).surface.to_dict()
    except ConfigError as exc:
        raise ConfigError(re.sub(r"(?<![\w.])surface\.(?=\w)", f"{key}.", str(exc))) from None


def _model(surface: dict) -> str:
    return surface.get("model", DEFAULT_MODEL)


def parse_sample(raw: Any) -> Sample:
    """The ``sample:`` section: background surface and height, features over it."""
    raw = _mapping("sample", raw)
    _unknown("sample", raw, ("background", "features"))
    if raw.get("background") is None:
        raise ConfigError(
            "sample.background: missing; expected a surface section plus its height, e.g. {height: 0.0, k0: 64.0}"
        )
    bg = dict(_mapping("sample.background", raw["background"]))
    height = _num("sample.background.height", bg.pop("height", 0.0))
    background = _surface("sample.background", bg)
    feats = raw.get("features") or []
    if not isinstance(feats, list):
        raise ConfigError(f"sample.features: {feats!r} is not allowed; expected a list of features")
    features = tuple(_feature(i, f, bg) for i, f in enumerate(feats))
    return Sample(background, height, features)


FEATURE_KEYS = {"disk": ("shape", "center", "radius", "height", "surface"),
                "rectangle": ("shape", "corner", "size", "height", "surface")}  # fmt: skip


def _feature(i: int, raw: Any, bg_raw: dict) -> Feature:
    key = f"sample.features.{i}"
    raw = _mapping(key, raw)
    shape = raw.get("shape")
    if shape not in SHAPES:
        raise ConfigError(f"{key}.shape: {shape!r} is not allowed; expected one of: {', '.join(SHAPES)}")
    _unknown(key, raw, FEATURE_KEYS[shape])
    own = dict(_mapping(f"{key}.surface", raw.get("surface")))
    if _model(own) != _model(bg_raw):  # another model: only the attraction keys carry over
        merged = {k: v for k, v in bg_raw.items() if k in COMMON_KEYS}
    else:
        merged = {k: v for k, v in bg_raw.items() if k != "model"}
    merged.update(own)
    surface = _surface(f"{key}.surface", merged)
    height = _num(f"{key}.height", raw.get("height", 0.0))
    if shape == "disk":
        for k in ("center", "radius"):
            if k not in raw:
                raise ConfigError(f"{key}.{k}: missing; a disk needs center [x, y] and radius [m]")
        center = _pair(f"{key}.center", raw["center"], None, "finite numbers [m]")
        radius = _num(f"{key}.radius", raw["radius"], lambda v: v > 0, "a radius > 0 m")
        return Feature("disk", height, surface, center=center, radius=radius)
    for k in ("corner", "size"):
        if k not in raw:
            raise ConfigError(f"{key}.{k}: missing; a rectangle needs corner [x0, y0] and size [w, h] [m]")
    corner = _pair(f"{key}.corner", raw["corner"], None, "finite numbers [m]")
    size = _pair(f"{key}.size", raw["size"], lambda v: v > 0, "lengths > 0 m")
    return Feature("rectangle", height, surface, corner=corner, size=size)


def _extract(raw: Any) -> dict:
    """The ``extract:`` section: the sweep's extraction keys (study.grid.EXTRACT_KEYS)."""
    return extract_section(_mapping(EXTRACT_SECTION, raw))


def _check_cross(point: Config, spec: ScanSpec, sample: Sample) -> None:
    """Checks that involve more than one section."""
    n, period = point.numerics, 1.0 / point.probe.f1
    need = n.record_cycles + MIN_PIXEL_PERIODS
    for t in spec.pixel_times if "transient" in spec.steady else ():
        if round(t / period) < need:
            raise ConfigError(
                f"scan.pixel_time: {t!r} is not allowed; expected >= (numerics.record_cycles + {MIN_PIXEL_PERIODS}) "
                f"drive periods ({need * period:.3g} s): the first-contact window and the recorded periods"
            )
    amp = point.operation.free_amplitude
    r = spec.raster
    for i, f in enumerate(sample.features):
        x0, y0, x1, y1 = f.bounds()
        if x1 <= 0 or y1 <= 0 or x0 >= r.size_x or y0 >= r.size_y:
            raise ConfigError(f"sample.features.{i}: {f.shape} over x {x0:g}..{x1:g} m, y {y0:g}..{y1:g} m is not "
                              f"allowed; expected a feature that overlaps the scan area 0..{r.size_x:g} x "
                              f"0..{r.size_y:g} m (scan.size)")  # fmt: skip
        if abs(f.height - sample.height) >= amp:
            raise ConfigError(
                f"sample.features.{i}.height: {f.height!r} is not allowed; expected within the free amplitude "
                f"({amp:g} m) of the background height ({sample.height:g} m): a taller step is not tapping-mode imaging"
            )
    for m in spec.methods:
        allowed = METHODS[m].surface_models
        for where, surf in [("sample.background", sample.background)] + [
            (f"sample.features.{i}.surface", f.surface) for i, f in enumerate(sample.features)
        ]:
            if _model(surf) not in allowed:
                raise ConfigError(f"scan.methods: {m!r} cannot extract the {_model(surf)!r} surface of {where} "
                                  f"(it extracts: {', '.join(allowed)})")  # fmt: skip
    if point.operation.base_height is not None:
        raise ConfigError("operation.base_height: a scan needs the amplitude controller; expected null")


def build(raw: dict, name: str = "scan") -> ScanConfig:
    """Validate a scan config mapping (module docstring) into a :class:`ScanConfig`."""
    if not isinstance(raw, dict):
        raise ConfigError(f"a scan config must be a mapping, got {type(raw).__name__}")
    if "surface" in raw:
        raise ConfigError(
            "surface: a scan takes its surfaces from 'sample:' (background and features); remove 'surface:'"
        )
    if "sweep" in raw:
        raise ConfigError("sweep: a scan config has no 'sweep:' block; list pixel times in scan.pixel_time")
    for k in raw:
        if k not in TOP_KEYS:
            raise ConfigError(f"unknown top-level key {k!r}; allowed in a scan config: {', '.join(TOP_KEYS)}")
    if "scan" not in raw or "sample" not in raw:
        missing = "scan" if "scan" not in raw else "sample"
        raise ConfigError(f"{missing}: missing; a scan config needs the sections 'scan:' and 'sample:'")
    numerics = _mapping("numerics", raw.get("numerics"))
    if "steady" in numerics:
        raise ConfigError(
            "numerics.steady: a scan sets each pixel's steady state with scan.steady; remove numerics.steady"
        )
    extract = _extract(raw.get(EXTRACT_SECTION))
    force = extract.get("force", DEFAULT_FORCE)
    spec = parse_scan(raw.get("scan"), extract)
    sample = parse_sample(raw.get("sample"))
    point = from_dict({**{s: raw[s] for s in POINT_SECTIONS if s in raw}, "surface": sample.background})
    if point.numerics.temperature:  # a label is a claim: the pixels would be recorded without it
        raise ConfigError(
            f"numerics.temperature: {point.numerics.temperature:g} K is not allowed in a scan; expected 0 (the scan's "
            "pixels are recorded without thermal noise; the detector keys act: with numerics.instrument thermal or lab "
            "set numerics.temperature: 0)"
        )
    _check_cross(point, spec, sample)
    name = str(raw.get("name") or name)
    description = str(raw.get("description") or "")
    resolved = _resolved(name, description, point, spec, sample, force)
    return ScanConfig(name, description, point, spec, sample, force, resolved)


def _resolved(name, description, point: Config, spec: ScanSpec, sample: Sample, force: str) -> dict:
    """The re-runnable config: every key resolved (the ``numerics.steady`` default left out)."""
    pd = point.to_dict()
    pd["numerics"].pop("steady")
    r = spec.raster
    out: dict = {"name": name}
    if description:
        out["description"] = description
    out.update({s: pd[s] for s in POINT_SECTIONS})
    out[EXTRACT_SECTION] = {"force": force}

    def one(v):
        return v[0] if len(v) == 1 else list(v)

    out["scan"] = {"pixels": [r.nx, r.ny], "size": [r.size_x, r.size_y], "pixel_time": one(spec.pixel_times),
                   "steady": one(spec.steady), "methods": list(spec.methods)}  # fmt: skip
    out["sample"] = {"background": {"height": sample.height, **sample.background},
                     "features": [f.to_dict() for f in sample.features]}  # fmt: skip
    return out


# ----------------------------------------------------------------------------- files and overrides


def set_path(d: dict, key: str, value: Any) -> None:
    """Set a dotted ``key`` in the nested config ``d`` (list items by index:
    ``sample.features.0.height``); ConfigError (one line) when the path does not exist."""
    parts = key.split(".")
    if len(parts) < 2 or parts[0] not in TOP_KEYS or parts[0] in META_KEYS:
        raise ConfigError(f"--set {key}: unknown key; keys are section.name with section in "
                          f"{', '.join(s for s in TOP_KEYS if s not in META_KEYS)}")  # fmt: skip
    node: Any = d
    for i, part in enumerate(parts[:-1]):
        nxt = parts[i + 1]
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                raise ConfigError(
                    f"--set {key}: {'.'.join(parts[:i])} has {len(node)} items; {part!r} is not one of them"
                )
            node = node[int(part)]
            continue
        if not isinstance(node, dict):
            raise ConfigError(f"--set {key}: {'.'.join(parts[:i])} is not a section")
        if part not in node or node[part] is None:
            node[part] = [] if nxt.isdigit() else {}
        node = node[part]
    last = parts[-1]
    if isinstance(node, list):
        if not last.isdigit() or int(last) >= len(node):
            raise ConfigError(f"--set {key}: {'.'.join(parts[:-1])} has {len(node)} items; {last!r} is not one of them")
        node[int(last)] = value
    elif isinstance(node, dict):
        node[last] = value
    else:
        raise ConfigError(f"--set {key}: {'.'.join(parts[:-1])} is not a section")


def load_scan(path: str | Path, overrides: dict | None = None) -> ScanConfig:
    """Read and validate a scan YAML (``overrides``: dotted keys); the name defaults to the file stem."""
    raw = copy.deepcopy(read_yaml(path))
    for key, value in (overrides or {}).items():
        set_path(raw, key, value)
    return build(raw, name=Path(path).stem)


def dump(cfg: ScanConfig) -> str:
    """The resolved config as YAML (``<output stem>.config.yaml``)."""
    return yaml.safe_dump(cfg.resolved, sort_keys=False)
