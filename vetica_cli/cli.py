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
    penetration, contact times, zero-reference depth).  Files are named
    <table stem>_<figure>.png.
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
    a0: Optional[float] = typer.Option(
        None, "--a0", help="Intermolecular distance, m: Z1 = a0 (thesis eq. 84) for a record without approach segment, "
        "with z_tip measured from the undeformed surface; default: the metadata's."
    ),
    vdw_on_surface: Optional[bool] = typer.Option(
        None, "--vdw-on-surface/--no-vdw-on-surface",
        help="Whether the surface feels the tip's van der Waals pull (Z1 = a0 + Fa(a0)/Kg when it does; the pre-stress "
        "of vetica-prestress); default: the metadata's.",
    ),
    contact: Optional[List[str]] = typer.Option(
        None, "--contact", help="Contact constant of the material units, key=value (repeatable): tip_radius (m), nu_tip, "
        "nu_sample, e_tip (Pa); default thesis table 6 (R = the metadata's tip radius, else 10 nm).",
    ),
    prestress: Optional[str] = typer.Option(
        None, "--prestress", help="vetica-prestress: auto (adhesion if the surface feels the pull, else creep), "
        "adhesion, creep or fit.",
    ),
):
    """Extract k0, k_inf, cd (and tau_c, Kg, Kr, tau_r) from a run with VETICA
    or another registered method (--method; e.g. full fits the SLS surface model
    to every sample), and the material units: DMT, glassy and rubbery moduli [Pa]
    and viscosity [Pa s] (thesis 4.6.2, eqs. 90-92).

    Prints value, theory and error % (theory known only when the file's
    metadata holds the surface parameters), the spread over taps, the
    force-reconstruction error against f_ts when both are present, and the
    extraction time.  A CSV or Parquet with only t, z_tip and f_ts (or z_paddle
    with --k2 --f2 --q2) is read as measured: Z1 from --z1, else from --a0
    (thesis eq. 84) with --vdw-on-surface/--no-vdw-on-surface.
    """
    import json

    from .extraction import extract_file
    from .extraction.format import format_table, to_json
    from .extraction.material import parse_contact

    opts = {} if prestress is None else {"prestress": prestress}
    res = extract_file(run, force=force, method=method, kg_points=kg_points, k2=k2, f2=f2, q2=q2, z1=z1, f1=f1,
                       cutoff_hz=cutoff, a0=a0, vdw_on_surface=vdw_on_surface, contact=parse_contact(contact),
                       **opts)  # fmt: skip
    typer.echo(json.dumps(to_json(res), allow_nan=False) if json_out else format_table(res, run))


def _number(option: str, raw: Optional[str]) -> Optional[float]:
    """A number option read as text, so that bad input is one line (InputError)."""
    from .errors import InputError

    if raw is None:
        return None
    try:
        return float(raw)
    except ValueError:
        raise InputError(f"{option} {raw!r} is not allowed; expected a number") from None


def _numbers(option: str, raw: Optional[str]) -> Optional[list]:
    """A comma-separated list of numbers, e.g. --f1 10e3,50e3."""
    from .errors import InputError

    if raw is None:
        return None
    values = [_number(option, x.strip()) for x in raw.split(",") if x.strip()]
    if not values:
        raise InputError(f"{option} {raw!r} is not allowed; expected comma-separated numbers")
    return values


@app.command()
@user_errors
def advise(
    k_inf: Optional[str] = typer.Option(None, "--k-inf", help="Equilibrium spring k_inf of the SLS, N/m."),
    k0: Optional[str] = typer.Option(None, "--k0", help="Maxwell-arm spring k0, N/m."),
    cd: Optional[str] = typer.Option(None, "--cd", help="Dashpot cd, kg/s."),
    e_glassy: Optional[str] = typer.Option(None, "--e-glassy", help="Glassy sample modulus, Pa (instead of the springs)."),
    e_rubbery: Optional[str] = typer.Option(None, "--e-rubbery", help="Rubbery sample modulus, Pa."),
    tau_r: Optional[str] = typer.Option(None, "--tau-r", help="Relaxation time, s."),
    depth: str = typer.Option("2e-9", "--depth", help="Penetration at which moduli become springs, m (thesis eqs. 90-92)."),
    contact: Optional[List[str]] = typer.Option(
        None, "--contact", help="Contact constant for the moduli, key=value: nu_tip, nu_sample, e_tip (Pa), tip_radius (m)."
    ),
    f1: Optional[str] = typer.Option(None, "--f1", help="Drive frequencies, Hz, comma-separated (f2 = 15 f1); "
                                     "default 10e3,20e3,50e3,100e3."),  # fmt: skip
    setpoint: Optional[str] = typer.Option(None, "--setpoint", help="Set points A_sp/A0; default 0.4,0.6,0.8."),
    print_step: Optional[str] = typer.Option(None, "--print-step", help="Print steps, s; default 0.5e-9,2e-9,8e-9."),
    k2: Optional[str] = typer.Option(None, "--k2", help="Paddle stiffnesses, N/m; default 200,700."),
    methods: str = typer.Option("vetica-prestress,full", "--methods", help="Methods that must all recover the material."),
    force: str = typer.Option("reconstructed", "--force", help="Force analysed: reconstructed (as measured) or true."),
    set_: Optional[List[str]] = typer.Option(None, "--set", help="Probe/operation/numerics key of the base, e.g. "
                                             "--set probe.k1=5 (not a knob, not the material)."),  # fmt: skip
    jobs: int = typer.Option(2, "--jobs", "-j", help="Parallel workers (processes), one core each."),
    output: Path = typer.Option(Path("advise.png"), "-o", "--output", help="PNG of the map to write."),
    table: Optional[Path] = typer.Option(None, "--table", help="Also write every setting's row as Parquet."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object: {\"settings\": [...], ...}."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
):
    """Which settings make the extraction work for a material: a small study over the
    drive frequency (f2 = 15 f1), set point, print step and paddle stiffness within the
    thesis's ranges, each setting simulated to its periodic state and extracted by every
    method of --methods; prints the settings under which all of them recover the material
    (tau_c error < 30 %, k0, k_inf, cd within 5 %), ranked by margin, and draws the map.
    The keys of --json's settings can be passed to vetica simulate --set.
    """
    import json

    from .extraction.material import parse_contact
    from .plots.advise import write_advice_figure
    from .simulation.config import parse_set
    from .study.advise import advice_json, contact_for, format_advice, material_from
    from .study.advise import advise as run_advice

    overrides = parse_set(set_)
    cm = contact_for(overrides, parse_contact(contact))
    material = material_from(_number("--k-inf", k_inf), _number("--k0", k0), _number("--cd", cd),
                             _number("--e-glassy", e_glassy), _number("--e-rubbery", e_rubbery),
                             _number("--tau-r", tau_r), _number("--depth", depth), cm)  # fmt: skip
    knobs = {"probe.f1": _numbers("--f1", f1), "operation.setpoint": _numbers("--setpoint", setpoint),
             "numerics.print_step": _numbers("--print-step", print_step), "probe.k2": _numbers("--k2", k2)}  # fmt: skip
    from .errors import InputError

    if output.suffix.lower() != ".png":
        raise InputError(f"-o {str(output)!r}: the map is written as PNG; expected a .png path")
    if table is not None and table.suffix.lower() != ".parquet":
        raise InputError(f"--table {str(table)!r}: the table is written as Parquet; expected a .parquet path")
    adv = run_advice(material, overrides, knobs, [m.strip() for m in methods.split(",") if m.strip()], force, jobs,
                     progress=not (quiet or json_out))  # fmt: skip
    figure = write_advice_figure(adv, output)
    if table is not None:
        from .io import write_table

        write_table(adv.table, table, advice_json(adv, figure))
    typer.echo(json.dumps(advice_json(adv, figure), allow_nan=False) if json_out else format_advice(adv, figure))


def main():  # pragma: no cover - console script entry
    app()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
