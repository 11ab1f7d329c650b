"""The ``extract:`` section of every batch config (sweep, scan): how each point's record is
analysed, not what is simulated.

* ``extract.method``: a registered extraction method (:mod:`vetica_cli.extraction`);
* ``extract.force``: ``both`` (the simulator's true force and the force reconstructed from
  the paddle signal, one row each), ``true`` or ``reconstructed`` (one row).

Also the keys every batch config may carry besides its sections (:data:`META_KEYS`).
"""

from __future__ import annotations

from typing import Any

from ..errors import ConfigError
from ..extraction import DEFAULT_METHOD, METHODS, SOURCES

META_KEYS = ("name", "description")
# extraction keys: not part of the simulated config; key -> (allowed values, default)
EXTRACT_KEYS = {
    "extract.method": (tuple(METHODS), DEFAULT_METHOD),
    "extract.force": (("both", *SOURCES), "both"),
}
EXTRACT_SECTION = "extract"


def check_extract_value(key: str, value: Any, where: str) -> str:
    """An extraction key's value, or a one-line ConfigError listing the allowed values."""
    allowed = EXTRACT_KEYS[key][0]
    if isinstance(value, bool):  # YAML 1.1 reads a bare `true` (extract.force) as a boolean
        value = str(value).lower()
    if not isinstance(value, str) or value not in allowed:
        raise ConfigError(f"{where}: {value!r} is not allowed; expected one of: {', '.join(allowed)}")
    return value


def check_methods(methods: Any, where: str) -> tuple[str, ...]:
    """A list of method names (or one name), each registered and none twice; ConfigError
    (one line) otherwise: a method named twice would give duplicate rows."""
    names = [methods] if isinstance(methods, str) else methods
    if not isinstance(names, list) or not names:
        raise ConfigError(f"{where}: {methods!r} is not allowed; expected a method or a list of: {', '.join(METHODS)}")
    out = [check_extract_value("extract.method", m, where) for m in names]
    dup = sorted({m for m in out if out.count(m) > 1})
    if dup:
        raise ConfigError(f"{where}: {', '.join(dup)} named twice; expected each method once")
    return tuple(out)


def extract_section(body: Any) -> dict:
    """The base ``extract:`` section, checked: {name: value} for keys of EXTRACT_KEYS."""
    if body is None:
        return {}
    if not isinstance(body, dict):
        raise ConfigError(f"section {EXTRACT_SECTION!r} must be a mapping, got {body!r}")
    out = {}
    for name, value in body.items():
        key = f"{EXTRACT_SECTION}.{name}"
        if key not in EXTRACT_KEYS:
            raise ConfigError(f"unknown key {key!r}; allowed: {', '.join(EXTRACT_KEYS)}")
        out[name] = check_extract_value(key, value, key)
    return out


def point_sources(force: str = "both") -> tuple:
    """Force sources extracted for a point with ``extract.force = force``, in table order."""
    return SOURCES if force == "both" else (force,)
