"""The instrument's own numbers: `observables` (amplitude, phase and the E_diss,
virial and loss tangent that follow from them, Cleveland et al. 1998; Proksch et al. 2016) and `dmt-fit` (per-tap adhesion,
DMT modulus on the unloading branch, loop dissipation, deformation), checked against the
simulator's exact energy bookkeeping and against closed forms; the truth columns of the
surface models; the CLI's JSON; a scan's tan d_AM and DMT maps."""

import json
import math

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from vetica_cli import surfaces
from vetica_cli.cli import app
from vetica_cli.constants import EV
from vetica_cli.extraction import extract
from vetica_cli.extraction.observables import am_observables
from vetica_cli.io import read_table, write_run
from vetica_cli.plots.scanmaps import ScanGeometry, fig_instrument
from vetica_cli.scan.config import build
from vetica_cli.scan.run import run_scan
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import simulate

FAST = {"numerics.print_step": 0.5e-9, "numerics.record_cycles": 3}  # a small record of the worked example


@pytest.fixture(scope="module")
def worked(tmp_path_factory):
    """The worked example (thesis tables 2-4) sampled every 0.5 ns, 3 periods, as `vetica simulate` writes it."""
    path = tmp_path_factory.mktemp("inst") / "run.parquet"
    run = simulate(load(None, FAST))
    write_run(run, path)
    return path, run


def test_free_cantilever_gives_a0_90_degrees_and_no_dissipation():
    """A cantilever 1 um above the surface (this feature's check): the lock-in gives A = A0 and
    phi = 90 deg to 1e-6, and E_diss from them is 0 within 0.1 eV (5e-6 of pi k A0^2/Q)."""
    run = simulate(load(None, {"operation.base_height": 1e-6}))
    res = extract(run.frame(), run.metadata(), force="true", method="observables")
    a0 = run.params["operation"]["free_amplitude"]
    assert res.value("amplitude_obs") == pytest.approx(a0, rel=1e-6, abs=0.0)
    assert res.value("phase_obs") == pytest.approx(90.0, abs=1e-6 * 90.0)
    assert abs(res.value("e_diss_obs")) < 0.1
    scale = math.pi * 10.0 * a0**2 / 100.0 / EV  # pi k1 A0^2 / Q1 [eV]
    assert abs(res.value("e_diss_obs")) < 5e-6 * scale


def test_closed_forms_reduce_to_the_resonant_loss_tangent():
    """Cleveland et al. 1998; Proksch et al. 2016: at Omega = 1, tan d_AM = (sin phi - A/A0)/cos phi; a free mode (A = A0,
    phi = 90 deg) dissipates nothing and has no virial."""
    amp, a0, phi = 70e-9, 100e-9, 48.9
    o = am_observables(amp, phi, a0, 10.0, 100.0, 1.0)
    p = math.radians(phi)
    assert o["tan_delta"] == pytest.approx((math.sin(p) - amp / a0) / abs(math.cos(p)), rel=1e-12, abs=0.0)
    free = am_observables(a0, 90.0, a0, 10.0, 100.0, 1.0)
    assert abs(free["e_diss"]) < 1e-12 * math.pi * 10 * a0**2 / 100 and abs(free["virial"]) < 1e-25


def test_formulas_match_the_kernel_on_a_kelvin_voigt_like_surface():
    """An SLS with a stiff Maxwell arm (k0 = 1000 N/m, tau_r = 1 ns << contact 3 us) is a
    Kelvin-Voigt solid (k_inf = 4 N/m parallel to eta = cd = 1e-6 kg/s).  E_diss from amplitude
    and phase equals what the drive loses beyond the flexural damping -- the sample's
    dissipation PLUS the paddle's (the kernel's energy balance) -- within 0.5 % (measured
    +0.25 %; the rest: higher harmonics, z_tip carrying the paddle's deflection); against the
    sample's alone it is high by about the paddle's share (0.8 %).  The virial matches the
    kernel's <F_ts (z_tip - Zb)> within 0.5 % (measured 0.13 %), and tan d_AM is the material's
    eta omega / k at the drive frequency (Cleveland et al. 1998; Proksch et al. 2016) within 3 % (measured +1.1 %)."""
    run = simulate(load(None, {**FAST, "surface.k0": 1000.0, "surface.cd": 1e-6}))
    res = extract(run.frame(), run.metadata(), force="true", method="observables")
    e = run.energy
    both = e["sample_dissipation"] + e["paddle_damping"]
    share = 100 * e["paddle_damping"] / e["sample_dissipation"]
    assert res.value("e_diss_obs") == pytest.approx(both, rel=0.005)
    assert res.estimates["e_diss_obs"].theory == pytest.approx(e["sample_dissipation"], rel=1e-12)
    assert 0.5 * share < res.estimates["e_diss_obs"].error_pct < 2 * share
    assert res.value("virial_obs") == pytest.approx(run.observables["virial_ev"], rel=0.005)
    omega = 2 * math.pi * 50e3
    assert res.estimates["tan_delta_am"].theory == pytest.approx(omega * 1e-6 / 4.0, rel=0.01)  # eta omega / k
    assert res.value("tan_delta_am") == pytest.approx(omega * 1e-6 / 4.0, rel=0.03)


def test_sls_loss_tangent_is_the_spec_closed_form():
    """Cleveland et al. 1998; Proksch et al. 2016: k' = k_inf + k0 x^2/(1+x^2), k'' = k0 x/(1+x^2), x = omega cd/k0; a Wiechert
    surface with one arm is the same SLS."""
    p = {"k_inf": 4.0, "k0": 128.0, "cd": 3e-5}
    w = 2 * math.pi * 50e3
    x = w * p["cd"] / p["k0"]
    ks, kl = surfaces.get("sls").complex_stiffness(p, w)
    assert ks == pytest.approx(4.0 + 128.0 * x * x / (1 + x * x), rel=1e-14, abs=0.0)
    assert kl == pytest.approx(128.0 * x / (1 + x * x), rel=1e-14, abs=0.0)
    wp = surfaces.get("wiechert").parse({"k_inf": 4.0, "arms": [{"k": 128.0, "cd": 3e-5}]})
    th = surfaces.get("wiechert").dynamic_theory(wp, 50e3, 1e-6)
    assert th["tan_delta_drive"] == pytest.approx(kl / ks, rel=1e-14, abs=0.0)
    assert th["e_storage_drive"] is None  # springs have no modulus


def hertz_record(e_star=1e9, radius=10e-9, f_adh=5e-9, depth=3e-9, periods=4, n=4000):
    """A synthetic tapping record on an elastic DMT sample: z_tip = A cos(w t) + offset
    reaching ``depth`` below the surface at z = 0; in contact F = -F_adh + 4/3 E* sqrt(R)
    (-z)^1.5, outside the DMT attraction -F_adh (a0/(z + a0))^2 (a0 = 0.2 nm), continuous at
    z = 0, its minimum."""
    amp, f1 = 50e-9, 50e3
    tc = np.arccos((depth - amp) / amp) / (2 * np.pi * f1)  # z = 0: a sample at each contact and separation
    t = np.arange(periods * n) / (n * f1)
    t = np.unique(np.concatenate([t, [(k + s * tc * f1) / f1 for k in range(periods + 1) for s in (-1, 1)]]))
    t = t[(t >= 0) & (t < periods / f1)]
    z = amp * np.cos(2 * np.pi * f1 * t) + amp - depth
    inside = z <= 0
    f = np.where(inside, -f_adh + 4 / 3 * e_star * np.sqrt(radius) * np.clip(-z, 0, None) ** 1.5,
                 -f_adh * (0.2e-9 / (np.clip(z, 0, None) + 0.2e-9)) ** 2)  # fmt: skip
    return pd.DataFrame({"t": t, "z_tip": z, "f_ts": f})


def test_dmt_fit_recovers_the_modulus_of_a_hertz_force_curve():
    """Closed form (Hertz + constant adhesion, DMT): the fit returns E* = 1 GPa, the adhesion
    5 nN, the deformation 3 nm (to the sampling), the unloading stiffness 2 E* sqrt(R delta),
    and no dissipation (an elastic loop)."""
    e_star, radius, depth = 1e9, 10e-9, 3e-9
    res = extract(hertz_record(e_star, radius, 5e-9, depth), {"time_sampling": "nonuniform"}, force="true", method="dmt-fit", tip_radius=radius)
    assert res.taps >= 2
    assert res.value("e_dmt") == pytest.approx(e_star, rel=1e-4)
    assert res.value("adhesion") == pytest.approx(5e-9, rel=1e-4, abs=0.0)
    assert res.value("deformation") == pytest.approx(depth, rel=1e-3)
    assert res.value("k_dmt") == pytest.approx(2 * e_star * math.sqrt(radius * depth), rel=1e-3)
    loop = abs(res.value("e_diss_tap"))
    assert loop < 1e-4 * 5e-9 * depth / EV  # << the adhesion's work over the deformation
    assert res.estimates["e_dmt"].theory is None  # no metadata: no truth


@pytest.mark.parametrize("method, names", [
    ("observables", ("amplitude_obs", "phase_obs", "e_diss_obs", "virial_obs", "tan_delta_am")),
    ("dmt-fit", ("adhesion", "e_dmt", "k_dmt", "e_diss_tap", "deformation")),
])  # fmt: skip
def test_extract_json_gives_theory_and_signed_errors(worked, method, names):
    """`vetica extract run.parquet --method observables|dmt-fit --json` (this feature's done-when):
    every quantity with its value, theory and signed error, and the surface's k', k'', tan d
    at the drive frequency and at pi / contact time under 'theory'."""
    path, run = worked
    res = CliRunner().invoke(app, ["extract", str(path), "--method", method, "--json", "--force", "true"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert out["method"] == method
    for name in names:
        e = out[name]
        if e["theory"] is not None and e["value"] is not None:
            assert e["error_pct"] == pytest.approx(100 * (e["value"] - e["theory"]) / e["theory"], rel=1e-9, abs=0.0)
    assert out["theory"]["tan_delta_drive"]["value"] == pytest.approx(
        surfaces.get("sls").dynamic_theory(run.params["surface"], 50e3, None)["tan_delta_drive"], rel=1e-12
    )
    assert out["theory"]["k_storage_contact"]["value"] is not None
    if method == "observables":  # the simulator's exact amplitude, E_diss (+ the paddle's) and virial
        assert out["amplitude_obs"]["error_pct"] == pytest.approx(0.0, abs=1e-3)
        assert out["tan_delta_am"]["theory"] == out["theory"]["tan_delta_drive"]["value"]
    else:
        # the force minimum is -Fa(a0), sampled every 0.5 ns (measured -0.49 %)
        assert -1.0 < out["adhesion"]["error_pct"] <= 0.0
        assert out["e_diss_tap"]["error_pct"] == pytest.approx(0.0, abs=0.5)  # loop area = -closed int F dz


def test_measured_record_without_metadata_names_the_missing_inputs(worked, tmp_path):
    """A record as an instrument has it (t, z_tip, f_ts, no metadata): the lock-in needs A0,
    k1, Q1, f1 and the drive's time origin as user inputs, and says so in one line."""
    path, _ = worked
    df, _ = read_table(path)
    csv = tmp_path / "measured.csv"
    df[df["segment"] == "steady"][["t", "z_tip", "f_ts"]].to_csv(csv, index=False)
    res = CliRunner().invoke(app, ["extract", str(csv), "--method", "observables"])
    assert res.exit_code == 2 and "--free-amplitude" in res.output and "--drive-t0" in res.output, res.output
    res = CliRunner().invoke(app, ["extract", str(csv), "--method", "observables", "--json", "--free-amplitude",
                                   "100e-9", "--k1", "10", "--q1", "100", "--f1", "50e3", "--drive-t0", "0"])  # fmt: skip
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert out["amplitude_obs"]["value"] == pytest.approx(70e-9, rel=1e-4) and out["tan_delta_am"]["theory"] is None
    res = CliRunner().invoke(app, ["extract", str(csv), "--method", "dmt-fit"])
    assert res.exit_code == 2 and "--tip-radius" in res.output, res.output


def test_scan_writes_tan_delta_and_dmt_maps(tmp_path):
    """A small scan (3 x 2 pixels, periodic orbits) across a soft feature: every pixel has
    tan d_AM and the DMT modulus in the table, tan d_AM's truth follows the domain's surface,
    and the instrument figure draws them beside VETICA's tau_c."""
    raw = {
        "numerics": {"print_step": 1e-9, "record_cycles": 3, "approach_cycles": 1},
        "scan": {"pixels": [3, 2], "size": [3e-7, 2e-7], "pixel_time": 0.2e-3, "steady": "orbit",
                 "methods": ["vetica", "observables", "dmt-fit"]},
        "sample": {"background": {"height": 0.0, "k_inf": 4.0, "k0": 128.0, "cd": 3e-5},
                   "features": [{"shape": "rectangle", "corner": [2e-7, 0.0], "size": [1e-7, 2e-7], "height": 0.0,
                                 "surface": {"k0": 32.0, "cd": 3e-4}}]},
        "extract": {"force": "true"},
    }  # fmt: skip
    cfg = build(raw, name="inst_scan")
    out = tmp_path / "scan.parquet"
    run_scan(cfg, out, jobs=1, progress=False)
    df, meta = read_table(out)
    obs, dmt = df[df["method"] == "observables"], df[df["method"] == "dmt-fit"]
    assert len(obs) == 6 and np.isfinite(obs["tan_delta_am"]).all() and np.isfinite(dmt["e_dmt"]).all()
    for _, r in obs.iterrows():
        s = {"k_inf": 4.0, "k0": 128.0, "cd": 3e-5} if r["domain"] == 0 else {"k_inf": 4.0, "k0": 32.0, "cd": 3e-4}
        assert r["tan_delta_am_theory"] == pytest.approx(
            surfaces.get("sls").dynamic_theory(s, 50e3, None)["tan_delta_drive"], rel=1e-12, abs=0.0
        )
    fig = fig_instrument(ScanGeometry.of(df, meta), df, "inst_scan")
    assert fig is not None and len([a for a in fig.axes if a.images]) >= 5  # tau_c, tan d, E*, k_DMT (+ truths)


def test_advise_refuses_a_method_that_does_not_estimate_the_material(tmp_path):
    """advise ranks settings by the tau_c, k0, k_inf, cd errors; the instrument's numbers have
    none of them: one line, exit 2, before any simulation and with nothing written."""
    out = tmp_path / "a.png"
    res = CliRunner().invoke(app, ["advise", "--k-inf", "4", "--k0", "64", "--cd", "1e-4", "--methods", "dmt-fit",
                                   "-o", str(out)])  # fmt: skip
    assert res.exit_code == 2 and "does not estimate tau_c, k0, k_inf, cd" in res.output and not out.exists()


def test_observables_sigma_needs_a_record_longer_than_the_ring_down(worked):
    """The per-period values share the cantilever's memory (ring-down Q1 f_d / (pi f1) periods,
    31.8 for Q1 = 100): a 3-period record reports no sigma and says why; with Q1 = 0.6 (0.19
    periods, 3 periods >= 10 ring-downs) sigma is the spread's standard error over
    n_eff = n / (1 + 2 tau) independent periods (the exponential series' integrated
    autocorrelation time), t-scaled."""
    from vetica_cli.extraction.result import t_factor

    path, _ = worked
    df, meta = read_table(path)
    short = extract(df, meta, "true", "observables")
    assert all(e.sigma is None for e in short.estimates.values())
    assert short.info["uncertainty"]["source"].startswith("none: the record spans 3 drive periods")
    low_q = extract(df, meta, "true", "observables", q1=0.6)
    tau = 0.6 / math.pi
    sp = low_q.estimates["amplitude_obs"].spread
    n_eff = sp.n / (1 + 2 * tau)
    expect = sp.std / math.sqrt(n_eff) * t_factor(int(n_eff)) / low_q.estimates["amplitude_obs"].value
    assert low_q.estimates["amplitude_obs"].sigma == pytest.approx(expect, rel=1e-12, abs=0.0)
