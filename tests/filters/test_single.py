"""The single-map SLAM filter end to end on simulated THOR logs: accuracy, floor handling,
map files, determinism, the NumPy kernel twins."""

import numpy as np
import pytest

from pfslam.config import SlamConfig, with_values
from pfslam.eval.metrics import trajectory_errors
from pfslam.filters.single import SingleMapSlam
from pfslam.geometry import compose, wrap_angle
from pfslam.io.logs import load_log
from pfslam.kernels import NUMPY
from pfslam.maps.grid import OccupancyGrid
from pfslam.pipeline import build_map, close_loops, run_slam, write_outputs
from pfslam.sensor import scan_to_points
from pfslam.tools.simulate import simulate


@pytest.fixture(scope="module")
def office(office_sim, office_log):
    return office_sim, office_log


@pytest.mark.slow
def test_office_loop_slam_beats_odometry(office, tmp_path):
    res, log = office
    assert log.frames[-1].t - log.frames[0].t >= 179.0 and len(log.frames) >= 40 * 179
    odom_heading_drift = np.rad2deg(abs(wrap_angle(res.odom[-1, 2] - res.truth[-1, 2])))
    assert odom_heading_drift >= 10.0
    # Three filter seeds: on this log 3 of 20 (seeds 0, 12, 17; seeds 4-19 did the same
    # before the float32 kernels, 2 of 16) let the heading drift 1 deg in the first minute
    # and keep a 0.19 m offset after the loop closes; the others end within 0.03 m.
    runs = [close_loops(run_slam(log.frames, SlamConfig(filter="single", seed=seed))) for seed in range(3)]
    errs = [trajectory_errors(r.t, r.poses, res.t, res.truth) for r in runs]
    mid = int(np.argsort([e.ate_rmse for e in errs])[1])  # outputs and map of the median run
    run, slam = runs[mid], errs[mid]
    odom = trajectory_errors(run.t, run.odometry, res.t, res.truth)
    assert slam.matched == len(log.frames)
    # The loop-closing back end (the default) worked behind the single-map filter.
    assert all(r.closure is not None and r.closure.stats.loops_in_graph > 20 for r in runs)
    # Raw ATE (both start at the origin) and the SE(2)-aligned ATE.
    assert np.median([e.ate_rmse for e in errs]) <= 0.05, errs
    assert np.median([e.ate_rmse_aligned for e in errs]) <= 0.05, errs
    for e in errs:
        assert e.ate_rmse <= 0.3 and e.ate_rmse_aligned <= 0.15, e
        assert odom.ate_rmse >= 5 * e.ate_rmse and odom.ate_rmse_aligned >= 5 * e.ate_rmse_aligned, (odom, e)
    # The outputs are complete and the map reloads.
    out = write_outputs(run, tmp_path / "out", {"log": str(res.lidar_path)}, (res.t, res.truth))
    for name in ("map.pgm", "map.yaml", "map.png", "trajectory.tum", "odometry.tum", "run.json"):
        assert (out / name).is_file(), name
    g = OccupancyGrid.load_ros(out / "map.yaml")
    # Walls of the world land where they are: every occupied cell of the SLAM map lies near
    # a wall segment (in the start-relative map frame).
    occ = np.argwhere(g.thresholded() == 100)
    xy = g.cell_to_world(occ[:, 0], occ[:, 1])
    world_xy = compose(res.truth_world[0], np.column_stack([xy, np.zeros(len(xy))]))[:, :2]
    d = _distance_to_segments(world_xy, res.world.segments)
    assert np.quantile(d, 0.99) < 0.15 and len(occ) > 1000


def _distance_to_segments(p, seg):
    a, b = seg[:, :2], seg[:, 2:]
    ab = b - a
    t = np.clip(np.einsum("pkj,kj->pk", p[:, None, :] - a[None], ab) / np.maximum((ab**2).sum(1), 1e-12), 0, 1)
    q = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(p[:, None, :] - q, axis=2).min(axis=1)


def test_head_pitched_down_maps_no_floor_as_wall(tmp_path):
    # Head pitched 25 deg down: every beam meets the floor about 3 m away unless a wall is nearer.
    res = simulate("office", 30.0, seed=3, out_dir=tmp_path, head_pitch=np.deg2rad(25.0))
    log = load_log(res.lidar_path, res.joint_path)
    floor = sum(len(scan_to_points(f).floor) for f in log.frames[:50])
    cfg = SlamConfig()
    grid = build_map(log.frames, res.truth, cfg)
    occ = np.argwhere(grid.thresholded() == 100)
    xy = grid.cell_to_world(occ[:, 0], occ[:, 1])
    world_xy = compose(res.truth_world[0], np.column_stack([xy, np.zeros(len(xy))]))[:, :2]
    d = _distance_to_segments(world_xy, res.world.segments)
    assert floor > 50 * 100 and len(occ) > 0  # most beams meet the floor
    assert d.max() < 0.1, f"{np.sum(d >= 0.1)} occupied cells away from walls"
    # The floor around the robot is mapped free.
    r, c = grid.world_to_cell(res.truth[len(res.truth) // 2, None, :2] + [[1.5, 0.0]])
    assert grid.thresholded()[r[0], c[0]] == 0
    # Control: without ground removal the floor ring becomes "walls".
    bad = build_map(log.frames, res.truth, with_values(cfg, {"sensor.ground_z": -1.0}))
    occ = np.argwhere(bad.thresholded() == 100)
    xy = bad.cell_to_world(occ[:, 0], occ[:, 1])
    world_xy = compose(res.truth_world[0], np.column_stack([xy, np.zeros(len(xy))]))[:, :2]
    assert np.sum(_distance_to_segments(world_xy, res.world.segments) >= 0.1) > 100


def test_same_seed_same_result(office):
    res, log = office
    frames = log.frames[200:800]
    a = run_slam(frames, SlamConfig(filter="single", seed=5))
    b = run_slam(frames, SlamConfig(filter="single", seed=5))
    np.testing.assert_array_equal(a.poses, b.poses)


@pytest.mark.slow
def test_numpy_twins_give_the_same_trajectory(office):
    _, log = office
    frames = log.frames[180:330]
    a = run_slam(frames, SlamConfig(filter="single", seed=2))
    s = SingleMapSlam(SlamConfig(seed=2), kernels="numpy")
    assert s.kernels is NUMPY
    b = np.array([s.step(f).pose for f in frames])
    np.testing.assert_allclose(a.poses, b, atol=1e-9)
    np.testing.assert_allclose(a.grid.logodds, s.grid.logodds, atol=1e-5)
    # The filter's own record of its trajectory is what step() returned.
    t, poses = s.trajectory()
    np.testing.assert_array_equal(poses, b)
    np.testing.assert_array_equal(t, [f.t for f in frames])
    assert s.map is s.grid


def test_interrupted_run_keeps_what_was_computed(office, tmp_path):
    import json

    _, log = office

    def stop(i, n):
        if i > 100:
            raise KeyboardInterrupt

    run = close_loops(run_slam(log.frames[:400], SlamConfig(filter="single"), stop))
    assert run.interrupted and 100 < run.scans < 400
    assert np.all(np.isfinite(run.poses)) and len(run.t) == run.scans
    out = write_outputs(run, tmp_path / "o", {})
    info = json.loads((out / "run.json").read_text())
    assert info["interrupted"] and info["scans_processed"] == run.scans
    lines = (out / "trajectory.tum").read_text().splitlines()
    assert (out / "config.yaml").is_file() and len(lines) == run.scans + 1  # a header line


def _walled_grid():
    g = OccupancyGrid(origin=(-5.0, -5.0), shape=(200, 200))
    g.logodds[:, 140] = 10.0  # a wall at x = 2.00..2.05
    return g


def test_smoothed_wall_map_is_the_gaussian_of_the_wall_distance():
    from pfslam.config import SensorConfig
    from pfslam.filters.single import SmoothedWallMap

    g = _walled_grid()
    wm = SmoothedWallMap(SensorConfig(field_sigma=0.1))
    v = wm.get(g, np.zeros((1, 3)), np.array([[2.0, 0.0]]))
    assert v.shape == g.logodds.shape and v.dtype == np.float32
    r, c = g.world_to_cell(np.array([[2.025, 0.0], [1.925, 0.0], [1.825, 0.0]]))
    np.testing.assert_allclose(v[r, c], [1.0, np.exp(-0.5), np.exp(-2.0)], rtol=1e-6)  # 0, 0.1, 0.2 m off


def test_smoothed_wall_map_is_reused_until_enough_scans_or_motion():
    from pfslam.config import SensorConfig
    from pfslam.filters.single import SmoothedWallMap

    g = _walled_grid()
    wm = SmoothedWallMap(SensorConfig(field_refresh_scans=3, field_refresh_m=0.25, field_refresh_deg=5.0))
    poses, pts = np.zeros((1, 3)), np.array([[2.0, 0.0]])
    wm.get(g, poses, pts)
    g.logodds[:, 60] = 10.0  # a new wall at x = -2, inside the window
    r, c = g.world_to_cell(np.array([[-1.975, 0.0]]))
    for _ in range(2):  # two small steps: the last map is reused, the new wall not yet in it
        wm.since_build.add(np.array([0.05, 0.0, 0.0]))
        assert wm.get(g, poses, pts)[r[0], c[0]] < 1e-6
    wm.since_build.add(np.array([0.05, 0.0, 0.0]))  # the third scan: rebuilt
    assert wm.get(g, poses, pts)[r[0], c[0]] == pytest.approx(1.0)
    g.logodds[:, 60] = 0.0
    wm.since_build.add(np.array([0.0, 0.0, np.deg2rad(6.0)]))  # a turn past field_refresh_deg: rebuilt
    assert wm.get(g, poses, pts)[r[0], c[0]] < 1e-6
    g.logodds[:, 60] = 10.0
    wm.since_build.add(np.array([0.3, 0.0, 0.0]))  # a step past field_refresh_m: rebuilt
    assert wm.get(g, poses, pts)[r[0], c[0]] == pytest.approx(1.0)
