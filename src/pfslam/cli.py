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
from typer.core import TyperArgument, TyperCommand, TyperGroup, TyperOption

from pfslam import __version__
from pfslam.errors import InputError, PfslamError

# -- help: panels, each default stated once, value names instead of type tags ----------------

# The panels options are grouped in, in the order they appear in a command's signature.
INPUT = "Input"
OUTPUT = "Output"
FILTER = "Filter"
ODOMETRY = "Odometry"
VIEWS = "Views"
BAGS = "ROS bags"


def _help_option(option: Any, params: list[Any]) -> Any:
    """The --help option without a type tag, listed last in the Output panel (else the last
    panel of ``params``)."""
    if option is not None:
        option.metavar = ""
        named = [p.rich_help_panel for p in params if isinstance(p, TyperOption) and p.rich_help_panel]
        if named:
            option.rich_help_panel = OUTPUT if OUTPUT in named else named[-1]
    return option


class _Command(TyperCommand):
    """A command whose help states each default once, in the option's own text (Typer's
    "[default: ...]" is off: most defaults come from the config, where Typer only sees None),
    shows no type tag for a flag or an argument (an option's value is named by its metavar:
    FILE, N, S), and lists --help last in the Output panel."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        for p in self.params:
            if isinstance(p, TyperOption):
                p.show_default = False
                if p.is_flag:
                    p.metavar = ""
            elif isinstance(p, TyperArgument):  # (instance attributes: this argument's, not the class's)
                p.show_default = False
                setattr(p, "display_type_rich", lambda ctx: None)  # noqa: B010
                if p.hidden:  # an argument kept only to refuse it with a message: not in the usage line
                    setattr(p, "get_usage_pieces", lambda ctx: [])  # noqa: B010

    def get_help_option(self, ctx: Any) -> Any:
        return _help_option(super().get_help_option(ctx), self.params)


class _Group(TyperGroup):
    """The ``pfslam`` group: its --help without a type tag."""

    def get_help_option(self, ctx: Any) -> Any:
        return _help_option(super().get_help_option(ctx), self.params)


app = typer.Typer(
    cls=_Group,
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
    tab.add_column("trajectory", no_wrap=True, overflow="fold")  # a file name whole, never "trajectory.t..."
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


def _command(name: Optional[str] = None) -> Callable[[F], F]:
    """``@app.command`` with :class:`_Command`'s help."""
    return app.command(name, cls=_Command)


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
    from pfslam.io.common import missing_folders, remove_if_empty

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


WORLD = "World"


@_command()
@guarded
def simulate(
    out: Path = typer.Option(
        ...,
        "--out",
        "-o",
        metavar="DIR",
        rich_help_panel=OUTPUT,
        help="Output folder for the THOR-format log and the ground truth.",
    ),
    world: str = typer.Option(
        "office",
        "--world",
        "-w",
        metavar="NAME",
        rich_help_panel=WORLD,
        help="office (default), corridor, or a world that repeats itself to fool loop closing: pillars "
        "(a corridor ring with a pillar and a door every 3 m), rooms (six identical rooms in a row) or "
        "twins (two identical corridors walked the same way).",
    ),
    duration: float = typer.Option(
        180.0, "--duration", metavar="S", rich_help_panel=WORLD, help="Seconds of log (default 180)."
    ),
    seed: int = typer.Option(0, "--seed", metavar="N", rich_help_panel=WORLD, help=SEED_HELP),
    gait: str = typer.Option(
        "calm",
        "--gait",
        metavar="NAME",
        rich_help_panel=WORLD,
        help="calm (default: the demo's walk) or rough: 6 cm sway, corners turned in place with "
        "the head pitched to the floor, the head nodding 10-45 deg down, odometry drifting 0.8 deg/m.",
    ),
    head_pitch_deg: Optional[float] = typer.Option(
        None,
        "--head-pitch-deg",
        metavar="DEG",
        rich_help_panel=WORLD,
        help="Hold the head at this pitch (positive = down) instead of moving it.",
    ),
    no_drift: bool = typer.Option(
        False, "--no-drift", rich_help_panel=WORLD, help="Odometry without scale error and heading bias."
    ),
    layout: str = typer.Option(
        "penn",
        "--layout",
        metavar="NAME",
        rich_help_panel=OUTPUT,
        help="Odometry field: penn (default: pose) or ucsd (delta_pose).",
    ),
) -> None:
    """Simulate a THOR humanoid log in a built-in world.

    Writes the lidar and joint .mat files, groundtruth.tum and the true map.yaml into OUT."""
    from pfslam.errors import ConfigError
    from pfslam.tools.simulate import simulate as sim

    if head_pitch_deg is not None and not abs(head_pitch_deg) <= 90.0:
        raise ConfigError(f"--head-pitch-deg must be a number of degrees within +-90, not {head_pitch_deg}")
    pitch = None if head_pitch_deg is None else float(np.deg2rad(head_pitch_deg))
    from pfslam.io.common import prepare_output_dir
    from pfslam.io.logs import MAX_SCANS_ENV, scan_limit
    from pfslam.pipeline import DEMO_RATE_HZ

    limit = scan_limit()
    if limit is not None and duration > limit / DEMO_RATE_HZ:  # no run would read the rest
        duration = limit / DEMO_RATE_HZ
        _warn(f"{MAX_SCANS_ENV}={limit} is set: simulating {duration:g} s ({limit} scans)")
    with _cleaned_up(out):
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


@_command()
@guarded
def demo(
    out: Path = typer.Option(
        Path("demo_out"), "--out", "-o", metavar="DIR", rich_help_panel=OUTPUT, help="Output folder (default demo_out)."
    ),
    duration: float = typer.Option(
        180.0, "--duration", metavar="S", rich_help_panel=WORLD, help="Seconds of simulated log (default 180)."
    ),
    seed: int = typer.Option(
        0, "--seed", metavar="N", rich_help_panel=WORLD, help="Random seed of the log and the filter (default 0)."
    ),
    filter_: Optional[str] = typer.Option(None, "--filter", metavar="NAME", rich_help_panel=FILTER, help=FILTER_HELP),
    every: int = typer.Option(
        1, "--every", metavar="K", rich_help_panel=FILTER, help="Process every K-th scan (default 1: all)."
    ),
    backend: Optional[str] = typer.Option(None, "--backend", metavar="NAME", rich_help_panel=FILTER, help=BACKEND_HELP),
    search: bool = typer.Option(
        False,
        "--search/--no-search",
        rich_help_panel=FILTER,
        help="Local x/y/theta search per particle: single (default off).",
    ),
    video: Optional[Path] = VIDEO_OPTION,
    video_fps: Optional[float] = VIDEO_FPS_OPTION,
    rerun: bool = RERUN_OPTION,
    rerun_save: Optional[Path] = RERUN_SAVE_OPTION,
) -> None:
    """Simulate a THOR office loop, run SLAM on it, and score SLAM and odometry against ground truth."""
    from pfslam import pipeline
    from pfslam.config import SlamConfig

    cfg = _settings(
        SlamConfig,
        None,
        {
            "seed": ("--seed", seed),
            "every": ("--every", every),
            "local_search.enabled": ("--search", search),
            "filter": ("--filter", filter_),
            "backend": ("--backend", backend),
        },
    )
    views = _views(video, video_fps, rerun, rerun_save)
    with _cleaned_up(out):
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


MATCHING = "Matching"


@_command()
@guarded
def evaluate(
    estimate: Path = typer.Argument(..., metavar="EST", help="Estimated trajectory (TUM)."),
    stray: Optional[Path] = typer.Argument(None, hidden=True),  # a second argument: refused, see below
    reference: Optional[Path] = typer.Option(
        None,
        "--reference",
        "-r",
        metavar="REF",
        rich_help_panel=INPUT,
        help="Reference trajectory (TUM): ATE (raw and SE(2)-aligned) and RPE against it.",
    ),
    relations: Optional[Path] = typer.Option(
        None,
        "--relations",
        metavar="FILE",
        rich_help_panel=INPUT,
        help="SLAM-benchmark relations file (t1 t2 x y z roll pitch yaw), with or without REF.",
    ),
    time_offset: float = typer.Option(
        0.0,
        "--time-offset",
        metavar="S",
        rich_help_panel=INPUT,
        help="Subtracted from the relations' time stamps to reach the estimate's clock (default 0).",
    ),
    max_dt: float = typer.Option(
        0.02,
        "--max-dt",
        metavar="S",
        rich_help_panel=MATCHING,
        help="Largest time difference of two poses paired (default 0.02).",
    ),
    rpe_delta: int = typer.Option(
        10, "--rpe-delta", metavar="N", rich_help_panel=MATCHING, help="RPE over N poses (default 10)."
    ),
    plot: Optional[Path] = typer.Option(
        None,
        "--plot",
        metavar="DIR",
        rich_help_panel=OUTPUT,
        help="Folder for evo-style pictures against REF: trajectory_error.png (the aligned estimate "
        "coloured by its error) and error_over_time.png.",
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

    if stray is not None:
        raise InputError(stray, "give the reference with --reference: pfslam evaluate EST --reference REF")
    ref = reference
    if ref is None and relations is None:
        raise InputError(estimate, "give a reference trajectory (--reference) or --relations")
    if plot is not None and ref is None:
        raise InputError(plot, "--plot draws the errors against a reference trajectory: give one")
    with _cleaned_up(plot):
        if plot is not None:
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

                files = plot_errors(
                    pose_errors(t_est, est, t_ref, ref_poses, max_dt), plot, name=str(estimate), reference=str(ref)
                )
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


RUNS = "Runs"


@_command()
@guarded
def sweep(
    spec: Path = typer.Argument(
        ..., metavar="SPEC", help="Sweep spec (YAML): logs, seeds and settings (see the README, 'Sweeps')."
    ),
    out: Path = typer.Option(
        ...,
        "--out",
        "-o",
        metavar="DIR",
        rich_help_panel=OUTPUT,
        help="Output folder: runs/, results.csv/.parquet, summary.png.",
    ),
    workers: Optional[int] = typer.Option(
        None,
        "--workers",
        "-w",
        metavar="N",
        rich_help_panel=RUNS,
        help="Worker processes of the local Dask cluster (default: one per CPU).",
    ),
    scheduler: Optional[str] = typer.Option(
        None,
        "--scheduler",
        metavar="ADDRESS",
        rich_help_panel=RUNS,
        help="Run on an existing Dask cluster: its scheduler's address (tcp://HOST:PORT) or "
        "scheduler file. Its workers must see the logs and OUT at the same paths.",
    ),
    timeout: Optional[float] = typer.Option(
        None, "--timeout", metavar="S", rich_help_panel=RUNS, help="Kill a run after S seconds (status timeout)."
    ),
    retry_failed: bool = typer.Option(
        False,
        "--retry-failed",
        rich_help_panel=RUNS,
        help="Run again the runs of OUT that ended in error, killed or timeout.",
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
    with _cleaned_up(out):
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


@_command("dump-config")
@guarded
def dump_config_cmd(
    section: Optional[str] = typer.Argument(
        None, metavar="SECTION", help="Print only this section (slam, localize or calibrate), without its heading."
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


@_command()
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
