"""extract(run table) -> k0, k_inf, cd and the VETICA constants, with errors
against the run's own truth when its metadata knows it.

Input: a table with at least ``t`` [s], ``z_tip`` [m] and ``f_ts`` [N] (the
true force) or ``z_paddle`` [m] (from which the force is reconstructed by
spectral inversion, SPEC 6), optionally a ``segment`` column ('approach' =
the window around the first contact, 'steady' = the taps to analyse), and the
``vetica`` metadata dict written by ``vetica simulate`` ({} for measured
data: then the probe's ``k2, f2, q2`` and ``Z1`` come as keyword arguments).
"""

from __future__ import annotations

import math
import time

import numpy as np

from .errors import InputError
from .signals.spectral import reconstruct_force, reconstruction_error
from .signals.taps import first_contact_minimum
from .vetica import NAMES, theory, vetica

FORCES = ("auto", "true", "reconstructed")
METHODS = ("vetica", "full")


def _finite_or_none(v):
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def _segment(df, name):
    if "segment" not in df.columns:
        return None
    seg = df["segment"]
    # compare the categorical's codes, not a 1e6-row string copy of the column
    sel = df[(seg == name).to_numpy()] if not hasattr(seg, "cat") or name in seg.cat.categories else df.iloc[:0]
    return sel if len(sel) else None


def _column(df, name, where):
    a = df[name].to_numpy(dtype=float)
    if not np.all(np.isfinite(a)):
        raise InputError(f"column {name!r} has missing or non-finite values in {where}")
    return a


def _check_time(t, where):
    if len(t) < 2 or not np.all(np.diff(t) > 0):
        raise InputError(f"time column 't' is not strictly increasing in {where}")


def resolve_force(df, force: str) -> tuple[str, set]:
    """Check the columns an extraction needs and resolve ``force='auto'``
    (reconstructed when ``z_paddle`` is present).  Returns ``(force, columns)``;
    InputError names what is missing."""
    cols = set(df.columns)
    missing = [c for c in ("t", "z_tip") if c not in cols]
    if missing or not ({"f_ts", "z_paddle"} & cols):
        need = missing + ([] if {"f_ts", "z_paddle"} & cols else ["f_ts or z_paddle"])
        raise InputError(f"missing column(s): {', '.join(need)} (need t, z_tip and f_ts or z_paddle)")
    if force == "auto":
        force = "reconstructed" if "z_paddle" in cols else "true"
    fcol = "f_ts" if force == "true" else "z_paddle"
    if fcol not in cols:
        raise InputError(f"--force {force} needs the column {fcol!r}, which the table does not have")
    return force, cols


def force_column(seg, where, force, probe, info, *, k2=None, f2=None, q2=None, cutoff_hz=None, taper=0.0):
    """The force of a segment: the ``f_ts`` column ('true'), or the spectral
    inversion of ``z_paddle`` ('reconstructed', thesis eqs. 17-20) with the
    probe's ``k2, f2, q2`` from the keywords or else the metadata ``probe``
    section.  Records the cut-off in ``info``; InputError names missing probe
    parameters."""
    if force == "true":
        return _column(seg, "f_ts", where)
    p = {"k2": k2 if k2 is not None else probe.get("k2"),
         "f2": f2 if f2 is not None else probe.get("f2"),
         "q2": q2 if q2 is not None else probe.get("q2")}  # fmt: skip
    absent = [k for k, v in p.items() if v is None]
    if absent:
        raise InputError(
            f"the force reconstruction needs the probe's {', '.join(absent)} (not in the file's metadata): "
            f"pass {' '.join('--' + k for k in absent)}, or use --force true"
        )
    rec = reconstruct_force(seg["t"].to_numpy(float), _column(seg, "z_paddle", where),
                            p["k2"], p["f2"], p["q2"], cutoff_hz=cutoff_hz, taper=taper)  # fmt: skip
    info["cutoff_hz"] = rec.cutoff_hz
    return rec.f


def steady_force(steady, force, cols, force_of, probe, f1, info):
    """The force of the steady record; for a reconstructed force also its error
    against ``f_ts`` (when present) and the cut-off in drive harmonics, in ``info``."""
    f = force_of(steady, "the steady record")
    if force == "reconstructed" and "f_ts" in cols:
        info["reconstruction_error"] = reconstruction_error(f, _column(steady, "f_ts", "the steady record"))
    drive = f1 if f1 is not None else probe.get("f1")
    if "cutoff_hz" in info and drive:
        info["cutoff_harmonic"] = info["cutoff_hz"] / drive
    return f


def z1_reference(approach, z1, meta, force_of, info, need_approach=False):
    """Z1, the undeformed-surface reference (thesis eq. 84): ``z1`` if given, else
    the tip position at the first force minimum of the approach segment, else
    the metadata's observable.  Returns ``(z1, approach_record)`` where
    ``approach_record = (z_tip, force, index of Z1)`` when the approach segment
    was analysed (always with ``need_approach``, else only when Z1 comes from
    it); records the value and its source in ``info``."""
    rec = None
    if approach is not None and (z1 is None or need_approach):
        ta = _column(approach, "t", "the approach segment")
        _check_time(ta, "the approach segment")
        fa = force_of(approach, "the approach segment")
        i1 = first_contact_minimum(fa)
        rec = (_column(approach, "z_tip", "the approach segment"), fa, i1)
    if z1 is not None:
        value, source = float(z1), "given"
    elif rec is not None:
        value, source = float(rec[0][rec[2]]), "approach segment"
    elif (meta.get("observables") or {}).get("z1") is not None:
        value, source = float(meta["observables"]["z1"]), "metadata"
    else:
        raise InputError("Z1 unknown: the table has no 'approach' segment and no metadata; pass --z1")
    info["z1"] = value
    info["z1_source"] = source
    return value, rec


def extract(
    df,
    meta: dict | None = None,
    force: str = "auto",
    kg_points: int = 10,
    method: str = "vetica",
    *,
    k2: float | None = None,
    f2: float | None = None,
    q2: float | None = None,
    z1: float | None = None,
    f1: float | None = None,
    cutoff_hz: float | None = None,
    taper: float = 0.0,
    kr_guess: float | None = None,
) -> dict:
    """Extract ``tau_c, k_g, k_r, tau_r, k0, k_inf, cd`` from a run table.

    ``force``: 'true' uses the ``f_ts`` column, 'reconstructed' rebuilds the
    force from ``z_paddle`` (probe ``k2, f2, q2`` from the metadata or the
    keyword arguments; low-pass ``cutoff_hz``, default the Nyquist frequency,
    with a raised-cosine ``taper``); 'auto' = reconstructed when ``z_paddle``
    is present.  ``Z1`` comes from ``z1`` if given, else from the first force
    minimum of the 'approach' segment (with the chosen force), else from the
    metadata.  ``f1`` (drive frequency, Hz) only labels the cut-off in drive
    harmonics.  ``method``: 'vetica' (thesis 3.3) or 'full' (whole-cycle SLS
    model inversion, :func:`vetica_cli.fullfit.extract_full`, issue 6).

    Returns ``{name: {"value", "theory", "error_pct", "spread"}, ...,
    "force", "taps", "method", "info"}``; theory and error_pct are None when
    the metadata does not hold the surface's k0, k_inf, cd.  Raises
    InputError (one line) for missing columns, non-increasing time, no
    contact, too few taps or missing probe parameters.
    """
    meta = meta or {}
    if force not in FORCES:
        raise InputError(f"force {force!r} not allowed; choose one of: {', '.join(FORCES)}")
    if method not in METHODS:
        raise InputError(f"method {method!r} not available; choose one of: {', '.join(METHODS)}")
    if isinstance(kg_points, bool) or not isinstance(kg_points, (int, np.integer)) or kg_points < 2:
        raise InputError(f"kg_points {kg_points!r} not allowed; expected an integer >= 2")
    if method == "full":  # whole-cycle model inversion (issue 6); fullfit imports this module
        from .fullfit import extract_full

        return extract_full(df, meta, force=force, kg_points=kg_points, k2=k2, f2=f2, q2=q2, z1=z1, f1=f1,
                            cutoff_hz=cutoff_hz, taper=taper)  # fmt: skip
    force, cols = resolve_force(df, force)

    steady = _segment(df, "steady")
    if steady is None:  # measured data: every row not labelled 'approach'
        steady = df if "segment" not in cols else df[df["segment"].astype(str) != "approach"]
        if not len(steady):
            raise InputError("the table has no rows outside the 'approach' segment to analyse")
    approach = _segment(df, "approach")
    t = _column(steady, "t", "the steady record")
    _check_time(t, "the steady record")
    z = _column(steady, "z_tip", "the steady record")

    params = meta.get("params") or {}
    probe = params.get("probe") or {}
    surface = params.get("surface") or {}
    warnings = []
    info: dict = {}
    t_start = time.perf_counter()

    def force_of(seg, where):
        return force_column(seg, where, force, probe, info, k2=k2, f2=f2, q2=q2, cutoff_hz=cutoff_hz, taper=taper)

    f = steady_force(steady, force, cols, force_of, probe, f1, info)
    t_rec = time.perf_counter()
    z1_value, _ = z1_reference(approach, z1, meta, force_of, info, need_approach=False)

    ex = vetica(t, z, f, z1_value, kg_points=kg_points, kr_guess=kr_guess)
    truth = None
    if all(surface.get(k) is not None for k in ("k0", "k_inf", "cd")):
        truth = theory(surface["k0"], surface["k_inf"], surface["cd"])
    spread = ex.spread()
    out = {}
    for name in NAMES:
        v = _finite_or_none(ex.values.get(name))
        th = _finite_or_none(truth[name]) if truth else None
        err = 100.0 * abs(v - th) / abs(th) if (v is not None and th) else None
        out[name] = {"value": v, "theory": th, "error_pct": err, "spread": spread[name]}
    out["force"] = force
    out["taps"] = ex.taps
    out["method"] = method
    info["timing_s"] = {
        "reconstruction": (t_rec - t_start) if force == "reconstructed" else 0.0,
        **ex.timing_s,
        "total": time.perf_counter() - t_start,
    }
    info["diagnostics"] = ex.diagnostics
    info["warnings"] = warnings + ex.warnings + list(meta.get("warnings") or [])
    out["info"] = info
    return out


ROWS = (
    ("tau_c", "tau_c", "s"),
    ("k_g", "Kg", "N/m"),
    ("k_r", "Kr", "N/m"),
    ("tau_r", "tau_r", "s"),
    ("k0", "k0", "N/m"),
    ("k_inf", "k_inf", "N/m"),
    ("cd", "cd", "kg/s"),
)


def _num(v, fmt=".5g"):
    return "-" if v is None else format(v, fmt)


def format_table(res: dict, source=None) -> str:
    """Plain-text table of an :func:`extract` result (value, theory, error %,
    spread over taps) plus the reconstruction error, Z1 and timing."""
    info = res.get("info", {})
    name = "whole-cycle fit" if res.get("method") == "full" else "VETICA"
    head = f"{name} on {source}" if source is not None else name
    z1 = info.get("z1")
    lines = [
        (
            f"{head}: force {res['force']}, {res['taps']} taps, "
            f"Z1 = {_num(z1 * 1e9 if z1 is not None else None, '.4f')} nm ({info.get('z1_source', '?')})"
        ),
        f"{'quantity':<14}{'value':>13}{'theory':>13}{'error %':>10}   "
        + ("fit uncertainty" if res.get("method") == "full" else "spread over taps (std; min .. max)"),
    ]
    for key, label, unit in ROWS:
        e = res[key]
        sp = e.get("spread") or {}
        spread = (
            f"{_num(sp.get('std'), '.2g')}; {_num(sp.get('min'))} .. {_num(sp.get('max'))} (n={sp.get('n')})"
            if sp.get("n")
            else "-"
        )
        if res.get("method") == "full":  # one fit over the record: 1-sigma and identifiability instead
            u = (res.get("uncertainty") or {}).get(key)
            ok = (res.get("identifiable") or {}).get(key)
            spread = f"1-sigma {_num(u * 100 if u is not None else None, '.2g')} %" + (
                "" if ok is None else ("" if ok else "  NOT IDENTIFIABLE")
            )
        lines.append(
            f"{label + ' [' + unit + ']':<14}{_num(e['value']):>13}{_num(e['theory']):>13}"
            f"{_num(e['error_pct'], '.2f'):>10}   {spread}"
        )
    if "cutoff_hz" in info:
        harm = f" = {info['cutoff_harmonic']:.4g} f1" if "cutoff_harmonic" in info else ""
        lines.append(
            f"force reconstruction: spectral inversion of z_paddle, low-pass cut-off {info['cutoff_hz']:.4g} Hz{harm}"
        )
    if "reconstruction_error" in info:
        r = info["reconstruction_error"]
        lines.append(
            f"reconstructed vs true f_ts (% of peak force): RMS {r['rms_pct']:.2g}, max {r['max_pct']:.2g}, "
            f"peak {r['peak_pct']:+.2g}"
        )
    tm = info.get("timing_s", {})
    if res.get("method") == "full":
        ident = res.get("identifiable") or {}
        for k, why in (res.get("identifiable_reason") or {}).items():
            if why and not ident.get(k, True):
                lines.append(f"{k} not identifiable: {why}")
        if tm:
            lines.append("time: " + ", ".join(f"{k} {v:.2f} s" for k, v in tm.items() if isinstance(v, (int, float))))
    elif tm:
        lines.append(
            f"time: reconstruction {tm.get('reconstruction', 0):.2f} s, stage 1 {tm.get('stage1', 0):.3f} s, "
            f"stage 2 {tm.get('stage2', 0):.3f} s ({tm.get('stage2_per_tap', 0) * 1e3:.0f} ms per tap)"
        )
    for w in info.get("warnings", []):
        lines.append(f"warning: {w}")
    return "\n".join(lines)
