"""Value checks shared by every config section (probe, operation, surface models,
numerics): YAML scalars coerced to the declared type, range rules, and one-line
:class:`~vetica_cli.errors.ConfigError` messages that name the key, the value and
what is allowed (STYLE: validate once, at the boundary)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

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
