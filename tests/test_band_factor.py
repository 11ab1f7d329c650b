"""The band correction's limit, which keeps a wrong whole-cycle fit from going out unflagged.

A correction by more than ``BAND_FACTOR_MAX`` (2x) either way is not divided out and is trusted to no
better than its own size.  Where it came from: a 300 K ``lab`` record of a 239:7.4 N/m surface (held-out
draw 34, material 5, replica 0: the draw's one silently wrong result) whose fit read k_g 159 N/m on the
record; the model's band said -99.9 % and the answer went out as 1.5e5 N/m at a 1-sigma of 29 %,
unflagged (truth 246 N/m).  With the fit's kernels compiled without contraction that replica's fit ends
elsewhere, flagged: the test gives the band term's verdict to an extraction instead.
"""

import math

import pytest

from vetica_cli.extraction import extract_many
from vetica_cli.extraction.uncertainty import BAND_FACTOR_MAX, beyond_factor, correctable
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import simulate

def test_a_band_correction_beyond_a_factor_of_two_is_not_trusted_below_its_size():
    assert BAND_FACTOR_MAX == 2.0
    assert correctable(-0.4) and correctable(0.9) and correctable(-0.5) and correctable(1.0)
    assert not correctable(-0.51) and not correctable(1.01) and not correctable(-1.0) and not correctable(math.nan)
    out = beyond_factor({"a": -0.999, "b": -0.35, "c": 5.3e5, "d": -1.0}, {"a": 0.0, "b": 0.01, "c": 2.0, "d": 1.6})
    assert out == {"a": 0.999, "b": 0.01, "c": 5.3e5, "d": 1.6}


def test_a_band_correction_beyond_a_factor_of_two_is_flagged_and_not_divided_out(monkeypatch):
    """The band term's verdict on one quantity beyond 2x (k_g, -99.9 % as the lab record's model said) and one
    within (k0, +30 %), given to a real extraction: the first keeps the record's own value with a sigma of its
    bias's size and the reason says it was not corrected; the second is divided by 1.3."""
    import vetica_cli.extraction.uncertainty as unc

    run = simulate(load(None, {"numerics.record_cycles": 4, "numerics.print_step": 1e-9}))
    plain = extract_many(run.frame(), run.metadata(), "true", {"full": {}})["full"]
    bias = {"k_g": -0.999, "k0": 0.3}
    band = {"source": "model", "bias": bias, "sigma": beyond_factor(bias, {"k_g": 0.0, "k0": 0.01}), "cutoff_hz": 1.75e6}
    monkeypatch.setattr(unc, "band_term", lambda *a, **k: dict(band))
    got = extract_many(run.frame(), run.metadata(), "true", {"full": {}})["full"]
    kg, k0 = got.estimates["k_g"], got.estimates["k0"]
    assert kg.value == pytest.approx(plain.estimates["k_g"].value, rel=1e-12)  # 1e3 x it if divided out
    assert kg.sigma >= 0.999 and kg.identifiable is False
    assert "beyond 2x: not corrected" in kg.reason, kg.reason
    assert k0.value == pytest.approx(plain.estimates["k0"].value / 1.3, rel=1e-12)
    assert k0.sigma == pytest.approx(math.hypot(plain.estimates["k0"].sigma, 0.01), rel=1e-9)
    assert "band" not in (k0.reason or ""), k0.reason
