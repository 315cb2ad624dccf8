"""The pose graph: nodes (x, y, theta), edges (relative poses with their standard
deviations), solved on GTSAM with a robust loss on the loop edges, and written in g2o's
text format."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pfslam.config import RobustLoss
from pfslam.types import Array


@dataclass
class PoseGraph:
    """Poses (the initial guess, (N, 3)) and edges: edge k says that node ``j[k]`` seen from
    node ``i[k]`` is at ``z[k]`` (x, y, theta in i's frame), with the information matrix
    ``info[k]`` (3 x 3, the inverse covariance of the error in j's frame: x, y, theta);
    ``loop[k]`` marks the loop edges (the robust loss applies to them), ``soft[k]`` the edges
    that may have slipped (the front end's path where no scan match backs it): the robust loss
    applies to them too, but they are never counted as loops dropped."""

    poses: Array
    i: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    j: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    z: Array = field(default_factory=lambda: np.zeros((0, 3)))
    info: Array = field(default_factory=lambda: np.zeros((0, 3, 3)))
    loop: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=bool))
    soft: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=bool))

    def add(self, i: int, j: int, z: Array, sigma: Array, loop: bool) -> None:
        self.add_many(np.array([i]), np.array([j]), np.atleast_2d(z), np.atleast_2d(sigma), np.array([loop]))

    def add_many(
        self,
        i: NDArray[np.int64],
        j: NDArray[np.int64],
        z: Array,
        sigma: Array | None,
        loop: NDArray[np.bool_],
        info: Array | None = None,
        soft: bool = False,
    ) -> None:
        """Edges with independent errors of standard deviations ``sigma`` ((K, 3): x, y,
        theta), or with full information matrices ``info`` ((K, 3, 3)) instead."""
        z = np.asarray(z, dtype=float).reshape(-1, 3)
        if info is None:
            if sigma is None:
                raise ValueError("an edge needs its standard deviations or its information matrix")
            s = np.asarray(sigma, dtype=float).reshape(-1, 3)
            info = np.zeros((len(s), 3, 3))
            info[:, [0, 1, 2], [0, 1, 2]] = 1.0 / s**2
        self.i = np.concatenate([self.i, np.asarray(i, dtype=np.int64)])
        self.j = np.concatenate([self.j, np.asarray(j, dtype=np.int64)])
        self.z = np.vstack([self.z, z])
        self.info = np.concatenate([self.info, np.asarray(info, dtype=float).reshape(-1, 3, 3)])
        self.loop = np.concatenate([self.loop, np.asarray(loop, dtype=bool)])
        self.soft = np.concatenate([self.soft, np.full(len(z), soft, dtype=bool)])

    @property
    def sigma(self) -> Array:
        """Each edge's standard deviations (x, y, theta: the square roots of its covariance's
        diagonal)."""
        if not len(self.info):
            return np.zeros((0, 3))
        return np.sqrt(np.diagonal(np.linalg.inv(self.info), axis1=1, axis2=2))

    @property
    def loops(self) -> int:
        return int(self.loop.sum())


def solve(
    graph: PoseGraph,
    loss: RobustLoss = RobustLoss.CAUCHY,
    scale: float = 3.0,
    initial: Array | None = None,
    iterations: int = 100,
    held: int = 1,
    trusted: bool = False,
) -> tuple[Array, NDArray[np.bool_]]:
    """The poses that best explain the edges, from ``initial`` (default: ``graph.poses``), the
    first ``held`` poses (at least one) held where they are, and which loop edges they keep (an inlier mask over
    ``graph.loop``'s edges). The sequential edges' errors are Gaussian. On the loop edges:
    ``gnc``, graduated non-convexity (Yang et al. 2020) over a truncated quadratic, from the
    convex problem to one where a loop more than ``scale`` standard deviations off weighs
    nothing (it finds the loops that agree however far the guess is; about ten solves);
    ``cauchy`` or ``huber`` with that scale, one Levenberg-Marquardt solve (a loop far off at
    the start pulls little). ``trusted``: the loops were checked already (against the path
    and each other): they are kept as they are, Gaussian, and only the soft edges are sorted
    (a scan match that fell into the wrong minimum gives way to them)."""
    import gtsam

    n = len(graph.poses)
    start = graph.poses if initial is None else initial
    if n == 0:
        return start.copy(), np.zeros(0, dtype=bool)
    g = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    for k, p in enumerate(start):
        values.insert(k, gtsam.Pose2(float(p[0]), float(p[1]), float(p[2])))
    for k in range(min(max(held, 1), n)):
        g.add(gtsam.PriorFactorPose2(k, gtsam.Pose2(*map(float, start[k])), gtsam.noiseModel.Constrained.All(3)))
    est = gtsam.noiseModel.mEstimator
    robust = est.Cauchy.Create(scale) if loss == RobustLoss.CAUCHY else est.Huber.Create(scale)
    inliers = list(range(g.size()))  # the priors
    loop_factor: list[int] = []
    soft_factor: list[int] = []
    trusted_factor: list[int] = []
    sorted_loops = not trusted
    gnc = loss == RobustLoss.GNC and bool((graph.loop & sorted_loops).any() or (graph.soft & ~graph.loop).any())
    for i, j, z, info, lp, sf in zip(graph.i, graph.j, graph.z, graph.info, graph.loop, graph.soft):
        noise: Any = gtsam.noiseModel.Gaussian.Information(np.asarray(info, dtype=float))
        if ((lp and sorted_loops) or (sf and not lp)) and not gnc:
            noise = gtsam.noiseModel.Robust.Create(robust if lp else est.Cauchy.Create(scale), noise)
        if lp:
            (loop_factor if sorted_loops else inliers).append(g.size())
            if not sorted_loops:
                trusted_factor.append(g.size())
        else:
            (soft_factor if sf else inliers).append(g.size())
        g.add(gtsam.BetweenFactorPose2(int(i), int(j), gtsam.Pose2(float(z[0]), float(z[1]), float(z[2])), noise))
    lm = gtsam.LevenbergMarquardtParams()
    lm.setMaxIterations(iterations)
    lm.setRelativeErrorTol(1e-3)  # (a thousandth of the cost: well below what moves a map cell)
    if gnc:
        params = gtsam.GncLMParams(lm)
        params.setLossType(gtsam.GncLossType.TLS)
        params.setKnownInliers(inliers)
        opt = gtsam.GncLMOptimizer(g, values, params)
        opt.setInlierCostThresholds(0.5 * scale**2)
        result = opt.optimize()
        weights = np.asarray(opt.getWeights())
        keep = weights[loop_factor] > 0.5 if loop_factor else np.ones(len(trusted_factor), dtype=bool)
        # GNC stops its inner solves early; the loops it kept, solved to the end from there
        # (the ones it dropped left out; the soft edges it dropped kept, a millionth as sure,
        # so that no node is left without an edge).
        polish = gtsam.NonlinearFactorGraph()
        dropped = {f for f, k in zip(loop_factor, keep) if not k}
        slipped = {f for f in soft_factor if weights[f] <= 0.5}
        first = g.size() - len(graph.i)  # the priors come first
        for f in range(g.size()):
            if f in slipped:
                e = f - first
                weak = gtsam.noiseModel.Gaussian.Information(1e-6 * np.asarray(graph.info[e], dtype=float))
                z = graph.z[e]
                pose = gtsam.Pose2(float(z[0]), float(z[1]), float(z[2]))
                polish.add(gtsam.BetweenFactorPose2(int(graph.i[e]), int(graph.j[e]), pose, weak))
            elif f not in dropped:
                polish.add(g.at(f))
        result = gtsam.LevenbergMarquardtOptimizer(polish, result, lm).optimize()
    else:
        result = gtsam.LevenbergMarquardtOptimizer(g, values, lm).optimize()
        keep = np.ones(int(graph.loop.sum()), dtype=np.bool_)
    out = np.empty((n, 3))
    for k in range(n):
        p = result.atPose2(k)
        out[k] = (p.x(), p.y(), p.theta())
    if loss != RobustLoss.GNC and loop_factor:
        keep = whitened(graph, out)[graph.loop] <= scale
    if trusted:
        keep = np.ones(int(graph.loop.sum()), dtype=np.bool_)
    return out, keep


def whitened(graph: PoseGraph, poses: Array) -> Array:
    """Each edge's error at ``poses`` in standard deviations (its Mahalanobis length under the
    edge's information matrix)."""
    from pfslam.geometry import relative

    if len(graph.i) == 0:
        return np.zeros(0)
    err = relative(graph.z, relative(poses[graph.i], poses[graph.j]))
    return np.sqrt(np.maximum(np.einsum("ki,kij,kj->k", err, graph.info, err), 0.0))


def write_g2o(path: str | Path, graph: PoseGraph, poses: Array | None = None) -> Path:
    """``graph`` in g2o's text format (VERTEX_SE2 id x y theta; EDGE_SE2 i j dx dy dtheta and the
    upper triangle of the information matrix), with ``poses`` (default: the graph's own) as
    the vertices; g2o's and GTSAM's tools read it. The loop edges come last, after the comment
    line :data:`LOOPS_MARK` (the edges before it join nearby nodes: consecutive ones and the
    scan matches over a few nodes)."""
    path = Path(path)
    p = graph.poses if poses is None else poses
    lines = [f"VERTEX_SE2 {k} {x:.6f} {y:.6f} {t:.6f}" for k, (x, y, t) in enumerate(p)]
    for loops in (False, True):
        k = np.nonzero(graph.loop == loops)[0]
        if loops:
            lines.append(LOOPS_MARK)
        for i, j, z, m in zip(graph.i[k], graph.j[k], graph.z[k], graph.info[k]):
            upper = " ".join(f"{m[a, b]:.6g}" for a in range(3) for b in range(a, 3))
            lines.append(f"EDGE_SE2 {i} {j} {z[0]:.6f} {z[1]:.6f} {z[2]:.6f} {upper}")
    path.write_text("\n".join(lines) + "\n")
    return path


LOOPS_MARK = "# pfslam: loop edges follow"


def read_g2o(path: str | Path) -> PoseGraph:
    """A graph written by :func:`write_g2o` (or any g2o SE2 file): its vertices as the poses, the
    edges after :data:`LOOPS_MARK` loops (in a file without it: every edge that joins
    non-consecutive vertices)."""
    verts: dict[int, tuple[float, float, float]] = {}
    edges: list[tuple[float, ...]] = []
    marked: int | None = None  # the edges from this one on are loops
    for line in Path(path).read_text().splitlines():
        if line.strip() == LOOPS_MARK:
            marked = len(edges)
        f = line.split()
        if not f:
            continue
        if f[0] == "VERTEX_SE2":
            verts[int(f[1])] = (float(f[2]), float(f[3]), float(f[4]))
        elif f[0] == "EDGE_SE2":
            a, b = int(f[1]), int(f[2])
            edges.append((a, b, *(float(v) for v in f[3:12])))
    ids = sorted(verts)
    graph = PoseGraph(np.array([verts[k] for k in ids], dtype=float).reshape(-1, 3))
    if edges:
        e = np.array(edges)
        u = e[:, 5:11]  # the information's upper triangle: xx xy xt yy yt tt
        info = np.stack(
            [u[:, [0, 1, 2]], u[:, [1, 3, 4]], u[:, [2, 4, 5]]],
            axis=1,
        )
        graph.add_many(
            e[:, 0].astype(np.int64),
            e[:, 1].astype(np.int64),
            e[:, 2:5],
            None,
            np.arange(len(e)) >= marked if marked is not None else np.abs(e[:, 1] - e[:, 0]) != 1,
            info=info,
        )
    return graph


CHI2_3_MEDIAN = 2.366  # the median of a chi^2 of three degrees of freedom
FACTOR_RANGE = (0.1, 100.0)  # a group's variance is scaled by at most this much either way


def variance_factors(graph: PoseGraph, poses: Array) -> dict[str, float]:
    """How much each group of edges (``front``: neither loop nor soft, ``match``: soft, ``loop``)
    erred at ``poses`` against what it claims: the median of its squared Mahalanobis errors
    over that of a chi^2 of three degrees of freedom (a robust variance component estimate;
    1 where a group has no edge), within :data:`FACTOR_RANGE`. A front end that drifted shows
    in its edges' errors once the loops pull the path straight, and its edges are then
    loosened by as much; a front end that did not, tightened."""
    w = whitened(graph, poses) ** 2
    groups = {"front": ~graph.loop & ~graph.soft, "match": graph.soft & ~graph.loop, "loop": graph.loop}
    out = {}
    for name, k in groups.items():
        f = float(np.median(w[k])) / CHI2_3_MEDIAN if k.any() else 1.0
        out[name] = float(np.clip(f, *FACTOR_RANGE))
    return out


def reweighted(graph: PoseGraph, factors: dict[str, float]) -> PoseGraph:
    """``graph`` with each group's information divided by its variance factor
    (:func:`variance_factors`)."""
    scale = np.where(graph.loop, factors["loop"], np.where(graph.soft, factors["match"], factors["front"]))
    return PoseGraph(graph.poses, graph.i, graph.j, graph.z, graph.info / scale[:, None, None], graph.loop, graph.soft)
