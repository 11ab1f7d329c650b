"""Force reconstruction by spectral inversion of the paddle signal (thesis
eqs. 17-20).

References: the paddle equation of motion ``m2 zp'' + c2 zp' + k2 zp = Fts``
(thesis eq. 16) evaluated analytically on a chosen trajectory, and the
simulator's own true force ``f_ts``.
"""

import math

import numpy as np
import pytest

from vetica_cli.errors import InputError
from vetica_cli.signals.spectral import paddle_inverse_transfer, reconstruct_force, reconstruction_error
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import simulate

K2, F2, Q2 = 700.0, 750e3, 1000.0  # thesis worked-example paddle
W2 = 2 * math.pi * F2
M2 = K2 / W2**2
C2 = M2 * W2 / Q2


def _analytic(t, f1, harmonics, drift=(0.0, 0.0)):
    """Paddle trajectory ``zp = sum A sin(k w t + phi) + d1 t + d2 t^2`` and the force
    ``m2 zp'' + c2 zp' + k2 zp`` it needs (thesis eq. 16), both closed form."""
    w = 2 * math.pi * f1
    zp = drift[0] * t + drift[1] * t**2
    v = drift[0] + 2 * drift[1] * t
    acc = 2 * drift[1] * np.ones_like(t)
    for k, amp, phi in harmonics:
        ph = k * w * t + phi
        zp = zp + amp * np.sin(ph)
        v = v + amp * k * w * np.cos(ph)
        acc = acc - amp * (k * w) ** 2 * np.sin(ph)
    return zp, M2 * acc + C2 * v + K2 * zp


HARMONICS = [(1, 3e-10, 0.3), (3, 5e-11, 1.0), (15, 2e-10, -0.4), (40, 1e-12, 2.0)]


def test_inverse_transfer_is_the_paddle_operator():
    """1/T(w) = k2 - m2 w^2 + i c2 w (thesis eq. 17 against eq. 16), to rounding."""
    w = np.array([0.0, 1e5, W2, 1e9])
    expected = K2 - M2 * w**2 + 1j * C2 * w
    np.testing.assert_allclose(paddle_inverse_transfer(w, K2, F2, Q2), expected, rtol=1e-12)


def test_reconstruction_of_whole_periods_matches_the_equation_of_motion():
    """Exactly 4 periods of a 50 kHz periodic signal: error < 1e-5 of the peak force
    (measured 1.7e-6, set by the end-derivative estimates of the end correction)."""
    f1, h = 50e3, 1e-9
    t = np.arange(4 * 20000) * h
    zp, force = _analytic(t, f1, HARMONICS)
    rec = reconstruct_force(t, zp, K2, F2, Q2)
    assert np.max(np.abs(rec.f - force)) < 1e-5 * np.max(np.abs(force))


def test_end_correction_removes_leakage_of_a_drifting_non_periodic_window():
    """f1 = 75 kHz sampled at 1 ns (13333.3 samples per period) plus a slow drift of
    the mean, as the simulator's steady window has: a plain FFT is off by more than
    the peak force; with the Bernoulli end correction the error is < 1e-5 of it
    (measured 3.5e-6)."""
    f1, h = 75e3, 1e-9
    t = 1e-3 + np.arange(40000) * h  # 3.00 periods, not an integer number of samples per period
    zp, force = _analytic(t, f1, HARMONICS, drift=(2e-7, 3e-4))
    n = len(t)
    w = 2 * math.pi * np.fft.rfftfreq(n, h)
    plain = np.fft.irfft(np.fft.rfft(zp) * paddle_inverse_transfer(w, K2, F2, Q2), n)
    peak = np.max(np.abs(force))
    assert np.max(np.abs(plain - force)) > peak
    rec = reconstruct_force(t, zp, K2, F2, Q2)
    assert np.max(np.abs(rec.f - force)) < 1e-5 * peak


def test_lowpass_cutoff_keeps_harmonics_below_and_removes_those_above():
    """Cut-off between the 15th and 40th harmonic: the reconstruction equals the
    force of harmonics 1, 3 and 15 alone (1e-5 of the peak force; measured 1.3e-6)."""
    f1, h = 50e3, 1e-9
    t = np.arange(2 * 20000) * h
    zp, _ = _analytic(t, f1, HARMONICS)
    _, low = _analytic(t, f1, HARMONICS[:3])
    rec = reconstruct_force(t, zp, K2, F2, Q2, cutoff_hz=25 * f1)
    assert rec.cutoff_hz == pytest.approx(25 * f1)
    assert np.max(np.abs(rec.f - low)) < 1e-5 * np.max(np.abs(low))


@pytest.mark.parametrize(
    "bad, match",
    [
        ({"t": np.r_[np.arange(100) * 1e-9, 1e-6]}, "uniformly sampled"),
        ({"t": np.arange(10) * 1e-9, "z_paddle": np.zeros(10)}, "at least"),
        ({"k2": 0.0}, "must be > 0"),
        ({"cutoff_hz": -1.0}, "cut-off"),
        ({"taper": 1.5}, "taper"),
    ],
)
def test_bad_input_is_a_one_line_input_error(bad, match):
    args = {"t": np.arange(101) * 1e-9, "z_paddle": np.zeros(101), "k2": K2, "f2": F2, "q2": Q2}
    args.update(bad)
    with pytest.raises(InputError, match=match):
        reconstruct_force(**args)


# ----------------------------------------------------------------------------- against the simulator


@pytest.fixture(scope="module")
def worked(worked_example):
    """Worked example (thesis tables 2-4), vdW pull on the surface off (the setting
    of the worked-example bounds; see results/thesis/worked_example.md; conftest, once a session)."""
    return worked_example(pull=False).frame()


def _steady(df):
    return df[df.segment == "steady"]


def test_reconstructed_force_matches_simulated_force(worked):
    """Full band (cut-off at Nyquist, 4 GHz): measured RMS 3e-5 % and largest error
    0.01 % (at the contact kinks) of the peak force; held to 1e-3 % RMS, 0.1 % max,
    1e-3 % on the peak force."""
    s = _steady(worked)
    rec = reconstruct_force(s.t.to_numpy(), s.z_paddle.to_numpy(), K2, F2, Q2)
    err = reconstruction_error(rec.f, s.f_ts.to_numpy())
    assert err["rms_pct"] < 1e-3
    assert err["max_pct"] < 0.1
    assert abs(err["peak_pct"]) < 1e-3


def test_lower_cutoff_smears_the_contact_kinks(worked):
    """A 20 MHz low-pass (400 harmonics of f1) keeps the RMS error small (0.1 %) but
    the error at the contact/separation kinks grows to several % of the peak force
    (measured 4.5 %): the reason VETICA's nanosecond stages need the full band."""
    s = _steady(worked)
    rec = reconstruct_force(s.t.to_numpy(), s.z_paddle.to_numpy(), K2, F2, Q2, cutoff_hz=20e6)
    err = reconstruction_error(rec.f, s.f_ts.to_numpy())
    assert err["rms_pct"] < 0.3
    assert err["max_pct"] > 2.0


def test_reconstruction_when_the_period_is_not_a_whole_number_of_samples():
    """f1 = 75 kHz, f2 = 15 f1 (T / print step = 106666.7): RMS < 1e-3 %, max < 0.1 %
    of the peak force (measured 5e-5 % and 0.02 %)."""
    run = simulate(load(None, {"probe.f1": 75e3, "probe.f2": 1.125e6, "surface.vdw_on_surface": False}))
    s = run.steady
    rec = reconstruct_force(s[:, 0], s[:, 3], K2, 1.125e6, Q2)
    err = reconstruction_error(rec.f, s[:, 5])
    assert err["rms_pct"] < 1e-3
    assert err["max_pct"] < 0.1


@pytest.mark.parametrize("n", [32439, 32440, 4096, 1001])
def test_awkward_lengths_give_the_same_transform(n):
    """A window whose length has a large prime factor (3 x 10813, 8 x 5 x 811) is transformed
    by scipy's FFT instead of numpy's: the same DFT, held against numpy's to 1e-13 of the
    spectrum's (the signal's) largest value, both ways."""
    from vetica_cli.signals.spectral import irfft, rfft

    x = np.random.default_rng(n).standard_normal(n)
    spec = np.fft.rfft(x)
    assert np.max(np.abs(rfft(x) - spec)) < 1e-13 * np.max(np.abs(spec))
    assert np.max(np.abs(irfft(spec, n) - x)) < 1e-13 * np.max(np.abs(x))


@pytest.mark.parametrize("jumps", [(2e-12, -3e-4, 5e6), (0.0, 1e-3, -2e7), (1e-12, 0.0, 0.0), (1e-12, 2e-4, 3e6, 1e14, -1e21)])
def test_long_window_correction_is_the_same_bits_as_the_array_code(jumps, monkeypatch):
    """A window longer than CACHE_SAMPLES takes its Bernoulli end correction (b, b', b'') in one
    compiled pass (signals/passes.py), the same scalar operations in the same order as the
    numpy code of shorter windows: equal bits (and signs of zero), whatever jumps are left out; the
    paddle operator added to the inverted force in the same order too (the reconstruction of a
    window of 300,001 samples, compiled and numpy paths, equal, the paddle's inverse transfer and its
    frequencies included)."""
    from vetica_cli.signals import spectral

    n, h = 300_001, 1.25e-10
    fast = spectral.bernoulli_correction(np.array(jumps), n, h)
    monkeypatch.setattr(spectral, "CACHE_SAMPLES", 10**12)  # the numpy path for every length
    slow = spectral.bernoulli_correction(np.array(jumps), n, h)
    for a, b in zip(fast, slow):
        assert np.array_equal(a, b) and np.array_equal(np.signbit(a), np.signbit(b))
    t = np.arange(n) * h
    zp = 1e-10 * np.sin(2 * np.pi * 5e4 * t) ** 3 + 1e-12 * t / t[-1]  # not periodic in the window
    ref = spectral.reconstruct_force(t, zp, K2, 7.5e5, Q2).f
    monkeypatch.undo()
    assert np.array_equal(spectral.reconstruct_force(t, zp, K2, 7.5e5, Q2).f, ref)


@pytest.mark.parametrize("n, drive_hz", [(300_001, 2.5e5), (1_600_000, 5e4)])
def test_long_spectrum_noise_reading_is_the_same_bits_as_the_array_code(n, drive_hz, monkeypatch):
    """The noise reading of a spectrum longer than LONG_BINS (signals/noise.py: measure) takes its
    Hann-windowed and raw powers and its harmonic comb (each bin's place in harmonics, and whether it
    is far enough from one to hold noise) from compiled passes (signals/passes.py): the same bands,
    noise and signal levels, cut-off and rule, bit for bit, as the numpy code shorter spectra take; on a
    window that is a whole number of drive periods (10) and one that is not (9.375)."""
    from vetica_cli.signals import noise

    rng = np.random.default_rng(n)
    h = 1.25e-10
    x = rng.standard_normal(n) + 50.0 * np.sin(2 * np.pi * drive_hz * h * np.arange(n)) ** 3
    spec = np.fft.rfft(x)
    fast = noise.measure(None, h, drive_hz, spectrum=spec, n=n)
    monkeypatch.setattr(noise, "LONG_BINS", 10**12)
    slow = noise.measure(None, h, drive_hz, spectrum=spec, n=n)
    assert (fast.cutoff_hz, fast.noise_rms, fast.white_equivalent, fast.rule) == (
        slow.cutoff_hz, slow.noise_rms, slow.white_equivalent, slow.rule)  # fmt: skip
    for field in ("f_lo", "f_hi", "noise", "signal"):
        assert np.array_equal(getattr(fast.spectrum, field), getattr(slow.spectrum, field)), field


@pytest.mark.parametrize("n, h", [(1_600_000, 1.25e-10), (300_001, 1e-9), (32_439, 2e-9)])
def test_long_window_paddle_gain_is_the_same_bits_as_numpy(n, h):
    """rfftfreq and 1/T(w) of a long window from one compiled pass (signals/passes.py: paddle_gain),
    the imaginary part divided as numpy divides a complex number by a real one: equal bits."""
    import math

    from vetica_cli.signals.passes import paddle_gain
    from vetica_cli.signals.spectral import paddle_inverse_transfer

    freq = np.fft.rfftfreq(n, h)
    gain = paddle_inverse_transfer(2.0 * math.pi * freq, K2, F2, Q2)
    f1, g1 = paddle_gain(n, h, K2, 2.0 * math.pi * F2, Q2)
    assert np.array_equal(freq, f1) and np.array_equal(gain.real, g1.real) and np.array_equal(gain.imag, g1.imag)
