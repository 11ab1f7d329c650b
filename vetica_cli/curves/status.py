"""Honest fit rows: the one place that says whether a fitted row of ``vetica fit`` is sound.

A row's ``status`` is ``ok`` only when the fit converged, every relaxation time lies within
the fitted window, and every fitted parameter is larger than its standard error; otherwise it
is the first failing reason of :data:`FLAGS` and ``error`` says which parameter and by how
much.  ``selected`` (the lowest information criterion per curve) never picks a flagged row
while a row with status ``ok`` exists for the curve; a curve with only flagged rows selects
its best flagged row, which keeps its status.

Rows that carry no fit (a file that cannot be read, a curve that does not suit the fit, a
fit that raised) have the statuses of :data:`NO_FIT`.
"""

from __future__ import annotations

import math

FLAGS = {
    "not_converged": "the optimizer stopped before converging (iteration limit, or a parameter at its bound)",
    "tau_beyond_window": "a relaxation time is longer than the fitted window: it stands for 'slower than the record'",
    "se_exceeds_value": "a parameter's standard error is larger than its value: the data do not determine it",
}
NO_FIT = {
    "failed": "the curve was read and suits the fit, but the fit could not be made (error says why)",
    "unsuited": "the curve was read but does not suit the fit (another modality, no contact, no time axis...)",
    "unreadable": "the file could not be read (error says why)",
}
STATUSES = ("ok", *FLAGS, *NO_FIT)
STATUS_TEXT = "ok (sound fit) | " + " | ".join(f"{k} ({v})" for k, v in {**FLAGS, **NO_FIT}.items())
# parameters whose standard error is checked, by prefix (the contact height is not a modulus)
CHECKED = ("e_inf", "e0", "beta", "e_")


def _fitted_params(row: dict) -> list[str]:
    out = []
    for k, v in row.items():
        if k.startswith("se_") or not isinstance(v, (int, float)) or isinstance(v, bool):
            continue
        if k in ("e_hertz", "e_0") or not (k.startswith(CHECKED) or k.startswith("tau_")):
            continue
        if f"se_{k}" in row and math.isfinite(v):
            out.append(k)
    return out


def judge(row: dict, window_s: float) -> tuple[str, str]:
    """``(status, reason)`` of a fitted row (module docstring); ``window_s`` [s] the time span
    the fit's residuals cover."""
    if not row.get("converged", True):
        return "not_converged", "the fit stopped at the iteration limit"
    if row.get("at_bound"):
        return "not_converged", f"{row['at_bound']} at the bound of its fit range: the data do not determine it"
    long = [k for k in row if k.startswith("tau_") and isinstance(row[k], float) and row[k] > window_s]
    if long:
        k = max(long, key=lambda q: row[q])
        return "tau_beyond_window", f"{k} = {row[k]:.3g} s is {row[k] / window_s:.3g} x the fitted window ({window_s:.3g} s)"
    loose = []
    for k in _fitted_params(row):
        se, v = row[f"se_{k}"], row[k]
        if not math.isfinite(se) or se > abs(v):
            loose.append((se / abs(v) if v else math.inf, k))
    if loose:
        ratio, k = max(loose)
        return "se_exceeds_value", f"{k} = {row[k]:.3g} +- {row[f'se_{k}']:.3g} (standard error {ratio:.2g} x the value)"
    return "ok", ""


def select(rows: list[dict], criterion: str) -> None:
    """Set ``selected`` on the rows of one curve (in place): the lowest ``criterion`` among the
    rows with status ``ok``, else among the fitted rows; ``d_<criterion>`` against the selected."""
    fitted = [r for r in rows if r.get("status") not in NO_FIT and math.isfinite(r.get(criterion, math.nan))]
    pool = [r for r in fitted if r["status"] == "ok"] or fitted
    best = min(pool, key=lambda r: r[criterion]) if pool else None
    for r in rows:
        r["selected"] = r is best
        if best is not None and r in fitted:
            r["d_" + criterion] = r[criterion] - best[criterion]
