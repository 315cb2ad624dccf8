"""The commands that run on a log: ``slam``, ``calibrate``, ``localize``, ``convert``."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Optional

import numpy as np
import typer
from rich.markup import escape

from pfslam.cli.app import FILTER, INPUT, ODOMETRY, OUTPUT, _command, guarded, out_console
from pfslam.cli.options import (
    ANY_LOG_HELP,
    BACKEND_HELP,
    BASE_FRAME_OPTION,
    FILTER_HELP,
    LOG_HELP,
    ODOM_FRAME_OPTION,
    ODOM_TOPIC_OPTION,
    RERUN_OPTION,
    RERUN_SAVE_OPTION,
    SCAN_TOPIC_OPTION,
    SEED_HELP,
    VIDEO_FPS_OPTION,
    VIDEO_OPTION,
    _bag_options,
    _cleaned_up,
    _config_option,
    _ground_truth_option,
    _joint_option,
    _level_head_option,
    _odometry_option,
    _parse_triple,
    _scan_latency_option,
    _settings,
    _views,
    _wheel_scale_option,
)
from pfslam.cli.render import _calibration_table, _Printer, _report, _run
from pfslam.errors import InputError


@_command()
@guarded
def slam(
    log: Path = typer.Argument(..., metavar="LOG", help=LOG_HELP),
    joint: Optional[Path] = _joint_option(),
    level_head: bool = _level_head_option(),
    ground_truth: Optional[Path] = _ground_truth_option(),
    config: Optional[Path] = _config_option(),
    out: Path = typer.Option(
        Path("out"), "--out", "-o", metavar="DIR", rich_help_panel=OUTPUT, help="Output folder (default out)."
    ),
    filter_: Optional[str] = typer.Option(None, "--filter", metavar="NAME", rich_help_panel=FILTER, help=FILTER_HELP),
    particles: Optional[int] = typer.Option(
        None,
        "--particles",
        "-n",
        metavar="N",
        rich_help_panel=FILTER,
        help="Particles (default 30 for rbpf, 100 for single).",
    ),
    seed: Optional[int] = typer.Option(None, "--seed", metavar="N", rich_help_panel=FILTER, help=SEED_HELP),
    every: Optional[int] = typer.Option(
        None, "--every", metavar="K", rich_help_panel=FILTER, help="Process every K-th scan (default 1: all)."
    ),
    backend: Optional[str] = typer.Option(None, "--backend", metavar="NAME", rich_help_panel=FILTER, help=BACKEND_HELP),
    search: Optional[bool] = typer.Option(
        None,
        "--search/--no-search",
        rich_help_panel=FILTER,
        help="Local x/y/theta search per particle: single (default off).",
    ),
    estimate: Optional[str] = typer.Option(
        None, "--estimate", metavar="NAME", rich_help_panel=FILTER, help="Pose estimate: mean (default) or best."
    ),
    score: Optional[str] = typer.Option(
        None,
        "--score",
        metavar="NAME",
        rich_help_panel=FILTER,
        help="Scoring map: auto (default), field or cells.",
    ),
    odometry: str = _odometry_option(),
    wheel_scale: float = _wheel_scale_option(),
    calibrate: Optional[bool] = typer.Option(
        None,
        "--calibrate/--no-calibrate",
        rich_help_panel=ODOMETRY,
        help="Calibrate the odometry on the scans (default: Mines).",
    ),
    scan_latency: float = _scan_latency_option(),
    video: Optional[Path] = VIDEO_OPTION,
    video_fps: Optional[float] = VIDEO_FPS_OPTION,
    rerun: bool = RERUN_OPTION,
    rerun_save: Optional[Path] = RERUN_SAVE_OPTION,
    scan_topic: Optional[str] = SCAN_TOPIC_OPTION,
    odom_topic: Optional[str] = ODOM_TOPIC_OPTION,
    base_frame: Optional[str] = BASE_FRAME_OPTION,
    odom_frame: Optional[str] = ODOM_FRAME_OPTION,
) -> None:
    """Build a map and a trajectory from a log (its kind told from the file).

    Writes map.pgm/.yaml/.png, trajectory.tum, odometry.tum, config.yaml and run.json into OUT."""
    from pfslam import pipeline
    from pfslam.config import SlamConfig

    cfg = _settings(
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
    views = _views(video, video_fps, rerun, rerun_save)
    with _cleaned_up(out):
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
            reporter=_Printer(),
            **_bag_options(scan_topic, odom_topic, base_frame, odom_frame),
        )
    _report(outcome)


@_command("calibrate")
@guarded
def calibrate_cmd(
    log: Path = typer.Argument(..., metavar="LOG", help=ANY_LOG_HELP),
    joint: Optional[Path] = _joint_option(),
    level_head: bool = _level_head_option(),
    config: Optional[Path] = _config_option(),
    odometry: str = _odometry_option(),
    wheel_scale: float = _wheel_scale_option("Factor already applied to wheel travel (Mines logs; default 1)."),
    axle: float = typer.Option(
        0.33,
        "--axle",
        metavar="M",
        rich_help_panel=ODOMETRY,
        help="Distance between the wheels (m; wheel logs only; default 0.33).",
    ),
    scan_topic: Optional[str] = SCAN_TOPIC_OPTION,
    odom_topic: Optional[str] = ODOM_TOPIC_OPTION,
    base_frame: Optional[str] = BASE_FRAME_OPTION,
    odom_frame: Optional[str] = ODOM_FRAME_OPTION,
) -> None:
    """Measure the odometry's scale and the scan latency by matching the scans (no ground truth needed).

    `pfslam slam --calibrate` applies them."""
    from pfslam import pipeline
    from pfslam.config import CalibrationConfig
    from pfslam.tools.calibrate import CalibrationError, calibrate

    cal_cfg = pipeline.settings(CalibrationConfig, config)
    log_data = pipeline.load(
        log,
        joint,
        _Printer(),
        odometry=odometry,
        wheel_scale=wheel_scale,
        level_head=level_head,
        **_bag_options(scan_topic, odom_topic, base_frame, odom_frame),
    )
    try:
        cal = _run("calibrate", 1, lambda cb: calibrate(log_data.frames, axle=axle, config=cal_cfg, progress=cb))
    except CalibrationError as e:
        raise InputError(log, str(e)) from None
    out_console.print(_calibration_table(cal))
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


@_command()
@guarded
def localize(
    log: Path = typer.Argument(..., metavar="LOG", help=ANY_LOG_HELP),
    map_yaml: Path = typer.Option(
        ...,
        "--map",
        "-m",
        metavar="FILE",
        rich_help_panel=INPUT,
        help="Map in the ROS map_server format (map.yaml).",
    ),
    joint: Optional[Path] = _joint_option(),
    level_head: bool = _level_head_option(),
    ground_truth: Optional[Path] = _ground_truth_option(),
    config: Optional[Path] = _config_option(),
    out: Path = typer.Option(
        Path("out_localize"),
        "--out",
        "-o",
        metavar="DIR",
        rich_help_panel=OUTPUT,
        help="Output folder (default out_localize).",
    ),
    initial_pose: Optional[str] = typer.Option(
        None,
        "--initial-pose",
        metavar="X,Y,DEG",
        rich_help_panel=START,
        help="Start pose (default: where the map's run began, or 0,0,0).",
    ),
    initial_std: Optional[str] = typer.Option(
        None,
        "--initial-std",
        metavar="SX,SY,SDEG",
        rich_help_panel=START,
        help="Start spread, metres and degrees (default 0.1,0.1,5).",
    ),
    global_: bool = typer.Option(
        False, "--global", rich_help_panel=START, help="Unknown start: particles uniform over free space."
    ),
    particles: Optional[int] = typer.Option(
        None,
        "--particles",
        "-n",
        metavar="N",
        rich_help_panel=FILTER,
        help="Particles at the start (KLD adapts it; default 500).",
    ),
    max_particles: Optional[int] = typer.Option(
        None, "--max-particles", metavar="N", rich_help_panel=FILTER, help="KLD-sampling's upper bound (default 5000)."
    ),
    no_kld: bool = typer.Option(False, "--no-kld", rich_help_panel=FILTER, help="Keep the particle count fixed."),
    no_recovery: bool = typer.Option(
        False, "--no-recovery", rich_help_panel=FILTER, help="No random particles when lost."
    ),
    model: Optional[str] = typer.Option(
        None,
        "--model",
        metavar="NAME",
        rich_help_panel=FILTER,
        help="Sensor model: likelihood_field (default) or beam.",
    ),
    seed: Optional[int] = typer.Option(None, "--seed", metavar="N", rich_help_panel=FILTER, help=SEED_HELP),
    odometry: str = _odometry_option(),
    wheel_scale: float = _wheel_scale_option(),
    calibrate: bool = typer.Option(
        False,
        "--calibrate",
        rich_help_panel=ODOMETRY,
        help="Calibrate the odometry on the scans (default off).",
    ),
    scan_latency: float = _scan_latency_option(),
    video: Optional[Path] = VIDEO_OPTION,
    video_fps: Optional[float] = VIDEO_FPS_OPTION,
    rerun: bool = RERUN_OPTION,
    rerun_save: Optional[Path] = RERUN_SAVE_OPTION,
    scan_topic: Optional[str] = SCAN_TOPIC_OPTION,
    odom_topic: Optional[str] = ODOM_TOPIC_OPTION,
    base_frame: Optional[str] = BASE_FRAME_OPTION,
    odom_frame: Optional[str] = ODOM_FRAME_OPTION,
) -> None:
    """Track the robot on a known map (Monte Carlo localization).

    Writes trajectory.tum, odometry.tum, covariance.csv, localization.png, config.yaml, run.json."""
    from pfslam import pipeline
    from pfslam.config import LocalizerConfig, with_particle_counts

    spread: dict[str, tuple[str, Any]] = {}
    if initial_std is not None:  # degrees on the command line, radians in the config (as in ROS)
        std = _parse_triple(initial_std, "--initial-std", "SX,SY,STHETA_DEG")
        if min(std) < 0:
            raise InputError("--initial-std", f"spreads must not be negative, got {initial_std!r}")
        spread = {
            "initial_std_x": ("--initial-std", std[0]),
            "initial_std_y": ("--initial-std", std[1]),
            "initial_std_theta": ("--initial-std", float(np.deg2rad(std[2]))),
        }
    views = _views(video, video_fps, rerun, rerun_save)
    base = _settings(
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
    pose = _parse_triple(initial_pose, "--initial-pose") if initial_pose and not global_ else None
    with _cleaned_up(out):
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
            reporter=_Printer(),
            **_bag_options(scan_topic, odom_topic, base_frame, odom_frame),
        )
    _report(outcome)


@_command()
@guarded
def convert(
    log: Path = typer.Argument(..., metavar="LOG", help="Input log (anything `pfslam slam` reads)."),
    out: Path = typer.Argument(
        ...,
        metavar="OUT",
        help="A .bag (ROS 1), .mcap (MCAP), .log/.log.gz (CARMEN) or a name without a suffix (a ROS 2 bag folder).",
    ),
    joint: Optional[Path] = _joint_option(),
    level_head: bool = _level_head_option(),
    odometry: str = _odometry_option(
        "log (default), or synthetic[:SEED]: write the drifting odometry made from a corrected log's poses."
    ),
    wheel_scale: float = _wheel_scale_option(),
    to: Optional[str] = typer.Option(
        None,
        "--to",
        metavar="FORMAT",
        rich_help_panel=OUTPUT,
        help="ros1, ros2, mcap or carmen (default: from OUT's name).",
    ),
    force: bool = typer.Option(False, "--force", rich_help_panel=OUTPUT, help="Replace OUT if it exists."),
    scan_topic: Optional[str] = SCAN_TOPIC_OPTION,
    odom_topic: Optional[str] = ODOM_TOPIC_OPTION,
    base_frame: Optional[str] = BASE_FRAME_OPTION,
    odom_frame: Optional[str] = ODOM_FRAME_OPTION,
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
        **_bag_options(scan_topic, odom_topic, base_frame, odom_frame),
    )
    printer = _Printer()
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
