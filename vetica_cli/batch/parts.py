"""Persisted parts: one Parquet file per finished job in ``<output>.parts/``, written
atomically as it completes, so a killed batch run again computes only the missing
jobs (STYLE: batches behave like hydra's multirun).  Knows no physics: a part is a
frame with metadata, named by a key the caller computes (a hash of what the job
computes).

A part records its key and a fingerprint of the source that computed it
(:func:`code_fingerprint` of the roots the caller names); the caller's ``check``
says whether a part is usable.  :func:`scan_parts` says how many parts it reuses
and removes the others, by reason: corrupt, stale, or foreign (not a job of this
batch).  A batch holds :func:`vetica_cli.batch.lock.output_lock` on its output while
it runs.
"""

from __future__ import annotations

import ast
import functools
import hashlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import InputError
from ..io import read_table, write_table

if TYPE_CHECKING:  # pandas is imported with the first part read or written: a dry run starts without it
    import pandas as pd

PACKAGE = Path(__file__).resolve().parent.parent


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


def fingerprint_files(roots: tuple[str, ...]) -> list[Path]:
    """The import closure of ``roots`` (package-relative paths, e.g. a sweep's point task
    and point keys: :data:`vetica_cli.study.sweep.SWEEP_ROOTS`)."""
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
def code_fingerprint(roots: tuple[str, ...]) -> str:
    """Hash of the package source that computes a job (:func:`fingerprint_files` of
    ``roots``, which each batch names: a sweep its point task, a scan its line task).  A
    part made by different code is stale and is recomputed, so a resumed batch never mixes
    results of two code versions; editing e.g. the plots leaves parts valid."""
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
STALE = "stale (made by other code, or for another setting of its job)"
FOREIGN = "foreign (not a job of this batch: an older config or another batch)"
DISCARDED = "discarded (--no-resume)"

Check = Callable[["pd.DataFrame", dict, object], str]  # (frame, metadata, expected) -> '' or a reason


def read_part(path: Path, key: str, fingerprint: str, expected=None, check: Check | None = None
              ) -> tuple[pd.DataFrame | None, str]:  # fmt: skip
    """``(frame, '')`` for a usable part, else ``(None, why)`` with ``why`` one of
    :data:`CORRUPT` or :data:`STALE` (``''`` with None when there is no file).  A part is
    stale when its key or code fingerprint differ, or when ``check(frame, meta,
    expected)`` names a reason."""
    if not path.is_file():
        return None, ""
    try:
        df, meta = read_table(path)
    except InputError:
        return None, CORRUPT
    if len(df) == 0:
        return None, CORRUPT
    if meta.get("key") != key or meta.get("code") != fingerprint:
        return None, STALE
    why = check(df, meta, expected) if check is not None else ""
    return (None, why) if why else (df, "")


def write_part(pdir: Path, key: str, frame: pd.DataFrame, fingerprint: str, meta: dict | None = None) -> Path:
    """Persist a finished job's frame (atomically) with its key, the code fingerprint and ``meta``."""
    return write_table(frame, part_path(pdir, key), {"key": key, "code": fingerprint, **(meta or {})})


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


def scan_parts(pdir: Path, expected: dict, resume: bool, fingerprint: str, check: Check | None = None
               ) -> tuple[dict, PartsReport]:  # fmt: skip
    """The usable persisted jobs of a batch and a report of the rest, which is removed.

    ``expected``: key -> what ``check`` compares a part with, for every job of the batch.
    A part file is reused when :func:`read_part` accepts it (and ``resume``); it is
    removed when it is corrupt, stale, foreign (its key is no job of the batch) or,
    without ``resume``, in any case.  Returns ``(key -> frame, report)``."""
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
            rows, why = read_part(f, f.stem, fingerprint, expected[f.stem], check)
            if rows is not None:
                done[f.stem] = rows
                continue
        report.removed[why] = report.removed.get(why, 0) + 1
        f.unlink(missing_ok=True)
    report.reused = len(done)
    return done, report


def remove_parts(pdir: Path) -> bool:
    """Remove the parts folder of a finished batch (its part files and half-written
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
