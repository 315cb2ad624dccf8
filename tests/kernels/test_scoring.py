"""SLAM's scoring kernels against their NumPy twins: correlation of projected hits with the
map, and the local x/y/theta search."""

import numpy as np
import pytest

from pfslam.kernels.scoring import correlation_kernel, correlation_numpy, local_search_kernel, local_search_numpy


def _random_case(seed, n=40, m=200, shape=(120, 150)):
    rng = np.random.default_rng(seed)
    lo = rng.normal(scale=5, size=shape).astype(np.float32)
    poses = np.column_stack([rng.uniform(1, 6, n), rng.uniform(1, 5, n), rng.uniform(-np.pi, np.pi, n)])
    pts = rng.uniform(-4, 4, size=(m, 2))
    return poses, pts, lo


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("free", [-1.0, 0.0])
def test_correlation_kernel_matches_numpy(seed, free):
    poses, pts, lo = _random_case(seed)
    args = (poses, pts, lo, -0.3, 0.2, 20.0, 1 / 6, free)
    # Fractional log-odds: the kernel sums in float32 across SIMD lanes.
    np.testing.assert_allclose(correlation_kernel(*args), correlation_numpy(*args), rtol=1e-6, atol=1e-5)
    # Integer log-odds (what +3 / -1 updates give): every hit in the same cell, sums exact.
    args = (poses, pts, np.round(lo * 4), -0.3, 0.2, 20.0, 1 / 6, free)
    np.testing.assert_array_equal(correlation_kernel(*args), correlation_numpy(*args))


def test_hits_on_cell_edges_fall_in_the_same_cell_as_the_twin():
    # Points exactly on (or a rounding error from) cell edges, seen from poses on edges.
    rng = np.random.default_rng(3)
    lo = rng.integers(-8, 9, size=(90, 90)).astype(np.float32)
    k = rng.integers(-30, 30, size=(300, 2))
    pts = k * 0.05
    poses = np.column_stack(
        [
            rng.integers(20, 70, 30) * 0.05,
            rng.integers(20, 70, 30) * 0.05,
            rng.choice([0.0, np.pi / 2, np.pi, -np.pi / 2, 1e-9], 30),
        ]
    )
    for org in (0.0, -0.05, 0.1 / 3):
        args = (poses, pts, lo, org, org, 20.0, 1 / 6, -1.0)
        np.testing.assert_array_equal(correlation_kernel(*args), correlation_numpy(*args))


def rng_uniform(seed, a, b, n):
    return np.random.default_rng(seed).uniform(a, b, n)


@pytest.mark.parametrize("seed", range(3))
def test_local_search_kernel_matches_numpy(seed):
    poses, pts, lo = _random_case(seed, n=10, m=100)
    dc = np.array([0, -1, 1], dtype=np.int64)
    dt = np.array([0.0, -0.01, 0.01])
    lo = np.round(lo * 4)  # integer log-odds: sums exact, so ties break the same way
    # Poses near the edge take the bounds-checked path, the others the unchecked one.
    poses[:3, :2] = [[0.1, 0.1], [7.4, 5.9], [3.0, 0.05]]
    a = local_search_kernel(poses, pts, lo, 0.0, 0.0, 20.0, 1 / 6, -1.0, dc, dt)
    b = local_search_numpy(poses, pts, lo, 0.0, 0.0, 20.0, 1 / 6, -1.0, dc, dt)
    np.testing.assert_array_equal(a[0], b[0])
    for x, y in zip(a[1:], b[1:]):
        assert np.array_equal(x, y)
    # All shifted cells on the grid (the unchecked path) for the poses in the middle.
    mid = np.column_stack([rng_uniform(seed, 2, 5, 10), rng_uniform(seed + 1, 2, 4, 10), poses[:, 2]])
    a = local_search_kernel(mid, pts / 4, lo, 0.0, 0.0, 20.0, 1 / 6, -1.0, dc, dt)
    b = local_search_numpy(mid, pts / 4, lo, 0.0, 0.0, 20.0, 1 / 6, -1.0, dc, dt)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    # Its zero offset is the plain correlation score.
    z = local_search_kernel(poses, pts, lo, 0.0, 0.0, 20.0, 1 / 6, -1.0, np.array([0]), np.array([0.0]))
    np.testing.assert_array_equal(z[0], correlation_kernel(poses, pts, lo, 0.0, 0.0, 20.0, 1 / 6, -1.0))


def test_correlation_peaks_at_true_pose():
    lo = np.zeros((100, 100), np.float32)
    lo[:, 60] = 10.0  # wall at x = 3.0..3.05 with 0.05 m cells, origin 0
    pts = np.column_stack([np.full(50, 1.025), np.linspace(-1, 1, 50)])
    true = np.array([[2.0, 2.5, 0.0]])
    wrong = np.array([[2.2, 2.5, 0.0]])
    a = correlation_kernel(true, pts, lo, 0.0, 0.0, 20.0, 1 / 6, -1.0)
    b = correlation_kernel(wrong, pts, lo, 0.0, 0.0, 20.0, 1 / 6, -1.0)
    assert a[0] == pytest.approx(50.0) and b[0] == 0.0
    best, bx, by, bt = local_search_kernel(
        np.array([[2.05, 2.5, 0.0]]), pts, lo, 0.0, 0.0, 20.0, 1 / 6, -1.0, np.array([0, -1, 1]), np.array([0.0])
    )
    assert best[0] == pytest.approx(50.0) and bx[0] == 1  # shifted by -1 cell in x
