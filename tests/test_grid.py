"""The sweep grammar (vetica_cli.study.grid): lists, logspace, linspace, zip groups,
derived keys, the cartesian product, and one-line errors for bad study configs.

Reference values are the grammar's definitions: ``logspace [a, b, n]`` is
``10**linspace(a, b, n)``, ``linspace`` is numpy's, derived keys follow thesis
4.4.2 (``k0 = ratio * k_inf``) and 4.5.1 (``f2 = 15 f1``).  Values are rounded
to 12 significant digits by design, so comparisons use rel=1e-12.
"""

import numpy as np
import pytest

from vetica_cli.errors import ConfigError
from vetica_cli.study.grid import config_keys, expand, load_study, parse_values, point_key, sweepable_keys


def test_logspace_gives_clean_decades_and_points_per_decade():
    v = parse_values("surface.cd", {"logspace": [-5, 3, 33]})
    assert len(v) == 33
    np.testing.assert_allclose(v, np.logspace(-5, 3, 33), rtol=1e-12)
    # 4 points a decade: every 4th value is an exact power of ten as written in a table
    assert v[0] == 1e-5 and v[4] == 1e-4 and v[20] == 1.0 and v[-1] == 1e3
    assert [repr(x) for x in v[::4]] == [repr(10.0**e) for e in range(-5, 4)]


def test_linspace_and_lists():
    np.testing.assert_allclose(
        parse_values("operation.setpoint", {"linspace": [0.25, 0.8, 5]}), [0.25, 0.3875, 0.525, 0.6625, 0.8], rtol=1e-12
    )
    assert parse_values("probe.k2", [200, 700, 1200]) == [200, 700, 1200]
    # YAML 1.1 reads 1e-4 without a dot as a string: range arguments accept it
    assert parse_values("surface.cd", {"logspace": ["-4", "-3", 2]}) == [1e-4, 1e-3]


def test_cartesian_product_first_key_varies_slowest():
    st = expand({"sweep": {"surface.cd": [1e-5, 1e-4, 1e-3], "operation.setpoint": [0.5, 0.7]}})
    assert st.keys == ("surface.cd", "operation.setpoint")
    got = [(p.values["surface.cd"], p.values["operation.setpoint"]) for p in st.points]
    assert got == [(1e-5, 0.5), (1e-5, 0.7), (1e-4, 0.5), (1e-4, 0.7), (1e-3, 0.5), (1e-3, 0.7)]
    for p in st.points:
        assert p.config.surface.cd == p.values["surface.cd"]
        assert p.config.operation.setpoint == p.values["operation.setpoint"]
    assert [p.index for p in st.points] == list(range(6))
    assert len({p.key for p in st.points}) == 6


def test_zip_group_varies_keys_together_and_is_one_factor():
    st = expand(
        {
            "sweep": {
                "zip": {"probe.f1": [10e3, 50e3, 100e3], "numerics.max_time": [0.05, 0.01, 0.005]},
                "surface.cd": [1e-5, 1e-3],
            }
        }
    )
    assert len(st.points) == 6
    assert st.keys == ("probe.f1", "numerics.max_time", "surface.cd")
    pairs = {(p.config.probe.f1, p.config.numerics.max_time) for p in st.points}
    assert pairs == {(10e3, 0.05), (50e3, 0.01), (100e3, 0.005)}


def test_derived_keys_stiffness_ratio_and_f2_ratio():
    st = expand(
        {
            "surface": {"k_inf": 4.0},
            "probe": {"f2_ratio": 15},
            "sweep": {"surface.stiffness_ratio": [0.125, 1, 32], "probe.f1": [10e3, 100e3]},
        }
    )
    assert len(st.points) == 6
    for p in st.points:
        assert p.config.surface.k0 == pytest.approx(4.0 * p.values["surface.stiffness_ratio"], rel=1e-12, abs=0.0)
        assert p.config.probe.f2 == pytest.approx(15 * p.config.probe.f1, rel=1e-12)
    assert sorted({p.config.surface.k0 for p in st.points}) == [0.5, 4.0, 128.0]


def test_derived_key_follows_a_swept_source():
    st = expand({"sweep": {"surface.k_inf": [2.0, 4.0], "surface.stiffness_ratio": [16]}})
    assert [p.config.surface.k0 for p in st.points] == [32.0, 64.0]


def test_swept_derived_key_overrides_base_target_and_resolved_config_reruns():
    raw = {"name": "x", "surface": {"stiffness_ratio": 16}, "sweep": {"surface.cd": [1e-5, 1e-4]}}
    st = expand(raw)
    assert {p.config.surface.k0 for p in st.points} == {64.0}
    # the saved, resolved config expands to the same points
    again = expand(st.resolved())
    assert [p.key for p in again.points] == [p.key for p in st.points]
    st2 = expand({"surface": {"k0": 10.0}, "sweep": {"surface.stiffness_ratio": [2, 4]}})
    assert [p.config.surface.k0 for p in st2.points] == [8.0, 16.0]


def test_overrides_apply_to_the_base_only():
    st = expand({"sweep": {"surface.cd": [1e-5]}}, overrides={"numerics.print_step": 1e-9})
    assert st.points[0].config.numerics.print_step == 1e-9
    with pytest.raises(ConfigError, match="swept"):
        expand({"sweep": {"surface.cd": [1e-5]}}, overrides={"surface.cd": 1e-4})


def test_point_key_is_stable_and_config_sensitive():
    a = expand({"sweep": {"surface.cd": [1e-5, 1e-4]}})
    b = expand({"sweep": {"surface.cd": [1e-5, 1e-4]}})
    assert [p.key for p in a.points] == [p.key for p in b.points]
    assert a.points[0].key == point_key(a.points[0].config)
    assert a.points[0].key != a.points[1].key


def test_sweepable_keys_cover_the_schema_and_derived_keys():
    keys = sweepable_keys()
    assert "surface.cd" in keys and "numerics.print_step" in keys
    assert "surface.stiffness_ratio" in keys and "probe.f2_ratio" in keys
    assert set(config_keys()) < set(keys)


@pytest.mark.parametrize(
    "raw, fragment",
    [
        ({"sweep": {"surface.kzero": [1, 2]}}, "unknown key 'surface.kzero'"),
        ({"sweep": {"nosection.cd": [1, 2]}}, "unknown key 'nosection.cd'"),
        ({"sweep": {"surface.cd": {"logspace": [-5, 3]}}}, "[first, last, n]"),
        ({"sweep": {"surface.cd": {"logspace": [-5, 3, 2.5]}}}, "integer"),
        ({"sweep": {"surface.cd": {"logspace": [-5, 3, -1]}}}, "integer >= 1"),
        ({"sweep": {"surface.cd": {"logspace": ["a", 3, 4]}}}, "finite number"),
        ({"sweep": {"surface.cd": {"geomspace": [1, 2, 3]}}}, "expected a list"),
        ({"sweep": {"surface.cd": 1e-4}}, "expected a list"),
        ({"sweep": {"surface.cd": {"logspace": [-5, 3, 0]}}}, "empty grid"),
        ({"sweep": {"surface.cd": []}}, "empty grid"),
        ({"sweep": {}}, "empty grid"),
        ({"surface": {"cd": 1e-4}}, "empty grid"),
        ({"sweep": {"zip": {"probe.f1": [1e4, 2e4], "probe.f2": [1e5]}}}, "equal lengths"),
        ({"sweep": {"operation.setpoint": [0.5, 1.2]}}, "operation.setpoint"),
        ({"sweep": {"surface.stiffness_ratio": [1], "surface.k0": [4]}}, "both swept"),
        ({"surface": {"stiffness_ratio": 2, "k0": 4}, "sweep": {"surface.cd": [1]}}, "both set"),
        ({"sweep": {"surface.cd": [1e-4, 1e-4]}}, "surface.cd=0.0001 appears twice"),
        ({"sweep": {"extract.method": ["vetica", "vetica"]}}, "extract.method='vetica' appears twice"),
        ({"sweep": {"surface.cd": [1e-4, "1e-4"]}}, "same config"),
        ({"sweep": {"surface.cd": [1e-4]}, "sweeps": 1}, "unknown top-level key"),
        ({"sweep": {"surface.stiffness_ratio": [-1]}}, "ratio > 0"),
    ],
)
def test_bad_study_configs_raise_one_line_config_errors(raw, fragment):
    with pytest.raises(ConfigError) as exc:
        expand(raw)
    msg = str(exc.value)
    assert fragment in msg
    assert "\n" not in msg


def test_invalid_point_is_named_in_the_error():
    with pytest.raises(ConfigError, match=r"point 1 \(operation.setpoint=1.2\)"):
        expand({"sweep": {"operation.setpoint": [0.5, 1.2]}})


def test_load_study_names_the_study_after_the_file(tmp_path):
    p = tmp_path / "mystudy.yaml"
    p.write_text("sweep:\n  surface.cd: {logspace: [-5, -4, 2]}\n")
    st = load_study(p)
    assert st.name == "mystudy"
    assert [pt.values["surface.cd"] for pt in st.points] == [1e-5, 1e-4]
