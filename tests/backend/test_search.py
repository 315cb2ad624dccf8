"""The loop search where a front end slipped along a corridor: the match from its guess is a
local optimum there, and the local window's search finds the place."""

from __future__ import annotations

import numpy as np
from wallpoints import submap_of, walls

from pfslam.backend.nodes import Nodes
from pfslam.backend.search import search_node
from pfslam.backend.submaps import Submap
from pfslam.config import GraphConfig
from pfslam.geometry import compose, relative
from pfslam.kernels.bnb import pyramid_depth

RES = 0.05

# A corridor 3 m wide, bare but for door frames (short stubs off its walls) at uneven places:
# across, its walls pin a pose; along, only the frames do.
CORRIDOR = [(-12.0, -1.5, 12.0, -1.5), (-12.0, 1.5, 12.0, 1.5)] + [
    seg
    for x in (-7.3, -2.9, 0.8, 4.6, 8.9)
    for seg in ((x, -1.5, x, -1.1), (x + 0.9, -1.5, x + 0.9, -1.1), (x - 1.1, 1.5, x - 1.1, 1.1))
]


def seen_from(world: np.ndarray, pose: np.ndarray, reach: float = 8.0) -> np.ndarray:
    local = relative(pose, np.column_stack([world, np.zeros(len(world))]))[:, :2]
    return local[np.hypot(local[:, 0], local[:, 1]) <= reach]


def test_a_guess_slid_along_a_corridor_is_not_taken_for_the_loop() -> None:
    c = GraphConfig()
    world = walls(CORRIDOR)
    # the submap: the corridor's walls in the frame of its first node (at the origin)
    sub = submap_of(world, RES, c.field_sigma, pyramid_depth(int(round(c.window_m / RES))))
    assert isinstance(sub, Submap)
    truth = np.array([1.3, 0.2, np.deg2rad(2.0)])
    rng = np.random.default_rng(3)
    pts = seen_from(world, truth) + rng.normal(0.0, 0.005, (1, 2))
    dense = pts[:: max(1, len(pts) // 600)]
    sparse = dense[:: max(1, len(dense) // 200)]
    slid = compose(truth, np.array([0.35, 0.0, 0.0]))  # where the front end put the node: 35 cm along
    nodes = Nodes(
        np.array([0, 1]),
        np.array([np.zeros(3), slid]),
        [np.zeros((1, 2), np.float32), sparse.astype(np.float32)],
        dense=[np.zeros((1, 2), np.float32), dense.astype(np.float32)],
    )
    lp, tried = search_node(1, sub, 0, (0, 1), nodes.poses, False, np.array([0.0, 30.0]), nodes, c, RES)
    assert lp is not None and [t.stage for t in tried] == ["local"]
    err = relative(truth, lp.pose)
    assert np.hypot(err[0], err[1]) < 0.03 and abs(np.rad2deg(err[2])) < 0.5
