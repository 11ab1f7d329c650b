"""The tap methods' compiled pass against the Python path it replaces.

The pass measures a record's taps, stage 1b's slopes and contacts once (kept on the record),
runs stage 2 over every tap in one compiled call and the pre-stress fixed point of stages 1b and 2
compiled, and the error bars and checks re-run only the stages that move with Z1 or Kg.  References:

* ``tests/data/tap_pass_reference.json``: the estimates, relative sigmas and flags of the Python
  path before the compiled pass (git ad810cf; ``scripts/tap_pass_reference.py`` says how it was
  written) on the extraction bench's pixel records (4 periods at 1 ns; stiff and soft SLS,
  noise-free and at 300 K; true and reconstructed force); the 300 K entries since rewritten by the
  compiled pass of the version that changed those records (the noisy kernel's surface rule) and
  their band term (the narrower bands' noise), and again by the version whose error bars carry stage 1b's
  contact-location term (the stiff record's k_g sigma 2.79 -> 2.83 %; values unchanged), and by the
  version whose whole-cycle fit frees the start state on an F test (the soft record's reconstructed-force
  band correction, read on the referee's surface: tau_c +1.9 %), and by the version whose thermal
  recording takes exact far steps (the records' noise drawn anew), and by the version whose records drop
  the approach's first samples to a length the FFT is fast on (the stiff record's reconstructed-force
  tau_c +0.22 %), and by the version whose band term tests the record's step against the noise measured on
  the taps (the stiff record's reconstructed-force sigmas: vetica-prestress's k_g 2.05 -> 2.23 %, values and
  flags unchanged), and by the version whose Kg term is a central difference over +-1 sigma (the 300 K
  reconstructed-force sigmas of k_r, k_inf, k0, cd, tau_r by up to 25 %, the soft record's true-force k_inf,
  -8 % off, no longer flagged; values unchanged), and by the version whose Z1 is the first contact's
  approach-side well (the soft records' entries, noise-free too: their Z1 448 -> 403 pm, the pull-off well
  replaced by the snap-in; true-force tau_c +32.4 -> +28.9 %, k_inf -8.8 -> -6.5 %): a regression reference
  there, not the Python path's;
* the same functions on the same record with the Python loops (a stage 1 measured without the
  record's times carries no contacts, and the stages then run tap by tap in Python), and whole
  re-runs of the method at the moved Z1 and Kg.
"""

import dataclasses
import json
import math
from pathlib import Path

import pytest

from vetica_cli.extraction import extract, get
from vetica_cli.extraction.record import build_record
from vetica_cli.extraction.vetica import measure_stage1, vetica
from vetica_cli.extraction.vetica_prestress import vetica_prestress
from vetica_cli.extraction.methods.tapchecks import STAGE2

REFERENCE = Path(__file__).parent / "data" / "tap_pass_reference.json"
RTOL = 1e-3  # the compiled pass's agreement with the Python path, relative
SIGMA_FLOOR = 1e-4  # relative sigmas below this are the pre-stress fixed point's tolerance (1e-9) over the error
# bars' step: their last digits are rounding in both paths (a k_g sigma of 9e-7 moves by 2e-8), not compared


def _record(name: str):
    """The run table and metadata of the reference's record ``name`` (its config overrides)."""
    from vetica_cli.simulation.config import load
    from vetica_cli.simulation.simulate import simulate

    run = simulate(load(None, json.loads(REFERENCE.read_text())["records"][name]))
    return run.frame(), run.metadata()


@pytest.fixture(scope="module")
def reference():
    return json.loads(REFERENCE.read_text())["estimates"]


@pytest.mark.parametrize("name", ["stiff", "soft", "stiff 300 K", "soft 300 K"])
def test_tap_methods_equal_the_python_path_on_pixel_records(reference, name):
    df, meta = _record(name)
    for key, ref in reference[name].items():
        force, method = key.split("/")
        res = extract(df, meta, force=force, method=method)
        for q, (value, sigma, identifiable) in ref.items():
            e = res.estimates[q]
            where = f"{name}, {key}, {q}"
            if value is None:
                assert e.value is None, where
                continue
            assert e.value == pytest.approx(value, rel=RTOL), where
            if e.identifiable != identifiable:  # since the reference: a flagged stage's dependents judged by its
                # error times their gradient (tapchecks.stage_dependents); only such a flag may have gone
                stage_flagged = any(res.estimates[s].identifiable is False for s in ("tau_c", "k_g"))
                assert identifiable is False and q in STAGE2 and stage_flagged, where
            if sigma is not None and math.isfinite(sigma) and sigma > SIGMA_FLOOR:
                assert e.sigma == pytest.approx(sigma, rel=RTOL), where
            elif sigma is not None and not math.isfinite(sigma):
                assert not math.isfinite(e.sigma), where


@pytest.fixture(scope="module")
def soft_record():
    df, meta = _record("soft")
    return build_record(df, meta, "reconstructed", tap_windows=True)


def test_compiled_stage2_equals_the_per_tap_loop(soft_record):
    """VETICA with its contacts (stage 2 in one compiled call) against the same stage 1 without
    them (stage 2 tap by tap): the same solver on the same samples, equal to rounding."""
    r = soft_record
    loop = vetica(r.t, r.z, r.f, r.z1, stage1=measure_stage1(r.z, r.f, 10, r.taps))
    compiled = vetica(r.t, r.z, r.f, r.z1, stage1=measure_stage1(r.z, r.f, 10, r.taps, t=r.t))
    for q, v in loop.values.items():
        assert compiled.values[q] == pytest.approx(v, rel=1e-12, abs=0.0), q


@pytest.mark.parametrize("mode", ["adhesion", "creep", "fit"])
def test_compiled_prestress_fixed_point_equals_the_python_loop(soft_record, mode):
    """The pre-stress fixed point compiled against its Python loop: both stop where Kg and Kr move
    by less than 1e-9 relative, so they agree to well within 1e-8 (the line fit of stage 1b summed in
    another order moves the last digits only)."""
    r = soft_record
    loop = vetica_prestress(r.t, r.z, r.f, r.z1, prestress=mode, stage1=measure_stage1(r.z, r.f, 10, r.taps))
    compiled = vetica_prestress(r.t, r.z, r.f, r.z1, prestress=mode, stage1=measure_stage1(r.z, r.f, 10, r.taps, t=r.t))
    for q, v in loop.values.items():
        assert compiled.values[q] == pytest.approx(v, rel=1e-8, abs=0.0), (mode, q)


@pytest.mark.parametrize("method", ["vetica", "vetica-prestress"])
def test_error_bar_reruns_equal_whole_runs(soft_record, method):
    """The error bars' re-runs at Z1 +- 10 pm and at stage 1b's slopes scaled by 1 +- 1 % (only the
    stages that move, from the taps measured once) give what a whole run at those inputs gives:
    the same stages on the same samples, equal to rounding."""
    m = get(method)
    opts = m.options({})
    for z1, scale in ((soft_record.z1 + 1e-11, None), (soft_record.z1 - 1e-11, None), (None, 1.01), (None, 0.99)):
        moved = m.moved(soft_record, opts, z1=z1, kg_scale=scale)
        rec = soft_record if z1 is None else dataclasses.replace(soft_record, z1=z1, memo={})
        whole = m.run(rec, opts if scale is None else {**opts, "kg_scale": scale}).estimates
        for q, e in whole.items():
            assert moved[q].value == pytest.approx(e.value, rel=1e-12, abs=0.0), (z1, scale, q)
