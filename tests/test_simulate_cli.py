"""`vetica simulate`: configuration errors exit 2 with one line and write nothing;
a good run writes a self-describing Parquet."""

import json

import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from vetica_cli.cli import app
from vetica_cli.errors import ConfigError
from vetica_cli.simulation.config import from_dict, load, parse_set

runner = CliRunner()

# cheap point: coarse print step, few recorded periods
CHEAP = ["--set", "numerics.print_step=1e-9", "--set", "numerics.record_cycles=2"]


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--set", "surface.k0=-5"], "surface.k0"),
        (["--set", "probe.f1=0"], "probe.f1"),
        (["--set", "operation.setpoint=1.2"], "operation.setpoint"),
        (["--set", "numerics.print_step=1e-11"], "numerics.print_step"),
        (["--set", "numerics.print_step=0.13e-9"], "integer multiple"),
        (["--set", "surface.kzero=5"], "surface.kzero"),
        (["--set", "nosection.k=5"], "nosection.k"),
        (["--set", "surface.cd=abc"], "surface.cd"),
        (["--set", "surface.vdw_on_surface=maybe"], "surface.vdw_on_surface"),
        (["--set", "numerics.record_cycles=2.5"], "numerics.record_cycles"),
        (["--set", "surface.k0"], "section.key=value"),
    ],
)
def test_bad_configuration_exits_2_names_key_and_writes_nothing(tmp_path, args, fragment):
    out = tmp_path / "run.parquet"
    result = runner.invoke(app, ["simulate", *args, "-o", str(out)])
    assert result.exit_code == 2
    msg = result.stderr.strip()
    assert fragment in msg
    assert len(msg.splitlines()) == 1
    assert "Traceback" not in result.output
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []


def test_bad_yaml_file_and_unknown_section_exit_2(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("surface: {k0: [1, 2\n")
    r = runner.invoke(app, ["simulate", str(bad), "-o", str(tmp_path / "o.parquet")])
    assert r.exit_code == 2 and "not valid YAML" in r.stderr
    unk = tmp_path / "unk.yaml"
    unk.write_text("surfaces:\n  k0: 3\n")
    r = runner.invoke(app, ["simulate", str(unk), "-o", str(tmp_path / "o.parquet")])
    assert r.exit_code == 2 and "surfaces" in r.stderr
    missing = runner.invoke(app, ["simulate", str(tmp_path / "nope.yaml")])
    assert missing.exit_code == 2 and "does not exist" in missing.stderr
    assert not (tmp_path / "o.parquet").exists()


def test_config_error_messages_state_allowed_values():
    with pytest.raises(ConfigError, match=r"surface\.k_inf: -1.0 is not allowed; expected a stiffness in \[1e-06, "
                       r"1e\+06\] N/m \(a contact's spring"):  # the one range of the quantity (vetica_cli.ranges)
        from_dict({"surface": {"k_inf": -1.0}})
    with pytest.raises(ConfigError, match="allowed in probe"):
        load(None, {"probe.mass": 1.0})
    assert parse_set(["surface.cd=1e-4", "surface.vdw_on_surface=false"]) == {
        "surface.cd": 1e-4,
        "surface.vdw_on_surface": False,
    }


def test_simulate_writes_columns_units_params_and_observables(tmp_path):
    out = tmp_path / "run.parquet"
    result = runner.invoke(app, ["simulate", *CHEAP, "--set", "surface.cd=1e-4", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert "stop_reason: steady" in result.stdout
    table = pq.read_table(out)
    assert table.column_names == [
        "t", "z_tip", "z_cantilever", "z_paddle", "z_base", "f_ts", "x_surface", "x_dashpot", "segment",
    ]  # fmt: skip
    meta = json.loads(table.schema.metadata[b"vetica"])
    assert meta["stop_reason"] == "steady"
    assert meta["params"]["surface"]["cd"] == 1e-4
    assert meta["params"]["numerics"]["dt"] == 0.025e-9
    assert meta["units"]["f_ts"] == "N" and meta["units"]["t"] == "s"
    import pint  # every unit of a run parses with a unit library; the segment's meaning is apart

    ureg = pint.UnitRegistry()
    for unit in meta["units"].values():
        ureg.parse_units(unit)
    assert meta["descriptions"]["segment"].startswith("approach = ")
    for key in (
        "e_diss_ev", "peak_force", "max_penetration", "contact_time", "noncontact_time", "paddle_amplitude",
        "ss_zero_depth", "amplitude", "phase_deg", "virial_ev", "z1",
    ):  # fmt: skip
        assert isinstance(meta["observables"][key], float), key
    segs = set(table.column("segment").to_pylist())
    assert segs == {"approach", "steady"}
    assert meta["version"]
    # no temporary files left behind
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.parquet"]


def test_time_budget_exhaustion_is_reported_not_hidden(tmp_path):
    """The time-stepped transient with a budget too short to settle: stop_reason max_time,
    a warning, and the last periods still recorded."""
    out = tmp_path / "run.parquet"
    r = runner.invoke(
        app, ["simulate", *CHEAP, "--set", "numerics.steady=transient", "--set", "numerics.max_time=0.3e-3",
              "--set", "numerics.settle_cycles=1", "-o", str(out)],
    )  # fmt: skip
    assert r.exit_code == 0, r.output
    meta = json.loads(pq.read_schema(out).metadata[b"vetica"])
    assert meta["stop_reason"] == "max_time"
    assert any("no proven periodic state" in w for w in meta["warnings"])
    assert "warning: no proven periodic state" in r.stdout
    assert len(pq.read_table(out).column("t")) > 0
