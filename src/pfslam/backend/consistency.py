"""Every loop checked against what the front end knew, and against the other loops.

A loop says "node ``i`` seen from node ``a`` is at ``z``"; the path between them says where the
front end (and the scan matches between nearby nodes) put it, with an uncertainty that grows
with the steps between them. Each is a Gaussian; their difference is checked as a Mahalanobis
distance (:func:`gate`): a loop far outside it is refused before the solve, whatever its score.
Two loops near each other close a cycle through two short paths (between their anchors and
between their nodes): two true loops agree to within the short paths' uncertainty, a loop slid
along a corridor does not agree with its true neighbours (:func:`consistent`, pairwise
consistency maximisation as in Mangelson et al. 2018, greedily).

The uncertainties are carried as world-frame (left) perturbations: a perturbation of a node
moves everything after it rigidly, so the covariances of the pieces of a cycle add without
being carried from frame to frame. ``Ad(X)`` maps a perturbation in the frame of pose ``X`` to
the world's.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from pfslam.geometry import compose, relative, wrap_angle
from pfslam.types import Array

PAIR_CHI2 = 16.27  # chi^2 of 3 degrees of freedom at 99.9 %: two loops whose cycle is beyond it disagree
PAIR_REACH = 40  # nodes: loops are compared when their anchors and their nodes are this close (in steps)


def adjoint(poses: Array) -> Array:
    """``Ad(X)`` of each pose ((N, 3) -> (N, 3, 3)): (dx, dy, dtheta) in X's frame to the world's."""
    p = np.asarray(poses, dtype=float).reshape(-1, 3)
    c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
    out = np.zeros((len(p), 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = c, -s, p[:, 1]
    out[:, 1, 0], out[:, 1, 1], out[:, 1, 2] = s, c, -p[:, 0]
    out[:, 2, 2] = 1.0
    return out


def to_world(poses: Array, cov: Array) -> Array:
    """Covariances ((N, 3, 3)) of perturbations in each pose's frame, as world-frame ones."""
    ad = adjoint(poses)
    return np.asarray(ad @ cov @ np.transpose(ad, (0, 2, 1)))


def world_difference(x: Array, y: Array) -> Array:
    """The world-frame perturbation that takes poses ``y`` to poses ``x`` ((N, 3) each, to first
    order in the heading): ``x = Exp(d) y``."""
    dth = wrap_angle(x[:, 2] - y[:, 2])
    c, s = np.cos(dth), np.sin(dth)
    tx = x[:, 0] - (c * y[:, 0] - s * y[:, 1])
    ty = x[:, 1] - (s * y[:, 0] + c * y[:, 1])
    return np.column_stack([tx, ty, dth])


@dataclass
class Paths:
    """What the front end knew of where any node is relative to any other: each node's own error
    (``jitter``, (3, 3) in its frame: a filter's pose jitters about its map by a few
    centimetres and a fraction of a degree, but does not add up from step to step), and a drift
    that grows with the distance travelled between them (``drift_m`` m and ``drift_rad`` rad per
    metre; ``travel``: the path length to each node)."""

    poses: Array
    travel: Array
    jitter: Array
    drift_m: float
    drift_rad: float
    # Steps no scan match backs (from node k to k + 1), counted from the start ((N,)), and what
    # the front end may have got wrong over each (m, rad: a turn missed where the scans barely
    # overlap).
    slips: Array | None = None
    slip_m: float = 0.0
    slip_rad: float = 0.0

    # What the chain of edges between nearby nodes knows (:class:`Chain`): where given, the
    # covariance between two nodes is propagated along it instead of drift_* per metre and slips.
    chain: Chain | None = None

    def between(self, a: NDArray[np.int64], b: NDArray[np.int64]) -> Array:
        """The world-frame covariance of where node ``b`` is relative to node ``a`` ((K, 3, 3)):
        both nodes' jitter and the drift over the path between them (turning about ``b``), and
        the slips it may hold; with a :attr:`chain`, what the edges along it know instead of
        the drift and the slips."""
        jit = np.broadcast_to(self.jitter, (len(a), 3, 3))
        if self.chain is not None:
            return to_world(self.poses[a], jit) + to_world(self.poses[b], jit) + self.chain.between(a, b)
        d = np.abs(self.travel[b] - self.travel[a])
        drift = np.zeros((len(d), 3, 3))
        drift[:, 0, 0] = drift[:, 1, 1] = (self.drift_m * d) ** 2
        drift[:, 2, 2] = (self.drift_rad * d) ** 2
        if self.slips is not None:
            k = np.abs(self.slips[b] - self.slips[a])
            drift[:, 0, 0] += k * self.slip_m**2
            drift[:, 1, 1] += k * self.slip_m**2
            drift[:, 2, 2] += k * self.slip_rad**2
        jit = np.broadcast_to(self.jitter, (len(d), 3, 3))
        return to_world(self.poses[a], jit) + to_world(self.poses[b], jit + drift)


@dataclass
class Chain:
    """The covariance of where one node is relative to another, propagated along the edges
    between nearby nodes (spans of 1, 4, 16 ... nodes; :func:`~pfslam.backend.search.front_paths`
    gives it the scan matches alone). Each edge's covariance (all the edges over its span combined, carried
    into the world frame at its end) is spread evenly over the node steps it spans; each step
    takes the surest of the edges over it, and the covariance between two nodes is the sum
    over the steps between them. Large along a bare corridor, where no edge pins the path
    along it, and where no match backs a step (the front end may have slipped there); small
    where the scans pinned the path."""

    sums: Array  # (N, 3, 3): the steps' covariances added up from the first node

    @classmethod
    def of(
        cls,
        poses: Array,
        i: NDArray[np.int64],
        j: NDArray[np.int64],
        info: Array,
        missing: Array,
    ) -> Chain:
        """From the edges (``i`` -> ``j``, information ``info`` in j's frame) between ``poses``
        ((N, 3)); a step no edge spans counts ``missing`` ((N, 3, 3), world frame)."""
        n = len(poses)
        rate = missing[: max(n - 1, 0)].copy()
        cost = np.trace(rate, axis1=1, axis2=2) if n > 1 else np.zeros(0)
        span = j - i
        for m in sorted({int(s) for s in span.tolist()}):
            k = span == m
            total = np.zeros((n, 3, 3))
            np.add.at(total, i[k], info[k])
            have = np.zeros(n, dtype=bool)
            have[i[k]] = True
            start = np.flatnonzero(have & (np.arange(n) + m < n))
            if not len(start):
                continue
            per_step = to_world(poses[start + m], np.asarray(np.linalg.inv(total[start]), dtype=np.float64)) / m
            tr = np.trace(per_step, axis1=1, axis2=2)
            for off in range(m):  # each step the edge spans
                at = start + off
                better = tr < cost[at]
                rate[at[better]] = per_step[better]
                cost[at[better]] = tr[better]
        sums = np.zeros((n, 3, 3))
        if n > 1:
            sums[1:] = np.cumsum(rate, axis=0)
        return cls(sums)

    def between(self, a: NDArray[np.int64], b: NDArray[np.int64]) -> Array:
        """The world-frame covariance the chain gives of node ``b`` relative to node ``a``."""
        return np.asarray(np.abs(self.sums[np.maximum(a, b)] - self.sums[np.minimum(a, b)]))


def _chi2(d: Array, cov: Array) -> Array:
    return np.einsum("ki,ki->k", d, np.linalg.solve(cov, d[..., None])[..., 0])


def gate(
    anchor: NDArray[np.int64], node: NDArray[np.int64], z: Array, loop_cov: Array, poses: Array, paths: Paths
) -> Array:
    """Each loop's Mahalanobis distance (chi^2) from where ``poses`` put its node relative to its
    anchor, under the loop's covariance (``loop_cov``, node frame) and the path's
    (:meth:`Paths.between`)."""
    said = compose(poses[anchor], z)
    d = world_difference(said, poses[node])
    cov = to_world(said, loop_cov) + paths.between(anchor, node)
    return _chi2(d, cov)


def correlated(submap: NDArray[np.int64], travel: Array, reach_m: float) -> NDArray[np.int64]:
    """Which loops share their evidence (a group number per loop): loops into one submap from
    nodes within ``reach_m`` of travel of each other, chained. One stretch of path matched into
    one submap meets that submap's look-alikes together: five such loops slid alike are one
    piece of evidence, not five. (Loops into the next submap, which holds half the same scans,
    are not of the group, or one pass along a corridor would chain into one group; they never
    confirm it either: :func:`confirmed`.)"""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(submap)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    link = (submap[:, None] == submap[None, :]) & (np.abs(travel[:, None] - travel[None, :]) <= reach_m)
    p, q = np.nonzero(link)
    _, label = connected_components(coo_matrix((np.ones(len(p)), (p, q)), shape=(n, n)), directed=False)
    return np.asarray(label, dtype=np.int64)


def consistent(
    anchor: NDArray[np.int64],
    node: NDArray[np.int64],
    z: Array,
    loop_cov: Array,
    poses: Array,
    paths: Paths,
    reach: int = PAIR_REACH,
    limit: float = PAIR_CHI2,
    group: NDArray[np.int64] | None = None,
    prior: Array | None = None,
) -> NDArray[np.bool_]:
    """The loops kept by pairwise consistency: each pair whose anchors and nodes are within
    ``reach`` nodes of each other is a cycle (loop p, the path from node p to node q, loop q
    backwards, the path between the anchors), which two true loops close to within its
    uncertainty (chi^2 under ``limit``). The loop with the most disagreements is dropped, and
    again, until no two kept loops disagree (a greedy maximum consistent set).

    ``group``: loops that share their evidence (:func:`correlated`); a disagreement with a loop
    of a group of k counts 1/k, so that a group outvotes no single independent loop by its
    numbers. ``prior``: each loop's distance from the front end's path (the gate's chi^2);
    between loops as much at odds, the one farther from it goes first."""
    n = len(anchor)
    keep = np.ones(n, dtype=bool)
    p, q = _near_pairs(anchor, node, reach, np.triu(np.ones((n, n), dtype=bool), 1))
    if not len(p):
        return keep
    bad = _cycle_chi2(anchor, node, z, loop_cov, poses, paths, p, q) > limit
    p, q = p[bad], q[bad]
    size = np.bincount(group)[group].astype(float) if group is not None else np.ones(n)
    # loop p's count: its disagreements, each weighing 1 / (the other loop's group size)
    count = np.bincount(p, 1.0 / size[q], minlength=n) + np.bincount(q, 1.0 / size[p], minlength=n)
    tie = np.zeros(n) if prior is None else np.asarray(prior, dtype=float)
    while len(p):
        top = count >= count.max() - 1e-9
        worst = int(np.flatnonzero(top)[np.argmax(tie[top])])
        keep[worst] = False
        gone = (p == worst) | (q == worst)
        np.subtract.at(count, p[gone], 1.0 / size[q[gone]])
        np.subtract.at(count, q[gone], 1.0 / size[p[gone]])
        count[worst] = -np.inf
        p, q = p[~gone], q[~gone]
    return keep


def confirmed(
    anchor: NDArray[np.int64],
    node: NDArray[np.int64],
    submap: NDArray[np.int64],
    z: Array,
    loop_cov: Array,
    poses: Array,
    paths: Paths,
    group: NDArray[np.int64],
    reach: int = PAIR_REACH,
    limit: float = PAIR_CHI2,
) -> NDArray[np.bool_]:
    """Which loops' groups (:func:`correlated`) another group confirms: a loop of it into a
    submap not next to theirs (other look-alikes) closes a cycle with one of theirs within
    ``limit``. An unconfirmed group is one piece of evidence, however many loops it holds."""
    out = np.zeros(len(anchor), dtype=bool)
    other = (group[:, None] != group[None, :]) & (np.abs(submap[:, None] - submap[None, :]) > 1)
    p, q = _near_pairs(anchor, node, reach, other)
    if not len(p):
        return out
    agree = _cycle_chi2(anchor, node, z, loop_cov, poses, paths, p, q) <= limit
    sure = np.unique(group[p[agree]])
    return np.isin(group, sure)


def _near_pairs(
    anchor: NDArray[np.int64], node: NDArray[np.int64], reach: int, among: NDArray[np.bool_]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The pairs of loops (p, q) that ``among`` ((n, n)) allows whose anchors and whose nodes
    are within ``reach`` nodes of each other: the ones whose cycle is short enough to check."""
    if len(anchor) < 2:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    p, q = np.nonzero(
        (np.abs(anchor[:, None] - anchor[None, :]) <= reach) & (np.abs(node[:, None] - node[None, :]) <= reach) & among
    )
    return p.astype(np.int64), q.astype(np.int64)


def _cycle_chi2(
    anchor: NDArray[np.int64],
    node: NDArray[np.int64],
    z: Array,
    loop_cov: Array,
    poses: Array,
    paths: Paths,
    p: NDArray[np.int64],
    q: NDArray[np.int64],
) -> Array:
    """The chi^2 of the cycle each pair of loops (``p``, ``q``) closes with the paths between
    their anchors and between their nodes."""
    # Where each loop puts node node[p]: loop p directly; loop q through its own node and the
    # path from node[q] to node[p], from where anchor[q] is relative to anchor[p].
    by_p = compose(poses[anchor[p]], z[p])
    node_q = compose(poses[anchor[q]], z[q])
    by_q = compose(node_q, relative(poses[node[q]], poses[node[p]]))
    d = world_difference(by_p, by_q)
    cov = (
        to_world(by_p, loop_cov[p])
        + to_world(node_q, loop_cov[q])
        + paths.between(anchor[p], anchor[q])
        + paths.between(node[q], node[p])
    )
    return _chi2(d, cov)


def loop_arrays(loops: Sequence[object]) -> tuple[NDArray[np.int64], NDArray[np.int64], Array]:
    """(anchors, nodes, poses) of loops (objects with ``anchor``, ``node``, ``pose``)."""
    a = np.array([lp.anchor for lp in loops], dtype=np.int64)  # type: ignore[attr-defined]
    i = np.array([lp.node for lp in loops], dtype=np.int64)  # type: ignore[attr-defined]
    z = np.array([lp.pose for lp in loops], dtype=np.float64).reshape(-1, 3)  # type: ignore[attr-defined]
    return a, i, z
