"""Whole-cycle model inversion, ``--method full``.

References: finite differences of the kernel itself (its tangent-linear
Jacobian), the simulator's own force and dashpot state (the prescribed-
trajectory surface must reproduce them at the true parameters), the true
surface parameters of simulated runs (k0, k_inf, cd from the metadata; the
issue's done-when: the worked example within 1 %), and VETICA's errors on the
same run (thesis 3.3).
"""

import math

import numpy as np
import pytest

from vetica_cli.core.prescribed import NDIR, arm_coefficients, arms_force, surface_force
from vetica_cli.errors import InputError
from vetica_cli.extraction import extract
from vetica_cli.extraction.format import to_json
from vetica_cli.extraction.fullfit.model import SurfaceFit
from vetica_cli.extraction.record import segment
from vetica_cli.signals.taps import first_contact_minimum
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import simulate

K0, KINF, CD = 128.0, 4.0, 3e-5  # worked example (thesis tables 2-4)
HR6 = 0.2e-18 * 10e-9 / 6  # H R / 6 [J m]
A0 = 0.2e-9


def _taps(n=8000, h=0.1e-9, mean=2e-9, amp=3e-9, period=200e-9):
    """Synthetic tip trajectory tapping the surface: z = mean + amp cos(2 pi t/period)."""
    t = np.arange(n) * h
    return np.ascontiguousarray(mean + amp * np.cos(2 * np.pi * t / period)), h


def _run(z, h, theta, s0=0.0, xd0=-1e-10, ndir=0, substeps=1, block=16, coarse=False, far_gap=5e-9):
    n = len(z)
    want = np.ones(n, np.uint8) if not coarse else ((np.arange(n) + 1) % block == 0).astype(np.uint8)
    ok = np.full(n // block, 1 if coarse else 0, np.uint8)
    out_f = np.empty(int(want.sum()))
    out_j = np.empty((len(out_f), NDIR))
    res = surface_force(z, s0, *theta, A0, True, h, block, ok, want, far_gap, substeps, 1e-9,
                        xd0, False, ndir, out_f, out_j)  # fmt: skip
    return out_f, out_j, res


@pytest.mark.parametrize("substeps", [1, 5])
def test_tangent_linear_kernel_matches_finite_differences(substeps):
    """dFts/d(Xd0, s0, ln k_inf, ln k0, ln cd, ln HR/6) against central differences
    of the kernel itself; rtol 1e-5 on the column norm (contact schedule fixed)."""
    z, h = _taps()
    theta = np.array([KINF, K0, CD, HR6])
    f, jac, _ = _run(z, h, theta, ndir=NDIR, substeps=substeps)
    assert np.max(f) > 1e-8 and np.min(f) < -5e-9  # the trajectory taps the surface
    steps = (1e-15, 1e-15, 1e-6, 1e-6, 1e-6, 1e-6)
    for j, eps in enumerate(steps):

        def g(sign, j=j, eps=eps):
            th, s0, xd0 = theta.copy(), 0.0, -1e-10
            if j == 0:
                xd0 += sign * eps
            elif j == 1:
                s0 += sign * eps
            else:
                th[j - 2] *= math.exp(sign * eps)
            return _run(z, h, th, s0=s0, xd0=xd0, substeps=substeps)[0]

        fd = (g(1) - g(-1)) / (2 * eps)
        assert np.linalg.norm(fd - jac[:, j]) <= 1e-5 * np.linalg.norm(jac[:, j]), j


@pytest.mark.parametrize("substeps", [1, 5])
def test_kernel_without_the_start_state_direction_is_the_same_kernel(substeps):
    """A record whose start state is known (the approach, from an undeformed surface) skips the
    Xd0 direction (``dir0 = 1``): the force and every other column, bit for bit."""
    z, h = _taps()
    n = len(z)
    want, ok = np.ones(n, np.uint8), np.zeros(n // 16, np.uint8)
    out = []
    for dir0 in (0, 1):
        f, j = np.empty(n), np.empty((n, NDIR))
        surface_force(z, 0.0, KINF, K0, CD, HR6, A0, True, h, 16, ok, want, 5e-9, substeps, 1e-9, 0.0, False, NDIR,
                      f, j, dir0)  # fmt: skip
        out.append((f, j[:, 1:]))
    np.testing.assert_array_equal(out[0][0], out[1][0])
    np.testing.assert_array_equal(out[0][1], out[1][1])


def _run_arms(z, h, p, xd0, ndir=0, s0=0.0, substeps=1, vdw=True, block=16):
    """The N-arm kernel on ``z``: ``p = (k_inf, k_1, cd_1, ..., H R/6)``."""
    n, na = len(z), len(xd0)
    co = arm_coefficients(p[0], p[1:-1:2], p[2:-1:2], p[-1], A0, vdw, (h, h * block, h / substeps), ndir > na + 1)
    f, jac = np.empty(n), np.empty((n, 3 * na + 3))
    res = arms_force(z, s0, A0, block, np.zeros(n // block, np.uint8), np.ones(n, np.uint8), 5e-9, substeps, 1e-9,
                     np.array(xd0, float), False, ndir, *co, f, jac)  # fmt: skip
    return f, jac, res


@pytest.mark.slow
@pytest.mark.parametrize("vdw", [True, False])
@pytest.mark.parametrize("substeps", [1, 5])
def test_n_arm_tangents_match_finite_differences(substeps, vdw):
    """Two arms (tau 0.47 us and 3 ns): dFts along (Xd0_1, Xd0_2, s0, ln k_inf, ln k_i, ln cd_i,
    ln HR/6) -- the coefficient derivatives by complex step -- against central differences
    of the kernel itself; rtol 1e-6 on the column norm (measured <= 1.1e-7)."""
    z, h = _taps()
    p = np.array([KINF, 64.0, 3e-5, 32.0, 1e-7, HR6])
    xd0 = [-1e-10, -2e-10]
    f, jac, _ = _run_arms(z, h, p, xd0, ndir=9, substeps=substeps, vdw=vdw)
    assert np.max(f) > 1e-8
    for c in range(9):

        def g(sign, c=c):
            pp, s0, x0 = p.copy(), 0.0, list(xd0)
            eps = 1e-15 if c <= 2 else 1e-6
            if c < 2:
                x0[c] += sign * eps
            elif c == 2:
                s0 += sign * eps
            else:
                pp[c - 3] *= math.exp(sign * eps)
            return _run_arms(z, h, pp, x0, s0=s0, substeps=substeps, vdw=vdw)[0] / eps

        fd = 0.5 * (g(1) - g(-1))
        assert np.linalg.norm(fd - jac[:, c]) <= 1e-6 * np.linalg.norm(jac[:, c]), c


@pytest.mark.parametrize("substeps", [1, 5])
def test_n_arm_kernel_with_one_arm_is_the_sls_kernel(substeps):
    """The general kernel with one arm against the SLS fast path (a different code: scalar
    closed-form coefficients and tangents): force to 1e-12 of the peak, every Jacobian column
    to 1e-6 of its norm (measured 7e-8: the SLS path leaves out the start state's parameter
    derivatives of the first sample's surface position)."""
    z, h = _taps()
    f1, j1, r1 = _run(z, h, (KINF, K0, CD, HR6), xd0=-1e-10, ndir=NDIR, substeps=substeps)
    f2, j2, r2 = _run_arms(z, h, np.array([KINF, K0, CD, HR6]), [-1e-10], ndir=NDIR, substeps=substeps)
    assert np.max(np.abs(f2 - f1)) <= 1e-12 * np.max(np.abs(f1))
    for c in range(NDIR):
        assert np.linalg.norm(j2[:, c] - j1[:, c]) <= 1e-6 * np.linalg.norm(j1[:, c]), c
    assert r1[5:] == r2[5:]  # contacts, separations, coarse steps


def test_far_field_coarse_steps_do_not_change_the_force():
    """Blocks of 16 samples advanced in one exact step where the gap exceeds 5 nm give
    the force of the sample-by-sample update to 1e-6 of the peak force."""
    z, h = _taps(n=32000, mean=20e-9, amp=22e-9, period=800e-9)
    theta = (KINF, K0, CD, HR6)
    fine, _, res_fine = _run(z, h, theta, coarse=False)
    coarse, _, res_coarse = _run(z, h, theta, coarse=True)
    assert res_coarse[7] > 1000 and res_fine[7] == 0  # coarse steps were taken
    want = (np.arange(len(z)) + 1) % 16 == 0
    np.testing.assert_allclose(coarse, fine[want], rtol=0, atol=1e-6 * np.max(fine))


# ----------------------------------------------------------------------------- worked example


@pytest.fixture(scope="module")
def worked(worked_example):
    """The worked example at the defaults (PS 0.125 ns, 10 recorded periods; conftest, once a session)."""
    run = worked_example()
    return run.frame(), run.metadata()


def test_prescribed_surface_reproduces_the_simulator_at_the_true_parameters(worked):
    """Driven by the simulator's own z_tip with the true k_inf, k0, cd and s0 = 0, the
    periodic model gives f_ts to 2e-6 of the peak force (RMS; measured 4.0e-7: in contact
    the model updates the dashpot once per 0.125 ns sample with the simulator's linear-target
    step, the surface moving linearly across it; the step that held the surface at the sample,
    first order, gave 9.7e-5: its relaxation read (h - dt)/2 late, ~4 pN) and the dashpot
    position at the window start to 1e-4 (simulator: x_dashpot of the last sample, one period on)."""
    df, _ = worked
    st, ap = segment(df, "steady"), segment(df, "approach")
    t, z, f = st["t"].to_numpy(), st["z_tip"].to_numpy(), st["f_ts"].to_numpy()
    i1 = first_contact_minimum(ap["f_ts"].to_numpy())
    h = (t[-1] - t[0]) / (len(t) - 1)
    model = SurfaceFit(z, f, h, ap["z_tip"].to_numpy()[i1], (ap["z_tip"].to_numpy(), ap["f_ts"].to_numpy(), i1),
                       A0, 10e-9, True, near_stride=1, substeps=5)  # fmt: skip
    fm, _ = model.evaluate(np.array([KINF, K0, CD, HR6]), 0.0, ndir=0)
    rms = np.sqrt(np.mean((fm - model.f) ** 2)) / np.max(f)
    assert rms < 2e-6
    assert model.window_start_xd == pytest.approx(st["x_dashpot"].to_numpy()[-1], rel=1e-4, abs=0.0)


@pytest.mark.parametrize("force", ["true", "reconstructed"])
def test_full_method_recovers_the_worked_example_within_1_percent(worked, force):
    """Target: k0, k_inf, cd within 1 % of the run's truth (measured: 0.02 %),
    every parameter identifiable, the same keys as VETICA's extract()."""
    df, meta = worked
    res = extract(df, meta, force=force, method="full")
    for name in ("k0", "k_inf", "cd", "tau_c", "k_g"):
        assert abs(res.estimates[name].error_pct) < 1.0, name
    assert {k: res.estimates[k].identifiable for k in res.fitted} == {"k_inf": True, "k0": True, "cd": True}
    assert all(0 < res.estimates[k].sigma < 0.01 for k in ("k0", "k_inf", "cd"))
    ref = extract(df, meta, force=force)
    assert set(ref.estimates) <= set(res.estimates)
    assert set(to_json(ref)) - {"info"} <= set(to_json(res)) - {"info"}
    assert res.method == "full" and res.force == force and res.taps == ref.taps


@pytest.mark.parametrize(
    "start", [{"k_inf": 0.04, "k0": 1.28, "cd": 3e-8}, {"k_inf": 400.0, "k0": 12800.0, "cd": 3e-2}]
)
def test_converges_from_starts_decades_away(worked, start):
    """Starting stiffnesses 100x off and cd 1000x off (both ways): still within 1 %."""
    df, meta = worked
    res = extract(df, meta, force="true", method="full", start=start)
    for name in ("k0", "k_inf", "cd"):
        assert abs(res.estimates[name].error_pct) < 1.0, name


def test_offset_of_the_tip_coordinate_only_moves_the_surface_height(worked):
    """Adding 3 nm to z_tip (an instrument's unknown offset) changes neither k0, k_inf nor
    cd (rtol 1e-4); the fitted surface height moves by the 3 nm (to 1 pm)."""
    df, meta = worked
    shifted = df.copy()
    shifted["z_tip"] = shifted["z_tip"] + 3e-9
    a = extract(df, meta, force="true", method="full")
    b = extract(shifted, meta, force="true", method="full")
    for name in ("k0", "k_inf", "cd"):
        assert b.value(name) == pytest.approx(a.value(name), rel=1e-4), name
    ha, hb = a.info["fit"]["surface_height_m"], b.info["fit"]["surface_height_m"]
    assert hb - ha == pytest.approx(3e-9, abs=1e-12)


def test_a_good_start_scans_only_its_neighbours_and_picks_what_the_whole_scan_picks(worked, monkeypatch):
    """VETICA's start on the worked example fits to 3 % of the peak force after its Gauss-Newton
    step (under GOOD_START_RMS): the cd scan then tries only the grid's cd within two decades of
    it, and the fit must return what it returns after the whole scan, to 1e-9 (the same pick:
    the same arithmetic), with fewer model passes."""
    from vetica_cli.extraction.fullfit import fit as fullfit_fit

    df, meta = worked
    short = extract(df, meta, force="true", method="full")
    monkeypatch.setattr(fullfit_fit, "GOOD_START_RMS", 0.0)
    whole = extract(df, meta, force="true", method="full")
    for name in ("k0", "k_inf", "cd"):
        assert short.value(name) == pytest.approx(whole.value(name), rel=1e-9, abs=0.0), name
        assert short.estimates[name].sigma == pytest.approx(whole.estimates[name].sigma, rel=1e-6, abs=0.0), name
    assert short.info["fit"]["model_passes"] < whole.info["fit"]["model_passes"]


def test_models_of_one_record_share_the_approach_passes(worked):
    """A model of the whole window built after one of its first period (the fit's stages) takes
    the first's approach record and its last passes: its force and Jacobian at the first's last
    point are those of a model built alone, bit for bit, with one kernel pass fewer."""
    df, _ = worked
    st, ap = segment(df, "steady"), segment(df, "approach")
    t, z, f = st["t"].to_numpy(), st["z_tip"].to_numpy(), st["f_ts"].to_numpy()
    za, fa = ap["z_tip"].to_numpy(), ap["f_ts"].to_numpy()
    i1 = first_contact_minimum(fa)
    h = (t[-1] - t[0]) / (len(t) - 1)
    approach = (za, fa, i1)

    def make(n, shared=None):
        return SurfaceFit(z[:n], f[:n], h, za[i1], approach, A0, 10e-9, True, substeps=5, shared=shared)

    theta, s0 = np.array([KINF, K0, CD, HR6]), 1e-12
    sub = make(len(z) // 10)
    sub.evaluate(theta, s0, ndir=5)
    whole, alone = make(len(z), shared=sub), make(len(z))
    fw, jw = whole.evaluate(theta, s0, ndir=5)
    fs, js = alone.evaluate(theta, s0, ndir=5)
    assert whole.approach is sub.approach
    np.testing.assert_array_equal(fw, fs)
    np.testing.assert_array_equal(jw, js)
    assert whole.passes == alone.passes - 1


def test_residual_samples_every_stride():
    """The samples a residual is taken at: every ``near_stride``-th sample (index divisible by
    it) where the tip is within the near gap of the reference, every ``far_stride``-th
    (index + 1 divisible by it) elsewhere."""
    from vetica_cli.extraction.fullfit.model import SampledRecord

    z, _ = _taps(n=5000, mean=8e-9, amp=6e-9)
    rec = SampledRecord(z, np.zeros(len(z)), 0.0, 4, 64, 16, 5e-9, ndir=6)
    i = np.arange(len(z))
    expected = np.where(z < 5e-9, i % 4 == 0, (i + 1) % 64 == 0)
    assert 0 < expected.sum() < len(z) and (z < 5e-9).any() and (z >= 5e-9).any()
    np.testing.assert_array_equal(rec.idx, np.flatnonzero(expected))


@pytest.mark.parametrize("kw, fragment", [({"force": "model"}, "force"), ({"state": "steady"}, "state")])
def test_bad_options_raise_one_line_input_errors(worked, kw, fragment):
    df, meta = worked
    with pytest.raises(InputError, match=fragment):
        extract(df.iloc[:10], meta, method="full", **kw)


# ----------------------------------------------------------------------------- beyond VETICA


@pytest.mark.slow
def test_recovers_cd_0p01_ratio_16_where_vetica_fails():
    """cd = 1e-2 kg/s, k0:k_inf = 16:1 (outside VETICA's acceptance regime, thesis fig. 52):
    VETICA's k_inf error exceeds 30 % (measured on the periodic orbit: k_inf -61 %, cd +29 %);
    the full method is within 1 % on the true and the reconstructed force."""
    run = simulate(load(None, {"surface.k0": 64.0, "surface.cd": 1e-2}))
    df, meta = run.frame(), run.metadata()
    ref = extract(df, meta, force="true")
    assert abs(ref.estimates["k_inf"].error_pct) > 30
    for force in ("true", "reconstructed"):
        res = extract(df, meta, force=force, method="full")
        for name in ("k0", "k_inf", "cd"):
            assert abs(res.estimates[name].error_pct) < 1.0, (force, name)
            assert res.estimates[name].identifiable, (force, name)


@pytest.mark.slow
def test_frozen_dashpot_is_flagged_not_identifiable():
    """cd = 1e2 kg/s (tau_c ~ 27 s): on the periodic orbit the dashpot moves by ~1e-6 of its
    stretch within a tap.  Noise-free, that signature is still above the fit's residual and
    k0, k_inf, cd come back (measured: cd -0.22 %, k_inf -6e-5 %); with 1 pN of force noise
    (measured signature 9e-7 of the peak, below 10 x the residual) the fit must say so -- cd,
    k0 and k_inf not identifiable -- while Kg = k0 + k_inf, the stiffness such a surface
    shows, is recovered within 1 %."""
    base = {"surface.k0": 64.0, "surface.cd": 100.0}
    run = simulate(load(None, base))
    res = extract(run.frame(), run.metadata(), force="true", method="full")
    assert all(abs(res.estimates[k].error_pct) < 1.0 for k in ("k0", "k_inf", "cd"))
    run = simulate(load(None, {**base, "numerics.force_noise": 1e-12}))
    res = extract(run.frame(), run.metadata(), force="true", method="full")
    assert {k: res.estimates[k].identifiable for k in res.fitted} == {"k_inf": False, "k0": False, "cd": False}
    assert abs(res.estimates["k_g"].error_pct) < 1.0
    assert res.estimates["k_g"].sigma < 0.01


def test_a_jump_that_straddles_a_sample_is_left_out():
    """A snap to contact whose runaway a sample catches half-way shows as two big steps of one
    sign; held together against the steps either side, they are one jump (and its samples are
    left out), where each step alone is under JUMP_RATIO times its bigger neighbour.  A smooth rise
    of big steps, and a lone step under the ratio, are not jumps.  (Force shape: the 1:2 record
    below, samples 182094-182105 relative to its peak.)"""
    from vetica_cli.extraction.fullfit.model import JUMP_RATIO, jump_samples

    pull = [-0.0224, -0.0235, -0.0247, -0.0262, -0.0282, -0.0314, -0.0590, -0.0723, -0.0714, -0.0706, -0.0697]
    lead = list(np.linspace(-0.002, -0.0215, 20))  # the attraction growing smoothly (steps of 0.1 %)
    f = np.array(lead + pull + list(np.linspace(-0.06, 1.0, 40)) + list(np.linspace(1.0, 0.0, 40)) + [0.0] * 20)
    d = np.abs(np.diff(f))
    i = 20 + 5  # the step -0.0314 -> -0.0590, then -0.0590 -> -0.0723
    assert d[i] < JUMP_RATIO * d[i + 1] and d[i + 1] < JUMP_RATIO * d[i]  # neither step alone is a jump
    out = jump_samples(f)
    assert out[i] and out[i + 1] and out[i + 2] and out[i + 3]
    assert not out[:10].any() and not out[40:].any()  # the lead-in's far part, the smooth rise and fall: no jump
    g = f.copy()
    g[i + 1] = g[i]  # the same jump in one step: one step, as before
    assert jump_samples(g)[i : i + 3].all()


def test_the_fit_of_a_snapping_surface_whose_jump_straddles_a_sample():
    """1:2 (k0 2, k_inf 4 N/m; Kg 6 N/m snaps to the tip), cd 1e-3 kg/s, 0.5 ns, noise-free, true force:
    each tap's snap falls across a sample (the jump read in two steps), which the fit missed, and a
    sample a tap a whole jump off the model's made the least squares rugged: cd -4.1 % at a 1-sigma of
    4.1 %.  With the jump left out: k0, k_inf, cd within 0.01 % (measured 0.000 %), the RMS residual
    below 1e-5 of the peak."""
    run = simulate(load(None, {"surface.k_inf": 4.0, "surface.stiffness_ratio": 0.5, "surface.cd": 1e-3,
                               "numerics.print_step": 0.5e-9}))  # fmt: skip
    res = extract(run.frame(), run.metadata(), force="true", method="full")
    for q in ("k0", "k_inf", "cd"):
        assert abs(res.estimates[q].error_pct) < 0.01, (q, res.estimates[q].error_pct)
    assert res.info["fit"]["residual_rms_pct"] < 1e-3


def test_a_first_stage_that_ends_on_the_frozen_plateau_is_fitted_from_below_it(monkeypatch):
    """16:1 (k0 64, k_inf 4 N/m), cd 1e-3 kg/s, 0.125 ns, 1 pm of detector noise, the force reconstructed
    (low-passed at 5.5 MHz by its noise): from its cd scan's start the first stage walked onto the frozen
    plateau (cd 4.5e4 kg/s, RMS 1.96 % of the peak, every quantity flagged), where the right valley is at
    1.43 %.  Fitted again from the scan's best point below the plateau (FROZEN_RETRY): k0, k_inf within 1 %,
    cd within 3 % (measured -0.27, +0.27, -1.7 %), unflagged.  Without the retry the first stage ends on the
    plateau (the control); the whole window's stages then walked off it on the fit's kernels without
    floating-point contraction (cd -1.5 %), where with contraction they stayed (cd off the scale): which of
    the two a record sees is a knife edge, which the retry takes away."""
    import vetica_cli.extraction.fullfit.method as fm
    from vetica_cli.extraction.fullfit.fit import CD_SCAN

    run = simulate(load(None, {"surface.k_inf": 4.0, "surface.stiffness_ratio": 16, "surface.cd": 1e-3,
                               "numerics.position_noise": 1e-12}))  # fmt: skip
    df, meta = run.frame(), run.metadata()
    res = extract(df, meta, force="reconstructed", method="full")
    assert res.info["fit"]["frozen_retry"] is True
    for q, tol in (("k0", 1.0), ("k_inf", 1.0), ("cd", 3.0)):
        assert abs(res.estimates[q].error_pct) < tol, (q, res.estimates[q].error_pct)
        assert res.estimates[q].identifiable is not False, (q, res.estimates[q].reason)
    monkeypatch.setattr(fm, "FROZEN_RETRY", False)
    first = []
    fit_surface = fm.fit_surface

    def spy(*a, **k):
        out = fit_surface(*a, **k)
        first.append(float(out["theta"][2]))
        return out

    monkeypatch.setattr(fm, "fit_surface", spy)
    extract(df, meta, force="reconstructed", method="full")
    assert first and first[0] >= CD_SCAN[-1], first  # the first stage (the first fit) on the frozen plateau


# ----------------------------------------------------------------------------- the window's start state


@pytest.mark.slow
def test_a_record_taken_before_the_surface_settled_releases_the_start_state():
    """A record 4 ms after the approach (``numerics.steady: transient`` stopped by ``max_time``;
    cd 3e-2 kg/s at 32:1, tau_c 0.23 ms): its dashpot has not reached the periodic orbit.  Held
    periodic the fit reads k_inf +138 % (measured); ``state='auto'`` sees the state remove more than
    half the residual (measured 0.995), frees it and recovers the surface within 0.01 % (measured
    3e-4 %)."""
    run = simulate(load(None, {"surface.cd": 3e-2, "numerics.steady": "transient", "numerics.max_time": 4e-3,
                               "numerics.record_cycles": 4, "numerics.print_step": 1e-9}))  # fmt: skip
    df, meta = run.frame(), run.metadata()
    held = extract(df, meta, force="true", method="full", state="periodic")
    assert abs(held.estimates["k_inf"].error_pct) > 50.0
    res = extract(df, meta, force="true", method="full")
    assert res.info["free_state_gain"] > 0.5 and res.info["fit"]["state"] == "free"
    for q in ("k0", "k_inf", "cd"):
        assert abs(res.estimates[q].error_pct) < 0.01, q


def test_misfit_term_is_the_misfit_over_the_dashpots_signature():
    """The misfit term against its closed form: one arm (the SLS) of signature ``s`` = (k0/Kg) x the
    larger of its relaxation in a contact and its creep between taps (thesis SLS: tau_r = cd/k0,
    tau_c = cd Kg/(k0 k_inf)); a misfit ``m`` gives ln cd a 1-sigma of m/s, and so tau_c and tau_r
    (each proportional to cd), and nothing to k0, k_inf or Kg, which do not depend on cd.  No
    misfit, no term."""
    from vetica_cli.extraction.fullfit.uncertainty import misfit_term
    from vetica_cli.surfaces import get

    sls = get("sls")
    k_inf, k0, cd, t_contact, t_free = 4.0, 64.0, 100.0, 1.4e-6, 18.6e-6
    params = sls.from_arms(k_inf, [k0], [cd])
    grads = sls.log_gradients(params)
    kg = k0 + k_inf
    relax = 1.0 - math.exp(-t_contact * k0 / cd)
    creep = 1.0 - math.exp(-t_free * k0 * k_inf / (cd * kg))
    s = k0 / kg * max(relax, creep)
    out = misfit_term(7e-8, k_inf, [(k0, cd)], t_contact, t_free, grads, 5)
    for q in ("cd", "tau_c", "tau_r"):
        assert out[q] == pytest.approx(7e-8 / s, rel=1e-9, abs=0), q
    for q in ("k0", "k_inf", "k_g"):
        assert out[q] == 0.0, q
    assert misfit_term(0.0, k_inf, [(k0, cd)], t_contact, t_free, grads, 5) == {}


def test_systematic_misfit_is_what_repeats_every_period():
    """:func:`systematic_misfit` against its construction: rows every 4 samples, a period of 400
    samples (10 periods); a residual that repeats every period (RMS 0.3) plus white noise (RMS 0.2,
    independent from row to row): the repeating part comes back within its sampling error (~0.2^2 /
    sqrt(1000 pairs)), the rest is the noise; white noise alone repeats nothing; a force noise floor
    above the residual bounds it to 0."""
    from vetica_cli.extraction.fullfit.uncertainty import systematic_misfit

    rng = np.random.default_rng(5)
    idx = np.arange(0, 4000, 4)
    shape = 0.3 * math.sqrt(2.0) * np.sin(2 * np.pi * idx / 400 * 3)  # RMS 0.3, period 400 samples
    noise = rng.normal(0.0, 0.2, len(idx))
    rep, rest = systematic_misfit(shape + noise, idx, 400, 0.0)
    assert rep == pytest.approx(0.3, abs=0.02) and rest == pytest.approx(0.2, abs=0.02)
    rep, rest = systematic_misfit(noise, idx, 400, 0.0)
    assert rep < 0.03 and rest == pytest.approx(0.2, abs=0.02)
    assert systematic_misfit(shape, idx, 400, 1.0)[0] == 0.0


def test_misfit_pairs_rows_a_drive_period_apart_when_the_taps_spacing_misses_it():
    """The period the misfit's rows are paired at, against its construction: a tip position of period
    400 samples (a cosine and its third harmonic), the taps' spacing read 6 samples long (as on a
    stripped 300 K record: 40,009 for 40,000); :func:`drive_period` reads 400 back from the position.
    Rows thinned to every 4th sample on a grid offset by 2 from the period's (so 401 and
    the period's 400 are on different grids): white noise alone, asked to pair at
    401, repeats nothing beyond its sampling error (the covariance of ~1000 pairs: sd 0.2^2 / sqrt(1000),
    so below 0.06 after the square root; the lag search pairs at 400), where with no row pairs the bound
    calls the residual above the floor a misfit, sqrt(0.2^2 - 0.1^2) = 0.17 (the old reading)."""
    from vetica_cli.extraction.fullfit.uncertainty import drive_period, systematic_misfit

    n = np.arange(4400)
    z = np.cos(2 * np.pi * n / 400) + 0.2 * np.cos(6 * np.pi * n / 400 + 0.3)
    idx = np.arange(2, 4000, 4)
    assert drive_period(z, idx, 406) == 400
    noise = np.random.default_rng(7).normal(0.0, 0.2, len(idx))
    rep, rest = systematic_misfit(noise, idx, 401, 0.1)
    assert rep < 0.06 and rest == pytest.approx(0.2, abs=0.02)


def test_release_significance_is_the_f_test_of_the_added_state_column():
    """:func:`release_significant` against its construction, a linear model: 2000 rows, two
    parameter columns and one start-state column.  The gain of one Gauss-Newton step (from the fit
    without the state column) gives the F statistic of the nested models, ``(SSR_0 - SSR_1) /
    (SSR_1 / (n - 3))``, which is compared here by solving both least-squares problems directly.
    Noise alone: the state column is significant at p = 1e-3 in about 1 of 1000 draws (0 of 200
    here, each draw's F below chi2_1(0.999) = 10.83, the quantile of the chi-square
    distribution's tables); a state component of 0.2 noise sigma over the whole record (F ~ 80) is
    always significant, though it removes under 4 % of the residual (the old 'half the residual'
    test misses it)."""
    from vetica_cli.extraction.fullfit.uncertainty import gn_gain, release_significant

    rng = np.random.default_rng(11)
    n = 2000
    t = np.linspace(0.0, 1.0, n)
    jac = np.column_stack([np.sin(7 * t), t**2])
    state = np.exp(-3 * t)
    jac_free = np.column_stack([jac, state])
    fired = 0
    for _ in range(200):
        y = rng.normal(0.0, 1.0, n)
        res = y - jac @ np.linalg.lstsq(jac, y, rcond=None)[0]  # residual of the fit without the state
        gain = gn_gain(res, jac_free)
        ssr0 = float(res @ res)
        ssr1 = float(np.sum((y - jac_free @ np.linalg.lstsq(jac_free, y, rcond=None)[0]) ** 2))
        f = (ssr0 - ssr1) / (ssr1 / (n - 3))
        assert gain / (1 - gain) * (n - 3) == pytest.approx(f, rel=1e-9, abs=1e-8)  # F meets 10.8: SSR_0 - SSR_1 of ~2000 each rounds at ~1e-10
        fired += release_significant(jac, jac_free, gain, 1e-3)
        assert release_significant(jac, jac_free, gain, 1e-3) == (f > 10.828)
    assert fired == 0
    for _ in range(20):
        y = rng.normal(0.0, 1.0, n) + 0.2 * state / np.sqrt(np.mean(state**2))
        res = y - jac @ np.linalg.lstsq(jac, y, rcond=None)[0]
        gain = gn_gain(res, jac_free)
        assert gain < 0.5 and release_significant(jac, jac_free, gain, 1e-3)
    assert not release_significant(jac, jac, gain, 1e-3)  # no column added: nothing to release


# ----------------------------------------------------------------------------- valleys of the first stage


@pytest.mark.slow
def test_a_poor_first_stage_is_fitted_again_from_the_scans_other_points(monkeypatch):
    """A 300 K record (a coverage-check draw: k_inf 3.6738, k0 37.8653 N/m, cd 5.104e-4 kg/s, noise seed
    866632014; ten periods at 0.5 ns, the force reconstructed from the paddle): the cd scan's best point (the
    frozen plateau) converges, on the first period, to a local minimum with the surface 148 pm under the
    approach's Z1 and k_inf +18 % (RMS 1.9 % of the peak against a noise floor of 0.36 %; measured without
    the refits: k_inf +18.0 %, tau_c -16.5 %, at a 1-sigma of 3.7 % and 4.2 %, unflagged).  Fitted again from
    the scan's other points (``POOR_STARTS``), the first stage finds the right valley (18x lower cost) and
    k0, k_inf, cd come back within 3 sigma and 2 % of the truth.  Without the refits the fit must stay wrong
    (the test's own control: the record still has the valley; the fast-arm start, tried last, also finds
    the valley on this record, so it is off in the control too).  That was with Z1 read from the force alone
    (the first contact's pull-off well, 24 pm above its snap-in); read on the way in, as Z1 now is, the first
    stage starts nearer the surface and finds the valley itself (within 0.4 %, no refit).  The rule is tested
    on the record as the force alone reads it (``approach_side_well`` the identity), the default reading on the
    record as it is."""
    import vetica_cli.extraction.fullfit.method as fm
    import vetica_cli.signals.taps as taps_mod
    from vetica_cli.simulation.simulate import replicas

    truth = {"k_inf": 3.6738, "k0": 37.8653, "cd": 5.104e-4}
    over = {"numerics.record_cycles": 10, "numerics.temperature": 300.0, "numerics.print_step": 0.5e-9}
    run = replicas(load(None, {**over, **{f"surface.{k}": v for k, v in truth.items()}}), [866632014])[0]
    df, meta = run.frame(), run.metadata()
    default = extract(df, meta, force="reconstructed", method="full")
    for name, value in truth.items():
        e = default.estimates[name]
        assert abs(e.value / value - 1) < min(0.02, 3 * e.sigma), (name, e.value, e.sigma)
    monkeypatch.setattr(taps_mod, "approach_side_well", lambda z, f, i: i)  # Z1 from the force alone
    res = extract(df, meta, force="reconstructed", method="full")
    assert res.info["fit"]["rescanned"]
    for name, value in truth.items():
        e = res.estimates[name]
        assert abs(e.value / value - 1) < min(0.02, 3 * e.sigma), (name, e.value, e.sigma)
    monkeypatch.setattr(fm, "POOR_STARTS", 0)
    monkeypatch.setattr(fm, "FAST_ARM_RETRY", False)  # later retries that also find the valley here
    monkeypatch.setattr(fm, "ARM_PROFILE_RETRY", False)
    off = extract(df, meta, force="reconstructed", method="full")
    assert off.estimates["k_inf"].value / truth["k_inf"] - 1 > 0.1


def test_a_first_stage_that_stays_poor_is_fitted_from_the_generic_split(monkeypatch):
    """A first stage still poor after every earlier retry (the cd grid again, the scan's other
    points) is fitted once more from the generic split (k0 = 0.9 Kg of the loading slope, the whole
    cd grid), and the better kept.  Found on a 300 K replica of a stiff surface (k_inf 9.2, k0 238
    N/m, cd 3.8e-5 kg/s; 10 periods at 0.5 ns, the force reconstructed; `scripts/trust.py`'s
    development draw 30, material 3, replica 10) with the kernels that held the surface at each
    sample: VETICA's first taps gave the start k_inf 39.5, k0 0.12 N/m, every start stayed at an
    RMS of 16 % of the peak and the fit ended at k_g ~1e6 N/m, flagged; from the generic split,
    every parameter within 0.2 %.  With the simulator's own contact step the fit finds that surface
    from any start tried (k_inf 240 / k0 0.01, 1 / 1, 0.1 / 2000 N/m), so here every first-stage
    fit before the generic one is reported poor (its cost x 1e6): the rule, not the record, is
    tested -- the generic start is tried, kept, and the answer is the record's (within 1 %)."""
    import vetica_cli.extraction.fullfit.method as fm
    from vetica_cli.simulation.simulate import replicas

    material = {"k_inf": 9.1976, "k0": 237.8199, "cd": 3.815e-05}
    cfg = load(None, {"numerics.temperature": 300.0, "numerics.print_step": 0.5e-9, "numerics.record_cycles": 10,
                      **{f"surface.{k}": v for k, v in material.items()}})  # fmt: skip
    run = replicas(cfg, [672193119])[0]
    generic, real_fit, real_start = [], fm.fit_surface, fm.generic_start

    def recorded_start(*a, **k):
        generic.append(real_start(*a, **k))
        return generic[-1]

    def poor_until_generic(model, theta0, *a, **k):
        fit = real_fit(model, theta0, *a, **k)
        is_generic = bool(generic) and list(theta0[:3]) == [generic[0][q] for q in ("k_inf", "k0", "cd")]
        if not generic:  # a first-stage fit before the generic restart: reported poor
            fit = {**fit, "cost": fit["cost"] * 1e6}
        calls.append(is_generic)
        return fit

    monkeypatch.setattr(fm, "generic_start", recorded_start)
    monkeypatch.setattr(fm, "fit_surface", poor_until_generic)
    for retry in (True, False):
        calls = []
        monkeypatch.setattr(fm, "GENERIC_RETRY", retry)
        res = extract(run.frame(), run.metadata(), force="reconstructed", method="full")
        assert res.info["fit"]["generic_start"] is retry
        assert (True in calls) is retry and len(calls) >= 2  # the first stage (and its retries), the whole window
    generic.clear()
    monkeypatch.setattr(fm, "GENERIC_RETRY", True)
    res = extract(run.frame(), run.metadata(), force="reconstructed", method="full")
    for q in ("k0", "k_inf", "cd"):
        e = res.estimates[q]
        assert abs(e.value / material[q] - 1.0) < 0.01, q
        assert e.identifiable is not False, (q, e.reason)


def test_an_arm_faster_than_the_loading_is_fitted_from_the_slope_read_as_k_inf(monkeypatch):
    """The cross-model study's SLS record at tau f1 = 1e-3 (k_inf 4, k0 128 N/m, tau 20 ns: cd 2.56e-6 kg/s;
    no surface pull, 3 recorded periods, the force reconstructed, the surface's parameters removed from the
    metadata and the attraction's constants stated, as results/cross_model has it): the arm relaxes during a
    tap's loading, whose slope (~1.5 N/m) reads near k_inf, not Kg; every start that read it as Kg ended with k0
    at its bound (a Kelvin-Voigt surface) at an RMS of 4.2 % of the peak, tau_r -99.7 %, flagged.  From k_inf =
    the slope under an arm 4, 16, 64 times stiffer (FAST_ARM_RETRY): tau_r, k_g within 3 %, k_inf, cd within 1 %
    (measured +1.3, -1.2, +0.09, +0.04 %), the RMS residual under 1 %; without the retry k0 is off by decades."""
    import copy

    import vetica_cli.extraction.fullfit.method as fm

    run = simulate(load(None, {"surface.k_inf": 4.0, "surface.k0": 128.0, "surface.cd": 20e-9 * 128.0,
                               "surface.hamaker": 0.2e-18, "surface.a0": 0.2e-9, "surface.vdw_on_surface": False,
                               "numerics.record_cycles": 3}))  # fmt: skip
    df, meta = run.frame(), run.metadata()
    meta = copy.deepcopy(meta)
    meta["params"]["surface"] = {k: meta["params"]["surface"][k] for k in ("hamaker", "a0", "vdw_on_surface")}
    opts = dict(force="reconstructed", method="full", a0=0.2e-9, vdw_on_surface=False, fit_model="sls", arms=1,
                hamaker=0.2e-18, tip_radius=10e-9)  # fmt: skip
    truth = {"tau_r": 20e-9, "k_g": 132.0, "k_inf": 4.0, "cd": 2.56e-6}
    default = extract(df, meta, **opts)  # the arm-and-height profile, tried after it, may improve on it
    for q, tol in (("tau_r", 3.0), ("k_g", 3.0), ("k_inf", 1.0), ("cd", 1.0)):
        assert abs(100.0 * (default.estimates[q].value / truth[q] - 1.0)) < tol, q
    monkeypatch.setattr(fm, "ARM_PROFILE_RETRY", False)
    res = extract(df, meta, **opts)
    assert res.info["fit"]["fast_arm_start"] in fm.FAST_ARM_RATIOS
    for q, tol in (("tau_r", 3.0), ("k_g", 3.0), ("k_inf", 1.0), ("cd", 1.0)):
        err = 100.0 * (res.estimates[q].value / truth[q] - 1.0)
        assert abs(err) < tol, (q, err)
    assert res.info["fit"]["residual_rms_pct"] < 1.0
    monkeypatch.setattr(fm, "FAST_ARM_RETRY", False)
    off = extract(df, meta, **opts)
    assert off.estimates["k0"].value > 100 * 128.0


@pytest.mark.slow
def test_an_arm_faster_than_a_few_samples_is_found_by_the_profile_of_its_spring_and_the_height(monkeypatch):
    """16:1 (k_inf 4, k0 64 N/m), cd 1e-7 kg/s: the arm relaxes in 1.6 ns, 13 samples of 0.125 ns (the lowest
    point of configs/method_low_cd.yaml), noise-free, true force.  Every start of the fit found cd within 4 % with
    k0 -97 % and the height 17 pm off, at 0.54 % of the peak (under the 1 % the residual check allows: unflagged);
    the right valley is narrow in the arm's spring and the height together.  From the best of the two profiled at
    the fitted cd (ARM_PROFILE_RETRY): k0, k_inf, cd within 0.1 % (measured 0.02, 0.00, 0.003 %).  The control,
    without it: k0 more than 50 % off."""
    import vetica_cli.extraction.fullfit.method as fm

    run = simulate(load(None, {"surface.k_inf": 4.0, "surface.stiffness_ratio": 16, "surface.cd": 1e-7,
                               "numerics.print_step": 0.125e-9, "numerics.record_cycles": 4}))  # fmt: skip
    df, meta = run.frame(), run.metadata()
    res = extract(df, meta, force="true", method="full")
    assert res.info["fit"]["arm_profile"] is True
    for q in ("k0", "k_inf", "cd"):
        assert abs(res.estimates[q].error_pct) < 0.1, (q, res.estimates[q].error_pct)
    monkeypatch.setattr(fm, "ARM_PROFILE_RETRY", False)
    off = extract(df, meta, force="true", method="full")
    assert abs(off.estimates["k0"].error_pct) > 50.0, off.estimates["k0"].error_pct
