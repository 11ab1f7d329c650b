"""simulate(config) -> Run: unpack the config into SI numbers and drive the kernel.

Choices where the thesis is silent or unclear (see README "Modelling choices"):

* Drive: a force ``F0 cos(w1 t)`` on the cantilever mass with ``F0 = k1 A0/Q1``
  (free tip amplitude ``A0`` at resonance), equivalent to the thesis's base
  excitation for the point-mass model.
* Time grid: one drive period is a whole number of integration steps, so
  ``numerics.dt`` is adjusted by less than half a step per period (relative
  change below 1e-6 for every study setting; none for the study frequencies,
  whose periods are whole multiples of 0.025 ns); the print step is a whole
  number of those steps.  The metadata records both as used.
* Amplitude: the first harmonic of ``z_tip - Zb`` over a drive period (what
  an instrument's lock-in amplifier measures).  Version 0.1 used the peak-to-
  peak half ``(max - min)/2``, which the paddle's ringing at 15 f1 makes a
  non-smooth function of the state (the global maximum jumps between ringing
  peaks); the measured difference is in README "Modelling choices".
* Warm start (``numerics.warm_start``, default): the cantilever starts at the
  set-point amplitude with the phase lag the drive sustains there,
  ``asin(A_sp/A0)`` (the repulsive orbit's phase when the sample dissipates
  little), its lowest point ``approach_gap`` above the surface, and the base
  descends by that gap over one period until the first contact (the
  ``Z1`` window).  The first taps are then gentle, as in the thesis's slow
  approach, and the state is already near the periodic one.  Cold start:
  free steady state at ``A0`` and a base descent at ``approach_rate`` (auto:
  reach the set point in ~100 periods), like thesis fig. 18.
* Controller: PI (velocity form) once per drive period on the amplitude; the
  correction is a ramp over the next period; the base is held during the
  recorded window.
* Steady state (``numerics.steady``): ``orbit`` (default) solves the periodic
  orbit of the controlled system; ``transient`` time-steps it as an instrument
  would, for at most ``numerics.max_time``.  Either way "steady" is claimed
  only when the recorded window proves periodic (:mod:`vetica_cli.core.engine`).
* Integrator (``numerics.integrator``): ``hybrid`` (default) or ``verlet`` (all
  fine steps), :mod:`vetica_cli.core.tapping`.
* Fixed base (``operation.base_height``): no controller; warm start means the
  free steady state, cold start means from rest.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .. import __version__
from ..core import engine, session, tapping
from ..io import segments_table
from .config import Config, load
from .instrument import apply_instrument
from .observables import compute_observables
from .thermal import add_thermal, add_thermal_batch

if TYPE_CHECKING:
    import pandas as pd

SEGMENTS = ("approach", "steady")


EXTRA_UNITS = {"contact_radius": "m"}  # recorded columns some surface models add after the dashpots (hertz)


def columns(n_arms: int, extra: tuple = ()) -> list[str]:
    """Recorded columns: the SLS's ``x_dashpot``, or ``x_dashpot_1..N`` for several arms,
    then the model's ``extra`` columns (hertz: ``contact_radius``)."""
    base = list(tapping.COLUMNS[:-1])
    return base + (["x_dashpot"] if n_arms == 1 else [f"x_dashpot_{i + 1}" for i in range(n_arms)]) + list(extra)


def units(n_arms: int, extra: tuple = ()) -> dict:
    u = {"t": "s", "z_tip": "m", "z_cantilever": "m", "z_paddle": "m", "z_base": "m", "f_ts": "N", "x_surface": "m"}
    u.update({c: "m" for c in columns(n_arms)[7:]})
    u.update({c: EXTRA_UNITS[c] for c in extra})
    u["segment"] = ""  # a label, no unit (what it means: SEGMENT_MEANING, metadata 'descriptions')
    return u


SEGMENT_MEANING = "approach = first-approach window (Z1); steady = recorded steady-state drive periods"


@dataclass
class Derived:
    """SI numbers derived from a Config (thesis eqs. 13-16)."""

    omega1: float
    omega2: float
    m1: float
    m2: float
    c1: float
    c2: float
    f0: float
    a_sp: float
    period: float
    dt: float  # integration step used: period / steps_per_period [s]
    steps_per_period: int
    stride: int  # integration steps per print step
    print_step: float  # print step used [s]
    n_steady: int  # samples of the recorded window
    n_ring: int  # samples of the first-approach window
    max_periods: int  # numerics.max_time in drive periods


def derive(cfg: Config) -> Derived:
    p, o, n = cfg.probe, cfg.operation, cfg.numerics
    w1 = 2 * math.pi * p.f1
    w2 = 2 * math.pi * p.f2
    m1 = p.k1 / w1**2
    m2 = p.k2 / w2**2
    period = 1.0 / p.f1
    nt = int(round(period / n.dt))
    dt = period / nt
    stride = int(round(n.print_step / n.dt))
    return Derived(
        omega1=w1,
        omega2=w2,
        m1=m1,
        m2=m2,
        c1=m1 * w1 / p.q1,
        c2=m2 * w2 / p.q2,
        f0=p.k1 * o.free_amplitude / p.q1,
        a_sp=o.setpoint * o.free_amplitude,
        period=period,
        dt=dt,
        steps_per_period=nt,
        stride=stride,
        print_step=stride * dt,
        n_steady=int(round(n.record_cycles * nt / stride)),
        n_ring=max(2, int(round(n.approach_cycles * nt / stride))),
        max_periods=max(1, int(n.max_time / period)),
    )


def kernel_setup(cfg: Config, d: Derived) -> engine.KernelSetup:
    """The kernel's inputs; the surface as coefficient arrays from its model
    (:meth:`vetica_cli.surfaces.SurfaceModel.kernel_arms`)."""
    p, s, n = cfg.probe, cfg.surface, cfg.numerics
    k_inf, k, cd = s.surface_model.kernel_arms(s.params)
    return engine.KernelSetup(
        m1=d.m1, k1=p.k1, c1=d.c1, m2=d.m2, k2=p.k2, c2=d.c2, omega=d.omega1, f0=d.f0,
        k_inf=float(k_inf), k=np.asarray(k, float), cd=np.asarray(cd, float),
        hr6=s.hamaker * p.tip_radius / 6.0, a0=s.a0, vdw_on_surface=s.vdw_on_surface,
        a_sp=d.a_sp, dt=d.dt, steps_per_period=d.steps_per_period, stride=d.stride,
        hybrid=n.integrator == "hybrid", d_switch=n.switch_gap,
    )  # fmt: skip


def initial_state(cfg: Config, d: Derived) -> tuple[float, float, float, bool, float]:
    """``(Zb0, zc0, vc0, controller_on, approach_rate)`` for the chosen start (module docstring).

    The cantilever starts as ``zc = A cos(w1 t - phi)`` at ``t = 0``."""
    o, s, n = cfg.operation, cfg.surface, cfg.numerics
    if o.base_height is not None:
        amp = o.free_amplitude if n.warm_start else 0.0
        return o.base_height, 0.0, amp * d.omega1, False, 0.0
    if n.warm_start:
        amp = d.a_sp
        phi = math.asin(min(d.a_sp / o.free_amplitude, 1.0))
        rate = n.approach_rate or n.approach_gap / d.period
    else:
        amp = o.free_amplitude
        phi = 0.5 * math.pi
        rate = n.approach_rate or (o.free_amplitude - d.a_sp) / (100 * d.period)
    zb0 = amp + s.a0 + n.approach_gap
    return zb0, amp * math.cos(phi), amp * d.omega1 * math.sin(phi), True, rate


@dataclass
class Run:
    """Result of one simulation: recorded samples and their context."""

    approach: np.ndarray  # samples around the first contact (columns())
    steady: np.ndarray  # samples of the recorded steady periods
    info: dict  # kernel bookkeeping
    stop_reason: str  # steady | steady (transient fallback) | max_time | max_time (orbit solver failed)
    params: dict  # resolved configuration
    observables: dict = field(default_factory=dict)
    energy: dict = field(default_factory=dict)  # per-cycle energy balance [eV]
    warnings: list = field(default_factory=list)
    wall_s: float = 0.0
    timing_s: dict = field(default_factory=dict)  # kernel wall time: approach, steady, record, total [s]
    extra_columns: tuple = ()  # recorded columns after the dashpots (hertz: contact_radius)

    @property
    def n_arms(self) -> int:
        return self.steady.shape[1] - 7 - len(self.extra_columns)

    @property
    def steady_ok(self) -> bool:
        """The recorded window is proven periodic (``stop_reason`` starts with ``steady``)."""
        return self.stop_reason.startswith("steady")

    def frame(self) -> "pd.DataFrame":
        """Both segments as one tidy table (:func:`columns` + a categorical ``segment``)."""
        import pandas as pd

        parts = (self.approach, self.steady)
        data = {name: np.concatenate([p[:, j] for p in parts]) for j, name in enumerate(columns(self.n_arms, self.extra_columns))}
        codes = np.repeat(np.arange(len(parts), dtype=np.int8), [len(p) for p in parts])
        data["segment"] = pd.Categorical.from_codes(codes, categories=list(SEGMENTS))
        return pd.DataFrame(data, copy=False)

    def arrow(self):
        """Both segments as one Arrow table (the columns of :meth:`frame`), one chunk per
        segment; the recorded columns are contiguous, so no sample is copied."""
        return segments_table(columns(self.n_arms, self.extra_columns), [self.approach, self.steady], list(SEGMENTS))

    def metadata(self) -> dict:
        return {
            "params": self.params,
            "units": units(self.n_arms, self.extra_columns),  # each a unit a unit library parses ('' for none)
            "descriptions": {"segment": SEGMENT_MEANING},
            "version": __version__,
            "stop_reason": self.stop_reason,
            "observables": self.observables,
            "energy_ev_per_cycle": self.energy,
            "warnings": self.warnings,
            "wall_s": self.wall_s,
            "timing_s": self.timing_s,
            "kernel": _plain(self.info),
        }


def _plain(v):
    """JSON-ready copy: nan -> None, numpy scalars -> floats."""
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, float, np.integer, np.floating)):
        v = float(v) if not isinstance(v, (int, np.integer)) else int(v)
        return None if isinstance(v, float) and not math.isfinite(v) else v
    return v


def _mech_energy(st: engine.KernelSetup, s) -> float:
    """Kinetic + elastic energy of both probe oscillators [J]."""
    return session.probe_energy(s, st.m1, st.k1, st.m2, st.k2)


def run_info(rr: engine.RunResult, st: engine.KernelSetup, d: Derived) -> dict:
    """The kernel bookkeeping of a run, by name (metadata 'kernel')."""
    T = tapping
    w = rr.window
    o = w.outputs
    n = len(st.k)
    return {
        "dt_used": d.dt,
        "print_step_used": d.print_step,
        "steps_per_period": d.steps_per_period,
        "t_first_contact": rr.info["t_first_contact"],
        "z_first_contact": rr.info["z_first_contact"],
        "t_record_start": session.step_index(w.states[0]) * d.dt,
        "t_end": session.step_index(w.states[-1]) * d.dt,
        "periods_evaluated": rr.info["periods_evaluated"],
        "approach_periods": rr.info["approach_periods"],
        "w_drive": o[T.O_WDRIVE],
        "d_cantilever": o[T.O_D1],
        "d_paddle": o[T.O_D2],
        "w_ts": o[T.O_WTS],
        "d_dashpot": o[T.O_DDASH],
        "d_dashpot_arms": [float(v) for v in o[T.NO_BASE + n : T.NO_BASE + 2 * n]],
        "e_mech_start": _mech_energy(st, w.states[0]),
        "e_mech_end": _mech_energy(st, w.states[-1]),
        "contact_steps": o[T.O_CSTEPS],
        "n_contacts": o[T.O_NCONT],
        "n_separations": o[T.O_NSEP],
        "max_contacts_per_period": o[T.O_MAXCPP],
        "z_contact_last": o[T.O_ZCONT_LAST],
        "z_separation_last": o[T.O_ZSEP_LAST],
        "t_contact_last": o[T.O_TCONT_LAST],
        "t_separation_last": o[T.O_TSEP_LAST],
        "zb_final": session.base(w.states[-1]),
        # first harmonic of z_tip - Zb over the recorded window (the kernel's projection:
        # exact on far steps, trapezoidal on fine steps)
        "amplitude_h1": engine.amplitude(o, (len(w.states) - 1) * d.period),
        "phase_h1_deg": engine.phase_deg(o),
        "fine_steps": o[T.O_FINE],
        "far_steps": o[T.O_FAR],
        "steady": {
            "method": rr.info["steady_method"],
            "orbit": rr.info.get("orbit"),
            "proof": w.proof,
            "approach_branch": rr.info["approach_branch"],
            "orbit_branch": rr.info.get("orbit_branch"),
        },
    }


def simulate(cfg: Config) -> Run:
    """Run one point to its steady state and record it (approach, steady state, recorded window)."""
    run, kern, s0, d = noise_free_point(cfg)
    if kern is not None:
        add_thermal(run, kern, s0, cfg, d)  # noisy recorded periods from the noise-free orbit
    apply_instrument(run, cfg)
    return run


def replicas(cfg: Config, seeds) -> list[Run]:
    """Runs of ``cfg`` at each ``numerics.noise_seed`` in ``seeds``: the noise-free orbit is
    found once and only the noise (thermal recording, detector) is redone per seed, each
    run the one :func:`simulate` gives at that seed.  For studies of the noise (coverage of
    the standard errors)."""
    import dataclasses

    run, kern, s0, d = noise_free_point(cfg)
    configs = [dataclasses.replace(cfg, numerics=dataclasses.replace(cfg.numerics, noise_seed=int(seed)))
               for seed in seeds]  # fmt: skip
    return _noisy_runs(run, kern, s0, d, configs)


THERMAL_BATCH = 4  # replicas whose thermal recordings advance together (scripts/thermal_batch_timing.py)


def _noisy_runs(run, kern, s0, d, configs) -> list[Run]:
    """Copies of the noise-free ``run`` with each configuration's noise (thermal recording, then the
    detector's), the thermal recordings :data:`THERMAL_BATCH` at a time; each run the one
    :func:`simulate` gives at its configuration (bit for bit)."""
    import copy

    out = []
    for i in range(0, len(configs), THERMAL_BATCH):
        group = configs[i : i + THERMAL_BATCH]
        runs = []
        for c in group:
            r = copy.copy(run)
            hot = kern is not None and bool(c.numerics.temperature)  # its steady record is replaced: no copy
            steady = run.steady if hot else run.steady.copy()
            r.approach, r.steady, r.info, r.params = run.approach.copy(), steady, dict(run.info), c.to_dict()
            runs.append(r)
        if kern is not None:
            add_thermal_batch(runs, kern, s0, group, d)
        for r, c in zip(runs, group):
            apply_instrument(r, c)
        out += runs
    return out


REFERENCE_TEMPERATURE = 1e-9  # [K] the noise-free reference of a thermal record: its recording path, no noise to speak of


def replica_seeds(noise_seed: int, n: int) -> list[int]:
    """``n`` noise seeds of the replicas of a point whose own seed is ``noise_seed``: independent
    streams (``SeedSequence([noise_seed, i])``), reproducible, none equal to the point's."""
    from ..checks import MAX_SEED

    return [int(np.random.SeedSequence([int(noise_seed), i]).generate_state(1)[0]) % MAX_SEED for i in range(1, n + 1)]


def replica_set(cfg: Config, n: int) -> tuple[Run, list[Run]]:
    """``(reference, replicas)``: ``n`` noisy recordings of ``cfg`` (:func:`replica_seeds`), and the
    noise-free record made by the same recording path -- the thermal kernel at
    :data:`REFERENCE_TEMPERATURE` when the point is at a temperature (its plain Verlet probe
    differs from the fine kernel's exact probe map: 5e-6 of the peak force on a 5:1 surface at
    0.05 ns), without the detector's noise and
    quantisation -- all from one solution of the noise-free orbit."""
    import dataclasses

    run, kern, s0, d = noise_free_point(cfg)
    quiet = dataclasses.replace(cfg.numerics, position_noise=0.0, force_noise=0.0, adc_resolution=0.0,
                                detector_noise_density=0.0,
                                temperature=REFERENCE_TEMPERATURE if cfg.numerics.temperature else 0.0)  # fmt: skip
    configs = [dataclasses.replace(cfg, numerics=quiet)]
    configs += [dataclasses.replace(cfg, numerics=dataclasses.replace(cfg.numerics, noise_seed=seed))
                for seed in replica_seeds(cfg.numerics.noise_seed, n)]  # fmt: skip
    out = _noisy_runs(run, kern, s0, d, configs)
    return out[0], out[1:]


def noise_free_point(cfg: Config):
    """The point's noise-free run (orbit, records, observables) and what the thermal
    recording starts from: ``(run, kernel or None, state at the window start, derived)``."""
    d = derive(cfg)
    st = kernel_setup(cfg, d)
    n = cfg.numerics
    zb0, zc0, vc0, ctrl, rate = initial_state(cfg, d)
    spec = engine.RunSpec(
        zb0=zb0, zc0=zc0, vc0=vc0, controller_on=ctrl, kp=n.kp, ki=n.ki, approach_rate=rate,
        n_ring=d.n_ring, record_cycles=n.record_cycles, steady=n.steady, max_periods=d.max_periods,
        tol=n.tol_orbit, tol_amp=n.tol_amp, orbit_max_periods=n.orbit_max_periods,
        settle_cycles=n.settle_cycles, tol_z=n.tol_z,
    )  # fmt: skip
    t0 = time.perf_counter()
    model = cfg.surface.surface_model
    rr, kernel_info, kern = model.run_kernel(cfg, st, spec)  # the model's own kernel (surfaces: run_kernel)
    wall = time.perf_counter() - t0
    run = Run(
        approach=rr.approach,
        steady=rr.steady,
        info=run_info(rr, st, d),
        stop_reason=rr.stop_reason,
        params=cfg.to_dict(),
        wall_s=wall,
        timing_s=rr.info["timing_s"],
        extra_columns=model.extra_columns,
    )
    if kernel_info is not None:
        run.info[model.kernel_info_key] = kernel_info
    compute_observables(run, cfg, d)  # from the noise-free signals
    run.warnings = rr.warnings + run.warnings
    return run, kern, (rr.window.states[0] if kern is not None else None), d
