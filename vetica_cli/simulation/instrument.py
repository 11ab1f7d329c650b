"""The detector model: what the instrument adds to the recorded signals
after the kernel -- a finite position-detector bandwidth and white noise.

The amplitude controller inside the kernel sees the noise-free signal, so a run
with the instrument model is the noise-free run with :func:`apply_instrument`
applied to its records; a study shares one simulation between points that
differ only in these keys (:func:`noise_free`).
"""

from __future__ import annotations

import math

import numpy as np

from .config import Config, from_dict

# numerics keys that act after the kernel
INSTRUMENT_KEYS = ("position_noise", "force_noise", "noise_seed", "detector_bandwidth", "adc_resolution",
                   "detector_noise_density")


def noise_free(cfg: Config) -> Config:
    """``cfg`` without the instrument model (the config the kernel sees: the
    instrument keys act only after it, in :func:`apply_instrument`).  With thermal
    noise (``numerics.temperature``, part of the simulation) the seed stays: it
    seeds the Brownian forces too."""
    n = cfg.numerics
    keys = [k for k in INSTRUMENT_KEYS if not (k == "noise_seed" and n.temperature)]
    if not any(getattr(n, k) for k in keys):
        return cfg
    d = cfg.to_dict()
    for k in keys:
        d["numerics"][k] = 0
    return from_dict(d)


def detector_lowpass(x: np.ndarray, fc: float, ts: float, periodic: bool) -> np.ndarray:
    """One-pole (RC) low-pass ``y_n = a y_(n-1) + (1 - a) x_n``, ``a = exp(-2 pi fc ts)``:
    a detector of bandwidth ``fc`` [Hz] sampled every ``ts`` [s].  A periodic window
    is filtered twice and the second pass kept (steady state of the filter).  Compiled
    (:func:`vetica_cli.core.detector.one_pole`: scipy.signal's ``lfilter`` to the bit, without
    importing scipy.signal and with it scipy.stats)."""
    from ..core.detector import one_pole

    a = math.exp(-2.0 * math.pi * fc * ts)
    x = np.ascontiguousarray(x, dtype=float)
    y = np.empty_like(x)
    if not len(x):
        return y
    last = one_pole(x, a, x[-1] if periodic else x[0], y)
    if periodic:
        one_pole(x, a, last, y)
    return y


def apply_instrument(run, cfg: Config) -> None:
    """Detector realism on the recorded signals: the detector's white noise of density
    ``numerics.detector_noise_density`` [m/sqrt(Hz)] and a finite position-detector
    bandwidth (the noise passes through it, as a photodetector's does), then white Gaussian noise of the given RMS on the deflections
    (z_tip is rebuilt as z_base + z_cantilever + z_paddle) and on f_ts, then the
    deflections quantised to the ADC step ``numerics.adc_resolution`` (round to the
    nearest level).
    x_surface and x_dashpot are the simulator's truth and stay noise-free.
    Seeded: the same config gives the same noise."""
    n = cfg.numerics
    if not (n.position_noise or n.force_noise or n.detector_bandwidth or n.adc_resolution or n.detector_noise_density):
        return
    from ..core import tapping  # the kernel module (numba): not imported by the dry runs that plan noise

    rng = np.random.default_rng(n.noise_seed)
    ic, ip, it, ib, iff = (tapping.COLUMNS.index(c) for c in ("z_cantilever", "z_paddle", "z_tip", "z_base", "f_ts"))
    # the detector's own white noise enters before its bandwidth: one-sided density d over the sampled
    # band 1/(2 print_step) is a per-sample RMS of d / sqrt(2 print_step)
    density_rms = n.detector_noise_density / math.sqrt(2.0 * n.print_step)
    dens_rng = np.random.default_rng([n.noise_seed, 17]) if density_rms else None  # its own stream: the other
    for arr, periodic in ((run.approach, False), (run.steady, True)):  # noises draw as before
        if not len(arr):
            continue
        for i in (ic, ip):
            if density_rms:
                arr[:, i] += dens_rng.normal(0.0, density_rms, len(arr))
            if n.detector_bandwidth:
                arr[:, i] = detector_lowpass(arr[:, i], n.detector_bandwidth, n.print_step, periodic)
            if n.position_noise:
                arr[:, i] += rng.normal(0.0, n.position_noise, len(arr))
            if n.adc_resolution:
                arr[:, i] = np.round(arr[:, i] / n.adc_resolution) * n.adc_resolution
        arr[:, it] = arr[:, ib] + arr[:, ic] + arr[:, ip]
        if n.force_noise:
            arr[:, iff] += rng.normal(0.0, n.force_noise, len(arr))
