"""Walls as dense points: what a perfect scan of a few segments would hit, for tests of scan
matching on a known surface; and whether walls cross (for the tests of generated worlds)."""

from __future__ import annotations

import numpy as np


def walls(segments: list[tuple[float, float, float, float]], step: float = 0.01) -> np.ndarray:
    """Points every ``step`` (m) along each segment ``(x0, y0, x1, y1)``, both ends included, (N, 2)."""
    out = []
    for x0, y0, x1, y1 in segments:
        n = max(2, int(np.hypot(x1 - x0, y1 - y0) / step))
        a = np.linspace(0.0, 1.0, n)
        out.append(np.column_stack([x0 + a * (x1 - x0), y0 + a * (y1 - y0)]))
    return np.vstack(out)


def submap_of(world: np.ndarray, res: float, sigma: float, depth: int) -> object:
    """A back-end submap (score field, pyramid, surface) of the wall points ``world`` ((N, 2),
    in the frame of its first node, at the origin), on a grid of ``res`` with a metre of margin."""
    from pfslam.backend.submaps import field_of

    cells = np.floor(world / res).astype(np.int64)
    origin = cells.min(axis=0) * res - 1.0
    occ = np.zeros(tuple((cells.max(axis=0) - cells.min(axis=0) + 41)[::-1]), dtype=bool)
    rc = np.floor((world - origin) / res).astype(np.int64)
    occ[rc[:, 1], rc[:, 0]] = True
    sub = field_of(occ, origin, res, sigma, depth, world)
    assert sub is not None
    return sub


def crossing(segs: np.ndarray) -> bool:
    """Whether two of the wall segments ``segs`` ((K, 4): x0 y0 x1 y1) cross, each through the
    other's inside (a T where one ends on the other is not a crossing)."""
    a0, a1 = segs[:, None, :2], segs[:, None, 2:]
    b0, b1 = segs[None, :, :2], segs[None, :, 2:]

    def side(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
        v = (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])
        return np.sign(np.where(np.abs(v) < 1e-9, 0.0, v))

    return bool(np.any((side(a0, a1, b0) * side(a0, a1, b1) < 0) & (side(b0, b1, a0) * side(b0, b1, a1) < 0)))


def point_distances(pts: np.ndarray, segs: np.ndarray) -> np.ndarray:
    """(N,) the distance from each of ``pts`` ((N, 2)) to the nearest of the segments ``segs``."""
    a, b = segs[None, :, :2], segs[None, :, 2:]
    e = b - a
    p = pts[:, None, :]
    u = np.clip(np.sum((p - a) * e, axis=2) / np.maximum(np.sum(e * e, axis=2), 1e-12), 0.0, 1.0)
    return np.min(np.linalg.norm(p - (a + u[..., None] * e), axis=2), axis=1)
