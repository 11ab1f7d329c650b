"""The one validator vocabulary of every config (simulate, sweep, scan, advise) and command
option: YAML read strictly (:func:`load_yaml`: duplicate keys, anchors and aliases refused),
YAML scalars coerced to the declared type (:func:`coerce`, :func:`finite`), range rules
(:func:`within`, :data:`LIMITS`: each physical or practical range with where it comes
from), and one-line :class:`~vetica_cli.errors.ConfigError` messages that name the key,
the value and what is allowed (STYLE: validate once, at the boundary, before any work).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import yaml

from .errors import ConfigError

Rule = tuple[Callable[[Any], bool], str]  # (predicate, description of what is allowed)


def positive(v) -> bool:
    return v > 0


def nonneg(v) -> bool:
    return v >= 0


def open_unit(v) -> bool:
    return 0 < v < 1


def one_of(*names: str) -> "Rule":
    """Rule: the value is one of ``names``."""
    return (lambda v: v in names, "one of: " + ", ".join(names))


def number(value: Any) -> Any:
    """YAML 1.1 reads '1e-4' (no dot) as a string: turn numeric strings into floats."""
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            return value
    return value


def _finite(value: int | float) -> bool:
    """A finite number that a float holds (an integer beyond 1.8e308 is not)."""
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False


def coerce(key: str, value: Any, tp: str) -> Any:
    """Coerce a YAML value to the declared type ('float', 'int', 'bool', 'float | None',
    'str') or raise ConfigError."""
    if tp == "str":
        if isinstance(value, str):
            return value
        raise ConfigError(f"{key}: {value!r} is not allowed; expected a name")
    if tp != "bool":
        value = number(value)
    if tp == "bool":
        if isinstance(value, bool):
            return value
        raise ConfigError(f"{key}: {value!r} is not allowed; expected true or false")
    if tp == "int":
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not _finite(value) or value != int(value):
            raise ConfigError(f"{key}: {value!r} is not allowed; expected an integer")
        return int(value)
    if tp == "float | None":
        if value is None:
            return None
        tp = "float"
    if tp == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not _finite(value):
            raise ConfigError(f"{key}: {value!r} is not allowed; expected a finite number")
        return float(value)
    raise AssertionError(tp)


def check(key: str, raw: Any, value: Any, rule: Rule | None) -> Any:
    """``value`` (coerced from ``raw``) if it satisfies ``rule``, else a ConfigError."""
    if rule is not None:
        pred, allowed = rule
        if not pred(value):
            raise ConfigError(f"{key}: {raw!r} is not allowed; expected {allowed}")
    return value


def finite(key: str, value: Any, rule: Rule | None = None, allowed: str = "a finite number") -> float:
    """A YAML value as a finite float satisfying ``rule`` (numeric strings read, an integer
    beyond the float range refused), else ConfigError naming ``key`` and ``allowed``."""
    v = number(value)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not _finite(v):
        raise ConfigError(f"{key}: {value!r} is not allowed; expected {allowed}")
    if rule is not None and not rule[0](float(v)):
        raise ConfigError(f"{key}: {value!r} is not allowed; expected {rule[1]}")
    return float(v)


def integer(key: str, value: Any, lo: int, hi: int, what: str = "an integer") -> int:
    """A YAML value as an integer in ``[lo, hi]``, else ConfigError (one line)."""
    v = number(value)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not _finite(v) or v != int(v) or not lo <= v <= hi:
        raise ConfigError(f"{key}: {value!r} is not allowed; expected {what} in {lo}..{hi}")
    return int(v)


# --------------------------------------------------------------------------- ranges and their sources


def within(lo: float, hi: float, what: str, unit: str = "", why: str = "") -> Rule:
    """Rule: ``lo <= value <= hi``, described as ``'<what> in [lo, hi] unit (why)'``."""
    text = f"{what} in [{lo:g}, {hi:g}]" + (f" {unit}" if unit else "") + (f" ({why})" if why else "")
    return (lambda v: lo <= v <= hi, text)


# key -> (lo, hi, unit, where the range comes from): nonsense refused before any work
LIMITS = {
    "probe.tip_radius": (0.5e-9, 1e-6, "m", "sharp tips are 1-20 nm, the thesis's 10 nm (table 2); a blunt tip up "
                         "to 1 um; larger probes are outside the point-tip vdW and contact model"),
    "surface.hamaker": (1e-21, 1e-18, "J", "Hamaker constants of condensed media across air lie in 4e-21 .. 5e-19 J "
                        "(Israelachvili, Intermolecular and Surface Forces, ch. 13); the thesis's 2e-19 J"),
    "surface.a0": (0.1e-9, 1e-9, "m", "the intermolecular cut-off distance is ~0.165-0.2 nm (thesis table 2: 0.2 nm)"),
    "operation.free_amplitude": (0.1e-9, 1e-6, "m", "tapping-mode free amplitudes are 1-100 nm (thesis table 1: 100 nm)"),
    "probe.q1": (0.5, 1e6, "", "underdamped; air ~100-1000, vacuum up to ~1e5"),
    "probe.q2": (0.5, 1e6, "", "underdamped; air ~100-1000, vacuum up to ~1e5"),
    "probe.f1": (1e2, 1e8, "Hz", "cantilever resonances lie in 1 kHz .. 10 MHz (thesis table 1: 10-100 kHz)"),
    "probe.f2": (1e2, 1e9, "Hz", "torsional resonances lie above the flexural ones (thesis 2.4.2: f2 = 15 f1)"),
    "probe.k1": (1e-3, 1e3, "N/m", "cantilever stiffnesses lie in 0.01 .. 100 N/m (thesis table 1: 10 N/m)"),
    "probe.k2": (1e-1, 1e5, "N/m", "torsional stiffnesses (thesis table 1: 70-700 N/m; fig. 30 up to 1200)"),
    # force curves (vetica fit): the probe of a force curve may be a colloidal bead, far beyond the tapping tip's
    # 1 um (whose bound is the point-tip vdW model's); the lower bound is the same sharp tip's
    "fit.tip_radius": (0.5e-9, 1e-4, "m", "sharp tips of 1-20 nm up to colloidal probes of 100 um radius (beads "
                       "of 2-200 um diameter are glued to cantilevers for cells and tissue)"),
    "probe.sensitivity": (1e-10, 1e-5, "m/V", "optical-lever sensitivities are ~10-500 nm/V (the afmformats "
                          "example files: 45-91 nm/V)"),
    "record.rate": (1.0, 1e9, "Hz", "force curves are sampled at 10 Hz to 1 MHz (the afmformats example files: "
                    "205 Hz to 10.7 kHz); 1 GHz is a tapping record's 1 ns print step"),
}
MAX_CYCLES = 10000  # drive periods recorded or settled: 10000 periods at 50 kHz are 0.2 s, far beyond a steady state
MAX_ORBIT_PERIODS = 100000  # period evaluations of the orbit solver (default 150)
MAX_SEED = 2**32 - 1  # numpy's legacy seed range, which every generator accepts
MAX_ARMS = 8  # Maxwell arms of a Wiechert surface or fit: the thesis uses 1-2 (5.3.2); 8 relaxation times per
#               decade-spaced record are already beyond what one tapping record identifies
MAX_VALUES_PER_KEY = 1_000_000  # values one sweep key (a range's count) may have
MAX_POINTS = 10_000_000  # points of one sweep: a larger grid is refused outright (--yes cannot start it)


def limit(key: str, what: str) -> Rule:
    """The rule of ``key`` from :data:`LIMITS` (``what``: the noun, e.g. 'a radius')."""
    lo, hi, unit, why = LIMITS[key]
    return within(lo, hi, what, unit, why)


# --------------------------------------------------------------------------- YAML


class _StrictLoader(yaml.SafeLoader):
    """YAML's safe loader that refuses duplicate keys (the last one would win silently) and
    anchors/aliases (an alias bomb expands to gigabytes; no vetica config needs them)."""

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise ConfigError(f"{self.name}: an alias (*{event.anchor}) at line {event.start_mark.line + 1} is not "
                              "allowed; expected plain values (write the value out)")  # fmt: skip
        event = self.peek_event()
        anchor = getattr(event, "anchor", None)
        if anchor is not None:
            raise ConfigError(f"{self.name}: an anchor (&{anchor}) at line {event.start_mark.line + 1} is not "
                              "allowed; expected plain values")  # fmt: skip
        return super().compose_node(parent, index)

    def construct_mapping(self, node, deep=False):
        seen: dict = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in seen:
                raise ConfigError(f"{self.name}: key {key!r} appears twice (lines {seen[key] + 1} and "
                                  f"{key_node.start_mark.line + 1}); expected each key once")  # fmt: skip
            seen[key] = key_node.start_mark.line
        return super().construct_mapping(node, deep=deep)


def load_yaml(text: str, name: str = "config") -> Any:
    """Parse YAML ``text`` strictly (:class:`_StrictLoader`; ``name`` in the messages)."""
    loader = _StrictLoader(text)
    loader.name = name
    try:
        return loader.get_single_data()
    finally:
        loader.dispose()
