"""Every registered surface model and extraction method follows the convention of its
registry (vetica_cli/surfaces/base.py, vetica_cli/extraction/base.py), and a second
surface model -- with a non-scalar config key, like the Wiechert surface's list of arms
(SPEC 11) -- plugs in through the registry alone.

References: the SLS worked example (thesis tables 2-4) for the theory values; the
convention itself for everything else."""

from __future__ import annotations

import inspect
import json
import math
from typing import ClassVar

import numpy as np
import pytest
from typer.testing import CliRunner

from vetica_cli import surfaces
from vetica_cli.checks import check, coerce, positive
from vetica_cli.cli import app
from vetica_cli.errors import ConfigError, InputError
from vetica_cli.extraction import METHODS, ExtractionResult, extract
from vetica_cli.extraction.format import format_table, to_json
from vetica_cli.simulation.config import Config, from_dict, load
from vetica_cli.simulation.simulate import simulate
from vetica_cli.study.grid import EXTRACT_KEYS, expand
from vetica_cli.study.schema import result_columns

MODELS = list(surfaces.MODELS.values())


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.key)
def test_surface_model_declares_keys_units_and_a_documented_equation(model):
    assert surfaces.MODELS[model.key] is model and model.name
    assert model.parameter_keys and all(isinstance(k, str) for k in model.parameter_keys)
    assert set(model.parameter_units) == set(model.parameter_keys) and all(model.parameter_units.values())
    assert set(model.parameter_labels) >= set(model.parameter_keys)
    doc = surfaces.base.doc(model)
    assert "thesis" in doc and "=" in doc, "docstring: the equation and its thesis reference"
    assert model.quantities and all(q.unit and q.label and q.tex for q in model.quantities.values())
    assert set(model.fit_bounds) == set(model.parameter_keys)
    assert model.theory_source
    for name, dk in model.derived_keys.items():
        assert dk.target in model.config_keys and dk.source in model.config_keys, name


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.key)
def test_theory_kernel_arms_and_gradients_are_consistent(model):
    params = model.parse({})
    assert set(params) == set(model.config_keys)
    th = model.theory(params)
    assert list(th) == list(model.quantities)  # every declared quantity, in table order
    assert all(isinstance(v, float) and math.isfinite(v) for v in th.values())
    k_inf, k, cd = model.kernel_arms(params)
    assert isinstance(k_inf, float) and k_inf > 0
    assert k.ndim == cd.ndim == 1 and len(k) == len(cd) >= 1 and k.dtype == cd.dtype == np.float64
    assert np.all(k > 0) and np.all(cd > 0)
    grads = model.log_gradients(params)
    assert set(grads) == set(model.quantities)
    assert all(len(g) == len(model.parameter_keys) for g in grads.values())
    for p in model.parameter_keys:  # a parameter's own log-gradient is the unit vector
        if p in grads:
            assert grads[p] == tuple(1.0 if q == p else 0.0 for q in model.parameter_keys)
    for p, (lo, hi) in model.fit_bounds.items():
        if isinstance(params.get(p), float):
            assert lo < params[p] < hi, p


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.key)
def test_surface_section_is_validated_by_its_model(model):
    """A value the model's rule refuses is a one-line ConfigError naming surface.<key>; the
    section round-trips through the config."""
    for name, (pred, allowed) in model.rules.items():
        if not pred(-1.0):
            with pytest.raises(ConfigError, match=rf"surface\.{name}: -1.0 is not allowed; expected {allowed}"):
                from_dict({"surface": {"model": model.key, name: -1.0}})
    with pytest.raises(ConfigError, match=r"unknown key 'surface.nope'; allowed in surface: model, "):
        from_dict({"surface": {"model": model.key, "nope": 1.0}})
    cfg = from_dict({"surface": {"model": model.key}})
    assert cfg.surface.model == model.key and from_dict(cfg.to_dict()) == cfg


def test_sls_section_reads_as_in_version_0_1():
    """The SLS YAML schema and the metadata's params.surface are unchanged (no 'model' key
    for the default model); the model's theory is the worked example's (thesis table 2:
    tau_c = 7.7344e-6 s; table 3: Kg = 132 N/m)."""
    assert list(Config().to_dict()["surface"]) == ["k_inf", "k0", "cd", "hamaker", "a0", "vdw_on_surface"]
    assert Config().surface.k0 == 128.0 and Config() == from_dict({"surface": {"model": "sls"}})
    th = surfaces.get("sls").theory(Config().surface.params)
    assert th["tau_c"] == pytest.approx(7.7344e-6, rel=1e-4) and th["k_g"] == 132.0
    with pytest.raises(ConfigError, match="surface.model: 'maxwell' is not allowed; expected one of: sls"):
        load(None, {"surface.model": "maxwell"})


# --------------------------------------------------------------------- a second model


class ToyWiechert(surfaces.SurfaceModel):
    """Wiechert surface for this test (thesis 5.3.2, SPEC 11): ``k_inf`` in parallel with
    Maxwell arms ``arms: [{k, cd}, ...]``; relaxation modulus ``E(t) = k_inf + sum k_i
    exp(-t/tau_i)``, ``tau_i = cd_i / k_i``; glassy ``Kg = k_inf + sum k_i``."""

    key = "toy_wiechert"
    name = "Wiechert"
    parameter_keys = ("k_inf", "k_1", "cd_1", "k_2", "cd_2")
    parameter_units: ClassVar[dict] = {"k_inf": "N/m", "k_1": "N/m", "cd_1": "kg/s", "k_2": "N/m", "cd_2": "kg/s"}
    parameter_labels: ClassVar[dict] = {k: k for k in parameter_keys}
    defaults: ClassVar[dict] = {"k_inf": 4.0, "arms": [{"k": 64.0, "cd": 1e-4}, {"k": 16.0, "cd": 1e-2}]}
    rules: ClassVar[dict] = {"k_inf": (positive, "a stiffness > 0 N/m")}
    quantities: ClassVar[dict] = {
        "k_g": surfaces.Quantity("N/m", "Kg", "$K_g$"),
        "tau_1": surfaces.Quantity("s", "tau_1", r"$\tau_1$"),
        "tau_2": surfaces.Quantity("s", "tau_2", r"$\tau_2$"),
        "k_inf": surfaces.Quantity("N/m", "k_inf", r"$k_\infty$"),
    }
    fit_bounds: ClassVar[dict] = {k: (1e-13, 1e6) for k in parameter_keys}
    theory_source = "Wiechert theory value (SPEC 11)"

    def parse_key(self, name, value):
        if name != "arms":
            return super().parse_key(name, value)
        if not isinstance(value, list) or len(value) != 2 or not all(isinstance(a, dict) for a in value):
            raise ConfigError(f"surface.arms: {value!r} is not allowed; expected a list of two {{k, cd}} mappings")
        return [{f: check(f"surface.arms[{i}].{f}", a.get(f), coerce(f"surface.arms[{i}].{f}", a.get(f), "float"),
                          (positive, "a value > 0")) for f in ("k", "cd")} for i, a in enumerate(value)]  # fmt: skip

    def theory(self, params):
        arms = params["arms"]
        return {"k_g": params["k_inf"] + sum(a["k"] for a in arms), "tau_1": arms[0]["cd"] / arms[0]["k"],
                "tau_2": arms[1]["cd"] / arms[1]["k"], "k_inf": float(params["k_inf"])}  # fmt: skip

    def kernel_arms(self, params):
        arms = params["arms"]
        return float(params["k_inf"]), np.array([a["k"] for a in arms]), np.array([a["cd"] for a in arms])

    def log_gradients(self, params):
        kg = self.theory(params)["k_g"]
        k1, k2 = (a["k"] for a in params["arms"])
        return {"k_g": (params["k_inf"] / kg, k1 / kg, 0.0, k2 / kg, 0.0), "tau_1": (0.0, -1.0, 1.0, 0.0, 0.0),
                "tau_2": (0.0, 0.0, 0.0, -1.0, 1.0), "k_inf": (1.0, 0.0, 0.0, 0.0, 0.0)}  # fmt: skip


@pytest.fixture
def toy_model():
    surfaces.register(ToyWiechert)
    yield surfaces.MODELS[ToyWiechert.key]
    del surfaces.MODELS[ToyWiechert.key]


def test_a_model_with_a_list_of_arms_plugs_in_through_the_registry(toy_model):
    test_surface_model_declares_keys_units_and_a_documented_equation(toy_model)
    test_theory_kernel_arms_and_gradients_are_consistent(toy_model)
    cfg = from_dict({"surface": {"model": "toy_wiechert", "arms": [{"k": 10, "cd": "1e-3"}, {"k": 5, "cd": 1}]}})
    assert cfg.surface.arms[0] == {"k": 10.0, "cd": 1e-3} and cfg.surface.hamaker == 0.2e-18
    assert cfg.to_dict()["surface"]["model"] == "toy_wiechert" and from_dict(cfg.to_dict()) == cfg
    assert hash(from_dict(cfg.to_dict())) == hash(cfg)  # configs stay hashable with a list-valued key
    with pytest.raises(ConfigError, match=r"surface.arms\[1\].cd: -1 is not allowed"):
        from_dict({"surface": {"model": "toy_wiechert", "arms": [{"k": 1, "cd": 1}, {"k": 1, "cd": -1}]}})
    # the study grid and the table schema follow the model
    st = expand({"surface": {"model": "toy_wiechert"}, "sweep": {"surface.k_inf": [2.0, 4.0]}})
    assert [p.config.surface.k_inf for p in st.points] == [2.0, 4.0]
    cols = result_columns([toy_model])
    assert "tau_1_err_pct" in cols and "k_inf_sigma_pct" in cols and "k0" not in cols
    # the kernel takes the arms as coefficient arrays: it simulates, and records every dashpot
    run = simulate(cfg.with_overrides({"numerics.record_cycles": 1, "numerics.print_step": 1e-9}))
    assert run.steady_ok and list(run.frame().columns)[7:9] == ["x_dashpot_1", "x_dashpot_2"]


# --------------------------------------------------------------------- extraction methods


@pytest.fixture(scope="module")
def cheap_run():
    """A cheap SLS run (dt 0.05 ns, PS 1 ns, 3 recorded periods, cd 1e-4 kg/s, 16:1)."""
    run = simulate(load(None, {"surface.k0": 64.0, "surface.cd": 1e-4, "numerics.dt": 0.05e-9,
                               "numerics.print_step": 1e-9, "numerics.record_cycles": 3,
                               "numerics.max_time": 0.002, "numerics.kp": 0.05, "numerics.ki": 0.03}))  # fmt: skip
    return run.frame(), run.metadata()


@pytest.mark.parametrize("key", list(METHODS))
def test_extraction_method_follows_the_convention(key, cheap_run):
    m = METHODS[key]
    assert m.key == key and m.title and m.description and "\n" not in m.description
    assert set(m.surface_models) <= set(surfaces.MODELS) and m.seconds_per_point > 0
    assert m.options({}) == m.options_default
    with pytest.raises(InputError, match=f"method {key!r} takes no option 'nope'"):
        m.options({"nope": 1})
    df, meta = cheap_run
    res = extract(df, meta, force="true", method=key)
    assert isinstance(res, ExtractionResult) and res.method == key and res.force == "true"
    model = surfaces.get(res.model)
    assert list(res.estimates)[: len(model.quantities)] == list(model.quantities)
    for name, e in res.estimates.items():
        if name in model.quantities:
            assert e.unit == model.quantities[name].unit
        if e.value is not None and e.theory:
            assert e.error_pct == pytest.approx(100 * (e.value - e.theory) / e.theory)  # signed
    out = to_json(res)
    json.dumps(out, allow_nan=False)
    assert {"force", "taps", "method", "info"} <= set(out)
    assert all({"value", "theory", "error_pct", "spread"} <= set(out[n]) for n in res.estimates)
    assert format_table(res).startswith(m.title)


def test_method_choices_come_from_the_registry():
    assert EXTRACT_KEYS["extract.method"][0] == tuple(METHODS)
    help_text = " ".join(CliRunner().invoke(app, ["extract", "--help"], terminal_width=300).output.split())
    for key in METHODS:
        assert key in help_text
    assert inspect.getdoc(type(METHODS["vetica"]))
