"""Run figures (``vetica plot RUN``): tip and surface trajectories with the transitions
(thesis fig. 33), force against tip position with the dissipation loop (fig. 28),
reconstructed against true force (thesis 2.3) and the "4-D" force curve (fig. 62, 5.3.1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from .. import surfaces
from ..constants import EV
from ..errors import InputError
from ..signals.spectral import reconstruct_force, spectral_derivative
from ..signals.taps import find_taps
from .style import axis_label, new_figure


@dataclass
class RunData:
    """Steady segment of a run, trimmed to whole drive periods, in SI."""

    t: np.ndarray
    z: np.ndarray
    f: np.ndarray
    x: np.ndarray
    zp: np.ndarray | None
    on: np.ndarray  # sample indices of the contact transitions (force minima)
    off: np.ndarray  # sample indices of the separation transitions (force minima)
    contact: np.ndarray  # bool: tip in contact (from a contact to its separation)
    period: float
    spp: int  # samples per drive period
    a0: float
    z1: float | None
    params: dict
    observables: dict
    cutoff_hz: float | None = None  # low-pass of the spectral operations (None = Nyquist)


def load_run(df: pd.DataFrame, meta: dict) -> RunData:
    """The whole steady periods of a run, with its contact and separation transitions."""
    p = meta["params"]
    try:
        f1 = float(p["probe"]["f1"])
        ps = float(p["numerics"]["print_step"])
        a0 = float(p["surface"]["a0"])
    except (KeyError, TypeError, ValueError):
        raise InputError("run metadata lacks probe.f1, numerics.print_step or surface.a0") from None
    st = df[df["segment"].astype(str) == "steady"].sort_values("t")
    period = 1.0 / f1
    spp = round(period / ps)
    n = (len(st) // spp) * spp
    if n == 0:
        raise InputError(f"the run records {len(st)} steady samples, less than one drive period ({spp} samples)")
    st = st.iloc[:n]
    z = st["z_tip"].to_numpy(float)
    x = st["x_surface"].to_numpy(float)
    f = st["f_ts"].to_numpy(float)
    on, off = find_transitions(z, x, f, a0, spp)
    contact = np.zeros(n, bool)
    for i, j in zip(on, off):
        contact[i : j + 1] = True
    obs = meta.get("observables") or {}
    z1 = obs.get("z1")
    return RunData(
        t=st["t"].to_numpy(float),
        z=z,
        f=f,
        x=x,
        zp=st["z_paddle"].to_numpy(float) if "z_paddle" in st else None,
        on=on,
        off=off,
        contact=contact,
        period=period,
        spp=spp,
        a0=a0,
        z1=float(z1) if z1 is not None else None,
        params=p,
        observables=obs,
    )


def find_transitions(z: np.ndarray, x: np.ndarray, f: np.ndarray, a0: float, spp: int) -> tuple[np.ndarray, np.ndarray]:
    """Sample indices of the contact and separation transitions of each complete tap.

    They are the force minima VETICA reads (thesis 3.3.1 and fig. 32:
    ``F_ts`` is smallest, ``-Fa(a0)``, at contact and at separation), found by
    ``signals.taps.find_taps`` so the figures mark the very points the extraction
    uses.  With fewer than two taps in the record (``spp`` samples per drive
    period tell), ``find_taps`` declines or splits a tap at its paddle
    ringing; then the simulator's own contact state is used: in contact the tip and
    the surface move together at the gap ``a0``, so the edges of
    ``z_tip - x_surface <= a0 (1 + 1e-6)`` are the transitions (noise-free
    records only).
    """
    try:
        taps = find_taps(f)
        if taps.spacing >= 0.75 * spp and len(taps.contact):
            return taps.contact, taps.separation
        # taps closer than a drive period: find_taps split one tap at its paddle ringing (it needs
        # at least two real taps to tell the ringing gaps from the gaps between taps)
    except InputError:
        pass
    c = ((z - x) <= a0 * (1 + 1e-6)).astype(np.int8)
    d = np.diff(c)
    on = np.flatnonzero(d == 1) + 1  # first contact sample
    off = np.flatnonzero(d == -1)  # last contact sample
    if len(on) and len(off) and off[0] < on[0]:
        off = off[1:]
    k = min(len(on), len(off))
    return on[:k], off[:k]


def transitions(run: RunData) -> tuple[np.ndarray, np.ndarray]:
    """(contact, separation) sample indices, one pair per complete tap."""
    return run.on, run.off


def tap_window(run: RunData) -> np.ndarray:
    """Sample indices of one drive period centred on a contact.

    The last contact with half a period recorded on each side; if there is
    none (a record of one period), the record is read as periodic, which it
    is up to the simulator's steady-state drift, and the window wraps.
    """
    on, _ = transitions(run)
    if not len(on):
        raise InputError("no contact in the recorded steady periods")
    half = run.spp // 2
    inside = on[(on - half >= 0) & (on - half + run.spp <= len(run.t))]
    i = int(inside[-1]) if len(inside) else int(on[-1])
    return (np.arange(run.spp) + i - half) % len(run.t)


def loop_energy_ev(z: np.ndarray, f: np.ndarray) -> float:
    """Energy the sample takes over one closed period: ``-closed-integral F_ts dz_tip`` in eV (thesis 4.2.1)."""
    zc = np.append(z, z[0])
    fc = np.append(f, f[0])
    return float(-np.sum(0.5 * (fc[1:] + fc[:-1]) * np.diff(zc)) / EV)


def reconstructed_force(run: RunData, cutoff_hz: float | None = None) -> tuple[np.ndarray | None, str]:
    """Force rebuilt from the paddle signal by spectral inversion (``vetica_cli.signals.spectral.reconstruct_force``,
    thesis eqs. 17-20; ``cutoff_hz`` None = its default, Nyquist), or (None, why not)."""
    if run.zp is None:
        return None, "reconstructed-force figure skipped: the run has no z_paddle column"
    p = run.params["probe"]
    rec = reconstruct_force(run.t, run.zp, k2=float(p["k2"]), f2=float(p["f2"]), q2=float(p["q2"]), cutoff_hz=cutoff_hz)
    return np.asarray(rec.f, float), ""


def _system_line(p: dict, cutoff_hz: float | None = None) -> str:
    pr, op, su, nu = p["probe"], p["operation"], p["surface"], p["numerics"]
    model = surfaces.get(su.get("model", surfaces.DEFAULT_MODEL))
    return (
        f"$f_1$ {pr['f1'] * 1e-3:g} kHz, $f_2$ {pr['f2'] * 1e-3:g} kHz, $k_1$ {pr['k1']:g} N/m, $k_2$ {pr['k2']:g} N/m, "
        f"$A_{{sp}}$ {op['setpoint'] * op['free_amplitude'] * 1e9:g} nm, PS {nu['print_step'] * 1e9:g} ns, "
        + ", ".join(model.title_items(su))
        + (f"; spectral low-pass {cutoff_hz * 1e-6:g} MHz" if cutoff_hz else "")
        + (
            f"; noise {nu.get('position_noise', 0) * 1e12:g} pm, {nu.get('force_noise', 0) * 1e9:g} nN RMS"
            if nu.get("position_noise") or nu.get("force_noise")
            else ""
        )
    )


def run_figures(df: pd.DataFrame, meta: dict, cutoff_hz: float | None = None) -> tuple[list, list]:
    """[(name, Figure)], [notes] for a simulate run."""
    run = load_run(df, meta)
    run.cutoff_hz = cutoff_hz
    figs, notes = [], []
    nu = run.params.get("numerics", {})
    if cutoff_hz is None and (nu.get("position_noise") or nu.get("force_noise")):
        notes.append(
            "the run has detector noise: spectral inversion and the spectral derivative amplify it up to "
            "Nyquist; pass --cutoff HZ (e.g. a few times the paddle resonance) for readable force curves"
        )
    figs.append(("fig33_trajectories", fig_trajectories(run)))
    if not run.contact.any():
        notes.append("force-curve figures skipped: no contact in the recorded steady periods")
        return figs, notes
    f_rec, why = reconstructed_force(run, cutoff_hz)
    if why:
        notes.append(why)
    figs.append(("fig28_force_distance", fig_force_distance(run, f_rec)))
    if f_rec is not None:
        figs.append(("force_reconstruction", fig_reconstruction(run, f_rec)))
    figs.append(("fig62_force_distance_velocity", fig_force_velocity(run, f_rec)))
    return figs, notes


def fig_trajectories(run: RunData) -> Figure:
    """Tip and surface positions over the recorded taps, transitions marked (thesis fig. 33)."""
    t_us = (run.t - run.t[0]) * 1e6
    z_nm, x_nm = run.z * 1e9, run.x * 1e9
    on, off = transitions(run)
    fig = new_figure(11, 7.5)
    ax_all, ax_zoom = fig.subplots(2, 1)
    k = max(1, len(t_us) // 20000)  # overview: about 2000 points per period is plenty
    ax_all.plot(t_us[::k], z_nm[::k], color="tab:blue", lw=0.9, label="tip $z_{tip}$")
    ax_all.plot(t_us[::k], x_nm[::k], color="tab:red", ls="--", lw=1.2, label="surface $X$")
    ax_all.set_ylabel(axis_label("position above the undeformed surface", "nm"))
    ax_all.set_xlabel(axis_label("time since the start of the recorded steady window", "µs"))
    ax_all.set_title("(a) all recorded steady drive periods", fontsize=10, loc="left")
    ax_all.legend(loc="upper right", fontsize=8)
    # (b) zoom on the surface over at most three taps: the creep between taps
    n_taps = min(3, max(1, len(on)))
    end = on[n_taps] if len(on) > n_taps else len(t_us)
    start = max(0, on[0] - run.spp // 8) if len(on) else 0
    sl = slice(start, end)
    ax_zoom.plot(t_us[sl], z_nm[sl], color="tab:blue", lw=1.0, label="tip $z_{tip}$")
    ax_zoom.plot(t_us[sl], x_nm[sl], color="tab:red", ls="--", lw=1.5, label="surface $X$")
    for idx, lab in ((on, "contact"), (off, "separation")):
        idx = idx[(idx >= sl.start) & (idx < sl.stop)]
        ax_zoom.plot(
            t_us[idx],
            z_nm[idx],
            "kx" if lab == "contact" else "k+",
            ms=9,
            mew=1.8,
            ls="none",
            label=f"{lab} (force minimum)",
        )
    if run.z1 is not None:
        ax_zoom.axhline(run.z1 * 1e9, color="0.4", ls=":", lw=1, label=r"$Z_1$ (first-approach contact)")
    lo = np.min(x_nm[sl])
    hi = max(run.z1 * 1e9 if run.z1 is not None else 0.0, np.max(z_nm[on]) if len(on) else 0.0)
    pad = 0.25 * (hi - lo) + 0.1
    ax_zoom.set_ylim(lo - pad, hi + 2 * pad)
    ax_zoom.set_xlim(t_us[sl.start], t_us[sl.stop - 1])
    ax_zoom.set_ylabel(axis_label("position", "nm"))
    ax_zoom.set_xlabel(axis_label("time since the start of the recorded steady window", "µs"))
    ax_zoom.set_title(f"(b) near the surface, {n_taps} taps: surface creep between taps", fontsize=10, loc="left")
    ax_zoom.legend(loc="upper right", fontsize=8, ncol=3)
    for ax in (ax_all, ax_zoom):
        ax.grid(alpha=0.3)
    fig.suptitle(
        "Tip and surface trajectories with the contact/separation transitions (cf. thesis fig. 33)\n"
        + _system_line(run.params),
        fontsize=10,
    )
    return fig


def _force_window(run: RunData, sl: np.ndarray) -> tuple[float, float]:
    """x-limits (nm) of a force-distance plot: the contact excursion plus the attractive tail."""
    z = run.z[sl] * 1e9
    c = run.contact[sl]
    zc = z[c]
    span = max(np.ptp(zc), 0.5)
    return float(np.min(z) - 0.1 * span), float(np.max(zc) + max(1.0, 0.6 * span))


def _near(run: RunData, sl: np.ndarray, zmax_nm: float) -> np.ndarray:
    """The contiguous samples of the tap window around its contact with the tip below ``zmax_nm``
    (what a force-distance plot shows; the rest of the period is far from the surface)."""
    z = run.z[sl] * 1e9
    ic = np.flatnonzero(run.contact[sl])
    above = z > zmax_nm
    left = np.flatnonzero(above[: ic[0]])
    right = np.flatnonzero(above[ic[-1] :])
    a = left[-1] if len(left) else 0
    b = ic[-1] + right[0] + 1 if len(right) else len(z)
    return sl[a:b]


def fig_force_distance(run: RunData, f_rec: np.ndarray | None) -> Figure:
    """Force against tip position over one tap, with the dissipation loop (thesis fig. 28).

    ``E_diss = -closed-integral F_ts dz_tip`` over the drawn period (eV); the
    run's kernel value (integrated at ``dt``) is quoted beside it.
    """
    period = tap_window(run)
    xlo, xhi = _force_window(run, period)
    sl = _near(run, period, xhi + 0.05 * (xhi - xlo))
    z_nm, f_nn = run.z[sl] * 1e9, run.f[sl] * 1e9
    v = np.gradient(run.z[sl])
    down = v < 0
    fig = new_figure(9, 6.5)
    ax = fig.subplots()
    ax.fill(z_nm, f_nn, color="gold", alpha=0.35, lw=0, label="dissipation loop (area = $E_{diss}$)")
    zd, fd = np.where(down, z_nm, np.nan), np.where(down, f_nn, np.nan)
    zu, fu = np.where(~down, z_nm, np.nan), np.where(~down, f_nn, np.nan)
    ax.plot(zd, fd, color="tab:blue", lw=1.6, label="true $F_{ts}$, approach (tip moving down)")
    ax.plot(zu, fu, color="tab:red", lw=1.6, label="true $F_{ts}$, retract (tip moving up)")
    e_true = loop_energy_ev(run.z[period], run.f[period])
    text = [f"$E_{{diss}}$ (loop area, true force) = {e_true:.4g} eV/cycle"]
    if f_rec is not None:
        ax.plot(z_nm, f_rec[sl] * 1e9, color="k", ls="--", lw=1.0, label="reconstructed force (spectral inversion)")
        text.append(
            f"$E_{{diss}}$ (loop area, reconstructed) = {loop_energy_ev(run.z[period], f_rec[period]):.4g} eV/cycle"
        )
    e_kernel = run.observables.get("e_diss_ev")
    if e_kernel is not None:
        text.append(f"$E_{{diss}}$ (run, integrated at dt) = {e_kernel:.4g} eV/cycle")
    _mark_transitions(ax, run, sl, z_nm, f_nn)
    ax.axhline(0, color="0.5", lw=0.6)
    ax.axvline(0, color="0.5", lw=0.6, ls=":", label="undeformed surface ($z_{tip}$ = 0)")
    ax.set_xlim(xlo, xhi)
    ax.set_xlabel(axis_label("tip position $z_{tip}$ above the undeformed surface", "nm"))
    ax.set_ylabel(axis_label("tip-sample force $F_{ts}$ (repulsive > 0)", "nN"))
    ax.legend(loc="upper right", fontsize=8)
    ax.text(
        0.98,
        0.5,
        "\n".join(text),
        transform=ax.transAxes,
        ha="right",
        va="top",
        fontsize=9,
        bbox={"boxstyle": "round", "fc": "white", "ec": "0.7"},
    )
    ax.grid(alpha=0.3)
    fig.suptitle(
        "Force against tip position over one steady tap: the dissipation loop (cf. thesis fig. 28)\n"
        + _system_line(run.params),
        fontsize=10,
    )
    return fig


def _mark_transitions(ax, run: RunData, sl: np.ndarray, z_nm: np.ndarray, f_nn: np.ndarray) -> None:
    """D1 contact, D2 peak force and D3 separation of the drawn tap (thesis fig. 28)."""
    on, off = transitions(run)
    i_on = np.flatnonzero(np.isin(sl, on))
    i_off = np.flatnonzero(np.isin(sl, off))
    marks = [
        (i_on[0] if len(i_on) else None, "D1: contact (force minimum before the repulsion)", "x"),
        (int(np.argmax(f_nn)), "D2: peak force", "^"),
        (i_off[0] if len(i_off) else None, "D3: separation (force minimum after it)", "+"),
    ]
    for i, lab, m in marks:
        if i is None:
            continue
        ax.plot(z_nm[i], f_nn[i], m, color="k", ms=10, mew=2, ls="none", label=f"{lab}, $z_{{tip}}$ {z_nm[i]:.3g} nm")


def fig_reconstruction(run: RunData, f_rec: np.ndarray) -> Figure:
    """Reconstructed (spectral inversion) against true force over one tap, and their difference."""
    sl = tap_window(run)
    t_us = np.arange(len(sl)) * (run.period / run.spp) * 1e6
    ft, fr = run.f[sl] * 1e9, f_rec[sl] * 1e9
    c = run.contact[sl]
    ic = np.flatnonzero(c)
    pad = max(ic[-1] - ic[0], 10)
    zoom = slice(max(0, ic[0] - pad), min(len(t_us), ic[-1] + pad))
    err = fr - ft
    e_all = f_rec - run.f
    peak = float(np.max(run.f)) * 1e9
    rms = float(np.sqrt(np.mean(e_all**2))) * 1e9
    worst = float(np.max(np.abs(e_all))) * 1e9
    dpk = float(np.max(f_rec) - np.max(run.f)) * 1e9
    fig = new_figure(10, 7)
    ax, ax_err = fig.subplots(2, 1, sharex=True, height_ratios=[2.2, 1])
    ax.plot(t_us[zoom], ft[zoom], color="k", lw=1.8, label="true $F_{ts}$ (simulator)")
    ax.plot(t_us[zoom], fr[zoom], color="tab:red", ls="--", lw=1.4, label="reconstructed (spectral inversion)")
    ax.set_ylabel(axis_label("force", "nN"))
    ax.legend(fontsize=9)
    ax.grid(alpha=0.3)
    ax_err.plot(t_us[zoom], err[zoom], color="tab:purple", lw=1.0)
    ax_err.axhline(0, color="0.5", lw=0.6)
    ax_err.set_ylabel(axis_label("reconstructed - true", "nN"))
    ax_err.set_xlabel(axis_label("time within the drawn period", "µs"))
    ax_err.grid(alpha=0.3)
    ax_err.set_title(
        f"difference; over all {len(run.t) // run.spp} steady periods, relative to the peak force {peak:.3g} nN:\n"
        f"RMS {rms:.3g} nN ({100 * rms / peak:.2g} %), largest {worst:.3g} nN ({100 * worst / peak:.2g} %), "
        f"peak {dpk:+.3g} nN ({100 * dpk / peak:+.2g} %)",
        fontsize=9,
        loc="left",
    )
    fig.suptitle(
        "Reconstructed against true tip-sample force over one contact (thesis 2.3, eqs. 17-20)\n"
        + _system_line(run.params, run.cutoff_hz),
        fontsize=10,
    )
    return fig


def fig_force_velocity(run: RunData, f_rec: np.ndarray | None) -> Figure:
    """ "4-D" force curve: force against tip position and tip velocity (thesis fig. 62, 5.3.1).

    Velocity from the spectral derivative ``i w Z(w)`` over all whole steady
    periods (thesis eq. 93); drawn over one tap near the surface.
    """
    dt = float(run.params["numerics"]["print_step"])
    v_all = spectral_derivative(run.z, dt, run.cutoff_hz)
    period = tap_window(run)
    _xlo, xhi = _force_window(run, period)
    sl = _near(run, period, xhi)
    z_nm, f_nn, v_mm = run.z[sl] * 1e9, run.f[sl] * 1e9, v_all[sl] * 1e3
    down = v_mm < 0
    fig = new_figure(13, 6)
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2)
    for mask, col, lab in ((down, "tab:blue", "approach (v < 0)"), (~down, "tab:red", "retract (v > 0)")):
        zz, vv, ff = (np.where(mask, a, np.nan) for a in (z_nm, v_mm, f_nn))
        ax3.plot(zz, vv, ff, color=col, lw=2.4, label=f"true $F_{{ts}}$, {lab}")
        ax2.plot(vv, ff, color=col, lw=2.4, label=f"true $F_{{ts}}$, {lab}")
    if f_rec is not None:
        fr = f_rec[sl] * 1e9
        ax3.plot(z_nm, v_mm, fr, color="k", ls="--", lw=0.8, alpha=0.7, label="reconstructed force (dashed)")
        ax2.plot(v_mm, fr, color="k", ls="--", lw=0.8, alpha=0.7, label="reconstructed force (dashed)")
    # arrows along the trajectory (direction of time), as in the thesis figure
    for k in range(len(z_nm) // 9, len(z_nm) - 1, max(1, len(z_nm) // 9)):
        col = "tab:blue" if down[k] else "tab:red"
        ax2.annotate(
            "",
            xy=(v_mm[k + 1], f_nn[k + 1]),
            xytext=(v_mm[k], f_nn[k]),
            arrowprops={"arrowstyle": "-|>", "color": col, "lw": 1.2, "mutation_scale": 14},
        )
    ax3.set_xlabel(axis_label("tip position", "nm"))
    ax3.set_ylabel(axis_label("tip velocity", "mm/s"))
    ax3.set_zlabel(axis_label("$F_{ts}$", "nN"))
    ax3.view_init(elev=22, azim=-55)
    ax3.set_title("(a) force against position and velocity", fontsize=10, loc="left")
    ax3.legend(fontsize=8, loc="upper left")
    ax2.axhline(0, color="0.5", lw=0.6)
    ax2.axvline(0, color="0.5", lw=0.6)
    ax2.set_xlabel(axis_label("tip velocity $dz_{tip}/dt$ (spectral derivative)", "mm/s"))
    ax2.set_ylabel(axis_label("tip-sample force $F_{ts}$", "nN"))
    ax2.set_title(f"(b) projection on force-velocity; tip below {xhi:.2g} nm, arrows = time", fontsize=10, loc="left")
    ax2.legend(fontsize=8)
    ax2.grid(alpha=0.3)
    fig.suptitle(
        '"4-D" force curve: force against distance and tip velocity (cf. thesis fig. 62, section 5.3.1)\n'
        + _system_line(run.params, run.cutoff_hz),
        fontsize=10,
    )
    return fig
