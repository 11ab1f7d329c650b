"""A point recorded N times with independent noise (``sweep.replicas: N``): what its rows say.

Each replica is extracted as a single point is; the row of the point (per force source)
then carries, for each quantity ``q`` of the surface model (the ``_sigma_pct`` columns):

* ``q``: the median of the replicas' values (``q_err_pct`` its error against the theory);
* ``q_sigma_pct``: the median of the replicas' reported relative 1-sigma;
* ``q_spread_pct``: the replicas' standard deviation relative to the median (what the
  reported sigma claims to be);
* ``q_reference``: the method's answer on the noise-free record made by the same recording
  path (:func:`vetica_cli.simulation.simulate.replica_set`);
* ``q_coverage``: the fraction of the unflagged replicas with a finite sigma whose +-2 sigma
  covers that reference (the claim: ~0.95);
* ``q_flagged``: the fraction of the replicas flagged (``unidentified``) or without a value;

``unidentified`` names the quantities flagged in more than half of the replicas; ``status`` is
the worst of the replicas' (``ok`` < ``no_estimate`` < ``not_steady`` < ``failed``), ``error``
the first replica's error; ``replicas`` the number of replicas.
"""

from __future__ import annotations

import math

import numpy as np

REPLICA_SUFFIXES = ("spread_pct", "reference", "coverage", "flagged")
ORDER = ("ok", "no_estimate", "not_steady", "failed")


def replica_columns(sigmas) -> list[str]:
    """The columns a replicated point adds (after the ``_sigma_pct`` ones)."""
    return [f"{q}_{s}" for q in sigmas for s in REPLICA_SUFFIXES] + ["replicas"]


def replica_meta(sigmas) -> dict:
    """``column -> (unit, description)`` of :func:`replica_columns`."""
    meta = {}
    for q in sigmas:
        meta[f"{q}_spread_pct"] = ("percent", "standard deviation of the replicas' values, relative to their median")
        meta[f"{q}_reference"] = ("", "the method's answer on the point's noise-free record (same recording path), "
                                      "in the quantity's unit")  # fmt: skip
        meta[f"{q}_coverage"] = ("", "fraction of the unflagged replicas whose +-2 sigma covers the noise-free answer")
        meta[f"{q}_flagged"] = ("", "fraction of the replicas flagged or without a value")
    meta["replicas"] = ("", "independent noisy recordings of the point summarised in the row (1 = a single record)")
    return meta


def summarise(rows: list[dict], results: list, reference, sigmas) -> dict:
    """One row from the replicas' ``rows`` (as :func:`vetica_cli.rows.task.fill_row` made them;
    ``results``: their ExtractionResults or None where the extraction raised; ``reference``: the
    noise-free record's result or None)."""
    out = dict(rows[0])
    n = len(rows)
    for key in out:
        if key.endswith("_err_pct") or key.endswith("_sigma_pct") or key == "taps":
            continue
        vals = [r.get(key) for r in rows]
        if all(isinstance(v, float) for v in vals) and not key.endswith("_theory") and key not in ("sim_time", "wall_s"):
            finite = [v for v in vals if math.isfinite(v)]
            out[key] = float(np.median(finite)) if finite else math.nan
    for key in [k for k in out if k.endswith("_err_pct")]:
        q = key[: -len("_err_pct")]
        th = out.get(f"{q}_theory")
        v = out.get(q)
        out[key] = 100.0 * (v - th) / th if th and v is not None and math.isfinite(v) and math.isfinite(th) else math.nan
    for q in sigmas:
        vals = np.array([r.get(q, math.nan) for r in rows], float)
        sig = np.array([r.get(f"{q}_sigma_pct", math.nan) for r in rows], float) / 100.0
        flagged = np.array([q in str(r.get("unidentified", "")).split(",") or not math.isfinite(v)
                            for r, v in zip(rows, vals)])  # fmt: skip
        med = out.get(q, math.nan)
        finite = vals[np.isfinite(vals)]
        out[f"{q}_sigma_pct"] = float(100.0 * np.nanmedian(sig)) if np.any(np.isfinite(sig)) else math.nan
        out[f"{q}_spread_pct"] = float(100.0 * np.std(finite, ddof=1) / abs(med)) if len(finite) > 1 and med else math.nan
        e = reference.estimates.get(q) if reference is not None else None
        ref = float(e.value) if e is not None and e.value is not None else math.nan
        out[f"{q}_reference"] = ref
        ok = ~flagged & np.isfinite(sig) & np.isfinite(vals)
        if math.isfinite(ref) and ok.any():
            covered = np.abs(vals[ok] - ref) <= 2.0 * sig[ok] * np.abs(vals[ok])
            out[f"{q}_coverage"] = float(np.mean(covered))
        else:
            out[f"{q}_coverage"] = math.nan
        out[f"{q}_flagged"] = float(np.mean(flagged))
    counts = {}
    for r in rows:
        for q in str(r.get("unidentified", "")).split(","):
            if q:
                counts[q] = counts.get(q, 0) + 1
    out["unidentified"] = ",".join(q for q in sigmas if counts.get(q, 0) > n / 2)
    out["status"] = max((r.get("status", "failed") for r in rows), key=lambda s: ORDER.index(s) if s in ORDER else 3)
    out["error"] = next((r["error"] for r in rows if r.get("error")), "")
    out["taps"] = int(np.median([r.get("taps", -1) for r in rows]))
    out["wall_s"] = float(sum(r.get("wall_s", 0.0) for r in rows))
    out["replicas"] = n
    return out
