"""Extraction of a surface's parameters from a record: the registry of methods
(:mod:`.base`), the shared input handling (:mod:`.record`), the typed result
(:mod:`.result`) and its one formatter (:mod:`.format`).

Methods register themselves on import: ``vetica`` (:mod:`.vetica`, thesis 3.3),
``vetica-prestress`` (:mod:`.vetica_prestress`, VETICA with the Maxwell arm's
pre-stress at contact) and ``full`` (:mod:`.fullfit`, the whole-cycle inversion).
Every result carries its material units (:mod:`.material`, thesis 4.6.2).  Adding a method is adding
its module and one import line below.
"""

from __future__ import annotations

from ..errors import InputError
from ..io import read_table
from .base import DEFAULT_METHOD, METHODS, ExtractionMethod, get, register

# isort: off
# the methods register themselves; this order is the order of the --method choices
from . import vetica as _vetica  # noqa: F401  (registers 'vetica')
from . import vetica_prestress as _vetica_prestress  # noqa: F401  (registers 'vetica-prestress')
from . import fullfit as _fullfit  # noqa: F401  (registers 'full')

# isort: on
from .material import ContactModel, contact_metadata, contact_model, material_entries, tap_contact
from .record import FORCES, SOURCES, Record, build_record
from .result import Estimate, ExtractionResult, Spread
from .sanity import check
from .uncertainty import calibrate


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
    a0: float | None = None,
    vdw_on_surface: bool | None = None,
    contact: ContactModel | dict | None = None,
    **options,
) -> ExtractionResult:
    """Extract the surface from a run table with a registered ``method``.

    ``df`` and ``meta`` as :func:`~.record.build_record` takes them, with the
    force source ``force`` ('auto', 'true', 'reconstructed'), the probe keywords
    for data without metadata (``k2, f2, q2``), ``z1``, ``f1`` and the
    reconstruction's low-pass ``cutoff_hz``/``taper``, the intermolecular distance ``a0``
    and the surface pull ``vdw_on_surface`` (for Z1 on a record without approach or
    metadata, :func:`~.record.z1_estimate`), and the ``contact`` model of the material
    units (a :class:`~.material.ContactModel`, or overrides ``{key: value}`` of thesis
    table 6; the tip radius defaults to the metadata's probe).  ``options`` are the
    method's own (``kg_points`` for both; ``kr_guess`` for vetica; ``start``,
    ``state``, ``fit_hamaker``, ... for full: ``METHODS[key].options_default``).
    Theory values and errors are None when the metadata does not hold the
    surface's parameters.  Raises InputError (one line) for a bad option,
    missing columns, non-increasing time, no contact, too few taps or missing
    probe parameters.
    """
    kw = {"k2": k2, "f2": f2, "q2": q2, "z1": z1, "f1": f1, "cutoff_hz": cutoff_hz, "taper": taper, "a0": a0,
          "vdw_on_surface": vdw_on_surface, "contact": contact}  # fmt: skip
    return extract_many(df, meta, force, {method: options}, **kw)[method]


def extract_many(df, meta: dict | None, force: str, methods: dict, *, contact=None, **record_kw) -> dict:
    """Several methods on one record: ``methods = {key: options}``; the record (and a
    reconstructed force) is built once, with the approach segment analysed when any method
    needs it and the time step checked when any needs a uniform one.  ``record_kw`` as
    :func:`~.record.build_record` takes them; ``contact`` as :func:`extract`.  Returns
    ``{key: ExtractionResult}`` in the order given (each with its material units)."""
    if force not in FORCES:
        raise InputError(f"force {force!r} not allowed; choose one of: {', '.join(FORCES)}")
    ms = {key: get(key) for key in methods}
    # the constants the record takes (a0, the surface pull) are options of a method that fits with them too
    shared = {k: record_kw[k] for k in ("a0", "vdw_on_surface") if record_kw.get(k) is not None}
    opts = {key: m.options({**{k: v for k, v in shared.items() if k in m.options_default}, **(methods[key] or {})})
            for key, m in ms.items()}  # fmt: skip
    radius = ((meta or {}).get("params") or {}).get("probe", {}).get("tip_radius")
    cm = contact if isinstance(contact, ContactModel) else contact_model(contact, radius)
    radius_source = ("given" if isinstance(contact, ContactModel) or (contact or {}).get("tip_radius") is not None
                     else "metadata (probe.tip_radius)" if radius is not None else "thesis table 6")  # fmt: skip
    uniform = next((k for k, m in ms.items() if m.uniform_sampling), None)
    record = build_record(df, meta, force, need_approach=any(m.needs_approach for m in ms.values()),
                          need_z1=any(m.needs_z1 for m in ms.values()), uniform=uniform, **record_kw)  # fmt: skip
    for key, m in ms.items():
        if record.model.key not in m.surface_models:
            able = [k for k, other in METHODS.items() if record.model.key in other.surface_models]
            raise InputError(
                f"method {m.key!r} cannot extract this record's surface, {record.model.describe(record.surface)}"
                f"{': ' + m.surface_note if m.surface_note else ''} (it extracts: {', '.join(m.surface_models)})"
                + (f"; use --method {' or '.join(able)}" if able else "")
            )
    out = {}
    for key, m in ms.items():
        res = m.run(record, opts[key])
        calibrate(res, record, m, opts[key])  # a standard error for every estimate (.uncertainty)
        check(res, record, opts[key])  # identifiability and sanity checks: no silent wrong answer (.sanity)
        add_material(res, record, cm, radius_source)
        out[key] = res
    return out


def add_material(res: ExtractionResult, record: Record, cm: ContactModel, radius_source: str) -> None:
    """Fill ``res.material`` and ``res.contact`` (thesis 4.6.2, eqs. 90-92): the record's
    peak force and penetration below the undeformed surface (:func:`~.material.tap_contact`;
    the adhesion lift at Z1 taken off with the extracted Kg when the record says the surface
    feels the pull) with the extracted (and, where known, the theory) ``Kg, Kr, tau_r``."""
    values = {k: res.value(k) for k in ("k_g", "k_r", "tau_r")}
    kg = values["k_g"] if record.vdw_on_surface and values["k_g"] and values["k_g"] > 0 else None
    z1 = record.z1
    fit = res.info.get("fit") or {}
    if z1 is None and fit.get("surface_height_m") is not None and record.a0 is not None:
        z1 = fit["surface_height_m"] + record.a0  # a fit that found the surface without Z1: where the tip meets it
    peak, depth = tap_contact(record.z, record.f, z1, kg) if z1 is not None else (float("nan"), float("nan"))
    values = {k: (v if v is not None else float("nan")) for k, v in values.items()}
    res.material = material_entries(peak, depth, values, record.truth, cm)
    res.contact = contact_metadata(cm, radius_source)


def extract_file(path, force: str = "auto", method: str = DEFAULT_METHOD, **kwargs) -> ExtractionResult:
    """:func:`extract` on a Parquet (with metadata) or CSV table (``vetica extract PATH``)."""
    df, meta = read_table(path)
    return extract(df, meta, force=force, method=method, **kwargs)


__all__ = [
    "DEFAULT_METHOD",
    "FORCES",
    "METHODS",
    "SOURCES",
    "ContactModel",
    "Estimate",
    "ExtractionMethod",
    "ExtractionResult",
    "Record",
    "Spread",
    "add_material",
    "build_record",
    "contact_model",
    "extract",
    "extract_file",
    "extract_many",
    "get",
    "register",
]
