"""The batch layer (vetica_cli.batch) on its own: the progress bar's first estimate and
notice, and the numba-cache check behind the compile notice."""

import io
import os
import time

from rich.console import Console

from vetica_cli.batch.progress import Progress
from vetica_cli.simulation import jit


def test_the_bar_shows_the_cost_model_estimate_until_a_job_has_finished():
    out = io.StringIO()
    console = Console(file=out, force_terminal=False, width=200)
    bar = Progress(10, 0, 0, console=console, estimate_s=125.0)
    column = bar.progress.columns[-1]
    task = bar.progress.tasks[0]
    with bar:
        assert str(column.render(task)).startswith("~2:0")  # 125 s less the moments since the start
        bar.advance(1, 0)
        assert not str(column.render(task)).startswith("~")  # rich's measured time left from now on


def test_while_the_kernels_compile_the_bar_says_compiling_instead_of_counting_down():
    """The cold run's bar counted '~0:05 left ... ~0:00 left' through ~100 s of compilation: with
    a compile notice it prints the notice and says 'compiling' until the first job has finished."""
    out = io.StringIO()
    console = Console(file=out, force_terminal=False, width=200)
    bar = Progress(10, 0, 0, console=console, estimate_s=125.0, notice="compiling the kernels ...")
    column = bar.progress.columns[-1]
    task = bar.progress.tasks[0]
    with bar:
        assert str(column.render(task)) == "compiling"
        bar.advance(1, 0)
        assert str(column.render(task)) not in ("compiling", "") and not str(column.render(task)).startswith("~")
    assert "compiling the kernels ..." in out.getvalue()


def test_kernels_count_as_cached_only_with_an_index_newer_than_the_source(tmp_path, monkeypatch):
    """An empty NUMBA_CACHE_DIR: not cached (the notice is due); an index of every cached core
    module newer than its source: cached; one older than its source: stale, not cached."""
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    assert not jit.kernels_cached() and jit.compile_notice().startswith("compiling the numba kernels")
    modules = jit.cached_modules()
    assert {m.stem for m in modules} >= {"tapping", "expm"}
    sub = tmp_path / "core_0"
    sub.mkdir()
    for m in modules:
        (sub / f"{m.stem}.fn-1.py311.nbi").write_bytes(b"")
    assert jit.kernels_cached() and jit.compile_notice() is None
    old = time.time() - 10 * 365 * 86400
    os.utime(sub / f"{modules[0].stem}.fn-1.py311.nbi", (old, old))
    assert not jit.kernels_cached()


def test_the_notice_asks_only_for_the_modules_the_job_compiles(tmp_path, monkeypatch):
    """The notice printed on every warm run: it wanted an index for all 8 cached modules while a
    study compiles 4 (measured with an empty NUMBA_CACHE_DIR: an SLS simulation tapping and expm,
    VETICA on the reconstructed force superposition and paddle).  With exactly those indexes, the
    job's notice is None and the all-modules check still says not cached."""
    from vetica_cli.extraction import extraction_modules
    from vetica_cli.simulation.config import load

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    cfg = load(None)
    need = jit.simulation_modules(cfg) | extraction_modules(("vetica",))
    assert need == {"tapping", "expm", "superposition", "paddle"}
    assert jit.compile_notice(need) is not None
    for stem in need:
        (tmp_path / f"{stem}.fn-1.py311.nbi").write_bytes(b"")
    assert jit.compile_notice(need) is None and not jit.kernels_cached()
    hertz = jit.simulation_modules(load(None, {"surface.model": "hertz"}))
    assert "mdr" in hertz and jit.compile_notice(hertz) is not None
    thermal = jit.simulation_modules(load(None, {"numerics.temperature": 300}))
    assert {"thermal", "prescribed"} <= thermal
    lab = jit.simulation_modules(load(None, {"numerics.instrument": "lab"}))
    assert {"thermal", "prescribed", "detector"} <= lab and "detector" not in thermal
