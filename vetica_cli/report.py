"""Short human-readable summaries printed by the commands."""

from __future__ import annotations


def _fmt(v, unit="", scale=1.0, digits=4):
    if v is None:
        return "n/a"
    return f"{v * scale:.{digits}g}{(' ' + unit) if unit else ''}"


def run_summary(run, path=None) -> str:
    """A few lines describing a simulate() run."""
    o = run.observables
    i = run.info
    lines = [
        f"stop_reason: {run.stop_reason} after {i['t_end'] * 1e3:.3f} ms simulated "
        f"({int(i['steps']):,} steps, {run.wall_s:.2f} s wall, {run.wall_s / i['steps'] * 1e9:.1f} ns/step)",
        f"amplitude {_fmt(o['amplitude'], 'nm', 1e9)}, phase {_fmt(o['phase_deg'], 'deg')}, "
        f"E_diss {_fmt(o['e_diss_ev'], 'eV/cycle')}, virial {_fmt(o['virial_ev'], 'eV')}",
        f"peak force {_fmt(o['peak_force'], 'nN', 1e9)}, max penetration {_fmt(o['max_penetration'], 'nm', 1e9)}, "
        f"contact {_fmt(o['contact_time'], 'us', 1e6)} / non-contact {_fmt(o['noncontact_time'], 'us', 1e6)} per cycle",
        f"paddle amplitude {_fmt(o['paddle_amplitude'], 'nm', 1e9)}, Z1 {_fmt(o['z1'], 'nm', 1e9)}, "
        f"steady-state zero depth {_fmt(o['ss_zero_depth'], 'nm', 1e9)}",
    ]
    for w in run.warnings:
        lines.append(f"warning: {w}")
    if path is not None:
        lines.append(f"wrote {path}")
    return "\n".join(lines)
