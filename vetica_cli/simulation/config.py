"""Configuration of one simulation point: YAML -> frozen dataclasses.

Every default and every validation of the probe, operation and numerics
sections lives here; the ``surface:`` section is validated by its surface model
(:mod:`vetica_cli.surfaces`: ``surface.model``, default ``sls``, plus the
model's keys) and the attraction keys common to every model.  Defaults are the
thesis's worked example (thesis tables 2-4).  All values are SI.

A config error raises :class:`ConfigError` with one line naming the key, the
value and what is allowed; the CLI turns it into exit status 2 before any work.
"""

from __future__ import annotations

import copy
import functools
import json
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import yaml

from .. import surfaces
from ..checks import MAX_CYCLES, MAX_ORBIT_PERIODS, MAX_SEED, MAX_YAML_BYTES, check, coerce, limit, load_yaml, number
from ..checks import nonneg as _nonneg
from ..checks import one_of
from ..checks import open_unit as _open_unit
from ..checks import positive as _positive
from ..constants import TIP_RADIUS
from ..errors import ConfigError
from ..surfaces import COMMON_KEYS, DEFAULT_MODEL


@dataclass(frozen=True)
class Probe:
    """Torsional Harmonic Cantilever (thesis 2.4.2, table 1)."""

    f1: float = 50e3  # flexural resonance [Hz]
    f2: float = 750e3  # torsional (paddle) resonance [Hz]
    k1: float = 10.0  # flexural stiffness [N/m]
    k2: float = 700.0  # torsional stiffness [N/m]
    q1: float = 100.0  # flexural quality factor (air)
    q2: float = 1000.0  # torsional quality factor (air)
    tip_radius: float = TIP_RADIUS  # [m]


@dataclass(frozen=True)
class Operation:
    """Amplitude-modulation operation (thesis 3.1.2)."""

    free_amplitude: float = 100e-9  # A0 [m]
    setpoint: float = 0.7  # A_sp / A0, in (0, 1)
    base_height: float | None = None  # fixed Zb [m]; null = PI amplitude control


def _default_params() -> dict:
    return surfaces.get(DEFAULT_MODEL).parse({})


@dataclass(frozen=True)
class Surface:
    """The sample: a registered surface model with its parameters (``params``; for the
    default ``sls``: ``k_inf``, ``k0``, ``cd``, read as ``surface.k0`` too) and the van
    der Waals attraction every model shares (thesis 3.2, eq. 3)."""

    params: dict = field(default_factory=_default_params)  # the model's keys (surfaces.<model>)
    hamaker: float = COMMON_KEYS["hamaker"].default  # Hamaker constant H [J]
    a0: float = COMMON_KEYS["a0"].default  # intermolecular distance [m]
    vdw_on_surface: bool = COMMON_KEYS["vdw_on_surface"].default  # van der Waals also pulls the surface
    model: str = DEFAULT_MODEL  # surface.model: key of the surface model (vetica_cli.surfaces)

    def __getattr__(self, name: str):
        params = self.__dict__.get("params")
        if params is not None and name in params:
            return params[name]
        if params is not None and "." in name:  # an item of a non-scalar key, e.g. arms.1.cd
            return surfaces.get(self.__dict__.get("model")).get_item(params, name)
        raise AttributeError(f"surface ({self.__dict__.get('model')}) has no key {name!r}")

    @property
    def surface_model(self) -> surfaces.SurfaceModel:
        """The surface model specialised to these parameters (e.g. the number of arms)."""
        return surfaces.get(self.model).for_params(self.params)

    def __hash__(self) -> int:  # params may hold lists (arms): hash the section as written
        return hash(json.dumps(self.to_dict(), sort_keys=True))

    def to_dict(self) -> dict:
        """The section as written in YAML and in the metadata: the model's keys, then the
        common ones; ``model`` only when it is not the default, so an SLS section (and the
        hashes and metadata made from it) reads exactly as in version 0.1."""
        d = {} if self.model == DEFAULT_MODEL else {"model": self.model}
        d.update(copy.deepcopy(self.params))
        d.update(hamaker=self.hamaker, a0=self.a0, vdw_on_surface=self.vdw_on_surface)
        return d


@dataclass(frozen=True)
class Numerics:
    """Integration, control, steady-state detection and recording."""

    dt: float = 0.025e-9  # integration step [s] (thesis: 0.025 ns for every run)
    print_step: float = 0.125e-9  # sampling interval of the records [s]
    record_cycles: int = 10  # steady drive periods recorded
    steady: str = "orbit"  # orbit: solve the periodic orbit | transient: time-step it, as an instrument does
    integrator: str = "hybrid"  # hybrid: exact propagation away from the surface | verlet: all fine steps
    switch_gap: float = 2e-9  # hybrid: gap [m] below which (and in contact) only fine steps are taken (scripts/hybrid_vs_verlet.py)
    tol_orbit: float = 1e-13  # steady: per-period state change and mean arm stretch <= tol_orbit [m]
    orbit_max_periods: int = 150  # period evaluations of the orbit solver's first strategy
    max_time: float = 0.03  # simulated-time budget of the approach and of the transient [s]
    kp: float = 0.2  # PI proportional gain [m per m of amplitude error]
    ki: float = 0.05  # PI integral gain [m per m of amplitude error per period]
    tol_amp: float = 2e-5  # steady: |A - A_sp| <= tol_amp * A_sp
    tol_z: float = 1e-12  # transient: contact position changes <= tol_z per period [m] count as settled
    settle_cycles: int = 10  # transient: settled periods before a window is recorded and put to the proof
    warm_start: bool = True  # start oscillating at A_sp just above the surface
    approach_gap: float = 0.5e-9  # initial clearance of the lowest tip point [m]
    approach_rate: float = 0.0  # base descent before the first contact [m/s]
    approach_cycles: float = 2.0  # length of the recorded first-approach window [periods]
    position_noise: float = 0.0  # RMS detector noise on z_cantilever, z_paddle (and so z_tip) [m]
    force_noise: float = 0.0  # RMS noise on the recorded f_ts [N]
    noise_seed: int = 0  # seed of the noise generator (same seed -> same noise)
    detector_bandwidth: float = 0.0  # one-pole low-pass of the position detector [Hz]; 0 = infinite
    adc_resolution: float = 0.0  # quantisation step of the recorded deflections [m]; 0 = none
    temperature: float = 0.0  # thermal (Brownian) noise of the probe modes in the recorded periods [K]; 0 = none
    detector_noise_density: float = 0.0  # white displacement noise of the detector, before its bandwidth [m/sqrt(Hz)]
    instrument: str = "thesis"  # preset of the keys above (INSTRUMENTS): thesis (noise-free) | thermal | lab


@dataclass(frozen=True)
class Config:
    probe: Probe = field(default_factory=Probe)
    operation: Operation = field(default_factory=Operation)
    surface: Surface = field(default_factory=Surface)
    numerics: Numerics = field(default_factory=Numerics)

    def to_dict(self) -> dict:
        return {  # the probe, operation and numerics fields are scalars: a shallow copy is dataclasses.asdict
            "probe": _shallow(self.probe),
            "operation": _shallow(self.operation),
            "surface": self.surface.to_dict(),
            "numerics": _shallow(self.numerics),
        }

    def with_overrides(self, overrides: dict[str, Any]) -> "Config":
        """New config with dotted-key overrides applied and validated."""
        d = self.to_dict()
        new = overrides.get("numerics.instrument")
        if new is not None and new != self.numerics.instrument and new in INSTRUMENTS:
            old = INSTRUMENTS.get(self.numerics.instrument, {})
            for k, v in INSTRUMENTS[new].items():  # a key still at the old preset's value follows the new preset
                if f"numerics.{k}" not in overrides and d["numerics"].get(k) == old.get(k):
                    d["numerics"][k] = v
        for key, value in overrides.items():
            _set_dotted(d, key, value)
        return from_dict(d)


@functools.lru_cache(maxsize=None)
def _field_names(cls) -> tuple[str, ...]:
    return tuple(f.name for f in fields(cls))


def _shallow(obj) -> dict:
    return {name: getattr(obj, name) for name in _field_names(type(obj))}


SECTIONS = {"probe": Probe, "operation": Operation, "surface": Surface, "numerics": Numerics}

# derived keys (thesis ch. 4), settable in a study's base sections or swept: key -> (target, source),
# target = value * source: the probe's f2 = 15 f1 (thesis 4.5.1) and each surface model's own
DERIVED = {
    **{
        f"surface.{name}": (f"surface.{dk.target}", f"surface.{dk.source}")
        for model in surfaces.MODELS.values()
        for name, dk in model.derived_keys.items()
    },
    "probe.f2_ratio": ("probe.f2", "probe.f1"),
}

# key -> (predicate, description of what is allowed); physical ranges from the one table (vetica_cli.ranges),
# the surface's rules are its model's
RULES = {
    "probe.f1": limit("probe.f1"),
    "probe.f2": limit("probe.f2"),
    "probe.k1": limit("probe.k1"),
    "probe.k2": limit("probe.k2"),
    "probe.q1": limit("probe.q1"),
    "probe.q2": limit("probe.q2"),
    "probe.tip_radius": limit("probe.tip_radius"),
    "operation.free_amplitude": limit("operation.free_amplitude"),
    "operation.setpoint": limit("operation.setpoint"),
    "operation.base_height": (lambda v: v is None or v > 0, "null (PI control) or a height > 0 m"),
    "numerics.dt": limit("numerics.dt"),
    "numerics.print_step": limit("numerics.print_step"),
    "numerics.record_cycles": (lambda v: 1 <= v <= MAX_CYCLES, f"an integer in 1..{MAX_CYCLES}"),
    "numerics.steady": one_of("orbit", "transient"),
    "numerics.integrator": one_of("hybrid", "verlet"),
    "numerics.instrument": one_of("thesis", "thermal", "lab"),
    "numerics.switch_gap": (_positive, "a distance > 0 m"),
    "numerics.tol_orbit": (_positive, "a distance > 0 m"),
    "numerics.orbit_max_periods": (lambda v: 10 <= v <= MAX_ORBIT_PERIODS, f"an integer in 10..{MAX_ORBIT_PERIODS}"),
    "numerics.max_time": (_positive, "a time > 0 s"),
    "numerics.kp": (_nonneg, "a gain >= 0"),
    "numerics.ki": (_positive, "a gain > 0"),
    "numerics.tol_amp": (_open_unit, "a relative tolerance in (0, 1)"),
    "numerics.tol_z": (_positive, "a distance > 0 m"),
    "numerics.settle_cycles": (lambda v: 1 <= v <= MAX_CYCLES, f"an integer in 1..{MAX_CYCLES}"),
    "numerics.approach_gap": (_nonneg, "a distance >= 0 m"),
    "numerics.approach_rate": (_nonneg, "a speed >= 0 m/s"),
    "numerics.approach_cycles": (lambda v: 0 < v <= 20, "a number of periods in (0, 20]"),
    "numerics.position_noise": (_nonneg, "an RMS noise >= 0 m"),
    "numerics.force_noise": (_nonneg, "an RMS noise >= 0 N"),
    "numerics.noise_seed": (lambda v: 0 <= v <= MAX_SEED, f"an integer in 0..{MAX_SEED}"),
    "numerics.detector_bandwidth": (_nonneg, "a bandwidth >= 0 Hz (0 = infinite)"),
    "numerics.adc_resolution": (_nonneg, "a quantisation step >= 0 m (0 = none)"),
    "numerics.temperature": limit("numerics.temperature"),
    "numerics.detector_noise_density": limit("numerics.detector_noise_density"),
}


# Instrument presets (``numerics.instrument``): the recording chain as a named set of numerics keys.  A preset
# fills the keys a config leaves unset (a key set explicitly wins); ``thesis`` is the default, noise-free record.
INSTRUMENTS = {
    # the thesis's own records: noise-free, sampled every 0.125 ns (thesis table 1, sections 4.3-4.5)
    "thesis": {"temperature": 0.0, "detector_noise_density": 0.0, "detector_bandwidth": 0.0,
               "adc_resolution": 0.0, "print_step": 0.125e-9, "position_noise": 0.0, "force_noise": 0.0},
    # the thermal limit: the probe at room temperature read by a perfect detector (no noise, no band limit, no ADC)
    "thermal": {"temperature": 300.0, "detector_noise_density": 0.0, "detector_bandwidth": 0.0,
                "adc_resolution": 0.0, "print_step": 0.5e-9, "position_noise": 0.0, "force_noise": 0.0},
    # a room-temperature THC set-up (sources in INSTRUMENT_SOURCES and docs/noise.md)
    "lab": {"temperature": 300.0, "detector_noise_density": 50e-15, "detector_bandwidth": 5e6,
            "adc_resolution": 0.3e-12, "print_step": 2e-9, "position_noise": 0.0, "force_noise": 0.0},
}  # fmt: skip
INSTRUMENT_SOURCES = {
    "lab": {
        "temperature": "room temperature, 300 K: the Brownian force of each probe mode by fluctuation-dissipation "
                       "(2.4 pm RMS on the 700 N/m paddle, 20 pm on the 10 N/m cantilever)",
        "detector_noise_density": "50 fm/sqrt(Hz): good optical-beam-deflection detectors reach 10-100 fm/sqrt(Hz); "
                                  "17 fm/sqrt(Hz) is the lowest reported (Fukuma et al., Rev. Sci. Instrum. 76, "
                                  "053704, 2005)",
        "detector_bandwidth": "5 MHz: the photodetector and amplifier of a fast set-up (a few MHz), 100 drive "
                              "harmonics at 50 kHz",
        "print_step": "2 ns: a 500 MS/s digitiser, Nyquist 250 MHz, far above the detector band (the thesis samples "
                      "0.125-8 ns, table 1)",
        "adc_resolution": "0.3 pm: a 16-bit ADC over a +-10 nm range of the deflection channel (20 nm / 65536); the "
                          "cantilever's and paddle's thermal motion (20 and 2.4 pm RMS) dither it",
    },
    "thesis": {"print_step": "0.125 ns, noise-free: the thesis's records (thesis table 1)"},
    "thermal": {"temperature": "room temperature, 300 K, as lab; every detector term off: what thermal noise alone "
                               "leaves (the limit no detector improves on)",
                "print_step": "0.5 ns: the thesis's parametric studies (thesis ch. 4)"},
}  # fmt: skip


def apply_instrument_preset(numerics: dict) -> dict:
    """The numerics section with its ``instrument`` preset filling every preset key it does not set
    (a new dict; ConfigError for an unknown preset)."""
    name = numerics.get("instrument", "thesis")
    if name not in INSTRUMENTS:
        raise ConfigError(f"numerics.instrument: {name!r} is not allowed; expected one of: {', '.join(INSTRUMENTS)}")
    return {**INSTRUMENTS[name], **numerics}


def section_names(sec: str) -> list[str]:
    """The keys of a section; for ``surface``: ``model``, every registered model's keys
    (in registration order), then the keys common to every model."""
    if sec != "surface":
        return [f.name for f in fields(SECTIONS[sec])]
    names = ["model"]
    for model in surfaces.MODELS.values():
        names += [k for k in model.config_keys if k not in names]
    return names + list(COMMON_KEYS)


def item_key(key: str) -> bool:
    """Whether ``key`` is a dotted item of a surface model's non-scalar key, e.g. a Wiechert
    arm's ``surface.arms.1.cd`` (settable and sweepable; the model checks it)."""
    sec, _, name = key.partition(".")
    return sec == "surface" and any(m.item_key(name) for m in surfaces.MODELS.values())


def _set_dotted(d: dict, key: str, value: Any) -> None:
    sec, _, name = key.partition(".")
    if sec not in SECTIONS or not name or ("." in name and not item_key(key)):
        raise ConfigError(f"unknown key {key!r}; keys are section.name with section in {sorted(SECTIONS)}")
    allowed = section_names(sec)
    if name not in allowed and not item_key(key):
        raise ConfigError(f"unknown key {key!r}; allowed in {sec}: {', '.join(allowed)}")
    d.setdefault(sec, {})[name] = value


def from_dict(d: dict | None) -> Config:
    """Build and validate a Config from a nested dict (missing keys -> defaults)."""
    d = d or {}
    if not isinstance(d, dict):
        raise ConfigError(f"config must be a mapping of sections, got {type(d).__name__}")
    unknown = set(d) - set(SECTIONS)
    if unknown:
        raise ConfigError(f"unknown section {sorted(unknown)[0]!r}; allowed: {', '.join(SECTIONS)}")
    built = {}
    for sec, cls in SECTIONS.items():
        raw = d.get(sec)
        raw = {} if raw is None else raw  # an empty section; 0, '' or [] are not sections
        if not isinstance(raw, dict):
            raise ConfigError(f"section {sec!r} must be a mapping, got {raw!r}")
        if sec == "numerics" and "instrument" in raw:
            raw = apply_instrument_preset(raw)
        built[sec] = _surface(raw) if sec == "surface" else _section(sec, cls, raw)
    cfg = Config(**built)
    _check_cross(cfg)
    return cfg


def _section(sec: str, cls, raw: dict):
    """A probe, operation or numerics section: each key coerced to its field's type and checked."""
    kw = {}
    names = {f.name: f for f in fields(cls)}
    for name, value in raw.items():
        if name not in names:
            raise ConfigError(f"unknown key '{sec}.{name}'; allowed in {sec}: {', '.join(names)}")
        key = f"{sec}.{name}"
        kw[name] = check(key, value, coerce(key, value, str(names[name].type)), RULES.get(key))
    return cls(**kw)


def _surface(raw: dict) -> Surface:
    """The surface section: ``model`` picks the surface model, which validates its own keys
    (a model may hold non-scalar keys, e.g. a list of arms); the attraction keys are common."""
    model = surfaces.get(raw.get("model", DEFAULT_MODEL))
    allowed = ["model", *model.config_keys, *COMMON_KEYS]
    common, values, items = {}, {}, {}
    for name, value in raw.items():
        key = f"surface.{name}"
        if name == "model":
            continue
        if name in COMMON_KEYS:
            spec = COMMON_KEYS[name]
            common[name] = check(key, value, coerce(key, value, spec.type), spec.rule)
        elif name in model.config_keys:
            values[name] = model.parse_key(name, value)
        elif model.item_key(name):  # e.g. arms.1.cd: applied after the arms list
            items[name] = value
        else:
            raise ConfigError(f"unknown key {key!r}; allowed in surface: {', '.join(allowed)}")
    if items:
        values = model.set_items(values, items)
    return Surface(params=model.complete(values), model=model.key, **{**model.common_defaults, **common})


def defaults(model: str = DEFAULT_MODEL) -> dict:
    """The default config as nested dicts, with the default parameters of surface ``model``."""
    m = surfaces.get(model)
    return Config(surface=Surface(params=m.parse({}), model=model, **m.common_defaults)).to_dict()


@functools.lru_cache(maxsize=None)
def _defaults_cached(model: str) -> dict:
    """:func:`defaults`, computed once per model (read only: callers must not change it)."""
    return defaults(model)


MAX_RECORD_SAMPLES = 5e7  # recorded steady samples (8 float64 columns: 3.2 GB in memory); the default holds 1.6e6


def _check_cross(cfg: Config) -> None:
    """Checks that involve more than one key."""
    cfg.surface.surface_model.check_config(cfg)
    n = cfg.numerics
    if n.print_step < n.dt:
        raise ConfigError(
            f"numerics.print_step: {n.print_step!r} is not allowed; expected >= numerics.dt ({n.dt!r} s)"
        )
    ratio = n.print_step / n.dt
    if abs(ratio - round(ratio)) > 1e-6 * ratio:
        raise ConfigError(
            f"numerics.print_step: {n.print_step!r} is not allowed; expected an integer multiple of numerics.dt ({n.dt!r} s)"
        )
    p = cfg.probe
    period = 1.0 / p.f1
    if not p.f2 > p.f1:
        raise ConfigError(
            f"probe.f2: {p.f2!r} is not allowed; expected above probe.f1 ({p.f1!r} Hz): the torsional resonance lies "
            "above the flexural one (thesis 2.4.2: f2 = 15 f1)"
        )
    if n.temperature > 0 and not cfg.surface.surface_model.supports_key("thermal"):
        able = [k for k, m in surfaces.MODELS.items() if m.supports_key("thermal")]
        raise ConfigError(
            f"numerics.temperature: {n.temperature!r} is not allowed with surface.model {cfg.surface.model}; expected 0 "
            f"(the thermal recording kernel integrates the flat-punch surfaces {', '.join(able[:-1])} and {able[-1]} only)"
        )
    amp = cfg.operation.free_amplitude
    if n.approach_gap > amp:
        raise ConfigError(
            f"numerics.approach_gap: {n.approach_gap!r} is not allowed; expected a clearance <= the free amplitude "
            f"operation.free_amplitude ({amp:g} m): the tip starts within one oscillation of the surface"
        )
    if n.position_noise > 0.1 * amp:
        raise ConfigError(
            f"numerics.position_noise: {n.position_noise!r} is not allowed; expected an RMS noise <= 0.1 "
            f"operation.free_amplitude ({0.1 * amp:g} m; detectors reach pm to tens of pm)"
        )
    if n.force_noise > p.k1 * amp:
        raise ConfigError(
            f"numerics.force_noise: {n.force_noise!r} is not allowed; expected an RMS noise <= probe.k1 "
            f"operation.free_amplitude ({p.k1 * amp:g} N, the cantilever's largest force; tap forces are nN)"
        )
    if 0 < n.detector_bandwidth <= p.f1:
        raise ConfigError(
            f"numerics.detector_bandwidth: {n.detector_bandwidth!r} is not allowed; expected 0 (infinite) "
            f"or above the drive frequency probe.f1 ({p.f1!r} Hz)"
        )
    if n.dt > period / 200 or n.dt > 1.0 / p.f2 / 50:
        raise ConfigError(
            f"numerics.dt: {n.dt!r} is not allowed; expected <= 1/50 of the paddle period ({1 / p.f2 / 50:.3g} s)"
        )
    if n.print_step > period / 20:
        raise ConfigError(
            f"numerics.print_step: {n.print_step!r} is not allowed; expected <= 1/20 of the drive period ({period / 20:.3g} s)"
        )
    samples = n.record_cycles * period / n.print_step
    if samples > MAX_RECORD_SAMPLES:
        raise ConfigError(
            f"numerics.record_cycles: {n.record_cycles!r} is not allowed at this print step; expected at most "
            f"{int(MAX_RECORD_SAMPLES * n.print_step / period)} periods (the record would hold {samples:.3g} samples, "
            f"limit {MAX_RECORD_SAMPLES:.0e})"
        )
    if n.max_time < (n.record_cycles + n.settle_cycles + 2) * period:
        raise ConfigError(
            f"numerics.max_time: {n.max_time!r} is not allowed; expected >= (record_cycles + settle_cycles + 2) drive periods "
            f"({(n.record_cycles + n.settle_cycles + 2) * period:.3g} s)"
        )


def parse_set(items: list[str] | None, option: str = "--set") -> dict[str, Any]:
    """Parse ``--set section.key=value`` items (or another ``option``'s key=value items);
    values are YAML scalars."""
    out: dict[str, Any] = {}
    for item in items or []:
        if "=" not in item:
            raise ConfigError(f"{option} {item!r} is not allowed; expected " + ("section.key=value" if option == "--set"
                              else "key=value"))  # fmt: skip
        key, raw = item.split("=", 1)
        try:
            value = load_yaml(raw, f"{option} {key.strip()}") if raw.strip() else None
        except yaml.YAMLError:
            raise ConfigError(f"{option} {item!r}: the value is not a valid YAML scalar") from None
        out[key.strip()] = number(value)
    return out


def read_yaml(path: str | Path) -> dict:
    """Read a YAML mapping or raise ConfigError (missing file, bad YAML)."""
    p = Path(path)
    try:
        is_dir, is_file = p.is_dir(), p.is_file()
    except (OSError, ValueError) as exc:  # e.g. a name too long for the file system
        raise ConfigError(f"config file {str(p)!r} is not a usable path ({type(exc).__name__})") from None
    if is_dir:
        raise ConfigError(f"config file {str(p)!r} is a folder; expected a YAML file")
    if not is_file:
        raise ConfigError(f"config file {str(p)!r} does not exist")
    try:
        size = p.stat().st_size
        if size > MAX_YAML_BYTES:  # before reading it: a 30 MB list took 575 s and 3.2 GB to refuse
            raise ConfigError(f"config file {str(p)!r} holds {size} bytes; expected at most {MAX_YAML_BYTES} (a config; "
                              "write long value lists as ranges, e.g. {logspace: [-5, 3, 33]})")  # fmt: skip
        data = load_yaml(p.read_bytes().decode("utf-8"), f"config file {str(p)!r}")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"config file {str(p)!r} cannot be read as UTF-8 text ({type(exc).__name__})") from None
    except yaml.YAMLError as exc:
        line = getattr(getattr(exc, "problem_mark", None), "line", None)
        where = f" (line {line + 1})" if line is not None else ""
        raise ConfigError(f"config file {str(p)!r} is not valid YAML{where}") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"config file {str(p)!r} must hold a mapping of sections")
    return data


def resolve_derived(sections: dict, derived: dict[str, Any]) -> None:
    """Set each derived key's target in ``sections`` (nested dicts, changed in place):
    ``target = value * source`` (:data:`DERIVED`; the source from ``sections`` or the
    defaults), rounded to 12 significant digits as sweep values are.  ConfigError for a
    value that is not a number > 0."""
    if not derived:
        return
    surface = sections.get("surface")
    model = surface.get("model") if isinstance(surface, dict) else None
    dflt = _defaults_cached(model if isinstance(model, str) and model in surfaces.MODELS else DEFAULT_MODEL)
    for dkey, value in derived.items():
        target, source = DERIVED[dkey]
        try:
            v = coerce(dkey, number(value), "float")
        except ConfigError:
            v = None
        if v is None or not v > 0:
            raise ConfigError(f"{dkey}: {value!r} is not allowed; expected a ratio > 0")
        ssec, sname = source.split(".")
        src = (sections.get(ssec) or {}).get(sname, dflt[ssec][sname])
        src = coerce(source, src, "float")
        tsec, tname = target.split(".")
        if not isinstance(sections.get(tsec), dict):
            sections[tsec] = {}
        sections[tsec][tname] = float(f"{v * src:.12g}")


def load(path: str | Path | None = None, overrides: dict[str, Any] | None = None) -> Config:
    """Load a single-point config (YAML or defaults) with dotted overrides.  Derived keys
    (:data:`DERIVED`, e.g. ``surface.stiffness_ratio``) may be set in the file or by an
    override, as in a study's base; an override of either a derived key or its target
    replaces the other one set in the file."""
    d = read_yaml(path) if path else {}
    if "sweep" in d:
        raise ConfigError(f"{path}: has a 'sweep:' block; run it with 'vetica sweep', not 'vetica simulate'")
    cfg_d = {k: dict(v) if isinstance(v, dict) else v for k, v in d.items()}
    derived: dict[str, Any] = {}
    for dkey, (target, _) in DERIVED.items():
        dsec, dname = dkey.split(".")
        body = cfg_d.get(dsec)
        if isinstance(body, dict) and dname in body:
            if target.split(".")[1] in body:
                raise ConfigError(f"{dkey} and {target} are both set in {path}; set one of them")
            derived[dkey] = body.pop(dname)
    targets = {t: dk for dk, (t, _) in DERIVED.items()}
    for key, value in (overrides or {}).items():
        if key in DERIVED:
            tsec, tname = DERIVED[key][0].split(".")
            if isinstance(cfg_d.get(tsec), dict):
                cfg_d[tsec].pop(tname, None)
            derived[key] = value
            continue
        if key in targets:
            derived.pop(targets[key], None)
        _set_dotted(cfg_d, key, value)
    resolve_derived(cfg_d, derived)
    return from_dict(cfg_d)
