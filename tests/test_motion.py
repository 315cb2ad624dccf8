import numpy as np
import pytest

from pfslam.geometry import compose
from pfslam.motion import DiffDriveMotion, OdometryMotion


def test_odometry_no_noise_when_still():
    m = OdometryMotion()
    p = np.random.default_rng(0).normal(size=(50, 3))
    out = m.apply(p, np.zeros(3), 0.025, np.random.default_rng(1))
    assert np.allclose(out[:, :2], p[:, :2])


def test_odometry_noise_scales_with_interval():
    m = OdometryMotion()
    p = np.zeros((20000, 3))
    u = np.array([0.05, 0, 0])
    a = m.apply(p, u, 0.25, np.random.default_rng(1))
    b = m.apply(p, u, 0.025, np.random.default_rng(1))
    assert np.std(a[:, 1]) == pytest.approx(0.01, rel=0.05)
    assert np.std(b[:, 1]) == pytest.approx(0.01 * np.sqrt(0.1), rel=0.05)
    assert np.mean(a[:, 0]) == pytest.approx(0.05, abs=1e-3)


def test_odometry_applies_in_local_frame():
    m = OdometryMotion(sigma=(0, 0, 0))
    p = np.array([[1.0, 1.0, np.pi / 2]])
    out = m.apply(p, np.array([1.0, 0, 0]), 0.1, np.random.default_rng(0))
    assert np.allclose(out, compose(p, [1, 0, 0]))
    assert np.allclose(out[0, :2], [1, 2])


def test_diffdrive_straight_and_turn():
    p = np.zeros((1, 3))
    assert np.allclose(DiffDriveMotion.arc(p, np.array(1.0), np.array(1.0), 0.33), [[1, 0, 0]])
    # Turn in place: wheels opposite.
    q = DiffDriveMotion.arc(p, np.array(-0.165 * np.pi / 2), np.array(0.165 * np.pi / 2), 0.33)
    assert np.allclose(q, [[0, 0, np.pi / 2]], atol=1e-12)
    # Quarter circle of radius 1 (left wheel on r=1-0.165, right on r=1+0.165).
    r = DiffDriveMotion.arc(p, np.array((1 - 0.165) * np.pi / 2), np.array((1 + 0.165) * np.pi / 2), 0.33)
    assert np.allclose(r, [[1, 1, np.pi / 2]], atol=1e-12)


def test_diffdrive_noise_proportional_to_travel():
    m = DiffDriveMotion(axle=0.33, k_left=0.01, k_right=0.01)
    p = np.zeros((20000, 3))
    a = m.apply(p, 1.0, 1.0, np.random.default_rng(0))
    b = m.apply(p, 0.0, 0.0, np.random.default_rng(0))
    c = m.apply(p, 2.0, 2.0, np.random.default_rng(0))
    assert np.std(a[:, 0]) == pytest.approx(0.01 / np.sqrt(2), rel=0.05)
    assert np.std(a[:, 2]) == pytest.approx(0.01 * np.sqrt(2) / 0.33, rel=0.05)
    assert np.std(c[:, 2]) == pytest.approx(2 * np.std(a[:, 2]), rel=0.05)
    assert np.all(b == 0)
