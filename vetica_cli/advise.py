"""``vetica advise``: the settings under which the extraction recovers a given material.  The thesis's stated purpose is advice to experimentalists: which
set point, frequency and print step make the method work for *their* material (thesis
4.5-4.6, 5.2).

Given a material -- the SLS springs and dashpot, or glassy and rubbery moduli and a
relaxation time (converted at a stated penetration, :func:`material_from`) -- and
optionally the probe (``--set probe.k1=...``), a small study runs over the
experimentalist's knobs within the thesis's ranges (:data:`KNOBS`: drive frequency
``f1`` with ``f2 = 15 f1``, amplitude set point, print step, paddle stiffness ``k2``)
with the periodic-orbit solver, extracts every record with each method asked for, and
ranks the settings by their margin:

    margin of a method = min(1 - (|q error| + 2 sigma_q)/limit_q) over q = tau_c (limit 30 %),
                         k0, k_inf, cd (5 % each); sigma_q the method's relative 1-sigma [%]
    score of a setting = the smallest margin over the methods

so a setting *recovers the material* (score > 0 and no estimate flagged) when every
method keeps the retardation time within the acceptance regime's 30 % (thesis fig. 52,
:data:`vetica_cli.rows.schema.ACCEPT_ERR_PCT`) and each element within 5 %, its error
bar included, none of those estimates is flagged by the sanity checks (``unidentified``,
:mod:`vetica_cli.extraction.sanity`), and the record is a proven periodic state.

**Noise.**  The records carry the instrument's thermal noise (``temperature``, 300 K by
default on the command line: the Brownian force on both probe modes from the
fluctuation-dissipation theorem, :mod:`vetica_cli.simulation.thermal`; 0 = noise-free,
the thesis's records).  One noisy record per setting: the error of that one record could
be small by luck, so the margin counts the method's own 2-sigma with it -- a setting is
advised when the error *and* the error bar fit within the limits, which is what the
user will see on their instrument.

The cost: one simulation per setting, grouped by the print-step policy every batch
follows (:func:`vetica_cli.rows.plan.group`: points share a simulation only when they
differ in the extraction and the instrument keys, so each print step is its own run and
the record is exactly what ``vetica simulate`` with the setting gives), each record
extracted by every method.  The simulations run on the batch launcher (loky, ``jobs``
workers, one thread each).
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from . import surfaces
from .checks import CONFIRM_ITEMS, confirm_cost, finite, limit
from .ranges import check_range
from .errors import ConfigError, InputError
from .extraction import METHODS, SOURCES, extract, extract_many, extraction_modules
from .extraction.material import ContactModel, contact_model, stiffness
from .simulation.config import from_dict, load
from .simulation.cost import kernel_seconds
from .simulation.jit import compile_notice, simulation_modules
from .batch.launch import make_launcher
from .batch.progress import Progress
from .rows.plan import group
from .rows.schema import ACCEPT_ERR_PCT

if TYPE_CHECKING:  # pandas and the simulator (numba) load with the study: a refused input loads neither
    import pandas as pd

F2_RATIO = 15.0  # f2 = 15 f1 (thesis 4.5.1)
MAX_REPLICAS = 50  # --replicas: noisy records per setting
RECORD_CYCLES = 4  # drive periods recorded per setting (VETICA needs two complete taps in a row)
PARAM_LIMIT_PCT = 5.0  # [%] each of k0, k_inf, cd within this
LIMITS = {"tau_c": ACCEPT_ERR_PCT, "k0": PARAM_LIMIT_PCT, "k_inf": PARAM_LIMIT_PCT, "cd": PARAM_LIMIT_PCT}
DEFAULT_METHODS = ("vetica-prestress", "full")
DEFAULT_DEPTH = 2e-9  # [m] penetration at which moduli are turned into springs (the worked example's ~2.4 nm)
MATERIAL_KEYS = ("surface.model", "surface.k_inf", "surface.k0", "surface.cd")


@dataclass(frozen=True)
class Knob:
    """One of the experimentalist's settings: its default values and the thesis's range."""

    default: tuple
    lo: float
    hi: float
    unit: str
    label: str


KNOBS = {
    "probe.f1": Knob((10e3, 20e3, 50e3, 100e3), 10e3, 100e3, "Hz",
                     "drive frequency f1, with f2 = 15 f1 (thesis table 1, 4.5.1, figs. 51-52)"),
    "operation.setpoint": Knob((0.4, 0.6, 0.8), 0.25, 0.8, "", "amplitude set point A_sp/A0 (thesis table 1, fig. 54)"),
    "numerics.print_step": Knob((0.5e-9, 2e-9, 8e-9), 0.125e-9, 8e-9, "s", "print step (thesis table 1, figs. 59-61)"),
    "probe.k2": Knob((200.0, 700.0), 70.0, 1200.0, "N/m", "paddle stiffness k2 (thesis table 1: 70-700; fig. 30: 200-1200)"),
}  # fmt: skip
MAX_KNOB_VALUES = 20  # values of one knob: the defaults have 2-4, the thesis's figures 5-9 a range
SETTING_KEYS = ("probe.f1", "probe.f2", "operation.setpoint", "numerics.print_step", "probe.k2")


@dataclass(frozen=True)
class Material:
    """The SLS the advice is for, and how it was given."""

    k_inf: float  # [N/m]
    k0: float  # [N/m]
    cd: float  # [kg/s]
    given: str  # one line: the input and, for moduli, the conversion

    def overrides(self) -> dict:
        return {"surface.k_inf": self.k_inf, "surface.k0": self.k0, "surface.cd": self.cd}

    def theory(self) -> dict:
        return surfaces.get(surfaces.DEFAULT_MODEL).theory({"k_inf": self.k_inf, "k0": self.k0, "cd": self.cd})


def material_from(k_inf=None, k0=None, cd=None, e_glassy=None, e_rubbery=None, tau_r=None,
                  depth: float = DEFAULT_DEPTH, cm: ContactModel | None = None) -> Material:  # fmt: skip
    """The material from ``k_inf, k0, cd`` [N/m, N/m, kg/s], or from the glassy and rubbery
    sample moduli and the relaxation time [Pa, Pa, s]: each modulus acts as the spring
    ``K = 4/3 E* sqrt(R delta)`` at the penetration ``depth`` (thesis eqs. 90-92 with
    the contact ``cm``, :func:`vetica_cli.extraction.material.stiffness`), so ``k_inf =
    K(E_rubbery)``, ``k0 = K(E_glassy) - k_inf``, ``cd = tau_r k0``.  InputError (one
    line) for a missing, mixed or out-of-range input."""
    springs = {"--k-inf": k_inf, "--k0": k0, "--cd": cd}
    mods = {"--e-glassy": e_glassy, "--e-rubbery": e_rubbery, "--tau-r": tau_r}
    how = "give the material as --k-inf --k0 --cd [N/m, N/m, kg/s] or as --e-glassy --e-rubbery --tau-r [Pa, Pa, s]"
    s_given = [k for k, v in springs.items() if v is not None]
    m_given = [k for k, v in mods.items() if v is not None]
    if s_given and m_given:
        raise InputError(f"{' '.join(s_given)} and {' '.join(m_given)} mix two ways of giving the material; {how}")
    if len(s_given) == 3:
        vals = {k: check_range(k, v) for k, v in springs.items()}
        return Material(vals["--k-inf"], vals["--k0"], vals["--cd"],
                        f"k_inf {vals['--k-inf']:g} N/m, k0 {vals['--k0']:g} N/m, cd {vals['--cd']:g} kg/s")  # fmt: skip
    if len(m_given) == 3:
        eg, er, tr = (check_range(k, v) for k, v in mods.items())
        depth = check_range("--depth", depth)
        if not eg > er:
            raise InputError(
                f"--e-glassy {eg:g} must exceed --e-rubbery {er:g} (a relaxing solid: E_glassy > E_rubbery)"
            )
        cm = cm or ContactModel()
        k_inf = stiffness(er, depth, cm)
        k0 = stiffness(eg, depth, cm) - k_inf
        for name, k in (("k_inf", k_inf), ("k0", k0), ("cd", tr * k0)):  # the springs the moduli make, in range too
            check_range(f"surface.{name}", k, f"{name} {k:.4g} from --e-glassy --e-rubbery --tau-r at --depth {depth:g}")
        return Material(k_inf, k0, tr * k0,
                        f"E_glassy {eg:g} Pa, E_rubbery {er:g} Pa, tau_r {tr:g} s as springs at {depth * 1e9:g} nm "
                        f"(thesis eqs. 90-92, R {cm.tip_radius * 1e9:g} nm): k_inf {k_inf:.4g} N/m, k0 {k0:.4g} N/m, "
                        f"cd {tr * k0:.4g} kg/s")  # fmt: skip
    missing = [k for k in (springs if s_given else mods if m_given else {}) if k not in s_given + m_given]
    raise InputError((f"missing {' '.join(missing)}; " if missing else "no material given; ") + how)


def knob_values(given: dict | None) -> dict:
    """Values of every knob: the given lists (each value inside the thesis's range) or the
    defaults; ConfigError (one line) otherwise."""
    out = {}
    for key, knob in KNOBS.items():
        vals = (given or {}).get(key) or knob.default
        if len(vals) > MAX_KNOB_VALUES:
            raise ConfigError(f"{key}: {len(vals)} values are not allowed; expected at most {MAX_KNOB_VALUES} (each "
                              "value multiplies the simulations)")  # fmt: skip
        clean = []
        for v in vals:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ConfigError(f"{key}: {v!r} is not allowed; expected a number")
            if not knob.lo * (1 - 1e-9) <= v <= knob.hi * (1 + 1e-9):
                raise ConfigError(
                    f"{key}: {v:g} is not allowed; expected values within the thesis's range {knob.lo:g} .. {knob.hi:g} "
                    f"{knob.unit}".rstrip()
                )
            clean.append(float(v))
        out[key] = tuple(sorted(set(clean)))
    return out


def margin(errors: dict, sigmas: dict | None = None) -> float:
    """``min(1 - (|error| + 2 sigma)/limit)`` over :data:`LIMITS` (positive = recovered;
    errors and ``sigmas`` in %, no sigma = 0); nan when an error or a given sigma is unknown."""
    vals = [errors.get(k) for k in LIMITS]
    sig = [0.0 if sigmas is None else sigmas.get(k) for k in LIMITS]
    if any(v is None or not math.isfinite(v) for v in vals + sig):
        return math.nan
    return min(1.0 - (abs(v) + 2.0 * s) / lim for v, s, lim in zip(vals, sig, LIMITS.values()))


@dataclass(frozen=True)
class Setting:
    """One setting of the advice study: its resolved config (what :func:`vetica_cli.rows.plan.group` groups)."""

    config: object


def advise_task(item: dict) -> list[dict]:
    """Simulate the settings of one planned task (they share one simulation) and extract each
    with every method: one row per setting (module level: joblib pickles it).  Never
    raises: errors become rows with status 'failed'."""
    from .simulation.simulate import simulate

    cfgs, methods, force = item["configs"], item["methods"], item["force"]
    if item.get("replicas", 1) > 1:
        return [replicated_row(cfg_d, methods, force, item["replicas"]) for cfg_d in cfgs]
    t0 = time.perf_counter()
    try:
        run = simulate(from_dict(cfgs[0]))
        err = ""
    except Exception as exc:  # noqa: BLE001 - a failed setting becomes rows
        run, err = None, f"simulate: {type(exc).__name__}: {exc}"
    sim_wall = time.perf_counter() - t0
    rows = []
    for cfg_d in cfgs:
        row = _empty_row(cfg_d, methods, err, sim_wall / len(cfgs))
        if run is not None:
            _extract_row(row, run, methods, force)
        margins = [row[f"{m}.margin"] for m in methods]
        row["score"] = min(margins) if row["status"] == "ok" and all(math.isfinite(v) for v in margins) else math.nan
        flagged = any(row[f"{m}.flagged"] for m in methods)
        row["recovered"] = bool(row["score"] > 0 and not flagged) if math.isfinite(row["score"]) else False
        rows.append(row)
    return rows


def _empty_row(cfg_d: dict, methods, err: str, sim_wall: float) -> dict:
    row = {**{k: cfg_d[k.split(".")[0]][k.split(".")[1]] for k in SETTING_KEYS}, "status": "failed",
           "stop_reason": "", "error": err, "sim_wall_s": sim_wall, "extract_wall_s": 0.0}  # fmt: skip
    for m in methods:
        for q in LIMITS:
            row[f"{m}.{q}_err_pct"] = math.nan
            row[f"{m}.{q}_sigma_pct"] = math.nan
        row[f"{m}.margin"] = math.nan
        row[f"{m}.flagged"] = ""
        row[f"{m}.why"] = ""
    return row


def replicated_row(cfg_d: dict, methods, force: str, n: int) -> dict:
    """One setting recorded ``n`` times with independent noise (``--replicas``;
    :func:`vetica_cli.simulation.simulate.replica_set`): each record extracted as a single one is,
    then the row holds, per method, the replicas' median error and median sigma of each quantity,
    the quantities flagged in more than half of them, the most frequent reason, and the margin of
    the medians; ``status`` ok when every replica's is."""
    from .simulation.simulate import replica_set

    t0 = time.perf_counter()
    try:
        _, runs = replica_set(from_dict(cfg_d), n)
    except Exception as exc:  # noqa: BLE001 - a failed setting becomes a row
        row = _empty_row(cfg_d, methods, f"simulate: {type(exc).__name__}: {exc}", time.perf_counter() - t0)
        row["replicas"] = n
        return row
    sim_wall = time.perf_counter() - t0
    rows = []
    for run in runs:
        r = _empty_row(cfg_d, methods, "", sim_wall / n)
        _extract_row(r, run, methods, force)
        rows.append(r)
    out = dict(rows[0])
    out["status"] = "ok" if all(r["status"] == "ok" for r in rows) else next(r["status"] for r in rows if r["status"] != "ok")
    out["error"] = next((r["error"] for r in rows if r["error"]), "")
    out["extract_wall_s"] = sum(r["extract_wall_s"] for r in rows)
    out["replicas"] = n
    for m in methods:
        errs, sigs = {}, {}
        for q in LIMITS:
            e = np.array([r[f"{m}.{q}_err_pct"] for r in rows], float)
            sg = np.array([r[f"{m}.{q}_sigma_pct"] for r in rows], float)
            errs[q] = float(np.nanmedian(e)) if np.isfinite(e).any() else None
            sigs[q] = float(np.nanmedian(sg)) if np.isfinite(sg).any() else None
            out[f"{m}.{q}_err_pct"] = math.nan if errs[q] is None else errs[q]
            out[f"{m}.{q}_sigma_pct"] = math.nan if sigs[q] is None else sigs[q]
        out[f"{m}.margin"] = margin(errs, sigs)
        out[f"{m}.flagged"] = ",".join(q for q in LIMITS
                                       if sum(q in r[f"{m}.flagged"].split(",") for r in rows) > n / 2)  # fmt: skip
        whys = [r[f"{m}.why"] for r in rows if r[f"{m}.why"]]
        out[f"{m}.why"] = max(set(whys), key=whys.count) if len(whys) > n / 2 else ""
    margins = [out[f"{m}.margin"] for m in methods]
    out["score"] = min(margins) if out["status"] == "ok" and all(math.isfinite(v) for v in margins) else math.nan
    flagged = any(out[f"{m}.flagged"] for m in methods)
    out["recovered"] = bool(out["score"] > 0 and not flagged) if math.isfinite(out["score"]) else False
    return out


def _extract_row(row: dict, run, methods, force: str) -> None:
    df, meta = run.frame(), run.metadata()
    row["stop_reason"] = run.stop_reason
    row["status"] = "ok" if run.steady_ok else "not_steady"
    errors = []
    t0 = time.perf_counter()
    try:  # one record (one force reconstruction) for every method
        results = extract_many(df, meta, force, {m: {} for m in methods})
    except Exception:  # noqa: BLE001 - then method by method, to say which one failed
        results = {}
    for m in methods:
        res = results.get(m)
        if res is None:
            try:
                res = extract(df, meta, force=force, method=m)
            except Exception as exc:  # noqa: BLE001
                errors.append(f"{m}: {type(exc).__name__}: {exc}")
                continue
        errs = {q: res.estimates[q].error_pct for q in LIMITS}
        sigs = {q: None if res.estimates[q].sigma is None else 100.0 * res.estimates[q].sigma for q in LIMITS}
        for q, v in errs.items():
            row[f"{m}.{q}_err_pct"] = math.nan if v is None else float(v)
            row[f"{m}.{q}_sigma_pct"] = math.nan if sigs[q] is None else float(sigs[q])
        row[f"{m}.margin"] = margin(errs, sigs)
        row[f"{m}.flagged"] = ",".join(q for q in LIMITS if res.estimates[q].identifiable is False)
        row[f"{m}.why"] = defeat(res, errs, sigs)
    row["extract_wall_s"] = time.perf_counter() - t0
    row["error"] = "; ".join(" ".join(e.split())[:300] for e in errors)


def defeat(res, errs: dict, sigs: dict) -> str:
    """What keeps a method from recovering the material on one setting, in a few words ('' when
    nothing does): the first flag's reason (the checks name the cause: the surface pull the
    thesis's stages ignore, taps read in noise, a force band that does not resolve the contact,
    a quantity the record does not determine), else the quantity whose error or error bar
    leaves the limits -- ``noise`` when its 2-sigma alone does, its ``error`` otherwise."""
    for q in LIMITS:
        e = res.estimates[q]
        if e.identifiable is False and e.reason:
            return f"{q}: {e.reason}"[:120]
    worst, why = math.inf, ""
    for (q, v), lim in zip(errs.items(), LIMITS.values()):
        s = sigs.get(q)
        if v is None:
            return f"{q}: no estimate"
        m = 1.0 - (abs(v) + 2.0 * (s or 0.0)) / lim
        if m < worst:
            worst = m
            why = (f"{q}: noise (2 sigma {2 * s:.2g} % of a {lim:g} % limit)" if s and 2.0 * s > lim
                   else f"{q}: error {v:+.2g} % (limit {lim:g} %, 2 sigma {2 * (s or 0.0):.2g} %)")  # fmt: skip
    return why if worst <= 0 else ""


@dataclass
class Advice:
    """What ``vetica advise`` found."""

    material: Material
    methods: tuple
    force: str
    knobs: dict  # key -> values tried
    table: pd.DataFrame  # one row per setting (SETTING_KEYS, per-method errors and margins, score, status)
    base: dict  # the resolved base config (probe, operation, numerics) the settings change
    wall_s: float = 0.0
    jobs: int = 2
    simulations: int = 0
    notes: list = field(default_factory=list)

    def settings(self) -> list[dict]:
        """The settings that recover the material, best first: ``{dotted key: value, ..., "score"}``
        (every key but ``score`` is a config key ``vetica simulate --set`` takes)."""
        ok = self.table[self.table["recovered"]].sort_values("score", ascending=False, kind="mergesort")
        return [{**{k: _plain(r[k]) for k in SETTING_KEYS}, "score": float(r["score"])} for _, r in ok.iterrows()]


def _plain(v):
    return float(v) if isinstance(v, (float, np.floating, int, np.integer)) else v


def base_config(material: Material, overrides: dict | None = None) -> dict:
    """The resolved config the knobs vary: defaults, the material, then ``overrides``
    (``--set``; not a knob or a material key), with ``record_cycles`` = :data:`RECORD_CYCLES`
    unless given.  ConfigError (one line) for a bad key or value."""
    overrides = dict(overrides or {})
    for key in overrides:
        if key in KNOBS or key == "probe.f2":
            raise ConfigError(f"--set {key}: the key is a knob of the advice; give its values with the knob's option")
        if key in MATERIAL_KEYS:
            raise ConfigError(f"--set {key}: the material is given by --k-inf --k0 --cd (or the moduli)")
    overrides.setdefault("numerics.record_cycles", RECORD_CYCLES)
    return load(None, {**material.overrides(), **overrides}).to_dict()


def advise(material: Material, overrides: dict | None = None, knobs: dict | None = None,
           methods=DEFAULT_METHODS, force: str = "reconstructed", jobs: int = 2, progress: bool = False,
           yes: bool = False, replicas: int = 1) -> Advice:  # fmt: skip
    """Run the advice study (module docstring) and rank its settings.

    ``overrides``: ``--set`` keys of the probe, operation, numerics or surface attraction
    (``numerics.temperature`` [K]: the thermal noise of the records, 0 = none);
    ``knobs``: ``{knob key: values}`` replacing :data:`KNOBS` defaults; ``methods``:
    registered extraction methods that must all recover the material; ``force``: the
    force source extracted ('reconstructed' is what an instrument has); ``replicas``: noisy
    records per setting (:func:`replicated_row`; 1 = one record).  Every setting is
    checked as a config before any work starts (ConfigError/InputError, one line)."""
    if isinstance(replicas, bool) or not isinstance(replicas, int) or not 1 <= replicas <= MAX_REPLICAS:
        raise InputError(f"--replicas {replicas!r} is not allowed; expected an integer in 1..{MAX_REPLICAS}")
    methods = tuple(methods)
    if not methods:
        raise InputError("--methods: expected at least one method")
    for m in methods:
        if m not in METHODS:
            raise InputError(f"--methods: {m!r} is not a method; choose from: {', '.join(METHODS)}")
        own = METHODS[m].quantities(surfaces.get(surfaces.DEFAULT_MODEL))
        if not set(LIMITS) <= set(own):  # the instrument's numbers (observables, dmt-fit) do not estimate them
            able = [k for k, me in METHODS.items() if set(LIMITS) <= set(me.quantities(surfaces.get(surfaces.DEFAULT_MODEL)))]
            raise InputError(f"--methods: {m!r} does not estimate {', '.join(LIMITS)} (the material advise checks); "
                             f"choose from: {', '.join(able)}")  # fmt: skip
    twice = sorted({m for m in methods if methods.count(m) > 1})
    if twice:
        raise InputError(f"--methods: {', '.join(twice)} named twice; expected each method once")
    if force not in SOURCES:
        raise InputError(f"--force {force!r} not allowed; choose one of: {', '.join(SOURCES)}")
    values = knob_values(knobs)
    base = base_config(material, overrides)
    n = math.prod(len(v) for v in values.values())
    if n > CONFIRM_ITEMS:  # refused before n configs are built (160 000 took 13 s)
        confirm_cost(f"this advice ({n} settings)", 0.0, yes, n, "settings")
    settings = []
    for f1 in sorted(values["probe.f1"]):  # slow (low f1) settings first: the workers finish together
        for sp in values["operation.setpoint"]:
            for k2 in values["probe.k2"]:
                for ps in values["numerics.print_step"]:  # every setting a valid config before work starts
                    d = copy.deepcopy(base)
                    d["probe"].update(f1=f1, f2=F2_RATIO * f1, k2=k2)
                    d["operation"]["setpoint"] = sp
                    d["numerics"]["print_step"] = ps
                    try:
                        settings.append(Setting(from_dict(d)))
                    except ConfigError as exc:
                        raise ConfigError(f"setting f1 {f1:g} Hz, set point {sp:g}, print step {ps:g} s, k2 {k2:g} N/m: "
                                          f"{exc}") from None  # fmt: skip
    tasks = group(settings)
    seconds = sum(kernel_seconds(t.points[0].config) + len(t.points) * sum(METHODS[m].seconds_per_point for m in methods)
                  for t in tasks) * replicas  # fmt: skip
    if replicas > 1 and not (base.get("numerics") or {}).get("temperature"):
        raise InputError(f"--replicas {replicas}: the records are noise-free (--temperature 0); every replica would "
                         "be the same")  # fmt: skip
    confirm_cost(f"this advice ({len(settings)} settings, {len(tasks)} simulations on {jobs} worker(s))",
                 seconds / max(1, min(jobs, len(tasks))), yes, len(tasks), "simulations")  # fmt: skip
    items = [{"configs": [p.config.to_dict() for p in task.points], "methods": methods, "force": force,
              "replicas": replicas} for task in tasks]  # fmt: skip
    t0 = time.perf_counter()
    rows: list = [None] * len(items)
    bar = Progress(len(items), 0, 0, enabled=progress, name="advise", unit="simulations",
                   notice=compile_notice(simulation_modules(settings[0].config) | extraction_modules(methods, (force,)))
                   if progress else None)  # fmt: skip
    failed = 0

    def on_result(i, res):
        nonlocal failed
        rows[i] = res
        failed += sum(r["status"] == "failed" for r in res)
        bar.advance(1, failed)

    with make_launcher("loky", jobs) as launcher, bar:
        launcher.launch(advise_task, items, on_result)
    import pandas as pd  # here: an input refused before the study loads no pandas

    table = pd.DataFrame([r for rs in rows for r in rs])
    return Advice(material=material, methods=methods, force=force, knobs=values, table=table,
                  base={k: v for k, v in base.items() if k != "surface"}, wall_s=time.perf_counter() - t0, jobs=jobs,
                  simulations=len(items))  # fmt: skip


def contact_for(overrides: dict | None, contact: dict | None) -> ContactModel:
    """The contact model of a moduli input: table 6 with the probe's tip radius (``--set
    probe.tip_radius``) and ``--contact`` overrides."""
    radius = (overrides or {}).get("probe.tip_radius")
    if radius is not None:
        radius = finite("--set probe.tip_radius", radius, limit("probe.tip_radius", "a radius"))
    return contact_model(contact, radius)


def format_advice(adv: Advice, figure=None, top: int = 10) -> str:
    """The text report: the material, the criteria, what ran, and the ranked settings."""
    th = adv.material.theory()
    t = adv.table
    lines = [
        f"material: {adv.material.given} (tau_c {th['tau_c']:.4g} s, tau_r {th['tau_r']:.4g} s)",
        (
            f"criteria: tau_c error < {ACCEPT_ERR_PCT:g} %, k0, k_inf, cd within {PARAM_LIMIT_PCT:g} %, for "
            f"{' and '.join(adv.methods)} ({adv.force} force), error bar (2 sigma) included and no estimate "
            "flagged; score = smallest margin min(1 - (|error| + 2 sigma)/limit) over the methods"
        ),
        (f"records: thermal noise at {temperature_of(adv):g} K ({replicas_text(adv)})" if temperature_of(adv)
         else "records: noise-free (temperature 0 K; an instrument's are not: --temperature 300)"),
        f"{len(t)} settings ({adv.simulations} simulations, {RECORD_CYCLES} periods each) in {adv.wall_s:.1f} s on "
        f"{adv.jobs} worker(s): "
        + ", ".join(f"{m} recovers {recovered_by(t, m)}" for m in adv.methods)
        + f"; all of them: {int(t['recovered'].sum())}",
    ]
    n_bad = int((t["status"] != "ok").sum())
    if n_bad:
        lines.append(f"{n_bad} settings not counted (no proven periodic state or failed; see the table's status)")
    settings = adv.settings()
    head = f"{'rank':>4} {'score':>6} {'f1 [kHz]':>9} {'set point':>9} {'PS [ns]':>8} {'k2 [N/m]':>9}   "
    head += "   ".join(f"{m}: tau_c/k0/k_inf/cd error %" for m in adv.methods)
    if settings:
        lines += ["settings that recover the material, best first:", head]
        ranked = t[t["recovered"]].sort_values("score", ascending=False, kind="mergesort")
        lines += [_setting_line(i + 1, r, adv.methods) for i, (_, r) in enumerate(ranked.head(top).iterrows())]
        if len(settings) > top:
            lines.append(f"... {len(settings) - top} more (--json lists every one)")
    else:
        lines.append("no setting recovers the material; the closest:")
        lines.append(head)
        close = t.assign(_s=t["score"].fillna(-np.inf)).sort_values("_s", ascending=False, kind="mergesort")
        lines += [_setting_line(i + 1, r, adv.methods) for i, (_, r) in enumerate(close.head(3).iterrows())]
    if figure is not None:
        lines.append(f"wrote {figure}")
    return "\n".join(lines)


def recovered_by(t: pd.DataFrame, m: str) -> int:
    """Settings where method ``m`` alone recovers the material (margin > 0, nothing flagged)."""
    return int(((t[f"{m}.margin"] > 0) & (t[f"{m}.flagged"] == "")).sum())


def replicas_text(adv: Advice) -> str:
    n = int(adv.table["replicas"].iloc[0]) if "replicas" in adv.table and len(adv.table) else 1
    return "one noisy record per setting" if n == 1 else (f"{n} noisy records per setting: medians, and a quantity "
                                                          "flagged when more than half flag it")  # fmt: skip


def temperature_of(adv: Advice) -> float:
    """The records' temperature [K] (0: noise-free)."""
    return float((adv.base.get("numerics") or {}).get("temperature", 0.0) or 0.0)


def _setting_line(rank: int, r, methods) -> str:
    errs = "   ".join(
        "/".join("-" if not math.isfinite(r[f"{m}.{q}_err_pct"]) else f"{r[f'{m}.{q}_err_pct']:+.2g}" for q in LIMITS)
        for m in methods
    )
    why = "; ".join(f"{m} -- {r[f'{m}.why']}" for m in methods if r.get(f"{m}.why"))
    if why:
        errs += f"   ({why})"
    score = "-" if not math.isfinite(r["score"]) else f"{r['score']:.3f}"
    return (f"{rank:>4} {score:>6} {r['probe.f1'] / 1e3:>9g} {r['operation.setpoint']:>9g} "
            f"{r['numerics.print_step'] * 1e9:>8g} {r['probe.k2']:>9g}   {errs}")  # fmt: skip


def advice_json(adv: Advice, figure=None) -> dict:
    """``{"settings": [{dotted key: value, ..., "score"}, ...] (best first), "material",
    "criteria", "methods", "force", "evaluated", "recovered_by", "figure", "wall_s"}``."""
    t = adv.table
    return {
        "settings": adv.settings(),
        "material": {
            "k_inf": adv.material.k_inf,
            "k0": adv.material.k0,
            "cd": adv.material.cd,
            "given": adv.material.given,
        },  # fmt: skip
        "criteria": {
            "tau_c_err_pct": ACCEPT_ERR_PCT,
            "parameter_err_pct": PARAM_LIMIT_PCT,
            "score": "min over methods of min(1 - (|error| + 2 sigma)/limit); recovered: score > 0 and no estimate flagged",
        },  # fmt: skip
        "methods": list(adv.methods),
        "force": adv.force,
        "knobs": {k: list(v) for k, v in adv.knobs.items()},
        "evaluated": len(t),
        "recovered_by": {m: recovered_by(t, m) for m in adv.methods},
        "temperature_k": temperature_of(adv),
        "figure": None if figure is None else str(figure),
        "wall_s": adv.wall_s,
    }
