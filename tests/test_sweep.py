"""`vetica sweep`: jobs, failure rows, persisted parts and resume, determinism,
print-step sharing, the Dask backend, bad configs, the study configs, and the
smoke sweep end to end.

Most machinery tests use cheap real simulations (dt 0.05 ns, 100 drive periods,
2 recorded periods) and a fake extraction passed to the sweep as its task
(``PointTask(extract=fake_extract)``), so they test the sweep, not the physics;
the smoke test runs the real extraction.
"""

import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pint
import pytest
import yaml
from typer.testing import CliRunner

from vetica_cli import surfaces
from vetica_cli.cli import app
from vetica_cli.extraction import SOURCES, Estimate, ExtractionResult
from vetica_cli.io import read_table
from vetica_cli.simulation.config import Config, load
from vetica_cli.simulation.simulate import simulate
from vetica_cli.study.acceptance import acceptance_regime, format_acceptance
from vetica_cli.study.grid import expand, load_study
from vetica_cli.rows.plan import group
from vetica_cli.rows.schema import STATUSES
from vetica_cli.batch.parts import fingerprint_files, parts_dir
from vetica_cli.study.sweep import SWEEP_ROOTS, run_sweep
from vetica_cli.rows.task import PointTask

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"
runner = CliRunner()

# cheap points: coarse dt and print step, a short budget, two recorded periods
CHEAP = {
    "surface": {"k_inf": 4.0, "stiffness_ratio": 16},
    "numerics": {"dt": 0.05e-9, "print_step": 1e-9, "record_cycles": 2, "max_time": 0.002, "kp": 0.05, "ki": 0.03},
}
ISSUE_COLUMNS = [
    "force_source",
    *[f"{n}{s}" for n in ("tau_c", "k_g", "k_r", "k0", "k_inf", "cd") for s in ("", "_theory", "_err_pct")],
    "e_diss_ev", "peak_force", "max_penetration", "contact_time", "noncontact_time", "paddle_amplitude",
    "ss_zero_depth", "amplitude", "phase_deg", "stop_reason", "status", "error", "wall_s",
]  # fmt: skip


def cheap_study(sweep_block, **top):
    raw = {k: dict(v) for k, v in CHEAP.items()}
    raw.update(top)
    raw["sweep"] = sweep_block
    return expand(raw, name="t")


def fake_extract(df, meta, force, method="vetica"):
    """Deterministic stand-in for vetica_cli.extraction.extract: tau_c off by a force-dependent
    factor that also depends on the simulated signal (so determinism is tested)."""
    s = meta["params"]["surface"]
    th = {
        "tau_c": s["cd"] * (s["k0"] + s["k_inf"]) / (s["k0"] * s["k_inf"]),
        "k_g": s["k0"] + s["k_inf"],
        "k_r": s["k_inf"],
        "tau_r": s["cd"] / s["k0"],
        "k0": s["k0"],
        "k_inf": s["k_inf"],
        "cd": s["cd"],
    }
    wiggle = float(np.mean(df["z_tip"].to_numpy())) * 1e6  # ~1e-2, from the simulation
    factor = (1.1 if force == "true" else 1.5) + wiggle
    units = {n: q.unit for n, q in surfaces.get("sls").quantities.items()}
    est = {n: Estimate(t * factor, units[n], t, 100 * abs(t * factor - t) / t) for n, t in th.items()}
    return ExtractionResult(method=method, force=force, taps=2, estimates=est)


FAKE = PointTask(extract=fake_extract)


def numeric_equal(a: pd.DataFrame, b: pd.DataFrame) -> None:
    """Bit-identical numeric columns (wall_s excluded: a wall clock) and equal text columns."""
    assert list(a.columns) == list(b.columns)
    for c in a.columns:
        if c == "wall_s":
            continue
        if pd.api.types.is_numeric_dtype(a[c]):
            assert np.array_equal(a[c].to_numpy(), b[c].to_numpy(), equal_nan=True), c
        else:
            assert list(a[c]) == list(b[c]), c


# --------------------------------------------------------------------- job and table


def test_failing_point_becomes_a_failed_row_and_the_others_run(tmp_path):
    """One point's simulation raises, another point's true-force extraction raises:
    both become rows with status 'failed' and the error text; the extraction failure
    keeps the simulation's columns; the remaining point is unaffected."""

    def exploding_simulate(cfg):
        if cfg.surface.cd == 1e-4:
            raise RuntimeError("kernel exploded")
        return simulate(cfg)

    def extract(df, meta, force, method):
        if meta["params"]["surface"]["cd"] == 1e-3 and force == "true":
            raise ValueError("no taps found")
        return fake_extract(df, meta, force, method)

    st = cheap_study({"surface.cd": [1e-5, 1e-4, 1e-3]})
    task = PointTask(simulate=exploding_simulate, extract=extract)
    res = run_sweep(st, tmp_path / "t.parquet", jobs=1, progress=False, task=task)
    t = res.table
    assert len(t) == 6
    by = {(r["surface.cd"], r["force_source"]): r for _, r in t.iterrows()}
    for src in SOURCES:
        r = by[(1e-4, src)]
        assert r["status"] == "failed" and "simulate: RuntimeError: kernel exploded" in r["error"]
        assert math.isnan(r["e_diss_ev"]) and math.isnan(r["tau_c"])
        # theory still filled from the config: tau_c = cd (k0 + k_inf)/(k0 k_inf)
        assert r["tau_c_theory"] == pytest.approx(1e-4 * 68 / 256, rel=1e-12, abs=0.0)
    r = by[(1e-3, "true")]
    assert r["status"] == "failed" and "extract(true): ValueError: no taps found" in r["error"]
    assert r["e_diss_ev"] > 0 and r["stop_reason"] in ("steady", "max_time")
    assert by[(1e-3, "reconstructed")]["status"] in ("ok", "not_steady")
    for src in SOURCES:
        assert by[(1e-5, src)]["status"] in ("ok", "not_steady")
        assert by[(1e-5, src)]["error"] == ""
    # status follows stop_reason for rows that did not fail
    ok = t[t["status"] != "failed"]
    assert ((ok["status"] == "ok") == (ok["stop_reason"] == "steady")).all()


def test_table_has_issue_columns_units_metadata_and_saved_config(tmp_path):
    st = cheap_study({"surface.cd": [1e-5, 1e-3]}, name="cols")
    out = tmp_path / "res" / "cols.parquet"
    res = run_sweep(st, out, jobs=1, progress=False, task=FAKE)
    df, meta = read_table(out)
    for c in ["point", "surface.cd", *ISSUE_COLUMNS]:
        assert c in df.columns, c
    assert list(df["force_source"]) == ["true", "reconstructed"] * 2
    assert set(meta["units"]) == set(df.columns) == set(meta["descriptions"])
    # every unit parses with a unit library (pint); the meanings are apart, in 'descriptions'
    ureg = pint.UnitRegistry()
    for col, unit in meta["units"].items():
        ureg.parse_units(unit)  # raises for free text
    assert ureg.parse_units(meta["units"]["k_g"]) == ureg.parse_units("N/m")
    assert ureg.parse_units(meta["units"]["surface.cd"]) == ureg.parse_units("kg/s")
    assert ureg.parse_units(meta["units"]["tau_c_err_pct"]) == ureg.parse_units("percent")
    assert meta["swept_keys"] == ["surface.cd"] and meta["points"] == 2
    assert meta["config"]["surface"]["stiffness_ratio"] == 16
    # the config saved next to the table expands to the same points
    saved = yaml.safe_load(res.config_path.read_text())
    assert res.config_path == out.with_name("cols.config.yaml")
    assert [p.key for p in expand(saved).points] == [p.key for p in st.points]
    # fake tau_c errors are ~10 % (true) and ~50 % (reconstructed): acceptance only for true
    acc = {e["force_source"]: e for e in meta["acceptance"]}
    ok_true = df[(df.force_source == "true") & (df.status == "ok")]
    assert acc["true"]["n_accepted"] == len(ok_true)
    assert acc["reconstructed"]["n_accepted"] == 0


def test_acceptance_regime_per_combination_and_source():
    """Range of cd with status ok and tau_c error < 30 % (thesis fig. 52), per set point
    and force source; not_steady points do not count; gaps are flagged."""
    rows = []
    errs = {0.5: [80, 20, 10, 25, 90], 0.7: [10, 50, 10, 10, 10]}
    cds = [1e-5, 1e-4, 1e-3, 1e-2, 1e-1]
    for sp, e in errs.items():
        for cd, err in zip(cds, e):
            for src in SOURCES:
                status = "not_steady" if (sp == 0.7 and cd == 1e-1) else "ok"
                rows.append(
                    {
                        "operation.setpoint": sp,
                        "surface.cd": cd,
                        "force_source": src,
                        "status": status,
                        "tau_c_err_pct": err if src == "true" else 99.0,
                    }
                )
    acc = acceptance_regime(pd.DataFrame(rows), ("operation.setpoint", "surface.cd"))
    got = {(e["operation.setpoint"], e["force_source"]): e for e in acc}
    a = got[(0.5, "true")]
    assert (a["cd_min"], a["cd_max"], a["n_accepted"], a["contiguous"]) == (1e-4, 1e-2, 3, True)
    assert a["decades"] == pytest.approx(2.0)
    b = got[(0.7, "true")]
    assert (b["cd_min"], b["cd_max"], b["n_accepted"], b["n_not_steady"], b["contiguous"]) == (1e-5, 1e-2, 3, 1, False)
    assert got[(0.5, "reconstructed")]["n_accepted"] == 0
    text = format_acceptance(acc, ("operation.setpoint", "surface.cd"))
    assert "operation.setpoint=0.5, true force: cd 0.0001 .. 0.01 kg/s (2.00 decades)" in text
    assert "with gaps" in text


def test_acceptance_regime_takes_the_magnitude_of_signed_errors():
    """Tables store signed errors (100 (estimate - theory)/theory): an underestimate by
    50 % is as far outside the 30 % regime (thesis fig. 52) as an overestimate."""
    t = pd.DataFrame({"surface.cd": [1e-5, 1e-4, 1e-3, 1e-2], "force_source": "true", "status": "ok",
                      "tau_c_err_pct": [-50.0, -20.0, 25.0, 45.0]})  # fmt: skip
    (a,) = acceptance_regime(t, ("surface.cd",))
    assert (a["cd_min"], a["cd_max"], a["n_accepted"], a["contiguous"]) == (1e-4, 1e-3, 2, True)


# --------------------------------------------------------------------- resume and determinism

RESUME_SCRIPT = textwrap.dedent(
    """
    import os, sys, time
    sys.path.insert(0, {tests!r})
    from test_sweep import cheap_study, fake_extract
    from vetica_cli.study.sweep import run_sweep
    from vetica_cli.rows.task import PointTask

    def slow_extract(df, meta, force, method):
        time.sleep(float(os.environ.get("FAKE_SLEEP", "0")))
        return fake_extract(df, meta, force, method)

    st = cheap_study({{"surface.cd": {{"logspace": [-5, -3, 5]}}}})
    run_sweep(st, sys.argv[1], jobs=1, progress=False, task=PointTask(extract=slow_extract))
    """
)


def test_killed_sweep_resumes_only_missing_points_and_ends_with_the_same_table(tmp_path):
    """kill -9 a sweep after some parts are persisted; the rerun computes only the
    missing points; its table equals an uninterrupted run's (wall_s excluded)."""
    script = tmp_path / "run.py"
    script.write_text(RESUME_SCRIPT.format(tests=str(Path(__file__).parent)))
    out = tmp_path / "a" / "t.parquet"
    parts = parts_dir(out)
    env = dict(os.environ, FAKE_SLEEP="0.8")
    proc = subprocess.Popen([sys.executable, str(script), str(out)], env=env, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and len(list(parts.glob("*.parquet"))) < 2:
            assert proc.poll() is None, "the sweep ended before it could be killed"
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    persisted = {p.stem for p in parts.glob("*.parquet")}
    assert 2 <= len(persisted) < 5, persisted
    assert not out.exists()

    st = cheap_study({"surface.cd": {"logspace": [-5, -3, 5]}})
    res = run_sweep(st, out, jobs=1, progress=False, task=FAKE, keep_parts=True)
    assert set(res.reused) == persisted
    assert set(res.computed) == {p.key for p in st.points} - persisted

    ref = run_sweep(st, tmp_path / "b" / "t.parquet", jobs=1, progress=False, task=FAKE)
    assert len(ref.computed) == 5
    numeric_equal(res.table, ref.table)
    numeric_equal(read_table(out)[0], read_table(tmp_path / "b" / "t.parquet")[0])
    # a third run reuses everything (the parts were kept); --no-resume recomputes everything and,
    # without keep_parts, removes the parts folder after success
    again = run_sweep(st, out, jobs=1, progress=False, task=FAKE, keep_parts=True)
    assert again.computed == [] and len(again.reused) == 5
    fresh = run_sweep(st, out, jobs=1, resume=False, progress=False, task=FAKE)
    assert len(fresh.computed) == 5 and any("5 discarded (--no-resume)" in n for n in fresh.notes)
    numeric_equal(fresh.table, ref.table)
    assert not parts.exists() and not ref.parts_kept


def test_parts_made_by_other_code_or_config_are_recomputed(tmp_path):
    """A persisted part whose code fingerprint differs (the simulator or the
    extraction changed since) is stale; so is an unreadable part."""
    from vetica_cli.io import write_table

    st = cheap_study({"surface.cd": [1e-5, 1e-4, 1e-3]})
    out = tmp_path / "t.parquet"
    first = run_sweep(st, out, jobs=1, progress=False, task=FAKE, keep_parts=True)
    assert len(first.computed) == 3
    k0, k1 = st.points[0].key, st.points[1].key
    part = parts_dir(out) / f"{k0}.parquet"
    df, meta = read_table(part)
    write_table(df, part, {**meta, "code": "0000000000000000"})
    (parts_dir(out) / f"{k1}.parquet").write_bytes(b"not parquet")
    again = run_sweep(st, out, jobs=1, progress=False, task=FAKE)
    assert sorted(again.computed) == sorted([k0, k1])
    assert again.reused == [st.points[2].key]
    numeric_equal(again.table, first.table)


def test_code_fingerprint_covers_simulation_and_extraction_only():
    names = {f.relative_to(ROOT / "vetica_cli").as_posix() for f in fingerprint_files(SWEEP_ROOTS)}
    assert {"simulation/simulate.py", "core/tapping.py", "core/engine.py", "core/coefficients.py", "core/sls.py", "core/prescribed.py", "simulation/observables.py",
            "simulation/config.py", "simulation/instrument.py", "extraction/__init__.py", "extraction/methods/vetica.py",
            "extraction/record.py", "extraction/result.py", "extraction/fullfit/model.py",
            "extraction/fullfit/method.py", "signals/spectral.py", "signals/taps.py", "surfaces/sls.py",
            "surfaces/base.py", "rows/task.py", "rows/plan.py", "study/grid.py", "rows/schema.py",
            "study/table.py"} <= names  # fmt: skip
    assert not {n for n in names if n.startswith(("plots/", "batch/", "scan/"))}
    assert not names & {"cli.py", "report.py", "bench.py", "study/sweep.py", "study/cost.py"}  # fmt: skip


def test_same_config_gives_bit_identical_numeric_columns_with_two_workers(tmp_path):
    """Two loky workers, unordered completion: rows are still in grid order and the
    numeric columns are bit-identical across runs (real extraction)."""
    st = cheap_study({"surface.cd": [1e-5, 1e-3], "numerics.print_step": [0.5e-9, 1e-9]})
    a = run_sweep(st, tmp_path / "a.parquet", jobs=2, progress=False)
    b = run_sweep(st, tmp_path / "b.parquet", jobs=2, progress=False)
    assert len(a.computed) == len(b.computed) == 4
    assert list(a.table["point"]) == [p.key for p in st.points for _ in SOURCES]
    numeric_equal(a.table, b.table)


# --------------------------------------------------------------------- print step


def test_trajectory_does_not_depend_on_the_print_step():
    """The print step only samples the trajectory: the controller measures the first
    harmonic on the integration steps, not on the print-step samples (version 0.1's
    max - min of the samples made the base height depend on the print step at the
    1e-13 m level).  Runs at 0.125, 1 and 4 ns agree at their common sample times to
    1e-15 m (measured <= 2e-16 m: the far steps of a recorded window are one print step
    long) and in E_diss, amplitude and phase to 1e-5."""
    base = {"surface.k0": 64.0, "surface.cd": 1e-4, "numerics.record_cycles": 2}
    runs = [simulate(load(None, {**base, "numerics.print_step": ps})) for ps in (0.125e-9, 1e-9, 4e-9)]
    ref = runs[0]
    for r in runs[1:]:
        ta = np.round(ref.steady[:, 0] / 1e-12).astype(np.int64)
        tb = np.round(r.steady[:, 0] / 1e-12).astype(np.int64)
        _, ia, ib = np.intersect1d(ta, tb, return_indices=True)
        assert len(ib) == len(tb)
        assert np.max(np.abs(ref.steady[ia, 1] - r.steady[ib, 1])) < 1e-15
        for k in ("e_diss_ev", "amplitude", "phase_deg"):
            assert r.observables[k] == pytest.approx(ref.observables[k], rel=1e-5, abs=0.0), k


def test_plan_shares_only_identical_simulations():
    """Points that differ in the print step are simulated separately; points that differ only
    in the method or the instrument keys share one simulation."""
    st = cheap_study({"surface.cd": [1e-5, 1e-4], "numerics.print_step": [0.5e-9, 1e-9, 2e-9]})
    assert len(group(st.points)) == 6 and all(len(t.points) == 1 for t in group(st.points))
    st2 = cheap_study({"surface.cd": [1e-5, 1e-4], "numerics.position_noise": [0.0, 1e-12]})
    assert len(group(st2.points)) == 2 and all(len(t.points) == 2 for t in group(st2.points))


# --------------------------------------------------------------------- Dask


def test_dask_backend_on_a_local_cluster(tmp_path):
    """The same jobs through joblib's dask backend on a distributed.LocalCluster
    (in-process workers) give the same table as the local run."""
    distributed = pytest.importorskip("distributed")
    st = cheap_study({"surface.cd": [1e-5, 1e-3]})
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cl:
        res = run_sweep(st, tmp_path / "d.parquet", backend="dask", scheduler=cl.scheduler_address,
                        progress=False, task=FAKE)  # fmt: skip
    assert len(res.computed) == 2 and len(res.table) == 4
    ref = run_sweep(st, tmp_path / "l.parquet", jobs=1, progress=False, task=FAKE)
    numeric_equal(res.table, ref.table)


# --------------------------------------------------------------------- command line


def _bad(tmp_path, text):
    p = tmp_path / "study.yaml"
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    "text, extra, fragment",
    [
        ("sweep:\n  surface.kzero: [1, 2]\n", [], "unknown key 'surface.kzero'"),
        ("sweep:\n  surface.cd: {logspace: [-5, 3]}\n", [], "[first, last, n]"),
        ("sweep:\n  surface.cd: {linspace: [1, 2, 2.5]}\n", [], "integer"),
        ("sweep:\n  surface.cd: []\n", [], "empty grid"),
        ("surface: {cd: 1.0e-4}\n", [], "empty grid"),
        ("sweep:\n  operation.setpoint: [0.5, 1.5]\n", [], "operation.setpoint"),
        ("sweep:\n  surface.cd: [1.0e-4]\n", ["--backend", "spark"], "--backend 'spark'"),
        ("sweep:\n  surface.cd: [1.0e-4]\n", ["--scheduler", "tcp://127.0.0.1:1"], "--scheduler needs --backend dask"),
        ("sweep:\n  surface.cd: [1.0e-4]\n", ["--jobs", "0"], "'--jobs' / '-j': 0 is not allowed"),
        ("sweep:\n  surface.cd: [1.0e-4]\n", ["--set", "surface.cd=1e-3"], "swept"),
        ("sweep:\n  surface.cd: [1.0e-4]\n", ["--set", "surface.nope=1"], "surface.nope"),
    ],
)
def test_bad_study_exits_2_with_one_line_and_writes_nothing(tmp_path, text, extra, fragment):
    cfg = _bad(tmp_path, text)
    out = tmp_path / "out" / "t.parquet"
    r = runner.invoke(app, ["sweep", str(cfg), "-o", str(out), "-q", *extra])
    assert r.exit_code == 2, r.output
    msg = r.stderr.strip()
    assert fragment in msg
    assert len(msg.splitlines()) == 1 and "Traceback" not in r.output
    assert not (tmp_path / "out").exists()


def test_missing_config_file_and_non_parquet_output_exit_2(tmp_path):
    r = runner.invoke(app, ["sweep", str(tmp_path / "nope.yaml")])
    assert r.exit_code == 2 and "does not exist" in r.stderr
    cfg = _bad(tmp_path, "sweep:\n  surface.cd: [1.0e-4]\n")
    r = runner.invoke(app, ["sweep", str(cfg), "-o", str(tmp_path / "t.csv")])
    assert r.exit_code == 2 and ".parquet" in r.stderr
    assert not (tmp_path / "t.csv").exists()


def test_dry_run_lists_points_and_writes_nothing(tmp_path):
    r = runner.invoke(app, ["sweep", str(CONFIGS / "print_step.yaml"), "--dry-run", "-o", str(tmp_path / "p.parquet")])
    assert r.exit_code == 0, r.output
    assert "91 points" in r.stdout and "91 simulations" in r.stdout
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------- study configs


def test_worked_example_yaml_is_the_defaults():
    assert load(CONFIGS / "worked_example.yaml") == Config()


@pytest.mark.parametrize("name", ["dashpot", "stiffness_ratio", "setpoint", "frequency", "print_step",
                                  "paddle_stiffness", "smoke"])  # fmt: skip
def test_study_configs_expand(name):
    st = load_study(CONFIGS / f"{name}.yaml")
    assert st.name == name and len(st.points) >= 4
    for p in st.points:
        assert p.config.numerics.dt == (0.05e-9 if name == "smoke" else 0.025e-9)


def test_dashpot_study_meets_the_issue_minimum():
    """The thesis's dashpot grid: cd 1e-5 .. 1e3 kg/s, at least 4 points a decade, ratio 16:1."""
    st = load_study(CONFIGS / "dashpot.yaml")
    cds = sorted(p.config.surface.cd for p in st.points)
    assert cds[0] == 1e-5 and cds[-1] == 1e3
    assert len(cds) >= 4 * 8 + 1
    assert np.max(np.diff(np.log10(cds))) <= 0.25 + 1e-12
    assert {p.config.surface.k0 / p.config.surface.k_inf for p in st.points} == {16.0}


def test_frequency_study_keeps_f2_at_15_f1():
    st = load_study(CONFIGS / "frequency.yaml")
    for p in st.points:
        assert p.config.probe.f2 == pytest.approx(15 * p.config.probe.f1, rel=1e-12)


# --------------------------------------------------------------------- smoke, end to end


def test_smoke_sweep_end_to_end(tmp_path):
    """`vetica sweep configs/smoke.yaml` with the real simulation and extraction:
    4 points x 2 force sources; values checked against the SLS theory and the
    operating point (set point 70 % of A0 = 100 nm)."""
    out = tmp_path / "smoke.parquet"
    t0 = time.perf_counter()
    r = runner.invoke(app, ["sweep", str(CONFIGS / "smoke.yaml"), "-o", str(out), "-q"])
    wall = time.perf_counter() - t0
    assert r.exit_code == 0, r.output
    assert "acceptance regime" in r.stdout
    df, meta = read_table(out)
    assert df.shape[0] == 8
    for c in ["point", "surface.cd", "numerics.print_step", *ISSUE_COLUMNS]:
        assert c in df.columns, c
    assert set(df["status"]) <= set(STATUSES)
    assert (df["status"] != "failed").all(), df.loc[df.status == "failed", "error"].tolist()
    th = df["surface.cd"] * (64 + 4) / (64 * 4)  # tau_c = cd (k0 + k_inf)/(k0 k_inf)
    np.testing.assert_allclose(df["tau_c_theory"], th, rtol=1e-12)
    assert ((df["e_diss_ev"] > 0) & (df["e_diss_ev"] < 1e4)).all()
    assert ((df["peak_force"] > 0) & (df["peak_force"] < 1e-6)).all()
    np.testing.assert_allclose(df["amplitude"], 70e-9, rtol=0.05)
    np.testing.assert_allclose(df["contact_time"] + df["noncontact_time"], 1 / 50e3, rtol=1e-9)
    true = df[df.force_source == "true"]
    assert np.isfinite(true["tau_c"]).all() and (true["tau_c"] > 0).all()
    assert np.isfinite(true["k_g"]).all()
    assert meta["acceptance"] and out.with_name("smoke.config.yaml").is_file()
    print(f"smoke sweep wall time: {wall:.1f} s")
