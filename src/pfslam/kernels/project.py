"""Projecting robot-frame points into grid cells in float32 (shared by the scoring and
likelihood kernels), and the NumPy twin of the projection."""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

from pfslam.types import Array

# --- projecting hits into the grid (float32, for SIMD) ------------------------------------
#
# The scoring kernels compute cell coordinates in float32, eight to a 256-bit vector
# instead of four: with 0.05 m cells and maps of a few thousand cells a side the rounding
# stays below 1e-4 of a cell (5 µm). The steps are written as IEEE float32 operations in
# the order the NumPy twins use (no fused multiply-add), so a kernel and its twin put
# every hit in the same cell. Only the sums may be split across vector lanes ("reassoc");
# sums of integer-valued log-odds (what +3 / -1 updates give) are exact in any order, and
# the tests compare kernels and twins exactly on such maps, which would also catch a
# compiler reordering the coordinate steps.

SUM_FASTMATH = {"reassoc", "nsz"}
MAX_CELLS = 2**31  # flat cell indices are 32-bit


@nb.njit(cache=True)
def points32(pts: Array) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    m = pts.shape[0]
    xs = np.empty(m, np.float32)
    ys = np.empty(m, np.float32)
    for k in range(m):
        xs[k] = pts[k, 0]
        ys[k] = pts[k, 1]
    return xs, ys


@nb.njit(cache=True)
def frame32(x: float, y: float, th: float, ox: float, oy: float, inv_res: float) -> tuple:
    """cos and sin of the heading in cells per metre, and the position in cells."""
    return (
        np.float32(np.cos(th) * inv_res),
        np.float32(np.sin(th) * inv_res),
        np.float32((x - ox) * inv_res),
        np.float32((y - oy) * inv_res),
    )


@nb.njit(cache=True, inline="always")
def project(c, s, fx0, fy0, x, y) -> tuple:
    """Cell coordinates of robot-frame point (x, y), in the twins' order of operations."""
    return fx0 + c * x - s * y, fy0 + s * x + c * y


@nb.njit(cache=True, inline="always")
def lookup(flat, fx, fy, hf, wf, wu) -> tuple:
    """Whether (fx, fy) lies on the grid, and the value of its cell (of cell 0 if not)."""
    zero = np.float32(0.0)
    ok = (fx >= zero) & (fx < wf) & (fy >= zero) & (fy < hf)
    return ok, flat[np.uint32(fy) * wu + np.uint32(fx) if ok else np.uint32(0)]


@nb.njit(cache=True)
def check_size(h: int, w: int) -> None:
    if h * w >= MAX_CELLS:
        raise ValueError("grid too large for the scoring kernels (2^31 cells or more)")


def project_numpy(poses: Array, pts: Array, ox: float, oy: float, inv_res: float) -> tuple[Array, Array]:
    """Cell coordinates (fx, fy) of every particle's points, float32 in the kernels' order."""
    xs = pts[:, 0].astype(np.float32)
    ys = pts[:, 1].astype(np.float32)
    c = (np.cos(poses[:, 2]) * inv_res).astype(np.float32)[:, None]
    s = (np.sin(poses[:, 2]) * inv_res).astype(np.float32)[:, None]
    fx0 = ((poses[:, 0] - ox) * inv_res).astype(np.float32)[:, None]
    fy0 = ((poses[:, 1] - oy) * inv_res).astype(np.float32)[:, None]
    return fx0 + c * xs - s * ys, fy0 + s * xs + c * ys


def cells_numpy(
    poses: Array, pts: Array, ox: float, oy: float, inv_res: float
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    fx, fy = project_numpy(poses, pts, ox, oy, inv_res)
    return np.floor(fy).astype(np.int64), np.floor(fx).astype(np.int64)
