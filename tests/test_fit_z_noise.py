"""The whole-cycle fit's correction for white noise on z_tip (errors in variables,
:mod:`vetica_cli.extraction.fullfit.eiv`).

Reference: the same fit on the same record without the z_tip noise (the bias is the noise's,
so the noise-free record's answer is what the noisy one must reach within its own error bar).
The surface is development draw 4's stiffest (k_inf 7.5, k0 474 N/m, cd 1.061e-5 kg/s: taps a
few tens of pm deep in the fast arm), its record stripped to ``t, z_tip, f_ts`` with 1 pm of
white noise on z_tip and 0.1 nN on f_ts, as ``scripts/trust.py`` strips them.  Measured before
the correction (8 replicas of 300 K records): k0 -4.9 ... -9.7 of its own sigmas off, every replica.
"""

import numpy as np
import pytest

from vetica_cli.extraction import extract_many
from vetica_cli.extraction.fullfit import eiv
from vetica_cli.signals.slopes import white_noise_floor
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import simulate
from vetica_cli.surfaces.sls import SLS

MATERIAL = {"surface.k_inf": 7.5, "surface.k0": 473.9942, "surface.cd": 1.061e-05}
A0 = 0.2e-9
Z_NOISE, F_NOISE = 1e-12, 1e-10  # [m], [N]: scripts/trust.py's stripped records


@pytest.fixture(scope="module")
def stripped():
    run = simulate(load(None, {**MATERIAL, "numerics.print_step": 0.5e-9, "numerics.record_cycles": 10}))
    df = run.frame()
    df = df[df["segment"] == "steady"]
    t = df["t"].to_numpy()
    f1 = run.params["probe"]["f1"]
    keep = (t >= t[0] + 1 / (3 * f1)) & (t < t[0] + (1 / 3 + 6) / f1)  # six periods from a third of one in
    return df.loc[keep, ["t", "z_tip", "f_ts"]].reset_index(drop=True)


def _fit(df):
    return extract_many(df, None, "true", {"full": {}}, a0=A0, vdw_on_surface=True)["full"]


def _z_scores(res, ref, quantities=("k0", "tau_r")):
    return {q: (res.estimates[q].value / ref.estimates[q].value - 1.0) / res.estimates[q].sigma for q in quantities}


def test_the_z_tip_noise_bias_is_taken_off_the_stiff_surfaces_fit(stripped, monkeypatch):
    ref = _fit(stripped)
    assert ref.info["fit"]["z_noise"]["applied"] is False  # a noise-free record: no correction (rounding floor)
    rng = np.random.default_rng(2024)
    noisy = stripped.copy()
    noisy["z_tip"] += rng.normal(0.0, Z_NOISE, len(noisy))
    noisy["f_ts"] += rng.normal(0.0, F_NOISE, len(noisy))
    got = _fit(noisy)
    info = got.info["fit"]["z_noise"]
    assert info["applied"] is True
    assert info["sigma_z_m"] == pytest.approx(Z_NOISE, rel=0.05, abs=0)  # the second-difference floor reads the noise
    corrected = _z_scores(got, ref)
    # the parameters corrected, every other quantity computed from them (k_r is k_inf; tau_c, k_g follow)
    est = got.estimates
    theory = SLS().theory({k: est[k].value for k in ("k_inf", "k0", "cd")})
    for q in ("k_r", "k_g", "tau_c", "tau_r"):
        assert est[q].value == pytest.approx(theory[q], rel=1e-12, abs=0)
    monkeypatch.setattr(eiv, "GATE", np.inf)  # the same record without the correction
    raw = _z_scores(_fit(noisy), ref)
    assert raw["k0"] < -3.0 and raw["tau_r"] > 3.0, raw  # the bias the correction is for
    from vetica_cli.extraction.base import METHODS

    assert any(line.startswith("z_tip's white noise") for line in METHODS["full"].detail_lines(got))  # said
    assert all(abs(v) < 2.5 for v in corrected.values()), corrected


def test_the_correction_is_made_only_where_the_z_noise_is_a_sizeable_part_of_the_force_noise(stripped):
    """With 1 nN on f_ts the 1 pm on z_tip adds 0.47 nN through k0: under the gate, left alone."""
    rng = np.random.default_rng(7)
    noisy = stripped.copy()
    noisy["z_tip"] += rng.normal(0.0, Z_NOISE, len(noisy))
    noisy["f_ts"] += rng.normal(0.0, 1e-9, len(noisy))
    info = _fit(noisy).info["fit"]["z_noise"]
    assert info["ratio"] == pytest.approx(474 * Z_NOISE / 1e-9, rel=0.1)
    assert info["applied"] is False


def test_a_noise_free_record_at_a_coarse_print_step_is_not_read_as_noisy():
    """At an 8 ns print step the tip's swing curves enough between samples that its second
    differences read 2.9e-13 m of 'noise' (``white_noise_floor``); the fourth differences read
    1.4e-16 m (rounding), and the fit is not corrected: at cd 1 kg/s the correction had flagged a
    right dashpot (results/methods, method_dashpot at 8 ns)."""
    run = simulate(load(None, {"numerics.print_step": 8e-9, "surface.cd": 1.0, "surface.k0": 60.0,
                               "surface.k_inf": 4.0, "numerics.record_cycles": 6}))  # fmt: skip
    df, meta = run.frame(), run.metadata()
    z = df[df["segment"] == "steady"]["z_tip"].to_numpy()
    assert white_noise_floor(z) > 1e-13  # what the second differences say
    assert white_noise_floor(z, order=4) < 1e-15
    res = extract_many(df, meta, "true", {"full": {}})["full"]
    assert res.info["fit"]["z_noise"]["applied"] is False


def test_a_wiechert_fits_parameters_are_corrected_and_its_other_quantities_follow():
    """Two Maxwell arms (configs/wiechert.yaml with stiffer arms, k 300 and 100 N/m), stripped, 1 pm on
    z_tip and 0.1 nN on f_ts, fitted with two arms: the correction is made (it raised a KeyError here:
    the Wiechert's theory takes its arms as a list, not the flat parameter names), every parameter stays
    within 3 of its sigmas of the noise-free fit, and k_g is k_inf plus the arms' stiffnesses."""
    run = simulate(load("configs/wiechert.yaml", {"surface.arms.1.k": 300.0, "surface.arms.2.k": 100.0,
                                                  "numerics.print_step": 0.5e-9, "numerics.record_cycles": 6}))
    df = run.frame()
    df = df[df["segment"] == "steady"][["t", "z_tip", "f_ts"]].reset_index(drop=True)

    def fit(d):
        return extract_many(d, None, "true", {"full": {"arms": 2}}, a0=A0, vdw_on_surface=True)["full"]

    ref = fit(df)
    rng = np.random.default_rng(11)
    noisy = df.copy()
    noisy["z_tip"] += rng.normal(0.0, Z_NOISE, len(noisy))
    noisy["f_ts"] += rng.normal(0.0, F_NOISE, len(noisy))
    got = fit(noisy)
    assert got.info["fit"]["z_noise"]["applied"] is True
    est = got.estimates
    for q in ("k_inf", "k_1", "cd_1", "k_2", "cd_2"):
        assert abs(est[q].value / ref.estimates[q].value - 1.0) < 3.0 * est[q].sigma, q
    kg = est["k_inf"].value + est["k_1"].value + est["k_2"].value
    assert est["k_g"].value == pytest.approx(kg, rel=1e-12, abs=0)
