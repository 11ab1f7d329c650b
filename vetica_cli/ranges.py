"""One range per physical quantity, with where it comes from: the single table every place a
user types a quantity checks against -- config keys (``probe.tip_radius``,
``surface.cd``, ``surface.arms.<i>.e`` ...), the options of every command (``extract
--tip-radius``, ``advise --k-inf``, ``fit --tip-radius`` ...) and the constants stated for
a record -- so a value is refused (one line naming it, the allowed range and its source,
exit status 2) wherever it is typed, and nowhere accepted that another place refuses.

Public API: :data:`QUANTITIES` (quantity -> :class:`Range`), :data:`KEYS` (config key or
option -> quantity), :func:`check_range` (the check, for any command: e.g.
``check_range("tip_radius", value, "--tip-radius")``) and :func:`range_rule` (the
``(predicate, allowed)`` rule of :mod:`vetica_cli.checks`).  A range is wide -- what an
instrument or a material can plausibly have -- and exists to catch a value in the wrong
unit (a radius of 1 m, a stiffness of 1e30 N/m), not to second-guess an unusual one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from .errors import ConfigError


@dataclass(frozen=True)
class Range:
    """``lo <= value <= hi`` (``<`` at an open end) in SI ``unit``; ``what`` names the quantity
    in a message ('a radius'), ``source`` says where the range comes from."""

    lo: float
    hi: float
    unit: str
    what: str
    source: str
    lo_open: bool = False
    hi_open: bool = False

    def ok(self, v: float) -> bool:
        above = v > self.lo if self.lo_open else v >= self.lo
        below = v < self.hi if self.hi_open else v <= self.hi
        return above and below

    def allowed(self, what: str | None = None) -> str:
        """E.g. ``'a radius in [5e-10, 1e-06] m (sharp tips ...)'``."""
        left, right = "(" if self.lo_open else "[", ")" if self.hi_open else "]"
        unit = f" {self.unit}" if self.unit else ""
        return f"{what or self.what} in {left}{self.lo:g}, {self.hi:g}{right}{unit} ({self.source})"


# quantity -> range and its source
QUANTITIES: dict[str, Range] = {
    "tip_radius": Range(0.5e-9, 1e-6, "m", "a radius", "sharp tips are 1-20 nm, the thesis's 10 nm (table 2); a blunt "
                        "tip up to 1 um; larger probes are outside the point-tip vdW and contact model"),
    "hamaker": Range(1e-21, 1e-18, "J", "a Hamaker constant", "Hamaker constants of condensed media across air lie in "
                     "4e-21 .. 5e-19 J (Israelachvili, Intermolecular and Surface Forces, ch. 13); the thesis's 2e-19 J"),
    "a0": Range(0.1e-9, 1e-9, "m", "a distance", "the intermolecular cut-off distance is ~0.165-0.2 nm (thesis "
                "table 2: 0.2 nm)"),
    "free_amplitude": Range(0.1e-9, 1e-6, "m", "an amplitude", "tapping-mode free amplitudes are 1-100 nm (thesis "
                            "table 1: 100 nm)"),
    "quality_factor": Range(0.5, 1e6, "", "a quality factor", "underdamped; air ~100-1000, vacuum up to ~1e5",
                            lo_open=True),
    "flexural_frequency": Range(1e3, 1e8, "Hz", "a frequency", "cantilever resonances lie in 1 kHz .. 10 MHz (thesis "
                                "table 1: 10-100 kHz); a record whose time is in ms shows one below 1 kHz"),
    "torsional_frequency": Range(1e3, 1e9, "Hz", "a frequency", "torsional resonances lie above the flexural ones "
                                 "(thesis 2.4.2: f2 = 15 f1)"),
    "flexural_stiffness": Range(1e-3, 1e3, "N/m", "a stiffness", "cantilever stiffnesses lie in 0.01 .. 100 N/m "
                                "(thesis table 1: 10 N/m)"),
    "torsional_stiffness": Range(1e-1, 1e5, "N/m", "a stiffness", "torsional stiffnesses (thesis table 1: 70-700 N/m; "
                                 "fig. 30 up to 1200)"),
    "surface_stiffness": Range(1e-6, 1e6, "N/m", "a stiffness", "a contact's spring k = 2 a E* (thesis eq. 90): "
                               "contact radii 1-100 nm and moduli 10 Pa .. 1 TPa; thesis table 1: 0.5-128 N/m"),
    "dashpot": Range(1e-18, 1e10, "kg/s", "a dashpot coefficient", "cd = k tau_r over the surface stiffnesses "
                     "1e-6 .. 1e6 N/m and relaxation times 1e-12 .. 1e4 s; thesis table 1: 1e-5 .. 1e3 kg/s"),
    "modulus": Range(10.0, 2e12, "Pa", "a modulus", "the softest hydrogels ~10 Pa .. diamond 1.1 TPa"),
    "relaxation_time": Range(1e-12, 1e4, "s", "a relaxation time", "molecular rearrangements (ps) .. hours of "
                             "polymer creep"),
    "poisson_ratio": Range(-1.0, 0.5, "", "a Poisson ratio", "a stable isotropic solid; 0.5 incompressible",
                           lo_open=True),
    "setpoint": Range(0.0, 1.0, "", "a fraction of the free amplitude", "tapping needs a set amplitude below the free "
                      "one; thesis table 1: 0.25-0.8", lo_open=True, hi_open=True),
    "temperature": Range(0.0, 2000.0, "K", "a temperature", "0 = no thermal noise; an instrument in air ~300 K"),
    "probe_radius": Range(0.5e-9, 1e-4, "m", "a radius", "force curves: sharp tips of 1-20 nm up to colloidal probes "
                          "of 100 um radius (beads of 2-200 um diameter glued to cantilevers for cells and tissue)"),
    "sensitivity": Range(1e-10, 1e-5, "m/V", "a sensitivity", "optical-lever sensitivities are ~10-500 nm/V (the "
                         "afmformats example files: 45-91 nm/V)"),
    "sample_rate": Range(1.0, 1e9, "Hz", "a rate", "force curves are sampled at 10 Hz to 1 MHz (the afmformats example "
                         "files: 205 Hz to 10.7 kHz); 1 GHz is a tapping record's 1 ns print step"),
    "noise_density": Range(0.0, 1e-11, "m/sqrt(Hz)", "a noise density", "0 = none; optical-beam-deflection detectors "
                           "reach 1e-14 .. 1e-13 m/sqrt(Hz) (Fukuma et al. 2005: 1.7e-14)"),
    "time_step": Range(1e-15, 1e-6, "s", "a time step", "the thesis's dt 0.025 ns (table 1); a step of 1 us cannot "
                       "resolve a kHz cantilever"),
    "print_step": Range(1e-12, 1e-4, "s", "a sampling interval", "the thesis's print steps 0.125-8 ns (table 1); "
                        "instrument digitisers sample at 10 kHz .. 10 GHz"),
    "depth": Range(1e-11, 1e-6, "m", "a penetration", "tapping penetrations are 0.1-10 nm (the worked example's "
                   "~2.4 nm)"),
    "scan_size": Range(1e-10, 2e-4, "m", "a scan length", "AFM scanners travel 1 nm .. 100-200 um"),
    "pixel_time": Range(1e-6, 10.0, "s", "a time per pixel", "line rates 0.01-100 Hz over 16-4096 pixels give "
                        "2 us .. 6 s a pixel (thesis 4.6.1: 15 ms settling)"),
}  # fmt: skip

# config key or command option -> quantity (one quantity may be typed in many places)
KEYS: dict[str, str] = {
    "probe.tip_radius": "tip_radius", "--tip-radius": "tip_radius", "tip_radius": "tip_radius",
    "surface.hamaker": "hamaker", "--hamaker": "hamaker",
    "surface.a0": "a0", "--a0": "a0",
    "operation.free_amplitude": "free_amplitude", "--free-amplitude": "free_amplitude",
    "probe.q1": "quality_factor", "probe.q2": "quality_factor", "--q1": "quality_factor", "--q2": "quality_factor",
    "probe.f1": "flexural_frequency", "--f1": "flexural_frequency", "--drive-frequency": "flexural_frequency",
    "probe.f2": "torsional_frequency", "--f2": "torsional_frequency",
    "probe.k1": "flexural_stiffness", "--k1": "flexural_stiffness",
    "probe.k2": "torsional_stiffness", "--k2": "torsional_stiffness",
    "surface.k_inf": "surface_stiffness", "surface.k0": "surface_stiffness", "surface.arms.k": "surface_stiffness",
    "--k-inf": "surface_stiffness", "--k0": "surface_stiffness",
    "surface.cd": "dashpot", "surface.arms.cd": "dashpot", "--cd": "dashpot",
    "surface.e_inf": "modulus", "surface.arms.e": "modulus", "--e-glassy": "modulus", "--e-rubbery": "modulus",
    "e_tip": "modulus",
    "surface.arms.tau": "relaxation_time", "--tau-r": "relaxation_time",
    "surface.nu": "poisson_ratio", "--nu": "poisson_ratio", "nu_tip": "poisson_ratio", "nu_sample": "poisson_ratio",
    "operation.setpoint": "setpoint", "--setpoint": "setpoint",
    "numerics.temperature": "temperature", "numerics.detector_noise_density": "noise_density", "--temperature": "temperature",
    "numerics.dt": "time_step",
    "numerics.print_step": "print_step", "--print-step": "print_step",
    "--depth": "depth",
    "scan.size": "scan_size",
    "fit.tip_radius": "probe_radius", "probe.sensitivity": "sensitivity", "record.rate": "sample_rate",
    "scan.pixel_time": "pixel_time",
}  # fmt: skip


def range_of(key: str) -> Range:
    """The range of a quantity, or of the quantity a config key or option holds."""
    return QUANTITIES[KEYS.get(key, key)]


def range_rule(key: str, what: str | None = None) -> tuple:
    """The ``(predicate, allowed text)`` rule of :mod:`vetica_cli.checks` for a quantity, key or option."""
    r = range_of(key)
    return (r.ok, r.allowed(what))


def check_range(quantity: str, value: Any, name: str | None = None) -> float:
    """``value`` as a float when it is a finite number within the range of ``quantity`` (a
    :data:`QUANTITIES` name, or a key or option of :data:`KEYS`); otherwise ConfigError, one
    line: ``'<name>: <value> is not allowed; expected <what> in [lo, hi] unit (source)'``.
    ``name``: how the user typed it (a config key, ``--tip-radius``); default ``quantity``."""
    r = range_of(quantity)
    name = name or quantity
    try:
        v = float(value) if not isinstance(value, bool) else math.nan
    except (TypeError, ValueError, OverflowError):
        v = math.nan
    if not math.isfinite(v) or not r.ok(v):
        raise ConfigError(f"{name}: {value!r} is not allowed; expected {r.allowed()}")
    return v
