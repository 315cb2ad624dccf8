"""The global start by branch and bound (issue 46): the first scan matched over the whole map
puts the particles where the robot is; where two places look alike the filter keeps both and
says it is ambiguous; the uniform spread is still there."""

from __future__ import annotations

import numpy as np
from locworld import drive, frames_along, room, scan

from pfslam.config import LocalizerConfig
from pfslam.filters.globalstart import MODE_MIN
from pfslam.filters.localize import Localizer
from pfslam.geometry import wrap_angle
from pfslam.maps.grid import OccupancyGrid

TWIN_DX = 6.0  # m: the second room is the first moved this far along x


def _twin_rooms() -> OccupancyGrid:
    """Two closed rooms, 4 x 3 m, the second a copy of the first TWIN_DX m along x, each with
    an off-centre block (so a room maps onto itself by no turn or mirror)."""
    g = OccupancyGrid(resolution=0.05, origin=(-1.0, -1.0), shape=(100, 240))  # x -1..11, y -1..4
    g.logodds[:] = -10
    for dx in (0, int(TWIN_DX / 0.05)):
        c0 = 20 + dx
        g.logodds[20, c0 : c0 + 81] = g.logodds[80, c0 : c0 + 81] = 10  # walls y = 0 and y = 3
        g.logodds[20:81, c0] = g.logodds[20:81, c0 + 80] = 10  # walls x = 0 and x = 4 (+ dx)
        g.logodds[30:45, c0 + 55 : c0 + 70] = 10  # a block x 2.75..3.5, y 0.5..1.25
    return g


def _near(poses: np.ndarray, pose, r: float = 0.3) -> int:
    return int(np.sum(np.hypot(poses[:, 0] - pose[0], poses[:, 1] - pose[1]) <= r))


def test_one_scan_puts_the_start_where_the_robot_is():
    g = room()
    truth = drive([(7.0, 2.0), (8.0, 3.0), (8.0, 5.0)], step=0.1)
    frames = frames_along(g, truth)
    loc = Localizer(g, LocalizerConfig(seed=0))
    loc.initialize_global()
    e = loc.step(frames[0])
    assert e.updated
    assert np.hypot(*(e.pose[:2] - truth[0, :2])) <= 0.1
    assert abs(wrap_angle(e.pose[2] - truth[0, 2])) <= np.deg2rad(3.0)
    info = loc.diagnostics()["global_start"]
    assert info["mode"] == "bnb" and info["candidates"] >= 1 and info["best_score"] > 0.8
    # (the room turned half round fits nearly as well: a second candidate, soon given up)
    for f, x in zip(frames[1:], truth[1:], strict=True):
        e = loc.step(f)
        assert np.hypot(*(e.pose[:2] - x[:2])) <= 0.1
    assert not loc.ambiguous
    assert loc.diagnostics()["global_start"]["resolved_at_update"] < len(frames)
    # A known start is never ambiguous, and has no start to report.
    loc.initialize_around(truth[0], np.array([0.1, 0.1, 0.05]))
    assert not loc.ambiguous and "global_start" not in loc.diagnostics()


def test_twin_rooms_keep_both_places_and_say_so():
    g = _twin_rooms()
    truth = drive([(1.0, 1.0), (2.0, 2.2), (1.2, 2.0)], step=0.1)
    frames = frames_along(g, truth)
    cfg = LocalizerConfig(seed=2)
    loc = Localizer(g, cfg)
    loc.initialize_global()
    for f, x in zip(frames, truth, strict=True):
        loc.step(f)
        assert loc.ambiguous  # it sees only what both rooms show alike
        poses = loc.particles.poses
        # particles at both places, enough of each to follow it (not drifted away to one)
        assert _near(poses, x) >= MODE_MIN // 2 and _near(poses, x + [TWIN_DX, 0, 0]) >= MODE_MIN // 2
    info = loc.diagnostics()["global_start"]
    assert info["ambiguous"] and info["candidates"] >= 2
    assert info["next_score"] >= 0.95 * info["best_score"]
    # One room holding 99 % of the weight: the other still keeps its particles (KLD-sampling
    # or plain resampling would leave it a handful), and the start stays ambiguous.
    twin = loc.particles.poses[:, 0] > TWIN_DX - 1.0
    loc.particles.log_weights = np.where(twin, np.log(0.01 / twin.sum()), np.log(0.99 / (~twin).sum()))
    assert loc.resample() and loc.ambiguous
    assert _near(loc.particles.poses, truth[-1] + [TWIN_DX, 0, 0]) >= MODE_MIN * 0.9


def test_the_uniform_spread_and_the_fallback():
    g = room()
    loc = Localizer(g, LocalizerConfig(seed=0, global_start="uniform", global_density=0.0, global_particles=5000))
    loc.initialize_global()
    assert loc.n == loc.global_count == 5000 and loc.ambiguous
    assert loc.diagnostics()["global_start"]["mode"] == "uniform"
    # A first scan with too few points to match: the particles are spread uniformly instead.
    loc = Localizer(g, LocalizerConfig(seed=0, global_density=0.0, global_particles=5000))
    loc.initialize_global()
    f = scan(g, np.array([7.0, 2.0, 0.8]), 0.0, np.zeros(3))
    f.ranges[5:] = np.inf
    loc.step(f)
    info = loc.diagnostics()["global_start"]
    assert "fallback" in info and info["candidates"] == 0 and loc.ambiguous
    assert loc.n >= loc.config.min_particles
