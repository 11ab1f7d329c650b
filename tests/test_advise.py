"""`vetica advise`: material input, the knob grid, the print-step policy
shared with the sweep (one simulation per setting), the margin and ranking, the JSON
settings as config keys, and one-line errors with exit status 2.

References: the conversion of thesis eqs. 90-92 (moduli -> springs -> moduli round trip,
rtol 1e-12), a separate `simulate` of a setting (its record is the advice's, bit for bit:
the same config, the same code path), the margin's definition (module docstring of
vetica_cli/advise.py), and the config schema (every settings key must be accepted by
`vetica simulate --set`).
"""

import json
import math
import time

import pytest
from typer.testing import CliRunner

from vetica_cli.cli import app
from vetica_cli.errors import USER_ERRORS, ConfigError, InputError
from vetica_cli.extraction.material import ContactModel, moduli
from vetica_cli.simulation.config import load
from vetica_cli.advise import (
    KNOBS,
    SETTING_KEYS,
    advice_json,
    advise,
    format_advice,
    knob_values,
    margin,
    material_from,
)

runner = CliRunner()


def test_material_from_springs_and_from_moduli():
    m = material_from(4, 64, 3e-3)
    assert (m.k_inf, m.k0, m.cd) == (4.0, 64.0, 3e-3)
    cm = ContactModel()
    mm = material_from(e_glassy=5e9, e_rubbery=2e8, tau_r=1e-5, depth=2e-9, cm=cm)
    back = moduli(1.0, 2e-9, mm.k0 + mm.k_inf, mm.k_inf, mm.cd / mm.k0, cm)
    assert back["E_glassy"] == pytest.approx(5e9, rel=1e-12)
    assert back["E_rubbery"] == pytest.approx(2e8, rel=1e-12)
    assert mm.cd / mm.k0 == pytest.approx(1e-5, rel=1e-12, abs=0.0)  # tau_r = cd / k0


@pytest.mark.parametrize(
    "kw, fragment",
    [({"k_inf": 4, "k0": 64}, "missing --cd; give the material as --k-inf --k0 --cd"),
     ({"k_inf": 4, "k0": -1, "cd": 1}, "--k0: -1 is not allowed; expected a stiffness in [1e-06, 1e+06] N/m"),
     ({"k_inf": 4, "k0": 64, "cd": math.nan}, "--cd: nan is not allowed"),
     ({"k_inf": 1e30, "k0": 64, "cd": 1}, "--k-inf: 1e+30 is not allowed; expected a stiffness in [1e-06, 1e+06] N/m"),
     ({"k_inf": 4, "k0": 64, "cd": 1e30}, "--cd: 1e+30 is not allowed; expected a dashpot coefficient in [1e-18, "),
     ({"e_glassy": 1e30, "e_rubbery": 1e9, "tau_r": 1}, "--e-glassy: 1e+30 is not allowed; expected a modulus in"),
     ({"k_inf": 4, "e_glassy": 1e9}, "mix two ways"),
     ({"e_glassy": 1e8, "e_rubbery": 1e9, "tau_r": 1}, "--e-glassy 1e+08 must exceed --e-rubbery"),
     ({}, "no material given")],
)  # fmt: skip
def test_bad_material_is_a_one_line_error(kw, fragment):
    """A missing, mixed or out-of-range material (the one range of each quantity, vetica_cli.ranges:
    advise --k-inf 1e30 and --cd 1e30 were accepted) is one line."""
    with pytest.raises(USER_ERRORS) as exc:
        material_from(**kw)
    assert fragment in str(exc.value) and "\n" not in str(exc.value)


def test_margin_is_the_smallest_headroom_against_the_limits():
    """min(1 - |tau_c|/30, 1 - |p|/5): 15 % on tau_c leaves 0.5; 4 % on cd leaves 0.2."""
    assert margin({"tau_c": 15.0, "k0": 1.0, "k_inf": -2.0, "cd": 4.0}) == pytest.approx(0.2)
    assert margin({"tau_c": -15.0, "k0": 0.0, "k_inf": 0.0, "cd": 0.0}) == pytest.approx(0.5)
    assert margin({"tau_c": 1.0, "k0": 6.0, "k_inf": 0.0, "cd": 0.0}) == pytest.approx(-0.2)
    assert math.isnan(margin({"tau_c": 1.0, "k0": None, "k_inf": 0.0, "cd": 0.0}))


def test_margin_counts_the_error_bar():
    """min(1 - (|error| + 2 sigma)/limit): 1 % error with a 1.5 % sigma on cd leaves
    1 - 4/5 = 0.2; an unknown or unbounded sigma leaves no margin; zero sigmas give the error-only margin."""
    errs = {"tau_c": 3.0, "k0": 0.0, "k_inf": 0.0, "cd": 1.0}
    sig = {"tau_c": 0.0, "k0": 0.0, "k_inf": 0.0, "cd": 1.5}
    assert margin(errs, sig) == pytest.approx(0.2)
    assert math.isnan(margin(errs, {**sig, "k0": float("inf")}))  # an unbounded error bar: not recovered
    assert math.isnan(margin(errs, {**sig, "k0": None}))
    assert margin(errs, dict.fromkeys(errs, 0.0)) == pytest.approx(margin(errs))


def test_knobs_default_within_the_thesis_ranges_and_are_checked():
    vals = knob_values(None)
    for key, knob in KNOBS.items():
        assert all(knob.lo <= v <= knob.hi for v in vals[key]), key
    with pytest.raises(ConfigError, match="probe.f1: 200000 is not allowed; expected values within"):
        knob_values({"probe.f1": [50e3, 200e3]})
    assert knob_values({"numerics.print_step": [0.5e-9, 0.75e-9]})["numerics.print_step"] == (0.5e-9, 0.75e-9)
    assert knob_values({"operation.setpoint": [0.7, 0.4, 0.7]})["operation.setpoint"] == (0.4, 0.7)


def test_each_print_step_is_its_own_simulation_as_in_a_sweep():
    """One print-step policy (vetica_cli.rows.plan): settings that differ in the print step are
    separate simulations; the advice's task on a setting gives what `simulate` of it gives."""
    from vetica_cli.advise import Setting
    from vetica_cli.rows.plan import group

    cfgs = [load(None, {"numerics.record_cycles": 2, "numerics.print_step": ps}) for ps in (0.5e-9, 1e-9)]
    assert [len(t.points) for t in group([Setting(c) for c in cfgs])] == [1, 1]


@pytest.fixture(scope="module")
def small_advice():
    """The worked example's material on a 1 x 1 x 2 x 1 grid (50 kHz, set point 0.7, print
    steps 0.5 and 1 ns, k2 700 N/m), true force, one worker."""
    knobs = {"probe.f1": [50e3], "operation.setpoint": [0.7], "numerics.print_step": [0.5e-9, 1e-9],
             "probe.k2": [700.0]}  # fmt: skip
    return advise(material_from(4, 128, 3e-5), {}, knobs, ("vetica-prestress", "full"), "true", jobs=1)


def test_advice_rows_scores_and_settings(small_advice):
    adv = small_advice
    t = adv.table
    assert len(t) == 2 and adv.simulations == 2  # one per print step (rows.plan)
    assert list(t["numerics.print_step"]) == [0.5e-9, 1e-9]
    assert (t["probe.f2"] == 15 * t["probe.f1"]).all()  # thesis 4.5.1
    for _, r in t.iterrows():
        assert r["status"] == "ok"
        assert r["score"] == pytest.approx(min(r["vetica-prestress.margin"], r["full.margin"]))
        errs = {q: r[f"full.{q}_err_pct"] for q in ("tau_c", "k0", "k_inf", "cd")}
        sigs = {q: r[f"full.{q}_sigma_pct"] for q in ("tau_c", "k0", "k_inf", "cd")}
        assert r["full.margin"] == pytest.approx(margin(errs, sigs))
        assert r["recovered"] == (r["score"] > 0 and not r["full.flagged"] and not r["vetica-prestress.flagged"])
    settings = adv.settings()
    assert settings and [s["score"] for s in settings] == sorted((s["score"] for s in settings), reverse=True)
    assert all(s["score"] > 0 for s in settings)
    for s in settings:
        assert set(s) == {*SETTING_KEYS, "score"}
        cfg = load(None, {k: v for k, v in s.items() if k != "score"})  # every key is a config key
        assert cfg.probe.f1 == s["probe.f1"] and cfg.numerics.print_step == s["numerics.print_step"]
    text = format_advice(adv)
    assert "settings that recover the material, best first" in text
    js = advice_json(adv)
    assert js["settings"] == settings and js["evaluated"] == 2


def test_cli_bad_material_exits_2_with_one_line_and_writes_nothing(tmp_path):
    png = tmp_path / "a.png"
    for args in (["--k-inf", "4", "--k0", "sixty"], ["--k-inf", "4", "--k0", "64"],
                 ["--k-inf", "4", "--k0", "64", "--cd", "0"], ["--e-glassy", "1e9", "--cd", "1"]):  # fmt: skip
        r = runner.invoke(app, ["advise", *args, "-o", str(png)])
        assert r.exit_code == 2, r.output
        assert len(r.output.strip().splitlines()) == 1 and r.output.startswith("error: "), r.output
    r = runner.invoke(app, ["advise", "--k-inf", "4", "--k0", "64", "--cd", "3e-3", "--set", "probe.f1=3e4",
                            "-o", str(png)])  # fmt: skip
    assert r.exit_code == 2 and "knob" in r.output
    assert not png.exists()


def test_cli_outputs_are_checked_before_the_minutes_of_work(tmp_path):
    """advise checked its outputs only after its study.  A figure or table path under
    a file, or in a place that cannot be written, now exits 2 at once (well under the seconds
    one simulation takes) with one line, leaving nothing."""
    (tmp_path / "afile").write_text("x")
    good = ["--k-inf", "4", "--k0", "64", "--cd", "3e-3"]
    for args, fragment in ((["-o", str(tmp_path / "afile" / "a.png")], "a part of the path is a file"),
                           (["-o", str(tmp_path / "a.png"), "--table", "/proc/vetica_t.parquet"], "/proc"),
                           (["-o", str(tmp_path / "a.jpg")], ".png")):  # fmt: skip
        t0 = time.perf_counter()
        r = runner.invoke(app, ["advise", *good, *args])
        assert r.exit_code == 2 and time.perf_counter() - t0 < 5, r.output
        assert len(r.output.strip().splitlines()) == 1 and fragment in r.output, r.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_cli_json_settings_go_straight_back_to_simulate(tmp_path):
    png = tmp_path / "map.png"
    r = runner.invoke(app, ["advise", "--k-inf", "4", "--k0", "128", "--cd", "3e-5", "--f1", "50e3",
                            "--setpoint", "0.7", "--print-step", "1e-9", "--k2", "700", "--force", "true",
                            "--temperature", "0", "--jobs", "1", "-o", str(png), "--json"])  # fmt: skip
    assert r.exit_code == 0, r.output
    out = json.loads(r.output)
    assert out["temperature_k"] == 0.0
    assert png.is_file() and out["figure"] == str(png)
    assert out["settings"], out
    best = out["settings"][0]
    sets = [f"--set={k}={v}" for k, v in best.items() if k != "score"]
    r2 = runner.invoke(app, ["simulate", *sets, "--set", "numerics.record_cycles=2", "-o", str(tmp_path / "r.parquet"),
                             "-q"])  # fmt: skip
    assert r2.exit_code == 0, r2.output


@pytest.mark.parametrize("args, fragment", [(["--temperature", "-3"], "[0, 2000] K"),
                                            (["--temperature", "warm"], "--temperature 'warm'"),
                                            (["--set", "numerics.temperature=10"], "--temperature")])  # fmt: skip
def test_cli_bad_temperature_exits_2_before_any_work(tmp_path, args, fragment):
    r = runner.invoke(app, ["advise", "--k-inf", "4", "--k0", "64", "--cd", "3e-3", "-o", str(tmp_path / "a.png"), *args])
    assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1 and fragment in r.output, r.output
    assert not list(tmp_path.iterdir())
