"""Per-run observables (thesis ch. 4).

All computed over the recorded steady window, which spans ``record_cycles``
whole drive periods with the base held fixed.  Energies per drive cycle.
"""

from __future__ import annotations

import math

import numpy as np

from ..constants import EV
from ..errors import InputError
from ..signals.taps import find_taps, first_contact_minimum

OBSERVABLE_UNITS = {
    "e_diss_ev": "eV per drive cycle: -(closed integral of f_ts dz_tip), energy the sample takes",
    "peak_force": "N: largest repulsive f_ts",
    "max_penetration": "m: deepest surface position below the undeformed surface (positive into the sample)",
    "contact_time": "s per drive cycle in contact",
    "noncontact_time": "s per drive cycle out of contact",
    "paddle_amplitude": "m: (max - min)/2 of z_paddle",
    "ss_zero_depth": "m: Z1 minus the tip position at the last steady contact (depth of the steady-state zero reference)",
    "amplitude": "m: first-harmonic amplitude of z_tip - z_base",
    "phase_deg": "deg: lag of the first harmonic of z_tip - z_base behind the drive force (90 = free resonance)",
    "virial_ev": "eV: mean of f_ts (z_tip - z_base) over the window",
    "z1": "m: tip position at the first force minimum of the approach (undeformed-surface reference)",
    "contact_pos_dev": (
        "m: tip position at the contact force minimum of each recorded tap (the sample VETICA takes, at the print "
        "step) minus the true contact position (the integration step at which the tip met the surface), mean "
        "over the taps (thesis figs. 59-60)"
    ),
    "separation_pos_dev": "m: the same at separation (force minimum after the peak minus the true separation)",
    "contact_time_dev": "s: time of each tap's contact force minimum minus the true contact time, mean over the taps",
    "separation_time_dev": "s: the same at separation",
}


def first_force_minimum(t: np.ndarray, z_tip: np.ndarray, f_ts: np.ndarray) -> tuple[float, float, int]:
    """Tip position and time at the first force minimum of an approach record:
    the first adhesion well, as VETICA finds it (:func:`vetica_cli.signals.taps.first_contact_minimum`,
    thesis 3.3.1, eq. 84).  Returns ``(z1, t1, index)``; nan, -1 if there is no contact.
    """
    if len(f_ts) == 0:
        return math.nan, math.nan, -1
    try:
        i = first_contact_minimum(f_ts, z=z_tip)
    except InputError:
        return math.nan, math.nan, -1
    return float(z_tip[i]), float(t[i]), i


def harmonic(t: np.ndarray, y: np.ndarray, omega: float) -> tuple[float, float]:
    """First-harmonic amplitude and lag (deg) of ``y`` behind ``cos(omega t)``.

    ``y ~ A cos(omega t - phi)``; for a resonant free oscillator driven by
    ``F0 cos(omega t)``, ``phi = 90`` degrees.  The samples must span whole
    periods.
    """
    c = 2.0 * np.mean(y * np.cos(omega * t))
    s = 2.0 * np.mean(y * np.sin(omega * t))
    return float(np.hypot(c, s)), float(np.degrees(np.arctan2(s, c)))


def tap_deviations(t, z_tip, f_ts, info: dict, period: float) -> dict:
    """Where the record places each tap's contact and separation (its force minima, sampled
    at the print step: what VETICA and an instrument see) against where they happened (the
    kernel's last contact and separation events, to the integration step), thesis figs.
    59-60.  The orbit repeats every period, so each tap is compared with the true event of
    its own period: time differences are taken modulo the period.  Means over the
    record's complete taps; nan without two taps or a true event."""
    out = dict.fromkeys(("contact_pos_dev", "separation_pos_dev", "contact_time_dev", "separation_time_dev"), math.nan)
    try:
        taps = find_taps(f_ts)
    except InputError:
        return out
    for edge, idx in (("contact", taps.contact), ("separation", taps.separation)):
        z_true, t_true = info[f"z_{edge}_last"], info[f"t_{edge}_last"]
        if not len(idx) or not (math.isfinite(z_true) and math.isfinite(t_true)):
            continue
        lag = np.remainder(t[idx] - t_true + 0.5 * period, period) - 0.5 * period
        out[f"{edge}_pos_dev"] = float(np.mean(z_tip[idx] - z_true))
        out[f"{edge}_time_dev"] = float(np.mean(lag))
    return out


def compute_observables(run, cfg, d) -> None:
    """Fill ``run.observables``, ``run.energy`` and ``run.warnings``."""
    from ..core import tapping  # the kernel module (numba): the tables' schemas import this module's units

    s = run.steady
    col = {name: s[:, i] for i, name in enumerate(tapping.COLUMNS[:-1])}
    info = run.info
    cycles = cfg.numerics.record_cycles
    q = col["z_tip"] - col["z_base"]
    amp, phase = info["amplitude_h1"], info["phase_h1_deg"]
    a = run.approach
    z1, _, _ = first_force_minimum(a[:, 0], a[:, 1], a[:, 5]) if len(a) else (math.nan, math.nan, -1)
    contact_time = info["contact_steps"] * d.dt / cycles
    obs = {
        "e_diss_ev": info["w_ts"] / cycles / EV,
        "peak_force": float(np.max(col["f_ts"])),
        "max_penetration": float(-np.min(col["x_surface"])),
        "contact_time": contact_time,
        "noncontact_time": d.period - contact_time,
        "paddle_amplitude": float(0.5 * (np.max(col["z_paddle"]) - np.min(col["z_paddle"]))),
        "ss_zero_depth": z1 - info["z_contact_last"],
        "amplitude": amp,
        "phase_deg": phase,
        "virial_ev": float(np.mean(col["f_ts"] * q)) / EV,
        "z1": z1,
        **tap_deviations(col["t"], col["z_tip"], col["f_ts"], info, d.period),
    }
    run.observables = {k: (None if isinstance(v, float) and math.isnan(v) else float(v)) for k, v in obs.items()}
    run.energy = {
        "drive_work": info["w_drive"] / cycles / EV,
        "cantilever_damping": info["d_cantilever"] / cycles / EV,
        "paddle_damping": info["d_paddle"] / cycles / EV,
        "sample_dissipation": info["w_ts"] / cycles / EV,
        "dashpot_dissipation": info["d_dashpot"] / cycles / EV,
        **(
            {f"dashpot_dissipation_{i + 1}": v / cycles / EV for i, v in enumerate(info["d_dashpot_arms"])}
            if len(info["d_dashpot_arms"]) > 1
            else {}
        ),
        "probe_energy_change": (info["e_mech_end"] - info["e_mech_start"]) / cycles / EV,
    }
    warnings = []
    if not run.steady_ok:
        warnings.append(
            f"no proven periodic state within numerics.max_time = {cfg.numerics.max_time} s "
            f"({run.stop_reason}); the last periods were recorded anyway"
        )
    if not len(a) or math.isnan(z1):
        warnings.append("no first-approach contact recorded: Z1 unknown")
    if info["max_contacts_per_period"] > 1:
        warnings.append(
            f"paddle chatter: up to {int(info['max_contacts_per_period'])} contacts in one drive period "
            "(VETICA assumes one contact and one separation per tap)"
        )
    if info["n_contacts"] == 0:
        warnings.append("no contact during the recorded steady periods")
    run.warnings = warnings
