"""SLAM scoring: correlation of projected hits with a map, and the local x/y/theta
search, each with its NumPy twin."""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

from pfslam.kernels.project import (
    SUM_FASTMATH,
    cells_numpy,
    check_size,
    frame32,
    lookup,
    points32,
    project,
)
from pfslam.types import Array


@nb.njit(cache=True, fastmath=SUM_FASTMATH)
def _clipped_sum(flat, xs, ys, c, s, fx0, fy0, h: int, w: int, lo: np.float32, hi: np.float32) -> np.float32:
    """Sum over the points of the map value clipped to [lo, hi]; points off the grid add 0."""
    hf, wf, wu = np.float32(h), np.float32(w), np.uint32(w)
    zero = np.float32(0.0)
    acc = zero
    for k in range(xs.shape[0]):
        fx, fy = project(c, s, fx0, fy0, xs[k], ys[k])
        ok, v = lookup(flat, fx, fy, hf, wf, wu)
        v = min(hi, max(lo, v))
        acc += v if ok else zero
    return acc


# --- correlation scoring (SLAM) ---------------------------------------------------------
#
# The map value of a cell is its log-odds divided by ``sat`` and clipped to [lo, 1]:
# confirmed walls count +1, unknown 0, confirmed free space ``lo`` (-1 counts free space
# as strongly against a hit as a wall for it; 0 ignores free space). The kernels clip in
# log-odds units (to [lo * sat, sat]) and divide the sum once.


@nb.njit(cache=True)
def correlation_kernel(
    poses: Array,
    pts: Array,
    logodds: NDArray[np.float32],
    ox: float,
    oy: float,
    inv_res: float,
    inv_sat: float,
    lo: float,
) -> Array:
    """Correlation score of every particle: the sum of map values at its projected hits."""
    n = poses.shape[0]
    h, w = logodds.shape
    check_size(h, w)
    flat = logodds.ravel()
    xs, ys = points32(pts)
    hi = np.float32(1.0 / inv_sat)
    lo32 = np.float32(lo / inv_sat)
    out = np.empty(n)
    for i in range(n):
        c, s, fx0, fy0 = frame32(poses[i, 0], poses[i, 1], poses[i, 2], ox, oy, inv_res)
        out[i] = _clipped_sum(flat, xs, ys, c, s, fx0, fy0, h, w, lo32, hi) * inv_sat
    return out


def _values_numpy(
    logodds: NDArray[np.float32], row: NDArray[np.int64], col: NDArray[np.int64], inv_sat: float, lo: float
) -> Array:
    h, w = logodds.shape
    inside = (row >= 0) & (row < h) & (col >= 0) & (col < w)
    v = np.zeros(row.shape)
    v[inside] = np.clip(logodds[row[inside], col[inside]], np.float32(lo / inv_sat), np.float32(1.0 / inv_sat))
    return v.sum(axis=-1) * inv_sat


def correlation_numpy(
    poses: Array,
    pts: Array,
    logodds: NDArray[np.float32],
    ox: float,
    oy: float,
    inv_res: float,
    inv_sat: float,
    lo: float,
) -> Array:
    """NumPy twin of :func:`correlation_kernel`."""
    row, col = cells_numpy(poses, pts, ox, oy, inv_res)
    return _values_numpy(logodds, row, col, inv_sat, lo)


@nb.njit(cache=True)
def _grid_cells(xs, ys, c, s, fx0, fy0, rows: NDArray[np.int32], cols: NDArray[np.int32]) -> None:
    """Row and column of each point's cell (may lie off the grid; clamped to ±2^30)."""
    big = np.float32(2.0**30)
    for k in range(xs.shape[0]):
        fx, fy = project(c, s, fx0, fy0, xs[k], ys[k])
        fx = np.floor(fx)
        fy = np.floor(fy)
        cols[k] = np.int32(min(big, max(-big, fx)))
        rows[k] = np.int32(min(big, max(-big, fy)))


@nb.njit(cache=True, fastmath=SUM_FASTMATH)
def _shifted_sum(
    flat: NDArray[np.float32], base: NDArray[np.int32], off: int, lo: np.float32, hi: np.float32
) -> np.float32:
    acc = np.float32(0.0)
    for k in range(base.shape[0]):
        acc += min(hi, max(lo, flat[np.uint32(base[k] + off)]))  # base + off lies on the grid
    return acc


@nb.njit(cache=True, fastmath=SUM_FASTMATH)
def _shifted_sum_checked(
    flat: NDArray[np.float32],
    rows: NDArray[np.int32],
    cols: NDArray[np.int32],
    dr: int,
    dc: int,
    h: int,
    w: int,
    lo: np.float32,
    hi: np.float32,
) -> np.float32:
    hu = np.uint32(h)
    wu = np.uint32(w)
    acc = np.float32(0.0)
    for k in range(rows.shape[0]):
        r = np.uint32(rows[k] + dr)
        c = np.uint32(cols[k] + dc)
        ok = (r < hu) & (c < wu)
        v = min(hi, max(lo, flat[r * wu + c if ok else np.uint32(0)]))
        acc += v if ok else np.float32(0.0)
    return acc


@nb.njit(cache=True)
def local_search_kernel(
    poses: Array,
    pts: Array,
    logodds: NDArray[np.float32],
    ox: float,
    oy: float,
    inv_res: float,
    inv_sat: float,
    lo: float,
    dcells: NDArray[np.int64],
    dthetas: Array,
) -> tuple[Array, NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """Best correlation over a local grid of whole-cell x/y shifts and heading offsets.

    Returns the best score of each particle and the indices (into ``dcells`` for x and
    y, into ``dthetas`` for theta) of its best offset. Shifts are whole cells, so the
    cell of each point is computed once per heading and shifted by integers; when every
    shifted cell stays on the grid the sums skip the bounds checks.
    """
    n = poses.shape[0]
    m = pts.shape[0]
    nc = dcells.shape[0]
    nt = dthetas.shape[0]
    h, w = logodds.shape
    check_size(h, w)
    flat = logodds.ravel()
    xs, ys = points32(pts)
    hi = np.float32(1.0 / inv_sat)
    lo32 = np.float32(lo / inv_sat)
    dmin = dcells.min()
    dmax = dcells.max()
    best = np.full(n, -np.inf)
    bx = np.zeros(n, dtype=np.int64)
    by = np.zeros(n, dtype=np.int64)
    bt = np.zeros(n, dtype=np.int64)
    rows = np.empty(m, dtype=np.int32)
    cols = np.empty(m, dtype=np.int32)
    base = np.empty(m, dtype=np.int32)  # flat cell index (grids of < 2^31 cells)
    for i in range(n):
        for t in range(nt):
            c, s, fx0, fy0 = frame32(poses[i, 0], poses[i, 1], poses[i, 2] + dthetas[t], ox, oy, inv_res)
            _grid_cells(xs, ys, c, s, fx0, fy0, rows, cols)
            fits = m == 0 or (
                rows.min() + dmin >= 0 and rows.max() + dmax < h and cols.min() + dmin >= 0 and cols.max() + dmax < w
            )
            if fits:
                for k in range(m):
                    base[k] = rows[k] * w + cols[k]
            for a in range(nc):
                for b in range(nc):
                    if fits:
                        acc = _shifted_sum(flat, base, dcells[b] * w + dcells[a], lo32, hi)
                    else:
                        acc = _shifted_sum_checked(flat, rows, cols, dcells[b], dcells[a], h, w, lo32, hi)
                    # Ties keep the earliest offset; put zero offsets first for stability.
                    score = acc * inv_sat
                    if score > best[i]:
                        best[i] = score
                        bx[i] = a
                        by[i] = b
                        bt[i] = t
    return best, bx, by, bt


def local_search_numpy(
    poses: Array,
    pts: Array,
    logodds: NDArray[np.float32],
    ox: float,
    oy: float,
    inv_res: float,
    inv_sat: float,
    lo: float,
    dcells: NDArray[np.int64],
    dthetas: Array,
) -> tuple[Array, NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """NumPy twin of :func:`local_search_kernel`."""
    n = len(poses)
    nc, nt = len(dcells), len(dthetas)
    scores = np.empty((n, nt, nc, nc))
    for t, dth in enumerate(dthetas):
        row, col = cells_numpy(poses + np.array([0.0, 0.0, dth]), pts, ox, oy, inv_res)
        for a, dx in enumerate(dcells):
            for b, dy in enumerate(dcells):
                scores[:, t, a, b] = _values_numpy(logodds, row + dy, col + dx, inv_sat, lo)
    flat = scores.reshape(n, -1)
    j = np.argmax(flat, axis=1)
    t, a, b = np.unravel_index(j, (nt, nc, nc))
    return flat[np.arange(n), j], a.astype(np.int64), b.astype(np.int64), t.astype(np.int64)
