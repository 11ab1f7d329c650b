"""VETICA with the Maxwell arm's pre-stress at contact (method
``vetica-prestress``, vetica_cli/extraction/vetica_prestress.py).

References: the SLS in contact (massless SLS: X = z_tip - a0, cd Xd' = k0 (X - Xd)) whose
force is equation (1) of the module docstring exactly -- checked against the
simulator's recorded force and its own surface and dashpot positions; the pre-stress
formula against the simulator's k0 (X - Xd) at the contact sample; the SLS theory
values of the worked example (thesis tables 2-4).  Tolerances are stated per test.
"""

import math

import numpy as np
import pytest

from vetica_cli import surfaces
from vetica_cli.errors import InputError
from vetica_cli.extraction import extract
from vetica_cli.extraction.vetica_prestress import model_force, prestress_of, stage2_tap, tap_fits, vetica_prestress
from vetica_cli.signals.taps import find_taps
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import simulate

TH = surfaces.get("sls").theory({"k0": 128.0, "k_inf": 4.0, "cd": 3e-5})  # the worked example


@pytest.fixture(scope="module")
def runs():
    out = {}
    for vdw in (True, False):
        r = simulate(load(None, {"surface.vdw_on_surface": vdw, "numerics.record_cycles": 4}))
        df, meta = r.frame(), r.metadata()
        s = df[df.segment == "steady"]
        out[vdw] = (df, meta, {c: s[c].to_numpy() for c in ("t", "z_tip", "f_ts", "x_surface", "x_dashpot")})
    return out


def err(res, k):
    return 100.0 * (res.value(k) - TH[k]) / TH[k]


@pytest.mark.parametrize("vdw", [True, False])
def test_equation_1_is_the_sls_contact_force(runs, vdw):
    """With the true Kg, Kr, tau_r and the arm's true stress k0 (X - Xd) at the contact
    sample, equation (1) on the sum-of-sines trajectory gives the recorded force within
    0.05 % of the peak force (the sine fit's residual)."""
    _, _, s = runs[vdw]
    taps = find_taps(s["f_ts"])
    fits = tap_fits(s["t"], s["z_tip"], s["f_ts"], taps, 10)
    for tf, ic in zip(fits, taps.contact):
        sigma0 = 128.0 * (s["x_surface"][ic] - s["x_dashpot"][ic])
        f = model_force(tf.u, tf.sup, tf.fc, sigma0, TH["k_g"], TH["k_r"], TH["tau_r"])
        assert np.max(np.abs(f - tf.f)) < 5e-4 * np.max(tf.f)


@pytest.mark.parametrize("vdw", [True, False])
def test_prestress_from_the_record_matches_the_arms_stress(runs, vdw):
    """adhesion (pull on) / creep (pull off) formula with the true Kg, Kr and the measured
    Z1 against the simulator's k0 (X - Xd) at the contact sample: within 2 % (the formula
    leaves out the dashpot's creep during the first approach, k0 Xd1/Kg in Z1) plus the force
    the contact builds within the sample after the contact instant, Kg |dz| over one sample."""
    _, meta, s = runs[vdw]
    z1 = meta["observables"]["z1"]
    taps = find_taps(s["f_ts"])
    for ic in taps.contact:
        true = 128.0 * (s["x_surface"][ic] - s["x_dashpot"][ic])
        mode = "adhesion" if vdw else "creep"
        got = prestress_of(mode, s["f_ts"][ic], s["z_tip"][ic], z1, TH["k_g"], TH["k_r"])
        within_sample = TH["k_g"] * abs(s["z_tip"][ic + 1] - s["z_tip"][ic])
        assert abs(got - true) < 0.02 * abs(true) + within_sample


def test_stage2_with_exact_stage1_inputs_recovers_kr(runs):
    """Thesis stage 2 fed the exact tau_c and Kg leaves Kr +17 % off under the surface pull
    (results/thesis/worked_example.md); with the pre-stress term from the record Kr is within 0.3 %
    (measured: -0.013 % with the simulator's own stress; the record's formula misses the
    first approach's creep, about 1 % of sigma0)."""
    _, meta, s = runs[True]
    z1 = meta["observables"]["z1"]
    taps = find_taps(s["f_ts"])
    for tf in tap_fits(s["t"], s["z_tip"], s["f_ts"], taps, 10):
        kr, _, rms = stage2_tap(tf, "adhesion", z1, TH["k_g"], TH["tau_c"], 0.4, 0.0)
        assert kr == pytest.approx(TH["k_r"], rel=3e-3)
        assert rms < 1e-3 * np.max(tf.f)


def test_worked_example_with_the_pull(runs):
    """vetica-prestress on the worked example (surface pull on, Z1 from the approach):
    Kg within 0.2 % (the thesis's stage 1b +3.9 %), k0 within 0.2 %, cd within 0.5 %,
    k_inf within 3 % (what is left is stage 1a's tau_c, +2.7 %, unchanged by this method)."""
    df, meta, _ = runs[True]
    res = extract(df, meta, force="true", method="vetica-prestress")
    assert res.info["prestress"] == "auto: adhesion (surface pull from the metadata)"
    for k, bound in (("k_g", 0.2), ("k0", 0.2), ("cd", 0.5), ("k_inf", 3.0)):
        assert abs(err(res, k)) < bound, (k, err(res, k))
    plain = extract(df, meta, force="true", method="vetica")
    assert res.value("tau_c") == plain.value("tau_c")  # stage 1a is the thesis's
    assert abs(err(plain, "k_inf")) > 5 * abs(err(res, "k_inf"))


@pytest.mark.parametrize("mode", ["auto", "creep", "fit"])
def test_worked_example_without_the_pull(runs, mode):
    """Surface pull off: only the creep stresses the arm; creep (auto picks it from the
    metadata) and fit recover k0, k_inf, cd and Kg within 0.2 %."""
    df, meta, _ = runs[False]
    res = extract(df, meta, force="true", method="vetica-prestress", prestress=mode)
    for k in ("k_g", "k0", "k_inf", "cd"):
        assert abs(err(res, k)) < 0.2, (mode, k, err(res, k))
    if mode == "auto":
        assert res.info["prestress"].startswith("auto: creep")


def test_adhesion_on_a_surface_without_the_pull_is_biased(runs):
    """The pull is an input, not a detail: the adhesion pre-stress on a surface that did not
    feel the pull puts Kr more than 5 % off (here about -13 %)."""
    df, meta, _ = runs[False]
    res = extract(df, meta, force="true", method="vetica-prestress", prestress="adhesion")
    assert err(res, "k_inf") < -5


def test_no_creep_interval_gives_nan_with_a_warning_like_vetica(runs):
    """Z1 at the tip's lowest point: no tap separates or lands below it, so stage 1a has no
    creep interval (a Z1 outside the record's tip range is refused as input)."""
    df, meta, s = runs[False]
    res = extract(df, meta, force="true", method="vetica-prestress", z1=float(s["z_tip"].min()))
    assert res.value("tau_c") is None and res.value("k0") is None
    assert any("stage 1a" in w for w in res.warnings)


def test_bad_options_are_one_line_errors(runs):
    df, meta, s = runs[False]
    with pytest.raises(InputError, match="prestress 'x' not allowed; choose one of: auto, adhesion, creep, fit"):
        extract(df, meta, force="true", method="vetica-prestress", prestress="x")
    with pytest.raises(InputError, match="not allowed here"):
        vetica_prestress(s["t"], s["z_tip"], s["f_ts"], 2e-10, prestress="auto")
    assert math.isfinite(vetica_prestress(s["t"], s["z_tip"], s["f_ts"], 2e-10, prestress="creep").values["k0"])


@pytest.mark.slow
def test_stages_without_a_fixed_point_are_flagged():
    """A `lab` record (300 K, the detector's band and noise) of a 7:1 surface (k_inf 2.12, k0 14.23
    N/m, cd 3.8e-4 kg/s; noise seed 267771479) whose contact the 1.75 MHz band leaves unresolved:
    vetica-prestress's stages 1b and 2 do not reach a fixed point in their 60 iterations and stop at
    Kg 1960 N/m (the surface's 16.4; stage 1b's slope 35.8).  Every quantity the fixed point gives
    is flagged, with the reason (it was unflagged at a 9 % sigma)."""
    from vetica_cli.extraction import extract_many
    from vetica_cli.simulation.config import load
    from vetica_cli.simulation.simulate import replicas

    ov = {"numerics.record_cycles": 10, "numerics.instrument": "lab", "surface.k_inf": 2.1207,
          "surface.k0": 14.2305, "surface.cd": 3.826e-4}  # fmt: skip
    run = replicas(load(None, ov), [267771479])[0]
    res = extract_many(run.frame(), run.metadata(), "reconstructed", {"vetica-prestress": {}})["vetica-prestress"]
    assert res.diagnostics["converged"] is False
    for q in ("k_g", "k0", "k_r", "k_inf", "cd", "tau_r"):
        e = res.estimates[q]
        assert e.value is None or e.identifiable is False, (q, e.value)
    # its reason among each quantity's flags (the first one shown: here the taps' irregular intervals,
    # 0.55-1.6 x their median, flag every quantity first)
    flags = res.info["sanity"]["flags"]
    assert all(any("fixed point" in r for r in flags[q]) for q in ("k_g", "k0", "k_r", "k_inf", "cd", "tau_r"))
