"""The real-time extraction path against the thesis's: the compiled stage 2 on the samples
(vetica_cli.core.superposition, ``stage2='closed'``) and the force rebuilt in the tap windows
(vetica_cli.signals.tapforce).

References: the closed-form convolution of a sum of sines with the exponential kernel
(:func:`vetica_cli.extraction.vetica.exp_conv_cos`, itself checked by quadrature in
test_vetica.py); an SLS force computed in closed form for a known Kr; and, on a simulated
pixel record (worked example, 4 periods at 1 ns), the thesis's path on the same record: the
sum-of-sines stage 2 (``stage2='sines'``) and the spectral inversion of the whole record.
"""

import math

import numpy as np
import pytest

from vetica_cli import surfaces
from vetica_cli.core.superposition import superpose
from vetica_cli.errors import InputError
from vetica_cli.extraction import extract
from vetica_cli.extraction.record import build_record
from vetica_cli.extraction.vetica import SineFit, boltzmann_force, exp_conv_cos, fit_sum_of_sines, stage2_kr, \
    stage2_tap_closed  # fmt: skip
from vetica_cli.signals.spectral import reconstruct_force
from vetica_cli.signals.tapforce import MARGIN, fft_length, reconstruct_taps
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import simulate

TH = surfaces.get("sls").theory({"k0": 128.0, "k_inf": 4.0, "cd": 3e-5})  # worked example (thesis tables 2-4)
T_C = 1.4e-6  # [s] a contact of the worked example lasts ~1.4 us (1361 samples at 1 ns)
FIT = SineFit(b=np.array([2.2e6, 4.1e6, 0.0]), p=np.array([-3e-9, 2e-10, 0.0]), q=np.array([1e-10, -5e-11, 1e-9]),
              rms=0.0)  # a contact-like trajectory: down by ~4 nm and back  # fmt: skip


def test_recursion_equals_the_closed_form_convolution():
    """The recursion is exact for a piecewise-linear indentation; for the smooth sum of sines
    its error is O(h^2): below 1e-6 of the integral's range at 1 ns (~1400 samples)."""
    u = np.linspace(0.0, T_C, 1401)
    h = u[1] - u[0]
    delta = FIT(np.array([0.0]))[0] - FIT(u)
    tau = 2.7e-7
    y, dy = np.empty_like(u), np.empty_like(u)
    superpose(delta, h, tau, y, dy)
    b = np.concatenate([FIT.b, FIT.b])
    c = np.concatenate([np.zeros(3), np.full(3, 0.5 * np.pi)])
    w = -np.concatenate([FIT.b * FIT.p, FIT.b * FIT.q])  # delta' = sum w cos(b u + c)
    exact = exp_conv_cos(u, b, c, tau) @ w
    assert np.max(np.abs(y - exact)) < 1e-6 * np.ptp(exact)
    # the tau-derivative against a central difference of the recursion itself
    y2, y1 = np.empty_like(u), np.empty_like(u)
    superpose(delta, h, tau * (1 + 1e-6), y2, dy.copy())
    superpose(delta, h, tau * (1 - 1e-6), y1, dy.copy())
    superpose(delta, h, tau, y, dy)
    assert np.max(np.abs(dy - (y2 - y1) / (2e-6 * tau))) < 1e-6 * np.max(np.abs(dy))


def test_closed_stage2_recovers_kr_of_an_exact_sls_force():
    """Force of the SLS (thesis eqs. 75-78, closed form) for the worked example's Kg, Kr,
    tau_c on 1 ns samples: the compiled stage 2 returns Kr to 1e-5 (the O(h^2) of the
    recursion), the thesis's sum-of-sines path to 1e-5 as well, and they agree."""
    u = np.linspace(0.0, T_C, 1401)
    z = FIT(u)
    fc = -8e-9
    f = boltzmann_force(u, FIT, TH["k_g"], TH["k_r"], TH["tau_c"] * TH["k_r"] / TH["k_g"], fc)
    kr, _s0, rms, calls = stage2_tap_closed(u, z, f, TH["k_g"], TH["tau_c"], fc)
    assert kr == pytest.approx(TH["k_r"], rel=1e-5)
    assert rms < 1e-5 * np.max(np.abs(f)) and calls < 80
    kr_sines = stage2_kr(u, f, fit_sum_of_sines(u, z), TH["k_g"], TH["tau_c"], fc)[0]
    assert kr_sines == pytest.approx(TH["k_r"], rel=1e-5)
    # not a constant step: the caller is told to take the thesis's path
    assert stage2_tap_closed(u * (1 + 0.01 * (np.arange(len(u)) % 2)), z, f, TH["k_g"], TH["tau_c"], fc) is None


def test_fft_length_is_the_smallest_5_smooth_length():
    for n in (1, 7, 1873, 2049, 4097):
        m = fft_length(n)
        assert m >= n
        k = m
        for p in (2, 3, 5):
            while k % p == 0:
                k //= p
        assert k == 1
        assert all(not _smooth(j) for j in range(n, m))


def _smooth(j: int) -> bool:
    for p in (2, 3, 5):
        while j % p == 0:
            j //= p
    return j == 1


@pytest.fixture(scope="module")
def pixel():
    """A scan pixel's record (configs/scan_blend.yaml: 4 periods at 1 ns) of the worked example."""
    run = simulate(load(None, {"numerics.print_step": 1e-9, "numerics.record_cycles": 4}))
    return run.frame(), run.metadata()


def test_tap_windows_rebuild_the_whole_record_inversion(pixel):
    """From half a margin before each contact to half a margin after its separation the
    force equals the spectral inversion of the whole record to 1e-6 of the peak force
    (measured: ~2e-8; the window's last few samples ring by up to 0.4 %, which is why the
    margin is there), and the taps are those of that force."""
    df, meta = pixel
    st = df[df["segment"] == "steady"]
    p = meta["params"]["probe"]
    t, zp = st["t"].to_numpy(), st["z_paddle"].to_numpy()
    whole = reconstruct_force(t, zp, p["k2"], p["f2"], p["q2"]).f
    tf = reconstruct_taps(t, zp, p["k2"], p["f2"], p["q2"])
    assert len(tf.taps.contact) == 3
    for (a, b), c, s in zip(tf.windows, tf.taps.contact, tf.taps.separation):
        assert a < c < s < b
        lo, hi = c - MARGIN // 2, s + MARGIN // 2
        assert np.max(np.abs(tf.f[lo:hi] - whole[lo:hi])) < 1e-6 * np.max(whole)
        assert c == a + int(np.argmin(whole[a : (c + s) // 2]))


@pytest.mark.parametrize("method", ["vetica", "vetica-prestress"])
def test_closed_stage2_agrees_with_the_thesis_fit_on_a_pixel(pixel, method):
    """On the pixel record, the compiled stage 2 with the tap windows and the thesis's
    sum-of-sines fit agree to 5e-4 relative in every quantity (measured: <= 1e-4; the sine
    fit's own residual is what differs), and the option for the thesis's fit still works."""
    df, meta = pixel
    fast = extract(df, meta, force="reconstructed", method=method, cutoff_hz=math.inf)  # Nyquist: tap windows
    thesis = extract(df, meta, force="reconstructed", method=method, stage2="sines", cutoff_hz=math.inf)
    assert fast.diagnostics["stage2"] == "closed" and thesis.diagnostics["stage2"] == "sines"
    assert fast.info.get("force_windows") == 3  # the force was rebuilt in the 3 tap windows
    assert "sine_fit_rms_m" in thesis.diagnostics
    for q in ("tau_c", "k_g", "k_r", "k0", "k_inf", "cd"):
        assert fast.value(q) == pytest.approx(thesis.value(q), rel=5e-4), q
        assert math.isfinite(fast.value(q))
    assert fast.timing_s["total"] > 0


def test_stage2_option_is_checked(pixel):
    df, meta = pixel
    with pytest.raises(InputError, match="stage2 'fast' not allowed; choose one of: closed, sines"):
        extract(df, meta, force="true", method="vetica", stage2="fast")


@pytest.mark.parametrize("noise", [1e-12, 1e-10])
def test_tap_windows_step_aside_on_a_noisy_paddle_signal(pixel, noise):
    """Detector noise on the paddle signal (RMS ``noise`` [m], seeded): at the Nyquist cut-off
    the inversion amplifies it by ``(w/w2)^2`` (~4e5 at 500 MHz), so no force minimum is a clean
    contact kink and the windows return None (measured down to 1e-12 m at 1 ns); with a
    cut-off below Nyquist they always do.  build_record then rebuilds the whole record: the
    same force and taps as without the windows."""
    df, meta = pixel
    st = df[df["segment"] == "steady"]
    p = meta["params"]["probe"]
    t = st["t"].to_numpy()
    zp = st["z_paddle"].to_numpy() + noise * np.random.default_rng(7).standard_normal(len(t))
    assert reconstruct_taps(t, zp, p["k2"], p["f2"], p["q2"]) is None
    clean = st["z_paddle"].to_numpy()
    assert reconstruct_taps(t, clean, p["k2"], p["f2"], p["q2"], cutoff_hz=100e6) is None
    noisy = df.copy()
    noisy.loc[noisy["segment"] == "steady", "z_paddle"] = zp
    rec = build_record(noisy, meta, "reconstructed", tap_windows=True)
    ref = build_record(noisy, meta, "reconstructed")
    assert "force_windows" not in rec.info and rec.taps is None
    assert np.array_equal(rec.f, ref.f) and rec.z1 == ref.z1


def test_extract_cli_stage2_option(tmp_path):
    """``vetica extract --stage2``: sines runs the thesis's fit (its diagnostics say so); a bad
    value is one line and exit 2."""
    import json

    from typer.testing import CliRunner

    from vetica_cli.cli import app
    from vetica_cli.io import write_run

    path = write_run(simulate(load(None, {"numerics.print_step": 1e-9, "numerics.record_cycles": 3})),
                     tmp_path / "r.parquet")  # fmt: skip
    r = CliRunner().invoke(app, ["extract", str(path), "--stage2", "sines", "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.output)
    assert out["info"]["diagnostics"]["stage2"] == "sines" and out["info"]["timing_s"]["total"] > 0
    bad = CliRunner().invoke(app, ["extract", str(path), "--stage2", "fast"])
    assert bad.exit_code == 2 and "stage2 'fast' not allowed; choose one of: closed, sines" in bad.output


def test_warm_start_outside_the_bounds_scans_them():
    """A fixed-point iteration of vetica-prestress may move Kg below the previous Kr; the warm
    start then has no bracket inside (0, Kg) and must scan the bounds (it read past an empty
    scan and divided by zero: 65 rows of the method_dashpot study failed).  Reference: the
    same tap solved cold (no guess) gives the same Kr to the solver's tolerance."""
    from vetica_cli.core.superposition import solve_kr

    h, kg, kr_true, tau_c = 1e-10, 60.0, 4.0, 7.7e-6
    u = np.arange(200) * h
    delta = 1e-9 * np.sin(np.pi * u / u[-1])
    y, dy = np.empty_like(u), np.empty_like(u)
    superpose(delta, h, tau_c * kr_true / kg, y, dy)
    force = -(kr_true * delta + (kg - kr_true) * y)
    cold = solve_kr(delta, force, h, kg, tau_c, 0.0, -1.0, 0.0, 0.0, False, 16, 1e-10)
    warm = solve_kr(delta, force, h, kg, tau_c, 0.0, 1.01 * kg, 0.0, 0.0, False, 0, 1e-10)
    assert math.isfinite(warm[0]) and 0 < warm[0] < kg
    assert warm[0] == pytest.approx(cold[0], rel=1e-6, abs=0.0)
