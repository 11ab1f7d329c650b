"""How each method's error bar compares with its replicas' scatter, part by part, on a draw of
``scripts/trust.py``'s materials (development: its seeds are the trust check's, so use a draw that
is not the committed held-out one).

For ``--materials`` SLS surfaces of ``--draw-seed`` (:func:`trust.draw_materials`) at 300 K (the
trust check's ``thermal`` condition: ten periods at 0.5 ns, the force reconstructed from the paddle),
``--replicas`` noisy records of each (the trust check's noise seeds for that draw) and the
noise-free reference; every method in ``--methods`` on each.  Per method and quantity, over the
unflagged results: ``coverage`` of the reference by +-2 sigma, the z-score ``(value/ref - 1)/sigma``'s
standard deviation (1 = calibrated; below 1 the error bar is too wide) and mean, the median sigma and
its band term's part (``band``), per material the replicas' scatter against the median sigma, and for the
tap methods the median of each of the sigma's parts (``info.uncertainty.parts``: the taps' tau_c, Kg, Kr
and Z1).  ``--out`` keeps the rows, with the band term's bias and the record's step to fc/sqrt(2) less
the model's (``step_diff``: what the band term's test reads).

    PYTHONPATH=. python scripts/sigma_parts.py --draw-seed 21 --replicas 12 --methods vetica vetica-prestress
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from trust import METHODS, answers, condition_overrides, draw_materials, noise_free, noise_seeds  # noqa: E402

from vetica_cli.simulation.config import load  # noqa: E402
from vetica_cli.simulation.simulate import replicas  # noqa: E402


def rows_of(draw: int, index: int, material: dict, n: int, methods) -> list[dict]:
    """One material's replicas: a row per replica, method and quantity."""
    ov = {**condition_overrides("thermal", 0.5e-9, 10), **{f"surface.{k}": v for k, v in material.items()}}
    ref = answers(noise_free(ov), "thermal", methods=methods)
    seeds = noise_seeds(draw, index, "thermal", n)
    out = []
    for r, run in enumerate(replicas(load(None, ov), [int(s) for s in seeds])):
        got = answers(run, "thermal", methods=methods)
        for m in methods:
            res, rm = got[m], ref[m]
            if isinstance(res, str) or isinstance(rm, str):
                continue
            unc = res.info.get("uncertainty") or {}
            band, parts = unc.get("band") or {}, unc.get("parts") or {}
            for q, e in res.estimates.items():
                f = rm.estimates.get(q)
                if e.value is None or e.sigma is None or f is None or f.value is None or not f.value:
                    continue
                out.append({"material": index, "replica": r, "method": m, "quantity": q, "value": e.value,
                            "reference": f.value, "sigma": e.sigma, "flagged": e.identifiable is False,
                            "band_sigma": (band.get("sigma") or {}).get(q, 0.0),
                            "band_bias": (band.get("bias") or {}).get(q, 0.0),
                            "step_diff": (band.get("record_step") or {}).get(q, np.nan)
                            - (band.get("model_step") or {}).get(q, np.nan),
                            **{f"part_{k}": v for k, v in (parts.get(q) or {}).items()}})  # fmt: skip
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--draw-seed", type=int, required=True)
    ap.add_argument("--materials", type=int, default=6)
    ap.add_argument("--replicas", type=int, default=12)
    ap.add_argument("--methods", nargs="*", default=["vetica", "vetica-prestress", "full", "dmt-fit"], choices=METHODS)
    ap.add_argument("--out", default=None, help="also write the rows to this Parquet file")
    a = ap.parse_args(argv)
    rows = []
    for i, mat in enumerate(draw_materials(a.materials, a.draw_seed)):
        rows += rows_of(a.draw_seed, i, mat, a.replicas, a.methods)
        print(f"material {i} {mat}: done", flush=True)
    d = pd.DataFrame(rows)
    if a.out:
        d.to_parquet(a.out)
    d = d[~d.flagged]
    d["dev"] = d.value / d.reference - 1.0
    d["z"] = d.dev / d.sigma
    pcols = [c for c in d.columns if c.startswith("part_")]  # the tap methods' terms (tapsigmas: info "parts")
    print("| method | quantity | results | coverage | std(z) | mean(z) | median sigma | median band part | "
          "scatter / sigma by material |" + "".join(f" median {c[5:]} part |" for c in pcols))  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|" + "---|" * len(pcols))
    for (m, q), g in d.groupby(["method", "quantity"]):
        per = [f"{h.dev.std() / h.sigma.median():.2f}" for _, h in g.groupby("material") if len(h) > 2]
        print(f"| {m} | {q} | {len(g)} | {np.mean(np.abs(g.z) <= 2):.3f} | {g.z.std():.2f} | {g.z.mean():+.2f} | "
              f"{g.sigma.median():.2e} | {g.band_sigma.median():.2e} | {' '.join(per)} |"
              + "".join(f" {g[c].median():.2e} |" for c in pcols))
    if not len(d):
        print("no unflagged results", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
