"""End-to-end SLAM on simulated THOR logs: accuracy, floor handling, map files."""

import numpy as np
import pytest

from pfslam.config import SlamConfig
from pfslam.evaluate import trajectory_errors
from pfslam.geometry import compose, wrap_angle
from pfslam.grid import OccupancyGrid
from pfslam.io.logs import load_log
from pfslam.pipeline import build_map, run_slam, write_slam_outputs
from pfslam.sensor import scan_to_points
from pfslam.simulate import simulate


@pytest.fixture(scope="module")
def office(tmp_path_factory):
    res = simulate("office", 180.0, seed=0, out_dir=tmp_path_factory.mktemp("office"))
    return res, load_log(res.lidar_path, res.joint_path)


def test_office_loop_slam_beats_odometry(office, tmp_path):
    res, log = office
    assert log.frames[-1].t - log.frames[0].t >= 179.0 and len(log.frames) >= 40 * 179
    odom_heading_drift = np.rad2deg(abs(wrap_angle(res.odom[-1, 2] - res.truth[-1, 2])))
    assert odom_heading_drift >= 10.0
    # Three filter seeds: on this log 3 of 20 (seeds 0, 12, 17; seeds 4-19 did the same
    # before the float32 kernels, 2 of 16) let the heading drift 1 deg in the first minute
    # and keep a 0.19 m offset after the loop closes; the others end within 0.03 m.
    runs = [run_slam(log.frames, SlamConfig(seed=seed)) for seed in range(3)]
    errs = [trajectory_errors(r.t, r.poses, res.t, res.truth) for r in runs]
    mid = int(np.argsort([e.ate_rmse for e in errs])[1])  # outputs and map of the median run
    run, slam = runs[mid], errs[mid]
    odom = trajectory_errors(run.t, run.odometry, res.t, res.truth)
    assert slam.matched == len(log.frames)
    # Raw ATE (both start at the origin) and the SE(2)-aligned ATE.
    assert np.median([e.ate_rmse for e in errs]) <= 0.05, errs
    assert np.median([e.ate_rmse_aligned for e in errs]) <= 0.05, errs
    for e in errs:
        assert e.ate_rmse <= 0.3 and e.ate_rmse_aligned <= 0.15, e
        assert odom.ate_rmse >= 5 * e.ate_rmse and odom.ate_rmse_aligned >= 5 * e.ate_rmse_aligned, (odom, e)
    # The outputs are complete and the map reloads.
    out = write_slam_outputs(run, tmp_path / "out", {"log": str(res.lidar_path)}, (res.t, res.truth))
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
    cfg.sensor.ground_z = -1.0
    bad = build_map(log.frames, res.truth, cfg)
    occ = np.argwhere(bad.thresholded() == 100)
    xy = bad.cell_to_world(occ[:, 0], occ[:, 1])
    world_xy = compose(res.truth_world[0], np.column_stack([xy, np.zeros(len(xy))]))[:, :2]
    assert np.sum(_distance_to_segments(world_xy, res.world.segments) >= 0.1) > 100


def test_same_seed_same_result(office):
    res, log = office
    frames = log.frames[200:800]
    a = run_slam(frames, SlamConfig(seed=5))
    b = run_slam(frames, SlamConfig(seed=5))
    np.testing.assert_array_equal(a.poses, b.poses)


def test_numpy_twins_give_the_same_trajectory(office):
    _, log = office
    frames = log.frames[180:330]
    a = run_slam(frames, SlamConfig(seed=2))
    from pfslam.slam import Slam

    s = Slam(SlamConfig(seed=2), backend="numpy")
    b = np.array([s.step(f).pose for f in frames])
    np.testing.assert_allclose(a.poses, b, atol=1e-9)
    np.testing.assert_allclose(a.grid.logodds, s.grid.logodds, atol=1e-5)


def test_interrupted_run_keeps_what_was_computed(office, tmp_path):
    import json

    _, log = office

    def stop(i, n):
        if i > 100:
            raise KeyboardInterrupt

    run = run_slam(log.frames[:400], SlamConfig(), stop)
    assert run.interrupted and 100 < run.scans < 400
    assert np.all(np.isfinite(run.poses)) and len(run.t) == run.scans
    out = write_slam_outputs(run, tmp_path / "o", {})
    info = json.loads((out / "run.json").read_text())
    assert info["interrupted"] and info["scans_processed"] == run.scans
    lines = (out / "trajectory.tum").read_text().splitlines()
    assert (out / "config.yaml").is_file() and len(lines) == run.scans + 1  # a header line
