"""What a run is: load, correct, run the filter, close the loops, leave the session, score,
write. ``pfslam slam``, ``localize`` and ``demo`` call :func:`slam`, :func:`localize` and
:func:`demo`, and so does a script: the same call on the same log and settings writes the same
files::

    from pfslam.pipeline import slam
    outcome = slam("intel.gfs.log.gz", "out", odometry="synthetic:0")
    outcome.run.poses, outcome.scores.errors, outcome.out
    outcome.run.phases  # seconds: load, filter, backend, session, score, write

Or the steps one by one, on frames already loaded (``config`` made concrete for the log with
:func:`~pfslam.config.resolve_filter`)::

    run = run_slam(frames, config)   # the filter's run
    run = close_loops(run)           # the back end's step (backend: graph)
    run = leave_session(run)         # the session the run leaves, for --resume

Nothing here prints or exits: what a person should be told goes to a :class:`Reporter` (the
command line's prints it; the default, :class:`Quiet`, keeps the warnings in a list), and how
a run ended is in the returned :class:`Outcome` (``run.error``, ``run.interrupted``).

Modules: :mod:`~pfslam.pipeline.commands` (slam, demo, localize: each a table of its steps),
:mod:`~pfslam.pipeline.steps` (settings, load, correct, the watched run, scoring, writing,
the phases' clock), :mod:`~pfslam.pipeline.report` (:class:`Reporter`, :class:`Quiet`,
:class:`Outcome`), :mod:`~pfslam.pipeline.prepare` (output folder, checks, odometry
corrections), :mod:`~pfslam.pipeline.run` (the step loop, :class:`Run`),
:mod:`~pfslam.pipeline.closing` (the back end's step), :mod:`~pfslam.pipeline.sessions` (sessions:
made, written, read, continued), :mod:`~pfslam.pipeline.score` (trajectory errors, map
agreement, loop edges), :mod:`~pfslam.pipeline.outputs` (the files),
:mod:`~pfslam.pipeline.evaluation` (``pfslam evaluate``). May import every other package
except the command line.
"""

from __future__ import annotations

from pfslam.pipeline.closing import close_loops
from pfslam.pipeline.commands import demo, localize, slam
from pfslam.pipeline.evaluation import Evaluation, evaluate
from pfslam.pipeline.outputs import write_outputs
from pfslam.pipeline.report import Outcome, Quiet, Reporter
from pfslam.pipeline.run import Run, build_map, make_slam, run_filter, run_localization, run_slam
from pfslam.pipeline.score import Scores
from pfslam.pipeline.sessions import StartMode, leave_session
from pfslam.pipeline.steps import LogInput, load, settings

__all__ = [
    "Evaluation",
    "LogInput",
    "Outcome",
    "Quiet",
    "Reporter",
    "Run",
    "Scores",
    "StartMode",
    "build_map",
    "close_loops",
    "demo",
    "evaluate",
    "leave_session",
    "load",
    "localize",
    "make_slam",
    "run_filter",
    "run_localization",
    "run_slam",
    "settings",
    "slam",
    "write_outputs",
]
