"""A loop's uncertainty from its whole score surface (issue 53): places that score about as
well as the match widen its covariance towards them, so a match with a look-alike a pillar's
width along a corridor says so, where the curvature at its peak cannot; a match whose look-alikes
lie every way is refused."""

from __future__ import annotations

import numpy as np
from wallpoints import submap_of as wall_submap
from wallpoints import walls

from pfslam.backend.submaps import Submap, surface_spread
from pfslam.config import GraphConfig
from pfslam.geometry import relative
from pfslam.kernels.bnb import pyramid_depth

RES = 0.05


def submap_of(segments: list[tuple[float, float, float, float]]) -> tuple[Submap, np.ndarray]:
    world = walls(segments)
    sub = wall_submap(world, RES, GraphConfig().field_sigma, pyramid_depth(10))
    assert isinstance(sub, Submap)
    return sub, world


def seen(world: np.ndarray, pose: np.ndarray, reach: float = 8.0) -> np.ndarray:
    local = relative(pose, np.column_stack([world, np.zeros(len(world))]))[:, :2]
    return local[np.hypot(local[:, 0], local[:, 1]) <= reach][::3]


def spread_at(segments: list[tuple[float, float, float, float]], pose: np.ndarray) -> np.ndarray:
    c = GraphConfig()
    sub, world = submap_of(segments)
    pts = seen(world, pose)
    return surface_spread(sub, pts, pose, RES, c.surface_m, c.surface_deg, c.near_best, c.peak_m, c.peak_deg)


def test_a_room_pins_the_match_and_widens_nothing() -> None:
    room = [(-3.0, -2.0, 3.0, -2.0), (3.0, -2.0, 3.0, 2.5), (3.0, 2.5, -3.0, 2.5), (-3.0, 2.5, -3.0, -2.0)]
    room += [(0.5, -2.0, 0.5, -1.2), (-1.5, 2.5, -1.5, 1.9)]
    s = spread_at(room, np.array([0.2, 0.1, 0.1]))
    assert np.sqrt(s[0, 0]) < 0.02 and np.sqrt(s[1, 1]) < 0.02 and np.sqrt(s[2, 2]) < np.deg2rad(0.3)


def test_a_bare_corridor_is_wide_along_and_tight_across() -> None:
    corridor = [(-20.0, -1.5, 20.0, -1.5), (-20.0, 1.5, 20.0, 1.5)]
    s = spread_at(corridor, np.array([0.0, 0.0, 0.0]))
    assert np.sqrt(s[0, 0]) > 0.2  # along: every place scores the same
    assert np.sqrt(s[1, 1]) < 0.03  # across: pinned


def test_a_look_alike_a_pillars_width_along_widens_the_loop_that_way() -> None:
    """Stubs every 0.5 m on both walls: the scan fits as well half a metre along, and the
    spread says so along the corridor (not across it), whichever way the match is turned."""
    corridor = [(-20.0, -1.5, 20.0, -1.5), (-20.0, 1.5, 20.0, 1.5)]
    stubs = [(x, -1.5, x, -1.2) for x in np.arange(-3.0, 3.01, 0.5)] + [
        (x, 1.5, x, 1.2) for x in np.arange(-3.0, 3.01, 0.5)
    ]
    corridor += stubs
    for heading in (0.0, np.pi / 2):
        turn = np.array([[np.cos(heading), -np.sin(heading)], [np.sin(heading), np.cos(heading)]])
        segs = [tuple((turn @ np.array(s[:2])).tolist() + (turn @ np.array(s[2:])).tolist()) for s in corridor]
        s = spread_at(segs, np.array([0.0, 0.0, heading]))  # type: ignore[arg-type]
        # in the match's own frame: along is x, across y
        assert np.sqrt(s[0, 0]) > 0.25, s
        assert np.sqrt(s[1, 1]) < 0.05, s
