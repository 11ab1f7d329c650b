"""Shared fixtures: the reference runs simulated once per test session.

The thesis worked example (tables 2-4, the defaults) is what most physics tests check
against, with the surface pull on (the default) and off (the setting of the worked-example
bounds).  Each is simulated once per session here (about 4 s each on the project machine,
warm) instead of once in each of eight modules; a module takes a deep copy
(:func:`worked_example`), so no test can change another module's run.
"""

import copy

import numpy as np
import pytest

from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import simulate

_APPROX = pytest.approx
APPROX_ABS = 1e-12  # pytest.approx's absolute tolerance when none is given


def _approx_guarded(expected, rel=None, abs=None, nan_ok=False):
    """``pytest.approx`` that refuses a comparison its default absolute tolerance would decide:
    without ``abs=``, pytest adds 1e-12, and vetica's SI lengths, forces and energies (1e-27 ..
    1e-5) then compare at 1e-12 absolute, not at their relative tolerance -- 58 such calls could
    not fail (the free probe's equipartition among them) before they were given ``abs=0``.  A
    nonzero expected number whose relative tolerance is below 1e-12 absolute needs ``abs=``."""
    if abs is None and not isinstance(expected, (bool, np.bool_)):
        try:
            vals = np.abs(np.asarray(expected, dtype=float)).ravel()
        except (TypeError, ValueError):
            vals = np.array([])
        vals = vals[np.isfinite(vals) & (vals > 0)]
        r = 1e-6 if rel is None else float(rel)
        if vals.size and r * float(np.min(vals)) < APPROX_ABS:
            raise AssertionError(
                f"pytest.approx({float(np.min(vals)):.3g}, rel={r:g}) without abs=: its default absolute tolerance "
                f"{APPROX_ABS:g} decides the comparison; pass abs= (0 for a relative comparison)"
            )
    return _APPROX(expected, rel=rel, abs=abs, nan_ok=nan_ok)


pytest.approx = _approx_guarded  # before the test modules import it (conftest is imported first)


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
