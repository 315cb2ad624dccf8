"""The loop-closing back end behind either filter (``backend: graph``).

The filter's path is cut into nodes (a scan every ``graph.node_m`` of travel or
``graph.node_deg`` of turn). Each node's scan is matched point to line on the scans of the
nodes 1, 4 and 16 before it (:mod:`~pfslam.backend.registration`): those matches are edges of the
graph and place the nodes of each submap, so that a submap (a run of consecutive nodes, each
node in two) is as sharp as a scan. Each node is then matched against the older submaps near
it (:mod:`~pfslam.backend.search`): from where the front end put it first, by branch and bound
over max-pooled grids where that fails (:mod:`pfslam.kernels.bnb`), refined point to line with
an information matrix from its own fit. Every loop is checked against the front end's path
and against the other loops (:mod:`~pfslam.backend.consistency`) before the pose graph
(:mod:`~pfslam.backend.graph`) is solved on GTSAM; the scans between nodes follow their nodes.

Modules: :mod:`~pfslam.backend.nodes` (the nodes, their points, their submaps),
:mod:`~pfslam.backend.registration` (the scan-to-scan registration), :mod:`~pfslam.backend.submaps`
(a submap's field, pyramid and surface; the branch-and-bound match, the point-to-line
refinement), :mod:`~pfslam.backend.search` (the loop search), :mod:`~pfslam.backend.consistency`
(the gate and pairwise consistency), :mod:`~pfslam.backend.edges` (the edges' information),
:mod:`~pfslam.backend.graph` (the graph, its solve, the edges' variance factors, g2o files),
:mod:`~pfslam.backend.loops` (the closure of a run), :mod:`~pfslam.backend.start` (where a
resumed run's first scan lies in its session's map), :mod:`~pfslam.backend.settings` (the part
of a run's settings it reads). Sessions themselves (made, written, read, continued) are
:mod:`pfslam.pipeline.sessions`. It may import the config, geometry, sensor, maps and kernels; nothing here
imports a filter.
"""
