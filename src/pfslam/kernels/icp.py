"""Point-to-line matching of a scan against a local map's surface (the loop search's
refinement): the map's hits reduced to one sample per fine cell with the normal of the wall
through it (:func:`surface_kernel`), a lookup grid of each cell's nearest sample, and
Gauss-Newton on the points' distances along those normals under a Huber weight
(:func:`icp_kernel`), which also gives the match's information matrix (J^T W J).

A point on a wall measures the pose across the wall and nothing along it: the information
matrix says which directions the match pins (along a bare corridor it is about nil), which is
what the back end's graph and its checks need to know of a loop. The residual is the exact
distance of each point to a line through a measured hit, not to a cell centre: no grid
quantisation biases the match.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from pfslam.kernels.solve3 import solve3
from pfslam.types import Array


@nb.njit(cache=True, inline="always")
def wall_normal(sxx: float, syy: float, sxy: float, flatness: float, out: Array) -> bool:
    """Whether points whose scatter about their mean is ``sxx``, ``syy``, ``sxy`` lie on a wall
    (their spread across under ``flatness`` times along), and if so its unit normal into
    ``out`` (2,): across the direction of the larger spread."""
    tr = sxx + syy
    det = sxx * syy - sxy * sxy
    gap = math.sqrt(max(tr * tr / 4.0 - det, 0.0))
    lo = tr / 2.0 - gap
    hi = tr / 2.0 + gap
    if hi <= 0.0 or lo > flatness * flatness * hi:
        return False
    a = 0.5 * math.atan2(2.0 * sxy, sxx - syy)  # the direction of the larger spread
    out[0] = -math.sin(a)
    out[1] = math.cos(a)
    return True


@nb.njit(cache=True, nogil=True)
def surface_kernel(
    points: Array, cell: float, normal_radius: float, reach: float, flatness: float
) -> tuple[Array, Array, NDArray[np.bool_], NDArray[np.int32], float, float]:
    """The surface of ``points`` ((N, 2), one frame): one sample per ``cell``-wide cell (the mean
    of its points), each sample's unit normal fitted to the samples within ``normal_radius``
    (``flat``: at least three of them, their spread across under ``flatness`` times along),
    and the lookup grid: for each cell within ``reach`` of a sample, the index of the nearest
    flat sample (-1: none). Returns (samples (M, 2), normals (M, 2), flat (M,), lookup (H, W),
    ox, oy), the lookup's lower-left corner at (ox, oy)."""
    n = points.shape[0]
    if n == 0:
        return (
            np.zeros((0, 2)),
            np.zeros((0, 2)),
            np.zeros(0, dtype=np.bool_),
            np.full((1, 1), -1, dtype=np.int32),
            0.0,
            0.0,
        )
    pad = int(math.ceil(max(reach, 2 * normal_radius) / cell)) + 1
    x0 = points[:, 0].min() - pad * cell
    y0 = points[:, 1].min() - pad * cell
    w = int((points[:, 0].max() - x0) / cell) + pad + 2
    h = int((points[:, 1].max() - y0) / cell) + pad + 2
    # one sample per cell: the mean of the points in it
    owner = np.full((h, w), -1, dtype=np.int32)
    sx = np.zeros(n)
    sy = np.zeros(n)
    cnt = np.zeros(n)
    m = 0
    for k in range(n):
        c = int((points[k, 0] - x0) / cell)
        r = int((points[k, 1] - y0) / cell)
        j = owner[r, c]
        if j < 0:
            j = m
            owner[r, c] = j
            m += 1
        sx[j] += points[k, 0]
        sy[j] += points[k, 1]
        cnt[j] += 1.0
    samples = np.empty((m, 2))
    for j in range(m):
        samples[j, 0] = sx[j] / cnt[j]
        samples[j, 1] = sy[j] / cnt[j]
    # each sample's normal from its neighbours' scatter: within ``normal_radius``, or twice as
    # far where fewer than five samples are that close (a sparse scan's far walls)
    normals = np.zeros((m, 2))
    flat = np.zeros(m, dtype=np.bool_)
    for j in range(m):
        px, py = samples[j, 0], samples[j, 1]
        c0 = int((px - x0) / cell)
        r0 = int((py - y0) / cell)
        for wide in range(2):
            radius = normal_radius * (1 + wide)
            rad = int(math.ceil(radius / cell))
            r2 = radius * radius
            k = 0
            mx = 0.0
            my = 0.0
            for r in range(max(r0 - rad, 0), min(r0 + rad + 1, owner.shape[0])):
                for c in range(max(c0 - rad, 0), min(c0 + rad + 1, owner.shape[1])):
                    i = owner[r, c]
                    if i >= 0:
                        dx = samples[i, 0] - px
                        dy = samples[i, 1] - py
                        if dx * dx + dy * dy <= r2:
                            mx += samples[i, 0]
                            my += samples[i, 1]
                            k += 1
            if k >= 5:
                break
        if k < 3:
            continue
        mx /= k
        my /= k
        sxx = 0.0
        syy = 0.0
        sxy = 0.0
        for r in range(max(r0 - rad, 0), min(r0 + rad + 1, owner.shape[0])):
            for c in range(max(c0 - rad, 0), min(c0 + rad + 1, owner.shape[1])):
                i = owner[r, c]
                if i >= 0:
                    dx = samples[i, 0] - px
                    dy = samples[i, 1] - py
                    if dx * dx + dy * dy <= r2:
                        ex = samples[i, 0] - mx
                        ey = samples[i, 1] - my
                        sxx += ex * ex
                        syy += ey * ey
                        sxy += ex * ey
        flat[j] = wall_normal(sxx, syy, sxy, flatness, normals[j])
    # the lookup: each cell near a flat sample holds the nearest one
    lookup = np.full((h, w), -1, dtype=np.int32)
    best = np.full((h, w), np.inf)
    rr = int(math.ceil(reach / cell))
    for j in range(m):
        if not flat[j]:
            continue
        px, py = samples[j, 0], samples[j, 1]
        c0 = int((px - x0) / cell)
        r0 = int((py - y0) / cell)
        for r in range(max(r0 - rr, 0), min(r0 + rr + 1, h)):
            cy = y0 + (r + 0.5) * cell - py
            for c in range(max(c0 - rr, 0), min(c0 + rr + 1, w)):
                cx = x0 + (c + 0.5) * cell - px
                d = cx * cx + cy * cy
                if d < best[r, c]:
                    best[r, c] = d
                    lookup[r, c] = j
    return samples, normals, flat, lookup, x0, y0


@nb.njit(cache=True, nogil=True)
def icp_kernel(
    samples: Array,
    normals: Array,
    lookup: NDArray[np.int32],
    ox: float,
    oy: float,
    cell: float,
    pts: Array,
    pose: Array,
    max_dist: float,
    huber: float,
    iterations: int,
    prior: Array,
    prior_weight: Array,
    tangent: float,
) -> tuple[Array, Array, float, int]:
    """Point-to-line Gauss-Newton of ``pts`` ((N, 2), robot frame) from ``pose`` against a
    surface (:func:`surface_kernel`): each point paired with the sample its cell looks up
    (within ``max_dist`` of it), its residual the distance along the sample's normal, weighed
    by a Huber weight of scale ``huber`` (a point more than ``tangent`` from the sample along the
    wall is past its end: not paired), plus a prior at ``prior`` (x, y, theta) of information
    ``prior_weight`` (3 x 3, in the units of one point's squared residual: where the points
    pin nothing, along a corridor, the pose stays at the prior's). Returns (pose, J^T W J of
    the points alone at the last pairing (3 x 3: x, y, theta, in the map's frame), the
    weighted mean square residual, points paired)."""
    h, w = lookup.shape
    p = pose.copy()
    hess = np.zeros((3, 3))
    mse = 0.0
    used = 0
    gate = max_dist  # residuals beyond this are not a pair (a wall's end paired across a corner)
    for _ in range(iterations):
        c, s = math.cos(p[2]), math.sin(p[2])
        hess[:, :] = 0.0
        g = np.zeros(3)
        wsum = 0.0
        rsum = 0.0
        used = 0
        for k in range(pts.shape[0]):
            qx = p[0] + c * pts[k, 0] - s * pts[k, 1]
            qy = p[1] + s * pts[k, 0] + c * pts[k, 1]
            col = int(math.floor((qx - ox) / cell))
            row = int(math.floor((qy - oy) / cell))
            if col < 0 or row < 0 or col >= w or row >= h:
                continue
            j = lookup[row, col]
            if j < 0:
                continue
            dx = qx - samples[j, 0]
            dy = qy - samples[j, 1]
            d2 = dx * dx + dy * dy
            if d2 > max_dist * max_dist:
                continue
            nx, ny = normals[j, 0], normals[j, 1]
            e = nx * dx + ny * dy
            ae = abs(e)
            if ae > gate or d2 - e * e > tangent * tangent:
                continue  # off the wall across, or past its end along it
            wt = 1.0 if ae <= huber else huber / ae
            # d(q)/d(theta) = (-(s px + c py), c px - s py)
            j2 = nx * (-(s * pts[k, 0] + c * pts[k, 1])) + ny * (c * pts[k, 0] - s * pts[k, 1])
            jac0, jac1 = nx, ny
            hess[0, 0] += wt * jac0 * jac0
            hess[0, 1] += wt * jac0 * jac1
            hess[0, 2] += wt * jac0 * j2
            hess[1, 1] += wt * jac1 * jac1
            hess[1, 2] += wt * jac1 * j2
            hess[2, 2] += wt * j2 * j2
            g[0] += wt * jac0 * e
            g[1] += wt * jac1 * e
            g[2] += wt * j2 * e
            wsum += wt
            rsum += wt * e * e
            used += 1
        hess[1, 0] = hess[0, 1]
        hess[2, 0] = hess[0, 2]
        hess[2, 1] = hess[1, 2]
        mse = rsum / wsum if wsum > 0 else 0.0
        if used < 3:
            break
        gate = max(3.0 * math.sqrt(mse), 2.0 * huber)
        damped = hess + prior_weight
        dp = p - prior
        dp[2] = math.atan2(math.sin(dp[2]), math.cos(dp[2]))
        for a in range(3):
            damped[a, a] += 1e-9
            for b in range(3):
                g[a] += prior_weight[a, b] * dp[b]
        step = solve3(damped, -g)
        p[0] += step[0]
        p[1] += step[1]
        p[2] += step[2]
        if abs(step[0]) < 1e-5 and abs(step[1]) < 1e-5 and abs(step[2]) < 1e-6:
            break
    return p, hess, mse, used


@nb.njit(cache=True, nogil=True)
def sequence_normals_kernel(
    points: Array, radius: float, flatness: float, window: int
) -> tuple[Array, NDArray[np.bool_]]:
    """Each of ``points``' (N, 2) unit normal fitted to the points within ``radius`` of it among
    the ``window`` before and after it in their order (a scan's hits, in the order its beams
    swept: a wall's hits are neighbours), or within twice the radius where fewer than five
    are, and whether the fit is a wall (at least five points, their spread across under
    ``flatness`` times along). No grid: for what a scan pins of its pose, where nothing is
    looked up."""
    n = points.shape[0]
    normals = np.zeros((n, 2))
    flat = np.zeros(n, dtype=np.bool_)
    for j in range(n):
        px, py = points[j, 0], points[j, 1]
        lo, hi = max(j - window, 0), min(j + window + 1, n)
        # five points within the radius, or within twice it (a far wall's hits are sparse)
        r2 = radius * radius
        k = 0
        mx = 0.0
        my = 0.0
        for attempt in range(2):
            r2 = radius * radius * (1 + 3 * attempt)
            k = 0
            mx = 0.0
            my = 0.0
            for i in range(lo, hi):
                dx = points[i, 0] - px
                dy = points[i, 1] - py
                if dx * dx + dy * dy <= r2:
                    mx += points[i, 0]
                    my += points[i, 1]
                    k += 1
            if k >= 5:
                break
        if k < 5:
            continue
        mx /= k
        my /= k
        sxx = 0.0
        syy = 0.0
        sxy = 0.0
        for i in range(lo, hi):
            dx = points[i, 0] - px
            dy = points[i, 1] - py
            if dx * dx + dy * dy <= r2:
                ex = points[i, 0] - mx
                ey = points[i, 1] - my
                sxx += ex * ex
                syy += ey * ey
                sxy += ex * ey
        flat[j] = wall_normal(sxx, syy, sxy, flatness, normals[j])
    return normals, flat
