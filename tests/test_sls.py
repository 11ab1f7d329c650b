"""The surface updates against the closed-form SLS creep and relaxation.

Reference: Zener standard linear solid (thesis 2.5, eqs. 43-44, 68, 74-75):
relaxation modulus  E_rel(t) = Kr + (Kg - Kr) exp(-t/tau_r),   tau_r = cd/k0
creep compliance    J(t) = 1/Kr - (1/Kr - 1/Kg) exp(-t/tau_c), tau_c = cd (k0+k_inf)/(k0 k_inf)
with Kg = k0 + k_inf, Kr = k_inf.
"""

import math

import numpy as np
import pytest

from vetica_cli.core.sls import NEWTON_TOL, contact_update, noncontact_update, sls_coefficients, vdw_force

K_INF, K0, CD = 4.0, 128.0, 3e-5  # thesis worked example (table 4)
KG, KR = K0 + K_INF, K_INF
TAU_R = CD / K0
TAU_C = CD * KG / (K0 * K_INF)
DT = 0.025e-9
HR6 = 0.2e-18 * 10e-9 / 6
A0 = 0.2e-9


def test_retardation_time_of_worked_example_matches_thesis_table_2():
    # thesis table 2: tau_c theory = 7.7344e-6 s
    assert TAU_C == pytest.approx(7.7344e-6, rel=1e-4)


@pytest.mark.parametrize("cd", [1e-6, 3e-5, 1e-2])
def test_prescribed_indentation_relaxes_as_closed_form(cd):
    """Hold X = -delta: F_sls(t) = -delta (Kr + (Kg - Kr) exp(-t/tau_r)); rtol 1e-3."""
    ec, er, alpha, beta, gamma, kc, k0er, *_ = sls_coefficients(K_INF, K0, cd, DT, HR6, A0, True)
    tau_r = cd / K0
    delta = 2e-9
    xd = 0.0
    n_steps = int(min(5 * tau_r, 2e-5) / DT)
    t = np.arange(1, n_steps + 1) * DT
    f = np.empty(n_steps)
    for i in range(n_steps):
        f[i], xd = contact_update(-delta, xd, kc, k0er, er)
    expected = -delta * (KR + (KG - KR) * np.exp(-t / tau_r))
    np.testing.assert_allclose(f, expected, rtol=1e-3)


@pytest.mark.parametrize("vdw_on_surface", [True, False])
def test_released_surface_creeps_back_with_retardation_time(vdw_on_surface):
    """After a long hold at X = -delta (Xd = X), release with no load:
    X(t) = (k0/Kg) X0 exp(-t/tau_c) (closed-form recovery); rtol 1e-3."""
    ec, er, alpha, beta, gamma, kc, k0er, *_ = sls_coefficients(K_INF, K0, CD, DT, 0.0, A0, vdw_on_surface)
    x0 = -2e-9
    xd = x0
    n_steps = int(3 * TAU_C / DT)
    xs = np.empty(n_steps)
    for i in range(n_steps):
        # hr6 = 0: no attraction, the released surface only creeps
        _, xs[i], xd = noncontact_update(1e-6, xd, 0.0, 0.0, 0.0, alpha, beta, gamma, ec)
    t = np.arange(n_steps) * DT  # X_n uses Xd_{n-1}: X_0 is the instant of release
    expected = K0 / KG * x0 * np.exp(-t / TAU_C)
    np.testing.assert_allclose(xs, expected, rtol=1e-3)


def test_constant_pull_gives_closed_form_creep_compliance():
    """Constant van der Waals pull F on the surface from rest:
    X(t) = F J(t), J(t) = 1/Kr - (1/Kr - 1/Kg) exp(-t/tau_c); rtol 1e-3."""
    ec, er, alpha, beta, gamma, kc, k0er, *_ = sls_coefficients(K_INF, K0, CD, DT, HR6, A0, True)
    d = 0.5e-9  # fixed gap -> constant Fa
    fa_expected = HR6 / d**2
    xd = 0.0
    n_steps = int(4 * TAU_C / DT)
    xs = np.empty(n_steps)
    fa = 0.0  # no guess: the first step divides exactly, later ones refine the previous force
    for i in range(n_steps):
        fa, xs[i], xd = noncontact_update(d, xd, fa, HR6, 1 / HR6, alpha, beta, gamma, ec)
    assert fa == pytest.approx(fa_expected, rel=1e-12, abs=0.0)
    t = np.arange(1, n_steps + 1) * DT
    j = 1 / KR - (1 / KR - 1 / KG) * np.exp(-t / TAU_C)
    np.testing.assert_allclose(xs, fa_expected * j, rtol=1e-3)


def test_dashpot_step_is_stable_and_never_overshoots_when_tau_below_dt():
    """cd so small that tau_r = cd/k0 << dt: the exact exponential step must not
    overshoot the surface (the thesis's clamp) nor go unstable."""
    cd = 1e-12  # tau_r = 8e-15 s << dt
    ec, er, alpha, beta, gamma, kc, k0er, *_ = sls_coefficients(K_INF, K0, cd, DT, HR6, A0, True)
    xd = 0.0
    x = -1e-9
    for _ in range(100):
        f, xd = contact_update(x, xd, kc, k0er, er)
        assert x <= xd <= 0.0
    # fully relaxed: only k_inf carries load
    assert f == pytest.approx(K_INF * x, rel=1e-9, abs=0.0)
    assert math.isfinite(f)


@pytest.mark.parametrize("rel_guess_error", [0.0, 1e-6, 0.9e-4, -0.9e-4, 1e-3, 0.5, -1.0])
def test_vdw_force_newton_step_is_within_1e_8_of_exact(rel_guess_error):
    """Fa = H R/(6 d^2) (thesis eq. 3) from a guess off by rel_guess_error: one
    Newton step leaves a relative error <= (guess error)^2 <= 1e-8; guesses off by
    more than NEWTON_TOL fall back to the exact division."""
    for d in (0.2001e-9, 0.35e-9, 5e-9, 1e-6):
        exact = HR6 / d**2
        fa = vdw_force(d, exact * (1 + rel_guess_error), HR6, 1 / HR6)
        bound = rel_guess_error**2 * 1.01 if abs(rel_guess_error) <= NEWTON_TOL else 1e-15
        assert abs(fa / exact - 1) <= max(bound, 1e-15)
