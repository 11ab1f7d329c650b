"""The cost of a study before it runs: points, simulations and a rough bound on the
time, computed from the grid's factors without resolving every point, so that
``--dry-run`` and the size guard answer at once for a grid of a million points."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from pathlib import Path

from ..checks import number
from ..extraction import METHODS, get
from ..extraction.base import record_cost_scale
from ..simulation.config import Numerics, Probe
from ..simulation.cost import kernel_seconds, kernel_seconds_of  # noqa: F401  (re-exported)
from ..simulation.instrument import INSTRUMENT_KEYS
from ..batch.parts import parts_dir
from ..rows.extract import EXTRACT_KEYS, point_sources
from ..rows.plan import group
from .grid import Grid
from ..batch.progress import duration  # noqa: F401  (re-exported: the sweep's and scan's estimates)

# keys the kernel-time estimate reads (section.name -> default), and keys that never need a
# simulation of their own (points differing only in them share one: rows.plan)
COST_KEYS = {
    "probe.f1": Probe.f1,
    "numerics.dt": Numerics.dt,
    "numerics.print_step": Numerics.print_step,
    "numerics.record_cycles": Numerics.record_cycles,
    "numerics.integrator": Numerics.integrator,
    "numerics.steady": Numerics.steady,
    "numerics.max_time": Numerics.max_time,
}
SHARING_KEYS = (*EXTRACT_KEYS, *(f"numerics.{k}" for k in INSTRUMENT_KEYS))
EXACT_COMBOS = 20000  # cost combinations summed one by one; above, a regular sample of them is scaled


RECORD_KEYS = ("numerics.record_cycles", "numerics.print_step")  # an extraction's cost scales with its record's samples


@dataclass(frozen=True)
class Cost:
    """What a study will cost: points, simulations, core-seconds of kernel and extraction."""

    points: int
    simulations: int
    kernel_s: float
    extract_s: float

    @property
    def core_s(self) -> float:
        return self.kernel_s + self.extract_s

    def wall_s(self, jobs: int) -> float:
        return self.core_s / max(1, jobs)


def _base_value(g: Grid, key: str, default):
    sec, name = key.split(".")
    if key in EXTRACT_KEYS:
        return g.extract.get(name, default)
    body = g.base_clean.get(sec)
    return body.get(name, default) if isinstance(body, dict) else default


def _sum_over(factors: list[list[dict]], fn) -> float:
    """Sum of ``fn(merged assignment)`` over the cartesian product of ``factors``; a regular
    sample scaled to the full count when the product exceeds :data:`EXACT_COMBOS`."""
    if not factors:
        return fn({})
    total = math.prod(len(f) for f in factors)
    if total <= EXACT_COMBOS:
        combos = itertools.product(*factors)
        scale = 1.0
    else:  # every k-th combination (k coprime with nothing in particular: a spread sample)
        k = total // EXACT_COMBOS + 1
        combos = (_nth(factors, i) for i in range(0, total, k))
        scale = total / len(range(0, total, k))
    acc = 0.0
    for combo in combos:
        merged: dict = {}
        for part in combo:
            merged.update(part)
        acc += fn(merged)
    return acc * scale


def _nth(factors, i: int) -> tuple:
    out = []
    for f in reversed(factors):
        i, j = divmod(i, len(f))
        out.append(f[j])
    return tuple(reversed(out))


def grid_cost(g: Grid) -> Cost:
    """Points, simulations and the estimated core-seconds of grid ``g`` (:func:`kernel_seconds_of`
    per simulation, each method's ``seconds_per_point`` per point), from its factors alone."""
    # per factor: the distinct simulations it makes (its assignments without the sharing keys)
    sim_factors = []
    for f in g.factors:
        keys = sorted({k for a in f[:1] for k in a if k not in SHARING_KEYS})  # a factor's keys are its first's
        if keys and len(keys) == len(f[0]):  # no sharing key: every assignment is its own simulation, unless repeated
            sim_factors.append(f)
            continue
        distinct = {}
        for a in f:
            try:  # hashable values (numbers, names): a tuple is the cheap key of a million assignments
                ident = tuple(a.get(k) for k in keys)
                hash(ident)
            except TypeError:  # e.g. a list of arms
                ident = repr([a.get(k) for k in keys])
            distinct.setdefault(ident, a)
        sim_factors.append([{k: v for k, v in a.items() if k not in SHARING_KEYS} for a in distinct.values()])
    simulations = math.prod(len(f) for f in sim_factors)
    base_cost = {k: _base_value(g, k, d) for k, d in COST_KEYS.items()}

    def kernel(assign: dict) -> float:
        v = {**base_cost, **{k: x for k, x in assign.items() if k in COST_KEYS}}
        try:
            return kernel_seconds_of(*(number(v[k]) if k not in ("numerics.integrator", "numerics.steady") else v[k]
                                       for k in COST_KEYS))  # fmt: skip
        except (TypeError, ValueError, ZeroDivisionError, OverflowError):
            return 0.0  # an invalid value: the point checks report it

    costly = [any(k in COST_KEYS for a in f for k in a) for f in sim_factors]
    others = math.prod(len(f) for f, c in zip(sim_factors, costly) if not c)
    kernel_s = others * _sum_over([f for f, c in zip(sim_factors, costly) if c], kernel)

    base_ext = {k: _base_value(g, k, d) for k, (_, d) in EXTRACT_KEYS.items()}
    base_ext.update({k: base_cost[k] for k in RECORD_KEYS})

    def extract(assign: dict) -> float:
        v = {**base_ext, **{k: x for k, x in assign.items() if k in EXTRACT_KEYS or k in RECORD_KEYS}}
        try:
            scale = record_cost_scale(number(v["numerics.record_cycles"]), number(v["numerics.print_step"]))
        except (TypeError, ValueError, ZeroDivisionError, OverflowError):
            return 0.0  # an invalid value: the point checks report it
        return get(v["extract.method"]).seconds_per_point * len(point_sources(v["extract.force"])) / 2 * scale

    ext_factors = []
    for f in g.factors:  # a factor's keys are its first assignment's; most factors hold no extraction key
        keys = [k for k in f[0] if k in EXTRACT_KEYS or k in RECORD_KEYS]
        ext_factors.append([{k: a[k] for k in keys} for a in f] if keys else [{}] * len(f))
    used = [any(f) for f in ext_factors]
    rest = math.prod(len(f) for f, u in zip(ext_factors, used) if not u)
    extract_s = rest * _sum_over([f for f, u in zip(ext_factors, used) if u], extract)
    if g.replicas > 1:  # each point recorded replicas + 1 times (the noise-free reference), each record extracted
        extract_s *= g.replicas + 1
        kernel_s += g.n_points * (g.replicas + 1) * thermal_seconds(g)
    return Cost(points=g.n_points, simulations=simulations, kernel_s=kernel_s, extract_s=extract_s)


THERMAL_STEP_S = 7e-8  # [s] one fine step of the thermal recording kernel (scripts/trust.py records: 0.6 s a 10-period replica)


def thermal_seconds(g: Grid) -> float:
    """Core-seconds of one thermal recording of the base point (its recorded periods and the two
    settling ones at the fine step), 0 for a point without temperature."""
    from ..simulation.config import INSTRUMENTS

    names = {_base_value(g, "numerics.instrument", "thesis")}
    names |= {a["numerics.instrument"] for f in g.factors for a in f if "numerics.instrument" in a}  # swept presets
    preset = max((INSTRUMENTS.get(n, {}) for n in names), key=lambda p: p.get("temperature", 0.0))
    try:
        t = float(number(_base_value(g, "numerics.temperature", preset.get("temperature", 0.0))))
        if not t:
            return 0.0
        f1 = float(number(_base_value(g, "probe.f1", 50e3)))
        dt = float(number(_base_value(g, "numerics.dt", 0.025e-9)))
        cycles = float(number(_base_value(g, "numerics.record_cycles", 10)))
    except (TypeError, ValueError):
        return 0.0
    return (cycles + 2.0) / f1 / dt * THERMAL_STEP_S


def study_core_seconds(study) -> float:
    """Estimated core-seconds of a resolved study (kernel per simulation, extraction per point)."""
    total = 0.0
    for task in group(study.points):
        total += kernel_seconds(task.points[0].config)
        for p in task.points:
            n = p.config.numerics
            reps = p.replicas + 1 if p.replicas > 1 else 1  # the replicas and their noise-free reference
            total += (get(p.method).seconds_per_point * len(point_sources(p.force)) / 2
                      * record_cost_scale(n.record_cycles, n.print_step)) * reps  # fmt: skip
    return total


def wall_estimate(core_s: float, jobs: int) -> float:
    """Wall seconds of ``core_s`` core-seconds on ``jobs`` workers (the bar's first estimate)."""
    return core_s / max(1, jobs)


def dry_run_text(g: Grid, output: Path, jobs: int, checked: int | None = None) -> str:
    """Points, simulations, a cost estimate (:func:`grid_cost`) and the first points."""
    c = grid_cost(g)
    per_method = ", ".join(f"{m.seconds_per_point:g} s a {k} point" for k, m in METHODS.items())
    lines = [
        f"study {g.name}: {c.points} points over {', '.join(g.keys)}; {c.simulations} simulations",
        (
            f"cost ~{c.core_s:.0f} core-s = {duration(c.wall_s(jobs))} wall on {jobs} workers: "
            f"kernel ~{c.kernel_s:.0f} core-s, extraction ~{c.extract_s:.0f} core-s ({per_method})"
        ),
        f"output: {output} (parts in {parts_dir(output)}/)",
    ]
    for i in range(min(5, c.points)):
        lines.append(f"  point {i}: {g.point(i).label()}")
    if c.points > 5:
        lines.append(f"  ... {c.points - 5} more")
    values = sum(len(f) for f in g.factors)
    which = "every swept value" if checked is None or checked >= values else f"{checked} of the {values} swept values"
    lines.append(f"checked: {which} against the base config; every point is checked when the sweep starts")
    return "\n".join(lines)
