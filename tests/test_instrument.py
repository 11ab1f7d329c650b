"""Instrument realism on the recorded signals: detector noise and bandwidth."""

import math

import numpy as np
import pytest

from vetica_cli.core.tapping import COLUMNS
from vetica_cli.errors import ConfigError
from vetica_cli.simulation.config import load
from vetica_cli.simulation.observables import harmonic
from vetica_cli.simulation.simulate import simulate

BASE = {"numerics.print_step": 1e-9, "numerics.record_cycles": 2}
IC, IP, IT, IB, IF = (COLUMNS.index(c) for c in ("z_cantilever", "z_paddle", "z_tip", "z_base", "f_ts"))


@pytest.fixture(scope="module")
def clean():
    return simulate(load(None, BASE))


def test_noise_has_the_requested_rms_and_is_reproducible(clean):
    """White Gaussian noise: sample RMS within 2 % of the set value (n = 40000 samples,
    statistical spread ~0.4 %); the same seed gives the same noise, another seed does not."""
    over = {**BASE, "numerics.position_noise": 10e-12, "numerics.force_noise": 50e-12, "numerics.noise_seed": 7}
    noisy = simulate(load(None, over))
    diff = noisy.steady - clean.steady
    assert np.std(diff[:, IC]) == pytest.approx(10e-12, rel=0.02, abs=0.0)
    assert np.std(diff[:, IP]) == pytest.approx(10e-12, rel=0.02, abs=0.0)
    assert np.std(diff[:, IF]) == pytest.approx(50e-12, rel=0.02)
    # z_tip stays the sum of its parts; the surface truth is untouched
    np.testing.assert_allclose(noisy.steady[:, IT], noisy.steady[:, IB] + noisy.steady[:, IC] + noisy.steady[:, IP])
    np.testing.assert_array_equal(noisy.steady[:, COLUMNS.index("x_surface")], clean.steady[:, COLUMNS.index("x_surface")])
    # observables come from the noise-free signals
    assert noisy.observables == clean.observables
    again = simulate(load(None, over))
    np.testing.assert_array_equal(again.steady, noisy.steady)
    other = simulate(load(None, {**over, "numerics.noise_seed": 8}))
    assert not np.array_equal(other.steady[:, IC], noisy.steady[:, IC])


def test_detector_bandwidth_lags_the_deflection_as_a_one_pole_filter(clean):
    """A one-pole low-pass of bandwidth fc delays the first harmonic at f1 by
    atan(f1/fc) and scales it by 1/sqrt(1 + (f1/fc)^2) (closed form; 1e-3 deg, 1e-4)."""
    fc = 1e6
    lagged = simulate(load(None, {**BASE, "numerics.detector_bandwidth": fc}))
    w = 2 * math.pi * 50e3
    t = clean.steady[:, 0]
    a0, p0 = harmonic(t, clean.steady[:, IC], w)
    a1, p1 = harmonic(t, lagged.steady[:, IC], w)
    # discrete one-pole filter: exact response at f1 for the sampled filter
    ts = 1e-9
    a = math.exp(-2 * math.pi * fc * ts)
    h = (1 - a) / (1 - a * np.exp(-1j * w * ts))
    assert p1 - p0 == pytest.approx(-math.degrees(np.angle(h)), abs=1e-3)
    assert a1 / a0 == pytest.approx(abs(h), rel=1e-4)
    # and that is close to the continuous-time atan(f1/fc)
    assert p1 - p0 == pytest.approx(math.degrees(math.atan(50e3 / fc)), rel=0.01)


def test_detector_bandwidth_below_drive_frequency_is_rejected():
    with pytest.raises(ConfigError, match="numerics.detector_bandwidth"):
        load(None, {"numerics.detector_bandwidth": 10e3})
