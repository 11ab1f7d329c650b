"""The print-step policy of every batch (sweep, scan, advise): which points share one simulation.

Points that differ only in ``extract.method`` or in the instrument keys
``numerics.position_noise``, ``force_noise``, ``noise_seed`` and
``detector_bandwidth`` share one noise-free simulation: the method only reads
the record, and the instrument model
(:func:`vetica_cli.simulation.instrument.apply_instrument`) post-processes the
recorded signals after the kernel (the amplitude controller sees the noise-free
signal), so each point's record is the shared record with its own instrument
model applied: bit-identical to a separate simulation of that point.

Points that differ in the print step are simulated separately.  Version 0.1
shared one simulation recorded at the finest print step among them (its
kernel cost seconds a point); with the periodic-orbit solver a point costs a
few tenths of a second, and a separate run records exactly what a user running
that point gets, so the subsampling rules of the recorder no longer have to be
rebuilt here.
"""

from __future__ import annotations

import copy
import json
from collections import defaultdict
from dataclasses import dataclass

from ..simulation.instrument import apply_instrument, noise_free


@dataclass
class Task:
    points: list  # of points (anything with a ``config``), which share one simulation


def group(points) -> list[Task]:
    """Group points (anything with a resolved ``config``) into jobs that share one
    simulation (they differ only in the extraction method and the instrument keys); every
    other point is a job of its own."""
    groups: dict = defaultdict(list)
    for p in points:
        groups[simulation_key(p.config)].append(p)
    return [Task(pts) for pts in groups.values()]


def simulation_key(cfg) -> str:
    """Points with equal keys need the same simulation (they differ at most in the
    extraction method and the instrument keys)."""
    return json.dumps(noise_free(cfg).to_dict(), sort_keys=True)


def point_run(shared, cfg):
    """The Run a separate simulation of ``cfg`` gives, from ``shared`` (the noise-free
    simulation of every point with the same :func:`simulation_key`): a copy with ``cfg``'s
    parameters and instrument model."""
    run = copy.deepcopy(shared)
    run.params = cfg.to_dict()
    apply_instrument(run, cfg)  # on the recorded signals, after the kernel, as simulate() does
    return run
