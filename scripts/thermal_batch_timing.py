"""CPU time per replica of the thermal recording: one replica at a time against several advanced
together in one kernel call (``thermal_records``), at R = 1, 2, 4, 8.

    PYTHONPATH=. python scripts/thermal_batch_timing.py                 # the worked example at 300 K
    PYTHONPATH=. python scripts/thermal_batch_timing.py --repeats 5 --set numerics.record_cycles=2
    PYTHONPATH=. python scripts/thermal_batch_timing.py --replica-set 30  # also replica_set(cfg, 30), whole

CPU time (``time.process_time``), medians of ``--repeats`` runs (the machine is shared: wall
time is noise).  The one-at-a-time column is ``thermal_record`` per replica (the path
``simulate`` takes), the batched one ``thermal_records`` of R replicas divided by R; both draw
the noise and run the kernel.  The noise-free orbit is solved once, outside the timings; every
timed call records from it.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from vetica_cli.simulation import simulate as S
from vetica_cli.simulation import thermal as T
from vetica_cli.simulation.config import load


def _value(text: str):
    try:
        return float(text) if any(c in text for c in ".e") else int(text)
    except ValueError:
        return text


def cpu(fn) -> float:
    t = time.process_time()
    fn()
    return time.process_time() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--sizes", default="1,2,4,8", help="batch sizes R")
    ap.add_argument("--set", action="append", default=[], help="config override key=value (repeatable)")
    ap.add_argument("--replica-set", type=int, default=0, help="also time replica_set(cfg, N), whole")
    args = ap.parse_args()
    ov = {"numerics.temperature": 300.0}
    for kv in args.set:
        k, v = kv.split("=", 1)
        ov[k] = _value(v)
    cfg = load(None, ov)
    run, kern, s0, d = S.noise_free_point(cfg)
    print(f"steps per period {kern.nt}, periods {T.SETTLE_CYCLES + cfg.numerics.record_cycles}, "
          f"samples {d.n_steady}, arms {kern.n_arms}, repeats {args.repeats} (medians, CPU s)")  # fmt: skip

    def rngs(n, k):  # the generators of n replicas, another set for each repeat k
        return [np.random.default_rng([k, i]) for i in range(n)]

    T.thermal_record(kern, s0, cfg, d, rngs(1, 0)[0])  # compiled and warm
    single = statistics.median(cpu(lambda: T.thermal_record(kern, s0, cfg, d, rngs(1, k)[0]))
                               for k in range(args.repeats))  # fmt: skip
    print(f"{'R':>3} {'one at a time':>14} {'batched':>10} {'ratio':>7}   [CPU s per replica]")
    for n in (int(x) for x in args.sizes.split(",")):
        T.thermal_records(kern, s0, [cfg] * n, d, rngs(n, 0))  # warm at this size (memory)
        per = statistics.median(cpu(lambda: T.thermal_records(kern, s0, [cfg] * n, d, rngs(n, k))) / n
                                for k in range(args.repeats))  # fmt: skip
        print(f"{n:3d} {single:14.3f} {per:10.3f} {single / per:7.2f}")
    if args.replica_set:
        times = [cpu(lambda: S.replica_set(cfg, args.replica_set)) for _ in range(args.repeats)]
        print(f"replica_set(cfg, {args.replica_set}): median {statistics.median(times):.2f} CPU s "
              f"({', '.join(f'{t:.2f}' for t in times)}; includes solving the noise-free orbit)")  # fmt: skip


if __name__ == "__main__":
    main()
