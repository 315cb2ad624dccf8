"""Kernels on tiled, copy-on-write maps (one map per particle, see :mod:`pfslam.maps.tiled`):
the ray update of one particle's map and the correlation score of every particle against
its own map. They read the tile table inline (no per-cell helper call); their NumPy twins
are the dense kernels run on each particle's map made dense (:meth:`TiledMaps.dense`).

A map is a table ``(TH, TW)`` of tile numbers (-1: a tile never written, all zero) into a
shared ``pool`` of ``(T, T)`` float32 tiles, ``T = 1 << shift``. A tile shared by several
particles (``refs > 1``) is copied before it is written; a fresh one is taken from the
``free`` stack (``nfree[0]`` entries) and zeroed.

Each pool tile has a twin in ``near``, a ``(T, T)`` uint16 cache for the match: for a cell
whose 3 x 3 neighbourhood lies in the tile, the bits of which of those nine cells are
occupied (log-odds above 0), or ``UNKNOWN`` until a match first needs it. Whether a tile's
entries are stale (:func:`stale_flag`) is kept apart, in the rows of ``near`` past the pool's
(one entry per tile, each on a cache line of its own: 64 bytes a tile): a tile taken fresh or copied is marked
stale (no cache is copied), and so is a tile a scan's rays write (the whole tile, not only the
neighbours of the cells that changed); the first match to read a stale tile sets every entry
unknown. So a tile no match reads (the far free space of a long laser's rays, copied by 30
particles after a resampling) never brings its cache's page into memory. A hit's nearest
occupied neighbour costs one lookup and the cells that are set, not nine reads, and the
answer is the same. (Particles sharing a tile
may fill its entries from two threads at once: they write the same values, or unknown.)
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

from pfslam.kernels.project import frame32, points32, project
from pfslam.kernels.raycast import axis_setup
from pfslam.types import Array

UNKNOWN = 0xFFFF  # a near-cache entry not computed since its neighbourhood last changed


def _mask_offsets() -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """Per 3 x 3 occupancy mask (bit 3 * (dr + 1) + (dc + 1) set: cell (r + dr, c + dc)
    occupied), how many cells are set and their row and column offsets."""
    count = np.zeros(512, dtype=np.int64)
    dr = np.zeros((512, 9), dtype=np.int64)
    dc = np.zeros((512, 9), dtype=np.int64)
    for mask in range(512):
        for b in range(9):
            if mask >> b & 1:
                dr[mask, count[mask]], dc[mask, count[mask]] = b // 3 - 1, b % 3 - 1
                count[mask] += 1
    return count, dr, dc


_MASK_N, _MASK_DR, _MASK_DC = _mask_offsets()


FLAG_SPACING = 5  # a stale flag every 2^5 entries (64 bytes): one per cache line, no two tiles' flags on one


def near_rows(tiles: int, shift: int) -> int:
    """Rows (tiles) of the ``near`` array of a pool of ``tiles`` tiles: one per tile, then the
    stale flags (:func:`stale_flag`)."""
    per = 1 << max(2 * shift - FLAG_SPACING, 0)
    return tiles + -(-tiles // per)


@nb.njit(cache=True, inline="always")
def stale_flag(pool, idx: int, shift: int) -> tuple[int, int, int]:
    """Where tile ``idx``'s stale flag is in ``near`` (row, r, c; tiles ``1 << shift`` cells a
    side): in the rows past the pool's, each on a cache line of its own (the particles'
    threads write the flags of their own tiles; flags side by side would make them take the
    line from each other at every write), found by shifts (it is read per hit)."""
    per = max(2 * shift - FLAG_SPACING, 0)
    entry = (idx & ((1 << per) - 1)) << FLAG_SPACING if per > 0 else 0
    return pool.shape[0] + (idx >> per), entry >> shift, entry & ((1 << shift) - 1)


@nb.njit(cache=True, inline="always")
def mark_stale(pool, near, idx: int, shift: int) -> None:
    """Tile ``idx``'s near cache is stale (see the module notes), written only when it was not."""
    row, r, c = stale_flag(pool, idx, shift)
    if near[row, r, c] == 0:
        near[row, r, c] = 1


@nb.njit(cache=True)
def _own_tile(table, pool, near, refs, free, nfree, tr: int, tc: int, shift: int) -> int:
    """The tile at (tr, tc) of this table, made this table's own (fresh or copied, with its
    near cache)."""
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
    mark_stale(pool, near, new, shift)  # reset when a match first reads it
    refs[new] = 1
    table[tr, tc] = new
    return new


@nb.njit(cache=True, inline="always")
def _writable_tile(table, pool, near, refs, free, nfree, tr: int, tc: int, own: bool, shift: int) -> int:
    """The tile at (tr, tc) to write: made this table's own (``own``), or -1 if it is not
    already (never written, or shared)."""
    if own:
        return _own_tile(table, pool, near, refs, free, nfree, tr, tc, shift)
    idx = table[tr, tc]
    return idx if idx >= 0 and refs[idx] == 1 else -1


@nb.njit(cache=True, inline="always")
def _add(pool, idx: int, r: int, c: int, add: float, lo: float, hi: float) -> None:
    """Add ``add`` to cell (r, c) of tile ``idx``, clamped to [lo, hi]."""
    pool[idx, r, c] = min(hi, max(lo, pool[idx, r, c] + add))


@nb.njit(cache=True, inline="always")
def _mark_hits(ends, hit, ox: float, oy: float, inv_res: float, marks, mr0: int, mc0: int, value: int) -> None:
    """Set the scratch window's cells that end a hit to ``value``."""
    mh, mw = marks.shape
    for k in range(ends.shape[0]):
        if hit[k]:
            r1 = int(np.floor((ends[k, 1] - oy) * inv_res)) - mr0
            c1 = int(np.floor((ends[k, 0] - ox) * inv_res)) - mc0
            if 0 <= r1 < mh and 0 <= c1 < mw:
                marks[r1, c1] = value


@nb.njit(cache=True)
def _scan_rays(
    table,
    pool,
    near,
    refs,
    free,
    nfree,
    shift: int,
    ox: float,
    oy: float,
    inv_res: float,
    sx: float,
    sy: float,
    ends,
    hit,
    l_occ: float,
    l_free: float,
    l_clamp: float,
    marks,
    mr0: int,
    mc0: int,
    own: bool,
) -> int:
    """The ray update of one map (see :func:`tiled_ray_update_kernel`). With ``own`` a tile
    is made the map's own before its first write (the free stack is used); without, every
    tile written must be the map's own already (``refs == 1``): one that is not is left
    unwritten and counted, and the count is returned."""
    th, tw = table.shape
    m = (1 << shift) - 1
    fx0 = (sx - ox) * inv_res
    fy0 = (sy - oy) * inv_res
    c0 = int(np.floor(fx0))
    r0 = int(np.floor(fy0))
    misses = 0
    lo, hi, vfree, vocc = -l_clamp, l_clamp, l_free, l_occ  # float64 sums, as the dense kernel
    _mark_hits(ends, hit, ox, oy, inv_res, marks, mr0, mc0, 1)
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
                    idx = _writable_tile(table, pool, near, refs, free, nfree, tr, tc, own, shift)
                    ltr, ltc = tr, tc
                    if idx >= 0:
                        mark_stale(pool, near, idx, shift)  # written: its near cache is stale
                if idx >= 0:
                    _add(pool, idx, r & m, c & m, vfree, lo, hi)
                else:
                    misses += 1
            if tmx < tmy:
                c += sc
                tmx += tdx
            else:
                r += sr
                tmy += tdy
        tr, tc = r1 >> shift, c1 >> shift
        if r1 >= 0 and c1 >= 0 and tr < th and tc < tw and (hit[k] or marks[r1 - mr0, c1 - mc0] == 0):
            idx = _writable_tile(table, pool, near, refs, free, nfree, tr, tc, own, shift)
            if idx >= 0:
                mark_stale(pool, near, idx, shift)
                _add(pool, idx, r1 & m, c1 & m, vocc if hit[k] else vfree, lo, hi)
            else:
                misses += 1
    _mark_hits(ends, hit, ox, oy, inv_res, marks, mr0, mc0, 0)
    return misses


@nb.njit(cache=True)
def tiled_ray_update_kernel(
    table: NDArray[np.int32],
    pool: NDArray[np.float32],
    near: NDArray[np.uint16],
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
    _scan_rays(
        table,
        pool,
        near,
        refs,
        free,
        nfree,
        shift,
        ox,
        oy,
        inv_res,
        sx,
        sy,
        ends,
        hit,
        l_occ,
        l_free,
        l_clamp,
        marks,
        mr0,
        mc0,
        True,
    )


# --- every particle's map at once: own the tiles first, then write in parallel -----------
#
# Taking a tile from the free stack cannot be done by two threads at once, and a particle
# cannot know which tiles it writes without tracing its rays. So a first pass marks, for
# each particle, every tile its scan's segments pass through (the tiles whose closed square
# meets a segment, widened by a hair against rounding: a superset of the tiles of the
# cells the exact traversal visits); a short serial pass makes those tiles each particle's
# own; and the ray updates then run one particle per thread, writing only tiles no other
# map holds.

_HAIR = 1e-6  # tiles: the widening of a segment against rounding in the cell traversal


@nb.njit(cache=True, parallel=True)
def segment_tiles_kernel(
    tables: NDArray[np.int32],
    refs: NDArray[np.int32],
    shift: int,
    ox: float,
    oy: float,
    inv_res: float,
    sensors: Array,
    ends: Array,
    boxes: NDArray[np.int64],
    mask: NDArray[np.uint8],
) -> NDArray[np.int64]:
    """Mark in ``mask[i]`` (zeroed, the tables' shape) every tile of map ``i``'s grid that a
    segment from ``sensors[i]`` to an end ``ends[i, k]`` (world frame) passes through;
    ``boxes[i]`` receives the marked tiles' bounding box (tr0, tc0, tr1, tc1, inclusive).
    Returns per map the marked tiles it does not own yet (never written, or shared)."""
    n, th, tw = tables.shape
    inv_t = inv_res / (1 << shift)
    need = np.zeros(n, dtype=np.int64)
    for i in nb.prange(n):
        ax = (sensors[i, 0] - ox) * inv_t
        ay = (sensors[i, 1] - oy) * inv_t
        br0, bc0, br1, bc1 = th, tw, -1, -1
        for k in range(ends.shape[1]):
            bx = (ends[i, k, 0] - ox) * inv_t
            by = (ends[i, k, 1] - oy) * inv_t
            xl, xh = min(ax, bx), max(ax, bx)
            for tc in range(max(int(np.floor(xl - _HAIR)), 0), min(int(np.floor(xh + _HAIR)), tw - 1) + 1):
                # The segment's y over this tile column (clipped to the segment).
                u0 = min(max(float(tc), xl), xh)
                u1 = min(max(float(tc + 1), xl), xh)
                if bx != ax:
                    y0 = ay + (by - ay) * (u0 - ax) / (bx - ax)
                    y1 = ay + (by - ay) * (u1 - ax) / (bx - ax)
                else:
                    y0, y1 = ay, by
                yl, yh = min(y0, y1), max(y0, y1)
                for tr in range(max(int(np.floor(yl - _HAIR)), 0), min(int(np.floor(yh + _HAIR)), th - 1) + 1):
                    mask[i, tr, tc] = 1
                    br0, bc0, br1, bc1 = min(br0, tr), min(bc0, tc), max(br1, tr), max(bc1, tc)
        boxes[i, 0], boxes[i, 1], boxes[i, 2], boxes[i, 3] = br0, bc0, br1, bc1
        k = 0
        for tr in range(br0, br1 + 1):
            for tc in range(bc0, bc1 + 1):
                if mask[i, tr, tc]:
                    idx = tables[i, tr, tc]
                    if idx < 0 or refs[idx] != 1:
                        k += 1
        need[i] = k
    return need


@nb.njit(cache=True)
def own_tiles_kernel(
    tables: NDArray[np.int32],
    pool: NDArray[np.float32],
    near: NDArray[np.uint16],
    refs: NDArray[np.int32],
    free: NDArray[np.int32],
    nfree: NDArray[np.int64],
    mask: NDArray[np.uint8],
    boxes: NDArray[np.int64],
) -> None:
    """Make every tile marked in ``mask[i]`` map ``i``'s own (fresh or copied). The free
    stack must hold enough tiles (what :func:`segment_tiles_kernel` counted)."""
    shift = 0
    while (1 << shift) < pool.shape[1]:
        shift += 1
    for i in range(tables.shape[0]):
        for tr in range(boxes[i, 0], boxes[i, 2] + 1):
            for tc in range(boxes[i, 1], boxes[i, 3] + 1):
                if mask[i, tr, tc]:
                    _own_tile(tables[i], pool, near, refs, free, nfree, tr, tc, shift)


@nb.njit(cache=True, parallel=True)
def tiled_scan_update_kernel(
    tables: NDArray[np.int32],
    pool: NDArray[np.float32],
    near: NDArray[np.uint16],
    refs: NDArray[np.int32],
    shift: int,
    ox: float,
    oy: float,
    inv_res: float,
    sensors: Array,
    ends: Array,
    hit: NDArray[np.bool_],
    l_occ: float,
    l_free: float,
    l_clamp: float,
    marks: NDArray[np.uint8],
    corners: NDArray[np.int64],
) -> int:
    """:func:`tiled_ray_update_kernel` for every map ``i`` with its scan (``sensors[i]``,
    ``ends[i]``, world frame), in parallel: one map per thread at a time, each thread with
    its own scratch window ``marks[j]``, whose cell (0, 0) is grid cell ``corners[i]`` for
    map ``i``. Every tile written must be the map's own already (:func:`own_tiles_kernel`);
    returns the cells that could not be written because one was not (0 unless misused)."""
    n = tables.shape[0]
    chunks = marks.shape[0]
    misses = np.zeros(chunks, dtype=np.int64)
    dummy_free = np.zeros(1, dtype=np.int32)
    dummy_nfree = np.zeros(1, dtype=np.int64)
    for j in nb.prange(chunks):
        for i in range(j, n, chunks):
            misses[j] += _scan_rays(
                tables[i],
                pool,
                near,
                refs,
                dummy_free,
                dummy_nfree,
                shift,
                ox,
                oy,
                inv_res,
                sensors[i, 0],
                sensors[i, 1],
                ends[i],
                hit,
                l_occ,
                l_free,
                l_clamp,
                marks[j],
                corners[i, 0],
                corners[i, 1],
                False,
            )
    return int(misses.sum())


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
def cached_mask(pool, near, idx: int, r0: int, c0: int, shift: int) -> int:
    """The 3 x 3 occupancy mask (bit 3 (dr + 1) + (dc + 1): log-odds above 0) around cell
    (r0, c0), whose neighbourhood lies in pool tile ``idx`` (tiles ``1 << shift`` cells a
    side), from the tile's near cache, filled here where it is unknown (see the module notes)."""
    m = (1 << shift) - 1
    row, fr, fc = stale_flag(pool, idx, shift)
    if near[row, fr, fc] != 0:
        near[idx] = UNKNOWN
        near[row, fr, fc] = 0
    mask = near[idx, r0 & m, c0 & m]
    if mask == UNKNOWN:
        tile = pool[idx]
        mask = 0
        for b in range(9):
            if tile[(r0 + b // 3 - 1) & m, (c0 + b % 3 - 1) & m] > 0.0:
                mask |= 1 << b
        near[idx, r0 & m, c0 & m] = mask
    return mask


@nb.njit(cache=True, inline="always")
def _near(
    table, pool, near, shift: int, th: int, tw: int, fx: float, fy: float, radius: int, occ: float, cached: bool
) -> tuple[float, float, float]:
    """Squared distance (cells) from (fx, fy) to the nearest occupied cell centre within
    ``radius`` cells (a large number if there is none) and that centre less (fx, fy).
    ``cached``: radius 1 and occupied meaning above 0, so the near cache answers (see the
    module notes)."""
    m = (1 << shift) - 1
    r0 = int(np.floor(fy))
    c0 = int(np.floor(fx))
    best, bx, by = 1e30, 0.0, 0.0
    tr, tc = (r0 - radius) >> shift, (c0 - radius) >> shift
    if (
        r0 - radius >= 0
        and c0 - radius >= 0
        and (r0 + radius) >> shift == tr
        and (c0 + radius) >> shift == tc
        and tr < th
        and tc < tw
    ):
        # The neighbourhood lies in one tile (most hits): one table lookup.
        idx = table[tr, tc]
        if idx < 0:
            return best, bx, by
        tile = pool[idx]
        if cached:
            mask = cached_mask(pool, near, idx, r0, c0, shift)
            for j in range(_MASK_N[mask]):
                dx = c0 + _MASK_DC[mask, j] + 0.5 - fx
                dy = r0 + _MASK_DR[mask, j] + 0.5 - fy
                d = dx * dx + dy * dy
                if d < best:
                    best, bx, by = d, dx, dy
            return best, bx, by
        for r in range(r0 - radius, r0 + radius + 1):
            dy = r + 0.5 - fy
            for c in range(c0 - radius, c0 + radius + 1):
                if tile[r & m, c & m] > occ:
                    dx = c + 0.5 - fx
                    d = dx * dx + dy * dy
                    if d < best:
                        best, bx, by = d, dx, dy
        return best, bx, by
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
                    best, bx, by = d, dx, dy
    return best, bx, by


@nb.njit(cache=True)
def _match_score(
    table,
    pool,
    near,
    shift: int,
    x: float,
    y: float,
    th_: float,
    xs,
    ys,
    ox: float,
    oy: float,
    inv_res: float,
    inv2s2: float,
    radius: int,
    occ: float,
    log_floor: float,
    loglik: bool,
) -> float:
    """The hits (robot frame) at pose (x, y, th_) on one map: the match score, the sum of
    exp(-d^2 / 2 sigma^2), or with ``loglik`` the log-likelihood, the sum of
    max(-d^2 / 2 sigma^2, log_floor) (``inv2s2`` = 1 / 2 sigma^2 in cells)."""
    tth, ttw = table.shape
    cached = radius == 1 and occ == 0.0
    c = np.cos(th_) * inv_res
    s = np.sin(th_) * inv_res
    fx0 = (x - ox) * inv_res
    fy0 = (y - oy) * inv_res
    acc = 0.0
    for k in range(xs.shape[0]):
        fx = fx0 + c * xs[k] - s * ys[k]
        fy = fy0 + s * xs[k] + c * ys[k]
        d = _near(table, pool, near, shift, tth, ttw, fx, fy, radius, occ, cached)[0]
        if loglik:
            acc += max(-d * inv2s2, log_floor)
        elif d < 1e29:
            acc += np.exp(-d * inv2s2)
    return acc


@nb.njit(cache=True)
def scan_setup(pts, res: float, sigma: float):
    """1 / res, 1 / (2 sigma^2) in cells, and the hits' x and y columns (contiguous)."""
    inv_res = 1.0 / res
    sc = sigma * inv_res
    return inv_res, 0.5 / (sc * sc), np.ascontiguousarray(pts[:, 0]), np.ascontiguousarray(pts[:, 1])


@nb.njit(cache=True, parallel=True)
def tiled_match_kernel(
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
    inv_res, inv2s2, xs, ys = scan_setup(pts, res, sigma)
    out = np.empty(n)
    for i in nb.prange(n):  # particles are independent: one thread each
        table = tables[i]
        x, y, t = poses[i, 0], poses[i, 1], poses[i, 2]
        x0, y0, t0 = x, y, t
        best = _match_score(table, pool, near, shift, x, y, t, xs, ys, ox, oy, inv_res, inv2s2, radius, occ, 0.0, False)
        raw = best
        ls, as_ = lstep, astep
        for _ in range(refinements + 1):
            undo = -1  # the move back to where the last step came from: known to score less
            for _ in range(50):  # climb at this step size
                bx, by, bt, bm = x, y, t, -1
                for move in range(6):
                    if move == undo:
                        continue
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
                    sv = _match_score(
                        table, pool, near, shift, cx, cy, ct, xs, ys, ox, oy, inv_res, inv2s2, radius, occ, 0.0, False
                    )
                    v = sv
                    if prior_w > 0.0:
                        v -= prior_w * (
                            ((cx - x0) ** 2 + (cy - y0) ** 2) / (2.0 * prior_xy * prior_xy)
                            + (ct - t0) ** 2 / (2.0 * prior_th * prior_th)
                        )
                    if v > best:
                        best, bx, by, bt, raw, bm = v, cx, cy, ct, sv, move
                if bm < 0:
                    break
                x, y, t = bx, by, bt
                undo = bm ^ 1  # moves come in pairs: +x/-x, +y/-y, +theta/-theta
            ls *= 0.5
            as_ *= 0.5
        poses[i, 0], poses[i, 1], poses[i, 2] = x, y, t
        out[i] = raw
    return out


@nb.njit(cache=True)
def tiled_loglik_kernel(
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
    radius: int,
    occ: float,
    floor: float,
) -> Array:
    """Every particle's log-likelihood of its hits on its own map: the sum over hits of
    log(max(exp(-d^2 / 2 sigma^2), floor)), d as in the match (no occupied neighbour: floor)."""
    n = poses.shape[0]
    inv_res, inv2s2, xs, ys = scan_setup(pts, res, sigma)
    out = np.empty(n)
    for i in range(n):
        out[i] = _match_score(
            tables[i],
            pool,
            near,
            shift,
            poses[i, 0],
            poses[i, 1],
            poses[i, 2],
            xs,
            ys,
            ox,
            oy,
            inv_res,
            inv2s2,
            radius,
            occ,
            np.log(floor),
            True,
        )
    return out
