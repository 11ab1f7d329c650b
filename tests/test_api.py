"""The Python API (vetica_cli/api.py, docs/api.md): the commands' functions with the workers'
thread cap, giving the commands' results."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from threadpoolctl import threadpool_info
from typer.testing import CliRunner

from vetica_cli import api
from vetica_cli.batch.launch import one_thread
from vetica_cli.cli import app
from vetica_cli.errors import InputError

DATA = Path(__file__).parent / "data" / "afmformats"
FD = DATA / "fmt-jpk-fd_spot3-0192.jpk-force"


def blas_threads() -> list[int]:
    return [p["num_threads"] for p in threadpool_info() if p["user_api"] in ("blas", "openmp")]


def test_one_thread_caps_blas_and_restores_it():
    before = blas_threads()
    with one_thread():
        assert blas_threads() and set(blas_threads()) == {1}
    assert blas_threads() == before


def test_api_calls_run_capped(monkeypatch):
    """Inside an API call BLAS runs one thread (the fit's least squares); ``threads`` is checked."""
    seen = []
    import vetica_cli.curves.batch as batch

    real = batch.fit_files

    def spy(*a, **k):
        seen.append(set(blas_threads()))
        return real(*a, **k)

    monkeypatch.setattr(batch, "fit_files", spy)
    api.fit([FD], 5e-6)
    assert seen == [{1}]
    with pytest.raises(InputError, match="threads=0"):
        api.fit([FD], 5e-6, threads=0)


def test_api_fit_gives_the_command_table(tmp_path):
    out = tmp_path / "cli.parquet"
    res = CliRunner().invoke(app, ["fit", str(FD), "--tip-radius", "5e-6", "-o", str(out), "-q", "-j", "1"])
    assert res.exit_code == 0, res.output
    cli = pd.read_parquet(out)
    table = api.fit(FD, tip_radius=5e-6)
    np.testing.assert_allclose(table[["e0", "beta", "e_hertz"]].to_numpy(), cli[["e0", "beta", "e_hertz"]].to_numpy())
    assert table.attrs["vetica"]["units"]["e0"] == "Pa"


@pytest.mark.slow
def test_api_simulate_and_extract_from_a_dict():
    """A config given as a dict (derived keys resolved as in a file) is simulated and extracted;
    the result is the one ``extract`` gives on the run's table."""
    cfg = {"surface": {"k_inf": 4.0, "stiffness_ratio": 16, "cd": 1e-5},
           "numerics": {"dt": 0.05e-9, "record_cycles": 3, "print_step": 0.5e-9}}  # fmt: skip
    run = api.simulate(cfg)
    assert run.params["surface"]["k0"] == 64.0
    res = api.extract(run, force="true")
    again = api.extract((run.frame(), run.metadata()), force="true")
    assert res.estimates["k0"].value == again.estimates["k0"].value
