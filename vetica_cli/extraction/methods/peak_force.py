"""Peak force and tap duration per tap, with their spread: the worked example of a model-free
method in docs/extending.md (a method is this file and one registration line).

For each complete tap of the record (:func:`vetica_cli.signals.taps.find_taps`: contact and
separation at the force minima around a repulsive peak)::

    F_peak,i = max F_ts over tap i                                  [N]
    t_tap,i  = t(separation minimum) - t(contact minimum)           [s]

The values are the means over the taps (the base's error bars: their standard error,
t-scaled).  Truth (simulated records): the simulator's ``peak_force`` and ``contact_time``
observables.  Runs on a record of any surface model: it reads only the force.
"""

from __future__ import annotations

import time

import numpy as np

from ...surfaces import Quantity
from ..base import ModelFreeMethod, register
from ..record import Record
from ..result import ExtractionResult, Spread, estimates

QUANTITIES: dict[str, Quantity] = {
    "peak_force_tap": Quantity("N", "F_peak", r"$F_{peak}$", "nN", 1e9, True, "largest repulsive force of a tap"),
    "tap_duration": Quantity("s", "t_tap", r"$t_{tap}$", "µs", 1e6, True, "time from contact to separation of a tap"),
}


@register
class PeakForce(ModelFreeMethod):
    """Per-tap peak force and tap duration (contact to separation), means over the taps."""

    key = "peak-force"
    description = "per-tap peak force and tap duration (contact to separation), means over the taps"
    title = "peak force and tap duration"
    references = ("thesis 3.3.1 (taps located at the force minima)",)
    needs_z1 = False
    seconds_per_point = 0.05  # both forces, 10 periods at 0.125 ns (the taps only)
    fixed_quantities = QUANTITIES
    theory_sources = {"peak_force_tap": "the simulator's largest repulsive f_ts (observable 'peak_force')",
                      "tap_duration": "the simulator's contact time per cycle (observable 'contact_time')"}  # fmt: skip

    def run(self, record: Record, options: dict) -> ExtractionResult:
        from ...signals.taps import find_taps

        t0 = time.perf_counter()
        taps = find_taps(record.f)
        peaks = np.array([np.max(record.f[c : s + 1]) for c, s in zip(taps.contact, taps.separation)])
        durations = record.t[taps.separation] - record.t[taps.contact]
        per = {"peak_force_tap": peaks, "tap_duration": durations}
        values = {k: float(np.mean(v)) for k, v in per.items()}
        ko = record.observables
        truth = {"peak_force_tap": ko.get("peak_force"), "tap_duration": ko.get("contact_time")}
        units = {k: q.unit for k, q in QUANTITIES.items()}
        timing = {"reconstruction": record.reconstruction_s, "taps": time.perf_counter() - t0,
                  "total": time.perf_counter() - record.t_start}  # fmt: skip
        return ExtractionResult(method=self.key, force=record.force, taps=len(peaks), model=record.model.key,
                                estimates=estimates(values, units, truth, spreads={k: Spread.of(v) for k, v in per.items()}),
                                info=dict(record.info), warnings=list(record.meta_warnings), timing_s=timing,
                                references=self.dynamic_references(record))  # fmt: skip

    def dynamic_references(self, record: Record) -> dict:
        """The surface's storage and loss stiffness at the drive frequency (theory only)."""
        from .observables import dynamic_references

        return dynamic_references(record, record.probe.get("f1"))
