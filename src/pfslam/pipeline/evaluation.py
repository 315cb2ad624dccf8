"""``pfslam evaluate`` as a library call: a trajectory's errors against a reference (ATE raw and
SE(2)-aligned, RPE, optional pictures) and/or the SLAM benchmark's relations metric, returned
for the caller to show."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from pfslam.errors import InputError

if TYPE_CHECKING:
    from pfslam.eval.metrics import RelationErrors, TrajectoryErrors


@dataclass
class Evaluation:
    """What :func:`evaluate` measured: ``errors`` against the reference (a
    :class:`~pfslam.eval.metrics.TrajectoryErrors`, None without one), the pictures drawn, the
    ``relations`` metric (None without a relations file), and what the caller should warn of."""

    errors: TrajectoryErrors | None = None
    pictures: list[Path] = field(default_factory=list)
    relations: RelationErrors | None = None
    warnings: list[str] = field(default_factory=list)


def evaluate(
    estimate: Path,
    reference: Path | None = None,
    relations: Path | None = None,
    *,
    time_offset: float = 0.0,
    max_dt: float = 0.02,
    rpe_delta: int = 10,
    plot: Path | None = None,
) -> Evaluation:
    """The errors of the TUM trajectory ``estimate`` against the TUM ``reference`` (poses paired
    within ``max_dt`` s, RPE over ``rpe_delta`` poses; with ``plot``, the pictures written into
    that folder) and/or against the benchmark ``relations`` (their stamps minus
    ``time_offset``). Bad input is an :class:`~pfslam.errors.InputError` naming the file."""
    from pfslam.eval.metrics import pose_errors, read_relations, relation_errors, trajectory_errors
    from pfslam.io.trajectory import read_tum

    if reference is None and relations is None:
        raise InputError(estimate, "give a reference trajectory (--reference) or --relations")
    if plot is not None and reference is None:
        raise InputError(plot, "--plot draws the errors against a reference trajectory: give one")
    if plot is not None:
        from pfslam.io.folders import prepare_output_dir

        prepare_output_dir(plot)
    out = Evaluation()
    t_est, est = read_tum(estimate)
    if reference is not None:
        t_ref, ref_poses = read_tum(reference)
        try:
            out.errors = e = trajectory_errors(t_est, est, t_ref, ref_poses, max_dt=max_dt, rpe_delta=rpe_delta)
        except ValueError as ex:
            raise InputError(estimate, str(ex)) from None
        if plot is not None:
            from pfslam.views.figures import plot_errors

            paired = pose_errors(t_est, est, t_ref, ref_poses, max_dt)
            out.pictures = plot_errors(paired, plot, name=str(estimate), reference=str(reference))
        if e.rpe_delta < rpe_delta:
            out.warnings.append(
                f"--rpe-delta {rpe_delta} is more than the {e.matched - 1} steps between the {e.matched} matched "
                f"poses: the RPE is over {e.rpe_delta} poses"
            )
    if relations is not None:
        out.relations = r = relation_errors(
            t_est, est, read_relations(relations), time_offset=time_offset, max_dt=max_dt
        )
        if r.matched == 0:
            raise InputError(
                relations,
                f"no relation has its two ends on two estimated poses within {max_dt:g} s "
                f"(check --time-offset; {r.skipped} skipped: {relations_why(r, max_dt)})",
            )
    return out


def relations_why(r: RelationErrors, max_dt: float) -> str:
    """Why relations were skipped, for messages."""
    return (
        f"{r.unmatched} with an end not within {max_dt:g} s of an estimated pose, "
        f"{r.same_pose} with both ends on the same pose"
    )
