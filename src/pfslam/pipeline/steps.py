"""The steps a command is made of: its settings, the log loaded and corrected, the run watched
(progress, views), scored, and its results written."""

from __future__ import annotations

import contextlib
import gc
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterator, Sequence, Unpack

import numpy as np

from pfslam.config import (
    CalibrationConfig,
    SlamConfig,
    load_config,
    resolve_filter,
    with_values,
)
from pfslam.errors import ConfigError, InputError, PfslamError
from pfslam.frames import Frame, frame_times
from pfslam.io.logs import BagOptions
from pfslam.pipeline.outputs import write_outputs
from pfslam.pipeline.prepare import (
    correct_odometry,
    reference_truth,
    require_returns,
    wheel_encoder_log,
)
from pfslam.pipeline.report import Bars, Outcome, Quiet, Reporter, T
from pfslam.pipeline.run import Observer, Progress, Run, Truth
from pfslam.pipeline.score import Scores, score_loops, score_map_agreement, score_trajectories
from pfslam.process import interrupts_held

if TYPE_CHECKING:
    from pfslam.io.common import LoadedLog
    from pfslam.views.live import LiveView, ViewRequest

# -- settings ------------------------------------------------------------------------------


def settings(cls: type[T], path: str | Path | None = None, values: dict[str, Any] | None = None) -> T:
    """``cls``'s settings: the defaults, then the file's (its section of a sectioned file),
    then ``values`` (dotted keys; None = not given); validated once, errors naming the file
    or the key."""
    base = load_config(path, cls) if path is not None else cls()
    given = {k: v for k, v in (values or {}).items() if v is not None}
    return with_values(base, given) if given else base


def calibration_settings(path: str | Path | None) -> CalibrationConfig:
    """The ``calibrate:`` section of a sectioned config file, else the defaults."""
    return load_config(path, CalibrationConfig, section_only=True) if path is not None else CalibrationConfig()


def concrete_config(config: SlamConfig, log_format: str, config_file: str | Path | None) -> SlamConfig:
    """``config`` made concrete for the log kind; a setting the filter that runs does not read
    is refused, naming the config file when there is one."""
    try:
        return resolve_filter(config, log_format)
    except ConfigError as e:
        if config_file is not None:
            raise InputError(config_file, str(e)) from None
        raise


# -- the steps -----------------------------------------------------------------------------


@dataclass(frozen=True)
class LogInput:
    """A log as the commands read it (``pfslam slam``, ``localize``, ``calibrate``): the file,
    its joint file (THOR), the odometry to use (``log``, or ``synthetic:SEED`` on a corrected
    log), a scale of the wheels' travel, what to do with a THOR log without its joint file
    (``level_head``: see :func:`~pfslam.io.logs.check_joint`), the scans' latency behind the
    odometry (s), the ROS bag options, and at most how many scans to read."""

    log: str | Path
    joint: str | Path | None = None
    odometry: str = "log"
    wheel_scale: float = 1.0
    level_head: bool | None = None
    scan_latency: float = 0.0
    bag: BagOptions = field(default_factory=lambda: BagOptions())
    max_scans: int | None = None  # read at most this many scans (None: all)

    @classmethod
    def of(
        cls,
        log: str | Path,
        joint: str | Path | None = None,
        *,
        odometry: str = "log",
        wheel_scale: float = 1.0,
        level_head: bool | None = None,
        scan_latency: float = 0.0,
        max_scans: int | None = None,
        **bag: Unpack[BagOptions],
    ) -> LogInput:
        """The input from the commands' arguments (paths as given)."""
        return cls(log, joint, odometry, wheel_scale, level_head, scan_latency, BagOptions(**bag), max_scans)


def load(source: LogInput, reporter: Reporter | None = None) -> LoadedLog:
    """Load a log, report its notes and warnings, and require a valid return."""
    from pfslam.io.logs import load_log

    rep = reporter if reporter is not None else Quiet()
    log_data = load_log(
        source.log,
        source.joint,
        odometry=source.odometry,
        wheel_scale=source.wheel_scale,
        level_head=source.level_head,
        max_scans=source.max_scans,
        **source.bag,
    )
    for n in log_data.notes:
        rep.note(n)
    for w in log_data.warnings:
        rep.warn(w)
    require_returns(source.log, log_data.frames)
    return log_data


def correct(
    source: LogInput,
    frames: Sequence[Frame],
    reporter: Reporter,
    *,
    calibrate: bool | None,
    axle: float = 0.33,
    config: CalibrationConfig | None = None,
) -> tuple[Sequence[Frame], dict[str, Any]]:
    """The odometry's corrections: the source's ``scan_latency``, then the calibration from
    the scans.

    ``calibrate`` None means per log kind: a wheel-encoder log is calibrated (its encoder
    constants are rarely right: on Mines ``exp2.dat`` the scans show twice the documented
    travel) unless a correction was given by hand (``wheel_scale``, ``scan_latency``). A
    calibration the scans cannot make, or one that is not plausible (a scale outside 0.2-5,
    or no better fit to the scans' motion), is a warning and the odometry is used as read.
    Returns the frames and what was applied (for run.json)."""
    cfg = config if config is not None else CalibrationConfig()
    log, scan_latency = source.log, source.scan_latency
    if calibrate is None:
        if not wheel_encoder_log(frames) or source.wheel_scale != 1.0 or scan_latency:
            return correct(source, frames, reporter, calibrate=False, axle=axle)
        reporter.say("wheel-encoder log: calibrating the odometry from the scans (--no-calibrate to skip)")
        try:
            with reporter.progress([("calibrate", 1, "scans")]) as (cb,):
                fixed, info, cal = correct_odometry(log, frames, scan_latency, True, axle, cb, cfg)
        except InputError as e:
            reporter.warn(f"{e}; the odometry is used as read (uncalibrated)")
            return correct(source, frames, reporter, calibrate=False, axle=axle)
        assert cal is not None  # (asked to calibrate, it measured or raised)
        if not cal.plausible():
            reporter.warn(
                f"{log}: the scans' calibration is not plausible (translation x{cal.trans_scale:.3f}, "
                f"rotation x{cal.rot_scale:.3f}, heading residual {cal.rot_residual_deg_uncalibrated:.2f}"
                f" -> {cal.rot_residual_deg:.2f} deg); the odometry is used as read (uncalibrated)"
            )
            return correct(source, frames, reporter, calibrate=False, axle=axle)
        reporter.calibration(cal)
        return fixed, info
    with reporter.progress([("calibrate", 1, "scans")]) if calibrate else contextlib.nullcontext([None]) as (cb,):
        frames, info, cal = correct_odometry(log, frames, scan_latency, calibrate, axle, cb, cfg)
    if cal is not None:
        reporter.calibration(cal)
    return frames, info


class Watch:
    """What a filter run is given while it is watched (:func:`watched`): its progress bar and
    the observer that draws it into the views (None: no views)."""

    def __init__(self, progress: Progress, views: ViewRequest | None, live: LiveView | None) -> None:
        self.progress = progress
        self.views, self.live = views, live
        self.observer: Observer | None = live
        self.run: Run | None = None

    def finish(self, run: Run) -> Run:
        """Finish the views of ``run`` (the video written, the recording flushed) before its
        results are written; a view that cannot be finished is the run's error. Returns ``run``."""
        self.run = run
        if self.live is None or self.views is None:
            return run
        with interrupts_held() as got:
            try:
                self.live.close()
            except Exception as e:  # a full disk, an encoder's error: reported with the results
                run.error = run.error or f"finishing {self.views.video or self.views.rerun_save}: {e}"
        run.interrupted = run.interrupted or bool(got)
        return run


@contextlib.contextmanager
def watched(
    reporter: Reporter,
    label: str,
    steps: Sequence[Frame],
    views: ViewRequest | None,
    truth: Truth | None,
    ground_z: float,
    kind: str,
    title: str,
    truth_label: str = "ground truth",
) -> Iterator[Watch]:
    """A filter run over ``steps`` watched: a progress bar, and with views asked for (a
    :class:`~pfslam.views.live.ViewRequest`) the views it is drawn into (a second bar counts
    the video's frames), which the body finishes with :meth:`Watch.finish`; what the views
    say is reported after the bars. The objects made before the run (modules, compiled
    kernels, the log's index: about 200,000) leave the collector's care while it runs (a full
    collection would walk them all and stall one scan by about 90 ms) and return to it after."""
    gc.freeze()
    try:
        video: Bars = [("video", 1, "frames")] if views and views.video is not None else []
        with reporter.progress([(label, len(steps), "scans")] + video) as cbs:
            live = None
            if views:
                live = views.open(
                    frame_times(steps), truth, ground_z, kind, title, truth_label, cbs[1] if video else None
                )
            watch = Watch(cbs[0], views, live)
            yield watch
        if live is not None:
            for v in live.views:
                if v.problem is not None:
                    reporter.warn(v.problem)
                elif watch.run is not None and watch.run.error is None:
                    reporter.say(v.report())
    finally:
        gc.unfreeze()


def warn_notes(reporter: Reporter, run: Run) -> None:
    """Say what the user must hear about ``run`` (its notes), after its steps."""
    for note in run.notes:
        reporter.warn(note)


def score_run(
    run: Run,
    frames: Sequence[Frame],
    truth: Truth | None,
    source: object,
    names: tuple[str, str],
    agreement: bool,
    reporter: Reporter,
) -> Scores:
    """Score the run (trajectory errors against ``truth``; with ``agreement`` the map
    agreement) and report the figures; Ctrl-C skips the rest of the scoring and keeps the
    results, and a figure that cannot be computed is a warning."""
    scores = Scores()
    try:
        scores = score_trajectories(run, truth, names)
        if scores.problem is not None:
            reporter.warn(f"{source}: not scored ({scores.problem})")
        if agreement:
            score_map_agreement(run, frames, scores)
        score_loops(run, truth)
    except KeyboardInterrupt:
        run.interrupted = True
    except PfslamError as e:
        reporter.warn(f"{source}: not fully scored ({e})")
    reporter.scores(scores)
    return scores


def write_results(
    run: Run,
    scores: Scores,
    out: Path,
    log: object,
    info: dict[str, Any],
    truth: Truth | None,
    truth_label: str,
    calibration: CalibrationConfig | None = None,
) -> Outcome:
    """Write the results (also of a run stopped early); a run that did nothing raises instead
    (its error, or KeyboardInterrupt)."""
    if run.scans == 0 and run.error is not None:
        raise PfslamError(f"{log}: {run.error}")
    if run.scans == 0 and run.interrupted:
        raise KeyboardInterrupt
    with interrupts_held() as got:
        write_outputs(run, out, info, truth, truth_label, calibration)
    run.interrupted = run.interrupted or bool(got)
    return Outcome(run, scores, Path(out), log, got)


class PhaseClock:
    """The seconds of a command's phases for ``run.json`` (``seconds_by_phase``): the process
    before the command (start-up and imports, from the shell), loading, the filter loop as the
    run measured it, the views and the rest of the filter's step, the back end, the session
    left, and scoring; writing is added as the results are written."""

    def __init__(self) -> None:
        from pfslam.process import process_seconds

        self.phases: dict[str, float | None] = {"before_command": process_seconds()}
        self._last = time.perf_counter()

    def _lap(self) -> float:
        now = time.perf_counter()
        took, self._last = now - self._last, now
        return took

    def loaded(self) -> None:
        self.phases["load"] = self._lap()

    def ran(self, run: Run) -> None:
        """The filter's step is over (its loop's own seconds are ``run.seconds``)."""
        took = self._lap()
        self.phases.update(filter=run.seconds, backend=0.0, filter_views_and_other=took - run.seconds)

    def closed(self) -> None:
        """The back end's step is over."""
        self.phases["backend"] = self._lap()

    def left(self) -> None:
        """The session is made."""
        self.phases["session"] = self._lap()

    def scored(self, run: Run) -> None:
        self.phases["score"] = self._lap()
        run.phases = self.phases


def slam_truth(ground_truth: str | Path | None, log_data: LoadedLog) -> tuple[Truth | None, Truth | None, str]:
    """What a SLAM run is scored against: the ground truth file, read, if given (else None),
    the log's own reference poses (corrected CARMEN logs), and the label for them."""
    from pfslam.io.trajectory import read_tum

    truth = read_tum(ground_truth) if ground_truth is not None else None
    return truth, reference_truth(log_data), "ground truth" if ground_truth is not None else "reference"


def input_info(source: LogInput, log_data: LoadedLog, extra: dict[str, Any]) -> dict[str, Any]:
    """``run.json``'s ``input``: the log, its joint file, its kind and odometry, the wheel scale,
    the records skipped, the frames its poses are in, and ``extra`` (the corrections made)."""
    return {
        "log": str(source.log),
        "joint": str(source.joint) if source.joint else None,
        "format": log_data.format,
        "odometry": log_data.odometry,
        "wheel_scale": source.wheel_scale,
        **({"skipped_records": log_data.skipped} if log_data.skipped else {}),
        "frames": frames_info(log_data),
        **extra,
    }


def frames_info(log_data: LoadedLog) -> dict[str, Any]:
    """Which frame each trajectory of a run is in (``run.json``'s ``input.frames``): the
    trajectory, the odometry and the map's start are the robot base's (on the floor, x
    forward), the frame the log's odometry gives; the laser sits in it at the first scan's
    mount (x, y m, heading deg; a THOR head moves it scan by scan). A corrected CARMEN log's own
    poses (its reference) are the laser's, which the log itself places at the base (mount 0:
    both of its poses are equal), so all are the same frame there."""
    m = log_data.frames[0].mount if len(log_data.frames) else np.eye(4)
    yaw = float(np.degrees(np.arctan2(m[1, 0], m[0, 0])))
    return {
        "trajectory": "robot base",
        "laser_in_base": [round(float(m[0, 3]), 4), round(float(m[1, 3]), 4), round(yaw, 3)],
        **({"reference": "the log's own poses, in the robot base"} if log_data.reference is not None else {}),
    }
