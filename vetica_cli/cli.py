"""The ``vetica`` command line.  Each command parses its arguments and calls one
importable function.  Every user error -- a bad option value (typer/click's own
checks included), config, input file or output path -- prints one line on stderr
and exits with status 2, before any work and with nothing written.

Adding a command is one decorated function here: ``@app.command()`` then
``@user_errors``, options parsed by typer (value checks through :func:`checked`),
and one call into the package.
"""

from __future__ import annotations

import functools
import importlib
import math
import signal
import sys
from pathlib import Path
from typing import List, Optional

import typer
from typer.core import TyperGroup

from . import __version__
from .checks import limit
from .errors import USER_ERRORS
from .extraction import DEFAULT_METHOD, METHODS
from .interrupt import INTERRUPTED_EARLY, interrupt_handled


def one_line(text: str) -> str:
    """``text`` on one line (click's messages may hold line breaks)."""
    return " ".join(str(text).split())


# click's exception classes: click's own, or the copy typer >= 0.26 vendors (typer's errors are its subclasses)
click_errors = importlib.import_module(typer.BadParameter.__module__)
NoArgsIsHelp = getattr(click_errors, "NoArgsIsHelpError", ())  # click >= 8.2: a bare command shows its help


class VeticaGroup(TyperGroup):
    """The command group: click's usage errors (unknown option, bad integer, missing
    argument...) become one line ``error: ...`` with exit status 2 instead of a usage block."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        try:
            rv = super().main(args=args, prog_name=prog_name, complete_var=complete_var, standalone_mode=False,
                              **extra)  # fmt: skip
        except NoArgsIsHelp as exc:  # `vetica` or `vetica CMD` alone: the help
            typer.echo(exc.ctx.get_help() if exc.ctx is not None else str(exc))
            rv = 0
        except click_errors.ClickException as exc:
            hint = f" (see: {exc.ctx.command_path} --help)" if getattr(exc, "ctx", None) is not None else ""
            typer.echo(f"error: {one_line(exc.format_message())}{hint}", err=True)
            rv = exc.exit_code
        except typer.Abort:
            typer.echo("aborted", err=True)
            rv = 1
        if not standalone_mode:
            return rv
        sys.exit(rv if isinstance(rv, int) else 0)


app = typer.Typer(
    cls=VeticaGroup,
    name="vetica",
    add_completion=False,
    no_args_is_help=True,
    help=None,  # ROOT_HELP, on the callback
    pretty_exceptions_enable=False,
    rich_markup_mode=None,  # help text is printed as written: '[vetica, full]' is text, not markup
)


def show_version(value: bool) -> None:
    if value:
        typer.echo(f"vetica {__version__}")
        raise typer.Exit()


def root_help() -> str:
    """The app's help, from the registries: the surface models it simulates and the methods it
    extracts with."""
    from .surfaces import MODELS

    return ("Simulate tapping-mode AFM (torsional harmonic cantilever) on a viscoelastic surface ("
            + ", ".join(m.name for m in MODELS.values()) + ") and extract the surface's parameters back from "
            "the record (" + ", ".join(METHODS) + "); fit measured force curves.  All values SI.")  # fmt: skip


@app.callback(help=root_help())
def root(
    version: bool = typer.Option(
        False, "--version", help="Print the version and exit.", is_eager=True, callback=show_version
    ),
):
    """The command group (its help: :func:`root_help`)."""


_REPORTED: list[bool] = []  # an interrupt already reported by a command (typer must not end silently)


def user_errors(fn):
    """Turn USER_ERRORS into one line on stderr and exit status 2."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except USER_ERRORS as exc:
            typer.echo(f"error: {one_line(exc)}", err=True)
            raise typer.Exit(2) from None
        except KeyboardInterrupt as exc:  # a batch says what it persisted; before, nothing is written yet
            typer.echo(one_line(exc) or INTERRUPTED_EARLY, err=True)
            _REPORTED.append(True)
            raise typer.Exit(getattr(exc, "exit_code", 130)) from None

    return wrapper


def checked(allowed: str, ok):
    """An option callback: the value (None passes) must be finite and satisfy ``ok(value)``;
    otherwise a usage error naming the value and ``allowed``."""

    def callback(value):
        if value is None:
            return value
        if isinstance(value, float) and not math.isfinite(value) or not ok(value):
            raise typer.BadParameter(f"{value!r} is not allowed; expected {allowed}")
        return value

    return callback


def _cutoff_option(value):
    """``--cutoff``: None (auto), ``math.inf`` (nyquist) or a frequency > 0 Hz."""
    if value is None or value.strip().lower() == "auto":
        return None
    if value.strip().lower() == "nyquist":
        return math.inf
    try:
        v = float(value)
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and v > 0):
        raise typer.BadParameter(f"{value!r} is not allowed; expected auto, nyquist or a frequency > 0 Hz")
    return v


SET_HELP = "Override one config key, e.g. --set surface.cd=1e-4 (repeatable)."
YES_HELP = "Start work estimated over 2 h (or 5000 items), the threshold every command asks past."


@app.command(short_help='One point to its proven steady state; the recorded signals and their metadata.')
@user_errors
def simulate(
    config: Optional[Path] = typer.Argument(None, help="YAML config of one point; defaults = thesis worked example."),
    set_: Optional[List[str]] = typer.Option(None, "--set", help=SET_HELP),
    output: Path = typer.Option(Path("run.parquet"), "-o", "--output", help="Parquet file to write (checked first)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="Do not print the summary."),
    yes: bool = typer.Option(False, "--yes", "-y", help=YES_HELP),
):
    """Simulate one point to steady state and write the recorded signals.

    Writes columns t, z_tip, z_cantilever, z_paddle, z_base, f_ts, x_surface,
    x_dashpot, segment (approach | steady); the Parquet metadata key 'vetica'
    holds the resolved params, units, stop_reason and observables.  Derived keys
    work as in a study: --set surface.stiffness_ratio=16 sets k0 = 16 k_inf.
    """
    from .report import run_summary
    from .simulation.config import parse_set
    from .simulation.command import simulate_file

    notice = None if quiet else (lambda line: typer.echo(line, err=True))  # said only when kernels will compile
    run = simulate_file(config, output, parse_set(set_), notice=notice, yes=yes)
    if not quiet:
        typer.echo(run_summary(run, output))


@app.command(short_help='What the simulation costs (all-fine Verlet against the hybrid integrator) and what extraction costs per pixel record.')
@user_errors
def bench(
    repeat: int = typer.Option(
        3, help="Timed runs after one warm-up (compilation) run.", callback=checked("an integer >= 1", lambda v: v >= 1)
    ),
    set_: Optional[List[str]] = typer.Option(None, "--set", help=SET_HELP),
    part: str = typer.Option(
        "all", help="all | simulation | extraction (per pixel record and method).",
        callback=checked("one of: all, simulation, extraction", lambda v: v in ("all", "simulation", "extraction")),
    ),  # fmt: skip
    yes: bool = typer.Option(False, "--yes", "-y", help=YES_HELP),
):
    """Time the simulation on the worked example, all-fine Verlet against the hybrid
    integrator: ns per fine step, ms per drive period, seconds per point (approach,
    steady state, recorded window); and the extraction of a scan pixel's record per
    method (CPU ms); medians of the repeated runs, one core."""
    from .bench import check_bench, run_bench, run_extraction_bench
    from .simulation.config import parse_set

    overrides = parse_set(set_)
    check_bench(overrides, repeat, part, yes)  # every config and the cost, before any work
    if part in ("all", "simulation"):
        typer.echo(run_bench(overrides, repeat))
    if part in ("all", "extraction"):
        typer.echo(run_extraction_bench(repeat=max(5, 5 * repeat), overrides=overrides))


def sweep(
    config: Path = typer.Argument(..., help="Study YAML: single-point sections plus a 'sweep:' block (see configs/)."),
    output: Optional[Path] = typer.Option(
        None, "-o", "--output", help="Parquet table to write (default: sweeps/<config name>.parquet)."
    ),
    jobs: Optional[int] = typer.Option(
        None, "--jobs", "-j", show_default=False,
        help="Parallel workers (processes), one core each; more than the cores warns.  Default: 2, or none "
        "(this process) for a study estimated under 8 core-seconds, where starting workers costs more than it saves.",
        callback=checked("an integer >= 1", lambda v: v >= 1),
    ),  # fmt: skip
    backend: str = typer.Option("loky", help="loky (local processes) or dask (a Dask cluster via joblib)."),
    scheduler: Optional[str] = typer.Option(
        None, help="Dask scheduler address, e.g. tcp://host:8786 (with --backend dask; default: a local cluster)."
    ),
    resume: bool = typer.Option(
        True, "--resume/--no-resume", help="Reuse points persisted in <output>.parts/ by an earlier (killed) run."
    ),
    set_: Optional[List[str]] = typer.Option(None, "--set", help=SET_HELP + " Applies to the base; not to swept keys."),
    dry_run: bool = typer.Option(False, "--dry-run", help="Print the points and a cost estimate, run nothing."),
    yes: bool = typer.Option(
        False, "--yes", "-y", help="Start a study over 5000 points or 2 h estimated (otherwise it stops and says so)."
    ),
    keep_parts: bool = typer.Option(False, "--keep-parts", help="Keep <output>.parts/ after a successful sweep."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
):
    """Run a parametric study: simulate every point of the grid, extract it
    with the true and the reconstructed force (extract.force), by a registered
    extraction method (extract.method: [METHODS]; see vetica extract --help), and write one tidy
    table (one row per point, method and force source) plus <name>.config.yaml.
    Points differing only in method or instrument noise share one simulation.

    Prints the acceptance regime at the end: for every combination of the
    other swept keys, the range of surface.cd where the tau_c error is below
    30 % (status ok).  Rows have status ok, no_estimate (steady, but the
    extraction gave no value; why: the error column), not_steady or failed.

    Finished points are kept in <output>.parts/ while the sweep runs; Ctrl-C or
    SIGTERM stops it, a rerun computes only the missing points, and the folder is
    removed after success.  A second sweep on the same output exits at once.
    """
    from .simulation.config import parse_set
    from .study.sweep import sweep_command

    text = sweep_command(config, output, parse_set(set_), dry_run=dry_run, jobs=jobs, yes=yes, backend=backend,
                         scheduler=scheduler, resume=resume, progress=not quiet, keep_parts=keep_parts,
                         log=lambda line: typer.echo(line, err=True))  # fmt: skip
    typer.echo(text)


sweep.__doc__ = sweep.__doc__.replace("[METHODS]", "[" + ", ".join(METHODS) + "]")  # the registry's methods
app.command(short_help="A parametric study: every grid point simulated and extracted, one tidy Parquet table.")(
    user_errors(sweep))


@app.command(short_help='Virtual imaging: a sample map scanned pixel by pixel, every pixel extracted.')
@user_errors
def scan(
    config: Path = typer.Argument(..., help="Scan YAML: probe/operation/numerics/extract plus 'scan:' and 'sample:'."),
    output: Optional[Path] = typer.Option(
        None, "-o", "--output", help="Parquet table to write (default: sweeps/<config name>.parquet, git-ignored)."
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
    keep_parts: bool = typer.Option(False, "--keep-parts", help="Keep <output>.parts/ after success."),
    yes: bool = typer.Option(False, "--yes", "-y", help=YES_HELP),
):
    """Image a heterogeneous sample as a tapping-mode AFM does: scan it line by line, pixel by
    pixel (the cantilever and the controller carry over, the surface under each pixel starts
    undeformed), extract every pixel with every scan.methods, and write one tidy table (one
    row per pixel, method and force source: x, y, height_true, topography, amplitude,
    phase_deg, e_diss_ev, ..., each estimate with _theory and _err_pct, status, error) plus
    <name>.config.yaml and <name>.summary.md (per-domain medians against the truth, apparent
    heights, edge-artefact widths).  A killed scan run again computes only the missing lines;
    Ctrl-C, SIGTERM and SIGHUP stop it as they stop a sweep, a second scan on the same output
    exits at once, and the parts folder is removed after success.
    """
    from .scan.run import scan_command
    from .simulation.config import parse_set

    text = scan_command(config, output, parse_set(set_), dry_run=dry_run, jobs=jobs, backend=backend, yes=yes,
                        scheduler=scheduler, resume=resume, progress=not quiet, keep_parts=keep_parts,
                        log=lambda line: typer.echo(line, err=True))  # fmt: skip
    typer.echo(text)


@app.command(short_help="The thesis's figures from a sweep table or a run; images and profiles of a scan; a fit table's figures.")
@user_errors
def plot(
    table: Path = typer.Argument(..., help="A run (vetica simulate), sweep (vetica sweep), scan (vetica scan) or fit "
                                 "table (vetica fit), Parquet."),
    output: Optional[Path] = typer.Option(
        None, "-o", "--output", help="Folder for the PNG figures (default: figures/ next to TABLE)."
    ),
    cutoff: Optional[float] = typer.Option(
        None,
        "--cutoff",
        help="Low-pass cut-off [Hz] of the force reconstruction and tip velocity of a run; default: Nyquist. "
        "Noisy records need one.",
        callback=checked("a frequency > 0 Hz", lambda v: v > 0),
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
    truth and error, and a line profile.  A fit table (vetica fit) gives each curve's data
    against its fits (when its file is where the table says), histograms of the selected
    parameters and a map of every parameter of each force map.  Files are named
    <table stem>_<figure>.png.
    """
    from .plots import plot as _plot

    result = _plot(table, output, cutoff)
    for note in result.notes:
        typer.echo(f"note: {note}")
    for p in result.paths:
        typer.echo(f"wrote {p}")


def _method_flags() -> dict:
    """``{option name: (Option, methods)}`` of every method option that declares a flag of its
    own (:attr:`~vetica_cli.extraction.base.Option.flag`), in registry order: the flags of
    ``vetica extract`` beside ``--option key=value`` are generated from these declarations."""
    out: dict = {}
    for key, m in METHODS.items():
        for o in m.option_specs:
            if o.flag:
                out.setdefault(o.name, (o, []))[1].append(key)
    return out


METHOD_FLAGS = _method_flags()
FLAG_TYPES = {"int": int, "float": float, "str": str, "bool": bool}


def extract(
    run: Path = typer.Argument(
        ..., help="Parquet written by 'vetica simulate', or any Parquet/CSV with t, z_tip and f_ts or z_paddle."
    ),
    force: str = typer.Option(
        "auto",
        "--force",
        help="Force to analyse: reconstructed (spectral inversion of z_paddle), true (the f_ts column) or "
        "auto (reconstructed when the table has z_paddle, else true).",
    ),
    method: str = typer.Option(
        DEFAULT_METHOD,
        "--method",
        help="Extraction method: " + "; ".join(f"{k} = {m.description}" for k, m in METHODS.items()) + ".",
    ),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object instead of the table."),
    k2: Optional[float] = typer.Option(None, "--k2", help="Paddle stiffness, N/m (data without metadata).",
                                       callback=checked("a stiffness > 0 N/m", lambda v: v > 0)),
    f2: Optional[float] = typer.Option(None, "--f2", help="Paddle resonance, Hz (data without metadata).",
                                       callback=checked("a frequency > 0 Hz", lambda v: v > 0)),
    q2: Optional[float] = typer.Option(None, "--q2", help="Paddle quality factor (data without metadata).",
                                       callback=checked("a quality factor > 0.5", lambda v: v > 0.5)),
    z1: Optional[float] = typer.Option(
        None, "--z1", help="Tip position at the first approach force minimum, m (within the record's z_tip range); "
        "default: from the approach segment.", callback=checked("a finite tip position in m", lambda v: True),
    ),
    f1: Optional[float] = typer.Option(
        None, "--f1", help="Drive frequency, Hz; labels the cut-off in harmonics (and is observables' f1).",
        callback=checked("a frequency > 0 Hz", lambda v: v > 0),
    ),
    cutoff: Optional[str] = typer.Option(
        None, "--cutoff", help="Low-pass cut-off of the force reconstruction: auto (default: where the inverted noise "
        "meets the force's drive harmonics, measured on the record), nyquist (the whole sampled band), or a frequency "
        "in Hz.", callback=_cutoff_option,
    ),
    a0: Optional[float] = typer.Option(
        None, "--a0", help="Intermolecular distance a0, m (default: the metadata's): Z1 = a0 (thesis eq. 84) for a "
        "record without approach segment, z_tip measured from the undeformed surface; --method full fits with it "
        "(else 0.2 nm assumed).", callback=checked(limit("surface.a0", "a distance")[1], limit("surface.a0", "")[0]),
    ),
    vdw_on_surface: Optional[bool] = typer.Option(
        None, "--vdw-on-surface/--no-vdw-on-surface",
        help="Whether the surface feels the tip's van der Waals pull (Z1 = a0 + Fa(a0)/Kg when it does; the pre-stress "
        "of vetica-prestress); default: the metadata's; --method full fits both and keeps the better when unknown.",
    ),
    contact: Optional[List[str]] = typer.Option(
        None, "--contact", help="Contact constant of the material units, key=value (repeatable): tip_radius (m), nu_tip, "
        "nu_sample, e_tip (Pa); default thesis table 6 (R = the metadata's tip radius, else 10 nm).",
    ),
    option: Optional[List[str]] = typer.Option(
        None, "--option", help="A method option, key=value (repeatable), as the method declares it (name, type, unit): "
        "e.g. --option arms=2 --option state=free for --method full; an unknown one lists the method's options.",
    ),
    **flags,
):  # fmt: skip
    """Extract a surface's parameters from a run with a registered method (--method):
    VETICA's tau_c, Kg, Kr, tau_r, k0, k_inf, cd by default; the whole-cycle fit's parameters
    of the SLS, Wiechert or Hertzian surface (full); the instrument's observables; per-tap
    force-curve numbers -- and the material units where the method gives stiffnesses: DMT,
    glassy and rubbery moduli [Pa] and viscosity [Pa s] (thesis 4.6.2, eqs. 90-92).

    Prints value, theory and error % (theory known only when the file's
    metadata holds the surface parameters), the spread over taps (or the fit's
    uncertainty), what was fitted and what assumed, the force-reconstruction error
    against f_ts when both are present, and the extraction time.  A CSV or Parquet
    with only t, z_tip and f_ts (or z_paddle with --k2 --f2 --q2) is read as
    measured: Z1 from --z1, else from --a0 (thesis eq. 84) with
    --vdw-on-surface/--no-vdw-on-surface.  A method's options are set with --option
    key=value; the flags after --option are shortcuts the methods declare.
    """
    import json

    from .errors import InputError
    from .extraction import extract_file
    from .extraction.format import format_table, to_json
    from .extraction.material import parse_contact

    from .extraction import RecordInputs
    from .simulation.config import parse_set

    inputs = RecordInputs.of({"k2": k2, "f2": f2, "q2": q2, "z1": z1, "f1": f1, "cutoff": cutoff, "a0": a0,
                              "vdw_on_surface": vdw_on_surface}, {"cutoff_hz": "cutoff"})  # fmt: skip
    if method not in METHODS:
        raise InputError(f"--method {method!r} is not allowed; choose one of: {', '.join(METHODS)}")
    m = METHODS[method]
    opts = {}
    for name, value in flags.items():  # a flag's number is checked against the method's declaration of it here
        o = m.option(name)
        if value is not None:
            opts[name] = o.parse(value, METHOD_FLAGS[name][0].flag) if o is not None and o.type != "str" else value
    given = m.parse_options(parse_set(option, "--option"))
    both = sorted(set(given) & set(opts))
    if both:
        raise InputError(f"--option {both[0]} and {METHOD_FLAGS[both[0]][0].flag} both given; give one of them")
    res = extract_file(run, force=force, method=method, inputs=inputs, contact=parse_contact(contact),
                       **{**opts, **given})  # fmt: skip
    typer.echo(json.dumps(to_json(res), allow_nan=False) if json_out else format_table(res, run))


def _flag_parameter(name: str, o, methods: list) -> "inspect.Parameter":
    """The ``vetica extract`` parameter of a method option's own flag (its help from the declaration)."""
    import inspect

    unit = f" [{o.unit}]" if o.unit else ""
    help_ = f"{', '.join(methods)}: {o.help}{unit}; as --option {name}=VALUE."
    return inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, annotation=Optional[FLAG_TYPES[o.type]],
                             default=typer.Option(None, o.flag, help=help_, show_default=False))  # fmt: skip


def _register_extract() -> None:
    """``vetica extract``: its fixed parameters, then one flag per declared method option."""
    import inspect

    sig = inspect.signature(extract)
    fixed = [p for p in sig.parameters.values() if p.kind != inspect.Parameter.VAR_KEYWORD]
    fixed = [p.replace(annotation=_HINTS[p.name]) for p in fixed]
    extract.__signature__ = sig.replace(parameters=fixed + [_flag_parameter(n, o, ms) for n, (o, ms) in METHOD_FLAGS.items()])
    extract.__annotations__ = {}
    app.command(name="extract", short_help="A surface's parameters from a run or a measured record, by a registered "
                "method.")(user_errors(extract))  # fmt: skip


_HINTS = {"run": Path, "force": str, "method": str, "json_out": bool, "k2": Optional[float], "f2": Optional[float],
          "q2": Optional[float], "z1": Optional[float], "f1": Optional[float], "cutoff": Optional[str],
          "a0": Optional[float], "vdw_on_surface": Optional[bool], "contact": Optional[List[str]],
          "option": Optional[List[str]]}  # fmt: skip
_register_extract()


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


@app.command(short_help='Which f1, set point, print step and paddle stiffness recover a material.')
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
    temperature: str = typer.Option("300", "--temperature", help="Thermal noise of the records, K (0 = noise-free, "
                                    "the thesis's records; an instrument's are at ~300 K)."),  # fmt: skip
    set_: Optional[List[str]] = typer.Option(None, "--set", help="Probe/operation/numerics key of the base, e.g. "
                                             "--set probe.k1=5 (not a knob, not the material)."),  # fmt: skip
    jobs: int = typer.Option(2, "--jobs", "-j", help="Parallel workers (processes), one core each."),
    replicas: int = typer.Option(1, "--replicas", help="Noisy records per setting (1..50): medians of their errors "
                                 "and sigmas, a quantity flagged when more than half flag it."),
    output: Path = typer.Option(Path("advise.png"), "-o", "--output", help="PNG of the map to write."),
    table: Optional[Path] = typer.Option(None, "--table", help="Also write every setting's row as Parquet."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object: {\"settings\": [...], ...}."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
    yes: bool = typer.Option(False, "--yes", "-y", help=YES_HELP),
):
    """Which settings make the extraction work for a material: a small study over the
    drive frequency (f2 = 15 f1), set point, print step and paddle stiffness within the
    thesis's ranges, each setting simulated to its periodic state and extracted by every
    method of --methods; prints the settings under which all of them recover the material
    (tau_c error < 30 %, k0, k_inf, cd within 5 %, each with its 2-sigma error bar, and no
    estimate flagged), ranked by margin, and draws the map.  The records carry the thermal
    noise of --temperature (300 K by default).
    The keys of --json's settings can be passed to vetica simulate --set.
    """
    import json

    from .extraction.material import parse_contact
    from .simulation.config import parse_set
    from .advise import advice_json, contact_for, format_advice, material_from
    from .advise import advise as run_advice

    overrides = parse_set(set_)
    if "numerics.temperature" in overrides:
        from .errors import ConfigError

        raise ConfigError("--set numerics.temperature: give the records' temperature with --temperature")
    overrides["numerics.temperature"] = _number("--temperature", temperature)
    cm = contact_for(overrides, parse_contact(contact))
    material = material_from(_number("--k-inf", k_inf), _number("--k0", k0), _number("--cd", cd),
                             _number("--e-glassy", e_glassy), _number("--e-rubbery", e_rubbery),
                             _number("--tau-r", tau_r), _number("--depth", depth), cm)  # fmt: skip
    knobs = {"probe.f1": _numbers("--f1", f1), "operation.setpoint": _numbers("--setpoint", setpoint),
             "numerics.print_step": _numbers("--print-step", print_step), "probe.k2": _numbers("--k2", k2)}  # fmt: skip
    from .io import check_output_file, write_table

    check_output_file(output, "-o", ".png")  # every output checked before the work (minutes)
    if table is not None:
        check_output_file(table, "--table", ".parquet")
    adv = run_advice(material, overrides, knobs, [m.strip() for m in methods.split(",") if m.strip()], force, jobs,
                     progress=not (quiet or json_out), yes=yes, replicas=replicas)  # fmt: skip
    from .plots.advise import write_advice_figure  # matplotlib and pandas: after the inputs and the study

    figure = write_advice_figure(adv, output)
    if table is not None:
        try:
            write_table(adv.table, table, advice_json(adv, figure))
        except BaseException:  # nothing half-written: the figure goes with the table
            Path(figure).unlink(missing_ok=True)
            raise
    typer.echo(json.dumps(advice_json(adv, figure), allow_nan=False) if json_out else format_advice(adv, figure))


@app.command(short_help='Viscoelastic fits of measured force curves and maps.')
@user_errors
def fit(
    curves: List[Path] = typer.Argument(..., help="Force-curve files (force-distance, stress relaxation, creep; any "
                                        "format afmformats reads, and JPK text exports) or folders of them."),
    tip_radius: Optional[float] = typer.Option(None, "--tip-radius", help="Radius R [m] of the spherical tip "
                                               "(required; 0.5 nm to 100 um)."),
    modulus: str = typer.Option("power-law", "--modulus", help="Force-distance curves: power-law (E = e0 (t/1 s)^-beta) "
                                "or maxwell (e_inf + 1-3 arms e_i exp(-t/tau_i))."),
    nu: float = typer.Option(0.5, "--nu", help="Poisson ratio of the sample (default 0.5, incompressible)."),
    meta: Optional[List[str]] = typer.Option(None, "--meta", help="Metadata a file lacks or gets wrong, KEY=VALUE "
                                             "(repeatable): spring_constant (N/m), sensitivity (m/V), rate (Hz)."),
    height: str = typer.Option("measured", "--height", help="Height channel: measured (closed-loop sensor) or piezo."),
    criterion: str = typer.Option("bic", "--criterion", help="Arm-count selection: bic or aic."),
    window: str = typer.Option("dwell", "--window", help="Dwell curves: residuals on the dwell (approach as loading "
                               "history; contact from the approach) or all."),
    points: int = typer.Option(400, "--points", help="Force-distance curves: grid points the curve is binned to "
                               "(50-5000; the fit's cost grows as their square)."),
    output: Path = typer.Option(Path("fit.parquet"), "-o", "--output", help="Parquet table to write (checked first)."),
    figures: Optional[Path] = typer.Option(None, "--figures", help="Folder for the figures (fits, histograms, maps)."),
    jobs: int = typer.Option(2, "--jobs", "-j", help="Parallel worker processes; more than the cores warns; a small "
                             "batch runs in this process.", callback=checked("an integer >= 1", lambda v: v >= 1)),
    resume: bool = typer.Option(True, "--resume/--no-resume", help="Reuse curves persisted in <output>.parts/ by an "
                                "earlier (killed) run."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar or summary."),
):  # fmt: skip
    """Fit viscoelastic models to measured force curves (pip install -e ".[formats]").

    Force-distance curves (approach and retract; single curves, force maps, QI data): Ting's
    viscoelastic Hertz contact through loading and unloading with a power-law modulus (e0, beta)
    or Maxwell arms, and the approach's elastic Hertz modulus e_hertz beside it.  Dwell curves
    (stress relaxation, creep): Lee-Radok with 1-3 Maxwell arms.  One row per curve (and arm
    count) with standard errors, the contact, AIC, BIC, selected, status (ok, or why not) and
    error; a file that cannot be read or fitted is a row with its reason and the rest go on.
    Units in the Parquet metadata.  Ctrl-C, SIGTERM and SIGHUP stop it; a rerun fits only the
    missing curves.
    """
    from .curves.batch import fit_files

    res = fit_files(curves, tip_radius, output, figures, nu=nu, height=height, criterion=criterion, window=window,
                    modulus=modulus, points=points, meta=meta, jobs=jobs, progress=not quiet, resume=resume,
                    log=lambda line: typer.echo(line, err=True))  # fmt: skip
    if not quiet:
        typer.echo(res.summary(criterion))


@app.command(short_help='Maps to NetCDF and Gwyddion.')
@user_errors
def export(
    table: Path = typer.Argument(..., help="A map table: a scan (vetica scan) or a force-map fit (vetica fit)."),
    output: Path = typer.Option(..., "-o", "--output", help="File to write: .nc (NetCDF), .gwy (Gwyddion) or .gsf "
                                "(Gwyddion Simple Field; one file per channel when several)."),
    quantity: Optional[List[str]] = typer.Option(None, "--quantity", help="Only this column (repeatable); default: "
                                                 "every numeric column."),
):  # fmt: skip
    """Write a scan or a force map out of Parquet for the tools AFM users open
    (pip install -e ".[export]"): NetCDF through xarray (every column a variable with its
    units and description), Gwyddion .gwy (one channel per quantity and pass, method, force
    source or file) or .gsf.  The variant dimensions are pass, extraction_method,
    force_source (scans) and file (fits); the image axes y, x.
    """
    from .export import export as _export

    for p in _export(table, output, quantity):
        typer.echo(f"wrote {p}")


def main():  # pragma: no cover - console script entry
    """Run the app.  Ctrl-C outside a command's body (typer's parsing, option callbacks: typer
    turns it into a silent exit 130) is reported in one line like any other interrupt."""
    try:
        app()
    except KeyboardInterrupt:  # Ctrl-C while the modules load: nothing has been written
        sys.stderr.write(INTERRUPTED_EARLY + "\n")
        interrupt_handled()
        sys.exit(130)
    except SystemExit as exc:
        if exc.code in (0, None) and not _REPORTED:  # the command finished: a Ctrl-C from here on interrupts nothing
            signal.signal(signal.SIGINT, signal.SIG_IGN)  # (one during the interpreter's shutdown ended it by
            interrupt_handled()  # SIGINT, status -2, after a sweep had written its table)
        if exc.code == 130 and not _REPORTED:
            sys.stderr.write(INTERRUPTED_EARLY + "\n")
        if exc.code == 130 or _REPORTED:  # an interrupt ended the command (a normal exit needs no ctypes)
            interrupt_handled()
        raise


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
