"""The options the commands share, as ``Annotated`` aliases (one line per option in a command's
signature), the helpers that declare them, and how option values become settings."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Iterator, Optional

import numpy as np
import typer

from pfslam.cli.app import BAGS, FILTER, INPUT, ODOMETRY, VIEWS
from pfslam.errors import InputError
from pfslam.io.logs import BagOptions

if TYPE_CHECKING:
    from pfslam.views.live import ViewRequest


def views_from(video: Optional[Path], fps: Optional[float], rerun: bool, rerun_save: Optional[Path]) -> ViewRequest:
    """The views asked for, checked before any work (missing packages, file names: one line, exit 2)."""
    from pfslam.views.live import ViewRequest

    views = ViewRequest(video, fps, rerun, rerun_save)
    views.check()
    return views


def parse_triple(text: str, what: str, form: str = "X,Y,THETA_DEG") -> list[float]:

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


def settings_from(cls: type, config: Optional[Path], options: dict[str, tuple[str, Any]]) -> Any:
    """``cls``'s settings from ``config`` and the command line (``options``: config key ->
    (option, value)), an invalid value named as typed; a SLAM config's filter choice checked
    too (a setting the filter that runs does not read), before the log is read. An error in
    a value of the file names the file and the key."""
    from pfslam import pipeline
    from pfslam.config import SlamConfig, check_settings
    from pfslam.errors import ConfigError

    try:
        cfg: Any = pipeline.settings(cls, config, {key: value for key, (_, value) in options.items()})
        if cls is SlamConfig:
            check_settings(cfg)
    except ConfigError as e:
        text = _as_typed(str(e), options)
        if config is not None and not text.startswith("-"):  # about a value of the file
            raise InputError(config, text) from None
        raise ConfigError(text) from None
    return cfg


def bag_options(
    scan_topic: Optional[str], odom_topic: Optional[str], base_frame: Optional[str], odom_frame: Optional[str]
) -> BagOptions:
    """The ROS bag options for load_log (None: not given)."""
    return {"scan_topic": scan_topic, "odom_topic": odom_topic, "base_frame": base_frame, "odom_frame": odom_frame}


@contextlib.contextmanager
def cleaned_up(out: Optional[Path]) -> Iterator[None]:
    """Run the body; if it fails (an error, Ctrl-C) the output folders it made for ``out`` and
    left empty are removed (never one that existed before or holds anything)."""
    from pfslam.io.folders import missing_folders, remove_if_empty

    made = missing_folders(out) if out is not None else []
    try:
        yield
    except BaseException:
        remove_if_empty(made)
        raise


def opt(*decls: str, panel: str, help: str, metavar: str = "") -> Any:
    """A ``typer.Option`` for an ``Annotated`` alias: its help states the default itself (most
    defaults come from the config, where Typer only sees None, so its "[default: ...]" is off);
    a flag (no ``metavar``) shows no type tag."""
    return typer.Option(*decls, metavar=metavar, rich_help_panel=panel, help=help, show_default=False)


def arg(metavar: str, help: str) -> Any:
    """A ``typer.Argument`` for an ``Annotated`` alias, named ``metavar`` in the help."""
    return typer.Argument(metavar=metavar, help=help, show_default=False)


LOG_HELP = "THOR lidar .mat, CARMEN .log(.gz), Mines .dat or ROS bag."
ANY_LOG_HELP = "Log file (anything `pfslam slam` reads)."
FILTER_HELP = "auto (default), rbpf (a map per particle) or single."
BACKEND_HELP = "Loop closing: graph (default; writes graph.g2o) or none."
SEED_HELP = "Random seed (default 0)."

Log = Annotated[Path, arg("LOG", LOG_HELP)]
AnyLog = Annotated[Path, arg("LOG", ANY_LOG_HELP)]
Joint = Annotated[
    Optional[Path],
    opt("--joint", "-j", metavar="FILE", panel=INPUT, help="The THOR joint .mat (head angles): a THOR log needs one."),
]
LevelHead = Annotated[bool, opt("--level-head", panel=INPUT, help="A THOR log without --joint: assume a level head.")]
ConfigFile = Annotated[
    Optional[Path],
    opt(
        "--config",
        "-c",
        metavar="FILE",
        panel=INPUT,
        help="YAML settings (see `pfslam dump-config`); options here win.",
    ),
]
GroundTruth = Annotated[
    Optional[Path], opt("--ground-truth", "-g", metavar="FILE", panel=INPUT, help="TUM ground truth to score against.")
]

FilterName = Annotated[Optional[str], opt("--filter", metavar="NAME", panel=FILTER, help=FILTER_HELP)]
Backend = Annotated[Optional[str], opt("--backend", metavar="NAME", panel=FILTER, help=BACKEND_HELP)]
Every = Annotated[
    Optional[int], opt("--every", metavar="K", panel=FILTER, help="Process every K-th scan (default 1: all).")
]
Search = Annotated[
    Optional[bool],
    opt("--search/--no-search", panel=FILTER, help="Local x/y/theta search per particle: single (default off)."),
]
Seed = Annotated[Optional[int], opt("--seed", metavar="N", panel=FILTER, help=SEED_HELP)]

Odometry = Annotated[
    str, opt("--odometry", metavar="SRC", panel=ODOMETRY, help="log (default) or synthetic[:SEED] (corrected logs).")
]
WheelScale = Annotated[
    float, opt("--wheel-scale", metavar="X", panel=ODOMETRY, help="Factor on wheel travel (Mines logs; default 1).")
]
ScanLatency = Annotated[
    float, opt("--scan-latency", metavar="S", panel=ODOMETRY, help="Read the odometry at t - S (default 0).")
]

Video = Annotated[
    Optional[Path],
    opt(
        "--video",
        metavar="FILE",
        panel=VIEWS,
        help="Render the run into FILE.mp4 or .gif (pip install 'pfslam\\[video]').",
    ),
]
VideoFps = Annotated[
    Optional[float],
    opt(
        "--video-fps", metavar="N", panel=VIEWS, help="Frames per second of --video (default 20 for .mp4, 10 for .gif)."
    ),
]
Rerun = Annotated[
    bool, opt("--rerun", panel=VIEWS, help="Watch the run live in the rerun viewer (pip install 'pfslam\\[viz]').")
]
RerunSave = Annotated[
    Optional[Path],
    opt(
        "--rerun-save",
        metavar="FILE",
        panel=VIEWS,
        help="Save a rerun recording FILE.rrd (open it with `rerun FILE.rrd`).",
    ),
]

ScanTopic = Annotated[
    Optional[str],
    opt(
        "--scan-topic",
        metavar="TOPIC",
        panel=BAGS,
        help="The sensor_msgs/LaserScan topic (default: the bag's only one).",
    ),
]
OdomTopic = Annotated[
    Optional[str],
    opt(
        "--odom-topic",
        metavar="TOPIC",
        panel=BAGS,
        help="The nav_msgs/Odometry topic (default: the bag's only one), or /tf.",
    ),
]
BaseFrame = Annotated[
    Optional[str],
    opt(
        "--base-frame",
        metavar="FRAME",
        panel=BAGS,
        help="The robot's frame (default: the Odometry's child, else base_link).",
    ),
]
OdomFrame = Annotated[
    Optional[str],
    opt("--odom-frame", metavar="FRAME", panel=BAGS, help="The odometry frame of /tf odometry (default odom)."),
]


MAX_SCANS_ENV = "PFSLAM_MAX_SCANS"


def scan_limit() -> int | None:
    """The environment's ``PFSLAM_MAX_SCANS`` (read here, once per command, and passed down as
    ``max_scans``): read at most this many scans of any log (a quick look at a long log; the
    documentation's test runs every command so), said in a warning. None if unset."""
    from pfslam.cli.app import warn

    value = os.environ.get(MAX_SCANS_ENV, "").strip()
    if not value:
        return None
    try:
        limit = int(value)
    except ValueError:
        limit = 0
    if limit < 1:
        raise InputError(Path(MAX_SCANS_ENV), f"must be a whole number of scans of at least 1, not {value!r}")
    warn(f"{MAX_SCANS_ENV}={limit} is set: at most {limit} scans of a log are read")
    return limit
