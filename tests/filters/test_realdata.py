"""The filters on real scans: Freiburg 079 and Intel with synthetic drifting odometry, scored
against the reference poses."""

import numpy as np
import pytest
from datafiles import need

from pfslam.config import SlamConfig
from pfslam.eval.metrics import trajectory_errors
from pfslam.io.logs import load_log
from pfslam.pipeline import close_loops, run_slam

pytestmark = [pytest.mark.realdata, pytest.mark.slow]


def test_fr079_slam_with_synthetic_odometry():
    log = load_log(need("carmen/fr079.gfs.log.gz"), odometry="synthetic")
    t = np.array([f.t for f in log.frames])
    run = close_loops(run_slam(log.frames, SlamConfig(filter="single")))
    slam = trajectory_errors(run.t, run.poses, t, log.reference)
    odom = trajectory_errors(run.t, run.odometry, t, log.reference)
    assert odom.ate_rmse >= 1.0, odom
    assert slam.ate_rmse_aligned <= 0.20, slam
    assert slam.ate_rmse <= 0.20, slam  # the map frame starts at the first odometry pose


def test_intel_localization_on_a_map_from_the_reference():
    from pfslam.config import LocalizerConfig
    from pfslam.pipeline import build_map, run_localization

    log = load_log(need("carmen/intel.gfs.log.gz"), odometry="synthetic")
    ref = log.reference
    grid = build_map(log.frames, ref)  # the map from the reference poses; the filter sees only odometry
    run = run_localization(log.frames, grid, LocalizerConfig(), (ref[0], np.array([0.1, 0.1, 0.05])))
    err = np.hypot(*(run.poses[:, :2] - ref[:, :2]).T)
    assert np.sqrt(np.mean(err**2)) <= 0.15
    odo = np.hypot(*(run.odometry[:, :2] - ref[:, :2]).T)
    assert np.sqrt(np.mean(odo**2)) >= 1.0


def test_intel_slam_with_synthetic_odometry(intel_single_map):
    from pfslam.eval.metrics import read_relations, relation_errors
    from pfslam.io.trajectory import read_tum

    log = load_log(need("carmen/intel.gfs.log.gz"), odometry="synthetic")
    t = np.array([f.t for f in log.frames])
    # run_slam(log.frames, SlamConfig(filter="single")), as pfslam.slam runs it and writes its
    # poses (one run for this test and test_intel_map_then_localize[single]: see conftest.py)
    t_run, poses = read_tum(intel_single_map / "trajectory.tum")
    _, odometry = read_tum(intel_single_map / "odometry.tum")
    slam = trajectory_errors(t_run, poses, t, log.reference)
    odom = trajectory_errors(t_run, odometry, t, log.reference)
    assert odom.ate_rmse >= 1.0, odom
    assert slam.ate_rmse_aligned <= 0.20, slam
    rel = relation_errors(t_run, poses, read_relations(need("carmen/intel.relations")), 976052857.338, 0.02)
    ref = relation_errors(t, log.reference, read_relations(need("carmen/intel.relations")), 976052857.338, 0.02)
    assert rel.matched == ref.matched == 120  # on two different scans (see tests/test_evaluate.py)
    print(
        f"Intel relations: SLAM {rel.trans_mean:.4f} m / {rel.rot_mean_deg:.2f} deg, "
        f"reference {ref.trans_mean:.4f} m / {ref.rot_mean_deg:.2f} deg"
    )
    assert rel.trans_mean <= 1.5 * ref.trans_mean
