"""The loop search: each node matched against the older submaps near it (where the front end
put it, point to line; failing that by branch and bound over a window as wide as the drift
since could be), each match refined point to line with what it pins, and the loops checked
against the front end's path and each other before they go into the graph."""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from pfslam.backend.consistency import Chain, Paths, confirmed, consistent, correlated, gate, loop_arrays
from pfslam.backend.edges import loop_information
from pfslam.backend.nodes import Nodes, ScanOf, build_submap, submap_hits
from pfslam.backend.registration import Steps, fits
from pfslam.backend.settings import BackendSettings
from pfslam.backend.submaps import Submap, Surface, refine, surface_spread
from pfslam.config import GraphConfig
from pfslam.geometry import compose, relative
from pfslam.kernels.bnb import bilinear_score_kernel, window_match
from pfslam.types import Array


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
    # how far places that score about as well lie from it (3 x 3 covariance, node frame): see :func:`widened`
    spread: Array | None = None
    share: int = 1  # loops it shares one piece of evidence with (itself among them): its information is divided by it


def start_tie(session_poses: Array, start: Array, held: int) -> Loop:
    """A resumed run's start as an edge: from the session's node nearest to ``start`` to the
    run's first node (index ``held``)."""
    nearest = int(np.argmin(np.hypot(*(session_poses[:, :2] - start[:2]).T)))
    return Loop(nearest, held, -1, relative(session_poses[nearest], start), 1.0)


def near_submaps(
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


def by_submap(pairs: list[tuple[int, int]]) -> dict[int, list[int]]:
    """(submap, node) pairs grouped by submap, in submap order (each submap is built once)."""
    out: dict[int, list[int]] = {}
    for s, i in sorted(pairs):
        out.setdefault(s, []).append(i)
    return out


def strongest_loops(found: dict[tuple[int, int], Loop], k: int) -> list[Loop]:
    """The ``k`` best-scoring loops of each node, in (submap, node) order."""
    by_node: dict[int, list[tuple[float, tuple[int, int]]]] = {}
    for key, lp in found.items():
        by_node.setdefault(lp.node, []).append((-lp.score, key))
    keep = sorted(key for v in by_node.values() for _, key in sorted(v)[:k])
    return [found[key] for key in keep]


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
    and ``slip_m`` / ``slip_deg`` over each step that no scan match backs (``steps``)."""
    jitter = np.diag([c.node_sigma_m**2, c.node_sigma_m**2, np.deg2rad(c.node_sigma_deg) ** 2])
    slips = None
    chain = None
    if steps is not None:
        slips = np.concatenate([[0.0], np.cumsum(steps.unmatched_steps(len(poses)))])
        if c.gate_chain and len(steps):
            # a step with no edge at all (between runs, or from a held session): as unsure as a slip
            missing = np.zeros((len(poses), 3, 3))
            missing[:, 0, 0] = missing[:, 1, 1] = c.slip_m**2
            missing[:, 2, 2] = np.deg2rad(c.slip_deg) ** 2
            # (the scan matches alone: the front end's own steps are what is checked, not evidence)
            k = steps.matched
            chain = Chain.of(poses, steps.i[k], steps.j[k], steps.info[k], missing)
    return Paths(
        poses,
        travel,
        jitter,
        c.path_drift,
        float(np.deg2rad(c.path_drift_deg)),
        slips,
        c.slip_m,
        float(np.deg2rad(c.slip_deg)),
        chain,
    )


def loop_covariances(loops: Sequence[Loop], nodes: Nodes, c: GraphConfig) -> Array:
    """Each loop's covariance (node frame): its refined match's, never surer than the
    ``loop_sigma_*`` floors; a loop whose match was not refined (a scan too noisy or sparse for
    walls to be fitted to it), what its node's scan pins, never surer than ``unrefined_m``,
    ``unrefined_deg``; either widened by the places its score surface holds that score
    about as well (:func:`widened`)."""
    if not loops:
        return np.zeros((0, 3, 3))
    info = nodes.information()
    coarse = replace(
        c, loop_sigma_m=max(c.loop_sigma_m, c.unrefined_m), loop_sigma_deg=max(c.loop_sigma_deg, c.unrefined_deg)
    )
    out = []
    for lp in loops:
        if lp.info is not None:
            out.append(loop_information(lp.info[None], c)[0])
        else:
            out.append(loop_information(info[lp.node][None], coarse)[0])
    cov = np.linalg.inv(np.array(out))
    for k, lp in enumerate(loops):
        if lp.spread is not None:
            cov[k] += lp.spread
        cov[k] *= lp.share
    return np.asarray(cov)


def checked_loops(
    loops: list[Loop], nodes: Nodes, poses: Array, travel: Array, c: GraphConfig, *, solved: bool = True
) -> tuple[list[Loop], list[Loop], list[Loop]]:
    """The loops that pass the checks against the path (:func:`~pfslam.backend.consistency.gate`)
    and against each other (:func:`~pfslam.backend.consistency.consistent`), from ``poses``;
    and those refused by each (kept, far, inconsistent). With ``gate_chain``, before any solve
    (not ``solved``: ``poses`` the front end's) the path is the nodes as their edges alone
    place them (``nodes.registered``), which the chain's covariance is about."""
    if c.gate_chain and nodes.registered is not None and not solved:
        poses = nodes.registered
    paths = front_paths(poses, travel, c, nodes.steps)
    a, i, z = loop_arrays(loops)
    sub = np.array([lp.submap for lp in loops], dtype=np.int64)
    cov = loop_covariances(loops, nodes, c)
    chi2 = gate(a, i, z, cov, poses, paths)
    near = chi2 <= c.gate_chi2
    far = [lp for lp, ok in zip(loops, near) if not ok]
    if not near.any():
        return [], far, []
    a, i, z, sub, cov, chi2 = a[near], i[near], z[near], sub[near], cov[near], chi2[near]
    close = [lp for lp, ok in zip(loops, near) if ok]
    group = correlated(sub, travel[i], c.chain_m)
    agree = consistent(a, i, z, cov, poses, paths, c.pair_reach, c.gate_chi2, group=group, prior=chi2)
    # Each group the others do not confirm weighs as one loop in the solve (its loops share it).
    kept = np.flatnonzero(agree)
    group = correlated(sub[kept], travel[i[kept]], c.chain_m)
    sure = confirmed(a[kept], i[kept], sub[kept], z[kept], cov[kept], poses, paths, group, c.pair_reach, c.gate_chi2)
    size = np.bincount(group)[group] if len(kept) else np.zeros(0, dtype=np.int64)
    out = [replace(close[k], share=1 if ok else int(m)) for k, ok, m in zip(kept.tolist(), sure, size)]
    return out, far, [lp for lp, ok in zip(close, agree) if not ok]


def verify_chains(
    alone: Sequence[Loop],
    scan_of: ScanOf,
    nodes: Nodes,
    spans: Sequence[tuple[int, int]],
    current: Array,
    travel: Array,
    found: dict[tuple[int, int], Loop],
    config: BackendSettings,
    depth: int,
    pool: ThreadPoolExecutor,
) -> tuple[list[Loop], int]:
    """The loops of the nodes near each loop of ``alone`` (within ``chain_m`` of travel, into
    the same submap), each searched over a small window where that loop's correction puts the
    node: a true loop's neighbours match there too, and :func:`chained` then backs it. With
    them, how many matches their score surface refused (:func:`widened`)."""
    c = config.graph
    res = config.map.resolution
    tol = (2 * c.chain_tol_m, 2 * c.chain_tol_deg)
    out: list[Loop] = []
    spread = 0
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
            return job[0], job[1], window_match(sub, nodes.points[job[0]], job[1], tol[0], tol[1], c.min_score, res)

        for who, guess, m in pool.map(one, jobs):
            got = refined(Loop(a, who, s, m[0], m[1]), sub, nodes, c, guess) if m is not None else None
            wide = widened(got, sub, nodes, c, res) if got is not None else None
            spread += got is not None and wide is None
            if wide is not None:
                out.append(wide)
    return out, spread


def refined(lp: Loop, sub: Submap, nodes: Nodes, c: GraphConfig, guess: Array | None = None) -> Loop | None:
    """The loop refined point to line on its submap's surface, held at ``guess`` (where the
    search looked) in what the match does not pin, with what it pins. Where the refinement
    pairs too few of the node's points or fits them badly (:func:`~pfslam.backend.registration.fits`:
    walls could not be fitted to a noisy or sparse scan), the branch and bound match as it was
    (as unsure as :func:`loop_covariances` says), or None for a loop that had none (``score``
    0: a refinement tried straight from the guess)."""
    if sub.surface is None:
        return lp
    pts = np.asarray(nodes.dense[lp.node] if nodes.dense is not None else nodes.points[lp.node], dtype=np.float64)
    r = refine(sub.surface, pts, lp.pose, c.scan_points, guess)
    if fits(r, len(pts), c.loop_paired, c.step_rms_m):
        return replace(lp, pose=r.pose, info=r.info)
    return replace(lp, info=None) if lp.score > 0 else None


def direct(lp: Loop, sub: Submap, nodes: Nodes, c: GraphConfig, res: float) -> Loop | None:
    """The loop ``lp`` refined from its pose (where the front end put its node) as it is, if the
    refinement holds and the node's points score ``min_score`` on the submap's field there:
    no search is needed where the front end was within a match's reach of the truth."""
    out = refined(lp, sub, nodes, c, lp.pose)
    if out is None:
        return None
    score = float(
        bilinear_score_kernel(sub.field, nodes.points[lp.node].astype(np.float64), out.pose, sub.ox, sub.oy, res)
    )
    return replace(out, score=score) if score >= c.min_score else None


def refreshed(
    found: dict[tuple[int, int], Loop],
    scan_of: ScanOf,
    nodes: Nodes,
    spans: Sequence[tuple[int, int]],
    current: Array,
    c: GraphConfig,
    pool: ThreadPoolExecutor,
) -> dict[tuple[int, int], Loop]:
    """Every loop refined again on its submap's surface from where it was, held at where
    ``current`` puts its node (:func:`refined`)."""
    by_sub: dict[int, list[tuple[int, int]]] = {}
    for key in found:
        by_sub.setdefault(key[0], []).append(key)

    def one(s: int) -> list[tuple[tuple[int, int], Loop | None]]:
        a, e = spans[s]
        h = submap_hits(scan_of, nodes, a, e)
        if len(h) < 10:
            return [(key, found[key]) for key in by_sub[s]]
        sub = Submap(np.zeros((1, 1), np.float32), np.zeros((1, 1, 1), np.float32), 0.0, 0.0, Surface.of(h))
        return [(key, refined(found[key], sub, nodes, c, relative(current[a], current[key[1]]))) for key in by_sub[s]]

    return {key: lp for done in pool.map(one, sorted(by_sub)) for key, lp in done if lp is not None}


def widened(lp: Loop, sub: Submap, nodes: Nodes, c: GraphConfig, res: float) -> Loop | None:
    """The loop with the spread of the places on its submap that score about as well as its
    match (:func:`~pfslam.backend.submaps.surface_spread`, turned into a covariance about the
    node's pose), which :func:`loop_covariances` adds to its match's; None where that spread
    leaves every direction of position more uncertain than ``ambiguous_m`` (a match too
    ambiguous to be of use)."""
    if c.surface_m <= 0:
        return lp
    spread = surface_spread(
        sub, nodes.points[lp.node], lp.pose, res, c.surface_m, c.surface_deg, c.near_best, c.peak_m, c.peak_deg
    )
    if float(np.linalg.eigvalsh(spread[:2, :2])[0]) > c.ambiguous_m**2:
        return None
    return replace(lp, spread=spread)


@dataclass
class Tried:
    """One match tried: its stage (local or wide), its seconds, and whether it was refused as
    ambiguous (by the wide search's second best, or by its score surface's spread)."""

    stage: str
    seconds: float
    ambiguous: bool
    spread: bool = False


def search_node(
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
) -> tuple[Loop | None, list[Tried]]:
    """Node ``i`` against submap ``s`` (nodes ``span``), from the poses ``current``: the local
    window first; failing that (if ``wide_ok``) the wide one, as wide as the drift since the
    submap could be (``travel``: path length to each node; ``since``: its length where node
    ``i``'s run began, which a resumed run's start was placed at): the front end may have
    placed the node far off. The loop found, and each match tried (:class:`Tried`)."""
    a, e = span
    guess = relative(current[a], current[i])
    stages = [("local", c.local_m, c.local_deg)]
    if wide_ok:
        run_m = float(travel[i] - max(travel[e - 1], since))
        wide_m = min(c.window_m, max(c.local_m, c.drift_per_m * run_m))
        wide_deg = min(c.window_deg, max(c.local_deg, c.drift_deg_per_m * run_m))
        if wide_m > c.local_m or wide_deg > c.local_deg:
            stages.append(("wide", wide_m, wide_deg))
    spent: list[Tried] = []
    began = time.perf_counter()
    lp = direct(Loop(a, i, s, guess, 0.0), sub, nodes, c, res)
    if lp is not None:
        # Where the front end put the node within a match's reach, the match from there is the
        # loop, unless it is a local optimum: a front end that slipped along a corridor leaves
        # the walls matched and the features along it a few decimetres off, out of the
        # refinement's reach. The local window is searched for a place that scores better
        # (bounded by this one's score: where there is none, the search is cut short).
        m = window_match(sub, nodes.points[i], guess, c.local_m, c.local_deg, lp.score + c.better_score, res)
        if m is not None:
            d = relative(lp.pose, m[0])
            if np.hypot(d[0], d[1]) > c.better_m or abs(np.rad2deg(d[2])) > c.better_deg:
                lp = refined(Loop(a, i, s, m[0], m[1]), sub, nodes, c) or lp
        out = widened(lp, sub, nodes, c, res)
        spent.append(Tried("local", time.perf_counter() - began, False, out is None))
        return out, spent
    for stage, win_m, win_deg in stages:
        began = time.perf_counter()
        wide = stage == "wide"
        score = c.wide_min_score if wide else c.min_score
        why: list[str] = []
        m = window_match(
            sub, nodes.points[i], guess, win_m, win_deg, score, res, wide, c.ambiguity if wide else 0.0, why
        )
        # (a wide match is held where it matched: the front end's guess may be metres off)
        lp = refined(Loop(a, i, s, m[0], m[1]), sub, nodes, c, None if wide else guess) if m is not None else None
        out = widened(lp, sub, nodes, c, res) if lp is not None else None
        spent.append(Tried(stage, time.perf_counter() - began, bool(why), lp is not None and out is None))
        if lp is not None:
            return out, spent
    return None, spent
