"""Planning a study: which points share one simulation (SPEC 8, thesis 4.5.4).

Simulation sharing.  Points that differ only in ``extract.method`` or in the
instrument keys ``numerics.position_noise``, ``force_noise``, ``noise_seed``
and ``detector_bandwidth`` share one noise-free simulation: the method only
reads the record, and the instrument model
(:func:`vetica_cli.simulation.instrument.apply_instrument`) post-processes the
recorded signals after the kernel (the amplitude controller sees the noise-free
signal), so each point's record is the shared record with its own instrument
model applied: bit-identical to a separate simulation of that point.  This
is always on.

Print-step sharing (thesis 4.5.4: "all simulations use the same time step and
the resolution is altered by changing the print step"): points that differ
only in ``numerics.print_step`` can share one simulation recorded at the
finest print step; each coarser point takes every k-th sample of it, which are
exactly the samples a separate run at that print step would record *if* the
trajectory did not depend on the print step.  It does, slightly: the amplitude
controller measures ``(max - min)/2`` of the print-step samples once per drive
period, so the base height and the moment steady state is declared can differ
at the picometre level.  See ``benchmarks/notes/print_step_sharing.md`` for the
measured difference; sharing is on by default and can be switched off
(``share_print_step=False``, CLI ``--no-share-print-step``).
"""

from __future__ import annotations

import copy
import json
import math
from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from ..simulation.config import from_dict
from ..simulation.instrument import apply_instrument, noise_free
from ..simulation.observables import compute_observables
from ..simulation.simulate import Run, derive
from .grid import Study


@dataclass
class Task:
    points: list  # of Point
    sim_print_step: float  # print step the task simulates at (finest of its points)


def plan(study: Study, share_print_step: bool = True) -> list[Task]:
    """Group points into jobs that share one simulation: points differing only in
    extraction method and instrument keys always, and print-step groups when
    ``share_print_step``; every other point is a job of its own."""
    groups: dict = defaultdict(list)
    order = []
    for p in study.points:
        if share_print_step:
            gk = share_group_key(p.config) or f"alone:{simulation_key(p.config)}"
        else:
            gk = f"alone:{simulation_key(p.config)}"
        if gk not in groups:
            order.append(gk)
        groups[gk].append(p)
    tasks = []
    for gk in order:
        pts = groups[gk]
        if len(pts) > 1 and fine_config([p.config for p in pts]) is not None:
            tasks.append(Task(pts, min(p.config.numerics.print_step for p in pts)))
        else:
            tasks.extend(Task([p], p.config.numerics.print_step) for p in pts)
    return tasks


def simulation_key(cfg) -> str:
    """Points with equal keys need the same simulation (they differ at most in the
    extraction method and the instrument keys)."""
    return json.dumps(noise_free(cfg).to_dict(), sort_keys=True)


def share_group_key(cfg) -> str | None:
    """Points with equal keys may share one simulation (they differ only in
    print step, extraction method and instrument keys, and their controller
    period is the same number of steps)."""
    cfg = noise_free(cfg)
    d = cfg.to_dict()
    d["numerics"].pop("print_step")
    d["numerics"].pop("approach_cycles")
    dv = derive(cfg)
    spp_steps = dv.samples_per_period * dv.stride
    # the controller period must be a whole number of print steps
    if abs(dv.samples_per_period * cfg.numerics.print_step - dv.period) > 1e-9 * dv.period:
        return None
    return json.dumps(
        {"cfg": d, "steps_per_period": spp_steps, "approach_cycles": cfg.numerics.approach_cycles}, sort_keys=True
    )


def fine_config(cfgs):
    """Config of the shared simulation, noise-free: the finest print step of the
    group, and an approach window two drive periods longer so it covers every
    coarser window; or, when every point has the same simulation
    (:func:`simulation_key`), exactly that simulation."""
    cfgs = [noise_free(c) for c in cfgs]
    if len({simulation_key(c) for c in cfgs}) == 1:
        return cfgs[0]
    finest = min(cfgs, key=lambda c: c.numerics.print_step)
    ps = [c.numerics.print_step for c in cfgs]
    for p in ps:
        k = p / finest.numerics.print_step
        if abs(k - round(k)) > 1e-9 * k:
            return None
    d = finest.to_dict()
    d["numerics"]["approach_cycles"] = min(20.0, finest.numerics.approach_cycles + 2.0)
    return from_dict(d)


def point_run(shared, scfg, cfg):
    """The Run a separate simulation of ``cfg`` would give, taken from ``shared``
    (the noise-free simulation of ``scfg``), or None if the shared record does not
    hold it: a copy when the simulations are the same, else the print-step
    subsample (:func:`subsample`); then ``cfg``'s instrument model."""
    if simulation_key(cfg) == simulation_key(scfg):
        run = copy.deepcopy(shared)
        run.params = cfg.to_dict()
    else:
        run = subsample(shared, scfg, noise_free(cfg))
        if run is None:
            return None
        run.params = cfg.to_dict()
    apply_instrument(run, cfg)  # on the recorded signals, after the kernel, as simulate() does
    return run


def subsample(fine, cfg_f, cfg_c):
    """The Run a separate simulation at cfg_c's (coarser) print step would record,
    taken from ``fine`` (recorded at cfg_f's print step), or None if the fine
    record does not hold every needed sample.

    The kernel stores a sample at every step index ``j * stride`` (``j >= 1``):
    the approach ring keeps the last ``n_ring`` samples up to the
    ``n_ring // 2``-th sample counted from the first sample at or after the
    first-contact step whose force is repulsive (or up to the start of the
    recorded window), and the steady window holds ``n_steady``
    samples after the recording-start step.  Both are rebuilt here from step
    indices.
    """
    n = cfg_c.numerics
    dt = n.dt
    dc = derive(cfg_c)
    s = dc.stride
    info = dict(fine.info)
    n_rec = round(info["t_record_start"] / dt)
    t_fc = info["t_first_contact"]
    j_rec = n_rec // s
    a_idx = np.rint(fine.approach[:, 0] / dt).astype(np.int64)
    pos = {int(v): i for i, v in enumerate(a_idx)}
    j_end = j_rec
    if t_fc is not None and not math.isnan(t_fc):
        n_fc = round(t_fc / dt)
        # first coarse sample after the first contact with a repulsive force
        rep = [int(v) // s for v, f in zip(a_idx, fine.approach[:, 5]) if v % s == 0 and v >= n_fc and f > 0.0]
        if rep:
            j_end = min(rep[0] + dc.n_ring // 2 - 1, j_rec)
        elif a_idx[-1] < n_rec - s:  # the fine window ended before any repulsive coarse sample
            return None
    j_start = max(1, j_end - dc.n_ring + 1)
    want = [j * s for j in range(j_start, j_end + 1)]
    if any(w not in pos for w in want):
        return None
    approach = fine.approach[[pos[w] for w in want]]
    s_idx = np.rint(fine.steady[:, 0] / dt).astype(np.int64)
    keep = ((s_idx - n_rec) % s) == 0
    steady = fine.steady[keep]
    if len(steady) != dc.n_steady:
        return None
    info["approach_written"] = float(j_end)
    run = Run(
        approach=approach,
        steady=steady,
        info=info,
        stop_reason=fine.stop_reason,
        params=cfg_c.to_dict(),
        wall_s=fine.wall_s,
    )
    compute_observables(run, cfg_c, dc)
    return run
