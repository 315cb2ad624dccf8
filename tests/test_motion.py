"""Motion models: Gaussian odometry increments, differential drive, AMCL's odometry model."""

import numpy as np
import pytest

from pfslam.geometry import compose, wrap_angle
from pfslam.motion import (
    FLOOR_ROT_K,
    FLOOR_ROT_PER_M,
    FLOOR_TRANS_K,
    AmclOdometryMotion,
    DiffDriveMotion,
    OdometryMotion,
)


def test_odometry_no_noise_when_still():
    m = OdometryMotion()
    p = np.random.default_rng(0).normal(size=(50, 3))
    out = m.apply(p, np.zeros(3), 0.025, np.random.default_rng(1))
    assert np.allclose(out[:, :2], p[:, :2])


def test_odometry_noise_scales_with_interval():
    m = OdometryMotion(floor_trans_k=0.0, floor_rot_k=0.0, floor_rot_per_m=0.0)  # the time term alone
    p = np.zeros((20000, 3))
    u = np.array([0.05, 0, 0])
    a = m.apply(p, u, 0.25, np.random.default_rng(1))
    b = m.apply(p, u, 0.025, np.random.default_rng(1))
    assert np.std(a[:, 1]) == pytest.approx(0.01, rel=0.05)
    assert np.std(b[:, 1]) == pytest.approx(0.01 * np.sqrt(0.1), rel=0.05)
    assert np.mean(a[:, 0]) == pytest.approx(0.05, abs=1e-3)


def test_odometry_noise_has_a_motion_floor_so_zero_dt_never_freezes():
    """A log whose time stamps do not advance gives dt = 0: the particles must still spread,
    in proportion to the motion. The floor bounds the noise from below; it adds nothing
    where the time term is larger (a 40 Hz log's small steps: unchanged runs)."""
    m = OdometryMotion()
    p = np.zeros((20000, 3))
    u = np.array([0.5, 0.0, 0.4])  # half a metre and 23 degrees, in no time at all
    a = m.apply(p, u, 0.0, np.random.default_rng(2))
    assert np.std(a[:, 1]) == pytest.approx(FLOOR_TRANS_K * 0.5, rel=0.05)
    turn = np.hypot(FLOOR_ROT_K * 0.4, FLOOR_ROT_PER_M * 0.5)
    assert np.std(wrap_angle(a[:, 2] - 0.4)) == pytest.approx(turn, rel=0.05)
    # Over a long interval the time term rules; the floor is a bound, not a sum.
    np.testing.assert_allclose(m.noise_sigma(u, 2.5), np.array(m.sigma) * np.sqrt(10.0))
    np.testing.assert_allclose(m.noise_sigma(u, 0.25), np.maximum(m.sigma, [0.01, 0.01, turn]))
    # A user's per-metre terms still add in quadrature to the time term; still is still.
    assert OdometryMotion(trans_k=0.1).noise_sigma(u, 0.0)[0] == pytest.approx(0.05)
    assert OdometryMotion(trans_k=0.1).noise_sigma(u, 0.25)[0] == pytest.approx(np.hypot(0.01, 0.05))
    assert not OdometryMotion().noise_sigma(np.zeros(3), 0.0).any()
    # A step at the demo's 40 Hz: the floor is below the time term, the noise is the time term.
    small = np.array([0.012, 0.001, 0.004])
    np.testing.assert_array_equal(m.noise_sigma(small, 0.025), np.array(m.sigma) * np.sqrt(0.025 / 0.25))


def test_odometry_applies_in_local_frame():
    m = OdometryMotion.noise_free()
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


def test_amcl_motion_model():
    rng = np.random.default_rng(0)
    p = np.tile([1.0, 2.0, 0.3], (2000, 1))
    u = np.array([0.5, 0.05, 0.2])
    exact = AmclOdometryMotion(0, 0, 0, 0).apply(p, u, 0.1, rng)
    np.testing.assert_allclose(exact, compose(p, u), atol=1e-12)
    m = AmclOdometryMotion()
    short = m.apply(p, u * 0.2, 0.1, rng)
    long = m.apply(p, u, 0.1, rng)
    assert np.std(long[:, 0]) > 2 * np.std(short[:, 0])
    np.testing.assert_allclose(np.mean(long, axis=0), compose(p[0], u), atol=0.02)
    back = m.apply(p, np.array([-0.5, 0.0, 0.0]), 0.1, rng)  # reversing is not a half turn
    assert np.all(np.abs(wrap_angle(back[:, 2] - 0.3)) < 0.6)
    np.testing.assert_allclose(m.apply(p, np.zeros(3), 0.1, rng), p, atol=1e-12)
    assert m.is_still(np.zeros(3)) and not m.is_still(u)


def test_amcl_noise_does_not_depend_on_the_time_step():
    p = np.tile([1.0, 2.0, 0.3], (50, 1))
    u = np.array([0.5, 0.05, 0.2])
    a = AmclOdometryMotion().apply(p, u, 0.01, np.random.default_rng(4))
    b = AmclOdometryMotion().apply(p, u, 10.0, np.random.default_rng(4))
    np.testing.assert_array_equal(a, b)


def test_amcl_motion_is_exact_without_noise_backwards_and_sideways():
    rng = np.random.default_rng(0)
    p = np.array([[1.0, 2.0, 0.3], [-1.0, 0.5, 3.0]])
    m = AmclOdometryMotion(0, 0, 0, 0)
    for u in ([-0.5, 0.1, 0.3], [0.0, 0.004, 0.0], [0.003, -0.002, 0.01], [-0.2, -0.3, -2.5]):
        np.testing.assert_allclose(m.apply(p, np.array(u), 0.1, rng), compose(p, np.array(u)), atol=1e-12)
    # Sub-centimetre sideways jitter does not turn into heading noise of alpha1 * 90 deg.
    q = AmclOdometryMotion().apply(np.tile([0.0, 0.0, 0.0], (2000, 1)), np.array([0.0, 0.005, 0.0]), 0.1, rng)
    assert np.std(q[:, 2]) < 0.01
