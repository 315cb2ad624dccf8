"""How well a scan fits one particle's map of tiles (:mod:`pfslam.maps.tiled`): the counts the
SLAM health is made of (:mod:`pfslam.filters.health`). Read-only: no tile is taken or written."""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

from pfslam.types import Array


@nb.njit(cache=True, inline="always")
def _cell(table, pool, shift: int, th: int, tw: int, r: int, c: int) -> float:
    """The log-odds of cell (r, c) of the map ``table`` (0 off the grid or never written)."""
    if r < 0 or c < 0 or (r >> shift) >= th or (c >> shift) >= tw:
        return 0.0
    idx = table[r >> shift, c >> shift]
    if idx < 0:
        return 0.0
    m = (1 << shift) - 1
    return pool[idx, r & m, c & m]


@nb.njit(cache=True)
def tiled_fit_kernel(
    table: NDArray[np.int32],
    pool: NDArray[np.float32],
    shift: int,
    pose: Array,
    sensor: Array,
    ends: Array,
    hit: NDArray[np.bool_],
    ox: float,
    oy: float,
    inv_res: float,
    tol: int,
    wall: float,
) -> tuple[int, int, int]:
    """How one map (``table``) judges a scan seen at ``pose``: ``ends`` (robot frame) the beams'
    end points from the ``sensor`` (robot frame), ``hit`` whether each ended on something (a
    beam that returned nothing ends where its free space is taken to end). Returns the counts
    (judged, explained, contradicted):

    * explained: a hit with a cell above 0 within ``tol`` cells (a mapped wall where it ended);
    * contradicted: a beam not explained whose path, up to ``tol`` cells short of its end,
      crosses a cell at ``wall`` or above (a wall the map is sure of, seen through);
    * judged: those two, and the hits that end in a cell the map holds free: the beams the map
      can say something of. A hit in a cell never seen, crossing no wall, is new ground."""
    th, tw = table.shape[0], table.shape[1]
    c, s = np.cos(pose[2]), np.sin(pose[2])
    sx = (pose[0] + c * sensor[0] - s * sensor[1] - ox) * inv_res
    sy = (pose[1] + s * sensor[0] + c * sensor[1] - oy) * inv_res
    judged = explained = contradicted = 0
    for k in range(ends.shape[0]):
        ex = (pose[0] + c * ends[k, 0] - s * ends[k, 1] - ox) * inv_res
        ey = (pose[1] + s * ends[k, 0] + c * ends[k, 1] - oy) * inv_res
        r0, c0 = int(np.floor(ey)), int(np.floor(ex))
        if hit[k]:
            near = False
            for r in range(r0 - tol, r0 + tol + 1):
                for cc in range(c0 - tol, c0 + tol + 1):
                    if _cell(table, pool, shift, th, tw, r, cc) > 0.0:
                        near = True
                        break
                if near:
                    break
            if near:
                judged += 1
                explained += 1
                continue
        # the beam's path, in half-cell steps, up to tol cells short of its end
        dx, dy = ex - sx, ey - sy
        length = np.sqrt(dx * dx + dy * dy)
        steps = int(2.0 * (length - tol))
        crossed = False
        if steps > 0:
            ux, uy = 0.5 * dx / length, 0.5 * dy / length
            for j in range(steps):
                px, py = sx + j * ux, sy + j * uy
                if _cell(table, pool, shift, th, tw, int(np.floor(py)), int(np.floor(px))) >= wall:
                    crossed = True
                    break
        if crossed:
            judged += 1
            contradicted += 1
        elif hit[k] and _cell(table, pool, shift, th, tw, r0, c0) < 0.0:
            judged += 1
    return judged, explained, contradicted


@nb.njit(cache=True, parallel=True)
def tiled_seen_through_kernel(
    tables: NDArray[np.int32],
    pool: NDArray[np.float32],
    shift: int,
    poses: Array,
    sensor: Array,
    ends: Array,
    ox: float,
    oy: float,
    inv_res: float,
    tol: int,
    wall: float,
) -> NDArray[np.int64]:
    """Per map ``i`` (``tables[i]``, the scan seen at ``poses[i]``): how many beams cross, up
    to ``tol`` cells short of their ends, a cell at ``wall`` or above (:func:`tiled_fit_kernel`'s
    contradicted count with every beam taken as one that hit nothing), the maps in parallel."""
    n = tables.shape[0]
    out = np.zeros(n, dtype=np.int64)
    none = np.zeros(ends.shape[0], dtype=np.bool_)
    for i in nb.prange(n):
        out[i] = tiled_fit_kernel(tables[i], pool, shift, poses[i], sensor, ends, none, ox, oy, inv_res, tol, wall)[2]
    return out
