"""Virtual imaging: a sample map and a raster scan of it, one pixel after
the other as a tapping-mode AFM scans, with the surface extracted on every pixel.

:mod:`.sample` (geometry, painting the raster), :mod:`.config` (the scan config),
:mod:`.pixel` (driving the kernel pixel by pixel), :mod:`.line` (a line as a job),
:mod:`.table` (the tidy table), :mod:`.run` (``vetica scan``), :mod:`.analysis`
(per-domain statistics, apparent heights, edge widths).
"""
