"""Thermal (Brownian) noise of the probe in the recorded periods (fluctuation-dissipation).

At ``numerics.temperature`` T > 0 each probe mode (stiffness k, mass m, quality
factor Q, angular resonance w0 = sqrt(k/m)) feels a white random force of one-sided
power spectral density ``S_F = 4 kB T m w0 / Q`` (fluctuation-dissipation); the
kernel draws it per fine step as a Gaussian of variance ``S_F / (2 dt)`` and, over a far
step of the hybrid integrator, as each mode's exact sampled Ornstein-Uhlenbeck increment
(:mod:`vetica_cli.core.thermal`).  A free mode then fluctuates with
``<z^2> = kB T / k`` (equipartition) and the Lorentzian spectrum
``S_z(f) = S_F |1/(k (1 - (w/w0)^2 + i w/(Q w0)))|^2``.

How this fits the noise-free steady state (the periodic steady state): the orbit solver (or the
transient) still finds the *noise-free* periodic orbit, and it stays the
reference every "steady" claim is about (the proof, the observables and the
energy balance are computed on it).  The recorded periods are then re-run with
the noise: from the orbit's state at the start of the recorded window, plus a
draw of each free mode's equilibrium fluctuation (``zc, zp`` with variance
``kB T/k``, ``vc, vp`` with ``kB T/m``: the stationary state of the noise the
oscillators would have accumulated over their ring-down times ``2Q/w0``, 32 and
21 drive periods for the default probe, far longer than any affordable
settling), ``SETTLE_CYCLES`` noisy periods are run unrecorded (the contact's
share of the dynamics settles in a few taps) and then ``numerics.record_cycles``
noisy periods are recorded at the print step, their times the real ones (the
window starts ``SETTLE_CYCLES`` periods after the noise-free one).  The first-
approach window gets the free probe's thermal motion added to ``zc`` and ``zp``
(the exact sampled Ornstein-Uhlenbeck oscillator: exact by superposition while
out of contact), and its ``f_ts`` the surface's response to that motion
(:func:`approach_response`): the force of the surface driven by the noisy tip
minus that driven by the noise-free tip, both by the prescribed-trajectory kernel
(:mod:`vetica_cli.core.prescribed`, the simulator's surface rules at its ``dt``).
Without it the record would put the first contact -- where Z1 is read -- at the
noise-free time while ``z_tip`` there carries the cantilever's thermal offset
(~20 pm at 300 K), an error no instrument has: the tip meets the surface where it
actually is.  The probe's own reaction to that change of force (each mode driven by it
from rest, :func:`forced_motion`) is added to ``zc`` and ``zp`` and the force recomputed,
twice: the paddle signal the force is reconstructed from then carries the contact where the
noisy tip makes it (without it the reconstructed approach put Z1's force minimum at the
noise-free time, and Z1 scattered by +-35 pm from replica to replica at 300 K, 0.5 ns,
against +-0.3 pm on the true force).

Seeded by ``numerics.noise_seed`` (the detector noise of
:mod:`.instrument` comes after and uses the same seed through its own generator).
"""

from __future__ import annotations

import math

import numpy as np

from ..core import prescribed, session, tapping
from ..core import thermal as kernel
from ..core.coefficients import L_H

KB = 1.380649e-23  # Boltzmann constant [J/K] (SI, exact)
SETTLE_CYCLES = 2  # noisy periods run before the recorded ones
_SEED_SALT = 0x7E57  # the thermal generator's stream differs from the detector noise's


def force_psd(m: float, k: float, q: float, temperature: float) -> float:
    """One-sided PSD of the Brownian force on a mode, ``S_F = 4 kB T m w0/Q`` [N^2/Hz]."""
    return 4.0 * KB * temperature * m * math.sqrt(k / m) / q


def step_sigma(m: float, k: float, q: float, temperature: float, dt: float) -> float:
    """RMS of the per-step Gaussian force, ``sqrt(S_F / (2 dt))`` [N]."""
    return math.sqrt(force_psd(m, k, q, temperature) / (2.0 * dt))


def displacement_psd(f, m: float, k: float, q: float, temperature: float):
    """One-sided PSD of a free mode's thermal displacement at frequency ``f`` [m^2/Hz]
    (the Lorentzian of the oscillator's transfer function)."""
    w0 = math.sqrt(k / m)
    r = 2 * np.pi * np.asarray(f, float) / w0
    return force_psd(m, k, q, temperature) / (k * k * ((1 - r * r) ** 2 + (r / q) ** 2))


def sampled_flow(m: float, k: float, q: float, temperature: float, h: float):
    """``(phi, cov)``: the exact transition of a free mode's thermal state ``(z, v)`` over an
    interval ``h`` (``phi = exp(A h)``) and the covariance of its noise increment,
    ``int_0^h exp(A s) Q exp(A^T s) ds`` with the Langevin force's intensity
    ``Q = diag(0, 2 c kB T/m^2)`` (which equals ``Sigma - phi Sigma phi^T`` with the
    equilibrium ``Sigma = diag(kB T/k, kB T/m)``), by Van Loan's block exponential: the
    difference form loses every digit when ``h`` is a small fraction of the period (the
    position variance grows as ``h^3``) and can turn indefinite."""
    from scipy.linalg import expm

    c = math.sqrt(k * m) / q
    a = np.array([[0.0, 1.0], [-k / m, -c / m]])
    qn = np.diag([0.0, 2.0 * c * KB * temperature / (m * m)])
    big = np.zeros((4, 4))
    big[:2, :2], big[:2, 2:], big[2:, 2:] = -a, qn, a.T
    e = expm(big * h)
    phi = e[2:, 2:].T
    cov = phi @ e[:2, 2:]
    return phi, 0.5 * (cov + cov.T)


def _sqrt_psd(cov: np.ndarray) -> np.ndarray:
    """A square root ``L`` with ``L L^T = cov`` of a positive semi-definite 2 x 2 covariance
    (eigenvalues below zero by round-off clipped to zero)."""
    w, v = np.linalg.eigh(cov)
    return v * np.sqrt(np.clip(w, 0.0, None))


def free_motion(rng, m, k, q, temperature, h, n) -> np.ndarray:
    """``n`` samples, ``h`` apart, of a free mode's thermal displacement, started in equilibrium."""
    phi, cov = sampled_flow(m, k, q, temperature, h)
    w = rng.standard_normal((n, 2)) @ _sqrt_psd(cov).T
    x0 = rng.standard_normal(2) * np.sqrt([KB * temperature / k, KB * temperature / m])
    return kernel.linear_flow(phi, w, x0)


def forced_motion(m: float, k: float, q: float, h: float, u: np.ndarray) -> np.ndarray:
    """A mode's displacement [m] on ``n`` samples ``h`` apart when a force ``u`` [N] (samples)
    drives it from rest: the exact flow of ``m x'' + c x' + k x = u`` over each interval with
    the force held at the interval's mean of its end samples (``x_(j+1) = phi x_j + Gamma
    (u_j + u_(j+1))/2``, ``Gamma = A^-1 (phi - I) (0, 1/m)``)."""
    from scipy.linalg import expm

    u = np.asarray(u, float)
    n = len(u)
    if n < 2:
        return np.zeros(n)
    c = math.sqrt(k * m) / q
    a = np.array([[0.0, 1.0], [-k / m, -c / m]])
    phi = expm(a * h)
    gamma = np.linalg.solve(a, (phi - np.eye(2)) @ np.array([0.0, 1.0 / m]))
    um = 0.5 * (u[:-1] + u[1:])
    x = kernel.linear_flow(phi, um[:, None] * gamma[None, :], np.zeros(2))
    return np.concatenate(([0.0], x))


def modes(cfg, d):
    """``[(m, k, Q), ...]`` of the cantilever and the paddle."""
    p = cfg.probe
    return [(d.m1, p.k1, p.q1), (d.m2, p.k2, p.q2)]


def equipartition_kick(s, cfg, d, rng) -> None:
    """Add the free modes' equipartition draw to the probe of the state ``s`` (in place)."""
    temp = cfg.numerics.temperature
    (m1, k1, q1), (m2, k2, q2) = modes(cfg, d)
    dzc = rng.normal(0.0, math.sqrt(KB * temp / k1))  # equipartition, drawn in this order (the seed's stream)
    dvc = rng.normal(0.0, math.sqrt(KB * temp / m1))
    dzp = rng.normal(0.0, math.sqrt(KB * temp / k2))
    dvp = rng.normal(0.0, math.sqrt(KB * temp / m2))
    session.kick_probe(s, dzc, dvc, dzp, dvp)


def thermal_records(kern, s0, cfgs, d, rngs) -> list[np.ndarray]:
    """The recorded periods with the Brownian forces (module docstring) of several replicas at
    once, from the noise-free state ``s0`` at the start of the recorded window: replica ``r``
    at the temperature of ``cfgs[r]`` with the generator ``rngs[r]`` (the same record and the
    same draws from it as :func:`thermal_record` alone; the configurations differ at most in
    their noise).  Each record is a view of one buffer shared by the batch."""
    n_rep = len(rngs)
    if n_rep == 0:
        return []
    record_cycles = {c.numerics.record_cycles for c in cfgs}
    if len(record_cycles) != 1:
        raise ValueError("thermal_records: the replicas of a batch record the same number of periods")
    cycles = record_cycles.pop()
    st = kern.setup
    p, a, emi = kern.coef[0], kern.coef[1], kern.coef[2]
    s = np.tile(np.array(s0, float), (n_rep, 1))
    sig = np.empty((n_rep, 2))
    for r, (cfg, rng) in enumerate(zip(cfgs, rngs)):
        equipartition_kick(s[r], cfg, d, rng)
        sig[r] = [step_sigma(m, k, q, cfg.numerics.temperature, st.dt) for (m, k, q) in modes(cfg, d)]
    nt = kern.nt
    buf = np.zeros((n_rep, d.n_steady, 7 + kern.n_arms))
    lad, lemi, lg = kern.coef[6], kern.coef[7], kern.coef[8]  # the recording ladder: one print step
    if st.hybrid and lad.shape[0] > 0:  # fine steps near the surface, exact far steps with the sampled noise
        pos = np.full(n_rep, -1, np.int64)
        h = float(lad[0, L_H])
        for r, (cfg, rng) in enumerate(zip(cfgs, rngs)):
            lc = np.array([_sqrt_psd(sampled_flow(m, k, q, cfg.numerics.temperature, h)[1]) for (m, k, q) in modes(cfg, d)])
            for steps, start in ((SETTLE_CYCLES * nt, -1), (cycles * nt, 0)):
                origin = session.step_index(s[r])
                pos[r] = kernel.brownian_hybrid(s[r], rng, sig[r, 0], sig[r, 1], lc, p, a, emi, lad, lemi, lg, buf[r],
                                                st.stride, origin, start, steps)  # fmt: skip
        return [buf[r, : pos[r]] for r in range(n_rep)]
    z1, z2 = np.empty((n_rep, nt)), np.empty((n_rep, nt))
    pos = np.full(n_rep, -1, np.int64)
    origin = np.zeros(n_rep, np.int64)
    for cyc in range(SETTLE_CYCLES + cycles):
        if cyc == SETTLE_CYCLES:
            pos[:] = 0
            origin[:] = [session.step_index(s[r]) for r in range(n_rep)]
        for r, rng in enumerate(rngs):  # per replica as rng.normal(0, sig, nt) drew them: fb1, then fb2
            rng.standard_normal(nt, out=z1[r])
            rng.standard_normal(nt, out=z2[r])
        if n_rep == 1:  # the one-replica kernel (its state in registers)
            pos[0] = kernel.brownian_steps(s[0], z1[0], z2[0], p, a, emi, buf[0], st.stride, origin[0], pos[0],
                                           sig[0, 0], sig[0, 1], True)  # fmt: skip
        else:
            kernel.brownian_steps_batch(s, z1, z2, sig, p, a, emi, buf, st.stride, origin, pos)
    return [buf[r, : pos[r]] for r in range(n_rep)]


def thermal_record(kern, s0, cfg, d, rng) -> np.ndarray:
    """The recorded periods with the Brownian forces (module docstring), from the
    noise-free state ``s0`` at the start of the recorded window."""
    return thermal_records(kern, s0, [cfg], d, [rng])[0]


def approach_response(z_noisy, z_clean, st, d) -> np.ndarray:
    """Change of the tip-sample force [N] when the surface (undeformed at the window's
    start) is driven by the tip positions ``z_noisy`` instead of ``z_clean`` (print-step
    samples; ``st`` the kernel setup): the prescribed-trajectory kernel, every sample
    wanted, no far blocks, sub-stepped at the simulator's ``dt`` near the surface."""
    n = len(z_clean)
    h = d.print_step
    steps = (h, h, h / d.stride)
    co = prescribed.arm_coefficients(st.k_inf, st.k, st.cd, st.hr6, st.a0, st.vdw_on_surface, steps, tangents=False)
    kg = st.k_inf + float(np.sum(st.k))
    sub_gap = max(2.0 * st.a0, (200.0 * st.hr6 / kg) ** (1.0 / 3.0))
    want = np.ones(n, np.uint8)
    coarse = np.zeros(n, np.uint8)
    out = []
    for z in (z_noisy, z_clean):
        f = np.zeros(n)
        prescribed.arms_force(np.ascontiguousarray(z, float), 0.0, st.a0, 1, coarse, want, 1.0, d.stride, sub_gap,
                              np.zeros(len(st.k)), False, 0, *co, f, np.zeros((n, 1)))  # fmt: skip
        out.append(f)
    return out[0] - out[1]


APPROACH_PASSES = 2  # reaction-then-force passes of the approach window (the change of z_tip after 2: < 1e-3 pm)


def generator(cfg):
    """The thermal noise's generator of a configuration (its ``numerics.noise_seed``)."""
    return np.random.default_rng([cfg.numerics.noise_seed, _SEED_SALT])


def add_thermal(run, kern, s0, cfg, d) -> None:
    """Replace ``run.steady`` by the noisy recorded periods and add the free probe's thermal
    motion to the first-approach window (module docstring).  Nothing at T = 0."""
    add_thermal_batch([run], kern, s0, [cfg], d)


def add_thermal_batch(runs, kern, s0, cfgs, d) -> None:
    """:func:`add_thermal` of each ``runs[r]`` at ``cfgs[r]`` (replicas of one noise-free run,
    differing at most in their noise), the recorded periods advanced together
    (:func:`thermal_records`); each run as :func:`add_thermal` alone makes it, bit for bit."""
    hot = [(run, cfg) for run, cfg in zip(runs, cfgs) if cfg.numerics.temperature]
    rngs = [generator(cfg) for _, cfg in hot]
    records = thermal_records(kern, s0, [cfg for _, cfg in hot], d, rngs)
    for (run, cfg), rng, rec in zip(hot, rngs, records):  # each generator goes on to its approach window
        run.steady = rec
        _approach_thermal(run, kern, cfg, d, rng)


def _approach_thermal(run, kern, cfg, d, rng) -> None:
    """The free probe's thermal motion (and the surface's and the probe's response to it) added to
    the first-approach window of ``run``, drawn from ``rng`` after the recorded periods; the
    thermal metadata."""
    temp = cfg.numerics.temperature
    ap = run.approach
    if len(ap):
        names = ("z_cantilever", "z_paddle", "z_tip", "z_base", "f_ts")
        ic, ip, it, ib, iff = (tapping.COLUMNS.index(c) for c in names)
        z_clean = ap[:, it].copy()
        h = d.print_step
        free = [free_motion(rng, m, k, q, temp, h, len(ap)) for (m, k, q) in modes(cfg, d)]
        z_free = z_clean + free[0] + free[1]
        df = approach_response(z_free, z_clean, kern.setup, d)
        for _ in range(APPROACH_PASSES):  # the probe's own reaction to the changed force, then the force again
            react = [forced_motion(m, k, q, h, df) for (m, k, q) in modes(cfg, d)]
            df = approach_response(z_free + react[0] + react[1], z_clean, kern.setup, d)
        for col, th, re in zip((ic, ip), free, react):  # the force is the surface's under the tip recorded
            ap[:, col] += th + re
        ap[:, it] = ap[:, ib] + ap[:, ic] + ap[:, ip]
        ap[:, iff] += df
    (m1, k1, q1), (m2, k2, q2) = modes(cfg, d)
    run.info["thermal"] = {
        "temperature_K": temp,
        "settle_cycles": SETTLE_CYCLES,
        "t_record_start": float(run.steady[0, 0]) if len(run.steady) else None,
        "rms_cantilever_m": math.sqrt(KB * temp / k1),
        "rms_paddle_m": math.sqrt(KB * temp / k2),
        "force_psd_cantilever_N2_per_Hz": force_psd(m1, k1, q1, temp),
        "force_psd_paddle_N2_per_Hz": force_psd(m2, k2, q2, temp),
    }
