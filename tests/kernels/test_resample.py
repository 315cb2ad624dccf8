"""Systematic resampling: the kernel against its NumPy twin."""

import numpy as np

from pfslam.kernels.resample import systematic_kernel, systematic_numpy


def test_systematic_kernel_matches_numpy_twin():
    rng = np.random.default_rng(5)
    for n_w, n in ((1, 5), (10, 10), (1000, 300), (300, 5000)):
        w = rng.random(n_w) ** 4
        w[rng.random(n_w) < 0.3] = 0.0
        w = w / w.sum() if w.sum() > 0 else np.full(n_w, 1 / n_w)
        u0 = float(rng.random())
        got, want = np.full(n, -1, np.int64), np.full(n, -2, np.int64)
        systematic_kernel(w, u0, got)
        systematic_numpy(w, u0, want)
        np.testing.assert_array_equal(got, want)
