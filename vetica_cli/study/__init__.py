"""Parametric studies: the grid of points (:mod:`.grid`), planning and shared
simulations (:mod:`.plan`), the task a worker runs (:mod:`.task`), launchers
(:mod:`.launch`), persisted parts (:mod:`.store`), the output lock (:mod:`.lock`),
the table schema and row statuses (:mod:`.schema`), the acceptance regime
(:mod:`.acceptance`), the orchestration (:mod:`.sweep`), the cost estimate from the
grid alone (:mod:`.cost`) and the progress bar."""
