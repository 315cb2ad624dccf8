"""The outdoor campus (pfslam.tools.campus): its route's length, loops and clearance, the open
lawn where the laser sees little, what stands on it, one campus per seed; the world ``campus``
of the simulators and of ``pfslam simulate``, whose wheeled robot drives it once round with a
SICK laser; the wheeled robot's --beams, --fov and --speed, and its one-lap duration."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from wallpoints import crossing, point_distances

from pfslam.errors import ConfigError
from pfslam.tools.buildings import lap_length, route_clearance
from pfslam.tools.campus import (
    CLEARANCE,
    ROUTE,
    SICK_BEAMS,
    SICK_FOV_DEG,
    SICK_RANGE,
    Campus,
    campus,
    campus_world,
    open_share,
    returns,
    route_points,
    segments_within,
)
from pfslam.tools.places import world_named
from pfslam.tools.raycast import raycast
from pfslam.tools.walk import build_path, eval_path
from pfslam.tools.wheeled import WHEELED, Drive, drive

SEEDS = range(8)


@pytest.fixture(scope="module")
def campuses() -> list[Campus]:
    return [campus(seed) for seed in SEEDS]


# --- the helpers that measure a route -----------------------------------------------------------


def test_returns_finds_each_lap_of_a_figure_of_eight() -> None:
    """Two 60 m squares through the origin, one after the other: the route comes back to the
    origin after each 240 m lap (twice), and a 100 m square once round (400 m) once; a square
    too small (a 20 m lap) never."""
    eight = np.array([[0.0, 0.0], [60, 0], [60, 60], [0, 60], [0, 0], [-60, 0], [-60, -60], [0, -60]])
    back = returns(eight)
    assert len(back) == 2
    assert all(abs(after - before - 240.0) <= 4.0 for before, after in back), back
    square = np.array([[0.0, 0.0], [100, 0], [100, 100], [0, 100]])
    assert len(returns(square)) == 1
    assert returns(square / 20.0) == []  # back after 20 m: shorter than 100
    pts, along = route_points(square, 2.0)
    assert len(pts) == 200 and along[-1] == 398.0
    np.testing.assert_allclose(pts[50], [100.0, 0.0])


def test_segments_within_counts_what_comes_within_reach() -> None:
    segs = np.array([[10.0, -1.0, 10.0, 1.0], [90.0, 0.0, 95.0, 0.0], [-50.0, 79.0, 50.0, 79.0]])
    np.testing.assert_array_equal(segments_within(np.array([[0.0, 0.0], [200.0, 0.0]]), segs, 80.0), [2, 0])


# --- the campus ---------------------------------------------------------------------------------


def test_route_length_loops_and_start(campuses: list[Campus]) -> None:
    """A lap of 1.2-1.95 km that comes back to a place it passed 100-400 m before three times
    or more; the start on the first leg, facing along it; every leg long enough to drive."""
    for c in campuses:
        w = c.world
        assert ROUTE[0] <= lap_length(w) <= ROUTE[1] and 1000.0 <= lap_length(w) <= 2000.0, c.seed
        back = returns(w.waypoints)
        assert len(back) >= 3, (c.seed, back)
        assert all(100.0 <= after - before <= 400.0 for before, after in back)
        wp = w.waypoints
        d = wp[1] - wp[0]
        np.testing.assert_allclose(w.start, [*wp[0], np.arctan2(d[1], d[0])])
        legs = np.hypot(*(np.roll(wp, -1, axis=0) - wp).T)
        assert legs.min() > 5.0, c.seed
        assert 3 <= len(c.laps) <= 5 and len(set(c.laps)) == len(c.laps)
        assert w.name == f"campus-{c.seed}" and w.wall_height == 3.0


def test_route_clears_every_segment(campuses: list[Campus]) -> None:
    """The route keeps 1.5 m from every segment, and the wheeled robot's drive along it (corners
    as 0.6 m arcs) 1.2 m."""
    for c in campuses:
        assert route_clearance(c.world) >= CLEARANCE == 1.5, c.seed
    for c in campuses[:2]:
        duration = lap_length(c.world) / 1.0 + 60.0
        prims = build_path(c.world, duration, np.random.default_rng(c.seed), WHEELED, 1.0)
        xy, _ = eval_path(prims, np.arange(0.0, duration, 1.0))
        assert point_distances(xy[:, :2], c.world.segments).min() >= 1.2, c.seed


def test_open_ground_where_the_laser_sees_little(campuses: list[Campus]) -> None:
    """On 5 % of the route or more fewer than 80 segments (a dozen trees and poles) lie within
    the laser's 80 m; from there, a SICK scan returns on few of its beams."""
    for c in campuses:
        assert open_share(c.world) >= 0.05, c.seed
    w = campuses[0].world
    pts, _ = route_points(w.waypoints, 2.0)
    k = int(np.argmin(segments_within(pts, w.segments, SICK_RANGE)))
    a = np.deg2rad(np.linspace(-SICK_FOV_DEG / 2, SICK_FOV_DEG / 2, SICK_BEAMS))
    for heading in (0.0, np.pi / 2, np.pi, -np.pi / 2):
        dirs = np.column_stack([np.cos(a + heading), np.sin(a + heading), np.zeros_like(a)])
        r = raycast(np.array([*pts[k], 0.3]), dirs, w.segments, w.wall_height, SICK_RANGE)
        assert np.mean(r < SICK_RANGE) < 0.1, heading


def test_what_stands_on_the_campus(campuses: list[Campus]) -> None:
    """Buildings (some turned, some L-shaped), trees of 6-8 sides, hexagonal lamp poles, cars
    of 4; a few thousand segments at most, none crossing another; an open lawn 100 m and more
    across; about 250 x 250 m of streets."""
    for c in campuses:
        n = c.counts
        assert n["buildings"] >= 7 and n["trees"] >= 20 and n["poles"] >= 5 and n["cars"] >= 10, c.seed
        assert 6 * n["trees"] <= n["tree_segments"] <= 8 * n["trees"]
        assert n["pole_segments"] == 6 * n["poles"] and n["car_segments"] == 4 * n["cars"]
        walls = len(c.world.segments)  # every wall piece is a building's, a tree's, a pole's or a car's
        assert sum(n[f"{k}_segments"] for k in ("wall", "tree", "pole", "car")) == walls
        assert walls <= 3000  # a few thousand wall pieces at most
        assert c.lawn[2] - c.lawn[0] >= 100.0 and c.lawn[3] - c.lawn[1] >= 100.0
        assert 200.0 <= c.xs[-1] <= 300.0 and 200.0 <= c.ys[-1] <= 300.0
        assert set(c.cells.values()) <= {"building", "lawn", "pair", "parking"}
    assert sum(c.counts["turned"] for c in campuses) >= 8
    assert sum(c.counts["l_shaped"] for c in campuses) >= 8
    for c in campuses[:2]:
        assert not crossing(c.world.segments), c.seed
    # trunks 0.2-0.6 m across, poles 0.1-0.2 m: the sides of a regular polygon that wide
    sides = np.hypot(*(c.world.segments[:, 2:] - c.world.segments[:, :2]).T)
    assert sides.min() >= 0.1 * np.sin(np.pi / 6) - 1e-3


def test_one_campus_per_seed(campuses: list[Campus]) -> None:
    a = campus_world(3)
    np.testing.assert_array_equal(a.segments, campuses[3].world.segments)
    np.testing.assert_array_equal(a.waypoints, campuses[3].world.waypoints)
    assert len({c.world.segments.tobytes() for c in campuses}) == len(campuses)
    assert len({c.world.waypoints.tobytes() for c in campuses}) == len(campuses)


def test_world_named_campus() -> None:
    a, b = world_named("campus", 5), campus_world(5)
    assert a.name == b.name == "campus-5"
    for field in ("segments", "start", "waypoints"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    with pytest.raises(ConfigError, match="known worlds: .*campus .*random"):
        world_named("mars")
    with pytest.raises(ConfigError, match="seed"):
        world_named("campus", -1)


# --- the wheeled robot: one lap; pfslam simulate's campus, --beams, --fov, --speed -----------------


def test_one_lap_ends_back_at_the_start(tmp_path: Path) -> None:
    """duration None: the log ends as the robot gets back to where it set off (the block
    building's 96 m lap at 2 m/s, its pauses and corners on the way); a lap longer than an
    hour is a ConfigError."""
    from pfslam.geometry import compose
    from pfslam.tools.wheeled import simulate_wheeled_bag
    from pfslam.tools.worlds import WORLDS

    res = simulate_wheeled_bag("block", None, seed=1, out_dir=tmp_path / "a", speed=2.0, rate_hz=5.0)
    w = WORLDS["block"]
    xy = compose(w.start, res.truth)[:, :2]
    travel = float(np.hypot(*np.diff(xy, axis=0).T).sum())
    assert lap_length(w) - 2.0 < travel < lap_length(w)  # (the corners' arcs cut them short)
    assert np.hypot(*(xy[-1] - xy[0])) < 0.45  # back, within the last scan's step
    assert np.hypot(*(xy[len(xy) // 2] - xy[0])) > 10.0
    with pytest.raises(ConfigError, match="one lap of the campus-0 route .* more than 3600 s"):
        simulate_wheeled_bag("campus", None, seed=0, out_dir=tmp_path / "b", speed=0.3)


def _captured(monkeypatch: pytest.MonkeyPatch) -> dict:
    """What `pfslam simulate --robot wheeled` passes the simulator (run: nothing)."""
    import pfslam.tools.wheeled as wheeled

    got: dict = {}

    def fake(world, duration_s, seed, out_dir, **kw):
        got.update(world=world, duration_s=duration_s, seed=seed, **kw)
        return wheeled.WheeledBag(Path(out_dir) / "log.bag", Path(out_dir) / "groundtruth.tum", *[np.zeros(1)] * 3)

    monkeypatch.setattr(wheeled, "simulate_wheeled_bag", fake)
    return got


def test_simulate_command_drives_the_campus_once_round_with_a_sick_laser(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The campus: once round at 1 m/s, 361 beams over 180 deg reaching 80 m, unless told;
    another world as before (720 beams over 270 deg, 20 m, 0.6 m/s, 180 s)."""
    from clirun import invoke

    got = _captured(monkeypatch)
    res, err = invoke("simulate", "--world", "campus", "--robot", "wheeled", "--seed", 4, "-o", tmp_path / "a")
    assert res.exit_code == 0, (res.output, err)
    assert got["world"] == "campus" and got["seed"] == 4 and got["duration_s"] is None
    assert (got["max_range"], got["beams"], got["fov_deg"], got["speed"]) == (80.0, 361, 180.0, 1.0)
    assert drive("campus").heading_bias_deg_per_m == got["heading_bias_deg_per_m"] < 0.3
    args = ("--duration", 50, "--beams", 181, "--fov", 90, "--speed", 2, "--max-range", 30)
    res, err = invoke("simulate", "--world", "campus", "--robot", "wheeled", "-o", tmp_path / "b", *args)
    assert res.exit_code == 0, (res.output, err)
    assert (got["duration_s"], got["max_range"], got["beams"], got["fov_deg"], got["speed"]) == (50, 30, 181, 90, 2)
    res, err = invoke("simulate", "--world", "block", "--robot", "wheeled", "-o", tmp_path / "c")
    assert res.exit_code == 0, (res.output, err)
    assert drive("block") == Drive() and got["duration_s"] == 180.0 and got["heading_bias_deg_per_m"] == 0.3
    assert (got["max_range"], got["beams"], got["fov_deg"], got["speed"]) == (20.0, 720, 270.0, 0.6)
    res, err = invoke("simulate", "--robot", "wheeled", "-o", tmp_path / "d", "--fov", 360, "--beams", 8)
    assert res.exit_code == 0, (res.output, err)
    assert got["fov_deg"] == 315.0  # all round: the last beam one step short of the first


def test_simulate_command_laser_and_speed_options(tmp_path: Path) -> None:
    """--beams, --fov and --speed make the bag's scans and drive (the hall, 10 s); the campus
    is in the help; a bad value, or one given the humanoid, is a one-line error."""
    from clirun import invoke, one_line_error

    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import read_tum

    res, _ = invoke("simulate", "--help")
    assert res.exit_code == 0 and "campus" in res.output and "--beams" in res.output
    out = tmp_path / "hall"
    args = ("--world", "hall", "--duration", 10, "--beams", 181, "--fov", 90, "--speed", 2.0)
    res, err = invoke("simulate", "--robot", "wheeled", "-o", out, *args)
    assert res.exit_code == 0, (res.output, err)
    f = load_log(out / "log.bag").frames[0]
    assert len(f.ranges) == 181 and np.rad2deg(f.angles[-1] - f.angles[0]) == pytest.approx(90.0)
    t, truth = read_tum(out / "groundtruth.tum")
    assert np.hypot(*np.diff(truth[:, :2], axis=0).T).max() / np.diff(t).max() == pytest.approx(2.0, abs=0.1)
    for bad, word in (
        (("--beams", 1), "--beams"),
        (("--fov", 400), "--fov"),
        (("--speed", 0), "--speed"),
        (("--speed", "nan"), "--speed"),
        (("--max-range", 500), "--max-range"),
    ):
        one_line_error(*invoke("simulate", "--robot", "wheeled", "-o", tmp_path / "x", *bad), word)
    for opt in ("--beams", "--fov", "--speed"):
        one_line_error(*invoke("simulate", "-o", tmp_path / "y", opt, 100), opt, "wheeled")
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()
