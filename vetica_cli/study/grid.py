"""Expand a study config (single-point schema + ``sweep:`` block) into points.

A study config is a single-point config (sections ``probe``, ``operation``,
``surface``, ``numerics``; see :mod:`vetica_cli.simulation.config`) plus, optionally,
``name``/``description`` strings and a ``sweep:`` block that maps dotted keys
to values::

    sweep:
      surface.cd: {logspace: [-5, 3, 33]}        # 10**linspace(-5, 3, 33)
      surface.stiffness_ratio: [0.125, 1, 32]    # a plain list
      operation.setpoint: {linspace: [0.25, 0.8, 5]}
      zip:                                       # varied together, one factor
        probe.f1: [10e3, 50e3]
        numerics.max_time: [0.05, 0.01]

Keys combine as a cartesian product in the order they are written (the first
key varies slowest); a ``zip:`` group (a mapping, or a list of mappings for
several groups) is one factor whose lists have equal lengths.  ``replicas: N`` (not a
key) records every point N times with independent noise (a noisy point: thermal or
detector noise) and summarises them in its rows (:mod:`vetica_cli.rows.replicas`).

Derived keys (thesis ch. 4) may be swept or set in the base sections:

* ``surface.stiffness_ratio`` sets ``surface.k0 = ratio * surface.k_inf``
  (thesis 4.4.2: ``k0:k_inf`` from 1:8 to 32:1 at ``k_inf = 4 N/m``);
* ``probe.f2_ratio`` sets ``probe.f2 = ratio * probe.f1`` (thesis 4.5.1:
  ``f2 = 15 f1``).

A value in the sweep block overrides the base; a derived key and its target
(``stiffness_ratio`` and ``k0``) may not both be set in the same layer.
Logspace/linspace values are rounded to 12 significant digits so that the
table shows ``1e-05``, not ``1.0000000000000001e-05``.

Extraction keys name how each point is analysed, not what is
simulated; they may be swept or set in an ``extract:`` section of the base:

* ``extract.method``: a registered extraction method (:mod:`vetica_cli.extraction`:
  ``vetica``, thesis 3.3, the default; ``full``, the whole-cycle model
  inversion).  Points that differ only in the method share one simulation
  (see :mod:`vetica_cli.rows.plan`).
* ``extract.force``: ``both`` (the default: the simulator's true force and the
  force reconstructed from the paddle signal, one row each), ``true`` or
  ``reconstructed`` (one row).  E.g. with detector noise the reconstruction at
  the Nyquist cut-off is hopeless and costly; zip it with the noise key.

The optional ``material:`` section sets the contact model of the table's material
columns (thesis 4.6.2, table 6; :mod:`vetica_cli.extraction.material`): ``tip_radius``
(default: each point's ``probe.tip_radius``), ``nu_tip``, ``nu_sample``, ``e_tip``.
It is applied when the table is assembled, so changing it recomputes no point
(``--set material.nu_sample=0.45`` works too).

Every problem raises :class:`ConfigError` with one line before any job starts:
unknown key, bad range, empty grid, an invalid point (with the point named),
duplicate points.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .. import __version__
from ..checks import MAX_POINTS, MAX_VALUES_PER_KEY, finite, number
from ..errors import ConfigError
from ..extraction import DEFAULT_METHOD, METHODS
from ..extraction.material import CONTACT_KEYS, contact_model
from ..simulation.config import (
    DERIVED,
    SECTIONS,
    Config,
    defaults,
    from_dict,
    item_key,
    read_yaml,
    resolve_derived,
    section_names,
)
from ..rows.extract import EXTRACT_KEYS, EXTRACT_SECTION, META_KEYS, check_extract_value, extract_section
from ..surfaces import DEFAULT_MODEL, MODELS

MATERIAL_SECTION = "material"  # contact model of the material columns (applied at assembly)
RANGE_FORMS = ("logspace", "linspace")
CHECKED_VALUES = 2000  # values of one factor the dry run resolves (spread over it, first and last included)


def config_keys() -> list[str]:
    """Every dotted key of the single-point schema, in declaration order."""
    return [f"{sec}.{name}" for sec in SECTIONS for name in section_names(sec)]


def sweepable_keys() -> list[str]:
    """Keys allowed in a ``sweep:`` block: the schema keys, derived keys and extraction keys
    (and the surface models' item keys, e.g. ``surface.arms.1.cd``: :func:`item_key`)."""
    return config_keys() + list(DERIVED) + list(EXTRACT_KEYS)


def allowed_text() -> str:
    """The sweepable keys for an error message, item patterns included."""
    items = [m.item_help for m in MODELS.values() if m.item_help]
    return ", ".join(sweepable_keys() + items)


@dataclass(frozen=True)
class Point:
    """One point of a study: its swept values and its resolved config."""

    index: int  # position in the grid (cartesian order)
    values: dict  # swept key -> value, in column order
    config: Config
    key: str  # hash of the resolved config and the extraction method (names the persisted part)
    method: str = DEFAULT_METHOD  # extract.method: how the point's run is analysed
    force: str = "both"  # extract.force: which force sources are extracted
    replicas: int = 1  # sweep.replicas: independent noisy recordings of the point, summarised in its rows

    def label(self) -> str:
        return ", ".join(f"{k}={v!r}" for k, v in self.values.items())


@dataclass(frozen=True)
class Study:
    name: str
    description: str
    keys: tuple  # swept keys, column order
    points: tuple  # of Point
    base: dict  # base sections as given (after overrides), derived keys included
    sweep: dict  # the sweep block as given
    extract: dict = None  # the base 'extract:' section as given (after overrides), e.g. {"method": "full"}
    material: dict = None  # the 'material:' section as given (after overrides), e.g. {"nu_sample": 0.45}
    replicas: int = 1  # sweep.replicas

    def resolved(self) -> dict:
        """A re-runnable study config: every base key resolved, sweep block as given."""
        # defaults filled in without validating the base alone: only the points
        # (base + sweep values) need to be valid configs
        clean, derived = _split_derived(self.base)
        base = defaults(_model_of(clean))
        for sec, body in clean.items():
            base[sec].update(body or {})
        for dkey, value in derived.items():
            sec, name = dkey.split(".")
            target = DERIVED[dkey][0].split(".")[1]
            base[sec].pop(target, None)
            base[sec][name] = value
        out = {"name": self.name}
        if self.description:
            out["description"] = self.description
        out.update(base)
        if self.extract:
            out[EXTRACT_SECTION] = dict(self.extract)
        if self.material:
            out[MATERIAL_SECTION] = dict(self.material)
        out["sweep"] = self.sweep
        return out


def point_key(cfg: Config, method: str = DEFAULT_METHOD, force: str = "both", replicas: int = 1) -> str:
    """Stable 16-hex hash of a resolved point config (and the package version),
    and of the extraction keys that are not the default (so points with the
    default extraction keep the keys they had before extraction keys existed)."""
    d = {"version": __version__, "config": cfg.to_dict()}
    if method != EXTRACT_KEYS["extract.method"][1]:
        d["method"] = method
    if force != EXTRACT_KEYS["extract.force"][1]:
        d["force"] = force
    if replicas != 1:
        d["replicas"] = replicas
    blob = json.dumps(d, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def _num(key: str, v: Any, what: str) -> float:
    return finite(f"sweep.{key}: {what}", v)


def _clean(x: float) -> float:
    return float(f"{x:.12g}")


def parse_values(key: str, spec: Any) -> list:
    """Values of one sweep entry: a list, ``{logspace: [e1, e2, n]}`` or ``{linspace: [a, b, n]}``."""
    if isinstance(spec, list):
        if not spec:
            raise ConfigError(f"sweep.{key}: empty list (empty grid); expected at least one value")
        if len(spec) > MAX_VALUES_PER_KEY:
            raise ConfigError(f"sweep.{key}: {len(spec)} values are not allowed; expected at most {MAX_VALUES_PER_KEY}")
        return list(spec)
    if isinstance(spec, dict) and len(spec) == 1 and next(iter(spec)) in RANGE_FORMS:
        form, args = next(iter(spec.items()))
        if not isinstance(args, list) or len(args) != 3:
            raise ConfigError(
                f"sweep.{key}: {form} {args!r} is not allowed; expected [first, last, n]"
                + (" with exponents of 10" if form == "logspace" else "")
            )
        a = _num(key, args[0], f"{form} first")
        b = _num(key, args[1], f"{form} last")
        n = number(args[2])
        if isinstance(n, bool) or not isinstance(n, (int, float)) or not math.isfinite(float(n)) or n != int(n) or n < 0:
            raise ConfigError(f"sweep.{key}: {form} count {args[2]!r} is not allowed; expected an integer >= 1")
        n = int(n)
        if n == 0:
            raise ConfigError(f"sweep.{key}: {form} with 0 points (empty grid); expected n >= 1")
        if n > MAX_VALUES_PER_KEY:
            raise ConfigError(f"sweep.{key}: {form} count {n} is not allowed; expected at most {MAX_VALUES_PER_KEY} "
                              "values of one key (combine keys instead: the grid is their product)")  # fmt: skip
        if n == 1 and a != b:
            raise ConfigError(
                f"sweep.{key}: {form} [{args[0]}, {args[1]}, 1] is ambiguous; use n >= 2 or first == last"
            )
        step = (b - a) / (n - 1) if n > 1 else 0.0
        lin = [a + i * step for i in range(n)]
        if n > 1:
            lin[-1] = b
        if form == "logspace":
            if max(abs(a), abs(b)) > 300:
                raise ConfigError(
                    f"sweep.{key}: logspace exponents {a:g}..{b:g} are out of range; expected |exponent| <= 300"
                )
            return [_clean(10.0**x) for x in lin]
        return [_clean(x) for x in lin]
    raise ConfigError(
        f"sweep.{key}: {spec!r} is not allowed; expected a list, {{logspace: [first_exponent, last_exponent, n]}} "
        "or {linspace: [first, last, n]}"
    )


def _check_key(key: Any) -> str:
    if not isinstance(key, str) or (key not in sweepable_keys() and not item_key(key)):
        raise ConfigError(f"sweep: unknown key {key!r}; allowed: {allowed_text()}")
    return key


def _factors(sweep: Any) -> tuple[list[str], list[list[dict]]]:
    """Sweep block -> (column keys, factors); each factor is a list of {key: value} assignments."""
    if sweep is None:
        raise ConfigError("the study has no 'sweep:' block (empty grid); use 'vetica simulate' for one point")
    if not isinstance(sweep, dict):
        raise ConfigError(f"sweep: must be a mapping of dotted keys to values, got {type(sweep).__name__}")
    if not sweep:
        raise ConfigError("sweep: empty block (empty grid); expected at least one swept key")
    keys: list[str] = []
    factors: list[list[dict]] = []

    def add_key(k):
        if k in keys:
            raise ConfigError(f"sweep: key {k!r} appears twice")
        keys.append(k)

    for key, spec in sweep.items():
        if key == "zip":
            groups = spec if isinstance(spec, list) else [spec]
            for g in groups:
                if not isinstance(g, dict) or not g:
                    raise ConfigError(
                        "sweep.zip: expected a mapping of dotted keys to lists (or a list of such mappings)"
                    )
                cols = {}
                for k, s in g.items():
                    add_key(_check_key(k))
                    cols[k] = parse_values(k, s)
                lengths = {k: len(v) for k, v in cols.items()}
                if len(set(lengths.values())) > 1:
                    desc = ", ".join(f"{k} has {n}" for k, n in lengths.items())
                    raise ConfigError(f"sweep.zip: lists must have equal lengths ({desc})")
                n = next(iter(lengths.values()))
                factors.append([{k: cols[k][i] for k in cols} for i in range(n)])
        else:
            add_key(_check_key(key))
            factors.append([{key: v} for v in parse_values(key, spec)])
    for factor in factors:  # extraction keys take names, not numbers: check them here
        for assign in factor:
            for k, v in assign.items():
                if k in EXTRACT_KEYS:
                    assign[k] = check_extract_value(k, v, f"sweep.{k}")
        _no_repeats(factor)
    for dkey, (target, _) in DERIVED.items():
        if dkey in keys and target in keys:
            raise ConfigError(f"sweep: {dkey} and {target} are both swept; sweep one of them")
    return keys, factors


def _no_repeats(factor: list[dict]) -> None:
    """ConfigError (one line) for a value given twice in one factor (e.g. ``extract.method:
    [vetica, vetica]``): its points would be duplicates."""
    keys = list(factor[0])
    try:
        idents = [a[keys[0]] for a in factor] if len(keys) == 1 else [tuple(a[k] for k in keys) for a in factor]
        if len(set(idents)) == len(idents):
            return
    except TypeError:  # unhashable values (a list of arms): the point keys catch duplicates
        return
    seen: set = set()
    for assign, ident in zip(factor, idents):
        if ident in seen:
            what = ", ".join(f"{k}={v!r}" for k, v in assign.items())
            raise ConfigError(f"sweep: {what} appears twice; expected each value once")
        seen.add(ident)


def _split_derived(base: dict) -> tuple[dict, dict]:
    """Base sections -> (schema-only sections, {derived dotted key: value})."""
    clean, derived = {}, {}
    for sec, body in base.items():
        if isinstance(body, dict):
            body = dict(body)
            for dkey in DERIVED:
                dsec, dname = dkey.split(".")
                if dsec == sec and dname in body:
                    derived[dkey] = body.pop(dname)
        clean[sec] = body
    for dkey, (target, _) in DERIVED.items():
        tsec, tname = target.split(".")
        if dkey in derived and isinstance(clean.get(tsec), dict) and tname in clean[tsec]:
            raise ConfigError(f"{dkey} and {target} are both set in the base config; set one of them")
    return clean, derived


def _resolve(base_clean: dict, base_derived: dict, assign: dict) -> dict:
    """Nested config dict for one point: base, then swept values, then derived keys."""
    d = {sec: dict(body) if isinstance(body, dict) else body for sec, body in base_clean.items()}
    derived = dict(base_derived)
    for key, value in assign.items():
        if key in DERIVED:
            derived[key] = value
            # a swept derived key overrides an explicit target in the base
            tsec, tname = DERIVED[key][0].split(".")
            if isinstance(d.get(tsec), dict):
                d[tsec].pop(tname, None)
        else:
            sec, name = key.split(".", 1)  # name may be an item path, e.g. arms.1.cd
            if key in (t for t, _ in DERIVED.values()):
                # a swept target overrides a derived key in the base
                for dk, (t, _) in DERIVED.items():
                    if t == key:
                        derived.pop(dk, None)
            d.setdefault(sec, {})
            if not isinstance(d[sec], dict):
                raise ConfigError(f"section {sec!r} must be a mapping, got {d[sec]!r}")
            d[sec][name] = value
    resolve_derived(d, derived)
    return d


@dataclass(frozen=True)
class Grid:
    """A study before its points are resolved: the base, the swept keys and their factors
    (one list of assignments per cartesian factor).  Cheap to build whatever the size of
    the grid, so the point count, the cost estimate (``--dry-run``) and the size guard
    come before the points are resolved one by one (:meth:`points`)."""

    name: str
    description: str
    keys: tuple  # swept keys, column order
    factors: tuple  # of lists of {key: value} assignments
    base: dict  # base sections as given (after overrides), derived keys included
    base_clean: dict  # base sections without derived keys
    base_derived: dict  # derived dotted key -> value set in the base
    sweep: Any  # the sweep block as given
    extract: dict  # the base 'extract:' section (after overrides)
    material: dict = None  # the 'material:' section (after overrides)
    replicas: int = 1  # sweep.replicas: noisy recordings of each point

    @property
    def n_points(self) -> int:
        return math.prod(len(f) for f in self.factors)

    def check_size(self) -> None:
        """ConfigError (one line) for a grid over :data:`vetica_cli.checks.MAX_POINTS` points."""
        if self.n_points > MAX_POINTS:
            raise ConfigError(f"sweep: {self.n_points} points are not allowed; expected at most {MAX_POINTS} "
                              f"(the product of {' x '.join(str(len(f)) for f in self.factors)} values)")  # fmt: skip

    def assignment(self, index: int) -> dict:
        """The swept assignments of point ``index`` (cartesian order, the first factor slowest)."""
        assign: dict = {}
        digits = []
        for f in reversed(self.factors):
            index, j = divmod(index, len(f))
            digits.append(j)
        for f, j in zip(self.factors, reversed(digits)):
            assign.update(f[j])
        return assign

    def point(self, index: int, assign: dict | None = None) -> Point:
        """Point ``index`` resolved and validated (ConfigError naming the point)."""
        assign = self.assignment(index) if assign is None else assign
        return _point(index, list(self.keys), assign, self.extract, self.base_clean, self.base_derived, self.replicas)

    def check_values(self, limit: int = CHECKED_VALUES) -> int:
        """Resolve, for swept values, the point that has it and the first value of every other
        factor: each value is checked against the base (range, type, the model's rules) in
        ``sum(len(factor))`` resolutions instead of one per point.  A factor of more than
        ``limit`` values (a range of a million) is checked at ``limit`` values spread over it,
        its first and last included, so the dry run answers in seconds; the sweep checks every
        point before it starts (:meth:`points`), as it checks combinations (e.g. a print step
        against a swept dt).  Returns how many values were checked."""
        strides = [math.prod(len(f) for f in self.factors[i + 1 :]) for i in range(len(self.factors))]
        checked = 0
        for stride, f in zip(strides, self.factors):
            n = len(f)
            picks = range(n) if n <= limit else sorted({round(i * (n - 1) / (limit - 1)) for i in range(limit)})
            for j in picks:
                self.point(j * stride)
                checked += 1
        return checked

    def points(self, on_progress=None) -> tuple:
        """Every point, resolved and validated, in grid order; ConfigError for an invalid or a
        duplicate point.  ``on_progress(done)`` is called every 10000 points."""
        points = []
        seen: dict[str, int] = {}
        for i, combo in enumerate(itertools.product(*self.factors)):
            assign: dict = {}
            for part in combo:
                assign.update(part)
            p = self.point(i, assign)
            if p.key in seen:
                label = ", ".join(f"{k}={assign[k]!r}" for k in self.keys)
                raise ConfigError(
                    f"points {seen[p.key]} and {i} ({label}) resolve to the same config; remove the duplicate"
                )
            seen[p.key] = i
            points.append(p)
            if on_progress is not None and (i + 1) % 10000 == 0:
                on_progress(i + 1)
        return tuple(points)

    def study(self, on_progress=None) -> Study:
        """The :class:`Study` with every point resolved (:meth:`points`)."""
        return Study(name=self.name, description=self.description, keys=self.keys, points=self.points(on_progress),
                     base=self.base, sweep=self.sweep, extract=self.extract, material=self.material,
                     replicas=self.replicas)  # fmt: skip


def grid(raw: dict, name: str = "study", overrides: dict | None = None) -> Grid:
    """Study config mapping -> :class:`Grid`: the top-level keys, the sweep block, the
    extract section and the overrides checked; no point resolved yet."""
    if not isinstance(raw, dict):
        raise ConfigError(f"a study config must be a mapping, got {type(raw).__name__}")
    allowed_top = set(SECTIONS) | {EXTRACT_SECTION, MATERIAL_SECTION, "sweep", *META_KEYS}
    for k in raw:
        if k not in allowed_top:
            allowed = ", ".join([*SECTIONS, EXTRACT_SECTION, MATERIAL_SECTION, "sweep", *META_KEYS])
            raise ConfigError(f"unknown top-level key {k!r}; allowed: {allowed}")
    name = str(raw.get("name") or name)
    description = str(raw.get("description") or "")
    sweep = raw.get("sweep")
    base = {k: (dict(v) if isinstance(v, dict) else v) for k, v in raw.items() if k in SECTIONS}
    extract = extract_section(raw.get(EXTRACT_SECTION))
    material = _material_section(raw.get(MATERIAL_SECTION))
    replicas = 1
    if isinstance(sweep, dict) and "replicas" in sweep:
        replicas = _replicas(sweep["replicas"])
        sweep = {k: v for k, v in sweep.items() if k != "replicas"}
    keys, factors = _factors(sweep)
    overrides = dict(overrides or {})
    for key in [k for k in overrides if k.startswith(MATERIAL_SECTION + ".")]:
        material[key.split(".", 1)[1]] = overrides.pop(key)
    material = _material_section(material, "--set material")
    _apply_overrides(base, extract, keys, overrides)
    base_clean, base_derived = _split_derived(base)
    g = Grid(name=name, description=description, keys=tuple(keys), factors=tuple(factors), base=base,
                base_clean=base_clean, base_derived=base_derived, sweep=raw.get("sweep"), extract=extract,
                material=material, replicas=replicas)  # fmt: skip
    g.check_size()
    return g


MAX_REPLICAS = 200  # sweep.replicas: noisy recordings of one point (coverage of a 2-sigma claim needs ~30)


def _replicas(value: Any) -> int:
    """``sweep.replicas``: an integer in 1..MAX_REPLICAS; ConfigError (one line) otherwise."""
    v = number(value)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)) or v != int(v) or not (
            1 <= v <= MAX_REPLICAS):  # fmt: skip
        raise ConfigError(f"sweep.replicas: {value!r} is not allowed; expected an integer in 1..{MAX_REPLICAS}")
    return int(v)


def expand(raw: dict, name: str = "study", overrides: dict | None = None) -> Study:
    """Study config mapping -> :class:`Study` with every point resolved and validated."""
    return grid(raw, name, overrides).study()


def _apply_overrides(base: dict, extract: dict, keys: list, overrides: dict) -> None:
    """``--set`` overrides into the base sections and the extract section (not on swept keys)."""
    for key, value in overrides.items():
        if key in keys:
            raise ConfigError(f"--set {key}: the key is swept by the study; change its sweep entry instead")
        if key not in sweepable_keys() and not item_key(key):
            raise ConfigError(f"unknown key {key!r}; allowed: {allowed_text()}")
        sec, kname = key.split(".", 1)
        if key in EXTRACT_KEYS:
            extract[kname] = check_extract_value(key, value, f"--set {key}")
            continue
        base.setdefault(sec, {})
        if not isinstance(base[sec], dict):
            raise ConfigError(f"section {sec!r} must be a mapping, got {base[sec]!r}")
        base[sec][kname] = value


def _point(i: int, keys: list, assign: dict, extract: dict, base_clean: dict, base_derived: dict,
           replicas: int = 1) -> Point:  # fmt: skip
    """Point ``i`` of the grid from its swept assignments: config resolved and validated,
    extraction keys from the assignment or the base ``extract:`` section."""
    values = {k: assign[k] for k in keys}
    label = ", ".join(f"{k}={v!r}" for k, v in values.items())
    ext = {**{k: extract.get(k.split(".")[1], d) for k, (_, d) in EXTRACT_KEYS.items()},
           **{k: v for k, v in assign.items() if k in EXTRACT_KEYS}}  # fmt: skip
    try:
        cfg = from_dict(_resolve(base_clean, base_derived, {k: v for k, v in assign.items() if k not in EXTRACT_KEYS}))
    except ConfigError as exc:
        raise ConfigError(f"point {i} ({label}): {exc}") from None
    method, force = ext["extract.method"], ext["extract.force"]
    # swept values as the config resolved them (e.g. '1e-4' -> 1e-4)
    resolved = {}
    for k in keys:
        if k in DERIVED:
            resolved[k] = _num(k, values[k], "value")
        elif k in EXTRACT_KEYS:
            resolved[k] = values[k]
        else:
            sec, nm = k.split(".", 1)
            resolved[k] = getattr(getattr(cfg, sec), nm)
    if cfg.surface.model not in METHODS[method].surface_models:
        surface = cfg.surface.surface_model.describe(cfg.surface.params)
        able = [k for k, m in METHODS.items() if cfg.surface.model in m.surface_models]
        raise ConfigError(f"point {i} ({label}): extract.method {method!r} cannot extract {surface} (it extracts: "
                          f"{', '.join(METHODS[method].surface_models)}); expected extract.method: "
                          f"{' or '.join(able) or 'none registered'}")  # fmt: skip
    if replicas > 1 and not _noisy(cfg):
        raise ConfigError(f"point {i} ({label}): sweep.replicas {replicas} needs a noisy record (numerics.temperature, "
                          "detector noise or numerics.instrument: lab); this point is noise-free, so every replica "
                          "would be the same")  # fmt: skip
    return Point(index=i, values=resolved, config=cfg, key=point_key(cfg, method, force, replicas), method=method,
                 force=force, replicas=replicas)  # fmt: skip


def _noisy(cfg: Config) -> bool:
    """Whether a point's record carries noise that a replica draws anew."""
    n = cfg.numerics
    return bool(n.temperature or n.position_noise or n.force_noise or n.detector_noise_density or n.adc_resolution)


def _model_of(sections: dict) -> str:
    """The surface model a study's (base or point) sections name (the default when they name none)."""
    surface = sections.get("surface")
    model = surface.get("model") if isinstance(surface, dict) else None
    return model if isinstance(model, str) and model in MODELS else DEFAULT_MODEL


def load_grid(path: str | Path, overrides: dict | None = None) -> Grid:
    """Read a study YAML as a :class:`Grid` (no point resolved); the name defaults to the file stem."""
    return grid(read_yaml(path), name=Path(path).stem, overrides=overrides)


def _material_section(body: Any, where: str = MATERIAL_SECTION) -> dict:
    """The ``material:`` section, checked (keys of the contact model, values in range):
    ``{key: float}``; ConfigError (one line) otherwise."""
    if body is None:
        return {}
    if not isinstance(body, dict):
        raise ConfigError(f"section {MATERIAL_SECTION!r} must be a mapping of {', '.join(CONTACT_KEYS)}, got {body!r}")
    cm = contact_model(body, where=where)
    return {k: getattr(cm, k) for k in body}


def load_study(path: str | Path, overrides: dict | None = None) -> Study:
    """Read and expand a study YAML; the study name defaults to the file stem."""
    return load_grid(path, overrides).study()
