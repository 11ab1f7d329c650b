"""The Python API: what the commands do, from a notebook or a script (docs/api.md).

Each function is the one the command calls, with the same checks and errors (an
:class:`~vetica_cli.errors.InputError` or :class:`~vetica_cli.errors.ConfigError` with a
one-line message), and runs with BLAS and OpenMP capped at ``threads`` threads (by default
the threads the environment sets, ``OPENBLAS_NUM_THREADS``, ``MKL_NUM_THREADS`` or
``OMP_NUM_THREADS``, else one, as in the commands and their workers:
:func:`vetica_cli.batch.launch.one_thread`).  Without
the cap a notebook's BLAS starts a thread per core for the small least-squares problems of
the fits and spends several times the CPU for the same numbers.

    from vetica_cli import api
    run = api.simulate(overrides={"surface.cd": 1e-4})          # a Run: run.frame(), run.metadata()
    res = api.extract(run, method="vetica")                     # an ExtractionResult: res.estimates
    table = api.fit(["curves/"], tip_radius=5e-6)                # a DataFrame, one row per curve
    api.export("scan.parquet", "scan.nc")                        # NetCDF, .gwy or .gsf
"""

from __future__ import annotations

import functools
import tempfile
from pathlib import Path

from .batch.launch import one_thread


def capped(fn):
    """Run ``fn`` under :func:`one_thread` with its ``threads`` keyword (default None: the
    environment's setting, else 1)."""

    @functools.wraps(fn)
    def wrapper(*args, threads: int | None = None, **kwargs):
        if threads is not None and (isinstance(threads, bool) or not isinstance(threads, int) or threads < 1):
            from .errors import InputError

            raise InputError(f"threads={threads!r} is not allowed; expected an integer >= 1")
        with one_thread(threads):
            return fn(*args, **kwargs)

    return wrapper


@capped
def simulate(config=None, overrides: dict | None = None):
    """Simulate one point (``vetica simulate``): ``config`` a YAML path, a dict of sections, or
    None (the thesis's worked example); ``overrides`` ``{"surface.cd": 1e-4, ...}`` as ``--set``.
    Returns the :class:`~vetica_cli.simulation.simulate.Run` (``run.frame()`` the signals,
    ``run.metadata()`` the parameters, units and observables)."""
    from .simulation.config import load
    from .simulation.simulate import simulate as _simulate

    if isinstance(config, dict):  # the same path as a YAML file: derived keys and overrides resolved alike
        import yaml

        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "config.yaml"
            path.write_text(yaml.safe_dump(config))
            cfg = load(path, overrides or {})
    else:
        cfg = load(config, overrides or {})
    return _simulate(cfg)


@capped
def extract(run, method: str = "vetica", force: str = "auto", **options):
    """Extract the surface (``vetica extract``) from a Run, a Parquet/CSV path, or a
    ``(DataFrame, metadata)`` pair, by a registered ``method``; ``options`` as
    :func:`vetica_cli.extraction.extract` takes them.  Returns the ExtractionResult."""
    from .extraction import extract as _extract
    from .extraction import extract_file

    if isinstance(run, (str, Path)):
        return extract_file(run, force=force, method=method, **options)
    if isinstance(run, tuple):
        df, meta = run
    else:
        df, meta = run.frame(), run.metadata()
    return _extract(df, meta, force=force, method=method, **options)


@capped
def fit(paths, tip_radius: float, output=None, **options):
    """Fit force curves (``vetica fit``): files or folders, the tip radius [m], and the command's
    options as keywords (``modulus``, ``nu``, ``meta``, ``criterion``, ``window``, ``points``,
    ``jobs`` (1 by default here: this process), ``figures``).  Writes the table to ``output``
    (a temporary file when None) and returns it as a DataFrame with its metadata in
    ``table.attrs['vetica']``."""
    from .curves.batch import fit_files
    from .io import read_meta

    options.setdefault("jobs", 1)
    options.setdefault("progress", False)
    if isinstance(paths, (str, Path)):
        paths = [paths]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(output) if output is not None else Path(tmp) / "fit.parquet"
        res = fit_files(paths, tip_radius, out, **options)
        table = res.table
        table.attrs["vetica"] = read_meta(out)
    return table


def export(table, output, quantities=None) -> list[Path]:
    """Write a scan or force-map table to ``output`` (``vetica export``: .nc, .gwy, .gsf)."""
    from .export import export as _export

    return _export(table, output, quantities)
