"""``scripts/regenerate_all.py``: every step names files that exist, and every result table it is
meant to regenerate is written by one of its steps (a table no step writes goes stale unseen)."""

from pathlib import Path

from script_module import script

ROOT = Path(__file__).resolve().parent.parent


def _script():
    return script("regenerate_all")


def test_every_config_and_script_a_step_names_exists():
    mod = _script()
    for name, (commands, _docs) in mod.STEPS.items():
        for cmd in commands:
            for arg in cmd[1:]:
                if arg.endswith((".yaml", ".py")) and not arg.startswith("-"):
                    assert (ROOT / arg).is_file(), f"step {name}: {arg} does not exist"


def test_the_lab_scan_and_noise_tables_are_each_written_by_a_step():
    mod = _script()
    written = {a for commands, _ in mod.STEPS.values() for cmd in commands for a in cmd if a.endswith(".parquet")}
    for folder in ("lab", "scans"):
        for table in (ROOT / "results" / folder).glob("*.parquet"):
            assert str(table.relative_to(ROOT)) in written, f"no step writes {table.relative_to(ROOT)}"
    for table in ("results/noise/thermal_methods.parquet", "results/noise/stripped_records.parquet"):
        assert table in written


def test_list_runs_nothing_and_prints_every_step(capsys):
    mod = _script()
    assert mod.main(["--list"]) == 0
    out = capsys.readouterr().out
    assert all(f"{name}:" in out for name in mod.STEPS)
