"""Localization sensor models: likelihood-field lookup and the beam model (ray cast per
beam), each with its NumPy twin."""

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
    project_numpy,
)
from pfslam.kernels.raycast import axis_setup
from pfslam.types import Array

# --- likelihood field lookup (localization) ---------------------------------------------


@nb.njit(cache=True, fastmath=SUM_FASTMATH, inline="always")
def _field_sum(flat, xs, ys, c, s, fx0, fy0, h: int, w: int, floor: np.float32) -> np.float32:
    """Sum over the points of the map value; points off the grid add ``floor``."""
    hf, wf, wu = np.float32(h), np.float32(w), np.uint32(w)
    acc = np.float32(0.0)
    for k in range(xs.shape[0]):
        fx, fy = project(c, s, fx0, fy0, xs[k], ys[k])
        ok, v = lookup(flat, fx, fy, hf, wf, wu)
        acc += v if ok else floor
    return acc


@nb.njit(cache=True, fastmath=SUM_FASTMATH, inline="always")
def _bilinear_sum(flat, xs, ys, c, s, fx0, fy0, h: int, w: int, floor: np.float32) -> np.float32:
    """Sum over the points of the map read bilinearly between the centres of the four cells
    around each point; a point without all four on the grid adds ``floor``."""
    half, zero = np.float32(0.5), np.float32(0.0)
    gw, gh, wu = np.float32(w - 1), np.float32(h - 1), np.uint32(w)
    acc = np.float32(0.0)
    for k in range(xs.shape[0]):
        fx, fy = project(c, s, fx0, fy0, xs[k], ys[k])
        gx = fx - half
        gy = fy - half
        ok = (gx >= zero) & (gx < gw) & (gy >= zero) & (gy < gh)
        i = np.uint32(gx) if ok else np.uint32(0)
        j = np.uint32(gy) if ok else np.uint32(0)
        ax = gx - np.float32(i)
        ay = gy - np.float32(j)
        q = j * wu + i
        v0 = flat[q] + ax * (flat[q + np.uint32(1)] - flat[q])
        v1 = flat[q + wu] + ax * (flat[q + wu + np.uint32(1)] - flat[q + wu])
        v = v0 + ay * (v1 - v0)
        acc += v if ok else floor
    return acc


@nb.njit(cache=True, fastmath=SUM_FASTMATH)
def likelihood_kernel(
    poses: Array,
    pts: Array,
    logp: NDArray[np.float32],
    ox: float,
    oy: float,
    inv_res: float,
    floor: float,
    interpolate: bool = False,
) -> Array:
    """Sum over beam end points of the log-probability field, for every particle.

    End points off the map count ``floor`` (the random-measurement term alone). With
    ``interpolate`` the field is read bilinearly between the centres of the four cells
    around each end point, so the sum changes continuously as a particle moves by less
    than a cell; an end point without all four on the grid counts ``floor`` (give the grid
    a border of one ``floor`` cell, as :meth:`LikelihoodField.padded` does, to read its
    outermost cells).
    """
    n = poses.shape[0]
    h, w = logp.shape
    check_size(h, w)
    flat = logp.ravel()
    xs, ys = points32(pts)
    fl = np.float32(floor)
    out = np.empty(n)
    if interpolate and (h < 2 or w < 2):  # no four cell centres around any point
        out[:] = fl * np.float32(xs.shape[0])
        return out
    for i in range(n):
        c, s, fx0, fy0 = frame32(poses[i, 0], poses[i, 1], poses[i, 2], ox, oy, inv_res)
        if interpolate:
            out[i] = _bilinear_sum(flat, xs, ys, c, s, fx0, fy0, h, w, fl)
        else:
            out[i] = _field_sum(flat, xs, ys, c, s, fx0, fy0, h, w, fl)
    return out


def likelihood_numpy(
    poses: Array,
    pts: Array,
    logp: NDArray[np.float32],
    ox: float,
    oy: float,
    inv_res: float,
    floor: float,
    interpolate: bool = False,
) -> Array:
    """NumPy twin of :func:`likelihood_kernel`."""
    h, w = logp.shape
    if not interpolate:
        row, col = cells_numpy(poses, pts, ox, oy, inv_res)
        inside = (row >= 0) & (row < h) & (col >= 0) & (col < w)
        v = np.full(row.shape, np.float32(floor), dtype=np.float64)
        v[inside] = logp[row[inside], col[inside]]
        return v.sum(axis=-1)
    if h < 2 or w < 2:
        return np.full(len(poses), float(np.float32(floor) * np.float32(len(pts))))
    fx, fy = project_numpy(poses, pts, ox, oy, inv_res)
    gx, gy = fx - np.float32(0.5), fy - np.float32(0.5)
    ok = (gx >= 0) & (gx < np.float32(w - 1)) & (gy >= 0) & (gy < np.float32(h - 1))
    i = np.where(ok, gx, 0).astype(np.int64)
    j = np.where(ok, gy, 0).astype(np.int64)
    ax, ay = gx - i.astype(np.float32), gy - j.astype(np.float32)
    v0 = logp[j, i] + ax * (logp[j, i + 1] - logp[j, i])
    v1 = logp[j + 1, i] + ax * (logp[j + 1, i + 1] - logp[j + 1, i])
    val = v0 + ay * (v1 - v0)
    return np.where(ok, val, np.float32(floor)).astype(np.float64).sum(axis=-1)


# --- beam model (localization, for comparison with the likelihood field) ----------------


@nb.njit(cache=True)
def cast_ray(
    occ: NDArray[np.uint8],
    ox: float,
    oy: float,
    inv_res: float,
    x0: float,
    y0: float,
    ux: float,
    uy: float,
    max_range: float,
) -> float:
    """Distance from (x0, y0) along the unit direction (ux, uy) to the first occupied cell
    (exact grid traversal); ``max_range`` if none is met or the ray leaves the grid."""
    h, w = occ.shape
    fx = (x0 - ox) * inv_res
    fy = (y0 - oy) * inv_res
    c = int(np.floor(fx))
    r = int(np.floor(fy))
    sc, tmx, tdx = axis_setup(fx, fx + ux)
    sr, tmy, tdy = axis_setup(fy, fy + uy)
    res = 1.0 / inv_res
    t = 0.0  # in cells
    limit = max_range * inv_res
    while t < limit:
        if r < 0 or r >= h or c < 0 or c >= w:
            return max_range
        if occ[r, c]:
            return t * res
        if tmx < tmy:
            t = tmx
            c += sc
            tmx += tdx
        else:
            t = tmy
            r += sr
            tmy += tdy
    return max_range


@nb.njit(cache=True)
def _beam_logp(
    z: float, zs: float, max_range: float, sigma: float, z_hit: float, z_short: float, lam: float, z_rand: float
) -> float:
    p = z_hit * np.exp(-0.5 * ((z - zs) / sigma) ** 2) / (sigma * np.sqrt(2.0 * np.pi)) + z_rand / max_range
    if z < zs:
        p += z_short * lam * np.exp(-lam * z)
    return np.log(p)


@nb.njit(cache=True)
def beam_kernel(
    poses: Array,
    sensor_xy: Array,
    pts: Array,
    occ: NDArray[np.uint8],
    ox: float,
    oy: float,
    inv_res: float,
    max_range: float,
    sigma: float,
    z_hit: float,
    z_short: float,
    lam: float,
    z_rand: float,
) -> Array:
    """Beam-model log-likelihood of every particle: each measured range against the range
    ray-cast in the map from the particle's sensor position along the beam."""
    n = poses.shape[0]
    m = pts.shape[0]
    out = np.zeros(n)
    for i in range(n):
        c = np.cos(poses[i, 2])
        s = np.sin(poses[i, 2])
        sx = poses[i, 0] + c * sensor_xy[0] - s * sensor_xy[1]
        sy = poses[i, 1] + s * sensor_xy[0] + c * sensor_xy[1]
        acc = 0.0
        for k in range(m):
            bx = pts[k, 0] - sensor_xy[0]
            by = pts[k, 1] - sensor_xy[1]
            z = np.hypot(bx, by)
            if z <= 0.0:
                continue
            ux = (c * bx - s * by) / z
            uy = (s * bx + c * by) / z
            zs = cast_ray(occ, ox, oy, inv_res, sx, sy, ux, uy, max_range)
            acc += _beam_logp(z, zs, max_range, sigma, z_hit, z_short, lam, z_rand)
        out[i] = acc
    return out


def beam_numpy(
    poses: Array,
    sensor_xy: Array,
    pts: Array,
    occ: NDArray[np.uint8],
    ox: float,
    oy: float,
    inv_res: float,
    max_range: float,
    sigma: float,
    z_hit: float,
    z_short: float,
    lam: float,
    z_rand: float,
) -> Array:
    """Twin of :func:`beam_kernel`: the same exact ray cast in plain Python per beam (slow;
    for tests), the likelihood vectorised."""
    poses = np.asarray(poses, float)
    b = np.asarray(pts, float) - np.asarray(sensor_xy, float)
    z = np.hypot(b[:, 0], b[:, 1])
    keep = z > 0
    b, z = b[keep], z[keep]
    c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
    sx = poses[:, 0:1] + c * sensor_xy[0] - s * sensor_xy[1]
    sy = poses[:, 1:2] + s * sensor_xy[0] + c * sensor_xy[1]
    ux = (c * b[None, :, 0] - s * b[None, :, 1]) / z
    uy = (s * b[None, :, 0] + c * b[None, :, 1]) / z
    cast = cast_ray.py_func
    zs = np.array(
        [
            [cast(occ, ox, oy, inv_res, sx[i, 0], sy[i, 0], ux[i, k], uy[i, k], max_range) for k in range(ux.shape[1])]
            for i in range(ux.shape[0])
        ]
    ).reshape(ux.shape)
    p = z_hit * np.exp(-0.5 * ((z - zs) / sigma) ** 2) / (sigma * np.sqrt(2 * np.pi)) + z_rand / max_range
    p = p + np.where(z < zs, z_short * lam * np.exp(-lam * z), 0.0)
    return np.log(p).sum(axis=1)


@nb.njit(cache=True, parallel=True)
def neighbourhood_masses(
    poses: NDArray[np.float64], weights: NDArray[np.float64], centres: NDArray[np.intp], radius: float, max_dth: float
) -> NDArray[np.float64]:
    """For each particle index in ``centres``: the total weight of the particles within
    ``radius`` m and ``max_dth`` rad of it (the localizer's estimate picks the largest)."""
    out = np.zeros(centres.shape[0])
    r2 = radius * radius
    for j in nb.prange(centres.shape[0]):  # one centre per thread
        cx, cy, ct = poses[centres[j], 0], poses[centres[j], 1], poses[centres[j], 2]
        acc = 0.0
        for i in range(poses.shape[0]):
            dx, dy = poses[i, 0] - cx, poses[i, 1] - cy
            if dx * dx + dy * dy <= r2:
                d = poses[i, 2] - ct  # both within [-pi, pi): d within (-2 pi, 2 pi)
                if d >= np.pi:
                    d -= 2.0 * np.pi
                elif d < -np.pi:
                    d += 2.0 * np.pi
                if abs(d) <= max_dth:
                    acc += weights[i]
        out[j] = acc
    return out


@nb.njit(cache=True)
def scan_fit_kernel(
    dist: NDArray[np.float32],
    occ: NDArray[np.uint8],
    ox: float,
    oy: float,
    inv_res: float,
    pose: Array,
    pts: Array,
    sensor_xy: Array,
    tolerance: float,
) -> tuple[int, int, bool]:
    """A scan's fit to the map at ``pose``: how many end points ``pts`` (N, 2; robot frame) lie
    within ``tolerance`` m of a wall (``dist``, the distance to the nearest occupied cell, m,
    is at most that: explained); how many of the others the ray from the sensor (at
    ``sensor_xy``, robot frame) reaches through an occupied cell of ``occ`` more than
    ``tolerance`` m before the end (contradicted); and whether the sensor itself is off the
    map or inside a wall."""
    h, w = occ.shape
    c, s = np.cos(pose[2]), np.sin(pose[2])
    sx = pose[0] + c * sensor_xy[0] - s * sensor_xy[1]
    sy = pose[1] + s * sensor_xy[0] + c * sensor_xy[1]
    sc, sr = int(np.floor((sx - ox) * inv_res)), int(np.floor((sy - oy) * inv_res))
    blocked = not (0 <= sr < h and 0 <= sc < w) or occ[sr, sc] != 0
    near_tol = dist.dtype.type(tolerance)  # compared in the field's own precision (0.2 m is 4 cells exactly)
    near = 0
    through = 0
    for k in range(pts.shape[0]):
        x = pose[0] + c * pts[k, 0] - s * pts[k, 1]
        y = pose[1] + s * pts[k, 0] + c * pts[k, 1]
        col, row = int(np.floor((x - ox) * inv_res)), int(np.floor((y - oy) * inv_res))
        if 0 <= row < h and 0 <= col < w and dist[row, col] <= near_tol:
            near += 1
            continue
        if blocked:
            continue
        dx, dy = x - sx, y - sy
        length = np.sqrt(dx * dx + dy * dy)
        reach = length - tolerance
        if reach > 0.0 and cast_ray(occ, ox, oy, inv_res, sx, sy, dx / length, dy / length, reach) < reach:
            through += 1
    return near, through, blocked
