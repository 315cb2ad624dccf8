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


@nb.njit(cache=True)
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
    Consecutive cells of a ray mostly share a tile: the last tile made this map's own is
    kept at hand, so the table is consulted once per tile a ray enters.
    """
    th, tw = table.shape
    m = (1 << shift) - 1
    fx0 = (sx - ox) * inv_res
    fy0 = (sy - oy) * inv_res
    c0 = int(np.floor(fx0))
    r0 = int(np.floor(fy0))
    mh, mw = marks.shape
    lo, hi, vfree, vocc = -l_clamp, l_clamp, l_free, l_occ  # float64 sums, as the dense kernel
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
        ltr, ltc, idx = -1, -1, -1
        for _ in range(n):
            if c == c1 and r == r1:
                break
            tr, tc = r >> shift, c >> shift
            if r >= 0 and c >= 0 and tr < th and tc < tw and marks[r - mr0, c - mc0] == 0:
                if tr != ltr or tc != ltc:
                    idx = _own_tile(table, pool, refs, free, nfree, tr, tc)
                    ltr, ltc = tr, tc
                v = pool[idx, r & m, c & m] + vfree
                pool[idx, r & m, c & m] = min(hi, max(lo, v))
            if tmx < tmy:
                c += sc
                tmx += tdx
            else:
                r += sr
                tmy += tdy
        tr, tc = r1 >> shift, c1 >> shift
        if r1 >= 0 and c1 >= 0 and tr < th and tc < tw and (hit[k] or marks[r1 - mr0, c1 - mc0] == 0):
            idx = _own_tile(table, pool, refs, free, nfree, tr, tc)
            v = pool[idx, r1 & m, c1 & m] + (vocc if hit[k] else vfree)
            pool[idx, r1 & m, c1 & m] = min(hi, max(lo, v))
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


# --- matching against a particle's own map: nearest occupied cell in a neighbourhood ------
#
# A hit scores exp(-d^2 / 2 sigma^2), d the distance from the hit to the centre of the
# nearest occupied cell among the (2 radius + 1)^2 cells around it (none: 0). No distance
# transform: the cost per hit is the neighbourhood, whatever the map's size or the laser's
# reach.


@nb.njit(cache=True, inline="always")
def _near(table, pool, shift: int, th: int, tw: int, fx: float, fy: float, radius: int, occ: float) -> float:
    """Squared distance (cells) from (fx, fy) to the nearest occupied cell centre within
    ``radius`` cells; a large number if there is none."""
    m = (1 << shift) - 1
    r0 = int(np.floor(fy))
    c0 = int(np.floor(fx))
    best = 1e30
    for r in range(r0 - radius, r0 + radius + 1):
        tr = r >> shift
        if r < 0 or tr >= th:
            continue
        dy = r + 0.5 - fy
        for c in range(c0 - radius, c0 + radius + 1):
            tc = c >> shift
            if c < 0 or tc >= tw:
                continue
            idx = table[tr, tc]
            if idx >= 0 and pool[idx, r & m, c & m] > occ:
                dx = c + 0.5 - fx
                d = dx * dx + dy * dy
                if d < best:
                    best = d
    return best


@nb.njit(cache=True)
def _match_score(table, pool, shift: int, x: float, y: float, th_: float, xs, ys, ox: float, oy: float,
                 inv_res: float, inv2s2: float, radius: int, occ: float, log_floor: float, loglik: bool) -> float:
    """The hits (robot frame) at pose (x, y, th_) on one map: the match score, the sum of
    exp(-d^2 / 2 sigma^2), or with ``loglik`` the log-likelihood, the sum of
    max(-d^2 / 2 sigma^2, log_floor) (``inv2s2`` = 1 / 2 sigma^2 in cells)."""
    tth, ttw = table.shape
    c = np.cos(th_) * inv_res
    s = np.sin(th_) * inv_res
    fx0 = (x - ox) * inv_res
    fy0 = (y - oy) * inv_res
    acc = 0.0
    for k in range(xs.shape[0]):
        fx = fx0 + c * xs[k] - s * ys[k]
        fy = fy0 + s * xs[k] + c * ys[k]
        d = _near(table, pool, shift, tth, ttw, fx, fy, radius, occ)
        if loglik:
            acc += max(-d * inv2s2, log_floor)
        elif d < 1e29:
            acc += np.exp(-d * inv2s2)
    return acc


@nb.njit(cache=True)
def _scan_setup(pts, res: float, sigma: float):
    """1 / res, 1 / (2 sigma^2) in cells, and the hits' x and y columns (contiguous)."""
    inv_res = 1.0 / res
    sc = sigma * inv_res
    return inv_res, 0.5 / (sc * sc), np.ascontiguousarray(pts[:, 0]), np.ascontiguousarray(pts[:, 1])


@nb.njit(cache=True, parallel=True)
def tiled_match_kernel(
    tables: NDArray[np.int32],
    pool: NDArray[np.float32],
    shift: int,
    poses: Array,
    pts: Array,
    ox: float,
    oy: float,
    res: float,
    sigma: float,
    radius: int,
    occ: float,
    lstep: float,
    astep: float,
    refinements: int,
    prior_w: float = 0.0,
    prior_xy: float = 1.0,
    prior_th: float = 1.0,
) -> Array:
    """Move every particle (``poses``, in place) to the pose that best matches its hits
    (robot frame) to its own map, by hill climbing in x, y and theta from where it is with
    steps of ``lstep`` m and ``astep`` rad, halved ``refinements`` times; returns each
    particle's match score there (the sum over hits of exp(-d^2 / 2 sigma^2)).

    With ``prior_w`` > 0 the climb maximises the score less ``prior_w`` times the motion
    prior's negative log, ``(dx^2 + dy^2) / (2 prior_xy^2) + dth^2 / (2 prior_th^2)`` of the
    move from where the particle started: a slide the odometry makes unlikely must buy
    itself with a better match."""
    n = poses.shape[0]
    inv_res, inv2s2, xs, ys = _scan_setup(pts, res, sigma)
    out = np.empty(n)
    for i in nb.prange(n):  # particles are independent: one thread each
        table = tables[i]
        x, y, t = poses[i, 0], poses[i, 1], poses[i, 2]
        x0, y0, t0 = x, y, t
        best = _match_score(table, pool, shift, x, y, t, xs, ys, ox, oy, inv_res, inv2s2, radius, occ, 0.0, False)
        raw = best
        ls, as_ = lstep, astep
        for _ in range(refinements + 1):
            for _ in range(50):  # climb at this step size
                bx, by, bt = x, y, t
                for move in range(6):
                    cx, cy, ct = x, y, t
                    if move == 0:
                        cx += ls
                    elif move == 1:
                        cx -= ls
                    elif move == 2:
                        cy += ls
                    elif move == 3:
                        cy -= ls
                    elif move == 4:
                        ct += as_
                    else:
                        ct -= as_
                    sv = _match_score(table, pool, shift, cx, cy, ct, xs, ys, ox, oy, inv_res, inv2s2, radius, occ,
                                      0.0, False)
                    v = sv
                    if prior_w > 0.0:
                        v -= prior_w * (((cx - x0) ** 2 + (cy - y0) ** 2) / (2.0 * prior_xy * prior_xy)
                                        + (ct - t0) ** 2 / (2.0 * prior_th * prior_th))
                    if v > best:
                        best, bx, by, bt, raw = v, cx, cy, ct, sv
                if bx == x and by == y and bt == t:
                    break
                x, y, t = bx, by, bt
            ls *= 0.5
            as_ *= 0.5
        poses[i, 0], poses[i, 1], poses[i, 2] = x, y, t
        out[i] = raw
    return out


@nb.njit(cache=True)
def tiled_loglik_kernel(
    tables: NDArray[np.int32],
    pool: NDArray[np.float32],
    shift: int,
    poses: Array,
    pts: Array,
    ox: float,
    oy: float,
    res: float,
    sigma: float,
    radius: int,
    occ: float,
    floor: float,
) -> Array:
    """Every particle's log-likelihood of its hits on its own map: the sum over hits of
    log(max(exp(-d^2 / 2 sigma^2), floor)), d as in the match (no occupied neighbour: floor)."""
    n = poses.shape[0]
    inv_res, inv2s2, xs, ys = _scan_setup(pts, res, sigma)
    out = np.empty(n)
    for i in range(n):
        out[i] = _match_score(tables[i], pool, shift, poses[i, 0], poses[i, 1], poses[i, 2], xs, ys, ox, oy, inv_res,
                              inv2s2, radius, occ, np.log(floor), True)
    return out
