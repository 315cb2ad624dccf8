"""The steps every command shares, with no printing: prepare a log (load, check, correct
the odometry), run a filter over its frames, score the run, write the results.

Progress goes to a callback; what a caller should tell the user comes back as values."""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from pfslam import __version__
from pfslam.config import CalibrationConfig, LocalizerConfig, SlamConfig, dump_sections, to_dict
from pfslam.errors import InputError
from pfslam.filters.base import SETTLED_SPREAD, Filter, position_std
from pfslam.frames import Estimate, Frame, frame_column, frame_times
from pfslam.geometry import compose, relative
from pfslam.maps.grid import OccupancyGrid, grid_from_config, integrate_scan
from pfslam.io.common import num
from pfslam.io.trajectory import write_covariance_csv, write_tum

Array = NDArray[np.float64]
Progress = Callable[[int, int], None]
# Called after each step with (step index, frame, filter, estimate), e.g. to draw the run as it goes.
Observer = Callable[[int, Frame, Filter, Estimate], None]
Truth = tuple[Array, Array]  # (times, poses)


# -- preparing a run ---------------------------------------------------------------------


def prepare_output_dir(out: Path) -> None:
    """Create the output folder before a long run, so an unwritable one fails at once."""
    if out.exists() and not out.is_dir():
        raise InputError(out, "the output folder exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(out, f"cannot create the output folder ({e.strerror or e})") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError(out, "the output folder is not writable")


def any_valid_return(frames: Sequence[Frame]) -> bool:
    """Whether some frame has a finite range inside its (min_range, max_range) (stops at the first)."""
    for f in frames:
        r = np.asarray(f.ranges, dtype=float)
        if np.any((r > f.min_range) & (r < f.max_range)):  # NaN compares False
            return True
    return False


def require_returns(log: object, frames: Sequence[Frame]) -> None:
    """InputError naming ``log`` if none of its frames has a valid return."""
    if not any_valid_return(frames):
        raise InputError(log, f"none of its {len(frames)} scans has a valid return (every range is NaN, "
                              "inf or outside the sensor's range)")


def reference_truth(log_data: Any) -> Truth | None:
    """The poses a corrected log carries, as ground truth, when the filter was fed other
    (synthetic) odometry; None otherwise."""
    if log_data.reference is None or log_data.odometry == "log":
        return None
    return frame_times(log_data.frames), log_data.reference


MAP_FILE = "map"  # the stem of the map a SLAM run writes (map.yaml, map.pgm)


@dataclass(frozen=True)
class MapStart:
    """Where the SLAM run that built a map started, in the map's frame."""

    pose: Array  # (x, y, theta), theta in radians
    trajectory: Path  # the trajectory.tum it was read from


def map_run_start(map_yaml: str | Path) -> MapStart | None:
    """Where the run that built ``map_yaml`` started (its first pose in time), when the map
    is one ``pfslam slam`` wrote: the run.json beside it is a SLAM run's and names this map
    (runs that did not record the name always wrote ``map.yaml``); the pose is read from the
    trajectory.tum beside it, in the frame the map's origin is given in. None for any other
    map (no such run.json). InputError naming the file when run.json says the map is a SLAM
    run's but its trajectory is missing or unreadable: a start guessed then could be wrong.
    """
    from pfslam.io.trajectory import read_tum

    folder = Path(map_yaml).parent
    try:
        info = json.loads((folder / "run.json").read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):  # none, unreadable or not JSON: not a run we know
        return None
    if not isinstance(info, dict) or info.get("run") != "slam":
        return None
    if info.get("map", f"{MAP_FILE}.yaml") != Path(map_yaml).name:
        return None
    path = folder / "trajectory.tum"
    if not path.is_file():
        raise InputError(path, f"not found, but {folder / 'run.json'} says {Path(map_yaml).name} is a SLAM run's "
                               "map: its start pose is read from this file (or give --initial-pose)")
    try:
        _, poses = read_tum(path)
    except InputError as e:
        raise InputError(path, f"{e.problem} (the start of the map's run is read from it; or give "
                               "--initial-pose)") from None
    return MapStart(poses[0].copy(), path)


def wheel_encoder_log(frames: Sequence[Frame]) -> bool:
    """Whether the log's motion comes from wheel encoders (wheel travel, no odometry pose),
    read from the columns (no scan is read)."""
    return (any(w is not None for w in frame_column(frames, "wheels"))
            and all(o is None for o in frame_column(frames, "odom")))


def correct_odometry(log: object, frames: Sequence[Frame], scan_latency: float, calibrate: bool, axle: float,
                     progress: Progress | None = None, config: CalibrationConfig | None = None,
                     ) -> tuple[Sequence[Frame], dict[str, Any], Any]:
    """Apply ``scan_latency`` (read the odometry at t - S), then, with ``calibrate``, the
    odometry scale and latency measured from the scans (with ``config``). Returns (frames,
    what was applied for run.json, the :class:`~pfslam.tools.calibrate.Calibration` or None)."""
    from pfslam.tools.calibrate import CalibrationError, apply_calibration, calibrate as measure, shift_odometry

    info: dict[str, Any] = {"scan_latency": scan_latency}
    if not np.isfinite(scan_latency) or abs(scan_latency) > 5.0:
        raise InputError(log, f"--scan-latency must be a number of seconds within +-5, not {scan_latency}")
    cal = None
    try:
        if scan_latency:
            frames = shift_odometry(frames, scan_latency)
        if calibrate:
            cal = measure(frames, axle=axle, config=config, progress=progress)
            frames = apply_calibration(frames, cal)
            info["calibration"] = cal.as_dict()
    except CalibrationError as e:
        raise InputError(log, str(e)) from None
    return frames, info, cal


# -- running a filter --------------------------------------------------------------------


def stop_reason(e: BaseException, i: int, frame: Frame | None) -> tuple[bool, str | None]:
    """Why a run loop stopped at frame ``i``: (interrupted, error message or None).

    Ctrl-C inside a Numba kernel surfaces as a SystemError caused by the KeyboardInterrupt;
    that is an interruption too. Any other error becomes a one-line message naming the scan,
    so the caller can write what was computed before it and then report it."""
    while e is not None:
        if isinstance(e, KeyboardInterrupt):
            return True, None
        if not isinstance(e, SystemError):
            break
        e = e.__cause__ or e.__context__  # type: ignore[assignment]
    where = f"scan {i + 1}" + (f" (t={num(frame.t)})" if frame is not None else "")
    text = str(e).splitlines()[0] if str(e) else type(e).__name__
    return False, f"stopped at {where}: {text}"


JUMP_BREAK = 1.0  # m: localization.png leaves a gap where the estimate jumps this much beyond the odometry's step


@dataclass
class Run:
    """What a filter run produced, for the scans it processed (all of them unless it was
    stopped early by Ctrl-C or an error)."""

    kind: str  # "slam" or "localization"
    t: Array
    poses: Array  # the filter's trajectory
    odometry: Array  # dead reckoning, in the filter's frame
    particles: NDArray[np.int64]  # particle count after each step
    grid: OccupancyGrid  # the map built (SLAM) or used (localization)
    config: SlamConfig | LocalizerConfig
    seconds: float
    resamples: int
    updates: int  # steps that weighed a scan
    clouds: list[tuple[float, Array]] = field(default_factory=list)  # (time, particle poses) at a few moments
    metrics: dict[str, Any] = field(default_factory=dict)
    # Localization: per step, the estimate's (3, 3) covariance (NaN where none) and whether it weighed a scan.
    covariances: Array | None = None
    updated: NDArray[np.bool_] | None = None
    interrupted: bool = False  # stopped early (Ctrl-C): the results cover the scans done
    error: str | None = None  # stopped early by an error (the message): the results cover the scans done
    filter_info: dict[str, Any] = field(default_factory=dict)  # which filter, and what it counted

    @property
    def scans(self) -> int:
        return len(self.t)

    @property
    def scans_per_second(self) -> float:
        return self.scans / self.seconds if self.seconds > 0 else float("inf")

    @property
    def real_time_factor(self) -> float:
        span = float(self.t[-1] - self.t[0]) if len(self.t) > 1 else 0.0
        return span / self.seconds if self.seconds > 0 else float("inf")


@dataclass
class _Steps:
    """Per-step records of a run, preallocated for ``n`` steps."""

    odometry: Array
    particles: NDArray[np.int64]
    spread: Array  # position standard deviation of the estimate (m); NaN where the filter gives none
    covariance: Array  # (n, 3, 3) covariance of the estimate; NaN where the filter gives none
    updated: NDArray[np.bool_]  # the step weighed a scan
    done: int = 0
    resamples: int = 0
    updates: int = 0
    slowest: float = 0.0  # seconds of the slowest step


def run_filter(filt: Filter, frames: Sequence[Frame], progress: Progress | None = None,
               snapshots: int = 0, observer: Observer | None = None,
               ) -> tuple[_Steps, list[tuple[float, Array]], float, bool, str | None]:
    """Step ``filt`` through ``frames``; stop early, keeping what was done, on Ctrl-C or an
    error. ``snapshots`` particle clouds are kept at evenly spread moments (filters with a
    ``particles`` set). ``observer(i, frames[i], filt, estimate)`` is called after each step
    (an error it raises stops the run like the filter's own). Returns (the per-step records,
    the clouds, the filter's seconds (the observer's time left out), interrupted, error)."""
    n = len(frames)
    steps = _Steps(np.empty((n, 3)), np.empty(n, dtype=np.int64), np.full(n, np.nan), np.full((n, 3, 3), np.nan),
                   np.zeros(n, dtype=bool))
    marks = set(np.linspace(0, n - 1, snapshots).round().astype(int).tolist()) if snapshots and n else set()
    clouds: list[tuple[float, Array]] = []
    interrupted, error = False, None
    watching = 0.0  # seconds spent in the observer
    start = time.perf_counter()
    i, frame = 0, None
    try:
        for i, frame in enumerate(frames):
            # (asked only when a cloud is kept: the Rao-Blackwellized filter builds its set anew)
            if i in marks and (particles := getattr(filt, "particles", None)) is not None:
                clouds.append((frame.t, particles.poses.copy()))
            began = time.perf_counter()
            est = filt.step(frame)
            steps.slowest = max(steps.slowest, time.perf_counter() - began)
            steps.odometry[i] = filt.odom_pose
            steps.particles[i] = est.particles
            if est.covariance is not None:
                steps.spread[i] = position_std(est.covariance)
                steps.covariance[i] = est.covariance
            steps.updated[i] = est.updated
            steps.resamples += int(est.resampled)
            steps.updates += int(est.updated)
            steps.done = i + 1
            if observer is not None:
                t_obs = time.perf_counter()
                observer(i, frame, filt, est)
                watching += time.perf_counter() - t_obs
            if progress is not None and (i % 50 == 0 or i == n - 1):
                progress(i + 1, n)
    except (KeyboardInterrupt, Exception) as e:  # keep what was computed; the caller writes it, then reports
        interrupted, error = stop_reason(e, i, frame)
    return steps, clouds, time.perf_counter() - start - watching, interrupted, error


def make_slam(config: SlamConfig) -> Filter:
    """The SLAM filter ``config.filter`` names: the single-map filter or the Rao-Blackwellized
    one (``auto`` without a log kind: the single-map filter; see ``config.resolve_filter``)."""
    if config.filter == "rbpf":
        from pfslam.filters.rbpf import RaoBlackwellizedSlam

        return RaoBlackwellizedSlam(config)
    from pfslam.filters.single import SingleMapSlam

    return SingleMapSlam(config)


def run_slam(frames: Sequence[Frame], config: SlamConfig, progress: Progress | None = None,
             observer: Observer | None = None) -> Run:
    """Run the SLAM filter of ``config.filter`` over every ``config.every``-th frame
    (``observer``: see :func:`run_filter`; its index counts the frames stepped)."""
    slam = make_slam(config)
    steps, _, seconds, interrupted, error = run_filter(slam, frames[:: config.every], progress, observer=observer)
    k = steps.done
    t, poses = (x[:k] for x in slam.trajectory())
    run = Run("slam", t, poses, steps.odometry[:k], steps.particles[:k], slam.map, config, seconds,
              steps.resamples, steps.updates, interrupted=interrupted, error=error)
    run.filter_info = {"filter": str(config.filter), "slowest_scan_ms": 1e3 * steps.slowest}
    maps = getattr(slam, "maps", None)
    if maps is not None:  # the Rao-Blackwellized filter: what its maps cost, where its time went
        run.filter_info.update(map_updates=int(slam.updates), unique_tiles=int(maps.unique_tiles),  # type: ignore[attr-defined]
                               tile_memory_mb=maps.nbytes / 2**20,
                               seconds_by_part=dict(slam.timings))  # type: ignore[attr-defined]
    return run


def run_localization(
    frames: Sequence[Frame],
    grid: OccupancyGrid,
    config: LocalizerConfig,
    initial: tuple[Array, Array] | None,
    progress: Progress | None = None,
    snapshots: int = 4,
    observer: Observer | None = None,
) -> Run:
    """Localize a frame stream on ``grid``: around ``initial`` = (pose, std), or globally if
    None (``observer``: see :func:`run_filter`)."""
    from pfslam.filters.localize import Localizer

    loc = Localizer(grid, config)
    if initial is None:
        loc.initialize_global()
    else:
        loc.initialize_around(*initial)
    steps, clouds, seconds, interrupted, error = run_filter(loc, frames, progress, snapshots, observer)
    k = steps.done
    t, poses = (x[:k] for x in loc.trajectory())
    odom = steps.odometry[:k]
    # Draw the odometry from the first moment the estimate is settled (for a global start
    # the first estimates are guesses), so the two can be compared by eye.
    settled = np.nonzero(steps.spread[:k] < SETTLED_SPREAD)[0]
    a = int(settled[0]) if len(settled) else 0
    if k:
        odom = compose(poses[a], relative(odom[a], odom))
    info = {"filter": "mcl", "global_start": initial is None, "first_particles": int(steps.particles[0]) if k else 0,
            "recoveries": loc.recoveries, "injected_particles": loc.injected}
    run = Run("localization", t, poses, odom, steps.particles[:k], grid, config, seconds, steps.resamples,
              steps.updates, clouds, covariances=steps.covariance[:k], updated=steps.updated[:k],
              interrupted=interrupted, error=error, filter_info=info)
    run.metrics["uncertainty"] = uncertainty_summary(run)
    return run


def uncertainty_summary(run: Run) -> dict[str, Any]:
    """Figures of the estimate's covariance over the steps that weighed a scan: how many,
    and the median, largest and last position standard deviation (m, sqrt(var x + var y))
    and heading standard deviation (deg). None for the figures of a run without updates."""
    cov = _updated_covariances(run)[2]
    pos = np.sqrt(np.maximum(cov[:, 0, 0] + cov[:, 1, 1], 0.0))
    head = np.rad2deg(np.sqrt(np.maximum(cov[:, 2, 2], 0.0)))
    out: dict[str, Any] = {"updates": len(cov)}
    for name, v in (("position_std_m", pos), ("heading_std_deg", head)):
        some = len(v) > 0
        out.update({f"{name}_median": float(np.median(v)) if some else None,
                    f"{name}_max": float(v.max()) if some else None,
                    f"{name}_last": float(v[-1]) if some else None})
    return out


def _updated_covariances(run: Run) -> tuple[Array, Array, Array]:
    """(times, poses, covariances) of the steps of ``run`` that weighed a scan and have a covariance."""
    if run.covariances is None or run.updated is None:
        return np.empty(0), np.empty((0, 3)), np.empty((0, 3, 3))
    keep = run.updated & np.isfinite(run.covariances).all(axis=(1, 2))
    return run.t[keep], run.poses[keep], run.covariances[keep]


def build_map(frames: Sequence[Frame], poses: Array, config: SlamConfig | None = None) -> OccupancyGrid:
    """Map a frame stream from known poses (mapping only, no filter): ground truth or a reference."""
    from pfslam.sensor import scan_to_points

    c = config if config is not None else SlamConfig()
    grid = grid_from_config(c.map, centred=False)
    for frame, pose in zip(frames, np.asarray(poses, dtype=float)):
        integrate_scan(grid, pose, scan_to_points(frame, ground_z=c.sensor.ground_z))
    return grid


# -- scoring a run -----------------------------------------------------------------------


@dataclass
class Scores:
    """The figures of a run: trajectory errors per trajectory (when a truth is known) and the
    map agreement (SLAM); ``problem`` says why the errors could not be computed, if so."""

    errors: dict[str, Any] = field(default_factory=dict)  # name -> TrajectoryErrors
    map_agreement: dict[str, float] = field(default_factory=dict)
    problem: str | None = None


def score_trajectories(run: Run, truth: Truth | None, names: tuple[str, str]) -> Scores:
    """ATE/RPE of the estimate and of the odometry against ``truth``, kept in ``run.metrics``."""
    from pfslam.eval.metrics import trajectory_errors

    scores = Scores()
    if truth is None or run.scans < 2:
        return scores
    try:
        scores.errors = {names[0]: trajectory_errors(run.t, run.poses, *truth),
                         names[1]: trajectory_errors(run.t, run.odometry, *truth)}
    except ValueError as e:  # e.g. no time stamps in common with the ground truth
        scores.problem = str(e)
        return scores
    run.metrics.update({k: v.as_dict() for k, v in scores.errors.items()})
    return scores


def score_map_agreement(run: Run, frames: Sequence[Frame], scores: Scores) -> None:
    """The map agreement of the estimate and of the odometry (needs no truth) over the
    frames the run processed (of ``frames``, the log's), into ``scores`` and
    ``run.metrics``; skipped for runs of fewer than 4 scans or stopped early. NaN for a
    trajectory whose scans span more than the largest map."""
    from pfslam.eval.metrics import map_agreement
    from pfslam.maps.grid import MapTooLarge

    if run.scans < 4 or run.interrupted:
        return
    every = run.config.every if isinstance(run.config, SlamConfig) else 1
    done = frames[::every][: run.scans]

    def agreement(poses: Array) -> float:
        try:
            return map_agreement(done, poses)
        except MapTooLarge:  # a trajectory that drifts hundreds of metres (odometry, most often)
            return float("nan")

    scores.map_agreement = {"SLAM": agreement(run.poses), "odometry": agreement(run.odometry)}
    run.metrics["map_agreement"] = scores.map_agreement


# -- writing the results -----------------------------------------------------------------


def _json(obj: Any) -> Any:
    """JSON-ready copy: NumPy scalars and arrays as Python values, NaN and inf as null."""
    if isinstance(obj, dict):
        return {str(k): _json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _json(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


def _peak_rss_mb() -> float | None:
    """The process's peak resident memory so far (MB), where the system tells it."""
    try:
        import resource

        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    except (ImportError, OSError):
        return None


def write_json(path: Path, info: dict[str, Any]) -> None:
    path.write_text(json.dumps(_json(info), indent=2, allow_nan=False))


def write_outputs(run: Run, out: str | Path, input_info: dict[str, Any], truth: Truth | None = None,
                  truth_label: str = "ground truth", calibration: CalibrationConfig | None = None) -> Path:
    """Write a run's results into ``out``: trajectory.tum, odometry.tum, config.yaml (the
    filter's settings, and ``calibration``'s when the odometry was calibrated: ready for
    ``--config``), run.json and a picture (SLAM: map.pgm/.yaml and map.png; localization:
    localization.png with particle clouds over the given map, and covariance.csv: the
    estimate's covariance at each update, see :func:`~pfslam.io.trajectory.write_covariance_csv`)."""
    from pfslam.views.figures import plot_map

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_tum(out / "trajectory.tum", run.t, run.poses)
    write_tum(out / "odometry.tum", run.t, run.odometry)
    used = (run.config,) if calibration is None else (run.config, calibration)
    (out / "config.yaml").write_text(dump_sections(*used))
    slam = run.kind == "slam"
    name = "SLAM" if slam else "estimate"
    trajs = [("odometry", run.odometry, "tab:orange"), (name, run.poses, "tab:blue")]
    if truth is not None:
        trajs.insert(0, (truth_label, truth[1], "tab:green"))
    info: dict[str, Any] = {
        "pfslam_version": __version__,
        "run": run.kind,
        "input": input_info,
        "config": to_dict(run.config),
        **({"calibration_config": to_dict(calibration)} if calibration is not None else {}),
        "scans_processed": run.scans,
        "interrupted": run.interrupted,
        "resamples": run.resamples,
        "updates": run.updates,
        "seconds": run.seconds,
        "scans_per_second": run.scans_per_second,
        "real_time_factor": run.real_time_factor,
        "peak_rss_mb": _peak_rss_mb(),
        **({"filter": run.filter_info} if run.filter_info else {}),
        "metrics": run.metrics,
    }
    if slam:
        run.grid.save_ros(out / MAP_FILE)
        # The map's name: `pfslam localize --map` starts where this run started (map_run_start).
        info["map"] = f"{MAP_FILE}.yaml"
        plot_map(run.grid, out / "map.png", trajs, title="pfslam map", times=run.t, timed=name)
    else:
        info["particles_first_last"] = [int(run.particles[0]), int(run.particles[-1])] if run.scans else None
        write_covariance_csv(out / "covariance.csv", *_updated_covariances(run))
        clouds = [(f"particles at {tc - run.t[0]:.0f} s", p) for tc, p in run.clouds]
        plot_map(run.grid, out / "localization.png", trajs, title="pfslam localization", times=run.t, timed=name,
                 clouds=clouds, jump=JUMP_BREAK)
    if run.error is not None:
        info["error"] = run.error
    write_json(out / "run.json", info)
    return out
