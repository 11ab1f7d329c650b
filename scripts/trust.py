"""Can a user trust vetica's numbers on a record like an instrument's?  The coverage check of the
error bars and flags on materials and noise seeds this script draws itself.

For ``--materials`` SLS surfaces drawn at random (``--draw-seed``; k_inf log-uniform in 1-10 N/m,
k0:k_inf 4-64, cd log-uniform over 1e-5 .. 1e-3 kg/s, the thesis's probe) and each record
condition:

* ``thermal`` -- the record ``vetica simulate --set numerics.temperature=300`` makes (approach
  segment, metadata, the force reconstructed from the paddle), at ``--print-step``;
* ``lab`` -- ``numerics.instrument: lab`` (300 K, detector noise and bandwidth, ADC, 2 ns);
* ``stripped`` -- the 300 K record stripped to ``t, z_tip, f_ts`` (true force, nine periods from a
  third of a period in, no approach, no metadata; what a user knows passed: a0 and the pull),
  with white detector noise of 1 pm on z_tip and 0.1 nN on f_ts;

the noise-free orbit is solved once and ``--replicas`` noisy recordings made from it
(``simulate.replicas``, noise seeds drawn from ``--draw-seed``), and every method extracts each.
The reference of a replica is the method's answer on the same condition's noise-free record made
by the same recording path (thermal kernel at 1e-9 K; for ``stripped`` without the white noise):
what the error bar is a claim about.  Per condition, method and quantity:

* ``coverage``: the fraction of unflagged results with a finite sigma whose reference lies within
  +-2 sigma (the claim: 0.90-0.98 for a 2-sigma interval of ~30 replicas); sigma holds the noise
  and the band term (the low-pass's bias: divided out where the whole-cycle fit's surface
  measures it, then its error; else its size);
* ``coverage_sound_ref``: the same, counting only results whose noise-free reference is itself
  unflagged (where the method's noise-free answer is one its checks stand behind; a flagged
  reference can move between the noise-free and the noisy record by more than the noise does,
  e.g. VETICA's k_g at 5:1, +18 % off the truth noise-free and flagged);
* ``width``: median sigma over the replicas' RMS deviation from the reference (1 = calibrated);
* ``flagged``: the fraction flagged (``unidentified``) or refused;
* ``flagged_right``: of the results within 10 % of the truth, the fraction flagged (the claim: <= 0.10);
* ``silently_wrong``: unflagged results off the truth by more than 10 % and more than 3 sigma (the
  claim: 0); not counted (empty) for a quantity whose "truth" is an analogue of another definition
  (:data:`ANALOGUES`: dmt-fit's k_dmt against the storage stiffness k' at pi / contact time, its
  deformation, from the contact force minimum, against the penetration below the undeformed
  surface, its e_dmt against a modulus the spring surfaces do not have): its error is the
  definitions' difference, not a wrong answer.

    PYTHONPATH=. python scripts/trust.py --materials 6 --replicas 30 --draw-seed 2 --out trust.parquet

The materials and seeds of a draw are not used by any test or other script until its held-out run;
then it becomes a development draw (``tests/test_fullfit.py`` holds a draw-21 record,
``scripts/sigma_parts.py`` and ``scripts/approach_noise.py`` read any draw, ``tests/test_fit_z_noise.py``
holds a draw-4 surface, ``tests/test_fullfit.py`` and ``tests/test_band_term.py`` a draw-30 replica,
``tests/test_z1_reading.py`` a draw-33 surface, ``tests/test_band_factor.py`` a draw-34 one).  Development has used
draw seeds 1-34 (each version's held-out table became the next one's development draw); the committed table
(results/noise/trust.md, trust.parquet) is ``--draw-seed 35 --materials 6 --replicas 20``, run once on the final
code; the next fresh seed is 36.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd

from stripped_records import stripped  # scripts/stripped_records.py: nine periods as t, z_tip, f_ts
from table_units import stamp  # scripts/table_units.py
from vetica_cli.extraction import extract_many
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import replicas
from vetica_cli.surfaces.sls import SLS

METHODS = ("vetica", "vetica-prestress", "full", "dmt-fit", "observables")
CONDITIONS = ("thermal", "lab", "stripped")
A0 = 0.2e-9
ANALOGUES = {("dmt-fit", "k_dmt"), ("dmt-fit", "deformation"), ("dmt-fit", "e_dmt")}  # silently_wrong not counted
STRIPPED_NOISE = (1e-12, 1e-10)  # white detector noise of a stripped record: z_tip [m], f_ts [N]


def draw_materials(n: int, seed: int) -> list[dict]:
    """``n`` SLS surfaces (module docstring) from the draw seed."""
    rng = np.random.default_rng([seed, 27])
    out = []
    for _ in range(n):
        k_inf = float(10 ** rng.uniform(0.0, 1.0))
        ratio = float(2 ** rng.uniform(2.0, 6.0))
        cd = float(10 ** rng.uniform(-5.0, -3.0))
        out.append({"k_inf": round(k_inf, 4), "k0": round(ratio * k_inf, 4), "cd": float(f"{cd:.4g}")})
    return out


def condition_overrides(condition: str, print_step: float, cycles: int) -> dict:
    base = {"numerics.record_cycles": cycles}
    if condition == "lab":
        return {**base, "numerics.instrument": "lab"}
    return {**base, "numerics.temperature": 300.0, "numerics.print_step": print_step}


def noise_free(ov: dict):
    """The reference record of a condition's overrides ``ov``: the same recording path without noise (the
    thermal kernel at 1e-9 K, no detector noise, no ADC)."""
    return replicas(load(None, {**ov, "numerics.temperature": 1e-9, "numerics.detector_noise_density": 0.0,
                                "numerics.adc_resolution": 0.0}), [0])[0]  # fmt: skip


def noise_seeds(draw_seed: int, index: int, condition: str, n: int) -> np.ndarray:
    """The ``n`` noise seeds of material ``index`` of a draw under ``condition``."""
    return np.random.default_rng([draw_seed, index, CONDITIONS.index(condition)]).integers(1, 2**31, n)


def answers(run, condition: str, rng=None, cutoff_hz=None, methods=METHODS) -> dict:
    """``{method: ExtractionResult or the refusal's text}`` on one run under ``condition``
    (``cutoff_hz``: the reconstruction's low-pass, default the automatic one)."""
    out = {}
    if condition == "stripped":
        df = stripped(run)
        if rng is not None:
            df["z_tip"] += rng.normal(0.0, STRIPPED_NOISE[0], len(df))
            df["f_ts"] += rng.normal(0.0, STRIPPED_NOISE[1], len(df))
        args = (df, None, "true")
        kw = {"a0": A0, "vdw_on_surface": True}
    else:
        args = (run.frame(), run.metadata(), "reconstructed")
        kw = {} if cutoff_hz is None else {"cutoff_hz": cutoff_hz}
    for m in methods:
        if condition == "stripped" and m == "observables":
            continue  # amplitude and phase need the drive: not in a stripped record
        try:
            out[m] = extract_many(*args, {m: {}}, **kw)[m]
        except Exception as exc:  # noqa: BLE001 - a refused record is a row, as in a sweep
            out[m] = str(exc).splitlines()[0][:200]
    return out


def material_rows(material: dict, index: int, condition: str, replicas_n: int, draw_seed: int,
                  print_step: float, cycles: int, methods=METHODS) -> list[dict]:  # fmt: skip
    """Rows of one material under one condition: every replica, method and quantity."""
    t0 = time.perf_counter()
    ov = {**condition_overrides(condition, print_step, cycles), **{f"surface.{k}": v for k, v in material.items()}}
    truth = SLS().theory(material)
    ref_full = answers(noise_free(ov), condition, methods=methods)
    seeds = noise_seeds(draw_seed, index, condition, replicas_n)
    runs = replicas(load(None, ov), [int(s) for s in seeds])
    rng0 = [np.random.default_rng([int(seed), 5]) for seed in seeds]
    got_all = [answers(run, condition, rng, methods=methods) for run, rng in zip(runs, rng0)]
    # the same-band reference: the noise-free record read through the band the noisy records' noise chose
    ref = ref_full  # the error bar (noise and the band's bias) is a claim about the noise-free answer at the whole band
    rows = []
    for r, (seed, got) in enumerate(zip(seeds, got_all)):
        for m, res in got.items():
            refm, reff = ref.get(m), ref_full.get(m)
            for q in _quantities(res, refm):
                e = res.estimates.get(q) if not isinstance(res, str) else None
                re_ = refm.estimates.get(q) if refm is not None and not isinstance(refm, str) else None
                rf_ = reff.estimates.get(q) if reff is not None and not isinstance(reff, str) else None
                band = ((res.info.get("uncertainty") or {}).get("band") or {}).get("bias", {}) if e else {}
                v = e.value if e is not None else None
                sig = e.sigma if e is not None and e.sigma is not None else math.nan
                th = truth.get(q) if q in truth else (e.theory if e is not None else None)
                rows.append({
                    "condition": condition, "material": index, **material, "replica": r, "seed": int(seed),
                    "method": m, "quantity": q, "value": _nan(v), "reference": _nan(re_.value if re_ else None),
                    "reference_full_band": _nan(rf_.value if rf_ else None), "band_bias": _nan(band.get(q)),
                    "reference_flagged": re_ is None or re_.value is None or re_.identifiable is False,
                    "truth": _nan(th), "sigma_rel": sig if math.isfinite(sig) else math.nan,
                    "flagged": isinstance(res, str) or e is None or v is None or e.identifiable is False,
                    "reason": res if isinstance(res, str) else (e.reason or "") if e is not None else "",
                    "cutoff_hz": (res.info.get("cutoff_hz") if not isinstance(res, str) else math.nan) or math.nan,
                })  # fmt: skip
    print(f"  {condition} material {index} {material}: {time.perf_counter() - t0:.1f} s", flush=True)
    return rows


def _quantities(res, ref) -> list[str]:
    for r in (res, ref):
        if r is not None and not isinstance(r, str):
            return [q for q, e in r.estimates.items() if e.unit != "" or q in ("tan_delta_am",)]
    return []


def _nan(v):
    return math.nan if v is None else float(v)


def summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per condition, method and quantity: the module docstring's measures."""
    t = table.copy()
    ok = ~t["flagged"] & t["value"].notna()
    dev = (t["value"] - t["reference"]) / t["reference"].abs()
    t["covered"] = (dev.abs() <= 2.0 * t["sigma_rel"]) & t["sigma_rel"].notna()
    t["countable"] = ok & t["sigma_rel"].notna() & t["reference"].notna()
    err = (t["value"] - t["truth"]) / t["truth"].abs()
    t["within10"] = (err.abs() <= 0.10) & t["value"].notna()
    t["wrong"] = ok & (err.abs() > 0.10) & (err.abs() > 3.0 * t["sigma_rel"].fillna(np.inf))
    t["dev"] = dev
    rows = []
    for (c, m, q), g in t.groupby(["condition", "method", "quantity"], sort=False):
        cnt = g[g["countable"]]
        snd = cnt[~cnt["reference_flagged"]] if "reference_flagged" in cnt else cnt.iloc[:0]
        rms = float(np.sqrt(np.nanmean(cnt["dev"] ** 2))) if len(cnt) else math.nan
        w10 = g[g["within10"]]
        rows.append({
            "condition": c, "method": m, "quantity": q, "results": len(g), "countable": len(cnt),
            "coverage": float(cnt["covered"].mean()) if len(cnt) else math.nan,
            "coverage_sound_ref": float(snd["covered"].mean()) if len(snd) else math.nan,
            "width": float(np.nanmedian(cnt["sigma_rel"])) / rms if len(cnt) and rms > 0 else math.nan,
            "flagged": float(g["flagged"].mean()),
            "flagged_right": float(w10["flagged"].mean()) if len(w10) else math.nan,
            "silently_wrong": math.nan if (m, q) in ANALOGUES else int(g["wrong"].sum()),
            "median_err_pct": float(100 * np.nanmedian(np.abs(err[g.index]))),
        })  # fmt: skip
    return pd.DataFrame(rows)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--materials", type=int, default=6)
    ap.add_argument("--replicas", type=int, default=30)
    ap.add_argument("--draw-seed", type=int, default=2)
    ap.add_argument("--conditions", nargs="*", default=list(CONDITIONS), choices=CONDITIONS)
    ap.add_argument("--print-step", type=float, default=0.5e-9, help="thermal and stripped conditions [s]")
    ap.add_argument("--cycles", type=int, default=10, help="recorded periods")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--methods", nargs="*", default=list(METHODS), choices=METHODS, help="methods extracted (default all)")
    ap.add_argument("--out", default="trust.parquet")
    ap.add_argument("--md", default=None, help="also write the summary as a Markdown table to this file")
    args = ap.parse_args(argv)
    from joblib import Parallel, delayed

    mats = draw_materials(args.materials, args.draw_seed)
    tasks = [(mat, i, c) for c in args.conditions for i, mat in enumerate(mats)]
    t0 = time.perf_counter()
    parts = Parallel(n_jobs=args.jobs)(delayed(material_rows)(mat, i, c, args.replicas, args.draw_seed,
                                                              args.print_step, args.cycles, tuple(args.methods))
                               for mat, i, c in tasks)  # fmt: skip
    table = pd.DataFrame([r for p in parts for r in p])
    table.to_parquet(args.out)
    stamp(args.out)  # units and descriptions in the metadata
    s = summary(table)
    with pd.option_context("display.width", 220, "display.max_columns", 20, "display.max_rows", 500):
        print(s.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    print(f"{len(table)} rows, {time.perf_counter() - t0:.0f} s; wrote {args.out}")
    if args.md:
        cmd = " ".join(["PYTHONPATH=. python scripts/trust.py", *(argv if argv is not None else __import__("sys").argv[1:])])
        head = (f"Generated by `{cmd}` ({len(mats)} materials drawn with draw seed {args.draw_seed}: "
                + "; ".join(f"k_inf {m['k_inf']:g}, k0 {m['k0']:g}, cd {m['cd']:g}" for m in mats)
                + f"; {args.replicas} replicas each; {time.perf_counter() - t0:.0f} s on {args.jobs} workers).\n\n")
        cols = list(s.columns)
        lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
        for _, r in s.iterrows():
            lines.append("| " + " | ".join(f"{v:.3g}" if isinstance(v, float) else str(v) for v in r) + " |")
        Path(args.md).write_text(head + "\n".join(lines) + "\n")
    return table


if __name__ == "__main__":
    main()
