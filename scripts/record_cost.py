"""What a worked-example point costs in the simulator's kernel, and what recording a sample costs
against the cost of writing it to memory.  CPU time (``time.process_time``), medians of
``--repeat`` runs after a warm-up (numba's cache loaded, kernels compiled), one core.

* point: ``simulate()``'s kernel stages on the defaults (the worked example) -- the approach
  (with its recorded first-contact window), the steady-state solve, the 10 recorded periods
  -- and the point to its proven periodic state (approach + solve);
* per recorded sample: one drive period from the solved orbit recorded at the print step as the
  recorded window records it (energy integrals on) divided by its samples, beside the same
  recording without the energy integrals, the same period unrecorded (the free ladder of long
  exact steps) and recorded into a small ring buffer that stays in the cache (the recording's
  stepping and bookkeeping without the memory traffic);
* memory floor: writing a recorded window's samples (every column) into a fresh column-major
  buffer as the window allocates it (zeroed pages, first touch included) and into a buffer
  already touched, per sample.

Run it against another checkout (``PYTHONPATH=/path/to/it``) for a before/after; ``--json``
prints one line of the numbers for a driver that alternates checkouts.

    python scripts/record_cost.py [--repeat 7] [--json] [--set key=value ...]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
import types


def cpu(fn, repeat: int) -> float:
    """Median CPU seconds of ``fn()`` over ``repeat`` calls (:func:`vetica_cli.bench.cpu_ms`)."""
    from vetica_cli.bench import cpu_ms

    return cpu_ms(fn, repeat) / 1e3


def parse_sets(items) -> dict:
    import yaml

    out = {}
    for it in items or ():
        k, v = it.split("=", 1)
        out[k] = yaml.safe_load(v)
    return out


def measure(repeat: int, overrides: dict) -> dict:
    import numpy as np

    from vetica_cli.core import engine
    from vetica_cli.core import tapping as T
    from vetica_cli.simulation.config import load
    from vetica_cli.simulation.simulate import derive, kernel_setup, simulate

    cfg = load(None, overrides)
    d = derive(cfg)
    # the kernel stages as simulate() runs them, timed in CPU seconds (engine.run's own split)
    engine.time = types.SimpleNamespace(perf_counter=time.process_time)
    try:
        run = simulate(cfg)  # warm-up
        stages = [simulate(cfg).timing_s for _ in range(repeat)]
    finally:
        engine.time = time
    med = {k: statistics.median(t[k] for t in stages) for k in stages[0]}

    # one period from the end of the recorded window (on the orbit)
    kern = engine.Kernel(kernel_setup(cfg, d))
    res = engine.solve_steady(kern, _approached(kern, cfg, d), engine.Controller(
        kern.setup.a_sp, cfg.numerics.kp, cfg.numerics.ki, kern.nt, kern.setup.dt), 0.5 * cfg.numerics.tol_orbit,
        cfg.numerics.orbit_max_periods, False, True)  # fmt: skip
    s0 = res.state
    n_samples = kern.nt // kern.setup.stride

    def recorded():
        s = s0.copy()
        buf = engine.record_buffer(n_samples, kern.n_rec)
        rec = T.new_recorder(stride=kern.setup.stride, origin=int(s[T.S_IDX]), ring=False, active=True)
        kern.advance_raw(s, kern.nt, 0.0, buf, rec, True, kern.new_outputs())
        return buf

    def no_energy():
        s = s0.copy()
        buf = engine.record_buffer(n_samples, kern.n_rec)
        rec = T.new_recorder(stride=kern.setup.stride, origin=int(s[T.S_IDX]), ring=False, active=True)
        kern.advance_raw(s, kern.nt, 0.0, buf, rec, False, kern.new_outputs())

    def unrecorded():
        s = s0.copy()
        kern.advance_raw(s, kern.nt, 0.0, kern._nobuf, T.new_recorder(), False, kern.new_outputs())

    small = engine.record_buffer(1024, kern.n_rec)

    def cached():
        s = s0.copy()
        rec = T.new_recorder(stride=kern.setup.stride, origin=int(s[T.S_IDX]), ring=True, active=True)
        rec[T.R_REP], rec[T.R_LEFT] = 1, 1 << 62  # a ring that never closes (it would after its first contact)
        kern.advance_raw(s, kern.nt, 0.0, small, rec, True, kern.new_outputs())

    ncol = 7 + kern.n_rec
    n_window = cfg.numerics.record_cycles * n_samples

    def floor_fresh():
        b = engine.record_buffer(n_window, kern.n_rec)
        for j in range(ncol):
            b[:, j] = 1.0
        return b

    warm = engine.record_buffer(n_window, kern.n_rec)

    def floor_warm():
        for j in range(ncol):
            warm[:, j] = 1.0

    for fn in (recorded, no_energy, unrecorded, cached, floor_fresh, floor_warm):
        fn()
    # alternate the measured functions so a load change hits them alike
    times = {f.__name__: [] for f in (recorded, no_energy, unrecorded, cached, floor_fresh, floor_warm)}
    for _ in range(repeat):
        for f in (recorded, no_energy, unrecorded, cached, floor_fresh, floor_warm):
            times[f.__name__].append(cpu(f, 1))
    t = {k: statistics.median(v) for k, v in times.items()}
    ns = 1e9 / n_samples
    return {
        "samples_per_period": n_samples,
        "columns": ncol,
        "approach_ms": 1e3 * med["approach"],
        "steady_ms": 1e3 * med["steady"],
        "record_ms": 1e3 * med["record"],
        "to_proven_state_ms": 1e3 * (med["approach"] + med["steady"]),
        "point_ms": 1e3 * med["total"],
        "recorded_period_ms": 1e3 * t["recorded"],
        "unrecorded_period_ms": 1e3 * t["unrecorded"],
        "no_energy_period_ms": 1e3 * t["no_energy"],
        "ns_per_sample_no_energy": ns * t["no_energy"],
        "cached_period_ms": 1e3 * t["cached"],
        "ns_per_sample": ns * t["recorded"],
        "ns_per_sample_cached": ns * t["cached"],
        "floor_fresh_ns": 1e9 * t["floor_fresh"] / n_window,
        "floor_warm_ns": 1e9 * t["floor_warm"] / n_window,
        "periods_evaluated": run.info["periods_evaluated"],
    }


def _approached(kern, cfg, d):
    """The state after the controlled approach of ``simulate()`` (the orbit solve's start)."""
    from vetica_cli.core import engine
    from vetica_cli.simulation.simulate import initial_state

    zb0, zc0, vc0, ctrl_on, rate = initial_state(cfg, d)
    s = engine.new_state(zc0, vc0, 0.0, 0.0, zb0, kern.n_state)
    ctrl = engine.Controller(kern.setup.a_sp, cfg.numerics.kp, cfg.numerics.ki, kern.nt, kern.setup.dt, rate, ctrl_on)
    engine.approach(kern, s, ctrl, d.n_ring, d.max_periods)
    return s


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--json", action="store_true", help="one JSON line of the numbers")
    ap.add_argument("--set", action="append", metavar="KEY=VALUE", help="config override (dotted key)")
    args = ap.parse_args(argv)
    r = measure(args.repeat, parse_sets(args.set))
    if args.json:
        print(json.dumps(r))
        return
    print(f"CPU time, medians of {args.repeat}; {r['samples_per_period']} samples a period, {r['columns']} columns")
    print(f"point (kernel): approach {r['approach_ms']:.1f} ms + steady state {r['steady_ms']:.1f} ms = "
          f"{r['to_proven_state_ms']:.1f} ms to the proven periodic state; recorded window {r['record_ms']:.1f} ms; "
          f"total {r['point_ms']:.1f} ms ({r['periods_evaluated']} periods evaluated)")  # fmt: skip
    print(f"one period from the orbit: recorded {r['recorded_period_ms']:.2f} ms, unrecorded "
          f"{r['unrecorded_period_ms']:.2f} ms, into a cached ring {r['cached_period_ms']:.2f} ms")
    print(f"per recorded sample: {r['ns_per_sample']:.1f} ns (into a cached ring {r['ns_per_sample_cached']:.1f} ns, "
          f"without the energy integrals {r['ns_per_sample_no_energy']:.1f} ns); "
          f"memory floor {r['floor_fresh_ns']:.1f} ns fresh buffer, {r['floor_warm_ns']:.1f} ns touched")


if __name__ == "__main__":
    main()
