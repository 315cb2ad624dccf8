"""The loop-closure matcher's kernels against brute force: the max-pooled pyramid, branch and
bound against every offset scored, the field against the distance transform."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.ndimage import distance_transform_edt, gaussian_filter

from pfslam.kernels.bnb import (
    bilinear_score_kernel,
    bnb_kernel,
    bnb_numpy,
    field_kernel,
    pyramid_kernel,
    refine_kernel,
)


def smooth_grid(rng: np.random.Generator, h: int = 48, w: int = 56) -> np.ndarray:
    g = gaussian_filter(rng.random((h, w)), 1.5)
    g = (g - g.min()) / (g.max() - g.min())
    return g.astype(np.float32)


@given(seed=st.integers(0, 10_000), depth=st.integers(1, 5))
@settings(max_examples=30, deadline=None)
def test_pyramid_levels_are_block_maxima(seed: int, depth: int) -> None:
    g = smooth_grid(np.random.default_rng(seed), 23, 31)
    pyr = pyramid_kernel(g, depth)
    for lv in range(depth):
        b = 1 << lv
        for r in range(0, 23, 5):
            for c in range(0, 31, 7):
                assert pyr[lv, r, c] == g[r : r + b, c : c + b].max()


@given(seed=st.integers(0, 10_000), window=st.integers(0, 9), min_score=st.sampled_from([0.0, 0.3, 0.6]))
@settings(max_examples=40, deadline=None)
def test_branch_and_bound_finds_the_exhaustive_best(seed: int, window: int, min_score: float) -> None:
    rng = np.random.default_rng(seed)
    g = smooth_grid(rng)
    cols = rng.integers(-5, 60, size=(3, 25)).astype(np.int32)
    rows = rng.integers(-5, 52, size=(3, 25)).astype(np.int32)
    depth = int(max(1, np.ceil(np.log2(2 * window + 1))))
    s, k, dc, dr = bnb_kernel(pyramid_kernel(g, depth), cols, rows, window, min_score, -1, 0, 0, 0, 0)
    s0, k0, dc0, dr0 = bnb_numpy(g, cols, rows, window, min_score)
    assert s == pytest.approx(s0, abs=1e-5)
    if k0 >= 0:  # the offset it names scores what it says
        r, c = rows[k] + dr, cols[k] + dc
        ok = (r >= 0) & (r < g.shape[0]) & (c >= 0) & (c < g.shape[1])
        assert g[r[ok], c[ok]].sum() / 25 == pytest.approx(s, abs=1e-5)
        assert abs(dc) <= window and abs(dr) <= window


def test_the_runner_up_leaves_out_the_best_neighbourhood() -> None:
    rng = np.random.default_rng(4)
    g = smooth_grid(rng)
    cols = rng.integers(0, 56, size=(1, 30)).astype(np.int32)
    rows = rng.integers(0, 48, size=(1, 30)).astype(np.int32)
    pyr = pyramid_kernel(g, 4)
    s, k, dc, dr = bnb_kernel(pyr, cols, rows, 8, 0.0, -1, 0, 0, 0, 0)
    s2, k2, dc2, dr2 = bnb_kernel(pyr, cols, rows, 8, 0.0, k, dc, dr, 2, 0)
    assert s2 <= s
    assert max(abs(dc2 - dc), abs(dr2 - dr)) > 2
    # the exhaustive best outside that neighbourhood
    best = 0.0
    for c in range(-8, 9):
        for r in range(-8, 9):
            if max(abs(c - dc), abs(r - dr)) <= 2:
                continue
            rr, cc = rows[0] + r, cols[0] + c
            ok = (rr >= 0) & (rr < 48) & (cc >= 0) & (cc < 56)
            best = max(best, g[rr[ok], cc[ok]].sum() / 30)
    assert s2 == pytest.approx(best, abs=1e-5)


def test_field_is_the_truncated_gaussian_of_the_distance() -> None:
    rng = np.random.default_rng(1)
    occ = rng.random((40, 50)) < 0.02
    sigma, radius = 1.5, 5
    f = field_kernel(occ, sigma, radius)
    d = distance_transform_edt(~occ)
    want = np.where(d <= radius, np.exp(-0.5 * (d / sigma) ** 2), 0.0)
    # inside the radius the stamp and the true distance agree (the stamp is a square: corners
    # farther than the radius may still be reached)
    near = d <= radius
    assert np.allclose(f[near], want[near], atol=1e-6)
    assert (f[~near] <= np.exp(-0.5 * (radius / sigma) ** 2) + 1e-7).all()


def test_refinement_reaches_a_sub_cell_optimum() -> None:
    """A wall pattern shifted by a fraction of a cell: the hill climb on the bilinear field
    finds the shift to a tenth of a cell."""
    res = 0.05
    occ = np.zeros((80, 80), dtype=bool)
    occ[10, 10:70] = occ[10:70, 10] = occ[69, 10:70] = occ[30:50, 45] = True
    f = field_kernel(occ, 1.5, 5)
    rows, cols = np.nonzero(occ)
    pts = np.column_stack([(cols + 0.5) * res, (rows + 0.5) * res]).astype(float)
    true = np.array([0.013, -0.021, np.deg2rad(0.4)])
    # points seen from the true pose: moved by its inverse
    c, s = np.cos(-true[2]), np.sin(-true[2])
    q = pts - true[:2]
    seen = np.column_stack([c * q[:, 0] - s * q[:, 1], s * q[:, 0] + c * q[:, 1]])
    pose, score = refine_kernel(f, seen, np.zeros(3), 0.0, 0.0, res, res / 2, np.deg2rad(0.5), 5)
    assert np.hypot(*(pose[:2] - true[:2])) < 0.1 * res
    assert abs(pose[2] - true[2]) < np.deg2rad(0.1)
    assert score == pytest.approx(bilinear_score_kernel(f, seen, pose, 0.0, 0.0, res))
    assert score > bilinear_score_kernel(f, seen, np.zeros(3), 0.0, 0.0, res)
