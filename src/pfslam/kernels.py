"""Numba kernels for the hot loops, each with a plain NumPy twin that the tests compare it with."""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


# --- exact ray traversal (Amanatides & Woo) ---------------------------------------------


@nb.njit(cache=True, inline="always")
def _axis_setup(f0: float, f1: float) -> tuple[int, float, float]:
    """Step direction, parametric distance to the first grid line, and between lines."""
    d = f1 - f0
    if d > 0.0:
        return 1, (np.floor(f0) + 1.0 - f0) / d, 1.0 / d
    if d < 0.0:
        return -1, (f0 - np.floor(f0)) / -d, -1.0 / d
    return 0, np.inf, np.inf


@nb.njit(cache=True)
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
        sc, tmx, tdx = _axis_setup(fx0, fx1)
        sr, tmy, tdy = _axis_setup(fy0, fy1)
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
    sc, tmx, tdx = _axis_setup.py_func(fx0, fx1)
    sr, tmy, tdy = _axis_setup.py_func(fy0, fy1)
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


# --- projecting hits into the grid (float32, for SIMD) ------------------------------------
#
# The scoring kernels compute cell coordinates in float32, eight to a 256-bit vector
# instead of four: with 0.05 m cells and maps of a few thousand cells a side the rounding
# stays below 1e-4 of a cell (5 µm). The steps are written as IEEE float32 operations in
# the order the NumPy twins use (no fused multiply-add), so a kernel and its twin put
# every hit in the same cell. Only the sums may be split across vector lanes ("reassoc");
# sums of integer-valued log-odds (what +3 / -1 updates give) are exact in any order, and
# the tests compare kernels and twins exactly on such maps, which would also catch a
# compiler reordering the coordinate steps.

_SUM = {"reassoc", "nsz"}
_MAX_CELLS = 2**31  # flat cell indices are 32-bit


@nb.njit(cache=True)
def _points32(pts: Array) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    m = pts.shape[0]
    xs = np.empty(m, np.float32)
    ys = np.empty(m, np.float32)
    for k in range(m):
        xs[k] = pts[k, 0]
        ys[k] = pts[k, 1]
    return xs, ys


@nb.njit(cache=True)
def _frame32(x: float, y: float, th: float, ox: float, oy: float, inv_res: float) -> tuple:
    """cos and sin of the heading in cells per metre, and the position in cells."""
    return (np.float32(np.cos(th) * inv_res), np.float32(np.sin(th) * inv_res),
            np.float32((x - ox) * inv_res), np.float32((y - oy) * inv_res))


@nb.njit(cache=True, inline="always")
def _project(c, s, fx0, fy0, x, y) -> tuple:
    """Cell coordinates of robot-frame point (x, y), in the twins' order of operations."""
    return fx0 + c * x - s * y, fy0 + s * x + c * y


@nb.njit(cache=True, inline="always")
def _lookup(flat, fx, fy, hf, wf, wu) -> tuple:
    """Whether (fx, fy) lies on the grid, and the value of its cell (of cell 0 if not)."""
    zero = np.float32(0.0)
    ok = (fx >= zero) & (fx < wf) & (fy >= zero) & (fy < hf)
    return ok, flat[np.uint32(fy) * wu + np.uint32(fx) if ok else np.uint32(0)]


@nb.njit(cache=True, fastmath=_SUM)
def _clipped_sum(flat, xs, ys, c, s, fx0, fy0, h: int, w: int, lo: np.float32, hi: np.float32) -> float:
    """Sum over the points of the map value clipped to [lo, hi]; points off the grid add 0."""
    hf, wf, wu = np.float32(h), np.float32(w), np.uint32(w)
    zero = np.float32(0.0)
    acc = zero
    for k in range(xs.shape[0]):
        fx, fy = _project(c, s, fx0, fy0, xs[k], ys[k])
        ok, v = _lookup(flat, fx, fy, hf, wf, wu)
        v = min(hi, max(lo, v))
        acc += v if ok else zero
    return acc


@nb.njit(cache=True, fastmath=_SUM)
def _field_sum(flat, xs, ys, c, s, fx0, fy0, h: int, w: int, floor: np.float32) -> float:
    """Sum over the points of the map value; points off the grid add ``floor``."""
    hf, wf, wu = np.float32(h), np.float32(w), np.uint32(w)
    acc = np.float32(0.0)
    for k in range(xs.shape[0]):
        fx, fy = _project(c, s, fx0, fy0, xs[k], ys[k])
        ok, v = _lookup(flat, fx, fy, hf, wf, wu)
        acc += v if ok else floor
    return acc


@nb.njit(cache=True)
def _check_size(h: int, w: int) -> None:
    if h * w >= _MAX_CELLS:
        raise ValueError("grid too large for the scoring kernels (2^31 cells or more)")


def _project_numpy(poses: Array, pts: Array, ox: float, oy: float, inv_res: float) -> tuple[Array, Array]:
    """Cell coordinates (fx, fy) of every particle's points, float32 in the kernels' order."""
    xs = pts[:, 0].astype(np.float32)
    ys = pts[:, 1].astype(np.float32)
    c = (np.cos(poses[:, 2]) * inv_res).astype(np.float32)[:, None]
    s = (np.sin(poses[:, 2]) * inv_res).astype(np.float32)[:, None]
    fx0 = ((poses[:, 0] - ox) * inv_res).astype(np.float32)[:, None]
    fy0 = ((poses[:, 1] - oy) * inv_res).astype(np.float32)[:, None]
    return fx0 + c * xs - s * ys, fy0 + s * xs + c * ys


# --- correlation scoring (SLAM) ---------------------------------------------------------
#
# The map value of a cell is its log-odds divided by ``sat`` and clipped to [lo, 1]:
# confirmed walls count +1, unknown 0, confirmed free space ``lo`` (-1 counts free space
# as strongly against a hit as a wall for it; 0 ignores free space). The kernels clip in
# log-odds units (to [lo * sat, sat]) and divide the sum once.


@nb.njit(cache=True)
def correlation_kernel(
    poses: Array, pts: Array, logodds: NDArray[np.float32], ox: float, oy: float, inv_res: float, inv_sat: float, lo: float
) -> Array:
    """Correlation score of every particle: the sum of map values at its projected hits."""
    n = poses.shape[0]
    h, w = logodds.shape
    _check_size(h, w)
    flat = logodds.ravel()
    xs, ys = _points32(pts)
    hi = np.float32(1.0 / inv_sat)
    lo32 = np.float32(lo / inv_sat)
    out = np.empty(n)
    for i in range(n):
        c, s, fx0, fy0 = _frame32(poses[i, 0], poses[i, 1], poses[i, 2], ox, oy, inv_res)
        out[i] = _clipped_sum(flat, xs, ys, c, s, fx0, fy0, h, w, lo32, hi) * inv_sat
    return out


def _cells_numpy(poses: Array, pts: Array, ox: float, oy: float, inv_res: float) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    fx, fy = _project_numpy(poses, pts, ox, oy, inv_res)
    return np.floor(fy).astype(np.int64), np.floor(fx).astype(np.int64)


def _values_numpy(
    logodds: NDArray[np.float32], row: NDArray[np.int64], col: NDArray[np.int64], inv_sat: float, lo: float
) -> Array:
    h, w = logodds.shape
    inside = (row >= 0) & (row < h) & (col >= 0) & (col < w)
    v = np.zeros(row.shape)
    v[inside] = np.clip(logodds[row[inside], col[inside]], np.float32(lo / inv_sat), np.float32(1.0 / inv_sat))
    return v.sum(axis=-1) * inv_sat


def correlation_numpy(
    poses: Array, pts: Array, logodds: NDArray[np.float32], ox: float, oy: float, inv_res: float, inv_sat: float, lo: float
) -> Array:
    """NumPy twin of :func:`correlation_kernel`."""
    row, col = _cells_numpy(poses, pts, ox, oy, inv_res)
    return _values_numpy(logodds, row, col, inv_sat, lo)


@nb.njit(cache=True)
def _grid_cells(xs, ys, c, s, fx0, fy0, rows: NDArray[np.int32], cols: NDArray[np.int32]) -> None:
    """Row and column of each point's cell (may lie off the grid; clamped to ±2^30)."""
    big = np.float32(2.0**30)
    for k in range(xs.shape[0]):
        fx, fy = _project(c, s, fx0, fy0, xs[k], ys[k])
        fx = np.floor(fx)
        fy = np.floor(fy)
        cols[k] = np.int32(min(big, max(-big, fx)))
        rows[k] = np.int32(min(big, max(-big, fy)))


@nb.njit(cache=True, fastmath=_SUM)
def _shifted_sum(flat: NDArray[np.float32], base: NDArray[np.int32], off: int, lo: np.float32, hi: np.float32) -> float:
    acc = np.float32(0.0)
    for k in range(base.shape[0]):
        acc += min(hi, max(lo, flat[np.uint32(base[k] + off)]))  # base + off lies on the grid
    return acc


@nb.njit(cache=True, fastmath=_SUM)
def _shifted_sum_checked(flat: NDArray[np.float32], rows: NDArray[np.int32], cols: NDArray[np.int32], dr: int,
                         dc: int, h: int, w: int, lo: np.float32, hi: np.float32) -> float:
    hu = np.uint32(h)
    wu = np.uint32(w)
    acc = np.float32(0.0)
    for k in range(rows.shape[0]):
        r = np.uint32(rows[k] + dr)
        c = np.uint32(cols[k] + dc)
        ok = (r < hu) & (c < wu)
        v = min(hi, max(lo, flat[r * wu + c if ok else np.uint32(0)]))
        acc += v if ok else np.float32(0.0)
    return acc


@nb.njit(cache=True)
def search_kernel(
    poses: Array,
    pts: Array,
    logodds: NDArray[np.float32],
    ox: float,
    oy: float,
    inv_res: float,
    inv_sat: float,
    lo: float,
    dcells: NDArray[np.int64],
    dthetas: Array,
) -> tuple[Array, NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """Best correlation over a local grid of whole-cell x/y shifts and heading offsets.

    Returns the best score of each particle and the indices (into ``dcells`` for x and
    y, into ``dthetas`` for theta) of its best offset. Shifts are whole cells, so the
    cell of each point is computed once per heading and shifted by integers; when every
    shifted cell stays on the grid the sums skip the bounds checks.
    """
    n = poses.shape[0]
    m = pts.shape[0]
    nc = dcells.shape[0]
    nt = dthetas.shape[0]
    h, w = logodds.shape
    _check_size(h, w)
    flat = logodds.ravel()
    xs, ys = _points32(pts)
    hi = np.float32(1.0 / inv_sat)
    lo32 = np.float32(lo / inv_sat)
    dmin = dcells.min()
    dmax = dcells.max()
    best = np.full(n, -np.inf)
    bx = np.zeros(n, dtype=np.int64)
    by = np.zeros(n, dtype=np.int64)
    bt = np.zeros(n, dtype=np.int64)
    rows = np.empty(m, dtype=np.int32)
    cols = np.empty(m, dtype=np.int32)
    base = np.empty(m, dtype=np.int32)  # flat cell index (grids of < 2^31 cells)
    for i in range(n):
        for t in range(nt):
            c, s, fx0, fy0 = _frame32(poses[i, 0], poses[i, 1], poses[i, 2] + dthetas[t], ox, oy, inv_res)
            _grid_cells(xs, ys, c, s, fx0, fy0, rows, cols)
            fits = m == 0 or (rows.min() + dmin >= 0 and rows.max() + dmax < h
                              and cols.min() + dmin >= 0 and cols.max() + dmax < w)
            if fits:
                for k in range(m):
                    base[k] = rows[k] * w + cols[k]
            for a in range(nc):
                for b in range(nc):
                    if fits:
                        acc = _shifted_sum(flat, base, dcells[b] * w + dcells[a], lo32, hi)
                    else:
                        acc = _shifted_sum_checked(flat, rows, cols, dcells[b], dcells[a], h, w, lo32, hi)
                    # Ties keep the earliest offset; put zero offsets first for stability.
                    score = acc * inv_sat
                    if score > best[i]:
                        best[i] = score
                        bx[i] = a
                        by[i] = b
                        bt[i] = t
    return best, bx, by, bt


def search_numpy(
    poses: Array,
    pts: Array,
    logodds: NDArray[np.float32],
    ox: float,
    oy: float,
    inv_res: float,
    inv_sat: float,
    lo: float,
    dcells: NDArray[np.int64],
    dthetas: Array,
) -> tuple[Array, NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """NumPy twin of :func:`search_kernel`."""
    n = len(poses)
    nc, nt = len(dcells), len(dthetas)
    scores = np.empty((n, nt, nc, nc))
    for t, dth in enumerate(dthetas):
        row, col = _cells_numpy(poses + np.array([0.0, 0.0, dth]), pts, ox, oy, inv_res)
        for a, dx in enumerate(dcells):
            for b, dy in enumerate(dcells):
                scores[:, t, a, b] = _values_numpy(logodds, row + dy, col + dx, inv_sat, lo)
    flat = scores.reshape(n, -1)
    j = np.argmax(flat, axis=1)
    t, a, b = np.unravel_index(j, (nt, nc, nc))
    return flat[np.arange(n), j], a.astype(np.int64), b.astype(np.int64), t.astype(np.int64)


# --- likelihood field lookup (localization) ---------------------------------------------


@nb.njit(cache=True)
def likelihood_kernel(
    poses: Array, pts: Array, logp: NDArray[np.float32], ox: float, oy: float, inv_res: float, floor: float
) -> Array:
    """Sum over beam end points of the log-probability field, for every particle.

    End points off the map count ``floor`` (the random-measurement term alone).
    """
    n = poses.shape[0]
    h, w = logp.shape
    _check_size(h, w)
    flat = logp.ravel()
    xs, ys = _points32(pts)
    fl = np.float32(floor)
    out = np.empty(n)
    for i in range(n):
        c, s, fx0, fy0 = _frame32(poses[i, 0], poses[i, 1], poses[i, 2], ox, oy, inv_res)
        out[i] = _field_sum(flat, xs, ys, c, s, fx0, fy0, h, w, fl)
    return out


def likelihood_numpy(
    poses: Array, pts: Array, logp: NDArray[np.float32], ox: float, oy: float, inv_res: float, floor: float
) -> Array:
    """NumPy twin of :func:`likelihood_kernel`."""
    row, col = _cells_numpy(poses, pts, ox, oy, inv_res)
    h, w = logp.shape
    inside = (row >= 0) & (row < h) & (col >= 0) & (col < w)
    v = np.full(row.shape, np.float32(floor), dtype=np.float64)
    v[inside] = logp[row[inside], col[inside]]
    return v.sum(axis=-1)


# --- beam model (localization, for comparison with the likelihood field) ----------------


@nb.njit(cache=True)
def cast_ray(occ: NDArray[np.uint8], ox: float, oy: float, inv_res: float, x0: float, y0: float, ux: float,
             uy: float, max_range: float) -> float:
    """Distance from (x0, y0) along the unit direction (ux, uy) to the first occupied cell
    (exact grid traversal); ``max_range`` if none is met or the ray leaves the grid."""
    h, w = occ.shape
    fx = (x0 - ox) * inv_res
    fy = (y0 - oy) * inv_res
    c = int(np.floor(fx))
    r = int(np.floor(fy))
    sc, tmx, tdx = _axis_setup(fx, fx + ux)
    sr, tmy, tdy = _axis_setup(fy, fy + uy)
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
def _beam_logp(z: float, zs: float, max_range: float, sigma: float, z_hit: float, z_short: float, lam: float,
               z_rand: float) -> float:
    p = z_hit * np.exp(-0.5 * ((z - zs) / sigma) ** 2) / (sigma * np.sqrt(2.0 * np.pi)) + z_rand / max_range
    if z < zs:
        p += z_short * lam * np.exp(-lam * z)
    return np.log(p)


@nb.njit(cache=True)
def beam_kernel(poses: Array, sensor_xy: Array, pts: Array, occ: NDArray[np.uint8], ox: float, oy: float,
                inv_res: float, max_range: float, sigma: float, z_hit: float, z_short: float, lam: float,
                z_rand: float) -> Array:
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


def beam_numpy(poses: Array, sensor_xy: Array, pts: Array, occ: NDArray[np.uint8], ox: float, oy: float,
               inv_res: float, max_range: float, sigma: float, z_hit: float, z_short: float, lam: float,
               z_rand: float) -> Array:
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
    zs = np.array([[cast(occ, ox, oy, inv_res, sx[i, 0], sy[i, 0], ux[i, k], uy[i, k], max_range)
                    for k in range(ux.shape[1])] for i in range(ux.shape[0])]).reshape(ux.shape)
    p = z_hit * np.exp(-0.5 * ((z - zs) / sigma) ** 2) / (sigma * np.sqrt(2 * np.pi)) + z_rand / max_range
    p = p + np.where(z < zs, z_short * lam * np.exp(-lam * z), 0.0)
    return np.log(p).sum(axis=1)


# --- systematic resampling -----------------------------------------------------------------


@nb.njit(cache=True)
def systematic_kernel(w: Array, u0: float, out: NDArray[np.int64]) -> None:
    """Systematic (low-variance) resampling into ``out``: pointer ``i`` is (u0 + i) / n with
    offset ``u0`` in [0, 1) and n = len(out), and gets the first index whose cumulative weight
    exceeds it (the last index if none does). One walk along the weights, O(N + n), no
    allocation; ``w`` must sum to 1."""
    m = w.shape[0]
    n = out.shape[0]
    inv_n = 1.0 / n
    last = m - 1
    j = 0
    c = w[0]  # cumulative weight up to and including j
    for i in range(n):
        u = (u0 + i) * inv_n
        while j < last and c <= u:
            j += 1
            c += w[j]
        out[i] = j


def systematic_numpy(w: Array, u0: float, out: NDArray[np.int64]) -> None:
    """NumPy twin of :func:`systematic_kernel` (binary search of every pointer)."""
    c = np.cumsum(np.asarray(w, dtype=float))
    c[-1] = 1.0
    u = (u0 + np.arange(len(out))) * (1.0 / len(out))
    np.minimum(np.searchsorted(c, u, side="right"), len(c) - 1, out=out)
