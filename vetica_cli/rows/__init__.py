"""The rows of every batch table: the point task that simulates and extracts a point
(:mod:`.task`), the print-step policy deciding which points share a simulation
(:mod:`.plan`), the row schema built from the surface and method registries
(:mod:`.schema`) and the ``extract:`` section (:mod:`.extract`)."""
