"""Every bad input fails fast: exit status 2, one line on stderr starting ``error:``, no
traceback, nothing on stdout and nothing written -- for the cases a new user met (each
named below) and for malformed configs, option values and input files that hypothesis
generates.

A generated input is bad by construction: a value that the key's documented rule (its
type; ``vetica_cli.simulation.config.RULES``, the surface model's ``rules``) rejects, a
key or section that does not exist, a file with a cell that is not a number, a missing
column, a truncated Parquet file...  What is tested is the command's behaviour on it, not
the rule.  Each run happens in a fresh folder whose listing must not change.
"""

import math
import os
import string
import tempfile
from contextlib import contextmanager
from dataclasses import fields
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from vetica_cli import surfaces
from vetica_cli.cli import app
from vetica_cli.io import write_run
from vetica_cli.simulation import simulate as simulate_module
from vetica_cli.simulation.config import RULES, SECTIONS, load
from vetica_cli.surfaces import COMMON_KEYS

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()
PROPERTY = settings(max_examples=int(os.environ.get("VETICA_PROPERTY_EXAMPLES", "60")), deadline=None, suppress_health_check=[HealthCheck.too_slow])


@contextmanager
def folder():
    """A fresh folder; yields it and checks on exit that nothing appeared in it that the
    test did not put there (the test lists its own files in ``mine``)."""
    with tempfile.TemporaryDirectory() as d:
        yield Path(d)


def listing(d: Path) -> set:
    return {str(p.relative_to(d)) for p in d.rglob("*")}


def refused(args, d: Path, *fragments):
    """Run ``vetica ARGS`` in folder ``d``: exit 2, one line ``error: ...`` naming the
    fragments, no traceback, nothing on stdout, nothing new in ``d``."""
    before = listing(d)
    cwd = os.getcwd()
    os.chdir(d)  # a default output (run.parquet, sweeps/...) would land here
    try:
        r = runner.invoke(app, [str(a) for a in args])
    finally:
        os.chdir(cwd)
    assert r.exception is None or isinstance(r.exception, SystemExit), repr(r.exception)
    assert r.exit_code == 2, (args, r.output)
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), (args, r.stderr)
    assert "Traceback" not in r.output and r.stdout == "", (args, r.output)
    for f in fragments:
        assert f in lines[0], (args, lines[0])
    assert listing(d) == before, (args, listing(d) - before)
    return lines[0]


# --------------------------------------------------------------------- a small valid record


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    """A valid cheap run (Parquet) and its steady record as CSV text (t, z_tip, f_ts), from
    which the file strategies make broken copies."""
    d = tmp_path_factory.mktemp("record")
    run = simulate_module.simulate(load(None, {"numerics.dt": 0.05e-9, "numerics.print_step": 1e-9,
                                               "numerics.record_cycles": 3}))  # fmt: skip
    path = d / "run.parquet"
    write_run(run, path)
    df = run.frame()
    steady = df[(df.segment == "steady").to_numpy()][["t", "z_tip", "f_ts"]]
    return {"parquet": path, "csv": steady.to_csv(index=False), "z1": run.observables["z1"],
            "zmin": float(steady.z_tip.min()), "zmax": float(steady.z_tip.max())}  # fmt: skip


def test_the_valid_record_extracts(record):
    """The base of the file strategies is good: its breakage is what is refused."""
    with folder() as d:
        (d / "ok.csv").write_text(record["csv"])
        r = runner.invoke(app, ["extract", str(d / "ok.csv"), "--z1", repr(record["z1"])])
        assert r.exit_code == 0, r.output


# --------------------------------------------------------------------- the cases met by a new user and those found, named

CASES = [
    # (what, argv builder taking (folder, record), fragments of the message)
    ("simulate -o into /proc", lambda d, r: ["simulate", "-o", "/proc/x.parquet"], ["/proc"]),
    ("sweep -o into /proc", lambda d, r: ["sweep", ROOT / "configs/smoke.yaml", "-o", "/proc/x.parquet"], ["/proc"]),
    ("plot -o into /proc", lambda d, r: ["plot", r["parquet"], "-o", "/proc/figs"], ["/proc"]),
    ("simulate -o an existing folder", lambda d, r: ["simulate", "-o", d / "adir"], ["existing folder"]),
    ("plot -o an existing file", lambda d, r: ["plot", r["parquet"], "-o", d / "afile.txt"], ["existing file"]),
    ("extract a CSV with a non-numeric value", lambda d, r: ["extract", d / "bad.csv", "--z1", "2e-10"],
     ["'z_tip'", "'abc' is not a number"]),
    ("extract --z1 nan", lambda d, r: ["extract", r["parquet"], "--z1", "nan"], ["--z1", "nan"]),
    ("extract --z1 -1", lambda d, r: ["extract", r["parquet"], "--z1", "-1"], ["--z1", "z_tip range"]),
    ("extract --kg-points 100000", lambda d, r: ["extract", r["parquet"], "--kg-points", "100000"],
     ["kg_points 100000", "expected an integer in [2, "]),
    ("extract a folder", lambda d, r: ["extract", d / "adir"], ["is a folder"]),
    ("simulate a folder as config", lambda d, r: ["simulate", d / "adir", "-o", d / "x.parquet"], ["is a folder"]),
    ("sweep a folder as config", lambda d, r: ["sweep", d / "adir", "-o", d / "x.parquet"], ["is a folder"]),
    ("sweep --jobs 0", lambda d, r: ["sweep", ROOT / "configs/smoke.yaml", "--jobs", "0", "-o", d / "x.parquet"],
     ["--jobs"]),
    ("sweep --jobs abc", lambda d, r: ["sweep", ROOT / "configs/smoke.yaml", "--jobs", "abc"], ["--jobs"]),
    ("extract --cutoff 0", lambda d, r: ["extract", r["parquet"], "--cutoff", "0"], ["--cutoff"]),
    ("extract --q2 0.5", lambda d, r: ["extract", r["parquet"], "--q2", "0.5"], ["--q2"]),
    ("extract --k2 inf", lambda d, r: ["extract", r["parquet"], "--k2", "inf"], ["--k2"]),
    ("an unknown option", lambda d, r: ["extract", r["parquet"], "--nope"], ["--nope"]),
    ("an unknown command", lambda d, r: ["simulat"], ["simulat"]),
    ("a missing argument", lambda d, r: ["extract"], ["Missing argument"]),
    ("simulate -o not .parquet", lambda d, r: ["simulate", "-o", d / "run.csv"], [".parquet"]),
    ("simulate -o under a file", lambda d, r: ["simulate", "-o", d / "afile.txt" / "x.parquet"], ["is a file"]),
    ("simulate -o a name too long", lambda d, r: ["simulate", "-o", d / ("x" * 300 + ".parquet")], ["-o"]),
    ("simulate a config too long a name", lambda d, r: ["simulate", d / ("x" * 300 + ".yaml")], ["config file"]),
    ("simulate a binary config", lambda d, r: ["simulate", d / "bin.yaml", "-o", d / "x.parquet"], ["UTF-8"]),
    ("extract a truncated Parquet", lambda d, r: ["extract", d / "cut.parquet"], ["not a readable Parquet"]),
    ("extract an empty CSV", lambda d, r: ["extract", d / "empty.csv"], ["not a readable CSV"]),
    ("sweep with parts folder taken by a file", lambda d, r: ["sweep", ROOT / "configs/smoke.yaml", "-o",
     d / "afile.parquet"], ["parts folder"]),
    ("sweep --scheduler without dask", lambda d, r: ["sweep", ROOT / "configs/smoke.yaml", "--scheduler", "tcp://x:1",
     "-o", d / "x.parquet"], ["--scheduler needs --backend dask"]),
    # found while hardening (tracebacks or nonsense accepted on main)
    ("an integer key set to .nan", lambda d, r: ["simulate", "--set", "numerics.record_cycles=.nan", "-o",
     d / "x.parquet"], ["numerics.record_cycles", "integer"]),
    ("a number beyond the float range", lambda d, r: ["simulate", "--set", "probe.f1=1" + "0" * 400, "-o",
     d / "x.parquet"], ["probe.f1", "finite"]),
    ("a logspace count of .nan", lambda d, r: ["sweep", d / "nan.yaml", "-o", d / "x.parquet"], ["logspace count"]),
    ("a section that is 0", lambda d, r: ["simulate", d / "zero.yaml", "-o", d / "x.parquet"], ["'probe' must be a mapping"]),
    ("a record too long for memory", lambda d, r: ["simulate", "--set", "numerics.record_cycles=5000", "--set",
     "numerics.max_time=1e6", "-o", d / "x.parquet"], ["numerics.record_cycles", "at most 312 periods"]),
    ("plot a CSV", lambda d, r: ["plot", d / "bad.csv", "-o", d / "figs"], ["is not a number"]),
    ("bench --repeat 0", lambda d, r: ["bench", "--repeat", "0"], ["--repeat"]),
    ("sweep --backend spark", lambda d, r: ["sweep", ROOT / "configs/smoke.yaml", "--backend", "spark", "-o",
     d / "x.parquet"], ["--backend 'spark'"]),
    ("extract --method fancy", lambda d, r: ["extract", r["parquet"], "--method", "fancy"], ["fancy"]),
    ("extract --force measured", lambda d, r: ["extract", r["parquet"], "--force", "measured"], ["measured"]),
]  # fmt: skip


def _setup_issue_files(d: Path, record) -> None:
    (d / "adir").mkdir()
    (d / "afile.txt").write_text("x")
    (d / "afile.parquet.parts").write_text("x")
    lines = record["csv"].splitlines()
    t, z, f = lines[501].split(",")
    lines[501] = ",".join([t, "abc", f])
    (d / "bad.csv").write_text("\n".join(lines) + "\n")
    (d / "bin.yaml").write_bytes(b"\xff\xfe\x00probe: {f1: 1}\n")
    (d / "cut.parquet").write_bytes(Path(record["parquet"]).read_bytes()[:5000])
    (d / "empty.csv").write_text("")
    (d / "nan.yaml").write_text("sweep:\n  surface.cd: {logspace: [-5, 3, .nan]}\n")
    (d / "zero.yaml").write_text("probe: 0\nnumerics: {record_cycles: 1, print_step: 1.0e-9}\n")


@pytest.mark.parametrize("what, argv, fragments", CASES, ids=[c[0] for c in CASES])
def test_each_listed_bad_input_is_refused_with_one_line(record, what, argv, fragments):
    with folder() as d:
        _setup_issue_files(d, record)
        refused(argv(d, record), d, *fragments)


def test_simulate_checks_its_output_before_it_simulates(monkeypatch):
    """An unwritable -o fails at once: the simulation is never started (it used to fail after it)."""

    def must_not_run(cfg):
        raise AssertionError("simulate() ran before the output was checked")

    monkeypatch.setattr(simulate_module, "simulate", must_not_run)
    with folder() as d:
        refused(["simulate", "-o", "/proc/x.parquet"], d, "/proc")


def test_stiffness_ratio_works_in_simulate_as_in_a_sweep():
    """surface.stiffness_ratio (a derived key) is accepted by simulate's config and --set,
    as in a study: k0 = ratio * k_inf (thesis 4.4.2)."""
    assert load(None, {"surface.stiffness_ratio": 16}).surface.k0 == 64.0
    assert load(None, {"surface.k_inf": 2.0, "surface.stiffness_ratio": 8}).surface.k0 == 16.0
    with folder() as d:
        cfg = d / "p.yaml"
        cfg.write_text("surface: {k_inf: 4.0, stiffness_ratio: 32}\n")
        assert load(cfg).surface.k0 == 128.0
        cfg.write_text("surface: {k0: 4.0, stiffness_ratio: 32}\n")
        refused(["simulate", cfg, "-o", d / "x.parquet"], d, "set one of them")
        refused(["simulate", "--set", "surface.stiffness_ratio=-2", "-o", d / "x.parquet"], d, "ratio > 0")


def test_help_prints_brackets_as_written_and_version_prints():
    """Help is plain text: '[vetica, full]' is not eaten as markup (it was, in sweep --help)."""
    r = runner.invoke(app, ["sweep", "--help"])
    from vetica_cli.extraction import METHODS

    assert r.exit_code == 0 and f"extract.method: [{', '.join(METHODS)}]" in " ".join(r.output.split())
    assert "--keep-parts" in r.output and "--yes" in r.output
    r = runner.invoke(app, ["--version"])
    assert r.exit_code == 0 and r.stdout.strip().startswith("vetica 0.")


# --------------------------------------------------------------------- generated configs

# every scalar config key with its declared type and its rule (what the user is told)
KEYS = {}
for sec, cls in SECTIONS.items():
    if sec == "surface":
        continue
    for fld in fields(cls):
        KEYS[f"{sec}.{fld.name}"] = (str(fld.type), RULES.get(f"{sec}.{fld.name}"))
_SLS = surfaces.get("sls")
for name in _SLS.config_keys:
    KEYS[f"surface.{name}"] = ("float", _SLS.rules.get(name))
for name, spec in COMMON_KEYS.items():
    KEYS[f"surface.{name}"] = (spec.type, spec.rule)

JUNK = st.one_of(
    st.text(alphabet=string.ascii_letters + "-_ ", min_size=1, max_size=8).filter(lambda s: s.strip()),
    st.integers(min_value=10**309, max_value=10**400),  # beyond the float range
    st.lists(st.integers(-3, 3), min_size=1, max_size=3),
    st.dictionaries(st.sampled_from(["a", "b"]), st.integers(0, 3), min_size=1, max_size=2),
)
NON_FINITE = st.sampled_from([math.nan, math.inf, -math.inf])


def _is_number_text(v) -> bool:
    try:
        float(v)
        return True
    except (TypeError, ValueError):
        return False


@st.composite
def bad_value(draw, key):
    """A value of ``key`` its type or its rule rejects."""
    tp, rule = KEYS[key]
    kind = draw(st.sampled_from(["junk", "range"] if rule is not None and tp != "str" else ["junk"]))
    if tp == "bool":
        return draw(st.one_of(st.integers(2, 9), st.floats(allow_nan=False), JUNK).filter(
            lambda v: str(v).lower() not in ("true", "false", "yes", "no", "on", "off", "y", "n")))
    if tp == "str":
        allowed = set(rule[1].split(": ")[1].split(", ")) if rule else set()
        return draw(st.one_of(st.text(string.ascii_lowercase, min_size=1, max_size=8), st.integers(), st.floats())
                    .filter(lambda v: v not in allowed))  # fmt: skip
    if kind == "junk":
        v = draw(st.one_of(JUNK, NON_FINITE, st.booleans()))
        assume(not (isinstance(v, str) and _is_number_text(v) and math.isfinite(float(v))))
        if tp == "float | None":
            assume(v is not None)
        return v
    pred, _ = rule
    number = st.integers(-10**6, 10**6) if tp == "int" else st.floats(-1e6, 1e6, allow_nan=False)
    v = draw(st.one_of(number, st.sampled_from([0, -1, 1, 1.5, -1e-12, 0.5, 2.0])))
    if tp == "int" and isinstance(v, float) and v != int(v):
        v = int(v)
    assume(not pred(v))
    return v


@st.composite
def bad_config(draw):
    """A one-point config with exactly one thing wrong: a bad value, an unknown key or an
    unknown section.  Returns ``(yaml text, what is wrong)``."""
    d: dict = {"numerics": {"record_cycles": 2, "print_step": 1e-9}}
    what = draw(st.sampled_from(["value", "value", "value", "key", "section", "shape"]))
    if what == "value":
        key = draw(st.sampled_from(sorted(KEYS)))
        sec, name = key.split(".")
        d.setdefault(sec, {})[name] = draw(bad_value(key))
        return d, key
    if what == "key":
        sec = draw(st.sampled_from(list(SECTIONS)))
        name = draw(st.text(string.ascii_lowercase + "_", min_size=1, max_size=10))
        assume(f"{sec}.{name}" not in KEYS and name not in ("model", "stiffness_ratio", "f2_ratio"))
        d.setdefault(sec, {})[name] = 1.0
        return d, f"{sec}.{name}"
    if what == "section":
        sec = draw(st.text(string.ascii_lowercase, min_size=1, max_size=10))
        assume(sec not in SECTIONS and sec != "sweep")
        d[sec] = {"a": 1}
        return d, sec
    sec = draw(st.sampled_from(list(SECTIONS)))
    d[sec] = draw(st.one_of(st.integers(), st.text(min_size=1, max_size=5), st.lists(st.integers(), min_size=1)))
    return d, sec


@PROPERTY
@given(case=bad_config(), via_set=st.booleans())
def test_malformed_configs_are_refused_before_any_simulation(case, via_set):
    d, what = case
    with folder() as tmp:
        out = tmp / "run.parquet"
        if via_set and all(isinstance(v, dict) for v in d.values()):
            sets = [a for sec, body in d.items() for k, v in body.items()
                    for a in ("--set", f"{sec}.{k}={yaml.safe_dump(v, default_flow_style=True).strip().removesuffix(chr(10) + '...')}")]  # fmt: skip
            refused(["simulate", *sets, "-o", out, "-q"], tmp)
        else:
            cfg = tmp / "bad.yaml"
            cfg.write_text(yaml.safe_dump(d))
            refused(["simulate", cfg, "-o", out, "-q"], tmp)


@st.composite
def bad_sweep(draw):
    """A study config whose sweep block is malformed or holds one value a rule rejects."""
    base = {"numerics": {"dt": 0.05e-9, "print_step": 1e-9, "record_cycles": 2, "max_time": 0.002}}
    kind = draw(st.sampled_from(["value", "value", "unknown", "range", "zip", "empty", "derived"]))
    good = {"surface.cd": [1e-5, 1e-4]}
    if kind == "value":
        key = draw(st.sampled_from([k for k, (tp, _) in KEYS.items() if tp in ("float", "int", "float | None")]))
        values = [draw(bad_value(key))]
        sweep = {**good, key: values} if key != "surface.cd" else {key: values}
    elif kind == "unknown":
        name = draw(st.text(string.ascii_lowercase + ".", min_size=1, max_size=12))
        assume(name not in KEYS and name not in ("zip",))
        sweep = {**good, name: [1, 2]}
    elif kind == "range":
        form = draw(st.sampled_from(["logspace", "linspace"]))
        args = draw(st.one_of(
            st.lists(st.floats(-5, 5), max_size=5).filter(lambda a: len(a) != 3),
            st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.sampled_from([0, -1, 2.5, "x", None])).map(list),
            st.tuples(st.sampled_from(["a", None, math.nan]), st.floats(-5, 5), st.integers(2, 5)).map(list),
        ))  # fmt: skip
        sweep = {"surface.cd": {form: args}}
    elif kind == "zip":
        n = draw(st.integers(1, 4))
        sweep = {"zip": {"surface.cd": [1e-5] * n, "operation.setpoint": [0.5] * (n + draw(st.integers(1, 3)))}}
    elif kind == "empty":
        sweep = draw(st.sampled_from([None, {}, {"surface.cd": []}, [1, 2], "x"]))
    else:
        sweep = {"surface.stiffness_ratio": [draw(st.sampled_from([0, -1, "x", math.inf]))]}
    return {**base, "sweep": sweep}


@PROPERTY
@given(study=bad_sweep(), dry=st.booleans())
def test_malformed_studies_are_refused_before_any_point_runs(study, dry):
    with folder() as tmp:
        cfg = tmp / "study.yaml"
        cfg.write_text(yaml.safe_dump(study))
        out = tmp / "o" / "study.parquet"
        refused(["sweep", cfg, "-o", out, "-q", *(["--dry-run"] if dry else [])], tmp)


# --------------------------------------------------------------------- generated option values

OPTIONS = {
    "--z1": st.one_of(NON_FINITE, st.floats(1e-6, 1e3), st.floats(-1e3, -1e-6)),
    "--kg-points": st.one_of(st.integers(-5, 1), st.integers(10**6, 10**9)),
    "--cutoff": st.one_of(NON_FINITE, st.floats(-1e12, 0)),
    "--k2": st.one_of(NON_FINITE, st.floats(-1e3, 0)),
    "--f2": st.one_of(NON_FINITE, st.floats(-1e7, 0)),
    "--q2": st.one_of(NON_FINITE, st.floats(-10, 0.5)),
    "--f1": st.one_of(NON_FINITE, st.floats(-1e7, 0)),
    "--force": st.text(string.ascii_lowercase, min_size=1, max_size=8).filter(
        lambda s: s not in ("auto", "true", "reconstructed")),
    "--method": st.text(string.ascii_lowercase, min_size=1, max_size=8).filter(lambda s: s not in ("vetica", "full")),
}


@PROPERTY
@given(option=st.sampled_from(sorted(OPTIONS)), data=st.data(), text=st.booleans())
def test_nonsense_option_values_are_refused(record, option, data, text):
    """Each extract option outside its range (or not a number at all) exits 2 before the
    extraction: --z1 outside the record's tip range, --kg-points beyond every contact ..."""
    value = data.draw(OPTIONS[option])
    if option == "--z1" and isinstance(value, float) and math.isfinite(value):
        assume(not record["zmin"] <= value <= record["zmax"])
    if text and option not in ("--force", "--method"):
        value = data.draw(st.text(string.ascii_letters, min_size=1, max_size=6).filter(
            lambda s: not _is_number_text(s)))  # fmt: skip
    with folder() as tmp:
        refused(["extract", record["parquet"], option, repr(value) if isinstance(value, float) else value], tmp)


@PROPERTY
@given(jobs=st.one_of(st.integers(-50, 0), st.text(string.ascii_letters, min_size=1, max_size=4)),
       backend=st.text(string.ascii_lowercase, min_size=1, max_size=6))  # fmt: skip
def test_nonsense_sweep_options_are_refused(jobs, backend):
    with folder() as tmp:
        out = tmp / "o.parquet"
        refused(["sweep", ROOT / "configs/smoke.yaml", "-o", out, "--jobs", jobs], tmp)
        assume(backend not in ("loky", "dask"))
        refused(["sweep", ROOT / "configs/smoke.yaml", "-o", out, "--backend", backend], tmp)


# --------------------------------------------------------------------- generated broken files


@st.composite
def broken_csv(draw, csv_text):
    """The valid record's CSV with one defect: a cell that is not a number, an empty or
    non-finite cell, a required column gone, time going backwards, only the header,
    garbage bytes."""
    lines = csv_text.splitlines()
    kind = draw(st.sampled_from(["token", "nan", "column", "time", "header", "garbage", "blank"]))
    if kind == "garbage":
        return draw(st.binary(min_size=1, max_size=200)), kind
    if kind == "header":
        return (lines[0] + "\n").encode(), kind
    if kind == "column":
        drop = draw(st.sampled_from([0, 1, 2]))
        return ("\n".join(",".join(c for j, c in enumerate(ln.split(",")) if j != drop) for ln in lines) + "\n").encode(), kind
    i = draw(st.integers(1, len(lines) - 1))
    cells = lines[i].split(",")
    j = draw(st.integers(0, 2))
    if kind == "token":
        cells[j] = draw(st.text(string.ascii_letters + "#$%", min_size=1, max_size=5).filter(lambda s: not _is_number_text(s)))
    elif kind == "nan":
        cells[j] = draw(st.sampled_from(["nan", "inf", "-inf", "NaN"]))
    elif kind == "blank":
        cells[j] = ""
    else:  # time: this sample repeats the previous one's time
        prev = lines[i - 1].split(",")[0] if i > 1 else lines[2].split(",")[0]
        cells[0] = prev
    lines[i] = ",".join(cells)
    return ("\n".join(lines) + "\n").encode(), kind


@PROPERTY
@given(data=st.data())
def test_broken_csv_files_are_refused(record, data):
    body, kind = data.draw(broken_csv(record["csv"]))
    if kind == "garbage":
        assume(b"\n" not in body or not body.strip(b"\n\r ,0123456789.e-+").strip())
    with folder() as tmp:
        p = tmp / "in.csv"
        p.write_bytes(body)
        refused(["extract", p, "--z1", repr(record["z1"]), "--force", "true"], tmp)


@PROPERTY
@given(cut=st.integers(0, 20000), garbage=st.binary(min_size=0, max_size=64))
def test_truncated_or_garbage_parquet_files_are_refused(record, cut, garbage):
    raw = Path(record["parquet"]).read_bytes()
    assume(cut < len(raw) - 8)  # the footer goes: never a whole file
    with folder() as tmp:
        p = tmp / "in.parquet"
        p.write_bytes(raw[:cut] + garbage)
        refused(["extract", p], tmp)
        refused(["plot", p, "-o", tmp / "figs"], tmp)


def test_a_run_table_with_text_in_a_number_column_is_refused(record):
    """A Parquet file (not a CSV) whose z_tip is text."""
    df = pd.read_parquet(record["parquet"])
    df["z_tip"] = df["z_tip"].astype(str)
    df.loc[len(df) - 10, "z_tip"] = "abc"  # in the steady segment
    with folder() as tmp:
        p = tmp / "t.parquet"
        df.to_parquet(p)
        refused(["extract", p, "--z1", repr(record["z1"]), "--force", "true"], tmp, "'z_tip'")
    assert np.isfinite(record["z1"])
