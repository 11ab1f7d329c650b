"""The one formatter of extraction results: the text table of ``vetica extract`` and
its ``--json`` object (same keys for every method)."""

from __future__ import annotations

from .. import surfaces
from .base import get
from .result import ExtractionResult, Spread, finite_or_none


def _num(v, fmt=".5g"):
    return "-" if v is None else format(v, fmt)


def _spread_text(sp: Spread | None) -> str:
    if sp is None or not sp.n:
        return "-"
    return f"{_num(sp.std, '.2g')}; {_num(sp.min)} .. {_num(sp.max)} (n={sp.n})"


def _sigma_text(e) -> str:
    u = finite_or_none(e.sigma)
    text = f"1-sigma {_num(u * 100 if u is not None else None, '.2g')} %"
    return text + ("  NOT IDENTIFIABLE" if e.identifiable is False else "")


def format_table(res: ExtractionResult, source=None) -> str:
    """Plain-text table of an extraction: value, theory, error % and the spread over taps
    (or, for a method that reports them, the 1-sigma uncertainty and identifiability),
    plus the force reconstruction, Z1, warnings and timing."""
    info = res.info
    method = get(res.method)
    head = f"{method.title} on {source}" if source is not None else method.title
    z1 = info.get("z1")
    with_sigma = any(e.sigma is not None for e in res.estimates.values())
    with_spread = any(e.spread is not None and e.spread.n for e in res.estimates.values())
    labels = surfaces.get(res.model).quantities
    lines = [
        (
            f"{head}: force {res.force}, {res.taps} taps, "
            f"Z1 = {_num(z1 * 1e9 if z1 is not None else None, '.4f')} nm ({info.get('z1_source', '?')})"
        ),
        f"{'quantity':<14}{'value':>13}{'theory':>13}{'error %':>10}   "
        + ("spread over taps (std; min .. max) | standard error" if with_sigma and with_spread
           else "fit uncertainty" if with_sigma else "spread over taps (std; min .. max)"),
    ]
    for key, e in res.estimates.items():
        label = labels[key].label if key in labels else key
        extra = _sigma_text(e) if with_sigma else _spread_text(e.spread)
        if with_sigma and with_spread:
            extra = f"{_spread_text(e.spread)} | {extra}"
        lines.append(
            f"{label + ' [' + e.unit + ']':<14}{_num(e.value):>13}{_num(e.theory):>13}"
            f"{_num(e.error_pct, '.2f'):>10}   {extra}"
        )
    lines += _reference_lines(res)
    lines += _material_lines(res)
    lines += method.detail_lines(res)
    src = (info.get("uncertainty") or {}).get("source")
    if not with_sigma and isinstance(src, str) and src.startswith("none"):
        lines.append(f"standard error: {src}")
    lines += _reconstruction_lines(info)
    for k in res.fitted or [q for q, e in res.estimates.items() if e.identifiable is False]:
        e = res.estimates[k]
        if e.reason and e.identifiable is False:
            lines.append(f"{k} not identifiable: {e.reason}")
    if res.timing_s:
        lines.append(method.timing_line(res.timing_s))
    for w in res.warnings:
        lines.append(f"warning: {w}")
    return "\n".join(lines)


def _si(v, unit: str) -> str:
    """``v`` with an SI prefix: 1.23 GPa, 700 Pa s."""
    if v is None:
        return "-"
    for scale, prefix in ((1e12, "T"), (1e9, "G"), (1e6, "M"), (1e3, "k"), (1.0, ""), (1e-3, "m"), (1e-6, "µ"),
                          (1e-9, "n"), (1e-12, "p")):  # fmt: skip
        if abs(v) >= scale:
            return f"{v / scale:.4g} {prefix}{unit}"
    return f"{v:.4g} {unit}"


def _material_lines(res: ExtractionResult) -> list[str]:
    """Material units (thesis 4.6.2): the moduli and viscosity, then the contact behind them."""
    m, c = res.material, res.contact
    if not m:
        return []
    lines = [f"{'material':<14}{'value':>13}{'theory':>13}{'error %':>10}"]
    for name in ("E_dmt", "E_glassy", "E_rubbery", "viscosity"):
        e = m.get(name)
        if e is None:
            continue
        unit = e["unit"].replace(" ", "·")
        lines.append(f"{name + ' [' + unit + ']':<14}{_num(e['value'], '.4g'):>13}{_num(e.get('theory'), '.4g'):>13}"
                     f"{_num(e.get('error_pct'), '.2f'):>10}   {_si(e['value'], unit)}")  # fmt: skip
    if c:
        r = c["tip_radius"]["value"]
        lines.append(
            f"material from the peak force {_si(m['peak_force']['value'], 'N')} at {_si(m['penetration']['value'], 'm')} "
            f"below Z1 (medians over taps); DMT contact (thesis eqs. 90-92): R {r * 1e9:.4g} nm "
            f"({c.get('tip_radius_source', '?')}), nu tip {c['nu_tip']['value']:g}, nu sample {c['nu_sample']['value']:g}, "
            f"E tip {c['e_tip']['value'] / 1e9:.4g} GPa; viscosity = E_dmt tau_r"
        )
    return lines


def _reference_lines(res: ExtractionResult) -> list[str]:
    """The method's theory-only values (:meth:`~.base.ExtractionMethod.references`), one line."""
    refs = get(res.method).reference_quantities(surfaces.get(res.model))
    items = [f"{q.label} {_num(res.references.get(k), '.4g')}{' ' + q.unit if q.unit else ''}"
             for k, q in refs.items() if res.references.get(k) is not None]  # fmt: skip
    return ["theory: " + ", ".join(items)] if items else []


def _reconstruction_lines(info: dict) -> list[str]:
    lines = []
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
    band = (info.get("uncertainty") or {}).get("band") or {}
    if band.get("bias"):
        worst = sorted(band["bias"].items(), key=lambda kv: -abs(kv[1]))[:3]
        text = ", ".join(f"{q} {100 * b:+.2g} %" if band.get("source") == "model" else
                         f"{q} ~{100 * abs(b):.2g} %" for q, b in worst)  # fmt: skip
        lines.append(
            f"the low-pass's bias, read on the whole-cycle fit's surface and divided out (largest: {text}); its error "
            "is in the standard errors" if band.get("source") == "model" else
            f"the low-pass's bias, estimated on the record (largest: {text}), is in the standard errors"
        )
    if band.get("unmeasured"):
        lines.append(f"the low-pass's bias not read for {', '.join(band['unmeasured'])} (no value on the force low-passed "
                     "once more, no model of it): flagged")  # fmt: skip
    return lines


def to_json(res: ExtractionResult) -> dict:
    """The JSON object of ``vetica extract --json``: ``{quantity: {value, theory, error_pct,
    spread[, sigma][, identifiable, reason]}, ..., force, taps, method[, uncertainty,
    identifiable, identifiable_reason], material, contact_model, info}`` (the keys of version
    0.1 plus ``sigma``, ``identifiable`` and ``reason`` per quantity where the method reports
    them, and the material units: ``material = {E_dmt, E_glassy, E_rubbery, viscosity,
    peak_force, penetration: {value, unit, description[, theory, error_pct]}}`` with the
    contact model behind them in ``contact_model``, thesis 4.6.2)."""
    out: dict = {}
    for name, e in res.estimates.items():
        entry = {
            "value": e.value,
            "theory": e.theory,
            "error_pct": e.error_pct,
            "spread": (e.spread or Spread()).as_dict(),
        }
        if e.sigma is not None:
            entry["sigma"] = finite_or_none(e.sigma)
        if e.identifiable is not None:
            entry.update(identifiable=e.identifiable, reason=e.reason)
        out[name] = entry
    out.update(force=res.force, taps=res.taps, method=res.method)
    if any(e.sigma is not None for e in res.estimates.values()):  # None = unbounded
        out["uncertainty"] = {k: finite_or_none(e.sigma) for k, e in res.estimates.items() if e.sigma is not None}
    if res.fitted:
        out["identifiable"] = {k: bool(res.estimates[k].identifiable) for k in res.fitted}
        out["identifiable_reason"] = {k: res.estimates[k].reason for k in res.fitted}
    if res.references:
        refs = get(res.method).reference_quantities(surfaces.get(res.model))
        out["theory"] = {k: {"value": finite_or_none(v), "unit": refs[k].unit if k in refs else ""}
                         for k, v in res.references.items()}  # fmt: skip
    if res.material is not None:
        out["material"] = res.material
        out["contact_model"] = res.contact
    info = {**res.info, "timing_s": res.timing_s}
    if res.diagnostics is not None:
        info["diagnostics"] = res.diagnostics
    info["warnings"] = list(res.warnings)
    out["info"] = info
    return out
