"""Parametric sweeps: ``run_sweep(study, output)`` (``vetica sweep CONFIG``).

One *point* of a study (see :mod:`vetica_cli.grid`) is simulated once and then
extracted twice, with the simulator's true force and with the force
reconstructed from the paddle signal (SPEC 6-7), giving two rows of a tidy
table.  The point's ``extract.method`` (``vetica``, the default, or ``full``,
the whole-cycle inversion of :mod:`vetica_cli.fullfit`) chooses the
extraction; the table's ``method`` column records it.  ``extract.force``
(``both``, ``true`` or ``reconstructed``) restricts the force sources.  Points fan out to joblib workers (loky by default, or a Dask cluster
through joblib's dask backend); inner numba/BLAS threads are capped at one per
worker so two workers use two cores.

Nothing is lost:

* a point whose simulation or extraction raises becomes a row with
  ``status = 'failed'`` and the error text (the simulation's columns are kept
  when only the extraction failed); the other points run on;
* every finished point is written at once, atomically, to
  ``<output>.parts/<point key>.parquet`` (the key is a hash of the resolved
  point config and the package version; the part also records a hash of the
  source that computed it, and a part from other code is recomputed), so a
  killed sweep run again computes only the missing points;
* the final table is assembled from the parts in grid order and written
  atomically, with the units, the resolved study config and the acceptance
  regime in its Parquet metadata; the config is also saved as
  ``<output stem>.config.yaml``.

Simulation sharing.  Points that differ only in ``extract.method`` or in the
instrument keys ``numerics.position_noise``, ``force_noise``, ``noise_seed``
and ``detector_bandwidth`` share one noise-free simulation: the method only
reads the record, and the instrument model
(:func:`vetica_cli.simulation.instrument.apply_instrument`) post-processes the recorded
signals after the kernel (the amplitude controller sees the noise-free
signal), so each point's record is the shared record with its own instrument
model applied: bit-identical to a separate simulation of that point.  This
is always on.

Print-step sharing (thesis 4.5.4: "all simulations use the same time step and
the resolution is altered by changing the print step"): points that differ
only in ``numerics.print_step`` can share one simulation recorded at the
finest print step; each coarser point takes every k-th sample of it, which are
exactly the samples a separate run at that print step would record *if* the
trajectory did not depend on the print step.  It does, slightly: the amplitude
controller measures ``(max - min)/2`` of the print-step samples once per drive
period, so the base height and the moment steady state is declared can differ
at the picometre level.  See ``benchmarks/notes/print_step_sharing.md`` for the
measured difference; sharing is on by default and can be switched off
(``share_print_step=False``, CLI ``--no-share-print-step``).
"""

from __future__ import annotations

import functools
import math
import os
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from . import __version__
from .errors import InputError
from .grid import EXTRACT_KEYS, Point, Study
from .simulation.config import from_dict
from .simulation.instrument import apply_instrument, noise_free
from .simulation.observables import OBSERVABLE_UNITS, compute_observables
from .simulation.simulate import Run, derive, simulate

SOURCES = ("true", "reconstructed")
METHODS = ("vetica", "full")  # extract.method: thesis 3.3 / whole-cycle inversion (vetica_cli.fullfit)
FITTED = ("k0", "k_inf", "cd")  # parameters the full method reports uncertainties and identifiability for
ESTIMATES = ("tau_c", "k_g", "k_r", "tau_r", "k0", "k_inf", "cd")
OBSERVABLES = (
    "e_diss_ev",
    "peak_force",
    "max_penetration",
    "contact_time",
    "noncontact_time",
    "paddle_amplitude",
    "ss_zero_depth",
    "amplitude",
    "phase_deg",
    "virial_ev",
    "z1",
)
STATUSES = ("ok", "not_steady", "failed")
ACCEPT_ERR_PCT = 30.0  # acceptance regime: tau_c error below 30 % (thesis fig. 52)
THREAD_VARS = ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")

ESTIMATE_UNITS = {
    "tau_c": "s",
    "k_g": "N/m",
    "k_r": "N/m",
    "tau_r": "s",
    "k0": "N/m",
    "k_inf": "N/m",
    "cd": "kg/s",
}


def result_columns() -> list[str]:
    """Columns a job fills for each (point, force source), in table order."""
    cols = ["method", "force_source"]
    for name in ESTIMATES:
        cols += [name, f"{name}_theory", f"{name}_err_pct"]
    cols += [f"{name}_sigma_pct" for name in FITTED]
    cols += ["unidentified", "taps", *OBSERVABLES, "stop_reason", "sim_time", "status", "error", "wall_s"]
    return cols


def column_units(study: Study) -> dict:
    units = {"point": "hash of the resolved point config (names its part file)"}
    for k in study.keys:
        if k not in EXTRACT_KEYS:
            units[k] = "swept key (SI, as in the config schema)"
    units["method"] = "extraction: vetica (thesis 3.3) | full (whole-cycle SLS inversion, issue 6); extract.method"
    units["force_source"] = "true = simulator f_ts; reconstructed = spectral inversion of the paddle signal"
    for name in ESTIMATES:
        u = ESTIMATE_UNITS[name]
        units[name] = f"{u}: VETICA estimate"
        units[f"{name}_theory"] = f"{u}: SLS theory value (SPEC 7)"
        units[f"{name}_err_pct"] = "%: 100 (estimate - theory) / theory, signed (tables before v0.2: its magnitude)"
    for name in FITTED:
        units[f"{name}_sigma_pct"] = (
            "%: relative 1-sigma of the full method's estimate (Jacobian; NaN for vetica or unbounded)"
        )
    units["unidentified"] = (
        "full method: fitted parameters flagged not identifiable, comma-separated ('' = none); always '' for vetica"
    )
    units["taps"] = "taps used by stage 1a"
    for name in OBSERVABLES:
        units[name] = OBSERVABLE_UNITS.get(name, "")
    units["stop_reason"] = "steady | max_time (numerics.max_time reached before steady state)"
    units["sim_time"] = "s: simulated time to steady state plus the recorded periods (or numerics.max_time)"
    units["status"] = "ok | not_steady (stop_reason max_time) | failed (see error)"
    units["error"] = "error text of a failed simulation or extraction"
    units["wall_s"] = (
        "s: wall time of the point's simulation (shared by the points of a print-step group) plus this row's extraction"
    )
    return units


# --------------------------------------------------------------------------- job


def theory(cfg) -> dict:
    """Theory values of the point's surface (its model's, e.g. the SLS's of SPEC 7)."""
    return cfg.surface.surface_model.theory(cfg.surface.params)


def _extract(df, meta, force, method="vetica"):
    """The real extraction (vetica_cli.extraction); tests may replace this."""
    from .extraction import extract

    return extract(df, meta, force=force, method=method, kg_points=10)


def _simulate(cfg):
    return simulate(cfg)


def _err_text(exc: BaseException) -> str:
    text = f"{type(exc).__name__}: {exc}".strip()
    return " ".join(text.split())[:500]


def _nan_row(cfg, source: str, method: str = "vetica") -> dict:
    th = theory(cfg)
    row: dict = {"method": method, "force_source": source}
    for name in ESTIMATES:
        row[name] = math.nan
        row[f"{name}_theory"] = float(th[name])
        row[f"{name}_err_pct"] = math.nan
    for name in FITTED:
        row[f"{name}_sigma_pct"] = math.nan
    row["unidentified"] = ""
    row["taps"] = -1
    for name in OBSERVABLES:
        row[name] = math.nan
    row.update(stop_reason="", sim_time=math.nan, status="failed", error="", wall_s=0.0)
    return row


def point_sources(force: str = "both") -> tuple:
    """Force sources extracted for a point with ``extract.force = force``, in table order."""
    return SOURCES if force == "both" else (force,)


def _rows_for_run(cfg, run, sim_wall: float, method: str = "vetica", force: str = "both") -> list[dict]:
    """Extract a finished run with each force source -> one row each."""
    df = run.frame()
    meta = run.metadata()
    rows = []
    for source in point_sources(force):
        row = _nan_row(cfg, source, method)
        for name in OBSERVABLES:
            v = run.observables.get(name)
            row[name] = math.nan if v is None else float(v)
        row["stop_reason"] = run.stop_reason
        row["sim_time"] = float(run.info["t_end"])
        t0 = time.perf_counter()
        try:
            res = _extract(df, meta, source) if method == "vetica" else _extract(df, meta, source, method=method)
            for name in ESTIMATES:
                e = res.estimates.get(name)
                if e is None:
                    continue
                row[name] = _float(e.value)
                if e.theory is not None:
                    row[f"{name}_theory"] = _float(e.theory)
                row[f"{name}_err_pct"] = _float(e.error_pct)
            for name in FITTED:
                e = res.estimates.get(name)
                sigma = _float(e.sigma if e is not None else None)
                row[f"{name}_sigma_pct"] = 100.0 * sigma if math.isfinite(sigma) else math.nan
            row["unidentified"] = ",".join(
                k for k in FITTED if k in res.estimates and res.estimates[k].identifiable is False
            )
            row["taps"] = int(res.taps if res.taps is not None else -1)
            row["status"] = "ok" if run.stop_reason == "steady" else "not_steady"
            row["error"] = ""
        except Exception as exc:  # noqa: BLE001 - a failed point becomes a row
            row["status"] = "failed"
            where = source if method == "vetica" else f"{source}, {method}"
            row["error"] = f"extract({where}): {_err_text(exc)}"
        row["wall_s"] = sim_wall + (time.perf_counter() - t0)
        rows.append(row)
    return rows


def _float(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def _failed_rows(cfg, exc: BaseException, where: str, wall: float, method: str = "vetica", force="both") -> list[dict]:
    rows = []
    for source in point_sources(force):
        row = _nan_row(cfg, source, method)
        row["error"] = f"{where}: {_err_text(exc)}"
        row["wall_s"] = wall
        rows.append(row)
    return rows


def _simulate_point(cfg, method: str = "vetica", force: str = "both") -> list[dict]:
    t0 = time.perf_counter()
    try:
        run = _simulate(cfg)
    except Exception as exc:  # noqa: BLE001
        return _failed_rows(cfg, exc, "simulate", time.perf_counter() - t0, method, force)
    return _rows_for_run(cfg, run, time.perf_counter() - t0, method, force)


def _subsample(fine, cfg_f, cfg_c):
    """The Run a separate simulation at cfg_c's (coarser) print step would record,
    taken from ``fine`` (recorded at cfg_f's print step), or None if the fine
    record does not hold every needed sample.

    The kernel stores a sample at every step index ``j * stride`` (``j >= 1``):
    the approach ring keeps the last ``n_ring`` samples up to the
    ``n_ring // 2``-th sample counted from the first sample at or after the
    first-contact step whose force is repulsive (or up to the start of the
    recorded window), and the steady window holds ``n_steady``
    samples after the recording-start step.  Both are rebuilt here from step
    indices.
    """
    n = cfg_c.numerics
    dt = n.dt
    dc = derive(cfg_c)
    s = dc.stride
    info = dict(fine.info)
    n_rec = round(info["t_record_start"] / dt)
    t_fc = info["t_first_contact"]
    j_rec = n_rec // s
    a_idx = np.rint(fine.approach[:, 0] / dt).astype(np.int64)
    pos = {int(v): i for i, v in enumerate(a_idx)}
    j_end = j_rec
    if t_fc is not None and not math.isnan(t_fc):
        n_fc = round(t_fc / dt)
        # first coarse sample after the first contact with a repulsive force
        rep = [int(v) // s for v, f in zip(a_idx, fine.approach[:, 5]) if v % s == 0 and v >= n_fc and f > 0.0]
        if rep:
            j_end = min(rep[0] + dc.n_ring // 2 - 1, j_rec)
        elif a_idx[-1] < n_rec - s:  # the fine window ended before any repulsive coarse sample
            return None
    j_start = max(1, j_end - dc.n_ring + 1)
    want = [j * s for j in range(j_start, j_end + 1)]
    if any(w not in pos for w in want):
        return None
    approach = fine.approach[[pos[w] for w in want]]
    s_idx = np.rint(fine.steady[:, 0] / dt).astype(np.int64)
    keep = ((s_idx - n_rec) % s) == 0
    steady = fine.steady[keep]
    if len(steady) != dc.n_steady:
        return None
    info["approach_written"] = float(j_end)
    run = Run(
        approach=approach,
        steady=steady,
        info=info,
        stop_reason=fine.stop_reason,
        params=cfg_c.to_dict(),
        wall_s=fine.wall_s,
    )
    compute_observables(run, cfg_c, dc)
    return run


def simulation_key(cfg) -> str:
    """Points with equal keys need the same simulation (they differ at most in the
    extraction method and the instrument keys)."""
    import json

    return json.dumps(noise_free(cfg).to_dict(), sort_keys=True)


def share_group_key(cfg) -> str | None:
    """Points with equal keys may share one simulation (they differ only in
    print step, extraction method and instrument keys, and their controller
    period is the same number of steps)."""
    import json

    cfg = noise_free(cfg)
    d = cfg.to_dict()
    d["numerics"].pop("print_step")
    d["numerics"].pop("approach_cycles")
    dv = derive(cfg)
    spp_steps = dv.samples_per_period * dv.stride
    # the controller period must be a whole number of print steps
    if abs(dv.samples_per_period * cfg.numerics.print_step - dv.period) > 1e-9 * dv.period:
        return None
    return json.dumps(
        {"cfg": d, "steps_per_period": spp_steps, "approach_cycles": cfg.numerics.approach_cycles}, sort_keys=True
    )


def fine_config(cfgs):
    """Config of the shared simulation, noise-free: the finest print step of the
    group, and an approach window two drive periods longer so it covers every
    coarser window; or, when every point has the same simulation
    (:func:`simulation_key`), exactly that simulation."""
    cfgs = [noise_free(c) for c in cfgs]
    if len({simulation_key(c) for c in cfgs}) == 1:
        return cfgs[0]
    finest = min(cfgs, key=lambda c: c.numerics.print_step)
    ps = [c.numerics.print_step for c in cfgs]
    for p in ps:
        k = p / finest.numerics.print_step
        if abs(k - round(k)) > 1e-9 * k:
            return None
    d = finest.to_dict()
    d["numerics"]["approach_cycles"] = min(20.0, finest.numerics.approach_cycles + 2.0)
    return from_dict(d)


def point_run(shared, scfg, cfg):
    """The Run a separate simulation of ``cfg`` would give, taken from ``shared``
    (the noise-free simulation of ``scfg``), or None if the shared record does not
    hold it: a copy when the simulations are the same, else the print-step
    subsample (:func:`_subsample`); then ``cfg``'s instrument model."""
    import copy

    if simulation_key(cfg) == simulation_key(scfg):
        run = copy.deepcopy(shared)
        run.params = cfg.to_dict()
    else:
        run = _subsample(shared, scfg, noise_free(cfg))
        if run is None:
            return None
        run.params = cfg.to_dict()
    apply_instrument(run, cfg)  # on the recorded signals, after the kernel, as simulate() does
    return run


def _item(item) -> tuple[str, dict, str, str]:
    key, d, *rest = item
    rest = list(rest) + ["vetica", "both"][len(rest) :]
    return key, d, rest[0], rest[1]


def run_task(items: list[tuple], share: bool = True) -> list[tuple[str, list[dict], float]]:
    """Joblib job: simulate and extract one point, or one group sharing a simulation.

    ``items`` are ``(point key, resolved config dict[, extract.method[, extract.force]])``.
    Returns ``[(point key, rows, print step simulated at), ...]``.  Never
    raises for a point: errors become rows with status 'failed'.
    """
    items = [_item(it) for it in items]
    cfgs = [from_dict(d) for _, d, _, _ in items]
    out = []
    if len(items) == 1 or not share:
        for (key, _, method, force), cfg in zip(items, cfgs):
            out.append((key, _simulate_point(cfg, method, force), cfg.numerics.print_step))
        return out
    fcfg = fine_config(cfgs)
    t0 = time.perf_counter()
    fine, fine_exc = None, None
    if fcfg is not None:
        try:
            fine = _simulate(fcfg)
        except Exception as exc:  # noqa: BLE001
            fine_exc = exc
    sim_wall = time.perf_counter() - t0
    for (key, _, method, force), cfg in zip(items, cfgs):
        ps = fcfg.numerics.print_step if fcfg is not None else cfg.numerics.print_step
        if fine_exc is not None:
            out.append((key, _failed_rows(cfg, fine_exc, "simulate", sim_wall, method, force), ps))
            continue
        run = point_run(fine, fcfg, cfg) if fine is not None else None
        if run is None:  # the shared record does not cover this point: run it alone
            out.append((key, _simulate_point(cfg, method, force), cfg.numerics.print_step))
        else:
            out.append((key, _rows_for_run(cfg, run, sim_wall, method, force), ps))
    return out


# --------------------------------------------------------------------------- plan


@dataclass
class Task:
    points: list  # of Point
    sim_print_step: float  # print step the task simulates at (finest of its points)


def plan(study: Study, share_print_step: bool = True) -> list[Task]:
    """Group points into jobs that share one simulation: points differing only in
    extraction method and instrument keys always, and print-step groups when
    ``share_print_step``; every other point is a job of its own."""
    groups: dict = defaultdict(list)
    order = []
    for p in study.points:
        if share_print_step:
            gk = share_group_key(p.config) or f"alone:{simulation_key(p.config)}"
        else:
            gk = f"alone:{simulation_key(p.config)}"
        if gk not in groups:
            order.append(gk)
        groups[gk].append(p)
    tasks = []
    for gk in order:
        pts = groups[gk]
        if len(pts) > 1 and fine_config([p.config for p in pts]) is not None:
            tasks.append(Task(pts, min(p.config.numerics.print_step for p in pts)))
        else:
            tasks.extend(Task([p], p.config.numerics.print_step) for p in pts)
    return tasks


# --------------------------------------------------------------------------- parts


# the modules whose import closure computes a point (simulation, extraction, this sweep)
_FINGERPRINT_ROOTS = ("sweep.py", "grid.py", "simulation/simulate.py", "extraction/__init__.py")


def _local_imports(path: Path, root: Path) -> set[Path]:
    """Package files imported by ``path`` (relative imports, at any depth in the file)."""
    import ast

    out: set[Path] = set()
    pkg = path.parent
    for node in ast.walk(ast.parse(path.read_bytes())):
        if not isinstance(node, ast.ImportFrom) or node.level == 0:
            continue
        base = pkg
        for _ in range(node.level - 1):
            base = base.parent
        if node.module:
            base = base.joinpath(*node.module.split("."))
        candidates = [base.with_suffix(".py"), base / "__init__.py"]
        candidates += [base / f"{a.name}.py" for a in node.names]  # from .core import thc
        candidates += [base / a.name / "__init__.py" for a in node.names]  # from .. import surfaces
        out.update(c.resolve() for c in candidates if c.is_file() and root in c.resolve().parents)
    return out


def fingerprint_files() -> list[Path]:
    """The import closure of the simulation, the extraction and the sweep."""
    root = Path(__file__).resolve().parent
    todo = [root / name for name in _FINGERPRINT_ROOTS if (root / name).is_file()]
    seen: set[Path] = set()
    while todo:
        f = todo.pop()
        if f in seen:
            continue
        seen.add(f)
        todo.extend(_local_imports(f, root) - seen)
    return sorted(seen)


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """Hash of the package source that computes a point (:func:`fingerprint_files`).
    A part made by different code is stale and is recomputed, so a resumed sweep
    never mixes results of two code versions; editing e.g. the plots leaves
    parts valid."""
    import hashlib

    root = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for f in fingerprint_files():
        h.update(str(f.relative_to(root)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


def parts_dir(output: Path) -> Path:
    return output.with_name(output.name + ".parts")


def _part_path(pdir: Path, key: str) -> Path:
    return pdir / f"{key}.parquet"


def read_part(
    path: Path, key: str, sim_print_step: float, method: str = "vetica", force: str = "both"
) -> pd.DataFrame | None:
    """A persisted point, or None if absent, unreadable or made differently."""
    from .io import read_table

    if not path.is_file():
        return None
    try:
        df, meta = read_table(path)
    except InputError:
        return None
    if meta.get("point") != key or meta.get("code") != code_fingerprint():
        return None
    if not math.isclose(float(meta.get("sim_print_step", -1)), sim_print_step, rel_tol=1e-12):
        return None
    if list(df["force_source"]) != list(point_sources(force)):
        return None
    if "method" not in df.columns or set(df["method"]) != {method}:
        return None
    return df


def write_part(pdir: Path, point: Point, rows: list[dict], sim_print_step: float) -> Path:
    from .io import write_table

    df = pd.DataFrame(rows, columns=result_columns())
    meta = {
        "point": point.key,
        "index": point.index,
        "values": point.values,
        "params": point.config.to_dict(),
        "method": point.method,
        "force": point.force,
        "sim_print_step": sim_print_step,
        "version": __version__,
        "code": code_fingerprint(),
    }
    return write_table(df, _part_path(pdir, point.key), meta)


# --------------------------------------------------------------------------- run


@dataclass
class SweepResult:
    table: pd.DataFrame
    output: Path
    config_path: Path
    computed: list = field(default_factory=list)  # point keys computed in this call
    reused: list = field(default_factory=list)  # point keys taken from persisted parts
    acceptance: list = field(default_factory=list)
    wall_s: float = 0.0


def _cap_threads() -> None:
    for var in THREAD_VARS:
        os.environ.setdefault(var, "1")


class _Backend:
    """Where the jobs run: in this process (loky, 1 job), loky worker processes,
    or a Dask cluster (a given scheduler, or a local cluster of ``jobs``
    single-threaded worker processes).  Opened before any output is written,
    so an unreachable scheduler exits with one line and leaves nothing."""

    def __init__(self, backend: str, jobs: int, scheduler: str | None):
        self.backend, self.jobs, self.scheduler = backend, jobs, scheduler
        self.client = self.cluster = None
        if backend == "dask":
            try:
                from dask.distributed import Client, LocalCluster
            except ImportError:
                raise InputError("--backend dask needs dask and distributed: pip install -e '.[dask]'") from None
            if scheduler:
                try:
                    self.client = Client(scheduler, timeout="10s")
                except (OSError, TimeoutError, ValueError) as exc:
                    raise InputError(f"--scheduler {scheduler!r}: cannot connect ({type(exc).__name__})") from None
            else:
                self.cluster = LocalCluster(
                    n_workers=jobs,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    env={v: "1" for v in THREAD_VARS},
                )
                self.client = Client(self.cluster)

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()

    def run(self, tasks, share, on_result) -> None:
        """Run ``tasks``; call ``on_result(task, result)`` in this process as each finishes."""
        from joblib import Parallel, delayed, parallel_config

        if not tasks:
            return
        # plan() decided which points share a simulation: a multi-point task always shares
        calls = [
            delayed(run_task)([(p.key, p.config.to_dict(), p.method, p.force) for p in t.points], True) for t in tasks
        ]
        # results come back unordered; the first point key of a result names its task
        by_first = {t.points[0].key: t for t in tasks}
        if self.backend == "loky" and self.jobs == 1:
            for t, (fn, args, kwargs) in zip(tasks, calls):
                on_result(t, fn(*args, **kwargs))
            return
        if self.backend == "loky":
            cfg = parallel_config(backend="loky", n_jobs=self.jobs, inner_max_num_threads=1)
            par_kw = {"pre_dispatch": "n_jobs"}
        else:
            cfg = parallel_config(backend="dask", n_jobs=-1, wait_for_workers_timeout=60)
            par_kw = {}
        with cfg:
            par = Parallel(return_as="generator_unordered", batch_size=1, **par_kw)
            for res in par(calls):
                on_result(by_first[res[0][0]], res)


def run_sweep(
    study: Study,
    output: str | Path,
    jobs: int = 2,
    backend: str = "loky",
    scheduler: str | None = None,
    resume: bool = True,
    share_print_step: bool = True,
    progress: bool = True,
    console=None,
) -> SweepResult:
    """Run every missing point of ``study``, then assemble and write the table."""
    t_start = time.perf_counter()
    output = Path(output)
    if output.suffix.lower() != ".parquet":
        raise InputError(f"-o {str(output)!r}: the table is written as Parquet; expected a .parquet path")
    if jobs < 1:
        raise InputError(f"--jobs {jobs}: expected an integer >= 1")
    if backend not in ("loky", "dask"):
        raise InputError(f"--backend {backend!r} is not allowed; expected loky or dask")
    if scheduler and backend != "dask":
        raise InputError("--scheduler needs --backend dask")
    _cap_threads()
    runner = _Backend(backend, jobs, scheduler)
    try:
        return _run(study, output, runner, resume, share_print_step, progress, console, t_start)
    finally:
        runner.close()


def _run(study, output, runner, resume, share_print_step, progress, console, t_start) -> SweepResult:
    pdir = parts_dir(output)
    tasks = plan(study, share_print_step)
    done: dict[str, pd.DataFrame] = {}
    todo = []
    for t in tasks:
        if resume:
            got = {
                p.key: read_part(_part_path(pdir, p.key), p.key, t.sim_print_step, p.method, p.force) for p in t.points
            }
            for k, df in got.items():
                if df is not None:
                    done[k] = df
            if all(df is not None for df in got.values()):
                continue
        todo.append(t)
    reused = list(done)
    computed: list[str] = []
    pdir.mkdir(parents=True, exist_ok=True)
    for stale in pdir.glob(".*.tmp"):  # temporaries of a killed write
        stale.unlink(missing_ok=True)

    n_total = len(study.points)
    failed = {"n": sum(int((df["status"] == "failed").any()) for df in done.values())}
    bar = _Progress(n_total, len(done), failed["n"], enabled=progress, console=console)

    def on_result(task: Task, res):
        by_key = {p.key: p for p in task.points}
        for key, rows, sim_ps in res:
            point = by_key[key]
            write_part(pdir, point, rows, sim_ps)
            done[key] = pd.DataFrame(rows, columns=result_columns())
            computed.append(key)
            nf = int(any(r["status"] == "failed" for r in rows))
            failed["n"] += nf
            bar.advance(1, failed["n"])

    with bar:
        runner.run(todo, share_print_step, on_result)
    table = assemble(study, done)
    acceptance = acceptance_regime(table, study.keys)
    config_path = output.with_name(output.stem + ".config.yaml")
    meta = {
        "study": study.name,
        "description": study.description,
        "config": study.resolved(),
        "swept_keys": list(study.keys),
        "units": column_units(study),
        "version": __version__,
        "code": code_fingerprint(),
        "points": n_total,
        "share_print_step": share_print_step,
        "acceptance_err_pct": ACCEPT_ERR_PCT,
        "acceptance": acceptance,
        "config_file": config_path.name,
    }
    from .io import write_table

    write_table(table, output, meta)
    _write_text_atomic(config_path, yaml.safe_dump(study.resolved(), sort_keys=False))
    return SweepResult(
        table=table,
        output=output,
        config_path=config_path,
        computed=computed,
        reused=reused,
        acceptance=acceptance,
        wall_s=time.perf_counter() - t_start,
    )


def _write_text_atomic(path: Path, text: str) -> None:
    from .io import atomic_path

    with atomic_path(path) as tmp:
        tmp.write_text(text)


def assemble(study: Study, done: dict) -> pd.DataFrame:
    """The tidy table: points in grid order, 'true' before 'reconstructed'."""
    frames = []
    for p in study.points:
        df = done[p.key].copy()
        df = df[result_columns()]
        lead = pd.DataFrame({"point": [p.key] * len(df)})
        for k in study.keys:
            if k not in EXTRACT_KEYS:  # extract.method is the 'method' column
                lead[k] = [p.values[k]] * len(df)
        frames.append(pd.concat([lead, df.reset_index(drop=True)], axis=1))
    table = pd.concat(frames, ignore_index=True)
    order = {s: i for i, s in enumerate(SOURCES)}
    idx = {p.key: p.index for p in study.points}
    table = (
        table.assign(_i=table["point"].map(idx), _s=table["force_source"].map(order))
        .sort_values(["_i", "_s"], kind="mergesort")
        .drop(columns=["_i", "_s"])
        .reset_index(drop=True)
    )
    table["error"] = table["error"].fillna("").astype(str)
    table["unidentified"] = table["unidentified"].fillna("").astype(str)
    table["method"] = table["method"].astype(str)
    table["stop_reason"] = table["stop_reason"].fillna("").astype(str)
    table["taps"] = table["taps"].astype("int64")
    return table


def acceptance_regime(
    table: pd.DataFrame, keys, cd_key: str = "surface.cd", err_col: str = "tau_c_err_pct"
) -> list[dict]:
    """For every combination of the other swept keys (the extraction method is
    the 'method' column) and each force source: the range of cd with status
    'ok' and ``|err_col|`` below 30 % (tau_c error: thesis fig. 52)."""
    if cd_key not in keys:
        return []
    # extraction keys are columns of their own: extract.method -> 'method', extract.force -> 'force_source'
    others = ["method" if k == "extract.method" else k for k in keys if k != cd_key and k != "extract.force"]
    if "method" not in others and "method" in table.columns and table["method"].nunique() > 1:
        others.append("method")
    out = []
    group_cols = [*others, "force_source"]
    for combo, g in table.groupby(group_cols, sort=False, dropna=False):
        combo = combo if isinstance(combo, tuple) else (combo,)
        ok = g[(g["status"] == "ok") & (g[err_col].abs() < ACCEPT_ERR_PCT)]
        cds = sorted(ok[cd_key].astype(float))
        all_cd = sorted(g[cd_key].astype(float))
        entry = {k: _plain(v) for k, v in zip(group_cols, combo)}
        entry.update(
            n_points=len(g),
            n_accepted=len(cds),
            n_not_steady=int((g["status"] == "not_steady").sum()),
            n_failed=int((g["status"] == "failed").sum()),
            cd_min=cds[0] if cds else None,
            cd_max=cds[-1] if cds else None,
            decades=float(np.log10(cds[-1] / cds[0])) if cds else None,
            contiguous=bool(cds) and _contiguous(all_cd, cds),
        )
        out.append(entry)
    return out


def _plain(v):
    if isinstance(v, (np.floating,)):
        return float(v)
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, np.bool_):
        return bool(v)
    return v


def _contiguous(all_cd, accepted) -> bool:
    """True if the accepted cd values form one unbroken run of the grid."""
    i0 = all_cd.index(accepted[0])
    return all_cd[i0 : i0 + len(accepted)] == accepted


def format_acceptance(acc: list[dict], keys) -> str:
    """Human-readable acceptance regime, one line per combination and force source."""
    if "surface.cd" not in keys:
        return "acceptance regime: surface.cd is not swept, so there is no cd range to report"
    lines = [f"acceptance regime (status ok and tau_c error < {ACCEPT_ERR_PCT:g} %):"]
    for e in acc:
        where = ", ".join(f"{k}={_g(v)}" for k, v in e.items() if k not in _ACC_FIELDS and k != "force_source")
        head = f"  {where + ', ' if where else ''}{e['force_source']} force: "
        if e["n_accepted"] == 0:
            body = "none"
        else:
            body = f"cd {e['cd_min']:.3g} .. {e['cd_max']:.3g} kg/s ({e['decades']:.2f} decades)"
            if not e["contiguous"]:
                body += ", with gaps"
        extra = f"{e['n_accepted']}/{e['n_points']} points"
        if e["n_not_steady"]:
            extra += f", {e['n_not_steady']} not steady"
        if e["n_failed"]:
            extra += f", {e['n_failed']} failed"
        lines.append(f"{head}{body} [{extra}]")
    return "\n".join(lines)


_ACC_FIELDS = {"n_points", "n_accepted", "n_not_steady", "n_failed", "cd_min", "cd_max", "decades", "contiguous"}


def _g(v):
    return f"{v:g}" if isinstance(v, float) else str(v)


def summary(res: SweepResult, study: Study) -> str:
    t = res.table
    by_status = t["status"].value_counts().to_dict()
    lines = [
        f"{len(study.points)} points ({len(res.computed)} computed, {len(res.reused)} reused from "
        f"{parts_dir(res.output).name}/), {len(t)} rows: " + ", ".join(f"{by_status.get(s, 0)} {s}" for s in STATUSES),
        format_acceptance(res.acceptance, study.keys),
        f"wrote {res.output} and {res.config_path} in {res.wall_s:.1f} s",
    ]
    return "\n".join(lines)


class _Progress:
    """Rich progress bar: points done, failures, time left (stderr)."""

    def __init__(self, total: int, done: int, failed: int, enabled: bool = True, console=None):
        self.enabled = enabled and total > 0
        self.total, self.done0, self.failed = total, done, failed
        self.progress = None
        if self.enabled:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self.progress = Progress(
                TextColumn("[bold]sweep"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn("points, {task.fields[failed]} failed"),
                TimeElapsedColumn(),
                TextColumn("left"),
                TimeRemainingColumn(),
                console=console or Console(stderr=True),
            )
            self.task = self.progress.add_task("sweep", total=total, completed=done, failed=failed)

    def __enter__(self):
        if self.progress is not None:
            self.progress.start()
        return self

    def __exit__(self, *exc):
        if self.progress is not None:
            self.progress.stop()
        return False

    def advance(self, n: int, failed: int) -> None:
        if self.progress is not None:
            self.progress.update(self.task, advance=n, failed=failed)


# measured on the project machine (2 cores): `vetica bench` gives 14 ns per
# integration step on one core (worked example, dt = 0.025 ns); one extraction
# takes ~0.6 s (true force) + ~0.8 s (reconstructed) on 10 recorded periods.
# Used only for the --dry-run estimate.
NS_PER_STEP = 14.0
EXTRACT_S_PER_POINT = 1.4
# method 'full' (whole-cycle inversion), both force sources, 10 recorded periods at PS 0.125 ns,
# cd = 1e-3 kg/s at 16:1: 1.2 s (true force) + 1.8 s (reconstructed), measured while the
# other core was busy.  A noisy reconstructed force can take far longer with VETICA (~35 s at 10 pm).
EXTRACT_FULL_S_PER_POINT = 3.0


def dry_run_text(study: Study, output: Path, jobs: int, share_print_step: bool = True) -> str:
    """Points, jobs and a cost bound: kernel time if every simulation runs to
    numerics.max_time, plus the extraction of every point."""
    tasks = plan(study, share_print_step)
    kernel = sum(t.points[0].config.numerics.max_time / t.points[0].config.numerics.dt for t in tasks)
    kernel *= NS_PER_STEP * 1e-9
    extract = sum(
        (EXTRACT_FULL_S_PER_POINT if p.method == "full" else EXTRACT_S_PER_POINT) * len(point_sources(p.force)) / 2
        for p in study.points
    )
    total = kernel + extract
    lines = [
        (
            f"study {study.name}: {len(study.points)} points over {', '.join(study.keys)}; "
            f"{len(tasks)} simulations ({'print-step groups shared' if share_print_step else 'no print-step sharing'})"
        ),
        (
            f"cost at most {total:.0f} core-s = {total / max(jobs, 1) / 60:.1f} min wall on {jobs} workers: "
            f"kernel {kernel:.0f} core-s if every simulation runs to numerics.max_time ({NS_PER_STEP:g} ns/step), "
            f"extraction ~{extract:.0f} core-s ({EXTRACT_S_PER_POINT:g} s a vetica point, "
            f"{EXTRACT_FULL_S_PER_POINT:g} s a full one); steady points cost less"
        ),
        f"output: {output} (parts in {parts_dir(output)}/)",
    ]
    for p in study.points[:5]:
        lines.append(f"  point {p.index}: {p.label()}")
    if len(study.points) > 5:
        lines.append(f"  ... {len(study.points) - 5} more")
    return "\n".join(lines)
