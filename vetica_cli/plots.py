"""Figures from vetica tables (``vetica plot``), headless (matplotlib Agg).

Two kinds of input, told apart by their columns and metadata:

* a **run** written by ``vetica simulate`` (columns ``t, z_tip, f_ts,
  x_surface, z_paddle, segment``; metadata ``params``) gives the per-run
  figures of the thesis: tip and surface trajectories with the transition
  points (thesis fig. 33), force against tip position with the dissipation
  loop (fig. 28), reconstructed against true force (spectral inversion,
  thesis 2.3) and the "4-D" force curve, force against distance and tip
  velocity (fig. 62, thesis 5.3.1);
* a **sweep table** written by ``vetica sweep`` (one row per point and force
  source) gives the parametric-study figures of thesis chapter 4, chosen from
  the keys that were swept (see :func:`select_sweep_figures`).

Displayed units are the engineering ones a researcher reads (nm, nN, us, eV,
kHz, ns); the tables stay SI.  Conventions shared by every sweep figure:
true force = solid line, filled marker; reconstructed force = dashed line,
open marker; ``not_steady`` points are drawn with a grey cross over the
marker and do not count for the acceptance regime; ``failed`` points are
excluded and counted in the note at the bottom of the figure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure

from .constants import EV
from .errors import InputError
from .io import read_table
from .signals.spectral import reconstruct_force, spectral_derivative
from .signals.taps import find_taps

# ---------------------------------------------------------------------------
# display conventions

ACCEPT_PCT = 30.0  # acceptance regime: tau_c error below 30 % (thesis fig. 52)
ERR_FLOOR = 1e-3  # errors below this (%) are drawn at it on log axes
SOURCES = ("true", "reconstructed")
SOURCE_LABEL = {"true": "true force $F_{ts}$", "reconstructed": "reconstructed force (spectral inversion)"}
SOURCE_LS = {"true": "-", "reconstructed": "--"}
SOURCE_FILLED = {"true": True, "reconstructed": False}

# extracted quantities: column -> (label, unit, SI->display factor); styles as thesis fig. 46
QUANTITIES = {
    "tau_c": (r"$\tau_c$", "µs", 1e6),
    "k_g": (r"$K_g$", "N/m", 1.0),
    "k0": (r"$k_0$", "N/m", 1.0),
    "k_inf": (r"$k_\infty$", "N/m", 1.0),
    "cd": (r"$c_d$", "kg/s", 1.0),
}
Q_STYLE = {  # thesis fig. 46: tau_c green crosses, Kg magenta stars, k0 black circles, k_inf blue diamonds, cd red squares
    "tau_c": ("tab:green", "P"),
    "k_g": ("m", "*"),
    "k0": ("k", "o"),
    "k_inf": ("tab:blue", "D"),
    "cd": ("tab:red", "s"),
}

OBSERVABLES = {
    "e_diss_ev": (r"$E_{diss}$", "eV per cycle", 1.0),
    "peak_force": ("peak force", "nN", 1e9),
    "max_penetration": ("max. surface penetration", "nm", 1e9),
    "contact_time": ("contact time", "µs per cycle", 1e6),
    "noncontact_time": ("non-contact time", "µs per cycle", 1e6),
    "paddle_amplitude": ("paddle amplitude", "nm", 1e9),
    "ss_zero_depth": ("steady-state zero reference depth", "nm", 1e9),
}

# swept keys we know: key -> (label, unit, SI->display factor, scale)
CD, RATIO, SETPOINT, F1, PS, K2 = (
    "surface.cd",
    "surface.stiffness_ratio",
    "operation.setpoint",
    "probe.f1",
    "numerics.print_step",
    "probe.k2",
)
AXES = {
    CD: ("dashpot $c_d$", "kg/s", 1.0, "log"),
    RATIO: (r"stiffness ratio $k_0:k_\infty$", "", 1.0, "log2"),
    SETPOINT: ("amplitude set point", r"% of $A_0$", 100.0, "linear"),
    F1: ("cantilever resonance $f_1$", "kHz", 1e-3, "linear"),
    PS: ("print step PS", "ns", 1e9, "log2"),
    K2: ("paddle stiffness $k_2$", "N/m", 1.0, "linear"),
    "surface.k0": ("$k_0$", "N/m", 1.0, "log"),
    "surface.k_inf": (r"$k_\infty$", "N/m", 1.0, "log"),
    "probe.f2": ("paddle resonance $f_2$", "kHz", 1e-3, "linear"),
    "probe.k1": ("cantilever stiffness $k_1$", "N/m", 1.0, "linear"),
    "operation.free_amplitude": ("free amplitude $A_0$", "nm", 1e9, "linear"),
}
SHORT = {CD: "$c_d$", RATIO: r"$k_0:k_\infty$", SETPOINT: "set point", F1: "$f_1$", PS: "PS", K2: "$k_2$"}

RUN_COLUMNS = ("t", "z_tip", "f_ts", "x_surface", "segment")
SWEEP_COLUMNS = ("force_source", "status")



@dataclass
class PlotResult:
    """Files written and remarks for the user (figures skipped and why)."""

    paths: list = field(default_factory=list)
    notes: list = field(default_factory=list)


# ---------------------------------------------------------------------------
# entry point


def plot(path: str | Path, outdir: str | Path | None = None, cutoff_hz: float | None = None) -> PlotResult:
    """Write the figures for a run or sweep table into ``outdir``.

    ``outdir`` defaults to ``figures/`` next to the table.  ``cutoff_hz`` is
    the low-pass cut-off of the run figures' spectral operations (force
    reconstruction and tip velocity; None = Nyquist, as ``vetica extract``).  Files are named
    ``<table stem>_<figure>.png``, so several studies can share one folder.
    The input is read and checked completely before any file is written;
    each PNG is written to a temporary file and renamed into place.
    Raises InputError (one line) for a missing, corrupt or non-vetica file.
    """
    path = Path(path)
    if cutoff_hz is not None and not (math.isfinite(cutoff_hz) and cutoff_hz > 0):
        raise InputError(f"--cutoff {cutoff_hz!r} is not allowed; expected a frequency > 0 Hz")
    df, meta = read_table(path)
    kind = table_kind(df, meta, path)
    if kind == "run":
        figures, notes = run_figures(df, meta, cutoff_hz)
    else:
        figures, notes = sweep_figures(df, meta)
    outdir = Path(outdir) if outdir is not None else path.parent / "figures"
    result = PlotResult(notes=notes)
    for name, fig in figures:
        result.paths.append(_save(fig, outdir / f"{path.stem}_{name}.png"))
    return result


def table_kind(df: pd.DataFrame, meta: dict, path: Path | str = "table") -> str:
    """'run' or 'sweep'; InputError naming what is missing otherwise."""
    if not meta:
        raise InputError(
            f"{path}: no 'vetica' metadata; expected a run from 'vetica simulate' or a table from 'vetica sweep'"
        )
    if all(c in df.columns for c in SWEEP_COLUMNS):
        return "sweep"
    if all(c in df.columns for c in RUN_COLUMNS):
        if not isinstance(meta.get("params"), dict):
            raise InputError(f"{path}: run table without 'params' in its metadata; rewrite it with 'vetica simulate'")
        return "run"
    missing_run = [c for c in RUN_COLUMNS if c not in df.columns]
    raise InputError(
        f"{path}: neither a run (missing columns {', '.join(missing_run)}) "
        f"nor a sweep table (needs columns {', '.join(SWEEP_COLUMNS)})"
    )


def _save(fig: Figure, target: Path) -> Path:
    from .io import atomic_path

    with atomic_path(target) as tmp:
        FigureCanvasAgg(fig)
        _lean_log_axes(fig)
        fig.savefig(tmp, format="png", dpi=130)
    return target


def _lean_log_axes(fig: Figure) -> None:
    """No minor ticks on log axes spanning more than three decades: a tick per decade reads
    better there, and the minor tick artists were most of the drawing time."""
    from matplotlib.ticker import NullLocator

    for ax in fig.axes:
        for axis, lim, scale in ((ax.xaxis, ax.get_xlim, ax.get_xscale), (ax.yaxis, ax.get_ylim, ax.get_yscale)):
            if scale() != "log":
                continue
            lo, hi = sorted(lim())
            if lo > 0 and hi / lo > 1e3:
                axis.set_minor_locator(NullLocator())


def _figure(w: float, h: float) -> Figure:
    fig = Figure(figsize=(w, h), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _label(name: str, unit: str) -> str:
    return f"{name} [{unit}]" if unit else name


def _note(fig: Figure, text: str) -> None:
    """A grey note under the axes (excluded points, how a curve was averaged); space is reserved for it."""
    if not text:
        return
    lines = max(1, math.ceil(len(text) / (fig.get_figwidth() * 15)))
    h = (0.06 + 0.14 * lines) / fig.get_figheight()
    fig.get_layout_engine().set(rect=(0, h, 1, 1 - h))
    fig.text(0.005, 0.004, text, fontsize=7.5, color="0.3", ha="left", va="bottom", wrap=True)


# ---------------------------------------------------------------------------
# run figures


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
    the surface move together at the gap ``a0`` (SPEC 3), so the edges of
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
    return (
        f"$f_1$ {pr['f1'] * 1e-3:g} kHz, $f_2$ {pr['f2'] * 1e-3:g} kHz, $k_1$ {pr['k1']:g} N/m, $k_2$ {pr['k2']:g} N/m, "
        f"$A_{{sp}}$ {op['setpoint'] * op['free_amplitude'] * 1e9:g} nm, PS {nu['print_step'] * 1e9:g} ns, "
        f"$k_\\infty$ {su['k_inf']:g} N/m, $k_0$ {su['k0']:g} N/m, $c_d$ {su['cd']:g} kg/s"
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
    fig = _figure(11, 7.5)
    ax_all, ax_zoom = fig.subplots(2, 1)
    k = max(1, len(t_us) // 20000)  # overview: about 2000 points per period is plenty
    ax_all.plot(t_us[::k], z_nm[::k], color="tab:blue", lw=0.9, label="tip $z_{tip}$")
    ax_all.plot(t_us[::k], x_nm[::k], color="tab:red", ls="--", lw=1.2, label="surface $X$")
    ax_all.set_ylabel(_label("position above the undeformed surface", "nm"))
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
    ax_zoom.set_ylabel(_label("position", "nm"))
    ax_zoom.set_xlabel(_label("time since the start of the recorded steady window", "µs"))
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
    fig = _figure(9, 6.5)
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
    on, off = transitions(run)
    i_on = np.flatnonzero(np.isin(sl, on))
    i_off = np.flatnonzero(np.isin(sl, off))
    i_pk = int(np.argmax(f_nn))
    marks = [
        (i_on[0] if len(i_on) else None, "D1 contact", "x"),
        (i_pk, "D2 peak force", "^"),
        (i_off[0] if len(i_off) else None, "D3 separation", "+"),
    ]
    for i, lab, m in marks:
        if i is None:
            continue
        ax.plot(z_nm[i], f_nn[i], m, color="k", ms=10, mew=2, ls="none", label=f"{lab}: {z_nm[i]:.3g} nm")
    ax.axhline(0, color="0.5", lw=0.6)
    ax.axvline(0, color="0.5", lw=0.6, ls=":")
    ax.set_xlim(xlo, xhi)
    ax.set_xlabel(_label("tip position $z_{tip}$ above the undeformed surface", "nm"))
    ax.set_ylabel(_label("tip-sample force $F_{ts}$ (repulsive > 0)", "nN"))
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
    fig = _figure(10, 7)
    ax, ax_err = fig.subplots(2, 1, sharex=True, height_ratios=[2.2, 1])
    ax.plot(t_us[zoom], ft[zoom], color="k", lw=1.8, label="true $F_{ts}$ (simulator)")
    ax.plot(t_us[zoom], fr[zoom], color="tab:red", ls="--", lw=1.4, label="reconstructed (spectral inversion)")
    ax.set_ylabel(_label("force", "nN"))
    ax.legend(fontsize=9)
    ax.grid(alpha=0.3)
    ax_err.plot(t_us[zoom], err[zoom], color="tab:purple", lw=1.0)
    ax_err.axhline(0, color="0.5", lw=0.6)
    ax_err.set_ylabel(_label("reconstructed - true", "nN"))
    ax_err.set_xlabel(_label("time within the drawn period", "µs"))
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
    fig = _figure(13, 6)
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
    ax3.set_xlabel(_label("tip position", "nm"))
    ax3.set_ylabel(_label("tip velocity", "mm/s"))
    ax3.set_zlabel(_label("$F_{ts}$", "nN"))
    ax3.view_init(elev=22, azim=-55)
    ax3.set_title("(a) force against position and velocity", fontsize=10, loc="left")
    ax3.legend(fontsize=8, loc="upper left")
    ax2.axhline(0, color="0.5", lw=0.6)
    ax2.axvline(0, color="0.5", lw=0.6)
    ax2.set_xlabel(_label("tip velocity $dz_{tip}/dt$ (spectral derivative)", "mm/s"))
    ax2.set_ylabel(_label("tip-sample force $F_{ts}$", "nN"))
    ax2.set_title(f"(b) projection on force-velocity; tip below {xhi:.2g} nm, arrows = time", fontsize=10, loc="left")
    ax2.legend(fontsize=8)
    ax2.grid(alpha=0.3)
    fig.suptitle(
        '"4-D" force curve: force against distance and tip velocity (cf. thesis fig. 62, section 5.3.1)\n'
        + _system_line(run.params, run.cutoff_hz),
        fontsize=10,
    )
    return fig


# ---------------------------------------------------------------------------
# sweep tables

AXIS_PRIORITY = [CD, RATIO, SETPOINT, F1, PS, K2]


def _find_sweep_block(meta, depth: int = 0):
    """The resolved 'sweep' mapping anywhere in the first levels of the metadata (None if absent)."""
    if not isinstance(meta, dict) or depth > 3:
        return None
    if isinstance(meta.get("sweep"), dict):
        return meta["sweep"]
    for v in meta.values():
        found = _find_sweep_block(v, depth + 1)
        if found is not None:
            return found
    return None


def _names_in(block) -> set:
    """Every dotted name mentioned as a key in a sweep block (zip groups included)."""
    out = set()
    if isinstance(block, dict):
        for k, v in block.items():
            if isinstance(k, str) and "." in k:
                out.add(k)
            out |= _names_in(v)
    elif isinstance(block, list):
        for v in block:
            out |= _names_in(v)
    return out


def _base_config(meta) -> dict | None:
    """The study's fixed parameters (a dict with probe/operation/surface/numerics sections), if recorded."""
    for cand in (meta, meta.get("config"), meta.get("params"), meta.get("base")):
        if isinstance(cand, dict) and isinstance(cand.get("surface"), dict) and isinstance(cand.get("probe"), dict):
            return cand
    return None


def swept_keys(df: pd.DataFrame, meta: dict) -> list[str]:
    """The varied keys, most important first.

    A key counts when it is a dotted column with more than one distinct
    value, and (when the metadata records a 'sweep' block) is named there.
    Keys that vary in lockstep with a more important one (a ``zip`` group,
    ``f2 = 15 f1``, ``k0`` beside ``stiffness_ratio``) are dropped: they add no
    axis.
    """
    block = _find_sweep_block(meta)
    named = _names_in(block) if block is not None else None
    cand = [c for c in df.columns if "." in c and df[c].nunique(dropna=True) > 1]
    if named:
        cand = [c for c in cand if c in named] or cand
    rank = {k: i for i, k in enumerate(AXIS_PRIORITY)}
    cand.sort(key=lambda c: (rank.get(c, len(rank)), c))
    keep: list[str] = []
    for c in cand:
        if not any(_lockstep(df, c, k) for k in keep):
            keep.append(c)
    return keep


def _lockstep(df: pd.DataFrame, a: str, b: str) -> bool:
    pairs = df[[a, b]].dropna().drop_duplicates()
    return pairs[a].nunique() == len(pairs) == pairs[b].nunique()


def select_sweep_figures(swept: list[str]) -> list[tuple[str, str, tuple]]:
    """Figures for a sweep, chosen from the swept keys: [(file name, builder, args)].

    Thesis figures (ch. 4) and the keys that call for them:
    cd -> errors (43-46), extracted values when cd is the only axis (43, 45),
    E_diss against cd (41, one ratio), steady-state zero depth (57);
    cd x ratio -> E_diss map coloured by tau_c error (41, 50), paddle amplitude (49);
    cd x set point -> tau_c error map with zero-depth contours (58);
    cd x f1 / cd x print step -> acceptance regime (52 / 61);
    ratio -> peak force and penetration (48), errors within the regime (47);
    set point -> peak force and penetration (56), contact times (54), errors (55);
    f1 -> contact times (51); k2 -> E_diss (30);
    any other swept key -> errors against it (no thesis figure).
    """
    s = set(swept)
    others = [k for k in swept if k != CD]
    out: list[tuple[str, str, tuple]] = []
    if CD in s:
        out.append(("fig43-46_errors_vs_cd", "errors_vs_cd", ()))
        if not others:
            out.append(("fig43-45_values_vs_cd", "values_vs_cd", ()))
        if RATIO in s:
            out.append(("fig41-50_ediss_map_cd_ratio", "ediss_map", ()))
            out.append(("fig49_paddle_amplitude_vs_cd", "observable_vs_cd", ("paddle_amplitude", "49")))
        else:
            out.append(("fig41_ediss_vs_cd", "observable_vs_cd", ("e_diss_ev", "41")))
        out.append(("fig57_ss_zero_depth_vs_cd", "observable_vs_cd", ("ss_zero_depth", "57")))
        if SETPOINT in s:
            out.append(("fig58_tau_c_error_map_cd_setpoint", "depth_error_map", ()))
        if F1 in s:
            out.append(("fig52_acceptance_vs_f1", "acceptance_vs", (F1, "52")))
        if PS in s:
            out.append(("fig61_acceptance_vs_print_step", "acceptance_vs", (PS, "61")))
    if RATIO in s:
        out.append(("fig48_force_penetration_vs_ratio", "force_penetration_vs", (RATIO, "48")))
        out.append(("fig47_errors_vs_ratio", "errors_vs", (RATIO, "47")))
    if SETPOINT in s:
        out.append(("fig56_force_penetration_vs_setpoint", "force_penetration_vs", (SETPOINT, "56")))
        out.append(("fig54_contact_times_vs_setpoint", "contact_times_vs", (SETPOINT, "54")))
        out.append(("fig55_errors_vs_setpoint", "errors_vs", (SETPOINT, "55")))
    if F1 in s:
        out.append(("fig51_contact_times_vs_f1", "contact_times_vs", (F1, "51")))
    if K2 in s:
        out.append(("fig30_ediss_vs_k2", "observable_vs", (K2, "e_diss_ev", "30")))
    for k in others:
        if k not in AXIS_PRIORITY:
            out.append((f"errors_vs_{k.replace('.', '_')}", "errors_vs", (k, None)))
    return out


@dataclass
class SweepData:
    """The rows of a sweep table the figures draw, with the error columns as magnitudes
    (tables store signed errors; the figures' error axes are logarithmic)."""

    df: pd.DataFrame  # all rows
    swept: list
    base: dict | None

    def __post_init__(self):
        errs = [c for c in self.df.columns if c.endswith("_err_pct")]
        if errs:
            self.df = self.df.assign(**{c: self.df[c].abs() for c in errs})

    @property
    def others(self) -> list:
        return [k for k in self.swept if k != CD]

    def sources(self) -> list:
        present = set(self.df["force_source"].astype(str))
        return [s for s in SOURCES if s in present]

    def rows(self, source: str) -> pd.DataFrame:
        return self.df[self.df["force_source"].astype(str) == source]

    def points(self) -> pd.DataFrame:
        """One row per point (observables do not depend on the force source)."""
        d = self.df.copy()
        d["_rank"] = d["force_source"].astype(str).map({"true": 0, "reconstructed": 1}).fillna(2)
        return d.sort_values("_rank").drop_duplicates(subset=self.swept, keep="first").drop(columns="_rank")


def sweep_figures(df: pd.DataFrame, meta: dict) -> tuple[list, list]:
    """[(name, Figure)], [notes] for a sweep table."""
    bad = sorted(set(df["force_source"].astype(str)) - set(SOURCES))
    if bad:
        raise InputError(f"force_source has {bad[0]!r}; allowed: {', '.join(SOURCES)}")
    if df.empty:
        raise InputError("the sweep table has no rows")
    swept = swept_keys(df, meta)
    if not swept:
        raise InputError("the sweep table varies no key: nothing to plot against")
    # tables comparing extraction methods (sweep key extract.method): one set of figures per method
    methods = sorted(set(df["method"].astype(str))) if "method" in df.columns else ["vetica"]
    figs, notes = [], []
    for method in methods:
        dm = df[df["method"].astype(str) == method] if len(methods) > 1 else df
        sw = SweepData(df=dm, swept=swept, base=_base_config(meta))
        for name, builder, args in select_sweep_figures(swept):
            label = name if len(methods) == 1 else f"{name}_{method}"
            try:
                fig = BUILDERS[builder](sw, *args)
            except KeyError as exc:  # e.g. no 'ok' point for one force source
                notes.append(f"{label} skipped: no usable points ({exc})")
                continue
            if fig is None:
                notes.append(f"{label} skipped: no usable points")
                continue
            if method != "vetica" and fig._suptitle is not None:  # titles name the method shown
                fig._suptitle.set_text(fig._suptitle.get_text().replace("VETICA", f"{method} extraction"))
            figs.append((label, fig))
    notes.append(f"swept keys: {', '.join(swept)}" + (f"; methods: {', '.join(methods)}" if len(methods) > 1 else ""))
    return figs, notes


# -- sweep helpers ----------------------------------------------------------


def _axis_meta(key: str):
    return AXES.get(key, (key, "", 1.0, "linear"))


def _disp(key: str, values) -> np.ndarray:
    return np.asarray(values, float) * _axis_meta(key)[2]


def _fmt_value(key: str, v: float) -> str:
    if key == RATIO:
        return _ratio_label(v)
    _name, unit, scale, _ = _axis_meta(key)
    return f"{v * scale:.3g}{' ' + unit if unit else ''}"


def _ratio_label(r: float) -> str:
    return f"{r:.3g}:1" if r >= 1 else f"1:{1 / r:.3g}"


def _set_axis(ax, key: str, which: str = "x", values=None) -> None:
    name, unit, scale, kind = _axis_meta(key)
    set_label = ax.set_xlabel if which == "x" else ax.set_ylabel
    set_scale = ax.set_xscale if which == "x" else ax.set_yscale
    set_label(_label(name, unit))
    if kind == "log":
        set_scale("log")
    elif kind == "log2":
        set_scale("log", base=2)
        if values is not None:
            ticks = np.unique(np.asarray(values, float) * scale)
            axis = ax.xaxis if which == "x" else ax.yaxis
            if len(ticks) <= 12:
                axis.set_ticks(ticks)
                axis.set_ticks([], minor=True)
                labels = [_ratio_label(v) if key == RATIO else f"{v:g}" for v in ticks]
                axis.set_ticklabels(labels)


def _group_label(keys: list, vals: tuple) -> str:
    return ", ".join(f"{SHORT.get(k, k)} {_fmt_value(k, v)}" for k, v in zip(keys, vals))


def _groups(d: pd.DataFrame, keys: list):
    """[(label, values, sub-frame)] over the distinct combinations of ``keys`` (one group if none)."""
    if not keys:
        return [("", (), d)]
    out = []
    for vals, sub in d.groupby(keys, sort=True):
        vals = vals if isinstance(vals, tuple) else (vals,)
        out.append((_group_label(keys, vals), vals, sub))
    return out


def _colors(n: int):
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    return [cmap(0.05 + 0.85 * i / max(1, n - 1)) for i in range(n)]


def _status(d: pd.DataFrame) -> np.ndarray:
    return d["status"].astype(str).to_numpy()


def _series(ax, x, y, status, color, ls, marker, filled, label, floor=None, show_missing=False) -> set:
    """Line through the usable points; not-steady points get a grey cross over the marker.

    With ``show_missing``, points that ran (not failed) but have no value
    (the extraction returned none, e.g. no measurable creep for tau_c) are
    drawn as triangles on the top edge of the axes.  Returns the set of
    special markers drawn ({'not_steady', 'no_value'}) for the legend.
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    ran = (status != "failed") & np.isfinite(x)
    ok = ran & np.isfinite(y)
    if floor is not None:
        y = np.where(ok, np.maximum(y, floor), y)
    order = np.argsort(x[ok])
    xs, ys = x[ok][order], y[ok][order]
    ax.plot(
        xs,
        ys,
        ls=ls,
        color=color,
        marker=marker,
        ms=6,
        lw=1.4,
        mfc=color if filled else "white",
        mec=color,
        label=label,
    )
    flags = set()
    ns = ok & (status == "not_steady")
    if ns.any():
        ax.plot(x[ns], y[ns], "x", color="0.35", ms=11, mew=1.6, ls="none")
        flags.add("not_steady")
    missing = ran & ~np.isfinite(y)
    if show_missing and missing.any():
        ax.plot(
            x[missing],
            np.full(missing.sum(), 0.985),
            "^",
            transform=ax.get_xaxis_transform(),
            color=color,
            mfc=color if filled else "white",
            ms=8,
            ls="none",
            clip_on=False,
        )
        flags.add("no_value")
    return flags


def _extra_handles(flags: set) -> list:
    """Legend entries for the special markers of :func:`_series`."""
    from matplotlib.lines import Line2D

    h = []
    if "not_steady" in flags:
        h.append(Line2D([], [], marker="x", color="0.35", ms=9, mew=1.6, ls="none", label="not steady (hit max_time)"))
    if "no_value" in flags:
        h.append(Line2D([], [], marker="^", color="0.35", ms=8, ls="none", label="no value extracted (top edge)"))
    return h


def _status_note(d: pd.DataFrame, swept: list, extra: str = "", regime: bool = False, marked: bool = True) -> str:
    pts = d.drop_duplicates(subset=swept + ["status"])
    n_f = int((pts["status"].astype(str) == "failed").sum())
    n_ns = int((pts["status"].astype(str) == "not_steady").sum())
    parts = []
    if n_f:
        parts.append(f"{n_f} failed point(s) excluded")
    if n_ns and marked:
        parts.append(
            f"{n_ns} not-steady point(s) marked with a grey cross"
            + (" and left out of the acceptance regime" if regime else "")
        )
    elif n_ns:
        parts.append(f"{n_ns} not-steady point(s) left out")
    if extra:
        parts.append(extra)
    return "; ".join(parts)


def _fixed_line(sw: SweepData) -> str:
    """The study's fixed parameters (the keys not swept), for the title; derived keys
    (``stiffness_ratio``, ``f2_ratio``) as the study config states them."""
    b = sw.base
    if not b:
        return ""
    s = set(sw.swept)
    pr, op, su, nu = (b.get(k, {}) or {} for k in ("probe", "operation", "surface", "numerics"))
    items = []

    def num(d, k):
        v = d.get(k)
        return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None

    f1, f2, f2r = num(pr, "f1"), num(pr, "f2"), num(pr, "f2_ratio")
    if F1 not in s and f1:
        items.append(f"$f_1$ {f1 * 1e-3:g} kHz")
    if f2r:
        items.append(f"$f_2$ = {f2r:g} $f_1$")
    elif F1 not in s and "probe.f2" not in s and f2:
        items.append(f"$f_2$ {f2 * 1e-3:g} kHz")
    for key, d, name, unit, scale in (
        ("probe.k1", pr, "$k_1$", "N/m", 1.0),
        (K2, pr, "$k_2$", "N/m", 1.0),
        (SETPOINT, op, "set point", "%", 100.0),
        ("surface.k_inf", su, r"$k_\infty$", "N/m", 1.0),
    ):
        v = num(d, key.split(".")[1])
        if key not in s and v is not None:
            items.append(f"{name} {v * scale:g} {unit}")
    k_inf, k0, ratio = num(su, "k_inf"), num(su, "k0"), num(su, "stiffness_ratio")
    if ratio is None and k0 and k_inf:
        ratio = k0 / k_inf
    if RATIO not in s and "surface.k0" not in s and ratio:
        items.append(f"$k_0:k_\\infty$ {_ratio_label(ratio)}")
    for key, d, name, unit, scale in (
        (CD, su, "$c_d$", "kg/s", 1.0),
        (PS, nu, "PS", "ns", 1e9),
        ("numerics.dt", nu, "dt", "ns", 1e9),
    ):
        v = num(d, key.split(".")[1])
        if key not in s and v is not None:
            items.append(f"{name} {v * scale:g} {unit}")
    return ("fixed: " + ", ".join(items)) if items else ""


def _title(fig: Figure, sw: SweepData, text: str) -> None:
    fixed = _fixed_line(sw)
    fig.suptitle(text + ("\n" + fixed if fixed else ""), fontsize=10.5)


@dataclass
class Regime:
    """Acceptance regime of one force source at one setting of the other keys."""

    lo: float  # lowest accepted cd [kg/s]
    hi: float  # highest accepted cd [kg/s]
    accepted: np.ndarray  # every accepted cd
    contiguous: bool  # the accepted points are one unbroken run of the cd grid


def acceptance(d: pd.DataFrame, err_col: str = "tau_c_err_pct") -> Regime | None:
    """The range of cd whose points have status ok and a ``tau_c`` error below 30 % (thesis fig. 52).

    The same definition ``vetica sweep`` prints and stores in the table's
    metadata (``sweep.acceptance_regime``): lowest to highest accepted cd,
    and whether the accepted points are one unbroken run of the cd grid
    (a not-steady, failed or inaccurate point in between breaks it).
    None when no point is accepted.
    """
    grid = np.sort(d[CD].to_numpy(float))
    ok = d[(d["status"].astype(str) == "ok") & (d[err_col].abs() < ACCEPT_PCT)]
    acc = np.sort(ok[CD].to_numpy(float))
    if not len(acc):
        return None
    i0 = int(np.searchsorted(grid, acc[0]))
    contiguous = bool(np.array_equal(grid[i0 : i0 + len(acc)], acc))
    return Regime(float(acc[0]), float(acc[-1]), acc, contiguous)


def _half_step(cd: np.ndarray) -> float:
    u = np.unique(cd)
    return float(np.sqrt(np.median(u[1:] / u[:-1]))) if len(u) > 1 else 1.5


def _shade_regime(ax, rng, cd_values, color="tab:green", label=None):
    if rng is None:
        return
    h = _half_step(np.asarray(cd_values, float))
    ax.axvspan(rng.lo / h, rng.hi * h, color=color, alpha=0.12, lw=0, label=label)


# -- sweep figures ----------------------------------------------------------


def fig_errors_vs_cd(sw: SweepData) -> Figure | None:
    """Errors of tau_c, Kg, k0, k_inf, cd against cd, log axes, acceptance regime shaded (thesis figs. 43-46).

    Error = 100 |extracted - theory| / theory (SPEC 7).  With cd the only
    axis, one panel per force source holds the five quantities (fig. 46
    layout); with more axes, one panel per quantity holds a line per
    setting of the other keys.
    """
    sources = sw.sources()
    others = sw.others
    flags = set()
    if not others:
        fig = _figure(6.2 * len(sources) + 0.6, 5.6)
        axes = np.atleast_1d(fig.subplots(1, len(sources), sharey=True))
        for ax, src in zip(axes, sources):
            d = sw.rows(src)
            rng = acceptance(d)
            _shade_regime(ax, rng, d[CD], label="acceptance regime (τc error < 30 %)")
            for q, (qlab, _, _) in QUANTITIES.items():
                col, mk = Q_STYLE[q]
                flags |= _series(
                    ax,
                    d[CD],
                    d[f"{q}_err_pct"],
                    _status(d),
                    col,
                    SOURCE_LS[src],
                    mk,
                    SOURCE_FILLED[src],
                    qlab,
                    floor=ERR_FLOOR,
                    show_missing=True,
                )
            ax.axhline(ACCEPT_PCT, color="k", ls=":", lw=1)
            ax.set_title(
                f"{SOURCE_LABEL[src]} ({'solid' if src == 'true' else 'dashed'})\n{_regime_text(rng)}", fontsize=10
            )
            _err_axes(ax)
        axes[0].set_ylabel(_label("error |extracted - theory| / theory", "%"))
        handles, _labels = axes[-1].get_legend_handles_labels()
        handles += _extra_handles(flags)
        axes[-1].legend(handles=handles, fontsize=8, loc="upper left")
    else:
        groups = _groups(sw.df, others)
        colors = _colors(len(groups))
        fig = _figure(15, 8.5)
        axes = fig.subplots(2, 3).ravel()
        for ax, (q, (qlab, _, _)) in zip(axes, QUANTITIES.items()):
            for (glab, _, g), color in zip(groups, colors):
                for src in sources:
                    d = g[g["force_source"].astype(str) == src]
                    flags |= _series(
                        ax,
                        d[CD],
                        d[f"{q}_err_pct"],
                        _status(d),
                        color,
                        SOURCE_LS[src],
                        "o",
                        SOURCE_FILLED[src],
                        None,
                        floor=ERR_FLOOR,
                        show_missing=True,
                    )
            if q == "tau_c":
                ax.axhline(ACCEPT_PCT, color="k", ls=":", lw=1.2)
                ax.text(
                    0.01, ACCEPT_PCT, " 30 % (acceptance)", transform=ax.get_yaxis_transform(), va="bottom", fontsize=8
                )
            ax.set_title(f"error of {qlab}", fontsize=10)
            ax.set_ylabel(_label("error", "%"))
            _err_axes(ax)
        _legend_panel(axes[-1], groups, colors, sources, flags)
    _note(
        fig,
        _status_note(
            sw.df,
            sw.swept,
            f"errors below {ERR_FLOOR:g} % drawn at {ERR_FLOOR:g} %; "
            "dotted line: 30 % (acceptance regime: τc error < 30 %)",
            regime=True,
        ),
    )
    how = "acceptance regime (τc error < 30 %) shaded" if not others else "dotted: the 30 % acceptance threshold on τc"
    _title(fig, sw, f"VETICA errors against the dashpot; {how} (cf. thesis figs. 43-46)")
    return fig


def _regime_text(rng: Regime | None) -> str:
    if rng is None:
        return "no acceptance regime (no ok point with τc error < 30 %)"
    broken = "" if rng.contiguous else ", not contiguous"
    return f"acceptance regime {rng.lo:.2g} to {rng.hi:.2g} kg/s ({len(rng.accepted)} points{broken})"


def _err_axes(ax) -> None:
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(_label("dashpot $c_d$", "kg/s"))
    ax.grid(alpha=0.3, which="major")
    _plain_log_labels(ax)


def _plain_log_labels(ax) -> None:
    """On a log y axis spanning less than three decades, label ticks 0.3, 1, 3, 10 instead of 3x10^-1 ...;
    below a factor 4, switch to a linear axis."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    lo, hi = ax.get_ylim() if ax.get_yscale() == "log" else (1.0, 1e9)
    if lo > 0 and hi / lo < 4:  # less than about half a decade: a linear axis reads better
        ax.set_yscale("linear")
        ax.relim()
        ax.autoscale_view()
        return
    if lo > 0 and hi / lo < 1e3:
        fmt = FuncFormatter(lambda v, _: f"{v:g}")
        subs = np.arange(1.0, 10.0) if hi / lo < 30 else (1.0, 2.0, 3.0, 5.0)
        ax.yaxis.set_major_locator(LogLocator(base=10, subs=subs))
        ax.yaxis.set_major_formatter(fmt)
        ax.yaxis.set_minor_formatter(NullFormatter())


def _outside_legend(ax, handles) -> None:
    """Legend to the right of the axes when it lists several settings (inside it would hide data)."""
    if len(handles) <= 3:
        ax.legend(handles=handles, fontsize=8, loc="best")
        return
    ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)


def _legend_panel(ax, groups, colors, sources, flags, title=None) -> None:
    """Use an empty axes as the legend: colours = settings, line styles = force source."""
    from matplotlib.lines import Line2D

    ax.axis("off")
    h = [Line2D([], [], color=c, lw=3, label=lab) for (lab, _, _), c in zip(groups, colors)]
    h += [
        Line2D(
            [],
            [],
            color="0.2",
            ls=SOURCE_LS[s],
            marker="o",
            mfc="0.2" if SOURCE_FILLED[s] else "white",
            label=SOURCE_LABEL[s],
        )
        for s in sources
    ]
    h += _extra_handles(flags)
    ax.legend(handles=h, loc="center", fontsize=9, title=title, ncol=2 if len(h) > 14 else 1)


def fig_values_vs_cd(sw: SweepData) -> Figure | None:
    """Extracted against theory for tau_c, Kg, k0, k_inf, cd over cd (thesis figs. 43 A-B, 45 A-C)."""
    fig = _figure(15, 8.5)
    axes = fig.subplots(2, 3).ravel()
    flags = set()
    t = sw.rows(sw.sources()[0])
    rng = acceptance(sw.rows("true")) if "true" in sw.sources() else None
    for ax, (q, (qlab, unit, scale)) in zip(axes, QUANTITIES.items()):
        _shade_regime(ax, rng, t[CD], label="acceptance regime (true force)")
        th = t.sort_values(CD)
        ax.plot(th[CD], th[f"{q}_theory"] * scale, color="k", lw=1.6, label="theory")
        for src, mk, col in (("true", "x", "tab:red"), ("reconstructed", "o", "tab:blue")):
            if src not in sw.sources():
                continue
            d = sw.rows(src)
            flags |= _series(
                ax,
                d[CD],
                d[q] * scale,
                _status(d),
                col,
                SOURCE_LS[src],
                mk,
                SOURCE_FILLED[src],
                "VETICA, " + SOURCE_LABEL[src],
                show_missing=True,
            )
        ax.set_xscale("log")
        vals = np.concatenate([th[f"{q}_theory"].to_numpy(float), t[q].to_numpy(float)]) * scale
        vals = vals[np.isfinite(vals) & (vals > 0)]
        if len(vals) and vals.max() / vals.min() > 30:
            ax.set_yscale("log")
        ax.set_xlabel(_label("dashpot $c_d$", "kg/s"))
        ax.set_ylabel(_label(qlab, unit))
        ax.set_title(qlab, fontsize=10)
        ax.grid(alpha=0.3)
    handles, _labels = axes[0].get_legend_handles_labels()
    handles += _extra_handles(flags)
    axes[-1].axis("off")
    axes[-1].legend(handles=handles, loc="center", fontsize=9)
    _note(fig, _status_note(sw.df, sw.swept))
    _title(fig, sw, "VETICA extracted values against theory over the dashpot (cf. thesis figs. 43 and 45)")
    return fig


def fig_observable_vs_cd(sw: SweepData, obs: str, thesis: str) -> Figure | None:
    """An observable against cd, one line per setting of the other keys (thesis figs. 41, 49, 57).

    A key that does not change the observable (the print step, when the
    sweep shares one simulation between print steps) gets no lines of its
    own: they would lie on top of each other.
    """
    pts = sw.points()
    keep = [k for k in sw.others if not _no_effect(pts, obs, k, [CD] + [o for o in sw.others if o != k])]
    dropped = [k for k in sw.others if k not in keep]
    if dropped:
        pts = pts.drop_duplicates(subset=[CD] + keep)
    groups = _groups(pts, keep)
    colors = _colors(len(groups))
    name, unit, scale = OBSERVABLES[obs]
    fig = _figure(9.5, 6)
    ax = fig.subplots()
    flags = set()
    for (glab, _, g), color in zip(groups, colors):
        flags |= _series(ax, g[CD], g[obs] * scale, _status(g), color, "-", "o", True, glab or None)
    ax.set_xscale("log")
    vals = (pts[obs] * scale).to_numpy(float)
    vals = vals[np.isfinite(vals)]
    if len(vals) and np.all(vals > 0) and vals.max() / vals.min() > 100:
        ax.set_yscale("log")
    elif len(vals) and np.any(vals < 0) and np.any(vals > 0):
        big = np.max(np.abs(vals))
        small = np.min(np.abs(vals[vals != 0]))
        if big / small > 100:  # both signs over decades (a depth above and below Z1): symmetric log
            ax.set_yscale("symlog", linthresh=max(small, 1e-3 * big))
            ax.axhline(0, color="0.5", lw=0.6)
    ax.set_xlabel(_label("dashpot $c_d$", "kg/s"))
    ylabel = {"ss_zero_depth": r"steady-state zero reference depth below $Z_1$"}.get(obs, name)
    ax.set_ylabel(_label(ylabel, unit))
    ax.grid(alpha=0.3)
    handles, _ = ax.get_legend_handles_labels()
    handles += _extra_handles(flags)
    if handles:
        _outside_legend(ax, handles)
    what = {
        "e_diss_ev": "Energy dissipated per cycle against the dashpot",
        "paddle_amplitude": "Paddle amplitude against the dashpot for each stiffness ratio",
        "ss_zero_depth": "Steady-state zero reference depth against the dashpot",
    }[obs]
    same = ", ".join(_axis_meta(k)[0] for k in dropped)
    extra = f"identical for every {same} (one line drawn)" if dropped else ""
    _note(fig, _status_note(pts, [CD] + keep, extra))
    _title(fig, sw, f"{what} (cf. thesis fig. {thesis})")
    return fig


def _no_effect(pts: pd.DataFrame, col: str, key: str, others: list) -> bool:
    """True when ``col`` is the same (to 1e-9) at every value of ``key`` for each setting of ``others``."""
    d = pts[pts["status"].astype(str) != "failed"]
    if d[key].nunique() < 2:
        return False
    spread = d.groupby(others)[col].agg(lambda v: np.nanmax(v) - np.nanmin(v) if v.notna().any() else 0.0)
    scale = np.nanmax(np.abs(d[col].to_numpy(float))) if d[col].notna().any() else 0.0
    return bool(np.all(spread.to_numpy(float) <= 1e-9 * scale))


def _edges(values: np.ndarray, log: bool) -> np.ndarray:
    v = np.log(values) if log else np.asarray(values, float)
    if len(v) == 1:
        e = np.array([v[0] - 0.5, v[0] + 0.5])
    else:
        mid = 0.5 * (v[1:] + v[:-1])
        e = np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])
    return np.exp(e) if log else e


def _grid(d: pd.DataFrame, ykey: str, col: str):
    """(cd values, y values, 2-D array [y, cd]) of ``col`` with failed points as NaN, and the not-steady mask."""
    d = d.copy()
    d.loc[d["status"].astype(str) == "failed", col] = np.nan
    piv = d.pivot_table(index=ykey, columns=CD, values=col, aggfunc="mean", dropna=False)
    ns = d.assign(_ns=(d["status"].astype(str) == "not_steady").astype(float))
    nsp = ns.pivot_table(index=ykey, columns=CD, values="_ns", aggfunc="max").reindex_like(piv).fillna(0) > 0
    return piv.columns.to_numpy(float), piv.index.to_numpy(float), piv.to_numpy(float), nsp.to_numpy()


def _heat(ax, fig, x, y, z, ykey, ns, norm, cmap, clabel):
    ax.set_facecolor("0.85")
    xe = _edges(x, True)
    ye = _edges(y * _axis_meta(ykey)[2], _axis_meta(ykey)[3] != "linear")
    m = ax.pcolormesh(xe, ye, np.ma.masked_invalid(z), norm=norm, cmap=cmap, shading="flat")
    over = norm is not None and np.nanmax(z) > norm.vmax if np.isfinite(z).any() else False
    cb = fig.colorbar(m, ax=ax, extend="max" if over else "neither")
    if isinstance(norm, LogNorm) and norm.vmax / norm.vmin < 1e3:
        from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

        cb.ax.yaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 3.0, 5.0)))
        cb.ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        cb.ax.yaxis.set_minor_formatter(NullFormatter())
    cb.set_label(clabel)
    yy, xx = np.meshgrid(y * _axis_meta(ykey)[2], x, indexing="ij")
    if ns.any():
        ax.plot(xx[ns], yy[ns], "X", color="w", mec="k", mew=0.8, ms=9, ls="none")
    ax.set_xscale("log")
    ax.set_xlabel(_label("dashpot $c_d$", "kg/s"))
    _set_axis(ax, ykey, "y", y)
    ax.set_xlim(xe[0], xe[-1])
    ax.set_ylim(ye[0], ye[-1])
    return xx, yy


def _lognorm(*arrays, cap: float | None = None):
    v = np.concatenate([np.ravel(a) for a in arrays])
    v = v[np.isfinite(v) & (v > 0)]
    if not len(v):
        return None
    hi = max(v.max(), v.min() * 10)
    if cap is not None:
        hi = max(min(hi, cap), v.min() * 10)
    return LogNorm(vmin=v.min(), vmax=hi)


def _contours(ax, xx, yy, z, fmt: str, log: bool, color="k"):
    """Labelled contour lines of ``z`` (masked where not finite); decade levels when ``log``."""
    zm = np.ma.masked_invalid(z)
    if zm.count() < 4 or z.shape[0] < 2 or z.shape[1] < 2:
        return
    if log:
        zl = np.ma.log10(np.ma.masked_less_equal(zm, 0))
        if zl.count() < 4:
            return
        lo, hi = math.floor(zl.min()), math.ceil(zl.max())
        step = max(1, (hi - lo) // 6)
        levels = np.arange(lo, hi + 1, step)
        cs = ax.contour(xx, yy, zl, levels=levels, colors=color, linewidths=0.9, negative_linestyles="solid")
        ax.clabel(cs, fontsize=7.5, fmt=lambda v: fmt % (10**v))
    else:
        cs = ax.contour(xx, yy, zm, levels=6, colors=color, linewidths=0.9, negative_linestyles="solid")
        ax.clabel(cs, fontsize=7.5, fmt=fmt)


def _accept_contour(ax, xx, yy, err):
    """The 30 % line of the tau_c error (the acceptance regime's edge), bright green."""
    zm = np.ma.masked_invalid(err)
    if zm.count() >= 4 and err.shape[0] > 1 and err.shape[1] > 1 and zm.min() < ACCEPT_PCT < zm.max():
        ax.contour(xx, yy, zm, levels=[ACCEPT_PCT], colors="lime", linewidths=2.4)


ERR_CAP = 1e3  # colour scales of tau_c error stop here (the interesting part is below 30 %)


def fig_ediss_map(sw: SweepData) -> Figure | None:
    """E_diss over cd x stiffness ratio (thesis fig. 41) and the tau_c error over the same plane with
    E_diss contours (thesis fig. 50), for each force source."""
    pts = sw.points()
    x, y, e, ns = _grid(pts, RATIO, "e_diss_ev")
    sources = sw.sources()
    fig = _figure(14, 11)
    axes = fig.subplots(2, 2).ravel()
    vpos = e[np.isfinite(e)]
    logscale = bool(len(vpos) and np.all(vpos > 0) and vpos.max() / vpos.min() > 30)
    norm = _lognorm(e) if logscale else None
    xx, yy = _heat(axes[0], fig, x, y, e, RATIO, ns, norm, "magma", _label("$E_{diss}$", "eV per cycle"))
    _contours(axes[0], xx, yy, e, "%.3g eV", logscale, color="w")
    axes[0].set_title("(a) $E_{diss}$ per cycle (cf. fig. 41); white: contours [eV]", fontsize=10, loc="left")
    # (b) the same as lines against cd, one per ratio
    ax = axes[1]
    groups = _groups(pts, [RATIO])
    flags = set()
    for (glab, _, g), color in zip(groups, _colors(len(groups))):
        flags |= _series(ax, g[CD], g["e_diss_ev"], _status(g), color, "-", "o", True, glab)
    ax.set_xscale("log")
    if logscale:
        ax.set_yscale("log")
    ax.set_xlabel(_label("dashpot $c_d$", "kg/s"))
    ax.set_ylabel(_label("$E_{diss}$", "eV per cycle"))
    ax.grid(alpha=0.3)
    h, _ = ax.get_legend_handles_labels()
    h += _extra_handles(flags)
    ax.legend(handles=h, fontsize=8)
    ax.set_title("(b) $E_{diss}$ against $c_d$, one line per stiffness ratio", fontsize=10, loc="left")
    errs = [_grid(sw.rows(src), RATIO, "tau_c_err_pct") for src in sources]
    enorm = _lognorm(*[g[2] for g in errs], cap=ERR_CAP) or LogNorm(1, 100)
    for i, (ax, src, (_, _, err, ns_s)) in enumerate(zip(axes[2:], sources, errs)):
        _heat(ax, fig, x, y, err, RATIO, ns_s, enorm, "RdYlBu_r", _label("τc error", "%"))
        _contours(ax, xx, yy, e, "%.3g eV", logscale)
        _accept_contour(ax, xx, yy, err)
        ax.set_title(
            f"({'cd'[i]}) τc error, {SOURCE_LABEL[src]} (cf. fig. 50)\n"
            "black: $E_{diss}$ contours [eV]; green: 30 % (acceptance edge)",
            fontsize=10,
            loc="left",
        )
    for ax in axes[2 + len(sources) :]:
        ax.axis("off")
    _note(
        fig,
        _status_note(
            pts,
            sw.swept,
            f"grey cells: no value (failed point, or VETICA found no τc); τc error colours stop at {ERR_CAP:g} %",
            regime=True,
        ).replace("grey cross", "cross (white X on maps)"),
    )
    _title(
        fig,
        sw,
        "Energy dissipated per cycle over dashpot × stiffness ratio, and the τc error on the same "
        "plane (cf. thesis figs. 41 and 50)",
    )
    return fig


def fig_depth_error_map(sw: SweepData) -> Figure | None:
    """tau_c error over cd x set point with contours of the steady-state zero reference depth (thesis fig. 58)."""
    pts = sw.points()
    x, y, depth, _ = _grid(pts, SETPOINT, "ss_zero_depth")
    sources = sw.sources()
    errs = [_grid(sw.rows(src), SETPOINT, "tau_c_err_pct") for src in sources]
    enorm = _lognorm(*[g[2] for g in errs], cap=ERR_CAP) or LogNorm(1, 100)
    fig = _figure(7 * len(sources), 6)
    axes = np.atleast_1d(fig.subplots(1, len(sources)))
    d_nm = depth * 1e9
    dpos = d_nm[np.isfinite(d_nm)]
    dlog = bool(len(dpos) and np.all(dpos > 0) and dpos.max() / dpos.min() > 30)
    for ax, src, (_, _, err, ns) in zip(axes, sources, errs):
        xx, yy = _heat(ax, fig, x, y, err, SETPOINT, ns, enorm, "RdYlBu_r", _label("τc error", "%"))
        _contours(ax, xx, yy, d_nm, "%.2g nm", dlog)
        _accept_contour(ax, xx, yy, err)
        ax.set_title(
            f"τc error, {SOURCE_LABEL[src]}\nblack: steady-state zero reference depth [nm]; green: 30 %",
            fontsize=9.5,
            loc="left",
        )
    _note(
        fig,
        _status_note(
            pts,
            sw.swept,
            f"grey cells: no value (failed point, or VETICA found no τc); τc error colours stop at {ERR_CAP:g} %",
            regime=True,
        ).replace("grey cross", "white X"),
    )
    _title(
        fig,
        sw,
        "τc error against dashpot and set point, with the steady-state zero reference depth (cf. thesis fig. 58)",
    )
    return fig


def fig_acceptance_vs(sw: SweepData, key: str, thesis: str) -> Figure | None:
    """Acceptance regime (cd range with tau_c error < 30 %) against ``key`` (thesis fig. 52: f1; fig. 61: PS).

    (a) tau_c error against cd, one line per setting; (b) the regime's cd
    interval per setting, for each force source.
    """
    sources = sw.sources()
    others = sw.others
    groups = _groups(sw.df, others)
    colors = _colors(len(groups))
    fig = _figure(15, 6.3)
    ax_e, ax_r = fig.subplots(1, 2, width_ratios=[1.15, 1])
    flags = set()
    for (glab, _, g), color in zip(groups, colors):
        for src in sources:
            d = g[g["force_source"].astype(str) == src]
            flags |= _series(
                ax_e,
                d[CD],
                d["tau_c_err_pct"],
                _status(d),
                color,
                SOURCE_LS[src],
                "o",
                SOURCE_FILLED[src],
                glab if src == sources[0] else None,
                floor=ERR_FLOOR,
                show_missing=True,
            )
    ax_e.axhline(ACCEPT_PCT, color="k", ls=":", lw=1.2)
    ax_e.text(0.01, ACCEPT_PCT, " 30 %", transform=ax_e.get_yaxis_transform(), va="bottom", fontsize=8)
    _err_axes(ax_e)
    ax_e.set_ylabel(_label("τc error", "%"))
    ax_e.set_title("(a) τc error (solid: true force, dashed: reconstructed)", fontsize=10, loc="left")
    h, _ = ax_e.get_legend_handles_labels()
    h += _extra_handles(flags)
    ax_e.legend(handles=h, fontsize=8, loc="best")
    # (b) interval bars
    off = {"true": -0.17, "reconstructed": 0.17} if len(sources) > 1 else {sources[0]: 0.0}
    hs = {}
    cd_all = sw.df[CD].to_numpy(float)
    h2 = _half_step(cd_all)
    for i, ((glab, _, g), color) in enumerate(zip(groups, colors)):
        for src in sources:
            rng = acceptance(g[g["force_source"].astype(str) == src])
            yv = i + off[src]
            if rng is None:
                ax_r.text(
                    np.sqrt(cd_all.min() * cd_all.max()), yv, "none", ha="center", va="center", fontsize=8, color="0.3"
                )
                continue
            lo, hi = rng.lo / h2, rng.hi * h2
            hs[src] = ax_r.barh(
                yv,
                hi - lo,
                left=lo,
                height=0.3,
                color=color if src == "true" else "white",
                alpha=1.0 if rng.contiguous else 0.45,
                edgecolor=color,
                hatch=None if src == "true" else "///",
                lw=1.5,
                label=SOURCE_LABEL[src],
            )
            ax_r.plot(rng.accepted, np.full(len(rng.accepted), yv), "|", color="k", ms=9, mew=1.5)
            span = f"{rng.lo:.2g} only" if rng.lo == rng.hi else f"{rng.lo:.2g} to {rng.hi:.2g}"
            broken = "" if rng.contiguous else " (broken)"
            ax_r.text(hi * 1.15, yv, span + broken, va="center", fontsize=7.5)
    ax_r.set_xscale("log")
    his = [
        r.hi
        for _, _, g in groups
        for r in [acceptance(g[g["force_source"].astype(str) == s]) for s in sources]
        if r is not None
    ]
    ax_r.set_xlim(cd_all.min() / h2 / 1.5, max([cd_all.max() * h2 * 1.5] + [h * h2 * 150 for h in his]))
    ax_r.set_yticks(range(len(groups)))
    ax_r.set_yticklabels([lab for lab, _, _ in groups], fontsize=8)
    ax_r.set_ylim(-0.7, len(groups) - 0.3)
    ax_r.set_xlabel(_label("dashpot $c_d$ inside the acceptance regime", "kg/s"))
    ax_r.set_title("(b) acceptance regime (τc error < 30 %): cd from ... to ... [kg/s]", fontsize=10, loc="left")
    ax_r.grid(alpha=0.3, axis="x")
    if hs:
        ax_r.legend(handles=list(hs.values()), fontsize=8, loc="lower right")
    name = _axis_meta(key)[0]
    _note(
        fig,
        _status_note(
            sw.df,
            sw.swept,
            "bars: lowest to highest accepted cd, ticks: the accepted points; pale bar: the accepted points are not "
            "one unbroken run of the grid",
            regime=True,
        ),
    )
    _title(fig, sw, f"Acceptance regime against {name} (cf. thesis fig. {thesis})")
    return fig


def _common_ok(pts: pd.DataFrame, key: str, rest: list) -> tuple[pd.DataFrame, bool]:
    """The ok points whose values of the other keys ``rest`` are ok at every value of ``key``.

    Averaging over a different set of cd values at each setting would draw the change of
    sample, not the effect of ``key``; (ok points, False) when no such common set exists.
    """
    ok = pts[pts["status"].astype(str) == "ok"]
    if not rest:
        return ok, True
    n_key = pts[key].nunique()
    counts = ok.groupby(rest)[key].nunique()
    common = counts[counts == n_key].index
    if len(common) == 0:
        return ok, False
    sel = ok.set_index(rest).index.isin(common)
    return ok[sel], True


def _mean_band(pts: pd.DataFrame, key: str, col: str, rest: list | None = None):
    """Mean, min and max of ``col`` at each value of ``key`` over the ok points of the other keys
    ``rest`` that are ok at every value of ``key`` (all ok points if there are none)."""
    ok, _ = _common_ok(pts, key, rest or [])
    g = ok.groupby(key)[col]
    return g.mean(), g.min(), g.max(), g.count()


def _twin_plot(sw: SweepData, key: str, left: str, right: str, styles, title: str) -> Figure | None:
    pts = sw.points()
    averaged = len(sw.swept) > 1
    fig = _figure(9.5, 6)
    ax_l = fig.subplots()
    ax_r = ax_l.twinx()
    lines = []
    for ax, col, (color, ls, mk) in ((ax_l, left, styles[0]), (ax_r, right, styles[1])):
        name, unit, scale = OBSERVABLES[col]
        if averaged:
            mean, lo, hi, _n = _mean_band(pts, key, col, [k for k in sw.swept if k != key])
            x = _disp(key, mean.index)
            ax.fill_between(x, lo * scale, hi * scale, color=color, alpha=0.15, lw=0)
            (ln,) = ax.plot(x, mean * scale, ls=ls, marker=mk, color=color, lw=1.6, ms=7, label=f"{name} (mean)")
        else:
            d = pts[pts["status"].astype(str) != "failed"].sort_values(key)
            (ln,) = ax.plot(_disp(key, d[key]), d[col] * scale, ls=ls, marker=mk, color=color, lw=1.6, ms=7, label=name)
            ns = (d["status"].astype(str) == "not_steady").to_numpy()
            if ns.any():
                ax.plot(_disp(key, d[key])[ns], (d[col] * scale).to_numpy()[ns], "x", color="0.35", ms=11, mew=1.6)
        lines.append(ln)
        ax.set_ylabel(_label(name, unit), color=color)
        ax.tick_params(axis="y", colors=color)
    _set_axis(ax_l, key, "x", pts[key])
    ax_l.grid(alpha=0.3)
    ax_l.legend(handles=lines, fontsize=9, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=2, frameon=False)
    extra = ""
    if averaged:
        rest = [k for k in sw.swept if k != key]
        over = ", ".join(rest)
        sub, common = _common_ok(pts, key, rest)
        n = len(sub.drop_duplicates(subset=rest))
        which = (
            f"the {n} values of {over} that are ok at every {_axis_meta(key)[0]}"
            if common
            else f"the ok points of {over}"
        )
        extra = f"lines: mean over {which}; bands: their min-max range"
    _note(fig, _status_note(pts, sw.swept, extra, marked=not averaged))
    _title(fig, sw, title)
    return fig


def fig_force_penetration_vs(sw: SweepData, key: str, thesis: str) -> Figure | None:
    """Maximum surface penetration (left, blue triangles) and peak force (right, green dashed circles)
    against the stiffness ratio (thesis fig. 48) or the set point (fig. 56)."""
    what = "stiffness ratio" if key == RATIO else _axis_meta(key)[0]
    return _twin_plot(
        sw,
        key,
        "max_penetration",
        "peak_force",
        (("tab:blue", "-", "^"), ("tab:green", "--", "o")),
        f"Maximum surface penetration and peak force against {what} (cf. thesis fig. {thesis})",
    )


def fig_contact_times_vs(sw: SweepData, key: str, thesis: str) -> Figure | None:
    """Contact (left) and non-contact (right) time per cycle against f1 (thesis fig. 51) or set point (fig. 54)."""
    what = _axis_meta(key)[0]
    return _twin_plot(
        sw,
        key,
        "contact_time",
        "noncontact_time",
        (("tab:blue", "-", "^"), ("tab:red", "--", "o")),
        f"Time per drive cycle in contact and out of contact against {what} (cf. thesis fig. {thesis})",
    )


def fig_errors_vs(sw: SweepData, key: str, thesis: str | None) -> Figure | None:
    """Errors of the five VETICA quantities against ``key`` (thesis fig. 47: ratio; fig. 55: set point).

    With cd swept too, each point is the mean error over the cd values inside
    that setting's acceptance regime (as the thesis averages), computed per
    force source; otherwise the mean over the other keys.
    """
    sources = sw.sources()
    fig = _figure(10, 6.3)
    ax = fig.subplots()
    cd_swept = CD in sw.swept
    rest = [k for k in sw.others if k != key]
    plotted = False
    for src in sources:
        d = sw.rows(src)
        rows = []
        d = d[d["status"].astype(str) == "ok"]
        for kv, g in d.groupby(key):
            sel = []
            for _, _, gg in _groups(g, rest):
                if cd_swept:
                    rng = acceptance(gg)
                    if rng is None:
                        continue
                    gg = gg[(gg[CD] >= rng.lo) & (gg[CD] <= rng.hi)]
                sel.append(gg[gg["status"].astype(str) == "ok"])
            sel = pd.concat(sel) if sel else g.iloc[:0]
            rows.append({key: kv, **{q: sel[f"{q}_err_pct"].mean() if len(sel) else np.nan for q in QUANTITIES}})
        m = pd.DataFrame(rows)
        for q, (qlab, _, _) in QUANTITIES.items():
            col, mk = Q_STYLE[q]
            y = np.maximum(m[q].to_numpy(float), ERR_FLOOR)
            if np.isfinite(y).any():
                plotted = True
            ax.plot(
                _disp(key, m[key]),
                y,
                ls=SOURCE_LS[src],
                marker=mk,
                color=col,
                ms=7,
                lw=1.4,
                mfc=col if SOURCE_FILLED[src] else "white",
                label=f"{qlab}, {'true' if src == 'true' else 'reconstructed'}",
            )
    if not plotted:
        return None
    ax.set_yscale("log")
    ax.axhline(ACCEPT_PCT, color="k", ls=":", lw=1)
    _plain_log_labels(ax)
    _set_axis(ax, key, "x", sw.df[key])
    ax.set_ylabel(_label("mean error" + (" within the acceptance regime" if cd_swept else ""), "%"))
    ax.grid(alpha=0.3)
    _outside_legend(ax, ax.get_legend_handles_labels()[0])
    name = "stiffness ratio" if key == RATIO else _axis_meta(key)[0]
    ref = f" (cf. thesis fig. {thesis})" if thesis else " (no thesis counterpart)"
    extra = (
        (
            "mean over the ok cd points inside each setting's own acceptance regime; "
            "settings without a regime are left out"
        )
        if cd_swept
        else "mean over the other swept keys"
    )
    _note(fig, _status_note(sw.df, sw.swept, extra + "; solid: true force, dashed: reconstructed", marked=False))
    _title(fig, sw, f"VETICA errors against {name}{ref}")
    return fig


def fig_observable_vs(sw: SweepData, key: str, obs: str, thesis: str) -> Figure | None:
    """An observable against a swept key, one line per setting of the rest (thesis fig. 30: E_diss vs k2)."""
    pts = sw.points()
    rest = [k for k in sw.swept if k != key]
    groups = _groups(pts, rest)
    colors = _colors(len(groups)) if rest else ["tab:purple"]
    name, unit, scale = OBSERVABLES[obs]
    fig = _figure(9, 6)
    ax = fig.subplots()
    flags = set()
    for (glab, _, g), color in zip(groups, colors):
        flags |= _series(ax, _disp(key, g[key]), g[obs] * scale, _status(g), color, "-", "o", True, glab or None)
    _set_axis(ax, key, "x", pts[key])
    ax.set_ylabel(_label(name, unit))
    ax.grid(alpha=0.3)
    h, _ = ax.get_legend_handles_labels()
    h += _extra_handles(flags)
    if h:
        _outside_legend(ax, h)
    _note(fig, _status_note(pts, sw.swept))
    _title(fig, sw, f"{name} against {_axis_meta(key)[0]} (cf. thesis fig. {thesis})")
    return fig


BUILDERS = {
    "errors_vs_cd": fig_errors_vs_cd,
    "values_vs_cd": fig_values_vs_cd,
    "observable_vs_cd": fig_observable_vs_cd,
    "ediss_map": fig_ediss_map,
    "depth_error_map": fig_depth_error_map,
    "acceptance_vs": fig_acceptance_vs,
    "force_penetration_vs": fig_force_penetration_vs,
    "contact_times_vs": fig_contact_times_vs,
    "errors_vs": fig_errors_vs,
    "observable_vs": fig_observable_vs,
}
