"""The front end's path registered again, scan to scan: each node's scan matched point to line
on the scans of the nodes 1, 4, 16, ... before it (:func:`~pfslam.backend.submaps.refine`),
held at the front end's relative pose in what the scans do not pin (along a bare corridor).

A particle filter's path is as good as its map over the long run, but from scan to scan it
jitters: its proposal's peak moves by a few millimetres to centimetres along walls, and the
map it draws is blurred by as much. Two scans of the same walls matched to each other agree
to a millimetre or two across them. Those matches, over spans of 1, 4, 16 ... nodes (so that
their errors do not add up from node to node as one chain's would), are the graph's edges
between nearby nodes; solved alone they place each submap's nodes (:func:`local_poses`), so
that a submap is as sharp as a scan and a loop into it as precise as a match; solved with the
loops, they let the graph bend the path only where its loops say the front end drifted.
"""

from __future__ import annotations

from concurrent.futures import Executor
from dataclasses import dataclass
from typing import Callable

import numpy as np
from numpy.typing import NDArray

from pfslam.backend.edges import WEAK_DEG, WEAK_M, sequential_information
from pfslam.backend.graph import PoseGraph, solve
from pfslam.backend.submaps import Refined, Surface, refine
from pfslam.config import GraphConfig
from pfslam.geometry import relative
from pfslam.sensor import ScanPoints
from pfslam.types import Array


@dataclass
class Steps:
    """The graph's edges between nearby nodes: node ``j[k]`` seen from node ``i[k]`` at ``z[k]``
    with the information ``info[k]`` (3 x 3, node j's frame): the matches of two scans
    (``matched``) and the front end's relative poses (``matched`` False)."""

    i: NDArray[np.int64]
    j: NDArray[np.int64]
    z: Array
    info: Array
    matched: NDArray[np.bool_]

    def __len__(self) -> int:
        return len(self.i)

    def subset(self, k: NDArray[np.bool_] | NDArray[np.int64]) -> Steps:
        """The edges ``k`` (a mask or indices)."""
        return Steps(self.i[k], self.j[k], self.z[k], self.info[k], self.matched[k])

    def add_to(self, graph: PoseGraph) -> None:
        """These edges into ``graph``: the front end's as they are (a backbone that bends where it
        is least sure, never breaks), the matches as edges that may be wrong (``soft``: a match
        started from a front end that missed a turn can fall into the wrong minimum with it;
        where loops that agree say so, the solve gives it up)."""
        for m in (False, True):
            k = self.matched == m
            graph.add_many(self.i[k], self.j[k], self.z[k], None, np.zeros(int(k.sum()), dtype=bool), self.info[k], m)

    def unmatched_steps(self, n: int) -> NDArray[np.bool_]:
        """Which of the ``n - 1`` steps between consecutive nodes no match backs."""
        out = np.ones(max(n - 1, 0), dtype=bool)
        k = self.matched & (self.j - self.i == 1)
        out[self.i[k]] = False
        return out


def fits(r: Refined, points: int, fraction: float, max_rms: float) -> bool:
    """Whether a refinement of ``points`` points holds: it paired at least ``fraction`` of them
    (and 30) within ``max_rms`` (m, root mean square) of the walls."""
    return r.paired >= max(30, fraction * points) and r.rms <= max_rms


def match_spans(c: GraphConfig) -> list[int]:
    """The node spans matched: 1, 4, 16, ... (``match_levels`` of them)."""
    return [4**k for k in range(c.match_levels)]


def front_steps(poses: Array, pairs: Array, scan_info: Array, c: GraphConfig) -> Steps:
    """The front end's relative poses between the node ``pairs`` ((K, 2)), as sure as
    :func:`~pfslam.backend.edges.sequential_information` says (growing with the distance, looser
    where the later node's scan pins nothing)."""
    i, j = pairs[:, 0].astype(np.int64), pairs[:, 1].astype(np.int64)
    z = relative(poses[i], poses[j])
    return Steps(i, j, z, sequential_information(scan_info[j], z, c), np.zeros(len(i), dtype=bool))


def register_steps(
    poses: Array,
    own: NDArray[np.bool_],
    run: NDArray[np.int64] | None,
    scan_info: Array,
    hits: Callable[[int], ScanPoints],
    dense: list[NDArray[np.float32]],
    c: GraphConfig,
    pool: Executor,
) -> Steps:
    """The edges between nearby nodes (``poses``: the front end's, (N, 3)): for each node ``i``
    (where ``own[i]``: not held from a session) and the node ``i + m`` for every span ``m`` of
    :func:`match_spans` within one run (``run``: each node's, None: one run), the front end's relative
    pose (:func:`front_steps`) and the match of the later node's ``dense`` points on the earlier
    one's hits (``hits(i)``), started from it. A match that pairs too few points, fits badly or
    lies far outside the front end's pose is not used; the others are as sure as
    :func:`calibrated` finds them against the front end."""
    n = len(poses)
    pairs = [
        (i, i + m)
        for m in match_spans(c)
        for i in range(n - m)
        if own[i] and own[i + m] and (run is None or run[i] == run[i + m])
    ]
    if not pairs:
        return Steps(
            np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros(0, bool)
        )
    front = front_steps(poses, np.array(pairs), scan_info, c)
    by_source: dict[int, list[int]] = {}
    for k, (i, _) in enumerate(pairs):
        by_source.setdefault(i, []).append(k)
    weak = np.diag([WEAK_M**-2, WEAK_M**-2, np.deg2rad(WEAK_DEG) ** -2])

    def one(i: int) -> list[tuple[int, Array, Array]]:
        h = hits(i).hits
        if len(h) < 10:
            return []
        surface = Surface.of(h)
        done = []
        for k in by_source[i]:
            pts = dense[int(front.j[k])]
            if len(pts) < 10:
                continue
            cov = np.linalg.inv(front.info[k])
            sigma = (float(np.sqrt(max(cov[0, 0], cov[1, 1]))), float(np.rad2deg(np.sqrt(cov[2, 2]))))
            r = refine(surface, pts, front.z[k], c.scan_points, front.z[k], sigma)
            if not fits(r, len(pts), c.step_paired, c.step_rms_m):
                continue
            # a match the front end's pose lies far outside of failed (or the front end did:
            # either way the front end's is kept, as the safer of the two)
            nu = relative(front.z[k], r.pose)
            if float(nu @ np.linalg.solve(np.linalg.inv(r.info + weak) + cov, nu)) > c.step_gate_chi2:
                continue
            done.append((k, r.pose, r.info + weak))
        return done

    found = [d for done in pool.map(one, sorted(by_source)) for d in done]
    backed = {(int(front.i[d[0]]), int(front.j[d[0]])) for d in found}
    front = slipping(front, backed, c)
    if not found:
        return front
    at = front.subset(np.array([d[0] for d in found], dtype=np.int64))
    matches = Steps(
        at.i,
        at.j,
        np.array([d[1] for d in found], dtype=np.float64),
        np.array([d[2] for d in found], dtype=np.float64),
        np.ones(len(at), dtype=np.bool_),
    )
    matches = calibrated(matches, front)
    return Steps(
        np.concatenate([matches.i, front.i]),
        np.concatenate([matches.j, front.j]),
        np.concatenate([matches.z, front.z]),
        np.concatenate([matches.info, front.info]),
        np.concatenate([matches.matched, front.matched]),
    )


def slipping(front: Steps, backed: set[tuple[int, int]], c: GraphConfig) -> Steps:
    """The front end's steps, those between consecutive nodes that no match backs (``backed``: the
    pairs that were matched) as unsure as ``slip_m`` and ``slip_deg`` more: where
    consecutive scans did not match, the front end most likely erred too, and a loop's
    correction should go there."""
    k = np.array([j - i == 1 and (i, j) not in backed for i, j in zip(front.i.tolist(), front.j.tolist())], dtype=float)
    if not k.any():
        return front
    slip = np.zeros((len(k), 3, 3))
    slip[:, 0, 0] = slip[:, 1, 1] = k * c.slip_m**2
    slip[:, 2, 2] = k * np.deg2rad(c.slip_deg) ** 2
    info = np.asarray(np.linalg.inv(np.linalg.inv(front.info) + slip), dtype=np.float64)
    return Steps(front.i, front.j, front.z, info, front.matched)


CHI2_1_MEDIAN = 0.455  # the median of a chi^2 of one degree of freedom


def calibrated(matches: Steps, front: Steps) -> Steps:
    """``matches`` as sure as they are found to be: per span and per axis (x, y, heading, in
    the later node's frame), their differences from the front end's relative poses (``front``,
    which hold each pair of nodes) are squared against the variance both claim; where their
    median is above what a Gaussian gives, the scan matches claimed too much (a sparse scan,
    a real laser's distortion, a corridor: the residual of a fit does not show it) and their
    variance on that axis is raised by that factor. Against a front end as sure as the
    settings say, matches that are as good as they claim keep their own."""
    out = Steps(matches.i, matches.j, matches.z, matches.info.copy(), matches.matched)
    pos = {(int(a), int(b)): k for k, (a, b) in enumerate(zip(front.i, front.j))}
    at = np.array([pos[(int(a), int(b))] for a, b in zip(matches.i, matches.j)], dtype=np.int64)
    nu = relative(front.z[at], matches.z)
    cov = np.linalg.inv(matches.info)
    both = cov + np.linalg.inv(front.info[at])
    span = matches.j - matches.i
    for m in np.unique(span):
        k = span == m
        if k.sum() < 10:
            continue
        ratio = np.median(nu[k] ** 2 / np.diagonal(both[k], axis1=1, axis2=2), axis=0) / CHI2_1_MEDIAN
        # the variance both claim is too small by ``ratio``: the front end's is fixed, so the
        # matches' must grow by what is missing (never shrink)
        var_m = np.median(np.diagonal(cov[k], axis1=1, axis2=2), axis=0)
        var_f = np.median(np.diagonal(np.linalg.inv(front.info[at[k]]), axis1=1, axis2=2), axis=0)
        scale = np.maximum(1.0, (ratio * (var_m + var_f) - var_f) / var_m)
        d = 1.0 / np.sqrt(scale)
        out.info[k] = out.info[k] * np.outer(d, d)[None]
    return out


def local_poses(poses: Array, steps: Steps, held: int) -> Array:
    """The nodes placed by their steps alone (solved from ``poses``, the first ``held`` (at
    least one) held): where each is relative to its neighbours, as sharp as the matches; over
    the long run it drifts as the steps' errors add up."""
    graph = PoseGraph(poses.copy())
    steps.add_to(graph)
    out, _ = solve(graph, held=held)
    return out
