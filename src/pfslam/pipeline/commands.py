"""The commands: ``pfslam slam``, ``demo`` and ``localize`` as library calls, each a table of
its steps (:mod:`~pfslam.pipeline.steps`)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Sequence, Unpack

import numpy as np

from pfslam.config import (
    Backend,
    LocalizerConfig,
    SlamConfig,
    resolve_filter,
)
from pfslam.errors import InputError
from pfslam.io.folders import prepare_output_dir
from pfslam.io.logs import BagOptions
from pfslam.pipeline.closing import close_loops
from pfslam.pipeline.prepare import (
    map_file,
    map_run_start,
    reference_truth,
)
from pfslam.pipeline.report import Outcome, Quiet, Reporter
from pfslam.pipeline.run import Run, run_localization, run_slam
from pfslam.pipeline.sessions import continued, leave_session, open_session

if TYPE_CHECKING:
    from pfslam.views.live import ViewRequest
from pfslam.pipeline.steps import (
    LogInput,
    PhaseClock,
    calibration_settings,
    concrete_config,
    correct,
    frames_info,
    input_info,
    load,
    score_run,
    settings,
    slam_truth,
    warn_notes,
    watched,
    write_results,
)
from pfslam.pipeline.warm import Warming
from pfslam.process import hand_back_freed

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
    views: ViewRequest | None = None,
    reporter: Reporter | None = None,
    resume: str | Path | None = None,
    start: Sequence[float] | None = None,
    max_scans: int | None = None,
    **bag: Unpack[BagOptions],
) -> Outcome:
    """``pfslam slam``: build a map and a trajectory from a log and write them into ``out``.

    ``config``: the settings (default: ``config_file``'s ``slam`` section, else the
    defaults), made concrete for the log kind (:func:`~pfslam.config.resolve_filter`);
    ``calibrate`` None calibrates wheel-encoder logs (see :func:`correct`); ``views`` a
    :class:`~pfslam.views.live.ViewRequest`; ``bag`` the ROS bag options (scan_topic,
    odom_topic, base_frame, odom_frame); ``level_head``: a THOR log without its joint file
    (:func:`~pfslam.io.logs.check_joint`: None warns, False refuses, True runs it level);
    ``resume``: a session to continue (a run's output folder), the log's first scan placed in
    its map by a global search, or at ``start`` (x, y, degrees) if given
    (:mod:`~pfslam.pipeline.sessions`); ``max_scans``: read at most this many scans of the log."""
    from pfslam.io.trajectory import write_tum

    clock = PhaseClock()
    rep = reporter if reporter is not None else Quiet()
    cfg = config if config is not None else settings(SlamConfig, config_file)
    cal_cfg = calibration_settings(config_file) if calibrate is not False else None
    out, session = Path(out), open_session(resume)
    prepare_output_dir(out)
    source = LogInput.of(
        log,
        joint,
        odometry=odometry,
        wheel_scale=wheel_scale,
        level_head=level_head,
        scan_latency=scan_latency,
        max_scans=max_scans,
        **bag,
    )
    log_data = load(source, rep)
    cfg = concrete_config(cfg, log_data.format, config_file)  # (the one place it is made concrete)
    warming = Warming(rep, cfg)  # (once the log is read: a log that cannot be read starts no compile)
    truth, reference, label = slam_truth(ground_truth, log_data)
    frames, cal_info = correct(source, log_data.frames, rep, calibrate=calibrate, axle=cfg.motion.axle, config=cal_cfg)
    cfg, resumed = continued(log, cfg, resume, session, frames, start, rep)
    clock.loaded()
    warming.wait()
    shown = truth if truth is not None else reference
    with watched(
        rep, "SLAM", frames[:: cfg.every], views, shown, cfg.sensor.ground_z, "slam", "pfslam slam", label
    ) as w:
        run = w.finish(run_slam(frames, cfg, w.progress, w.observer, resume=resumed))
    clock.ran(run)
    run = loops_closed(run, rep)
    hand_back_freed()  # (each step's freed heap handed back: the next one's peak starts lower)
    clock.closed()
    run = leave_session(run)
    clock.left()
    warn_notes(rep, run)
    if truth is None and reference is not None:
        truth = reference
        write_tum(out / "reference.tum", *truth)
    scores = score_run(run, frames, truth, ground_truth or "reference", ("SLAM", "odometry"), True, rep)
    hand_back_freed()
    clock.scored(run)
    info = input_info(source, log_data, cal_info)
    return write_results(run, scores, out, log, info, truth, label, cal_cfg if "calibration" in cal_info else None)


def loops_closed(run: Run, reporter: Reporter) -> Run:
    """The back end's step (``backend: graph``: :func:`~pfslam.pipeline.closing.close_loops`),
    with its own progress bar; the run as it was otherwise."""
    if not (isinstance(run.config, SlamConfig) and run.config.backend == Backend.GRAPH):
        return run
    with reporter.progress([("loop closing", 1, "submaps")]) as (bar,):
        return close_loops(run, bar)


DEMO_RATE_HZ = 40.0  # the simulated THOR lidar's scans per second


def demo(
    out: str | Path = "demo_out",
    *,
    duration: float = 180.0,
    seed: int = 0,
    config: SlamConfig | None = None,
    views: ViewRequest | None = None,
    reporter: Reporter | None = None,
    max_scans: int | None = None,
) -> Outcome:
    """``pfslam demo``: simulate a THOR office loop into ``out/log``, run SLAM on it (the
    filter ``pfslam slam`` picks), score SLAM and the odometry against the ground truth."""
    from pfslam.config import check_number
    from pfslam.tools.simulate import MAX_DURATION
    from pfslam.tools.simulate import simulate as sim

    rep = reporter if reporter is not None else Quiet()
    check_number("--duration", duration, gt=0.0, le=MAX_DURATION, what="a finite number of seconds")
    cfg = config if config is not None else SlamConfig(seed=seed)
    out = Path(out)
    prepare_output_dir(out)
    if max_scans is not None and duration > max_scans / DEMO_RATE_HZ:  # the rest would not be read
        duration = max_scans / DEMO_RATE_HZ
        rep.warn(f"at most {max_scans} scans are read: the demo simulates {duration:g} s")
    warming = Warming(rep, cfg)
    rep.note(f"simulating {duration:g} s of a THOR humanoid walking an office loop ...")
    res = sim(world="office", duration_s=duration, seed=seed, out_dir=out / "log")
    from pfslam.io.trajectory import read_tum

    log_data = load(LogInput(res.lidar_path, res.joint_path, max_scans=max_scans), rep)
    cfg = resolve_filter(cfg, log_data.format)
    frames = log_data.frames
    truth = read_tum(res.groundtruth_path)
    warming.wait()
    with watched(rep, "SLAM", frames[:: cfg.every], views, truth, cfg.sensor.ground_z, "slam", "pfslam demo") as w:
        run = w.finish(run_slam(frames, cfg, w.progress, w.observer))
    run = leave_session(loops_closed(run, rep))
    hand_back_freed()
    warn_notes(rep, run)
    scores = score_run(run, frames, truth, res.groundtruth_path, ("SLAM", "odometry"), False, rep)
    hand_back_freed()
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
    views: ViewRequest | None = None,
    reporter: Reporter | None = None,
    max_scans: int | None = None,
    **bag: Unpack[BagOptions],
) -> Outcome:
    """``pfslam localize``: track the robot of ``log`` on the map ``map_yaml``.

    ``map_yaml`` may be a ``pfslam slam`` output folder (its map.yaml); ``initial_pose`` (X, Y,
    THETA_DEG in the map frame): default, where the map's SLAM run
    started (for a map ``pfslam slam`` wrote), else 0,0,0; ``global_start``: particles over
    all free space instead; ``level_head`` as for :func:`slam`."""
    from pfslam.filters.localize import check_start_pose
    from pfslam.io.logs import check_joint
    from pfslam.io.trajectory import read_tum
    from pfslam.maps.grid import OccupancyGrid

    check_joint(Path(log), joint, level_head)  # the log's pairing, before the map is read
    map_yaml = map_file(map_yaml)

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
            check_start_pose(grid, initial[0])
        except InputError as e:
            raise InputError(map_yaml, f"{what}: {e.problem}") from None
    source = LogInput.of(
        log,
        joint,
        odometry=odometry,
        wheel_scale=wheel_scale,
        level_head=level_head,
        scan_latency=scan_latency,
        max_scans=max_scans,
        **bag,
    )
    log_data = load(source, rep)
    truth = read_tum(ground_truth) if ground_truth is not None else None
    label = "ground truth"
    if truth is None and (truth := reference_truth(log_data)) is not None:
        label = "reference"
    frames, cal_info = correct(source, log_data.frames, rep, calibrate=calibrate, axle=cfg.axle, config=cal_cfg)
    with watched(rep, "localize", frames, views, truth, cfg.ground_z, "localization", "pfslam localize", label) as w:
        run = w.finish(run_localization(frames, grid, cfg, initial, w.progress, observer=w.observer))
    warn_notes(rep, run)
    scores = score_run(run, frames, truth, ground_truth or "reference", ("estimate", "odometry"), False, rep)
    info = {
        "log": str(log),
        "map": str(map_yaml),
        "format": log_data.format,
        "odometry": log_data.odometry,
        "global": global_start,
        "wheel_scale": wheel_scale,
        **({"skipped_records": log_data.skipped} if log_data.skipped else {}),
        "frames": frames_info(log_data),
        **cal_info,
    }
    return write_results(run, scores, out, log, info, truth, label, cal_cfg)
