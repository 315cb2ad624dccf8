import numpy as np
import pytest

from pfslam.evaluate import align_se2, associate, trajectory_errors
from pfslam.geometry import compose


def _traj(n=200, seed=0):
    rng = np.random.default_rng(seed)
    th = np.cumsum(rng.normal(0, 0.05, n))
    xy = np.cumsum(np.column_stack([np.cos(th), np.sin(th)]) * 0.1, axis=0)
    return np.arange(n) * 0.1, np.column_stack([xy, th])


def test_identical_is_zero():
    t, p = _traj()
    e = trajectory_errors(t, p, t, p)
    assert e.ate_rmse == 0 and e.ate_rmse_aligned < 1e-12 and e.rpe_trans_rmse < 1e-12


def test_alignment_removes_rigid_transform():
    t, p = _traj()
    g = np.array([3.0, -2.0, 0.7])
    moved = compose(g, p)
    e = trajectory_errors(t, moved, t, p)
    assert e.ate_rmse > 1.0
    assert e.ate_rmse_aligned < 1e-9
    assert e.rpe_trans_rmse < 1e-9  # RPE is invariant to a rigid transform
    assert np.allclose(compose(align_se2(moved, p), moved), p, atol=1e-9)


def test_constant_offset_ate():
    t, p = _traj()
    q = p.copy()
    q[:, 0] += 0.3
    e = trajectory_errors(t, q, t, p)
    assert e.ate_rmse == pytest.approx(0.3)


def test_associate_nearest_within_tolerance():
    i, j = associate(np.array([0.0, 1.0, 2.05, 5.0]), np.array([2.0, 0.01, 1.0]), max_dt=0.06)
    assert list(i) == [0, 1, 2] and list(j) == [1, 2, 0]
