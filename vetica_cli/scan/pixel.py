"""Driving the tapping kernel pixel by pixel along one scan line (thesis 4.6.1).

**Coordinates.**  The kernel works relative to the local undeformed surface (gap
``d = z_tip - X``, ``X = 0`` undeformed).  With the absolute base height ``B`` the
amplitude controller holds and a pixel of true height ``h``, the pixel runs with
``Zb = B - h``; moving to a pixel of height ``h'`` keeps ``B`` and sets ``Zb = B - h'``:
the tip jumps with the sample, and the controller then reacts as a real one does to a
step.  What carries over from pixel to pixel is the cantilever and paddle state
``(zc, vc, zp, vp)``, the absolute base ``B`` and the PI controller (its last error
and its ramp).

**A massless local surface.**  Each pixel's surface is the massless SLS (or Wiechert)
of the single-point model under the tip, with no lateral extent: under a new pixel it starts
undeformed (``Xd_i = 0``), so the first tap on it gives that pixel's own ``Z1``.  This
leaves out every lateral coupling of a real sample: the deformation field around
the contact (a few contact radii, ``sqrt(R delta)`` ~ 3 nm here) that would reach a
neighbour closer than that (the thesis's contamination concern, 4.6.1), the creep
recovery of a pixel still relaxing from its neighbour's indentation, tip
convolution of topographic edges (the tip radius, 10 nm), friction and lateral
forces.  An edge artefact in these maps therefore comes only from what the probe
and the controller carry across the edge, and from a pixel time too short to reach
the pixel's steady state.

**Pixel boundaries** fall at the top of the tip's swing (the line's first pixel
starts there, every pixel lasts a whole number of drive periods): there the tip is
farthest from the sample (about ``2 A_sp`` above it), so the surface is never
swapped under a tip in contact.

**A pixel** (``scan.steady``):

* ``transient`` -- what the instrument sees in ``pixel_time``: the first-contact
  window (:func:`first_contact_window`, ``numerics.approach_cycles`` periods of
  samples that close half a window after the first repulsive sample), then periods
  under the PI controller, then the last ``numerics.record_cycles`` periods
  recorded with the base held (:func:`vetica_cli.core.engine.record_window`, as
  every record of this project).  ``pixel_time`` is rounded to whole drive periods.
  ``stop_reason`` is ``steady`` only when that window proves periodic, else
  ``pixel_time``;
* ``orbit`` -- the reference for what a finite pixel time costs: after the
  first-contact window, the pixel's periodic orbit is solved
  (:func:`vetica_cli.core.engine.solve_steady`) and recorded; when the solver fails,
  the time-stepped transient continues for up to ``numerics.max_time``
  (``stop_reason`` as :func:`vetica_cli.core.engine.run` names them).

**A line** starts with its own approach (:func:`vetica_cli.core.engine.approach`, the
warm start of :func:`vetica_cli.simulation.simulate.initial_state` on the line's
first material) and the periodic orbit on its first pixel (a real scan arrives at a
line's first pixel already tapping and tracking, after the retrace; where the orbit
solver fails, a lead-in of one pixel time), then taps its pixels in order, the first
one again from an undeformed surface.

**Topography** (measured): ``B - Zb_ref``, the absolute base height held during the
pixel's recorded periods minus ``Zb_ref``, the base height of the background's own
periodic orbit above its undeformed surface (:func:`reference_base`).  So a
background pixel at its steady state reads its true height, and any other pixel
reads its true height plus the material contrast (its different indentation and
attraction under the same amplitude set point).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..core import engine, session
from ..core import tapping as T
from ..simulation.config import Config
from ..simulation.instrument import apply_instrument
from ..simulation.observables import compute_observables
from ..simulation.simulate import Derived, Run, derive, initial_state, kernel_setup, run_info, simulate

PIXEL_TIME_STOP = "pixel_time"  # stop_reason of a transient pixel whose record is not proven periodic


def run_spec(cfg: Config, d: Derived) -> engine.RunSpec:
    """The engine's numbers for ``cfg`` (as :func:`vetica_cli.simulation.simulate.simulate` builds them)."""
    n = cfg.numerics
    zb0, zc0, vc0, ctrl, rate = initial_state(cfg, d)
    return engine.RunSpec(
        zb0=zb0, zc0=zc0, vc0=vc0, controller_on=ctrl, kp=n.kp, ki=n.ki, approach_rate=rate,
        n_ring=d.n_ring, record_cycles=n.record_cycles, steady=n.steady, max_periods=d.max_periods,
        tol=n.tol_orbit, tol_amp=n.tol_amp, orbit_max_periods=n.orbit_max_periods,
        settle_cycles=n.settle_cycles, tol_z=n.tol_z,
    )  # fmt: skip


def reference_base(cfg: Config) -> tuple[float, str]:
    """``(Zb_ref, stop_reason)``: the base height [m] above the undeformed surface at which the
    controller holds the set point on the periodic orbit of ``cfg``'s surface (the background),
    the zero of the measured topography (module docstring)."""
    run = simulate(cfg)
    return float(run.info["zb_final"]), run.stop_reason


def first_contact_window(kern: engine.Kernel, s, ctrl: engine.Controller, n_ring: int, max_periods: int):
    """Whole periods from ``s`` under the PI controller, recorded into a ring of ``n_ring``
    samples from the start until ``n_ring/2`` samples after the first repulsive sample
    (the first-contact window: its first force minimum is ``Z1``, thesis eq. 84).

    Returns ``(samples in time order, periods run, time and tip position of the first
    contact)``; without a contact within ``max_periods`` the samples hold no contact."""
    ring = engine.record_buffer(max(n_ring, 2), kern.n_rec)  # F-ordered as every buffer: no second compile
    rec = T.new_recorder(stride=kern.setup.stride, origin=session.step_index(s), ring=True, active=True)
    k = 0
    t_fc = z_fc = math.nan
    while rec[T.R_ACTIVE] and k < max_periods:
        o = kern.advance(s, zb_step=ctrl.zb_step, buf=ring, rec=rec)
        if math.isnan(t_fc) and not math.isnan(o[T.O_T_FC]):
            t_fc, z_fc = float(o[T.O_T_FC]), float(o[T.O_Z_FC])
        ctrl.update(engine.amplitude(o, kern.period_s), True)
        k += 1
    written, n = int(rec[T.R_POS]), len(ring)
    if written >= n:
        j = written % n
        ordered = np.concatenate([ring[j:], ring[:j]])
    else:
        ordered = ring[:written].copy()
    return ordered, k, t_fc, z_fc


@dataclass
class PixelRecord:
    """What one pixel recorded, and how the kernel got there."""

    approach: np.ndarray  # first-contact window samples
    window: engine.Window  # the recorded periods
    stop_reason: str
    base: float  # [m] absolute base height B held during the recorded periods
    info: dict  # engine bookkeeping (run_info's keys)
    warnings: list = field(default_factory=list)
    wall_s: float = 0.0


class LineDriver:
    """One scan line: the kernel of each material (built once), the state and the
    controller carried from pixel to pixel (module docstring).

    ``configs[m]`` is the single-point config of material ``m``; they share probe,
    operation and numerics."""

    def __init__(self, configs: list[Config]):
        self.configs = configs
        self.d = derive(configs[0])
        self.spec = run_spec(configs[0], self.d)
        self.kernels: dict[int, engine.Kernel] = {}
        self.grids: dict[int, dict] = {}  # the MDR grid of each hertz material
        self.s = None
        self.ctrl = None
        self.base = math.nan  # absolute base height B [m]

    def kernel(self, m: int) -> engine.Kernel:
        if m not in self.kernels:
            st = kernel_setup(self.configs[m], self.d)
            cfg = self.configs[m]  # the material's model supplies its kernel (hertz: the MDR elements and their grid)
            kern, grid = cfg.surface.surface_model.line_kernel(cfg, st, run_spec(cfg, self.d))
            self.kernels[m] = kern
            if grid is not None:
                self.grids[m] = grid
        return self.kernels[m]

    def _enter(self, m: int, h: float) -> engine.Kernel:
        """Put the tip over a fresh pixel of material ``m`` and height ``h``: the probe state
        and ``B`` carry over, ``Zb = B - h``, the surface is undeformed and out of contact."""
        kern = self.kernel(m)
        self.s = session.enter(self.s, kern.n_state, self.base - h)
        return kern

    def _periods(self, kern, n: int) -> None:
        for _ in range(n):
            o = kern.advance(self.s, zb_step=self.ctrl.zb_step)
            self.ctrl.update(engine.amplitude(o, kern.period_s), True)

    def start(self, m: int, h: float, lead_periods: int) -> dict:
        """The line's own approach on its first pixel (material ``m``, height ``h``), then its
        periodic orbit there (as if the retrace had brought the tip back over it; else a lead-in
        of ``lead_periods`` periods), then to the top of the swing.  Returns the bookkeeping."""
        kern = self.kernel(m)
        sp = self.spec
        self.s = engine.new_state(sp.zc0, sp.vc0, 0.0, 0.0, sp.zb0, kern.n_state)
        self.ctrl = engine.Controller(kern.setup.a_sp, sp.kp, sp.ki, kern.nt, kern.setup.dt, sp.approach_rate, True)
        ap = engine.approach(kern, self.s, self.ctrl, sp.n_ring, sp.max_periods)
        res = engine.solve_steady(kern, self.s, self.ctrl, 0.5 * sp.tol, sp.orbit_max_periods, False, True)
        if res.converged:
            self.s = res.state.copy()
            self.ctrl.e_prev, self.ctrl.zb_step = 0.0, 0.0  # on the orbit the amplitude is the set point
            lead_periods = 1  # one period for the phase of the swing
        last = ap.last
        for _ in range(lead_periods):
            last = kern.advance(self.s, zb_step=self.ctrl.zb_step)
            self.ctrl.update(engine.amplitude(last, kern.period_s), True)
        # q = A cos(w t - phi) is highest at w t = phi: start every pixel there
        phi = math.radians(engine.phase_deg(last)) % (2.0 * math.pi)
        steps = round(phi / (2.0 * math.pi) * kern.nt) % kern.nt
        if steps:
            kern.advance(self.s, n_steps=steps, zb_step=self.ctrl.zb_step)
        self.base = session.base(self.s) + h
        return {"approach_periods": ap.periods, "t_first_contact": ap.t_first_contact, "phase_steps": steps,
                "lead_in_orbit": res.converged}  # fmt: skip

    def transient(self, m: int, h: float, n_periods: int) -> PixelRecord:
        """A pixel tapped for ``n_periods`` drive periods, its last ``record_cycles`` recorded."""
        t0 = time.perf_counter()
        kern = self._enter(m, h)
        p0 = kern.periods
        rc = self.spec.record_cycles
        ring, k, t_fc, z_fc = first_contact_window(kern, self.s, self.ctrl, self.spec.n_ring, n_periods - rc)
        self._periods(kern, n_periods - rc - k)
        held = self.ctrl.zb_step
        win = engine.record_window(kern, self.s, self.spec, kern.setup.a_sp, False)
        self.ctrl.zb_step = held
        stop = "steady" if win.proven else PIXEL_TIME_STOP
        info = self._info(kern, p0, k, t_fc, z_fc, win, "transient")
        self.base = session.base(self.s) + h
        return PixelRecord(ring, win, stop, session.base(win.states[0]) + h, info, [], time.perf_counter() - t0)

    def orbit(self, m: int, h: float) -> PixelRecord:
        """A pixel at its periodic orbit (the first-contact window, then the orbit solver;
        the time-stepped transient within ``numerics.max_time`` where the solver fails)."""
        t0 = time.perf_counter()
        kern = self._enter(m, h)
        p0 = kern.periods
        sp = self.spec
        a_sp = kern.setup.a_sp
        ring, k, t_fc, z_fc = first_contact_window(kern, self.s, self.ctrl, sp.n_ring, sp.max_periods)
        res = engine.solve_steady(kern, self.s, self.ctrl, 0.5 * sp.tol, sp.orbit_max_periods, False, True)
        orbit = {key: getattr(res, key) for key in ("converged", "reason", "residual", "periods", "iterations",
                                                    "attempts", "monodromy_radius")}  # fmt: skip
        warnings, win = [], None
        if res.converged:
            s_orbit = res.state.copy()
            cand = engine.record_window(kern, s_orbit, sp, a_sp, False)
            if cand.proven and cand.outputs[T.O_NCONT] > 0:
                win, self.s, stop = cand, s_orbit, "steady"
                self.ctrl.e_prev, self.ctrl.zb_step = 0.0, 0.0  # on the orbit the amplitude is the set point
            else:
                warnings.append("the solved orbit failed the periodicity proof or lost the contact; "
                                "fell back to the time-stepped transient")  # fmt: skip
        else:
            warnings.append(f"orbit solver failed ({res.reason}); fell back to the time-stepped transient")
        if win is None:
            left = max(sp.max_periods - k - res.periods, sp.record_cycles + 1)
            win = engine.transient(kern, self.s, self.ctrl, sp, left, False)
            stop = "steady (transient fallback)" if win.proven else "max_time (orbit solver failed)"
        info = self._info(kern, p0, k, t_fc, z_fc, win, "orbit", orbit)
        base = session.base(win.states[0]) + h
        self.base = session.base(self.s) + h
        return PixelRecord(ring, win, stop, base, info, warnings, time.perf_counter() - t0)

    def _info(self, kern, p0, k, t_fc, z_fc, win, method, orbit=None) -> dict:
        o = win.outputs
        return {"t_first_contact": t_fc, "z_first_contact": z_fc, "periods_evaluated": kern.periods - p0,
                "approach_periods": k, "steady_method": method, "orbit": orbit,
                "approach_branch": {"repulsive": bool(o[T.O_FMAX] > 0.0)}}  # fmt: skip

    def to_run(self, m: int, rec: PixelRecord, cfg: Config) -> Run:
        """The pixel's records as a :class:`~vetica_cli.simulation.simulate.Run` (approach = the
        first-contact window, steady = the recorded periods), with its observables and the
        instrument model of ``cfg`` applied, ready for :mod:`vetica_cli.extraction`."""
        kern = self.kernel(m)
        rr = engine.RunResult(rec.approach, rec.window.samples, rec.stop_reason, rec.info, rec.warnings, rec.window)
        model = self.configs[m].surface.surface_model
        run = Run(approach=rec.approach, steady=rec.window.samples, info=run_info(rr, kern.setup, self.d),
                  stop_reason=rec.stop_reason, params=cfg.to_dict(), wall_s=rec.wall_s,
                  extra_columns=model.extra_columns)  # fmt: skip
        if m in self.grids:  # the kernel's grid, judged at this pixel's deepest tap (the model's)
            run.info[model.kernel_info_key] = model.pixel_kernel_info(cfg, self.grids[m], rr, kern)
        compute_observables(run, cfg, self.d)
        if rec.stop_reason == PIXEL_TIME_STOP:  # the budget of a transient pixel is its pixel time
            run.warnings = [w for w in run.warnings if not w.startswith("no proven periodic state")]
        run.warnings = rec.warnings + run.warnings
        apply_instrument(run, cfg)
        return run
