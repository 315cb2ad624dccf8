"""Kernels on tiled, copy-on-write maps (one map per particle, see :mod:`pfslam.tiled`):
the ray update of one particle's map and the correlation score of every particle against
its own map. They read the tile table inline (no per-cell helper call); their NumPy twins
are the dense kernels run on each particle's map made dense (:meth:`TiledMaps.dense`).

A map is a table ``(TH, TW)`` of tile numbers (-1: a tile never written, all zero) into a
shared ``pool`` of ``(T, T)`` float32 tiles, ``T = 1 << shift``. A tile shared by several
particles (``refs > 1``) is copied before it is written; a fresh one is taken from the
``free`` stack (``nfree[0]`` entries) and zeroed.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

from pfslam.kernels.project import frame32, points32, project
from pfslam.kernels.raycast import axis_setup

Array = NDArray[np.float64]


@nb.njit(cache=True, inline="always")
def _own_tile(table, pool, refs, free, nfree, tr: int, tc: int) -> int:
    """The tile at (tr, tc) of this table, made this table's own (fresh or copied)."""
    idx = table[tr, tc]
    if idx >= 0 and refs[idx] == 1:
        return idx
    nfree[0] -= 1
    new = free[nfree[0]]
    if idx < 0:
        pool[new] = 0.0
    else:
        pool[new] = pool[idx]
        refs[idx] -= 1
    refs[new] = 1
    table[tr, tc] = new
    return new


@nb.njit(cache=True, inline="always")
def _add(table, pool, refs, free, nfree, shift: int, r: int, c: int, v: float, clamp: float) -> None:
    th, tw = table.shape
    tr, tc = r >> shift, c >> shift
    if r < 0 or c < 0 or tr >= th or tc >= tw:
        return
    idx = _own_tile(table, pool, refs, free, nfree, tr, tc)
    m = (1 << shift) - 1
    x = pool[idx, r & m, c & m] + v
    pool[idx, r & m, c & m] = max(-clamp, min(clamp, x))


@nb.njit(cache=True)
def tiled_ray_update_kernel(
    table: NDArray[np.int32],
    pool: NDArray[np.float32],
    refs: NDArray[np.int32],
    free: NDArray[np.int32],
    nfree: NDArray[np.int64],
    shift: int,
    ox: float,
    oy: float,
    inv_res: float,
    sx: float,
    sy: float,
    ends: Array,
    hit: NDArray[np.bool_],
    l_occ: float,
    l_free: float,
    l_clamp: float,
    marks: NDArray[np.uint8],
    mr0: int,
    mc0: int,
) -> None:
    """:func:`pfslam.kernels.raycast.ray_update_kernel` on one particle's tiled map: every
    cell a beam crosses gets ``l_free`` once, its end cell ``l_occ`` (hit) or ``l_free``;
    a cell that ends a hit of this scan is not cleared by the scan's other beams.

    ``marks`` is a zeroed scratch window whose cell (0, 0) is grid cell (mr0, mc0) and
    which covers every cell the scan reaches (the bounding box of the sensor and the end
    points); it is left zeroed. The free stack must hold a tile for every tile of that box.
    """
    fx0 = (sx - ox) * inv_res
    fy0 = (sy - oy) * inv_res
    c0 = int(np.floor(fx0))
    r0 = int(np.floor(fy0))
    mh, mw = marks.shape
    for k in range(ends.shape[0]):
        if hit[k]:
            r1 = int(np.floor((ends[k, 1] - oy) * inv_res)) - mr0
            c1 = int(np.floor((ends[k, 0] - ox) * inv_res)) - mc0
            if 0 <= r1 < mh and 0 <= c1 < mw:
                marks[r1, c1] = 1
    for k in range(ends.shape[0]):
        fx1 = (ends[k, 0] - ox) * inv_res
        fy1 = (ends[k, 1] - oy) * inv_res
        c1 = int(np.floor(fx1))
        r1 = int(np.floor(fy1))
        sc, tmx, tdx = axis_setup(fx0, fx1)
        sr, tmy, tdy = axis_setup(fy0, fy1)
        c, r = c0, r0
        n = abs(c1 - c0) + abs(r1 - r0)
        for _ in range(n):
            if c == c1 and r == r1:
                break
            if marks[r - mr0, c - mc0] == 0:
                _add(table, pool, refs, free, nfree, shift, r, c, l_free, l_clamp)
            if tmx < tmy:
                c += sc
                tmx += tdx
            else:
                r += sr
                tmy += tdy
        if hit[k] or marks[r1 - mr0, c1 - mc0] == 0:
            _add(table, pool, refs, free, nfree, shift, r1, c1, l_occ if hit[k] else l_free, l_clamp)
    for k in range(ends.shape[0]):
        if hit[k]:
            r1 = int(np.floor((ends[k, 1] - oy) * inv_res)) - mr0
            c1 = int(np.floor((ends[k, 0] - ox) * inv_res)) - mc0
            if 0 <= r1 < mh and 0 <= c1 < mw:
                marks[r1, c1] = 0


@nb.njit(cache=True)
def tiled_correlation_kernel(
    tables: NDArray[np.int32],
    pool: NDArray[np.float32],
    shift: int,
    poses: Array,
    pts: Array,
    ox: float,
    oy: float,
    inv_res: float,
    inv_sat: float,
    lo: float,
) -> Array:
    """:func:`pfslam.kernels.scoring.correlation_kernel` with particle ``i`` scored on its
    own map ``tables[i]``: the sum of its cells' log-odds at the projected hits, clipped to
    [lo, 1] x sat, divided by sat (cells never written and points off the map add 0)."""
    n = poses.shape[0]
    _, th, tw = tables.shape
    xs, ys = points32(pts)
    hi = np.float32(1.0 / inv_sat)
    lo32 = np.float32(lo / inv_sat)
    zero = np.float32(0.0)
    hf, wf = np.float32(th << shift), np.float32(tw << shift)
    m = (1 << shift) - 1
    out = np.empty(n)
    for i in range(n):
        c, s, fx0, fy0 = frame32(poses[i, 0], poses[i, 1], poses[i, 2], ox, oy, inv_res)
        acc = zero
        for k in range(xs.shape[0]):
            fx, fy = project(c, s, fx0, fy0, xs[k], ys[k])
            if fx >= zero and fx < wf and fy >= zero and fy < hf:
                col, row = int(fx), int(fy)
                idx = tables[i, row >> shift, col >> shift]
                if idx >= 0:
                    acc += min(hi, max(lo32, pool[idx, row & m, col & m]))
        out[i] = acc * inv_sat
    return out
