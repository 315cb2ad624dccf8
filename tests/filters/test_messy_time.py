"""A log whose time stamps carry no timing must not freeze the filter on the odometry: the
motion noise has a floor in proportion to the motion, and the loaders give strictly
increasing times."""

import numpy as np
import pytest
from carmen_sim import write_corrected_log

from pfslam.config import SlamConfig, with_values
from pfslam.eval.metrics import map_agreement
from pfslam.filters.predict import Prediction
from pfslam.filters.predict import slam_prediction as odometry_prediction
from pfslam.frames import Frame
from pfslam.io.logs import load_log
from pfslam.pipeline import close_loops, run_slam


@pytest.mark.parametrize(
    "name, stamp",
    [
        ("zero", lambda i: 0.0),  # orebro
        ("constant", lambda i: 1018930000.0),  # belgioioso
        ("coarse", lambda i: f"{1134860000 + 150 * i:.6g}"),  # csail
    ],
)
def test_the_filter_spreads_and_beats_the_odometry_without_timing(tmp_path, name, stamp):
    p = tmp_path / f"{name}.log"
    write_corrected_log(p, stamp, n=80)
    log = load_log(p, odometry="synthetic")
    run = close_loops(run_slam(log.frames, with_values(SlamConfig(), {"filter": "single", "particles": 30})))
    assert np.all(np.diff(run.t) > 0)
    # It used to return the odometry to the last bit (no noise at dt = 0: every particle alike).
    assert np.abs(run.poses[:, :2] - run.odometry[:, :2]).max() > 0.3
    slam, odom = map_agreement(log.frames, run.poses), map_agreement(log.frames, run.odometry)
    assert slam > odom + 0.2, (slam, odom)
    ref_err = np.hypot(*(run.poses[:, :2] - log.reference[:, :2]).T).max()
    odo_err = np.hypot(*(run.odometry[:, :2] - log.reference[:, :2]).T).max()
    assert ref_err < 0.5 * odo_err, (ref_err, odo_err)


def test_the_prediction_spreads_particles_at_zero_dt():
    pred: Prediction = odometry_prediction(SlamConfig())
    a = Frame(t=5.0, ranges=np.ones(1), angles=np.zeros(1), odom=np.zeros(3))
    b = Frame(t=5.0, ranges=np.ones(1), angles=np.zeros(1), odom=np.array([0.5, 0.0, 0.2]))
    poses, _, moved = pred(np.zeros((500, 3)), a, b, np.random.default_rng(0))
    assert moved and poses[:, 0].std() > 0.005 and poses[:, 2].std() > 0.005
