"""The ``vetica`` command line.  Each command parses its arguments and calls
one importable function; user errors print one line and exit with status 2."""

from __future__ import annotations

import functools
import sys
from pathlib import Path
from typing import List, Optional

import typer

from .errors import USER_ERRORS

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
    from . import config as cfgmod
    from .io import write_run
    from .report import run_summary
    from .simulate import simulate as _simulate

    cfg = cfgmod.load(config, cfgmod.parse_set(set_))
    run = _simulate(cfg)
    write_run(run, output)
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
    from . import config as cfgmod
    from .bench import run_bench

    cfg = cfgmod.load(None, cfgmod.parse_set(set_))
    typer.echo(run_bench(cfg, repeat))


def main():  # pragma: no cover - console script entry
    app()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
