"""Map update: exact ray traversal (Amanatides & Woo) with log-odds updates, and its NumPy twin."""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

from pfslam.types import Array

# --- exact ray traversal (Amanatides & Woo) ---------------------------------------------


@nb.njit(cache=True, inline="always")
def axis_setup(f0: float, f1: float) -> tuple[int, float, float]:
    """Step direction, parametric distance to the first grid line, and between lines."""
    d = f1 - f0
    if d > 0.0:
        return 1, (np.floor(f0) + 1.0 - f0) / d, 1.0 / d
    if d < 0.0:
        return -1, (f0 - np.floor(f0)) / -d, -1.0 / d
    return 0, np.inf, np.inf


@nb.njit(cache=True, nogil=True)
def ray_update_kernel(
    logodds: NDArray[np.float32],
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
    stamp: NDArray[np.int32],
    scan_id: int,
) -> None:
    """Ray-update the grid in place with one scan: every cell a beam crosses gets ``l_free``
    once, its end cell ``l_occ`` (hit) or ``l_free`` (no obstacle, e.g. a floor hit);
    values are clamped to ±l_clamp.

    Hits take precedence within a scan: a cell that holds the end point of a hit of this
    scan is not cleared by the other beams of the same scan (beams grazing a wall would
    otherwise erase it). ``stamp`` (same shape as the grid) marks those cells with
    ``scan_id``, which must differ from every earlier call's.

    Cell (row, col) = (floor((y - oy) / res), floor((x - ox) / res)). Cells outside the
    array are skipped.
    """
    h, w = logodds.shape
    fx0 = (sx - ox) * inv_res
    fy0 = (sy - oy) * inv_res
    c0 = int(np.floor(fx0))
    r0 = int(np.floor(fy0))
    for k in range(ends.shape[0]):
        if hit[k]:
            c1 = int(np.floor((ends[k, 0] - ox) * inv_res))
            r1 = int(np.floor((ends[k, 1] - oy) * inv_res))
            if 0 <= r1 < h and 0 <= c1 < w:
                stamp[r1, c1] = scan_id
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
            if 0 <= r < h and 0 <= c < w and stamp[r, c] != scan_id:
                v = logodds[r, c] + l_free
                logodds[r, c] = max(-l_clamp, min(l_clamp, v))
            if tmx < tmy:
                c += sc
                tmx += tdx
            else:
                r += sr
                tmy += tdy
        if 0 <= r1 < h and 0 <= c1 < w and (hit[k] or stamp[r1, c1] != scan_id):
            v = logodds[r1, c1] + (l_occ if hit[k] else l_free)
            logodds[r1, c1] = max(-l_clamp, min(l_clamp, v))


def ray_cells(fx0: float, fy0: float, fx1: float, fy1: float) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Cells (rows, cols) a segment crosses, in cell coordinates, with the end cell last.

    The segment's crossings with vertical and horizontal grid lines are taken in
    parametric order (a tie at a corner steps in y), the same walk as the kernel.
    """
    c1, r1 = int(np.floor(fx1)), int(np.floor(fy1))
    c, r = int(np.floor(fx0)), int(np.floor(fy0))
    n = abs(c1 - c) + abs(r1 - r)
    sc, tmx, tdx = axis_setup.py_func(fx0, fx1)
    sr, tmy, tdy = axis_setup.py_func(fy0, fy1)
    rows: list[int] = []
    cols: list[int] = []
    for _ in range(n):
        if c == c1 and r == r1:
            break
        rows.append(r)
        cols.append(c)
        if tmx < tmy:
            c += sc
            tmx += tdx
        else:
            r += sr
            tmy += tdy
    rows.append(r1)
    cols.append(c1)
    return np.array(rows, dtype=np.int64), np.array(cols, dtype=np.int64)


@nb.njit(cache=True, nogil=True)
def ray_update_scans_kernel(
    logodds: NDArray[np.float32],
    ox: float,
    oy: float,
    inv_res: float,
    sensors: Array,
    ends: Array,
    hit: NDArray[np.bool_],
    starts: NDArray[np.int64],
    l_occ: float,
    l_free: float,
    l_clamp: float,
    stamp: NDArray[np.int32],
    first_id: int,
) -> None:
    """:func:`ray_update_kernel` for scans one after the other in one call: scan ``s`` is
    seen from ``sensors[s]`` with the beams ``ends[starts[s]:starts[s + 1]]`` (``hit`` alike)
    and stamped ``first_id + s``."""
    for s in range(sensors.shape[0]):
        a, b = starts[s], starts[s + 1]
        ray_update_kernel(
            logodds,
            ox,
            oy,
            inv_res,
            sensors[s, 0],
            sensors[s, 1],
            ends[a:b],
            hit[a:b],
            l_occ,
            l_free,
            l_clamp,
            stamp,
            first_id + s,
        )


def ray_update_numpy(
    logodds: NDArray[np.float32],
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
    stamp: NDArray[np.int32],
    scan_id: int,
) -> None:
    """NumPy twin of :func:`ray_update_kernel` (a loop over beams, vectorised per beam)."""
    h, w = logodds.shape
    fx0, fy0 = (sx - ox) * inv_res, (sy - oy) * inv_res
    hr = np.floor((ends[hit, 1] - oy) * inv_res).astype(np.int64)
    hc = np.floor((ends[hit, 0] - ox) * inv_res).astype(np.int64)
    inside = (hr >= 0) & (hr < h) & (hc >= 0) & (hc < w)
    stamp[hr[inside], hc[inside]] = scan_id
    for k in range(len(ends)):
        fx1, fy1 = (ends[k, 0] - ox) * inv_res, (ends[k, 1] - oy) * inv_res
        rows, cols = ray_cells(fx0, fy0, fx1, fy1)
        add = np.full(len(rows), l_free)
        if hit[k]:
            add[-1] = l_occ
        ok = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        protected = np.zeros(len(rows), dtype=bool)
        protected[ok] = stamp[rows[ok], cols[ok]] == scan_id
        if hit[k]:
            protected[-1] = False
        ok &= ~protected
        rr, cc = rows[ok], cols[ok]
        # Cells of one beam are distinct, so fancy-index assignment is safe.
        logodds[rr, cc] = np.clip(logodds[rr, cc].astype(np.float64) + add[ok], -l_clamp, l_clamp)


# --- map agreement: hits checked against a kept map -----------------------------------------


@nb.njit(cache=True, nogil=True)
def agreement_kernel(
    pose: Array,
    hits: Array,
    near_wall: NDArray[np.bool_],
    seen: NDArray[np.bool_],
    ox: float,
    oy: float,
    res: float,
    row0: int = 0,
    col0: int = 0,
) -> tuple[int, int]:
    """Of the ``hits`` (robot frame) placed at ``pose``, how many fall in a ``seen`` cell of
    the grid (origin ``ox``, ``oy``) and how many of those in a ``near_wall`` one. The
    points are moved as :func:`pfslam.geometry.transform_points` moves them. ``seen`` and
    ``near_wall`` may be a crop of the grid whose cell (0, 0) is the grid's (``row0``,
    ``col0``): the cells are counted on the grid's own origin, then shifted."""
    c, s = np.cos(pose[2]), np.sin(pose[2])
    h, w = seen.shape
    known = 0
    on_wall = 0
    for k in range(hits.shape[0]):
        x = pose[0] + c * hits[k, 0] - s * hits[k, 1]
        y = pose[1] + s * hits[k, 0] + c * hits[k, 1]
        r = int(np.floor((y - oy) / res)) - row0
        q = int(np.floor((x - ox) / res)) - col0
        if 0 <= r < h and 0 <= q < w and seen[r, q]:
            known += 1
            on_wall += int(near_wall[r, q])
    return known, on_wall
