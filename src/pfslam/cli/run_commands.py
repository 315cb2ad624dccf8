"""The commands that run on a log: ``slam``, ``calibrate``, ``localize``, ``convert``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Optional

import numpy as np
from rich.markup import escape

from pfslam.cli.app import FILTER, INPUT, ODOMETRY, OUTPUT, command, guarded, out_console
from pfslam.cli.options import (
    AnyLog,
    Backend,
    BaseFrame,
    ConfigFile,
    Every,
    FilterName,
    GroundTruth,
    Joint,
    LevelHead,
    Log,
    Odometry,
    OdomFrame,
    OdomTopic,
    Rerun,
    RerunSave,
    ScanLatency,
    ScanTopic,
    Search,
    Seed,
    Video,
    VideoFps,
    WheelScale,
    arg,
    bag_options,
    cleaned_up,
    opt,
    parse_triple,
    scan_limit,
    settings_from,
    views_from,
)
from pfslam.cli.render import Printer, calibration_table, report, run_with_progress
from pfslam.errors import InputError

ResumeDir = Annotated[
    Optional[Path],
    opt(
        "--resume",
        metavar="DIR",
        panel=INPUT,
        help="Continue the session of an earlier run (its output folder): the log's start found in its map.",
    ),
]
StartPose = Annotated[
    Optional[str],
    opt("--start", metavar="X,Y,DEG", panel=INPUT, help="With --resume: where the log starts in the old map."),
]
SlamOut = Annotated[Path, opt("--out", "-o", metavar="DIR", panel=OUTPUT, help="Output folder (default out).")]
SlamParticles = Annotated[
    Optional[int],
    opt("--particles", "-n", metavar="N", panel=FILTER, help="Particles (default 30 for rbpf, 100 for single)."),
]
Estimate = Annotated[
    Optional[str], opt("--estimate", metavar="NAME", panel=FILTER, help="Pose estimate: mean (default) or best.")
]
Score = Annotated[
    Optional[str], opt("--score", metavar="NAME", panel=FILTER, help="Scoring map: auto (default), field or cells.")
]
Calibrate = Annotated[
    Optional[bool],
    opt("--calibrate/--no-calibrate", panel=ODOMETRY, help="Calibrate the odometry on the scans (default: Mines)."),
]


@command()
@guarded
def slam(
    log: Log,
    joint: Joint = None,
    level_head: LevelHead = False,
    ground_truth: GroundTruth = None,
    config: ConfigFile = None,
    resume: ResumeDir = None,
    start: StartPose = None,
    out: SlamOut = Path("out"),
    filter_: FilterName = None,
    particles: SlamParticles = None,
    seed: Seed = None,
    every: Every = None,
    backend: Backend = None,
    search: Search = None,
    estimate: Estimate = None,
    score: Score = None,
    odometry: Odometry = "log",
    wheel_scale: WheelScale = 1.0,
    calibrate: Calibrate = None,
    scan_latency: ScanLatency = 0.0,
    video: Video = None,
    video_fps: VideoFps = None,
    rerun: Rerun = False,
    rerun_save: RerunSave = None,
    scan_topic: ScanTopic = None,
    odom_topic: OdomTopic = None,
    base_frame: BaseFrame = None,
    odom_frame: OdomFrame = None,
) -> None:
    """Build a map and a trajectory from a log (its kind told from the file).

    Writes map.pgm/.yaml/.png, trajectory.tum, odometry.tum, config.yaml, run.json and the
    session (session/: what --resume needs to continue the map with another log) into OUT."""
    from pfslam import pipeline
    from pfslam.config import SlamConfig

    cfg = settings_from(
        SlamConfig,
        config,
        {
            "particles": ("--particles", particles),
            "seed": ("--seed", seed),
            "every": ("--every", every),
            "local_search.enabled": ("--search", search),
            "estimate": ("--estimate", estimate),
            "sensor.scoring_map": ("--score", score),
            "filter": ("--filter", filter_),
            "backend": ("--backend", backend),
        },
    )
    views = views_from(video, video_fps, rerun, rerun_save)
    if start is not None and resume is None:
        raise InputError("--start", "places the log in the map of --resume DIR: give both")
    start_pose = parse_triple(start, "--start", "X,Y,DEG") if start is not None else None
    with cleaned_up(out):
        outcome = pipeline.slam(
            log,
            out,
            joint=joint,
            config=cfg,
            config_file=config,
            odometry=odometry,
            wheel_scale=wheel_scale,
            level_head=level_head,
            calibrate=calibrate,
            scan_latency=scan_latency,
            ground_truth=ground_truth,
            views=views,
            reporter=Printer(),
            resume=resume,
            start=start_pose,
            max_scans=scan_limit(),
            **bag_options(scan_topic, odom_topic, base_frame, odom_frame),
        )
    report(outcome)


AppliedWheelScale = Annotated[
    float,
    opt(
        "--wheel-scale",
        metavar="X",
        panel=ODOMETRY,
        help="Factor already applied to wheel travel (Mines logs; default 1).",
    ),
]
Axle = Annotated[
    float,
    opt("--axle", metavar="M", panel=ODOMETRY, help="Distance between the wheels (m; wheel logs only; default 0.33)."),
]


@command("calibrate")
@guarded
def calibrate_cmd(
    log: AnyLog,
    joint: Joint = None,
    level_head: LevelHead = False,
    config: ConfigFile = None,
    odometry: Odometry = "log",
    wheel_scale: AppliedWheelScale = 1.0,
    axle: Axle = 0.33,
    scan_topic: ScanTopic = None,
    odom_topic: OdomTopic = None,
    base_frame: BaseFrame = None,
    odom_frame: OdomFrame = None,
) -> None:
    """Measure the odometry's scale and the scan latency by matching the scans (no ground truth needed).

    `pfslam slam --calibrate` applies them."""
    from pfslam import pipeline
    from pfslam.config import CalibrationConfig
    from pfslam.tools.calibrate import CalibrationError, calibrate

    cal_cfg = pipeline.settings(CalibrationConfig, config)
    source = pipeline.LogInput.of(
        log,
        joint,
        odometry=odometry,
        wheel_scale=wheel_scale,
        level_head=level_head,
        max_scans=scan_limit(),
        **bag_options(scan_topic, odom_topic, base_frame, odom_frame),
    )
    log_data = pipeline.load(source, Printer())
    try:
        cal = run_with_progress(
            "calibrate", 1, lambda cb: calibrate(log_data.frames, axle=axle, config=cal_cfg, progress=cb)
        )
    except CalibrationError as e:
        raise InputError(log, str(e)) from None
    out_console.print(calibration_table(cal))
    if not cal.explains_odometry():
        out_console.print(
            "the correction explains little of the difference between odometry and scans: "
            "the odometry already agrees with them, and --calibrate is not needed",
            soft_wrap=True,
        )
    out_console.print(
        escape(
            f"{cal.source}: translation x{cal.trans_scale:.3f}, rotation x{cal.rot_scale:.3f}, scans taken "
            f"{cal.scan_latency:.3f} s before their time stamps. `pfslam slam --calibrate` applies this."
        ),
        soft_wrap=True,
    )


START = "Start"
MapFile = Annotated[
    Path,
    opt(
        "--map",
        "-m",
        metavar="FILE",
        panel=INPUT,
        help="Map in the ROS map_server format (map.yaml), or the output folder of a pfslam slam run.",
    ),
]
LocalizeOut = Annotated[
    Path, opt("--out", "-o", metavar="DIR", panel=OUTPUT, help="Output folder (default out_localize).")
]
InitialPose = Annotated[
    Optional[str],
    opt(
        "--initial-pose",
        metavar="X,Y,DEG",
        panel=START,
        help="Start pose (default: where the map's run began, or 0,0,0).",
    ),
]
InitialStd = Annotated[
    Optional[str],
    opt(
        "--initial-std",
        metavar="SX,SY,SDEG",
        panel=START,
        help="Start spread, metres and degrees (default 0.1,0.1,5).",
    ),
]
GlobalStart = Annotated[
    bool,
    opt(
        "--global",
        panel=START,
        help="Unknown start: the first scan is matched over the whole map and every heading, and the particles "
        "start at the places it fits best (all of them kept while they fit alike); localize.global_start: "
        "uniform spreads them over free space instead.",
    ),
]
LocalizeParticles = Annotated[
    Optional[int],
    opt("--particles", "-n", metavar="N", panel=FILTER, help="Particles at the start (KLD adapts it; default 500)."),
]
MaxParticles = Annotated[
    Optional[int], opt("--max-particles", metavar="N", panel=FILTER, help="KLD-sampling's upper bound (default 5000).")
]
NoKld = Annotated[bool, opt("--no-kld", panel=FILTER, help="Keep the particle count fixed.")]
NoRecovery = Annotated[bool, opt("--no-recovery", panel=FILTER, help="No random particles when lost.")]
Model = Annotated[
    Optional[str],
    opt("--model", metavar="NAME", panel=FILTER, help="Sensor model: likelihood_field (default) or beam."),
]
CalibrateFlag = Annotated[
    bool, opt("--calibrate", panel=ODOMETRY, help="Calibrate the odometry on the scans (default off).")
]


@command()
@guarded
def localize(
    log: AnyLog,
    map_yaml: MapFile,
    joint: Joint = None,
    level_head: LevelHead = False,
    ground_truth: GroundTruth = None,
    config: ConfigFile = None,
    out: LocalizeOut = Path("out_localize"),
    initial_pose: InitialPose = None,
    initial_std: InitialStd = None,
    global_: GlobalStart = False,
    particles: LocalizeParticles = None,
    max_particles: MaxParticles = None,
    no_kld: NoKld = False,
    no_recovery: NoRecovery = False,
    model: Model = None,
    seed: Seed = None,
    odometry: Odometry = "log",
    wheel_scale: WheelScale = 1.0,
    calibrate: CalibrateFlag = False,
    scan_latency: ScanLatency = 0.0,
    video: Video = None,
    video_fps: VideoFps = None,
    rerun: Rerun = False,
    rerun_save: RerunSave = None,
    scan_topic: ScanTopic = None,
    odom_topic: OdomTopic = None,
    base_frame: BaseFrame = None,
    odom_frame: OdomFrame = None,
) -> None:
    """Track the robot on a known map (Monte Carlo localization).

    Writes trajectory.tum, odometry.tum, covariance.csv, localization.png, config.yaml, run.json."""
    from pfslam import pipeline
    from pfslam.config import LocalizerConfig, with_particle_counts

    spread: dict[str, tuple[str, Any]] = {}
    if initial_std is not None:  # degrees on the command line, radians in the config (as in ROS)
        std = parse_triple(initial_std, "--initial-std", "SX,SY,STHETA_DEG")
        if min(std) < 0:
            raise InputError("--initial-std", f"spreads must not be negative, got {initial_std!r}")
        spread = {
            "initial_std_x": ("--initial-std", std[0]),
            "initial_std_y": ("--initial-std", std[1]),
            "initial_std_theta": ("--initial-std", float(np.deg2rad(std[2]))),
        }
    views = views_from(video, video_fps, rerun, rerun_save)
    base = settings_from(
        LocalizerConfig,
        config,
        {
            "seed": ("--seed", seed),
            "model": ("--model", model),
            "recovery": ("--no-recovery", False if no_recovery else None),
            "kld": ("--no-kld", False if no_kld else None),
            **spread,
        },
    )
    cfg = with_particle_counts(base, particles, max_particles)
    pose = parse_triple(initial_pose, "--initial-pose") if initial_pose and not global_ else None
    with cleaned_up(out):
        outcome = pipeline.localize(
            log,
            map_yaml,
            out,
            joint=joint,
            config=cfg,
            config_file=config,
            initial_pose=pose,
            global_start=global_,
            odometry=odometry,
            wheel_scale=wheel_scale,
            level_head=level_head,
            calibrate=calibrate,
            scan_latency=scan_latency,
            ground_truth=ground_truth,
            views=views,
            reporter=Printer(),
            max_scans=scan_limit(),
            **bag_options(scan_topic, odom_topic, base_frame, odom_frame),
        )
    report(outcome)


ConvertLog = Annotated[Path, arg("LOG", "Input log (anything `pfslam slam` reads).")]
ConvertOut = Annotated[
    Path,
    arg(
        "OUT",
        "A .bag (ROS 1), .mcap (MCAP), .log/.log.gz (CARMEN) or a name without a suffix (a ROS 2 bag folder).",
    ),
]
ConvertOdometry = Annotated[
    str,
    opt(
        "--odometry",
        metavar="SRC",
        panel=ODOMETRY,
        help="log (default), or synthetic[:SEED]: write the drifting odometry made from a corrected log's poses.",
    ),
]
ConvertTo = Annotated[
    Optional[str],
    opt("--to", metavar="FORMAT", panel=OUTPUT, help="ros1, ros2, mcap or carmen (default: from OUT's name)."),
]
Force = Annotated[bool, opt("--force", panel=OUTPUT, help="Replace OUT if it exists.")]


@command()
@guarded
def convert(
    log: ConvertLog,
    out: ConvertOut,
    joint: Joint = None,
    level_head: LevelHead = False,
    odometry: ConvertOdometry = "log",
    wheel_scale: WheelScale = 1.0,
    to: ConvertTo = None,
    force: Force = False,
    scan_topic: ScanTopic = None,
    odom_topic: OdomTopic = None,
    base_frame: BaseFrame = None,
    odom_frame: OdomFrame = None,
) -> None:
    """Write a log as a ROS bag or a CARMEN log.

    A ROS bag gets /scan (LaserScan, frame laser), /odom (Odometry, odom -> base_link) and
    /tf_static (base_link -> laser; /tf too when the mount moves); a CARMEN log FLASER lines."""
    from pfslam.tools.convert import convert as run_convert

    res = run_convert(
        log,
        out,
        to=to,
        force=force,
        joint=joint,
        odometry=odometry,
        wheel_scale=wheel_scale,
        level_head=level_head,
        max_scans=scan_limit(),
        **bag_options(scan_topic, odom_topic, base_frame, odom_frame),
    )
    printer = Printer()
    for n in res.notes:
        printer.note(n)
    for w in res.warnings:
        printer.warn(w)
    out_console.print(
        escape(
            f"wrote {res.scans} scans of {log} ({res.source_format}, odometry {res.odometry}) "
            f"to {res.path} ({res.description})"
        ),
        soft_wrap=True,
    )
