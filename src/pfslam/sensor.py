"""Scan to points, and the sensor models that score particles against a map."""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import NDArray

from pfslam.frames import Frame

Array = NDArray[np.float64]


@dataclass
class ScanPoints:
    """A scan in the robot base frame, after range filtering and ground removal.

    Attributes:
        hits: (M, 2) obstacle points (x, y) in the robot frame.
        floor: (F, 2) floor hits (free space up to them, never obstacles).
        sensor_xy: (2,) the sensor's position in the robot frame.
    """

    hits: Array
    floor: Array
    sensor_xy: Array


def scan_to_points(
    frame: Frame,
    ground_z: float = 0.15,
    beam_step: int = 1,
) -> ScanPoints:
    """Project a frame's valid beams through its mount to the robot base frame.

    Beams outside (min_range, max_range), NaN or inf are dropped. Points whose height
    above the floor is below ``ground_z`` are floor hits.
    """
    r = np.asarray(frame.ranges, dtype=float)[::beam_step]
    a = np.asarray(frame.angles, dtype=float)[::beam_step]
    ok = np.isfinite(r) & (r > frame.min_range) & (r < frame.max_range)
    r, a = r[ok], a[ok]
    m = frame.mount
    # Sensor-frame point (r cos a, r sin a, 0) through the 4x4 mount.
    px, py = r * np.cos(a), r * np.sin(a)
    xyz = m[:3, :2] @ np.vstack([px, py]) + m[:3, 3:4]
    ground = xyz[2] < ground_z
    pts = xyz[:2].T
    return ScanPoints(
        hits=np.ascontiguousarray(pts[~ground]),
        floor=np.ascontiguousarray(pts[ground]),
        sensor_xy=m[:2, 3].copy(),
    )


# --- correlation scoring ---------------------------------------------------------
#
# The map value of a cell is its log-odds divided by ``sat`` and clipped to [lo, 1]:
# confirmed walls count +1, unknown 0, confirmed free space ``lo`` (-1 counts free space
# as strongly against a hit as a wall for it; 0 ignores free space).


@nb.njit(cache=True)
def _cell_value(l: float, inv_sat: float, lo: float) -> float:
    v = l * inv_sat
    if v > 1.0:
        return 1.0
    if v < lo:
        return lo
    return v


@nb.njit(cache=True)
def correlation_kernel(
    poses: Array, pts: Array, logodds: NDArray[np.float32], ox: float, oy: float, inv_res: float, inv_sat: float, lo: float
) -> Array:
    """Correlation score of every particle: the sum of map values at its projected hits."""
    n = poses.shape[0]
    m = pts.shape[0]
    h, w = logodds.shape
    out = np.zeros(n)
    for i in range(n):
        c = np.cos(poses[i, 2])
        s = np.sin(poses[i, 2])
        fx0 = (poses[i, 0] - ox) * inv_res
        fy0 = (poses[i, 1] - oy) * inv_res
        acc = 0.0
        for k in range(m):
            col = int(np.floor(fx0 + (c * pts[k, 0] - s * pts[k, 1]) * inv_res))
            row = int(np.floor(fy0 + (s * pts[k, 0] + c * pts[k, 1]) * inv_res))
            if 0 <= row < h and 0 <= col < w:
                acc += _cell_value(logodds[row, col], inv_sat, lo)
        out[i] = acc
    return out


def _cells_numpy(poses: Array, pts: Array, ox: float, oy: float, inv_res: float) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    c = np.cos(poses[:, 2])[:, None]
    s = np.sin(poses[:, 2])[:, None]
    fx = (poses[:, 0:1] - ox) * inv_res + (c * pts[None, :, 0] - s * pts[None, :, 1]) * inv_res
    fy = (poses[:, 1:2] - oy) * inv_res + (s * pts[None, :, 0] + c * pts[None, :, 1]) * inv_res
    return np.floor(fy).astype(np.int64), np.floor(fx).astype(np.int64)


def _values_numpy(
    logodds: NDArray[np.float32], row: NDArray[np.int64], col: NDArray[np.int64], inv_sat: float, lo: float
) -> Array:
    h, w = logodds.shape
    inside = (row >= 0) & (row < h) & (col >= 0) & (col < w)
    v = np.zeros(row.shape)
    v[inside] = np.clip(logodds[row[inside], col[inside]].astype(float) * inv_sat, lo, 1.0)
    return v.sum(axis=-1)


def correlation_numpy(
    poses: Array, pts: Array, logodds: NDArray[np.float32], ox: float, oy: float, inv_res: float, inv_sat: float, lo: float
) -> Array:
    """NumPy twin of :func:`correlation_kernel`."""
    row, col = _cells_numpy(poses, pts, ox, oy, inv_res)
    return _values_numpy(logodds, row, col, inv_sat, lo)


@nb.njit(cache=True)
def search_kernel(
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
    cell of each point is computed once per heading and shifted by integers.
    """
    n = poses.shape[0]
    m = pts.shape[0]
    nc = dcells.shape[0]
    nt = dthetas.shape[0]
    h, w = logodds.shape
    best = np.full(n, -np.inf)
    bx = np.zeros(n, dtype=np.int64)
    by = np.zeros(n, dtype=np.int64)
    bt = np.zeros(n, dtype=np.int64)
    rows = np.empty(m, dtype=np.int64)
    cols = np.empty(m, dtype=np.int64)
    acc = np.empty((nc, nc))
    for i in range(n):
        fx0 = (poses[i, 0] - ox) * inv_res
        fy0 = (poses[i, 1] - oy) * inv_res
        for t in range(nt):
            th = poses[i, 2] + dthetas[t]
            c = np.cos(th)
            s = np.sin(th)
            for k in range(m):
                cols[k] = int(np.floor(fx0 + (c * pts[k, 0] - s * pts[k, 1]) * inv_res))
                rows[k] = int(np.floor(fy0 + (s * pts[k, 0] + c * pts[k, 1]) * inv_res))
            acc[:, :] = 0.0
            for k in range(m):
                for a in range(nc):
                    col = cols[k] + dcells[a]
                    if col < 0 or col >= w:
                        continue
                    for b in range(nc):
                        row = rows[k] + dcells[b]
                        if 0 <= row < h:
                            acc[a, b] += _cell_value(logodds[row, col], inv_sat, lo)
            for a in range(nc):
                for b in range(nc):
                    # Ties keep the earliest offset; put zero offsets first for stability.
                    if acc[a, b] > best[i]:
                        best[i] = acc[a, b]
                        bx[i] = a
                        by[i] = b
                        bt[i] = t
    return best, bx, by, bt


def search_numpy(
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
    """NumPy twin of :func:`search_kernel`."""
    n = len(poses)
    nc, nt = len(dcells), len(dthetas)
    scores = np.empty((n, nt, nc, nc))
    for t, dth in enumerate(dthetas):
        row, col = _cells_numpy(poses + np.array([0.0, 0.0, dth]), pts, ox, oy, inv_res)
        for a, dx in enumerate(dcells):
            for b, dy in enumerate(dcells):
                scores[:, t, a, b] = _values_numpy(logodds, row + dy, col + dx, inv_sat, lo)
    flat = scores.reshape(n, -1)
    j = np.argmax(flat, axis=1)
    t, a, b = np.unravel_index(j, (nt, nc, nc))
    return flat[np.arange(n), j], a.astype(np.int64), b.astype(np.int64), t.astype(np.int64)
