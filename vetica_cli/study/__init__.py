"""Parametric studies: the grid of points (:mod:`.grid`), planning and shared
simulations (:mod:`.plan`), the task a worker runs (:mod:`.task`), launchers
(:mod:`.launch`), persisted parts (:mod:`.store`), the table schema
(:mod:`.schema`), the acceptance regime (:mod:`.acceptance`), the orchestration
(:mod:`.sweep`), the dry-run cost (:mod:`.cost`) and the progress bar."""
