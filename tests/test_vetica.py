"""VETICA stages 1a, 1b, 2 (thesis 3.3 and 4.3) and the worked example.

References: the closed-form SLS constants (thesis eqs. 68, 75-76, 81-83), the
closed-form exponential convolution checked by quadrature, the SLS Maxwell-arm
equation integrated directly, and the thesis worked example (tables 2-4) with
the bounds set for it (tau_c, Kg, k0 <= 2 %; k_inf, cd <= 5 %).
"""

import math

import numpy as np
import pytest
from scipy.integrate import quad

from vetica_cli import surfaces
from vetica_cli.errors import InputError
from vetica_cli.extraction import extract
from vetica_cli.extraction.vetica import (
    SineFit,
    boltzmann_force,
    exp_conv_cos,
    fit_sum_of_sines,
    sls_elements,
    stage1a_tau_c,
    stage2_kr,
)
from vetica_cli.signals.taps import Taps, find_taps

K0, KINF, CD = 128.0, 4.0, 3e-5  # worked example (thesis tables 2-4)


def theory(k0, k_inf, cd):
    """The SLS model's theory values (vetica_cli.surfaces.sls; thesis eqs. 68, 75-76)."""
    return surfaces.get("sls").theory({"k0": k0, "k_inf": k_inf, "cd": cd})


def test_theory_constants_of_the_worked_example():
    """tau_c = 7.7344e-6 s (thesis table 2), Kg = 132 N/m (table 3), tau_r = cd/k0."""
    th = theory(K0, KINF, CD)
    assert th["tau_c"] == pytest.approx(7.7344e-6, rel=1e-4)
    assert th["k_g"] == 132.0
    assert th["tau_r"] == pytest.approx(CD / K0, rel=1e-12, abs=0.0)
    assert th["tau_r"] == pytest.approx(th["tau_c"] * KINF / th["k_g"], rel=1e-12, abs=0.0)  # thesis eq. 76


def test_sls_elements_invert_the_theory_constants():
    """Thesis eqs. 81-83 undo eqs. 68, 75-76 (to rounding)."""
    th = theory(K0, KINF, CD)
    back = sls_elements(th["tau_c"], th["k_g"], th["k_r"])
    for k in ("k0", "k_inf", "cd", "tau_r"):
        assert back[k] == pytest.approx(th[k], rel=1e-12, abs=0.0)


def test_thesis_table4_recomputed_from_its_own_stage1_values():
    """Thesis tables 2-4: tau_c 7.6152e-6, Kg 131.79, Kr 4.0869 give k0 = 127.70 and
    cd = 3.016e-5 through eqs. 81-83, not the printed 127.91 and 2.99e-5 (table 4 is
    internally inconsistent; results/thesis/worked_example.md)."""
    e = sls_elements(7.6152e-6, 131.79, 4.0869)
    assert e["k0"] == pytest.approx(127.70, abs=0.005)
    assert e["cd"] == pytest.approx(3.016e-5, rel=1e-3)


def test_exponential_convolution_closed_form_matches_quadrature():
    """int_0^u exp(-(u-s)/tau) cos(b s + c) ds: closed form against scipy quad, 1e-9."""
    tau, b, c = 2.3e-7, 3.1e6, 0.7
    u = np.array([0.0, 1e-7, 5e-7, 1.3e-6])
    got = exp_conv_cos(u, np.array([b]), np.array([c]), tau)[:, 0]
    ref = [quad(lambda s, uu=uu: math.exp(-(uu - s) / tau) * math.cos(b * s + c), 0, uu, epsabs=0, epsrel=1e-12)[0]
           for uu in u]  # fmt: skip
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-22)


def _maxwell_force(u, z, kg, kr, tau_r):
    """SLS force of an indentation delta = z(0) - z(u) from rest, by integrating the
    Maxwell arm sigma' = k0 delta' - sigma/tau_r exactly for piecewise-linear delta
    (thesis eqs. 43-44); F = kr delta + sigma."""
    delta = z[0] - z
    k0 = kg - kr
    sig = np.zeros_like(u)
    for i in range(1, len(u)):
        h = u[i] - u[i - 1]
        e = math.exp(-h / tau_r)
        sig[i] = sig[i - 1] * e + k0 * (delta[i] - delta[i - 1]) / h * tau_r * (1 - e)
    return kr * delta + sig


# a contact trajectory of the worked example's shape: 1.36 us, 2.3 nm deep, paddle ring
U = np.linspace(0.0, 1.36e-6, 4001)
TRUE_FIT = SineFit(
    b=np.array([2 * math.pi * 50e3, 2 * math.pi * 750e3, math.pi / 1.36e-6, 0.0]),
    p=np.array([-1.2e-9, 2e-10, -1.1e-9, 0.0]),
    q=np.array([0.3e-9, -1e-10, 0.0, 5e-10]),
    rms=0.0,
)
Z = TRUE_FIT(U)


def test_boltzmann_superposition_matches_the_maxwell_arm_equation():
    """Thesis eqs. 75-78 in closed form against the SLS differential equation
    integrated directly: 1e-5 of the peak force (discretisation of the reference)."""
    th = theory(K0, KINF, CD)
    f_ref = _maxwell_force(U, Z, th["k_g"], KINF, th["tau_r"])
    f = boltzmann_force(U, TRUE_FIT, th["k_g"], KINF, th["tau_r"])
    assert np.max(np.abs(f - f_ref)) < 1e-5 * np.max(np.abs(f_ref))


@pytest.mark.parametrize("guess", [1e-6, 1e-2, 4.0, 1e2, 131.0])
def test_stage2_recovers_kr_from_any_initial_guess(guess):
    """Kr from a synthetic SLS force, initial guesses over eight decades (the thesis
    tried ten, fig. 40, converging within 15 iterations): 1e-4 relative, < 40 evaluations."""
    th = theory(K0, KINF, CD)
    f = _maxwell_force(U, Z, th["k_g"], KINF, th["tau_r"]) - 8.3e-9  # contact offset -Fa(a0)
    fit = fit_sum_of_sines(U, Z)
    kr, _rms, nfev = stage2_kr(U, f, fit, th["k_g"], th["tau_c"], float(f[0]), kr_guess=guess)
    assert kr == pytest.approx(KINF, rel=1e-4)
    assert nfev < 40, nfev


def test_sum_of_sines_fits_a_contact_trajectory():
    """Three sines (+ constant) fit the synthetic 3-component trajectory to < 1 pm RMS
    (thesis fig. 38: residuals of a few pm)."""
    fit = fit_sum_of_sines(U, Z + 1e-13 * np.sin(7e7 * U))
    assert fit.rms < 1e-12


def test_stage1a_recovers_tau_c_from_exponential_creep():
    """Tip positions following Z(t) - Z1 = (Z' - Z1) exp(-t/tau_c) give thesis eq. 73's
    tau_c to rounding; a non-recovering interval gives nan."""
    tau_c, z1 = 7.7344e-6, 0.2e-9
    t = np.arange(22) * 1e-6
    z = np.full(22, z1)
    z[1] = z1 - 2.2e-9  # separation of tap 0
    z[10] = z1 - 2.2e-9 * math.exp(-9e-6 / tau_c)  # contact of tap 1
    z[11] = z1 + 1e-10  # separation of tap 1 above Z1: no creep towards Z1 to measure
    z[20] = z1 - 1e-10  # contact of tap 2
    taps = Taps(np.array([0, 10, 20]), np.array([1, 11, 21]), np.array([0, 10, 20]), 10.0)
    got = stage1a_tau_c(t, z, taps, z1)
    assert len(got) == 2
    assert got[0] == pytest.approx(tau_c, rel=1e-9, abs=0.0)
    assert math.isnan(got[1])


def test_find_taps_without_repulsion_is_an_input_error():
    f = -1e-9 / (1 + np.linspace(0, 10, 1000) ** 2)
    with pytest.raises(InputError, match="no contact found"):
        find_taps(f)


# ----------------------------------------------------------------------------- worked example


@pytest.fixture(scope="module")
def vdw_off(worked_example):
    """Worked example with the vdW pull on the surface off (the bounds' setting; conftest)."""
    run = worked_example(pull=False)
    return run.frame(), run.metadata()


@pytest.fixture(scope="module")
def vdw_on(worked_example):
    run = worked_example(pull=True)
    return run.frame(), run.metadata()


BOUNDS = {"tau_c": 2.0, "k_g": 2.0, "k0": 2.0, "k_inf": 5.0, "cd": 5.0}  # the target bounds, in %


@pytest.mark.parametrize("force", ["true", "reconstructed"])
def test_worked_example_within_issue_bounds(vdw_off, force):
    """Target bounds: tau_c, Kg, k0 <= 2 %; k_inf, cd <= 5 % with the true and the
    reconstructed force (vdW off; measured 0.06, 0.13-0.29, 0.09-0.26, 1.42, 1.32 %)."""
    df, meta = vdw_off
    res = extract(df, meta, force=force)
    assert res.force == force
    assert res.taps >= 5
    for name, bound in BOUNDS.items():
        assert abs(res.estimates[name].error_pct) <= bound, (name, res.estimates[name])


def test_spread_over_taps_is_reported_and_small(vdw_off):
    """Per-tap values of a steady record agree within 0.5 % (measured <= 0.07 %)."""
    df, meta = vdw_off
    res = extract(df, meta, force="true")
    for name in ("tau_c", "k_g", "k_r", "k0", "k_inf", "cd"):
        sp = res.estimates[name].spread
        assert sp.n >= res.taps - 1
        assert sp.min * (1 - 1e-12) <= res.value(name) <= sp.max * (1 + 1e-12)
        assert sp.std < 5e-3 * abs(sp.mean)


def test_kg_with_vdw_on_surface_is_the_prestress_relaxation_slope(vdw_on):
    """With the van der Waals pull on the surface, the Maxwell arm is pre-stretched at
    contact (sigma_M = k0 (X - Xd) ~ Fa(a0)) and its dashpot still moves, so the first
    samples measure Kg + k0 Xd'/|z_tip'| instead of Kg: the reason the vdW-on worked
    example misses the 2 % bound (measured +3.96 % against the predicted +4.06 %).
    Held: error > 2 %, and within 0.3 % of the predicted apparent stiffness."""
    df, meta = vdw_on
    res = extract(df, meta, force="true")
    s = df[df.segment == "steady"]
    t, z, x, xd = (s[c].to_numpy() for c in ("t", "z_tip", "x_surface", "x_dashpot"))
    taps = find_taps(s.f_ts.to_numpy())
    ic = taps.contact
    h = t[1] - t[0]
    v = (z[ic + 6] - z[ic + 1]) / (5 * h)
    vd = (xd[ic + 6] - xd[ic + 1]) / (5 * h)
    apparent = np.mean(K0 + KINF - K0 * vd / v)
    assert res.estimates["k_g"].error_pct > 2.0
    assert res.value("k_g") == pytest.approx(apparent, rel=3e-3)
    assert np.mean(K0 * (x[ic] - xd[ic])) == pytest.approx(8.33e-9, rel=0.1)  # ~ Fa(a0) = H R/(6 a0^2)
