"""The random buildings (pfslam.tools.buildings): their sizes, their routes' clearance from the
walls, the features along the corridors, one building per seed; the world ``random`` of the
simulators; the walk's standing start and the wheeled robot's laser mount."""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest
from wallpoints import crossing, point_distances

from pfslam.errors import ConfigError
from pfslam.tools.buildings import (
    CLEARANCE,
    MAX_LAP,
    PILLAR_CLEAR,
    RUN,
    WIDTH,
    Building,
    Wall,
    building,
    lap_length,
    random_building,
    route_clearance,
    walked_runs,
)
from pfslam.tools.places import world_named
from pfslam.tools.walk import GAITS, Prim, build_path, eval_path, routed
from pfslam.tools.wheeled import WHEELED
from pfslam.tools.worlds import WORLDS, World

SEEDS = range(100)
EPS = 1e-9  # m: sums of centimetres in floating point


@pytest.fixture(scope="module")
def buildings() -> list[Building]:
    return [building(seed) for seed in SEEDS]


def _turns(wp: np.ndarray) -> np.ndarray:
    """The turn (deg) at every waypoint of the closed route (0 where it goes straight on)."""
    d = np.roll(wp, -1, axis=0) - wp
    h = np.arctan2(d[:, 1], d[:, 0])
    return np.rad2deg(np.angle(np.exp(1j * (h - np.roll(h, 1)))))


def _corners(wp: np.ndarray) -> np.ndarray:
    """The turns (deg) at the route's corners, in order from waypoint 0."""
    turn = _turns(wp)
    return turn[np.abs(turn) > 1e-6]


def _unmirrored(b: Building) -> tuple[np.ndarray, np.ndarray]:
    """The building's wall segments and waypoints in its plan's frame."""
    if b.mirrored:
        return b.world.segments[:, [1, 0, 3, 2]], b.world.waypoints[:, ::-1]
    return b.world.segments, b.world.waypoints


def test_route_clearance_measures_the_nearest_wall() -> None:
    """The helper itself: a wall beside a leg, one across it, one near a corner."""
    square = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    w = World("t", np.array([[2.0, 0.3, 8.0, 0.3]]), waypoints=square)
    assert route_clearance(w) == pytest.approx(0.3)
    w = World("t", np.array([[5.0, -1.0, 5.0, 1.0], [20.0, 20.0, 30.0, 30.0]]), waypoints=square)
    assert route_clearance(w) == 0.0  # crossing a leg
    w = World("t", np.array([[-3.0, 11.0, -1.0, 11.0]]), waypoints=square)
    assert route_clearance(w) == pytest.approx(np.hypot(1.0, 1.0))  # nearest the corner (0, 10)
    assert walked_runs(np.array([[4.0, 0.0], [10.0, 0.0], [10.0, 6.0], [0.0, 6.0], [0.0, 0.0]])) == [
        6.0,
        10.0,
        6.0,
        10.0,
    ]


def test_route_clears_every_wall(buildings: list[Building]) -> None:
    """Every leg of every route keeps 0.4 m from every wall, and so does the walk along it, each
    gait (arcs round the corners: the humanoid's calm 0.8 m and the wheeled robot's 0.6 m;
    the rough gait's turns in place), both ways round, over a lap and a half."""
    for b in buildings:
        assert route_clearance(b.world) >= CLEARANCE, b.seed
        for route in ("loop", "reverse"):
            w = routed(b.world, route)
            for gait, speed in ((GAITS["calm"], 0.5), (GAITS["rough"], 0.5), (WHEELED, 0.6)):
                duration = 1.5 * lap_length(w) / speed
                prims = build_path(w, duration, np.random.default_rng(b.seed), gait, speed)
                xy, _ = eval_path(prims, np.arange(0.0, duration, 0.5))
                assert point_distances(xy[:, :2], w.segments).min() >= CLEARANCE, (b.seed, route)


def test_sizes_in_range(buildings: list[Building]) -> None:
    for b in buildings:
        wp = b.world.waypoints
        assert WIDTH[0] <= b.width <= WIDTH[1]
        runs = b.runs()
        assert all(RUN[0] <= r <= RUN[1] for r in runs), (b.seed, runs)
        assert lap_length(b.world) <= MAX_LAP + EPS <= 130.0 + EPS  # a humanoid lap at 0.5 m/s: 260 s and its pauses
        turns = _corners(wp)
        np.testing.assert_allclose(np.abs(turns), 90.0, atol=1e-9)  # every corner a right angle
        assert len(runs) == len(turns) == 4 * b.blocks
        if b.blocks == 1:  # a loop: the same way round at every corner
            assert abs(turns.sum()) == pytest.approx(360.0)
        else:  # a figure of eight: as many turns each way, the cross corridor walked twice
            assert turns.sum() == pytest.approx(0.0) and np.sum(turns > 0) == 4
        # the route's outer legs run half a width inside the outer walls
        _, wpu = _unmirrored(b)
        np.testing.assert_allclose(wpu.min(axis=0), [b.width / 2] * 2)
        np.testing.assert_allclose(wpu.max(axis=0), np.array(b.size) - b.width / 2)
        # the start: the first waypoint, facing along the first leg
        d = wp[1] - wp[0]
        np.testing.assert_allclose(b.world.start, [*wp[0], np.arctan2(d[1], d[0])])
        assert b.world.name == f"random-{b.seed}"


def test_one_and_two_blocks_occur(buildings: list[Building]) -> None:
    ones = sum(b.blocks == 1 for b in buildings)
    assert 45 <= ones <= 80, ones
    assert sum(b.mirrored for b in buildings) >= 20 and sum(not b.mirrored for b in buildings) >= 20


def test_features_apart_and_clear_of_the_corners(buildings: list[Building]) -> None:
    """Pillars protrude at most width/2 - 0.5 m; the features of a wall do not overlap; every
    wall that is not an outer wall or a block's face (the features' own) keeps a width + 1 m
    (along the corridor) from the corridor crossings at the route's corners; no two walls of a
    building cross."""
    kinds: set[str] = set()
    for b in buildings:
        kinds |= {f.kind for f in b.features}
        for k, st in enumerate(b.stretches):
            fs = sorted((f for f in b.features if f.stretch == k), key=lambda f: f.lo)
            for f in fs:
                assert st.lo <= f.lo < f.hi <= st.hi
                if f.kind == "pillar":
                    assert 0.3 - EPS <= f.hi - f.lo <= 1.2 + EPS and 0.2 <= f.depth <= b.width / 2 - PILLAR_CLEAR + EPS
                elif f.kind == "notch":
                    assert 0.3 - EPS <= f.hi - f.lo <= 1.2 + EPS and 0.2 <= f.depth <= 0.5
                else:
                    assert f.door is not None and 0.8 - EPS <= f.door[1] - f.door[0] <= 1.2 + EPS
                    assert f.lo < f.door[0] < f.door[1] < f.hi
                    if f.kind == "room":
                        assert st.outer and 3.0 - EPS <= f.hi - f.lo <= 6.0 + EPS and 3.0 <= f.depth <= 6.0
                    else:
                        assert not st.outer
            for f, g in zip(fs, fs[1:]):
                assert g.lo >= f.hi + 0.5 - EPS, (b.seed, f, g)
        segs, wp = _unmirrored(b)
        own = np.array([s for s in segs if not _on_a_wall(s, b.walls)]).reshape(-1, 4)
        assert len(own) == 3 * len(b.features) + 4 * sum(f.furniture is not None for f in b.features)
        pts = own.reshape(-1, 2)
        corners = wp[np.abs(_turns(wp)) > 1e-6]
        far = np.max(np.abs(pts[:, None, :] - corners[None, :, :]), axis=2)  # Chebyshev distance
        assert far.min(initial=np.inf) >= 1.5 * b.width + 1.0 - 1e-9, b.seed
        assert not crossing(b.world.segments), b.seed
    assert kinds == {"pillar", "notch", "room", "recess"}


def _on_a_wall(s: np.ndarray, walls: list[Wall]) -> bool:
    """Whether segment ``s`` lies on one of the plan's walls (an outer wall or a block's face)."""
    for w in walls:
        along, across = (s[[0, 2]], s[[1, 3]]) if w.horizontal else (s[[1, 3]], s[[0, 2]])
        if np.all(across == w.at) and w.a - EPS <= along.min() and along.max() <= w.b + EPS:
            return True
    return False


def test_crossing_check_sees_acrossing() -> None:
    assert crossing(np.array([[0.0, 0.0, 2.0, 0.0], [1.0, -1.0, 1.0, 1.0]]))
    assert not crossing(np.array([[0.0, 0.0, 2.0, 0.0], [1.0, 0.0, 1.0, 1.0]]))  # a T: touching


def test_long_bare_stretches_on_most_buildings(buildings: list[Building]) -> None:
    assert sum(b.bare() >= 8.0 for b in buildings) >= 60
    assert np.mean([len(b.features) for b in buildings]) >= 6.0


def test_one_building_per_seed(buildings: list[Building]) -> None:
    np.testing.assert_array_equal(random_building(17).segments, buildings[17].world.segments)
    np.testing.assert_array_equal(random_building(17).waypoints, buildings[17].world.waypoints)
    assert len({b.world.segments.tobytes() for b in buildings}) == len(buildings)
    assert len({b.world.waypoints.tobytes() for b in buildings}) == len(buildings)


def test_world_named_random() -> None:
    a, b = world_named("random", 5), random_building(5)
    assert a.name == b.name == "random-5" and a.wall_height == b.wall_height
    for field in ("segments", "start", "waypoints"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    np.testing.assert_array_equal(world_named("random").segments, random_building(0).segments)
    assert world_named("block") is WORLDS["block"]
    with pytest.raises(ConfigError, match="known worlds: .*block.* and random"):
        world_named("mars")
    with pytest.raises(ConfigError, match="seed"):
        world_named("random", -1)


# --- the walk: a standing start of any length; the wheeled robot's laser mount ----------------


def test_standing_start() -> None:
    w = WORLDS["office"]
    default = build_path(w, 300.0, np.random.default_rng(3))
    same = build_path(w, 300.0, np.random.default_rng(3), stand_s=None)
    assert len(default) == len(same) > 20
    for p, q in zip(default, same):
        for f in fields(Prim):
            a, b = getattr(p, f.name), getattr(q, f.name)
            assert (a is None and b is None) or np.array_equal(a, b), f.name  # bit for bit
    # today's walk: standing first for a draw of 4.5-5.5 s, then walking off
    first = float(np.random.default_rng(3).uniform(4.5, 5.5))
    assert default[0].kind == "pause" and default[0].t0 == 0.0 and default[0].dur == first
    assert default[1].kind == "line" and default[1].t0 == first
    # another stand: the same walk after it, sooner or later
    for stand in (0.0, 9.0):
        other = build_path(w, 300.0, np.random.default_rng(3), stand_s=stand)
        if stand == 0.0:
            assert other[0].kind == "line" and other[0].t0 == 0.0
        else:
            assert other[0].kind == "pause" and other[0].dur == stand
        rest = other[1:] if stand > 0.0 else other
        n = min(len(rest), len(default) - 1) - 1
        assert n > 10
        for p, q in zip(default[1 : 1 + n], rest[:n]):
            assert p.kind == q.kind and p.dur == pytest.approx(q.dur)
            assert q.t0 == pytest.approx(p.t0 - first + stand)
            np.testing.assert_allclose(p.p0, q.p0)


def test_simulators_take_the_stand_and_the_random_world(tmp_path: Path) -> None:
    """The humanoid walks off at once with stand_s=0 (and stands ~5 s without), in the random
    building of its seed, clear of its walls; the wheeled robot's laser sits where laser_x says."""
    from pfslam.io.logs import load_log
    from pfslam.tools.simulate import simulate
    from pfslam.tools.wheeled import LASER_MOUNT, simulate_wheeled_bag

    moved = []
    for stand in (None, 0.0):
        r = simulate("random", 30.0, seed=4, out_dir=tmp_path / f"h{stand}", rate_hz=5.0, stand_s=stand)
        assert r.world.name == "random-4"
        np.testing.assert_array_equal(r.world.segments, random_building(4).segments)
        assert point_distances(r.truth_world[:, :2], r.world.segments).min() >= CLEARANCE
        moved.append(np.hypot(*(r.truth_world[10, :2] - r.truth_world[0, :2])))  # after 2 s
    assert moved[0] < 0.05 < 0.5 < moved[1]
    with pytest.raises(ConfigError, match="stand_s"):
        simulate("office", 5.0, out_dir=tmp_path / "x", stand_s=-1.0)
    for laser_x in (None, 0.0, 0.25):
        res = simulate_wheeled_bag(
            "random", 5.0, seed=3, out_dir=tmp_path / f"w{laser_x}", rate_hz=5.0, laser_x=laser_x, stand_s=1.0
        )
        mount = load_log(res.bag).frames[0].mount
        want = LASER_MOUNT[0] if laser_x is None else laser_x
        np.testing.assert_allclose(mount[:3, 3], [want, 0.0, LASER_MOUNT[2]])
    with pytest.raises(ConfigError, match="laser_x"):
        simulate_wheeled_bag("block", 5.0, out_dir=tmp_path / "y", laser_x=float("nan"))
