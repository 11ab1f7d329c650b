"""The suite's guard on ``pytest.approx`` (tests/conftest.py): a comparison whose relative tolerance
is below pytest's default absolute one (1e-12) must say ``abs=``; otherwise it could not fail."""

import numpy as np
import pytest


def test_a_tiny_value_without_abs_is_refused():
    """4e-22 m^2 "within 5 %" without abs=: pytest's default 1e-12 would pass any value."""
    with pytest.raises(AssertionError, match="abs="):
        pytest.approx(4e-22, rel=0.05)
    with pytest.raises(AssertionError, match="abs="):
        pytest.approx(np.array([1.0, 3e-9]))  # default rel 1e-6: 3e-15 < 1e-12


def test_comparisons_the_default_does_not_decide_pass_through():
    assert 4.1e-22 != pytest.approx(4e-22, rel=0.01, abs=0)  # now it can fail
    assert 4.1e-22 == pytest.approx(4e-22, rel=0.05, abs=0)
    assert 1.0 + 1e-7 == pytest.approx(1.0)
    assert 1e-13 == pytest.approx(0.0)  # a zero expected: only an absolute tolerance means anything
    assert [1.0, 2.0] == pytest.approx([1.0, 2.0 + 1e-7])
