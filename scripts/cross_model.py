"""Cross-model study: every extraction method on records of every surface model
(results/cross_model/README.md states the records, the claims and their stated equivalents).

    python scripts/cross_model.py configs/cross_model.yaml [-o results/cross_model] [-j 2]

One simulation per (model, tau f1); every method on its record with the surface's parameters
stripped from the metadata (as an instrument has it) and the stated inputs of the config.
Writes table.csv, table.md and errors.png.
"""

from __future__ import annotations

import argparse
import copy
import math
import time
from pathlib import Path

import numpy as np
import yaml

QUANTITIES = ("tau", "glassy", "relaxed")


def surface_section(spec: dict, tau: float) -> dict:
    """The model's surface section with the fastest arm's relaxation time ``tau`` [s]."""
    s = copy.deepcopy(spec["surface"])
    ratios = spec.get("tau_ratio", [1.0])
    if s["model"] == "sls":
        s["cd"] = tau * s["k0"]
    elif s["model"] == "wiechert":
        for arm, r in zip(s["arms"], ratios):
            arm["cd"] = tau * r * arm["k"]
    else:
        for arm, r in zip(s["arms"], ratios):
            arm["tau"] = tau * r
    return s


def truths(model: str, surface: dict, obs: dict, radius: float) -> dict:
    """Per claim the truth (own model) or the stated equivalent (README), for linear and hertz claims."""
    lin, hz = {}, {}
    if model == "sls":
        lin = {"tau": surface["cd"] / surface["k0"], "glassy": surface["k0"] + surface["k_inf"], "relaxed": surface["k_inf"]}
        hz = {"tau": lin["tau"]}
    elif model == "wiechert":
        a = surface["arms"]
        lin = {"tau": a[0]["cd"] / a[0]["k"], "glassy": surface["k_inf"] + sum(x["k"] for x in a),
               "relaxed": surface["k_inf"]}  # fmt: skip
        hz = {"tau": lin["tau"]}
    else:
        s = 1.0 - surface["nu"] ** 2
        e_g = surface["e_inf"] + sum(x["e"] for x in surface["arms"])
        d = obs["max_penetration"]
        root = math.sqrt(radius * d)
        lin = {"tau": surface["arms"][0]["tau"], "glassy": 4.0 / 3.0 * e_g / s * root,
               "relaxed": 4.0 / 3.0 * surface["e_inf"] / s * root}  # fmt: skip
        hz = {"tau": surface["arms"][0]["tau"], "glassy": e_g, "relaxed": surface["e_inf"]}
    return {"linear": lin, "hertz": hz}


def claim_names(method: str, res) -> dict:
    """The estimate behind each claim, by claim name."""
    if method == "full hertz":
        return {"tau": "tau_1", "glassy": "e_g", "relaxed": "e_inf"}
    tau = "tau_r" if res.estimates.get("tau_r") is not None else "tau_1"
    return {"tau": tau, "glassy": "k_g", "relaxed": "k_r" if res.estimates.get("k_r") else "k_inf"}


def claims(method: str, res) -> dict:
    """What a method's result claims, by claim name."""
    return {q: res.value(n) for q, n in claim_names(method, res).items()}


def flagged(method: str, res) -> dict:
    """Whether the method flags each claim's estimate (``unidentified``, the sanity checks)."""
    return {q: res.estimates[n].identifiable is False if n in res.estimates else False
            for q, n in claim_names(method, res).items()}  # fmt: skip


def point(model: str, spec: dict, tau_f1: float, cfg: dict) -> list[dict]:
    from vetica_cli.extraction import extract
    from vetica_cli.simulation.config import from_dict
    from vetica_cli.simulation.simulate import simulate

    base = copy.deepcopy(cfg.get("base") or {})
    d = {k: dict(v) for k, v in base.items()}
    f1 = 50e3
    tau = tau_f1 / f1
    d["surface"] = {**d.get("surface", {}), **surface_section(spec, tau)}
    c = from_dict(d)
    f1 = c.probe.f1
    t0 = time.perf_counter()
    run = simulate(c)
    sim_s = time.perf_counter() - t0
    df, meta = run.frame(), run.metadata()
    stated = cfg["stated"]
    meta_s = copy.deepcopy(meta)
    meta_s["params"]["surface"] = {k: meta["params"]["surface"][k] for k in ("hamaker", "a0", "vdw_on_surface")}
    arms = spec["arms"]
    methods = {
        "vetica": ("vetica", {}),
        "vetica-prestress": ("vetica-prestress", {}),
        "full linear": ("full", {"fit_model": "sls" if arms == 1 else "wiechert", "arms": arms,
                                 "hamaker": stated["hamaker"], "tip_radius": stated["tip_radius"]}),
        "full hertz": ("full", {"fit_model": "hertz", "arms": arms, "hamaker": stated["hamaker"],
                                "tip_radius": stated["tip_radius"], "nu": stated["nu"]}),
    }  # fmt: skip
    tr = truths(model, c.surface.to_dict(), run.observables, c.probe.tip_radius)  # parsed: floats
    rows = []
    for name, (key, opts) in methods.items():
        t1 = time.perf_counter()
        status, msg, cl, fl = "ok", "", {}, {}
        try:
            res = extract(df, meta_s, force=cfg.get("force", "reconstructed"), method=key, a0=stated["a0"],
                          vdw_on_surface=stated["vdw_on_surface"], **opts)  # fmt: skip
            cl, fl = claims(name, res), flagged(name, res)
            if res.warnings:
                msg = res.warnings[0][:200]
        except Exception as exc:  # noqa: BLE001  (a method's failure is a result of the study)
            status, msg = "failed", f"{type(exc).__name__}: {str(exc)[:200]}"
        truth = tr["hertz" if name == "full hertz" else "linear"]
        for q in QUANTITIES:
            val, th = cl.get(q), truth.get(q)
            err = 100.0 * (val - th) / th if (val is not None and th is not None) else math.nan
            rows.append({"model": model, "tau_f1": tau_f1, "tau_s": tau, "method": name, "claim": q,
                         "value": math.nan if val is None else float(val),
                         "truth": math.nan if th is None else float(th),
                         "error_pct": err, "status": status if val is not None or status != "ok" else "no_estimate",
                         "unidentified": bool(fl.get(q, False)),
                         "steady": run.stop_reason, "message": msg, "sim_s": sim_s,
                         "extract_s": time.perf_counter() - t1})  # fmt: skip
    return rows


def figure(df, path: Path, models: list[str], methods: list[str]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(QUANTITIES), len(models), figsize=(3.2 * len(models), 2.6 * len(QUANTITIES)),
                             sharex=True, squeeze=False)  # fmt: skip
    labels = {"tau": "relaxation time", "glassy": "glassy stiffness/modulus", "relaxed": "relaxed stiffness/modulus"}
    for j, model in enumerate(models):
        for i, q in enumerate(QUANTITIES):
            ax = axes[i][j]
            for m, mk in zip(methods, "os^D"):
                sub = df[(df.model == model) & (df.method == m) & (df.claim == q)].sort_values("tau_f1")
                err = np.abs(sub.error_pct.to_numpy())
                if np.isfinite(err).any():
                    ax.loglog(sub.tau_f1, np.maximum(err, 1e-3), marker=mk, ms=4, label=m)
            ax.axhline(30, color="0.6", lw=0.8, ls="--")
            ax.axhline(1, color="0.8", lw=0.8, ls=":")
            if i == 0:
                ax.set_title(model)
            if j == 0:
                ax.set_ylabel(f"|error| % ({labels[q]})", fontsize=8)
            if i == len(QUANTITIES) - 1:
                ax.set_xlabel(r"$\tau f_1$")
    axes[0][0].legend(fontsize=7)
    fig.suptitle("cross-model study: |error| of each method's claim (reconstructed force); dashed 30 %, dotted 1 %",
                 fontsize=9)  # fmt: skip
    fig.tight_layout()
    fig.savefig(path, dpi=130)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("config")
    ap.add_argument("-o", "--output", default="results/cross_model")
    ap.add_argument("-j", "--jobs", type=int, default=None)
    a = ap.parse_args()
    cfg = yaml.safe_load(Path(a.config).read_text())
    out = Path(a.output)
    out.mkdir(parents=True, exist_ok=True)
    from joblib import Parallel, delayed

    tasks = [(m, spec, float(x)) for m, spec in cfg["models"].items() for x in cfg["tau_f1"]]
    t0 = time.perf_counter()
    parts = Parallel(n_jobs=a.jobs or cfg.get("jobs", 1), verbose=5)(delayed(point)(m, s, x, cfg) for m, s, x in tasks)
    import pandas as pd

    df = pd.DataFrame([r for p in parts for r in p])
    df.to_csv(out / "table.csv", index=False)
    methods = list(dict.fromkeys(df.method))
    models = list(cfg["models"])
    lines = [f"# cross-model errors (% of truth or stated equivalent; {time.perf_counter() - t0:.0f} s wall; "
             "u = the method flags it unidentified)", ""]
    for q in QUANTITIES:
        lines += [f"## {q}", "", "| model | tau f1 | " + " | ".join(methods) + " |",
                  "|---|---|" + "---|" * len(methods)]  # fmt: skip
        for model in models:
            for x in cfg["tau_f1"]:
                cells = []
                for m in methods:
                    r = df[(df.model == model) & (df.tau_f1 == x) & (df.method == m) & (df.claim == q)]
                    e = float(r.error_pct.iloc[0]) if len(r) else math.nan
                    if len(r) and not math.isfinite(float(r.truth.iloc[0])):
                        cells.append("n/a")  # no truth or stated equivalent for this claim (README)
                    else:
                        mark = " u" if len(r) and bool(r.unidentified.iloc[0]) else ""
                        cells.append(f"{e:+.3g}{mark}" if math.isfinite(e) else (str(r.status.iloc[0]) if len(r) else "-"))
                lines.append(f"| {model} | {x:g} | " + " | ".join(cells) + " |")
        lines.append("")
    (out / "table.md").write_text("\n".join(lines))
    figure(df, out / "errors.png", models, methods)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
