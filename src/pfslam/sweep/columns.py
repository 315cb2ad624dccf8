"""The columns of a sweep's table: a run's status and metrics (which of them a ``slam`` or a
``localize`` run has), those summarised per setting combination and plotted, and their labels
(see :mod:`pfslam.sweep`); their labels, units and digits are
:mod:`pfslam.eval.table`'s. Names only: nothing here reads or runs anything."""

from __future__ import annotations

STATUSES = ("ok", "error", "killed", "timeout")
# Of a SLAM run with the back end (run.json's backend, and metrics.loop_edges with a truth):
# whether its answer was kept (1) or the filter's (0), the loops in its last graph, how many of
# those and of all it found are off the truth (and of those in the graph, off by more than their
# own covariance says: loops_off_sure), the loops the gate (against the front end's path)
# and the score surface (look-alikes all round) refused, and its seconds (beside the run's
# ``seconds``).
BACKEND_METRICS = (
    "backend_kept",
    "loops_solved",
    "loops_off",
    "loops_found_off",
    "loops_off_sure",
    "refused_gate",
    "refused_spread",
    "backend_s",
)
METRICS = (
    "ate_raw",
    "ate_aligned",
    "heading_rmse_deg",
    "rpe_trans",
    "relations_trans",
    "relations_rot_deg",
    "relations_count",
    "map_agreement",
    "odometry_map_agreement",
    *BACKEND_METRICS,
    "scans",
    "scans_per_s",
    "real_time_factor",
    "peak_rss_mb",
    "seconds",
)
# Of a localization run only: seconds after the first motion from which the estimate stays
# within 0.3 m of the ground truth (run.json's metrics.estimate; empty if it ends further off
# or has no ground truth); and from its filter section, seconds until the cloud settled
# (empty if it never did), random-particle injections, the likelihood field's fitted width (m);
# and from its health (run.json's metrics.health), the seconds it said lost and degraded, and
# its lowest quality.
LOCALIZE_METRICS = ("within_after_s", "settle_s", "recoveries", "sigma_hit", "lost_s", "degraded_s", "quality_min")
COUNT_METRICS = (
    "scans",
    "relations_count",
    "recoveries",
    *(m for m in BACKEND_METRICS if m != "backend_s"),
)  # integers (empty where unknown)
HEAD_COLUMNS = ("log", "seed")
STATUS_COLUMNS = ("status", "exit_code", "message")
TAIL_COLUMNS = ("run_dir",)
# Summarised per log × setting combination (median and min-max over the ok runs), and plotted.
SUMMARY_METRICS = (
    "ate_aligned",
    "ate_raw",
    "relations_trans",
    "relations_rot_deg",
    "map_agreement",
    "scans_per_s",
    "peak_rss_mb",
)


def metric_columns(run: str = "slam") -> tuple[str, ...]:
    """The metric columns of a sweep's table: :data:`METRICS`, and for ``localize`` runs
    :data:`LOCALIZE_METRICS` before ``scans`` instead of :data:`BACKEND_METRICS`."""
    if run != "localize":
        return METRICS
    slam = tuple(m for m in METRICS if m not in BACKEND_METRICS)
    i = slam.index("scans")
    return (*slam[:i], *LOCALIZE_METRICS, *slam[i:])


def summary_metrics(run: str = "slam") -> tuple[str, ...]:
    """The metrics summarised and plotted: :data:`SUMMARY_METRICS`, and the time to be
    within :data:`~pfslam.eval.table.WITHIN_M` of the robot, the settle time and the seconds
    lost of ``localize`` runs after the ATEs."""
    if run != "localize":
        return SUMMARY_METRICS
    i = SUMMARY_METRICS.index("ate_raw") + 1
    return (*SUMMARY_METRICS[:i], "within_after_s", "settle_s", "lost_s", *SUMMARY_METRICS[i:])
