"""The SLS specialisation of the prescribed-trajectory kernel against the N-arm kernel with one
arm (core/prescribed.py: surface_force vs arms_force), on the worked example's record: the
same forces and Jacobian (max relative difference printed) and the time of one pass, value
only and with the full Jacobian (median of repeated passes, after a warm-up).

    PYTHONPATH=. python scripts/measure_prescribed_sls.py
"""

import statistics
import time

import numpy as np

from vetica_cli.core.prescribed import NDIR, arm_coefficients, arms_force, surface_force
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import simulate

K_INF, K0, CD, A0 = 4.0, 128.0, 3e-5, 0.2e-9  # thesis worked example (tables 2-4)
HR6 = 0.2e-18 * 10e-9 / 6.0  # H R / 6 [J m]
FAR_GAP, BLOCK, SUBSTEPS, SUB_GAP = 5e-9, 256, 4, 1e-9  # the full method's settings (fullfit.model)
REPEAT = 7


def main() -> None:
    run = simulate(load(None, {"numerics.record_cycles": 4}))
    df = run.frame()
    z = df.loc[df["segment"] == "steady", "z_tip"].to_numpy(float)
    h = run.params["numerics"]["print_step"]
    n = len(z)
    coarse_ok = np.ones(n // BLOCK, np.uint8)
    want = np.ones(n, np.uint8)
    co = arm_coefficients(K_INF, np.array([K0]), np.array([CD]), HR6, A0, True, (h, h * BLOCK, h / SUBSTEPS), True)
    print(f"record: {n} samples at {h * 1e9:g} ns (worked example, 4 periods)")
    for ndir in (0, NDIR):
        f1, j1 = np.zeros(n), np.zeros((n, NDIR))
        f2, j2 = np.zeros(n), np.zeros((n, 3 * 1 + 3))

        def sls():
            return surface_force(z, 0.0, K_INF, K0, CD, HR6, A0, True, h, BLOCK, coarse_ok, want, FAR_GAP, SUBSTEPS,
                                 SUB_GAP, 0.0, False, ndir, f1, j1)  # fmt: skip

        def arms():
            return arms_force(z, 0.0, A0, BLOCK, coarse_ok, want, FAR_GAP, SUBSTEPS, SUB_GAP, np.zeros(1), False,
                              ndir, *co, f2, j2)  # fmt: skip

        times = {}
        for name, fn in (("SLS kernel", sls), ("N-arm kernel, 1 arm", arms)):
            fn()
            walls = []
            for _ in range(REPEAT):
                t0 = time.perf_counter()
                fn()
                walls.append(time.perf_counter() - t0)
            times[name] = statistics.median(walls)
        diff = np.max(np.abs(f1 - f2)) / np.max(np.abs(f1))
        a, b = times["SLS kernel"], times["N-arm kernel, 1 arm"]
        print(f"ndir {ndir}: SLS {a * 1e3:.2f} ms, N-arm {b * 1e3:.2f} ms (x{b / a:.2f}); max |dF|/max|F| {diff:.2e}")


if __name__ == "__main__":
    main()
