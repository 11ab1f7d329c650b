"""Every registered surface model and extraction method follows the convention of its
registry (vetica_cli/surfaces/base.py, vetica_cli/extraction/base.py), and the Wiechert
surface -- a model with a non-scalar config key, its list of arms -- plugs in
through the registry alone: config, arm keys, sweeps, table schema, simulation.

References: the SLS worked example (thesis tables 2-4) for the theory values; the
convention itself for everything else."""

from __future__ import annotations

import inspect
import json
import math
import re

import numpy as np
import pytest
from typer.testing import CliRunner

from vetica_cli import surfaces
from vetica_cli.cli import app
from vetica_cli.errors import ConfigError, InputError
from vetica_cli.extraction import METHODS, ExtractionResult, extract
from vetica_cli.extraction.format import format_table, to_json
from vetica_cli.simulation.config import Config, from_dict, load
from vetica_cli.simulation.simulate import simulate
from vetica_cli.study.grid import EXTRACT_KEYS, expand
from vetica_cli.rows.schema import result_columns
from vetica_cli.testing import check_method, check_surface_model

MODELS = list(surfaces.MODELS.values())


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.key)
def test_surface_model_declares_keys_units_and_a_documented_equation(model):
    """The public convention check (vetica_cli.testing) on the model's declarations: keys,
    units, labels, quantities, fit bounds, its equation in the docstring and its references
    as data (``references = (...)``, not a word looked for in the docstring)."""
    assert type(surfaces.MODELS[model.key]) is type(model)  # registered (or specialised)
    check_surface_model(model, declarations_only=True)


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.key)
def test_surface_model_runs_the_whole_convention(model):
    """Theory, kernel arms, gradients, config round trip and a short run of its own kernel."""
    check_surface_model(model)


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.key)
def test_surface_section_is_validated_by_its_model(model):
    """A value the model's rule refuses is a one-line ConfigError naming surface.<key>; the
    section round-trips through the config."""
    for name, (pred, allowed) in model.rules.items():
        if not pred(-1.0):
            with pytest.raises(ConfigError, match=rf"surface\.{name}: -1.0 is not allowed; expected {re.escape(allowed)}"):
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


# --------------------------------------------------------------------- the Wiechert surface


def test_wiechert_model_specialises_to_its_arms():
    """A model with a list of arms follows the convention for any number of arms:
    parameters k_inf, k_1, cd_1, ..., theory Kg = k_inf + sum k_i (the two-arm example:
    4 + 64 + 32 = 100 N/m), tau_i = cd_i/k_i, and from_arms inverts kernel_arms."""
    generic = surfaces.get("wiechert")
    params = generic.parse({"arms": [{"k": 1, "cd": 2}, {"k": 3, "cd": 4}, {"k": 5, "cd": 6}]})
    three = generic.for_params(params)
    assert three.parameter_keys == ("k_inf", "k_1", "cd_1", "k_2", "cd_2", "k_3", "cd_3")
    test_surface_model_declares_keys_units_and_a_documented_equation(three)
    th = three.theory(params)
    assert list(th) == list(three.quantities) and th["k_g"] == 4.0 + 1 + 3 + 5 and th["tau_3"] == 6 / 5
    assert generic.theory(generic.parse({}))["k_g"] == 100.0
    grads = three.log_gradients(params)
    assert all(len(g) == 7 for g in grads.values()) and grads["tau_2"] == (0, 0, 0, -1, 1, 0, 0)
    assert three.from_arms(*three.kernel_arms(params)) == params
    assert three is generic.for_params(params) and generic.with_arms(2) is generic  # one instance per arm count


def test_wiechert_section_and_arm_keys():
    """The issue's schema: a list of arms; an arm's field is the key surface.arms.<i>.<k|cd>
    (1-based, as the result names k_1, cd_1) in --set, sweeps and one-line error messages."""
    cfg = from_dict({"surface": {"model": "wiechert", "arms": [{"k": 10, "cd": "1e-3"}, {"k": 5, "cd": 1}]}})
    assert cfg.surface.arms[0] == {"k": 10.0, "cd": 1e-3} and cfg.surface.hamaker == 0.2e-18
    assert cfg.to_dict()["surface"]["model"] == "wiechert" and from_dict(cfg.to_dict()) == cfg
    assert hash(from_dict(cfg.to_dict())) == hash(cfg)  # configs stay hashable with a list-valued key
    assert getattr(cfg.surface, "arms.2.cd") == 1.0
    assert load(None, {"surface.model": "wiechert", "surface.arms.1.cd": 2e-3}).surface.arms[0]["cd"] == 2e-3
    bad = {
        r"surface.arms.2.cd: -1 is not allowed; expected a dashpot coefficient in \[1e-18, 1e\+10\] kg/s": [{"k": 1, "cd": 1}, {"k": 1, "cd": -1}],
        r"surface.arms.1.k: 'x' is not allowed; expected a finite number": [{"k": "x", "cd": 1}],
        r"surface.arms.1: \{'k': 1\} has no 'cd'": [{"k": 1}],
        r"unknown key 'surface.arms.1.tau'; allowed in an arm: k, cd": [{"k": 1, "cd": 1, "tau": 1}],
        r"surface.arms: \[\] is not allowed; expected a list of 1..8 arms": [],
        r"surface.arms: a list of 9 arms is not allowed; expected a list of 1..8 arms": [{"k": 1, "cd": 1}] * 9,
    }  # fmt: skip
    for message, arms in bad.items():
        with pytest.raises(ConfigError, match=message):
            from_dict({"surface": {"model": "wiechert", "arms": arms}})
    with pytest.raises(ConfigError, match=r"surface.arms.3.cd: no arm 3; the surface has 2 arm\(s\)"):
        load(None, {"surface.model": "wiechert", "surface.arms.3.cd": 1.0})
    with pytest.raises(ConfigError, match=r"unknown key 'surface.arms.1.cd'; allowed in surface: model, k_inf, k0"):
        load(None, {"surface.arms.1.cd": 1.0})  # the SLS has no arms list


def test_wiechert_study_grid_schema_and_simulation():
    """The study grid sweeps an arm's key, the table schema follows the arms, a method that
    cannot extract the surface is refused before any work, and the kernel simulates the
    arms and records every dashpot."""
    study = {
        "surface": {"model": "wiechert"},
        "extract": {"method": "full"},
        "sweep": {"surface.arms.2.cd": [1e-4, 1e-3]},
    }
    st = expand(study)
    assert [p.config.surface.arms[1]["cd"] for p in st.points] == [1e-4, 1e-3]
    assert [p.values["surface.arms.2.cd"] for p in st.points] == [1e-4, 1e-3]
    cols = result_columns([p.config.surface.surface_model for p in st.points[:1]])
    assert {"k_2_err_pct", "cd_2_sigma_pct", "tau_1_theory", "k_inf_err_pct"} <= set(cols) and "k0" not in cols
    with pytest.raises(ConfigError, match="extract.method 'vetica' cannot extract a Wiechert surface with 2 Maxwell "
                                          "arms .*; expected extract.method: full"):  # fmt: skip
        expand({**study, "extract": {"method": "vetica"}})
    with pytest.raises(ConfigError, match=r"sweep: unknown key 'surface.arms.x.cd'; allowed: .*surface.arms.<i>.cd"):
        expand({**study, "sweep": {"surface.arms.x.cd": [1.0]}})
    with pytest.raises(ConfigError, match=r"point 0 \(surface.arms.3.k=1.0\): surface.arms.3.k: no arm 3"):
        expand({**study, "sweep": {"surface.arms.3.k": [1.0]}})
    cfg = from_dict({"surface": {"model": "wiechert"}})
    run = simulate(cfg.with_overrides({"numerics.record_cycles": 1, "numerics.print_step": 1e-9}))
    assert run.steady_ok and list(run.frame().columns)[7:9] == ["x_dashpot_1", "x_dashpot_2"]
    assert {"dashpot_dissipation_1", "dashpot_dissipation_2"} <= set(run.energy)


# --------------------------------------------------------------------- extraction methods


@pytest.mark.parametrize("key", list(METHODS))
def test_extraction_method_follows_the_convention(key):
    """The public convention check (vetica_cli.testing.check_method) on a record of a surface
    model the method declares."""
    check_method(METHODS[key])


def test_method_choices_come_from_the_registry():
    assert EXTRACT_KEYS["extract.method"][0] == tuple(METHODS)
    help_text = " ".join(CliRunner().invoke(app, ["extract", "--help"], terminal_width=300).output.split())
    for key in METHODS:
        assert key in help_text
    assert inspect.getdoc(type(METHODS["vetica"]))


def test_every_method_declares_its_settable_options_with_type_unit_and_help():
    """The registry, not the CLI, holds each method's options: every declared
    option is one the method takes (its default from the declaration), a settable one typed,
    each with help."""
    from vetica_cli.extraction import METHODS

    for key, m in METHODS.items():
        for o in m.option_specs:
            assert m.options_default[o.name] == o.default and o.help, (key, o)
            assert o.type in (("int", "float", "bool", "str") if o.settable else ("int", "float", "bool", "str", "any"))
            assert isinstance(o.unit, str)
