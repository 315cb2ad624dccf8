"""Localization's kernels against their NumPy twins: the likelihood field at the end points,
the beam model and its ray cast."""

import numpy as np
import pytest

from pfslam.kernels.likelihood import beam_kernel, beam_numpy, cast_ray, likelihood_kernel, likelihood_numpy


@pytest.mark.parametrize("seed", range(3))
def test_likelihood_kernel_matches_numpy(seed):
    rng = np.random.default_rng(seed)
    logp = rng.normal(-2, 1, (80, 90)).astype(np.float32)
    poses = np.column_stack([rng.uniform(0, 4, 50), rng.uniform(0, 4, 50), rng.uniform(-3, 3, 50)])
    pts = rng.uniform(-3, 3, (60, 2))
    args = (poses, pts, logp, -0.2, 0.1, 20.0, -7.0)
    # The kernel sums in float32 across SIMD lanes, the twin in float64.
    np.testing.assert_allclose(likelihood_kernel(*args), likelihood_numpy(*args), rtol=1e-6)


def test_beam_kernel_matches_twin_and_casts_exact_ranges():
    occ = np.zeros((100, 100), np.uint8)
    occ[:, 70] = 1  # a wall at x = 3.5 m (0.05 m cells from the origin)
    occ[20, :] = 1
    assert cast_ray(occ, 0.0, 0.0, 20.0, 1.0, 2.5, 1.0, 0.0, 30.0) == pytest.approx(2.5)
    assert cast_ray(occ, 0.0, 0.0, 20.0, 1.0, 2.5, -1.0, 0.0, 30.0) == 30.0  # leaves the grid
    rng = np.random.default_rng(0)
    poses = np.column_stack([rng.uniform(1, 3, 20), rng.uniform(1.5, 4, 20), rng.uniform(-3, 3, 20)])
    pts = rng.uniform(-2, 2, (30, 2))
    args = (poses, np.array([0.1, 0.0]), pts, occ, 0.0, 0.0, 20.0, 30.0, 0.1, 0.8, 0.1, 0.5, 0.1)
    np.testing.assert_allclose(beam_kernel(*args), beam_numpy(*args), atol=1e-9)
