"""``vetica simulate``: the config, the output path and the cost checked before the
simulation's modules are imported, so that a bad config or path is refused without loading
numba and the compiled kernels (:mod:`.simulate`)."""

from __future__ import annotations

from ..io import check_output_file
from .config import load


def simulate_file(config=None, output="run.parquet", overrides: dict | None = None, notice=None,
                  yes: bool = False):  # fmt: skip
    """``vetica simulate``: load a one-point YAML config (None = the defaults) with dotted
    ``overrides``, simulate it and write the run to ``output`` (Parquet with metadata).
    The config, the output path and the estimated cost (past the threshold every command
    asks past it needs ``yes``) are checked before the simulation starts; ``notice(line)``
    is called then when numba will compile the kernels this simulation needs (warm: not).
    Returns the :class:`~.simulate.Run`."""
    from ..checks import confirm_cost
    from .cost import simulation_seconds
    from .jit import compile_notice, simulation_modules

    cfg = load(config, overrides)
    check_output_file(output)
    confirm_cost("this simulation", simulation_seconds(cfg), yes)
    line = compile_notice(simulation_modules(cfg)) if notice is not None else None
    if line:
        notice(line)
    from ..io import write_run
    from .simulate import simulate  # numba and the kernels: only for a config that passed the checks

    run = simulate(cfg)
    write_run(run, output)
    return run
