"""The ``vetica`` command line.  Each command parses its arguments and calls
one importable function; user errors print one line and exit with status 2."""

from __future__ import annotations

import functools
import sys
from pathlib import Path
from typing import List, Optional

import typer

from .errors import USER_ERRORS
from .extraction import DEFAULT_METHOD, METHODS

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Simulate tapping-mode AFM (torsional harmonic cantilever) on a viscoelastic SLS surface "
    "and extract the surface's k0, k_inf, cd back with VETICA.  All values SI.",
    pretty_exceptions_enable=False,
)


def user_errors(fn):
    """Turn USER_ERRORS into one line on stderr and exit status 2."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except USER_ERRORS as exc:
            typer.echo(f"error: {exc}", err=True)
            raise typer.Exit(2) from None

    return wrapper


SET_HELP = "Override one config key, e.g. --set surface.cd=1e-4 (repeatable)."


@app.command()
@user_errors
def simulate(
    config: Optional[Path] = typer.Argument(None, help="YAML config of one point; defaults = thesis worked example."),
    set_: Optional[List[str]] = typer.Option(None, "--set", help=SET_HELP),
    output: Path = typer.Option(Path("run.parquet"), "-o", "--output", help="Parquet file to write."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="Do not print the summary."),
):
    """Simulate one point to steady state and write the recorded signals.

    Writes columns t, z_tip, z_cantilever, z_paddle, z_base, f_ts, x_surface,
    x_dashpot, segment (approach | steady); the Parquet metadata key 'vetica'
    holds the resolved params, units, stop_reason and observables.
    """
    from .report import run_summary
    from .simulation.config import parse_set
    from .simulation.simulate import simulate_file

    run = simulate_file(config, output, parse_set(set_))
    if not quiet:
        typer.echo(run_summary(run, output))


@app.command()
@user_errors
def bench(
    repeat: int = typer.Option(3, min=1, help="Timed runs after one warm-up (compilation) run."),
    set_: Optional[List[str]] = typer.Option(None, "--set", help=SET_HELP),
):
    """Time the kernel on the worked example: ns per integration step and
    wall seconds to steady state (one core)."""
    from .bench import run_bench
    from .simulation.config import parse_set

    typer.echo(run_bench(parse_set(set_), repeat))


@app.command()
@user_errors
def sweep(
    config: Path = typer.Argument(..., help="Study YAML: single-point sections plus a 'sweep:' block (see configs/)."),
    output: Optional[Path] = typer.Option(
        None, "-o", "--output", help="Parquet table to write (default: results/<config name>.parquet)."
    ),
    jobs: int = typer.Option(2, "--jobs", "-j", help="Parallel workers (processes), one core each."),
    backend: str = typer.Option("loky", help="loky (local processes) or dask (a Dask cluster via joblib)."),
    scheduler: Optional[str] = typer.Option(
        None, help="Dask scheduler address, e.g. tcp://host:8786 (with --backend dask; default: a local cluster)."
    ),
    resume: bool = typer.Option(
        True, "--resume/--no-resume", help="Reuse points persisted in <output>.parts/ by an earlier (killed) run."
    ),
    set_: Optional[List[str]] = typer.Option(None, "--set", help=SET_HELP + " Applies to the base; not to swept keys."),
    dry_run: bool = typer.Option(False, "--dry-run", help="Print the points and a cost bound, run nothing."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
):
    """Run a parametric study: simulate every point of the grid, extract it
    with the true and the reconstructed force (extract.force), by a registered
    extraction method (extract.method; see vetica extract --help), and write one tidy
    table (one row per point, method and force source) plus <name>.config.yaml.
    Points differing only in method or instrument noise share one simulation.

    Prints the acceptance regime at the end: for every combination of the
    other swept keys, the range of surface.cd where the tau_c error is below
    30 %.  A killed sweep run again computes only the missing points.
    """
    from .simulation.config import parse_set
    from .study.sweep import SweepInterrupted, sweep_command

    try:
        text = sweep_command(config, output, parse_set(set_), dry_run=dry_run, jobs=jobs, backend=backend,
                             scheduler=scheduler, resume=resume, progress=not quiet)  # fmt: skip
    except SweepInterrupted as exc:
        typer.echo(str(exc), err=True)
        raise typer.Exit(130) from None
    typer.echo(text)


@app.command()
@user_errors
def scan(
    config: Path = typer.Argument(..., help="Scan YAML: probe/operation/numerics/extract plus 'scan:' and 'sample:'."),
    output: Optional[Path] = typer.Option(
        None, "-o", "--output", help="Parquet table to write (default: results/<config name>.parquet)."
    ),
    jobs: int = typer.Option(2, "--jobs", "-j", help="Parallel workers (processes), one core each; a line per job."),
    backend: str = typer.Option("loky", help="loky (local processes) or dask (a Dask cluster via joblib)."),
    scheduler: Optional[str] = typer.Option(
        None, help="Dask scheduler address, e.g. tcp://host:8786 (with --backend dask; default: a local cluster)."
    ),
    resume: bool = typer.Option(
        True, "--resume/--no-resume", help="Reuse lines persisted in <output>.parts/ by an earlier (killed) run."
    ),
    set_: Optional[List[str]] = typer.Option(
        None, "--set", help="Override one key, e.g. --set scan.pixel_time=1e-3 or sample.features.0.height=2e-9."
    ),
    dry_run: bool = typer.Option(False, "--dry-run", help="Print the pixels, domains and a cost estimate, run nothing."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
):
    """Image a heterogeneous sample as a tapping-mode AFM does: scan it line by line, pixel by
    pixel (the cantilever and the controller carry over, the surface under each pixel starts
    undeformed), extract every pixel with every scan.methods, and write one tidy table (one
    row per pixel, method and force source: x, y, height_true, topography, amplitude,
    phase_deg, e_diss_ev, ..., each estimate with _theory and _err_pct, status, error) plus
    <name>.config.yaml and <name>.summary.md (per-domain medians against the truth, apparent
    heights, edge-artefact widths).  A killed scan run again computes only the missing lines.
    """
    from .scan.run import ScanInterrupted, scan_command
    from .simulation.config import parse_set

    try:
        text = scan_command(config, output, parse_set(set_), dry_run=dry_run, jobs=jobs, backend=backend,
                            scheduler=scheduler, resume=resume, progress=not quiet)  # fmt: skip
    except ScanInterrupted as exc:
        typer.echo(str(exc), err=True)
        raise typer.Exit(130) from None
    typer.echo(text)


@app.command()
@user_errors
def plot(
    table: Path = typer.Argument(..., help="A run (vetica simulate) or sweep table (vetica sweep), Parquet."),
    output: Optional[Path] = typer.Option(
        None, "-o", "--output", help="Folder for the PNG figures (default: figures/ next to TABLE)."
    ),
    cutoff: Optional[float] = typer.Option(
        None,
        "--cutoff",
        help="Low-pass cut-off [Hz] of the force reconstruction and tip velocity of a run; default: Nyquist. "
        "Noisy records need one.",
    ),
):
    """Draw the thesis's figures from a run or a sweep table (PNG, headless).

    A run gives trajectories with transitions (thesis fig. 33), force against
    tip position with the dissipation loop (fig. 28), reconstructed against true
    force, and force against distance and velocity (fig. 62).  A sweep table
    gives the chapter-4 figures that its swept keys call for (errors and
    acceptance regime against cd, f1, print step; E_diss maps; peak force,
    penetration, contact times, zero-reference depth).  A scan table (vetica scan)
    gives images of topography, phase, E_diss and each extracted property beside its
    truth and error, and a line profile.  Files are named <table stem>_<figure>.png.
    """
    from .plots import plot as _plot

    result = _plot(table, output, cutoff)
    for note in result.notes:
        typer.echo(f"note: {note}")
    for p in result.paths:
        typer.echo(f"wrote {p}")


@app.command()
@user_errors
def extract(
    run: Path = typer.Argument(
        ..., help="Parquet written by 'vetica simulate', or any Parquet/CSV with t, z_tip and f_ts or z_paddle."
    ),
    force: str = typer.Option(
        "auto",
        "--force",
        help="Force to analyse: reconstructed (spectral inversion of z_paddle) or true (the f_ts column); "
        "auto = reconstructed when z_paddle is present.",
    ),
    kg_points: int = typer.Option(
        10, "--kg-points", help="Samples after the contact minimum in the Kg fit (thesis: 10)."
    ),
    method: str = typer.Option(
        DEFAULT_METHOD,
        "--method",
        help="Extraction method: " + "; ".join(f"{k} = {m.description}" for k, m in METHODS.items()) + ".",
    ),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object instead of the table."),
    k2: Optional[float] = typer.Option(None, "--k2", help="Paddle stiffness, N/m (data without metadata)."),
    f2: Optional[float] = typer.Option(None, "--f2", help="Paddle resonance, Hz (data without metadata)."),
    q2: Optional[float] = typer.Option(None, "--q2", help="Paddle quality factor (data without metadata)."),
    z1: Optional[float] = typer.Option(
        None, "--z1", help="Tip position at the first approach force minimum, m; default: from the approach segment."
    ),
    f1: Optional[float] = typer.Option(
        None, "--f1", help="Drive frequency, Hz; only labels the cut-off in harmonics."
    ),
    cutoff: Optional[float] = typer.Option(
        None, "--cutoff", help="Low-pass cut-off of the force reconstruction, Hz; default: Nyquist, 1/(2 print step)."
    ),
):
    """Extract k0, k_inf, cd (and tau_c, Kg, Kr, tau_r) from a run with VETICA
    or another registered method (--method; e.g. full fits the SLS surface model
    to every sample).

    Prints value, theory and error % (theory known only when the file's
    metadata holds the surface parameters), the spread over taps, the
    force-reconstruction error against f_ts when both are present, and the
    extraction time.
    """
    import json

    from .extraction import extract_file
    from .extraction.format import format_table, to_json

    res = extract_file(run, force=force, method=method, kg_points=kg_points,
                       k2=k2, f2=f2, q2=q2, z1=z1, f1=f1, cutoff_hz=cutoff)  # fmt: skip
    typer.echo(json.dumps(to_json(res), allow_nan=False) if json_out else format_table(res, run))


def main():  # pragma: no cover - console script entry
    app()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
