"""Two-arm recovery of the hertz whole-cycle fit (docs/hertz.md): simulate the cross-model's
``hertz2`` surface (e_inf 0.5 GPa, e_1 1.0 GPa with tau, e_2 0.5 GPa with 10 tau, nu 0.5, the
worked example's probe and set point, attraction on the tip only) and fit it as an instrument
would (the surface's parameters removed from the metadata; stated: a0, H, R, nu, no surface pull).

    python scripts/hertz_two_arms.py [--tau-f1 0.1 1] [--elements auto] [--force true]
                                     [--grid-rel 1e-4]

``--elements`` is the simulator's grid (auto: 0.1 % of Hertz at the deepest tap; an integer for a
finer one), ``--grid-rel`` the fit grid's accuracy (default the fit's own, GRID_REL).  Prints per
record every parameter's error [%], relative 1-sigma, verdict, the fitted height and the time.
"""

from __future__ import annotations

import argparse
import copy
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tau-f1", type=float, nargs="+", default=[0.1, 1.0])
    ap.add_argument("--elements", default="auto")
    ap.add_argument("--force", default="true", choices=("true", "reconstructed"))
    ap.add_argument("--grid-rel", type=float, default=None)
    ap.add_argument("--record-cycles", type=int, default=3)
    args = ap.parse_args()
    from vetica_cli.extraction import extract
    from vetica_cli.extraction.fullfit import hertz as fit_hertz
    from vetica_cli.simulation.config import from_dict
    from vetica_cli.simulation.simulate import simulate

    if args.grid_rel is not None:
        fit_hertz.GRID_REL = args.grid_rel
    elements = args.elements if args.elements == "auto" else int(args.elements)
    for tf in args.tau_f1:
        tau = tf / 50e3  # the worked example's f1 = 50 kHz
        surface = {"model": "hertz", "e_inf": 5e8, "arms": [{"e": 1e9, "tau": tau}, {"e": 0.5e9, "tau": 10 * tau}],
                   "nu": 0.5, "elements": elements, "hamaker": 0.2e-18, "a0": 0.2e-9, "vdw_on_surface": False}
        t0 = time.perf_counter()
        run = simulate(from_dict({"surface": surface, "numerics": {"record_cycles": args.record_cycles}}))
        sim_s = time.perf_counter() - t0
        df, meta = run.frame(), run.metadata()
        meta_s = copy.deepcopy(meta)
        meta_s["params"]["surface"] = {k: surface[k] for k in ("hamaker", "a0", "vdw_on_surface")}
        t0 = time.perf_counter()
        res = extract(df, meta_s, force=args.force, method="full", fit_model="hertz", arms=2, a0=0.2e-9,
                      vdw_on_surface=False, hamaker=0.2e-18, tip_radius=10e-9, nu=0.5)  # fmt: skip
        fit_s = time.perf_counter() - t0
        truth = {"e_g": 2e9, "e_inf": 5e8, "e_1": 1e9, "tau_1": tau, "e_2": 5e8, "tau_2": 10 * tau}
        cells = []
        for name, v in truth.items():
            e = res.estimates[name]
            flag = "" if e.identifiable in (True, None) else " unidentified"
            cells.append(f"{name} {100 * (e.value - v) / v:+.3g} % (1-sigma {100 * e.sigma:.2g} %{flag})")
        fit = res.info["fit"]
        grid = meta["kernel"]["mdr"]
        print(f"tau f1 {tf:g}, simulator grid {grid['elements']} elements "
              f"({grid['elastic_force_error_at_delta_max']:.2g} of Hertz), fit grid {fit['elements']}, "
              f"{args.force} force: " + "; ".join(cells)
              + f"; RMS residual {fit['residual_rms_pct']:.2g} % of the peak; "
              f"height {fit['surface_height_m'] * 1e12:+.1f} pm (truth 0); simulate {sim_s:.0f} s, fit {fit_s:.0f} s",
              flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
