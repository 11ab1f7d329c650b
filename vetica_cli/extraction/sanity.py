"""No silent wrong answer: identifiability and sanity checks on every method's result
(:func:`check`, applied by :func:`vetica_cli.extraction.extract_many` after the
standard errors of :mod:`.uncertainty`).  A check that fails flags the quantities it
concerns ``identifiable = False`` with the reason (the table's ``unidentified``
column, ``NOT IDENTIFIABLE`` in the text table); the values stay, so a study can
still plot them.

Checks, each against something the record itself shows:

* **parameter at a bound** -- VETICA's stage 2 puts ``Kr`` in ``(0, Kg)``; at either
  end the least squares found no interior minimum (``k_r, k_inf, k0, cd, tau_r``).
* **condition of stage 1a** -- ``tau_c = -dt/ln r`` from the creep ``1 - r`` between
  taps; below ``CREEP_MIN`` the ratio's relative error is amplified by ``~1/(1 - r)``
  (the condition number) and a dashpot that barely creeps also barely relaxes in a
  contact, so everything but Kg is flagged (seen: 16:1 and 64:1 at cd 1e-2 and 1e-1
  kg/s, cd +13 .. +29 % with a 1-sigma of 1-2 %).
* **stages that disagree** -- VETICA's stages 1b and 2 assume the Maxwell arm unstressed
  at contact; ``vetica-prestress`` re-runs them with the pre-stress the record shows.
  Where the two differ by more than 3 sigma (vetica's) and ``DISAGREE`` relative, the
  thesis's stages are biased on this record (e.g. k_inf +13 % with the surface pull)
  and the differing quantities of ``vetica`` are flagged.
* **uncertainty** -- a relative 1-sigma above 100 % (the record does not determine the
  quantity).
* **what a flagged stage feeds** -- VETICA's stage 2 and the elements are computed from
  stage 1a's ``tau_c`` and stage 1b's ``Kg``: a flag on either (other than the disagreement
  between the two VETICA variants) flags ``Kr, k0, k_inf, cd, tau_r`` too, whatever their
  own propagated sigma says (seen: tau_c at 1.04 sigma, cd +26 % at 6 % sigma, unflagged).
* **residual against the noise floor** -- the model must explain the force to the
  record's noise: stage 2's force residual (VETICA: largest over taps) or the
  whole-cycle fit's RMS residual above ``RESIDUAL_FACTOR`` x the force noise floor
  plus ``MODEL_FLOOR`` of the peak force means the model does not describe the
  record (e.g. VETICA without the pre-stress on a surface that feels the pull), and
  its estimates carry a bias the 1-sigma does not.  Noise floor: the white part of
  the force record, from the median absolute second difference
  (``1.4826 MAD / sqrt(6)``; the force's own curvature at the print step is far
  below it).
* **more taps than oscillation cycles** -- a steady tapping record has at most one tap per
  cycle of the tip; a force in which :func:`~vetica_cli.signals.taps.find_taps` finds more
  taps than the tip's position shows cycles (plus one for the record's ends) is read in its
  noise (seen: a force reconstructed from a paddle signal with 1 pm of detector noise, noise
  floor 0.2 mN against an 80 nN tap, ~300 "taps" in 6 cycles, VETICA's Kg off by 1e3-1e5 %
  at a 1-sigma of 50-75 %): every quantity of a method that reads taps (``TAP_READERS``) is
  flagged.
* **surface height fitted, dashpot that hardly creeps** -- the whole-cycle fit with the
  surface height free tells ``k_inf`` from the Maxwell arm only by the creep between
  taps; below ``CREEP_MIN`` of it (``1 - exp(-t_free/tau_c)``, t_free the time out of
  contact per tap) a record fits as well with the stiffness split differently and the
  height moved (seen: 4:1, cd 1e-2 kg/s, k_inf +16 % at a residual of 1e-16 N), so
  everything but Kg is flagged.
* **Z1 estimates disagree** -- the whole-cycle fit finds the surface height without
  Z1; thesis eq. 84 brackets where the tip meets the pulled surface, between
  ``a0 + Fa/Kg`` (glassy lift) and ``a0 + Fa/Kr`` (rubbery lift).  A fitted contact
  height outside that bracket (by more than ``Z1_TOL`` plus 3x the position noise
  floor) means the fit traded the height against the surface's stiffness.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..signals.slopes import NOISE_SAMPLES, noise_floor  # noqa: F401  (re-exported: the white-noise RMS of a signal)
from .result import ExtractionResult

TOLERANCE = 0.10  # an estimate likely off by more than this (relative) is flagged: "likely wrong"
REL_LIMIT = 1.0  # relative 1-sigma above which a quantity is not determined
TAP_MODEL_FLOOR = 0.25  # a tap method's stage-2 residual above this fraction of the peak force: not the model
RESIDUAL_FACTOR = 3.0  # residual RMS above this many force noise floors ...
MODEL_FLOOR = 1e-2  # ... plus this fraction of the peak force: the model does not fit (0.1 % flagged right fits:
# 0.13 % of the peak on a noise-free 7:1, k_inf 1.44 N/m record whose every parameter was within 1.3 %)
Z1_TOL = 0.02e-9  # [m] slack of the eq.-84 bracket
Z1_MODEL = 0.02e-9  # [m] Z1's model uncertainty: a tenth of the intermolecular distance (where the tip "meets" the
# undeformed surface is defined only to the scale of the force law's minimum; the worked example's adhesion lift is 0.06 nm)
CREEP_MIN = 0.02  # creep fraction between taps below which a fitted height and k_inf trade
KR_BOUND = 1e-6  # Kr within this fraction of Kg from 0 or Kg: at stage 2's bound
STAGE2 = ("k_r", "k_inf", "k0", "cd", "tau_r")
TAP_READERS = ("vetica", "vetica-prestress", "dmt-fit")  # methods whose every quantity is read from the taps
DISAGREEMENT = "VETICA and VETICA with the pre-stress at contact differ"  # the disagreement check's reason


def _creep(record) -> float | None:
    """Median creep fraction ``1 - (Z(i+1) - Z1)/(Z'i - Z1)`` between taps (thesis eq. 73's ratio)."""
    from ..signals.taps import find_taps

    if record.z1 is None:
        return None
    taps = find_taps(record.f)
    z, z1 = record.z, record.z1
    c = [1.0 - (z[taps.contact[i + 1]] - z1) / (z[taps.separation[i]] - z1)
         for i in range(len(taps.contact) - 1) if z[taps.separation[i]] != z1]  # fmt: skip
    return float(np.median(c)) if c else None


MAX_REASON = 200  # characters of a flag's reason


def _tau_c_z1_sensitivity(record) -> float | None:
    """Relative change of stage 1a's tau_c (the median over creep intervals of thesis eq. 73)
    when Z1 is offset by :data:`Z1_MODEL` (the larger of the two directions): with ``r = (Z(i+1)
    - Z1)/(Z'i - Z1)``, ``d ln tau_c / d Z1 = (1/(Z(i+1) - Z1) - 1/(Z'i - Z1)) / ln r``.  Large
    when the creep between taps is nearly complete (``Z(i+1)`` within picometres of Z1: the
    retardation time is far below the time out of contact) or nearly absent; None without Z1."""
    from ..signals.taps import find_taps

    if record.z1 is None:
        return None
    taps = find_taps(record.f)
    z, z1 = record.z, record.z1
    out = []
    for i in range(len(taps.contact) - 1):
        zs, zc = z[taps.separation[i]] - z1, z[taps.contact[i + 1]] - z1
        if not (zs != 0 and 0.0 < zc / zs < 1.0):
            continue
        lr = math.log(zc / zs)
        worst = 0.0
        for d in (Z1_MODEL, -Z1_MODEL):
            zs2, zc2 = zs - d, zc - d
            if not (zs2 != 0 and 0.0 < zc2 / zs2 < 1.0):
                worst = math.inf
                break
            worst = max(worst, abs(lr / math.log(zc2 / zs2) - 1.0))
        out.append(worst)
    return float(np.median(out)) if out else None


def _lift_bracket(res: ExtractionResult, record, options) -> dict:
    """``{quantity: relative change}`` beyond :data:`TOLERANCE` when a tap method's Z1 comes from
    thesis eq. 84 with the surface pull (``a0 + Fa/Kg``: the surface lifted by the adhesion
    against its glassy stiffness, as if the pull acted at once) and is moved to the lift the
    pull's duration gives: ``a0 + Fa/K(t_pull)``, ``K(t) = Kr + (Kg - Kr) exp(-t/tau_r)`` the
    method's own relaxation stiffness over ``t_pull``, the time the record's attraction takes
    from half its depth to the contact minimum (:func:`_pull_time`).  A quantity that moves by
    more than the tolerance between the two is not determined by eq. 84's Z1."""
    from .base import METHODS

    src = str(record.info.get("z1_source", ""))
    kg, kr, tau_r = res.value("k_g"), res.value("k_r"), res.value("tau_r")
    if not (src.startswith("thesis eq. 84") and "Fa(a0)/Kg" in src and record.z1 is not None and record.a0):
        return {}
    if not (kg and kr and 0 < kr < kg and tau_r and tau_r > 0):
        return {}
    fa = (record.z1 - record.a0) * kg
    k_pull = kr + (kg - kr) * math.exp(-_pull_time(record) / tau_r)  # the relaxation stiffness over the pull
    if not (k_pull < kg * (1.0 - 1e-9)):
        return {}
    z1 = record.a0 + fa / k_pull
    try:
        alt = METHODS[res.method].run(dataclasses.replace(record, z1=z1), options or {}).estimates
    except Exception:  # noqa: BLE001 - the method refuses the rubbery lift: it cannot be told either way
        return {q: math.inf for q, e in res.estimates.items() if e.value is not None and q != "k_g"}
    out = {}
    for q, e in res.estimates.items():
        a = alt.get(q)
        if e.value and a is not None and a.value is not None:
            rel = (a.value - e.value) / abs(e.value)
            if abs(rel) > TOLERANCE:
                out[q] = rel
        elif e.value and q != "k_g":
            out[q] = math.inf
    return out


def _height_freedom(res: ExtractionResult, record, options) -> dict:
    """``{quantity: (relative difference, the pinned fit's value)}`` beyond :data:`TOLERANCE` and 3
    sigma between the whole-cycle fit with the surface height free (its default on a record
    without an approach tap) and the same fit with the height pinned at the record's Z1 from
    thesis eq. 84.  The height, ``k_inf`` and a slow dashpot form a long valley of the least
    squares: under 300 K noise a free height wandered along it (k_inf +16 .. +70 % at a 1-sigma
    of 4 %, linearised) on a 29:1 surface whose creep between taps was 22 %, where the
    pinned and free fits disagree.  Only for a fit that freed the height from an eq.-84 Z1."""
    from .base import METHODS

    fit = res.info.get("fit") or {}
    src = str(record.info.get("z1_source", ""))
    if not (fit.get("surface_height_source") == "fitted (steady window)" and src.startswith("thesis eq. 84")):
        return {}
    method = METHODS.get(res.method)
    if method is None or "fit_offset" not in method.options_default:
        return {}
    try:
        alt = method.run(record, method.options({**(options or {}), "fit_offset": False})).estimates
    except Exception:  # noqa: BLE001 - the pinned fit fails: no comparison
        return {}
    out = {}
    for q, e in res.estimates.items():
        a = alt.get(q)
        if e.value is None or a is None or a.value is None or not a.value:
            continue
        rel = (e.value - a.value) / abs(a.value)
        if abs(rel) > TOLERANCE and abs(rel) > 3.0 * (e.sigma or 0.0):
            out[q] = (rel, float(a.value))
    return out


RESOLVE = 0.1  # the force's low-pass may smear a kink over at most this fraction of the contact
CONTACT_SHARE = 0.15  # ... counted as at most this fraction of the drive period (tapping contacts: 5-10 %)


def _contact_resolved(res: ExtractionResult, record, info: dict) -> None:
    """Flag every quantity a method reads from the force when the force's low-pass (the
    reconstruction's cut-off fc, chosen from the noise) smears a kink over more than
    :data:`RESOLVE` of the contact: ``1/(2 fc)`` against the median contact time.  At the `lab`
    preset's noise the cut-off fell to 0.5-1 MHz (0.5-1 us of smear) against contacts of ~1.4 us,
    and the methods' numbers were off by 100-700 % with sigmas that did not say so."""
    from ..errors import InputError
    from ..signals.taps import find_taps

    fc = record.info.get("cutoff_hz")
    if not fc or res.method in FORCE_FREE:
        return
    try:
        taps = find_taps(record.f)
    except InputError:
        return
    if not len(taps.contact):
        return
    h = (record.t[-1] - record.t[0]) / (len(record.t) - 1)
    # the contact as the taps show it, but no longer than RESOLVE_PERIOD of the drive period: a force read in
    # noise merges its runs into long "contacts" (seen: 10 us on a 20 us period at the lab preset)
    contact = min(float(np.median(taps.separation - taps.contact)), CONTACT_SHARE * taps.spacing) * h
    smear = 0.5 / fc
    info["smear_over_contact"] = smear / contact if contact > 0 else math.inf
    if contact > 0 and smear > RESOLVE * contact:
        _flag(res, list(res.estimates), f"the force's band ({fc / 1e6:.3g} MHz, set by its noise) smears the contact "
                                        f"over {smear * 1e9:.3g} ns of its {contact * 1e9:.3g} ns: not resolved")  # fmt: skip


FORCE_FREE = ("observables",)  # methods that do not read the force


def _pull_time(record) -> float:
    """The time [s] the tip's attraction acts before contact: median over the record's taps of
    the time from the force first falling below half the contact minimum's (attractive) force
    to the contact minimum."""
    from ..signals.taps import find_taps

    taps = find_taps(record.f)
    f, t = record.f, record.t
    out = []
    start = 0
    for ic, isep in zip(taps.contact, taps.separation):
        ic = int(ic)
        half = 0.5 * float(f[ic])
        if half >= 0:
            continue
        j = ic
        while j > start and f[j - 1] < half:
            j -= 1
        out.append(float(t[ic] - t[j]))
        start = int(isep)
    return float(np.median(out)) if out else 0.0


PULL_BIASED = ("tau_c", "k_r", "k_inf", "tau_r", "cd")  # what the surface pull biases in the thesis's stages
REFEREE_SIGMA = 0.5  # the whole-cycle fit referees a quantity it determines to this relative 1-sigma


def _referee(res: ExtractionResult, record) -> tuple[dict, set]:
    """``({quantity: (relative difference, the fit's value)}, the quantities it confirmed)`` where the whole-cycle fit on the same
    record (an independent formulation: the surface driven by the measured tip, the tip's pull
    modelled, every sample used) determines the quantity to :data:`REFEREE_SIGMA`, passes its own
    checks, and the tap method differs from it by more than :data:`TOLERANCE` and 2 combined sigma
    (the two answers apart beyond their 95 % intervals: on stripped records the fit's free surface
    height widens its sigma of tau_c to 15-80 % while VETICA's tau_c was +75 ... +110 % off).  The thesis's stages assume the surface
    does not feel the pull; on a surface that does, stage 1a's creep starts where the adhesion
    held the surface, not at the tip (seen: a 7:1 surface with k_inf 1.44 N/m, tau_c +38 %
    noise-free, which no check of the tap method itself showed).  The fit's result is kept on the
    record for the other tap method."""
    from .base import METHODS

    full = next((m for m in METHODS.values() if getattr(m, "referee", False)), None)
    model = getattr(record, "model", None)
    if full is None or model is None or model.key not in full.surface_models or not hasattr(record, "memo"):
        return {}, set()
    key = ("referee", id(record.f), record.z1)
    if key not in record.memo:
        try:
            fit = full.run(record, full.options({}))
            check(fit, record)  # its own checks (no referee for the fit): a flagged quantity referees nothing
            record.memo[key] = fit.estimates
        except Exception:  # noqa: BLE001 - the fit refuses the record: no referee
            record.memo[key] = {}
    alt = record.memo[key]
    out, judged = {}, set()  # judged: confirmed -- agreeing, and within the tolerance at 2 sigma of the fit's own
    for q, e in res.estimates.items():
        a = alt.get(q)
        if e.value is None or a is None or a.value is None or not a.value or a.identifiable is False:
            continue
        sf = a.sigma if a.sigma is not None else math.inf
        if not sf <= REFEREE_SIGMA:
            continue
        rel = (e.value - a.value) / abs(a.value)
        if abs(rel) > TOLERANCE and abs(rel) > 2.0 * math.hypot(e.sigma or 0.0, sf):  # apart beyond their 95 %
            out[q] = (rel, float(a.value))
        elif 2.0 * sf <= TOLERANCE:  # the fit is precise enough to confirm the value within the tolerance
            judged.add(q)
    return out, judged


def _flag(res: ExtractionResult, names, reason: str) -> None:
    """Flag the quantities ``names`` with ``reason``: a quantity keeps the first reason it was
    flagged for (the most basic check runs first) and counts the others, so every reason is one
    short line (at most :data:`MAX_REASON` characters) with no repeated text; every reason is in
    ``res.info['sanity']['flags']``."""
    est = dict(res.estimates)
    flags = res.info.setdefault("sanity_flags", {})
    for q in names:
        e = est.get(q)
        if e is None or e.value is None:
            continue
        seen = flags.setdefault(q, [])
        if reason in seen:
            continue
        seen.append(reason)
        why = reason if len(seen) == 1 else f"{seen[0]} (+{len(seen) - 1} more check{'s' if len(seen) > 2 else ''})"
        if len(why) > MAX_REASON:
            why = why[: MAX_REASON - 1] + "…"
        est[q] = dataclasses.replace(e, identifiable=False, reason=why)
    res.estimates = est


def _taps_against_cycles(res: ExtractionResult, record, info: dict, floor_f: float, peak: float) -> None:
    """Flag every quantity when the force shows more taps than the tip shows oscillation
    cycles, plus one (module docstring)."""
    from ..errors import InputError
    from ..signals.taps import find_taps, oscillation_cycles

    cycles = oscillation_cycles(record.z)
    try:
        n = len(find_taps(record.f).contact)
    except InputError:  # fewer than two taps: the method itself refused or said so
        return
    info["taps"], info["oscillation_cycles"] = n, cycles
    if n > cycles + 1:
        _flag(res, list(res.estimates), f"{n} taps in {cycles} oscillation cycles of the tip: taps read in noise (noise "
                                        f"{floor_f:.3g} N, peak {peak:.3g} N)")  # fmt: skip


def _disagreement(res: ExtractionResult, record, options: dict) -> dict:
    """``{quantity: relative difference}`` where ``vetica`` and ``vetica-prestress`` differ
    beyond 3 combined sigma and :data:`DISAGREE` (module docstring)."""
    from .base import METHODS

    other = METHODS.get("vetica-prestress")
    if other is None:
        return {}
    opts = other.options({k: v for k, v in (options or {}).items() if k in other.options_default})
    try:
        alt = other.run(record, opts).estimates  # its own sigma not computed: the test uses vetica's
    except Exception:  # noqa: BLE001 - the other stages refuse the record: nothing to compare
        return {}
    out = {}
    for q, e in res.estimates.items():
        a = alt.get(q)
        if e.value is None or a is None or a.value is None:
            continue
        rel = (e.value - a.value) / abs(a.value)
        if abs(rel) > TOLERANCE and abs(rel) > 3.0 * (e.sigma or 0.0):
            out[q] = rel
    return out


def check(res: ExtractionResult, record, options: dict | None = None) -> ExtractionResult:
    """Run the checks of the module docstring on ``res`` (in place); the numbers behind
    them go to ``info['sanity']``."""
    f = np.asarray(record.f, float)
    peak = float(np.max(np.abs(f))) or 1.0
    floor_f = noise_floor(f)
    floor_z = noise_floor(record.z)
    limit = RESIDUAL_FACTOR * floor_f + MODEL_FLOOR * peak
    info = {"force_noise_floor_n": floor_f, "position_noise_floor_m": floor_z, "residual_limit_n": limit}
    est = res.estimates
    val = {k: e.value for k, e in est.items()}
    if res.method in TAP_READERS:
        _taps_against_cycles(res, record, info, floor_f, peak)
    if res.method in ("vetica", "vetica-prestress"):
        kg, kr = val.get("k_g"), val.get("k_r")
        if kg and kr is not None and (kr >= kg * (1 - KR_BOUND) or kr <= kg * KR_BOUND):
            _flag(res, STAGE2, f"stage 2's Kr = {kr:.4g} N/m sits at a bound of (0, Kg = {kg:.4g} N/m)")
        creep = _creep(record)
        info["creep_between_taps"] = creep
        if creep is not None and creep < CREEP_MIN:
            _flag(res, [q for q in est if q != "k_g"],
                  f"the surface creeps only {100 * creep:.2g} % between taps (< {100 * CREEP_MIN:g} %): tau_c "
                  f"ill-conditioned (x{1 / max(creep, 1e-300):.2g})")  # fmt: skip
        info["tau_c_per_z1_offset"] = _tau_c_z1_sensitivity(record)  # diagnosis only: Z1's noise is in sigma
        ref, judged = _referee(res, record)  # an independent formulation of the same quantities
        info["refereed"] = sorted(judged)
        info["whole_cycle_fit_difference"] = ref
        for q, (rel, value) in ref.items():
            _flag(res, [q], f"the whole-cycle fit gives {value:.4g} ({100 * rel:+.3g} %): the thesis's stages "
                            "misread this record")  # fmt: skip
        if record.vdw_on_surface is not False:  # the thesis's assumption broken, and nothing to confirm the result
            unconfirmed = [q for q in PULL_BIASED if q in est and q not in judged and q not in ref]
            _flag(res, unconfirmed, "the surface feels the tip's pull, which the thesis's stages ignore (tau_c +30 .. "
                                    "+100 % seen), and the whole-cycle fit cannot confirm this value")  # fmt: skip
        # the weaker checks judge only what the fit cannot (it measures the error they bound)
        lift = {q: v for q, v in _lift_bracket(res, record, options).items() if q not in judged}
        info["z1_lift_bracket"] = lift
        for q, rel in lift.items():
            _flag(res, [q], f"Z1 from thesis eq. 84: with the surface's lift over the pull's duration instead of the "
                            f"glassy one it moves {100 * rel:+.3g} %")  # fmt: skip
        if res.method == "vetica":
            diff = {q: v for q, v in _disagreement(res, record, options).items() if q not in judged}
            info["vetica_prestress_difference"] = diff
            for q, rel in diff.items():
                _flag(res, [q], f"{DISAGREEMENT} by {100 * rel:+.3g} %: the thesis's stages are biased here")
        rms = (res.diagnostics or {}).get("force_fit_rms_n")
        gross = RESIDUAL_FACTOR * floor_f + TAP_MODEL_FLOOR * peak
        info["residual_n"], info["residual_limit_n"] = rms, gross
        if rms is not None and rms > gross:
            _flag(res, list(est), f"stage 2's force residual {rms:.3g} N is {rms / peak:.2g} of the peak force: "
                                  "the model does not describe this record")  # fmt: skip
    else:
        fit = res.info.get("fit") or {}
        pct = fit.get("residual_rms_pct")
        if pct is not None:
            rms = pct / 100.0 * peak
            info["residual_n"] = rms
            if rms > limit:
                _flag(res, list(est), f"the fit's RMS residual {rms:.3g} N exceeds {RESIDUAL_FACTOR:g} x the noise "
                                      f"({floor_f:.3g} N) + {MODEL_FLOOR:g} x the peak force")  # fmt: skip
        tau_c = val.get("tau_c")
        if fit.get("surface_height_source") == "fitted (steady window)" and tau_c and tau_c > 0:
            from ..signals.taps import find_taps

            taps = find_taps(f)
            if len(taps.contact) >= 2:
                dt = float(np.median(np.diff(record.t)))
                period = float(np.median(np.diff(taps.contact))) * dt
                t_free = period - float(np.median(taps.separation - taps.contact)) * dt
                creep = -math.expm1(-t_free / tau_c)
                info["creep_between_taps"] = creep
                if creep < CREEP_MIN:
                    _flag(res, [q for q in est if q != "k_g"],
                          f"height fitted, creep {100 * creep:.2g} % between taps (< {100 * CREEP_MIN:g} %): k_inf "
                          "and the arm trade against it; pass --z1 to pin it")  # fmt: skip
        pinned = _height_freedom(res, record, options)
        info["height_pinned_difference"] = pinned
        for q, (rel, value) in pinned.items():
            _flag(res, [q], f"with the height pinned at eq. 84's Z1 the fit gives {value:.4g} ({100 * rel:+.3g} %): the "
                            "record does not fix the surface height")  # fmt: skip
        height = fit.get("surface_height_m")
        kg, kr = val.get("k_g"), val.get("k_inf")
        if record.z1 is None and height is not None and record.a0 and kg and kr and kg > 0 and kr > 0:
            fa = max(-float(np.min(f)), 0.0)
            z_fit = height + record.a0
            lo, hi = record.a0 + fa / kg - Z1_TOL, record.a0 + fa / kr + Z1_TOL
            slack = 3.0 * floor_z
            info["z1_fit_m"], info["z1_bracket_m"] = z_fit, [lo + Z1_TOL, hi - Z1_TOL]
            if not (lo - slack <= z_fit <= hi + slack):
                _flag(res, list(est), f"fitted contact height {z_fit * 1e9:.3g} nm outside thesis eq. 84's "
                                      f"bracket {(lo + Z1_TOL) * 1e9:.3g} .. {(hi - Z1_TOL) * 1e9:.3g} nm")  # fmt: skip
    _contact_resolved(res, record, info)
    band = ((res.info.get("uncertainty") or {}).get("band") or {})
    info["band_bias"] = band.get("bias")
    judged = set(info.get("refereed") or ())
    for q, b in ((q, b) for q, b in (band.get("bias") or {}).items() if q not in judged):  # refereed: the fit judges
        if b > TOLERANCE:
            _flag(res, [q], f"the force's band ({band['cutoff_hz'] / 1e6:.3g} MHz, set by its noise) biases it by "
                            f"~{100 * b:.2g} %: the contact is not resolved")  # fmt: skip
    for q, e in res.estimates.items():
        if e.value is not None and e.sigma is not None and not (e.sigma <= REL_LIMIT):
            if e.identifiable is not False:
                _flag(res, [q], f"relative 1-sigma {e.sigma:.3g} > {REL_LIMIT:g}: not determined by the record")
    if res.method in ("vetica", "vetica-prestress"):  # stage 2 and the elements are computed from tau_c and Kg
        for stage in ("tau_c", "k_g"):
            e = res.estimates.get(stage)
            if e is not None and e.value is not None and e.identifiable is False and not str(e.reason).startswith(
                    DISAGREEMENT):  # fmt: skip
                _flag(res, [q for q in STAGE2 if q in res.estimates], f"computed from {stage}, which is flagged")
    info["flags"] = res.info.pop("sanity_flags", {})
    res.info = {**res.info, "sanity": info}
    return res
