"""Scoring a run: trajectory errors against a truth, the map agreement that needs none."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
from numpy.typing import NDArray

from pfslam.config import SlamConfig
from pfslam.eval.table import WITHIN_M
from pfslam.frames import Frame
from pfslam.pipeline.run import Array, Run, Truth

if TYPE_CHECKING:
    from pfslam.backend.search import Loop

# -- scoring a run -----------------------------------------------------------------------


@dataclass
class Scores:
    """The figures of a run: trajectory errors per trajectory (when a truth is known) and the
    map agreement (SLAM); ``problem`` says why the errors could not be computed, if so."""

    errors: dict[str, Any] = field(default_factory=dict)  # name -> TrajectoryErrors
    map_agreement: dict[str, float] = field(default_factory=dict)
    problem: str | None = None


def score_trajectories(run: Run, truth: Truth | None, names: tuple[str, str]) -> Scores:
    """ATE/RPE of the estimate and of the odometry against ``truth``, kept in ``run.metrics``."""
    from pfslam.eval.metrics import trajectory_errors

    scores = Scores()
    if truth is None or run.scans < 2:
        return scores
    try:
        scores.errors = {
            names[0]: trajectory_errors(run.t, run.poses, *truth),
            names[1]: trajectory_errors(run.t, run.odometry, *truth),
        }
    except ValueError as e:  # e.g. no time stamps in common with the ground truth
        scores.problem = str(e)
        return scores
    run.metrics.update({k: v.as_dict() for k, v in scores.errors.items()})
    if run.kind != "slam":
        run.metrics[names[0]]["within_m"] = WITHIN_M
        run.metrics[names[0]]["within_after_s"] = within_after(run, truth)
    return scores


def within_after(run: Run, truth: Truth) -> float | None:
    """Seconds after the robot's first motion (by its odometry) from which the estimate's raw
    position error against ``truth`` stays within :data:`WITHIN_M` (0 if it always did;
    None if its last matched pose is further off): how long a global start, or a lost
    filter, took to find the robot for good."""
    from pfslam.eval.metrics import pose_errors
    from pfslam.pipeline.run import first_motion_time

    pe = pose_errors(run.t, run.poses, *truth)
    err = np.hypot(*(pe.estimate[:, :2] - pe.reference[:, :2]).T)
    if not len(err) or err[-1] > WITHIN_M:
        return None
    off = np.nonzero(err > WITHIN_M)[0]
    start = first_motion_time(run.t, run.odometry)
    return 0.0 if not len(off) else float(max(pe.t[off[-1] + 1] - start, 0.0))


SIDE_BY_SIDE_CELLS = 40_000_000  # the two map agreements' maps together (cells) past which they run one after the other
MAX_REACH = 100.0  # m: the farthest a laser's beams are taken to reach, for the maps' extent


def _cells(poses: Array, reach: float, resolution: float) -> float:
    """About how many cells the map of a path ``poses`` spans, its scans reaching ``reach``."""
    if not len(poses):
        return 0.0
    span = np.ptp(poses[:, :2], axis=0) + 2 * reach
    return float(np.prod(span / resolution))


def score_map_agreement(run: Run, frames: Sequence[Frame], scores: Scores) -> None:
    """The map agreement of the estimate and of the odometry (needs no truth) over the
    frames the run processed (of ``frames``, the log's), into ``scores`` and
    ``run.metrics``; skipped for runs of fewer than 4 scans or stopped early. NaN for a
    trajectory whose scans span more than the largest map."""
    from pfslam.eval.metrics import agreement_points, map_agreement
    from pfslam.maps.grid import MapTooLarge

    if run.scans < 4 or run.interrupted:
        return
    every = run.config.every if isinstance(run.config, SlamConfig) else 1
    done = frames[::every][: run.scans]
    n = min(len(done), len(run.poses), len(run.odometry))
    points = agreement_points(done[:n])  # the scans' points once for both trajectories

    known = run.backend.agreement_of_result() if run.backend is not None else None

    def agreement(poses: Array) -> float:
        if poses is run.poses and known is not None:  # the back end's check computed it already
            return known
        try:
            return map_agreement(done[:n], poses[:n], points=points)
        except MapTooLarge:  # a trajectory that drifts hundreds of metres (odometry, most often)
            return float("nan")

    # The two figures side by side (their ray updates release the GIL), unless their maps are
    # large: each costs about 16 bytes a cell (the grid, its scratch, three splits' masks).
    reach = float(np.median([f.max_range for f in done[: n : max(1, n // 100)]])) if n else 0.0
    if (
        sum(_cells(p[:n], min(reach, MAX_REACH), run.grid.resolution) for p in (run.poses, run.odometry))
        > SIDE_BY_SIDE_CELLS
    ):
        slam, odometry = agreement(run.poses), agreement(run.odometry)
    else:
        with ThreadPoolExecutor(2) as pool:
            slam, odometry = pool.map(agreement, (run.poses, run.odometry))
    scores.map_agreement = {"SLAM": slam, "odometry": odometry}
    run.metrics["map_agreement"] = scores.map_agreement


LOOP_OFF_M = 0.2  # a loop edge farther than this from the truth's relative pose is counted off ...
LOOP_OFF_DEG = 3.0  # ... or turned by more than this
SURELY_CHI2 = 16.27  # ... and beyond its own covariance by this (chi^2 of 3 dof at 99.9 %)


def score_loops(run: Run, truth: Truth | None) -> None:
    """How many of the back end's loop edges disagree with ``truth`` (the truth's relative pose
    between the two nodes farther than 0.2 m or turned more than 3 degrees from the edge),
    among those it found (before its checks), solved (in its last graph) and kept (in the
    answer the run keeps: none when the filter's stands), into ``run.metrics["loop_edges"]``;
    and of those solved, how many are off by more than they claim (``solved_off_beyond_own``:
    a loop 0.4 m off along a bare corridor whose look-alikes gave it 0.3 m of uncertainty
    that way is off, but as unsure as it says).
    A loop counts where the truth covers both its nodes (``unchecked``: the found ones it does
    not; a resumed run's nodes held from its session never)."""
    from pfslam.eval.metrics import associate
    from pfslam.geometry import relative

    c = run.backend.closure if run.backend is not None else None
    if c is None or truth is None or not (c.loops or c.found):
        return
    own = np.nonzero(c.nodes.scan >= 0)[0]  # (a session's nodes have no scan of this run)
    i_node, i_ref = associate(run.t[c.nodes.scan[own]], truth[0])
    ref_of = dict(zip(own[i_node].tolist(), i_ref.tolist()))

    def errors(loops: Sequence[Loop]) -> tuple[list[int], Array]:
        """The loops the truth covers (their indices) and each one's error (node frame)."""
        at, err = [], []
        for k, lp in enumerate(loops):
            if lp.anchor not in ref_of or lp.node not in ref_of:
                continue
            true_rel = relative(truth[1][ref_of[lp.anchor]], truth[1][ref_of[lp.node]])
            at.append(k)
            err.append(relative(true_rel, lp.pose))
        return at, np.array(err).reshape(-1, 3)

    def off(d: Array) -> NDArray[np.bool_]:
        return (np.hypot(d[:, 0], d[:, 1]) > LOOP_OFF_M) | (np.abs(np.rad2deg(d[:, 2])) > LOOP_OFF_DEG)

    found = c.found or c.loops
    at, d = errors(found)
    checked, found_off = len(at), int(off(d).sum())
    at, d = errors(c.loops)
    solved_off = int(off(d).sum())
    # ... and of those, the ones off by more than the loop itself claims (its covariance in
    # the solve, look-alikes and shared evidence included: chi^2 beyond 99.9 %, 3 dof)
    config = run.config
    surely = 0
    if len(at) and isinstance(config, SlamConfig):
        from pfslam.backend.search import loop_covariances

        cov = loop_covariances([c.loops[k] for k in at], c.nodes, config.graph)
        chi2 = np.einsum("ki,ki->k", d, np.linalg.solve(cov, d[..., None])[..., 0])
        surely = int((off(d) & (chi2 > SURELY_CHI2)).sum())
    kept = run.backend is not None and run.backend.kept
    run.metrics["loop_edges"] = {
        "found": len(found),
        "found_off": found_off,
        "solved": len(c.loops),
        "solved_off": solved_off,
        "solved_off_beyond_own": surely,
        "kept": len(c.loops) if kept else 0,
        "kept_off": solved_off if kept else 0,
        "unchecked": len(found) - checked,
    }
