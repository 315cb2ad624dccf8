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
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from rich.table import Table

from pfslam import __version__
from pfslam.errors import PfslamError

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Particle-filter SLAM and Monte Carlo localization for 2D lidar logs.",
    pretty_exceptions_enable=False,
)
out_console = Console()
err_console = Console(stderr=True)

F = TypeVar("F", bound=Callable[..., Any])


def _error(text: str) -> None:
    """One line on stderr; ``text`` is printed as is (file names may hold [brackets])."""
    err_console.print(f"[bold red]error:[/] {escape(text)}", highlight=False, soft_wrap=True)


def _warn(text: str) -> None:
    err_console.print(f"[yellow]warning:[/] {escape(text)}", highlight=False, soft_wrap=True)


def guarded(fn: F) -> F:
    """Turn pfslam's own errors into one line on stderr and exit code 2."""

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
            raise typer.Exit(130) from None

    return wrapper  # type: ignore[return-value]


def _progress() -> Progress:
    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]:>7.1f} scans/s"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=err_console,
        transient=False,
        disable=not err_console.is_terminal and "PFSLAM_PROGRESS" not in __import__("os").environ,
    )


def _load_config(config: Optional[Path], particles: Optional[int], seed: Optional[int], every: Optional[int],
                 search: Optional[bool] = None, estimate: Optional[str] = None,
                 score: Optional[str] = None):  # noqa: ANN202
    from pfslam.config import SlamConfig, load_config
    from pfslam.errors import ConfigError, InputError

    cfg = SlamConfig()
    if config is not None:
        cfg = load_config(config)
        try:
            cfg.validate()
        except ConfigError as e:  # a bad value in the file: name the file
            raise InputError(config, str(e)) from None
    if particles is not None:
        cfg.particles = particles
    if seed is not None:
        cfg.seed = seed
    if every is not None:
        cfg.every = every
    if search is not None:
        cfg.search.enabled = search
    if estimate is not None:
        cfg.estimate = estimate
    if score is not None:
        cfg.sensor.score = score
    return cfg.validate()  # the options' values


def _run_with_progress(frames: list, cfg: Any, label: str):  # noqa: ANN202
    from pfslam.pipeline import run_slam

    n = len(frames[:: cfg.every])
    t0 = time.perf_counter()
    with _progress() as prog:
        task = prog.add_task(label, total=n, rate=0.0)

        def cb(i: int, total: int) -> None:
            dt = time.perf_counter() - t0
            prog.update(task, completed=i, rate=i / dt if dt > 0 else 0.0)

        return run_slam(frames, cfg, cb)


def _errors_table(rows: dict[str, Any]) -> Table:
    tab = Table(show_header=True, header_style="bold")
    tab.add_column("trajectory")
    tab.add_column("ATE RMSE (m)", justify="right")
    tab.add_column("ATE aligned (m)", justify="right")
    tab.add_column("heading RMSE (deg)", justify="right")
    tab.add_column("RPE trans (m)", justify="right")
    for name, e in rows.items():
        tab.add_row(name, f"{e.ate_rmse:.3f}", f"{e.ate_rmse_aligned:.3f}", f"{e.heading_rmse_deg:.2f}",
                    f"{e.rpe_trans_rmse:.4f}")
    return tab


def _prepare_out(out: Path) -> None:
    """Create the output folder before a long run, so an unwritable one fails at once."""
    from pfslam.errors import InputError

    if out.exists() and not out.is_dir():
        raise InputError(out, "the output folder exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(out, f"cannot create the output folder ({e.strerror or e})") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError(out, "the output folder is not writable")


def _require_returns(log: Path, frames: list) -> None:
    from pfslam.errors import InputError
    from pfslam.pipeline import any_valid_return

    if not any_valid_return(frames):
        raise InputError(log, f"none of its {len(frames)} scans has a valid return (every range is NaN, "
                              "inf or outside the sensor's range)")


def _score(run: Any, truth: Any, source: object, names: tuple[str, str] = ("SLAM", "odometry")) -> Any:
    """ATE/RPE of the estimate and of the odometry against ``truth``, printed and kept in
    ``run.metrics``; a warning (not an error) when they cannot be matched in time."""
    from pfslam.evaluate import trajectory_errors

    if truth is None or run.scans < 2:
        return None
    try:
        rows = {names[0]: trajectory_errors(run.t, run.poses, *truth),
                names[1]: trajectory_errors(run.t, run.odometry, *truth)}
    except ValueError as e:  # e.g. no time stamps in common with the ground truth
        _warn(f"{source}: not scored ({e})")
        return None
    run.metrics = {k: v.as_dict() for k, v in rows.items()}
    out_console.print(_errors_table(rows))
    return rows


@contextlib.contextmanager
def _scoring(run: Any) -> Iterator[None]:
    """The optional scoring after a run: Ctrl-C skips the rest of it and keeps the results."""
    try:
        yield
    except KeyboardInterrupt:
        run.interrupted = True


@contextlib.contextmanager
def _interrupts_held() -> Iterator[list[int]]:
    """Ctrl-C while the results are written is noted (the list fills), not acted on at once."""
    got: list[int] = []
    try:
        old = signal.signal(signal.SIGINT, lambda sig, frame: got.append(sig))
    except ValueError:  # not the main thread: nothing to hold
        yield got
        return
    try:
        yield got
    finally:
        signal.signal(signal.SIGINT, old)


def _write_and_report(run: Any, out: Path, log: object, write: Callable[[], Any], summary: str) -> None:
    """Write the results (also of a run stopped early), then say how it ended."""
    if run.scans == 0 and run.error is not None:
        raise PfslamError(f"{log}: {run.error}")
    if run.scans == 0 and run.interrupted:
        raise KeyboardInterrupt
    with _interrupts_held() as got:
        write()
    run.interrupted = run.interrupted or bool(got)
    if run.error is not None:
        _error(f"{log}: {run.error}; the results for the {run.scans} scans before it are in {out}/")
        raise typer.Exit(2)
    if run.interrupted:
        err_console.print(f"[yellow]interrupted:[/] results for the {run.scans} scans done are in "
                          f"{escape(str(out))}/", highlight=False, soft_wrap=True)
        raise typer.Exit(130)
    out_console.print(escape(summary), soft_wrap=True)


@app.command()
@guarded
def slam(
    log: Path = typer.Argument(..., help="Log file: THOR lidar .mat, CARMEN log (.log/.gz), Mines .dat."),
    joint: Optional[Path] = typer.Option(None, "--joint", "-j", help="THOR joint .mat file (head angles, body roll/pitch)."),
    out: Path = typer.Option(Path("out"), "--out", "-o", help="Output folder."),
    particles: Optional[int] = typer.Option(None, "--particles", "-n", help="Number of particles (default 100)."),
    seed: Optional[int] = typer.Option(None, "--seed", help="Random seed (default 0)."),
    every: Optional[int] = typer.Option(None, "--every", help="Process every k-th scan (default 1: all)."),
    config: Optional[Path] = typer.Option(None, "--config", "-c", help="YAML config (see `pfslam dump-config`)."),
    search: Optional[bool] = typer.Option(
        None, "--search/--no-search", help="Local x/y/theta search grid around each particle (default: off)."
    ),
    estimate: Optional[str] = typer.Option(None, "--estimate", help="Pose estimate: mean (weighted, default) or best."),
    ground_truth: Optional[Path] = typer.Option(None, "--ground-truth", "-g", help="TUM ground truth to score against."),
    odometry: str = typer.Option(
        "log", "--odometry",
        help="Odometry source: 'log', or 'synthetic[:SEED]' for logs whose poses are already corrected "
             "(CARMEN .gfs logs): drifting odometry derived from them; they are saved as reference.tum.",
    ),
    wheel_scale: float = typer.Option(
        1.0, "--wheel-scale", help="Calibration factor on wheel travel from encoder counts (Mines logs)."
    ),
    score: Optional[str] = typer.Option(
        None, "--score", help="Scoring map: auto (default), field (smoothed walls) or cells (raw log-odds)."
    ),
    calibrate: bool = typer.Option(
        False, "--calibrate", help="Measure the odometry's scale and the scan latency from the scans "
                                   "(see `pfslam calibrate`) and correct the odometry before the SLAM."
    ),
    scan_latency: float = typer.Option(
        0.0, "--scan-latency", help="Scans were taken this many seconds before their time stamps: the "
                                    "odometry is read at t - S (applied before --calibrate's own estimate)."
    ),
) -> None:
    """Build a map and a trajectory from a log (THOR .mat, CARMEN, Mines .dat; detected from the file).

    Writes map.pgm/.yaml/.png, trajectory.tum, odometry.tum, run.json (and reference.tum)."""
    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import read_tum, write_tum

    cfg = _load_config(config, particles, seed, every, search, estimate, score)
    _prepare_out(out)
    log_data = load_log(log, joint, odometry=odometry, wheel_scale=wheel_scale)
    for w in log_data.warnings:
        _warn(w)
    _require_returns(log, log_data.frames)
    truth = read_tum(ground_truth) if ground_truth is not None else None
    frames, cal_info = _corrected_odometry(log, log_data.frames, scan_latency, calibrate, cfg.motion.axle)
    run = _run_with_progress(frames, cfg, "SLAM")
    if truth is None and log_data.reference is not None and log_data.odometry != "log":
        t_all = np.array([f.t for f in log_data.frames])
        write_tum(out / "reference.tum", t_all, log_data.reference)
        truth = (t_all, log_data.reference)
    with _scoring(run):
        _score(run, truth, ground_truth or "reference")
        if run.scans >= 4 and not run.interrupted:
            from pfslam.evaluate import map_agreement

            done = frames[:: cfg.every][: run.scans]
            agree = {"SLAM": map_agreement(done, run.poses), "odometry": map_agreement(done, run.odometry)}
            run.metrics["map_agreement"] = agree
            out_console.print(
                f"map agreement (later scans on the walls earlier scans mapped, within 0.1 m): "
                f"SLAM {agree['SLAM']:.3f}, odometry {agree['odometry']:.3f}", soft_wrap=True,
            )
    info = {"log": str(log), "joint": str(joint) if joint else None, "format": log_data.format,
            "odometry": log_data.odometry, "wheel_scale": wheel_scale, **cal_info}
    label = "ground truth" if ground_truth is not None else "reference"
    write_slam_outputs_and_report(run, out, info, truth, label, log)


def _calibration_table(cal: Any) -> Table:
    tab = Table(show_header=True, header_style="bold")
    tab.add_column("quantity")
    tab.add_column("value", justify="right")
    tab.add_row("translation scale", f"{cal.trans_scale:.3f}")
    tab.add_row("rotation scale", f"{cal.rot_scale:.3f}")
    tab.add_row("scan latency (s)", f"{cal.scan_latency:+.3f}")
    tab.add_row("heading residual per scan (deg), before -> after",
                f"{cal.rot_residual_deg_uncalibrated:.2f} -> {cal.rot_residual_deg:.2f}")
    tab.add_row("translation residual per scan (m)", f"{cal.trans_residual:.4f}")
    tab.add_row("scan pairs matched / used", f"{cal.pairs_matched} / {cal.pairs_used}")
    return tab


def _run_calibration(frames: list, axle: float) -> Any:
    from pfslam.calibrate import calibrate as calibrate_fn

    with _progress() as prog:
        task = prog.add_task("calibrate", total=1, rate=0.0)
        t0 = time.perf_counter()

        def cb(i: int, total: int) -> None:
            dt = time.perf_counter() - t0
            prog.update(task, total=total, completed=i, rate=i / dt if dt > 0 else 0.0)

        return calibrate_fn(frames, axle=axle, progress=cb)


def _corrected_odometry(log: Path, frames: list, scan_latency: float, calibrate: bool,
                        axle: float) -> tuple[list, dict[str, Any]]:
    """Apply --scan-latency, then (with --calibrate) the measured calibration."""
    from pfslam.calibrate import CalibrationError, apply_calibration, shift_odometry
    from pfslam.errors import InputError

    info: dict[str, Any] = {"scan_latency": scan_latency}
    if not np.isfinite(scan_latency) or abs(scan_latency) > 5.0:
        raise InputError(log, f"--scan-latency must be a number of seconds within +-5, not {scan_latency}")
    try:
        if scan_latency:
            frames = shift_odometry(frames, scan_latency)
        if calibrate:
            cal = _run_calibration(frames, axle)
            out_console.print(_calibration_table(cal))
            frames = apply_calibration(frames, cal)
            info["calibration"] = cal.as_dict()
    except CalibrationError as e:
        raise InputError(log, str(e)) from None
    return frames, info


def write_slam_outputs_and_report(run: Any, out: Path, info: dict[str, Any], truth: Any,
                                  truth_label: str, log: object) -> None:
    from pfslam.pipeline import write_slam_outputs

    _write_and_report(
        run, out, log, lambda: write_slam_outputs(run, out, info, truth, truth_label),
        f"{run.scans} scans in {run.seconds:.1f} s ({run.scans_per_second:.0f} scans/s, "
        f"{run.real_time_factor:.1f}x real time); results in {out}/",
    )


def _parse_triple(text: str, what: str) -> list[float]:
    from pfslam.errors import InputError

    try:
        v = [float(x) for x in text.replace(" ", "").split(",")]
    except ValueError:
        v = []
    if len(v) != 3 or not all(np.isfinite(v)):
        raise InputError(what, f"expected three numbers X,Y,THETA_DEG, got {text!r}")
    return v


@app.command("calibrate")
@guarded
def calibrate_cmd(
    log: Path = typer.Argument(..., help="Log file (anything `pfslam slam` reads)."),
    joint: Optional[Path] = typer.Option(None, "--joint", "-j", help="THOR joint .mat file."),
    odometry: str = typer.Option("log", "--odometry", help="'log' or 'synthetic[:SEED]' (corrected CARMEN logs)."),
    wheel_scale: float = typer.Option(1.0, "--wheel-scale", help="Calibration factor already applied to wheel travel."),
    axle: float = typer.Option(0.33, "--axle", help="Distance between the wheels (m), wheel logs only."),
) -> None:
    """Measure the odometry's translation/rotation scale and the scan latency by matching
    consecutive scans (no ground truth needed). `pfslam slam --calibrate` applies them."""
    from pfslam.calibrate import CalibrationError
    from pfslam.errors import InputError
    from pfslam.io.logs import load_log

    log_data = load_log(log, joint, odometry=odometry, wheel_scale=wheel_scale)
    for w in log_data.warnings:
        _warn(w)
    try:
        cal = _run_calibration(log_data.frames, axle)
    except CalibrationError as e:
        raise InputError(log, str(e)) from None
    out_console.print(_calibration_table(cal))
    if not cal.rot_residual_deg < 0.8 * cal.rot_residual_deg_uncalibrated:
        out_console.print("the correction explains little of the difference between odometry and scans: "
                          "the odometry already agrees with them, and --calibrate is not needed", soft_wrap=True)
    out_console.print(escape(
        f"{cal.source}: translation x{cal.trans_scale:.3f}, rotation x{cal.rot_scale:.3f}, scans taken "
        f"{cal.scan_latency:.3f} s before their time stamps. `pfslam slam --calibrate` applies this."),
        soft_wrap=True,
    )


@app.command()
@guarded
def localize(
    log: Path = typer.Argument(..., help="Log file (anything `pfslam slam` reads)."),
    map_yaml: Path = typer.Option(..., "--map", "-m", help="Map in the ROS map_server format (map.yaml)."),
    joint: Optional[Path] = typer.Option(None, "--joint", "-j", help="THOR joint .mat file."),
    initial_pose: Optional[str] = typer.Option(
        None, "--initial-pose", help="Start pose X,Y,THETA_DEG in the map frame (default: the map origin frame's 0,0,0)."
    ),
    initial_std: str = typer.Option("0.1,0.1,5", "--initial-std", help="Spread of the start: SX,SY,STHETA_DEG."),
    global_: bool = typer.Option(False, "--global", help="Unknown start: particles uniform over free space."),
    particles: Optional[int] = typer.Option(None, "--particles", "-n", help="Particles (initial; KLD adapts it)."),
    max_particles: Optional[int] = typer.Option(None, "--max-particles", help="KLD upper bound (default 5000)."),
    no_kld: bool = typer.Option(False, "--no-kld", help="Fixed particle count."),
    no_recovery: bool = typer.Option(False, "--no-recovery", help="No random particles when lost."),
    model: str = typer.Option("likelihood_field", "--model", help="Sensor model: likelihood_field or beam."),
    seed: int = typer.Option(0, "--seed", help="Random seed."),
    odometry: str = typer.Option("log", "--odometry", help="'log' or 'synthetic[:SEED]' (corrected CARMEN logs)."),
    wheel_scale: float = typer.Option(1.0, "--wheel-scale", help="Calibration factor on wheel travel (Mines logs)."),
    calibrate: bool = typer.Option(False, "--calibrate", help="Correct the odometry's scale and the scan latency "
                                                              "measured from the scans (see `pfslam calibrate`)."),
    scan_latency: float = typer.Option(0.0, "--scan-latency", help="Read the odometry at t - S (s)."),
    ground_truth: Optional[Path] = typer.Option(None, "--ground-truth", "-g", help="TUM ground truth to score against."),
    out: Path = typer.Option(Path("out_localize"), "--out", "-o", help="Output folder."),
) -> None:
    """Track the robot on a known map (Monte Carlo localization). Writes trajectory.tum, localization.png, run.json."""
    from pfslam.errors import InputError
    from pfslam.grid import OccupancyGrid
    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import read_tum
    from pfslam.localize import LocalizerConfig
    from pfslam.pipeline import run_localization, write_localization_outputs

    _prepare_out(out)
    grid = OccupancyGrid.load_ros(map_yaml)
    if not (grid.thresholded() == 0).any():
        raise InputError(map_yaml, "the map has no free cells")
    cfg = LocalizerConfig(seed=seed, recovery=not no_recovery, kld=not no_kld, model=model)
    for name, v in (("--particles", particles), ("--max-particles", max_particles)):
        if v is not None and v < 1:
            raise InputError(name, f"must be at least 1, not {v}")
    if particles is not None and max_particles is not None and particles > max_particles and not no_kld:
        raise InputError("--particles", f"{particles} is more than --max-particles {max_particles} "
                                        "(KLD-sampling keeps the count within it; --no-kld fixes the count)")
    if particles is not None:
        cfg.particles = particles
        cfg.min_particles = min(cfg.min_particles, particles)
    if max_particles is not None:
        cfg.max_particles = max_particles
        cfg.min_particles = min(cfg.min_particles, max_particles)
        cfg.global_particles = max(cfg.global_particles, max_particles)
    cfg.validate()
    initial = None
    if not global_:
        pose = _parse_triple(initial_pose, "--initial-pose") if initial_pose else [0.0, 0.0, 0.0]
        std = _parse_triple(initial_std, "--initial-std")
        if min(std) < 0:
            raise InputError("--initial-std", f"spreads must not be negative, got {initial_std!r}")
        initial = (np.array([pose[0], pose[1], np.deg2rad(pose[2])]), np.array([std[0], std[1], np.deg2rad(std[2])]))
        try:
            from pfslam.localize import Localizer

            Localizer(grid, cfg).check_pose(initial[0])
        except InputError as e:
            raise InputError(map_yaml, f"--initial-pose: {e.problem}") from None
    log_data = load_log(log, joint, odometry=odometry, wheel_scale=wheel_scale)
    for w in log_data.warnings:
        _warn(w)
    _require_returns(log, log_data.frames)
    truth = read_tum(ground_truth) if ground_truth is not None else None
    label = "ground truth"
    if truth is None and log_data.reference is not None and log_data.odometry != "log":
        truth = (np.array([f.t for f in log_data.frames]), log_data.reference)
        label = "reference"
    frames, cal_info = _corrected_odometry(log, log_data.frames, scan_latency, calibrate, cfg.axle)
    t0 = time.perf_counter()
    with _progress() as prog:
        task = prog.add_task("localize", total=len(frames), rate=0.0)

        def cb(i: int, total: int) -> None:
            dt = time.perf_counter() - t0
            prog.update(task, completed=i, rate=i / dt if dt > 0 else 0.0)

        run = run_localization(frames, grid, cfg, initial, cb)
    with _scoring(run):
        _score(run, truth, ground_truth or "reference", ("estimate", "odometry"))
    info = {"log": str(log), "map": str(map_yaml), "format": log_data.format, "odometry": log_data.odometry,
            "global": global_, "wheel_scale": wheel_scale, **cal_info}
    counts = f"particles {run.counts[0]} -> {run.counts[-1]}" if run.scans else ""
    _write_and_report(
        run, out, log, lambda: write_localization_outputs(run, grid, cfg, out, info, truth, label),
        f"{run.scans} scans in {run.seconds:.1f} s ({run.scans_per_second:.0f} scans/s, {run.updates} updates, "
        f"{counts}); results in {out}/",
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
) -> None:
    """Simulate a THOR humanoid log (lidar + joint .mat, groundtruth.tum, the true map.yaml) in a built-in world."""
    from pfslam.errors import ConfigError
    from pfslam.simulate import simulate as sim

    if head_pitch_deg is not None and not abs(head_pitch_deg) <= 90.0:
        raise ConfigError(f"--head-pitch-deg must be a number of degrees within +-90, not {head_pitch_deg}")
    pitch = None if head_pitch_deg is None else float(np.deg2rad(head_pitch_deg))
    _prepare_out(out)
    res = sim(world=world, duration_s=duration, seed=seed, out_dir=out, layout=layout, head_pitch=pitch,
              drift=not no_drift)
    out_console.print(escape(f"wrote {res.lidar_path}, {res.joint_path}, {res.groundtruth_path} and the true "
                             f"map {Path(res.lidar_path).parent / 'map.yaml'}"), soft_wrap=True)


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
) -> None:
    """Simulate a THOR office loop, run SLAM on it, and score SLAM and odometry against ground truth."""
    from pfslam.config import SlamConfig, check_number
    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import read_tum
    from pfslam.simulate import MAX_DURATION
    from pfslam.simulate import simulate as sim

    cfg = SlamConfig(seed=seed, every=every)
    cfg.search.enabled = search
    cfg.validate()
    check_number("--duration", duration, gt=0.0, le=MAX_DURATION, what="a finite number of seconds")
    _prepare_out(out)
    err_console.print(f"simulating {duration:g} s of a THOR humanoid walking an office loop ...")
    res = sim(world="office", duration_s=duration, seed=seed, out_dir=out / "log")
    log_data = load_log(res.lidar_path, res.joint_path)
    run = _run_with_progress(log_data.frames, cfg, "SLAM")
    truth = read_tum(res.groundtruth_path)
    rows = None
    with _scoring(run):
        rows = _score(run, truth, res.groundtruth_path)
    info = {"log": str(res.lidar_path), "joint": str(res.joint_path), "format": log_data.format}
    write_slam_outputs_and_report(run, out, info, truth, "ground truth", res.lidar_path)
    if rows is not None:
        out_console.print(escape(f"ATE SLAM {rows['SLAM'].ate_rmse:.3f} m, odometry "
                                 f"{rows['odometry'].ate_rmse:.3f} m; map: {out / 'map.png'}"), soft_wrap=True)


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
) -> None:
    """ATE (raw and SE(2)-aligned) and RPE against a reference, and/or the relations metric."""
    from pfslam.errors import InputError
    from pfslam.evaluate import read_relations, relation_errors, trajectory_errors
    from pfslam.io.trajectory import read_tum

    if reference is not None and reference_opt is not None:
        raise InputError(reference_opt, "give the reference once: as the second argument or with --reference")
    ref = reference or reference_opt
    if ref is None and relations is None:
        raise InputError(estimate, "give a reference trajectory (second argument or --reference) or --relations")
    t_est, est = read_tum(estimate)
    if ref is not None:
        try:
            e = trajectory_errors(t_est, est, *read_tum(ref), max_dt=max_dt, rpe_delta=rpe_delta)
        except ValueError as ex:
            raise InputError(estimate, str(ex)) from None
        out_console.print(_errors_table({estimate.name: e}))
        out_console.print(f"matched poses: {e.matched}")
    if relations is not None:
        r = relation_errors(t_est, est, read_relations(relations), time_offset=time_offset, max_dt=max_dt)
        if r.matched == 0:
            raise InputError(relations, f"no relation has both ends within {max_dt} s of an estimated pose "
                                        f"(check --time-offset; {r.skipped} relations skipped)")
        out_console.print(
            f"relations: {r.matched} matched, {r.skipped} skipped; translation {r.trans_mean:.4f} ± "
            f"{r.trans_std:.4f} m, rotation {r.rot_mean_deg:.3f} ± {r.rot_std_deg:.3f} deg",
            soft_wrap=True,
        )


@app.command("dump-config")
def dump_config_cmd() -> None:
    """Print the default SLAM config as YAML (edit it and pass it with --config)."""
    from pfslam.config import SlamConfig, dump_config

    sys.stdout.write(dump_config(SlamConfig()))


@app.command()
def version() -> None:
    """Print the pfslam version."""
    out_console.print(__version__)


def main() -> None:
    """The ``pfslam`` program: like ``app()``, but a usage error (unknown option, missing
    argument, a value of the wrong type) is one line on stderr rather than a framed box."""
    try:
        from click.exceptions import UsageError
    except ImportError:  # recent Typer carries its own copy of Click
        from typer._click.exceptions import UsageError  # type: ignore[no-redef]

    try:
        code = app(standalone_mode=False)
    except UsageError as e:
        where = e.ctx.command_path if e.ctx is not None else "pfslam"
        if e.format_message().strip():  # empty: no arguments at all, and the help was shown
            _error(f"{where}: {e.format_message()} (see '{where} --help')")
        sys.exit(2)
    except typer.Abort:  # Ctrl-C outside a command's own handling
        err_console.print("[yellow]interrupted[/]", highlight=False)
        sys.exit(130)
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":  # pragma: no cover
    main()
