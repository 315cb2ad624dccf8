"""What a run is: load, correct, run, score, write. ``pfslam slam``, ``localize`` and ``demo``
call :func:`slam`, :func:`localize` and :func:`demo`, and so does a script: the same call on
the same log and settings writes the same files::

    from pfslam.pipeline import slam
    outcome = slam("intel.gfs.log.gz", "out", odometry="synthetic:0")
    outcome.run.poses, outcome.scores.errors, outcome.out

Nothing here prints or exits: what a person should be told goes to a :class:`Reporter` (the
command line's prints it; the default, :class:`Quiet`, keeps the warnings in a list), and how
a run ended is in the returned :class:`Outcome` (``run.error``, ``run.interrupted``).

Modules: :mod:`~pfslam.pipeline.prepare` (output folder, checks, odometry corrections),
:mod:`~pfslam.pipeline.run` (the step loop, :class:`Run`), :mod:`~pfslam.pipeline.score`
(trajectory errors, map agreement), :mod:`~pfslam.pipeline.outputs` (the files). May import
every other package except the command line.
"""

from __future__ import annotations

import contextlib
import gc
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, ContextManager, Iterator, Protocol, Sequence, TypeVar, cast

import numpy as np

from pfslam.config import (
    Backend,
    CalibrationConfig,
    LocalizerConfig,
    SlamConfig,
    load_config,
    resolve_filter,
    with_values,
)
from pfslam.errors import ConfigError, InputError, PfslamError
from pfslam.frames import Frame, frame_times
from pfslam.io.common import prepare_output_dir
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
from pfslam.process import interrupts_held

__all__ = [
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

T = TypeVar("T")
Bars = list[tuple[str, int, str]]  # (label, total, unit counted) per progress bar


class Reporter(Protocol):
    """Where a run tells a person what happens: warnings, lines to show (``say``: results;
    ``note``: what is being done), the calibration it measured, its figures, and progress bars (one per (label, total, unit), each moved by
    the (done, total) callback the context gives)."""

    def warn(self, text: str) -> None: ...

    def say(self, text: str) -> None: ...

    def note(self, text: str) -> None: ...

    def calibration(self, cal: Any) -> None: ...

    def scores(self, scores: Scores) -> None: ...

    def progress(self, bars: Bars) -> ContextManager[list[Progress]]: ...


class Quiet:
    """A :class:`Reporter` for scripts and tests: keeps the warnings and lines, shows nothing."""

    def __init__(self) -> None:
        self.warnings: list[str] = []
        self.lines: list[str] = []

    def warn(self, text: str) -> None:
        self.warnings.append(text)

    def say(self, text: str) -> None:
        self.lines.append(text)

    def note(self, text: str) -> None:
        self.lines.append(text)

    def calibration(self, cal: Any) -> None:
        pass

    def scores(self, scores: Scores) -> None:
        pass

    @contextlib.contextmanager
    def progress(self, bars: Bars) -> Iterator[list[Progress]]:
        yield [lambda done, total: None for _ in bars]


@dataclass
class Outcome:
    """How a run ended: the :class:`Run` (``error``/``interrupted`` say if it stopped early),
    its figures, where its results are, and the stop signals received while they were written."""

    run: Run
    scores: Scores
    out: Path
    log: object = None  # the log it ran on (for messages)
    signals: list[int] = field(default_factory=list)

    def summary(self) -> str:
        """One line on what was done, for a run that ended normally."""
        run = self.run
        speed = f"{run.scans} scans in {run.seconds:.1f} s ({run.scans_per_second:.0f} scans/s, "
        if run.kind == "slam":
            loops = ""
            if run.backend is not None and run.backend.closure is not None:
                b = run.backend.closure.stats
                loops = (
                    f"; loop closing: {b.loops_in_graph} loops over {b.nodes} nodes ({b.refused} refused: "
                    f"{b.refused_ambiguous} ambiguous, {b.refused_unchained} unchained, {b.loops_dropped} "
                    f"disagreeing{f', {b.refused_far} far' if b.refused_far else ''})"
                    f"{'' if run.backend.kept else ', not kept'}, {run.backend_seconds:.1f} s"
                )
            return f"{speed}{run.real_time_factor:.1f}x real time){loops}; results in {self.out}/"
        counts = f"particles {run.particles[0]} -> {run.particles[-1]}" if run.scans else ""
        return f"{speed}{run.updates} updates, {counts}); results in {self.out}/"


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


def _resolved(config: SlamConfig, log_format: str, config_file: str | Path | None) -> SlamConfig:
    """``config`` made concrete for the log kind; a setting the filter that runs does not read
    is refused, naming the config file when there is one."""
    try:
        return resolve_filter(config, log_format)
    except ConfigError as e:
        if config_file is not None:
            raise InputError(config_file, str(e)) from None
        raise


# -- the steps -----------------------------------------------------------------------------


def load(
    log: str | Path,
    joint: str | Path | None = None,
    reporter: Reporter | None = None,
    *,
    odometry: str = "log",
    wheel_scale: float = 1.0,
    level_head: bool | None = None,
    **bag: str | None,
) -> Any:
    """Load a log (``bag``: the ROS bag options; ``level_head``: a THOR log without its joint
    file: see :func:`~pfslam.io.logs.check_joint`), report its notes and warnings, and require
    a valid return."""
    from pfslam.io.logs import load_log

    rep = reporter if reporter is not None else Quiet()
    log_data = load_log(
        log, joint, odometry=odometry, wheel_scale=wheel_scale, level_head=level_head, **cast("dict[str, Any]", bag)
    )
    for n in log_data.notes:
        rep.note(n)
    for w in log_data.warnings:
        rep.warn(w)
    require_returns(log, log_data.frames)
    return log_data


def correct(
    log: object,
    frames: Sequence[Frame],
    reporter: Reporter,
    *,
    calibrate: bool | None,
    scan_latency: float = 0.0,
    wheel_scale: float = 1.0,
    axle: float = 0.33,
    config: CalibrationConfig | None = None,
) -> tuple[Sequence[Frame], dict[str, Any]]:
    """The odometry's corrections: ``scan_latency``, then the calibration from the scans.

    ``calibrate`` None means per log kind: a wheel-encoder log is calibrated (its encoder
    constants are rarely right: on Mines ``exp2.dat`` the scans show twice the documented
    travel) unless a correction was given by hand (``wheel_scale``, ``scan_latency``). A
    calibration the scans cannot make, or one that is not plausible (a scale outside 0.2-5,
    or no better fit to the scans' motion), is a warning and the odometry is used as read.
    Returns the frames and what was applied (for run.json)."""
    cfg = config if config is not None else CalibrationConfig()
    if calibrate is None:
        if not wheel_encoder_log(frames) or wheel_scale != 1.0 or scan_latency:
            return correct(log, frames, reporter, calibrate=False, scan_latency=scan_latency, axle=axle)
        reporter.say("wheel-encoder log: calibrating the odometry from the scans (--no-calibrate to skip)")
        try:
            with reporter.progress([("calibrate", 1, "scans")]) as (cb,):
                fixed, info, cal = correct_odometry(log, frames, scan_latency, True, axle, cb, cfg)
        except InputError as e:
            reporter.warn(f"{e}; the odometry is used as read (uncalibrated)")
            return correct(log, frames, reporter, calibrate=False, scan_latency=scan_latency, axle=axle)
        if not cal.plausible():
            reporter.warn(
                f"{log}: the scans' calibration is not plausible (translation x{cal.trans_scale:.3f}, "
                f"rotation x{cal.rot_scale:.3f}, heading residual {cal.rot_residual_deg_uncalibrated:.2f}"
                f" -> {cal.rot_residual_deg:.2f} deg); the odometry is used as read (uncalibrated)"
            )
            return correct(log, frames, reporter, calibrate=False, scan_latency=scan_latency, axle=axle)
        reporter.calibration(cal)
        return fixed, info
    with reporter.progress([("calibrate", 1, "scans")]) if calibrate else contextlib.nullcontext([None]) as (cb,):
        frames, info, cal = correct_odometry(log, frames, scan_latency, calibrate, axle, cb, cfg)
    if cal is not None:
        reporter.calibration(cal)
    return frames, info


def run_watched(
    reporter: Reporter,
    label: str,
    steps: Sequence[Frame],
    fn: Callable[[Progress, Any, Progress | None], Run],
    views: Any,
    truth: Truth | None,
    ground_z: float,
    kind: str,
    title: str,
    truth_label: str = "ground truth",
    closing: bool = False,
) -> Run:
    """``fn(progress, observer, closing)`` runs the filter over ``steps`` (``closing``: the
    progress of the loop-closing back end, a second bar, if ``closing``); with views asked for (a
    :class:`~pfslam.views.live.ViewRequest`), the observer draws the run into them (a second
    bar counts the video's frames), and they are finished (the video written, the recording
    flushed) before the results are. A view that cannot be finished is the run's error."""
    # The objects made so far (modules, compiled kernels, the log's index: about 200,000)
    # leave the collector's care: a full collection during the run would walk them all and
    # stall one scan by about 90 ms.
    gc.freeze()
    extra: Bars = [("loop closing", 1, "submaps")] if closing else []
    if not views:
        with reporter.progress([(label, len(steps), "scans")] + extra) as cbs:
            run = fn(cbs[0], None, cbs[1] if closing else None)
        for note in run.notes:
            reporter.warn(note)
        return run
    video: Bars = [("video", 1, "frames")] if views.video is not None else []
    with reporter.progress([(label, len(steps), "scans")] + video + extra) as cbs:
        live = views.open(frame_times(steps), truth, ground_z, kind, title, truth_label, cbs[1] if video else None)
        run = fn(cbs[0], live, cbs[-1] if closing else None)
        with interrupts_held() as got:
            try:
                live.close()
            except Exception as e:  # a full disk, an encoder's error: reported with the results
                run.error = run.error or f"finishing {views.video or views.rerun_save}: {e}"
        run.interrupted = run.interrupted or bool(got)
    for v in live.views:
        if v.problem is not None:
            reporter.warn(v.problem)
        elif run.error is None:
            reporter.say(v.report())
    for note in run.notes:
        reporter.warn(note)
    return run


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


# -- the commands --------------------------------------------------------------------------


def slam(
    log: str | Path,
    out: str | Path = "out",
    *,
    joint: str | Path | None = None,
    config: SlamConfig | None = None,
    config_file: str | Path | None = None,
    odometry: str = "log",
    wheel_scale: float = 1.0,
    level_head: bool | None = None,
    calibrate: bool | None = None,
    scan_latency: float = 0.0,
    ground_truth: str | Path | None = None,
    views: Any = None,
    reporter: Reporter | None = None,
    **bag: str | None,
) -> Outcome:
    """``pfslam slam``: build a map and a trajectory from a log and write them into ``out``.

    ``config``: the settings (default: ``config_file``'s ``slam`` section, else the
    defaults), made concrete for the log kind (:func:`~pfslam.config.resolve_filter`);
    ``calibrate`` None calibrates wheel-encoder logs (see :func:`correct`); ``views`` a
    :class:`~pfslam.views.live.ViewRequest`; ``bag`` the ROS bag options (scan_topic,
    odom_topic, base_frame, odom_frame); ``level_head``: a THOR log without its joint file
    (:func:`~pfslam.io.logs.check_joint`: None warns, False refuses, True runs it level)."""
    from pfslam.io.trajectory import read_tum, write_tum
    from pfslam.process import process_seconds

    started = process_seconds()
    began = time.perf_counter()
    rep = reporter if reporter is not None else Quiet()
    cfg = config if config is not None else settings(SlamConfig, config_file)
    cal_cfg = calibration_settings(config_file) if calibrate is not False else None
    out = Path(out)
    prepare_output_dir(out)
    log_data = load(log, joint, rep, odometry=odometry, wheel_scale=wheel_scale, level_head=level_head, **bag)
    cfg = _resolved(cfg, log_data.format, config_file)
    truth = read_tum(ground_truth) if ground_truth is not None else None
    frames, cal_info = correct(
        log,
        log_data.frames,
        rep,
        calibrate=calibrate,
        scan_latency=scan_latency,
        wheel_scale=wheel_scale,
        axle=cfg.motion.axle,
        config=cal_cfg,
    )
    label = "ground truth" if ground_truth is not None else "reference"
    reference = reference_truth(log_data)
    loaded = time.perf_counter()
    run = run_watched(
        rep,
        "SLAM",
        frames[:: cfg.every],
        lambda cb, obs, closing: run_slam(frames, cfg, cb, obs, closing=closing),
        views,
        truth if truth is not None else reference,
        cfg.sensor.ground_z,
        "slam",
        "pfslam slam",
        label,
        closing=cfg.backend == Backend.GRAPH,
    )
    ran = time.perf_counter()
    if truth is None and reference is not None:
        truth = reference
        write_tum(out / "reference.tum", *truth)
    scores = score_run(run, frames, truth, ground_truth or "reference", ("SLAM", "odometry"), True, rep)
    run.phases = {
        "before_command": started,  # the process before it (start-up and imports, from the shell)
        "load": loaded - began,
        "filter": run.seconds,
        "backend": run.backend_seconds,
        "filter_views_and_other": ran - loaded - run.seconds - run.backend_seconds,
        "score": time.perf_counter() - ran,
    }
    info = {
        "log": str(log),
        "joint": str(joint) if joint else None,
        "format": log_data.format,
        "odometry": log_data.odometry,
        "wheel_scale": wheel_scale,
        **({"skipped_records": log_data.skipped} if log_data.skipped else {}),
        **cal_info,
    }
    return write_results(run, scores, out, log, info, truth, label, cal_cfg if "calibration" in cal_info else None)


DEMO_RATE_HZ = 40.0  # the simulated THOR lidar's scans per second


def demo(
    out: str | Path = "demo_out",
    *,
    duration: float = 180.0,
    seed: int = 0,
    config: SlamConfig | None = None,
    views: Any = None,
    reporter: Reporter | None = None,
) -> Outcome:
    """``pfslam demo``: simulate a THOR office loop into ``out/log``, run SLAM on it (the
    filter ``pfslam slam`` picks), score SLAM and the odometry against the ground truth."""
    from pfslam.config import check_number
    from pfslam.io.logs import MAX_SCANS_ENV, scan_limit
    from pfslam.tools.simulate import MAX_DURATION
    from pfslam.tools.simulate import simulate as sim

    rep = reporter if reporter is not None else Quiet()
    check_number("--duration", duration, gt=0.0, le=MAX_DURATION, what="a finite number of seconds")
    cfg = config if config is not None else SlamConfig(seed=seed)
    out = Path(out)
    prepare_output_dir(out)
    limit = scan_limit()
    if limit is not None and duration > limit / DEMO_RATE_HZ:  # the rest would not be read
        duration = limit / DEMO_RATE_HZ
        rep.warn(f"{MAX_SCANS_ENV}={limit} is set: the demo simulates {duration:g} s ({limit} scans)")
    rep.note(f"simulating {duration:g} s of a THOR humanoid walking an office loop ...")
    res = sim(world="office", duration_s=duration, seed=seed, out_dir=out / "log")
    from pfslam.io.trajectory import read_tum

    log_data = load(res.lidar_path, res.joint_path, rep)
    cfg = resolve_filter(cfg, log_data.format)
    frames = log_data.frames
    truth = read_tum(res.groundtruth_path)
    run = run_watched(
        rep,
        "SLAM",
        frames[:: cfg.every],
        lambda cb, obs, closing: run_slam(frames, cfg, cb, obs, closing=closing),
        views,
        truth,
        cfg.sensor.ground_z,
        "slam",
        "pfslam demo",
        closing=cfg.backend == Backend.GRAPH,
    )
    scores = score_run(run, frames, truth, res.groundtruth_path, ("SLAM", "odometry"), False, rep)
    info = {"log": str(res.lidar_path), "joint": str(res.joint_path), "format": log_data.format}
    return write_results(run, scores, out, res.lidar_path, info, truth, "ground truth")


def map_start_pose(map_yaml: str | Path, reporter: Reporter) -> tuple[list[float], str]:
    """The start pose X,Y,THETA_DEG when none is given, and what it is (for messages): where
    the map's SLAM run started (said in one line), else 0,0,0 of the map frame."""
    start = map_run_start(map_yaml)
    if start is None:
        return [0.0, 0.0, 0.0], "the default initial pose 0,0,0 (give --initial-pose or --global)"
    x, y, th = start.pose
    pose = [float(x) + 0.0, float(y) + 0.0, float(np.rad2deg(th)) + 0.0]  # + 0.0: no "-0.00" printed
    where = f"{pose[0]:.3f},{pose[1]:.3f},{pose[2]:.2f}"
    reporter.note(
        f"initial pose {where} (X,Y,THETA_DEG): where the map's run started, the first pose of "
        f"{start.trajectory}; give --initial-pose if this log starts elsewhere"
    )
    return pose, f"the initial pose {where}, where the map's run started ({start.trajectory})"


def localize(
    log: str | Path,
    map_yaml: str | Path,
    out: str | Path = "out_localize",
    *,
    joint: str | Path | None = None,
    config: LocalizerConfig | None = None,
    config_file: str | Path | None = None,
    initial_pose: Sequence[float] | None = None,
    global_start: bool = False,
    odometry: str = "log",
    wheel_scale: float = 1.0,
    level_head: bool | None = None,
    calibrate: bool = False,
    scan_latency: float = 0.0,
    ground_truth: str | Path | None = None,
    views: Any = None,
    reporter: Reporter | None = None,
    **bag: str | None,
) -> Outcome:
    """``pfslam localize``: track the robot of ``log`` on the map ``map_yaml``.

    ``initial_pose`` (X, Y, THETA_DEG in the map frame): default, where the map's SLAM run
    started (for a map ``pfslam slam`` wrote), else 0,0,0; ``global_start``: particles over
    all free space instead; ``level_head`` as for :func:`slam`."""
    from pfslam.filters.localize import Localizer
    from pfslam.io.logs import check_joint
    from pfslam.io.trajectory import read_tum
    from pfslam.maps.grid import OccupancyGrid

    check_joint(Path(log), joint, level_head)  # the log's pairing, before the map is read

    rep = reporter if reporter is not None else Quiet()
    cfg = config if config is not None else settings(LocalizerConfig, config_file)
    out = Path(out)
    prepare_output_dir(out)
    grid = OccupancyGrid.load_ros(map_yaml)
    if not (grid.thresholded() == 0).any():
        raise InputError(map_yaml, "the map has no free cells")
    cal_cfg = calibration_settings(config_file) if calibrate else None
    initial = None
    if not global_start:
        pose, what = (
            (list(initial_pose), "--initial-pose") if initial_pose is not None else map_start_pose(map_yaml, rep)
        )
        initial = (np.array([pose[0], pose[1], np.deg2rad(pose[2])]), np.array(cfg.initial_std))
        try:
            Localizer(grid, cfg).check_pose(initial[0])
        except InputError as e:
            raise InputError(map_yaml, f"{what}: {e.problem}") from None
    log_data = load(log, joint, rep, odometry=odometry, wheel_scale=wheel_scale, level_head=level_head, **bag)
    truth = read_tum(ground_truth) if ground_truth is not None else None
    label = "ground truth"
    if truth is None and (truth := reference_truth(log_data)) is not None:
        label = "reference"
    frames, cal_info = correct(
        log, log_data.frames, rep, calibrate=calibrate, scan_latency=scan_latency, axle=cfg.axle, config=cal_cfg
    )
    run = run_watched(
        rep,
        "localize",
        frames,
        lambda cb, obs, _: run_localization(frames, grid, cfg, initial, cb, observer=obs),
        views,
        truth,
        cfg.ground_z,
        "localization",
        "pfslam localize",
        label,
    )
    scores = score_run(run, frames, truth, ground_truth or "reference", ("estimate", "odometry"), False, rep)
    info = {
        "log": str(log),
        "map": str(map_yaml),
        "format": log_data.format,
        "odometry": log_data.odometry,
        "global": global_start,
        "wheel_scale": wheel_scale,
        **({"skipped_records": log_data.skipped} if log_data.skipped else {}),
        **cal_info,
    }
    return write_results(run, scores, out, log, info, truth, label, cal_cfg)
