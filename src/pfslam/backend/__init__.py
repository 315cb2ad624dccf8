"""The loop-closing back end behind either filter (``backend: graph``).

The filter's path is cut into nodes (a scan every ``graph.node_m`` of travel or
``graph.node_deg`` of turn); runs of consecutive nodes make submaps (each node in two),
local score fields in the frame of their first node. Each node is matched against the
older submaps near it over a window of metres and tens of degrees, by branch and bound over
max-pooled grids (:mod:`pfslam.kernels.bnb`), then refined below a cell; a match that
scores well enough is a loop edge. The pose graph (:mod:`~pfslam.backend.graph`):
consecutive nodes joined by the front end's relative poses, loop edges under a robust loss,
solved by Levenberg-Marquardt on GTSAM. The scans between nodes follow their nodes.

Modules: :mod:`~pfslam.backend.graph` (the graph, its solve, g2o files),
:mod:`~pfslam.backend.loops` (nodes, submaps, the search, the closure of a run). It may
import the config, geometry, sensor, maps and kernels; nothing here imports a filter.
"""
