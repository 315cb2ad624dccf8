"""Loops backed by a chain of neighbouring nodes that agree (Karto's way), and not alone."""

from __future__ import annotations

import numpy as np

from pfslam.backend.search import Loop, chained
from pfslam.config import GraphConfig
from pfslam.geometry import compose, relative


def path(n: int = 120) -> tuple[np.ndarray, np.ndarray]:
    poses = np.column_stack([np.arange(n) * 0.25, np.zeros(n), np.zeros(n)])
    travel = np.arange(n) * 0.25
    return poses, travel


def loop_at(poses: np.ndarray, anchor: int, node: int, fix: np.ndarray, submap: int = 0) -> Loop:
    """A loop that moves node ``node`` by the rigid motion ``fix`` (world frame)."""
    return Loop(anchor, node, submap, relative(poses[anchor], compose(fix, poses[node])), 0.8)


def test_a_chain_of_loops_that_agree_is_backed_and_a_lone_one_is_not() -> None:
    poses, travel = path()
    c = GraphConfig(chain_nodes=3)
    spans = [(0, 20), (10, 30)]
    fix = np.array([0.3, -0.2, np.deg2rad(2.0)])
    chain = [loop_at(poses, 0, k, fix) for k in (80, 81, 83)]
    lone = loop_at(poses, 0, 110, np.array([3.0, 0.0, 0.0]))
    assert chained(chain + [lone], spans, poses, travel, c) == [True, True, True, False]
    # neighbours that disagree (one moved a corridor step further) back nobody
    mixed = [loop_at(poses, 0, 80, fix), loop_at(poses, 0, 81, compose(np.array([3.0, 0, 0]), fix))]
    mixed.append(loop_at(poses, 0, 82, np.array([0.0, 1.0, 0.0])))
    assert chained(mixed, spans, poses, travel, c) == [False, False, False]
    # an overlapping submap counts; one far away does not; chains of one are off
    assert (
        chained(
            [loop_at(poses, 0, 80, fix), loop_at(poses, 10, 81, fix, 1), loop_at(poses, 0, 82, fix)],
            spans,
            poses,
            travel,
            c,
        )
        == [True] * 3
    )
    from dataclasses import replace

    assert chained([lone], spans, poses, travel, replace(c, chain_nodes=1)) == [True]
