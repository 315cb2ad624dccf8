"""Log-odds occupancy grid: growth, exact ray update, probabilities, ROS map_server files."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np
import yaml
from numpy.typing import NDArray

from pfslam.errors import InputError, PfslamError
from pfslam.geometry import transform_points
from pfslam.kernels.raycast import ray_update_kernel, ray_update_scans_kernel
from pfslam.types import Array

if TYPE_CHECKING:
    from collections.abc import Sequence

    from PIL.ImageFile import ImageFile

    from pfslam.config import MapConfig, SlamConfig
    from pfslam.frames import Frame
    from pfslam.kernels import RayKernel
    from pfslam.sensor import ScanPoints


FREE_PIXEL = 254
OCCUPIED_PIXEL = 0
UNKNOWN_PIXEL = 205
OCCUPIED_THRESH = 0.65
FREE_THRESH = 0.196
MAX_CELLS = 10**8  # 500 m x 500 m at 0.05 m; with its scratch array 800 MB


class MapTooLarge(PfslamError):
    """The map would grow past :data:`MAX_CELLS` (usually: the poses jumped far away)."""


class OccupancyGrid:
    """Log-odds cells; row index = y (row 0 lowest), column index = x.

    ``origin`` is the world position of the lower-left corner of cell (0, 0). The grid
    grows (by at least half its size on a side, so growth is rare) whenever an update
    reaches outside it; existing cells keep their world position.
    """

    def __init__(
        self,
        resolution: float = 0.05,
        l_occ: float = 3.0,
        l_free: float = -1.0,
        l_clamp: float = 120.0,
        origin: tuple[float, float] | Array = (0.0, 0.0),
        shape: tuple[int, int] = (0, 0),
    ) -> None:
        if resolution <= 0:
            raise ValueError("resolution must be positive")
        self.resolution = float(resolution)
        self.l_occ = float(l_occ)
        self.l_free = float(l_free)
        self.l_clamp = float(l_clamp)
        self.origin = np.array(origin, dtype=float)
        self.logodds = np.zeros(shape, dtype=np.float32)
        self._stamp = np.zeros(shape, dtype=np.int32)  # scratch for the ray update
        self._scan_id = 0

    # -- geometry ------------------------------------------------------------------

    @property
    def shape(self) -> tuple[int, int]:
        h, w = self.logodds.shape
        return h, w

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax) of the grid in the world."""
        h, w = self.shape
        ox, oy = self.origin
        return (ox, ox + w * self.resolution, oy, oy + h * self.resolution)

    def world_to_cell(self, xy: Array) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        xy = np.atleast_2d(np.asarray(xy, dtype=float))
        f = (xy - self.origin) / self.resolution
        return np.floor(f[:, 1]).astype(np.int64), np.floor(f[:, 0]).astype(np.int64)

    def cell_to_world(self, rows: NDArray[np.int64], cols: NDArray[np.int64]) -> Array:
        """Centres of cells (rows, cols) in world coordinates, (M, 2)."""
        rows = np.asarray(rows, dtype=float)
        cols = np.asarray(cols, dtype=float)
        return np.column_stack(
            [self.origin[0] + (cols + 0.5) * self.resolution, self.origin[1] + (rows + 0.5) * self.resolution]
        )

    def contains(self, xy: Array) -> NDArray[np.bool_]:
        r, c = self.world_to_cell(xy)
        h, w = self.shape
        return (r >= 0) & (r < h) & (c >= 0) & (c < w)

    def ensure_contains(self, xmin: float, ymin: float, xmax: float, ymax: float, margin: float = 1.0) -> bool:
        """Grow so that the box plus ``margin`` lies inside; return True if the grid grew."""
        res = self.resolution
        h, w = self.shape
        ox, oy = self.origin
        need_l = int(np.ceil((ox - (xmin - margin)) / res))
        need_b = int(np.ceil((oy - (ymin - margin)) / res))
        need_r = int(np.ceil((xmax + margin - (ox + w * res)) / res))
        need_t = int(np.ceil((ymax + margin - (oy + h * res)) / res))
        if max(need_l, need_b, need_r, need_t) <= 0:
            return False

        # Amortised growth: at least half the current size on each side that must grow.
        def grow(need: int, size: int) -> int:
            return max(need, size // 2, 16) if need > 0 else 0

        left, right = grow(need_l, w), grow(need_r, w)
        bottom, top = grow(need_b, h), grow(need_t, h)
        nh, nw = h + bottom + top, w + left + right
        if nh * nw > MAX_CELLS:
            raise MapTooLarge(
                f"the map would grow to {nw * res:.0f} m x {nh * res:.0f} m ({nw} x {nh} cells, more than "
                f"{MAX_CELLS:.0e}): a pose or scan point lies far away (x {xmin:.0f}..{xmax:.0f}, y "
                f"{ymin:.0f}..{ymax:.0f} m); check the odometry, or use a coarser map.resolution"
            )
        new = np.zeros((h + bottom + top, w + left + right), dtype=np.float32)
        new[bottom : bottom + h, left : left + w] = self.logodds
        self.logodds = new
        self._stamp = np.zeros(new.shape, dtype=np.int32)
        self.origin = np.array([ox - left * res, oy - bottom * res])
        return True

    # -- updates -------------------------------------------------------------------

    def update(
        self, sensor_xy: Array, endpoints: Array, hit: NDArray[np.bool_], ray_update: RayKernel = ray_update_kernel
    ) -> None:
        """Ray-update with one scan: from the sensor position to each end point (occupied if
        ``hit``). Pass all beams of a scan in one call: within it, hit cells are not cleared
        by the other beams. ``ray_update`` is the kernel (or its NumPy twin) that does it."""
        ends = np.ascontiguousarray(endpoints, dtype=float).reshape(-1, 2)
        if len(ends) == 0:
            return
        sx, sy = float(sensor_xy[0]), float(sensor_xy[1])
        lo = ends.min(axis=0)
        hi = ends.max(axis=0)
        self.ensure_contains(min(lo[0], sx), min(lo[1], sy), max(hi[0], sx), max(hi[1], sy))
        first = self._scan_ids(1)
        ray_update(
            self.logodds,
            float(self.origin[0]),
            float(self.origin[1]),
            1.0 / self.resolution,
            sx,
            sy,
            ends,
            np.ascontiguousarray(hit, dtype=np.bool_),
            self.l_occ,
            self.l_free,
            self.l_clamp,
            self._stamp,
            first,
        )

    def _scan_ids(self, n: int) -> int:
        """The first of ``n`` scan ids, new since the stamps were last cleared (the ray kernels
        keep a scan's hits from its own beams by them), taken."""
        if self._stamp.shape != self.logodds.shape:  # logodds replaced from outside
            self._stamp = np.zeros(self.logodds.shape, dtype=np.int32)
        if self._scan_id + n >= 2**31 - 2:
            self._stamp[:] = 0
            self._scan_id = 0
        self._scan_id += n
        return self._scan_id - n + 1

    def update_scans(self, sensors: Array, endpoints: Array, hit: NDArray[np.bool_], starts: NDArray[np.int64]) -> None:
        """:meth:`update` for many scans at once, in their order: scan ``s`` from ``sensors[s]``
        to ``endpoints[starts[s]:starts[s + 1]]``, the cells :meth:`update` a scan would give. It
        does not grow the grid: it must hold them already (cells outside it are skipped)."""
        n = len(sensors)
        if n == 0:
            return
        first = self._scan_ids(n)
        ray_update_scans_kernel(
            self.logodds,
            float(self.origin[0]),
            float(self.origin[1]),
            1.0 / self.resolution,
            np.ascontiguousarray(sensors, dtype=float),
            np.ascontiguousarray(endpoints, dtype=float),
            np.ascontiguousarray(hit, dtype=np.bool_),
            np.ascontiguousarray(starts, dtype=np.int64),
            self.l_occ,
            self.l_free,
            self.l_clamp,
            self._stamp,
            first,
        )

    # -- exports -------------------------------------------------------------------

    def probabilities(self) -> Array:
        """Occupancy probability of every cell (0.5 where unknown)."""
        return 1.0 / (1.0 + np.exp(-np.clip(self.logodds.astype(np.float64), -50, 50)))

    def thresholded(
        self, occupied_thresh: float = OCCUPIED_THRESH, free_thresh: float = FREE_THRESH
    ) -> NDArray[np.int8]:
        """100 occupied, 0 free, -1 unknown (the ROS OccupancyGrid convention)."""
        p = self.probabilities()
        out = np.full(self.shape, -1, dtype=np.int8)
        out[p > occupied_thresh] = 100
        out[p < free_thresh] = 0
        return out

    def known_bounds(self) -> tuple[int, int, int, int] | None:
        """(r0, r1, c0, c1), half-open, of the cells that were ever updated; None if none."""
        known = self.logodds != 0
        rows = np.nonzero(known.any(axis=1))[0]
        if len(rows) == 0:
            return None
        cols = np.nonzero(known.any(axis=0))[0]
        return int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1

    def cropped(self, margin_cells: int = 10) -> OccupancyGrid:
        """A copy holding only the known cells plus a margin (at least 1×1)."""
        b = self.known_bounds()
        h, w = self.shape
        if b is None:
            r0, r1, c0, c1 = 0, min(h, 1), 0, min(w, 1)
        else:
            r0, r1 = max(b[0] - margin_cells, 0), min(b[1] + margin_cells, h)
            c0, c1 = max(b[2] - margin_cells, 0), min(b[3] + margin_cells, w)
        part = self.logodds[r0:r1, c0:c1].copy()  # not a copy of the whole map first
        if part.size == 0:
            part = np.zeros((1, 1), dtype=np.float32)
        return OccupancyGrid.from_logodds(
            part,
            self.resolution,
            self.origin + np.array([c0, r0]) * self.resolution,
            self.l_occ,
            self.l_free,
            self.l_clamp,
        )

    def copy(self) -> OccupancyGrid:
        return OccupancyGrid.from_logodds(
            self.logodds.copy(), self.resolution, self.origin, self.l_occ, self.l_free, self.l_clamp
        )

    @classmethod
    def from_logodds(
        cls,
        logodds: NDArray[np.float32],
        resolution: float,
        origin: Array,
        l_occ: float = 3.0,
        l_free: float = -1.0,
        l_clamp: float = 120.0,
    ) -> OccupancyGrid:
        """A grid holding the array ``logodds`` (taken, not copied) whose lower-left corner
        is at ``origin``."""
        g = cls(resolution, l_occ, l_free, l_clamp, np.array(origin, dtype=float))
        g.logodds = np.asarray(logodds, dtype=np.float32)
        g._stamp = np.zeros(g.logodds.shape, dtype=np.int32)
        return g

    def save_ros(self, stem: str | Path, crop: bool = True, margin_cells: int = 10) -> tuple[Path, Path]:
        """Write ``stem.pgm`` (P5) and ``stem.yaml`` as ROS map_server reads them."""
        g = self.cropped(margin_cells) if crop else self
        stem = Path(stem)
        pgm = stem.with_suffix(".pgm")
        yml = stem.with_suffix(".yaml")
        t = g.thresholded()
        img = np.full(t.shape, UNKNOWN_PIXEL, dtype=np.uint8)
        img[t == 0] = FREE_PIXEL
        img[t == 100] = OCCUPIED_PIXEL
        img = img[::-1]  # top row = largest y
        h, w = cast("tuple[int, int]", img.shape)
        with open(pgm, "wb") as f:
            f.write(f"P5\n# pfslam map, {g.resolution} m/cell\n{w} {h}\n255\n".encode("ascii"))
            f.write(np.ascontiguousarray(img).tobytes())
        meta = {
            "image": pgm.name,
            "resolution": g.resolution,
            "origin": [float(g.origin[0]), float(g.origin[1]), 0.0],
            "negate": 0,
            "occupied_thresh": OCCUPIED_THRESH,
            "free_thresh": FREE_THRESH,
            "mode": "trinary",
        }
        yml.write_text(yaml.safe_dump(meta, sort_keys=False))
        return yml, pgm

    @classmethod
    def load_ros(cls, yaml_path: str | Path, l_sat: float = 10.0) -> OccupancyGrid:
        """Read a map_server map: occupied cells get +l_sat, free -l_sat, unknown 0."""
        p = Path(yaml_path)
        if p.is_dir():
            raise InputError(p, "is a folder, not a map file")
        if not p.is_file():
            raise InputError(p, "map file not found" if not p.exists() else "not a regular file")
        try:
            meta = yaml.safe_load(p.read_text(encoding="utf-8"))
        except (yaml.YAMLError, UnicodeDecodeError) as e:
            raise InputError(p, f"not valid YAML ({str(e).splitlines()[0]})") from None
        if not isinstance(meta, dict):
            raise InputError(p, "expected a YAML mapping with image, resolution, origin")
        for key in ("image", "resolution", "origin"):
            if key not in meta:
                raise InputError(p, f"missing key '{key}'")
        try:
            res = float(meta["resolution"])
            origin = [float(v) for v in meta["origin"]][:2]
            negate = int(meta.get("negate", 0))
            occ_t = float(meta.get("occupied_thresh", OCCUPIED_THRESH))
            free_t = float(meta.get("free_thresh", FREE_THRESH))
        except (TypeError, ValueError):
            raise InputError(p, "resolution, origin, negate and thresholds must be numbers") from None
        if not (np.isfinite(res) and res > 0) or len(origin) != 2 or not np.isfinite(origin).all():
            raise InputError(p, "resolution must be a finite positive number and origin [x, y, yaw] finite")
        yaw = meta["origin"][2] if isinstance(meta["origin"], (list, tuple)) and len(meta["origin"]) > 2 else 0.0
        try:
            yaw = float(yaw)
        except (TypeError, ValueError):
            raise InputError(p, "origin yaw must be a number") from None
        if yaw != 0.0:
            raise InputError(p, f"origin yaw {yaw} is not supported (only maps aligned with the world axes)")
        if not (0.0 <= free_t < occ_t <= 1.0):
            raise InputError(p, f"need 0 <= free_thresh < occupied_thresh <= 1, got {free_t} and {occ_t}")
        img_path = Path(str(meta["image"]))
        if not img_path.is_absolute():
            img_path = p.parent / img_path
        if not img_path.is_file():
            raise InputError(p, f"image file {img_path} not found")
        img = _read_image(img_path)
        v = img.astype(np.float64)
        occ = v / 255.0 if negate else (255.0 - v) / 255.0
        g = cls(resolution=res, l_clamp=max(l_sat, 1.0), origin=(origin[0], origin[1]))
        lo = np.zeros(img.shape, dtype=np.float32)
        lo[occ > occ_t] = l_sat
        lo[occ < free_t] = -l_sat
        g.logodds = np.ascontiguousarray(lo[::-1])
        return g


def grid_from_config(c: MapConfig, centred: bool = True) -> OccupancyGrid:
    """An empty map with the configured cells: ``initial_size`` metres a side around the
    origin when ``centred``, else empty (it grows as scans arrive)."""
    if not centred:
        return OccupancyGrid(resolution=c.resolution, l_occ=c.l_occ, l_free=c.l_free, l_clamp=c.l_clamp)
    half = c.initial_size / 2
    n = int(np.ceil(c.initial_size / c.resolution))
    return OccupancyGrid(
        resolution=c.resolution, l_occ=c.l_occ, l_free=c.l_free, l_clamp=c.l_clamp, origin=(-half, -half), shape=(n, n)
    )


def scan_beams(pose: Array, sp: ScanPoints) -> tuple[Array, Array, NDArray[np.bool_]]:
    """A scan seen from ``pose`` as a map update takes it (world frame): the sensor's position,
    the beams' ends (hits, then floor hits) and which are hits (occupied; floor hits free)."""
    origin = transform_points(pose, sp.sensor_xy[None])[0]
    pts = np.concatenate([sp.hits, sp.floor]) if len(sp.floor) else sp.hits
    return origin, transform_points(pose, pts), np.arange(len(pts)) < len(sp.hits)


def integrate_scan(grid: OccupancyGrid, pose: Array, sp: ScanPoints, ray_update: RayKernel = ray_update_kernel) -> None:
    """Ray-update ``grid`` with one scan seen from ``pose``: hits occupied, floor hits free."""
    origin, ends, hit = scan_beams(pose, sp)
    if len(ends):
        grid.update(origin, ends, hit, ray_update)


def map_from_poses(
    frames: Sequence[Frame],
    poses: Array,
    config: SlamConfig | None = None,
    as_filter: bool = False,
    base: OccupancyGrid | None = None,
) -> OccupancyGrid:
    """The map of ``frames`` seen from ``poses`` (mapping only, no filter: a ground truth, a
    reference, the loop-closing back end's answer): every scan written in full, or with
    ``as_filter`` as the filter of ``config`` writes its own: the Rao-Blackwellized filter a
    scan after each ``rbpf.update_m`` of travel or ``rbpf.update_deg`` of turn, no wall beyond
    ``rbpf.map_range`` (only free space up to it); the single-map filter every scan. ``base``:
    a map the scans are added to (a copy of it; a session's, for a resumed run)."""
    from pfslam.config import SlamConfig, SlamFilter
    from pfslam.geometry import relative
    from pfslam.sensor import beam_ends, scan_to_points

    c = config if config is not None else SlamConfig()
    grid = grid_from_config(c.map, centred=False) if base is None else base.copy()
    rbpf = as_filter and c.filter == SlamFilter.RBPF
    reach = c.rbpf.map_range if rbpf else np.inf
    turn = np.deg2rad(c.rbpf.update_deg)
    last: Array | None = None
    for frame, pose in zip(frames, np.asarray(poses, dtype=float)):
        if rbpf and last is not None:
            d = relative(last, pose)
            if np.hypot(d[0], d[1]) < c.rbpf.update_m and abs(d[2]) < turn:
                continue
        sp = scan_to_points(frame, ground_z=c.sensor.ground_z)
        if not len(sp.hits) and not len(sp.floor):
            continue
        last = pose
        ends, hit = beam_ends(sp.hits, sp.floor, sp.sensor_xy, reach)
        grid.update(transform_points(pose, sp.sensor_xy[None])[0], transform_points(pose, ends), hit)
    return grid


def _read_image(path: Path) -> NDArray[np.uint8]:
    """8-bit grey image of a map (PGM P5/P2, PNG or anything Pillow reads); colour is the mean
    of the channels, 16-bit grey is scaled to 8 bits. A PGM must hold exactly the pixels its
    header says: more would shear the map, fewer lose rows."""
    import io

    from PIL import Image

    try:
        data = path.read_bytes()  # read once: Pillow decodes it, the PGM check counts its pixels
        with Image.open(io.BytesIO(data)) as im:
            if im.format == "PPM":
                _check_pgm_size(path, im, data)
            if im.mode.startswith("I"):  # 16-bit grey
                a = np.asarray(im, dtype=np.float64) * (255.0 / 65535.0)
            else:
                a = np.asarray(im if im.mode == "L" else im.convert("RGB"), dtype=np.float64)
    except InputError:
        raise
    except Exception as e:  # noqa: BLE001 - any decoder failure is a bad file
        raise InputError(path, f"cannot read the map image ({type(e).__name__}: {e})") from None
    if a.ndim == 3:
        a = a[..., :3].mean(axis=2)
    return np.clip(np.round(a), 0, 255).astype(np.uint8)


def _check_pgm_size(path: Path, im: ImageFile, data: bytes) -> None:
    """InputError unless the PGM's data after its header is exactly width x height pixels."""
    w, h = im.size
    codec, offset = im.tile[0][0], im.tile[0][2]
    body = data[offset:]
    if codec == "ppm_plain":  # P2: whitespace-separated numbers
        n = len(body.split())
        if n != w * h:
            what = "truncated PGM" if n < w * h else "PGM data longer than its header says"
            raise InputError(path, f"{what}: {n} pixels, while {w}x{h} are {w * h}")
        return
    size = 2 if im.mode.startswith("I") else 1
    need = w * h * size
    if len(body) != need:
        what = "truncated PGM" if len(body) < need else "PGM data longer than its header says"
        raise InputError(
            path, f"{what}: {len(body)} bytes of pixels, while {w}x{h} pixels of {size} byte(s) are {need}"
        )
