"""Every registered surface model runs from every command -- simulate, extract, sweep, scan
(when it supports scans), plot -- through the registries alone, with the cheapest method that
declares it and with every model-free method: a new model or method is covered by adding its
file and its registration line, without editing this test.

Cheap settings (dt 0.05 ns, print step 1 ns, 3 recorded periods; a 3 x 1 scan): the commands'
wiring and the tables' shape, not physics (the physics of each model and method is tested in
its own test file).  Reference: the convention itself."""

from __future__ import annotations

import json

import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from vetica_cli import surfaces
from vetica_cli.cli import app
from vetica_cli.extraction import METHODS
from vetica_cli.extraction.base import ModelFreeMethod

CHEAP = {"dt": 0.05e-9, "print_step": 1.0e-9, "record_cycles": 3}
MODEL_FREE = [k for k, m in METHODS.items() if isinstance(m, ModelFreeMethod)]


def cheapest_method(model_key: str) -> str:
    """The registered method with the smallest cost estimate that extracts ``model_key``."""
    able = [(m.seconds_per_point, k) for k, m in METHODS.items() if model_key in m.surface_models]
    return min(able)[1]


def swept_parameter(model) -> tuple[str, list]:
    """A scalar parameter of the model and two values of it (its default, and 2x)."""
    params = model.parse({})
    name = next(p for p in model.parameter_keys if isinstance(params.get(p), float))
    return f"surface.{name}", [params[name], 2.0 * params[name]]


def invoke(*args):
    res = CliRunner().invoke(app, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    return res.output


@pytest.mark.slow
@pytest.mark.parametrize("key", list(surfaces.MODELS))
def test_every_model_runs_from_every_command(key, tmp_path):
    model = surfaces.get(key)
    sets = [f"--set=numerics.{k}={v}" for k, v in CHEAP.items()]
    run = tmp_path / "run.parquet"
    invoke("simulate", "-q", "-o", run, f"--set=surface.model={key}", *sets)
    for method in dict.fromkeys([cheapest_method(key), *MODEL_FREE]):
        out = json.loads(invoke("extract", run, "--method", method, "--force", "true", "--json"))
        assert out["method"] == method
    assert "wrote" in invoke("plot", run, "-o", tmp_path / "run_figs")

    swept, values = swept_parameter(model)
    method = cheapest_method(key)
    study = {"name": "every", "surface": {"model": key}, "numerics": CHEAP, "extract": {"method": method},
             "sweep": {swept: values}}  # fmt: skip
    (tmp_path / "every.yaml").write_text(yaml.safe_dump(study))
    table = tmp_path / "every.parquet"
    invoke("sweep", tmp_path / "every.yaml", "-o", table, "-q", "-j", "1")
    df = pd.read_parquet(table)
    assert len(df) == 4 and set(df["method"]) == {method}
    invoke("plot", table, "-o", tmp_path / "sweep_figs")

    if not model.supports_key("scan"):
        return
    scan = {"name": "every_scan", "numerics": {**CHEAP, "approach_cycles": 1}, "extract": {"force": "reconstructed"},
            "scan": {"pixels": [3, 1], "size": [0.3e-6, 0.1e-6], "steady": "orbit", "methods": MODEL_FREE},
            "sample": {"background": {"height": 0.0},
                       "features": [{"shape": "rectangle", "corner": [0.1e-6, 0.0], "size": [0.1e-6, 0.1e-6],
                                     "height": 1.0e-9, "surface": {"model": key}}]}}  # fmt: skip
    (tmp_path / "scan.yaml").write_text(yaml.safe_dump(scan))
    out = tmp_path / "scan.parquet"
    invoke("scan", tmp_path / "scan.yaml", "-o", out, "-q", "-j", "1")
    df = pd.read_parquet(out)
    assert len(df) == 3 * len(MODEL_FREE) and "failed" not in set(df["status"]), df[["method", "status", "error"]]
    invoke("plot", out, "-o", tmp_path / "scan_figs")
