"""``vetica export``: a map table out of Parquet, into the files AFM users open.

Two kinds of table are maps:

* a **scan** (``vetica scan``): one row per pixel, pass, method and force source; the image
  axes are the pixel indices ``iy``, ``ix`` with the pixel centres ``y``, ``x`` [m] as coordinates,
  the other dimensions are ``pass`` (the scan's passes: transient pixel times, orbit),
  ``extraction_method`` and ``force_source``;
* a **fit** of a force map (``vetica fit``): the selected row of each curve with grid indices;
  the axes are ``grid_y``, ``grid_x`` (with the curves' positions [m] where the file has them),
  the other dimension is ``file`` (a table may hold several maps).

A variant dimension is never called ``method``: ``xarray.Dataset.sel(method=...)`` is the
nearest-neighbour switch of ``sel``, so a dimension of that name cannot be selected by keyword.

Formats, by the output's suffix:

* ``.nc``: NetCDF-4 (xarray, h5netcdf) with every numeric and text column as a variable, its
  ``units`` and ``description`` (from the table's metadata) as attributes, and the table's
  metadata as the dataset's ``vetica`` attribute (JSON);
* ``.gwy``: a Gwyddion file (gwyfile), one channel per quantity and variant (the title names
  them, ``e0 | file=...``), the lateral and value units as Gwyddion SI units;
* ``.gsf``: Gwyddion Simple Field files (one channel each), written here: the text header
  ``Gwyddion Simple Field 1.0`` then ``Key = value`` lines (``XRes``, ``YRes``, ``XReal``,
  ``YReal``, ``XOffset``, ``YOffset``, ``XYUnits``, ``ZUnits``, ``Title``), NUL bytes padding the
  header to a multiple of 4 bytes (at least one), then ``XRes x YRes`` little-endian 32-bit
  floats, row by row (row 0: grid index y 0); one quantity gives the ``-o`` file, several give
  ``<stem>_<channel>.gsf`` beside it.

Needs the optional extra ``export`` (``pip install -e ".[export]"``: xarray, h5netcdf, gwyfile).
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError
from .io import atomic_path, check_output_file, read_table

FORMATS = (".nc", ".gwy", ".gsf")
EXTRA_HINT = 'pip install -e ".[export]"'
NOT_QUANTITIES = {"ix", "iy", "grid_x", "grid_y", "curve", "arms", "x", "y", "selected"}


@dataclass
class MapData:
    """A map table as arrays: ``dims`` (variant dims, then 'y', 'x'), their coordinate values,
    each variable's array (shape of the dims), and units and descriptions."""

    kind: str
    dims: list
    coords: dict  # dim -> values
    variables: dict  # name -> ndarray
    units: dict
    descriptions: dict
    x_m: np.ndarray | None = None  # [m] positions along the x axis (per x index), when known
    y_m: np.ndarray | None = None
    meta: dict = field(default_factory=dict)


def _module(name: str):
    import importlib

    try:
        return importlib.import_module(name)
    except ImportError:
        raise InputError(f"vetica export needs {name}: {EXTRA_HINT}") from None


def table_kind(df, meta: dict, path) -> str:
    if meta.get("table") == "scan":
        return "scan"
    if meta.get("table") == "fit" or meta.get("kind") == "force-curve fit":
        return "fit"
    raise InputError(f"{path}: not a map table; expected a table of 'vetica scan' or 'vetica fit'")


def _grid(df, variant: list, yi: str, xi: str, columns: list) -> tuple[dict, dict]:
    """``(coords, arrays)`` of the columns over ``variant + [y, x]`` (NaN / '' where no row)."""
    import pandas as pd

    coords = {d: list(dict.fromkeys(df[d].tolist())) for d in variant}
    ny, nx = int(df[yi].max()) + 1, int(df[xi].max()) + 1
    shape = [len(coords[d]) for d in variant] + [ny, nx]
    index = [df[d].map({v: i for i, v in enumerate(coords[d])}).to_numpy() for d in variant]
    index += [df[yi].to_numpy(int), df[xi].to_numpy(int)]
    arrays = {}
    for c in columns:
        col = df[c]
        if pd.api.types.is_bool_dtype(col):
            a = np.zeros(shape, bool)
            a[tuple(index)] = col.to_numpy(bool)
        elif pd.api.types.is_numeric_dtype(col):
            a = np.full(shape, np.nan)
            a[tuple(index)] = col.to_numpy(float)
        else:
            a = np.full(shape, "", dtype=object)
            a[tuple(index)] = col.fillna("").astype(str).to_numpy(object)
        arrays[c] = a
    coords["y"], coords["x"] = list(range(ny)), list(range(nx))
    return coords, arrays


def _axis_positions(df, idx: str, pos: str, n: int) -> np.ndarray | None:
    """Positions [m] along an axis at every index ``0..n-1``: the line through the rows' positions
    against their indices (a sparse force map has gaps), None when they do not define one."""
    if pos not in df or not df[pos].notna().any():
        return None
    means = df.groupby(idx)[pos].mean().dropna()
    if len(means) < 2:
        return None
    slope, offset = np.polyfit(means.index.to_numpy(float), means.to_numpy(float), 1)
    return offset + slope * np.arange(n) if slope != 0 else None


def map_data(path) -> MapData:
    """The map of a scan or fit table (module docstring); InputError for another table or a fit
    table without a force map."""
    df, meta = read_table(path)
    kind = table_kind(df, meta, path)
    units, desc = dict(meta.get("units", {})), dict(meta.get("descriptions", {}))
    if kind == "scan":
        passes = {(p.get("steady"), p.get("pixel_time")): p.get("label") for p in meta.get("scan", {}).get("passes", [])}

        def label(r):
            pt = r["pixel_time"]
            key = (r["steady"], None if pt != pt else float(pt))
            return passes.get(key) or (r["steady"] if pt != pt else f"{r['steady']} {pt:g} s")

        df = df.copy()
        df["pass"] = [label(r) for r in df[["steady", "pixel_time"]].to_dict("records")]
        df = df.rename(columns={"method": "extraction_method"})
        variant, yi, xi = ["pass", "extraction_method", "force_source"], "iy", "ix"
        desc["extraction_method"] = "the extraction method of the row"
        desc["pass"] = "the scan pass: transient (pixel time) or orbit"
        xcol, ycol = "x", "y"
    else:
        df = df[(df["grid_x"] >= 0) & (df["grid_y"] >= 0) & df["selected"]]
        if len(df) == 0:
            raise InputError(f"{path}: no force map in this fit table (no selected row with grid indices); "
                             "expected a table of a force map")  # fmt: skip
        variant, yi, xi = ["file"], "grid_y", "grid_x"
        xcol, ycol = "position_x", "position_y"
    columns = [c for c in df.columns if c not in set(variant) | {yi, xi, xcol, ycol, "steady", "path"}]
    coords, arrays = _grid(df, variant, yi, xi, columns)
    nx, ny = len(coords["x"]), len(coords["y"])
    x_m = _axis_positions(df, xi, xcol, nx) if xcol in df else None
    y_m = _axis_positions(df, yi, ycol, ny) if ycol in df else None
    return MapData(kind, variant + ["y", "x"], coords, arrays, units, desc, x_m, y_m, meta)


def to_dataset(m: MapData):
    """An xarray Dataset of the map: variables with ``units`` and ``description`` attributes."""
    xr = _module("xarray")
    data_vars = {}
    for name, a in m.variables.items():
        if a.dtype == object:
            a = a.astype(str)
        attrs = {"units": m.units.get(name, ""), "description": m.descriptions.get(name, "")}
        data_vars[name] = (m.dims, a, attrs)
    coords = {d: (d, np.asarray([str(x) for x in v]) if v and isinstance(v[0], str) else np.asarray(v))
              for d, v in m.coords.items()}  # fmt: skip
    coords["x"] = ("x", np.asarray(m.coords["x"]), {"description": "grid index along x (fast axis)"})
    coords["y"] = ("y", np.asarray(m.coords["y"]), {"description": "grid index along y (slow axis)"})
    if m.x_m is not None:
        coords["x_m"] = ("x", m.x_m, {"units": "m", "description": "position along x"})
    if m.y_m is not None:
        coords["y_m"] = ("y", m.y_m, {"units": "m", "description": "position along y"})
    ds = xr.Dataset(data_vars, coords=coords)
    ds.attrs["vetica"] = json.dumps(m.meta, default=str)
    ds.attrs["source"] = f"vetica {m.kind} table"
    return ds


def channels(m: MapData, quantities=None) -> list[tuple[str, np.ndarray, str]]:
    """``(title, 2-D image, unit)`` per numeric quantity and variant (NaN where no value)."""
    names = [n for n, a in m.variables.items() if a.dtype != object and a.dtype != bool and n not in NOT_QUANTITIES]
    if quantities:
        unknown = [q for q in quantities if q not in names]
        if unknown:
            raise InputError(f"--quantity {unknown[0]!r} is not a numeric column of this map; expected one of "
                             + ", ".join(names[:40]) + (" ..." if len(names) > 40 else ""))  # fmt: skip
        names = [n for n in names if n in quantities]
    variant = m.dims[:-2]
    out = []
    for idx in np.ndindex(*[len(m.coords[d]) for d in variant]):
        tag = ", ".join(f"{d}={m.coords[d][i]}" for d, i in zip(variant, idx))
        for n in names:
            img = np.asarray(m.variables[n][idx], float)
            if np.isfinite(img).any():
                out.append((f"{n} | {tag}" if tag else n, img, m.units.get(n, "")))
    return out


def extent(m: MapData) -> tuple[float, float, float, float, str]:
    """``(xreal, yreal, xoff, yoff, lateral unit)``: from the positions when known, else one per pixel."""
    nx, ny = len(m.coords["x"]), len(m.coords["y"])

    def span(pos, n):
        if pos is None or n < 2:
            return None
        pitch = (pos[-1] - pos[0]) / (n - 1)
        return (abs(pitch) * n, float(min(pos[0], pos[-1]) - abs(pitch) / 2)) if pitch != 0 else None

    sx, sy = span(m.x_m, nx), span(m.y_m, ny)
    if sx and sy:
        return sx[0], sy[0], sx[1], sy[1], "m"
    return float(nx), float(ny), 0.0, 0.0, ""


def gsf_bytes(img: np.ndarray, xreal: float, yreal: float, xoff: float, yoff: float, xy_unit: str, z_unit: str,
              title: str) -> bytes:  # fmt: skip
    """One Gwyddion Simple Field file (module docstring)."""
    ny, nx = img.shape
    head = (f"Gwyddion Simple Field 1.0\nXRes = {nx}\nYRes = {ny}\nXReal = {xreal!r}\nYReal = {yreal!r}\n"
            f"XOffset = {xoff!r}\nYOffset = {yoff!r}\nXYUnits = {xy_unit}\nZUnits = {z_unit}\n"
            f"Title = {title}\n").encode("utf-8")  # fmt: skip
    pad = 4 - len(head) % 4  # 1..4 NUL bytes
    data = np.ascontiguousarray(img, dtype="<f4").tobytes()
    return head + b"\0" * pad + data


def read_gsf(path) -> tuple[dict, np.ndarray]:
    """``(header, image)`` of a Gwyddion Simple Field file (for tests and users' scripts)."""
    raw = Path(path).read_bytes()
    end = raw.index(b"\0")
    lines = raw[:end].decode("utf-8").splitlines()
    if not lines or lines[0] != "Gwyddion Simple Field 1.0":
        raise InputError(f"{path}: not a Gwyddion Simple Field file")
    header = {k.strip(): v.strip() for k, _, v in (ln.partition("=") for ln in lines[1:]) if k.strip()}
    start = end + (4 - end % 4)
    nx, ny = int(header["XRes"]), int(header["YRes"])
    img = np.frombuffer(raw[start : start + 4 * nx * ny], dtype="<f4").reshape(ny, nx)
    return header, img


def safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("_")


def export(table, output, quantities=None) -> list[Path]:
    """Write the map of ``table`` to ``output`` (.nc, .gwy or .gsf); returns the files written.
    Everything is checked before anything is written (InputError, one line)."""
    out = Path(output)
    suffix = out.suffix.lower()
    if suffix not in FORMATS:
        raise InputError(f"-o {str(out)!r}: the format is told by the suffix; expected one of {', '.join(FORMATS)}")
    check_output_file(out, "-o", suffix)
    _module({".nc": "h5netcdf", ".gwy": "gwyfile", ".gsf": "numpy"}[suffix])
    if suffix == ".nc":
        _module("xarray")
    m = map_data(table)
    if suffix == ".nc":
        ds = to_dataset(m)
        if quantities:
            keep = [q for q in quantities if q in ds.data_vars]
            if len(keep) < len(quantities):
                bad = next(q for q in quantities if q not in ds.data_vars)
                raise InputError(f"--quantity {bad!r} is not a column of this map")
            ds = ds[keep]
        with atomic_path(out) as tmp:
            ds.to_netcdf(tmp, engine="h5netcdf", invalid_netcdf=True)
        return [out]
    chans = channels(m, quantities)
    if not chans:
        raise InputError(f"{table}: no quantity with a value in this map")
    xreal, yreal, xoff, yoff, xy_unit = extent(m)
    if suffix == ".gwy":
        from gwyfile.objects import GwyContainer, GwyDataField, GwySIUnit

        c = GwyContainer()
        for i, (title, img, unit) in enumerate(chans):
            c[f"/{i}/data"] = GwyDataField(np.ascontiguousarray(img, float), xreal=xreal, yreal=yreal, xoff=xoff,
                                           yoff=yoff, si_unit_xy=GwySIUnit(unitstr=xy_unit),
                                           si_unit_z=GwySIUnit(unitstr=unit))  # fmt: skip
            c[f"/{i}/data/title"] = title
        with atomic_path(out) as tmp:
            c.tofile(str(tmp))
        return [out]
    paths = [out] if len(chans) == 1 else [out.with_name(f"{out.stem}_{safe(t)}.gsf") for t, _, _ in chans]
    for p in paths:
        check_output_file(p, "-o", ".gsf")
    for p, (title, img, unit) in zip(paths, chans):
        with atomic_path(p) as tmp:
            Path(tmp).write_bytes(gsf_bytes(img, xreal, yreal, xoff, yoff, xy_unit, unit, title))
    return paths
