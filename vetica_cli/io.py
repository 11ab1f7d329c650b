"""Parquet read/write with self-describing metadata, and the checks of input and
output paths every command makes before it starts work.

Every table vetica writes carries, in the Parquet schema metadata under the
key ``vetica``, a JSON object with the resolved parameters, the unit of each
column and the version.  Writes are atomic: a temporary file in the same
directory is renamed over the target, so a reader never sees half a file.

Paths are checked at the boundary (:func:`check_input_file`,
:func:`check_output_file`, :func:`check_output_dir`): a missing file, a folder
where a file is expected, a file where a folder is expected, or a place that
cannot be written raise :class:`~vetica_cli.errors.InputError` with one line
before any work starts, and the checks themselves leave nothing behind.
"""

from __future__ import annotations

import json
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .errors import InputError

if TYPE_CHECKING:  # pyarrow is imported where a table is read or written: commands that do not, start without it
    import pandas as pd
    import pyarrow as pa

META_KEY = b"vetica"


def _stat(p: Path, label: str) -> os.stat_result | None:
    """``os.stat(p)``, None when nothing is there; InputError for a path the system refuses
    (name too long, a file used as a folder, a symlink loop, an embedded NUL byte...)."""
    try:
        return p.stat()
    except FileNotFoundError:
        return None
    except NotADirectoryError:
        raise InputError(f"{label}: a part of the path is a file, not a folder") from None
    except (OSError, ValueError) as exc:
        raise InputError(f"{label}: not a usable path ({_reason(exc)})") from None


def _reason(exc: BaseException) -> str:
    return getattr(exc, "strerror", None) or str(exc) or type(exc).__name__


def check_input_file(path: str | Path, what: str = "file") -> Path:
    """``path`` if it is a readable regular file; InputError (one line) saying what it is
    instead: missing, a folder, a device, unreadable."""
    p = Path(path)
    label = str(p)
    st = _stat(p, label)
    if st is None:
        raise InputError(f"{label}: no such file")
    if p.is_dir():
        raise InputError(f"{label}: is a folder; expected a {what}")
    if not p.is_file():
        raise InputError(f"{label}: not a regular file; expected a {what}")
    try:
        with open(p, "rb"):
            pass
    except OSError as exc:
        raise InputError(f"{label}: cannot be read ({_reason(exc)})") from None
    return p


def _writable_folder(folder: Path, label: str) -> None:
    """InputError unless ``folder`` exists and takes a new file, or can be created under its
    nearest existing ancestor.  Probed by creating and removing a temporary file there (the
    permission bits do not tell: root may not write /proc); nothing is left behind."""
    anc = folder
    while _stat(anc, label) is None:
        if anc.parent == anc:
            break
        anc = anc.parent
    if not anc.is_dir():
        raise InputError(f"{label}: {anc} is a file, not a folder")
    try:
        fd, tmp = tempfile.mkstemp(prefix=".vetica-write-check-", dir=anc)
    except OSError as exc:
        raise InputError(f"{label}: cannot write in {anc} ({_reason(exc)})") from None
    os.close(fd)
    os.unlink(tmp)


def check_output_file(path: str | Path, option: str = "-o", suffix: str | None = ".parquet") -> Path:
    """``path`` if a file can be written there (atomically, by rename): the name ends in
    ``suffix`` (when given), it is not a folder or a device, and its folder takes a new
    file.  InputError (one line, naming ``option``) otherwise; nothing is created."""
    p = Path(path)
    label = f"{option} {str(p)!r}"
    st = _stat(p, label)
    if st is not None and p.is_dir():
        raise InputError(f"{label}: is an existing folder; expected a file path")
    if st is not None and not p.is_file():
        raise InputError(f"{label}: is not a regular file; expected a file path")
    if suffix and p.suffix.lower() != suffix:
        raise InputError(f"{label}: the output is written as {suffix[1:].title()}; expected a {suffix} path")
    _writable_folder(p.parent, label)
    return p


def check_output_dir(path: str | Path, option: str = "-o") -> Path:
    """``path`` if figures can be written into it: an existing folder, or a new one that can
    be created.  InputError (one line) for an existing file or an unwritable place."""
    p = Path(path)
    label = f"{option} {str(p)!r}"
    st = _stat(p, label)
    if st is not None and not p.is_dir():
        raise InputError(f"{label}: is an existing file; expected a folder")
    _writable_folder(p, label)
    return p


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
    when it fails it is removed.  A reader never sees half a file.  A failure of the
    file system (disk full, the place vanished since the checks) is an InputError
    naming the path, not a traceback."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise InputError(f"cannot write {path} ({_reason(exc)})") from None
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise InputError(f"cannot write {path} ({_reason(exc)})") from None
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
    import pyarrow as pa

    return write_arrow(pa.Table.from_pandas(df, preserve_index=False), path, meta)


def write_arrow(table: pa.Table, path: str | Path, meta: dict) -> Path:
    """Write an Arrow ``table`` to ``path`` atomically with ``meta`` as JSON metadata.

    Only text and categorical columns are dictionary-encoded: Parquet's default tries a
    dictionary on every column, which for a run's 1.9 M distinct floats doubles the write
    and makes the read five times slower (measured on the worked example, 110 MB)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    md = dict(table.schema.metadata or {})
    md[META_KEY] = json.dumps(meta, default=_json_default, allow_nan=False).encode()
    table = table.replace_schema_metadata(md)
    coded = [f.name for f in table.schema
             if pa.types.is_dictionary(f.type) or pa.types.is_string(f.type) or pa.types.is_large_string(f.type)]
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp, use_dictionary=coded)
    return path


def read_meta(path: str | Path) -> dict:
    """The ``vetica`` metadata of a Parquet file ({} if absent)."""
    import pyarrow.parquet as pq

    try:
        md = pq.read_schema(path).metadata or {}
    except Exception as exc:  # pyarrow raises several types for corrupt files
        raise InputError(f"{path}: not a readable Parquet file ({type(exc).__name__})") from None
    raw = md.get(META_KEY)
    if not raw:
        return {}
    try:
        meta = json.loads(raw)
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError):
        raise InputError(f"{path}: the 'vetica' metadata is not valid JSON") from None
    check_meta(meta, path)
    return meta


# the 'vetica' metadata's keys whose values are mappings, and the sections of its 'params'
META_MAPPINGS = ("params", "units", "observables", "energy_ev_per_cycle", "config")
PARAM_SECTIONS = ("probe", "operation", "surface", "numerics")


def check_meta(meta, path) -> None:
    """InputError (one line) for ``vetica`` metadata of the wrong shape: not a mapping, or a
    known key (:data:`META_MAPPINGS`, the sections of ``params``) that is not a mapping, or
    ``warnings`` that is not a list (a file edited by hand or written by another tool)."""
    if not isinstance(meta, dict):
        raise InputError(f"{path}: the 'vetica' metadata is a {type(meta).__name__}; expected a JSON object")
    where = [(k, meta.get(k)) for k in META_MAPPINGS]
    params = meta.get("params")
    if isinstance(params, dict):
        where += [(f"params.{k}", params.get(k)) for k in PARAM_SECTIONS]
    for key, value in where:
        if value is not None and not isinstance(value, dict):
            raise InputError(f"{path}: the 'vetica' metadata's {key} is a {type(value).__name__}; expected a mapping")
    if meta.get("warnings") is not None and not isinstance(meta["warnings"], list):
        raise InputError(f"{path}: the 'vetica' metadata's warnings are a {type(meta['warnings']).__name__}; "
                         "expected a list")  # fmt: skip


def read_table(path: str | Path, columns: tuple | None = None) -> tuple[pd.DataFrame, dict]:
    """Read a Parquet (with metadata) or CSV (no metadata) table.  ``columns``: read only
    those of a Parquet file that it has (None: all; a CSV is read whole).

    Raises InputError with one line for a missing, unreadable or corrupt file.
    """
    p = check_input_file(path, "Parquet or CSV file")
    if p.suffix.lower() == ".csv":
        return read_csv(p), {}
    import pyarrow.parquet as pq  # here: a missing file is refused without loading pyarrow

    meta = read_meta(p)
    try:
        if columns is not None:
            have = set(pq.read_schema(p).names)
            columns = [c for c in columns if c in have]
        df = pq.read_table(p, columns=columns).to_pandas()
    except Exception as exc:
        raise InputError(f"{p}: not a readable Parquet file ({type(exc).__name__})") from None
    return df, meta


def read_csv(path: Path) -> pd.DataFrame:
    """A CSV table whose columns are numbers, except a text ``segment`` column; InputError
    naming the first cell that is not a number (column, row and value) or a file pandas
    cannot parse."""
    import pandas as pd

    try:
        df = pd.read_csv(path, low_memory=False)
    except Exception as exc:  # pandas raises several types (ParserError, UnicodeDecodeError, EmptyDataError)
        raise InputError(f"{path}: not a readable CSV file ({type(exc).__name__})") from None
    if df.columns.duplicated().any():
        dup = df.columns[df.columns.duplicated()][0]
        raise InputError(f"{path}: column {dup!r} appears twice")
    for name in df.columns:
        if name == "segment" or pd.api.types.is_numeric_dtype(df[name]):
            continue
        num = pd.to_numeric(df[name], errors="coerce")
        bad = num.isna() & df[name].notna()
        if bad.any():
            i = int(bad.to_numpy().argmax())
            raise InputError(
                f"{path}: column {name!r}, data row {i + 1}: {df[name].iloc[i]!r} is not a number; "
                "expected numbers (only 'segment' may hold text)"
            )
        df[name] = num
    return df


def segments_table(names: list[str], parts: list, labels: list[str]) -> pa.Table:
    """An Arrow table of float columns ``names`` from sample arrays ``parts`` (each
    ``(n_i, len(names))``), one chunk per part, plus a dictionary column ``segment`` naming
    each sample's part by ``labels``.  Built from the arrays' buffers: a contiguous column is
    not copied, and pyarrow does not import pandas (``pa.array`` does, for 0.3 s)."""
    import pyarrow as pa

    def column(arr, typ):
        arr = np.ascontiguousarray(arr)
        return pa.Array.from_buffers(typ, len(arr), [None, pa.py_buffer(arr)])

    words = [w.encode() for w in labels]
    offsets = np.cumsum([0, *map(len, words)]).astype(np.int32)
    dictionary = pa.Array.from_buffers(pa.string(), len(words), [None, pa.py_buffer(offsets), pa.py_buffer(b"".join(words))])
    cols = [pa.chunked_array([column(p[:, j], pa.float64()) for p in parts], pa.float64()) for j in range(len(names))]
    seg = pa.chunked_array(
        [pa.DictionaryArray.from_arrays(column(np.full(len(p), i, np.int8), pa.int8()), dictionary)
         for i, p in enumerate(parts)],
        pa.dictionary(pa.int8(), pa.string()),
    )  # fmt: skip
    return pa.table([*cols, seg], names=[*names, "segment"])


def write_run(run, path: str | Path) -> Path:
    """Write a simulate() Run (both segments) with its metadata, straight from its sample
    arrays (:meth:`~vetica_cli.simulation.simulate.Run.arrow`, no DataFrame in between)."""
    return write_arrow(run.arrow(), path, run.metadata())
