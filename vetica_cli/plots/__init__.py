"""Figures from vetica tables (``vetica plot``), headless (matplotlib Agg).

Two kinds of input, told apart by their columns and metadata:

* a **run** written by ``vetica simulate`` (columns ``t, z_tip, f_ts,
  x_surface, z_paddle, segment``; metadata ``params``) gives the per-run
  figures of the thesis: tip and surface trajectories with the transition
  points (thesis fig. 33), force against tip position with the dissipation
  loop (fig. 28), reconstructed against true force (spectral inversion,
  thesis 2.3) and the "4-D" force curve, force against distance and tip
  velocity (fig. 62, thesis 5.3.1);
* a **fit table** written by ``vetica fit`` gives each curve's data against its fits (when
  the curve files are still where the table's ``path`` says), the selected parameters'
  histograms and a map of every parameter of each force map;
* a **sweep table** written by ``vetica sweep`` (one row per point and force
  source) gives the parametric-study figures of thesis chapter 4, chosen from
  the keys that were swept (see :func:`.study.select_sweep_figures`).

Displayed units are the engineering ones a researcher reads (nm, nN, us, eV,
kHz, ns); the tables stay SI.  Conventions shared by every sweep figure:
true force = solid line, filled marker; reconstructed force = dashed line,
open marker; ``not_steady`` points are drawn with a grey cross over the
marker and do not count for the acceptance regime; ``no_estimate`` points (the
extraction gave no value; why is in the table's ``error``) show, where a value is
missing, as the quantity's own marker in a band above the data (one row per quantity) and
are counted in the note of the figures of estimates; ``failed`` points are excluded and
counted in the note at the bottom of the figure.  A shaded acceptance regime spans exactly
the stated cd range; a legend that would cover data is moved beside its axes
(:func:`.style.legends_off_data`).

Modules: :mod:`.style` (conventions and helpers), :mod:`.run` (run figures),
:mod:`.data` (the sweep rows the study figures draw), :mod:`.study` (which
study figures a table calls for), and one module per family of study figures:
:mod:`.errors`, :mod:`.acceptance`, :mod:`.maps`, :mod:`.observables`; and the scan
images of a map from ``vetica scan`` (:mod:`.scanmaps`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from ..errors import InputError
from ..io import check_output_dir, read_table
from .run import run_figures
from .scanmaps import scan_figures
from .study import sweep_figures
from .style import save_png

RUN_COLUMNS = ("t", "z_tip", "f_ts", "x_surface", "segment")


SWEEP_COLUMNS = ("force_source", "status")


@dataclass
class PlotResult:
    """Files written and remarks for the user (figures skipped and why)."""

    paths: list = field(default_factory=list)
    notes: list = field(default_factory=list)


def plot(path: str | Path, outdir: str | Path | None = None, cutoff_hz: float | None = None) -> PlotResult:
    """Write the figures for a run or sweep table into ``outdir``.

    ``outdir`` defaults to ``figures/`` next to the table.  ``cutoff_hz`` is
    the low-pass cut-off of the run figures' spectral operations (force
    reconstruction and tip velocity; None = Nyquist, as ``vetica extract``).  Files are named
    ``<table stem>_<figure>.png``, so several studies can share one folder.
    The input is read and checked completely before any file is written;
    each PNG is written to a temporary file and renamed into place, and when one cannot
    be written (a full disk) the ones this call wrote are removed.
    Raises InputError (one line) for a missing, corrupt or non-vetica file.
    """
    path = Path(path)
    if cutoff_hz is not None and not (math.isfinite(cutoff_hz) and cutoff_hz > 0):
        raise InputError(f"--cutoff {cutoff_hz!r} is not allowed; expected a frequency > 0 Hz")
    outdir = check_output_dir(Path(outdir) if outdir is not None else path.parent / "figures")
    df, meta = read_table(path)
    kind = table_kind(df, meta, path)
    if kind == "fit":
        figures, notes = fit_figures(df, meta)
    elif kind == "run":
        figures, notes = run_figures(df, meta, cutoff_hz)
    elif kind == "scan":
        figures, notes = scan_figures(df, meta)
    else:
        figures, notes = sweep_figures(df, meta)
    result = PlotResult(notes=notes)
    try:
        for name, fig in figures:
            result.paths.append(save_png(fig, outdir / f"{path.stem}_{name}.png"))
    except BaseException:  # a full disk, Ctrl-C: no figure set half-written, nothing left of this call
        for written in result.paths:
            Path(written).unlink(missing_ok=True)
        raise
    return result


def fit_figures(df: pd.DataFrame, meta: dict) -> tuple[list, list]:
    """A fit table (``vetica fit``): each curve's data against its fits when its file is still
    where the table says (``path``), the selected parameters' histograms and the force maps."""
    from ..curves.figures import build_figures
    from ..curves.read import read_inputs

    params = meta.get("params", {})
    paths = sorted({p for p in df.get("path", pd.Series(dtype=str)) if p and Path(p).is_file()})
    notes = []
    curves = []
    if paths:
        curves, _, _ = read_inputs(paths, params.get("height", "measured"), params.get("meta") or None)
        labels = dict(zip(df["path"], df["file"]))
        for c in curves:
            c.label = labels.get(c.source, c.label)
    missing = df["path"].nunique() - len(paths) if "path" in df else 0
    if missing:
        notes.append(f"{missing} file(s) of the table are not where it says: their fits are not drawn")
    return build_figures(df, curves, int(params.get("points", 400))), notes


def table_kind(df: pd.DataFrame, meta: dict, path: Path | str = "table") -> str:
    """'run', 'sweep' or 'scan' (a map from 'vetica scan'); InputError naming what is missing otherwise."""
    if not meta:
        raise InputError(
            f"{path}: no 'vetica' metadata; expected a run from 'vetica simulate' or a table from 'vetica sweep'"
        )
    if meta.get("table") == "scan":
        return "scan"
    if meta.get("table") == "fit" or meta.get("kind") == "force-curve fit":
        return "fit"
    if all(c in df.columns for c in SWEEP_COLUMNS):
        return "sweep"
    if all(c in df.columns for c in RUN_COLUMNS):
        if not isinstance(meta.get("params"), dict):
            raise InputError(f"{path}: run table without 'params' in its metadata; rewrite it with 'vetica simulate'")
        return "run"
    missing_run = [c for c in RUN_COLUMNS if c not in df.columns]
    raise InputError(
        f"{path}: neither a run (missing columns {', '.join(missing_run)}) "
        f"nor a sweep table (needs columns {', '.join(SWEEP_COLUMNS)})"
    )
