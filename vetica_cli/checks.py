"""The one validator vocabulary of every config (simulate, sweep, scan, advise) and command
option: YAML read strictly (:func:`load_yaml`: duplicate keys, anchors and aliases refused),
YAML scalars coerced to the declared type (:func:`coerce`, :func:`finite`), range rules
(:func:`within`; :func:`limit`: each physical range with where it comes from, from
the one table :mod:`vetica_cli.ranges`), and one-line :class:`~vetica_cli.errors.ConfigError` messages that name the key,
the value and what is allowed (STYLE: validate once, at the boundary, before any work).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import yaml

from .errors import ConfigError, InputError
from .ranges import range_of, range_rule

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


# key -> (lo, hi, unit, where the range comes from) of a force curve's stated constants, from the one table of
# ranges (vetica_cli.ranges): what vetica fit checks its --tip-radius and --meta values against
LIMITS = {key: (range_of(key).lo, range_of(key).hi, range_of(key).unit, range_of(key).source)
          for key in ("probe.tip_radius", "fit.tip_radius", "probe.k1", "probe.sensitivity", "record.rate")}  # fmt: skip
MAX_CYCLES = 10000  # drive periods recorded or settled: 10000 periods at 50 kHz are 0.2 s, far beyond a steady state
MAX_ORBIT_PERIODS = 100000  # period evaluations of the orbit solver (default 150)
MAX_SEED = 2**32 - 1  # numpy's legacy seed range, which every generator accepts
MAX_ARMS = 8  # Maxwell arms of a Wiechert or hertz surface, or a fit: the thesis uses 1-2 (5.3.2); 8 relaxation times per
#               decade-spaced record are already beyond what one tapping record identifies
MAX_VALUES_PER_KEY = 1_000_000  # values one sweep key (a range's count) may have
MAX_POINTS = 10_000_000  # points of one sweep: a larger grid is refused outright (--yes cannot start it)
MAX_LIST = 1000  # values of one command option's comma-separated list (advise --f1 ...): each multiplies the work

# The one threshold past which every command asks for --yes before it starts (sweep, scan, advise, simulate,
# bench): its estimated wall time, or the number of items (points, pixels, simulations) it would run
CONFIRM_ITEMS = 5000
CONFIRM_WALL_S = 2 * 3600.0  # [s]


def duration(seconds: float) -> str:
    """``seconds`` as a short human duration: 45 s, 12 min, 3.4 h, 2.1 days."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    if seconds < 48 * 3600:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.1f} days"


def confirm_cost(what: str, wall_s: float, yes: bool, items: int | None = None, unit: str = "items") -> None:
    """InputError (one line, how to go on) when a command's estimated wall time ``wall_s`` is over
    :data:`CONFIRM_WALL_S` or its ``items`` over :data:`CONFIRM_ITEMS`, unless ``yes``: every
    command estimates its cost before any work and asks past the same threshold.  ``what``
    names the work, e.g. 'this scan (64 x 64 pixels, 1 pass)'."""
    if yes or ((items is None or items <= CONFIRM_ITEMS) and wall_s <= CONFIRM_WALL_S):
        return
    count, over = (f"{items} {unit}, ", f"{CONFIRM_ITEMS} {unit} or ") if items is not None else ("", "")
    raise InputError(f"{what} is estimated at {count}{duration(wall_s)} (over {over}{duration(CONFIRM_WALL_S)}): add "
                     "--yes to start it")  # fmt: skip


def limit(key: str, what: str | None = None) -> Rule:
    """The rule of a config key, option or quantity from the one table of ranges
    (:data:`vetica_cli.ranges.QUANTITIES`; ``what``: the noun, e.g. 'a radius')."""
    return range_rule(key, what)


# --------------------------------------------------------------------------- YAML


class _StrictLoader(yaml.SafeLoader):
    """YAML's safe loader that refuses duplicate keys (the last one would win silently) and
    anchors/aliases (an alias bomb expands to gigabytes; no vetica config needs them)."""

    depth = 0  # nesting depth of the node being composed

    def compose_node(self, parent, index):
        if self.depth >= MAX_YAML_DEPTH:  # checked while parsing: deep nesting ends in RecursionError otherwise
            mark = self.peek_event().start_mark
            raise ConfigError(f"{self.name}: nesting deeper than {MAX_YAML_DEPTH} levels at line {mark.line + 1} is not "
                              "allowed; expected sections of plain values and short lists")  # fmt: skip
        self.depth += 1
        try:
            return self._compose_node(parent, index)
        finally:
            self.depth -= 1

    def _compose_node(self, parent, index):
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


MAX_YAML_DEPTH = 32  # nesting levels of a YAML document: a config needs 5 (sample.features.0.surface.arms.0)
MAX_YAML_BYTES = 1 << 20  # a config file: the largest study config is ~2 KB; long value lists are written as ranges


def load_yaml(text: str, name: str = "config") -> Any:
    """Parse YAML ``text`` strictly (:class:`_StrictLoader`; ``name`` in the messages): at most
    :data:`MAX_YAML_BYTES` of text and :data:`MAX_YAML_DEPTH` levels of nesting, checked
    before and while parsing (ConfigError, one line)."""
    if len(text) > MAX_YAML_BYTES:
        raise ConfigError(f"{name}: {len(text)} characters are not allowed; expected at most {MAX_YAML_BYTES} (a "
                          "config; write long value lists as ranges, e.g. {logspace: [-5, 3, 33]})")  # fmt: skip
    loader = _StrictLoader(text)
    loader.name = name
    try:
        return loader.get_single_data()
    finally:
        loader.dispose()
