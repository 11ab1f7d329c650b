"""Drives the tapping kernel (:mod:`.tapping`) through a run: approach, steady state, recording.

Plain floats and arrays (no config objects): the simulation layer unpacks a
config into :class:`KernelSetup` and calls :func:`run`.

Steady state.  The "steady state zero reference
equilibrium" of the thesis is the periodic orbit of the controlled system:
the state -- both oscillators and every dashpot -- repeats after one drive
period, at the base height where the amplitude equals the set point.  With
``steady = "orbit"`` it is *solved*, not waited for: Newton shooting on the
one-period map ``P(y; Zb)`` over ``y = (zc, vc, zp, vp, Xd_1..N)`` and ``Zb``::

    P(y; Zb) - y = 0,        A(y; Zb) - A_sp = 0

(``A``: amplitude of the first harmonic of ``z_tip - Zb`` over the period, what
the controller -- like an instrument's lock-in amplifier -- measures).  The residual of arm ``i`` is scaled by ``max(1, tau_i/T)``,
``tau_i = cd_i/k_i``: then it is the arm's mean stretch over the period,
``<X - Xd_i> = (tau_i/T) (Xd_i(T) - Xd_i(0))`` (from ``cd_i Xd_i' = k_i (X -
Xd_i)``), which a slow dashpot's tiny drift per period hides.  The Jacobian
comes from finite differences of the map (one period each), then Broyden
updates; a backtracking line search keeps every step a descent step.

"Steady" is a claim proven on the recorded periods themselves: they start
and end in the same state within ``tol`` (velocities as lengths ``v/w``,
arm drifts as mean stretches), and every arm's mean stretch ``<X - Xd_i>``
measured over them is below ``tol``.

The approach (thesis fig. 18) is time-stepped with the PI controller; its
first contact gives ``Z1``.  ``steady = "transient"`` continues the
time-stepped controlled run until the proof holds or the time budget ends
(what an instrument with a finite time per pixel sees); the orbit mode
falls back to it when Newton fails, and says so.
"""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from . import coefficients as C
from . import tapping as T

L_UNIT = 1e-9  # [m] length unit of the scaled Newton variables and residuals
FD_STEP = 1e-4  # finite-difference step, in L_UNIT (1e-13 m)
# trust radius of one Newton step, in L_UNIT: the probe state (a linear oscillator away from the
# surface) may change by tens of nm, the dashpots and the base height (which set the indentation,
# where the map is strongly nonlinear) by a few
MAX_STEP_PROBE = 50.0
MAX_STEP_SURFACE = 2.0
NOISE_ACCEPT = 2.0  # a solve stalled by the map's noise within this many tol counts as converged
MU0 = 1e-6  # initial Levenberg-Marquardt damping (relative to the diagonal of J^T J)
MU_MAX = 1e8


def _lm_step(jac, f, mu):
    """Levenberg-Marquardt step ``-(J^T J + mu D)^-1 J^T f`` (``D = diag J^T J``), inside the
    trust radius (MAX_STEP_PROBE for the probe state, MAX_STEP_SURFACE for the arms and the base)."""
    a = jac.T @ jac
    d = np.maximum(np.diag(a), 1e-12 * max(float(np.max(np.diag(a))), 1e-300))
    step = np.linalg.solve(a + mu * np.diag(d), -(jac.T @ f))
    big = max(float(np.max(np.abs(step[:4]))) / MAX_STEP_PROBE, float(np.max(np.abs(step[4:]))) / MAX_STEP_SURFACE)
    return step / big if big > 1.0 else step


def record_buffer(n_samples: int, n_arms: int) -> np.ndarray:
    """A zeroed sample buffer ``(n_samples, 7 + n_arms)`` in column-major order: each recorded
    column is contiguous, so tables and observables take columns without a copy (and every
    buffer the kernel sees has the one layout it is compiled for)."""
    return np.zeros((n_samples, 7 + n_arms), order="F")


@dataclass
class KernelSetup:
    """SI inputs of one run (probe, surface arrays, operation, numerics)."""

    m1: float
    k1: float
    c1: float
    m2: float
    k2: float
    c2: float
    omega: float  # drive [rad/s]
    f0: float  # drive force amplitude [N]
    k_inf: float
    k: np.ndarray  # arm springs [N/m]
    cd: np.ndarray  # arm dashpots [kg/s]
    hr6: float  # H R / 6 [J m]
    a0: float
    vdw_on_surface: bool
    a_sp: float  # amplitude set point [m]
    dt: float  # fine step [s] (drive period = steps_per_period dt exactly)
    steps_per_period: int
    stride: int  # fine steps per print step
    hybrid: bool = True
    d_switch: float = 2e-9  # [m] (numerics.switch_gap)
    ladder_max: int = 13  # longest far step 2**ladder_max dt

    def build(self):
        """Kernel coefficient arrays (see :func:`.coefficients.build`)."""
        ladder = [2**j for j in range(self.ladder_max + 1)] if self.hybrid else []
        p, a, emi, lad, lemi, lg = C.build(
            self.m1, self.k1, self.c1, self.m2, self.k2, self.c2, self.omega, self.f0,
            self.k_inf, self.k, self.cd, self.hr6, self.a0, self.vdw_on_surface,
            self.dt, self.steps_per_period, self.d_switch, ladder,
        )  # fmt: skip
        rec = [self.stride] if self.hybrid else []
        lr = C.ladder_tables(
            self.m1, self.k1, self.c1, self.m2, self.k2, self.c2, self.omega,
            self.k_inf, self.k, self.cd, self.vdw_on_surface, self.dt, rec,
        )  # fmt: skip
        return (p, a, emi, lad, lemi, lg, *lr)


class Kernel:
    """The compiled kernel with its coefficients: one period at a time."""

    def __init__(self, setup: KernelSetup):
        self.setup = setup
        self.coef = setup.build()
        self.n_arms = len(setup.k)
        self.nt = setup.steps_per_period
        self.period_s = setup.steps_per_period * setup.dt
        self.periods = 0  # period evaluations (kernel calls of one period)
        # surface models with more dashpots than arms (the MDR elements of core.mdr) override these
        self.n_state = self.n_arms  # dashpot entries of the state vector
        self.n_rec = self.n_arms  # recorded columns after the seven of tapping.COLUMNS[:-1]
        self.state_tau = np.asarray(setup.cd) / np.asarray(setup.k)  # relaxation time of each dashpot entry [s]
        self._nobuf = record_buffer(2, self.n_rec)

    def new_outputs(self) -> np.ndarray:
        return T.new_outputs(self.n_arms)

    def advance_raw(self, s, n_steps, zb_step, buf, rec, energy, o) -> None:
        """The compiled kernel's ``advance`` on ``s`` (no bookkeeping)."""
        T.advance(s, n_steps, zb_step, *self.coef, buf, rec, energy, o)

    def stretch(self, o) -> np.ndarray:
        """Per arm the mean-stretch integral ``int (X - Xd_i) dt`` [m s] of the outputs ``o``."""
        return o[T.NO_BASE : T.NO_BASE + self.n_arms]

    def advance(self, s, n_steps=None, zb_step=0.0, buf=None, rec=None, energy=False):
        """Advance ``s`` in place; returns the output vector (``T.O_*``)."""
        o = self.new_outputs()
        if rec is None:
            rec = T.new_recorder()
        self.advance_raw(s, self.nt if n_steps is None else n_steps, zb_step, self._nobuf if buf is None else buf,
                         rec, energy, o)  # fmt: skip
        self.periods += 1
        return o


def amplitude(o, duration: float) -> float:
    """Amplitude of the first harmonic of ``z_tip - Zb`` over a call of ``duration`` [s]
    (what a lock-in amplifier measures): ``(2/T) |int q exp(-i w t) dt|`` [m]."""
    return 2.0 / duration * math.hypot(o[T.O_HC], o[T.O_HS])


def phase_deg(o) -> float:
    """Lag of the first harmonic of ``z_tip - Zb`` behind the drive ``cos(w t)`` [deg]."""
    return math.degrees(-math.atan2(o[T.O_HS], o[T.O_HC]))


def new_state(zc, vc, zp, vp, zb, n_arms, contact=False, idx=0):
    s = np.zeros(T.S_XD + n_arms)
    s[T.S_ZC], s[T.S_VC], s[T.S_ZP], s[T.S_VP], s[T.S_ZB] = zc, vc, zp, vp, zb
    s[T.S_IDX] = idx
    s[T.S_CONTACT] = float(contact)
    return s


# ----------------------------------------------------------------------------- controller


@dataclass
class Controller:
    """PI on the base height once per drive period (thesis 3.1.2, fig. 19; no D).

    The correction ``-(kp (e - e_prev) + ki e)`` (velocity form, ``e`` the error
    of the first-harmonic amplitude over the period) is applied as a ramp over the next period; it acts only
    after the first contact.  Before it, the base descends at ``rate``.
    """

    a_sp: float
    kp: float
    ki: float
    steps_per_period: int
    dt: float
    rate: float = 0.0  # approach descent before the first contact [m/s]
    on: bool = True
    e_prev: float = 0.0
    zb_step: float = 0.0

    def __post_init__(self):
        self.zb_step = -self.rate * self.dt if self.on else 0.0

    def update(self, amp: float, contact_seen: bool) -> float:
        e = amp - self.a_sp
        if self.on:
            if contact_seen:
                self.zb_step = -(self.kp * (e - self.e_prev) + self.ki * e) / self.steps_per_period
            self.e_prev = e
        return e

    def copy(self) -> "Controller":
        return Controller(**{k: getattr(self, k) for k in self.__dataclass_fields__})


# ----------------------------------------------------------------------------- approach


@dataclass
class Approach:
    """Outcome of the time-stepped approach."""

    ring: np.ndarray  # samples around the first contact, in time order
    t_first_contact: float
    z_first_contact: float
    periods: int  # controller periods simulated
    last: np.ndarray  # outputs of the last period
    history: list = field(default_factory=list)  # per period: (amplitude, contact z, fmax)


def approach(kern: Kernel, s, ctrl: Controller, n_ring: int, max_periods: int, settle_rel: float = 1e-2,
             min_after: int = 3, pre_max: int = 10, no_contact_max: int | None = None) -> Approach:  # fmt: skip
    """Time-stepped controlled approach from ``s`` (modified in place).

    Runs whole periods, keeping a snapshot of the state and controller at
    every period start.  When the first contact happens, it rewinds
    ``ceil(n_ring/2 samples)`` worth of periods and re-runs them recording at
    the print step into a ring of ``n_ring`` samples that closes ``n_ring/2``
    samples after the first repulsive sample (the window for ``Z1``).  Then it
    continues until the amplitude is within ``settle_rel`` of the set point
    (at least ``min_after`` periods after the window, at most ``pre_max``):
    the start of the steady-state solve.  Without a contact it stops after
    ``no_contact_max`` periods (default: the whole budget).
    """
    stride = kern.setup.stride
    per_samples = kern.nt / stride
    back = int(math.ceil(0.5 * n_ring / per_samples)) + 1
    snaps: deque = deque(maxlen=back + 1)
    ring = record_buffer(max(n_ring, 2), kern.n_rec)
    rec = T.new_recorder(stride=stride, origin=0, ring=True, active=False)
    history = []
    k = 0
    recorded = False
    last = None
    after = 0
    streak = 0
    limit = max_periods if no_contact_max is None else min(max_periods, no_contact_max)
    while k < (max_periods if recorded else limit):
        snaps.append((s.copy(), ctrl.copy(), k, rec.copy()))
        o = kern.advance(s, zb_step=ctrl.zb_step, rec=rec)
        if not recorded and rec[T.R_FC]:
            # rewind and record the first contact's window
            s0, c0, k0, r0 = snaps[0]
            s[:] = s0
            ctrl = c0.copy()
            k = k0
            history = history[:k0]
            rec = r0.copy()
            rec[T.R_ORIGIN] = int(s[T.S_IDX])
            rec[T.R_ACTIVE] = 1
            recorded = True
            t_fc = z_fc = math.nan
            while rec[T.R_ACTIVE] and k < max_periods:
                o = kern.advance(s, zb_step=ctrl.zb_step, buf=ring, rec=rec)
                if math.isnan(t_fc) and not math.isnan(o[T.O_T_FC]):
                    t_fc, z_fc = o[T.O_T_FC], o[T.O_Z_FC]
                amp = amplitude(o, kern.period_s)
                ctrl.update(amp, bool(rec[T.R_FC]))
                history.append((amp, o[T.O_ZCONT], o[T.O_FMAX]))
                k += 1
                last = o
            continue
        amp = amplitude(o, kern.period_s)
        e = ctrl.update(amp, bool(rec[T.R_FC]))
        history.append((amp, o[T.O_ZCONT], o[T.O_FMAX]))
        last = o
        k += 1
        if recorded:
            after += 1
            in_touch = o[T.O_NCONT] > 0
            streak = streak + 1 if (in_touch and abs(e) <= settle_rel * ctrl.a_sp) else 0
            if after >= pre_max or streak >= min_after:
                break
    if not recorded:
        return Approach(ring[:0], math.nan, math.nan, k, last, history)
    written = int(rec[T.R_POS])
    n = len(ring)
    if written >= n:
        j = written % n
        ordered = np.concatenate([ring[j:], ring[:j]])
    else:
        ordered = ring[:written]
    return Approach(ordered, t_fc, z_fc, k, last, history)


# ----------------------------------------------------------------------------- orbit


@dataclass
class OrbitResult:
    converged: bool
    state: np.ndarray
    residual: float  # [m] max-norm of the scaled residual at the end
    periods: int  # period evaluations used
    iterations: int
    reason: str
    history: list = field(default_factory=list)  # residual per iteration [m]
    monodromy_radius: float = math.nan  # spectral radius of dP/dy at fixed Zb
    attempts: int = 1


class _Scaled:
    """Scaled Newton variables ``u`` (lengths in L_UNIT) <-> kernel state, and the residual.

    Velocities are scaled to lengths by their oscillator's frequency.  Each
    component of ``P(y) - y`` is divided by ``1 - exp(-T/tau)`` of the slowest
    way that component can decay over a period (the free cantilever and paddle:
    ``exp(-pi f/(f1 Q))``; arm ``i``: ``tau_i = cd_i/k_i``), so that the residual
    estimates the distance to the periodic orbit rather than the drift per period.
    For a slow arm that is its mean stretch ``<X - Xd_i> = (tau_i/T) dXd_i``.
    """

    def __init__(self, kern: Kernel, template):
        st = kern.setup
        w2 = math.sqrt(st.k2 / st.m2)
        n = kern.n_state
        period = kern.period_s
        self.template = template.copy()
        self.scale = np.concatenate([[L_UNIT, L_UNIT * st.omega, L_UNIT, L_UNIT * w2], np.full(n, L_UNIT), [L_UNIT]])
        decay_c = 0.5 * st.c1 / st.m1 * period
        decay_p = 0.5 * st.c2 / st.m2 * period
        tau = kern.state_tau
        rates = np.concatenate([[decay_c, decay_c, decay_p, decay_p], period / tau])
        self.weight = 1.0 / -np.expm1(-rates)
        # the solver works on the drift per period of the probe (its rows are then as large as
        # the amplitude row) and on the mean stretch of the arms; the convergence test and the
        # proof on the distance to the orbit (``weight``); ``solve_weight * conv_factor = weight``
        self.solve_weight = np.concatenate([np.ones(4), self.weight[4:]])
        self.conv_factor = np.concatenate([self.weight[:4], np.ones(n), [1.0]])
        self.n = 5 + n

    def state(self, u):
        s = self.template.copy()
        y = u * self.scale
        s[T.S_ZC], s[T.S_VC], s[T.S_ZP], s[T.S_VP] = y[0], y[1], y[2], y[3]
        s[T.S_XD:] = y[4:-1]
        s[T.S_ZB] = y[-1]
        return s  # at the template's step index: a period start

    def vars(self, s):
        y = np.concatenate([[s[T.S_ZC], s[T.S_VC], s[T.S_ZP], s[T.S_VP]], s[T.S_XD:], [s[T.S_ZB]]])
        return y / self.scale

    def residual(self, s0, s1, amp, a_sp):
        """Scaled ``P(y) - y`` (probe: drift per period; arms: mean stretch) and the amplitude
        error, in L_UNIT; times ``conv_factor`` it is the distance to the orbit."""
        d = np.concatenate([[s1[T.S_ZC] - s0[T.S_ZC], s1[T.S_VC] - s0[T.S_VC], s1[T.S_ZP] - s0[T.S_ZP],
                             s1[T.S_VP] - s0[T.S_VP]], s1[T.S_XD:] - s0[T.S_XD:]])  # fmt: skip
        d = d / self.scale[:-1] * self.solve_weight
        return np.concatenate([d, [(amp - a_sp) / L_UNIT]])


def solve_orbit(kern: Kernel, s_start, a_sp: float, tol: float, max_periods: int = 150,
                fixed_base: bool = False, want_contact: bool = True, hold_arms: bool = False) -> OrbitResult:  # fmt: skip
    """Newton/Broyden shooting for the periodic orbit at the set-point amplitude.

    ``s_start``: the state at a period start (from the controlled approach);
    ``tol`` [m]: max-norm of the scaled residual to reach; ``max_periods``:
    budget of period evaluations; ``fixed_base``: the base height is given
    (no controller): solve ``P(y) = y`` alone; ``hold_arms``: the dashpots stay
    at their start positions and only the probe (and base) are solved -- the
    first stage for slow surfaces; ``want_contact``: the approach
    settled on the repulsive branch, so a start without contact is moved down
    into it first (the amplitude then depends on the base height).
    """
    sc = _Scaled(kern, s_start)
    free = np.ones(sc.n, bool)  # which of (zc, vc, zp, vp, Xd.., Zb) are unknowns (and which rows count)
    rows = np.ones(sc.n, bool)
    if fixed_base:
        free[-1] = rows[-1] = False
    if hold_arms:
        free[4:-1] = rows[4:-1] = False
    n = int(free.sum())
    p0 = kern.periods
    u_all = sc.vars(s_start)
    conv = sc.conv_factor[rows]

    def distance(f):
        return float(np.max(np.abs(f * conv))) * L_UNIT

    def full(u):
        v = u_all.copy()
        v[free] = u
        return v

    def evaluate(u):
        s0 = sc.state(full(u))
        s1 = s0.copy()
        o = kern.advance(s1)
        r = sc.residual(s0, s1, amplitude(o, kern.period_s), a_sp)
        return r[rows], o, s1

    def used():
        return kern.periods - p0

    u = u_all[free].copy()
    f, o, _ = evaluate(u)
    # the amplitude depends on the base height only through the contact: start in contact
    for _ in range(20):
        if fixed_base or not want_contact or o[T.O_NCONT] > 0 or used() >= max_periods:
            break
        x_low = o[T.O_QMIN] + s_start[T.S_ZB] - kern.setup.a0
        u[-1] -= (max(x_low, 0.0) + 0.5e-9) / L_UNIT
        f, o, _ = evaluate(u)
    history = [distance(f)]
    jac = None
    fresh = False
    it = 0
    mu = MU0
    fails = 0
    reason = "budget"
    while True:
        fn = distance(f)
        if fn <= tol:
            reason = "converged"
            break
        if used() + (n + 1 if jac is None else 1) > max_periods:
            reason = "budget"
            break
        if jac is None:
            jac = np.empty((n, n))
            for j in range(n):
                up = u.copy()
                up[j] += FD_STEP
                fp, _, _ = evaluate(up)
                jac[:, j] = (fp - f) / FD_STEP
            fresh = True
        step = _lm_step(jac, f, mu)
        trial, on, _ = evaluate(u + step)
        it += 1
        f2 = float(f @ f)
        pred = f2 - float(np.sum((f + jac @ step) ** 2))
        actual = f2 - float(trial @ trial)
        same_branch = (on[T.O_NCONT] > 0) == (o[T.O_NCONT] > 0)  # losing the contact leaves the branch
        rho = actual / pred if pred > 0 else -1.0
        # Broyden rank-one update with every evaluated step (the secant holds whether or not it is taken)
        df = trial - f
        jac = jac + np.outer(df - jac @ step, step) / float(step @ step)
        if same_branch and rho > 1e-4:
            u, f, o = u + step, trial, on
            history.append(distance(f))
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            fresh = False
            fails = 0
            continue
        mu *= 4.0
        fails += 1
        if mu > MU_MAX:
            # no step reduces the residual any more: the map's own noise floor
            reason = "converged" if distance(f) <= NOISE_ACCEPT * tol else "no descent step at the largest damping"
            break
        if fails >= 2 and not fresh:
            jac = None  # the Broyden model went stale: rebuild by finite differences
            fails = 0
    s_end = sc.state(full(u))
    rad = monodromy_radius(jac, sc.solve_weight) if (jac is not None and free.all()) else math.nan
    return OrbitResult(reason == "converged", s_end, distance(f), used(), it, reason,
                       history, rad)  # fmt: skip


def anderson(kern: Kernel, s_start, a_sp: float, tol: float, max_periods: int, memory: int = 4,
             fixed_base: bool = False) -> OrbitResult:  # fmt: skip
    """The periodic orbit by Anderson-accelerated fixed-point iteration of the period map.

    The second strategy, for starts in strong transients (a violent first tap on a stiff
    surface, an amplitude that takes tens of periods to recover) where the Newton model
    keeps stepping into an extra or a lost contact.  Every iterate is one physical
    period, so the iteration follows the system's own contraction; the fixed-point map
    is ``G(u) = u + W (P(u) - u)`` with the base moved by the amplitude error
    (``dA/dZb ~ 1`` in contact) and each slow dashpot by its mean stretch over the
    period (``W = tau_i/T``: the position where it carries no mean force at the current
    probe orbit); Anderson mixing (``memory`` iterates) accelerates the slow modes.
    """
    sc = _Scaled(kern, s_start)
    p0 = kern.periods
    u = sc.vars(s_start)
    if fixed_base:
        free = np.ones(sc.n, bool)
        free[-1] = False
    hist_x, hist_g = [], []
    best = (math.inf, u.copy())
    reason = "budget"
    it = 0
    while kern.periods - p0 < max_periods:
        s0 = sc.state(u)
        s1 = s0.copy()
        o = kern.advance(s1)
        r = sc.residual(s0, s1, amplitude(o, kern.period_s), a_sp)
        dist = float(np.max(np.abs((r * sc.conv_factor)[:-1] if fixed_base else r * sc.conv_factor))) * L_UNIT
        if dist < best[0]:
            best = (dist, u.copy())
        if dist <= tol:
            reason = "converged"
            break
        g = sc.vars(s1)  # the period map's image
        g[-1] = u[-1] - (0.0 if fixed_base else r[-1])  # base moved by the amplitude error
        g[4:-1] = u[4:-1] + r[4:-1]  # each arm jumps by its mean stretch
        f = g - u
        hist_x.append(u.copy())
        hist_g.append(g.copy())
        if len(hist_x) > memory + 1:
            hist_x.pop(0)
            hist_g.pop(0)
        if len(hist_x) >= 2:
            fs = np.array([hg - hx for hx, hg in zip(hist_x, hist_g)])
            df = np.diff(fs, axis=0).T
            dg = np.diff(np.array(hist_g), axis=0).T
            gamma = np.linalg.lstsq(df, f, rcond=None)[0]
            u_new = g - dg @ gamma
        else:
            u_new = g
        # keep the extrapolation within the trust radius of a Newton step
        step = u_new - u
        big = max(float(np.max(np.abs(step[:4]))) / MAX_STEP_PROBE, float(np.max(np.abs(step[4:]))) / MAX_STEP_SURFACE)
        u = u + (step / big if big > 1.0 else step)
        it += 1
    return OrbitResult(reason == "converged", sc.state(best[1]), best[0], kern.periods - p0, it, reason)


STRATEGY = ("newton", "anderson")  # the solvers solve_steady tries, in order
ANDERSON_PERIODS = 250  # budget of the second strategy (beyond the first one's)


def solve_steady(kern: Kernel, s, ctrl: "Controller", tol, max_periods, fixed_base, want_contact,
                 strategy=None) -> OrbitResult:  # fmt: skip
    """The periodic orbit from the approach's state ``s``: Levenberg-Marquardt/Broyden
    shooting (:func:`solve_orbit`, fast near the orbit), and where it fails -- a start in
    a strong transient, where its linear model keeps stepping into an extra or a lost
    contact -- Anderson-accelerated iteration of the period map (:func:`anderson`),
    which follows the system's own contraction; each from the approach's state.
    ``max_periods`` is the first strategy's budget, ANDERSON_PERIODS the second's."""
    p0 = kern.periods
    res = None
    tried = []
    for name in strategy or STRATEGY:
        if name == "newton":
            res = solve_orbit(kern, s, ctrl.a_sp, tol, max_periods, fixed_base, want_contact)
        else:
            res = anderson(kern, s, ctrl.a_sp, tol, ANDERSON_PERIODS, fixed_base=fixed_base)
        tried.append(f"{name}: {res.reason}")
        if res.converged:
            break
    res.periods = kern.periods - p0
    res.attempts = len(tried)
    res.reason = "; ".join(tried)
    res.converged = tried[-1].endswith(": converged")
    return res


def monodromy_radius(jac, weights) -> float:
    """Spectral radius of ``dP/dy`` at fixed base height from the solver's Jacobian (scaled
    variables; the rows carry the weights of :class:`_Scaled`).  Below 1: the orbit is
    stable, as the one a time-stepped run settles on must be."""
    n = len(weights)
    m = jac[:n, :n] / np.asarray(weights)[:, None] + np.eye(n)
    return float(np.max(np.abs(np.linalg.eigvals(m))))


# ----------------------------------------------------------------------------- a whole run


@dataclass
class RunSpec:
    """Everything :func:`run` needs besides the kernel (plain numbers)."""

    zb0: float
    zc0: float
    vc0: float
    controller_on: bool
    kp: float
    ki: float
    approach_rate: float
    n_ring: int  # approach-window samples
    record_cycles: int
    steady: str  # "orbit" | "transient"
    max_periods: int  # time budget (numerics.max_time) in drive periods
    tol: float  # [m] periodicity tolerance of the proof (scaled state change, mean arm stretch)
    tol_amp: float  # relative amplitude tolerance of the proof
    orbit_max_periods: int = 150
    settle_cycles: int = 10  # transient: settled periods before a proof is attempted
    tol_z: float = 1e-12  # transient: contact-position drift per period counted as settled [m]


@dataclass
class RunResult:
    approach: np.ndarray  # samples of the first-approach window
    steady: np.ndarray  # samples of the recorded window
    stop_reason: str
    info: dict
    warnings: list
    window: "Window"  # the recorded window (outputs, period-boundary states, proof)


def record_periods(kern: Kernel, s, cycles: int):
    """Record ``cycles`` whole periods from ``s`` at the print step with the base held.

    Returns the samples, the outputs accumulated over the window (energies, mean
    arm stretch, first harmonic; ``O_MAXCPP`` = the most contact events in one
    period) and the state at the start of every period and after the last
    (``cycles + 1`` rows)."""
    st = kern.setup
    n_samples = int(round(cycles * kern.nt / st.stride))
    buf = record_buffer(n_samples, kern.n_rec)
    rec = T.new_recorder(stride=st.stride, origin=int(s[T.S_IDX]), ring=False, active=True)
    total = kern.new_outputs()
    states = [s.copy()]
    for _ in range(cycles):
        o = kern.new_outputs()
        kern.advance_raw(s, kern.nt, 0.0, buf, rec, True, o)
        kern.periods += 1
        states.append(s.copy())
        _accumulate(total, o)
    return buf[: int(min(rec[T.R_POS], n_samples))], total, np.array(states)


def _accumulate(total, o) -> None:
    """Add one period's outputs to a window's: integrals add, extrema combine, the first
    contact of the window is kept and the most contacts in one period tracked."""
    for i in (T.O_QMAX, T.O_FMAX):
        total[i] = max(total[i], o[i])
    for i in (T.O_QMIN, T.O_FMIN):
        total[i] = min(total[i], o[i])
    if math.isnan(total[T.O_ZCONT]):
        total[T.O_ZCONT] = o[T.O_ZCONT]
    for i in (T.O_ZCONT_LAST, T.O_ZSEP_LAST, T.O_TCONT_LAST, T.O_TSEP_LAST):
        if not math.isnan(o[i]):
            total[i] = o[i]
    total[T.O_MAXCPP] = max(total[T.O_MAXCPP], o[T.O_NCONT])
    for i in (T.O_NCONT, T.O_NSEP, T.O_CSTEPS, T.O_WDRIVE, T.O_D1, T.O_D2, T.O_WTS, T.O_DDASH, T.O_FINE,
              T.O_FAR, T.O_REJECT, T.O_HC, T.O_HS):  # fmt: skip
        total[i] += o[i]
    total[T.NO_BASE :] += o[T.NO_BASE :]


def proof(kern: Kernel, states, o, a_sp: float, fixed_base: bool) -> dict:
    """Is the recorded window periodic?  The largest change of the state over any one of its
    periods (:class:`_Scaled`: positions, velocities as ``v/w``, each dashpot as its mean
    stretch ``(tau_i/T) dXd_i``), every arm's mean stretch ``<X - Xd_i>`` measured over the
    window, and the first-harmonic amplitude's error."""
    cycles = len(states) - 1
    sc = _Scaled(kern, states[0])
    amp = amplitude(o, cycles * kern.period_s)
    drift = max(float(np.max(np.abs(sc.residual(a, b, amp, a_sp)[:-1]))) for a, b in zip(states[:-1], states[1:]))
    xm = kern.stretch(o) / (cycles * kern.period_s)
    return {
        "state_change_m": drift * L_UNIT,
        "mean_arm_stretch_m": [float(v) for v in xm],
        "amplitude_error_rel": None if fixed_base else float((amp - a_sp) / a_sp),
        "amplitude_m": float(amp),
        "phase_deg": phase_deg(o),
    }


def proven(pr: dict, tol: float, tol_amp: float) -> bool:
    """The claim "steady": the proof's numbers within the tolerances."""
    ok = pr["state_change_m"] <= tol and max(abs(v) for v in pr["mean_arm_stretch_m"]) <= tol
    if pr["amplitude_error_rel"] is not None:
        ok = ok and abs(pr["amplitude_error_rel"]) <= tol_amp
    return ok


@dataclass
class Window:
    """A recorded window: samples, outputs, the state at every period boundary, the proof."""

    samples: np.ndarray
    outputs: np.ndarray
    states: np.ndarray
    proof: dict
    proven: bool
    record_s: float = 0.0  # wall time of the recording [s]


def record_window(kern, s, spec, a_sp, fixed_base) -> Window:
    """Record ``spec.record_cycles`` periods from ``s`` (base held) and put them to the proof."""
    t0 = time.perf_counter()
    buf, o, states = record_periods(kern, s, spec.record_cycles)
    pr = proof(kern, states, o, a_sp, fixed_base)
    return Window(buf, o, states, pr, proven(pr, spec.tol, spec.tol_amp), time.perf_counter() - t0)


def transient(kern, s, ctrl, spec, periods_left, fixed_base) -> Window:
    """Time-stepped controlled run from ``s``: once the amplitude is within ``tol_amp`` and the
    contact position moves less than ``tol_z`` per period for ``settle_cycles`` periods, a
    window is recorded (base held) and put to the proof; the run goes on until a window
    proves periodic or the budget ends, and then records its last periods."""
    used = 0
    settled = 0
    z_prev = math.nan
    while True:
        if used + spec.record_cycles >= periods_left:
            return record_window(kern, s, spec, ctrl.a_sp, fixed_base)
        o = kern.advance(s, zb_step=ctrl.zb_step)
        used += 1
        e = ctrl.update(amplitude(o, kern.period_s), True)
        z = o[T.O_ZCONT]
        amp_ok = fixed_base or abs(e) <= spec.tol_amp * ctrl.a_sp
        z_ok = not math.isnan(z) and not math.isnan(z_prev) and abs(z - z_prev) <= spec.tol_z
        z_prev = z
        settled = settled + 1 if (amp_ok and z_ok) else 0
        if settled >= spec.settle_cycles:
            held = ctrl.zb_step
            win = record_window(kern, s, spec, ctrl.a_sp, fixed_base)
            used += spec.record_cycles
            if win.proven:
                return win
            settled = 0
            ctrl.zb_step = held


def run(kern: Kernel, spec: RunSpec) -> RunResult:
    """Approach, steady state (orbit or transient) and the recorded window.

    ``stop_reason``: ``steady`` (the recorded window is proven periodic), ``steady
    (transient fallback)`` (the orbit solver failed or left the approach's branch and
    the time-stepped transient reached a proven periodic state), ``max_time`` (the
    transient's budget ended first; the last periods are recorded, not claimed steady)
    or ``max_time (orbit solver failed)``."""
    st = kern.setup
    fixed_base = not spec.controller_on
    s = new_state(spec.zc0, spec.vc0, 0.0, 0.0, spec.zb0, kern.n_state)
    ctrl = Controller(st.a_sp, spec.kp, spec.ki, kern.nt, st.dt, spec.approach_rate, spec.controller_on)
    warnings: list = []
    info: dict = {"steady_method": spec.steady}
    # without a controller nothing brings the tip down: a free start settles within a few Q1 periods
    q1 = math.sqrt(st.k1 * st.m1) / st.c1
    no_contact_max = None if spec.controller_on else int(10 * q1)
    t0 = time.perf_counter()
    ap = approach(kern, s, ctrl, spec.n_ring, spec.max_periods, no_contact_max=no_contact_max)
    t_approach = time.perf_counter() - t0
    info.update(t_first_contact=ap.t_first_contact, z_first_contact=ap.z_first_contact, approach_periods=ap.periods)
    # the branch the controlled approach is on: repulsive if most of its periods since the first
    # contact were (a controller overshoot can lift the tip off for a few periods)
    since = [h for h in ap.history if not math.isnan(h[1])] or ap.history[-1:]
    info["approach_branch"] = {"repulsive": bool(since) and 2 * sum(h[2] > 0.0 for h in since) > len(since)}
    periods_left = spec.max_periods - ap.periods
    win = None
    if spec.steady == "orbit":
        res = solve_steady(kern, s, ctrl, 0.5 * spec.tol, spec.orbit_max_periods, fixed_base,
                           info["approach_branch"]["repulsive"])  # fmt: skip
        info["orbit"] = {k: getattr(res, k) for k in ("converged", "reason", "residual", "periods", "iterations",
                                                         "attempts", "monodromy_radius")}  # fmt: skip
        periods_left -= res.periods
        if res.converged:
            cand = record_window(kern, res.state.copy(), spec, st.a_sp, fixed_base)
            periods_left -= spec.record_cycles
            branch = _branch(cand.outputs, spec.record_cycles * kern.period_s)
            info["orbit_branch"] = branch
            changed = _branch_changed(info["approach_branch"], branch)
            if changed:
                warnings.append(f"the orbit solver converged on another oscillation branch ({changed}); "
                                "fell back to the time-stepped transient, which follows the approach")  # fmt: skip
            elif not cand.proven:
                warnings.append("the solved orbit failed the periodicity proof on its recorded window; "
                                "fell back to the time-stepped transient")  # fmt: skip
            else:
                win = cand
        else:
            warnings.append(f"orbit solver failed ({res.reason}, residual {res.residual:.3g} m after "
                            f"{res.periods} periods); fell back to the time-stepped transient")  # fmt: skip
        if win is not None:
            stop = "steady"
        else:
            win = transient(kern, s, ctrl, spec, max(periods_left, spec.record_cycles + 1), fixed_base)
            stop = "steady (transient fallback)" if win.proven else "max_time (orbit solver failed)"
    else:
        win = transient(kern, s, ctrl, spec, max(periods_left, spec.record_cycles + 1), fixed_base)
        stop = "steady" if win.proven else "max_time"
    info["proof"] = win.proof
    info["periods_evaluated"] = kern.periods
    total = time.perf_counter() - t0
    info["timing_s"] = {"approach": t_approach, "steady": total - t_approach - win.record_s,
                        "record": win.record_s, "total": total}  # fmt: skip
    return RunResult(ap.ring, win.samples, stop, info, warnings, win)


def _branch(o, duration) -> dict:
    """Oscillation branch of a window: repulsive (the force turns repulsive) or attractive, and the phase."""
    return {"repulsive": bool(o[T.O_FMAX] > 0.0), "phase_deg": phase_deg(o),
            "amplitude_m": amplitude(o, duration)}  # fmt: skip


def _branch_changed(a: dict, b: dict) -> str:
    """Tapping mode's coexisting oscillation states: the repulsive one (the force turns
    repulsive in every tap) and the attractive one (the tip feels only the attraction)."""
    if a["repulsive"] != b["repulsive"]:
        return (f"{'repulsive' if a['repulsive'] else 'attractive'} during the approach, "
                f"{'repulsive' if b['repulsive'] else 'attractive'} on the orbit")  # fmt: skip
    return ""
