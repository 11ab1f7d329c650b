"""``vetica fit``: many files in, one tidy table and figures out.

Every file given is read or refused in one line (:func:`.read.read_inputs`).  Each curve is a
job of the batch machinery (:func:`vetica_cli.batch.run.run_batch`: parts persisted as they
finish, a rerun fits only the missing curves, Ctrl-C/SIGTERM/SIGHUP stop the workers with one
line), fitted by the model its modality calls for:

* a **force-distance** curve (approach and retract): Ting's viscoelastic Hertz contact with a
  power-law modulus (``--modulus power-law``: ``e0`` [Pa], ``beta``; one row) or generalized
  Maxwell arms (``--modulus maxwell``: ``e_inf``, ``e_i`` [Pa], ``tau_i`` [s]; one row per arm
  count), the approach's elastic Hertz modulus ``e_hertz`` beside it (:mod:`.fd`);
* a **dwell** curve (stress relaxation, creep): Lee–Radok with 1–3 Maxwell arms (:mod:`.fit`).

Each row is judged (:mod:`.status`: ``ok``, or why not) and ``selected`` marks the lowest
criterion among the sound rows of a curve.  A file that cannot be read or holds no curve to fit
is a row with status ``unreadable`` or ``unsuited`` and ``error``; the rest go on.  Rows carry
the file's ``label`` (the shortest tail of its path that tells it apart from the others), the
path, the curve index, the modality and the force map's grid indices.  The units and
descriptions of every column and the inputs are in the Parquet metadata.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import __version__
from ..batch.launch import jobs_warning
from ..batch.parts import code_fingerprint
from ..batch.run import Bar, Job, check_batch_output, run_batch, signals_as_interrupt
from ..checks import LIMITS, within
from ..errors import InputError
from ..io import check_output_dir, write_table
from .fd import DEFAULT_POINTS, MAX_POINTS, MAXWELL_ARMS, MIN_POINTS, MODULI, fit_fd_curve
from .fit import ARM_COUNTS, CRITERIA, WINDOWS, CurveError, NoContact, fit_curve
from .read import DWELL, HEIGHTS, parse_meta, read_inputs
from .status import STATUS_TEXT, judge, select

FIT_ROOTS = ("curves/batch.py",)  # the modules whose import closure computes a curve's rows (the parts' fingerprint)
SERIAL_BELOW_S = 8.0  # [s] a batch estimated under this many core-seconds runs in this process (as a sweep does)
SECONDS_PER_CURVE = {"power-law": 0.02, "maxwell": 0.5, "dwell": 3.0}  # [CPU s] the estimate that decides it
MAX_ARMS = max(max(ARM_COUNTS), max(MAXWELL_ARMS))

COLUMNS = {  # column -> (unit, description); units in the Parquet metadata ('' = dimensionless or text)
    "file": ("", "the file: the shortest tail of its path that tells it apart from the other files of the batch"),
    "path": ("", "the file's path as given (or found in a folder given)"),
    "curve": ("", "index of the curve in its file (-1: the file as a whole)"),
    "modality": ("", "force-distance | stress-relaxation | creep-compliance"),
    "model": ("", "ting (force-distance: Ting's viscoelastic Hertz contact through loading and unloading) | "
              "leeradok (dwell curves: Lee-Radok, approach and dwell)"),
    "modulus": ("", "power-law (E(t) = e0 (t/t0)^-beta, t0 = 1 s) | maxwell (E(t) = e_inf + sum e_i exp(-t/tau_i))"),
    "arms": ("", "Maxwell arms of the modulus (0 for the power law)"),
    "selected": ("", "the row of its curve with the lowest criterion among the rows with status ok (among the "
                 "fitted rows when none is ok)"),
    "status": ("", STATUS_TEXT),
    "error": ("", "why the status is not ok (empty when it is)"),
    "e0": ("Pa", "power-law modulus at t0 = 1 s"),
    "beta": ("", "power-law exponent (0 elastic, 1 fluid)"),
    "e_inf": ("Pa", "equilibrium (long-time) Young's modulus"),
    "e_0": ("Pa", "instantaneous Young's modulus e_inf + sum e_i"),
    "e_hertz": ("Pa", "apparent elastic Young's modulus: Hertz fitted to the approach alone"),
    "contact": ("m", "contact height of the viscoelastic fit (the height channel's value at first contact)"),
    "contact_hertz": ("m", "contact height of the approach's elastic Hertz fit"),
    "indentation_max": ("m", "largest indentation (contact - h) - F/k"),
    "force_max": ("N", "largest baseline-corrected force in the fitted window"),
    "residual_rms": ("N", "root mean square residual of the viscoelastic fit"),
    "residual_rms_hertz": ("N", "root mean square residual of the approach's elastic Hertz fit"),
    "rss": ("N^2", "residual sum of squares"),
    "aic": ("", "Akaike information criterion N ln(RSS/N) + 2P (dimensionless)"),
    "bic": ("", "Bayesian information criterion N ln(RSS/N) + P ln N (dimensionless)"),
    "d_bic": ("", "bic minus the selected row's"),
    "d_aic": ("", "aic minus the selected row's"),
    "n_points": ("", "residuals of the fit (binned grid points for a force-distance curve)"),
    "n_params": ("", "fitted parameters"),
    "nfev": ("", "model evaluations of the best start"),
    "samples": ("", "recorded samples within the fitted window"),
    "converged": ("", "the optimizer reported convergence"),
    "converged_hertz": ("", "the elastic Hertz fit reported convergence"),
    "at_bound": ("", "the fitted parameters that ended at a bound of their range ('' none)"),
    "window": ("", "dwell curves: the residuals' window, dwell or all (approach and dwell)"),
    "window_s": ("s", "duration of the fitted window"),
    "step_s": ("s", "time step of the binned grid the force-distance fit runs on"),
    "height_channel": ("", "the height channel read: measured (closed-loop sensor) or piezo"),
    "spring_constant": ("N/m", "the cantilever's spring constant (the file's, or --meta)"),
    "position_x": ("m", "the curve's position x on the sample (the file's)"),
    "position_y": ("m", "the curve's position y on the sample (the file's)"),
    "grid_x": ("", "force map grid index x (-1: not a map)"),
    "grid_y": ("", "force map grid index y (-1: not a map)"),
    "tip_radius": ("m", "radius R of the spherical (paraboloid) tip, the input"),
    "nu": ("", "Poisson ratio of the sample, the input (dimensionless)"),
    "fit_cpu_s": ("s", "CPU time of the curve's fits (all rows of the curve)"),
}
for _k in range(1, MAX_ARMS + 1):
    COLUMNS.update({f"e_{_k}": ("Pa", f"modulus of Maxwell arm {_k} (arms sorted by relaxation time)"),
                    f"tau_{_k}": ("s", f"relaxation time of Maxwell arm {_k} (tau_1 < tau_2 < ...)")})  # fmt: skip
for _k, (_u, _d) in list(COLUMNS.items()):
    if _k in ("e0", "beta", "e_inf", "e_hertz", "contact", "contact_hertz") or _k.startswith(("e_", "tau_")) and _k != "e_0":
        COLUMNS[f"se_{_k}"] = (_u, f"standard error of {_k} (from the Jacobian; a lower bound when residuals correlate)")
FIRST = ["file", "curve", "modality", "model", "modulus", "arms", "selected", "status", "error"]


def check_options(tip_radius, nu: float, height: str, criterion: str, window: str, modulus: str = "power-law",
                  points: int = DEFAULT_POINTS, jobs: int = 2) -> None:  # fmt: skip
    """InputError (one line) for a missing or bad option, before any file is read."""
    lo, hi, unit, why = LIMITS["fit.tip_radius"]
    pred, allowed = within(lo, hi, "a radius", unit, why)
    if tip_radius is None:
        raise InputError(f"--tip-radius is required: the radius R [m] of the spherical tip, {allowed} (e.g. --tip-radius 5e-6)")
    if not (isinstance(tip_radius, (int, float)) and math.isfinite(tip_radius) and pred(tip_radius)):
        raise InputError(f"--tip-radius {tip_radius!r} is not allowed; expected {allowed}")
    if not (math.isfinite(nu) and -1.0 < nu <= 0.5):
        raise InputError(f"--nu {nu!r} is not allowed; expected a Poisson ratio in (-1, 0.5]")
    if height not in HEIGHTS:
        raise InputError(f"--height {height!r} is not allowed; expected one of {', '.join(HEIGHTS)}")
    if criterion not in CRITERIA:
        raise InputError(f"--criterion {criterion!r} is not allowed; expected one of {', '.join(CRITERIA)}")
    if window not in WINDOWS:
        raise InputError(f"--window {window!r} is not allowed; expected one of {', '.join(WINDOWS)}")
    if modulus not in MODULI:
        raise InputError(f"--modulus {modulus!r} is not allowed; expected one of {', '.join(MODULI)}")
    if isinstance(points, bool) or not isinstance(points, int) or not MIN_POINTS <= points <= MAX_POINTS:
        raise InputError(f"--points {points!r} is not allowed; expected an integer in {MIN_POINTS}..{MAX_POINTS}")
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise InputError(f"--jobs {jobs!r} is not allowed; expected an integer >= 1")


def base_columns(curve) -> dict:
    gx, gy = curve.meta.get("grid index x"), curve.meta.get("grid index y")
    return {"file": curve.label, "path": curve.source, "curve": curve.index, "modality": curve.modality,
            "height_channel": curve.height_channel, "spring_constant": curve.spring_constant,
            "position_x": float(curve.meta.get("position x", np.nan)),
            "position_y": float(curve.meta.get("position y", np.nan)),
            "grid_x": int(gx) if gx is not None else -1, "grid_y": int(gy) if gy is not None else -1}  # fmt: skip


def fit_job(job: dict) -> list[dict]:
    """The rows of one curve (module level: loky pickles it), judged and with ``selected`` set;
    a curve that cannot be fitted gives one row with status failed or unsuited."""
    curve = job["curve"]
    base = base_columns(curve)
    dwell = curve.modality in DWELL
    kind = {"model": "leeradok" if dwell else "ting", "modulus": "maxwell" if dwell else job["modulus"]}
    t0 = time.process_time()
    try:
        if dwell:
            rows = fit_curve(curve, job["tip_radius"], job["nu"], criterion=job["criterion"], window=job["window"])
            for r in rows:
                r["modulus"] = "maxwell"
        else:
            rows = fit_fd_curve(curve, job["tip_radius"], job["nu"], job["modulus"], points=job["points"])
    except NoContact as exc:
        return [{**base, **kind, "arms": 0, "status": "unsuited", "error": str(exc), "selected": False}]
    except (CurveError, np.linalg.LinAlgError, FloatingPointError, ValueError, ZeroDivisionError) as exc:
        err = " ".join(str(exc).split()) or type(exc).__name__
        return [{**base, **kind, "arms": 0, "status": "failed", "error": err, "selected": False}]
    cpu = time.process_time() - t0
    out = []
    for r in rows:
        status, why = judge(r, r.get("window_s", math.inf))
        out.append({**base, **r, "status": status, "error": why, "fit_cpu_s": cpu})
    select(out, job["criterion"])
    return out


def refusal_row(r) -> dict:
    return {"file": r.label, "path": r.source, "curve": r.index, "modality": r.modality, "status": r.status,
            "error": r.error, "selected": False, "grid_x": -1, "grid_y": -1}  # fmt: skip


def curve_key(curve, opts: dict) -> str:
    """The part key of a curve: its file (real path, size, modification time), index and the
    options that change its rows."""
    try:
        st = os.stat(curve.source)
        stamp = [os.path.realpath(curve.source), st.st_size, st.st_mtime_ns]
    except OSError:
        stamp = [curve.source]
    blob = json.dumps([stamp, curve.index, curve.height_channel, curve.spring_constant, opts], sort_keys=True)
    return hashlib.sha1(blob.encode()).hexdigest()[:20]


@dataclass
class FitResult:
    table: object  # pandas DataFrame
    output: Path
    notes: list = field(default_factory=list)
    computed: int = 0
    reused: int = 0
    figures: list = field(default_factory=list)
    wall_s: float = 0.0

    def summary(self, criterion: str = "bic") -> str:
        """One line: curves fitted (ok, flagged), refused, reused; where the table went."""
        df = self.table
        fitted = df[~df["status"].isin(("unreadable", "unsuited", "failed"))]
        curves = fitted.groupby(["path", "curve"])
        ok = int(curves["status"].apply(lambda s: (s == "ok").any()).sum()) if len(fitted) else 0
        n_curves = curves.ngroups if len(fitted) else 0
        per_file = df.groupby(["path", "curve"])["status"].first()
        refused = int(per_file.isin(("unreadable", "unsuited")).sum())
        failed = int(per_file.eq("failed").sum())
        reuse = f", {self.reused} reused from persisted parts" if self.reused else ""
        return (f"{self.output}: {n_curves} curves fitted ({ok} with a sound fit, {n_curves - ok} flagged), "
                f"{failed} failed, {refused} files or curves refused{reuse}; {self.wall_s:.1f} s")  # fmt: skip


def fit_files(paths, tip_radius, output: str | Path = "fit.parquet", figures: str | Path | None = None,
              nu: float = 0.5, height: str = "measured", criterion: str = "bic", window: str = "dwell",
              modulus: str = "power-law", points: int = DEFAULT_POINTS, meta=None, jobs: int = 2,
              progress: bool = True, resume: bool = True, log=None, launcher=None) -> FitResult:  # fmt: skip
    """Fit every curve of ``paths`` (files or folders) and write the table (and figures).

    Options, ``--meta`` items (``meta``: ``KEY=VALUE`` strings or a dict), the output paths and
    the figures folder are checked before any file is read (InputError, one line, nothing
    written); then every file is read or refused.  When no curve can be fitted at all the
    batch stops there with an InputError naming the refusals (nothing written).  Ctrl-C,
    SIGTERM or SIGHUP raise :class:`vetica_cli.batch.run.BatchInterrupted` with the persisted
    curves; run again, only the missing curves are fitted.  ``log(line)`` gets notes."""
    t_start = time.perf_counter()
    log = log or (lambda line: None)
    check_options(tip_radius, nu, height, criterion, window, modulus, points, jobs)
    meta_override = parse_meta([f"{k}={v}" for k, v in meta.items()] if isinstance(meta, dict) else meta)
    out = check_batch_output(output, ())
    fig_dir = check_output_dir(figures, "--figures") if figures is not None else None
    if launcher is None and jobs_warning(jobs):
        log(jobs_warning(jobs))
    curves, refused, notes = read_inputs(paths, height, meta_override)
    for n in notes:
        log(f"note: {n}")
    if not curves:
        first = refused[0]
        raise InputError(f"no curve to fit: {len(refused)} file(s) or curve(s) refused, e.g. {first.label}: {first.error}")
    import pandas as pd  # here: options and inputs refused before load no pandas

    opts = {"tip_radius": float(tip_radius), "nu": float(nu), "criterion": criterion, "window": window,
            "modulus": modulus, "points": int(points)}  # fmt: skip
    jobs_list = []
    for c in curves:
        key = curve_key(c, opts)
        jobs_list.append(Job({"curve": c, **opts}, {key: c.name}))
    if len({k for j in jobs_list for k in j.parts}) < len(jobs_list):  # the same curve twice (a copy of a file)
        seen, unique = set(), []
        for j in jobs_list:
            k = next(iter(j.parts))
            if k in seen:
                log(f"note: {j.arg['curve'].name} is the same file as another given; fitted once")
                continue
            seen.add(k)
            unique.append(j)
        jobs_list = unique
    order = {next(iter(j.parts)): i for i, j in enumerate(jobs_list)}

    def split(job: Job, rows) -> list:
        key = next(iter(job.parts))
        return [(key, pd.DataFrame(rows), {"curve": job.parts[key], "version": __version__})]

    def finish(done: dict):
        frames = [done[k] for k in sorted(done, key=lambda k: order.get(k, 1 << 30))]
        frames += [pd.DataFrame([refusal_row(r)]) for r in refused]
        rank = {p: i for i, p in enumerate(dict.fromkeys(str(f["path"].iloc[0]) for f in frames if len(f)))}
        frames.sort(key=lambda f: (rank.get(str(f["path"].iloc[0]), 0), int(f["curve"].iloc[0])) if len(f) else (0, 0))
        df = assemble(frames, tip_radius, nu)
        units = {c: COLUMNS[c][0] for c in df.columns if c in COLUMNS}
        descriptions = {c: COLUMNS[c][1] for c in df.columns if c in COLUMNS}
        table_meta = {"kind": "force-curve fit", "table": "fit", "version": __version__, "units": units,
                      "descriptions": descriptions, "code": code_fingerprint(FIT_ROOTS),
                      "params": {**opts, "height": height, "meta": meta_override,
                                 "model": "force-distance: Ting, sphere on E(t) (power law or Prony series); "
                                          "dwell: Lee-Radok, sphere on E(t) = e_inf + sum e_i exp(-t/tau_i)"}}  # fmt: skip
        write_table(df, out, table_meta)
        return df

    kind = "maxwell" if modulus == "maxwell" else "power-law"
    core_s = sum(SECONDS_PER_CURVE["dwell" if j.arg["curve"].modality in DWELL else kind] for j in jobs_list)
    bar = Bar(name="fit", unit="curves", count=lambda df: (1, int(not (df["status"] == "ok").any())))
    with signals_as_interrupt():
        table, run = run_batch(out, jobs_list, fit_job, split, fingerprint=code_fingerprint(FIT_ROOTS), finish=finish,
                               bar=bar, n_jobs=min(jobs, max(len(jobs_list), 1)), launcher=launcher,
                               serial_estimate=core_s, serial_below_s=SERIAL_BELOW_S, resume=resume,
                               progress=progress, log=log, what="curves")  # fmt: skip
    result = FitResult(table, out, notes + run.notes, len(run.computed), len(run.reused))
    if fig_dir is not None:
        from .figures import write_figures

        result.figures = write_figures(table, curves, fig_dir, points)
    result.wall_s = time.perf_counter() - t_start
    if not (table["status"] == "ok").any() and table["status"].isin(("unreadable", "unsuited", "failed")).all():
        raise InputError(f"no curve could be fitted; the rows with the reasons are in {out}")
    return result


def assemble(frames: list, tip_radius: float, nu: float):
    """One table from the curves' rows and the refusals: typed columns in a fixed order."""
    import pandas as pd

    df = pd.concat([f for f in frames if len(f)], ignore_index=True)
    for c in ("model", "modulus", "modality", "error", "window", "height_channel", "path", "file"):
        if c in df:
            df[c] = df[c].fillna("").astype(str)
    for c in ("arms", "grid_x", "grid_y", "curve"):
        if c in df:
            df[c] = df[c].fillna(-1 if c != "arms" else 0).astype("int64")
    if "at_bound" in df:
        df["at_bound"] = df["at_bound"].fillna("").astype(str)
    for c in ("selected", "converged", "converged_hertz"):
        if c in df:
            df[c] = df[c].astype("boolean").fillna(False).astype(bool)
    for c in FIRST:
        if c not in df:
            df[c] = "" if c in ("model", "modulus", "modality") else 0
    df["tip_radius"], df["nu"] = float(tip_radius), float(nu)
    return df[FIRST + [c for c in df.columns if c not in FIRST]]
