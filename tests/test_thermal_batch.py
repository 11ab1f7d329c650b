"""Several thermal-noise replicas advanced in one kernel call (``brownian_steps_batch``, the
all-fine recording of ``numerics.integrator: verlet``; the hybrid recording, ``brownian_hybrid``,
advances one replica a call with its own generator, and is held to the same claims).

The batch changes only the order in which the CPU meets the replicas' steps, never a
replica's arithmetic (the same operations in the same order, no fastmath) nor its
generator's draws (kick, then per period the cantilever's and the paddle's forces, then the
approach window's free motion).  So the claim is bit-identity, and every comparison here is
``np.array_equal``: any tolerance would hide a reordered sum or a skipped draw.
"""

import dataclasses

import numpy as np
import pytest

from vetica_cli.core import session
from vetica_cli.core import thermal as kernel
from vetica_cli.core.tapping import COLUMNS
from vetica_cli.simulation import simulate as S
from vetica_cli.simulation import thermal
from vetica_cli.simulation.config import load

# short records at a coarse print step (the worked example's point: one tap a period, so contacts)
FAST = {"numerics.temperature": 300.0, "numerics.record_cycles": 2, "numerics.print_step": 0.5e-9}
SEEDS = (1, 7, 123456)


@pytest.fixture(scope="module", params=[("sls", "verlet"), ("wiechert", "verlet"), ("sls", "hybrid"),
                                        ("wiechert", "hybrid")], ids="-".join)  # fmt: skip
def point(request):
    """``(cfg, run, kern, s0, d)``: the noise-free orbit of the default SLS point or of the two-arm
    Wiechert surface of configs/wiechert.yaml, solved once, with either integrator (``verlet``: the
    thermal recording in fine steps all the way, ``brownian_steps`` and its batch twin; ``hybrid``:
    exact far steps with the sampled noise, ``brownian_hybrid``)."""
    surface, integrator = request.param
    cfg = load(None if surface == "sls" else "configs/wiechert.yaml", {**FAST, "numerics.integrator": integrator})
    run, kern, s0, d = S.noise_free_point(cfg)
    assert kern.n_arms == (1 if surface == "sls" else 2)
    assert kern.setup.hybrid == (integrator == "hybrid")
    return cfg, run, kern, s0, d


def _at(cfg, **numerics):
    return dataclasses.replace(cfg, numerics=dataclasses.replace(cfg.numerics, **numerics))


def _rng(cfg, seed):
    """The thermal generator of ``cfg`` at ``numerics.noise_seed = seed``."""
    return thermal.generator(_at(cfg, noise_seed=seed))


def _contact_samples(rec, a0):
    """Samples recorded in contact (``X = z_tip - a0``)."""
    return int(np.sum(np.abs(rec[:, 1] - rec[:, 6] - a0) < 1e-6 * a0))


def _record_with_normal_draws(kern, s0, cfg, d, rng):
    """The recording as it was drawn before the batch: per period ``rng.normal(0, sig, nt)`` for
    the cantilever, then for the paddle, the forces handed to ``brownian_steps``."""
    st = kern.setup
    p, a, emi = kern.coef[0], kern.coef[1], kern.coef[2]
    s = np.array(s0, float).copy()
    thermal.equipartition_kick(s, cfg, d, rng)
    sig1, sig2 = (thermal.step_sigma(m, k, q, cfg.numerics.temperature, st.dt) for (m, k, q) in thermal.modes(cfg, d))
    buf = np.zeros((d.n_steady, 7 + kern.n_arms))
    pos, origin = -1, 0
    for cyc in range(thermal.SETTLE_CYCLES + cfg.numerics.record_cycles):
        if cyc == thermal.SETTLE_CYCLES:
            pos, origin = 0, session.step_index(s)
        fb1 = rng.normal(0.0, sig1, kern.nt)
        fb2 = rng.normal(0.0, sig2, kern.nt)
        pos = kernel.brownian_steps(s, fb1, fb2, p, a, emi, buf, st.stride, origin, pos)
    return buf[:pos]


def test_standard_normal_scaled_in_the_kernel_is_the_normal_draw():
    """``0.0 + s * standard_normal(n, out=...)`` equals ``normal(0, s, n)`` from the same stream,
    element for element (numpy computes ``loc + scale * z``), -0.0 included: the kernel's scaling
    gives the forces the generator gave before, so bit-identity is the right test."""
    cfg = load(None, FAST)
    for seed in SEEDS:
        s = 3.7e-11
        ref = _rng(cfg, seed).normal(0.0, s, 100_000)
        z = np.empty(100_000)
        _rng(cfg, seed).standard_normal(100_000, out=z)
        got = 0.0 + s * z
        assert np.array_equal(ref, got) and np.array_equal(np.signbit(ref), np.signbit(got))


def test_thermal_record_is_the_record_drawn_with_normal(point):
    """``thermal_record`` (standard-normal draws into reused buffers, scaled in the kernel) gives bit
    for bit the record of per-period ``rng.normal`` forces handed to ``brownian_steps`` as they are
    (as the recording drew them before), and leaves the generator where that left it: the single
    path (``simulate``) draws the same forces as before."""
    cfg, run, kern, s0, d = point
    if kern.setup.hybrid:
        pytest.skip("the hybrid recording draws its forces in the kernel, fine and far steps alike")
    for seed in SEEDS:
        r1, r2 = _rng(cfg, seed), _rng(cfg, seed)
        got = thermal.thermal_record(kern, s0, cfg, d, r1)
        ref = _record_with_normal_draws(kern, s0, cfg, d, r2)
        assert got.shape == ref.shape == (d.n_steady, 7 + kern.n_arms)
        assert np.array_equal(got, ref)
        assert r1.standard_normal() == r2.standard_normal()  # the same draws consumed


def test_batched_records_equal_one_at_a_time(point):
    """``thermal_records`` of several replicas (``brownian_steps_batch``: three seeds, and the
    replica-set reference at 1e-9 K, a different force scale, in the same batch) equals each
    replica's ``thermal_record`` alone (``brownian_steps``, the one-replica kernel), bit for bit,
    in records with contacts (the separation and contact branches differ between replicas), and
    leaves each generator where the single recording leaves it: the two kernels' arithmetic is
    held to be the same."""
    cfg, run, kern, s0, d = point
    cfgs = [_at(cfg, noise_seed=s) for s in SEEDS] + [_at(cfg, temperature=S.REFERENCE_TEMPERATURE)]
    seeds = list(SEEDS) + [99]
    rngs = [_rng(cfg, s) for s in seeds]
    batch = thermal.thermal_records(kern, s0, cfgs, d, rngs)
    for c, seed, rng, rec in zip(cfgs, seeds, rngs, batch):
        alone_rng = _rng(cfg, seed)
        alone = thermal.thermal_record(kern, s0, c, d, alone_rng)
        assert rec.shape == alone.shape == (d.n_steady, 7 + kern.n_arms)
        assert np.array_equal(rec, alone)
        assert rng.standard_normal() == alone_rng.standard_normal()
        assert _contact_samples(rec, kern.setup.a0) > 10  # taps recorded
    assert not np.array_equal(batch[0], batch[1])  # the replicas are not one another


def test_replicas_and_replica_set_equal_one_at_a_time(point, monkeypatch):
    """``replicas`` and ``replica_set`` (thermal recordings :data:`THERMAL_BATCH` at a time; five
    runs, so a full group and a remainder) give every run's records (steady, approach with its
    thermal motion, detector noise) and thermal metadata bit for bit as with one replica per
    kernel call, the path ``simulate`` takes."""
    cfg, run, kern, s0, d = point
    batched = S.replicas(cfg, [3, 4, 5, 6, 8]), S.replica_set(cfg, 4)
    monkeypatch.setattr(S, "THERMAL_BATCH", 1)
    single = S.replicas(cfg, [3, 4, 5, 6, 8]), S.replica_set(cfg, 4)
    runs_b = batched[0] + [batched[1][0]] + batched[1][1]
    runs_s = single[0] + [single[1][0]] + single[1][1]
    ia = COLUMNS.index("z_tip")
    for rb, rs in zip(runs_b, runs_s, strict=True):
        assert np.array_equal(rb.steady, rs.steady)
        assert np.array_equal(rb.approach, rs.approach)
        assert rb.info["thermal"] == rs.info["thermal"]
    assert not np.array_equal(runs_b[0].approach[:, ia], run.approach[:, ia])  # the approach got its noise
    assert not np.array_equal(runs_b[0].steady, runs_b[1].steady)
