"""``vetica fit`` on what users give it: every file read or refused in one line, a batch that goes
on past the files it cannot use, duplicate and same-named inputs, out-of-range options, --meta,
and SIGTERM with resume.  The files are afmformats' (MIT, tests/data/afmformats/README.md) and
corrupt copies made here."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from vetica_cli.cli import app
from vetica_cli.io import read_meta

DATA = Path(__file__).parent / "data" / "afmformats"
FD = DATA / "fmt-jpk-fd_spot3-0192.jpk-force"
MAP = DATA / "fmt-jpk-fd_map-data-reference-points.jpk-force-map"
QI = DATA / "fmt-jpk-fd_2020.02.07-16.29.05.036.jpk-qi-data"
IBW = DATA / "fmt-igor-fd_SiN_FD_plot.ibw"
WORKSHOP = DATA / "fmt-afm-workshop-fd_single_2018-08-01_13.06.09.csv"
runner = CliRunner()
ROOT = Path(__file__).resolve().parents[1]


def run(*args):
    return runner.invoke(app, ["fit", *map(str, args)])


def bad_files(folder: Path) -> dict:
    """One file of each kind a user may hand over by mistake (name -> path)."""
    folder.mkdir(parents=True, exist_ok=True)
    raw = FD.read_bytes()
    made = {
        "text": ("notes.txt", b"my notes, not a force curve\n"),
        "empty": ("empty.jpk-force", b""),
        "truncated": ("truncated.jpk-force", raw[: len(raw) // 2]),
        "zeroed": ("zeroed.jpk-force", bytes(len(raw))),
        "flipped": ("flipped.jpk-force", raw[:4000] + bytes(b ^ 0xFF for b in raw[4000:8000]) + raw[8000:]),
        "fake_zip": ("fake.zip", b"PK\x03\x04" + b"\x00" * 200),
        "csv": ("table.csv", b"a,b\n1,2\n3,4\n"),
        "renamed_ibw": ("spot3.ibw", raw),
    }
    out = {}
    for key, (name, data) in made.items():
        (folder / name).write_bytes(data)
        out[key] = folder / name
    return out


@pytest.mark.parametrize("kind", ["text", "empty", "truncated", "zeroed", "flipped", "fake_zip", "csv", "renamed_ibw"])
def test_a_bad_file_alone_is_one_line_exit_2_nothing_written(tmp_path, kind):
    path = bad_files(tmp_path / "in")[kind]
    out = tmp_path / "out" / "fit.parquet"
    res = run(path, "--tip-radius", "5e-6", "-o", out, "-q")
    lines = res.output.strip().splitlines()
    assert res.exit_code == 2 and len(lines) == 1 and "no curve to fit" in lines[0], res.output
    assert "Traceback" not in res.output and not (tmp_path / "out").exists()


def test_a_folder_without_afm_files_is_one_line(tmp_path):
    (tmp_path / "code").mkdir()
    (tmp_path / "code" / "model.py").write_text("x = 1\n")
    res = run(tmp_path / "code", "--tip-radius", "5e-6", "-o", tmp_path / "fit.parquet", "-q")
    assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1 and "without a file" in res.output


def test_bad_files_beside_good_ones_become_rows_and_the_rest_go_on(tmp_path):
    """Every bad kind, a QI file without contact, an approach-only Igor file and the workshop CSV
    without its metadata beside one good curve: exit 0, one summary line, a row per refused file
    with status and error, the good curve fitted ok."""
    bad = bad_files(tmp_path / "in")
    out = tmp_path / "fit.parquet"
    res = run(FD, *bad.values(), QI, IBW, WORKSHOP, "--tip-radius", "5e-6", "-o", out, "-j", "1")
    assert res.exit_code == 0, res.output
    assert "Traceback" not in res.output
    df = pd.read_parquet(out)
    good = df[df["path"] == str(FD)]
    assert list(good["status"]) == ["ok"] and bool(good["selected"].iloc[0])
    for p in bad.values():
        row = df[df["path"] == str(p)]
        assert len(row) == 1 and row["status"].iloc[0] == "unreadable" and row["error"].iloc[0], p
    assert set(df.loc[df["path"] == str(QI), "status"]) == {"unsuited"}  # 4 curves without contact
    assert "no retract" in df.loc[df["path"] == str(IBW), "error"].iloc[0]
    assert "--meta spring_constant" in df.loc[df["path"] == str(WORKSHOP), "error"].iloc[0]
    assert "1 curves fitted" in res.output.strip().splitlines()[-1]


def test_renamed_ibw_prints_no_reader_traceback(tmp_path):
    """igor2 and afmformats log a traceback for a JPK file renamed .ibw; the user sees one line
    (a subprocess: the readers' log handlers are the process's own)."""
    bad = bad_files(tmp_path / "in")["renamed_ibw"]
    r = subprocess.run([sys.executable, "-m", "vetica_cli", "fit", str(bad), "--tip-radius", "5e-6", "-o",
                        str(tmp_path / "fit.parquet"), "-q"], capture_output=True, text=True, timeout=120)  # fmt: skip
    assert r.returncode == 2 and r.stderr.strip().count("\n") == 0 and "Traceback" not in r.stderr, r.stderr


def test_meta_supplies_what_a_file_lacks(tmp_path):
    """The AFM Workshop CSV has no spring constant, sensitivity or sampling rate: with --meta
    spring_constant, sensitivity and rate it is read and fitted; without rate it is refused
    naming --meta rate."""
    out = tmp_path / "fit.parquet"
    meta = ["--meta", "spring_constant=0.05", "--meta", "sensitivity=50e-9"]
    res = run(WORKSHOP, "--tip-radius", "5e-6", "-o", out, "-q", *meta)
    assert res.exit_code == 2 and "--meta rate" in res.output and not out.exists()
    res = run(WORKSHOP, "--tip-radius", "5e-6", "-o", out, "-q", *meta, "--meta", "rate=1000")
    assert res.exit_code == 0, res.output
    df = pd.read_parquet(out)
    assert df["spring_constant"].iloc[0] == 0.05 and df["e_hertz"].iloc[0] > 0


@pytest.mark.parametrize("args,expect", [
    (["--tip-radius", "1"], "[5e-10, 0.0001] m"),
    (["--tip-radius", "1e-15"], "[5e-10, 0.0001] m"),
    (["--tip-radius", "5e-6", "--meta", "speed=3"], "KEY one of spring_constant, sensitivity, rate"),
    (["--tip-radius", "5e-6", "--meta", "sensitivity=1"], "a sensitivity in"),
    (["--tip-radius", "5e-6", "--modulus", "kelvin"], "power-law, maxwell"),
    (["--tip-radius", "5e-6", "--points", "10"], "50..5000"),
])  # fmt: skip
def test_bad_options_are_one_line_before_any_file_is_read(tmp_path, args, expect):
    out = tmp_path / "out" / "fit.parquet"
    res = run(FD, *args, "-o", out)
    lines = res.output.strip().splitlines()
    assert res.exit_code == 2 and len(lines) == 1 and expect in lines[0], res.output
    assert not (tmp_path / "out").exists()


def test_a_file_given_twice_is_fitted_once_with_a_note(tmp_path):
    out = tmp_path / "fit.parquet"
    res = run(FD, FD, DATA, "--tip-radius", "5e-6", "-o", out, "-q", "-j", "1")
    assert res.exit_code == 0, res.output
    assert "given again: read once" in res.output
    df = pd.read_parquet(out)
    assert (df["path"] == str(FD)).sum() == 1


def test_same_named_curves_in_two_folders_keep_their_paths_and_figures(tmp_path):
    for sub in ("a", "b"):
        (tmp_path / sub).mkdir()
        shutil.copy(FD, tmp_path / sub / "curve.jpk-force")
    (tmp_path / "b" / "curve.jpk-force").write_bytes(FD.read_bytes())
    out, figs = tmp_path / "fit.parquet", tmp_path / "figs"
    res = run(tmp_path / "a", tmp_path / "b", "--tip-radius", "5e-6", "-o", out, "--figures", figs, "-q", "-j", "1")
    assert res.exit_code == 0, res.output
    df = pd.read_parquet(out)
    assert sorted(df["file"]) == ["a/curve.jpk-force", "b/curve.jpk-force"]
    assert len(list(figs.glob("fit_*.png"))) == 2


def test_more_jobs_than_cores_warns(tmp_path):
    res = run(FD, "--tip-radius", "5e-6", "-o", tmp_path / "fit.parquet", "-q", "-j", "1000")
    assert res.exit_code == 0 and "warning: --jobs 1000 is more than the" in res.output


def test_force_map_table_has_units_grid_indices_and_maps(tmp_path):
    """A JPK force map: one row per curve with its grid indices; every column with a unit in the
    metadata ('' for aic, bic, nu: dimensionless); a map figure of every parameter."""
    out, figs = tmp_path / "fit.parquet", tmp_path / "figs"
    res = run(MAP, "--tip-radius", "5e-6", "-o", out, "--figures", figs, "-q", "-j", "1")
    assert res.exit_code == 0, res.output
    df = pd.read_parquet(out)
    assert list(zip(df["grid_x"], df["grid_y"])) == [(9, 4), (20, 5), (16, 16)]
    meta = read_meta(out)
    assert set(df.columns) <= set(meta["units"]) and set(df.columns) <= set(meta["descriptions"])
    assert meta["units"]["e0"] == "Pa" and meta["units"]["beta"] == "" and meta["units"]["bic"] == ""
    assert meta["units"]["nu"] == "" and meta["units"]["contact"] == "m"
    maps = {p.name for p in figs.glob("map_*.png")}
    assert {f"map_{MAP.name}_{p}.png" for p in ("e0", "beta", "e_hertz")} <= maps


@pytest.mark.slow
def test_sigterm_stops_with_one_line_and_a_rerun_fits_only_the_missing_curves(tmp_path):
    """SIGTERM during a Maxwell batch of 12 copies of a curve on 2 workers: exit 143 and one line
    saying how many curves are persisted (no loky warning); the rerun reuses them and fits the
    rest, and the table equals an uninterrupted run's."""
    folder = tmp_path / "in"
    folder.mkdir()
    for i in range(12):
        shutil.copy(MAP, folder / f"m{i:02d}.jpk-force-map")
    out = tmp_path / "fit.parquet"
    cmd = [sys.executable, "-m", "vetica_cli", "fit", str(folder), "--tip-radius", "5e-6", "--modulus", "maxwell",
           "-o", str(out), "-j", "2"]  # fmt: skip
    proc = subprocess.Popen(cmd + ["-q"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    parts = Path(str(out) + ".parts")
    deadline = time.time() + 120
    while time.time() < deadline and not (parts.is_dir() and len(list(parts.glob("*.parquet"))) >= 2):
        time.sleep(0.2)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM, err
    # beside it only the note of /dev/shm entries that other killed batches of this machine left
    lines = [ln for ln in err.strip().splitlines() if "left in /dev/shm by killed batches" not in ln]
    assert len(lines) == 1 and "interrupted (SIGTERM)" in lines[0] and "curves are persisted" in lines[0], err
    persisted = len(list(parts.glob("*.parquet")))
    assert 0 < persisted < 36 and not out.exists()
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    assert f"{persisted} reused" in r.stdout
    assert not parts.exists() and os.path.isfile(out)
    df = pd.read_parquet(out)
    assert len(df) == 36 * 3 and (df.groupby(["path", "curve"])["selected"].sum() == 1).all()


def test_plot_draws_a_fit_table(tmp_path):
    """vetica plot on a fit table: each curve's fit (its file is where the table says), the
    parameters' histograms and the force map's parameter maps; with the file gone, the
    histograms and maps and a note saying why the fits are not drawn."""
    folder = tmp_path / "in"
    folder.mkdir()
    shutil.copy(MAP, folder / MAP.name)
    out = tmp_path / "fit.parquet"
    assert run(folder, "--tip-radius", "5e-6", "-o", out, "-q", "-j", "1").exit_code == 0
    res = runner.invoke(app, ["plot", str(out), "-o", str(tmp_path / "figs")])
    assert res.exit_code == 0, res.output
    names = {p.name for p in (tmp_path / "figs").glob("*.png")}
    assert {f"fit_fit_{MAP.name}_{i}.png" for i in range(3)} <= names
    assert "fit_parameters.png" in names and f"fit_map_{MAP.name}_e0.png" in names
    (folder / MAP.name).unlink()
    res = runner.invoke(app, ["plot", str(out), "-o", str(tmp_path / "figs2")])
    assert res.exit_code == 0 and "not where it says" in res.output
    names = {p.name for p in (tmp_path / "figs2").glob("*.png")}
    assert "fit_parameters.png" in names and not any(n.startswith("fit_fit_") for n in names)
