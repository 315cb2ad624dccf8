"""Scoring a run: trajectory errors against a truth, the map agreement that needs none."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any, Sequence

from pfslam.config import SlamConfig
from pfslam.frames import Frame
from pfslam.pipeline.run import Array, Run, Truth

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
    return scores


def score_map_agreement(run: Run, frames: Sequence[Frame], scores: Scores) -> None:
    """The map agreement of the estimate and of the odometry (needs no truth) over the
    frames the run processed (of ``frames``, the log's), into ``scores`` and
    ``run.metrics``; skipped for runs of fewer than 4 scans or stopped early. NaN for a
    trajectory whose scans span more than the largest map."""
    from pfslam.eval.metrics import map_agreement
    from pfslam.maps.grid import MapTooLarge

    if run.scans < 4 or run.interrupted:
        return
    every = run.config.every if isinstance(run.config, SlamConfig) else 1
    done = frames[::every][: run.scans]

    def agreement(poses: Array) -> float:
        try:
            return map_agreement(done, poses)
        except MapTooLarge:  # a trajectory that drifts hundreds of metres (odometry, most often)
            return float("nan")

    # The two figures side by side: their ray updates release the GIL.
    with ThreadPoolExecutor(2) as pool:
        slam, odometry = pool.map(agreement, (run.poses, run.odometry))
    scores.map_agreement = {"SLAM": slam, "odometry": odometry}
    run.metrics["map_agreement"] = scores.map_agreement
