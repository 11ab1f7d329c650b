"""Equipartition over many seeds: a free probe's recorded deflection variance at 300 K against
``kB T / k`` (cantilever and paddle), the free probe of tests/test_thermal.py recorded with 12
noise seeds (one solution of the noise-free orbit, ``simulate.replicas``); prints the mean, the
standard deviation and the range of the relative deviation.  One seed's variance is an estimate
with a standard error of ~2 % (cantilever) and ~0.5 % (paddle): quote the spread, not one draw.

    PYTHONPATH=. python scripts/equipartition.py
"""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_thermal import FREE, IC, IP  # noqa: E402

from vetica_cli.simulation import thermal  # noqa: E402
from vetica_cli.simulation.config import load  # noqa: E402
from vetica_cli.simulation.simulate import replicas, simulate  # noqa: E402


def main(seeds: int = 12) -> None:
    cfg = load(None, {**FREE, "numerics.temperature": 300.0})
    clean = simulate(load(None, FREE))
    runs = replicas(cfg, range(1, seeds + 1))
    for col, k, name in ((IC, cfg.probe.k1, "cantilever"), (IP, cfg.probe.k2, "paddle")):
        r = np.array([np.var(run.steady[:, col] - clean.steady[:, col]) / (thermal.KB * 300.0 / k) - 1 for run in runs])
        r *= 100.0
        print(f"{name}: mean {r.mean():+.2f} %, sd {r.std(ddof=1):.2f} %, range {r.min():+.2f} .. {r.max():+.2f} % "
              f"over {len(r)} seeds")  # fmt: skip


if __name__ == "__main__":
    main()
