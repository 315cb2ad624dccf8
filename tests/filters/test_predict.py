"""The prediction step both filters share: wheel travel first, else the odometry increment,
else nothing."""

import numpy as np

from pfslam.config import SlamConfig
from pfslam.filters.predict import Prediction
from pfslam.filters.predict import slam_prediction as odometry_prediction
from pfslam.filters.single import zero_first_offsets
from pfslam.frames import Frame
from pfslam.geometry import compose, relative
from pfslam.motion import DiffDriveMotion, OdometryMotion

EMPTY = dict(ranges=np.array([]), angles=np.array([]))


def _noise_free():
    return Prediction(OdometryMotion.noise_free(), DiffDriveMotion(axle=0.5, k_left=0.0, k_right=0.0))


def test_the_odometry_increment_moves_the_particles():
    poses = np.array([[1.0, 2.0, 0.3], [0.0, 0.0, -1.0]])
    a = Frame(t=0.0, odom=np.array([5.0, 1.0, 0.2]), **EMPTY)
    b = Frame(t=0.1, odom=np.array([5.3, 1.1, 0.25]), **EMPTY)
    moved, u, went = _noise_free()(poses, a, b, np.random.default_rng(0))
    np.testing.assert_allclose(u, relative(a.odom, b.odom))
    np.testing.assert_allclose(moved, compose(poses, u), atol=1e-12)
    assert went
    still, u0, went = _noise_free()(poses, a, a, np.random.default_rng(0))
    np.testing.assert_allclose(u0, np.zeros(3), atol=1e-15)
    assert not went and np.allclose(still, poses)


def test_wheel_travel_wins_over_odometry_and_standing_wheels_do_nothing():
    poses = np.array([[2.0, 2.0, 0.0]])
    a = Frame(t=0.0, wheels=np.array([0.0, 0.0]), odom=np.zeros(3), **EMPTY)
    b = Frame(t=0.1, wheels=np.array([0.4, 0.6]), odom=np.array([9.0, 9.0, 0.0]), **EMPTY)
    moved, u, went = _noise_free()(poses, a, b, np.random.default_rng(0))
    want = DiffDriveMotion.arc(poses, np.array(0.4), np.array(0.6), 0.5)
    np.testing.assert_allclose(moved, want, atol=1e-12)
    np.testing.assert_allclose(compose(poses[0], u), want[0], atol=1e-12)
    assert went
    same, _, went = _noise_free()(poses, b, b, np.random.default_rng(0))
    assert not went and same is poses


def test_without_odometry_nothing_moves():
    poses = np.array([[2.0, 2.0, 0.0]])
    a = Frame(t=0.0, **EMPTY)
    b = Frame(t=0.1, odom=np.array([1.0, 0.0, 0.0]), **EMPTY)
    out, u, went = _noise_free()(poses, a, b, np.random.default_rng(0))
    assert u is None and not went and out is poses


def test_slam_prediction_takes_the_motion_config():
    c = SlamConfig()
    p = odometry_prediction(c)
    assert p.wheels.axle == c.motion.axle and p.wheels.k_left == c.motion.k_left
    assert p.odometry.ref_interval == c.motion.ref_interval
    np.testing.assert_allclose(
        p.odometry.sigma, (c.motion.sigma_x, c.motion.sigma_y, np.deg2rad(c.motion.sigma_theta_deg))
    )


def test_zero_first_offsets():
    np.testing.assert_array_equal(zero_first_offsets(0), [0])
    np.testing.assert_array_equal(zero_first_offsets(2), [0, -1, 1, -2, 2])
