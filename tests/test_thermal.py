"""Thermal (Brownian) noise of the probe in the recorded periods (fluctuation-dissipation).

References: equipartition ``<z^2> = kB T / k`` and the oscillator's Lorentzian
``S_z(f) = S_F / (k^2 ((1 - r^2)^2 + (r/Q)^2))``, ``S_F = 4 kB T m w0/Q``.
"""

import math

import numpy as np
import pytest
from scipy.signal import welch

from vetica_cli.core.tapping import COLUMNS
from vetica_cli.errors import ConfigError
from vetica_cli.simulation import thermal
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import derive, simulate

IC, IP, IT, IB, IF = (COLUMNS.index(c) for c in ("z_cantilever", "z_paddle", "z_tip", "z_base", "f_ts"))

# A free probe (base 1 um above the surface, never in contact) with low Q, so that its
# thermal correlation times 2Q/w0 (6.4 us and 0.42 us) are short against the 20 ms
# recorded: the relative standard error of the sample variance is ~sqrt(2Q/(w0 T)) <= 2 %.
FREE = {"operation.base_height": 1e-6, "probe.q1": 1.0, "probe.q2": 1.0, "numerics.dt": 1e-9,
        "numerics.print_step": 10e-9, "numerics.record_cycles": 1000}  # fmt: skip


@pytest.fixture(scope="module", params=["verlet", "hybrid"])
def free_runs(request):
    """Both thermal recordings: fine Verlet steps with a random force each (``verlet``) and, far from
    the surface as this probe always is, one exact step a print step with each mode's sampled
    Ornstein-Uhlenbeck increment (``hybrid``): two formulations of the same process."""
    ov = {**FREE, "numerics.integrator": request.param}
    clean = simulate(load(None, ov))
    cfg = load(None, {**ov, "numerics.temperature": 300.0, "numerics.noise_seed": 3})
    return cfg, clean, simulate(cfg)


def test_free_probe_variance_matches_equipartition(free_runs):
    """Deflection minus the noise-free periodic motion: variance kB T/k within 5 % for the
    cantilever (k1 = 10 N/m, 20 pm RMS) and 3 % for the paddle (k2 = 700 N/m, 2.4 pm RMS);
    standard errors ~2 % and ~0.5 %; with either integrator."""
    cfg, clean, noisy = free_runs
    assert noisy.steady.shape == clean.steady.shape
    for col, k, rtol in ((IC, cfg.probe.k1, 0.05), (IP, cfg.probe.k2, 0.03)):
        dz = noisy.steady[:, col] - clean.steady[:, col]
        assert np.var(dz) == pytest.approx(thermal.KB * 300.0 / k, rel=rtol, abs=0.0)
    # z_tip is the sum of its parts; a free probe feels only the (tiny) attraction
    np.testing.assert_allclose(noisy.steady[:, IT], noisy.steady[:, IB] + noisy.steady[:, IC] + noisy.steady[:, IP])


def test_free_probe_spectrum_matches_the_lorentzian(free_runs):
    """Welch PSD of each mode's thermal motion against the oscillator's Lorentzian, mean
    ratio over 0.5-1.5 f0 within 6 % (cantilever: ~15 averaged segments) and 3 % (paddle)."""
    cfg, clean, noisy = free_runs
    d = derive(cfg)
    for col, (m, k, q), rtol in zip((IC, IP), thermal.modes(cfg, d), (0.06, 0.03)):
        dz = noisy.steady[:, col] - clean.steady[:, col]
        f0 = math.sqrt(k / m) / (2 * math.pi)
        nps = int(2 ** math.ceil(math.log2(30 / (f0 * d.print_step))))
        f, psd = welch(dz, fs=1 / d.print_step, nperseg=nps)
        band = (f > 0.5 * f0) & (f < 1.5 * f0)
        ratio = psd[band] / thermal.displacement_psd(f[band], m, k, q, 300.0)
        assert band.sum() >= 20
        assert ratio.mean() == pytest.approx(1.0, abs=rtol)


@pytest.mark.parametrize("surface", [{}, {"surface.k_inf": 2.0, "surface.k0": 10.0, "surface.cd": 1.5e-5}],
                         ids=["worked-example", "snapping-5to1"])
def test_noisy_kernel_at_negligible_temperature_reproduces_the_orbit(surface):
    """The noisy recording kernel (plain Verlet) started on the noise-free orbit stays on it:
    at 1e-9 K (thermal RMS 4e-17 m) its periods match the orbit's within 0.1 pm in z_tip and
    1e-4 of the peak force in f_ts (measured: 2.4e-15 m and 4.6e-6; what is left is the probe's
    plain Verlet against the fine kernel's exact probe map).  Both kernels pull the surface by
    the same rule -- the attraction at the gap to the last step's surface -- so a surface soft
    enough to snap to the tip (Kg = 12 N/m: the pull's gain reaches 1 at 0.38 nm > a0) snaps at
    the same tip height in both; the previous rule of the noisy kernel (four fixed-point
    iterations from the unpulled surface each step) snapped 45 pm lower on such a surface (Kg 10.5 N/m), 4.7 %
    of the peak force off the orbit at the snap, and biased the whole-cycle fit of its records."""
    ov = {"numerics.record_cycles": 2, "numerics.dt": 0.05e-9, "numerics.print_step": 0.5e-9, **surface}
    a = simulate(load(None, ov)).steady
    b = simulate(load(None, {**ov, "numerics.temperature": 1e-9})).steady
    assert a.shape == b.shape
    assert np.abs(a[:, IT] - b[:, IT]).max() < 1e-13
    assert np.abs(a[:, IF] - b[:, IF]).max() < 1e-4 * np.abs(a[:, IF]).max()


def test_hybrid_and_verlet_tapping_records_carry_the_same_noise():
    """A tapping record (worked example, contacts every period): the hybrid recording (fine steps only
    in contact and within d_switch, exact far steps with the sampled noise elsewhere) against the
    all-fine Verlet one, 48 replicas each (the same seeds, so the same equipartition start): the mean
    variance of z_paddle, z_cantilever and f_ts about the noise-free record agrees within 25 %.  The
    replica-to-replica spread of a variance is ~60 % of its mean here (the cantilever's wander over
    its 32-period ring-down), so each mean has a standard error of ~9 % and the ratio ~12 %: 25 % is
    2 of them.  Measured at 150 replicas: the paddle's RMS 4.01 pm (hybrid) against 3.83 (verlet),
    the cantilever's 31.7 against 30.2 pm, the force's 0.211 against 0.194 nN.  Leaving out the far
    steps' noise drops the paddle's variance several-fold (most of the period is far steps)."""
    from vetica_cli.simulation.simulate import replicas

    ov = {"numerics.record_cycles": 2, "numerics.dt": 0.05e-9, "numerics.print_step": 0.5e-9}
    clean = simulate(load(None, ov)).steady
    seeds = list(range(1, 49))
    got = {}
    for integ in ("verlet", "hybrid"):
        runs = replicas(load(None, {**ov, "numerics.integrator": integ, "numerics.temperature": 300.0}), seeds)
        got[integ] = [np.mean([np.var(r.steady[:, c] - clean[:, c]) for r in runs]) for c in (IP, IC, IF)]
    for v, h in zip(got["verlet"], got["hybrid"]):
        assert h / v == pytest.approx(1.0, abs=0.25)


def test_thermal_noise_is_seeded_and_the_default_is_none():
    """Same seed, same record; another seed, another record; temperature 0 leaves the run
    as it was (bit for bit)."""
    ov = {"numerics.record_cycles": 1, "numerics.dt": 0.05e-9, "numerics.print_step": 0.5e-9}
    clean = simulate(load(None, ov))
    assert "thermal" not in clean.info
    one = simulate(load(None, {**ov, "numerics.temperature": 300.0, "numerics.noise_seed": 1}))
    again = simulate(load(None, {**ov, "numerics.temperature": 300.0, "numerics.noise_seed": 1}))
    other = simulate(load(None, {**ov, "numerics.temperature": 300.0, "numerics.noise_seed": 2}))
    np.testing.assert_array_equal(one.steady, again.steady)
    np.testing.assert_array_equal(one.approach, again.approach)
    assert not np.array_equal(one.steady[:, IF], other.steady[:, IF])
    # the paddle's thermal motion (2.4 pm RMS free) is what the force read from the paddle, k2 zp,
    # carries as noise; about the noise-free orbit one period of one seed reads 0.32-3.1x it (40 seeds,
    # measured: the orbit's own wander adds, the contacts stiffen it; the mean over replicas is
    # test_hybrid_and_verlet_tapping_records_carry_the_same_noise's claim)
    rms_paddle = math.sqrt(thermal.KB * 300 / 700)
    assert 0.2 * rms_paddle < np.std(one.steady[:, IP] - clean.steady[:, IP]) < 5.0 * rms_paddle
    assert np.std(one.steady[:, IF] - clean.steady[:, IF]) > 1e-12  # the true force feels it too
    assert one.observables == clean.observables  # observables from the noise-free orbit


def test_adc_quantises_the_deflections():
    """ADC step 1 pm: every recorded deflection is a whole number of steps."""
    ov = {"numerics.record_cycles": 1, "numerics.dt": 0.05e-9, "numerics.print_step": 0.5e-9,
          "numerics.adc_resolution": 1e-12}  # fmt: skip
    run = simulate(load(None, ov))
    for col in (IC, IP):
        q = run.steady[:, col] / 1e-12
        np.testing.assert_allclose(q, np.round(q), atol=1e-6)


@pytest.mark.parametrize("key,value", [("numerics.temperature", -1.0), ("numerics.adc_resolution", -1e-12)])
def test_bad_thermal_keys_are_refused(key, value):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        load(None, {key: value})


@pytest.mark.parametrize("h", [1e-6, 1e-8, 5e-10, 2.5e-11])
def test_sampled_noise_covariance_is_exact_and_positive(h):
    """The noise increment's covariance over an interval h (Van Loan's block exponential)
    against two independent forms: the equilibrium difference Sigma - phi Sigma phi^T where
    it keeps its digits (h >= 1e-8 s: rtol 1e-6), and the short-interval closed form of
    white force on a free mass, var v = Q h, cov(z, v) = Q h^2/2, var z = Q h^3/3,
    Q = 2 c kB T/m^2 (h << 1/w0 and m/c: rtol 1e-3).  Positive semi-definite at every h
    (the difference form turned indefinite at 0.5 ns and a 10 kHz cantilever: the
    'Matrix is not positive definite' of a 300 K advice)."""
    m, k, q, temp = 2.5e-11, 2.5, 150.0, 300.0  # a 50 kHz-ish mode, soft
    phi, cov = thermal.sampled_flow(m, k, q, temp, h)
    assert np.all(np.linalg.eigvalsh(cov) >= 0)
    c = math.sqrt(k * m) / q
    qv = 2 * c * thermal.KB * temp / m**2
    if h >= 1e-8:
        sig = np.diag([thermal.KB * temp / k, thermal.KB * temp / m])
        np.testing.assert_allclose(cov, sig - phi @ sig @ phi.T, rtol=1e-6, atol=1e-6 * np.abs(cov).max())
    if h <= 5e-10:
        np.testing.assert_allclose([cov[1, 1], cov[0, 1], cov[0, 0]], [qv * h, qv * h**2 / 2, qv * h**3 / 3], rtol=1e-3)


def test_approach_force_is_the_surface_driven_by_the_noisy_tip():
    """The approach window's f_ts at T > 0 = the noise-free force + approach_response (the
    prescribed-trajectory kernel's force under the noisy tip minus under the noise-free one).
    That kernel is checked against the simulator itself: driven by the noise-free approach
    tip it reproduces the recorded noise-free approach force within 1e-3 of the peak RMS and
    1e-2 at most (measured 1.2e-4 and 2.5e-3 on the 6-period coverage record of
    tests/test_thermal_coverage.py; the kernel updates the dashpot once per sample in
    contact).  And the response is the size the thermal offset makes it: the contact
    stiffness Kg (132 N/m) times the ~20 pm thermal motion is ~3 nN, so between 0.1 and
    10 nN at its largest."""
    from vetica_cli.simulation.simulate import derive, kernel_setup

    ov = {"numerics.record_cycles": 2, "numerics.dt": 0.05e-9, "numerics.print_step": 1e-9}
    cfg = load(None, {**ov, "numerics.temperature": 300.0, "numerics.noise_seed": 2})
    clean, noisy = simulate(load(None, ov)), simulate(cfg)
    d = derive(cfg)
    st = kernel_setup(cfg, d)
    z0, f0 = clean.approach[:, IT], clean.approach[:, IF]
    peak = float(np.max(np.abs(f0)))
    model = thermal.approach_response(z0, z0 + 1e-6, st, d)  # 1 um up: no force at all
    assert np.sqrt(np.mean((model - f0) ** 2)) < 1e-3 * peak
    assert np.max(np.abs(model - f0)) < 1e-2 * peak
    response = noisy.approach[:, IF] - f0
    np.testing.assert_allclose(response, thermal.approach_response(noisy.approach[:, IT], z0, st, d), atol=1e-15)
    assert 1e-10 < np.max(np.abs(response)) < 1e-8
