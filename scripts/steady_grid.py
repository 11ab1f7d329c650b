"""How the steady state is reached over the thesis's study grid.

    python scripts/steady_grid.py                 # every simulation of the 7 thesis studies + a cd range
    python scripts/steady_grid.py --quick         # the cd range only
    python scripts/steady_grid.py -o steady_grid.parquet

For every distinct simulation of the seven thesis study configs (``dashpot``,
``dashpot_vdw_off``, ``stiffness_ratio``, ``setpoint``, ``frequency``, ``print_step``,
``paddle_stiffness``), and for cd = 1e-7 ... 1e4 kg/s (12 values) at the extreme settings of
those studies (1:8 and 32:1, set point 25 % and 80 %, f1 10 and 100 kHz, print step 8 ns,
van der Waals pull off), it runs :func:`vetica_cli.simulation.simulate.simulate` with two
recorded periods and keeps from the run's metadata: how it became steady (orbit, transient
fallback, not at all), the orbit solver's period evaluations and residual, the proof
(state change over one recorded period, the arms' mean stretch), a change of oscillation branch
between the approach and the orbit, and the kernel's wall time to the proven steady state
(approach + steady, one core).  It prints the summary and writes the table.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
from joblib import Parallel, delayed

ROOT = Path(__file__).resolve().parent.parent
from regenerate_results import THESIS  # noqa: E402  (scripts/ is on the path when a script runs)

EXTREMES = {  # setting -> overrides of the worked example (16:1 unless stated, as the studies)
    "32:1": {"surface.stiffness_ratio": 32},
    "1:8": {"surface.stiffness_ratio": 0.125},
    "setpoint 25 %": {"surface.stiffness_ratio": 16, "operation.setpoint": 0.25},
    "setpoint 80 %": {"surface.stiffness_ratio": 16, "operation.setpoint": 0.8},
    "f1 10 kHz": {"surface.stiffness_ratio": 16, "probe.f1": 10e3, "probe.f2": 150e3},
    "f1 100 kHz": {"surface.stiffness_ratio": 16, "probe.f1": 100e3, "probe.f2": 1.5e6},
    "PS 8 ns": {"surface.stiffness_ratio": 16, "numerics.print_step": 8e-9},
    "vdW off": {"surface.stiffness_ratio": 16, "surface.vdw_on_surface": False},
}
CD_RANGE = np.logspace(-7, 4, 12)


def thesis_simulations() -> list[tuple[str, str, object]]:
    """(study, point label, config) of every distinct simulation of the seven thesis study configs."""
    from vetica_cli.study.grid import load_study
    from vetica_cli.rows.plan import group

    out = []
    for name in THESIS:
        for task in group(load_study(ROOT / "configs" / f"{name}.yaml").points):
            p = task.points[0]
            out.append((name, p.label(), p.config))
    return out


def configs(quick: bool) -> list[tuple[str, str, object]]:
    from vetica_cli.simulation.config import load

    out = [] if quick else thesis_simulations()
    for setting, over in EXTREMES.items():
        for cd in CD_RANGE:
            flat = {**over, "surface.cd": float(cd), "surface.k_inf": 4.0}
            out.append((f"cd range, {setting}", f"cd={cd:.3g}", load(None, flat)))
    return out


def one(study: str, label: str, cfg) -> dict:
    from dataclasses import replace

    from vetica_cli.simulation.simulate import simulate

    cfg = replace(cfg, numerics=replace(cfg.numerics, record_cycles=2))
    t0 = time.perf_counter()
    run = simulate(cfg)
    wall = time.perf_counter() - t0
    k = run.info
    st = k.get("steady", {})
    orbit = st.get("orbit") or {}
    proof = st.get("proof") or {}
    branch = (st.get("approach_branch") or {}).get("repulsive"), (st.get("orbit_branch") or {}).get("repulsive")
    return {
        "study": study, "point": label, "cd": float(np.atleast_1d(getattr(cfg.surface, "cd", np.nan))[0]),
        "stop_reason": run.stop_reason, "steady_ok": bool(run.steady_ok), "method": st.get("method"),
        "orbit_converged": orbit.get("converged"), "orbit_periods": orbit.get("periods"),
        "orbit_residual_m": orbit.get("residual"), "periods_evaluated": k.get("periods_evaluated"),
        "approach_periods": k.get("approach_periods"), "state_change_m": proof.get("state_change_m"),
        "mean_arm_stretch_m": max(abs(v) for v in (proof.get("mean_arm_stretch_m") or [np.nan])),
        "branch_change": branch[0] is not None and branch[1] is not None and branch[0] != branch[1],
        "kernel_to_steady_s": run.timing_s["approach"] + run.timing_s["steady"],
        "wall_s": wall,
    }  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="only the cd range at the extreme settings")
    ap.add_argument("-o", "--output", default=None, help="Parquet table to write (default: none)")
    ap.add_argument("-j", "--jobs", type=int, default=2)
    args = ap.parse_args()
    todo = configs(args.quick)
    print(f"{len(todo)} simulations", file=sys.stderr)
    rows = Parallel(n_jobs=args.jobs, verbose=5)(delayed(one)(*t) for t in todo)
    t = pd.DataFrame(rows)
    if args.output:
        t.to_parquet(args.output)
    t["group"] = np.where(t["study"].str.startswith("cd range"), "cd 1e-7 .. 1e4, extreme settings", "thesis study grid")
    pd.set_option("display.width", 200)
    for g, d in t.groupby("group"):
        per = d["orbit_periods"].dropna()
        ks = d["kernel_to_steady_s"]
        print(f"\n{g}: {len(d)} simulations")
        print(f"  steady (proven): {int(d['steady_ok'].sum())}; by method: {d['method'].value_counts().to_dict()}")
        print(f"  not steady: {int((~d['steady_ok']).sum())}; branch changes approach -> orbit: {int(d['branch_change'].sum())}")
        if len(per):
            print(f"  orbit solver period evaluations: median {per.median():.0f}, p90 {per.quantile(0.9):.0f}, max {per.max():.0f}")
        print(f"  periods evaluated in all (approach + solve + proof): median {d['periods_evaluated'].median():.0f}, "
              f"max {d['periods_evaluated'].max():.0f}")  # fmt: skip
        print(f"  kernel to proven steady state [s]: median {ks.median():.3f}, p90 {ks.quantile(0.9):.3f}, max {ks.max():.3f}")
        print(f"  largest proof: state change {d['state_change_m'].max():.2g} m, mean arm stretch {d['mean_arm_stretch_m'].max():.2g} m")
        bad = d[~d["steady_ok"] | (d["method"] != "orbit")]
        if len(bad):
            print(bad[["study", "point", "stop_reason", "method", "orbit_periods"]].to_string(index=False))


if __name__ == "__main__":
    main()
