"""The float32 projection shared by the scoring and likelihood kernels: the jitted steps and
the NumPy twin put every point in the same cell, and both agree with float64 geometry."""

import numpy as np
import pytest

from pfslam.geometry import transform_points
from pfslam.kernels.project import check_size, frame32, points32, project, project_numpy


def test_jitted_projection_is_the_twins_bit_for_bit():
    rng = np.random.default_rng(0)
    poses = np.column_stack([rng.uniform(-3, 3, 20), rng.uniform(-3, 3, 20), rng.uniform(-np.pi, np.pi, 20)])
    pts = rng.uniform(-8, 8, (50, 2))
    ox, oy, inv = -10.0, -7.5, 20.0
    fx, fy = project_numpy(poses, pts, ox, oy, inv)
    assert fx.dtype == fy.dtype == np.float32 and fx.shape == (20, 50)
    xs, ys = points32(pts)
    for i, (x, y, th) in enumerate(poses):
        # Numba hands float32 scalars back to Python as floats: exact, so make them float32 again.
        c, s, fx0, fy0 = (np.float32(v) for v in frame32(x, y, th, ox, oy, inv))
        gx, gy = project(c, s, fx0, fy0, xs, ys)
        assert gx.dtype == np.float32
        np.testing.assert_array_equal(gx, fx[i])
        np.testing.assert_array_equal(gy, fy[i])
        # float32 cell coordinates: within 1e-4 of a cell of the float64 geometry here.
        world = transform_points(poses[i], pts)
        np.testing.assert_allclose(fx[i], (world[:, 0] - ox) * inv, atol=1e-3)
        np.testing.assert_allclose(fy[i], (world[:, 1] - oy) * inv, atol=1e-3)


def test_grids_past_32_bit_cell_indices_are_refused():
    check_size(40_000, 50_000)  # 2e9 cells: still fits
    with pytest.raises(ValueError, match="too large"):
        check_size(2**16, 2**15)
