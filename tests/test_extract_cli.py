"""`vetica extract`: table and JSON output, measured data without metadata, and
one-line errors with exit status 2 for bad input."""

import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from vetica_cli.cli import app
from vetica_cli.io import write_run
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import simulate

NAMES = ("tau_c", "k_g", "k_r", "tau_r", "k0", "k_inf", "cd")


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    """The worked example (defaults) sampled every 0.5 ns, 3 recorded periods, written as
    by `vetica simulate` (small, so the CSV round trips stay fast)."""
    path = tmp_path_factory.mktemp("extract") / "run.parquet"
    write_run(simulate(load(None, {"numerics.record_cycles": 3, "numerics.print_step": 0.5e-9})), path)
    return path


@pytest.fixture(scope="module")
def frame(run_file):
    return pd.read_parquet(run_file)


def invoke(*args):
    return CliRunner().invoke(app, ["extract", *map(str, args)])


def _one_line_error(res, *words):
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), res.output
    assert "Traceback" not in res.output
    for w in words:
        assert w in lines[0], lines[0]


def test_table_lists_every_quantity_with_theory_and_error(run_file):
    res = invoke(run_file)
    assert res.exit_code == 0, res.output
    for label in ("tau_c", "Kg", "Kr", "tau_r", "k0", "k_inf", "cd", "error %", "reconstructed vs true f_ts"):
        assert label in res.output
    assert "force reconstructed" in res.output  # default when z_paddle is present


def test_json_is_one_object_with_the_issue_keys(run_file):
    res = invoke(run_file, "--json", "--force", "true", "--kg-points", "12")
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert out["force"] == "true"
    assert out["taps"] >= 2
    for name in NAMES:
        entry = out[name]
        assert set(entry) >= {"value", "theory", "error_pct"}
        assert entry["theory"] is not None
        # signed: 100 (extracted - theory) / theory
        assert entry["error_pct"] == pytest.approx(100 * (entry["value"] - entry["theory"]) / entry["theory"])


def test_measured_csv_without_metadata_needs_z1_and_gives_null_theory(frame, tmp_path):
    csv = tmp_path / "measured.csv"
    frame[frame.segment == "steady"][["t", "z_tip", "f_ts"]].to_csv(csv, index=False)
    _one_line_error(invoke(csv), "Z1", "--z1")
    res = invoke(csv, "--json", "--z1", "2.78e-10")
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert out["force"] == "true"  # no z_paddle
    assert out["k0"]["value"] > 0
    assert out["k0"]["theory"] is None and out["k0"]["error_pct"] is None


def test_measured_paddle_signal_needs_the_probe_options(frame, tmp_path):
    csv = tmp_path / "measured_paddle.csv"
    frame[["t", "z_tip", "z_paddle", "segment"]].to_csv(csv, index=False)
    _one_line_error(invoke(csv), "--k2", "--f2", "--q2")
    res = invoke(csv, "--json", "--k2", 700, "--f2", 750e3, "--q2", 1000, "--f1", 50e3)
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert out["force"] == "reconstructed"
    assert out["info"]["z1_source"] == "approach segment"
    assert out["info"]["cutoff_harmonic"] == pytest.approx(1e9 / 50e3)  # Nyquist of 0.5 ns


def test_missing_column_is_named(frame, tmp_path):
    p = tmp_path / "nozt.csv"
    frame[["t", "f_ts"]].iloc[:2000].to_csv(p, index=False)
    _one_line_error(invoke(p, "--z1", "2e-10"), "missing column", "z_tip")
    p2 = tmp_path / "noforce.csv"
    frame[["t", "z_tip"]].iloc[:2000].to_csv(p2, index=False)
    _one_line_error(invoke(p2, "--z1", "2e-10"), "f_ts or z_paddle")


def test_non_increasing_time_is_rejected(frame, tmp_path):
    d = frame[frame.segment == "steady"][["t", "z_tip", "f_ts"]].copy()
    d.loc[d.index[100], "t"] = d["t"].iloc[50]
    p = tmp_path / "time.csv"
    d.to_csv(p, index=False)
    _one_line_error(invoke(p, "--z1", "2e-10"), "not strictly increasing")


def test_no_contact_is_rejected(tmp_path):
    t = np.arange(20000) * 1e-9
    d = pd.DataFrame({"t": t, "z_tip": 20e-9 + 10e-9 * np.cos(2 * np.pi * 50e3 * t), "f_ts": -1e-12 + 0 * t})
    p = tmp_path / "free.csv"
    d.to_csv(p, index=False)
    _one_line_error(invoke(p, "--z1", "1.5e-8"), "no contact found")  # Z1 inside the tip's range (else refused)


def test_too_few_taps_is_rejected(frame, tmp_path):
    s = frame[frame.segment == "steady"][["t", "z_tip", "f_ts"]]
    p = tmp_path / "short.csv"
    s.iloc[: int(len(s) * 0.4)].to_csv(p, index=False)  # 1.2 drive periods: one tap
    _one_line_error(invoke(p, "--z1", "2.78e-10"), "too few taps")


@pytest.mark.parametrize(
    "args, words",
    [
        (["--force", "measured"], ["force", "reconstructed", "true"]),
        (["--kg-points", "1"], ["--kg-points", ">= 2"]),
        (["--method", "fancy"], ["method", "vetica", "full"]),
        (["--force", "true", "--cutoff", "1e9"], []),  # cut-off only matters when reconstructing: accepted
    ],
)
def test_bad_options(run_file, args, words):
    res = invoke(run_file, *args)
    if words:
        _one_line_error(res, *words)
    else:
        assert res.exit_code == 0, res.output


def test_missing_file_is_rejected(tmp_path):
    _one_line_error(invoke(tmp_path / "nope.parquet"), "no such file")


def test_method_full_prints_fit_uncertainty_and_json_with_identifiability(run_file):
    """--method full: same output formats, plus 1-sigma and identifiability;
    recovers the worked example's k0, k_inf, cd within 1 % (this
    coarse 0.5 ns, 3-period record still carries the information)."""
    res = invoke(run_file, "--method", "full", "--force", "true")
    assert res.exit_code == 0, res.output
    assert res.output.startswith("whole-cycle fit on") and "1-sigma" in res.output
    out = json.loads(invoke(run_file, "--method", "full", "--json").output)
    assert out["method"] == "full" and out["force"] == "reconstructed"
    for name in ("k0", "k_inf", "cd"):
        assert abs(out[name]["error_pct"]) < 1.0, name
        assert out["identifiable"][name] is True
        assert out["uncertainty"][name] is not None
