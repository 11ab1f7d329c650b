"""Parquet read/write with self-describing metadata.

Every table vetica writes carries, in the Parquet schema metadata under the
key ``vetica``, a JSON object with the resolved parameters, the unit of each
column and the version.  Writes are atomic: a temporary file in the same
directory is renamed over the target, so a reader never sees half a file.
"""

from __future__ import annotations

import json
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from .errors import InputError

META_KEY = b"vetica"


def _json_default(o):
    try:
        return float(o)
    except (TypeError, ValueError):
        return str(o)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def atomic_path(path: str | Path):
    """Yield a temporary path next to ``path``; when the block succeeds it is
    renamed over ``path`` (atomic on one file system) with normal permissions,
    when it fails it is removed.  A reader never sees half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (:func:`atomic_path`)."""
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text)
    return Path(path)


def write_table(df: pd.DataFrame, path: str | Path, meta: dict) -> Path:
    """Write ``df`` to ``path`` atomically with ``meta`` as JSON metadata."""
    table = pa.Table.from_pandas(df, preserve_index=False)
    md = dict(table.schema.metadata or {})
    md[META_KEY] = json.dumps(meta, default=_json_default, allow_nan=False).encode()
    table = table.replace_schema_metadata(md)
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp)
    return path


def read_meta(path: str | Path) -> dict:
    """The ``vetica`` metadata of a Parquet file ({} if absent)."""
    try:
        md = pq.read_schema(path).metadata or {}
    except Exception as exc:  # pyarrow raises several types for corrupt files
        raise InputError(f"{path}: not a readable Parquet file ({type(exc).__name__})") from None
    raw = md.get(META_KEY)
    if not raw:
        return {}
    try:
        return json.loads(raw)
    except json.JSONDecodeError:
        raise InputError(f"{path}: the 'vetica' metadata is not valid JSON") from None


def read_table(path: str | Path) -> tuple[pd.DataFrame, dict]:
    """Read a Parquet (with metadata) or CSV (no metadata) table.

    Raises InputError with one line for a missing, unreadable or corrupt file.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: no such file")
    if p.suffix.lower() == ".csv":
        try:
            return pd.read_csv(p), {}
        except Exception as exc:
            raise InputError(f"{p}: not a readable CSV file ({type(exc).__name__})") from None
    meta = read_meta(p)
    try:
        df = pq.read_table(p).to_pandas()
    except Exception as exc:
        raise InputError(f"{p}: not a readable Parquet file ({type(exc).__name__})") from None
    return df, meta


def write_run(run, path: str | Path) -> Path:
    """Write a simulate() Run (both segments) with its metadata."""
    return write_table(run.frame(), path, run.metadata())
