"""Whether numba's on-disk cache holds the compiled kernels, so a command can say, before a
silent first job, that the kernels are being compiled and how long that usually takes.

numba caches each ``cache=True`` function of :mod:`vetica_cli.core` as an index (``.nbi``)
beside the module (``core/__pycache__``) or under ``NUMBA_CACHE_DIR``; an index older than
its module's source is stale and the function is compiled again.
"""

from __future__ import annotations

import os
from pathlib import Path

CORE = Path(__file__).resolve().parent.parent / "core"
# [s] compiling the worked example's kernels from an empty cache, measured on the 2-core
# project machine at load ~4 (shared): 60 s cold against 4.3 s warm (`vetica simulate
# configs/worked_example.yaml` with NUMBA_CACHE_DIR emptied)
COMPILE_S = 55.0


def cached_modules() -> list[Path]:
    """The core modules with numba functions cached on disk (``cache=True`` in the source)."""
    return sorted(f for f in CORE.glob("*.py") if "cache=True" in f.read_text())


def kernels_cached() -> bool:
    """True when every cached core module has an index in numba's cache newer than its source."""
    env = os.environ.get("NUMBA_CACHE_DIR")
    roots = [Path(env)] if env else [CORE / "__pycache__"]
    for module in cached_modules():
        stamp = module.stat().st_mtime
        pattern = f"{module.stem}.*.nbi"
        found = [f for r in roots if r.is_dir() for f in (r.rglob(pattern) if env else r.glob(pattern))]
        if not any(f.stat().st_mtime >= stamp for f in found):
            return False
    return True


def compile_notice() -> str | None:
    """One line for a command to print before its first job when the cache lacks the kernels
    (None when they are cached)."""
    if kernels_cached():
        return None
    return (f"compiling the numba kernels (first run, or after a code change; usually about {COMPILE_S:.0f} s on 2 "
            "cores, once: later runs read them from the cache) ...")  # fmt: skip
