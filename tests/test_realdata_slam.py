"""SLAM on real scans: Freiburg 079 with synthetic drifting odometry, scored against the reference."""

import numpy as np

from pfslam.config import SlamConfig
from pfslam.evaluate import trajectory_errors
from pfslam.io.logs import load_log
from pfslam.pipeline import run_slam

from test_realdata_loaders import need


def test_fr079_slam_with_synthetic_odometry():
    log = load_log(need("carmen/fr079.gfs.log.gz"), odometry="synthetic")
    t = np.array([f.t for f in log.frames])
    run = run_slam(log.frames, SlamConfig())
    slam = trajectory_errors(run.t, run.poses, t, log.reference)
    odom = trajectory_errors(run.t, run.odometry, t, log.reference)
    assert odom.ate_rmse >= 1.0, odom
    assert slam.ate_rmse_aligned <= 0.20, slam
    assert slam.ate_rmse <= 0.20, slam  # the map frame starts at the first odometry pose
