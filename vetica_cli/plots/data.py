"""The rows of a sweep table the study figures draw (:class:`SweepData`), the swept keys
that make their axes, and the shared notes and titles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from .. import surfaces
from ..extraction import DEFAULT_METHOD, SOURCES
from .style import CD, F1, K2, PS, RATIO, SETPOINT, group_label, quantities

AXIS_PRIORITY = [CD, RATIO, SETPOINT, F1, PS, K2]


def _find_sweep_block(meta, depth: int = 0):
    """The resolved 'sweep' mapping anywhere in the first levels of the metadata (None if absent)."""
    if not isinstance(meta, dict) or depth > 3:
        return None
    if isinstance(meta.get("sweep"), dict):
        return meta["sweep"]
    for v in meta.values():
        found = _find_sweep_block(v, depth + 1)
        if found is not None:
            return found
    return None


def _names_in(block) -> set:
    """Every dotted name mentioned as a key in a sweep block (zip groups included)."""
    out = set()
    if isinstance(block, dict):
        for k, v in block.items():
            if isinstance(k, str) and "." in k:
                out.add(k)
            out |= _names_in(v)
    elif isinstance(block, list):
        for v in block:
            out |= _names_in(v)
    return out


def base_config(meta) -> dict | None:
    """The study's fixed parameters (a dict with probe/operation/surface/numerics sections), if recorded."""
    for cand in (meta, meta.get("config"), meta.get("params"), meta.get("base")):
        if isinstance(cand, dict) and isinstance(cand.get("surface"), dict) and isinstance(cand.get("probe"), dict):
            return cand
    return None


def swept_keys(df: pd.DataFrame, meta: dict) -> list[str]:
    """The varied keys, most important first.

    A key counts when it is a dotted column with more than one distinct
    value, and (when the metadata records a 'sweep' block) is named there.
    Keys that vary in lockstep with a more important one (a ``zip`` group,
    ``f2 = 15 f1``, ``k0`` beside ``stiffness_ratio``) are dropped: they add no
    axis.
    """
    block = _find_sweep_block(meta)
    named = _names_in(block) if block is not None else None
    cand = [c for c in df.columns if "." in c and df[c].nunique(dropna=True) > 1]
    if named:
        cand = [c for c in cand if c in named] or cand
    rank = {k: i for i, k in enumerate(AXIS_PRIORITY)}
    cand.sort(key=lambda c: (rank.get(c, len(rank)), c))
    keep: list[str] = []
    for c in cand:
        if not any(_lockstep(df, c, k) for k in keep):
            keep.append(c)
    return keep


def _lockstep(df: pd.DataFrame, a: str, b: str) -> bool:
    pairs = df[[a, b]].dropna().drop_duplicates()
    return pairs[a].nunique() == len(pairs) == pairs[b].nunique()


@dataclass
class SweepData:
    """The rows of a sweep table the figures draw, with the error columns as magnitudes
    (tables store signed errors; the figures' error axes are logarithmic)."""

    df: pd.DataFrame  # all rows
    swept: list
    base: dict | None
    method: str = DEFAULT_METHOD  # extraction method of the rows (titles name it)

    def __post_init__(self):
        errs = [c for c in self.df.columns if c.endswith("_err_pct")]
        if errs:
            self.df = self.df.assign(**{c: self.df[c].abs() for c in errs})

    @property
    def model(self) -> str:
        """The surface model of the study (its base config's; the default otherwise)."""
        su = (self.base or {}).get("surface") or {}
        return su.get("model", surfaces.DEFAULT_MODEL)

    @property
    def quantities(self) -> dict:
        return quantities(self.model)

    @property
    def others(self) -> list:
        return [k for k in self.swept if k != CD]

    def sources(self) -> list:
        present = set(self.df["force_source"].astype(str))
        return [s for s in SOURCES if s in present]

    def rows(self, source: str) -> pd.DataFrame:
        return self.df[self.df["force_source"].astype(str) == source]

    def points(self) -> pd.DataFrame:
        """One row per point (observables do not depend on the force source)."""
        d = self.df.copy()
        d["_rank"] = d["force_source"].astype(str).map({"true": 0, "reconstructed": 1}).fillna(2)
        return d.sort_values("_rank").drop_duplicates(subset=self.swept, keep="first").drop(columns="_rank")


def groups_of(d: pd.DataFrame, keys: list):
    """[(label, values, sub-frame)] over the distinct combinations of ``keys`` (one group if none)."""
    if not keys:
        return [("", (), d)]
    out = []
    for vals, sub in d.groupby(keys, sort=True):
        vals = vals if isinstance(vals, tuple) else (vals,)
        out.append((group_label(keys, vals), vals, sub))
    return out


def statuses(d: pd.DataFrame) -> np.ndarray:
    return d["status"].astype(str).to_numpy()


def status_note(
    d: pd.DataFrame, swept: list, extra: str = "", regime: bool = False, marked: bool = True, estimates: bool = True
) -> str:
    """The figure's note on excluded and marked points.  ``estimates=False`` for figures of the
    run's observables (E_diss, depths, times), which every steady point has whether or not the
    extraction gave an estimate: they do not mention the ``no_estimate`` points."""
    pts = d.drop_duplicates(subset=swept + ["status"])
    n_f = int((pts["status"].astype(str) == "failed").sum())
    n_ns = int((pts["status"].astype(str) == "not_steady").sum())
    n_ne = int((pts["status"].astype(str) == "no_estimate").sum())
    parts = []
    if n_f:
        parts.append(f"{n_f} failed point(s) excluded")
    if n_ne and estimates:
        parts.append(f"{n_ne} steady point(s) without an estimate (reason in the table's error column)")
    if n_ns and marked:
        parts.append(
            f"{n_ns} not-steady point(s) marked with a grey cross"
            + (" and left out of the acceptance regime" if regime else "")
        )
    elif n_ns:
        parts.append(f"{n_ns} not-steady point(s) left out")
    if extra:
        parts.append(extra)
    return "; ".join(parts)


def _fixed_line(sw: SweepData) -> str:
    """The study's fixed parameters (the keys not swept), for the title; derived keys
    (``stiffness_ratio``, ``f2_ratio``) as the study config states them."""
    b = sw.base
    if not b:
        return ""
    s = set(sw.swept)
    pr, op, su, nu = (b.get(k, {}) or {} for k in ("probe", "operation", "surface", "numerics"))
    items = []

    def num(d, k):
        v = d.get(k)
        return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None

    f1, f2, f2r = num(pr, "f1"), num(pr, "f2"), num(pr, "f2_ratio")
    if F1 not in s and f1:
        items.append(f"$f_1$ {f1 * 1e-3:g} kHz")
    if f2r:
        items.append(f"$f_2$ = {f2r:g} $f_1$")
    elif F1 not in s and "probe.f2" not in s and f2:
        items.append(f"$f_2$ {f2 * 1e-3:g} kHz")
    for key, d, name, unit, scale in (
        ("probe.k1", pr, "$k_1$", "N/m", 1.0),
        (K2, pr, "$k_2$", "N/m", 1.0),
        (SETPOINT, op, "set point", "%", 100.0),
    ):
        v = num(d, key.split(".")[1])
        if key not in s and v is not None:
            items.append(f"{name} {v * scale:g} {unit}")
    items += surfaces.get(sw.model).study_title_items(su, s)
    for key, d, name, unit, scale in ((PS, nu, "PS", "ns", 1e9), ("numerics.dt", nu, "dt", "ns", 1e9)):
        v = num(d, key.split(".")[1])
        if key not in s and v is not None:
            items.append(f"{name} {v * scale:g} {unit}")
    return ("fixed: " + ", ".join(items)) if items else ""


def set_title(fig: Figure, sw: SweepData, text: str) -> None:
    """The figure's title (naming the extraction method when it is not VETICA) and the fixed parameters."""
    if sw.method != DEFAULT_METHOD:
        text = text.replace("VETICA", f"{sw.method} extraction")
    fixed = _fixed_line(sw)
    fig.suptitle(text + ("\n" + fixed if fixed else ""), fontsize=10.5)
