"""The back end's nodes: the scans along the front end's path it is made of (a node every
``graph.node_m`` of travel or ``graph.node_deg`` of turn), each with the points it is matched
with and what its scan pins of its pose, a resumed run's nodes after its session's, and the
submaps drawn from runs of consecutive nodes."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from pfslam.backend.registration import Steps
from pfslam.backend.settings import BackendSettings
from pfslam.backend.submaps import Submap, field_of, surface_information
from pfslam.config import GraphConfig
from pfslam.frames import Frame
from pfslam.geometry import relative, transform_points, wrap_angle
from pfslam.maps.grid import grid_from_config, integrate_scan
from pfslam.sensor import ScanPoints, cell_keys, one_per_cell, scan_to_points
from pfslam.types import Array


@dataclass
class SessionNodes:
    """The graph's nodes of a session: their poses in the map's frame (as the session ended),
    the points each matches with (robot frame), what each scan pins of its pose (3 x 3), the
    scan's hits and floor points that build a submap (robot frame) and the sensor's place on
    the robot, the time of the scan, and the run each node came from."""

    poses: Array
    points: list[NDArray[np.float32]]
    info: Array
    hits: list[NDArray[np.float32]]
    floor: list[NDArray[np.float32]]
    sensor: Array
    times: Array
    run: NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.poses)

    def joined(self, other: SessionNodes) -> SessionNodes:
        """These nodes, then ``other``'s."""
        return SessionNodes(
            np.vstack([self.poses, other.poses]),
            self.points + other.points,
            np.concatenate([self.info, other.info]),
            self.hits + other.hits,
            self.floor + other.floor,
            np.vstack([self.sensor, other.sensor]),
            np.concatenate([self.times, other.times]),
            np.concatenate([self.run, other.run]),
        )


@dataclass
class Nodes:
    """The scans the graph is made of: their index in the run, their pose from the front
    end, the points matched (robot frame, float32, at most ``node_points`` each), and what
    each scan pins of its pose (:func:`~pfslam.backend.edges.scan_information`, (N, 3, 3);
    zero where not measured)."""

    scan: NDArray[np.int64]
    poses: Array
    points: list[NDArray[np.float32]]
    info: Array | None = None
    # A resumed run's nodes (:func:`with_session`): the run each node came from (None: all
    # one run), and how many come first from the session, held where they are.
    run: NDArray[np.int64] | None = None
    held: int = 0
    # Each node's hits, their mean in each half map cell (robot frame, float32): what its matches are refined with.
    dense: list[NDArray[np.float32]] | None = None
    # The nodes matched on nearby ones (:func:`~pfslam.backend.registration.register_steps`): the
    # graph's edges between them (None: the front end's path between consecutive nodes), and
    # the nodes placed by them alone, which submaps are drawn from (None: the front end's).
    steps: Steps | None = None
    registered: Array | None = None

    def local_poses(self, first: int, end: int) -> Array:
        """Nodes ``first..end-1`` in node ``first``'s frame (as registered, where they were)."""
        at = self.registered if self.registered is not None else self.poses
        return relative(at[first], at[first:end])

    def __len__(self) -> int:
        return len(self.scan)

    def information(self) -> Array:
        return self.info if self.info is not None else np.zeros((len(self), 3, 3))

    def same_run(self) -> NDArray[np.bool_]:
        """Whether each node and the next come from one run ((N - 1,))."""
        if self.run is None:
            return np.ones(max(len(self) - 1, 0), dtype=bool)
        return self.run[1:] == self.run[:-1]


SCANS_KEPT = 64  # the nodes' scans last worked out, kept (a submap's, its neighbours' while registering)
ScanOf = Callable[[int], ScanPoints]  # node k's scan (robot frame; hits within graph.max_range)


def frame_scans(frames: Sequence[Frame], nodes: Nodes, config: BackendSettings) -> ScanOf:
    """Node k's scan, from the frame it was taken at (``nodes.scan[k]``), its hits beyond
    ``graph.max_range`` left out."""

    @functools.lru_cache(maxsize=SCANS_KEPT)
    def scan(k: int) -> ScanPoints:
        sp = scan_to_points(frames[int(nodes.scan[k])], ground_z=config.ground_z)
        return ScanPoints(within(sp.hits, sp.sensor_xy, config.graph.max_range), sp.floor, sp.sensor_xy)

    return scan


def with_session(
    before: SessionNodes, new: Nodes, frames: Sequence[Frame], config: BackendSettings
) -> tuple[Nodes, ScanOf]:
    """A session's nodes (held where they are), then ``new``'s (a resumed run's, in the
    session's frame), and the scan of each: the session's stored ones, then ``frames``'."""
    k = len(before)
    run = np.concatenate([before.run, np.full(len(new), before.run.max(initial=-1) + 1, dtype=np.int64)])
    nodes = Nodes(
        np.concatenate([np.full(k, -1, dtype=np.int64), new.scan]),
        np.vstack([before.poses, new.poses]),
        [p.astype(np.float32) for p in before.points] + new.points,
        np.concatenate([before.info, new.information()]),
        run,
        k,
    )
    from_frames = frame_scans(frames, Nodes(new.scan, new.poses, new.points), config)

    def scan(j: int) -> ScanPoints:
        if j >= k:
            return from_frames(j - k)
        sensor = before.sensor[j]
        h = within(before.hits[j].astype(float), sensor, config.graph.max_range)
        return ScanPoints(h, before.floor[j].astype(float), sensor)

    # (the session's nodes' hits as the new ones' are kept, what their matches are refined with)
    half = config.map.resolution / 2
    held = [np.ascontiguousarray(cell_means(scan(j).hits, half), dtype=np.float32) for j in range(k)]
    nodes.dense = held + (new.dense if new.dense is not None else list(new.points))
    return nodes, scan


def node_points(sp: ScanPoints, c: GraphConfig, res: float) -> tuple[NDArray[np.float32], Array, NDArray[np.float32]]:
    """The hits of a scan kept for matching: within ``max_range`` of the sensor, one per cell
    of a grid two map cells wide, then at most ``node_points`` evenly spread; what the hits pin
    of the pose (:func:`~pfslam.backend.submaps.surface_information`); and the hits' means in
    cells half a map cell wide (what the node's matches are refined with)."""
    dense = cell_means(within(sp.hits, sp.sensor_xy, c.max_range), res / 2)
    h = one_per_cell(dense, 2 * res)
    kept = h[np.linspace(0, len(h) - 1, c.node_points).round().astype(np.int64)] if len(h) > c.node_points else h
    info = surface_information(dense, c.scan_sigma_m, c.scan_points)
    return np.ascontiguousarray(kept, dtype=np.float32), info, np.ascontiguousarray(dense, dtype=np.float32)


def within(hits: Array, sensor: Array, reach: float) -> Array:
    """The ``hits`` ((N, 2)) at most ``reach`` from the ``sensor`` (2,)."""
    return hits[np.hypot(hits[:, 0] - sensor[0], hits[:, 1] - sensor[1]) <= reach]


def cell_means(points: Array, cell: float) -> Array:
    """The mean of ``points`` ((N, 2)) in each cell of a grid ``cell`` wide, in the order of each
    cell's first point: unbiased where the first point of each cell would sit at the side a
    scan's sweep enters it (a turn of the whole scan, to a match)."""
    if not len(points):
        return points
    _, first, inverse = np.unique(cell_keys(points, cell), return_index=True, return_inverse=True)
    count = np.bincount(inverse)
    means = np.column_stack([np.bincount(inverse, points[:, 0]), np.bincount(inverse, points[:, 1])]) / count[:, None]
    return means[np.argsort(first)]


def select_nodes(frames: Sequence[Frame], poses: Array, config: BackendSettings) -> Nodes:
    """A node at the first scan with hits, then at each scan after ``node_m`` of travel or
    ``node_deg`` of turn (front-end poses) since the last node, if it has hits; and at the
    last scan."""
    c = config.graph
    res = config.map.resolution
    scans: list[int] = []
    pts: list[NDArray[np.float32]] = []
    dense: list[NDArray[np.float32]] = []
    infos: list[Array] = []
    last: Array | None = None
    turn = np.deg2rad(c.node_deg)
    n = len(poses)
    for k in range(n):
        if last is not None and k != n - 1:
            x, y, th = poses[k]
            if math.hypot(x - last[0], y - last[1]) < c.node_m and abs(wrap_angle(th - last[2])) < turn:
                continue
        p, info, d = node_points(scan_to_points(frames[k], ground_z=config.ground_z), c, res)
        if len(p) < 10:
            continue
        scans.append(k)
        pts.append(p)
        dense.append(d)
        infos.append(info)
        last = poses[k]
    idx = np.array(scans, dtype=np.int64)
    poses_at = poses[idx] if len(idx) else np.zeros((0, 3))
    return Nodes(idx, poses_at, pts, np.array(infos).reshape(-1, 3, 3), dense=dense)


def own_nodes(nodes: Nodes) -> Nodes:
    """The nodes of this run (those after the ones held from a session)."""
    k = nodes.held
    return Nodes(nodes.scan[k:], nodes.poses[k:], nodes.points[k:], nodes.information()[k:])


def submap_hits(scan_of: ScanOf, nodes: Nodes, first: int, end: int) -> Array:
    """The hits of nodes ``first..end-1`` in node ``first``'s frame (as registered)."""
    local = nodes.local_poses(first, end)
    out = [transform_points(local[k - first], scan_of(k).hits) for k in range(first, end)]
    return np.concatenate(out) if out else np.zeros((0, 2))


def build_submap(
    scan_of: ScanOf, nodes: Nodes, first: int, end: int, config: BackendSettings, depth: int
) -> Submap | None:
    """The submap of nodes ``first..end-1``: their scans (``scan_of``: hits beyond
    ``max_range`` left out) ray-traced into a grid in the first node's frame, the cells that
    end up occupied turned into the field exp(-d^2 / 2 sigma^2), and its max-pooled pyramid."""
    grid = grid_from_config(config.map, centred=False)
    local = nodes.local_poses(first, end)
    for k in range(first, end):
        integrate_scan(grid, local[k - first], scan_of(k))
    hits = submap_hits(scan_of, nodes, first, end)
    return field_of(grid.logodds > 0, grid.origin, grid.resolution, config.graph.field_sigma, depth, hits)
