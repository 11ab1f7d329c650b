"""Parametric sweeps: the grid of points (:mod:`.grid`), the cost estimate from the grid
alone (:mod:`.cost`), the sweep table (:mod:`.table`), the acceptance regime
(:mod:`.acceptance`) and the orchestration (:mod:`.sweep`).  The batch machinery is
:mod:`vetica_cli.batch`, the point task and the row schema :mod:`vetica_cli.rows`."""
