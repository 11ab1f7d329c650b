"""The extraction method as a sweep axis: ``extract.method`` in the
sweep grammar, one simulation shared by the points that differ only in method or
in the instrument keys, and a small end-to-end sweep with both methods.

Reference values: the grammar's definitions (grid.py docstring); for sharing,
separate simulations of the same points (the instrument model acts after the
kernel, vetica_cli/simulation/instrument.py:apply_instrument, so a shared record with the
point's noise applied must equal a separate run bit for bit); for the end to end
sweep, the SLS theory values of the configured surface.
"""

import math

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from vetica_cli import surfaces
from vetica_cli.cli import app
from vetica_cli.errors import ConfigError
from vetica_cli.extraction import METHODS, SOURCES, Estimate, ExtractionResult
from vetica_cli.io import read_table
from vetica_cli.simulation.config import load
from vetica_cli.simulation.instrument import noise_free
from vetica_cli.simulation.simulate import simulate
from vetica_cli.study.acceptance import acceptance_regime, format_acceptance
from vetica_cli.study.grid import expand, point_key
from vetica_cli.rows.plan import group, point_run
from vetica_cli.study.sweep import run_sweep
from vetica_cli.rows.task import PointTask

runner = CliRunner()

# cheap points (as tests/test_sweep.py): coarse dt and print step, short budget, three recorded periods
CHEAP = {
    "surface": {"k_inf": 4.0, "stiffness_ratio": 16},
    "numerics": {"dt": 0.05e-9, "print_step": 1e-9, "record_cycles": 3, "max_time": 0.002, "kp": 0.05, "ki": 0.03},
}


def cheap(sweep_block, **top):
    raw = {k: dict(v) for k, v in CHEAP.items()}
    raw.update(top)
    raw["sweep"] = sweep_block
    return expand(raw, name="m")


def fake_extract(df, meta, force, method="vetica"):
    """Stand-in extraction: errors of 10 % (vetica) or 1 % (full) on every estimate."""
    s = meta["params"]["surface"]
    th = {"tau_c": s["cd"] * (s["k0"] + s["k_inf"]) / (s["k0"] * s["k_inf"]), "k_g": s["k0"] + s["k_inf"],
          "k_r": s["k_inf"], "tau_r": s["cd"] / s["k0"], "k0": s["k0"], "k_inf": s["k_inf"], "cd": s["cd"]}  # fmt: skip
    f = 1.10 if method == "vetica" else 1.01
    units = {n: q.unit for n, q in surfaces.get("sls").quantities.items()}
    # VETICA flags its tau_c (a derived quantity, not one of the SLS parameters) and gives it a sigma
    sigma = {"k0": 0.002, "k_inf": 0.003, "cd": 2.0} if method == "full" else {"tau_c": 0.05}
    ident = {"k_inf": True, "k0": True, "cd": False} if method == "full" else {"tau_c": False}
    est = {n: Estimate(v * f, units[n], v, 100 * abs(f - 1), sigma=sigma.get(n), identifiable=ident.get(n))
           for n, v in th.items()}  # fmt: skip
    return ExtractionResult(method=method, force=force, taps=3, estimates=est, fitted=tuple(ident))


# --------------------------------------------------------------------- grammar


def test_method_is_a_sweep_key_with_vetica_as_default():
    st = cheap({"surface.cd": [1e-5, 1e-4], "extract.method": ["vetica", "full"]})
    assert st.keys == ("surface.cd", "extract.method")
    assert [(p.values["surface.cd"], p.method) for p in st.points] == [
        (1e-5, "vetica"), (1e-5, "full"), (1e-4, "vetica"), (1e-4, "full")]  # fmt: skip
    # the method is not part of the simulated config ...
    assert st.points[0].config == st.points[1].config
    # ... but it is part of the point key; a VETICA point keeps the key it had before the axis existed
    assert st.points[0].key != st.points[1].key
    assert st.points[0].key == point_key(st.points[0].config)
    assert all(p.method == "vetica" for p in cheap({"surface.cd": [1e-5]}).points)


def test_method_in_the_base_or_by_set_and_the_saved_config_reruns():
    st = cheap({"surface.cd": [1e-5]}, extract={"method": "full"})
    assert st.points[0].method == "full"
    again = expand(st.resolved())
    assert [p.key for p in again.points] == [p.key for p in st.points]
    assert again.points[0].method == "full"
    st2 = expand({**CHEAP, "sweep": {"surface.cd": [1e-5]}}, overrides={"extract.method": "full"})
    assert st2.points[0].method == "full" and st2.points[0].key == st.points[0].key


ALLOWED = ", ".join(METHODS)  # the registered methods, in registration order


@pytest.mark.parametrize(
    "raw, overrides, fragment",
    [
        ({"sweep": {"extract.method": ["vetica", "fit"]}}, None,
         f"sweep.extract.method: 'fit' is not allowed; expected one of: {ALLOWED}"),
        ({"sweep": {"extract.method": {"logspace": [0, 1, 2]}}}, None, f"expected one of: {ALLOWED}"),
        ({"extract": {"method": "VETICA"}, "sweep": {"surface.cd": [1e-5]}}, None, f"expected one of: {ALLOWED}"),
        ({"extract": {"forces": "true"}, "sweep": {"surface.cd": [1e-5]}}, None,
         "unknown key 'extract.forces'; allowed: extract.method, extract.force"),
        ({"extract": "full", "sweep": {"surface.cd": [1e-5]}}, None, "must be a mapping"),
        ({"sweep": {"surface.cd": [1e-5]}}, {"extract.method": "ful"}, "--set extract.method: 'ful' is not allowed"),
        ({"sweep": {"extract.method": ["full"]}}, {"extract.method": "vetica"}, "swept"),
        ({"sweep": {"extract.method": ["full", "full"]}}, None, "appears twice"),
        ({"sweep": {"extract.force": ["true", "measured"]}}, None,
         "sweep.extract.force: 'measured' is not allowed; expected one of: both, true, reconstructed"),
    ],
)  # fmt: skip
def test_bad_method_values_raise_one_line_errors_listing_the_allowed_values(raw, overrides, fragment):
    with pytest.raises(ConfigError) as exc:
        expand(raw, overrides=overrides)
    assert fragment in str(exc.value) and "\n" not in str(exc.value)


def test_bad_method_on_the_command_line_exits_2_and_writes_nothing(tmp_path):
    cfg = tmp_path / "s.yaml"
    cfg.write_text("sweep:\n  extract.method: [vetica, fast]\n")
    r = runner.invoke(app, ["sweep", str(cfg), "-o", str(tmp_path / "out" / "t.parquet"), "-q"])
    assert r.exit_code == 2
    assert r.stderr.strip().splitlines() == [
        f"error: sweep.extract.method: 'fast' is not allowed; expected one of: {ALLOWED}"]  # fmt: skip
    assert not (tmp_path / "out").exists()


# --------------------------------------------------------------------- sharing


def test_points_differing_in_method_and_noise_share_one_simulation(tmp_path):
    """2 cd x 2 methods x 2 noise levels = 8 points -> 2 simulations (counted)."""
    st = cheap({"surface.cd": [1e-5, 1e-3], "extract.method": ["vetica", "full"],
                "numerics.position_noise": [0.0, 1e-11]})  # fmt: skip
    assert [len(t.points) for t in group(st.points)] == [4, 4]
    calls = []

    def counting(cfg):
        calls.append(cfg)
        return simulate(cfg)

    task = PointTask(simulate=counting, extract=fake_extract)
    res = run_sweep(st, tmp_path / "t.parquet", jobs=1, progress=False, task=task, keep_parts=True)
    assert len(calls) == 2 and all(c.numerics.position_noise == 0 for c in calls)
    t = res.table
    assert len(t) == 16 and list(t["method"]) == (["vetica"] * 4 + ["full"] * 4) * 2
    assert "extract.method" not in t.columns and "numerics.position_noise" in t.columns
    # the observables are the noise-free simulation's for all four points of a cd
    for _, g in t.groupby("surface.cd"):
        assert g["e_diss_ev"].nunique() == 1
    full = t[t["method"] == "full"]
    np.testing.assert_allclose(full["cd_sigma_pct"], 200.0)
    assert set(full["unidentified"]) == {"cd"}
    # every quantity a table gives an error for carries its flag and sigma, the derived ones too:
    # a row whose tau_c is flagged says so (it did not when only the parameters k0, k_inf, cd had them)
    vet = t[t.method == "vetica"]
    assert set(vet["unidentified"]) == {"tau_c"} and (vet["tau_c_sigma_pct"] == 5.0).all()
    assert vet["k0_sigma_pct"].isna().all() and full["tau_c_sigma_pct"].isna().all()
    # a rerun reuses all 8 parts (kept)
    again = run_sweep(st, tmp_path / "t.parquet", jobs=1, progress=False, task=task)
    assert again.computed == [] and len(again.reused) == 8


def test_force_key_restricts_the_sources_and_zips_with_the_noise(tmp_path):
    """extract.force = true skips the reconstruction (hopeless and slow with detector
    noise at the Nyquist cut-off): one row for that point, two for 'both'."""
    st = cheap({"surface.cd": [1e-4],
                "zip": {"numerics.position_noise": [0.0, 1e-11], "extract.force": ["both", "true"]}})  # fmt: skip
    assert [p.force for p in st.points] == ["both", "true"]
    # YAML reads a bare `true` as a boolean: it means the force source 'true'
    assert expand({"sweep": {"extract.force": [True]}}).points[0].force == "true"
    assert "extract.force" in st.keys
    out = tmp_path / "f.parquet"
    task = PointTask(extract=fake_extract)
    res = run_sweep(st, out, jobs=1, progress=False, task=task, keep_parts=True)
    t = res.table
    assert list(zip(t["numerics.position_noise"], t["force_source"])) == [
        (0.0, "true"), (0.0, "reconstructed"), (1e-11, "true")]  # fmt: skip
    assert "extract.force" not in t.columns and set(read_table(out)[1]["units"]) == set(t.columns)
    again = run_sweep(st, out, jobs=1, progress=False, task=task)
    assert again.computed == [] and len(again.reused) == 2


def test_shared_record_with_noise_equals_a_separate_noisy_simulation():
    """The instrument model acts after the kernel, so the shared noise-free record with
    the point's noise applied is bit-identical to simulating the noisy point alone."""
    base = {"surface.k0": 64.0, "surface.cd": 1e-4, "numerics.dt": 0.05e-9, "numerics.record_cycles": 2,
            "numerics.print_step": 1e-9}  # fmt: skip
    noisy = load(None, {**base, "numerics.position_noise": 1e-11, "numerics.force_noise": 1e-11,
                        "numerics.noise_seed": 3, "numerics.detector_bandwidth": 20e6})  # fmt: skip
    clean = noise_free(noisy)
    assert clean.numerics.position_noise == 0 and clean == load(None, base)
    shared = simulate(clean)
    got = point_run(shared, noisy)
    sep = simulate(noisy)
    np.testing.assert_array_equal(got.steady, sep.steady)
    np.testing.assert_array_equal(got.approach, sep.approach)
    assert got.params == sep.params and got.stop_reason == sep.stop_reason
    np.testing.assert_equal(got.observables, sep.observables)  # NaN == NaN here
    assert np.std(got.steady[:, 2] - shared.steady[:, 2]) > 1e-12  # the noise is really there


# --------------------------------------------------------------------- end to end


def test_tiny_sweep_with_both_methods_end_to_end(tmp_path):
    """Real simulation and both real extractions on one cheap point (cd = 1e-4 kg/s,
    16:1), through the command line.  Reference: SLS theory of the configured surface.
    Tolerances: the whole-cycle inversion with the true force recovers k0, k_inf and
    cd to < 1 % (the target; measured ~0.03 % on this point); VETICA's
    acceptance regime ends near cd = 1e-4 kg/s at 16:1 (results/thesis/dashpot.parquet), so
    only finiteness is asked of it here."""
    cfg = tmp_path / "both.yaml"
    cfg.write_text(
        "surface: {k_inf: 4.0, stiffness_ratio: 16}\n"
        "numerics: {dt: 0.05e-9, print_step: 1.0e-9, record_cycles: 3, max_time: 0.002, kp: 0.05, ki: 0.03}\n"
        "sweep:\n  surface.cd: [1.0e-4]\n  extract.method: [vetica, full]\n"
    )
    out = tmp_path / "both.parquet"
    r = runner.invoke(app, ["sweep", str(cfg), "-o", str(out), "-q"])
    assert r.exit_code == 0, r.output
    assert "method=full, true force" in r.stdout and "method=vetica, true force" in r.stdout
    df, meta = read_table(out)
    assert list(df["method"]) == ["vetica", "vetica", "full", "full"]
    assert list(df["force_source"]) == ["true", "reconstructed"] * 2
    assert set(meta["units"]) == set(df.columns)
    assert meta["swept_keys"] == ["surface.cd", "extract.method"]
    assert (df["status"] != "failed").all(), df["error"].tolist()
    assert df["e_diss_ev"].nunique() == 1  # one simulation
    v = df[(df.method == "vetica") & (df.force_source == "true")].iloc[0]
    assert math.isfinite(v["tau_c"]) and math.isfinite(v["k_g"])
    f = df[(df.method == "full") & (df.force_source == "true")].iloc[0]
    for name in ("k0", "k_inf", "cd"):
        assert abs(f[f"{name}_err_pct"]) < 1.0, (name, f[f"{name}_err_pct"])
        assert math.isfinite(f[f"{name}_sigma_pct"])
    assert f["k0_theory"] == pytest.approx(64.0) and f["cd_theory"] == pytest.approx(1e-4)
    acc = {(e["method"], e["force_source"]): e for e in meta["acceptance"]}
    assert set(acc) == {(m, s) for m in ("vetica", "full") for s in SOURCES}


def test_acceptance_regime_by_cd_error_and_method():
    """The acceptance regime can be taken on any error column; the method column
    splits the groups even when the method is set in the base, not swept."""
    rows = []
    for method, errs in (("vetica", [90, 20, 10, 40]), ("full", [5, 1, 1, 2])):
        for cd, e in zip([1e-5, 1e-4, 1e-3, 1e-2], errs):
            rows.append({"surface.cd": cd, "method": method, "force_source": "true", "status": "ok",
                         "tau_c_err_pct": e, "cd_err_pct": e})  # fmt: skip
    t = pd.DataFrame(rows)
    acc = {e["method"]: e for e in acceptance_regime(t, ("surface.cd",), err_col="cd_err_pct")}
    assert (acc["vetica"]["cd_min"], acc["vetica"]["cd_max"]) == (1e-4, 1e-3)
    assert acc["full"]["decades"] == pytest.approx(3.0)
    text = format_acceptance(list(acc.values()), ("surface.cd",))
    assert "method=full, true force: cd 1e-05 .. 0.01 kg/s (3.00 decades)" in text
