"""Extraction of a surface's parameters from a record: the registry of methods
(:mod:`.base`), the shared input handling (:mod:`.record`), the typed result
(:mod:`.result`) and its one formatter (:mod:`.format`).

Methods register themselves on import: ``vetica`` (:mod:`.vetica`, thesis 3.3) and
``full`` (:mod:`.fullfit`, the whole-cycle inversion).  Adding a method is adding
its module and one import line below.
"""

from __future__ import annotations

from ..errors import InputError
from ..io import read_table
from .base import DEFAULT_METHOD, METHODS, ExtractionMethod, get, register

# isort: off
# the methods register themselves; this order is the order of the --method choices
from . import vetica as _vetica  # noqa: F401  (registers 'vetica')
from . import fullfit as _fullfit  # noqa: F401  (registers 'full')

# isort: on
from .record import FORCES, SOURCES, Record, build_record
from .result import Estimate, ExtractionResult, Spread


def extract(
    df,
    meta: dict | None = None,
    force: str = "auto",
    method: str = DEFAULT_METHOD,
    *,
    k2: float | None = None,
    f2: float | None = None,
    q2: float | None = None,
    z1: float | None = None,
    f1: float | None = None,
    cutoff_hz: float | None = None,
    taper: float = 0.0,
    **options,
) -> ExtractionResult:
    """Extract the surface from a run table with a registered ``method``.

    ``df`` and ``meta`` as :func:`~.record.build_record` takes them, with the
    force source ``force`` ('auto', 'true', 'reconstructed'), the probe keywords
    for data without metadata (``k2, f2, q2``), ``z1``, ``f1`` and the
    reconstruction's low-pass ``cutoff_hz``/``taper``.  ``options`` are the
    method's own (``kg_points`` for both; ``kr_guess`` for vetica; ``start``,
    ``state``, ``fit_hamaker``, ... for full: ``METHODS[key].options_default``).
    Theory values and errors are None when the metadata does not hold the
    surface's parameters.  Raises InputError (one line) for a bad option,
    missing columns, non-increasing time, no contact, too few taps or missing
    probe parameters.
    """
    if force not in FORCES:
        raise InputError(f"force {force!r} not allowed; choose one of: {', '.join(FORCES)}")
    m = get(method)
    opts = m.options(options)
    record = build_record(df, meta, force, need_approach=m.needs_approach, need_z1=m.needs_z1,
                          uniform=m.key if m.uniform_sampling else None,
                          k2=k2, f2=f2, q2=q2, z1=z1, f1=f1, cutoff_hz=cutoff_hz, taper=taper)  # fmt: skip
    if record.model.key not in m.surface_models:
        able = [k for k, other in METHODS.items() if record.model.key in other.surface_models]
        raise InputError(
            f"method {m.key!r} cannot extract this record's surface, {record.model.describe(record.surface)}"
            f"{': ' + m.surface_note if m.surface_note else ''} (it extracts: {', '.join(m.surface_models)})"
            + (f"; use --method {' or '.join(able)}" if able else "")
        )
    return m.run(record, opts)


def extract_file(path, force: str = "auto", method: str = DEFAULT_METHOD, **kwargs) -> ExtractionResult:
    """:func:`extract` on a Parquet (with metadata) or CSV table (``vetica extract PATH``)."""
    df, meta = read_table(path)
    return extract(df, meta, force=force, method=method, **kwargs)


__all__ = [
    "DEFAULT_METHOD",
    "FORCES",
    "METHODS",
    "SOURCES",
    "Estimate",
    "ExtractionMethod",
    "ExtractionResult",
    "Record",
    "Spread",
    "build_record",
    "extract",
    "extract_file",
    "get",
    "register",
]
