"""How sure an edge is, from the scans themselves: the information a node's scan gives about
its own pose (where its walls run, which way they face), and from it the sequential and loop
edges' information matrices.

A wall seen by the scan pins the pose across the wall, not along it: a hit at ``p`` (robot
frame) on a wall of normal ``n`` measures ``n . (dx, dy) + (p x n) dtheta`` of a small
motion (dx, dy, dtheta) in the robot's frame. Summed over the hits, ``J J^T / sigma^2`` is the
information a scan match has; in a corridor it is large across and about nil along, and
the graph's edges say so: a loop there does not pull along the corridor, and a correction is
put where the front end knew least."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pfslam.config import GraphConfig
from pfslam.types import Array

NEIGHBOURS = 6  # points a normal is fitted to (the point itself and its nearest)
NORMAL_RADIUS = 0.3  # m: neighbours farther than this are not on the same wall
FLATNESS = 0.1  # a normal is kept where the neighbours' spread across it is under this ratio of along
WEAK_M = 5.0  # m: the standard deviation that stands for 'no information' in position ...
WEAK_DEG = 45.0  # ... and in heading (keeps the graph's matrices well conditioned)


def normals(points: NDArray[np.floating], at: NDArray[np.floating] | None = None) -> tuple[Array, NDArray[np.bool_]]:
    """The wall normal (unit, (N, 2)) at each of ``at`` (default: ``points``) fitted to its
    nearest neighbours among ``points``, and whether the fit is a wall (at least three points
    within :data:`NORMAL_RADIUS`, spread along a line)."""
    from scipy.spatial import cKDTree

    p = np.asarray(points, dtype=float).reshape(-1, 2)
    q = p if at is None else np.asarray(at, dtype=float).reshape(-1, 2)
    n = len(q)
    out = np.zeros((n, 2))
    if len(p) < 3 or n == 0:
        return out, np.zeros(n, dtype=bool)
    k = min(NEIGHBOURS, len(p))
    dist, idx = cKDTree(p).query(q, k=k, distance_upper_bound=NORMAL_RADIUS)
    valid = np.isfinite(dist)
    idx = np.where(valid, idx, 0)
    nb = p[idx]  # (N, k, 2)
    w = valid.astype(float)
    count = w.sum(axis=1)
    mean = (nb * w[..., None]).sum(axis=1) / np.maximum(count, 1)[:, None]
    d = (nb - mean[:, None, :]) * w[..., None]
    sxx = (d[..., 0] ** 2).sum(axis=1)
    syy = (d[..., 1] ** 2).sum(axis=1)
    sxy = (d[..., 0] * d[..., 1]).sum(axis=1)
    # The 2 x 2 scatter's eigenvalues; the normal is the eigenvector of the smaller one.
    tr, det = sxx + syy, sxx * syy - sxy**2
    gap = np.sqrt(np.maximum(tr**2 / 4 - det, 0.0))
    lo, hi = tr / 2 - gap, tr / 2 + gap
    angle = 0.5 * np.arctan2(2 * sxy, sxx - syy)  # direction of the larger spread (the wall)
    out[:, 0], out[:, 1] = -np.sin(angle), np.cos(angle)
    ok = (count >= 3) & (hi > 0) & (lo <= FLATNESS**2 * hi)
    return out, ok


def scan_information(
    points: NDArray[np.floating], sigma: float, effective: int, at: NDArray[np.floating] | None = None
) -> Array:
    """The information (3 x 3, robot frame: x, y, theta) that matching ``points`` (robot frame)
    to a map of their walls gives about the robot's pose: ``J J^T / sigma^2`` over the points on
    a wall (``at``: those of ``points`` to sum over, default all), scaled down to ``effective``
    independent points (neighbouring hits of one wall do not err independently)."""
    p = np.asarray(points if at is None else at, dtype=float).reshape(-1, 2)
    nrm, ok = normals(points, at)
    if not ok.any():
        return np.zeros((3, 3))
    p, nrm = p[ok], nrm[ok]
    jac = np.column_stack([nrm[:, 0], nrm[:, 1], p[:, 0] * nrm[:, 1] - p[:, 1] * nrm[:, 0]])
    scale = min(1.0, effective / len(p)) / sigma**2
    return np.asarray(scale * (jac.T @ jac), dtype=np.float64)


def _weak() -> Array:
    return np.diag([WEAK_M**-2, WEAK_M**-2, np.deg2rad(WEAK_DEG) ** -2])


def sequential_information(scan_info: Array, step: Array, c: GraphConfig) -> Array:
    """The information matrices (K, 3, 3) of the edges between consecutive nodes (the front
    end's relative poses ``step``, (K, 3)): as sure as the ``node_sigma_*`` settings say
    (growing with the distance) where the later node's scan pins the pose (``scan_info``,
    (K, 3, 3)), and up to ``loose_along`` times less sure in the directions it does not pin
    (along a bare corridor, where the front end had only the odometry), so that a loop's
    correction goes where the front end knew least. Never surer than the settings: a front
    end can slip even where its scan pinned it, and the graph must be able to undo that."""
    d = np.hypot(step[:, 0], step[:, 1])
    sxy = c.node_sigma_m + c.node_sigma_per_m * d
    sth = np.deg2rad(c.node_sigma_deg + c.node_sigma_deg_per_m * d)
    base = np.zeros((len(d), 3, 3))
    base[:, 0, 0] = base[:, 1, 1] = sxy**2
    base[:, 2, 2] = sth**2
    # What the scan leaves open, at most (loose_along^2 - 1) times the base variance in any
    # direction: about nothing across a corridor, all of it along.
    room = c.loose_along**2 - 1.0
    cov = base
    if room > 0:
        cap = np.zeros_like(base)
        cap[:, [0, 1, 2], [0, 1, 2]] = 1.0 / (room * np.diagonal(base, axis1=1, axis2=2))
        cov = base + np.linalg.inv(scan_info + cap)
    return np.asarray(np.linalg.inv(cov), dtype=np.float64)


def loop_information(scan_info: Array, c: GraphConfig) -> Array:
    """The information matrices (K, 3, 3) of loop edges: what the node's scan pins
    (``scan_info``, (K, 3, 3)), never surer than ``loop_sigma_m`` / ``loop_sigma_deg`` in any
    direction, and nothing where the scan pins nothing (along a bare corridor)."""
    cov = np.linalg.inv(scan_info + _weak())
    cov += np.diag([c.loop_sigma_m**2, c.loop_sigma_m**2, np.deg2rad(c.loop_sigma_deg) ** 2])
    return np.asarray(np.linalg.inv(cov), dtype=np.float64)
