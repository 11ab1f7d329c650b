"""``vetica fit``: the Lee–Radok forward model against closed forms, recovery of known
parameters from simulated curves, the real JPK curves shipped with afmformats (MIT, see
tests/data/afmformats/README.md) and the one-line errors."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.special import dawsn
from typer.testing import CliRunner

from vetica_cli.cli import app
from vetica_cli.curves import leeradok as lr
from vetica_cli.curves.fit import fit_curve
from vetica_cli.curves.read import Curve, Unsuited, read_curves, to_curve
from vetica_cli.curves.reference import double_exponential

DATA = Path(__file__).parent / "data" / "afmformats"
SR = [DATA / "cell1-0001.jpk-force", DATA / "cell1-0008.jpk-force"]
CC = sorted(DATA.glob("fmt-jpk-cc_*.jpk-force"))
FD = DATA / "fmt-jpk-fd_spot3-0192.jpk-force"
R, NU = 5e-6, 0.5


def test_elastic_limit_is_hertz():
    """No arm: F = (4/3) E/(1-nu²) √R δ^1.5 (Hertz) exactly; an arm far slower than the record
    adds its modulus (instantaneous modulus e_inf + e_1), one far faster adds nothing."""
    t = np.linspace(0, 1, 201)
    d = 2e-6 * t
    hertz = lambda e: 4 / 3 * e / (1 - NU**2) * math.sqrt(R) * d**1.5  # noqa: E731
    np.testing.assert_allclose(lr.force(t, d, R, NU, 1000.0, [], []), hertz(1000.0), rtol=1e-12)
    np.testing.assert_allclose(lr.force(t, d, R, NU, 1000.0, [500.0], [1e9]), hertz(1500.0), rtol=1e-8)
    np.testing.assert_allclose(lr.force(t, d, R, NU, 1000.0, [500.0], [1e-9])[1:], hertz(1000.0)[1:], rtol=1e-6)


def test_lee_radok_constant_rate_matches_closed_form():
    """δ = v t, one arm: F = C [e_inf (vt)^1.5 + 1.5 e_1 v^1.5 tau^1.5 (u - D(u))], u = √(t/tau),
    D Dawson's integral (Lee–Radok's integral done by hand).  On a non-uniform axis (two
    sampling rates like a record's segments); the recursion is exact for p linear between
    samples, so the error is the piecewise-linear p's: rtol 2e-4 at these steps."""
    v, e_inf, e1, tau = 2e-5, 300.0, 500.0, 0.3
    t = np.concatenate([np.linspace(0, 0.5, 4001), np.linspace(0.5, 1.0, 801)[1:]])
    f = lr.force(t, v * t, R, NU, e_inf, [e1], [tau])
    u = np.sqrt(t / tau)
    exact = lr.hertz_constant(R, NU) * (e_inf * (v * t) ** 1.5 + 1.5 * e1 * v**1.5 * tau**1.5 * (u - dawsn(u)))
    np.testing.assert_allclose(f[200:], exact[200:], rtol=2e-4)


def test_creep_under_held_force_is_the_relaxation_form_inverted():
    """A force step F0 held: δ^1.5 = (F0/C) J(t) with the standard linear solid's creep
    compliance J = 1/e_inf - (1/e_inf - 1/e_0) exp(-t/tau_c), e_0 = e_inf + e_1,
    tau_c = tau e_0/e_inf (closed form); and the relaxation recursion run on that creep gives
    the held force back (the two are one model).  rtol 1e-4 at dt = tau/1000."""
    e_inf, e1, tau, f0 = 300.0, 500.0, 0.4, 5e-8
    t = np.linspace(0, 3, 7501)
    d = lr.creep(t, np.full_like(t, f0), R, NU, e_inf, [e1], [tau])
    e0, tau_c = e_inf + e1, tau * (e_inf + e1) / e_inf
    j = 1 / e_inf - (1 / e_inf - 1 / e0) * np.exp(-t / tau_c)
    np.testing.assert_allclose(d**1.5, f0 / lr.hertz_constant(R, NU) * j, rtol=1e-4)
    np.testing.assert_allclose(lr.force(t, d, R, NU, e_inf, [e1], [tau]), f0, rtol=1e-9)


def test_gradient_matches_finite_differences():
    """The fit's Jacobian (exact recursion derivatives) against central differences, rtol 1e-5."""
    t = np.concatenate([np.linspace(0, 1, 501), np.linspace(1, 5, 201)[1:]])
    p = np.clip(np.concatenate([np.linspace(-1e-6, 2e-6, 501), np.full(200, 2e-6)]), 0, None) ** 1.5
    dp = 1.5 * np.sqrt(p ** (2 / 3))
    e, tau = np.array([400.0, 150.0]), np.array([0.5, 3.0])
    _, g = lr.force_and_gradient(t, p, dp, 300.0, e, tau, 1.0)
    for i in range(2):
        h = 1e-6 * tau[i]
        tp, tm = tau.copy(), tau.copy()
        tp[i] += h
        tm[i] -= h
        fd = (lr.force_from_p(t, p, 300.0, e, tp, 1.0) - lr.force_from_p(t, p, 300.0, e, tm, 1.0)) / (2 * h)
        np.testing.assert_allclose(g[:, 4 + i], fd, rtol=1e-5, atol=1e-9 * np.abs(fd).max())


def simulated_curve(arms, seed=0, noise=0.11e-9):
    """A stress-relaxation record as the instrument gives it: 1 s pause, 1 s approach of the
    base over 6 µm at 2048 Hz (contact half-way), 30 s dwell at constant height at 256 Hz;
    cantilever k = 1 N/m in series (the tip sinks as the force relaxes), force noise
    0.11 nN rms (the pause segments of the JPK curves here have 0.11 nN)."""
    rng = np.random.default_rng(seed)
    k, h_c = 1.0, 1.0e-4
    t_p = np.arange(256) / 256
    t_a = 1 + np.arange(2048) / 2048
    t_d = 2 + np.arange(7680) / 256
    h_a = h_c + 3e-6 - 6e-6 * (t_a - 1) / (1 - 1 / 2048)
    t = np.concatenate([t_a, t_d])
    h = np.concatenate([h_a, np.full(t_d.size, h_a[-1])])
    e_inf, e, tau = arms
    f, _ = lr.height_controlled(t, h_c - h, k, e_inf, np.array(e, float), np.array(tau, float), lr.hertz_constant(R, NU))
    f = f + noise * rng.standard_normal(f.size)
    seg = np.concatenate([np.zeros(t_a.size, np.int8), np.ones(t_d.size, np.int8)])
    return Curve("sim", 0, "stress-relaxation", "measured", k, t, f, h, seg, {}, noise * rng.standard_normal(t_p.size)), h_c


@pytest.mark.parametrize("window", ["dwell", "all"])
def test_recovers_known_parameters_and_arm_count(window):
    """Two arms with known moduli and times, realistic noise: BIC picks 2 arms, every parameter
    (and the contact height) within 2 % (the issue's criterion)."""
    truth = (300.0, [450.0, 150.0], [1.5, 8.0])
    curve, h_c = simulated_curve(truth)
    rows = fit_curve(curve, R, NU, window=window)
    sel = [r for r in rows if r["selected"]]
    assert [r["arms"] for r in sel] == [2]
    r = sel[0]
    got = [r["e_inf"], r["e_1"], r["e_2"], r["tau_1"], r["tau_2"]]
    np.testing.assert_allclose(got, [truth[0], *truth[1], *truth[2]], rtol=0.02)
    assert abs(r["contact"] - h_c) < 0.02 * r["indentation_max"]
    assert all(0 < r[f"se_{p}"] < 0.02 * r[p] for p in ("e_inf", "e_1", "e_2", "tau_1", "tau_2"))


@pytest.mark.slow
def test_real_relaxation_times_match_the_afmformats_double_exponential():
    """Two JPK stress-relaxation curves (Battistella et al. 2022): the two-arm Lee–Radok times
    against the afmformats example's double exponential on the same dwells (reproduced in
    scipy; matches the example's lmfit fit to 4 digits): within 3 % ("a few percent"; measured
    1.0 % and 0.6 % lower, the tip sinking during the dwell).  The one-arm (SLS) fit is clearly
    worse: BIC higher by more than 1000, residual more than 3 times larger."""
    for curve in read_curves(SR):
        rows = {r["arms"]: r for r in fit_curve(curve, R, NU)}
        ref = double_exponential(curve.t[curve.segment == 1], curve.force[curve.segment == 1])
        np.testing.assert_allclose([rows[2]["tau_1"], rows[2]["tau_2"]], [ref["d1"], ref["d2"]], rtol=0.03)
        assert rows[1]["bic"] - rows[2]["bic"] > 1000
        assert rows[1]["residual_rms"] > 3 * rows[2]["residual_rms"]


@pytest.mark.slow
def test_real_creep_curves_fit():
    """Both JPK creep-compliance curves (approach and dwell fitted): a residual below 1 % of the
    held force, and more than one arm needed (the SLS leaves a residual 1.5 and 1.8 times as
    large, BIC higher by thousands; thresholds 1.3 and 100)."""
    for curve in read_curves(CC):
        assert curve.modality == "creep-compliance"
        rows = {r["arms"]: r for r in fit_curve(curve, R, NU, window="all")}
        best = next(r for r in rows.values() if r["selected"])
        assert best["residual_rms"] < 0.01 * best["force_max"]
        assert rows[1]["residual_rms"] > 1.3 * rows[2]["residual_rms"] and rows[1]["bic"] - rows[2]["bic"] > 100
        assert all(rows[3][f"tau_{i}"] < rows[3][f"tau_{i + 1}"] for i in (1, 2))


runner = CliRunner()


def run(args):
    return runner.invoke(app, args)


@pytest.mark.slow
def test_cli_writes_table_and_figures(tmp_path):
    out, figs = tmp_path / "fit.parquet", tmp_path / "figs"
    res = run(["fit", str(SR[0]), str(CC[1]), "--tip-radius", "5e-6", "-o", str(out), "--figures", str(figs),
               "--window", "all", "-q", "-j", "1"])  # fmt: skip
    assert res.exit_code == 0, res.output
    df = pd.read_parquet(out)
    assert len(df) == 6 and df.groupby("file")["selected"].sum().tolist() == [1, 1]
    assert set(df["status"]) <= {"ok", "not_converged", "tau_beyond_window", "se_exceeds_value"}
    assert (df.loc[df["selected"], "status"] == "ok").all()  # never a flagged row while a sound one exists
    from vetica_cli.io import read_meta

    meta = read_meta(out)
    assert meta["units"]["e_inf"] == "Pa" and meta["units"]["tau_1"] == "s" and meta["params"]["tip_radius"] == 5e-6
    assert (figs / "parameters.png").is_file() and len(list(figs.glob("fit_*.png"))) == 2


@pytest.mark.parametrize("case", ["no_radius", "nothing_to_fit", "no_extra"])
def test_cli_errors_are_one_line_and_write_nothing(tmp_path, monkeypatch, case):
    out = tmp_path / "out" / "fit.parquet"
    args = ["fit", str(SR[0]), "--tip-radius", "5e-6", "-o", str(out)]
    expect = {"no_radius": "--tip-radius is required", "nothing_to_fit": "no curve to fit",
              "no_extra": 'pip install -e ".[formats]"'}[case]  # fmt: skip
    if case == "no_radius":
        args = ["fit", str(SR[0]), "-o", str(out)]
    elif case == "nothing_to_fit":
        text = tmp_path / "notes.txt"
        text.write_text("not a force curve\n")
        args[1] = str(text)
        out = tmp_path / "fit.parquet"
        args[-1] = str(out)
    else:
        monkeypatch.setitem(sys.modules, "afmformats", None)  # import afmformats -> ImportError
    res = run(args)
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and expect in lines[0], res.output
    assert not out.exists() and not (tmp_path / "out").exists()


def test_curve_without_dwell_is_refused():
    """A stress-relaxation record whose dwell segment is missing: refused in one line naming it."""
    import afmformats
    from afmformats.mod_stress_relaxation import AFMStressRelaxation

    data = afmformats.load_data(SR[0])[0]
    keep = data["segment"] != 2
    cut = AFMStressRelaxation({c: np.asarray(data[c])[keep] for c in data.columns}, dict(data.metadata))
    with pytest.raises(Unsuited, match="has no dwell"):
        to_curve(cut, SR[0], 0)
