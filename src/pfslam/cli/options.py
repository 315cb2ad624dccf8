"""The options the commands share: their help texts and panels, the view and ROS bag options,
and how option values become settings."""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Any, Iterator, Optional

import numpy as np
import typer

from pfslam.cli.app import BAGS, INPUT, ODOMETRY, VIEWS
from pfslam.errors import InputError

VIDEO_OPTION = typer.Option(
    None,
    "--video",
    metavar="FILE",
    rich_help_panel=VIEWS,
    help="Render the run into FILE.mp4 or .gif (pip install 'pfslam\\[video]').",
)
VIDEO_FPS_OPTION = typer.Option(
    None,
    "--video-fps",
    metavar="N",
    rich_help_panel=VIEWS,
    help="Frames per second of --video (default 20 for .mp4, 10 for .gif).",
)
RERUN_OPTION = typer.Option(
    False,
    "--rerun",
    rich_help_panel=VIEWS,
    help="Watch the run live in the rerun viewer (pip install 'pfslam\\[viz]').",
)
RERUN_SAVE_OPTION = typer.Option(
    None,
    "--rerun-save",
    metavar="FILE",
    rich_help_panel=VIEWS,
    help="Save a rerun recording FILE.rrd (open it with `rerun FILE.rrd`).",
)


def _views(video: Optional[Path], fps: Optional[float], rerun: bool, rerun_save: Optional[Path]) -> Any:
    """The views asked for, checked before any work (missing packages, file names: one line, exit 2)."""
    from pfslam.views.live import ViewRequest

    views = ViewRequest(video, fps, rerun, rerun_save)
    views.check()
    return views


def _parse_triple(text: str, what: str, form: str = "X,Y,THETA_DEG") -> list[float]:

    try:
        v = [float(x) for x in text.replace(" ", "").split(",")]
    except ValueError:
        v = []
    if len(v) != 3 or not all(np.isfinite(v)):
        raise InputError(what, f"expected three numbers {form}, got {text!r}")
    return v


def _as_typed(text: str, options: dict[str, tuple[str, Any]]) -> str:
    """A config error's ``text`` naming the command-line options (``options``: config key ->
    (option, value; None: not given)) as the user types them rather than by their config keys:
    "particles must be ..." -> "--particles must be ..." where the value came from --particles,
    "set filter: single" -> "use --filter single" for any option of the command."""
    for key, (option, value) in options.items():
        if value is not None and text.startswith(f"{key} "):
            text = option + text[len(key) :]
        text = text.replace(f"set {key}: ", f"use {option} ")
    return text


def _settings(cls: type, config: Optional[Path], options: dict[str, tuple[str, Any]]) -> Any:
    """``cls``'s settings from ``config`` and the command line (``options``: config key ->
    (option, value)), an invalid value named as typed; a SLAM config's filter choice checked
    too (a setting the filter that runs does not read), before the log is read. An error in
    a value of the file names the file and the key."""
    from pfslam import pipeline
    from pfslam.config import SlamConfig, resolve_filter
    from pfslam.errors import ConfigError

    try:
        cfg: Any = pipeline.settings(cls, config, {key: value for key, (_, value) in options.items()})
        if cls is SlamConfig:
            resolve_filter(cfg)
    except ConfigError as e:
        text = _as_typed(str(e), options)
        if config is not None and not text.startswith("-"):  # about a value of the file
            raise InputError(config, text) from None
        raise ConfigError(text) from None
    return cfg


def _bag_options(
    scan_topic: Optional[str], odom_topic: Optional[str], base_frame: Optional[str], odom_frame: Optional[str]
) -> dict[str, Optional[str]]:
    """The ROS bag options for load_log (None: not given)."""
    return {"scan_topic": scan_topic, "odom_topic": odom_topic, "base_frame": base_frame, "odom_frame": odom_frame}


@contextlib.contextmanager
def _cleaned_up(out: Optional[Path]) -> Iterator[None]:
    """Run the body; if it fails (an error, Ctrl-C) the output folders it made for ``out`` and
    left empty are removed (never one that existed before or holds anything)."""
    from pfslam.io.folders import missing_folders, remove_if_empty

    made = missing_folders(out) if out is not None else []
    try:
        yield
    except BaseException:
        remove_if_empty(made)
        raise


LOG_HELP = "THOR lidar .mat, CARMEN .log(.gz), Mines .dat or ROS bag."
ANY_LOG_HELP = "Log file (anything `pfslam slam` reads)."
JOINT_HELP = "The THOR joint .mat (head angles): a THOR log needs one."
LEVEL_HEAD_HELP = "A THOR log without --joint: assume a level head."
CONFIG_HELP = "YAML settings (see `pfslam dump-config`); options here win."
GROUND_TRUTH_HELP = "TUM ground truth to score against."
ODOMETRY_HELP = "log (default) or synthetic[:SEED] (corrected logs)."
FILTER_HELP = "auto (default), rbpf (a map per particle) or single."
BACKEND_HELP = "Loop closing: graph (default; writes graph.g2o) or none."
SEED_HELP = "Random seed (default 0)."


def _joint_option() -> Any:
    return typer.Option(None, "--joint", "-j", metavar="FILE", rich_help_panel=INPUT, help=JOINT_HELP)


def _level_head_option() -> Any:
    return typer.Option(False, "--level-head", rich_help_panel=INPUT, help=LEVEL_HEAD_HELP)


def _config_option() -> Any:
    return typer.Option(None, "--config", "-c", metavar="FILE", rich_help_panel=INPUT, help=CONFIG_HELP)


def _ground_truth_option() -> Any:
    return typer.Option(None, "--ground-truth", "-g", metavar="FILE", rich_help_panel=INPUT, help=GROUND_TRUTH_HELP)


def _odometry_option(help: str = ODOMETRY_HELP) -> Any:
    return typer.Option("log", "--odometry", metavar="SRC", rich_help_panel=ODOMETRY, help=help)


def _wheel_scale_option(help: str = "Factor on wheel travel (Mines logs; default 1).") -> Any:
    return typer.Option(1.0, "--wheel-scale", metavar="X", rich_help_panel=ODOMETRY, help=help)


def _scan_latency_option() -> Any:
    return typer.Option(
        0.0,
        "--scan-latency",
        metavar="S",
        rich_help_panel=ODOMETRY,
        help="Read the odometry at t - S (default 0).",
    )


SCAN_TOPIC_OPTION = typer.Option(
    None,
    "--scan-topic",
    metavar="TOPIC",
    rich_help_panel=BAGS,
    help="The sensor_msgs/LaserScan topic (default: the bag's only one).",
)
ODOM_TOPIC_OPTION = typer.Option(
    None,
    "--odom-topic",
    metavar="TOPIC",
    rich_help_panel=BAGS,
    help="The nav_msgs/Odometry topic (default: the bag's only one), or /tf.",
)
BASE_FRAME_OPTION = typer.Option(
    None,
    "--base-frame",
    metavar="FRAME",
    rich_help_panel=BAGS,
    help="The robot's frame (default: the Odometry's child, else base_link).",
)
ODOM_FRAME_OPTION = typer.Option(
    None,
    "--odom-frame",
    metavar="FRAME",
    rich_help_panel=BAGS,
    help="The odometry frame of /tf odometry (default odom).",
)
