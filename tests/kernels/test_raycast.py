"""The map update kernel (exact ray traversal, log-odds) against its NumPy twin, and the
cell walk of a ray."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pfslam.kernels.raycast import ray_cells, ray_update_kernel, ray_update_numpy


def _both(seed, shape=(40, 50), n=30, snap=False):
    rng = np.random.default_rng(seed)
    a = rng.normal(0, 2, shape).astype(np.float32)
    b = a.copy()
    sx, sy = rng.uniform(0, 2.5), rng.uniform(0, 2)
    ends = rng.uniform(-0.5, 3, (n, 2))
    if snap:  # beams starting / ending exactly on grid lines and corners
        sx, sy = round(sx * 20) / 20, round(sy * 20) / 20
        ends = np.round(ends * 20) / 20
    hit = rng.random(n) < 0.5
    sa, sb = np.zeros(shape, np.int32), np.zeros(shape, np.int32)
    ray_update_kernel(a, 0.0, 0.0, 20.0, sx, sy, ends, hit, 3.0, -1.0, 5.0, sa, 1)
    ray_update_numpy(b, 0.0, 0.0, 20.0, sx, sy, ends, hit, 3.0, -1.0, 5.0, sb, 1)
    return a, b


@pytest.mark.parametrize("seed", range(20))
@pytest.mark.parametrize("snap", [False, True])
def test_ray_kernel_matches_numpy(seed, snap):
    a, b = _both(seed, snap=snap)
    np.testing.assert_array_equal(a, b)


@given(st.floats(0.0, 4.0), st.floats(0.0, 4.0), st.floats(0.0, 4.0), st.floats(0.0, 4.0))
@settings(max_examples=200, deadline=None)
def test_ray_cells_are_a_4_connected_walk_without_repeats(x0, y0, x1, y1):
    rows, cols = ray_cells(x0, y0, x1, y1)
    assert (rows[-1], cols[-1]) == (int(np.floor(y1)), int(np.floor(x1)))
    assert (rows[0], cols[0]) == (int(np.floor(y0)), int(np.floor(x0)))
    steps = np.abs(np.diff(rows)) + np.abs(np.diff(cols))
    assert np.all(steps == 1)
    assert len(set(zip(rows.tolist(), cols.tolist()))) == len(rows)
