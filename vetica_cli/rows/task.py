"""The point task: simulate one point, or one group of points sharing a simulation
(:mod:`.plan`), and extract each point with each of its force sources, giving the rows
of a batch table (:mod:`.schema`).  A sweep's launcher runs it; a scan builds its
pixels' rows with :meth:`PointTask.rows_for_run`.

:class:`PointTask` holds the simulation and extraction functions it calls, so a
test passes a fake extraction (``PointTask(extract=fake)``) to
:func:`vetica_cli.study.sweep.run_sweep` instead of patching this module.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ..extraction import DEFAULT_METHOD, METHODS, ExtractionResult, extract
from ..simulation.config import Config, from_dict
from ..simulation.instrument import noise_free
from .plan import point_run
from .extract import point_sources
from .replicas import replica_columns, summarise
from .schema import MATERIAL_INPUTS, OBSERVABLES, sigma_names

if TYPE_CHECKING:
    from ..simulation.simulate import Run


def simulate(cfg: Config) -> Run:
    """:func:`vetica_cli.simulation.simulate.simulate`, imported at the first point: a dry run
    plans the tasks without loading numba and the kernels."""
    from ..simulation.simulate import simulate as run

    return run(cfg)


def replica_set(cfg: Config, n: int) -> tuple:
    """:func:`vetica_cli.simulation.simulate.replica_set`, imported at the first point."""
    from ..simulation.simulate import replica_set as made

    return made(cfg, n)


Item = tuple  # (point key, resolved config dict, extract.method, extract.force)
Rows = list  # of dicts keyed by schema.result_columns()


def extract_point(df, meta: dict, force: str, method: str) -> ExtractionResult:
    """The extraction a study row records: :func:`vetica_cli.extraction.extract` with the
    CLI's defaults (kg_points 10, low-pass at Nyquist)."""
    return extract(df, meta, force=force, method=method)


def _err_text(exc: BaseException) -> str:
    text = f"{type(exc).__name__}: {exc}".strip()
    return " ".join(text.split())[:500]


def _float(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def nan_row(cfg: Config, source: str, method: str = DEFAULT_METHOD) -> dict:
    """A row of a point that produced nothing yet: theory values from the point's surface
    model, everything else empty, status 'failed'."""
    model = cfg.surface.surface_model
    th = model.theory(cfg.surface.params)
    row: dict = {"method": method, "force_source": source}
    for name in {**model.quantities, **METHODS[method].quantities(model)}:  # the method's own too (observables)
        row[name] = math.nan
        row[f"{name}_theory"] = float(th[name]) if name in th else math.nan
        row[f"{name}_err_pct"] = math.nan
    for name in sigma_names(model):
        row[f"{name}_sigma_pct"] = math.nan
    row["unidentified"] = ""
    row["taps"] = -1
    for name in OBSERVABLES:
        row[name] = math.nan
    for name in MATERIAL_INPUTS:
        row[name] = math.nan
    row.update(stop_reason="", sim_time=math.nan, status="failed", error="", wall_s=0.0)
    return row


def fill_row(row: dict, res: ExtractionResult, fitted: tuple[str, ...]) -> None:
    """Copy an extraction's estimates into a row (``fitted``: the sigma columns)."""
    for name, e in res.estimates.items():
        if f"{name}_err_pct" not in row:  # a quantity the table has no column for (e.g. a fitted H)
            continue
        row[name] = _float(e.value)
        if e.theory is not None:
            row[f"{name}_theory"] = _float(e.theory)
        row[f"{name}_err_pct"] = _float(e.error_pct)
    for name in fitted:
        e = res.estimates.get(name)
        sigma = _float(e.sigma if e is not None else None)
        row[f"{name}_sigma_pct"] = 100.0 * sigma if math.isfinite(sigma) else math.nan
    row["unidentified"] = ",".join(k for k in fitted if k in res.estimates and res.estimates[k].identifiable is False)
    for name, v in res.references.items():  # theory-only values (ExtractionMethod.references)
        row[f"{name}_theory"] = _float(v)
    row["taps"] = int(res.taps if res.taps is not None else -1)
    for name, entry in MATERIAL_INPUTS.items():  # the record's contact: the material columns' inputs
        row[name] = _float(((res.material or {}).get(entry) or {}).get("value"))


def missing_estimates(row: dict, res: ExtractionResult) -> list[str]:
    """The quantities the method reports for which ``row`` holds no value (in report order)."""
    return [name for name in res.estimates if f"{name}_err_pct" in row and not math.isfinite(row[name])]


def row_status(steady_ok: bool, missing: list[str], res: ExtractionResult) -> tuple[str, str]:
    """``(status, error)`` of a row whose extraction returned: 'not_steady' when the record
    is not proven periodic, else 'no_estimate' when a reported quantity has no value, else
    'ok'.  A missing estimate's reason (the method's warnings) goes into ``error`` whatever
    the status, so a row without values always says why."""
    error = ""
    if missing:
        why = "; ".join(str(w) for w in res.warnings) or "the method returned no value"
        error = " ".join(f"no estimate of {', '.join(missing)}: {why}".split())[:500]
    if not steady_ok:
        return "not_steady", error
    return ("no_estimate" if missing else "ok"), error


def _empty_replica_columns(cfg: Config) -> dict:
    return dict.fromkeys(replica_columns(sigma_names(cfg.surface.surface_model)), math.nan)


def failed_rows(cfg: Config, exc: BaseException, where: str, wall: float, method: str, force: str) -> Rows:
    rows = []
    for source in point_sources(force):
        row = nan_row(cfg, source, method)
        row["error"] = f"{where}: {_err_text(exc)}"
        row["wall_s"] = wall
        rows.append(row)
    return rows


@dataclass(frozen=True)
class PointTask:
    """Simulate and extract the points of one planned task (picklable: module-level functions).

    ``simulate(cfg) -> Run`` and ``extract(df, meta, force, method) -> ExtractionResult``
    default to the real ones."""

    simulate: Callable[[Config], Run] = simulate
    extract: Callable[..., ExtractionResult] = extract_point
    replicas: int = 1  # sweep.replicas: each point recorded this many times with independent noise (rows.replicas)
    replica_set: Callable = replica_set  # (cfg, n) -> (noise-free reference run, [noisy runs])

    def __call__(self, items: list[Item]) -> list[tuple[str, Rows]]:
        """``items`` = ``(point key, resolved config dict, extract.method, extract.force)`` of
        the task's points, which share one simulation (:func:`.plan.plan`: they differ at
        most in the method and the instrument keys).  Returns ``[(point key, rows), ...]``.  Never raises for a point: errors become rows with
        status 'failed'."""
        cfgs = [from_dict(d) for _, d, _, _ in items]
        if self.replicas > 1:  # points of one config (other methods) share its replicas: the same seeds, the same records
            out, sets = [], {}
            for (key, d, method, force), cfg in zip(items, cfgs):
                ident = repr(sorted(cfg.to_dict().items()))
                if ident not in sets:
                    t0 = time.perf_counter()
                    try:
                        sets[ident] = (self.replica_set(cfg, self.replicas), None, time.perf_counter() - t0)
                    except Exception as exc:  # noqa: BLE001
                        sets[ident] = (None, exc, time.perf_counter() - t0)
                made, exc, wall = sets[ident]
                out.append((key, self.replicated_rows(cfg, method, force, made, exc, wall)))
            return out
        if len(items) == 1:
            (key, _, method, force), cfg = items[0], cfgs[0]
            return [(key, self.simulate_point(cfg, method, force))]
        t0 = time.perf_counter()
        shared, exc = None, None
        try:
            shared = self.simulate(noise_free(cfgs[0]))
        except Exception as e:  # noqa: BLE001
            exc = e
        sim_wall = time.perf_counter() - t0
        out = []
        for (key, _, method, force), cfg in zip(items, cfgs):
            if exc is not None:
                out.append((key, failed_rows(cfg, exc, "simulate", sim_wall, method, force)))
            else:
                out.append((key, self.rows_for_run(cfg, point_run(shared, cfg), sim_wall, method, force)))
        return out

    def simulate_point(self, cfg: Config, method: str, force: str) -> Rows:
        """One point on its own: simulate, then extract (``replicas`` > 1: :meth:`replicated_rows`)."""
        if self.replicas > 1:
            t0 = time.perf_counter()
            try:
                made, exc = self.replica_set(cfg, self.replicas), None
            except Exception as e:  # noqa: BLE001
                made, exc = None, e
            return self.replicated_rows(cfg, method, force, made, exc, time.perf_counter() - t0)
        t0 = time.perf_counter()
        try:
            run = self.simulate(cfg)
        except Exception as exc:  # noqa: BLE001
            return failed_rows(cfg, exc, "simulate", time.perf_counter() - t0, method, force)
        return self.rows_for_run(cfg, run, time.perf_counter() - t0, method, force)

    def replicated_rows(self, cfg: Config, method: str, force: str, made, exc, wall: float) -> Rows:
        """The point recorded :attr:`replicas` times with independent noise and once without
        (``made`` = :func:`vetica_cli.simulation.simulate.replica_set`'s ``(reference, runs)``, or
        the exception ``exc`` it raised, in ``wall`` seconds), every record extracted, one row
        per force source summarising the replicas (:func:`vetica_cli.rows.replicas.summarise`)."""
        if made is None:
            rows = failed_rows(cfg, exc, "simulate", wall, method, force)
            return [{**r, **_empty_replica_columns(cfg), "replicas": self.replicas} for r in rows]
        reference, runs = made
        sim_wall = wall / (len(runs) + 1)
        fitted = sigma_names(cfg.surface.surface_model)
        out = []
        for source in point_sources(force):
            try:
                ref = self.extract(reference.frame(), reference.metadata(), source, method)
            except Exception:  # noqa: BLE001 - no reference: coverage unknown, the rows still say the rest
                ref = None
            rows, results = [], []
            for run in runs:
                row = self.rows_for_run(cfg, run, sim_wall, method, source)
                row = next(r for r in row if r["force_source"] == source)
                rows.append(row)
            out.append(summarise(rows, results, ref, fitted))
        return out

    def rows_for_run(self, cfg: Config, run: Run, sim_wall: float, method: str, force: str) -> Rows:
        """Extract a finished run with each force source -> one row each."""
        df, meta = run.frame(), run.metadata()
        fitted = sigma_names(cfg.surface.surface_model)
        rows = []
        for source in point_sources(force):
            row = nan_row(cfg, source, method)
            for name in OBSERVABLES:
                v = run.observables.get(name)
                row[name] = math.nan if v is None else float(v)
            row["stop_reason"] = run.stop_reason
            row["sim_time"] = float(run.info["t_end"])
            t0 = time.perf_counter()
            try:
                res = self.extract(df, meta, source, method)
                fill_row(row, res, fitted)
                row["status"], row["error"] = row_status(run.steady_ok, missing_estimates(row, res), res)
            except Exception as exc:  # noqa: BLE001 - a failed point becomes a row
                row["status"] = "failed"
                where = source if method == DEFAULT_METHOD else f"{source}, {method}"
                row["error"] = f"extract({where}): {_err_text(exc)}"
            row["wall_s"] = sim_wall + (time.perf_counter() - t0)
            rows.append(row)
        return rows
