"""Material units: springs and dashpots turned into moduli and a viscosity (thesis 4.6.2,
eqs. 90-92, table 6).

The surface of the model is a set of springs [N/m] and a dashpot [kg/s]; a material
has moduli [Pa] and a viscosity [Pa s].  The thesis connects them through the DMT
contact of a spherical tip of radius ``R`` (its eq. 4, the Hertz form of the
repulsion; the adhesion is the separate van der Waals term)::

    F      = 4/3 E* sqrt(R) delta^(3/2)                         (eq. 90)
    E*     = 3 F / (4 sqrt(R) delta^(3/2))                      (eq. 91)
    1/E*   = (1 - nu_tip^2)/E_tip + (1 - nu_sample^2)/E_sample  (eq. 92)

with the peak force ``F`` of a tap and the penetration ``delta`` at it; table 6:
``R = 10 nm``, ``nu_tip = nu_sample = 0.3``, ``E_tip = 130 GPa`` (silicon).  The
stiffnesses of the SLS become moduli by the same relation with the spring's force at
that depth, ``F = K delta`` (the secant of eq. 91, so a purely elastic surface gives
one modulus for all three):

    E_dmt      from the measured peak force and penetration       [Pa]
    E_glassy   from Kg = k0 + k_inf (instantaneous response)       [Pa]
    E_rubbery  from Kr = k_inf (relaxed response)                  [Pa]
    viscosity  = E_dmt * tau_r, tau_r = cd / k0                    [Pa s]

The viscosity is the thesis's "modulus times relaxation time" (4.6.2; its range of
700 Pa s to 70 GPa s is the DMT modulus times ``tau_r``).  A contact stiffer than
the tip allows (``1/E* <= (1 - nu_tip^2)/E_tip``) has no finite sample modulus: None.

The contact constants are a :class:`ContactModel`; ``vetica extract --contact
key=value`` and a study's ``material:`` section override them (:func:`contact_model`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ..constants import TIP_RADIUS
from ..ranges import range_of, range_rule
from ..errors import ConfigError
from ..signals.taps import find_taps

CONTACT_NAME = "DMT (thesis eqs. 90-92): F = 4/3 E* sqrt(R) delta^1.5, 1/E* = (1-nu_t^2)/E_t + (1-nu_s^2)/E_s"
CONTACT_SOURCE = "thesis 4.6.2, table 6"


@dataclass(frozen=True)
class ContactModel:
    """Constants of the tip-sample contact (thesis table 6)."""

    tip_radius: float = TIP_RADIUS  # R [m]
    nu_tip: float = 0.3  # Poisson ratio of the tip
    nu_sample: float = 0.3  # Poisson ratio of the sample
    e_tip: float = 130e9  # Young modulus of the tip (silicon) [Pa]

    def as_dict(self) -> dict:
        return asdict(self)


# key -> (unit, predicate, what is allowed)
CONTACT_KEYS = {key: (range_of(key).unit, *range_rule(key)) for key in ("tip_radius", "nu_tip", "nu_sample", "e_tip")}

# name -> (unit, description); the order of the table, the JSON object and the study columns
MATERIAL_UNITS = {
    "E_dmt": ("Pa", "DMT sample modulus from the peak force and the penetration (thesis eqs. 90-92)"),
    "E_glassy": ("Pa", "glassy sample modulus: eqs. 90-92 with F = Kg delta at the same penetration"),
    "E_rubbery": ("Pa", "rubbery sample modulus: eqs. 90-92 with F = Kr delta at the same penetration"),
    "viscosity": ("Pa s", "E_dmt tau_r, the thesis's modulus times relaxation time (4.6.2)"),
}
CONTACT_UNITS = {
    "peak_force": ("N", "peak repulsive force of a tap (median over the taps)"),
    "penetration": ("m", "depth of the tip's lowest point in a tap below the undeformed surface: below Z1, less "
                    "the adhesion lift -Fc/Kg when the surface feels the pull (median over the taps)"),
}


def contact_model(
    overrides: dict | None = None, tip_radius: float | None = None, where: str = "--contact"
) -> ContactModel:
    """A :class:`ContactModel` from the defaults (table 6; ``tip_radius`` replaces the
    default radius, e.g. the simulated probe's) and ``overrides`` ``{key: value}``;
    :class:`ConfigError` (one line) for an unknown key or a value out of range."""
    values = ContactModel().as_dict()
    if tip_radius is not None:
        values["tip_radius"] = float(tip_radius)
    for key, raw in (overrides or {}).items():
        if key not in CONTACT_KEYS:
            raise ConfigError(f"{where}: unknown key {key!r}; allowed: {', '.join(CONTACT_KEYS)}")
        _, pred, allowed = CONTACT_KEYS[key]
        try:
            v = float(raw)
        except (TypeError, ValueError):
            v = math.nan
        if isinstance(raw, bool) or not math.isfinite(v) or not pred(v):
            label = f"{where} {key}={raw}" if where == "--contact" else (
                f"{where}.{key}={raw}" if where.startswith("--") else f"{where}.{key}: {raw!r}")  # fmt: skip
            raise ConfigError(f"{label} is not allowed; expected {allowed}")
        values[key] = v
    return ContactModel(**values)


def parse_contact(items: list[str] | None) -> dict:
    """``--contact key=value`` items -> ``{key: value}`` (values checked by :func:`contact_model`)."""
    out = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep:
            raise ConfigError(
                f"--contact {item!r} is not allowed; expected key=value with key in {', '.join(CONTACT_KEYS)}"
            )
        out[key.strip()] = value.strip()
    return out


def reduced_modulus(force, depth, tip_radius: float):
    """``E* = 3 F / (4 sqrt(R) delta^(3/2))`` [Pa] (thesis eq. 91); nan for ``F <= 0`` or ``delta <= 0``."""
    force = np.asarray(force, dtype=float)
    depth = np.asarray(depth, dtype=float)
    ok = (force > 0) & (depth > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(ok, 3.0 * force / (4.0 * math.sqrt(tip_radius) * np.abs(depth) ** 1.5), np.nan)
    return out if out.ndim else float(out)


def sample_modulus(e_star, cm: ContactModel):
    """Sample modulus from the reduced modulus (thesis eq. 92) [Pa]:
    ``E_s = (1 - nu_s^2) / (1/E* - (1 - nu_t^2)/E_t)``; nan when the contact is at least as
    stiff as the tip alone (no finite sample modulus)."""
    e_star = np.asarray(e_star, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        compliance = 1.0 / e_star - (1.0 - cm.nu_tip**2) / cm.e_tip
        out = np.where(compliance > 0, (1.0 - cm.nu_sample**2) / compliance, np.nan)
    return out if out.ndim else float(out)


def stiffness(e_sample, depth: float, cm: ContactModel) -> float:
    """The spring [N/m] a sample modulus [Pa] acts as at a penetration ``depth`` [m]: the
    inverse of :func:`moduli`'s conversion, ``K = 4/3 E* sqrt(R delta)`` (secant of thesis
    eq. 90) with ``1/E* = (1 - nu_t^2)/E_t + (1 - nu_s^2)/E_s`` (eq. 92)."""
    e_star = 1.0 / ((1.0 - cm.nu_tip**2) / cm.e_tip + (1.0 - cm.nu_sample**2) / float(e_sample))
    return 4.0 / 3.0 * e_star * math.sqrt(cm.tip_radius * depth)


def moduli(peak_force, penetration, k_g, k_r, tau_r, cm: ContactModel) -> dict:
    """``E_dmt, E_glassy, E_rubbery`` [Pa] and ``viscosity`` [Pa s] (module docstring) from
    the peak force [N], the penetration at it [m], the glassy and rubbery stiffness [N/m]
    and the relaxation time [s]; scalars or arrays (a study table's columns), nan where
    an input is unknown or the contact has no finite sample modulus."""
    depth = np.asarray(penetration, dtype=float)
    e_dmt = sample_modulus(reduced_modulus(peak_force, depth, cm.tip_radius), cm)
    e_g = sample_modulus(reduced_modulus(np.asarray(k_g, dtype=float) * depth, depth, cm.tip_radius), cm)
    e_r = sample_modulus(reduced_modulus(np.asarray(k_r, dtype=float) * depth, depth, cm.tip_radius), cm)
    eta = np.asarray(e_dmt) * np.asarray(tau_r, dtype=float)
    return {"E_dmt": e_dmt, "E_glassy": e_g, "E_rubbery": e_r, "viscosity": eta if eta.ndim else float(eta)}


def tap_contact(z: np.ndarray, f: np.ndarray, z1: float, kg: float | None = None, taps=None) -> tuple[float, float]:
    """Peak force [N] and penetration [m] of a record, medians over its complete taps: per
    tap the largest force and the depth of the lowest tip position below the undeformed
    surface.  The tip meets the surface at ``Z1``; when the surface feels the pull it was
    lifted there by the adhesion against its glassy stiffness, so for a given
    ``kg`` [N/m] the lift ``-Fc/Kg`` (``Fc`` the force at the contact minima) is taken off
    the depth below ``Z1``; ``kg`` None: no lift (the surface does not feel the pull, or it
    is not known).  nan when the record has no complete tap.  ``taps``: the record's taps when
    already located (else found on ``f``)."""
    try:
        taps = find_taps(f) if taps is None else taps
    except ValueError:
        return math.nan, math.nan
    if not len(taps.contact):
        return math.nan, math.nan
    peak = [float(np.max(f[c : s + 1])) for c, s in zip(taps.contact, taps.separation)]
    depth = [float(z1 - np.min(z[c : s + 1])) for c, s in zip(taps.contact, taps.separation)]
    lift = -float(np.median(f[taps.contact])) / kg if kg else 0.0
    return float(np.median(peak)), float(np.median(depth)) - lift


def _finite(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def material_entries(peak_force: float, penetration: float, values: dict, truth: dict | None,
                     cm: ContactModel) -> dict:  # fmt: skip
    """The ``material`` object of an extraction: ``{name: {value, unit, description[, theory,
    error_pct]}}`` for :data:`MATERIAL_UNITS` and the contact inputs :data:`CONTACT_UNITS`.
    ``values`` and ``truth`` hold ``k_g, k_r, tau_r`` (extracted; theory when known); the
    theory moduli use the same peak force and penetration."""
    got = moduli(peak_force, penetration, values.get("k_g", math.nan), values.get("k_r", math.nan),
                 values.get("tau_r", math.nan), cm)  # fmt: skip
    th = None
    if truth and all(truth.get(k) is not None for k in ("k_g", "k_r", "tau_r")):
        th = moduli(peak_force, penetration, truth["k_g"], truth["k_r"], truth["tau_r"], cm)
    out = {}
    for name, (unit, desc) in MATERIAL_UNITS.items():
        entry = {"value": _finite(got[name]), "unit": unit, "description": desc}
        if th is not None and name != "E_dmt":
            theory = _finite(th[name])
            entry["theory"] = theory
            v = entry["value"]
            entry["error_pct"] = None if v is None or not theory else 100.0 * (v - theory) / theory
        out[name] = entry
    for name, value in (("peak_force", peak_force), ("penetration", penetration)):
        unit, desc = CONTACT_UNITS[name]
        out[name] = {"value": _finite(value), "unit": unit, "description": desc}
    return out


def contact_metadata(cm: ContactModel, tip_radius_source: str) -> dict:
    """The contact model as a table's or a JSON object's metadata states it."""
    return {
        "model": CONTACT_NAME,
        "source": CONTACT_SOURCE,
        **{k: {"value": v, "unit": CONTACT_KEYS[k][0]} for k, v in cm.as_dict().items()},
        "tip_radius_source": tip_radius_source,
    }
