"""Shared fixtures: the reference runs simulated once per test session.

The thesis worked example (tables 2-4, the defaults) is what most physics tests check
against, with the surface pull on (the default) and off (the setting of the worked-example
bounds).  Each is simulated once per session here (about 4 s each on the project machine,
warm) instead of once in each of eight modules; a module takes a deep copy
(:func:`worked_example`), so no test can change another module's run.
"""

import copy

import pytest

from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import simulate


@pytest.fixture(scope="session")
def _worked_runs():
    return {}


@pytest.fixture(scope="session")
def worked_example(_worked_runs):
    """``worked_example(pull=True)``: a copy of the worked example's run (the defaults; ``pull``:
    ``surface.vdw_on_surface``), simulated at its first use in the session."""

    def get(pull: bool = True):
        if pull not in _worked_runs:
            run = simulate(load(None, {} if pull else {"surface.vdw_on_surface": False}))
            assert run.steady_ok, "the worked example must reach its periodic state"
            _worked_runs[pull] = run
        return copy.deepcopy(_worked_runs[pull])

    return get
