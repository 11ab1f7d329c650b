"""What a process loads before it computes: the command line imports the heavy modules (numba
and the compiled kernels, pyarrow, pandas, scipy) only with the commands that use them, so
``vetica --help``, a refused config and a dry run start without them; and BLAS runs one thread
in every vetica process unless the user set its threads.

References: docs/performance.md ("Start-up": what a process imports, and why), docs/api.md
("Why the thread cap"); the modules' own docstrings (vetica_cli/__main__.py,
vetica_cli.batch.launch.cap_blas_threads).  Each check runs in a fresh interpreter, so that
the test process's own imports do not hide an import.  No timing is asserted: the times live in
docs/performance.md and scripts/readme_numbers.py.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("numba", "scipy", "scipy.stats", "pyarrow", "pandas", "matplotlib", "joblib")
BLAS_VARS = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS")


def fresh(code: str, env: dict | None = None, cwd: Path = ROOT) -> dict:
    """Run ``code`` in a new interpreter (this checkout first on the path); it prints one JSON line last."""
    base = {k: v for k, v in os.environ.items() if k not in BLAS_VARS}
    base["PYTHONPATH"] = os.pathsep.join([str(ROOT), base.get("PYTHONPATH", "")])
    res = subprocess.run([sys.executable, "-c", code], env={**base, **(env or {})}, cwd=cwd, capture_output=True,
                         text=True, timeout=120)  # fmt: skip
    assert res.returncode == 0, res.stderr
    return json.loads(res.stdout.strip().splitlines()[-1])


def loaded_after(argv: list[str], tmp_path: Path) -> dict:
    """``{"heavy": [...], "code": exit code}``: the heavy modules loaded by ``vetica ARGV`` (run by
    the console script's entry point, in a fresh interpreter)."""
    code = (
        "import json, sys\n"
        f"sys.argv = ['vetica', *{argv!r}]\n"
        "from vetica_cli.__main__ import main\n"
        "try:\n    main()\nexcept SystemExit as exc:\n    code = exc.code\nelse:\n    code = 0\n"
        f"print(json.dumps({{'heavy': [m for m in {HEAVY!r} if m in sys.modules], 'code': code}}))\n"
    )
    return fresh(code, cwd=tmp_path)


def test_importing_the_command_line_loads_no_heavy_module():
    """The CLI module (every command's options and help, the methods' registry) imports numpy,
    typer and the package's light modules only."""
    out = fresh(f"import json, sys; import vetica_cli.cli; "
                f"print(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))")
    assert out == []


@pytest.mark.parametrize("argv", [
    ["--help"],
    ["extract", "--help"],
    ["simulate", "--set", "surface.cd=-1", "-o", "run.parquet"],  # refused before the kernels are imported
    ["sweep", str(ROOT / "configs" / "smoke.yaml"), "--dry-run"],
    ["scan", str(ROOT / "configs" / "scan_edge.yaml"), "--dry-run"],
    ["advise", "--k-inf", "4", "--k0", "64", "--cd", "-1"],  # refused before the study
    ["bench", "--set", "surface.k_inf=1e20"],  # refused before the bench
    ["fit", "missing-folder", "--tip-radius", "5e-6"],  # refused before any fit
    ["extract", "missing.parquet"],  # refused before the table is read
])  # fmt: skip
def test_commands_that_compute_nothing_load_no_heavy_module(argv, tmp_path):
    out = loaded_after(argv, tmp_path)
    assert out["heavy"] == [] and out["code"] in (0, 2, None)
    assert not (tmp_path / "run.parquet").exists()


def test_the_extraction_methods_register_without_numba_or_scipy():
    """``vetica_cli.extraction`` registers every method (their declarations: options, flags, help)
    without the compiled kernels or scipy: those load when a method runs."""
    out = fresh("import json, sys; from vetica_cli.extraction import METHODS; "
                "print(json.dumps([list(METHODS), [m for m in ('numba', 'scipy') if m in sys.modules]]))")  # fmt: skip
    assert "full" in out[0] and "vetica" in out[0] and out[1] == []


BLAS_CODE = (
    "import json, os, sys\n"
    "sys.argv = ['vetica', '--version']\n"
    "from vetica_cli.__main__ import main\n"
    "try:\n    main()\nexcept SystemExit:\n    pass\n"
    "from threadpoolctl import threadpool_info\n"
    "print(json.dumps(sorted({p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas'})))\n"
)


def test_the_command_line_runs_blas_on_one_thread():
    """Before numpy loads, the command caps BLAS at one thread (the workers' cap), for the
    process and the workers it starts."""
    assert fresh(BLAS_CODE) == [1]


TWO_CORES = pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="BLAS runs at most a thread per core")


@TWO_CORES
def test_the_users_own_thread_setting_stands():
    """A user who set any of the BLAS/OpenMP variables keeps their setting, whole."""
    assert fresh(BLAS_CODE, env={"OPENBLAS_NUM_THREADS": "2"}) == [2]


@TWO_CORES
def test_the_api_caps_at_the_environments_threads(monkeypatch):
    """``threads`` left out: the environment's setting (here 2), else 1; given: that number."""
    from threadpoolctl import threadpool_info

    from vetica_cli import api

    def blas() -> set:
        return {p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}

    seen = []
    probe = api.capped(lambda: seen.append(blas()))
    for var in BLAS_VARS:
        monkeypatch.delenv(var, raising=False)
    probe()
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    probe()
    probe(threads=1)
    assert seen == [{1}, {2}, {1}]


def test_the_detector_low_pass_is_lfilter_to_the_bit_without_scipy_stats():
    """The detector's one-pole low-pass (vetica_cli.simulation.instrument.detector_lowpass) gives
    scipy.signal.lfilter's numbers exactly (reference: lfilter([1 - a], [1, -a], x, zi=...)),
    and filtering imports neither scipy.signal nor, through it, scipy.stats."""
    import math

    import numpy as np
    from scipy.signal import lfilter

    from vetica_cli.simulation.instrument import detector_lowpass

    x = np.random.default_rng(3).normal(size=5001) * 1e-9 + 1e-8 * np.sin(0.01 * np.arange(5001))
    fc, ts = 5e6, 2e-9
    a = math.exp(-2.0 * math.pi * fc * ts)
    once, _ = lfilter([1.0 - a], [1.0, -a], x, zi=[a * x[0]])
    _, zf = lfilter([1.0 - a], [1.0, -a], x, zi=[a * x[-1]])
    twice, _ = lfilter([1.0 - a], [1.0, -a], x, zi=zf)
    assert np.array_equal(detector_lowpass(x, fc, ts, False), once)
    assert np.array_equal(detector_lowpass(x, fc, ts, True), twice)
    out = fresh("import json, sys, numpy as np; from vetica_cli.simulation.instrument import detector_lowpass; "
                "detector_lowpass(np.ones(10), 5e6, 2e-9, True); "
                "print(json.dumps([m for m in ('scipy.signal', 'scipy.stats') if m in sys.modules]))")  # fmt: skip
    assert out == []
