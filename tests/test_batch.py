"""The batch layer (vetica_cli.batch) on its own: the progress bar's first estimate and
notice, and the numba-cache check behind the compile notice."""

import io
import os
import time

from rich.console import Console

from vetica_cli.batch.progress import Progress
from vetica_cli.simulation import jit


def test_the_bar_shows_the_cost_model_estimate_until_a_job_has_finished_and_prints_its_notice():
    out = io.StringIO()
    console = Console(file=out, force_terminal=False, width=200)
    bar = Progress(10, 0, 0, console=console, estimate_s=125.0, notice="compiling the kernels ...")
    column = bar.progress.columns[-1]
    task = bar.progress.tasks[0]
    with bar:
        assert str(column.render(task)).startswith("~2:0")  # 125 s less the moments since the start
        bar.advance(1, 0)
        assert not str(column.render(task)).startswith("~")  # rich's measured time left from now on
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
