"""Closing loops behind the filter: nodes along its path, submaps of consecutive nodes, a
branch-and-bound search of each node against the older submaps near it, and the pose graph
solved (see :mod:`pfslam.backend`)."""

from __future__ import annotations

import math
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Callable, Sequence

import numba
import numpy as np
from numpy.typing import NDArray

from pfslam.backend.chain import SLIP_DEG, SLIP_M, Steps, fits, local_poses, register_steps
from pfslam.backend.consistency import Paths
from pfslam.backend.edges import loop_information, scan_information, sequential_information
from pfslam.backend.graph import PoseGraph, reweighted, solve, variance_factors
from pfslam.backend.session import SessionNodes
from pfslam.backend.submaps import Submap, Surface, field_of, match, pyramid_depth, refine, surface_information
from pfslam.config import GraphConfig, RobustLoss, SlamConfig
from pfslam.frames import Frame
from pfslam.geometry import compose, relative, wrap_angle
from pfslam.maps.grid import grid_from_config, integrate_scan
from pfslam.sensor import ScanPoints, scan_to_points

Array = NDArray[np.float64]
Progress = Callable[[int, int], None]
LOOP_PAIRED = (
    0.1  # a loop's refinement pairs at least this fraction of the node's points (a submap is part of what it sees)
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
    # The nodes matched on nearby ones (:func:`~pfslam.backend.chain.register_steps`): the
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


ScanOf = Callable[[int], ScanPoints]  # node k's scan (robot frame; hits within graph.max_range)


def frame_scans(frames: Sequence[Frame], nodes: Nodes, config: SlamConfig) -> ScanOf:
    """Node k's scan, from the frame it was taken at (``nodes.scan[k]``), its hits beyond
    ``graph.max_range`` left out."""

    def scan(k: int) -> ScanPoints:
        sp = scan_to_points(frames[int(nodes.scan[k])], ground_z=config.sensor.ground_z)
        reach = np.hypot(sp.hits[:, 0] - sp.sensor_xy[0], sp.hits[:, 1] - sp.sensor_xy[1])
        return ScanPoints(sp.hits[reach <= config.graph.max_range], sp.floor, sp.sensor_xy)

    return scan


def with_session(before: SessionNodes, new: Nodes, frames: Sequence[Frame], config: SlamConfig) -> tuple[Nodes, ScanOf]:
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
        h = before.hits[j].astype(float)
        sensor = before.sensor[j]
        h = h[np.hypot(h[:, 0] - sensor[0], h[:, 1] - sensor[1]) <= config.graph.max_range]
        return ScanPoints(h, before.floor[j].astype(float), sensor)

    return nodes, scan


@dataclass
class Loop:
    """A loop edge found: node ``node`` seen from submap ``submap``'s first node ``anchor``
    at ``pose``, with its match ``score``."""

    anchor: int
    node: int
    submap: int
    pose: Array
    score: float
    info: Array | None = None  # what its match pins of the node's pose (3 x 3, node frame), if refined


@dataclass
class ClosureStats:
    """The back end's figures (``run.json``'s ``backend``): what was searched, what each check
    refused, what the graph kept, and the seconds each part took."""

    nodes: int = 0
    submaps: int = 0
    loops_tried: int = 0  # matches tried (local and wide)
    loops_tried_wide: int = 0
    loops_found: int = 0  # matches that scored well enough and were unique
    refused_ambiguous: int = 0  # matches refused: another place a corridor step away scored nearly as well
    refused_unchained: int = 0  # loops refused: too few neighbouring nodes matched the same place alike
    refused_far: int = 0  # loops refused with the far ones (see local_closure), when all of them made the map worse
    refused_gate: int = 0  # loops refused: far outside what the path between their nodes allows
    refused_pairs: int = 0  # loops refused: they disagree with other loops near them
    loops_in_graph: int = 0  # loops the last solve kept
    loops_dropped: int = 0  # loops a solve found to disagree with the rest
    seconds_nodes: float = 0.0
    seconds_chain: float = 0.0  # each node matched on the one before it
    seconds_search: float = 0.0
    seconds_solve: float = 0.0
    slowest_solve_ms: float = 0.0
    slowest_local_match_ms: float = 0.0
    slowest_wide_match_ms: float = 0.0
    largest_correction_m: float = 0.0

    @property
    def refused(self) -> int:
        """Loops refused by the checks: ambiguous, unchained, disagreeing with the rest, or far
        (dropped with the far ones when they made the map worse)."""
        return (
            self.refused_ambiguous
            + self.refused_unchained
            + self.loops_dropped
            + self.refused_far
            + self.refused_gate
            + self.refused_pairs
        )

    def as_dict(self) -> dict[str, float | int]:
        from dataclasses import asdict

        return {**asdict(self), "loops_refused": self.refused}


@dataclass
class LoopClosure:
    """What the back end did: every scan's pose after the solve, the graph (front-end poses
    as its initial guess) and the optimised node poses, the loops kept, and its figures."""

    poses: Array
    nodes: Nodes
    graph: PoseGraph
    optimised: Array
    loops: list[Loop] = field(default_factory=list)
    stats: ClosureStats = field(default_factory=ClosureStats)
    ties: list[Loop] = field(default_factory=list)  # a resumed run's start in the session's map
    found: list[Loop] = field(default_factory=list)  # every loop the search found, before the checks


def node_points(sp: ScanPoints, c: GraphConfig, res: float) -> tuple[NDArray[np.float32], Array, NDArray[np.float32]]:
    """The hits of a scan kept for matching: within ``max_range`` of the sensor, one per cell
    of a grid two map cells wide, then at most ``node_points`` evenly spread; what the hits pin
    of the pose (:func:`~pfslam.backend.submaps.surface_information`); and the hits' means in
    cells half a map cell wide (what the node's matches are refined with)."""
    h = sp.hits
    if len(h):
        h = h[np.hypot(h[:, 0] - sp.sensor_xy[0], h[:, 1] - sp.sensor_xy[1]) <= c.max_range]
    dense = cell_means(h, res / 2)
    h = one_per_cell(dense, 2 * res)
    kept = h[np.linspace(0, len(h) - 1, c.node_points).round().astype(np.int64)] if len(h) > c.node_points else h
    info = surface_information(dense, c.scan_sigma_m, c.scan_points)
    return np.ascontiguousarray(kept, dtype=np.float32), info, np.ascontiguousarray(dense, dtype=np.float32)


def cell_means(points: Array, cell: float) -> Array:
    """The mean of ``points`` ((N, 2)) in each cell of a grid ``cell`` wide, in the order of each
    cell's first point: unbiased where the first point of each cell would sit at the side a
    scan's sweep enters it (a turn of the whole scan, to a match)."""
    if not len(points):
        return points
    cells = np.floor(points / cell).astype(np.int64)
    _, first, inverse = np.unique(cells[:, 0] * 2_000_003 + cells[:, 1], return_index=True, return_inverse=True)
    count = np.bincount(inverse)
    means = np.column_stack([np.bincount(inverse, points[:, 0]), np.bincount(inverse, points[:, 1])]) / count[:, None]
    return means[np.argsort(first)]


def one_per_cell(points: Array, cell: float) -> Array:
    """The first of ``points`` ((N, 2)) in each cell of a grid ``cell`` wide, in their order."""
    if not len(points):
        return points
    cells = np.floor(points / cell).astype(np.int64)
    _, first = np.unique(cells[:, 0] * 2_000_003 + cells[:, 1], return_index=True)
    return points[np.sort(first)]


def start_tie(session_poses: Array, start: Array, held: int) -> Loop:
    """A resumed run's start as an edge: from the session's node nearest to ``start`` to the
    run's first node (index ``held``)."""
    nearest = int(np.argmin(np.hypot(*(session_poses[:, :2] - start[:2]).T)))
    return Loop(nearest, held, -1, relative(session_poses[nearest], start), 1.0)


def select_nodes(frames: Sequence[Frame], poses: Array, config: SlamConfig) -> Nodes:
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
        p, info, d = node_points(scan_to_points(frames[k], ground_z=config.sensor.ground_z), c, res)
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


def _submap_spans(n: int, span: int) -> list[tuple[int, int]]:
    """(first, end) node ranges: ``span`` nodes, a new one every half span."""
    step = max(span // 2, 1)
    return [(s, min(s + span, n)) for s in range(0, max(n - step, 1), step)] if n else []


def _spans(nodes: Nodes, span: int) -> list[tuple[int, int]]:
    """The submaps' node ranges, each within one run (:func:`_submap_spans` per run)."""
    cuts = [0, *(np.nonzero(~nodes.same_run())[0] + 1).tolist(), len(nodes)]
    return [(a + s, a + e) for a, b in zip(cuts[:-1], cuts[1:]) for s, e in _submap_spans(b - a, span)]


def build_submap(scan_of: ScanOf, nodes: Nodes, first: int, end: int, config: SlamConfig, depth: int) -> Submap | None:
    """The submap of nodes ``first..end-1``: their scans (``scan_of``: hits beyond
    ``max_range`` left out) ray-traced into a grid in the first node's frame, the cells that
    end up occupied turned into the field exp(-d^2 / 2 sigma^2), and its max-pooled pyramid."""
    grid = grid_from_config(config.map, centred=False)
    local = nodes.local_poses(first, end)
    for k in range(first, end):
        integrate_scan(grid, local[k - first], scan_of(k))
    hits = submap_hits(scan_of, nodes, first, end)
    return field_of(grid.logodds > 0, grid.origin, grid.resolution, config.graph.field_sigma, depth, hits)


def _near(
    poses: Array, spans: list[tuple[int, int]], c: GraphConfig, reach: float, first: int = 0
) -> dict[int, list[int]]:
    """For each node from ``first`` on, the submaps it is searched against: the nearest
    ``submaps_per_node`` that ended ``min_gap_nodes`` or more before it and have a node within
    ``reach`` of it."""
    n = len(poses)
    xy = poses[:, :2]
    dist = np.full((len(spans), n), np.inf)
    for s, (a, e) in enumerate(spans):
        later = (np.arange(n) >= e - 1 + c.min_gap_nodes) & (np.arange(n) >= first)
        if not later.any():
            continue
        d = np.hypot(xy[None, a:e, 0] - xy[later, None, 0], xy[None, a:e, 1] - xy[later, None, 1]).min(axis=1)
        dist[s, later] = d
    out: dict[int, list[int]] = {}
    order = np.argsort(dist, axis=0, kind="stable")[: c.submaps_per_node]
    for i in np.nonzero((dist <= reach).any(axis=0))[0]:
        out[int(i)] = [int(s) for s in order[:, i] if dist[s, i] <= reach]
    return out


def search_stride(nodes: int, c: GraphConfig) -> int:
    """Every how many nodes one is searched for loops: ``search_every``, or where that is 0 the
    fewest that searches at most ``search_budget`` of ``nodes`` (a small log is searched
    throughout, a long one sampled: the search's cost stays bounded)."""
    return c.search_every if c.search_every > 0 else max(1, -(-nodes // c.search_budget))


def _by_submap(pairs: list[tuple[int, int]]) -> dict[int, list[int]]:
    """(submap, node) pairs grouped by submap, in submap order (each submap is built once)."""
    out: dict[int, list[int]] = {}
    for s, i in sorted(pairs):
        out.setdefault(s, []).append(i)
    return out


def _strongest(found: dict[tuple[int, int], Loop], k: int) -> list[Loop]:
    """The ``k`` best-scoring loops of each node, in (submap, node) order."""
    by_node: dict[int, list[tuple[float, tuple[int, int]]]] = {}
    for key, lp in found.items():
        by_node.setdefault(lp.node, []).append((-lp.score, key))
    keep = sorted(key for v in by_node.values() for _, key in sorted(v)[:k])
    return [found[key] for key in keep]


def build_graph(nodes: Nodes, c: GraphConfig, loops: Sequence[Loop] = (), ties: Sequence[Loop] = ()) -> PoseGraph:
    """The graph: the nodes at their front-end poses, an edge between each two consecutive
    nodes of one run with their relative pose (as sure as the odometry between them and what
    the later scan pins: :func:`~pfslam.backend.edges.sequential_information`; none between
    nodes held from a session), the ``loops`` (as sure as the node's scan pins:
    :func:`~pfslam.backend.edges.loop_information`), and the ``ties`` (a resumed run's start in
    the session's map: as sure as a loop, without the robust loss)."""
    graph = PoseGraph(nodes.poses.copy())
    info = nodes.information()
    if len(nodes) > 1:
        if nodes.steps is not None:
            st = nodes.steps
            if not c.match_edges:  # (the matches place the submaps' nodes only)
                st = Steps(
                    st.i[~st.matched],
                    st.j[~st.matched],
                    st.z[~st.matched],
                    st.info[~st.matched],
                    st.matched[~st.matched],
                )
            st.add_to(graph)
        else:
            k = np.nonzero(nodes.same_run() & (np.arange(len(nodes) - 1) >= nodes.held))[0]
            z = relative(nodes.poses[k], nodes.poses[k + 1])
            graph.add_many(
                k, k + 1, z, None, np.zeros(len(k), dtype=bool), info=sequential_information(info[k + 1], z, c)
            )
    for edges, loop in ((ties, False), (loops, True)):
        if not edges:
            continue
        who = np.array([lp.node for lp in edges], dtype=np.int64)
        graph.add_many(
            np.array([lp.anchor for lp in edges], dtype=np.int64),
            who,
            np.array([lp.pose for lp in edges]),
            None,
            np.full(len(edges), loop, dtype=bool),
            info=np.linalg.inv(loop_covariances(edges, nodes, c)),
        )
    return graph


def chained(
    loops: Sequence[Loop], spans: Sequence[tuple[int, int]], current: Array, travel: Array, c: GraphConfig
) -> list[bool]:
    """Which loops are backed by a chain: at least ``chain_nodes`` loops (itself among them) of
    nodes within ``chain_m`` of travel of each other, into the same or an overlapping submap,
    that move the path alike (each loop's correction, applied to the other's node, lands
    within ``chain_tol_m`` / ``chain_tol_deg`` of where that loop puts it), as Karto accepts a
    loop. A false match seldom has neighbours that err the same way; a true loop has a run of
    them."""
    n = len(loops)
    if c.chain_nodes <= 1 or n == 0:
        return [True] * n
    # Where each loop puts its node (the world frame of ``current``), and the correction it asks.
    placed = np.array([compose(current[lp.anchor], lp.pose) for lp in loops])
    at = np.array([current[lp.node] for lp in loops])
    node = np.array([lp.node for lp in loops])
    sub = np.array([lp.submap for lp in loops])
    tol_th = np.deg2rad(c.chain_tol_deg)
    out = []
    for k in range(n):
        near = np.nonzero((np.abs(travel[node] - travel[node[k]]) <= c.chain_m) & (np.abs(sub - sub[k]) <= 1))[0]
        # the correction of loop k: the rigid motion taking its node's pose to where it puts it
        fix = compose(placed[k], relative(at[k], at[near]))
        d = relative(fix, placed[near])
        agree = (np.hypot(d[:, 0], d[:, 1]) <= c.chain_tol_m) & (np.abs(d[:, 2]) <= tol_th)
        out.append(len(np.unique(node[near[agree]])) >= c.chain_nodes)
    return out


def front_paths(poses: Array, travel: Array, c: GraphConfig, steps: Steps | None = None) -> Paths:
    """What the front end knew of the path between any two nodes (at ``poses``; ``travel``: the
    path length to each), what a loop is checked against: each node's jitter (``node_sigma_m``,
    ``node_sigma_deg``), the drift ``path_drift`` / ``path_drift_deg`` per metre between them,
    and :data:`SLIP_M` / :data:`SLIP_DEG` over each step that no scan match backs (``steps``)."""
    jitter = np.diag([c.node_sigma_m**2, c.node_sigma_m**2, np.deg2rad(c.node_sigma_deg) ** 2])
    slips = None
    if steps is not None:
        slips = np.concatenate([[0.0], np.cumsum(steps.unmatched_steps(len(poses)))])
    return Paths(
        poses,
        travel,
        jitter,
        c.path_drift,
        float(np.deg2rad(c.path_drift_deg)),
        slips,
        SLIP_M,
        float(np.deg2rad(SLIP_DEG)),
    )


UNREFINED_M = 0.05  # m: a loop whose match could not be refined point to line is at least this unsure ...
UNREFINED_DEG = 1.0  # ... and this (deg)


def loop_covariances(loops: Sequence[Loop], nodes: Nodes, c: GraphConfig) -> Array:
    """Each loop's covariance (node frame): its refined match's, never surer than the
    ``loop_sigma_*`` floors; a loop whose match was not refined (a scan too noisy or sparse for
    walls to be fitted to it), what its node's scan pins, never surer than :data:`UNREFINED_M`,
    :data:`UNREFINED_DEG`."""
    if not loops:
        return np.zeros((0, 3, 3))
    info = nodes.information()
    coarse = replace(c, loop_sigma_m=max(c.loop_sigma_m, UNREFINED_M), loop_sigma_deg=max(c.loop_sigma_deg, UNREFINED_DEG))
    out = []
    for lp in loops:
        if lp.info is not None:
            out.append(loop_information(lp.info[None], c)[0])
        else:
            out.append(loop_information(info[lp.node][None], coarse)[0])
    return np.asarray(np.linalg.inv(np.array(out)))


def checked_loops(
    loops: list[Loop], nodes: Nodes, poses: Array, travel: Array, c: GraphConfig
) -> tuple[list[Loop], list[Loop], list[Loop]]:
    """The loops that pass the checks against the path (:func:`~pfslam.backend.consistency.gate`)
    and against each other (:func:`~pfslam.backend.consistency.consistent`), from ``poses``;
    and those refused by each (kept, far, inconsistent)."""
    from pfslam.backend.consistency import consistent, gate, loop_arrays

    paths = front_paths(poses, travel, c, nodes.steps)
    a, i, z = loop_arrays(loops)
    cov = loop_covariances(loops, nodes, c)
    near = gate(a, i, z, cov, poses, paths) <= c.gate_chi2
    far = [lp for lp, ok in zip(loops, near) if not ok]
    if not near.any():
        return [], far, []
    agree = consistent(a[near], i[near], z[near], cov[near], poses, paths, limit=c.gate_chi2)
    close = [lp for lp, ok in zip(loops, near) if ok]
    return [lp for lp, ok in zip(close, agree) if ok], far, [lp for lp, ok in zip(close, agree) if not ok]


def place_scans(nodes: Nodes, front: Array, optimised: Array) -> Array:
    """Every scan's pose after the solve: each scan between two nodes placed from both by the
    front end's relative motion and blended by its place between them (before the first
    node and after the last, from that node alone)."""
    n = len(front)
    if len(nodes) == 0:
        return front.copy()
    idx = np.arange(n)
    after = np.clip(np.searchsorted(nodes.scan, idx, side="right") - 1, 0, len(nodes) - 1)
    before = np.clip(after + 1, 0, len(nodes) - 1)
    sa, sb = nodes.scan[after], nodes.scan[before]
    pa = compose(optimised[after], relative(front[sa], front))
    pb = compose(optimised[before], relative(front[sb], front))
    span = (sb - sa).astype(float)
    w = np.where(span > 0, (idx - sa) / np.where(span > 0, span, 1.0), 0.0)
    w = np.clip(w, 0.0, 1.0)
    w[idx < nodes.scan[0]] = 1.0  # before the first node: from it alone
    out = np.empty((n, 3))
    out[:, :2] = (1 - w)[:, None] * pa[:, :2] + w[:, None] * pb[:, :2]
    out[:, 2] = wrap_angle(pa[:, 2] + w * wrap_angle(pb[:, 2] - pa[:, 2]))
    return out


def _verify_chains(
    alone: Sequence[Loop],
    scan_of: ScanOf,
    nodes: Nodes,
    spans: Sequence[tuple[int, int]],
    current: Array,
    travel: Array,
    found: dict[tuple[int, int], Loop],
    config: SlamConfig,
    depth: int,
    pool: ThreadPoolExecutor,
) -> list[Loop]:
    """The loops of the nodes near each loop of ``alone`` (within ``chain_m`` of travel, into
    the same submap), each searched over a small window where that loop's correction puts the
    node: a true loop's neighbours match there too, and :func:`chained` then backs it."""
    c = config.graph
    res = config.map.resolution
    tol = (2 * c.chain_tol_m, 2 * c.chain_tol_deg)
    out: list[Loop] = []
    by_sub: dict[int, list[Loop]] = {}
    for lp in alone:
        by_sub.setdefault(lp.submap, []).append(lp)
    for s, group in sorted(by_sub.items()):
        a, e = spans[s]
        jobs: list[tuple[int, Array]] = []
        asked: set[int] = set()
        for lp in group:
            placed = compose(current[a], lp.pose)
            near = np.nonzero(np.abs(travel - travel[lp.node]) <= c.chain_m)[0].tolist()
            for j in near:
                if j == lp.node or j < max(e - 1 + c.min_gap_nodes, nodes.held) or (s, j) in found or j in asked:
                    continue
                asked.add(j)
                # where the loop's correction puts node j, in the submap's frame
                guess = relative(current[a], compose(placed, relative(current[lp.node], current[j])))
                jobs.append((j, guess))
        if not jobs:
            continue
        sub = build_submap(scan_of, nodes, a, e, config, depth)
        if sub is None:
            continue

        def one(job: tuple[int, Array], sub: Submap = sub) -> tuple[int, Array, tuple[Array, float] | None]:
            return job[0], job[1], match(sub, nodes.points[job[0]], job[1], tol[0], tol[1], c.min_score, res)

        for who, guess, m in pool.map(one, jobs):
            lp = _refined(Loop(a, who, s, m[0], m[1]), sub, nodes, c, guess) if m is not None else None
            if lp is not None:
                out.append(lp)
    return out


def _refined(lp: Loop, sub: Submap, nodes: Nodes, c: GraphConfig, guess: Array | None = None) -> Loop | None:
    """The loop refined point to line on its submap's surface, held at ``guess`` (where the
    search looked) in what the match does not pin, with what it pins. Where the refinement
    pairs too few of the node's points or fits them badly (:func:`~pfslam.backend.chain.fits`:
    walls could not be fitted to a noisy or sparse scan), the branch and bound match as it was
    (as unsure as :func:`loop_covariances` says), or None for a loop that had none (``score``
    0: a refinement tried straight from the guess)."""
    if sub.surface is None:
        return lp
    pts = np.asarray(nodes.dense[lp.node] if nodes.dense is not None else nodes.points[lp.node], dtype=np.float64)
    r = refine(sub.surface, pts, lp.pose, c.scan_points, guess)
    if fits(r, len(pts), LOOP_PAIRED):
        return replace(lp, pose=r.pose, info=r.info)
    return replace(lp, info=None) if lp.score > 0 else None


def _direct(lp: Loop, sub: Submap, nodes: Nodes, c: GraphConfig, res: float) -> Loop | None:
    """The loop ``lp`` refined from its pose (where the front end put its node) as it is, if the
    refinement holds and the node's points score ``min_score`` on the submap's field there:
    no search is needed where the front end was within a match's reach of the truth."""
    from pfslam.kernels.bnb import bilinear_score_kernel

    out = _refined(lp, sub, nodes, c, lp.pose)
    if out is None:
        return None
    score = float(bilinear_score_kernel(sub.field, nodes.points[lp.node].astype(np.float64), out.pose, sub.ox, sub.oy, res))
    return replace(out, score=score) if score >= c.min_score else None


def submap_hits(scan_of: ScanOf, nodes: Nodes, first: int, end: int) -> Array:
    """The hits of nodes ``first..end-1`` in node ``first``'s frame (as registered)."""
    local = nodes.local_poses(first, end)
    out = []
    for k in range(first, end):
        at = local[k - first]
        h = scan_of(k).hits
        c, s = np.cos(at[2]), np.sin(at[2])
        out.append(np.column_stack([at[0] + c * h[:, 0] - s * h[:, 1], at[1] + s * h[:, 0] + c * h[:, 1]]))
    return np.concatenate(out) if out else np.zeros((0, 2))


def _refreshed(
    found: dict[tuple[int, int], Loop],
    scan_of: ScanOf,
    nodes: Nodes,
    spans: Sequence[tuple[int, int]],
    current: Array,
    c: GraphConfig,
    pool: ThreadPoolExecutor,
) -> dict[tuple[int, int], Loop]:
    """Every loop refined again on its submap's surface from where it was, held at where
    ``current`` puts its node (:func:`_refined`)."""
    by_sub: dict[int, list[tuple[int, int]]] = {}
    for key in found:
        by_sub.setdefault(key[0], []).append(key)

    def one(s: int) -> list[tuple[tuple[int, int], Loop]]:
        a, e = spans[s]
        h = submap_hits(scan_of, nodes, a, e)
        if len(h) < 10:
            return [(key, found[key]) for key in by_sub[s]]
        sub = Submap(np.zeros((1, 1), np.float32), np.zeros((1, 1, 1), np.float32), 0.0, 0.0, Surface.of(h))
        return [(key, _refined(found[key], sub, nodes, c, relative(current[a], current[key[1]]))) for key in by_sub[s]]

    return {key: lp for done in pool.map(one, sorted(by_sub)) for key, lp in done if lp is not None}


@dataclass
class _Tried:
    """One match tried: its stage (local or wide), its seconds, and whether it was refused as
    ambiguous."""

    stage: str
    seconds: float
    ambiguous: bool


def _search(
    i: int,
    sub: Submap,
    s: int,
    span: tuple[int, int],
    current: Array,
    wide_ok: bool,
    travel: Array,
    nodes: Nodes,
    c: GraphConfig,
    res: float,
    since: float = 0.0,
) -> tuple[Loop | None, list[_Tried]]:
    """Node ``i`` against submap ``s`` (nodes ``span``), from the poses ``current``: the local
    window first; failing that (if ``wide_ok``) the wide one, as wide as the drift since the
    submap could be (``travel``: path length to each node; ``since``: its length where node
    ``i``'s run began, which a resumed run's start was placed at): the front end may have
    placed the node far off. The loop found, and each match tried (:class:`_Tried`)."""
    a, e = span
    guess = relative(current[a], current[i])
    stages = [("local", c.local_m, c.local_deg)]
    if wide_ok:
        run_m = float(travel[i] - max(travel[e - 1], since))
        wide_m = min(c.window_m, max(c.local_m, c.drift_per_m * run_m))
        wide_deg = min(c.window_deg, max(c.local_deg, c.drift_deg_per_m * run_m))
        if wide_m > c.local_m or wide_deg > c.local_deg:
            stages.append(("wide", wide_m, wide_deg))
    spent: list[_Tried] = []
    began = time.perf_counter()
    lp = _direct(Loop(a, i, s, guess, 0.0), sub, nodes, c, res)
    if lp is not None:
        # (where the front end put the node within a match's reach, the match from there is the loop)
        spent.append(_Tried("local", time.perf_counter() - began, False))
        return lp, spent
    for stage, win_m, win_deg in stages:
        began = time.perf_counter()
        wide = stage == "wide"
        score = c.wide_min_score if wide else c.min_score
        why: list[str] = []
        m = match(sub, nodes.points[i], guess, win_m, win_deg, score, res, wide, c.ambiguity if wide else 0.0, why)
        # (a wide match is held where it matched: the front end's guess may be metres off)
        lp = _refined(Loop(a, i, s, m[0], m[1]), sub, nodes, c, None if wide else guess) if m is not None else None
        spent.append(_Tried(stage, time.perf_counter() - began, bool(why)))
        if lp is not None:
            return lp, spent
    return None, spent


def close_loops(
    frames: Sequence[Frame],
    poses: Array,
    config: SlamConfig,
    progress: Progress | None = None,
    before: SessionNodes | None = None,
) -> LoopClosure:
    """The back end over a finished front-end run: ``frames`` the scans the filter stepped,
    ``poses`` its trajectory (one per frame). Each pass searches every node (every
    ``search_every``-th) against the submaps near it over the local window, then the nodes left with no loop (every
    ``wide_every``-th) against their nearest submap over the wide window (first pass only);
    the loops that a chain of neighbouring nodes backs (:func:`chained`) go into the graph,
    which is solved; the next pass starts from the solved poses. See :mod:`pfslam.backend`.

    ``before``: the nodes of the session a run resumed (``poses`` in its frame). They are held
    where they are; this run's nodes are searched against their submaps as against its own,
    and its first node is tied to the session's nearest node by the start found."""
    c = config.graph
    res = config.map.resolution
    clock = time.perf_counter()
    front = np.asarray(poses, dtype=float)
    nodes = own = select_nodes(frames, front, config)
    scan_of = frame_scans(frames, nodes, config)
    ties: list[Loop] = []
    if before is not None and len(before) and len(own):
        nodes, scan_of = with_session(before, own, frames, config)
        ties.append(start_tie(before.poses, own.poses[0], nodes.held))
    held = nodes.held
    pool = ThreadPoolExecutor(max(1, numba.get_num_threads()))
    if c.match_levels > 0 and len(nodes) > 1:
        clock_c = time.perf_counter()
        dense = nodes.dense if nodes.dense is not None else list(nodes.points)
        own_node = np.arange(len(nodes)) >= held
        nodes.steps = register_steps(nodes.poses, own_node, nodes.run, nodes.information(), scan_of, dense, c, pool)
        nodes.registered = local_poses(nodes.poses, nodes.steps, held + 1)
        chain_s = time.perf_counter() - clock_c
    else:
        chain_s = 0.0
    spans = _spans(nodes, c.submap_nodes)
    depth = pyramid_depth(int(round(max(c.window_m, c.local_m) / res)))
    stats = ClosureStats(
        nodes=len(nodes), submaps=len(spans), seconds_nodes=time.perf_counter() - clock - chain_s, seconds_chain=chain_s
    )
    found: dict[tuple[int, int], Loop] = {}
    slowest = {"local": 0.0, "wide": 0.0}
    current = nodes.poses.copy()
    optimised = current
    steps = np.hypot(*np.diff(nodes.poses[:, :2], axis=0).T) * nodes.same_run() if len(nodes) > 1 else np.zeros(0)
    travel = np.concatenate([[0.0], np.cumsum(steps)])  # path length to each node (m)
    since = np.zeros(len(nodes))  # ... where its run began
    since[held:] = travel[held] if held < len(nodes) else 0.0
    tried_at: dict[tuple[int, int], Array] = {}  # the guess each pair was last searched from
    solved_with = 0  # loops in the last solve
    dropped: set[tuple[int, int]] = set()  # loops a solve found to disagree
    refused: set[tuple[int, int]] = set()  # loops the checks refused
    checked: set[tuple[int, int]] = set()  # loops whose neighbours were searched for a chain
    loops: list[Loop] = []
    redo = np.array([c.local_m / 2, c.local_m / 2, np.deg2rad(c.local_deg) / 2])
    every = search_stride(len(nodes) - held, c)
    factors: dict[str, float] | None = None  # each group of edges' variance factor, once estimated
    for p in range(c.passes):
        clock = time.perf_counter()
        if p > 0 and found:
            # the loops found so far refined again from the solved poses: what a loop's match does
            # not pin (along a corridor) now comes from the graph's answer, not the front end's
            found = _refreshed(found, scan_of, nodes, spans, current, c, pool)
        near = _near(current, spans, c, c.search_radius + c.window_m, held)
        pairs = [(s, i) for i, subs in near.items() if (i - held) % every == 0 for s in subs if (s, i) not in found]
        looped = {i for _, i in found}  # nodes with a loop: later passes search the others wide

        batches = _by_submap(pairs)
        for done, (s, who) in enumerate(batches.items()):
            if progress is not None:
                progress(done, len(batches))
            a, e = spans[s]
            todo = []
            for i in who:
                guess = relative(current[a], current[i])
                last = tried_at.get((s, i))
                if last is not None and (np.abs(relative(last, guess)) < redo).all():
                    continue  # searched from about here before, in vain
                tried_at[(s, i)] = guess
                todo.append(i)
            if not todo:
                continue
            sub = build_submap(scan_of, nodes, a, e, config, depth)
            if sub is None:
                continue
            # The kernels release the GIL: the nodes are matched on every core.
            jobs = [
                (
                    i,
                    sub,
                    s,
                    spans[s],
                    current,
                    i % c.wide_every == 0 and (p == 0 or i not in looped),
                    travel,
                    nodes,
                    c,
                    res,
                    float(since[i]),
                )
                for i in todo
            ]
            for lp, spent in pool.map(lambda job: _search(*job), jobs):
                for tried in spent:
                    stats.loops_tried += 1
                    stats.loops_tried_wide += tried.stage == "wide"
                    stats.refused_ambiguous += tried.ambiguous
                    slowest[tried.stage] = max(slowest[tried.stage], tried.seconds)
                if lp is not None:
                    found[(s, lp.node)] = lp
        if progress is not None:
            progress(len(batches), len(batches))
        stats.seconds_search += time.perf_counter() - clock
        solved_with = len(found)
        clock = time.perf_counter()
        strongest = _strongest(found, c.loops_per_node)
        backed = chained(strongest, spans, current, travel, c)
        alone = [lp for lp, b in zip(strongest, backed) if not b and (lp.submap, lp.node) not in checked]
        if alone:
            # A loop with too few neighbours alike (a wide search tries every other node only):
            # its neighbours are searched where it says they are, and it stands if they agree.
            clock_v = time.perf_counter()
            for lp in _verify_chains(alone, scan_of, nodes, spans, current, travel, found, config, depth, pool):
                found[(lp.submap, lp.node)] = lp
            checked |= {(lp.submap, lp.node) for lp in alone}
            strongest = _strongest(found, c.loops_per_node)
            backed = chained(strongest, spans, current, travel, c)
            stats.seconds_search += time.perf_counter() - clock_v
        stats.refused_unchained = sum(not b for b in backed)
        loops = [lp for lp, b in zip(strongest, backed) if b and (lp.submap, lp.node) not in dropped | refused]
        if c.check_loops and loops:
            loops, far, odd = checked_loops(loops, nodes, current, travel, c)
            stats.refused_gate += len(far)
            stats.refused_pairs += len(odd)
            refused |= {(lp.submap, lp.node) for lp in far + odd}
        graph = build_graph(nodes, c, loops, ties)
        if factors is not None:
            graph = reweighted(graph, factors)
        # The first solve sorts the loops with ``loss`` (graduated non-convexity by default);
        # the later ones start from its answer, without the loops it dropped, under the
        # Cauchy loss (a new loop that disagrees pulls little): ten times cheaper.
        loss = c.loss if p == 0 else (RobustLoss.CAUCHY if c.loss == RobustLoss.GNC else c.loss)
        if loops or ties:
            optimised, keep = solve(graph, loss, c.loss_scale, initial=current, held=held, trusted=c.check_loops)
            dropped |= {(lp.submap, lp.node) for lp, k in zip(loops, keep) if not k}
            loops = [lp for lp, k in zip(loops, keep) if k]
            if c.reweigh and factors is None:
                # each group of edges weighed by how well it held up (the next pass solves with it)
                factors = variance_factors(build_graph(nodes, c, loops, ties), optimised)
        else:
            optimised = nodes.poses.copy()
        took = time.perf_counter() - clock
        stats.seconds_solve += took
        stats.slowest_solve_ms = max(stats.slowest_solve_ms, 1e3 * took)
        current = optimised
    pool.shutdown()
    # (with no loop the front end's answer stands, to the bit)
    out = place_scans(own, front, optimised[held:]) if loops else front.copy()
    stats.loops_found = len(found)
    stats.loops_in_graph = len(loops)
    stats.loops_dropped = len(dropped)
    stats.slowest_local_match_ms = 1e3 * slowest["local"]
    stats.slowest_wide_match_ms = 1e3 * slowest["wide"]
    stats.largest_correction_m = _largest_move(front, out)
    return LoopClosure(
        out, nodes, build_graph(nodes, c, loops, ties), optimised, loops, stats, ties, list(found.values())
    )


def _largest_move(before: Array, after: Array) -> float:
    """How far the back end moved a scan at most (m)."""
    return float(np.hypot(*(after[:, :2] - before[:, :2]).T).max()) if len(after) else 0.0


def local_closure(closure: LoopClosure, front: Array, config: SlamConfig) -> LoopClosure | None:
    """The closure again with only its loops that lie within the local window (``local_m``,
    ``local_deg``) of where the front end put their nodes, solved from the front end's poses:
    the back end that cannot move the path far, for when the far loops (a wide search's,
    where aliasing lives) made the map worse. None if it would keep no loop, or all of them."""
    c = config.graph
    nodes = closure.nodes
    if not closure.loops:
        return None
    turn = np.deg2rad(c.local_deg)
    near = []
    for lp in closure.loops:
        d = relative(relative(nodes.poses[lp.anchor], nodes.poses[lp.node]), lp.pose)
        near.append(bool(np.hypot(d[0], d[1]) <= c.local_m and abs(d[2]) <= turn))
    local = [lp for lp, ok in zip(closure.loops, near) if ok]
    if not local or len(local) == len(closure.loops):
        return None
    clock = time.perf_counter()
    graph = build_graph(nodes, c, local, closure.ties)
    optimised, keep = solve(graph, c.loss, c.loss_scale, initial=nodes.poses, held=nodes.held)
    kept = [lp for lp, k in zip(local, keep) if k]
    if not kept:
        return None
    out = place_scans(own_nodes(nodes), front, optimised[nodes.held :])
    stats = replace(
        closure.stats,
        loops_in_graph=len(kept),
        loops_dropped=closure.stats.loops_dropped + len(local) - len(kept),
        refused_far=len(closure.loops) - len(local),
        seconds_solve=closure.stats.seconds_solve + time.perf_counter() - clock,
        largest_correction_m=_largest_move(front, out),
    )
    return LoopClosure(
        out, nodes, build_graph(nodes, c, kept, closure.ties), optimised, kept, stats, closure.ties, closure.found
    )


def own_nodes(nodes: Nodes) -> Nodes:
    """The nodes of this run (those after the ones held from a session)."""
    k = nodes.held
    return Nodes(nodes.scan[k:], nodes.poses[k:], nodes.points[k:], nodes.information()[k:])
