"""Coverage of the whole-cycle fit's standard errors under thermal noise (numerics.temperature).

One noise-free orbit (worked-example surface, 6 periods at a 1 ns print step, dt 0.05 ns,
with the approach segment), 50 thermal recordings from it at 300 K (simulate.replicas: one
noise seed each, the orbit solved once), the fit on the true force of each, as recorded
and with white detector noise (1 pm on z_tip, 0.1 nN on f_ts) added: two noise levels.

Reference: the method's answer on the noise-free record made by the same recording path,
numerics.temperature = 1e-9 K (the thermal kernel with no noise to speak of).  Not the
0 K record: that one comes from the fine kernel, and the recording kernel alone moves the
fit's k_g and k0 by ~0.02 % (measured; ~4x their thermal error bar) -- a discretisation
difference of the simulator, not noise, which no error bar of the noise can contain
(results/noise/README.md has the coverage against both references).

Expected, with the detector's noise: the reference within +-2 sigma in ~95 % of replicas.  With
50 replicas the binomial standard error of a coverage is ~3 %, so a calibrated error bar passes
COVERAGE_MIN = 0.86 (95 % less 3 standard errors) and fails it when it is short by ~30 %.
Without it (the true force of a thermal record: no measurement noise at all, a record only the
simulator has) the fit's answer is the noise-free one to its kernel's own error: within SHIFT_MAX
(2e-5 relative; measured: at most 7.7e-6, tau_c) of the reference.  Since the fit steps the surface as the simulator does (2026-11-28)
its error bar there is 1.6e-6 relative and the replicas sit 1.4-1.8 of their spread (2e-6) from the
reference, so tau_c, k_inf and cd are covered in 0.58-0.70 only: what is left is the kernel's
error along the thermal path (the tip between samples), not noise, and the error bar is a claim
about noise; before, the held contact step's error (1e-4) set sigma 1.8-5.8x the scatter and
coverage 1.00.
Measured 2026-11-27 with this set-up: every quantity covered in 1.00 of the replicas
without detector noise (sigma 1.8-5.8 times the replicas' scatter, which is 3e-6 .. 5e-5 relative:
the fit's misfit floor on a true force, not noise) and in 0.96-1.00 with it (width 1.2-2.9; cd
10x); after the height term read on the steady taps (scripts/thermal_coverage.py's table, results/noise/README.md): 0.98-1.00
with it, width 1.2-2.7, cd 10x.  An earlier version's k_g and k0 were covered in 0.88 and 0.82 without detector noise and
held to a lower bound; no quantity needs one now.
"""

import math

import numpy as np
import pytest

from vetica_cli.extraction import extract_many
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import replicas

BASE = {"numerics.record_cycles": 6, "numerics.dt": 0.05e-9, "numerics.print_step": 1e-9}
TEMPERATURE = 300.0
REPLICAS = 50
DETECTOR = (1e-12, 1e-10)  # [m] on z_tip, [N] on f_ts
QUANTITIES = ("tau_c", "k_g", "k0", "k_inf", "cd")
COLUMNS = ["t", "z_tip", "f_ts", "segment"]
COVERAGE_MIN = 0.86
SHIFT_MAX = 2e-5  # relative: the thermal replicas' largest distance from the reference without detector noise


def _fit(df, meta):
    return extract_many(df[COLUMNS], meta, "true", {"full": {}})["full"].estimates


@pytest.fixture(scope="module")
def thermal_coverage():
    faint = replicas(load(None, {**BASE, "numerics.temperature": 1e-9}), [0])[0]
    ref = _fit(faint.frame(), faint.metadata())
    runs = replicas(load(None, {**BASE, "numerics.temperature": TEMPERATURE}), range(1, REPLICAS + 1))
    rng = np.random.default_rng(31)
    hits = {(level, q): [] for level in ("thermal", "thermal+detector") for q in QUANTITIES}
    shifts = {q: [] for q in QUANTITIES}
    for run in runs:
        df, meta = run.frame(), run.metadata()
        noisy = df.copy()
        noisy["z_tip"] += rng.normal(0.0, DETECTOR[0], len(df))
        noisy["f_ts"] += rng.normal(0.0, DETECTOR[1], len(df))
        for level, frame in (("thermal", df), ("thermal+detector", noisy)):
            est = _fit(frame, meta)
            for q in QUANTITIES:
                e, v0 = est[q], ref[q].value
                ok = e.value is not None and e.sigma is not None and math.isfinite(e.sigma)
                hits[(level, q)].append(ok and abs(e.value - v0) <= 2.0 * e.sigma * abs(e.value))
                if level == "thermal":
                    shifts[q].append(abs(e.value / v0 - 1.0) if e.value is not None else math.inf)
    out = {k: float(np.mean(v)) for k, v in hits.items()}
    print({f"{lv}/{q}": v for (lv, q), v in out.items()})  # pytest -s: the coverage table
    print({q: max(v) for q, v in shifts.items()})
    return out, {q: max(v) for q, v in shifts.items()}


@pytest.mark.slow
def test_two_sigma_covers_the_noise_free_answer_under_thermal_noise(thermal_coverage):
    coverage, shifts = thermal_coverage
    low = {k: v for k, v in coverage.items() if k[0] == "thermal+detector" and not COVERAGE_MIN <= v <= 1.0}
    assert not low, f"coverage outside [{COVERAGE_MIN}, 1]: {low}"
    far = {q: v for q, v in shifts.items() if not v < SHIFT_MAX}
    assert not far, f"without detector noise, farther than {SHIFT_MAX:g} from the noise-free answer: {far}"
