"""Coverage of the reported standard errors (extraction/uncertainty.py) over noisy replicas.

One simulated record (worked-example surface, 6 periods at a 1 ns print step, with
its approach segment), 50 replicas of white detector noise on z_tip and f_ts at each
of two levels, every method on each.  The 1-sigma a method reports is a statement
about the noise, so the reference is the method's own answer on the noise-free
record (its bias against the theory, e.g. VETICA's k_inf with the surface pull, is
a model error that no noise-driven error bar contains: the sanity checks of
extraction/sanity.py flag it instead).  Expected: the reference within +-2 sigma in
about 95 % of replicas; the binomial spread of a coverage over 50 replicas is ~3 %,
so the test accepts COVERAGE_MIN .. 1.0 (measured on 2026-11-27 after the fit's height term: 0.96 .. 1.00,
every method's k_g and k0 at 0.96-0.98, the fit's cd 0.98 at 1 pm + 0.1 nN, the rest at 1.00 -- conservative;
0.90 .. 1.00 on earlier versions; the table is in results/noise/README.md).
"""

import math

import numpy as np
import pytest

from vetica_cli.extraction import extract_many
from vetica_cli.simulation.config import load
from vetica_cli.simulation.simulate import simulate

METHODS = ("vetica", "vetica-prestress", "full")
QUANTITIES = ("tau_c", "k_g", "k0", "k_inf", "cd")
LEVELS = {"1pm+0.1nN": (1e-12, 1e-10), "0.5pm+0.3nN": (0.5e-12, 3e-10)}
REPLICAS = 50
COVERAGE_MIN = 0.86  # 90 % less 1.3 binomial standard errors of a coverage over 50 replicas


@pytest.fixture(scope="module")
def coverage():
    run = simulate(load(None, {"numerics.record_cycles": 6, "numerics.dt": 0.05e-9, "numerics.print_step": 1e-9}))
    meta = run.metadata()
    df0 = run.frame()[["t", "z_tip", "f_ts", "segment"]]
    ref = extract_many(df0, meta, "true", {m: {} for m in METHODS})
    out = {}
    for li, (level, (pn, fn)) in enumerate(LEVELS.items()):
        rng = np.random.default_rng([18, li])
        hits = {(m, q): [] for m in METHODS for q in QUANTITIES}
        for _ in range(REPLICAS):
            df = df0.copy()
            df["z_tip"] += rng.normal(0.0, pn, len(df))
            df["f_ts"] += rng.normal(0.0, fn, len(df))
            res = extract_many(df, meta, "true", {m: {} for m in METHODS})
            for m in METHODS:
                for q in QUANTITIES:
                    e, v0 = res[m].estimates[q], ref[m].estimates[q].value
                    ok = e.value is not None and e.sigma is not None and math.isfinite(e.sigma)
                    hits[(m, q)].append(ok and abs(e.value - v0) <= 2.0 * e.sigma * abs(e.value))
        out[level] = {k: float(np.mean(v)) for k, v in hits.items()}
        print(level, {f"{m}/{q}": v for (m, q), v in out[level].items()})  # pytest -s: the coverage table
    return out


@pytest.mark.slow
@pytest.mark.parametrize("level", list(LEVELS))
def test_two_sigma_covers_the_noise_free_answer(coverage, level):
    cov = coverage[level]
    low = {k: v for k, v in cov.items() if not (COVERAGE_MIN <= v <= 1.0)}
    assert not low, f"coverage outside [{COVERAGE_MIN}, 1]: {low}"


@pytest.mark.parametrize("rho, low, high", [(0.0, 0.93, 0.995), (0.3, 0.90, 0.99), (0.6, 0.84, 0.99)])
def test_the_per_tap_standard_error_widens_with_the_taps_serial_correlation(rho, low, high):
    """The default per-tap standard error (:meth:`Spread.serial_factor`) on nine values of a lag-one
    autoregression with correlation ``rho`` (unit innovations, stationary start), 4000 draws (seed
    fixed): +-2 sigma of the mean covers the process mean in ``low..high`` of them (binomial spread of
    4000 draws +-0.007).  Measured: 0.973, 0.928, 0.862 with the factor; 0.955, 0.866, 0.694 without.
    Independent values keep their plain t-scaled error (the factor only widens); correlated ones (the
    cantilever's slow thermal motion from tap to tap) need it, and nine values measure a strong
    correlation only roughly (at 0.6 the coverage stays under the 0.90 claimed)."""
    from vetica_cli.extraction.result import Spread, t_factor

    rng = np.random.default_rng(20261127)
    n, draws = 9, 4000
    hit = plain = 0
    for _ in range(draws):
        e = rng.normal(size=n)
        v = np.empty(n)
        v[0] = e[0] / math.sqrt(1.0 - rho * rho)
        for i in range(1, n):
            v[i] = rho * v[i - 1] + e[i]
        sp = Spread.of(v)
        se = sp.std / math.sqrt(n) * t_factor(n)
        hit += abs(sp.mean) <= 2.0 * se * sp.serial_factor()
        plain += abs(sp.mean) <= 2.0 * se
    assert low <= hit / draws <= high, hit / draws
    if rho > 0:
        assert plain / draws < 0.90 and hit - plain > 0.05 * draws, (plain / draws, hit / draws)
