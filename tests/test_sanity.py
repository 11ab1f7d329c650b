"""The sanity checks' building blocks: the noise floor and the reuse of a record's taps."""

import numpy as np
import pytest

from vetica_cli.extraction.sanity import NOISE_SAMPLES, noise_floor
from vetica_cli.signals.taps import find_taps, locate_taps


@pytest.mark.parametrize("n", [2000, 80_000, 1_600_000])
def test_noise_floor_recovers_white_noise_on_a_smooth_signal(n):
    """White noise of RMS s on a sine sampled 400 times a period: the second differences'
    MAD gives s.  Reference: the noise's own RMS (set); tolerance 5 % (the median of
    min(n, 8192) values has a relative standard error of ~1.4 %; the sine's own second
    difference, (2 pi / 400)^2 ~ 2.5e-4 of its amplitude, is 1/40 of s here)."""
    rng = np.random.default_rng(7)
    t = np.arange(n)
    s = 1e-2
    x = np.sin(2 * np.pi * t / 400) + s * rng.standard_normal(n)
    assert noise_floor(x) == pytest.approx(s, rel=0.05)


def test_noise_floor_subsample_agrees_with_every_sample():
    """The evenly spread subsample against the median over every second difference (the
    estimator before subsampling): within 5 % on 400 000 samples of white noise."""
    rng = np.random.default_rng(3)
    x = rng.standard_normal(400_000)
    d2 = np.diff(x, 2)
    full = 1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0)
    assert len(x) > 10 * NOISE_SAMPLES
    assert noise_floor(x) == pytest.approx(full, rel=0.05)
    assert full == pytest.approx(1.0, rel=0.02)


def _force(n_taps=5, spacing=400):
    t = np.arange(n_taps * spacing + spacing // 2)
    return np.maximum(np.sin(2 * np.pi * t / spacing), -0.1)


def test_find_taps_reuses_only_an_unchanged_array():
    """The cached answer equals a fresh search; a changed array (in place) is searched again."""
    f = _force()
    a, b = find_taps(f), locate_taps(f)
    np.testing.assert_array_equal(a.contact, b.contact)
    again = find_taps(f)
    np.testing.assert_array_equal(again.peak, b.peak)
    again.contact[:] = -1  # a caller changing its copy does not change the cache
    np.testing.assert_array_equal(find_taps(f).contact, b.contact)
    f[:] = _force(n_taps=11, spacing=200)[: len(f)]  # the same object with other values
    np.testing.assert_array_equal(find_taps(f).peak, locate_taps(f).peak)
    assert find_taps(f).spacing == pytest.approx(200, abs=1)
