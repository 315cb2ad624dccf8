"""One occupancy map per particle at little cost: tiles shared copy-on-write.

:class:`TiledMaps` holds ``N`` log-odds maps on one grid geometry (resolution, origin,
extent). Each map is a table of tile numbers into a shared pool of ``T x T`` float32 tiles
(``T = 32`` by default); tile number -1 is a tile never written (all zero, unknown). After
resampling, a child's table is a copy of its parent's and the tiles are shared, counted by
``refs``; the first write to a shared tile copies it (:mod:`pfslam.kernels.tiled`). So
resampling copies tables, not cells, and memory grows with what the particles disagree
about, not with N x the map.

The Rao-Blackwellized filter is built on this; :meth:`dense` gives any particle's map as
an :class:`~pfslam.maps.grid.OccupancyGrid`-shaped array, for output and for the tests, which
check every operation against dense maps kept the naive way.
"""

from __future__ import annotations

import mmap
import os
from typing import Callable

import numba as nb
import numpy as np
from numpy.typing import NDArray

from pfslam.kernels.fit import tiled_fit_kernel, tiled_seen_through_kernel
from pfslam.kernels.refine import tiled_refine_kernel
from pfslam.kernels.tiled import (
    near_rows,
    own_tiles_kernel,
    segment_tiles_kernel,
    tiled_correlation_kernel,
    tiled_loglik_kernel,
    tiled_match_kernel,
    tiled_ray_update_kernel,
    tiled_scan_update_kernel,
)
from pfslam.maps.grid import MAX_CELLS, MapTooLarge
from pfslam.types import Array

POOL_BYTES = 1 << 30  # the tile pool's first reservation (address space, at most a quarter of the memory)
RELEASE_BYTES = 64 << 20  # free tiles' memory handed back to the system when it passes this (see TiledMaps.resample)


def _reservation() -> int:
    """Bytes of the pool's first reservation: :data:`POOL_BYTES`, at most a quarter of the
    machine's memory (so that the system never refuses the address space), and at least 256 MB.
    Reserved, not used: growing the pool later would hold the old and the new side by side (on
    the campus, with 256 MB first, the peak went from 1.37 to 1.87 GB)."""
    try:
        physical = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        physical = 4 * POOL_BYTES
    return int(max(256 << 20, min(POOL_BYTES, physical // 4)))


_PRIVATE = getattr(mmap, "MAP_PRIVATE", None)  # (not on Windows: there NumPy's own zeros, never handed back)
_ANONYMOUS = getattr(mmap, "MAP_ANONYMOUS", None)


def _mapped(shape: tuple[int, ...], dtype: type) -> tuple[NDArray, mmap.mmap | None]:
    """A zeroed array on private anonymous memory of its own: a page becomes memory when first
    touched, and :func:`_release` hands pages back to the system. Where the system has no
    such mapping, NumPy's zeros (mapped as lazily) and no buffer to hand back."""
    count = int(np.prod(shape))
    if _PRIVATE is None or _ANONYMOUS is None or not hasattr(mmap.mmap, "madvise"):
        return np.zeros(shape, dtype=dtype), None
    buf = mmap.mmap(-1, max(count * np.dtype(dtype).itemsize, 1), flags=_PRIVATE | _ANONYMOUS)
    # Huge pages where the system allows them, as NumPy asks for its own large arrays: a page
    # fault per 2 MB, not per 4 kB, and fewer TLB misses (without, FR079's map updates took 7 %
    # longer). A range handed back later splits its huge pages.
    if hasattr(mmap, "MADV_HUGEPAGE"):
        try:
            buf.madvise(mmap.MADV_HUGEPAGE)
        except OSError:
            pass
    return np.frombuffer(buf, dtype=dtype, count=count).reshape(shape), buf


def _release(buf: mmap.mmap | None, starts: NDArray[np.int64], ends: NDArray[np.int64], size: int) -> None:
    """Hand back to the system the whole pages of ``buf`` inside each run of items
    ``starts[k]..ends[k] - 1`` (items ``size`` bytes each): they read as zeros when next touched.
    (None: nothing to hand back, see :func:`_mapped`.)"""
    if buf is None:
        return
    page = mmap.PAGESIZE
    for a, b in zip((-(-(starts * size) // page) * page).tolist(), ((ends * size) // page * page).tolist()):
        if b > a:
            buf.madvise(mmap.MADV_DONTNEED, a, b - a)


# What every per-particle kernel of the tiled maps takes first (see TiledMaps._kernel_args).
KernelArgs = tuple[
    NDArray[np.int32], NDArray[np.float32], NDArray[np.uint16], int, Array, Array, float, float, float, float
]


class TiledMaps:
    """``n`` log-odds maps sharing copy-on-write tiles (see the module notes).

    Cell (row, col) of the grid is (floor((y - oy) / res), floor((x - ox) / res)); the grid
    is ``tables.shape[1:] x T`` cells and grows by whole tiles (:meth:`ensure_contains`).
    """

    def __init__(
        self,
        n: int,
        resolution: float = 0.05,
        origin: tuple[float, float] | Array = (0.0, 0.0),
        tile_shift: int = 5,
        l_occ: float = 3.0,
        l_free: float = -1.0,
        l_clamp: float = 120.0,
        capacity: int | None = None,
        release_bytes: int = RELEASE_BYTES,
    ) -> None:
        if n < 1:
            raise ValueError("at least one map")
        if not 2 <= tile_shift <= 8:
            raise ValueError("tiles of 4 to 256 cells a side")
        self.resolution = float(resolution)
        self.origin = np.array(origin, dtype=float)
        self.shift = int(tile_shift)
        self.tile = 1 << self.shift
        self.l_occ, self.l_free, self.l_clamp = float(l_occ), float(l_free), float(l_clamp)
        self.tables = np.full((n, 0, 0), -1, dtype=np.int32)
        # The pool's first ``capacity`` tiles (default: :func:`_reservation`, 1 GB of them) are
        # address space, not memory: a page becomes memory when a tile on it is first used, and
        # tiles are taken lowest number first. So the pool rarely grows: growing copies the
        # tiles in use (old and new side by side for a moment). After a burst of copies (30
        # particles diverging over an open square), the tiles resampling frees are handed back
        # to the system (:meth:`resample`).
        if capacity is None:
            capacity = _reservation() // (self.tile * self.tile * 4)
        self._alloc(max(capacity, 1))
        self.refs = np.zeros(len(self.pool), dtype=np.int32)
        self.free = np.arange(len(self.pool) - 1, -1, -1, dtype=np.int32)  # a stack: the top is free[nfree - 1]
        self.nfree = np.array([len(self.pool)], dtype=np.int64)
        self._marks = np.zeros((0, 0), dtype=np.uint8)
        self._touched = 0  # tiles below this number may hold memory (handed out since the last release)
        self.release_bytes = release_bytes
        self.released_mb = 0.0  # memory handed back to the system so far

    def _alloc(self, tiles: int) -> None:
        """A new, zeroed pool and near cache of ``tiles`` tiles (each on memory of its own)."""
        self.pool, self._pool_buf = _mapped((tiles, self.tile, self.tile), np.float32)
        # Each tile's near cache, then their stale flags (see pfslam.kernels.tiled): zeros,
        # mapped as the pool.
        self.near, self._near_buf = _mapped((near_rows(tiles, self.shift), self.tile, self.tile), np.uint16)

    # -- geometry ------------------------------------------------------------------

    @property
    def n(self) -> int:
        return self.tables.shape[0]

    @property
    def shape(self) -> tuple[int, int]:
        """The grid's size in cells (rows, cols)."""
        return self.tables.shape[1] * self.tile, self.tables.shape[2] * self.tile

    @property
    def unique_tiles(self) -> int:
        """Tiles in use (each counted once however many maps share it)."""
        return int(len(self.pool) - self.nfree[0])

    @property
    def nbytes(self) -> int:
        """Bytes of the tiles in use (log-odds and near cache) and of the tables."""
        cell = self.pool.itemsize + self.near.itemsize
        return self.unique_tiles * self.tile * self.tile * cell + self.tables.nbytes

    def ensure_contains(self, xmin: float, ymin: float, xmax: float, ymax: float) -> bool:
        """Grow every table (by whole tiles, at least half its size on a side that must grow)
        so the box lies inside the grid; the cells keep their world position. Returns
        whether it grew; MapTooLarge past ``MAX_CELLS`` cells."""
        t, res = self.tile, self.resolution
        th, tw = self.tables.shape[1:]
        ox, oy = self.origin
        if th == 0:  # the first box: a grid around it
            self.origin = np.array([np.floor(xmin / (t * res)) * t * res, np.floor(ymin / (t * res)) * t * res])
            ox, oy = self.origin
            need = (int(np.ceil((ymax - oy) / (t * res))) or 1, int(np.ceil((xmax - ox) / (t * res))) or 1)
            self._check(*need)
            self.tables = np.full((self.n, *need), -1, dtype=np.int32)
            return True
        left = int(np.ceil((ox - xmin) / (t * res)))
        bottom = int(np.ceil((oy - ymin) / (t * res)))
        right = int(np.ceil((xmax - (ox + tw * t * res)) / (t * res)))
        top = int(np.ceil((ymax - (oy + th * t * res)) / (t * res)))
        if max(left, bottom, right, top) <= 0:
            return False

        def grow(need: int, size: int) -> int:
            return max(need, size // 2, 1) if need > 0 else 0

        left, right, bottom, top = grow(left, tw), grow(right, tw), grow(bottom, th), grow(top, th)
        self._check(th + bottom + top, tw + left + right)
        new = np.full((self.n, th + bottom + top, tw + left + right), -1, dtype=np.int32)
        new[:, bottom : bottom + th, left : left + tw] = self.tables
        self.tables = new
        self.origin = np.array([ox - left * t * res, oy - bottom * t * res])
        return True

    def _check(self, th: int, tw: int) -> None:
        if th * tw * self.tile * self.tile > MAX_CELLS:
            raise MapTooLarge(
                f"the map would grow to {tw * self.tile * self.resolution:.0f} m x "
                f"{th * self.tile * self.resolution:.0f} m (more than {MAX_CELLS:.0e} cells)"
            )

    def _reserve(self, tiles: int) -> None:
        """At least ``tiles`` free tiles (the pool doubles as needed)."""
        if self.nfree[0] >= tiles:
            return
        old = len(self.pool)
        size = max(2 * old, old + tiles - int(self.nfree[0]))
        pool, near = self.pool, self.near
        self._alloc(size)
        # only the tiles in use (a free one is written whole when taken: copying it would bring
        # the pages handed back into memory again)
        used = np.nonzero(self.refs[:old])[0]
        self.pool[used] = pool[used]
        self.near[used] = near[used]
        self.near[size:] = 1  # (every flag stale: the caches refill as matches read them, to the same values)
        del pool, near
        self.refs = np.concatenate([self.refs, np.zeros(size - old, dtype=np.int32)])
        k = int(self.nfree[0])
        free = np.empty(size, dtype=np.int32)  # the new tiles under the free ones on the stack
        free[: size - old] = np.arange(size - 1, old - 1, -1, dtype=np.int32)
        free[size - old : size - old + k] = self.free[:k]
        self.free = free
        self.nfree[0] = k + size - old

    def seed(self, logodds: NDArray[np.float32], origin: Array) -> None:
        """Every map becomes the log-odds grid ``logodds`` (lower-left corner at ``origin``,
        this resolution): one copy of its written tiles, shared by all (a map continued)."""
        t = self.tile
        h, w = logodds.shape
        th, tw = -(-h // t), -(-w // t)
        self._check(th, tw)
        cells = np.zeros((th * t, tw * t), dtype=np.float32)
        cells[:h, :w] = logodds
        blocks = cells.reshape(th, t, tw, t).swapaxes(1, 2)  # (th, tw, t, t)
        written = np.nonzero(np.abs(blocks).max(axis=(2, 3)) > 0)
        k = len(written[0])
        self.tables = np.full((self.n, th, tw), -1, dtype=np.int32)
        self.refs[:] = 0
        self.free[: len(self.pool)] = np.arange(len(self.pool) - 1, -1, -1, dtype=np.int32)
        self.nfree[0] = len(self.pool)
        self._reserve(k)
        top = int(self.nfree[0])
        ids = self.free[top - k : top][::-1].copy()
        self.nfree[0] = top - k
        self.pool[ids] = blocks[written]
        self.near[len(self.pool) :] = 1  # every cache stale (see pfslam.kernels.tiled)
        self.refs[ids] = self.n
        self.tables[:, written[0], written[1]] = ids
        self.origin = np.asarray(origin, dtype=float).reshape(2).copy()

    # -- updates -------------------------------------------------------------------

    def update(self, i: int, sensor_xy: Array, endpoints: Array, hit: NDArray[np.bool_]) -> None:
        """Ray-update map ``i`` with one scan from ``sensor_xy`` to ``endpoints`` (world
        frame; ``hit`` marks obstacles), as :meth:`OccupancyGrid.update` does; the grid grows
        to hold the scan."""
        ends = np.ascontiguousarray(endpoints, dtype=float).reshape(-1, 2)
        hit = np.ascontiguousarray(hit, dtype=bool)
        sx, sy = float(sensor_xy[0]), float(sensor_xy[1])
        xs = np.append(ends[:, 0], sx)
        ys = np.append(ends[:, 1], sy)
        margin = 2 * self.resolution
        self.ensure_contains(xs.min() - margin, ys.min() - margin, xs.max() + margin, ys.max() + margin)
        inv = 1.0 / self.resolution
        r0 = int(np.floor((ys.min() - self.origin[1]) * inv)) - 1
        c0 = int(np.floor((xs.min() - self.origin[0]) * inv)) - 1
        r1 = int(np.floor((ys.max() - self.origin[1]) * inv)) + 2
        c1 = int(np.floor((xs.max() - self.origin[0]) * inv)) + 2
        if self._marks.shape[0] < r1 - r0 or self._marks.shape[1] < c1 - c0:
            self._marks = np.zeros(
                (max(r1 - r0, self._marks.shape[0]), max(c1 - c0, self._marks.shape[1])), dtype=np.uint8
            )
        t = self.tile
        self._reserve(((r1 - 1) // t - r0 // t + 1) * ((c1 - 1) // t - c0 // t + 1))
        tiled_ray_update_kernel(
            self.tables[i],
            self.pool,
            self.near,
            self.refs,
            self.free,
            self.nfree,
            self.shift,
            float(self.origin[0]),
            float(self.origin[1]),
            inv,
            sx,
            sy,
            ends,
            hit,
            self.l_occ,
            self.l_free,
            self.l_clamp,
            self._marks,
            r0,
            c0,
        )

    def update_all(self, poses: Array, sensor: Array, endpoints: Array, hit: NDArray[np.bool_]) -> None:
        """Ray-update every map ``i`` with one scan seen from ``poses[i]``: the same as
        :meth:`update` (i, ...) for each ``i`` with the scan (``sensor`` position and
        ``endpoints``, in the robot frame) moved to that pose, but with the maps written in
        parallel. The tiles each map's rays pass through are made its own first (one pass,
        in order), so no two threads ever take a tile from the free stack or write one tile."""
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        if len(poses) != self.n:
            raise ValueError(f"{len(poses)} poses for {self.n} maps")
        ends_r = np.asarray(endpoints, dtype=float).reshape(-1, 2)
        hit = np.ascontiguousarray(hit, dtype=bool)
        c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
        ex = poses[:, 0:1] + c * ends_r[:, 0] - s * ends_r[:, 1]  # (n, m), as transform_points does
        ey = poses[:, 1:2] + s * ends_r[:, 0] + c * ends_r[:, 1]
        ends = np.stack([ex, ey], axis=-1)
        sensors = np.column_stack(
            [
                poses[:, 0] + c[:, 0] * sensor[0] - s[:, 0] * sensor[1],
                poses[:, 1] + s[:, 0] * sensor[0] + c[:, 0] * sensor[1],
            ]
        )
        lo, hi = sensors, sensors
        if len(ends_r):  # (reduced along contiguous rows: a strided min over (n, m, 2) costs 4x)
            lo = np.minimum(np.column_stack([ex.min(axis=1), ey.min(axis=1)]), sensors)
            hi = np.maximum(np.column_stack([ex.max(axis=1), ey.max(axis=1)]), sensors)
        margin = 2 * self.resolution
        self.ensure_contains(
            lo[:, 0].min() - margin, lo[:, 1].min() - margin, hi[:, 0].max() + margin, hi[:, 1].max() + margin
        )
        inv = 1.0 / self.resolution
        ox, oy = float(self.origin[0]), float(self.origin[1])
        # Each map's scratch window: the cells its scan reaches, with a cell to spare.
        corners = np.column_stack([np.floor((lo[:, 1] - oy) * inv) - 1, np.floor((lo[:, 0] - ox) * inv) - 1])
        far = np.column_stack([np.floor((hi[:, 1] - oy) * inv) + 2, np.floor((hi[:, 0] - ox) * inv) + 2])
        corners = corners.astype(np.int64)
        size = (far - corners).max(axis=0).astype(np.int64)
        mask = np.zeros(self.tables.shape, dtype=np.uint8)
        boxes = np.zeros((self.n, 4), dtype=np.int64)
        need = segment_tiles_kernel(self.tables, self.refs, self.shift, ox, oy, inv, sensors, ends, boxes, mask)
        self._reserve(int(need.sum()))
        own_tiles_kernel(self.tables, self.pool, self.near, self.refs, self.free, self.nfree, mask, boxes)
        chunks = max(1, min(nb.get_num_threads(), self.n))
        marks = np.zeros((chunks, int(size[0]), int(size[1])), dtype=np.uint8)
        missed = tiled_scan_update_kernel(
            self.tables,
            self.pool,
            self.near,
            self.refs,
            self.shift,
            ox,
            oy,
            inv,
            sensors,
            ends,
            hit,
            self.l_occ,
            self.l_free,
            self.l_clamp,
            marks,
            corners,
        )
        if missed:  # the first pass must have made every written tile the map's own
            raise RuntimeError(f"tiled map update: {missed} cells fell in tiles not owned")

    def resample(self, parents: NDArray[np.intp]) -> None:
        """Map ``k`` becomes a copy of map ``parents[k]``: tables are copied, tiles shared."""
        parents = np.asarray(parents, dtype=np.intp)
        if parents.ndim != 1 or len(parents) == 0 or parents.min() < 0 or parents.max() >= self.n:
            raise ValueError("parents must be indices of existing maps")
        if self.tables.size:
            self._touched = max(self._touched, int(self.tables.max()) + 1)
        self.tables = self.tables[parents]
        used = self.tables[self.tables >= 0]
        # (no tile numbered from ``_touched`` on is in use: the counts and the free stack of the
        # rest are written whole, without reading them)
        k = self._touched
        self.refs[:k] = np.bincount(used, minlength=k)[:k]
        free = np.concatenate(
            [np.arange(len(self.pool) - 1, k - 1, -1, dtype=np.int32), np.nonzero(self.refs[:k] == 0)[0][::-1]]
        ).astype(np.int32)
        self.free[: len(free)] = free
        self.nfree[0] = len(free)
        self._release_free()

    def _release_free(self) -> None:
        """Hand back to the system the memory of the free tiles numbered past twice the tiles
        in use (and past ``release_bytes`` of them, default :data:`RELEASE_BYTES`), once that is
        over ``release_bytes``. Tiles are taken lowest number first, so the updates' steady
        churn stays below that mark, in memory, and what a burst of copies left above it (30
        particles diverging over an open square, then resampled) goes back. The values read
        the same: a tile is written whole when it is next taken."""
        t2 = self.tile * self.tile
        cell = self.pool.itemsize + self.near.itemsize
        floor = max(2 * self.unique_tiles, self.unique_tiles + self.release_bytes // (t2 * cell))
        if (self._touched - floor) * t2 * cell < max(self.release_bytes, 1):
            return
        idle = floor + np.nonzero(self.refs[floor : self._touched] == 0)[0]
        if len(idle):
            cut = np.nonzero(np.diff(idle) > 1)[0]
            starts = idle[np.concatenate([[0], cut + 1])].astype(np.int64)
            ends = idle[np.concatenate([cut, [len(idle) - 1]])].astype(np.int64) + 1
            _release(self._pool_buf, starts, ends, t2 * self.pool.itemsize)
            _release(self._near_buf, starts, ends, t2 * self.near.itemsize)
            if self._pool_buf is not None:
                self.released_mb += len(idle) * t2 * cell / 2**20
        in_use = np.nonzero(self.refs[floor : self._touched])[0]
        self._touched = floor + int(in_use[-1]) + 1 if len(in_use) else floor

    # -- reading -------------------------------------------------------------------

    def correlation(self, poses: Array, pts: Array, inv_sat: float, lo: float) -> Array:
        """Every particle's correlation score on its own map (see the kernel)."""
        if self.tables.shape[1] == 0:
            return np.zeros(len(poses))
        return tiled_correlation_kernel(
            self.tables,
            self.pool,
            self.shift,
            np.ascontiguousarray(poses, dtype=float),
            np.ascontiguousarray(pts, dtype=float),
            float(self.origin[0]),
            float(self.origin[1]),
            1.0 / self.resolution,
            inv_sat,
            lo,
        )

    def match(
        self,
        poses: Array,
        pts: Array,
        sigma: float,
        radius: int,
        lstep: float,
        astep: float,
        refinements: int,
        prior_w: float = 0.0,
        prior_xy: float = 1.0,
        prior_th: float = 1.0,
    ) -> Array:
        """Move every particle's pose (``poses``, in place) to where its hits (robot frame)
        best match its own map; returns the match scores (see
        :func:`~pfslam.kernels.tiled.tiled_match_kernel`; occupied: log-odds above 0)."""
        args = (lstep, astep, refinements, prior_w, prior_xy, prior_th)
        return self._near_kernel(tiled_match_kernel, poses, pts, sigma, radius, *args)

    def refine(
        self,
        poses: Array,
        pts: Array,
        sigma: float,
        iterations: int,
        prior: Array,
        prior_w: float,
        prior_xy: float,
        prior_th: float,
        max_step: float,
        max_turn: float,
    ) -> tuple[Array, Array]:
        """Refine every particle's pose (``poses``, in place) on the smooth score; returns the
        scores and the information matrices (see :func:`~pfslam.kernels.refine.tiled_refine_kernel`)."""
        n = len(poses)
        if self.tables.shape[1] == 0:
            return np.zeros(n), np.zeros((n, 3, 3))
        prior = np.ascontiguousarray(prior, dtype=float)
        rest = (iterations, prior, prior_w, prior_xy, prior_th, max_step, max_turn)
        return tiled_refine_kernel(*self._kernel_args(poses, pts, sigma), *rest)

    def loglik(self, poses: Array, pts: Array, sigma: float, radius: int, floor: float) -> Array:
        """Every particle's log-likelihood of its hits on its own map (see
        :func:`~pfslam.kernels.tiled.tiled_loglik_kernel`; occupied: log-odds above 0)."""
        return self._near_kernel(
            tiled_loglik_kernel, np.ascontiguousarray(poses, dtype=float), pts, sigma, radius, floor
        )

    def fit(
        self, i: int, pose: Array, sensor: Array, ends: Array, hit: NDArray[np.bool_], tolerance: float, wall: float
    ) -> tuple[int, int, int]:
        """How map ``i`` judges a scan seen at ``pose`` (beams from ``sensor`` to ``ends``, robot
        frame; ``hit``: which ended on something): (judged, explained, contradicted) beams,
        ``tolerance`` (m) the distance within which a hit counts as on a wall, ``wall`` the
        log-odds from which a cell is a wall a beam cannot pass (see
        :func:`~pfslam.kernels.fit.tiled_fit_kernel`)."""
        if self.tables.shape[1] == 0 or not len(ends):
            return 0, 0, 0
        judged, explained, contradicted = tiled_fit_kernel(
            self.tables[i],
            self.pool,
            self.shift,
            np.asarray(pose, dtype=np.float64),
            np.asarray(sensor, dtype=np.float64),
            np.ascontiguousarray(ends, dtype=np.float64),
            np.ascontiguousarray(hit, dtype=np.bool_),
            *self._judging(tolerance, wall),
        )
        return int(judged), int(explained), int(contradicted)

    def _judging(self, tolerance: float, wall: float) -> tuple[float, float, float, int, float]:
        """The fit kernels' last arguments: the grid's origin and 1 / resolution, ``tolerance``
        in whole cells, ``wall``."""
        tol = max(0, int(round(tolerance / self.resolution)))
        return float(self.origin[0]), float(self.origin[1]), 1.0 / self.resolution, tol, float(wall)

    def seen_through(
        self, poses: Array, sensor: Array, ends: Array, tolerance: float, wall: float
    ) -> NDArray[np.int64]:
        """Per map ``i``, the beams of a scan seen at ``poses[i]`` (from ``sensor`` to ``ends``,
        robot frame) whose paths, up to ``tolerance`` (m) short of their ends, cross a cell at
        ``wall`` log-odds or above: walls the map is sure of that the scan saw through (see
        :func:`~pfslam.kernels.fit.tiled_seen_through_kernel`), every map at once."""
        if self.tables.shape[1] == 0 or not len(ends):
            return np.zeros(self.n, dtype=np.int64)
        return tiled_seen_through_kernel(
            self.tables,
            self.pool,
            self.shift,
            np.ascontiguousarray(poses, dtype=np.float64),
            np.asarray(sensor, dtype=np.float64),
            np.ascontiguousarray(ends, dtype=np.float64),
            *self._judging(tolerance, wall),
        )

    def _near_kernel(
        self, kernel: Callable[..., Array], poses: Array, pts: Array, sigma: float, radius: int, *rest: float
    ) -> Array:
        """``kernel`` (a match or log-likelihood kernel of :mod:`pfslam.kernels.tiled`) on
        every particle's map, with the near cache (occupied: log-odds above 0); zeros while
        the maps are empty."""
        if self.tables.shape[1] == 0:
            return np.zeros(len(poses))
        return kernel(*self._kernel_args(poses, pts, sigma), radius, 0.0, *rest)

    def _kernel_args(self, poses: Array, pts: Array, sigma: float) -> KernelArgs:
        """What every per-particle kernel of this map takes first: the tiles (tables, pool,
        near cache, shift), the poses, the hits (robot frame), the grid's origin and cell, and
        the kernel's width ``sigma``."""
        ox, oy = float(self.origin[0]), float(self.origin[1])
        pts = np.ascontiguousarray(pts, dtype=float)
        return (self.tables, self.pool, self.near, self.shift, poses, pts, ox, oy, self.resolution, sigma)

    def walls(self, i: int, box: tuple[float, float, float, float], factor: int) -> tuple[NDArray[np.bool_], Array]:
        """Map ``i``'s walls (log-odds above 0) within ``box`` (xmin, ymin, xmax, ymax; by
        whole tiles), on cells ``factor`` times as wide (one is a wall where any of its cells
        is; ``factor`` divides the tile), and the lower-left corner of the result: a coarse
        picture of a region of a map far larger than a dense copy of it could be."""
        t, res = self.tile, self.resolution
        if t % factor:
            raise ValueError(f"a tile of {t} cells is not made of {factor}-cell blocks")
        th, tw = self.tables.shape[1:]
        c0, r0 = (int(np.floor((v - o) / (t * res))) for v, o in zip(box[:2], self.origin))
        c1, r1 = (int(np.floor((v - o) / (t * res))) + 1 for v, o in zip(box[2:], self.origin))
        c0, r0, c1, r1 = max(c0, 0), max(r0, 0), min(max(c1, 0), tw), min(max(r1, 0), th)
        k = t // factor
        out = np.zeros((max(r1 - r0, 0) * k, max(c1 - c0, 0) * k), dtype=bool)
        table = self.tables[i, r0:r1, c0:c1]
        for tr, tc in zip(*np.nonzero(table >= 0)):
            wall = self.pool[table[tr, tc]] > 0
            out[tr * k : (tr + 1) * k, tc * k : (tc + 1) * k] = wall.reshape(k, factor, k, factor).any(axis=(1, 3))
        return out, self.origin + np.array([c0, r0]) * t * res

    def dense(self, i: int) -> NDArray[np.float32]:
        """Map ``i`` as a dense (rows, cols) log-odds array on the grid."""
        th, tw = self.tables.shape[1:]
        t = self.tile
        out = np.zeros((th * t, tw * t), dtype=np.float32)
        table = self.tables[i]
        for tr, tc in zip(*np.nonzero(table >= 0)):
            out[tr * t : (tr + 1) * t, tc * t : (tc + 1) * t] = self.pool[table[tr, tc]]
        return out
