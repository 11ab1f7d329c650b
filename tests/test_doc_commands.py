"""The docs are tests: every command shown in README.md and docs/ (fenced blocks and indented
lines starting with ``vetica ``) runs, as itself or as a fast variant of itself, and what the
docs say it prints or writes holds.

:data:`FAST` maps each documented command (as written, comment dropped) to the command the
suite runs and a check of its stated output.  A documented command missing from the mapping,
or a mapping entry no document shows any more, fails the first test, so a command cannot be
added to the docs, or changed there, without being run here.  Where the documented command is
long (a study, a scan, an advice of 72 simulations, a benchmark) the variant is the same command
made small with its own options (``--dry-run``, ``--set`` of fewer pixels or periods, one
setting); everything else runs as written.  Reference: the documents' own text."""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from vetica_cli.cli import app

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
CHEAP = "--set numerics.dt=0.05e-9 --set numerics.record_cycles=3 --set numerics.print_step=0.5e-9"
TINY_SCAN = "--set scan.pixels=[2,1] --set scan.pixel_time=[0.2e-3]"
ONE_SETTING = "--f1 50e3 --setpoint 0.6 --print-step 2e-9 --k2 700"


def documented() -> dict[str, str]:
    """``{command: 'file:line'}`` of every command the docs show (its trailing comment dropped)."""
    out = {}
    for doc in DOCS:
        fenced = False
        for i, line in enumerate(doc.read_text().splitlines(), 1):
            if line.strip().startswith("```"):
                fenced = not fenced
                continue
            if not (fenced or line.startswith("    ")):
                continue
            text = re.split(r"\s{2,}#", line.strip())[0].strip()
            m = re.search(r"(?:^|&& )(vetica .*)$", text)
            if m:
                out.setdefault(m.group(1), f"{doc.relative_to(ROOT)}:{i}")
    return out


# Checks of what the docs say a command prints or writes: (output, work folder) -> None
def wrote(*names):
    def check(out, w):
        for n in names:
            assert (w / n).exists(), n

    return check


def says(*words):
    def check(out, w):
        for word in words:
            assert word in out, word

    return check


def json_keys(*keys):
    def check(out, w):
        obj = json.loads(out)
        for k in keys:
            assert k in obj, k

    return check


def columns(path, *names):
    def check(out, w):
        have = set(pd.read_parquet(w / path).columns)
        assert set(names) <= have, sorted(set(names) - have)

    return check


def advice_json(out, w):
    obj = json.loads(out)
    keys = {"probe.f1", "probe.f2", "operation.setpoint", "numerics.print_step", "probe.k2", "score"}
    assert "settings" in obj and "temperature_k" in obj
    assert all(keys <= set(s) for s in obj["settings"])  # "every key but score goes back to vetica simulate --set"


# documented command -> (the command the suite runs, check of its stated output); in the order a reader meets them
FAST = {
    "vetica sweep configs/dashpot.yaml": (
        "vetica sweep configs/dashpot.yaml --dry-run", says("33 points", "output: sweeps/dashpot.parquet")),
    "vetica simulate -o run.parquet": (f"vetica simulate {CHEAP} -o run.parquet", wrote("run.parquet")),
    "vetica extract run.parquet": ("vetica extract run.parquet", says("force reconstructed", "tau_c")),
    "vetica extract run.parquet --force true": ("vetica extract run.parquet --force true", says("force true")),
    "vetica extract run.parquet --json": (
        "vetica extract run.parquet --json", json_keys("tau_c", "force", "taps")),
    "vetica extract measured.csv --z1 2e-10 --k2 700 --f2 750e3 --q2 1000": (
        "vetica extract measured.csv --z1 2e-10 --k2 700 --f2 750e3 --q2 1000", says("force reconstructed")),
    "vetica extract measured.csv --a0 0.2e-9 --vdw-on-surface --method vetica-prestress": (
        "vetica extract measured.csv --a0 0.2e-9 --vdw-on-surface --method vetica-prestress", says("tau_c")),
    "vetica extract measured.csv --method full": ("vetica extract measured.csv --method full", says("k_inf")),
    "vetica extract measured.csv --method full --z1 2.9e-10": (
        "vetica extract measured.csv --method full --z1 2.9e-10", says("k_inf")),
    "vetica extract measured.csv --method full --hamaker 2e-19 --tip-radius 1e-8 --a0 2e-10 --vdw-on-surface": (
        "vetica extract measured.csv --method full --hamaker 2e-19 --tip-radius 1e-8 --a0 2e-10 --vdw-on-surface",
        says("k_inf")),
    "vetica extract measured.csv --method full --arms 2": (
        "vetica extract measured.csv --method full --arms 2", says("k_1", "cd_1", "k_2", "cd_2")),
    "vetica plot run.parquet -o figures/": ("vetica plot run.parquet -o figures/", says("wrote figures/")),
    "vetica plot results/thesis/dashpot.parquet -o figures/": (
        "vetica plot results/thesis/dashpot.parquet -o figures/", says("wrote figures/")),
    "vetica sweep configs/print_step.yaml --dry-run": (
        "vetica sweep configs/print_step.yaml --dry-run", says("points", "simulations", "cost")),
    "vetica sweep configs/frequency.yaml --backend dask --scheduler tcp://host:8786": (
        "vetica sweep configs/frequency.yaml --backend dask --scheduler tcp://host:8786 --dry-run", says("points")),
    "vetica scan configs/scan_blend.yaml -o sweeps/scan_blend.parquet": (
        f"vetica scan configs/scan_blend.yaml {TINY_SCAN} -o sweeps/scan_blend.parquet",
        wrote("sweeps/scan_blend.parquet", "sweeps/scan_blend.config.yaml", "sweeps/scan_blend.summary.md")),
    "vetica scan configs/scan_edge.yaml --set scan.pixel_time=1e-3 -o edge.parquet": (
        "vetica scan configs/scan_edge.yaml --set scan.pixel_time=1e-3 --set scan.pixels=[2,1] "
        "--set scan.steady=transient -o edge.parquet", wrote("edge.parquet")),
    "vetica scan configs/scan_blend.yaml --dry-run": (
        "vetica scan configs/scan_blend.yaml --dry-run", says("pass transient 0.5 ms", "pass orbit", "would write")),
    "vetica scan configs/scan_blend.yaml --backend dask --scheduler tcp://host:8786": (
        "vetica scan configs/scan_blend.yaml --backend dask --scheduler tcp://host:8786 --dry-run", says("pass")),
    "vetica plot results/scans/scan_blend.parquet -o figures/": (
        "vetica plot results/scans/scan_blend.parquet -o figures/", says("wrote figures/")),
    "vetica advise --k-inf 4 --k0 64 --cd 3e-3 -o advise.png": (
        f"vetica advise --k-inf 4 --k0 64 --cd 3e-3 {ONE_SETTING} -o advise.png", wrote("advise.png")),
    "vetica advise --e-glassy 1e9 --e-rubbery 3e7 --tau-r 1e-6 --json": (
        f"vetica advise --e-glassy 1e9 --e-rubbery 3e7 --tau-r 1e-6 {ONE_SETTING} --json", advice_json),
    "vetica bench --repeat 5": (
        "vetica bench --repeat 1 --set numerics.dt=0.05e-9 --set numerics.print_step=1e-9",
        says("ns/fine step", "extraction per pixel record")),
    "vetica bench --repeat 3 --set surface.cd=1e-4": (
        "vetica bench --repeat 1 --part simulation --set surface.cd=1e-4 --set numerics.dt=0.05e-9 "
        "--set numerics.print_step=1e-9", says("hybrid vs verlet", "in CPU time")),
    "vetica simulate configs/wiechert.yaml -o w.parquet": (
        f"vetica simulate configs/wiechert.yaml {CHEAP} -o w.parquet", columns("w.parquet", "x_dashpot_1", "x_dashpot_2")),
    "vetica extract w.parquet --method full": ("vetica extract w.parquet --method full", says("k_1", "cd_1", "k_2", "cd_2")),
    "vetica simulate configs/wiechert.yaml --set surface.arms.2.cd=1e-2": (
        f"vetica simulate configs/wiechert.yaml --set surface.arms.2.cd=1e-2 {CHEAP} -o w2.parquet", wrote("w2.parquet")),
    "vetica sweep configs/wiechert_arm2_cd.yaml": (
        "vetica sweep configs/wiechert_arm2_cd.yaml --dry-run", says("surface.arms.2.cd")),
    # a synopsis: CURVES... stands for the curve files (the fit's own tests run it on every file of tests/data)
    "vetica fit CURVES... --tip-radius 5e-6 [--modulus power-law|maxwell] [-o fit.parquet]": (
        "vetica fit tests/data/afmformats/fmt-jpk-fd_spot3-0192.jpk-force --tip-radius 5e-6 --modulus power-law "
        "-o fit.parquet -j 1", wrote("fit.parquet")),
    # a synopsis: TABLE stands for a scan or force-map table (the export's own tests write every format)
    "vetica export TABLE -o map.nc|map.gwy|map.gsf [--quantity COLUMN ...]": (
        "vetica export results/scans/scan_edge.parquet -o map.nc", wrote("map.nc")),
}  # fmt: skip


def test_every_documented_command_is_mapped_to_the_command_the_suite_runs():
    shown = documented()
    missing = {c: where for c, where in shown.items() if c not in FAST}
    stale = [c for c in FAST if c not in shown]
    assert not missing, "documented commands the suite does not run (add them to FAST):\n" + "\n".join(
        f"{where}: {c}" for c, where in missing.items())
    assert not stale, "FAST holds commands no document shows:\n" + "\n".join(stale)


def test_every_fast_variant_is_the_documented_command_made_small():
    """A variant keeps the documented command's words (it adds options, or replaces a
    placeholder), so it runs what the docs show and not something else."""
    for doc, (fast, _) in FAST.items():
        if "CURVES..." in doc or "TABLE -o map.nc|" in doc:  # synopses: placeholders, alternatives in brackets
            continue
        words = shlex.split(fast)
        for w in shlex.split(doc):
            assert w in words or w.startswith("--repeat") or w in ("5", "3"), (doc, w)


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """A folder with the repository's configs, results and test data, as the docs assume."""
    w = tmp_path_factory.mktemp("docs")
    for name in ("configs", "results", "tests"):
        (w / name).symlink_to(ROOT / name)
    return w


@pytest.mark.slow
def test_documented_commands_run_and_what_they_say_holds(work, monkeypatch):
    """Every command of :data:`FAST` in the docs' order, in one folder (later commands read what
    earlier ones wrote: run.parquet, w.parquet; measured.csv is run.parquet's steady record, no
    metadata, with t, z_tip and z_paddle where the command gives the paddle's constants, else
    f_ts, as the docs describe it): exit status 0 and the stated output.  ~40 s."""
    monkeypatch.chdir(work)
    runner = CliRunner()
    failed = []
    for doc, (fast, check) in FAST.items():
        if fast.startswith("vetica extract measured.csv"):  # the paddle signal where the command gives the paddle
            df = pd.read_parquet(work / "run.parquet")
            cols = ["t", "z_tip", "z_paddle" if "--k2" in fast else "f_ts"]
            df[df["segment"] == "steady"][cols].to_csv(work / "measured.csv", index=False)
        res = runner.invoke(app, shlex.split(fast)[1:])
        if res.exit_code != 0:
            failed.append(f"{doc}: exit {res.exit_code}: {(res.stderr or res.output).strip()[-300:]}")
            continue
        try:
            check(res.stdout, work)
        except (AssertionError, ValueError, KeyError) as exc:
            failed.append(f"{doc}: stated output does not hold: {exc!r}")
    assert not failed, "\n".join(failed)
