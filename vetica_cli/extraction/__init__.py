"""Extraction of a surface's parameters from a record: the registry of methods
(:mod:`.base`), the shared input handling (:mod:`.record`), the typed result
(:mod:`.result`) and its one formatter (:mod:`.format`).

Methods register themselves on import (:mod:`.methods`): ``vetica`` (:mod:`.methods.vetica`,
thesis 3.3), ``vetica-prestress`` (:mod:`.methods.vetica_prestress`, VETICA with the Maxwell
arm's pre-stress at contact), ``full`` (:mod:`.fullfit`, the whole-cycle inversion), and the
instrument's own numbers for comparison: ``observables`` (:mod:`.methods.observables`:
amplitude, phase, E_diss, virial, loss tangent) and ``dmt-fit`` (:mod:`.methods.dmt_fit`:
per-tap DMT analysis).  ``vetica_cli.extraction.vetica`` and the other method modules stay
importable under their old names.  Every result carries its material units
(:mod:`.material`, thesis 4.6.2).  Adding a method is adding its module to :mod:`.methods`
and one import line there.
"""

from __future__ import annotations

from dataclasses import asdict, replace

import numpy as np

from ..errors import InputError
from ..io import read_table
from .base import DEFAULT_METHOD, METHODS, ExtractionMethod, Option, get, register
from . import methods  # noqa: F401  (registers every method, in the order of the --method choices)


def _alias_method_modules() -> None:
    """``vetica_cli.extraction.<name>`` for each module of :mod:`.methods` (where they lived
    before): scripts and notebooks that import them keep working."""
    import sys

    for name in ("vetica", "vetica_prestress", "observables", "dmt_fit"):
        mod = getattr(methods, name)
        sys.modules.setdefault(f"{__name__}.{name}", mod)
        globals().setdefault(name, mod)


_alias_method_modules()
from .material import MATERIAL_UNITS, ContactModel, contact_metadata, contact_model, material_entries, tap_contact
from .record import FORCES, RECORD_KEYS, SOURCES, Record, RecordInputs, build_record
from .referee import memo_key

RECORD_COLUMNS = ("t", "z_tip", "f_ts", "z_paddle", "segment")  # what any method reads of a run table
MATERIAL_NAMES = tuple(MATERIAL_UNITS)  # the thesis's material units (E_dmt, E_glassy, E_rubbery, viscosity)


def extraction_modules(methods, forces=SOURCES) -> set[str]:
    """The cached core modules extracting with ``methods`` (keys) from the force ``forces``
    compiles (:mod:`vetica_cli.simulation.jit`): each method's own, and ``paddle`` for a
    force reconstructed in the tap windows."""
    mods: set[str] = set()
    for key in methods:
        m = get(key)
        mods |= set(m.kernel_modules)
        if m.tap_windows and "reconstructed" in forces:
            mods.add("paddle")
    return mods
from .result import Estimate, ExtractionResult, Spread
from .sanity import check
from .uncertainty import calibrate


def extract(
    df,
    meta: dict | None = None,
    force: str = "auto",
    method: str = DEFAULT_METHOD,
    *,
    inputs: RecordInputs | None = None,
    contact: ContactModel | dict | None = None,
    **options,
) -> ExtractionResult:
    """Extract the surface from a run table with a registered ``method``.

    ``df`` and ``meta`` as :func:`~.record.build_record` takes them, with the
    force source ``force`` ('auto', 'true', 'reconstructed'), what the user states
    about the record (``inputs``, a :class:`~.record.RecordInputs`, or its fields as
    keywords: the probe keywords for data without metadata ``k2, f2, q2``, ``z1``,
    ``f1``, the reconstruction's low-pass ``cutoff_hz``/``taper``, the intermolecular
    distance ``a0`` and the surface pull ``vdw_on_surface``), and the ``contact``
    model of the material units (a :class:`~.material.ContactModel`, or overrides
    ``{key: value}`` of thesis table 6; the tip radius defaults to the metadata's
    probe).  The other keywords are the method's own options (``kg_points`` for both;
    ``kr_guess`` for vetica; ``start``, ``state``, ``fit_hamaker``, ... for full:
    ``METHODS[key].options_default``).  Theory values and errors are None when the
    metadata does not hold the surface's parameters.  Raises InputError (one line) for
    a bad option, missing columns, non-increasing time, no contact, too few taps or
    missing probe parameters.
    """
    inputs = replace(inputs or RecordInputs(), **{k: options.pop(k) for k in RECORD_KEYS if k in options})
    return extract_many(df, meta, force, {method: options}, inputs=inputs, contact=contact)[method]


def extract_many(df, meta: dict | None, force: str, methods: dict, *, contact=None, inputs: RecordInputs | None = None,
                 **record_kw) -> dict:  # fmt: skip
    """Several methods on one record: ``methods = {key: options}``; the record (and a
    reconstructed force) is built once, with the approach segment analysed when any method
    needs it and the time step checked when any needs a uniform one.  ``record_kw`` as
    :func:`~.record.build_record` takes them; ``contact`` as :func:`extract`.  Returns
    ``{key: ExtractionResult}`` in the order given (each with its material units)."""
    if force not in FORCES:
        raise InputError(f"force {force!r} not allowed; choose one of: {', '.join(FORCES)}")
    record_kw = asdict(replace(inputs or RecordInputs(), **record_kw))
    ms = {key: get(key) for key in methods}
    # the constants the record takes (a0, the surface pull, f1) are options of a method that uses them too
    shared = {k: record_kw[k] for k in ("a0", "vdw_on_surface", "f1") if record_kw.get(k) is not None}
    opts = {key: m.options({**{k: v for k, v in shared.items() if k in m.options_default}, **(methods[key] or {})})
            for key, m in ms.items()}  # fmt: skip
    radius = ((meta or {}).get("params") or {}).get("probe", {}).get("tip_radius")
    cm = contact if isinstance(contact, ContactModel) else contact_model(contact, radius)
    radius_source = ("given" if isinstance(contact, ContactModel) or (contact or {}).get("tip_radius") is not None
                     else "metadata (probe.tip_radius)" if radius is not None else "thesis table 6")  # fmt: skip
    uniform = next((k for k, m in ms.items() if m.uniform_sampling), None)
    record = build_record(df, meta, force, need_approach=any(m.needs_approach for m in ms.values()),
                          need_z1=any(m.needs_z1 for m in ms.values()), uniform=uniform,
                          tap_windows=all(m.tap_windows for m in ms.values()), **record_kw)  # fmt: skip
    for key, m in ms.items():
        if record.model.key not in m.surface_models:
            able = [k for k, other in METHODS.items() if record.model.key in other.surface_models
                    and set(record.model.parameter_keys) <= set(other.quantities(record.model))]  # estimates its parameters
            raise InputError(
                f"method {m.key!r} cannot extract this record's surface, {record.model.describe(record.surface)}"
                f"{': ' + m.surface_note if m.surface_note else ''} (it extracts: {', '.join(m.surface_models)})"
                + (f"; use --method {' or '.join(able)}" if able else "")
            )
    out = {}
    # a method other methods' checks consult (the whole-cycle fit referees the tap methods) runs first, and its
    # result on its default options is kept on the record for them (.sanity), so it is computed once
    referees = {k for m in ms.values() for k in (m.referee, m.band_model) if k}
    order = sorted(ms, key=lambda k: k not in referees)
    for key in order:
        m = ms[key]
        try:
            res = m.run(record, opts[key])
        except InputError as exc:
            raise InputError(_with_noise(str(exc), record)) from None
        calibrate(res, record, m, opts[key])  # a standard error for every estimate (.uncertainty)
        check(res, record, opts[key], m)  # identifiability and sanity checks: no silent wrong answer (.sanity)
        if key in referees and opts[key] == m.options({}):  # the referee's verdict on its defaults, for the others
            record.memo[memo_key("referee", key, record)] = res.estimates
        add_material(res, record, cm, radius_source)
        out[key] = res
    return {key: out[key] for key in ms}


def _with_noise(text: str, record: Record) -> str:
    """A refusal for want of taps, with the record's force noise when the taps may be lost in it."""
    noise = record.info.get("noise") or {}
    rms = noise.get("force_rms_n")
    peak = float(np.max(record.f)) if len(record.f) else 0.0
    if text.startswith("too few taps") and rms and peak > 0 and rms > 0.1 * peak:
        band = f" at its band {noise['cutoff_hz'] / 1e6:.3g} MHz" if noise.get("cutoff_hz") else ""
        text += (f"; the force's noise ({rms:.2g} N RMS{band}) is {rms / peak:.2g} of its peak: the taps do not "
                 "stand above it")  # fmt: skip
    return text


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
    peak, depth = tap_contact(record.z, record.f, z1, kg, record.taps) if z1 is not None else (float("nan"), float("nan"))
    values = {k: (v if v is not None else float("nan")) for k, v in values.items()}
    entries = material_entries(peak, depth, values, record.truth, cm)
    declared = set(record.model.material_columns) | {"E_dmt"}  # the surface model's (Kelvin-Voigt: E_dmt only)
    res.material = {k: v for k, v in entries.items() if k not in MATERIAL_NAMES or k in declared}
    res.contact = contact_metadata(cm, radius_source)


def extract_file(path, force: str = "auto", method: str = DEFAULT_METHOD, **kwargs) -> ExtractionResult:
    """:func:`extract` on a Parquet (with metadata) or CSV table (``vetica extract PATH``)."""
    df, meta = read_table(path, columns=RECORD_COLUMNS)
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
    "Option",
    "RECORD_KEYS",
    "Record",
    "RecordInputs",
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
