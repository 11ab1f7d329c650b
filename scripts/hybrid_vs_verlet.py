"""The hybrid integrator against all-fine Verlet on the thesis's study grid.

    python scripts/hybrid_vs_verlet.py              # every 12th simulation of the 7 studies, 3 switch gaps (~3 min)
    python scripts/hybrid_vs_verlet.py --every 4    # denser

For a sample of the distinct simulations of the seven thesis study configs it runs the point
with ``numerics.integrator: verlet`` (every step a fine Verlet step) and with ``hybrid`` at
switch gaps 0.5, 1 and 2 nm (the default), both to the periodic orbit, and prints the largest
relative difference of each observable that matters to the extraction (peak force, E_diss, contact time,
amplitude, phase) plus the penetration, with the point where it occurs, and the kernel time
of each integrator (median).  The longest far step is 2**13 fine steps (0.2 us at dt 0.025 ns,
1 % of the 50 kHz period; ``engine.KernelSetup.ladder_max``).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

import numpy as np
import pandas as pd
from joblib import Parallel, delayed

OBS = ["peak_force", "e_diss_ev", "contact_time", "amplitude", "phase_deg", "max_penetration"]
EDISS_FLOOR = 0.01  # [eV]
GAPS = [0.5e-9, 1e-9, 2e-9]  # 2 nm is numerics.switch_gap's default: the smallest of these with every observable within 1e-4


def sample(every: int) -> list[tuple[str, str, object]]:
    from steady_grid import thesis_simulations  # scripts/ is on the path when a script runs

    return thesis_simulations()[::every]


def one(study: str, label: str, cfg) -> list[dict]:
    from vetica_cli.simulation.simulate import simulate

    rows = []
    for integ, gap in [("verlet", np.nan)] + [("hybrid", g) for g in GAPS]:
        n = replace(cfg.numerics, record_cycles=2, integrator=integ)
        if integ == "hybrid":
            n = replace(n, switch_gap=gap)
        run = simulate(replace(cfg, numerics=n))
        rows.append({"study": study, "point": label, "integrator": integ, "switch_gap": gap,
                     "stop_reason": run.stop_reason, "kernel_s": run.timing_s["approach"] + run.timing_s["steady"],
                     **{k: run.observables[k] for k in OBS}})  # fmt: skip
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--every", type=int, default=12, help="take every n-th simulation of the grid")
    ap.add_argument("-j", "--jobs", type=int, default=2)
    args = ap.parse_args()
    todo = sample(args.every)
    print(f"{len(todo)} points x (verlet + {len(GAPS)} switch gaps)", file=sys.stderr)
    t = pd.DataFrame([r for rows in Parallel(n_jobs=args.jobs)(delayed(one)(*x) for x in todo) for r in rows])
    ref = t[t.integrator == "verlet"].set_index(["study", "point"])
    print(f"{len(todo)} points; all steady: {bool(t['stop_reason'].str.startswith('steady').all())}")
    print(f"verlet kernel to steady state: median {ref['kernel_s'].median():.3f} s")
    for gap in GAPS:
        h = t[(t.integrator == "hybrid") & (t.switch_gap == gap)].set_index(["study", "point"])
        cells = []
        for k in OBS:
            if k == "phase_deg":
                d = (h[k] - ref[k]).abs()  # degrees, absolute
            else:
                d = ((h[k] - ref[k]) / ref[k].abs()).abs()
            i = d.idxmax()
            cells.append(f"{k} {d.max():.1e}" + (" deg" if k == "phase_deg" else "") + f" ({i[0]}: {i[1]})")
        print(f"\nswitch gap {gap * 1e9:g} nm: kernel median {h['kernel_s'].median():.3f} s "
              f"({ref['kernel_s'].median() / h['kernel_s'].median():.1f}x faster than verlet)")  # fmt: skip
        for c in cells:
            print("  largest |relative difference|: " + c)
        # E_diss near zero (a frozen dashpot without the pull: ~1e-4 eV of a ~1e4 eV drive cycle)
        # makes its relative difference meaningless: the absolute one, and the relative one above 0.01 eV
        de = (h["e_diss_ev"] - ref["e_diss_ev"]).abs()
        big = ref["e_diss_ev"].abs() >= EDISS_FLOOR
        rb = de[big] / ref["e_diss_ev"][big].abs()
        i, j = rb.idxmax(), de.idxmax()
        over = rb[rb > 1e-4]
        print(f"  e_diss_ev above 1e-4 relative (E_diss >= {EDISS_FLOOR} eV): {len(over)} points"
              + "".join(f"; {k[0]}: {k[1]} {v:.1e} (E_diss {ref.loc[k, 'e_diss_ev']:.3g} eV)" for k, v in over.items()))
        print(f"  e_diss_ev: largest absolute difference {de.max():.1e} eV ({j[0]}: {j[1]}); largest relative where "
              f"E_diss >= {EDISS_FLOOR} eV: {rb.max():.1e} ({i[0]}: {i[1]}; {int(big.sum())} of {len(big)} points)")  # fmt: skip


if __name__ == "__main__":
    main()
