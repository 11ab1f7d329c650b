"""Simulation of one point: the config (:mod:`.config`), ``simulate()`` and the
recorded :class:`~.simulate.Run` (:mod:`.simulate`), the per-run observables
(:mod:`.observables`) and the detector model applied after the kernel
(:mod:`.instrument`)."""
