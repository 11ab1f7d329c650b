"""simulate(config) -> Run: unpack the config into SI floats and call the kernel.

Choices where the thesis is silent or unclear (see README "Modelling choices"):

* Drive: a force ``F0 cos(w1 t)`` on the cantilever mass with ``F0 = k1 A0/Q1``
  (free tip amplitude ``A0`` at resonance), equivalent to the thesis's base
  excitation for the point-mass model (SPEC 2).
* Warm start (``numerics.warm_start``, default): the cantilever starts in its
  free phase (``zc = A sin w1 t``) at the set-point amplitude with the lowest
  tip point ``approach_gap`` above the surface; the amplitude grows towards
  ``A0`` and touches the undisturbed surface within a period or two, so the
  first-approach contact (``Z1``) is recorded as in the thesis's slow approach.
  Cold start: free steady state at ``A0`` and a base descent at
  ``approach_rate`` (auto: reach the set point in ~100 periods), like thesis
  fig. 18.
* Controller: PI (velocity form) once per drive period on the running
  amplitude ``(max - min)/2`` of ``z_tip - Zb``; the correction is applied as a
  ramp over the next period so the tip never jumps.  It holds the base during
  the recorded steady window (the window is then exactly periodic, which the
  energy balance and the spectral inversion need).
* Fixed base (``operation.base_height``): no controller; warm start means the
  free steady state, cold start means from rest.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .. import __version__
from ..core import thc
from ..errors import ConfigError
from ..io import write_run
from .config import Config, load
from .instrument import apply_instrument
from .observables import compute_observables

UNITS = {
    "t": "s",
    "z_tip": "m",
    "z_cantilever": "m",
    "z_paddle": "m",
    "z_base": "m",
    "f_ts": "N",
    "x_surface": "m",
    "x_dashpot": "m",
    "segment": "approach = first-approach window (Z1); steady = recorded steady-state drive periods",
}


@dataclass
class Derived:
    """SI floats derived from a Config (thesis eqs. 13-16)."""

    omega1: float
    omega2: float
    m1: float
    m2: float
    c1: float
    c2: float
    f0: float
    a_sp: float
    period: float
    stride: int
    samples_per_period: int
    n_steady: int
    n_ring: int
    max_steps: int


def derive(cfg: Config) -> Derived:
    p, o, n = cfg.probe, cfg.operation, cfg.numerics
    w1 = 2 * math.pi * p.f1
    w2 = 2 * math.pi * p.f2
    m1 = p.k1 / w1**2
    m2 = p.k2 / w2**2
    period = 1.0 / p.f1
    stride = int(round(n.print_step / n.dt))
    spp = int(round(period / n.print_step))
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
        stride=stride,
        samples_per_period=spp,
        n_steady=int(round(n.record_cycles * period / n.print_step)),
        n_ring=max(2, int(round(n.approach_cycles * spp))),
        max_steps=int(n.max_time / n.dt),
    )


@dataclass
class Run:
    """Result of one simulation: recorded samples and their context."""

    approach: np.ndarray  # (n, 8) samples around the first contact, COLUMNS order
    steady: np.ndarray  # (n, 8) samples of the recorded steady periods
    info: dict  # kernel bookkeeping (INFO_NAMES)
    stop_reason: str  # "steady" or "max_time"
    params: dict  # resolved configuration
    observables: dict = field(default_factory=dict)
    energy: dict = field(default_factory=dict)  # per-cycle energy balance [eV]
    warnings: list = field(default_factory=list)
    wall_s: float = 0.0

    def frame(self) -> pd.DataFrame:
        """Both segments as one tidy table (columns of ``thc.COLUMNS`` + segment)."""
        parts = []
        for name, arr in (("approach", self.approach), ("steady", self.steady)):
            df = pd.DataFrame(arr, columns=list(thc.COLUMNS))
            df["segment"] = name
            parts.append(df)
        out = pd.concat(parts, ignore_index=True)
        out["segment"] = out["segment"].astype("category")
        return out

    def metadata(self) -> dict:
        return {
            "params": self.params,
            "units": UNITS,
            "version": __version__,
            "stop_reason": self.stop_reason,
            "observables": self.observables,
            "energy_ev_per_cycle": self.energy,
            "warnings": self.warnings,
            "wall_s": self.wall_s,
            "kernel": {k: (None if (isinstance(v, float) and math.isnan(v)) else v) for k, v in self.info.items()},
        }


def initial_state(cfg: Config, d: Derived) -> tuple[float, float, float, bool, float]:
    """(Zb0, zc0, vc0, controller_on, approach_rate) for the chosen start."""
    o, s, n = cfg.operation, cfg.surface, cfg.numerics
    if o.base_height is not None:
        amp = o.free_amplitude if n.warm_start else 0.0
        return o.base_height, 0.0, amp * d.omega1, False, 0.0
    if n.warm_start:
        amp = d.a_sp
        rate = n.approach_rate
    else:
        amp = o.free_amplitude
        rate = n.approach_rate or (o.free_amplitude - d.a_sp) / (100 * d.period)
    zb0 = amp + s.a0 + n.approach_gap
    return zb0, 0.0, amp * d.omega1, True, rate


def simulate(cfg: Config) -> Run:
    """Run one point to steady state and record it (SPEC sections 2-5)."""
    d = derive(cfg)
    p, s, n = cfg.probe, cfg.surface, cfg.numerics
    k_inf, k0, cd = _one_arm(cfg)
    zb0, zc0, vc0, ctrl, rate = initial_state(cfg, d)
    hr6 = s.hamaker * p.tip_radius / 6.0
    t0 = time.perf_counter()
    ring, steady, info_v, code = thc.integrate(
        d.m1, p.k1, d.c1, d.m2, p.k2, d.c2, d.omega1, d.f0,
        k_inf, k0, cd, hr6, s.a0, s.vdw_on_surface,
        d.a_sp, zb0, zc0, vc0, 0.0, 0.0, ctrl, n.kp, n.ki, rate,
        n.dt, d.stride, d.samples_per_period, d.max_steps, n.tol_amp, n.tol_z, n.settle_cycles,
        d.n_ring, d.n_steady,
    )  # fmt: skip
    wall = time.perf_counter() - t0
    info = {k: float(v) for k, v in zip(thc.INFO_NAMES, info_v)}
    written = int(info["approach_written"])
    if written >= d.n_ring:
        k = written % d.n_ring
        approach = np.concatenate([ring[k:], ring[:k]])
    else:
        approach = ring[:written]
    run = Run(
        approach=approach,
        steady=steady,
        info=info,
        stop_reason="steady" if code == thc.STOP_STEADY else "max_time",
        params=cfg.to_dict(),
        wall_s=wall,
    )
    compute_observables(run, cfg, d)  # from the noise-free signals
    apply_instrument(run, cfg)
    return run


def simulate_file(config=None, output="run.parquet", overrides: dict | None = None) -> Run:
    """``vetica simulate``: load a one-point YAML config (None = the defaults) with dotted
    ``overrides``, simulate it and write the run to ``output`` (Parquet with metadata)."""
    run = simulate(load(config, overrides))
    write_run(run, output)
    return run


def _one_arm(cfg: Config) -> tuple[float, float, float]:
    """``(k_inf, k0, cd)`` of the surface for the kernel, from its model's coefficient
    arrays (:meth:`vetica_cli.surfaces.SurfaceModel.kernel_arms`); the kernel takes one
    Maxwell arm."""
    k_inf, k, cd = cfg.surface.surface_model.kernel_arms(cfg.surface.params)
    if len(k) != 1:
        raise ConfigError(
            f"surface.model: {cfg.surface.model!r} has {len(k)} Maxwell arms; the simulation kernel takes one"
        )
    return k_inf, float(k[0]), float(cd[0])
