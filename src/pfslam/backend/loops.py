"""Closing loops behind the filter: nodes along its path registered to each other, submaps of
consecutive nodes, each node searched against the older submaps near it, the loops checked,
and the pose graph solved (see :mod:`pfslam.backend`)."""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Callable, Sequence

import numba
import numpy as np

from pfslam.backend.edges import sequential_information
from pfslam.backend.graph import PoseGraph, reweighted, solve, variance_factors
from pfslam.backend.nodes import (
    Nodes,
    ScanOf,
    SessionNodes,
    build_submap,
    frame_scans,
    own_nodes,
    select_nodes,
    with_session,
)
from pfslam.backend.registration import local_poses, register_steps
from pfslam.backend.search import (
    Loop,
    Tried,
    by_submap,
    chained,
    checked_loops,
    loop_covariances,
    near_submaps,
    refreshed,
    search_node,
    search_stride,
    start_tie,
    strongest_loops,
    verify_chains,
)
from pfslam.backend.settings import BackendSettings
from pfslam.backend.submaps import Submap
from pfslam.config import GraphConfig, RobustLoss
from pfslam.frames import Frame
from pfslam.geometry import compose, relative, wrap_angle
from pfslam.kernels.bnb import pyramid_depth
from pfslam.types import Array

Progress = Callable[[int, int], None]


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
    refused_spread: int = 0  # matches refused: places scoring about as well spread every way (see widened)
    refused_unchained: int = 0  # loops refused: too few neighbouring nodes matched the same place alike
    refused_far: int = 0  # loops refused with the far ones (see local_closure), when all of them made the map worse
    refused_gate: int = 0  # loops refused: far outside what the path between their nodes allows
    refused_pairs: int = 0  # loops refused: they disagree with other loops near them
    loops_shared: int = 0  # loops in the graph that share one piece of evidence with others (weighed as one)
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
            + self.refused_spread
            + self.refused_unchained
            + self.loops_dropped
            + self.refused_far
            + self.refused_gate
            + self.refused_pairs
        )

    def refusals(self) -> str:
        """The refused loops by the check that refused them, for a one-line report."""
        parts = [
            (self.refused_ambiguous, "ambiguous"),
            (self.refused_gate, "off the filter's path"),
            (self.refused_pairs, "at odds with their neighbours"),
            (self.loops_dropped, "dropped by the solve"),
            (self.refused_unchained, "unchained"),
            (self.refused_far, "far"),
            (self.refused_spread, "with look-alikes all round"),
        ]
        return ", ".join(f"{k} {what}" for k, what in parts[:4] + [p for p in parts[4:] if p[0]])

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


def _submap_spans(n: int, span: int) -> list[tuple[int, int]]:
    """(first, end) node ranges: ``span`` nodes, a new one every half span."""
    step = max(span // 2, 1)
    return [(s, min(s + span, n)) for s in range(0, max(n - step, 1), step)] if n else []


def _spans(nodes: Nodes, span: int) -> list[tuple[int, int]]:
    """The submaps' node ranges, each within one run (:func:`_submap_spans` per run)."""
    cuts = [0, *(np.nonzero(~nodes.same_run())[0] + 1).tolist(), len(nodes)]
    return [(a + s, a + e) for a, b in zip(cuts[:-1], cuts[1:]) for s, e in _submap_spans(b - a, span)]


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
                st = st.subset(~st.matched)
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
            info=np.asarray(np.linalg.inv(loop_covariances(edges, nodes, c)), dtype=np.float64),
        )
    return graph


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


def close_loops(
    frames: Sequence[Frame],
    poses: Array,
    config: BackendSettings,
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
    search = LoopSearch(nodes, scan_of, spans, config, depth, pool, stats, progress)
    current = nodes.poses.copy()
    optimised = current
    dropped: set[tuple[int, int]] = set()  # loops a solve found to disagree
    refused: set[tuple[int, int]] = set()  # loops the checks refused
    loops: list[Loop] = []
    factors: dict[str, float] | None = None  # each group of edges' variance factor, once estimated
    for p in range(c.passes):
        search.search(current, p)
        clock = time.perf_counter()
        strongest, backed = search.backed(current)
        stats.refused_unchained = sum(not b for b in backed)
        loops = [lp for lp, b in zip(strongest, backed) if b and (lp.submap, lp.node) not in dropped | refused]
        if c.check_loops and loops:
            loops, far, odd = checked_loops(loops, nodes, current, search.travel, c, solved=p > 0)
            stats.loops_shared = sum(lp.share > 1 for lp in loops)
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
    stats.loops_found = len(search.found)
    stats.loops_in_graph = len(loops)
    stats.loops_dropped = len(dropped)
    stats.slowest_local_match_ms = 1e3 * search.slowest["local"]
    stats.slowest_wide_match_ms = 1e3 * search.slowest["wide"]
    stats.largest_correction_m = _largest_move(front, out)
    return LoopClosure(
        out, nodes, build_graph(nodes, c, loops, ties), optimised, loops, stats, ties, list(search.found.values())
    )


class LoopSearch:
    """The loops of one back-end run, found pass by pass: each pass searches the nodes (every
    ``search_every``-th) against the submaps near where the poses of the pass put them, over
    the local window, and the nodes without a loop (every ``wide_every``-th) over the wide
    one (the first pass only for nodes that have one); a pair searched from about the same
    guess before is not searched again. The loops found so far are refined again from each
    later pass's poses; :meth:`backed` gives the strongest of each node with whether a chain
    of its neighbours backs it. Its counts go into ``stats``."""

    def __init__(
        self,
        nodes: Nodes,
        scan_of: ScanOf,
        spans: list[tuple[int, int]],
        config: BackendSettings,
        depth: int,
        pool: ThreadPoolExecutor,
        stats: ClosureStats,
        progress: Progress | None = None,
    ) -> None:
        c = config.graph
        self.nodes, self.scan_of, self.spans, self.config, self.depth = nodes, scan_of, spans, config, depth
        self.pool, self.stats, self.progress = pool, stats, progress
        held = nodes.held
        steps = np.hypot(*np.diff(nodes.poses[:, :2], axis=0).T) * nodes.same_run() if len(nodes) > 1 else np.zeros(0)
        self.travel = np.concatenate([[0.0], np.cumsum(steps)])  # path length to each node (m)
        self.since = np.zeros(len(nodes))  # ... where its run began
        self.since[held:] = self.travel[held] if held < len(nodes) else 0.0
        self.found: dict[tuple[int, int], Loop] = {}  # (submap, node): the loop found
        self.slowest = {"local": 0.0, "wide": 0.0}  # the slowest match of each stage (s)
        self.tried_at: dict[tuple[int, int], Array] = {}  # the guess each pair was last searched from
        self.checked: set[tuple[int, int]] = set()  # loops whose neighbours were searched for a chain
        self.redo = np.array([c.local_m / 2, c.local_m / 2, np.deg2rad(c.local_deg) / 2])
        self.every = search_stride(len(nodes) - held, c)

    def _plan(self, current: Array) -> list[tuple[int, list[int]]]:
        """(submap, its nodes to search) in submap order: the pairs not found yet and not
        searched from about here before."""
        c, held = self.config.graph, self.nodes.held
        near = near_submaps(current, self.spans, c, c.search_radius + c.window_m, held)
        pairs = [
            (s, i) for i, subs in near.items() if (i - held) % self.every == 0 for s in subs if (s, i) not in self.found
        ]
        plan = []
        for s, who in by_submap(pairs).items():
            a = self.spans[s][0]
            todo = []
            for i in who:
                guess = relative(current[a], current[i])
                last = self.tried_at.get((s, i))
                if last is not None and (np.abs(relative(last, guess)) < self.redo).all():
                    continue  # searched from about here before, in vain
                self.tried_at[(s, i)] = guess
                todo.append(i)
            if todo:
                plan.append((s, todo))
        return plan

    def search(self, current: Array, p: int) -> None:
        """Pass ``p``'s search from the poses ``current``: the loops it finds join :attr:`found`."""
        c, res, nodes, stats = self.config.graph, self.config.map.resolution, self.nodes, self.stats
        clock = time.perf_counter()
        if p > 0 and self.found:
            # the loops found so far refined again from the solved poses: what a loop's match does
            # not pin (along a corridor) now comes from the graph's answer, not the front end's
            self.found = refreshed(self.found, self.scan_of, nodes, self.spans, current, c, self.pool)
        looped = {i for _, i in self.found}  # nodes with a loop: later passes search the others wide
        plan = self._plan(current)

        def drawn(s: int) -> Submap | None:
            return build_submap(self.scan_of, nodes, *self.spans[s], self.config, self.depth)

        # Each submap is drawn on the pool while the one before it is searched: its kernels
        # release the GIL, and the search's single-threaded parts leave a core idle.
        ahead = self.pool.submit(drawn, plan[0][0]) if plan else None
        for done, (s, todo) in enumerate(plan):
            if self.progress is not None:
                self.progress(done, len(plan))
            assert ahead is not None
            sub = ahead.result()
            ahead = self.pool.submit(drawn, plan[done + 1][0]) if done + 1 < len(plan) else None
            if sub is None:
                continue

            def one(i: int, sub: Submap = sub, s: int = s) -> tuple[Loop | None, list[Tried]]:
                wide = i % c.wide_every == 0 and (p == 0 or i not in looped)
                return search_node(
                    i, sub, s, self.spans[s], current, wide, self.travel, nodes, c, res, float(self.since[i])
                )

            # The kernels release the GIL: the nodes are matched on every core.
            for lp, spent in self.pool.map(one, todo):
                for tried in spent:
                    stats.loops_tried += 1
                    stats.loops_tried_wide += tried.stage == "wide"
                    stats.refused_ambiguous += tried.ambiguous
                    stats.refused_spread += tried.spread
                    self.slowest[tried.stage] = max(self.slowest[tried.stage], tried.seconds)
                if lp is not None:
                    self.found[(s, lp.node)] = lp
        if self.progress is not None:
            self.progress(len(plan), len(plan))
        stats.seconds_search += time.perf_counter() - clock

    def backed(self, current: Array) -> tuple[list[Loop], list[bool]]:
        """The strongest loops of each node (``loops_per_node``) and whether a chain of
        neighbouring nodes backs each (:func:`chained`); a loop with too few neighbours alike
        (a wide search tries every other node only) first has its neighbours searched where it
        says they are (:func:`verify_chains`), once."""
        c = self.config.graph
        strongest = strongest_loops(self.found, c.loops_per_node)
        backed = chained(strongest, self.spans, current, self.travel, c)
        alone = [lp for lp, b in zip(strongest, backed) if not b and (lp.submap, lp.node) not in self.checked]
        if alone:
            clock = time.perf_counter()
            more, spread = verify_chains(
                alone, self.scan_of, self.nodes, self.spans, current, self.travel, self.found, self.config,
                self.depth, self.pool,
            )  # fmt: skip
            self.stats.refused_spread += spread
            for lp in more:
                self.found[(lp.submap, lp.node)] = lp
            self.checked |= {(lp.submap, lp.node) for lp in alone}
            strongest = strongest_loops(self.found, c.loops_per_node)
            backed = chained(strongest, self.spans, current, self.travel, c)
            self.stats.seconds_search += time.perf_counter() - clock
        return strongest, backed


def _largest_move(before: Array, after: Array) -> float:
    """How far the back end moved a scan at most (m)."""
    return float(np.hypot(*(after[:, :2] - before[:, :2]).T).max()) if len(after) else 0.0


def local_closure(closure: LoopClosure, front: Array, config: BackendSettings) -> LoopClosure | None:
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
