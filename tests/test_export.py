"""``vetica export``: scans and force-map fits to NetCDF (xarray), Gwyddion .gwy (gwyfile) and
.gsf, read back with the readers users have, units included; and its one-line errors."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from vetica_cli.cli import app
from vetica_cli.curves.batch import fit_files
from vetica_cli.export import gsf_bytes, read_gsf
from vetica_cli.io import read_meta

ROOT = Path(__file__).resolve().parents[1]
SCAN = ROOT / "results" / "scans" / "scan_edge.parquet"
MAP = ROOT / "tests" / "data" / "afmformats" / "fmt-jpk-fd_map-data-reference-points.jpk-force-map"
runner = CliRunner()
xr = pytest.importorskip("xarray")  # the export extra; .ci/run installs it
gwyfile = pytest.importorskip("gwyfile")


@pytest.fixture(scope="module")
def fit_map(tmp_path_factory):
    out = tmp_path_factory.mktemp("fit") / "map.parquet"
    fit_files([MAP], 5e-6, out, jobs=1, progress=False)
    return out


def test_scan_to_netcdf_keeps_every_value_with_its_units(tmp_path):
    """Every pixel's k_g of the committed edge scan is in the NetCDF at its pass, method and
    indices, with the table's unit; the method dimension is extraction_method (sel(method=...)
    is xarray's own keyword)."""
    out = tmp_path / "scan.nc"
    res = runner.invoke(app, ["export", str(SCAN), "-o", str(out)])
    assert res.exit_code == 0, res.output
    ds = xr.open_dataset(out, engine="h5netcdf")
    assert "method" not in ds.dims and "extraction_method" in ds.dims
    df = pd.read_parquet(SCAN)
    units = read_meta(SCAN)["units"]
    assert ds["k_g"].attrs["units"] == units["k_g"] == "N/m" and ds["k_g"].attrs["description"]
    orbit = df[(df["steady"] == "orbit") & (df["method"] == "full")]
    got = ds["k_g"].sel(extraction_method="full", force_source=orbit["force_source"].iloc[0], **{"pass": "orbit"})
    np.testing.assert_array_equal(got.values[orbit["iy"], orbit["ix"]], orbit["k_g"].to_numpy())
    np.testing.assert_allclose(ds["x_m"].values[orbit["ix"]], orbit["x"].to_numpy())


def test_fit_map_to_netcdf_gwy_and_gsf(tmp_path, fit_map):
    """A force-map fit: e0 at each curve's grid indices in all three formats, with Pa as its unit."""
    df = pd.read_parquet(fit_map)
    nc, gwy, gsf = tmp_path / "m.nc", tmp_path / "m.gwy", tmp_path / "m.gsf"
    for out, extra in ((nc, []), (gwy, []), (gsf, ["--quantity", "e0"])):
        res = runner.invoke(app, ["export", str(fit_map), "-o", str(out), *extra])
        assert res.exit_code == 0, res.output
    ds = xr.open_dataset(nc, engine="h5netcdf")
    assert ds["e0"].attrs["units"] == "Pa" and ds["beta"].attrs["units"] == ""
    e0 = ds["e0"].sel(file=MAP.name).values
    np.testing.assert_allclose(e0[df["grid_y"], df["grid_x"]], df["e0"])
    fields = gwyfile.util.get_datafields(gwyfile.load(str(gwy)))
    key = next(k for k in fields if k.startswith("e0 |"))
    field = fields[key]
    np.testing.assert_allclose(field.data[df["grid_y"], df["grid_x"]], df["e0"])
    assert field["si_unit_z"]["unitstr"] == "Pa" and field["si_unit_xy"]["unitstr"] == "m"
    header, img = read_gsf(gsf)
    assert header["ZUnits"] == "Pa" and header["XYUnits"] == "m"
    np.testing.assert_allclose(img[df["grid_y"], df["grid_x"]], df["e0"], rtol=1e-6)  # float32


def test_gsf_header_is_padded_to_four_bytes():
    """The Gwyddion Simple Field layout: the header, 1-4 NUL bytes to a multiple of 4, then the
    floats (little-endian float32, row by row)."""
    img = np.arange(6.0).reshape(2, 3)
    raw = gsf_bytes(img, 3e-6, 2e-6, 0.0, 0.0, "m", "Pa", "t")
    end = raw.index(b"\0")
    start = (end // 4 + 1) * 4
    assert raw[end:start] == b"\0" * (start - end) and len(raw) == start + 24
    np.testing.assert_array_equal(np.frombuffer(raw[start:], "<f4").reshape(2, 3), img)


@pytest.mark.parametrize("case,expect", [
    ("suffix", "expected one of .nc, .gwy, .gsf"),
    ("not_a_map", "not a map table"),
    ("no_extra", 'pip install -e ".[export]"'),
])  # fmt: skip
def test_errors_are_one_line_and_write_nothing(tmp_path, monkeypatch, case, expect):
    table, out = SCAN, tmp_path / "out" / "map.nc"
    if case == "suffix":
        out = tmp_path / "out" / "map.tiff"
    elif case == "not_a_map":
        pd.DataFrame({"a": [1.0]}).to_parquet(tmp_path / "t.parquet")
        table = tmp_path / "t.parquet"
    else:
        monkeypatch.setitem(sys.modules, "h5netcdf", None)
    res = runner.invoke(app, ["export", str(table), "-o", str(out)])
    lines = res.output.strip().splitlines()
    assert res.exit_code == 2 and len(lines) == 1 and expect in lines[0], res.output
    assert not (tmp_path / "out").exists()


def test_every_committed_table_has_a_unit_for_every_column():
    """Units live in the data: every tracked Parquet table's metadata names a unit ('' for
    dimensionless and text columns: aic, bic, nu, status...) for each of its columns."""
    import subprocess

    import pyarrow.parquet as pq

    files = subprocess.run(["git", "ls-files", "*.parquet"], cwd=ROOT, capture_output=True, text=True).stdout.split()
    assert files
    for f in files:
        units = read_meta(ROOT / f).get("units", {})
        missing = [c for c in pq.read_schema(ROOT / f).names if c not in units]
        assert not missing, f"{f}: no unit for {missing[:5]}"
