"""The ``pfslam`` command line. All printing and exit codes live here."""

from __future__ import annotations

import contextlib
import functools
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any, Callable, Iterator, Optional, TypeVar

import numpy as np
import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table

from pfslam import __version__
from pfslam.errors import InputError, PfslamError

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Particle-filter SLAM and Monte Carlo localization for 2D lidar logs.",
    pretty_exceptions_enable=False,
)


class _StdoutError(Exception):
    """Standard output could not be written (a full disk, a closed pipe); main() reports it."""

    def __init__(self, error: OSError) -> None:
        super().__init__(str(error))
        self.error = error


class _Stdout:
    """What ``out_console`` writes to: ``sys.stdout`` at the moment of writing (tests swap it),
    a failed write raised as :class:`_StdoutError` so that no handler takes it for a file's error."""

    def write(self, text: str) -> int:
        try:
            return sys.stdout.write(text)
        except OSError as e:
            raise _StdoutError(e) from None

    def flush(self) -> None:
        try:
            sys.stdout.flush()
        except OSError as e:
            raise _StdoutError(e) from None

    def __getattr__(self, name: str) -> Any:
        return getattr(sys.stdout, name)


out_console = Console(file=_Stdout())  # type: ignore[arg-type]
err_console = Console(stderr=True)

F = TypeVar("F", bound=Callable[..., Any])


def _error(text: str) -> None:
    """One line on stderr; ``text`` is printed as is (file names may hold [brackets])."""
    err_console.print(f"[bold red]error:[/] {escape(text)}", highlight=False, soft_wrap=True)


def _warn(text: str) -> None:
    err_console.print(f"[yellow]warning:[/] {escape(text)}", highlight=False, soft_wrap=True)


# Stop signals this process received (SIGTERM, and SIGINT while results were being written):
# main() reports a run stopped by SIGTERM with exit code 143 instead of Ctrl-C's 130.
_received: list[int] = []
EXIT_INTERRUPTED = 130  # 128 + SIGINT
EXIT_TERMINATED = 143  # 128 + SIGTERM
EXIT_CLOSED_PIPE = 141  # 128 + SIGPIPE: the reader of stdout went away (e.g. `| head`)


def _terminate(sig: int, frame: Any) -> None:
    """SIGTERM (batch schedulers, `timeout`) stops a run like Ctrl-C: the loops that keep what
    they computed on KeyboardInterrupt keep it, the results are written, then the exit is 143."""
    _received.append(sig)
    raise KeyboardInterrupt


def guarded(fn: F) -> F:
    """Turn pfslam's own errors into one line on stderr and exit code 2 (a standard output that
    fails, :class:`_StdoutError`, passes through to main(), which reports it for every command)."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except PfslamError as e:
            _error(str(e))
            raise typer.Exit(2) from None
        except OSError as e:  # e.g. an output folder that cannot be written
            where = e.filename if e.filename is not None else "pfslam"
            _error(f"{where}: {e.strerror or e}")
            raise typer.Exit(2) from None
        except MemoryError:
            _error("out of memory: fewer particles, a coarser map or a shorter log would fit")
            raise typer.Exit(2) from None
        except KeyboardInterrupt:
            err_console.print("[yellow]interrupted[/]", highlight=False)
            raise typer.Exit(EXIT_INTERRUPTED) from None

    return wrapper  # type: ignore[return-value]


def _progress() -> Progress:
    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]:>7.1f} {task.fields[unit]}/s"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=err_console,
        transient=False,
        disable=not err_console.is_terminal and "PFSLAM_PROGRESS" not in os.environ,
    )


@contextlib.contextmanager
def _progress_bars(bars: list[tuple[str, int, str]]) -> Iterator[list[Callable[[int, int], None]]]:
    """Progress bars on stderr, one per (label, total, unit counted), and the (done, total)
    callbacks that move them."""
    with _progress() as prog:
        t0 = time.perf_counter()

        def mover(task: Any) -> Callable[[int, int], None]:
            def cb(i: int, n: int) -> None:
                dt = time.perf_counter() - t0
                prog.update(task, total=n, completed=i, rate=i / dt if dt > 0 else 0.0)

            return cb

        yield [mover(prog.add_task(label, total=total, rate=0.0, unit=unit)) for label, total, unit in bars]


def _errors_table(rows: dict[str, Any]) -> Table:
    tab = Table(show_header=True, header_style="bold")
    tab.add_column("trajectory")
    tab.add_column("ATE RMSE (m)", justify="right")
    tab.add_column("ATE aligned (m)", justify="right")
    tab.add_column("heading RMSE (deg)", justify="right")
    tab.add_column("RPE trans (m)", justify="right")
    for name, e in rows.items():
        tab.add_row(
            name,
            f"{e.ate_rmse:.3f}",
            f"{e.ate_rmse_aligned:.3f}",
            f"{e.heading_rmse_deg:.2f}",
            f"{e.rpe_trans_rmse:.4f}",
        )
    return tab


def _calibration_table(cal: Any) -> Table:
    tab = Table(show_header=True, header_style="bold")
    tab.add_column("quantity")
    tab.add_column("value", justify="right")
    tab.add_row("translation scale", f"{cal.trans_scale:.3f}")
    tab.add_row("rotation scale", f"{cal.rot_scale:.3f}")
    tab.add_row("scan latency (s)", f"{cal.scan_latency:+.3f}")
    tab.add_row(
        "heading residual per scan (deg), before -> after",
        f"{cal.rot_residual_deg_uncalibrated:.2f} -> {cal.rot_residual_deg:.2f}",
    )
    tab.add_row("translation residual per scan (m)", f"{cal.trans_residual:.4f}")
    tab.add_row("scan pairs matched / used", f"{cal.pairs_matched} / {cal.pairs_used}")
    return tab


class _Printer:
    """The pipeline's reporter for a terminal: results on stdout, the rest on stderr."""

    def warn(self, text: str) -> None:
        _warn(text)

    def say(self, text: str) -> None:
        out_console.print(escape(text), soft_wrap=True)

    def note(self, text: str) -> None:
        err_console.print(escape(text), highlight=False, soft_wrap=True)

    def calibration(self, cal: Any) -> None:
        out_console.print(_calibration_table(cal))

    def scores(self, scores: Any) -> None:
        if scores.errors:
            out_console.print(_errors_table(scores.errors))
        if scores.map_agreement:
            shown = ", ".join(
                f"{k} {v:.3f}"
                if np.isfinite(v)
                else f"{k} - (no later scan re-observes its map, or it spans more than the largest map)"
                for k, v in scores.map_agreement.items()
            )
            out_console.print(
                f"map agreement (later scans on the walls earlier scans mapped, within 0.1 m): {shown}", soft_wrap=True
            )

    def progress(self, bars: list[tuple[str, int, str]]) -> Any:
        return _progress_bars(bars)


def _run(label: str, total: int, fn: Callable[[Callable[[int, int], None]], Any]) -> Any:
    with _progress_bars([(label, total, "scans")]) as (cb,):
        return fn(cb)


VIDEO_OPTION = typer.Option(
    None,
    "--video",
    help="Also render the run into a video, FILE.mp4 or FILE.gif: the map as it is at each "
    "moment, the particles, the scan, the trajectories so far, the time; the log plays at 6x "
    "real time (faster for logs over 4 minutes: 40 s at most). Needs pip install 'pfslam\\[video]'.",
)
VIDEO_FPS_OPTION = typer.Option(
    None, "--video-fps", help="Frames per second of --video (default 20 for .mp4, 10 for .gif)."
)
RERUN_OPTION = typer.Option(
    False,
    "--rerun",
    help="Watch the run live in the rerun viewer (spawned, or the one already listening on "
    "rerun's port). Needs pip install 'pfslam\\[viz]'.",
)
RERUN_SAVE_OPTION = typer.Option(
    None, "--rerun-save", help="Save the run as a rerun recording, FILE.rrd (open it with `rerun FILE.rrd`)."
)


def _views(video: Optional[Path], fps: Optional[float], rerun: bool, rerun_save: Optional[Path]) -> Any:
    """The views asked for, checked before any work (missing packages, file names: one line, exit 2)."""
    from pfslam.views.live import ViewRequest

    views = ViewRequest(video, fps, rerun, rerun_save)
    views.check()
    return views


def _report(outcome: Any) -> None:
    """Say how a run whose results were written ended; the exit code for one stopped early."""
    run = outcome.run
    _received.extend(outcome.signals)
    if run.error is not None:
        _error(f"{outcome.log}: {run.error}; the results for the {run.scans} scans before it are in {outcome.out}/")
        raise typer.Exit(2)
    if run.interrupted:
        err_console.print(
            f"[yellow]interrupted:[/] results for the {run.scans} scans done are in {escape(str(outcome.out))}/",
            highlight=False,
            soft_wrap=True,
        )
        raise typer.Exit(130)
    out_console.print(escape(outcome.summary()), soft_wrap=True)


def _parse_triple(text: str, what: str, form: str = "X,Y,THETA_DEG") -> list[float]:

    try:
        v = [float(x) for x in text.replace(" ", "").split(",")]
    except ValueError:
        v = []
    if len(v) != 3 or not all(np.isfinite(v)):
        raise InputError(what, f"expected three numbers {form}, got {text!r}")
    return v


ODOMETRY_HELP = (
    "Odometry source: 'log', or 'synthetic[:SEED]' for logs whose poses are already corrected "
    "(CARMEN .gfs logs): drifting odometry derived from them; they are saved as reference.tum."
)
CONFIG_HELP = "YAML config (see `pfslam dump-config`): the file's own section if it has sections."
BACKEND_HELP = (
    "Loop closing behind the filter: graph (the default: submaps, a branch-and-bound loop search and a "
    "robust pose graph on GTSAM; writes graph.g2o) or none (the filter's answer alone)."
)
FILTER_HELP = (
    "SLAM filter: auto (the default: rbpf, with the odometry prior in its match on wheeled logs; "
    "single with --search), single (one map updated from the estimate), or rbpf (a map per particle, "
    "scan-matched proposal, the best particle's loop-closed path; GMapping's family)."
)
LOG_HELP = "Log file: THOR lidar .mat, CARMEN log (.log/.gz), Mines .dat, ROS bag (.bag, .mcap, a ROS 2 bag folder)."
SCAN_TOPIC_HELP = "ROS bags: the sensor_msgs/LaserScan topic to read (default: the bag's only one)."
ODOM_TOPIC_HELP = (
    "ROS bags: the nav_msgs/Odometry topic (default: the bag's only one), or /tf for the "
    "odometry frame -> base frame transform."
)
BASE_FRAME_HELP = (
    "ROS bags: the robot's base frame (default: the Odometry's child frame, else base_footprint or base_link)."
)
ODOM_FRAME_HELP = "ROS bags: the odometry frame of the /tf odometry (default: odom)."


SCAN_TOPIC_OPTION = typer.Option(None, "--scan-topic", help=SCAN_TOPIC_HELP)
ODOM_TOPIC_OPTION = typer.Option(None, "--odom-topic", help=ODOM_TOPIC_HELP)
BASE_FRAME_OPTION = typer.Option(None, "--base-frame", help=BASE_FRAME_HELP)
ODOM_FRAME_OPTION = typer.Option(None, "--odom-frame", help=ODOM_FRAME_HELP)


def _bag_options(
    scan_topic: Optional[str], odom_topic: Optional[str], base_frame: Optional[str], odom_frame: Optional[str]
) -> dict[str, Optional[str]]:
    """The ROS bag options for load_log (None: not given)."""
    return {"scan_topic": scan_topic, "odom_topic": odom_topic, "base_frame": base_frame, "odom_frame": odom_frame}


@app.command()
@guarded
def slam(
    log: Path = typer.Argument(..., help=LOG_HELP),
    joint: Optional[Path] = typer.Option(
        None, "--joint", "-j", help="THOR joint .mat file (head angles, body roll/pitch)."
    ),
    out: Path = typer.Option(Path("out"), "--out", "-o", help="Output folder."),
    particles: Optional[int] = typer.Option(
        None, "--particles", "-n", help="Number of particles (default 100 for the single-map filter, 30 for rbpf)."
    ),
    seed: Optional[int] = typer.Option(None, "--seed", help="Random seed (default 0)."),
    every: Optional[int] = typer.Option(None, "--every", help="Process every k-th scan (default 1: all)."),
    config: Optional[Path] = typer.Option(None, "--config", "-c", help=CONFIG_HELP),
    filter_: Optional[str] = typer.Option(None, "--filter", help=FILTER_HELP),
    backend: Optional[str] = typer.Option(None, "--backend", help=BACKEND_HELP),
    search: Optional[bool] = typer.Option(
        None, "--search/--no-search", help="Local x/y/theta search grid around each particle (default: off)."
    ),
    estimate: Optional[str] = typer.Option(None, "--estimate", help="Pose estimate: mean (weighted, default) or best."),
    ground_truth: Optional[Path] = typer.Option(
        None, "--ground-truth", "-g", help="TUM ground truth to score against."
    ),
    odometry: str = typer.Option("log", "--odometry", help=ODOMETRY_HELP),
    wheel_scale: float = typer.Option(
        1.0, "--wheel-scale", help="Calibration factor on wheel travel from encoder counts (Mines logs)."
    ),
    score: Optional[str] = typer.Option(
        None, "--score", help="Scoring map: auto (default), field (smoothed walls) or cells (raw log-odds)."
    ),
    calibrate: Optional[bool] = typer.Option(
        None,
        "--calibrate/--no-calibrate",
        show_default=False,
        help="Measure the odometry's scale and the scan latency from the scans (see `pfslam calibrate`) and "
        "correct the odometry before the SLAM. Default: on for wheel-encoder logs (Mines) unless "
        "--wheel-scale or --scan-latency is given, off for logs whose odometry is a pose.",
    ),
    scan_latency: float = typer.Option(
        0.0,
        "--scan-latency",
        help="Scans were taken this many seconds before their time stamps: the "
        "odometry is read at t - S (applied before --calibrate's own estimate).",
    ),
    video: Optional[Path] = VIDEO_OPTION,
    video_fps: Optional[float] = VIDEO_FPS_OPTION,
    rerun: bool = RERUN_OPTION,
    rerun_save: Optional[Path] = RERUN_SAVE_OPTION,
    scan_topic: Optional[str] = SCAN_TOPIC_OPTION,
    odom_topic: Optional[str] = ODOM_TOPIC_OPTION,
    base_frame: Optional[str] = BASE_FRAME_OPTION,
    odom_frame: Optional[str] = ODOM_FRAME_OPTION,
) -> None:
    """Build a map and a trajectory from a log (THOR .mat, CARMEN, Mines .dat, ROS bag; detected from the file).

    Writes map.pgm/.yaml/.png, trajectory.tum, odometry.tum, config.yaml, run.json (and reference.tum)."""
    from pfslam import pipeline
    from pfslam.config import SlamConfig

    cfg = pipeline.settings(
        SlamConfig,
        config,
        {
            "particles": particles,
            "seed": seed,
            "every": every,
            "local_search.enabled": search,
            "estimate": estimate,
            "sensor.scoring_map": score,
            "filter": filter_,
            "backend": backend,
        },
    )
    views = _views(video, video_fps, rerun, rerun_save)
    outcome = pipeline.slam(
        log,
        out,
        joint=joint,
        config=cfg,
        config_file=config,
        odometry=odometry,
        wheel_scale=wheel_scale,
        calibrate=calibrate,
        scan_latency=scan_latency,
        ground_truth=ground_truth,
        views=views,
        reporter=_Printer(),
        **_bag_options(scan_topic, odom_topic, base_frame, odom_frame),
    )
    _report(outcome)


@app.command("calibrate")
@guarded
def calibrate_cmd(
    log: Path = typer.Argument(..., help="Log file (anything `pfslam slam` reads)."),
    joint: Optional[Path] = typer.Option(None, "--joint", "-j", help="THOR joint .mat file."),
    odometry: str = typer.Option("log", "--odometry", help="'log' or 'synthetic[:SEED]' (corrected CARMEN logs)."),
    wheel_scale: float = typer.Option(1.0, "--wheel-scale", help="Calibration factor already applied to wheel travel."),
    axle: float = typer.Option(0.33, "--axle", help="Distance between the wheels (m), wheel logs only."),
    config: Optional[Path] = typer.Option(None, "--config", "-c", help=CONFIG_HELP),
    scan_topic: Optional[str] = SCAN_TOPIC_OPTION,
    odom_topic: Optional[str] = ODOM_TOPIC_OPTION,
    base_frame: Optional[str] = BASE_FRAME_OPTION,
    odom_frame: Optional[str] = ODOM_FRAME_OPTION,
) -> None:
    """Measure the odometry's translation/rotation scale and the scan latency by matching
    consecutive scans (no ground truth needed). `pfslam slam --calibrate` applies them."""
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


@app.command()
@guarded
def localize(
    log: Path = typer.Argument(..., help="Log file (anything `pfslam slam` reads)."),
    map_yaml: Path = typer.Option(..., "--map", "-m", help="Map in the ROS map_server format (map.yaml)."),
    joint: Optional[Path] = typer.Option(None, "--joint", "-j", help="THOR joint .mat file."),
    initial_pose: Optional[str] = typer.Option(
        None,
        "--initial-pose",
        help="Start pose X,Y,THETA_DEG in the map frame (the frame map.yaml's origin is "
        "given in). Default: for a map `pfslam slam` wrote (its run.json and "
        "trajectory.tum beside it), where that run started (the first pose of its "
        "trajectory.tum; a line says so); for any other map 0,0,0.",
    ),
    initial_std: Optional[str] = typer.Option(
        None,
        "--initial-std",
        help="Spread (standard deviations) of the start: SX,SY,STHETA_DEG, metres and degrees "
        "(default: the config's initial_std_x/y/theta, in radians there; 0.1,0.1,5).",
    ),
    global_: bool = typer.Option(False, "--global", help="Unknown start: particles uniform over free space."),
    config: Optional[Path] = typer.Option(None, "--config", "-c", help=CONFIG_HELP),
    particles: Optional[int] = typer.Option(None, "--particles", "-n", help="Particles (initial; KLD adapts it)."),
    max_particles: Optional[int] = typer.Option(None, "--max-particles", help="KLD upper bound (default 5000)."),
    no_kld: bool = typer.Option(False, "--no-kld", help="Fixed particle count."),
    no_recovery: bool = typer.Option(False, "--no-recovery", help="No random particles when lost."),
    model: Optional[str] = typer.Option(None, "--model", help="Sensor model: likelihood_field (default) or beam."),
    seed: Optional[int] = typer.Option(None, "--seed", help="Random seed (default 0)."),
    odometry: str = typer.Option("log", "--odometry", help="'log' or 'synthetic[:SEED]' (corrected CARMEN logs)."),
    wheel_scale: float = typer.Option(1.0, "--wheel-scale", help="Calibration factor on wheel travel (Mines logs)."),
    calibrate: bool = typer.Option(
        False,
        "--calibrate",
        help="Correct the odometry's scale and the scan latency measured from the scans (see `pfslam calibrate`).",
    ),
    scan_latency: float = typer.Option(0.0, "--scan-latency", help="Read the odometry at t - S (s)."),
    ground_truth: Optional[Path] = typer.Option(
        None, "--ground-truth", "-g", help="TUM ground truth to score against."
    ),
    out: Path = typer.Option(Path("out_localize"), "--out", "-o", help="Output folder."),
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

    Writes trajectory.tum, odometry.tum, covariance.csv (the estimate's covariance at each
    update), localization.png, config.yaml, run.json."""
    from pfslam import pipeline
    from pfslam.config import LocalizerConfig, with_particle_counts

    spread: dict[str, Any] = {}
    if initial_std is not None:  # degrees on the command line, radians in the config (as in ROS)
        std = _parse_triple(initial_std, "--initial-std", "SX,SY,STHETA_DEG")
        if min(std) < 0:
            raise InputError("--initial-std", f"spreads must not be negative, got {initial_std!r}")
        spread = {"initial_std_x": std[0], "initial_std_y": std[1], "initial_std_theta": float(np.deg2rad(std[2]))}
    views = _views(video, video_fps, rerun, rerun_save)
    base = pipeline.settings(
        LocalizerConfig,
        config,
        {
            "seed": seed,
            "model": model,
            "recovery": False if no_recovery else None,
            "kld": False if no_kld else None,
            **spread,
        },
    )
    cfg = with_particle_counts(base, particles, max_particles)
    pose = _parse_triple(initial_pose, "--initial-pose") if initial_pose and not global_ else None
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
        calibrate=calibrate,
        scan_latency=scan_latency,
        ground_truth=ground_truth,
        views=views,
        reporter=_Printer(),
        **_bag_options(scan_topic, odom_topic, base_frame, odom_frame),
    )
    _report(outcome)


@app.command()
@guarded
def convert(
    log: Path = typer.Argument(..., help="Input log (anything `pfslam slam` reads)."),
    out: Path = typer.Argument(
        ...,
        help="Output: a .bag (ROS 1), .mcap (MCAP), .log/.log.gz (CARMEN) or a "
        "name without a suffix (a ROS 2 bag folder, sqlite3).",
    ),
    to: Optional[str] = typer.Option(
        None, "--to", help="Output format: ros1, ros2, mcap or carmen (default: from OUT's name)."
    ),
    force: bool = typer.Option(False, "--force", help="Replace OUT if it exists."),
    joint: Optional[Path] = typer.Option(None, "--joint", "-j", help="THOR joint .mat file."),
    odometry: str = typer.Option(
        "log",
        "--odometry",
        help="'log', or 'synthetic[:SEED]' for corrected CARMEN logs: "
        "the drifting odometry made from their poses is written.",
    ),
    wheel_scale: float = typer.Option(1.0, "--wheel-scale", help="Calibration factor on wheel travel (Mines logs)."),
    scan_topic: Optional[str] = SCAN_TOPIC_OPTION,
    odom_topic: Optional[str] = ODOM_TOPIC_OPTION,
    base_frame: Optional[str] = BASE_FRAME_OPTION,
    odom_frame: Optional[str] = ODOM_FRAME_OPTION,
) -> None:
    """Write a log as a ROS bag (/scan LaserScan in frame laser, /odom Odometry odom -> base_link,
    /tf_static base_link -> laser; /tf too when the mount moves) or a CARMEN log (FLASER lines)."""
    from pfslam.tools.convert import convert as run_convert

    res = run_convert(
        log,
        out,
        to=to,
        force=force,
        joint=joint,
        odometry=odometry,
        wheel_scale=wheel_scale,
        **_bag_options(scan_topic, odom_topic, base_frame, odom_frame),
    )
    for w in res.warnings:
        _warn(w)
    out_console.print(
        escape(
            f"wrote {res.scans} scans of {log} ({res.source_format}, odometry {res.odometry}) "
            f"to {res.path} ({res.description})"
        ),
        soft_wrap=True,
    )


@app.command()
@guarded
def simulate(
    out: Path = typer.Option(..., "--out", "-o", help="Output folder for the THOR-format log and ground truth."),
    world: str = typer.Option("office", "--world", "-w", help="World: office or corridor."),
    duration: float = typer.Option(180.0, "--duration", help="Seconds of log to simulate."),
    seed: int = typer.Option(0, "--seed", help="Random seed."),
    layout: str = typer.Option("penn", "--layout", help="Odometry field: penn (pose) or ucsd (delta_pose)."),
    head_pitch_deg: Optional[float] = typer.Option(
        None, "--head-pitch-deg", help="Hold the head at this pitch (positive = down) instead of moving it."
    ),
    no_drift: bool = typer.Option(False, "--no-drift", help="Odometry without scale error and heading bias."),
    gait: str = typer.Option(
        "calm",
        "--gait",
        help="calm (the demo's walk) or rough: 6 cm sway, corners turned in "
        "place with the head pitched to the floor, the head nodding "
        "10-45 deg down, odometry drifting 0.8 deg/m.",
    ),
) -> None:
    """Simulate a THOR humanoid log (lidar + joint .mat, groundtruth.tum, the true map.yaml) in a built-in world."""
    from pfslam.errors import ConfigError
    from pfslam.tools.simulate import simulate as sim

    if head_pitch_deg is not None and not abs(head_pitch_deg) <= 90.0:
        raise ConfigError(f"--head-pitch-deg must be a number of degrees within +-90, not {head_pitch_deg}")
    pitch = None if head_pitch_deg is None else float(np.deg2rad(head_pitch_deg))
    from pfslam.io.common import prepare_output_dir

    prepare_output_dir(out)
    res = sim(
        world=world,
        duration_s=duration,
        seed=seed,
        out_dir=out,
        layout=layout,
        head_pitch=pitch,
        drift=not no_drift,
        gait=gait,
    )
    out_console.print(
        escape(
            f"wrote {res.lidar_path}, {res.joint_path}, {res.groundtruth_path} and the true "
            f"map {Path(res.lidar_path).parent / 'map.yaml'}"
        ),
        soft_wrap=True,
    )


@app.command()
@guarded
def demo(
    out: Path = typer.Option(Path("demo_out"), "--out", "-o", help="Output folder."),
    duration: float = typer.Option(180.0, "--duration", help="Seconds of simulated log."),
    seed: int = typer.Option(0, "--seed", help="Random seed."),
    every: int = typer.Option(1, "--every", help="Process every k-th scan (default 1: all)."),
    search: bool = typer.Option(
        False, "--search/--no-search", help="Local x/y/theta search grid around each particle (default: off)."
    ),
    filter_: Optional[str] = typer.Option(None, "--filter", help=FILTER_HELP),
    backend: Optional[str] = typer.Option(None, "--backend", help=BACKEND_HELP),
    video: Optional[Path] = VIDEO_OPTION,
    video_fps: Optional[float] = VIDEO_FPS_OPTION,
    rerun: bool = RERUN_OPTION,
    rerun_save: Optional[Path] = RERUN_SAVE_OPTION,
) -> None:
    """Simulate a THOR office loop, run SLAM on it, and score SLAM and odometry against ground truth."""
    from pfslam import pipeline
    from pfslam.config import SlamConfig

    cfg = pipeline.settings(
        SlamConfig,
        None,
        {"seed": seed, "every": every, "local_search.enabled": search, "filter": filter_, "backend": backend},
    )
    views = _views(video, video_fps, rerun, rerun_save)
    outcome = pipeline.demo(out, duration=duration, seed=seed, config=cfg, views=views, reporter=_Printer())
    _report(outcome)
    rows = outcome.scores.errors
    if rows:
        out_console.print(
            escape(
                f"ATE SLAM {rows['SLAM'].ate_rmse:.3f} m, odometry "
                f"{rows['odometry'].ate_rmse:.3f} m; map: {outcome.out / 'map.png'}"
            ),
            soft_wrap=True,
        )


@app.command()
@guarded
def evaluate(
    estimate: Path = typer.Argument(..., help="Estimated trajectory (TUM)."),
    reference: Optional[Path] = typer.Argument(None, help="Reference trajectory (TUM)."),
    reference_opt: Optional[Path] = typer.Option(None, "--reference", "-r", help="Reference trajectory (TUM)."),
    relations: Optional[Path] = typer.Option(
        None, "--relations", help="SLAM-benchmark relations file (t1 t2 x y z roll pitch yaw)."
    ),
    time_offset: float = typer.Option(
        0.0, "--time-offset", help="Subtracted from the relation time stamps to reach the estimate's clock (s)."
    ),
    max_dt: float = typer.Option(0.02, "--max-dt", help="Largest time difference for matching poses (s)."),
    rpe_delta: int = typer.Option(10, "--rpe-delta", help="RPE over this many poses."),
    plot: Optional[Path] = typer.Option(
        None,
        "--plot",
        help="Folder for evo-style pictures against the reference: trajectory_error.png (the "
        "aligned estimate coloured by its error) and error_over_time.png.",
    ),
) -> None:
    """ATE (raw and SE(2)-aligned) and RPE against a reference, and/or the relations metric."""
    from pfslam.eval.metrics import (
        pose_errors,
        read_relations,
        relation_errors,
        trajectory_errors,
    )
    from pfslam.io.trajectory import read_tum

    if reference is not None and reference_opt is not None:
        raise InputError(reference_opt, "give the reference once: as the second argument or with --reference")
    ref = reference or reference_opt
    if ref is None and relations is None:
        raise InputError(estimate, "give a reference trajectory (second argument or --reference) or --relations")
    if plot is not None:
        if ref is None:
            raise InputError(plot, "--plot draws the errors against a reference trajectory: give one")
        from pfslam.io.common import prepare_output_dir

        prepare_output_dir(plot)
    t_est, est = read_tum(estimate)
    if ref is not None:
        t_ref, ref_poses = read_tum(ref)
        try:
            e = trajectory_errors(t_est, est, t_ref, ref_poses, max_dt=max_dt, rpe_delta=rpe_delta)
        except ValueError as ex:
            raise InputError(estimate, str(ex)) from None
        files = []
        if plot is not None:
            from pfslam.views.figures import plot_errors

            files = plot_errors(pose_errors(t_est, est, t_ref, ref_poses, max_dt), plot, name=estimate.name)
        if e.rpe_delta < rpe_delta:
            _warn(
                f"--rpe-delta {rpe_delta} is more than the {e.matched - 1} steps between the {e.matched} matched "
                f"poses: the RPE is over {e.rpe_delta} poses"
            )
        out_console.print(_errors_table({estimate.name: e}))
        out_console.print(f"matched poses: {e.matched}")
        if files:
            out_console.print(f"pictures: {', '.join(str(f) for f in files)}", soft_wrap=True)
    if relations is not None:
        r = relation_errors(t_est, est, read_relations(relations), time_offset=time_offset, max_dt=max_dt)
        why = (
            f"{r.unmatched} with an end not within {max_dt:g} s of an estimated pose, "
            f"{r.same_pose} with both ends on the same pose"
        )
        if r.matched == 0:
            raise InputError(
                relations,
                f"no relation has its two ends on two estimated poses within {max_dt:g} s "
                f"(check --time-offset; {r.skipped} skipped: {why})",
            )
        out_console.print(
            f"relations: {r.matched} matched, {r.skipped} skipped ({why}); translation {r.trans_mean:.4f} ± "
            f"{r.trans_std:.4f} m, rotation {r.rot_mean_deg:.3f} ± {r.rot_std_deg:.3f} deg",
            soft_wrap=True,
        )


@app.command()
@guarded
def sweep(
    spec: Path = typer.Argument(..., help="Sweep spec (YAML): logs, seeds and settings (see the README, 'Sweeps')."),
    out: Path = typer.Option(..., "--out", "-o", help="Output folder: runs/, results.csv/.parquet, summary.png."),
    workers: Optional[int] = typer.Option(
        None, "--workers", "-w", help="Worker processes of the local Dask cluster (default: one per CPU)."
    ),
    scheduler: Optional[str] = typer.Option(
        None,
        "--scheduler",
        help="Run on an existing Dask cluster: its scheduler's address (tcp://HOST:PORT) or "
        "scheduler file. Its workers must see the logs and OUT at the same paths.",
    ),
    timeout: Optional[float] = typer.Option(None, "--timeout", help="Kill a run after this many seconds (timeout)."),
    retry_failed: bool = typer.Option(
        False, "--retry-failed", help="Run again the runs of OUT that ended in error, killed or timeout."
    ),
) -> None:
    """Run `pfslam slam` over every log × setting combination × seed of a spec, in parallel on Dask.

    Each run is the real `pfslam slam` in its own subprocess, writing into OUT/runs/LOG/SETTINGS/seedK/;
    runs already done in OUT are skipped. Writes OUT/results.csv and results.parquet (one row per
    run), prints a summary (median and min-max over the seeds) and plots it (OUT/summary.png).
    Exit code 1 if some run failed (error, killed, timeout), 130 after Ctrl-C (the finished runs kept)."""
    from pfslam.config import check_int, check_number
    from pfslam.sweep import run as sweep_run
    from pfslam.sweep.runner import cpu_count
    from pfslam.sweep.spec import settings_text

    if workers is not None:
        check_int("--workers", workers, 1)
    if timeout is not None:
        check_number("--timeout", timeout, gt=0.0, what="a finite number of seconds")
    if workers is not None and scheduler is not None:
        _warn("--workers is ignored with --scheduler: the cluster has its own workers")
    plan = sweep_run.plan(spec, out, timeout, retry_failed)
    grid, jobs, keys = plan.spec, plan.jobs, plan.keys
    where = f"the Dask cluster at {scheduler}" if scheduler else f"{workers or cpu_count()} local workers"
    err_console.print(
        escape(
            f"{len(jobs)} runs ({len(grid.logs)} log(s) x {len(grid.combinations())} setting combination(s) x "
            f"{len(grid.seeds)} seed(s)): {len(plan.rows)} done already, {len(plan.todo)} to run"
            f"{' on ' + where if plan.todo else ''}"
        ),
        highlight=False,
        soft_wrap=True,
    )

    def describe(row: dict[str, Any]) -> str:
        text = f"{row['log']} {settings_text(row['settings'])} seed {row['seed']}: {row['status']}"
        if row["status"] != "ok":
            return f"{text} ({row['message']}); see {out / row['run_dir']}/stderr.txt"
        ate = f", ATE aligned {row['ate_aligned']:.3f} m" if row.get("ate_aligned") is not None else ""
        return f"{text}{ate} ({row['seconds']:.1f} s)"

    prog = Progress(
        TextColumn("[bold]sweep"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[failed]} failed"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=err_console,
        disable=not err_console.is_terminal and "PFSLAM_PROGRESS" not in os.environ or not plan.todo,
        speed_estimate_period=7 * 86400.0,  # the ETA from every run of this sweep, not the last 30 s
    )
    failed = sum(r["status"] != "ok" for r in plan.rows.values())
    with prog:
        task = prog.add_task("sweep", total=len(jobs), completed=len(plan.rows), failed=failed)

        def on_result(row: dict[str, Any]) -> None:
            nonlocal failed
            failed += row["status"] != "ok"
            prog.update(task, completed=len(plan.rows), failed=failed)
            line = f"[{len(plan.rows)}/{len(jobs)}] {describe(row)}"
            if row["status"] != "ok":
                prog.console.print(f"[yellow]warning:[/] {escape(line)}", highlight=False, soft_wrap=True)
            elif prog.disable:
                prog.console.print(escape(line), highlight=False, soft_wrap=True)

        res = sweep_run.run(plan, workers, scheduler, on_result)
    _received.extend(res.signals)
    table, summary, csv, parquet, png = res.table, res.summary, res.csv, res.parquet, res.png

    def span(rec: Any, m: str, digits: int) -> str:
        med, lo, hi = rec[f"{m}_median"], rec[f"{m}_min"], rec[f"{m}_max"]
        if not np.isfinite(med):
            return "–"
        return f"{med:.{digits}f}" if lo == hi else f"{med:.{digits}f}\n[dim]{lo:.{digits}f}–{hi:.{digits}f}[/]"

    if len(summary):
        tab = Table(
            show_header=True,
            header_style="bold",
            title="median (min–max) over the seeds' ok runs",
            title_justify="left",
        )
        columns = [
            ("ATE aligned (m)", "ate_aligned", 3),
            ("ATE raw (m)", "ate_raw", 3),
            ("relations trans (m)", "relations_trans", 3),
            ("relations rot (deg)", "relations_rot_deg", 2),
            ("map agreement", "map_agreement", 3),
            ("scans/s", "scans_per_s", 0),
        ]
        columns = [c for c in columns if summary[f"{c[1]}_median"].notna().any()]
        tab.add_column("log")
        if keys:
            tab.add_column("settings")
        tab.add_column("ok / runs", justify="right")
        for name, _, _ in columns:
            tab.add_column(name, justify="right")
        for _, rec in summary.iterrows():
            cells = [escape(str(rec["log"]))]
            if keys:  # one key=value a line
                cells.append(escape("\n".join(settings_text({k: rec[k]}) for k in keys)))
            cells.append(
                f"{rec['ok']} / {rec['runs']}" if not rec["failed"] else f"[red]{rec['ok']}[/] / {rec['runs']}"
            )
            tab.add_row(*cells, *[span(rec, m, d) for _, m, d in columns])
        # Piped into a file or a CI log the table keeps its width rather than wrapping to 80 columns.
        wide = out_console if out_console.is_terminal else Console(width=max(out_console.width, 160))
        wide.print(tab)
    bad = res.failed
    earlier = bad[~bad["run_dir"].isin(res.reported)]  # the failures of this sweep were reported as they came
    for _, rec in earlier.head(10).iterrows():
        _warn(
            f"{rec['run_dir']}: {rec['status']} (in an earlier sweep; --retry-failed runs it again): {rec['message']}"
        )
    if len(earlier) > 10:
        _warn(f"... and {len(earlier) - 10} more runs failed in an earlier sweep (column 'status' of {csv})")
    pictures = f", {png}" if png is not None else ""
    out_console.print(
        escape(
            f"{len(table)} runs in the table ({len(table) - len(bad)} ok, {len(bad)} failed): "
            f"{csv}, {parquet}{pictures}"
        ),
        soft_wrap=True,
    )
    if res.interrupted:
        err_console.print(
            f"[yellow]interrupted:[/] {len(table)} of {len(jobs)} runs done; the same command goes on from there",
            highlight=False,
            soft_wrap=True,
        )
        raise typer.Exit(130)
    if res.broken:
        _error(res.broken)
        raise typer.Exit(2)
    if len(bad):
        raise typer.Exit(1)


@app.command("dump-config")
@guarded
def dump_config_cmd(
    section: Optional[str] = typer.Argument(
        None, help="Print only this section (slam, localize or calibrate), without its heading."
    ),
) -> None:
    """Print the default configuration as YAML, every section (edit it and pass it with --config)."""
    from pfslam.config import SECTIONS, dump_config, dump_sections

    if section is None:
        text = dump_sections(*(cls() for cls in SECTIONS.values()))
    elif section in SECTIONS:
        text = dump_config(SECTIONS[section]())
    else:
        raise InputError("dump-config", f"unknown section {section!r} (one of {', '.join(SECTIONS)})")
    _Stdout().write(text)
    _Stdout().flush()


@app.command()
def version() -> None:
    """Print the pfslam version."""
    out_console.print(__version__)


def _stdout_failed(e: OSError) -> int:
    """Report a standard output that cannot be written; the exit code. A closed pipe is
    quiet (the reader has all it wanted: 141), anything else one line on stderr and 2."""
    try:  # what is still buffered goes nowhere, so the interpreter's last flush cannot fail again
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):
        pass
    if isinstance(e, BrokenPipeError):
        return EXIT_CLOSED_PIPE
    _error(f"standard output: {e.strerror or e}")
    return 2


def main() -> None:
    """The ``pfslam`` program: like ``app()``, but a usage error (unknown option, missing
    argument, a value of the wrong type) is one line on stderr rather than a framed box;
    SIGTERM stops a run like Ctrl-C (results kept) with exit code 143; a standard output
    that cannot be written is one line and exit code 2 (a closed pipe: a quiet exit, 141)."""
    try:  # recent Typer carries its own copy of Click (and raises its errors, even with click installed)
        from typer._click.exceptions import UsageError
    except ImportError:
        from click.exceptions import UsageError  # type: ignore[assignment]

    with contextlib.suppress(ValueError):  # ValueError: not the main thread (embedded): no handler
        signal.signal(signal.SIGTERM, _terminate)
    try:
        code = app(standalone_mode=False)
        sys.stdout.flush()
    except UsageError as e:
        where = e.ctx.command_path if e.ctx is not None else "pfslam"
        if e.format_message().strip():  # empty: no arguments at all, and the help was shown
            _error(f"{where}: {e.format_message()} (see '{where} --help')")
        code = 2
    except typer.Abort:  # Ctrl-C outside a command's own handling
        err_console.print("[yellow]interrupted[/]", highlight=False)
        code = EXIT_INTERRUPTED
    except _StdoutError as e:
        code = _stdout_failed(e.error)
    except OSError as e:  # outside the commands only Typer's own text (help) is written: to stdout
        if e.filename is not None:
            raise
        code = _stdout_failed(e)
    code = code if isinstance(code, int) else 0
    if code == EXIT_INTERRUPTED and signal.SIGTERM in _received:
        code = EXIT_TERMINATED
    sys.exit(code)


if __name__ == "__main__":  # pragma: no cover
    main()
