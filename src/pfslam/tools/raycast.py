"""Ray casting for the simulator: beams in 3D against a world's vertical walls and the floor
(Numba, with a NumPy twin for the tests)."""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from pfslam.types import Array

MAX_RANGE = 30.0


@nb.njit(cache=True)
def _segment_distances(ox: float, oy: float, segs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Horizontal distance from (ox, oy) to every segment."""
    k = segs.shape[0]
    out = np.empty(k)
    for j in range(k):
        ax, ay, bx, by = segs[j, 0], segs[j, 1], segs[j, 2], segs[j, 3]
        ex, ey = bx - ax, by - ay
        ee = ex * ex + ey * ey
        u = 0.0
        if ee > 0.0:
            u = ((ox - ax) * ex + (oy - ay) * ey) / ee
            u = min(1.0, max(0.0, u))
        px, py = ax + u * ex - ox, ay + u * ey - oy
        out[j] = math.sqrt(px * px + py * py)
    return out


@nb.njit(cache=True)
def _cast_beam(
    ox: float,
    oy: float,
    oz: float,
    dx: float,
    dy: float,
    dz: float,
    segs: NDArray[np.float64],
    order: NDArray[np.int64],
    dmin: NDArray[np.float64],
    wall_height: float,
    max_range: float,
) -> float:
    """Range along a unit 3D direction to the first wall or floor hit (max_range if none).

    ``order`` sorts the segments by their horizontal distance ``dmin`` from the sensor,
    so the search stops once no remaining segment can be nearer than the best hit.
    """
    best = max_range
    if dz < 0.0:
        tf = -oz / dz
        if tf < best:
            best = tf
    h = math.sqrt(dx * dx + dy * dy)
    for jj in range(order.shape[0]):
        j = order[jj]
        if dmin[j] > best * h:
            break
        ax, ay = segs[j, 0], segs[j, 1]
        ex, ey = segs[j, 2] - ax, segs[j, 3] - ay
        den = dx * ey - dy * ex
        if abs(den) < 1e-15:
            continue
        wx, wy = ax - ox, ay - oy
        t = (wx * ey - wy * ex) / den
        if t <= 1e-9 or t >= best:
            continue
        u = (wx * dy - wy * dx) / den
        if u < 0.0 or u > 1.0:
            continue
        z = oz + t * dz
        if z < 0.0 or z > wall_height:
            continue
        best = t
    if best >= max_range:
        return max_range
    return best


@nb.njit(cache=True)
def _raycast_kernel(
    origin: NDArray[np.float64],
    dirs: NDArray[np.float64],
    segs: NDArray[np.float64],
    wall_height: float,
    max_range: float,
) -> NDArray[np.float64]:
    dmin = _segment_distances(origin[0], origin[1], segs)
    order = np.argsort(dmin)
    out = np.empty(dirs.shape[0])
    for i in range(dirs.shape[0]):
        out[i] = _cast_beam(
            origin[0],
            origin[1],
            origin[2],
            dirs[i, 0],
            dirs[i, 1],
            dirs[i, 2],
            segs,
            order,
            dmin,
            wall_height,
            max_range,
        )
    return out


@nb.njit(cache=True)
def _raycast_scans(
    origins: NDArray[np.float64],
    rots: NDArray[np.float64],
    angles: NDArray[np.float64],
    segs: NDArray[np.float64],
    wall_height: float,
    max_range: float,
) -> NDArray[np.float32]:
    """(N, B) noise-free ranges for N sensor poses (origin, 3x3 rotation) and B beam angles."""
    n, b = origins.shape[0], angles.shape[0]
    out = np.empty((n, b), dtype=np.float32)
    ca, sa = np.cos(angles), np.sin(angles)
    for i in range(n):
        ox, oy, oz = origins[i, 0], origins[i, 1], origins[i, 2]
        dmin = _segment_distances(ox, oy, segs)
        order = np.argsort(dmin)
        r = rots[i]
        for k in range(b):
            dx = r[0, 0] * ca[k] + r[0, 1] * sa[k]
            dy = r[1, 0] * ca[k] + r[1, 1] * sa[k]
            dz = r[2, 0] * ca[k] + r[2, 1] * sa[k]
            out[i, k] = _cast_beam(ox, oy, oz, dx, dy, dz, segs, order, dmin, wall_height, max_range)
    return out


def raycast(
    origin: Array, dirs: Array, segments: Array, wall_height: float = 2.5, max_range: float = MAX_RANGE
) -> Array:
    """Ranges from a 3D sensor position along unit 3D directions ``(B, 3)`` (Numba).

    Targets: vertical walls ``segments`` (K, 4) standing from z = 0 to ``wall_height``,
    and the floor z = 0. A beam that hits nothing nearer than ``max_range`` returns
    ``max_range`` exactly. No noise.
    """
    o = np.ascontiguousarray(origin, dtype=np.float64).reshape(3)
    d = np.ascontiguousarray(dirs, dtype=np.float64).reshape(-1, 3)
    s = np.ascontiguousarray(segments, dtype=np.float64).reshape(-1, 4)
    return _raycast_kernel(o, d, s, float(wall_height), float(max_range))


def raycast_numpy(
    origin: Array, dirs: Array, segments: Array, wall_height: float = 2.5, max_range: float = MAX_RANGE
) -> Array:
    """NumPy twin of :func:`raycast` (brute force over all segments)."""
    o = np.asarray(origin, dtype=float).reshape(3)
    d = np.asarray(dirs, dtype=float).reshape(-1, 3)
    s = np.asarray(segments, dtype=float).reshape(-1, 4)
    dx, dy, dz = d[:, 0:1], d[:, 1:2], d[:, 2:3]
    ax, ay = s[None, :, 0], s[None, :, 1]
    ex, ey = s[None, :, 2] - ax, s[None, :, 3] - ay
    wx, wy = ax - o[0], ay - o[1]
    den = dx * ey - dy * ex
    ok = np.abs(den) >= 1e-15
    safe = np.where(ok, den, 1.0)
    t = (wx * ey - wy * ex) / safe
    u = (wx * dy - wy * dx) / safe
    z = o[2] + t * dz
    hit = ok & (t > 1e-9) & (u >= 0.0) & (u <= 1.0) & (z >= 0.0) & (z <= wall_height)
    best = np.min(np.where(hit, t, np.inf), axis=1) if s.shape[0] else np.full(d.shape[0], np.inf)
    neg = d[:, 2] < 0.0
    tf = np.where(neg, -o[2] / np.where(neg, d[:, 2], -1.0), np.inf)
    best = np.minimum(best, tf)
    return np.where(best >= max_range, max_range, best)
