"""The acceptance regime (thesis fig. 52): the range of the dashpot ``cd`` whose points
have status 'ok' (a steady record with every quantity estimated) and a ``tau_c`` error of
magnitude below 30 %; points with status 'no_estimate', 'not_steady' or 'failed' are
counted, never accepted.  The quantity and the swept parameter are the surface model's
declaration (:attr:`vetica_cli.surfaces.SurfaceModel.acceptance`: the SLS's ``(tau_c, cd)``);
a model that declares none has no regime.

One definition for ``vetica sweep`` (printed, and stored in the table's metadata),
``vetica plot`` (shaded regions, interval bars, the 30 % contour) and the scripts.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .. import surfaces
from ..rows.schema import ACCEPT_ERR_PCT  # [%] tau_c error below which a point is accepted (thesis fig. 52)

if TYPE_CHECKING:  # the tables are pandas frames; a dry run starts without pandas
    import pandas as pd


def acceptance_keys(model=None) -> tuple[str, str, str] | None:
    """``(swept key, error column, the key's unit)`` of the acceptance regime that ``model``
    (default: the default model, the thesis's SLS) declares; None when it declares none."""
    m = model if model is not None else surfaces.get(surfaces.DEFAULT_MODEL)
    if m.acceptance is None:
        return None
    quantity, parameter = m.acceptance
    return f"surface.{parameter}", f"{quantity}_err_pct", m.parameter_units.get(parameter, "")


CD_KEY, ERR_COL, _ = acceptance_keys()  # the default model's: the swept key the regime is a range of, the error that decides


def accepted(d: pd.DataFrame, err_col: str = ERR_COL) -> pd.Series:
    """Rows accepted: status 'ok' and ``|err_col| < ACCEPT_ERR_PCT`` (signed or unsigned errors)."""
    return (d["status"].astype(str) == "ok") & (d[err_col].abs() < ACCEPT_ERR_PCT)


@dataclass
class Regime:
    """Acceptance regime of one force source at one setting of the other keys."""

    lo: float  # lowest accepted cd [kg/s]
    hi: float  # highest accepted cd [kg/s]
    accepted: np.ndarray  # every accepted cd
    contiguous: bool  # the accepted points are one unbroken run of the cd grid

    @property
    def decades(self) -> float:
        return float(np.log10(self.hi / self.lo))


def regime(d: pd.DataFrame, err_col: str = ERR_COL, cd_key: str = CD_KEY) -> Regime | None:
    """The range of cd whose points are :func:`accepted`: lowest to highest accepted cd, and
    whether the accepted points are one unbroken run of the cd grid (a not-steady, failed
    or inaccurate point in between breaks it).  None when no point is accepted."""
    grid = np.sort(d[cd_key].to_numpy(float))
    acc = np.sort(d.loc[accepted(d, err_col), cd_key].to_numpy(float))
    if not len(acc):
        return None
    i0 = int(np.searchsorted(grid, acc[0]))
    contiguous = bool(np.array_equal(grid[i0 : i0 + len(acc)], acc))
    return Regime(float(acc[0]), float(acc[-1]), acc, contiguous)


_FIELDS = ("n_points", "n_accepted", "n_no_estimate", "n_not_steady", "n_failed", "cd_min", "cd_max", "decades", "contiguous")


def acceptance_regime(table: pd.DataFrame, keys, cd_key: str | None = None, err_col: str | None = None,
                      model=None) -> list[dict]:  # fmt: skip
    """:func:`regime` for every combination of the other swept keys (the extraction method
    is the 'method' column) and each force source, with point counts.  The swept key and the
    error column default to ``model``'s declaration (:func:`acceptance_keys`)."""
    declared = acceptance_keys(model)
    if declared is None and (cd_key is None or err_col is None):
        return []
    cd_key = cd_key or declared[0]
    err_col = err_col or declared[1]
    if cd_key not in keys:
        return []
    # extraction keys are columns of their own: extract.method -> 'method', extract.force -> 'force_source'
    others = ["method" if k == "extract.method" else k for k in keys if k != cd_key and k != "extract.force"]
    if "method" not in others and "method" in table.columns and table["method"].nunique() > 1:
        others.append("method")
    out = []
    group_cols = [*others, "force_source"]
    for combo, g in table.groupby(group_cols, sort=False, dropna=False):
        combo = combo if isinstance(combo, tuple) else (combo,)
        r = regime(g, err_col, cd_key)
        entry = {k: _plain(v) for k, v in zip(group_cols, combo)}
        entry.update(
            n_points=len(g),
            n_accepted=len(r.accepted) if r else 0,
            n_no_estimate=int((g["status"] == "no_estimate").sum()),
            n_not_steady=int((g["status"] == "not_steady").sum()),
            n_failed=int((g["status"] == "failed").sum()),
            cd_min=r.lo if r else None,
            cd_max=r.hi if r else None,
            decades=r.decades if r else None,
            contiguous=r.contiguous if r else False,
        )
        out.append(entry)
    return out


def _plain(v):
    if isinstance(v, (np.floating,)):
        return float(v)
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, np.bool_):
        return bool(v)
    return v


def format_acceptance(acc: list[dict], keys, model=None) -> str:
    """Human-readable acceptance regime, one line per combination and force source."""
    declared = acceptance_keys(model)
    if declared is None:
        return f"acceptance regime: the surface model {model.key} declares none"
    key, err_col, unit = declared
    name = key.split(".", 1)[1]
    if key not in keys:
        return f"acceptance regime: {key} is not swept, so there is no {name} range to report"
    lines = [f"acceptance regime (status ok and {err_col.removesuffix('_err_pct')} error < {ACCEPT_ERR_PCT:g} %):"]
    for e in acc:
        where = ", ".join(f"{k}={_g(v)}" for k, v in e.items() if k not in _FIELDS and k != "force_source")
        head = f"  {where + ', ' if where else ''}{e['force_source']} force: "
        if e["n_accepted"] == 0:
            body = "none"
        else:
            body = f"{name} {e['cd_min']:.3g} .. {e['cd_max']:.3g} {unit} ({e['decades']:.2f} decades)"
            if not e["contiguous"]:
                body += ", with gaps"
        extra = f"{e['n_accepted']}/{e['n_points']} points"
        if e.get("n_no_estimate"):
            extra += f", {e['n_no_estimate']} without an estimate"
        if e["n_not_steady"]:
            extra += f", {e['n_not_steady']} not steady"
        if e["n_failed"]:
            extra += f", {e['n_failed']} failed"
        lines.append(f"{head}{body} [{extra}]")
    return "\n".join(lines)


def _g(v):
    return f"{v:g}" if isinstance(v, float) else str(v)
