"""What an AM-AFM gives in tapping mode without a special probe: the amplitude and phase of
the tip at the drive frequency, and the dissipated energy, virial and loss tangent that
follow from them (the AM-AFM energy balance; Cleveland et al. 1998, San Paulo & Garcia 2001, Proksch et al.
2016).  Registered as extraction method ``observables``.

From the record's ``t`` and ``z_tip`` over a whole number of drive periods (a lock-in at
the drive frequency ``f_d``, phase reference the drive ``cos(2 pi f_d (t - t0))``)::

    z_tip ~ Zb + A cos(2 pi f_d (t - t0) - phi)            A [m], phi lag behind the drive [deg]

and, with the free amplitude ``A0`` for the same drive, the flexural mode's ``k1, Q1, f1``
and ``Omega = f_d / f1``, from the flexural equation of motion averaged over a period::

    E_diss   = (pi k1 A / Q1) (A0 sin phi - Omega A)                        [J per cycle]
    V_ts     = (k1 A / 2 Q1) (Q1 A (1 - Omega^2) - A0 cos phi)              [J]
    tan d_AM = E_diss / (2 pi |V_ts|)      (Omega = 1: (sin phi - A/A0)/cos phi)

Inputs: ``t`` and ``z_tip`` (the record's), and ``A0``, ``k1``, ``Q1``, ``f1``, the drive
frequency and the drive's time origin ``t0`` -- from the options, else the metadata of a
simulated run (its probe, ``operation.free_amplitude``, a drive at ``f1`` with ``t0 = 0`` on
the record's time axis).  A record without metadata needs all six as user inputs
(``vetica extract --free-amplitude --k1 --q1 --f1 [--drive-frequency] --drive-t0``).
The force is not used.

Truth (when the metadata holds it): the simulator's exact amplitude, phase, sample
dissipation ``-closed int F_ts dz_tip`` and virial ``<F_ts (z_tip - Zb)>``; for ``tan d_AM``
the material's own ``k''/k'`` at the drive frequency (the AM-AFM energy balance), with the surface's
``k', k'', tan delta`` at the drive frequency and at ``pi / contact time`` as references.

Where the formulas and the simulator differ: they balance the drive's work against the
flexural mode's damping, so on a torsional harmonic cantilever ``E_diss`` also holds what
the paddle dissipates (the kernel's ``paddle_damping``: +9 % at the worked example), and
they take the motion as one harmonic; ``V_ts`` is exact in the flexural mode but the record's
``z_tip`` adds the paddle's deflection.  Both are in the diagnostics.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ...constants import EV
from ...ranges import range_rule
from ...errors import InputError
from ...surfaces import Quantity
from ...surfaces.base import DYNAMIC_QUANTITIES
from ..base import ModelFreeMethod, Option, register
from ..record import Record
from ..result import ExtractionResult, estimates, t_factor

QUANTITIES: dict[str, Quantity] = {
    "amplitude_obs": Quantity("m", "A", "$A$", "nm", 1e9, True, "first-harmonic amplitude of z_tip at the drive frequency"),
    "phase_obs": Quantity("deg", "phi", r"$\phi$", "deg", 1.0, True, "lag of the tip behind the drive (90 free)"),
    "e_diss_obs": Quantity("eV", "E_diss", r"$E_{diss}$", "eV", 1.0, True, "dissipated energy per cycle from A and phi"),
    "virial_obs": Quantity("eV", "V_ts", r"$V_{ts}$", "eV", 1.0, True, "virial <F_ts (z - Zb)> from A and phi"),
    "tan_delta_am": Quantity("", "tan d_AM", r"$\tan\delta_{AM}$", "", 1.0, True, "loss tangent E_diss / (2 pi |V_ts|)"),
}  # fmt: skip
THEORY_SOURCES = {
    "amplitude_obs": "the simulator's first harmonic of z_tip - Zb (observable 'amplitude')",
    "phase_obs": "the simulator's phase (observable 'phase_deg')",
    "e_diss_obs": "the simulator's exact sample dissipation -closed int F_ts dz_tip (observable 'e_diss_ev')",
    "virial_obs": "the simulator's virial <F_ts (z_tip - Zb)> (observable 'virial_ev')",
    "tan_delta_am": "the surface's own k''/k' at the drive frequency (the AM-AFM energy balance)",
}
RINGDOWNS = 10  # a record this many ring-down times long or longer: its per-period scatter gives sigma

INPUTS = {  # option -> (CLI flag, unit, what it is)
    "free_amplitude": ("--free-amplitude", "m", "free amplitude A0 for the same drive"),
    "k1": ("--k1", "N/m", "flexural stiffness"),
    "q1": ("--q1", "", "flexural quality factor"),
    "f1": ("--f1", "Hz", "flexural resonance"),
    "drive_frequency": ("--drive-frequency", "Hz", "drive frequency (default f1)"),
    "drive_t0": ("--drive-t0", "s", "time at which the drive cos(2 pi f_d (t - t0)) peaks"),
}


def first_harmonic(t: np.ndarray, z: np.ndarray, f_drive: float, t0: float = 0.0) -> tuple[float, float, int, float]:
    """Amplitude [m] and lag [deg] of ``z ~ A cos(2 pi f_drive (t - t0) - phi)`` over the
    largest whole number of drive periods from the record's start (a lock-in amplifier:
    ``A cos phi = 2 <z cos>``, ``A sin phi = 2 <z sin>``, the rectangle rule, exact for a
    uniformly sampled periodic signal below Nyquist).  Returns ``(A, phi, periods, misfit)``
    with ``misfit`` the part of a sample by which the periods miss a whole number of samples.
    InputError for a record shorter than one period."""
    period = 1.0 / f_drive
    h = (t[-1] - t[0]) / (len(t) - 1)
    periods = int(math.floor((t[-1] - t[0] + h) / period * (1.0 + 1e-9)))
    if periods < 1:
        raise InputError(
            f"the record spans {(t[-1] - t[0] + h) / period:.3g} drive periods; amplitude and phase need at least one"
        )
    exact = periods * period / h
    n = int(round(exact))
    ph = 2.0 * math.pi * f_drive * (t[:n] - t0)
    c = 2.0 * float(np.mean(z[:n] * np.cos(ph)))
    s = 2.0 * float(np.mean(z[:n] * np.sin(ph)))
    return math.hypot(c, s), math.degrees(math.atan2(s, c)), periods, abs(exact - n)


def per_period(t: np.ndarray, z: np.ndarray, inp: dict, omega: float) -> dict:
    """``{quantity: Spread}`` of the lock-in and the energy balance over each whole drive period
    of the record on its own (their scatter: what the error bar of the record's values is
    computed from); {} for fewer than two periods."""
    from ..result import Spread

    f_d, t0 = inp["drive_frequency"], inp["drive_t0"]
    h = (t[-1] - t[0]) / (len(t) - 1)
    per_samples = 1.0 / (f_d * h)
    n_periods = int(math.floor(len(t) / per_samples * (1.0 + 1e-9)))
    if n_periods < 2:
        return {}
    rows = []
    for p in range(n_periods):
        a, b = int(round(p * per_samples)), int(round((p + 1) * per_samples))
        ph = 2.0 * math.pi * f_d * (t[a:b] - t0)
        c, s_ = 2.0 * float(np.mean(z[a:b] * np.cos(ph))), 2.0 * float(np.mean(z[a:b] * np.sin(ph)))
        amp, phase = math.hypot(c, s_), math.degrees(math.atan2(s_, c))
        obs = am_observables(amp, phase, inp["free_amplitude"], inp["k1"], inp["q1"], omega)
        rows.append((amp, phase, obs["e_diss"] / EV, obs["virial"] / EV, obs["tan_delta"]))
    arr = np.array(rows)
    return {k: Spread.of(arr[:, i]) for i, k in enumerate(("amplitude_obs", "phase_obs", "e_diss_obs", "virial_obs",
                                                           "tan_delta_am"))}  # fmt: skip


def am_observables(amp: float, phase_deg: float, a0: float, k1: float, q1: float, omega: float = 1.0) -> dict:
    """``E_diss`` [J per cycle], ``V_ts`` [J] and ``tan d_AM`` from amplitude [m], phase [deg],
    free amplitude [m], ``k1`` [N/m], ``Q1`` and ``Omega = f_drive/f1`` (module docstring, the AM-AFM energy balance)."""
    phi = math.radians(phase_deg)
    e = math.pi * k1 * amp / q1 * (a0 * math.sin(phi) - omega * amp)
    v = k1 * amp / (2.0 * q1) * (q1 * amp * (1.0 - omega * omega) - a0 * math.cos(phi))
    tan = e / (2.0 * math.pi * abs(v)) if v else math.nan
    return {"e_diss": e, "virial": v, "tan_delta": tan}


def instrument_inputs(record: Record, options: dict, names=tuple(INPUTS)) -> tuple[dict, dict]:
    """The stated inputs ``names`` (:data:`INPUTS`): the option, else the run's metadata;
    ``(values, sources)``.  InputError naming the flags of the missing ones."""
    probe, op = record.probe, record.params.get("operation") or {}
    meta = {"free_amplitude": op.get("free_amplitude"), "k1": probe.get("k1"), "q1": probe.get("q1"),
            "f1": probe.get("f1"), "drive_frequency": probe.get("f1"),  # the simulator drives at f1 (the probe model)
            "drive_t0": 0.0 if probe else None}  # fmt: skip  (its drive is cos(w1 t) on the record's time axis)
    values, sources = {}, {}
    for k in names:
        if options.get(k) is not None:
            values[k], sources[k] = float(options[k]), "given"
        elif k == "drive_frequency" and options.get("f1") is not None:
            values[k], sources[k] = float(options["f1"]), "given f1"
        elif meta[k] is not None:
            values[k], sources[k] = float(meta[k]), "metadata"
    missing = [k for k in names if k not in values]
    if missing:
        raise InputError(
            "the record has no metadata for "
            + ", ".join(f"the {INPUTS[k][2]} ({INPUTS[k][0]})" for k in missing)
            + ": pass " + " ".join(INPUTS[k][0] for k in missing)
        )  # fmt: skip
    return values, sources


def dynamic_references(record: Record, f_drive: float | None) -> dict:
    """The surface's k', k'', tan delta at the drive frequency and at pi / contact time
    (:meth:`~vetica_cli.surfaces.SurfaceModel.dynamic_theory`), the contact time the
    simulator's; all None without the surface's parameters."""
    if record.truth is None:
        return dict.fromkeys(DYNAMIC_QUANTITIES)
    return record.model.dynamic_theory(record.surface, f_drive, record.observables.get("contact_time"))


def check_positive(opts: dict, names: dict) -> None:
    """InputError for an option of ``names`` ({name: unit}) that is given but not a finite number > 0."""
    for name, unit in names.items():
        v = opts.get(name)
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0):
            raise InputError(f"{name.replace('_', '-')} {v!r} not allowed; expected a number > 0{' ' + unit if unit else ''}")


@register
class Observables(ModelFreeMethod):
    """Amplitude and phase at the drive frequency, and E_diss, V_ts and tan d_AM from them (the AM-AFM energy balance)."""

    key = "observables"
    reads_force = False  # the lock-in reads z_tip only
    description = ("the instrument's amplitude and phase, and E_diss, virial and loss tangent tan d_AM from them "
                   "(the AM-AFM energy balance)")  # fmt: skip
    title = "AM-AFM observables (amplitude and phase)"
    option_specs = tuple(
        Option(k, "float", None, unit, what if "default" in what else f"{what} (default: the metadata's)",
               range_rule(flag) if k != "drive_t0" else None, flag=flag if k != "f1" else None)  # --f1: the record's
        for k, (flag, unit, what) in INPUTS.items()
    )  # fmt: skip
    references = ("Cleveland et al. 1998", "San Paulo & Garcia 2001", "Proksch et al. 2016")
    scan_maps = ("tan_delta_am",)  # drawn in a scan's instrument figure
    needs_z1 = False
    uniform_sampling = True
    seconds_per_point = 0.5  # both forces, 10 periods at 0.125 ns: 0.49 CPU s measured
    theory_sources = THEORY_SOURCES
    fixed_quantities = QUANTITIES

    def run(self, record: Record, options: dict) -> ExtractionResult:
        inp, src = instrument_inputs(record, options)
        t0 = time.perf_counter()
        omega = inp["drive_frequency"] / inp["f1"]
        amp, phase, periods, misfit = first_harmonic(record.t, record.z, inp["drive_frequency"], inp["drive_t0"])
        if not inp["free_amplitude"] > amp:
            raise InputError(f"{INPUTS['free_amplitude'][0]}: {inp['free_amplitude']:g} m ({src['free_amplitude']}) is not "
                             f"allowed for this record; expected a free amplitude above the record's amplitude "
                             f"{amp:.4g} m (tapping sets the amplitude below the free one)")  # fmt: skip
        obs = am_observables(amp, phase, inp["free_amplitude"], inp["k1"], inp["q1"], omega)
        values = {"amplitude_obs": amp, "phase_obs": phase, "e_diss_obs": obs["e_diss"] / EV,
                  "virial_obs": obs["virial"] / EV, "tan_delta_am": obs["tan_delta"]}  # fmt: skip
        per = per_period(record.t, record.z, inp, omega)  # the same, period by period: their spread
        refs = dynamic_references(record, inp["drive_frequency"])
        ko = record.observables
        truth = {"amplitude_obs": ko.get("amplitude"), "phase_obs": ko.get("phase_deg"),
                 "e_diss_obs": ko.get("e_diss_ev"), "virial_obs": ko.get("virial_ev"),
                 "tan_delta_am": refs.get("tan_delta_drive")}  # fmt: skip
        units = {k: q.unit for k, q in QUANTITIES.items()}
        warnings = list(record.meta_warnings)
        if misfit > 0.01:
            warnings.append(f"{periods} drive periods miss a whole number of samples by {misfit:.2g} of a sample: "
                            "the amplitude and phase carry that leakage")  # fmt: skip
        if not 0.0 < phase < 180.0:
            warnings.append(f"phase {phase:.4g} deg outside (0, 180): the tip does not lag the drive as a damped mode")
        diag = {"periods": periods, "omega_ratio": omega, "amplitude_ratio": amp / inp["free_amplitude"],
                "inputs": {k: {"value": v, "source": src[k]} for k, v in inp.items()}}  # fmt: skip
        e = record.energy
        if e.get("paddle_damping") is not None and e.get("sample_dissipation") is not None:
            both = e["sample_dissipation"] + e["paddle_damping"]
            diag.update(paddle_damping_ev=e["paddle_damping"], sample_plus_paddle_ev=both,
                        e_diss_obs_vs_sample_plus_paddle_pct=100.0 * (values["e_diss_obs"] - both) / both if both
                        else None)  # fmt: skip
        timing = {"reconstruction": record.reconstruction_s, "lock_in": time.perf_counter() - t0,
                  "total": time.perf_counter() - record.t_start}  # fmt: skip
        return ExtractionResult(method=self.key, force=record.force, taps=_taps(record), model=record.model.key,
                                estimates=estimates(values, units, truth, spreads=per), info=dict(record.info),
                                diagnostics=diag,
                                warnings=warnings, timing_s=timing, references=refs)  # fmt: skip

    def sigmas(self, res: ExtractionResult, record, options: dict) -> tuple[dict, dict]:
        """The per-period values are not independent: the flexural mode remembers its state for
        its ring-down time ``2 Q1 / omega1``, ``tau = Q1 f_d / (pi f1)`` drive periods (32 for the
        thesis's probe; the free cantilever's, an upper bound in contact), so the record's mean
        over ``n`` periods carries the scatter of ``n_eff = n / (1 + 2 tau)`` independent ones
        (the integrated autocorrelation time of an exponentially correlated series).  Where the
        record spans fewer than :data:`RINGDOWNS` ring-down times its own scatter cannot measure
        that slow part (at 300 K, 10 periods: the per-period standard error covered the
        noise-free answer in 0.14-0.43 of replicas, scripts/trust.py) and no sigma is reported."""
        d = res.diagnostics or {}
        inp = {k: v["value"] for k, v in (d.get("inputs") or {}).items()}
        n = int(d.get("periods") or 0)
        tau = inp["q1"] * inp["drive_frequency"] / (math.pi * inp["f1"]) if inp.get("q1") and inp.get("f1") else math.inf
        if not n >= RINGDOWNS * tau:
            return {}, {"source": f"none: the record spans {n} drive periods, fewer than {RINGDOWNS} ring-down times of "
                                  f"the cantilever ({tau:.3g} periods each); its per-period scatter does not measure a "
                                  "noise the cantilever remembers that long"}  # fmt: skip
        out = {}
        n_eff = n / (1.0 + 2.0 * tau)
        for q, e in res.estimates.items():
            sp = e.spread
            if e.value and sp is not None and sp.std is not None and sp.n >= 2:
                out[q] = sp.std / math.sqrt(n_eff) * t_factor(max(2, int(n_eff))) / abs(e.value)
        return out, {"source": f"spread over {n} periods, {n_eff:.3g} independent ones (ring-down {tau:.3g} periods)"}

    def detail_lines(self, res: ExtractionResult) -> list[str]:
        d = res.diagnostics or {}
        inp = d.get("inputs") or {}
        lines = [
            f"lock-in at {_v(inp, 'drive_frequency', '.6g')} Hz over {d.get('periods', '?')} periods (drive t0 "
            f"{_v(inp, 'drive_t0', '.4g')} s); A/A0 {d.get('amplitude_ratio', math.nan):.6g}, Omega "
            f"{d.get('omega_ratio', math.nan):.6g}; A0 {_v(inp, 'free_amplitude', '.4g')} m, k1 {_v(inp, 'k1', '.4g')} "
            f"N/m, Q1 {_v(inp, 'q1', '.4g')} ({', '.join(sorted({v['source'] for v in inp.values()}))})"
        ]
        if d.get("sample_plus_paddle_ev") is not None:
            lines.append(f"the simulator's sample dissipation plus the paddle's damping: {d['sample_plus_paddle_ev']:.5g} eV "
                         f"(paddle {d['paddle_damping_ev']:.4g} eV); E_diss from A and phi counts both")  # fmt: skip
        return lines


def _v(inp: dict, k: str, fmt: str) -> str:
    e = inp.get(k)
    return "?" if e is None else format(e["value"], fmt)


def _taps(record: Record) -> int:
    """Complete taps in the record (0 for a record without contact, e.g. a free cantilever)."""
    from ...signals.taps import find_taps

    try:
        return len(find_taps(record.f).contact)
    except InputError:
        return 0
