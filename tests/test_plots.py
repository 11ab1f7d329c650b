"""vetica plot: figures for a simulate run and for sweep tables of each study kind.

Sweep tables here are synthetic: the schema ``vetica sweep`` writes
(one row per point and force source, swept keys by dotted name, value /
theory / error columns, observables, status) filled with physics-shaped
numbers (SLS theory values, thesis eqs. 43-44, 68, 75-76; error, dissipation and time curves
shaped like thesis ch. 4), so the figures can be exercised before real
tables exist.  Reference numbers of the run tests carry their source.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from vetica_cli.cli import app
from vetica_cli.io import read_table, write_run, write_table
from vetica_cli.plots.acceptance import fig_acceptance_vs
from vetica_cli.plots.data import SweepData, swept_keys
from vetica_cli.plots.errors import fig_errors_vs_cd
from vetica_cli.plots.observables import fig_observable_vs_cd, mean_band
from vetica_cli.plots.run import load_run, loop_energy_ev, tap_window, transitions
from vetica_cli.plots.study import select_sweep_figures
from vetica_cli.signals.spectral import spectral_derivative
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import simulate
from vetica_cli.study.acceptance import regime

runner = CliRunner()

# ---------------------------------------------------------------------------
# synthetic sweep tables

STUDIES = {  # study -> swept keys and their grids (small versions of configs/*.yaml)
    "dashpot": {"surface.cd": np.logspace(-5, 3, 17)},
    "stiffness_ratio": {"surface.cd": np.logspace(-5, 3, 9), "surface.stiffness_ratio": [0.125, 0.5, 1, 4, 16, 32]},
    "setpoint": {"surface.cd": np.logspace(-5, 3, 9), "operation.setpoint": [0.25, 0.4, 0.55, 0.7, 0.8]},
    "frequency": {"surface.cd": np.logspace(-5, 3, 9), "probe.f1": [10e3, 25e3, 50e3, 100e3]},
    "print_step": {"surface.cd": np.logspace(-5, 3, 9), "numerics.print_step": [0.125e-9, 0.5e-9, 2e-9, 8e-9]},
    "paddle_stiffness": {"probe.k2": [200.0, 400.0, 600.0, 800.0, 1000.0, 1200.0]},
}

BASE = {  # thesis worked-example system with ratio 16:1 and PS 0.5 ns (thesis fig. 43)
    "probe": {"f1": 50e3, "f2": 750e3, "k1": 10.0, "k2": 700.0, "q1": 100.0, "q2": 1000.0, "tip_radius": 10e-9},
    "operation": {"free_amplitude": 100e-9, "setpoint": 0.7, "base_height": None},
    "surface": {"k_inf": 4.0, "k0": 64.0, "cd": 3e-5, "hamaker": 0.2e-18, "a0": 0.2e-9, "vdw_on_surface": True},
    "numerics": {"dt": 0.025e-9, "print_step": 0.5e-9, "record_cycles": 10},
}


def _point(p: dict) -> dict:
    """Theory values and plausible extracted values / observables for one point."""
    k_inf = 4.0
    k0 = p.get("surface.stiffness_ratio", 16.0) * k_inf
    cd = p.get("surface.cd", 5e-4)
    f1 = p.get("probe.f1", 50e3)
    sp = p.get("operation.setpoint", 0.7)
    ps = p.get("numerics.print_step", 0.5e-9)
    k2 = p.get("probe.k2", 700.0)
    tau_c = cd * (k0 + k_inf) / (k0 * k_inf)
    period = 1 / f1
    contact = period * (0.07 + 0.25 * (0.8 - sp)) * (1 + 0.3 / (1 + (tau_c / 1e-6) ** 0.5))
    # tau_c error: bad when the surface recovers before the next tap (tau_c << non-contact time)
    # or barely creeps (tau_c >> it); the window widens as the print step shrinks (thesis figs. 52, 61)
    x = tau_c / (period - contact)
    err_tau = 1.5 + 40 * (ps / 0.5e-9) ** 0.5 * (0.02 / x) ** 0.8 + 3 * x**0.7
    theory = {"tau_c": tau_c, "k_g": k0 + k_inf, "k_r": k_inf, "k0": k0, "k_inf": k_inf, "cd": cd}
    err = {
        "tau_c": err_tau,
        "k_g": 0.3 + 0.05 * k0 / k_inf,
        "k_r": 2 + 30 / (1 + k0 / k_inf),
        "k0": 0.5 + 0.2 * err_tau,
        "k_inf": 2 + 30 / (1 + k0 / k_inf),
        "cd": 0.5 + err_tau,
    }
    y = tau_c / contact
    out = {
        "e_diss_ev": 700 * (k0 / (k0 + k_inf)) * y / (1 + y * y) * (1 + 0.3 * abs(k2 - 600) / 600),
        "peak_force": 5e-9 + 1.1e-9 * k0 / k_inf**0.2 * (1 - sp + 0.3),
        "max_penetration": 8e-9 / (1 + k0 / k_inf) ** 0.5 * (1.3 - sp),
        "contact_time": contact,
        "noncontact_time": period - contact,
        "paddle_amplitude": 0.6e-9 * (1 + 0.3 * math.cos(math.log2(k0 / k_inf))),
        "ss_zero_depth": 1.5e-9 * (1 - sp + 0.2) * math.exp(-(math.log10(tau_c / 3e-5) ** 2) / 3),
        "amplitude": sp * 100e-9,
        "phase_deg": 50.0,
    }
    return {"theory": theory, "err": err, "obs": out}


def synthetic_sweep(study: str, failed: int = 1, not_steady: int = 1) -> tuple[pd.DataFrame, dict]:
    """A table with the sweep schema; ``failed`` / ``not_steady`` points get that status."""
    keys = STUDIES[study]
    grid = pd.MultiIndex.from_product(list(keys.values()), names=list(keys)).to_frame(index=False)
    rows = []
    rng = np.random.default_rng(0)
    for i, p in enumerate(grid.to_dict("records")):
        pt = _point(p)
        status = "ok"
        if i == 3 and failed:
            status = "failed"
        elif i == 5 and not_steady:
            status = "not_steady"
        for src, scale in (("true", 1.0), ("reconstructed", 1.4)):
            row = dict(p, force_source=src)
            for q, th in pt["theory"].items():
                e = pt["err"][q] * scale * (1 + 0.1 * rng.standard_normal())
                row[q] = th * (1 + e / 100) if status != "failed" else np.nan
                row[f"{q}_theory"] = th
                row[f"{q}_err_pct"] = abs(e) if status != "failed" else np.nan
            for k, v in pt["obs"].items():
                row[k] = v if status != "failed" else np.nan
            row.update(
                stop_reason="max_time" if status == "not_steady" else "steady",
                status=status,
                error="RuntimeError: synthetic failure" if status == "failed" else "",
                wall_s=3.0,
            )
            rows.append(row)
    df = pd.DataFrame(rows)
    sweep = {k: list(map(float, v)) for k, v in keys.items()}
    meta = {"units": {"tau_c": "s", "k_g": "N/m", "e_diss_ev": "eV"}, "config": dict(BASE, sweep=sweep)}
    return df, meta


@pytest.fixture
def table(tmp_path):
    def make(study, **kw):
        df, meta = synthetic_sweep(study, **kw)
        return write_table(df, tmp_path / f"{study}.parquet", meta)

    return make


EXPECTED = {  # figure files per study kind (names follow the thesis figure numbers)
    "dashpot": {"fig43-46_errors_vs_cd", "fig43-45_values_vs_cd", "fig41_ediss_vs_cd", "fig57_ss_zero_depth_vs_cd"},
    "stiffness_ratio": {
        "fig43-46_errors_vs_cd",
        "fig41-50_ediss_map_cd_ratio",
        "fig49_paddle_amplitude_vs_cd",
        "fig57_ss_zero_depth_vs_cd",
        "fig48_force_penetration_vs_ratio",
        "fig47_errors_vs_ratio",
    },
    "setpoint": {
        "fig43-46_errors_vs_cd",
        "fig41_ediss_vs_cd",
        "fig57_ss_zero_depth_vs_cd",
        "fig58_tau_c_error_map_cd_setpoint",
        "fig56_force_penetration_vs_setpoint",
        "fig54_contact_times_vs_setpoint",
        "fig55_errors_vs_setpoint",
    },
    "frequency": {
        "fig43-46_errors_vs_cd",
        "fig41_ediss_vs_cd",
        "fig57_ss_zero_depth_vs_cd",
        "fig52_acceptance_vs_f1",
        "fig51_contact_times_vs_f1",
    },
    "print_step": {
        "fig43-46_errors_vs_cd",
        "fig41_ediss_vs_cd",
        "fig57_ss_zero_depth_vs_cd",
        "fig61_acceptance_vs_print_step",
    },
    "paddle_stiffness": {"fig30_ediss_vs_k2"},
}


@pytest.mark.parametrize("study", sorted(STUDIES))
def test_plot_writes_the_study_figures_for_each_sweep_kind(table, tmp_path, study):
    path = table(study)
    out = tmp_path / "figs"
    res = runner.invoke(app, ["plot", str(path), "-o", str(out)])
    assert res.exit_code == 0, res.output
    names = {p.name for p in out.glob("*.png")}
    assert names == {f"{study}_{n}.png" for n in EXPECTED[study]}
    for p in out.glob("*.png"):
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 20_000
    assert not list(out.glob(".*.tmp"))


def test_a_figure_that_cannot_be_written_leaves_none_of_the_set(table, tmp_path):
    """One figure of the set cannot be written (its name is taken by a folder, as a full disk
    refuses a write): exit 2, one line, and none of the figures this call drew is left."""
    path = table("dashpot")
    out = tmp_path / "figs"
    (out / "dashpot_fig57_ss_zero_depth_vs_cd.png").mkdir(parents=True)  # drawn last of the four
    res = runner.invoke(app, ["plot", str(path), "-o", str(out)])
    assert res.exit_code == 2 and len(res.stderr.strip().splitlines()) == 1, res.output
    assert not list(out.glob("*.png.*")) and [p.name for p in out.iterdir()] == ["dashpot_fig57_ss_zero_depth_vs_cd.png"]


def test_figure_selection_follows_the_swept_keys():
    cd_only = [n for n, _, _ in select_sweep_figures(["surface.cd"])]
    assert "fig43-45_values_vs_cd" in cd_only and not any("ratio" in n or "f1" in n for n in cd_only)
    f1 = [n for n, _, _ in select_sweep_figures(["surface.cd", "probe.f1"])]
    assert "fig52_acceptance_vs_f1" in f1 and "fig51_contact_times_vs_f1" in f1 and "fig43-45_values_vs_cd" not in f1
    # without cd there is no acceptance regime to draw
    assert [n for n, _, _ in select_sweep_figures(["probe.f1"])] == ["fig51_contact_times_vs_f1"]
    # an unknown swept key still gets its errors figure
    assert "errors_vs_probe_q2" in [n for n, _, _ in select_sweep_figures(["surface.cd", "probe.q2"])]


def test_swept_keys_come_from_varying_columns_and_drop_lockstep_keys():
    df, meta = synthetic_sweep("frequency")
    df["probe.f2"] = 15 * df["probe.f1"]  # a zip group / f2_ratio: varies with f1, adds no axis
    df["surface.k_inf"] = 4.0  # named but constant
    meta["config"]["sweep"]["probe.f2"] = [15 * f for f in meta["config"]["sweep"]["probe.f1"]]
    assert swept_keys(df, meta) == ["surface.cd", "probe.f1"]
    # a single-valued dotted column is not an axis even without a sweep block
    assert swept_keys(df, {"units": {}}) == ["surface.cd", "probe.f1"]


def test_acceptance_regime_spans_the_ok_points_below_30_percent():
    # hand-made errors over cd 1..8 (thesis fig. 52: acceptance = tau_c error < 30 %):
    # 80, 20, 10, 45, 5, 25, 28, 60 -> accepted cd 2, 3, 5, 6, 7: range 2..7, broken at cd 4
    d = pd.DataFrame(
        {"surface.cd": np.arange(1, 9.0), "tau_c_err_pct": [80, 20, 10, 45, 5, 25, 28, 60.0], "status": ["ok"] * 8}
    )
    r = regime(d)
    assert (r.lo, r.hi, r.contiguous) == (2.0, 7.0, False)
    assert list(r.accepted) == [2, 3, 5, 6, 7]
    d.loc[3, "tau_c_err_pct"] = 12.0
    assert regime(d).contiguous
    # a not-steady point is not accepted, whatever its error, and breaks the run
    d.loc[3, "status"] = "not_steady"
    r = regime(d)
    assert (r.lo, r.hi, r.contiguous) == (2.0, 7.0, False)
    d["tau_c_err_pct"] = 31.0
    assert regime(d) is None


@pytest.mark.parametrize("study", ["frequency", "print_step"])
def test_acceptance_regime_agrees_with_what_vetica_sweep_reports(study):
    from vetica_cli.study.acceptance import acceptance_regime

    df, _ = synthetic_sweep(study)
    other = next(k for k in STUDIES[study] if k != "surface.cd")
    for entry in acceptance_regime(df, list(STUDIES[study])):
        g = df[(df[other] == entry[other]) & (df["force_source"] == entry["force_source"])]
        r = regime(g)
        if entry["cd_min"] is None:
            assert r is None
        else:
            assert (r.lo, r.hi, r.contiguous) == (entry["cd_min"], entry["cd_max"], entry["contiguous"])


def test_failed_and_not_steady_points_are_reported_in_the_figure_note(table, tmp_path):
    df, _meta = synthetic_sweep("dashpot")
    sw = SweepData(df=df, swept=["surface.cd"], base=BASE)
    fig = fig_errors_vs_cd(sw)
    texts = " ".join(t.get_text() for t in fig.texts)
    assert "1 failed point(s) excluded" in texts and "1 not-steady point(s)" in texts


def test_a_key_without_effect_on_an_observable_gets_no_lines_of_its_own():
    # synthetic print-step study: the observables do not depend on the print step (one shared
    # simulation per cd), so E_diss against cd is one line, and the note says why
    df, meta = synthetic_sweep("print_step")
    sw = SweepData(df=df, swept=swept_keys(df, meta), base=BASE)
    fig = fig_observable_vs_cd(sw, "e_diss_ev", "41")
    assert len([ln for ln in fig.axes[0].get_lines() if ln.get_linestyle() == "-"]) == 1
    assert "identical for every print step" in " ".join(t.get_text() for t in fig.texts)
    # ...while the errors do depend on it: one line per print step and force source
    fig = fig_acceptance_vs(sw, "numerics.print_step", "61")
    assert len([ln for ln in fig.axes[0].get_lines() if len(ln.get_xdata()) > 2]) == 2 * 4


def test_means_against_a_setting_use_only_the_cd_values_ok_at_every_setting():
    # hand-made: setting 0.4 has cd 3 not steady, so the mean at every set point is over cd 1 and 2;
    # averaging over each setting's own ok points would mix in cd 3 at 0.25 only (mean 20, not 15)
    df = pd.DataFrame(
        {
            "operation.setpoint": [0.25, 0.25, 0.25, 0.4, 0.4, 0.4],
            "surface.cd": [1.0, 2.0, 3.0, 1.0, 2.0, 3.0],
            "status": ["ok", "ok", "ok", "ok", "ok", "not_steady"],
            "peak_force": [10.0, 20.0, 30.0, 10.0, 20.0, 90.0],
        }
    )
    mean, _lo, hi, n = mean_band(df, "operation.setpoint", "peak_force", ["surface.cd"])
    assert mean.tolist() == [15.0, 15.0] and n.tolist() == [2, 2] and hi.tolist() == [20.0, 20.0]
    # a steady record without an estimate still has its observables: it counts
    df.loc[1, "status"] = "no_estimate"
    assert mean_band(df, "operation.setpoint", "peak_force", ["surface.cd"])[0].tolist() == [15.0, 15.0]
    # no common value: fall back to every ok point
    df.loc[df["surface.cd"] < 3, "status"] = ["not_steady", "not_steady", "ok", "ok"]
    mean, *_ = mean_band(df, "operation.setpoint", "peak_force", ["surface.cd"])
    assert mean.tolist() == [30.0, 15.0]


def test_plot_rejects_corrupt_and_non_vetica_files_with_one_line(tmp_path):
    bad = tmp_path / "junk.parquet"
    bad.write_bytes(b"not parquet at all")
    other = tmp_path / "other.parquet"
    pd.DataFrame({"a": [1.0, 2.0]}).to_parquet(other)
    wrong_cols = write_table(pd.DataFrame({"a": [1.0]}), tmp_path / "wrong.parquet", {"units": {}})
    for path in (bad, other, wrong_cols, tmp_path / "missing.parquet"):
        res = runner.invoke(app, ["plot", str(path), "-o", str(tmp_path / "out")])
        assert res.exit_code == 2, (path, res.output)
        lines = res.output.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error:") and "Traceback" not in res.output
    assert not (tmp_path / "out").exists()
    res = runner.invoke(app, ["plot", str(bad), "--cutoff", "0"])
    assert res.exit_code == 2 and "--cutoff" in res.output


# ---------------------------------------------------------------------------
# run figures (one short real simulation)


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    """Worked example at PS 0.5 ns, 3 recorded periods: ~3 s of kernel time."""
    cfg = load(None, {"numerics.print_step": 0.5e-9, "numerics.record_cycles": 3})
    path = tmp_path_factory.mktemp("run") / "run.parquet"
    write_run(simulate(cfg), path)
    return path


def test_plot_writes_the_run_figures(run_file, tmp_path):
    out = tmp_path / "figs"
    res = runner.invoke(app, ["plot", str(run_file), "-o", str(out)])
    assert res.exit_code == 0, res.output
    names = {p.name for p in out.glob("*.png")}
    expected = {"run_fig33_trajectories.png", "run_fig28_force_distance.png", "run_fig62_force_distance_velocity.png"}
    assert expected <= names
    if _spectral_available():
        assert "run_force_reconstruction.png" in names
    else:
        assert "spectral" in res.output  # the skipped figure is reported


def _spectral_available() -> bool:
    try:
        from vetica_cli.signals import spectral  # noqa: F401
    except ImportError:
        return False
    return True


def test_dissipation_loop_area_matches_the_run_energy(run_file):
    # E_diss = -closed-integral F dz (thesis 4.2.1) over the sampled tap against the kernel's
    # per-step integral of the same quantity (observables e_diss_ev); sampling at 0.5 ns instead of
    # dt = 0.025 ns costs accuracy: tolerance 3 %
    df, meta = read_table(run_file)
    run = load_run(df, meta)
    sl = tap_window(run)
    e = loop_energy_ev(run.z[sl], run.f[sl])
    assert e == pytest.approx(meta["observables"]["e_diss_ev"], rel=0.03)


def test_transitions_are_the_force_minima_at_the_simulator_contact_edges(run_file):
    df, meta = read_table(run_file)
    run = load_run(df, meta)
    on, off = transitions(run)
    assert len(on) == len(off) >= 2  # 3 recorded periods; taps cut by the record's ends are dropped
    # each transition sits at a force minimum close to -Fa(a0) = -H R / (6 a0^2); sampled at
    # 0.5 ns the minimum can be missed by a little: 15 %
    fa0 = 0.2e-18 * 10e-9 / (6 * 0.2e-9**2)
    assert np.allclose(run.f[np.r_[on, off]], -fa0, rtol=0.15)
    # massless SLS: the force minima mark contact and separation, i.e. the edges of the simulator's own
    # contact state (gap = a0); the two must agree to one sample
    c = (run.z - run.x) <= run.a0 * (1 + 1e-6)
    assert np.all(c[on]) and not np.any(c[on - 2]) and np.all(c[off - 1]) and not np.any(c[off + 1])
    # each tap lasts the kernel's contact time per cycle (observables, integrated at dt): 2 samples
    assert np.allclose((off - on) * 0.5e-9, meta["observables"]["contact_time"], rtol=0, atol=2 * 0.5e-9)


def test_spectral_velocity_matches_the_analytic_derivative_despite_drift():
    # z = A sin(w t) + B cos(3 w t) + a 50 pm drift over the window (what a run steady to the
    # simulator's tolerance shows); analytic derivative as reference.  The end correction must hold
    # the spectral derivative to 1e-8 of the peak speed (a plain FFT derivative is off by ~30 %).
    f1, n_per, periods = 50e3, 4000, 3
    dt = 1 / f1 / n_per
    t = np.arange(n_per * periods) * dt
    w = 2 * np.pi * f1
    drift = 50e-12 / (n_per * periods * dt)
    z = 70e-9 * np.sin(w * t) + 2e-9 * np.cos(3 * w * t) + drift * t
    v = 70e-9 * w * np.cos(w * t) - 6e-9 * w * np.sin(3 * w * t) + drift
    assert np.allclose(spectral_derivative(z, dt), v, rtol=0, atol=1e-8 * np.max(np.abs(v)))


def test_spectral_velocity_cutoff_drops_the_band_above_it():
    # z = A sin(w t) + a 40th-harmonic ripple whose derivative is 0.57 % of the peak speed; a cut-off
    # at 10 f1 must return the derivative of the first term alone.  Tolerance 1e-5 of the peak speed:
    # the ripple still biases the end-jump fit slightly (measured 1e-6 at the window's ends)
    f1, n_per, periods = 50e3, 4000, 2
    dt = 1 / f1 / n_per
    t = np.arange(n_per * periods) * dt
    w = 2 * np.pi * f1
    z = 70e-9 * np.sin(w * t) + 1e-11 * np.sin(40 * w * t)
    v = spectral_derivative(z, dt, cutoff_hz=10 * f1)
    assert np.allclose(v, 70e-9 * w * np.cos(w * t), rtol=0, atol=1e-5 * 70e-9 * w)


def test_spectral_velocity_of_the_run_agrees_with_finite_differences(run_file):
    # the tip trajectory has kinks in its acceleration at contact; central differences at 0.5 ns
    # and the spectral derivative must still agree to 1 % of the peak speed
    df, meta = read_table(run_file)
    run = load_run(df, meta)
    dt = meta["params"]["numerics"]["print_step"]
    v = spectral_derivative(run.z, dt)
    fd = np.gradient(run.z, dt)
    assert np.max(np.abs(v - fd)[1:-1]) < 0.01 * np.max(np.abs(fd))


def test_tables_comparing_methods_get_one_titled_figure_set_per_method():
    """A sweep over extract.method: the figures are drawn per method,
    named and titled after it, instead of mixing both methods in one series."""
    from vetica_cli.plots.study import sweep_figures

    df, meta = synthetic_sweep("dashpot", failed=0, not_steady=0)
    both = pd.concat([df.assign(method="vetica"), df.assign(method="full")], ignore_index=True)
    figs, notes = sweep_figures(both, meta)
    names = [n for n, _ in figs]
    assert {n.rsplit("_", 1)[1] for n in names} == {"vetica", "full"}
    assert len(names) == 2 * len(EXPECTED["dashpot"])
    full = dict(figs)["fig43-46_errors_vs_cd_full"]
    assert "full extraction" in full.get_suptitle()
    assert "VETICA" in dict(figs)["fig43-46_errors_vs_cd_vetica"].get_suptitle()
    assert "methods: full, vetica" in notes[-1]


def test_a_text_swept_key_is_a_series_not_an_axis(tmp_path):
    """A study swept on a text key (numerics.steady: orbit | transient, as
    configs/findings_table5.yaml) plots: the cd figures carry it as series, no figure uses it
    as an axis, and the note says so (it used to raise converting 'orbit' to float)."""
    df, meta = synthetic_sweep("dashpot", failed=0, not_steady=0)
    df = pd.concat([df.assign(**{"numerics.steady": "orbit"}), df.assign(**{"numerics.steady": "transient"})])
    meta["config"]["sweep"]["numerics.steady"] = ["orbit", "transient"]
    path = write_table(df.reset_index(drop=True), tmp_path / "t.parquet", meta)
    res = runner.invoke(app, ["plot", str(path), "-o", str(tmp_path / "figs")])
    assert res.exit_code == 0, res.output
    names = {p.name for p in (tmp_path / "figs").glob("*.png")}
    assert "t_fig43-46_errors_vs_cd.png" in names and not any("numerics_steady" in n for n in names)
    assert "numerics.steady takes text values" in res.output
