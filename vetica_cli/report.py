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
    st = i.get("steady") or {}
    how = st.get("method", "")
    orbit = st.get("orbit") or {}
    proof = st.get("proof") or {}
    solve = (
        f", orbit solved in {orbit.get('periods')} period evaluations (residual {orbit.get('residual', 0):.2g} m)"
        if how == "orbit" and orbit.get("converged")
        else ""
    )
    stretch = max((abs(v) for v in proof.get("mean_arm_stretch_m") or [0.0]), default=0.0)
    lines = [
        f"stop_reason: {run.stop_reason} ({how}{solve}; {int(i['periods_evaluated'])} periods evaluated, "
        f"{run.wall_s:.2f} s wall)",
        f"periodicity of the recorded window: state change per period {proof.get('state_change_m', float('nan')):.2g} m, "
        f"mean arm stretch {stretch:.2g} m",
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
