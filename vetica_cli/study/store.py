"""Persisted points: one Parquet part per finished point in ``<output>.parts/``, written
atomically as it completes, so a killed sweep run again computes only the missing
points (STYLE: sweeps behave like hydra's multirun).

A part records the point key (a hash of the resolved point config and the
package version) and a fingerprint of the source that computed it
(:func:`code_fingerprint`); a part made by other code, for another print-step
group, method or force sources is stale and recomputed.  :func:`scan_parts` says
how many parts it reuses and removes the others, by reason: corrupt, stale, or
foreign (not a point of the study).  A sweep holds :func:`output_lock`
on its output while it runs.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from .. import __version__
from ..errors import InputError
from ..io import read_table, write_table
from .grid import Point
from .schema import point_sources, result_columns

PACKAGE = Path(__file__).resolve().parent.parent
# the modules whose import closure computes a point's rows: the task (simulation and extraction),
# the planning that shares simulations, the points and their keys, the row schema, and this store
FINGERPRINT_ROOTS = ("study/task.py", "study/plan.py", "study/grid.py", "study/schema.py", "study/store.py")


def _local_imports(path: Path, root: Path) -> set[Path]:
    """Package files imported by ``path`` (relative or ``vetica_cli.`` imports, at any depth in the file)."""
    out: set[Path] = set()
    for node in ast.walk(ast.parse(path.read_bytes())):
        if not isinstance(node, ast.ImportFrom):
            continue
        if node.level:
            base = path.parent
            for _ in range(node.level - 1):
                base = base.parent
            parts = node.module.split(".") if node.module else []
        elif node.module and node.module.split(".")[0] == root.name:
            base, parts = root, node.module.split(".")[1:]
        else:
            continue
        base = base.joinpath(*parts)
        candidates = [base.with_suffix(".py"), base / "__init__.py"]
        candidates += [base / f"{a.name}.py" for a in node.names]  # from .core import thc
        candidates += [base / a.name / "__init__.py" for a in node.names]  # from .. import surfaces
        out.update(c.resolve() for c in candidates if c.is_file() and root in c.resolve().parents)
    return out


def fingerprint_files(roots: tuple[str, ...] = FINGERPRINT_ROOTS) -> list[Path]:
    """The import closure of ``roots`` (package-relative paths; default
    :data:`FINGERPRINT_ROOTS`: simulation, extraction, surfaces, signals, kernels, and the
    study code that turns them into rows)."""
    todo = [PACKAGE / name for name in roots]
    missing = [str(f) for f in todo if not f.is_file()]
    if missing:  # a moved module must not silently drop out of the fingerprint
        raise FileNotFoundError(f"fingerprint roots missing: {', '.join(missing)}")
    seen: set[Path] = set()
    while todo:
        f = todo.pop()
        if f in seen:
            continue
        seen.add(f)
        todo.extend(_local_imports(f, PACKAGE) - seen)
    return sorted(seen)


@functools.lru_cache(maxsize=4)
def code_fingerprint(roots: tuple[str, ...] = FINGERPRINT_ROOTS) -> str:
    """Hash of the package source that computes a point (:func:`fingerprint_files` of
    ``roots``; a scan passes its own).  A part made by different code is stale and is
    recomputed, so a resumed sweep never mixes results of two code versions; editing
    e.g. the plots leaves parts valid."""
    h = hashlib.sha256()
    for f in fingerprint_files(roots):
        h.update(str(f.relative_to(PACKAGE)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


def parts_dir(output: Path) -> Path:
    return Path(output).with_name(Path(output).name + ".parts")


def part_path(pdir: Path, key: str) -> Path:
    return pdir / f"{key}.parquet"


# why a part file is not used (PartsReport counts them; the files are removed)
CORRUPT = "corrupt (unreadable, empty or incomplete)"
STALE = "stale (made by other code, or for another setting of its point)"
FOREIGN = "foreign (not a point of this study: an older config or another study)"
DISCARDED = "discarded (--no-resume)"


def check_part(path: Path, point: Point, sim_print_step: float) -> tuple[pd.DataFrame | None, str]:
    """``(rows, '')`` for a usable persisted point, else ``(None, why)`` with ``why`` one of
    :data:`CORRUPT` or :data:`STALE` (``''`` with None when there is no file)."""
    if not path.is_file():
        return None, ""
    try:
        df, meta = read_table(path)
    except InputError:
        return None, CORRUPT
    want = list(point_sources(point.force))
    if not {"force_source", "method", "status"} <= set(df.columns) or len(df) == 0:
        return None, CORRUPT
    if meta.get("point") != point.key or meta.get("code") != code_fingerprint():
        return None, STALE
    try:
        same_step = math.isclose(float(meta.get("sim_print_step", -1)), sim_print_step, rel_tol=1e-12)
    except (TypeError, ValueError):
        return None, CORRUPT
    if not same_step or set(df["method"]) != {point.method}:
        return None, STALE
    if list(df["force_source"]) != want:
        return None, CORRUPT if set(df["force_source"]) < set(want) else STALE
    return df, ""


def read_part(path: Path, point: Point, sim_print_step: float) -> pd.DataFrame | None:
    """A persisted point, or None if absent, unreadable or made differently (:func:`check_part`)."""
    return check_part(path, point, sim_print_step)[0]


@dataclass
class PartsReport:
    """What :func:`scan_parts` found in a parts folder: points reused, and the files it removed
    by reason."""

    folder: Path
    reused: int = 0
    removed: dict = field(default_factory=dict)  # reason -> number of part files
    temporaries: int = 0  # half-written files of a killed write

    def note(self) -> str | None:
        """One line for the user when anything was removed; None otherwise."""
        if not self.removed and not self.temporaries:
            return None
        items = [f"{self.removed[why]} {why}" for why in (CORRUPT, STALE, FOREIGN, DISCARDED) if why in self.removed]
        if self.temporaries:
            items.append(f"{self.temporaries} half-written (a killed write)")
        return f"parts in {self.folder}/: {self.reused} reused; removed " + ", ".join(items)


def scan_parts(pdir: Path, expected: dict, resume: bool) -> tuple[dict, PartsReport]:
    """The usable persisted points of a study and a report of the rest, which is removed.

    ``expected``: point key -> ``(Point, sim_print_step)`` of every point of the study.  A
    part file is reused when :func:`check_part` accepts it (and ``resume``); it is removed
    when it is corrupt, stale, foreign (its key is no point of the study) or, without
    ``resume``, in any case.  Returns ``(point key -> rows, report)``."""
    report = PartsReport(pdir)
    done: dict[str, pd.DataFrame] = {}
    if not pdir.is_dir():
        return done, report
    for tmp in pdir.glob(".*.tmp"):  # temporaries of a killed write
        tmp.unlink(missing_ok=True)
        report.temporaries += 1
    for f in sorted(pdir.glob("*.parquet")):
        if f.stem not in expected:
            why = FOREIGN
        elif not resume:
            why = DISCARDED
        else:
            rows, why = check_part(f, *expected[f.stem])
            if rows is not None:
                done[f.stem] = rows
                continue
        report.removed[why] = report.removed.get(why, 0) + 1
        f.unlink(missing_ok=True)
    report.reused = len(done)
    return done, report


def remove_parts(pdir: Path) -> bool:
    """Remove the parts folder of a finished sweep (its part files and half-written
    temporaries, then the folder).  False, leaving the folder, when it holds anything else."""
    if not pdir.is_dir():
        return True
    for f in [*pdir.glob("*.parquet"), *pdir.glob(".*.tmp")]:
        f.unlink(missing_ok=True)
    try:
        pdir.rmdir()
    except OSError:
        return False
    return True


def rows_frame(point: Point, rows: list[dict]) -> pd.DataFrame:
    """A point's rows as a frame with the columns of its surface model."""
    return pd.DataFrame(rows, columns=result_columns([point.config.surface.surface_model], [point.method]))


def write_part(pdir: Path, point: Point, rows: list[dict], sim_print_step: float) -> Path:
    """Persist a finished point (atomically)."""
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
    return write_table(rows_frame(point, rows), part_path(pdir, point.key), meta)
