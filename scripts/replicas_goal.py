"""The replicas goal: 30 thermal replicas of one point, each with the whole-cycle fit, in CPU time.

    PYTHONPATH=. python scripts/replicas_goal.py                      # the worked example at 300 K
    PYTHONPATH=. python scripts/replicas_goal.py --set numerics.record_cycles=4 --set numerics.print_step=1e-9

Prints the CPU seconds (``time.process_time``, this process; BLAS capped at one thread as the
``vetica`` command caps it) of ``replica_set(cfg, N)`` (the noise-free orbit once, N noisy
recordings in the kernel's groups) and of the whole-cycle fit (``full``, the force reconstructed
from the paddle, error bars and checks) on each record, and their sum against the goal of 1 CPU-s.
One run: the machine is shared, so repeat it and take the median.
"""

from __future__ import annotations

import argparse
import os
import time

for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--replicas", type=int, default=30)
    ap.add_argument("--set", action="append", default=[], help="a config override KEY=VALUE (as vetica --set)")
    args = ap.parse_args(argv)

    from vetica_cli.extraction import extract_many
    from vetica_cli.simulation.config import load, parse_set
    from vetica_cli.simulation.simulate import replica_set

    cfg = load(None, {"numerics.temperature": 300.0, **parse_set(args.set)})
    replica_set(cfg, 1)  # compile and warm the kernels outside the timing
    t0 = time.process_time()
    _, runs = replica_set(cfg, args.replicas)
    t_sim = time.process_time() - t0
    frames = [(r.frame(), r.metadata()) for r in runs]
    extract_many(*frames[0], "reconstructed", {"full": {}})  # warm
    t0 = time.process_time()
    for df, meta in frames:
        extract_many(df, meta, "reconstructed", {"full": {}})
    t_fit = time.process_time() - t0
    rows = len(frames[0][0])
    print(f"{args.replicas} replicas, {rows} rows each: simulate {t_sim:.2f} CPU-s ({t_sim / args.replicas:.3f} a "
          f"replica), whole-cycle fit {t_fit:.2f} CPU-s ({t_fit / args.replicas:.3f} a record), total "
          f"{t_sim + t_fit:.2f} CPU-s against a goal of 1 CPU-s ({(t_sim + t_fit):.1f}x)")


if __name__ == "__main__":
    main()
