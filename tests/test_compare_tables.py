"""``scripts/compare_tables.py --identical``: a regenerated table that moved nothing but its wall
times is told apart from one that moved, and the figures drawn from it are found beside it (a
study whose name starts another's, ``dashpot`` and ``dashpot_vdw_off``, keeps its own)."""

import math

import pandas as pd

from script_module import script


def _script():
    return script("compare_tables")


def _table():
    return pd.DataFrame({"point": ["a", "b"], "k0": [64.0, math.nan], "unidentified": ["", "cd"], "wall_s": [1.0, 2.0]})


def test_a_table_that_moved_only_its_wall_times_is_identical():
    mod = _script()
    old, new = _table(), _table()
    new["wall_s"] = [3.5, 0.1]
    assert mod.same_but_timings(old, new)  # NaN equal to NaN, the timing column left out


def test_a_moved_value_a_flag_or_a_row_is_not_identical():
    mod = _script()
    old = _table()
    for change in ({"k0": [64.0 * (1 + 1e-15), math.nan]}, {"k0": [64.0, 1.0]}, {"unidentified": ["", "k0"]}):
        new = _table().assign(**change)
        assert not mod.same_but_timings(old, new), change
    assert not mod.same_but_timings(old, _table().iloc[:1])
    assert not mod.same_but_timings(old, _table().assign(extra=1))


def test_a_tables_figures_are_its_own(tmp_path):
    mod = _script()
    for stem in ("dashpot", "dashpot_vdw_off"):
        _table().to_parquet(tmp_path / f"{stem}.parquet")
    (tmp_path / "figures").mkdir()
    figs = [tmp_path / "figures" / n for n in ("dashpot_fig41.png", "dashpot_vdw_off_fig41.png", "setpoint_fig41.png")]
    assert mod.figures_of(tmp_path / "dashpot.parquet", figs) == [figs[0]]
    assert mod.figures_of(tmp_path / "dashpot_vdw_off.parquet", figs) == [figs[1]]
