"""What a run is: load, correct, run, score, write. ``pfslam slam``, ``localize`` and ``demo``
call :func:`slam`, :func:`localize` and :func:`demo`, and so does a script: the same call on
the same log and settings writes the same files::

    from pfslam.pipeline import slam
    outcome = slam("intel.gfs.log.gz", "out", odometry="synthetic:0")
    outcome.run.poses, outcome.scores.errors, outcome.out

Nothing here prints or exits: what a person should be told goes to a :class:`Reporter` (the
command line's prints it; the default, :class:`Quiet`, keeps the warnings in a list), and how
a run ended is in the returned :class:`Outcome` (``run.error``, ``run.interrupted``).

Modules: :mod:`~pfslam.pipeline.commands` (slam, demo, localize: each a table of its steps),
:mod:`~pfslam.pipeline.steps` (settings, load, correct, run_watched, score_run,
write_results), :mod:`~pfslam.pipeline.report` (:class:`Reporter`, :class:`Quiet`,
:class:`Outcome`), :mod:`~pfslam.pipeline.prepare` (output folder, checks, odometry
corrections), :mod:`~pfslam.pipeline.run` (the step loop, :class:`Run`, the back end's step),
:mod:`~pfslam.pipeline.score` (trajectory errors, map agreement, loop edges),
:mod:`~pfslam.pipeline.outputs` (the files), :mod:`~pfslam.pipeline.evaluation` (``pfslam
evaluate``). May import every other package except the command line.
"""

from __future__ import annotations

from pfslam.io.folders import prepare_output_dir
from pfslam.pipeline.commands import DEMO_RATE_HZ, demo, localize, map_start_pose, slam
from pfslam.pipeline.evaluation import Evaluation, evaluate
from pfslam.pipeline.outputs import write_json, write_outputs
from pfslam.pipeline.prepare import (
    MAP_FILE,
    MapStart,
    any_valid_return,
    correct_odometry,
    map_run_start,
    reference_truth,
    require_returns,
    wheel_encoder_log,
)
from pfslam.pipeline.report import Outcome, Quiet, Reporter
from pfslam.pipeline.run import (
    JUMP_BREAK,
    Array,
    Observer,
    Progress,
    Run,
    Truth,
    build_map,
    make_slam,
    run_filter,
    run_localization,
    run_slam,
    stop_reason,
    uncertainty_summary,
)
from pfslam.pipeline.score import Scores, score_loops, score_map_agreement, score_trajectories
from pfslam.pipeline.steps import calibration_settings, correct, load, run_watched, score_run, settings, write_results
from pfslam.process import interrupts_held

__all__ = [
    "Evaluation",
    "evaluate",
    "DEMO_RATE_HZ",
    "calibration_settings",
    "map_start_pose",
    "run_watched",
    "score_run",
    "write_results",
    "JUMP_BREAK",
    "MAP_FILE",
    "Array",
    "MapStart",
    "Observer",
    "Outcome",
    "Progress",
    "Quiet",
    "Reporter",
    "Run",
    "Scores",
    "Truth",
    "interrupts_held",
    "any_valid_return",
    "build_map",
    "correct",
    "correct_odometry",
    "demo",
    "load",
    "localize",
    "make_slam",
    "map_run_start",
    "prepare_output_dir",
    "reference_truth",
    "require_returns",
    "run_filter",
    "run_localization",
    "run_slam",
    "settings",
    "slam",
    "stop_reason",
    "uncertainty_summary",
    "wheel_encoder_log",
    "write_json",
    "write_outputs",
    "score_loops",
    "score_map_agreement",
    "score_trajectories",
]
