"""Nothing a user types ends in a traceback, a runaway or a silent wrong unit: one range per
physical quantity wherever it is typed (vetica_cli.ranges), records checked for plausible
units, every command's cost estimated and bounded before work (the sweep's --yes threshold),
list sizes, arm counts, nesting depth and file sizes checked while parsing, and the readers'
errors in one line.

References: the ranges and their sources are the table's (vetica_cli.ranges.QUANTITIES); the
cases are the ones a new user's trial found accepted or running away (a radius of 1 m, a
stiffness of 1e30 N/m, a record whose time is in ms, scan.pixel_time 1000, 3000 drive
frequencies, 1000 hertz arms, a config nested thousands of levels deep, a 30 MB sweep list)."""

from __future__ import annotations

import json
import time

import pandas as pd
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from vetica_cli.checks import CONFIRM_ITEMS, CONFIRM_WALL_S, MAX_YAML_BYTES, confirm_cost, load_yaml
from vetica_cli.cli import app
from vetica_cli.errors import ConfigError, InputError
from vetica_cli.io import write_run
from vetica_cli.ranges import KEYS, QUANTITIES, check_range
from vetica_cli.simulation.config import load, read_yaml
from vetica_cli.simulation.simulate import simulate

runner = CliRunner()


def one_line(res, *words):
    """Exit 2, one line on stderr naming ``words``, no traceback."""
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in res.output, res.output
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    """A cheap run (dt 0.05 ns, 3 recorded periods at 0.5 ns) written as by `vetica simulate`."""
    path = tmp_path_factory.mktemp("bounds") / "run.parquet"
    cfg = {"numerics.dt": 0.05e-9, "numerics.record_cycles": 3, "numerics.print_step": 0.5e-9}
    write_run(simulate(load(None, cfg)), path)
    return path


# ------------------------------------------------------------------ one range per quantity


def test_every_key_names_a_quantity_with_a_source_and_a_nonempty_range():
    assert set(KEYS.values()) <= set(QUANTITIES)
    for name, r in QUANTITIES.items():
        assert r.lo < r.hi and r.source and r.what, name


def test_check_range_is_the_one_check_for_a_tip_radius_wherever_it_is_typed():
    """probe.tip_radius 0.5 nm - 1 um (the existing range, thesis table 2's 10 nm inside): the
    config key, extract --tip-radius, --contact tip_radius and the public check agree."""
    assert check_range("tip_radius", 10e-9, "--tip-radius") == 10e-9
    for bad in (1.0, 1e-15, float("nan"), "x", True):
        with pytest.raises(ConfigError, match=r"--tip-radius: .* is not allowed; expected a radius in \[5e-10, 1e-06\] m"):
            check_range("tip_radius", bad, "--tip-radius")
    with pytest.raises(ConfigError, match=r"probe.tip_radius: 1.0 is not allowed; expected a radius in \[5e-10, 1e-06\]"):
        load(None, {"probe.tip_radius": 1.0})


@pytest.mark.parametrize("key, value, words", [
    ("surface.k0", 1e30, "expected a stiffness in [1e-06, 1e+06] N/m"),
    ("surface.cd", 1e30, "expected a dashpot coefficient in [1e-18, 1e+10] kg/s"),
    ("probe.f1", 300.0, "expected a frequency in [1000, 1e+08] Hz"),
    ("numerics.dt", 1e-3, "expected a time step in [1e-15, 1e-06] s"),
    ("surface.arms", [{"k": 2e9, "cd": 1e-4}], "surface.arms.1.k"),
])  # fmt: skip
def test_config_values_outside_their_quantity_range_are_refused(key, value, words):
    over = {key: value} if key != "surface.arms" else {"surface.model": "wiechert", key: value}
    with pytest.raises(ConfigError) as exc:
        load(None, over)
    assert words in str(exc.value)


def test_hertz_surface_takes_at_most_as_many_arms_as_wiechert():
    """1000 hertz arms were accepted (Wiechert stops at 8): the list is refused by its length."""
    arms = [{"e": 1e9, "tau": 1e-6}] * 1000
    with pytest.raises(ConfigError, match=r"surface.arms: a list of 1000 arms is not allowed; expected a list of 1..8"):
        load(None, {"surface.model": "hertz", "surface.arms": arms})


@pytest.mark.parametrize("args, words", [
    (["--k-inf", "1e30", "--k0", "64", "--cd", "3e-3"], "--k-inf: 1e+30 is not allowed"),
    (["--k-inf", "4", "--k0", "64", "--cd", "1e30"], "--cd: 1e+30 is not allowed"),
    (["--k-inf", "4", "--k0", "64", "--cd", "3e-3", "--f1", ",".join(["5e4"] * 3000)], "probe.f1: 3000 values"),
])  # fmt: skip
def test_advise_refuses_nonsense_and_long_lists_before_any_work(args, words, tmp_path):
    res = runner.invoke(app, ["advise", *args, "-o", str(tmp_path / "a.png")])
    one_line(res, words)
    assert not (tmp_path / "a.png").exists()


def test_advise_with_more_settings_than_the_threshold_asks_for_yes_before_building_them(tmp_path):
    """20 values of each knob: 160 000 settings, refused at once (13 s of config building before)."""
    vals = {"--f1": [10e3 + 4e3 * i for i in range(20)], "--setpoint": [0.3 + 0.025 * i for i in range(20)],
            "--print-step": [(0.5 + 0.35 * i) * 1e-9 for i in range(20)], "--k2": [100 + 50 * i for i in range(20)]}
    args = [a for k, v in vals.items() for a in (k, ",".join(f"{x:.6g}" for x in v))]
    t0 = time.perf_counter()
    res = runner.invoke(app, ["advise", "--k-inf", "4", "--k0", "64", "--cd", "3e-3", *args, "-o", str(tmp_path / "a.png")])
    one_line(res, "160000 settings", "add --yes")
    assert time.perf_counter() - t0 < 5.0


# ------------------------------------------------------------------ records in other units


def test_a_record_whose_time_is_in_ms_is_refused(run_file, tmp_path):
    """t in ms shows a 50 Hz drive, below any cantilever's (tau_c and cd came out 1000x off)."""
    df = pd.read_parquet(run_file)
    rec = df[df["segment"] == "steady"][["t", "z_tip", "f_ts"]]
    rec.assign(t=rec["t"] * 1e3).to_csv(tmp_path / "ms.csv", index=False)
    res = runner.invoke(app, ["extract", str(tmp_path / "ms.csv"), "--a0", "0.2e-9", "--vdw-on-surface"])
    one_line(res, "oscillate at 50 Hz", "is t in seconds?")
    rec.to_csv(tmp_path / "s.csv", index=False)  # the same record in seconds is accepted
    assert runner.invoke(app, ["extract", str(tmp_path / "s.csv"), "--a0", "0.2e-9", "--vdw-on-surface"]).exit_code == 0
    one_line(runner.invoke(app, ["extract", str(tmp_path / "s.csv"), "--a0", "0.2e-9", "--vdw-on-surface", "--f1",
                                 "5e6"]), "0.01 times the drive frequency f1")  # fmt: skip


@pytest.mark.parametrize("args, words", [
    (["--free-amplitude", "1e3"], "--free-amplitude: 1000.0 is not allowed; expected an amplitude in"),
    (["--free-amplitude", "20e-9"], "expected a free amplitude above the record's amplitude 7e-08 m"),
    (["--q1", "1e9"], "--q1: 1000000000.0 is not allowed"),
])  # fmt: skip
def test_observables_inputs_are_checked_against_their_range_and_the_record(run_file, args, words):
    one_line(runner.invoke(app, ["extract", str(run_file), "--method", "observables", *args]), *words.split(" | "))


def test_metadata_of_the_wrong_shape_is_one_line(run_file, tmp_path):
    table = pq.read_table(run_file)
    for name, meta, words in [("list", [1, 2], "the 'vetica' metadata is a list"),
                              ("params", {"params": "probe"}, "params is a str"),
                              ("k2", {"params": {"probe": {"k2": "abc"}}}, "params.probe.k2 is 'abc'"),
                              ("kinf", {"params": {"surface": {"k_inf": "x", "k0": 1, "cd": 1}}}, "surface.k_inf: 'x'")]:
        md = dict(table.schema.metadata)
        md[b"vetica"] = json.dumps(meta).encode()
        pq.write_table(table.replace_schema_metadata(md), tmp_path / f"{name}.parquet")
        one_line(runner.invoke(app, ["extract", str(tmp_path / f"{name}.parquet"), "--force", "true"]), words)


# ------------------------------------------------------------------ runaways bounded before work


def test_confirm_cost_asks_past_the_sweep_threshold_only():
    confirm_cost("this", CONFIRM_WALL_S, False, CONFIRM_ITEMS)  # at the threshold: runs
    confirm_cost("this", 1e9, True, 10**9)  # --yes
    for wall, items in ((CONFIRM_WALL_S * 1.01, None), (1.0, CONFIRM_ITEMS + 1)):
        with pytest.raises(InputError, match="add --yes to start it"):
            confirm_cost("this", wall, False, items)


def test_a_scan_past_the_threshold_asks_for_yes_and_writes_nothing(tmp_path):
    """scan.pixel_time 0.4 s over 64 x 64 pixels: its own dry run's ~15 h (a scan estimated at
    18 h started without asking)."""
    cfg = tmp_path / "slow.yaml"
    cfg.write_text("scan: {pixels: [64, 64], pixel_time: 0.4}\nsample:\n  background: {height: 0.0}\n")
    res = runner.invoke(app, ["scan", str(cfg), "-o", str(tmp_path / "o" / "s.parquet")])
    one_line(res, "this scan (64 x 64 pixels", "add --yes")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("args, words", [
    (["simulate", "--set", "numerics.steady=transient", "--set", "numerics.max_time=300"], "this simulation is estimated"),
    (["bench", "--repeat", "50000"], "this bench"),
    (["bench", "--set", "surface.k_inf=1e20"], "surface.k_inf: 1e+20"),
])  # fmt: skip
def test_simulate_and_bench_estimate_their_cost_and_check_configs_first(args, words, tmp_path):
    t0 = time.perf_counter()
    one_line(runner.invoke(app, [*args, *(["-o", str(tmp_path / "r.parquet")] if args[0] == "simulate" else [])]), words)
    assert time.perf_counter() - t0 < 5.0 and not (tmp_path / "r.parquet").exists()


def test_bench_of_another_surface_model_plans_the_extraction_it_can_run():
    """vetica bench --set surface.model=hertz (README) exited 2 after 40 s of timing: the
    extraction bench set the SLS 'soft' keys on a hertz surface."""
    from vetica_cli.bench import check_bench, extraction_plan

    plan = extraction_plan({"surface.model": "hertz"})
    assert [name for name, _, _ in plan] == ["given"] and plan[0][1].surface.model == "hertz"
    assert "vetica" not in plan[0][2] and "full" in plan[0][2]
    check_bench({"surface.model": "hertz"}, 3)  # every config valid, cost under the threshold


def test_deep_nesting_and_large_configs_are_refused_while_parsing(tmp_path):
    """A config nested thousands of levels deep ended in RecursionError; a 30 MB sweep list
    took 575 s and 3.2 GB to refuse: the size is checked before reading, the depth while
    composing."""
    with pytest.raises(ConfigError, match="nesting deeper than 32 levels"):
        load_yaml("probe: " + "[" * 5000 + "]" * 5000)
    big = tmp_path / "big.yaml"
    big.write_text("sweep:\n  surface.cd: [" + "1.0e-5, " * (MAX_YAML_BYTES // 8 + 1) + "1.0e-5]\n")
    t0 = time.perf_counter()
    with pytest.raises(ConfigError, match=r"holds \d+ bytes; expected at most 1048576"):
        read_yaml(big)
    assert time.perf_counter() - t0 < 1.0
    res = runner.invoke(app, ["simulate", "--set", "probe.f1=" + "{a: " * 3000 + "1" + "}" * 3000, "-o",
                              str(tmp_path / "r.parquet")])  # fmt: skip
    one_line(res, "nesting deeper than 32 levels")

