"""Material units (thesis 4.6.2, eqs. 90-92, table 6).

References: the DMT/Hertz relation of thesis eq. 90 evaluated forward (a force made
from a chosen sample modulus must give that modulus back, rtol 1e-12), the limits
of eq. 92 (a rigid tip: E* = E_s/(1 - nu_s^2); a contact as stiff as the tip: no
finite sample modulus), and the consistency of the secant conversion (a purely
elastic spring F = K delta gives E_dmt = E_glassy = E_rubbery).
"""

import math

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from vetica_cli.cli import app
from vetica_cli.errors import ConfigError
from vetica_cli.extraction import extract
from vetica_cli.extraction.material import (
    ContactModel,
    contact_model,
    moduli,
    parse_contact,
    reduced_modulus,
    sample_modulus,
    stiffness,
    tap_contact,
)
from vetica_cli.signals.taps import find_taps

R = 10e-9  # thesis table 6


def hertz_force(e_sample, depth, cm: ContactModel):
    """Thesis eq. 90 forward: F = 4/3 E* sqrt(R) delta^1.5 with eq. 92's E*."""
    e_star = 1.0 / ((1 - cm.nu_tip**2) / cm.e_tip + (1 - cm.nu_sample**2) / e_sample)
    return 4.0 / 3.0 * e_star * math.sqrt(cm.tip_radius) * depth**1.5


def test_table6_defaults():
    """Thesis table 6: R 10 nm, nu 0.3 (tip and sample), E_tip 130 GPa (silicon)."""
    cm = ContactModel()
    assert (cm.tip_radius, cm.nu_tip, cm.nu_sample, cm.e_tip) == (10e-9, 0.3, 0.3, 130e9)


@pytest.mark.parametrize("e_sample", [32e6, 1e9, 9e9, 60e9])  # the thesis's 32 MPa .. 9 GPa and beyond
@pytest.mark.parametrize("depth", [0.3e-9, 2e-9, 20e-9])
def test_eqs_90_to_92_give_back_the_modulus_a_hertz_force_was_made_with(e_sample, depth):
    cm = ContactModel()
    f = hertz_force(e_sample, depth, cm)
    assert sample_modulus(reduced_modulus(f, depth, R), cm) == pytest.approx(e_sample, rel=1e-12)


def test_rigid_tip_limit_of_eq_92():
    """E_tip -> infinity: E* = E_s / (1 - nu_s^2) (rtol 1e-9 at E_tip = 1e20 Pa)."""
    cm = ContactModel(e_tip=1e20, nu_sample=0.45)
    assert sample_modulus(2e9 / (1 - 0.45**2), cm) == pytest.approx(2e9, rel=1e-9)


def test_a_contact_as_stiff_as_the_tip_has_no_finite_sample_modulus():
    cm = ContactModel()
    limit = cm.e_tip / (1 - cm.nu_tip**2)
    assert math.isnan(sample_modulus(limit, cm))
    assert math.isnan(sample_modulus(2 * limit, cm))
    assert math.isnan(reduced_modulus(0.0, 1e-9, R)) and math.isnan(reduced_modulus(1e-9, -1e-9, R))


def test_elastic_spring_gives_one_modulus_and_viscosity_is_modulus_times_tau_r():
    """F = K delta with Kg = Kr = K: the secant conversion of the springs (F = K delta at
    the same depth) equals the DMT modulus of that force; viscosity = E_dmt tau_r (thesis 4.6.2)."""
    cm, k, depth, tau_r = ContactModel(), 50.0, 1.5e-9, 2e-7
    m = moduli(k * depth, depth, k, k, tau_r, cm)
    assert m["E_glassy"] == pytest.approx(m["E_dmt"], rel=1e-12)
    assert m["E_rubbery"] == pytest.approx(m["E_dmt"], rel=1e-12)
    assert m["viscosity"] == pytest.approx(m["E_dmt"] * tau_r, rel=1e-12)


def test_stiffness_inverts_the_spring_conversion():
    cm = ContactModel(nu_sample=0.4)
    for e in (5e7, 3e9):
        k = stiffness(e, 2e-9, cm)
        assert moduli(k * 2e-9, 2e-9, k, k, 1.0, cm)["E_glassy"] == pytest.approx(e, rel=1e-12)


def test_moduli_work_on_table_columns():
    cm = ContactModel()
    peak = np.array([80e-9, np.nan, 10e-9])
    depth = np.array([2.4e-9, 1e-9, 0.0])
    m = moduli(peak, depth, np.array([132.0, 10.0, 5.0]), 4.0, 2e-7, cm)
    assert np.isfinite(m["E_dmt"][0]) and np.isnan(m["E_dmt"][1]) and np.isnan(m["E_dmt"][2])
    assert m["E_glassy"][0] == pytest.approx(moduli(80e-9, 2.4e-9, 132.0, 4.0, 2e-7, cm)["E_glassy"], rel=1e-12)


@pytest.mark.parametrize(
    "over, fragment",
    [({"nu_sample": 0.7}, "nu_sample=0.7 is not allowed; expected a Poisson ratio in (-1, 0.5]"),
     ({"e_tip": "-1"}, "e_tip=-1 is not allowed"), ({"radius": 1e-8}, "unknown key 'radius'"),
     ({"tip_radius": "x"}, "tip_radius=x is not allowed")],
)  # fmt: skip
def test_contact_constants_are_checked_with_one_line_errors(over, fragment):
    with pytest.raises(ConfigError) as exc:
        contact_model(over)
    assert fragment in str(exc.value) and "\n" not in str(exc.value)
    with pytest.raises(ConfigError):
        parse_contact(["nu_sample"])


def test_tap_contact_reads_peak_force_and_depth_below_z1():
    """Four triangular taps (contact in samples 50..150 of each 200): the adhesion well is
    deepest at the contact edges; peak force and lowest tip position per complete tap."""
    t = np.arange(800)
    ph = t % 200
    inside = (ph >= 50) & (ph <= 150)
    dist = np.minimum(abs(ph - 50), abs(ph - 150))
    f = np.where(inside, -1e-9 + 1e-8 * (1 - abs(ph - 100) / 50), -1e-9 * np.exp(-dist / 10.0))
    z = -1e-9 * np.cos(2 * np.pi * (ph - 100) / 200) - 0.5e-9 * (t // 200 == 1)  # second tap dips deeper
    peak, depth = tap_contact(z, f, 0.2e-9)
    assert peak == pytest.approx(-1e-9 + 1e-8, rel=1e-12, abs=0.0)
    # lowest tip position per tap: -1 nm (taps 1, 3) and -1.5 nm (tap 2); median of three -> 1 nm + Z1
    assert depth == pytest.approx(0.2e-9 + 1e-9, rel=1e-9, abs=0.0)


# ------------------------------------------------------------------ in extract and its JSON


@pytest.fixture(scope="module")
def run():
    from vetica_cli.simulation.config import load
    from vetica_cli.simulation.simulate import simulate

    return simulate(load(None, {"numerics.record_cycles": 3, "numerics.print_step": 0.5e-9}))


def test_extract_reports_material_from_the_record_and_theory(run):
    res = extract(run.frame(), run.metadata(), force="true")
    m = res.material
    assert [k for k in m] == ["E_dmt", "E_glassy", "E_rubbery", "viscosity", "peak_force", "penetration"]
    # the record's peak force is the run's observable (one periodic state: every tap equal): the largest recorded
    # sample (every 0.5 ns) against the largest over every fine step (0.025 ns), 1.6e-7 apart: rtol 1e-6
    assert m["peak_force"]["value"] == pytest.approx(run.observables["peak_force"], rel=1e-6, abs=0.0)
    # penetration: the tip's depth below Z1 is the surface's below its undeformed level plus the lift of the
    # first contact, X1 = Z1 - a0 (in contact X = z_tip - a0), to rounding; the method takes the adhesion lift
    # -Fc/Kg off (the surface feels the pull), which leaves X1 - Fa/Kg, the first approach's creep k0 Xd1/Kg
    # (20 pm in results/thesis/worked_example.md), plus Fa(a0) times the error of 1/Kg: within 25 pm
    x1 = run.observables["z1"] - 0.2e-9
    steady = run.frame()[lambda d: d.segment == "steady"]
    f = steady.f_ts.to_numpy()
    lift = -float(np.median(f[find_taps(f).contact])) / res.value("k_g")  # the record's adhesion Fa(a0) = -Fc
    assert m["penetration"]["value"] == pytest.approx(run.observables["max_penetration"] + x1 - lift, abs=1e-15)
    assert abs(m["penetration"]["value"] - run.observables["max_penetration"]) < 25e-12
    cm = ContactModel()
    want = moduli(m["peak_force"]["value"], m["penetration"]["value"], res.value("k_g"), res.value("k_r"),
                  res.value("tau_r"), cm)  # fmt: skip
    for k in ("E_dmt", "E_glassy", "E_rubbery", "viscosity"):
        assert m[k]["value"] == pytest.approx(want[k], rel=1e-12)
    th = res.estimates
    want_th = moduli(m["peak_force"]["value"], m["penetration"]["value"], th["k_g"].theory, th["k_r"].theory,
                     th["tau_r"].theory, cm)  # fmt: skip
    assert m["E_glassy"]["theory"] == pytest.approx(want_th["E_glassy"], rel=1e-12)
    assert res.contact["tip_radius"]["value"] == 10e-9 and res.contact["tip_radius_source"].startswith("metadata")


def test_extract_json_has_the_material_object_with_value_and_unit(run, tmp_path):
    from vetica_cli.io import write_run

    path = tmp_path / "run.parquet"
    write_run(run, path)
    r = CliRunner().invoke(app, ["extract", str(path), "--json", "--force", "true", "--contact", "nu_sample=0.45"])
    assert r.exit_code == 0, r.output
    import json

    out = json.loads(r.output)
    units = {"E_dmt": "Pa", "E_glassy": "Pa", "E_rubbery": "Pa", "viscosity": "Pa s", "peak_force": "N",
             "penetration": "m"}  # fmt: skip
    for k, unit in units.items():
        assert out["material"][k]["unit"] == unit and out["material"][k]["value"] > 0
    assert out["contact_model"]["nu_sample"]["value"] == 0.45
    r2 = CliRunner().invoke(app, ["extract", str(path), "--force", "true", "--contact", "nu_sample=2"])
    assert r2.exit_code == 2 and len(r2.output.strip().splitlines()) == 1, r2.output
    r3 = CliRunner().invoke(app, ["extract", str(path), "--force", "true"])
    assert "E_dmt [Pa]" in r3.output and "viscosity [Pa·s]" in r3.output and "DMT contact" in r3.output


def test_material_columns_of_a_sweep_follow_the_studys_contact_section(tmp_path):
    """The columns are computed when the table is assembled: a different contact section
    recomputes them from the persisted rows (kept with keep_parts; no point is simulated again)."""
    from vetica_cli.study.grid import expand
    from vetica_cli.study.sweep import run_sweep

    raw = {"numerics": {"record_cycles": 3, "print_step": 1e-9}, "extract": {"force": "true"},
           "sweep": {"surface.cd": [3e-5, 1e-3]}}  # fmt: skip
    out = tmp_path / "m.parquet"
    a = run_sweep(expand(raw), out, jobs=1, progress=False, keep_parts=True)
    b = run_sweep(expand({**raw, "material": {"nu_sample": 0.45}}), out, jobs=1, progress=False)
    assert len(b.reused) == 2 and not b.computed
    ta, tb = a.table, b.table
    for col in ("E_dmt", "E_glassy", "E_glassy_theory", "E_rubbery", "E_rubbery_theory", "viscosity",
                "viscosity_theory"):  # fmt: skip
        assert np.all(np.isfinite(ta[col])) and np.all(tb[col] < ta[col])  # (1 - nu^2) smaller
    want = moduli(ta["tap_peak_force"], ta["tap_depth"], ta["k_g_theory"], ta["k_r_theory"], ta["tau_r_theory"],
                  ContactModel())  # fmt: skip
    assert np.allclose(ta["E_glassy_theory"], want["E_glassy"], rtol=1e-12)
    assert np.allclose(ta["viscosity_theory"], want["viscosity"], rtol=1e-12)
    from vetica_cli.io import read_table

    _, meta = read_table(out)
    assert meta["material"]["nu_sample"]["value"] == 0.45 and "DMT" in meta["material"]["model"]
    assert meta["units"]["viscosity"].startswith("Pa s")
    with pytest.raises(ConfigError, match="material.nu_tip"):
        expand({**raw, "material": {"nu_tip": 0.9}})
    with pytest.raises(ConfigError, match="--set material.e_tip"):
        expand(raw, overrides={"material.e_tip": 0})


def test_material_ranges_script_prints_ranges_from_tables(tmp_path):
    """scripts/material_ranges.py on a table with the material columns (a frame written with
    the sweep's column names)."""
    import subprocess
    import sys
    from pathlib import Path

    from vetica_cli.io import write_table

    df = pd.DataFrame({"status": ["ok", "ok", "ok"], "force_source": ["true"] * 3, "method": ["vetica"] * 3,
                       "surface.cd": [1e-5, 1e-3, 1e1], "tau_c_err_pct": [1.0, 10.0, 90.0],
                       "E_dmt": [1e9, 2e9, 3e9], "viscosity_theory": [1e2, 1e5, 1e9], "tau_r_theory": [1e-7, 5e-5, 0.3]})  # fmt: skip
    write_table(df, tmp_path / "x.parquet", {"study": "x"})
    script = Path(__file__).resolve().parents[1] / "scripts" / "material_ranges.py"
    r = subprocess.run([sys.executable, str(script), str(tmp_path)], capture_output=True, text=True, check=True)
    assert "1 GPa .. 3 GPa" in r.stdout, r.stdout
    assert "100 Pa s .. 1 GPa s" in r.stdout and "100 Pa s .. 100 kPa s" in r.stdout, r.stdout
