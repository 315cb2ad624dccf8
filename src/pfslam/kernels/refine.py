"""A particle's match refined on a smooth score, and what the scan pins (issue 44).

The hill climb of :func:`~pfslam.kernels.tiled.tiled_match_kernel` scores a hit by its
distance to the nearest occupied cell centre: a field of bumps at cell centres, with no
gradient along a wall. Here each hit is read against the wall its 3 x 3 neighbourhood shows
(the occupancy mask the near cache already holds): where the occupied cells of the mask lie
on a line, the hit's residual is its distance across that line (point to line); where they
do not (a corner, a post, one cell), its offset from the nearest occupied centre (point to
point). The score is then smooth along a wall and flat where the walls say nothing, so
Gauss-Newton steps converge within a cell in two or three iterations, and the normal
equations at the optimum are the scan's information: ``Σ w Jᵀ J`` in m and rad, large across
walls, zero along a bare corridor. Every hit is weighed ``w = exp(-d² / 2 sigma²)`` (its
match score), so the sum is the hill climb's score to second order.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from pfslam.kernels.icp import wall_normal
from pfslam.kernels.solve3 import solve3
from pfslam.kernels.tiled import cached_mask, scan_setup
from pfslam.types import Array

_LINE_FLATNESS = 0.65  # a mask's cells are on a line when their spread across is under this times along


SKIP, LINE, POINT = 0, 1, 2  # how a hit is read against its mask


def _mask_geometry() -> tuple[NDArray[np.int64], Array]:
    """Per 3 x 3 occupancy mask (bit 3 (dr + 1) + (dc + 1)): how a hit is read against it
    (LINE: two or more occupied cells on a line; POINT: one alone (a post, a chair's leg, or
    the end of a wall mapped as far as the laser reached) or several off a line (a corner);
    SKIP: none), and a line's centroid offset (dc, dr) and unit normal (nx, ny) in cells
    (x along columns, y along rows)."""
    line = np.zeros(512, dtype=np.int64)
    geo = np.zeros((512, 4))
    normal = np.zeros(2)
    for mask in range(512):
        cells = [(b % 3 - 1, b // 3 - 1) for b in range(9) if mask >> b & 1]
        if not cells:
            continue
        line[mask] = POINT
        if len(cells) < 2:
            continue
        xy = np.array(cells, dtype=float)
        mx, my = xy.mean(axis=0)
        d = xy - (mx, my)
        if wall_normal(
            float(d[:, 0] @ d[:, 0]), float(d[:, 1] @ d[:, 1]), float(d[:, 0] @ d[:, 1]), _LINE_FLATNESS, normal
        ):
            line[mask] = LINE
            geo[mask] = (mx, my, normal[0], normal[1])
    return line, geo


_MASK_KIND, _MASK_GEO = _mask_geometry()


@nb.njit(cache=True, inline="always")
def _mask_at(table, pool, near, shift: int, th: int, tw: int, r0: int, c0: int) -> int:
    """The 3 x 3 occupancy mask (log-odds above 0) around cell (r0, c0): from the near cache
    where the neighbourhood lies in one tile, else read cell by cell. (Numba compiles
    :func:`~pfslam.kernels.tiled.cached_mask` into the kernels here and caches them by this
    file's date alone: a change to the near cache's layout must touch this file too, or the
    cached kernels read the old layout (as the stale flags did, moved out of the tiles, then
    spread one to a cache line).)"""
    m = (1 << shift) - 1
    tr, tc = (r0 - 1) >> shift, (c0 - 1) >> shift
    if r0 >= 1 and c0 >= 1 and (r0 + 1) >> shift == tr and (c0 + 1) >> shift == tc and tr < th and tc < tw:
        idx = table[tr, tc]
        if idx < 0:
            return 0
        return int(cached_mask(pool, near, idx, r0, c0, shift))
    mask = 0
    for b in range(9):
        r, c = r0 + b // 3 - 1, c0 + b % 3 - 1
        if r < 0 or c < 0 or (r >> shift) >= th or (c >> shift) >= tw:
            continue
        idx = table[r >> shift, c >> shift]
        if idx >= 0 and pool[idx, r & m, c & m] > 0.0:
            mask |= 1 << b
    return mask


@nb.njit(cache=True)
def _normal_equations(
    table,
    pool,
    near,
    shift: int,
    x: float,
    y: float,
    t: float,
    xs,
    ys,
    ox: float,
    oy: float,
    res: float,
    inv2s2: float,
    h,
    g,
) -> float:
    """Fill ``h`` (3, 3) and ``g`` (3,) with ``Σ w Jᵀ J`` and ``Σ w r Jᵀ`` of the hits at pose
    (x, y, t), r in metres and J per m and rad (see the module notes); returns the score
    ``Σ w``. ``inv2s2``: 1 / (2 sigma²) in cells²."""
    th, tw = table.shape
    inv_res = 1.0 / res
    c = math.cos(t)
    s = math.sin(t)
    h[:] = 0.0
    g[:] = 0.0
    score = 0.0
    for k in range(xs.shape[0]):
        rx = c * xs[k] - s * ys[k]  # the hit relative to the robot, world axes
        ry = s * xs[k] + c * ys[k]
        fx = (x + rx - ox) * inv_res
        fy = (y + ry - oy) * inv_res
        r0 = int(math.floor(fy))
        c0 = int(math.floor(fx))
        mask = _mask_at(table, pool, near, shift, th, tw, r0, c0)
        kind = _MASK_KIND[mask]
        if kind == SKIP:
            continue
        if kind == LINE:
            qx = c0 + 0.5 + _MASK_GEO[mask, 0]
            qy = r0 + 0.5 + _MASK_GEO[mask, 1]
            nx, ny = _MASK_GEO[mask, 2], _MASK_GEO[mask, 3]
            rr = nx * (fx - qx) + ny * (fy - qy)  # cells
            w = math.exp(-rr * rr * inv2s2)
            jt = -nx * ry + ny * rx  # d(residual)/d(theta), m
            r_m = rr * res
            score += w
            h[0, 0] += w * nx * nx
            h[0, 1] += w * nx * ny
            h[1, 1] += w * ny * ny
            h[0, 2] += w * nx * jt
            h[1, 2] += w * ny * jt
            h[2, 2] += w * jt * jt
            g[0] += w * r_m * nx
            g[1] += w * r_m * ny
            g[2] += w * r_m * jt
        else:  # the nearest occupied centre, point to point
            best, bx, by = 1e30, 0.0, 0.0
            for b in range(9):
                if mask >> b & 1:
                    dx = c0 + b % 3 - 1 + 0.5 - fx
                    dy = r0 + b // 3 - 1 + 0.5 - fy
                    d = dx * dx + dy * dy
                    if d < best:
                        best, bx, by = d, dx, dy
            w = math.exp(-best * inv2s2)
            score += w
            # residuals fx - qx = -bx (x) and -by (y), in m
            ex, ey = -bx * res, -by * res
            h[0, 0] += w
            h[1, 1] += w
            h[0, 2] += w * -ry
            h[1, 2] += w * rx
            h[2, 2] += w * (rx * rx + ry * ry)
            g[0] += w * ex
            g[1] += w * ey
            g[2] += w * (-ry * ex + rx * ey)
    h[1, 0] = h[0, 1]
    h[2, 0] = h[0, 2]
    h[2, 1] = h[1, 2]
    return score


@nb.njit(cache=True, inline="always")
def _objective(score: float, pw, x: float, y: float, t: float, prior) -> float:
    """The score less the motion prior's cost (weights ``pw`` per x, y, theta) at (x, y, t)."""
    return score - 0.5 * (pw[0] * ((x - prior[0]) ** 2 + (y - prior[1]) ** 2) + pw[2] * (t - prior[2]) ** 2)


@nb.njit(cache=True, parallel=True)
def tiled_refine_kernel(
    tables: NDArray[np.int32],
    pool: NDArray[np.float32],
    near: NDArray[np.uint16],
    shift: int,
    poses: Array,
    pts: Array,
    ox: float,
    oy: float,
    res: float,
    sigma: float,
    iterations: int,
    prior: Array,
    prior_w: float,
    prior_xy: float,
    prior_th: float,
    max_step: float,
    max_turn: float,
) -> tuple[Array, Array]:
    """Refine every particle's pose (``poses``, in place) by Gauss-Newton steps on the
    smooth score (see the module notes) against its own map, at most ``iterations``; with
    ``prior_w`` > 0 the motion prior of :func:`~pfslam.kernels.tiled.tiled_match_kernel`
    about ``prior`` (n, 3) is added. A step is at most ``max_step`` m and ``max_turn`` rad,
    and one that lowers the objective is not taken. Returns each particle's score (Σ w) and
    information ``Σ w Jᵀ J`` (n, 3, 3, per m² and rad², not yet divided by a variance) at its
    final pose."""
    n = poses.shape[0]
    _, inv2s2, xs, ys = scan_setup(pts, res, sigma)
    inv_s2 = 1.0 / (sigma * sigma)
    scores = np.zeros(n)
    infos = np.zeros((n, 3, 3))
    pw = np.zeros(3)
    if prior_w > 0.0:
        pw[0] = prior_w / (prior_xy * prior_xy)
        pw[1] = pw[0]
        pw[2] = prior_w / (prior_th * prior_th)
    for i in nb.prange(n):
        table = tables[i]
        h = np.zeros((3, 3))
        g = np.zeros(3)
        a = np.zeros((3, 3))
        b = np.zeros(3)
        h2 = np.zeros((3, 3))  # the normal equations at a step's end
        g2 = np.zeros(3)
        x, y, t = poses[i, 0], poses[i, 1], poses[i, 2]
        score = _normal_equations(table, pool, near, shift, x, y, t, xs, ys, ox, oy, res, inv2s2, h, g)
        obj = _objective(score, pw, x, y, t, prior[i])
        for _ in range(iterations):
            for j in range(3):
                for k in range(3):
                    a[j, k] = h[j, k] * inv_s2
                b[j] = -g[j] * inv_s2
            dev = (x - prior[i, 0], y - prior[i, 1], t - prior[i, 2])
            for j in range(3):
                a[j, j] += pw[j] + 1e-9 + 1e-3 * a[j, j]  # the prior, and a little damping
                b[j] -= pw[j] * dev[j]
            step = solve3(a, b)
            k_xy = math.hypot(step[0], step[1]) / max_step
            k_t = abs(step[2]) / max_turn
            k = max(1.0, k_xy, k_t)
            nx, ny, nt = x + step[0] / k, y + step[1] / k, t + step[2] / k
            s2 = _normal_equations(table, pool, near, shift, nx, ny, nt, xs, ys, ox, oy, res, inv2s2, h2, g2)
            o2 = _objective(s2, pw, nx, ny, nt, prior[i])
            if o2 < obj:
                break
            x, y, t, score, obj = nx, ny, nt, s2, o2
            h[:] = h2
            g[:] = g2
            if abs(step[0] / k) + abs(step[1] / k) < 1e-4 and abs(step[2] / k) < 1e-4:
                break
        poses[i, 0], poses[i, 1], poses[i, 2] = x, y, t
        scores[i] = score
        infos[i] = h
    return scores, infos
