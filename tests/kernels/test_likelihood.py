"""Localization's kernels against their NumPy twins: the likelihood field at the end points,
the beam model and its ray cast."""

import os

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


def test_the_field_sum_is_the_same_compiled_fresh_or_loaded_from_the_cache(tmp_path):
    """Runs are reproducible from the first: a process that compiles the kernel (a fresh
    install) and one that loads it from Numba's cache give the same bits. Before the sums were
    compiled inside their caller, the fresh compile inlined them differently and the first
    localization after an install ended 8 mm from every later one."""
    import subprocess
    import sys

    code = (
        "import hashlib, numpy as np\n"
        "from pfslam.kernels.likelihood import likelihood_kernel\n"
        "rng = np.random.default_rng(0)\n"
        "logp = rng.normal(-3, 1, size=(300, 300)).astype(np.float32)\n"
        "poses = np.column_stack([rng.uniform(2, 13, 200), rng.uniform(2, 13, 200), rng.uniform(-3, 3, 200)])\n"
        "pts = rng.uniform(-4, 4, size=(37, 2))\n"
        "print(*(hashlib.md5(likelihood_kernel(poses, pts, logp, 0.0, 0.0, 20.0, -5.0, i).tobytes()).hexdigest()"
        " for i in (False, True)))\n"
    )
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    fresh, cached = (
        subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
        for _ in range(2)
    )
    assert any((tmp_path / "cache").rglob("*.nbc"))  # (the second did load the first's compile)
    assert fresh == cached and len(fresh.split()) == 2
