"""The CPU time per curve of ``vetica fit`` that docs/fit.md quotes, measured in this process.

    python scripts/fit_timings.py            # prints a Markdown table and the machine's load

For every force-distance curve committed under tests/data (afmformats' JPK curves, MIT) and
the JPK text export: the median process time of ``repeat`` fits (after one that loads numba's
cached kernels) with the power law and with Maxwell arms (1-3, BIC), one thread (the API's cap,
vetica_cli.batch.launch.one_thread).  Then one dwell curve (Lee-Radok, 3 arm counts) with the cap
and without it (BLAS's own thread count), the table compared.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

from vetica_cli.batch.launch import one_thread
from vetica_cli.curves.fd import fit_fd_curve
from vetica_cli.curves.fit import fit_curve
from vetica_cli.curves.read import read_curves

ROOT = Path(__file__).resolve().parents[1]
FD_FILES = [ROOT / "tests/data/afmformats/fmt-jpk-fd_spot3-0192.jpk-force",
            ROOT / "tests/data/afmformats/fmt-jpk-fd_map-data-reference-points.jpk-force-map",
            ROOT / "tests/data/jpktext/spot3-0192-export.txt"]  # fmt: skip
DWELL = ROOT / "tests/data/afmformats/cell1-0001.jpk-force"
R = 5e-6


def cpu(fn, repeat: int) -> float:
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores\n")
    print("| curve | samples in window | power law [CPU ms] | Maxwell 1-3 arms [CPU ms] |")
    print("|---|---|---|---|")
    with one_thread():
        for c in read_curves(FD_FILES):
            pl = cpu(lambda: fit_fd_curve(c, R, 0.5), a.repeat)
            mx = cpu(lambda: fit_fd_curve(c, R, 0.5, "maxwell"), max(1, a.repeat // 2))
            n = fit_fd_curve(c, R, 0.5)[0]["samples"]
            print(f"| {c.name} | {n} | {1e3 * pl:.1f} | {1e3 * mx:.0f} |")
    curve = read_curves([DWELL])[0]
    with one_thread():
        t0 = time.process_time()
        capped = fit_curve(curve, R, 0.5)
        t_cap = time.process_time() - t0
    t0 = time.process_time()
    free = fit_curve(curve, R, 0.5)
    t_free = time.process_time() - t0
    same = all(abs(x["bic"] - y["bic"]) <= 1e-6 * abs(x["bic"]) for x, y in zip(capped, free))
    print(f"\ndwell curve {curve.name} (Lee-Radok, 1-3 arms): {t_cap:.2f} CPU-s with one BLAS thread, "
          f"{t_free:.2f} CPU-s with BLAS's own threads; same BIC to 1e-6: {same}")


if __name__ == "__main__":
    main()
