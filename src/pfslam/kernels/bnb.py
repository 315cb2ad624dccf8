"""Loop-closure matching: a scan against a local map over a wide window, by branch and bound
over max-pooled grids (the fast correlative scan matcher of Cartographer's paper, Hess et
al. 2016), then a sub-cell refinement on the bilinearly read grid.

The map is a score grid ``g[row, col]`` in [0, 1] (row = y, col = x; the lower-left corner
of cell (0, 0) at ``(ox, oy)``). Level ``h`` of the pyramid holds at each cell the largest
value of the ``2^h x 2^h`` block whose lower-left cell it is, so the mean over the points of
level ``h`` bounds the score of every offset of the block from above: a candidate whose
bound is below the best complete match so far is never opened.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import NDArray

from pfslam.types import Array

Grid = NDArray[np.float32]


@nb.njit(cache=True, nogil=True)
def pyramid_kernel(grid: Grid, depth: int) -> Grid:
    """The ``(depth, H, W)`` max-pooled levels of ``grid`` (level 0 is ``grid``); cells past
    the grid's edge count 0."""
    h, w = grid.shape
    out = np.zeros((depth, h, w), dtype=np.float32)
    out[0] = grid
    tmp = np.zeros((h, w), dtype=np.float32)
    for lv in range(1, depth):
        half = 1 << (lv - 1)
        prev = out[lv - 1]
        # level lv = max of four level lv-1 blocks offset by half
        for r in range(h):
            for c in range(w):
                v = prev[r, c]
                if c + half < w and prev[r, c + half] > v:
                    v = prev[r, c + half]
                tmp[r, c] = v
        for r in range(h):
            for c in range(w):
                v = tmp[r, c]
                if r + half < h and tmp[r + half, c] > v:
                    v = tmp[r + half, c]
                out[lv, r, c] = v
    return out


@nb.njit(cache=True, nogil=True)
def _level_score(
    level: Grid, cols: NDArray[np.int32], rows: NDArray[np.int32], dc: int, dr: int, size: int, beat: float = -1.0
) -> float:
    """Mean over the points of the level-``size`` block maxima at their cells moved by (dc, dr).
    A block that starts left of or below the grid but reaches into it is bounded by the block
    at the edge (which covers all of the grid's part of it). With ``beat``: cut short, at some
    figure no higher than ``beat``, once the points left could not lift the mean above it
    even all at 1 (the grid's values lie in [0, 1]): a caller that drops what does not beat
    ``beat`` drops the same candidates, and reads a fifth fewer cells in a wide search."""
    h, w = level.shape
    acc = 0.0
    n = cols.shape[0]
    need = beat * n
    for k in range(n):
        if (k & 15) == 0 and acc + (n - k) <= need:
            return acc / max(n, 1)
        c = cols[k] + dc
        r = rows[k] + dr
        if c < 0:
            c = 0 if c + size > 0 else w
        if r < 0:
            r = 0 if r + size > 0 else h
        if r < h and c < w:
            acc += level[r, c]
    return acc / max(cols.shape[0], 1)


@nb.njit(cache=True, nogil=True, inline="always")
def _top_level(
    pyramid: Grid, cols: NDArray[np.int32], rows: NDArray[np.int32], window: int, beat: float = -1.0
) -> tuple[NDArray[np.float64], NDArray[np.int32], NDArray[np.int32], NDArray[np.int32]]:
    """The coarsest level's blocks of a search over offsets ``-window..window`` cells: their
    scores (upper bounds of every match inside; those not above ``beat`` cut short, see
    :func:`_level_score`) and (rotation, column offset, row offset)."""
    depth = pyramid.shape[0]
    n_rot = cols.shape[0]
    top = depth - 1
    step = 1 << top
    n_side = (2 * window) // step + 1
    n_first = n_rot * n_side * n_side
    first_s = np.empty(n_first, dtype=np.float64)
    first_k = np.empty(n_first, dtype=np.int32)
    first_c = np.empty(n_first, dtype=np.int32)
    first_r = np.empty(n_first, dtype=np.int32)
    m = 0
    for k in range(n_rot):
        for i in range(n_side):
            for j in range(n_side):
                dc = -window + i * step
                dr = -window + j * step
                first_s[m] = _level_score(pyramid[top], cols[k], rows[k], dc, dr, step, beat)
                first_k[m] = k
                first_c[m] = dc
                first_r[m] = dr
                m += 1
    return first_s, first_k, first_c, first_r


@nb.njit(cache=True, nogil=True)
def bnb_kernel(
    pyramid: Grid,
    cols: NDArray[np.int32],
    rows: NDArray[np.int32],
    window: int,
    min_score: float,
    skip_k: int,
    skip_c: int,
    skip_r: int,
    skip_cells: int,
    skip_rot: int,
) -> tuple[float, int, int, int]:
    """The best (score, rotation, column offset, row offset) of the discretised points
        (``cols``/``rows``: (rotations, points) cells of each rotation at the guess) over offsets
        ``-window..window`` cells, or score -1 if none reaches ``min_score``. With ``skip_k`` >= 0 (-1:
    none, the other skip arguments then unused),
        the matches within ``skip_rot`` rotations and ``skip_cells`` cells (each axis) of
        (``skip_k``, ``skip_c``, ``skip_r``) are left out: the best match elsewhere, the runner-up
        that says whether the best one is ambiguous."""
    depth = pyramid.shape[0]
    n_rot = cols.shape[0]
    top = depth - 1
    step = 1 << top
    n_side = (2 * window) // step + 1
    n_first = n_rot * n_side * n_side
    cap = n_first + 4 * depth + 8
    st_k = np.empty(cap, dtype=np.int32)
    st_c = np.empty(cap, dtype=np.int32)
    st_r = np.empty(cap, dtype=np.int32)
    st_h = np.empty(cap, dtype=np.int32)
    st_s = np.empty(cap, dtype=np.float64)
    # The top level's candidates, pushed worst first so that the best is opened first.
    first_s, first_k, first_c, first_r = _top_level(pyramid, cols, rows, window, min_score)
    order = np.argsort(first_s)
    sp = 0
    for q in range(n_first):
        o = order[q]
        if first_s[o] <= min_score:
            continue
        st_k[sp] = first_k[o]
        st_c[sp] = first_c[o]
        st_r[sp] = first_r[o]
        st_h[sp] = top
        st_s[sp] = first_s[o]
        sp += 1
    best_s, best_k, best_c, best_r = min_score, -1, 0, 0
    ch_s = np.empty(4, dtype=np.float64)
    ch_c = np.empty(4, dtype=np.int32)
    ch_r = np.empty(4, dtype=np.int32)
    while sp > 0:
        sp -= 1
        k, dc, dr, h, s = st_k[sp], st_c[sp], st_r[sp], st_h[sp], st_s[sp]
        if s <= best_s:
            continue
        if h == 0:
            if (
                skip_k >= 0
                and abs(k - skip_k) <= skip_rot
                and abs(dc - skip_c) <= skip_cells
                and abs(dr - skip_r) <= skip_cells
            ):
                continue
            best_s, best_k, best_c, best_r = s, k, dc, dr
            continue
        half = 1 << (h - 1)
        nc = 0
        for a in range(2):
            for b in range(2):
                cc = dc + a * half
                rr = dr + b * half
                if cc > window or rr > window:
                    continue
                ch_s[nc] = _level_score(pyramid[h - 1], cols[k], rows[k], cc, rr, half, best_s)
                ch_c[nc] = cc
                ch_r[nc] = rr
                nc += 1
        # push the children worst first
        for _ in range(nc):
            w_i = -1
            w_s = np.inf
            for q in range(nc):
                if ch_s[q] < w_s:
                    w_s = ch_s[q]
                    w_i = q
            if w_s > best_s:
                st_k[sp] = k
                st_c[sp] = ch_c[w_i]
                st_r[sp] = ch_r[w_i]
                st_h[sp] = h - 1
                st_s[sp] = w_s
                sp += 1
            ch_s[w_i] = np.inf
    if best_k < 0:
        return -1.0, -1, 0, 0
    return best_s, best_k, best_c, best_r


@nb.njit(cache=True, nogil=True)
def bilinear_score_kernel(grid: Grid, pts: Array, pose: Array, ox: float, oy: float, res: float) -> float:
    """Mean over the points (in the scan's frame, placed at ``pose`` in the grid's frame) of
    the grid read with bilinear interpolation between cell centres (0 off the grid)."""
    h, w = grid.shape
    c, s = np.cos(pose[2]), np.sin(pose[2])
    acc = 0.0
    for k in range(pts.shape[0]):
        x = pose[0] + c * pts[k, 0] - s * pts[k, 1]
        y = pose[1] + s * pts[k, 0] + c * pts[k, 1]
        fx = (x - ox) / res - 0.5
        fy = (y - oy) / res - 0.5
        c0 = int(np.floor(fx))
        r0 = int(np.floor(fy))
        ax = fx - c0
        ay = fy - r0
        v = 0.0
        for dr in range(2):
            for dc in range(2):
                r = r0 + dr
                cc = c0 + dc
                if 0 <= r < h and 0 <= cc < w:
                    wgt = (ax if dc else 1.0 - ax) * (ay if dr else 1.0 - ay)
                    v += wgt * grid[r, cc]
        acc += v
    return acc / max(pts.shape[0], 1)


@nb.njit(cache=True, nogil=True)
def refine_kernel(
    grid: Grid,
    pts: Array,
    pose: Array,
    ox: float,
    oy: float,
    res: float,
    lstep: float,
    astep: float,
    halvings: int,
) -> tuple[Array, float]:
    """Hill climbing in x, y, theta on the bilinear score from ``pose``, the steps halved
    ``halvings`` times when no move helps: the pose and its score."""
    best = pose.copy()
    best_s = bilinear_score_kernel(grid, pts, best, ox, oy, res)
    trial = best.copy()
    for _ in range(halvings + 1):
        moved = True
        it = 0
        while moved and it < 50:
            moved = False
            it += 1
            for d in range(6):
                trial[:] = best
                axis = d // 2
                sign = 1.0 if d % 2 == 0 else -1.0
                trial[axis] += sign * (astep if axis == 2 else lstep)
                s = bilinear_score_kernel(grid, pts, trial, ox, oy, res)
                if s > best_s:
                    best_s = s
                    best[:] = trial
                    moved = True
        lstep *= 0.5
        astep *= 0.5
    return best, best_s


def bnb_numpy(
    grid: Grid, cols: NDArray[np.int32], rows: NDArray[np.int32], window: int, min_score: float
) -> tuple[float, int, int, int]:
    """The exhaustive twin of :func:`bnb_kernel`: every rotation and offset scored on ``grid``."""
    h, w = grid.shape
    best = (-1.0, -1, 0, 0)
    best_s = min_score
    for k in range(cols.shape[0]):
        for dc in range(-window, window + 1):
            c = cols[k] + dc
            okc = (c >= 0) & (c < w)
            for dr in range(-window, window + 1):
                r = rows[k] + dr
                ok = okc & (r >= 0) & (r < h)
                s = float(grid[r[ok], c[ok]].sum()) / max(len(c), 1)
                if s > best_s:
                    best_s = s
                    best = (s, k, dc, dr)
    return best


@nb.njit(cache=True, nogil=True)
def field_kernel(occupied: NDArray[np.bool_], sigma_cells: float, radius: int) -> Grid:
    """exp(-d^2 / 2 sigma^2) of each cell's distance d (cells) to the nearest occupied cell
    within ``radius`` cells (0 farther), by stamping each occupied cell's neighbourhood."""
    h, w = occupied.shape
    out = np.zeros((h, w), dtype=np.float32)
    k = 2 * radius + 1
    stamp = np.empty((k, k), dtype=np.float32)
    for dr in range(-radius, radius + 1):
        for dc in range(-radius, radius + 1):
            stamp[dr + radius, dc + radius] = np.exp(-0.5 * (dr * dr + dc * dc) / (sigma_cells * sigma_cells))
    for r in range(h):
        for c in range(w):
            if not occupied[r, c]:
                continue
            for dr in range(-radius, radius + 1):
                rr = r + dr
                if rr < 0 or rr >= h:
                    continue
                for dc in range(-radius, radius + 1):
                    cc = c + dc
                    if 0 <= cc < w:
                        v = stamp[dr + radius, dc + radius]
                        if v > out[rr, cc]:
                            out[rr, cc] = v
    return out


@nb.njit(cache=True, nogil=True)
def bnb_all_kernel(
    pyramid: Grid, cols: NDArray[np.int32], rows: NDArray[np.int32], window: int, min_score: float, cap: int
) -> tuple[NDArray[np.float64], NDArray[np.int32], bool]:
    """Every match of :func:`bnb_kernel`'s search that scores at least ``min_score``: their
    scores and (rotation, column offset, row offset) rows, by branch and bound pruned by
    ``min_score`` alone; at most ``cap`` of them (and True if more were left out)."""
    depth = pyramid.shape[0]
    top = depth - 1
    first_s, first_k, first_c, first_r = _top_level(pyramid, cols, rows, window)
    st = np.empty((len(first_s) + 4 * depth + 8, 4), dtype=np.int32)
    sp = 0
    for m in range(len(first_s)):
        if first_s[m] >= min_score:
            st[sp, 0], st[sp, 1], st[sp, 2], st[sp, 3] = first_k[m], first_c[m], first_r[m], top
            sp += 1
    out_s = np.empty(cap, dtype=np.float64)
    out = np.empty((cap, 3), dtype=np.int32)
    n = 0
    more = False
    while sp > 0:
        sp -= 1
        k, dc, dr, h = st[sp, 0], st[sp, 1], st[sp, 2], st[sp, 3]
        if h == 0:
            if n < cap:
                out_s[n] = _level_score(pyramid[0], cols[k], rows[k], dc, dr, 1)
                out[n, 0], out[n, 1], out[n, 2] = k, dc, dr
                n += 1
            else:
                more = True
            continue
        half = 1 << (h - 1)
        for a in range(2):
            for b in range(2):
                cc = dc + a * half
                rr = dr + b * half
                if cc > window or rr > window:
                    continue
                if _level_score(pyramid[h - 1], cols[k], rows[k], cc, rr, half) >= min_score:
                    st[sp, 0], st[sp, 1], st[sp, 2], st[sp, 3] = k, cc, rr, h - 1
                    sp += 1
    return out_s[:n], out[:n], more


def rotated_cells(
    pts: Array, x0: float, y0: float, angles: NDArray[np.floating], ox: float, oy: float, res: float
) -> tuple[NDArray[np.int32], NDArray[np.int32]]:
    """The cells (columns, rows: (rotations, points)) of the points ``pts`` ((N, 2)) turned by
    each of ``angles`` and placed at (``x0``, ``y0``), on a grid of cells ``res`` wide whose
    lower-left corner is (``ox``, ``oy``): what the searches above take."""
    cs, sn = np.cos(angles)[:, None], np.sin(angles)[:, None]
    x = x0 + cs * pts[None, :, 0] - sn * pts[None, :, 1]
    y = y0 + sn * pts[None, :, 0] + cs * pts[None, :, 1]
    return np.floor((x - ox) / res).astype(np.int32), np.floor((y - oy) / res).astype(np.int32)


@dataclass
class Found:
    """A branch-and-bound match: its ``score`` (the points' mean on the grid, 0..1), its heading
    index ``k`` and cell offsets ``dc``, ``dr``, and the ``pose`` they make (x, y, theta in the
    grid's frame, at cell precision: before any refinement)."""

    score: float
    k: int
    dc: int
    dr: int
    pose: Array


class WindowSearch:
    """One branch-and-bound search of a scan over a window (the fast correlative matcher of the
    module notes), below every caller that needs one (the back end's loop match, a resumed
    run's start, the localizer's global start), each keeping only its policy: which points,
    where, which headings, how wide, what score is enough and what counts as elsewhere.

    ``pts`` (robot frame, (N, 2)) turned by each of ``angles`` and placed at (``x``, ``y``) on
    a score grid of cells ``res`` wide (lower-left corner at (``ox``, ``oy``); ``pyramid``: its
    max-pooled levels, values in [0, 1]), moved by up to ``window`` cells along each axis."""

    def __init__(
        self,
        pyramid: Grid,
        pts: Array,
        x: float,
        y: float,
        angles: NDArray[np.floating],
        window: int,
        ox: float,
        oy: float,
        res: float,
    ) -> None:
        self.pyramid, self.x, self.y, self.angles, self.window, self.res = pyramid, x, y, angles, window, res
        self.cols, self.rows = rotated_cells(pts, x, y, angles, ox, oy, res)

    def _found(self, score: float, k: int, dc: int, dr: int) -> Found | None:
        if k < 0:
            return None
        pose = np.array([self.x + dc * self.res, self.y + dr * self.res, self.angles[k]])
        return Found(float(score), int(k), int(dc), int(dr), pose)

    def best(self, min_score: float) -> Found | None:
        """The best match, None if none scores above ``min_score``."""
        return self._found(*bnb_kernel(self.pyramid, self.cols, self.rows, self.window, min_score, -1, 0, 0, 0, 0))

    def elsewhere(self, best: Found, min_score: float, away_cells: int, away_turns: int) -> Found | None:
        """The best match more than ``away_cells`` cells (along either axis) or ``away_turns``
        heading steps from ``best``: the runner-up that says whether ``best`` is ambiguous; None
        if none scores above ``min_score``."""
        got = bnb_kernel(
            self.pyramid, self.cols, self.rows, self.window, min_score, best.k, best.dc, best.dr, away_cells, away_turns
        )
        return self._found(*got)

    def every(self, min_score: float, cap: int) -> tuple[NDArray[np.float64], NDArray[np.int32], bool]:
        """Every match scoring at least ``min_score`` (:func:`bnb_all_kernel`): their scores and
        (heading, column offset, row offset) rows, at most ``cap`` (True if more were left)."""
        return bnb_all_kernel(self.pyramid, self.cols, self.rows, self.window, min_score, cap)


def score_field(
    occ: NDArray[np.bool_], origin: Array, res: float, sigma: float, depth: int
) -> tuple[NDArray[np.float32], NDArray[np.float32], float, float] | None:
    """The score field exp(-d^2 / 2 sigma^2) of the occupied cells ``occ`` of a grid (its
    lower-left corner at ``origin``, cells ``res`` wide), cropped to them with a margin of 3
    sigma, its max-pooled pyramid of ``depth`` levels, and the crop's lower-left corner (x, y);
    None if no cell is occupied. What the branch-and-bound searches match scans on."""
    if not occ.any():
        return None
    rows, cols = np.nonzero(occ)
    margin = int(np.ceil(3 * sigma / res)) + 1
    r0, r1 = max(rows.min() - margin, 0), min(rows.max() + margin + 1, occ.shape[0])
    c0, c1 = max(cols.min() - margin, 0), min(cols.max() + margin + 1, occ.shape[1])
    sig = sigma / res
    fld = field_kernel(np.ascontiguousarray(occ[r0:r1, c0:c1]), sig, int(np.ceil(3 * sig)))
    return fld, pyramid_kernel(fld, depth), float(origin[0] + c0 * res), float(origin[1] + r0 * res)


@nb.njit(cache=True, nogil=True)
def score_surface_kernel(grid: Grid, cols: NDArray[np.int32], rows: NDArray[np.int32], window: int) -> Grid:
    """The score of every offset of a scan within +-``window`` cells: ``out[a, window + dr,
    window + dc]`` is the mean over the points of the grid at the points' cells (``cols``,
    ``rows``: (rotations, points), as :func:`rotated_cells` gives them for each heading ``a``)
    moved by (``dc``, ``dr``) cells; 0 off the grid. The whole score surface a search's
    window holds, not only its peak."""
    h, w = grid.shape
    na, n = cols.shape
    size = 2 * window + 1
    out = np.zeros((na, size, size), dtype=np.float32)
    for a in range(na):
        for i in range(size):
            dr = i - window
            for j in range(size):
                dc = j - window
                acc = 0.0
                for k in range(n):
                    r = rows[a, k] + dr
                    c = cols[a, k] + dc
                    if 0 <= r < h and 0 <= c < w:
                        acc += grid[r, c]
                out[a, i, j] = acc / max(n, 1)
    return out


MAX_DEPTH = 7  # pyramid levels: the coarsest cell is 64 x 64 fine cells (3.2 m at 0.05 m)
MAX_ROTATIONS = 401  # headings tried per search, whatever the window and the scan's reach


@dataclass
class ScoreGrid:
    """A score grid ``field`` (values in [0, 1], cells ``res`` wide: the caller's), its
    max-pooled ``pyramid`` and the lower-left corner (``ox``, ``oy``) of its cell (0, 0): what
    :func:`window_match` matches points on."""

    field: Grid
    pyramid: Grid
    ox: float
    oy: float


def window_match(
    grid: ScoreGrid,
    pts: NDArray[np.floating],
    guess: Array,
    window_m: float,
    window_deg: float,
    min_score: float,
    res: float,
    coarse: bool = False,
    ambiguity: float = 0.0,
    why: list[str] | None = None,
) -> tuple[Array, float] | None:
    """The pose of the points ``pts`` (robot frame) on the score grid ``grid`` (cells ``res``
    wide) within
    ``window_m`` / ``window_deg`` of ``guess``, by branch and bound then sub-cell refinement;
    None if the best match scores below ``min_score``. The headings are tried a step apart
    that moves the farthest point by at most a cell (``coarse``: two cells, and every other
    point searched; the refinement uses them all). With ``ambiguity`` > 0, a match is refused
    when another one at least half a metre or 5 degrees away scores ``ambiguity`` times as
    well (and ``"ambiguous"`` appended to ``why``)."""
    p = pts.astype(np.float64)
    reach = float(np.hypot(p[:, 0], p[:, 1]).max()) if len(p) else 0.0
    if reach <= 0:
        return None
    step = float(np.arccos(max(1.0 - res**2 / (2.0 * reach**2), -1.0))) * (2 if coarse else 1)
    half = np.deg2rad(window_deg)
    n_side = min(int(np.ceil(half / step)), MAX_ROTATIONS // 2) if half > 0 else 0
    step = half / n_side if n_side else step
    angles = guess[2] + step * np.arange(-n_side, n_side + 1)
    q = p[::2] if coarse else p
    window = int(round(window_m / res))
    depth = min(pyramid_depth(window), grid.pyramid.shape[0])
    search = WindowSearch(grid.pyramid[:depth], q, guess[0], guess[1], angles, window, grid.ox, grid.oy, res)
    found = search.best(float(min_score))
    if found is None:
        return None
    if ambiguity > 0:
        # The best match elsewhere (half a metre or 5 degrees away): a corridor's walls match as
        # well a few metres along it, and a loop taken there would tear the map.
        away_turns = int(np.ceil(np.deg2rad(5.0) / step)) if step > 0 else 0
        if search.elsewhere(found, ambiguity * found.score, int(round(0.5 / res)), away_turns) is not None:
            if why is not None:
                why.append("ambiguous")
            return None
    pose, score = refine_kernel(grid.field, p, found.pose, grid.ox, grid.oy, res, res / 2, step, 4)
    if score < min_score:
        return None
    pose[2] = (pose[2] + np.pi) % (2.0 * np.pi) - np.pi
    return pose, float(score)


def pyramid_depth(window: int) -> int:
    """Pyramid levels for a search of +-``window`` cells: the coarsest block about spans it."""
    return int(min(MAX_DEPTH, max(1, np.ceil(np.log2(2 * window + 1)))))
