"""``vetica fit``: many curves in, one tidy table and figures out.

One row per curve and arm count (``model`` leeradok, ``arms`` 1..3), the moduli ``e_inf``,
``e_1``... [Pa], relaxation times ``tau_1 < tau_2 < ...`` [s], their standard errors
``se_*``, the contact height, AIC/BIC, ``selected`` (the lowest criterion per curve) and
``status``/``error`` (a curve that cannot be fitted is a row with status error, the others
still run).  The units and the inputs (tip radius, Poisson ratio, height channel, criterion)
are in the Parquet metadata as every vetica table has them.  The curves run in parallel on the
study launchers (one loky worker per job), with the study progress bar.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import InputError
from ..io import check_output_dir, check_output_file, write_table
from ..batch.launch import make_launcher
from ..batch.progress import Progress
from .fit import ARM_COUNTS, CRITERIA, WINDOWS, CurveError, fit_curve
from .read import HEIGHTS, read_curves

UNITS = {"contact": "m", "se_contact": "m", "e_inf": "Pa", "se_e_inf": "Pa", "e_0": "Pa",
         "indentation_max": "m", "force_max": "N", "residual_rms": "N", "rss": "N^2",
         "tip_radius": "m", "spring_constant": "N/m", "position_x": "m", "position_y": "m"}  # fmt: skip
for _k in range(1, max(ARM_COUNTS) + 1):
    UNITS.update({f"e_{_k}": "Pa", f"se_e_{_k}": "Pa", f"tau_{_k}": "s", f"se_tau_{_k}": "s"})
TRACE_POINTS = 1500  # samples kept per curve for the figures


def check_options(tip_radius, nu: float, height: str, criterion: str, window: str) -> None:
    """InputError (one line) for a missing or bad option, before any file is read."""
    if tip_radius is None:
        raise InputError("--tip-radius is required: the radius R [m] of the spherical tip (e.g. --tip-radius 5e-6)")
    if not (np.isfinite(tip_radius) and tip_radius > 0):
        raise InputError(f"--tip-radius {tip_radius!r} is not allowed; expected a radius > 0 in m")
    if not (np.isfinite(nu) and -1.0 < nu <= 0.5):
        raise InputError(f"--nu {nu!r} is not allowed; expected a Poisson ratio in (-1, 0.5]")
    if height not in HEIGHTS:
        raise InputError(f"--height {height!r} is not allowed; expected one of {', '.join(HEIGHTS)}")
    if criterion not in CRITERIA:
        raise InputError(f"--criterion {criterion!r} is not allowed; expected one of {', '.join(CRITERIA)}")
    if window not in WINDOWS:
        raise InputError(f"--window {window!r} is not allowed; expected one of {', '.join(WINDOWS)}")


def fit_job(job: dict):
    """One curve (module level: loky pickles it): ``(rows, traces)``; a CurveError becomes rows
    with status error."""
    curve = job["curve"]
    base = {"file": Path(curve.source).name, "curve": curve.index, "modality": curve.modality,
            "height_channel": curve.height_channel, "spring_constant": curve.spring_constant,
            "position_x": curve.meta.get("position x", np.nan), "position_y": curve.meta.get("position y", np.nan),
            "grid_x": curve.meta.get("grid index x", -1), "grid_y": curve.meta.get("grid index y", -1)}  # fmt: skip
    try:
        rows, traces = fit_curve(curve, job["tip_radius"], job["nu"], criterion=job["criterion"], window=job["window"],
                                 with_traces=True)  # fmt: skip
    except (CurveError, np.linalg.LinAlgError, FloatingPointError, ValueError) as exc:
        err = " ".join(str(exc).split())
        return [{**base, "model": "leeradok", "arms": n, "status": "error", "error": err, "selected": False}
                for n in ARM_COUNTS], None  # fmt: skip
    step = max(1, traces["t"].size // TRACE_POINTS)
    small = {k: np.asarray(v)[::step] for k, v in traces.items()}
    return [{**base, **r, "status": "ok", "error": ""} for r in rows], small


def fit_files(paths, tip_radius, output: str | Path = "fit.parquet", figures: str | Path | None = None,
              nu: float = 0.5, height: str = "measured", criterion: str = "bic", window: str = "dwell",
              jobs: int = 2, progress: bool = True):  # fmt: skip
    """Fit every curve of ``paths`` (files or folders) and write the table (and figures).

    Everything the user gives is checked before work starts (options, output paths, every
    file's modality and dwell): a problem is one InputError and nothing is written."""
    import pandas as pd

    check_options(tip_radius, nu, height, criterion, window)
    out = check_output_file(output)
    fig_dir = check_output_dir(figures, "--figures") if figures is not None else None
    curves = read_curves(paths, height)
    jobs_list = [{"curve": c, "tip_radius": float(tip_radius), "nu": float(nu), "criterion": criterion, "window": window}
                 for c in curves]  # fmt: skip
    results: list = [None] * len(jobs_list)
    failed = 0
    with make_launcher("loky", min(jobs, max(len(jobs_list), 1))) as launcher, \
            Progress(len(jobs_list), 0, 0, enabled=progress, name="fit", unit="curves") as bar:  # fmt: skip

        def done(i, res):
            nonlocal failed
            results[i] = res
            failed += res[1] is None
            bar.advance(1, failed)

        launcher.launch(fit_job, jobs_list, done)
    rows = [r for res in results for r in res[0]]
    df = pd.DataFrame(rows)
    first = ["file", "curve", "modality", "model", "arms", "selected", "status", "error"]
    df = df[first + [c for c in df.columns if c not in first]]
    df["tip_radius"], df["nu"] = float(tip_radius), float(nu)
    meta = {"kind": "force-curve fit", "version": __version__, "units": {k: v for k, v in UNITS.items() if k in df},
            "params": {"tip_radius": tip_radius, "nu": nu, "height": height, "criterion": criterion, "window": window,
                       "model": "Lee-Radok sphere on E(t) = e_inf + sum e_i exp(-t/tau_i)"}}  # fmt: skip
    write_table(df, out, meta)
    if fig_dir is not None:
        from .figures import write_figures

        write_figures(df, [(c.name, r[1]) for c, r in zip(curves, results)], fig_dir)
    return df
