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


# The cached core modules a job compiles, measured: the indexes an empty NUMBA_CACHE_DIR holds after
# the job (a simulate, an extract per method, on the CLI).  An SLS or Wiechert simulation compiles tapping
# and expm, a hertz one mdr too (SurfaceModel.kernel_modules); thermal noise adds thermal and prescribed;
# a detector of finite bandwidth its low-pass (detector); an extraction its method's
# (ExtractionMethod.kernel_modules: vetica superposition, full prescribed, sls, superposition) and,
# for a force reconstructed in the tap windows, paddle (extraction_modules).
THERMAL_MODULES = ("thermal", "prescribed")
DETECTOR_MODULES = ("detector",)  # a detector of finite bandwidth (numerics.detector_bandwidth): its low-pass


def simulation_modules(cfg) -> set[str]:
    """The cached core modules a simulation of the resolved config ``cfg`` compiles."""
    mods = set(cfg.surface.surface_model.kernel_modules)
    if cfg.numerics.temperature > 0:
        mods |= set(THERMAL_MODULES)
    if cfg.numerics.detector_bandwidth > 0:
        mods |= set(DETECTOR_MODULES)
    return mods


def cached_modules() -> list[Path]:
    """The core modules with numba functions cached on disk (``cache=True`` in the source)."""
    return sorted(f for f in CORE.glob("*.py") if "cache=True" in f.read_text())


def kernels_cached(modules=None) -> bool:
    """True when every cached core module of ``modules`` (stems, e.g. ``{"tapping", "expm"}``;
    None: all of them) has an index in numba's cache newer than its source: what a job that
    compiles those modules finds without compiling."""
    env = os.environ.get("NUMBA_CACHE_DIR")
    roots = [Path(env)] if env else [CORE / "__pycache__"]
    for module in cached_modules():
        if modules is not None and module.stem not in modules:
            continue
        stamp = module.stat().st_mtime
        pattern = f"{module.stem}.*.nbi"
        found = [f for r in roots if r.is_dir() for f in (r.rglob(pattern) if env else r.glob(pattern))]
        if not any(f.stat().st_mtime >= stamp for f in found):
            return False
    return True


def compile_notice(modules=None) -> str | None:
    """One line for a command to print before its first job when the cache lacks the kernels
    of ``modules`` (the job's: :func:`simulation_modules` and the extraction's; None: every
    cached module), None when they are cached: a warm run prints nothing."""
    if kernels_cached(modules):
        return None
    return (f"compiling the numba kernels (first run, or after a code change; usually about {COMPILE_S:.0f} s on 2 "
            "cores, once: later runs read them from the cache) ...")  # fmt: skip
