"""Run a filter over a frame stream and write the results. No printing: progress goes to a callback."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from pfslam import __version__
from pfslam.config import SlamConfig, dump_config, to_dict
from pfslam.frames import Frame
from pfslam.grid import OccupancyGrid
from pfslam.io.trajectory import write_tum
from pfslam.slam import Slam

if TYPE_CHECKING:
    from pfslam.localize import LocalizerConfig

Progress = Callable[[int, int], None]


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
    where = f"scan {i + 1}" + (f" (t={frame.t:.3f})" if frame is not None else "")
    text = str(e).splitlines()[0] if str(e) else type(e).__name__
    return False, f"stopped at {where}: {text}"


def any_valid_return(frames: Sequence[Frame]) -> bool:
    """Whether some frame has a finite range inside its (min_range, max_range) (stops at the first)."""
    for f in frames:
        r = np.asarray(f.ranges, dtype=float)
        if np.any((r > f.min_range) & (r < f.max_range)):  # NaN compares False
            return True
    return False


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


def write_json(path: Path, info: dict[str, Any]) -> None:
    path.write_text(json.dumps(_json(info), indent=2, allow_nan=False))


@dataclass
class SlamRun:
    t: NDArray[np.float64]
    poses: NDArray[np.float64]
    odometry: NDArray[np.float64]
    grid: OccupancyGrid
    config: SlamConfig
    seconds: float
    scans: int
    resamples: int
    metrics: dict[str, Any] = field(default_factory=dict)
    interrupted: bool = False  # stopped early (Ctrl-C): the results cover the scans done
    error: str | None = None  # stopped early by an error (the message): the results cover the scans done

    @property
    def scans_per_second(self) -> float:
        return self.scans / self.seconds if self.seconds > 0 else float("inf")

    @property
    def real_time_factor(self) -> float:
        span = float(self.t[-1] - self.t[0]) if len(self.t) > 1 else 0.0
        return span / self.seconds if self.seconds > 0 else float("inf")


def run_slam(frames: Sequence[Frame], config: SlamConfig, progress: Progress | None = None) -> SlamRun:
    """Run SLAM over every ``config.every``-th frame."""
    slam = Slam(config)
    todo = frames[:: config.every]
    n = len(todo)
    t = np.empty(n)
    poses = np.empty((n, 3))
    odom = np.empty((n, 3))
    resamples = 0
    done = 0
    interrupted, error = False, None
    start = time.perf_counter()
    i, frame = 0, None
    try:
        for i, frame in enumerate(todo):
            est = slam.step(frame)
            t[i] = est.t
            poses[i] = est.pose
            odom[i] = slam.odom_pose
            resamples += int(est.resampled)
            done = i + 1
            if progress is not None and (i % 50 == 0 or i == n - 1):
                progress(i + 1, n)
    except (KeyboardInterrupt, Exception) as e:  # keep what was computed; the caller writes it, then reports
        interrupted, error = stop_reason(e, i, frame)
    seconds = time.perf_counter() - start
    return SlamRun(t[:done], poses[:done], odom[:done], slam.grid, config, seconds, done, resamples,
                   interrupted=interrupted, error=error)


def build_map(frames: Sequence[Frame], poses: NDArray[np.float64], config: SlamConfig | None = None) -> OccupancyGrid:
    """Map a frame stream from known poses (mapping only, no filter): ground truth or a reference."""
    from pfslam.sensor import scan_to_points
    from pfslam.slam import integrate_scan

    c = (config or SlamConfig()).validate()
    grid = OccupancyGrid(resolution=c.map.resolution, l_occ=c.map.l_occ, l_free=c.map.l_free, l_clamp=c.map.l_clamp)
    for frame, pose in zip(frames, np.asarray(poses, dtype=float)):
        integrate_scan(grid, pose, scan_to_points(frame, ground_z=c.sensor.ground_z))
    return grid


def write_slam_outputs(
    run: SlamRun,
    out: str | Path,
    input_info: dict[str, Any],
    truth: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    truth_label: str = "ground truth",
) -> Path:
    """Write map.pgm/yaml/png, trajectory.tum, odometry.tum, run.json into ``out``."""
    from pfslam.viz import plot_map

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_tum(out / "trajectory.tum", run.t, run.poses)
    write_tum(out / "odometry.tum", run.t, run.odometry)
    run.grid.save_ros(out / "map")
    (out / "config.yaml").write_text(dump_config(run.config))
    trajs = [("odometry", run.odometry, "tab:orange"), ("SLAM", run.poses, "tab:blue")]
    if truth is not None:
        trajs.insert(0, (truth_label, truth[1], "tab:green"))
    plot_map(run.grid, out / "map.png", trajs, title="pfslam map")
    info = {
        "pfslam_version": __version__,
        "input": input_info,
        "config": to_dict(run.config),
        "scans_processed": run.scans,
        "interrupted": run.interrupted,
        "resamples": run.resamples,
        "seconds": run.seconds,
        "scans_per_second": run.scans_per_second,
        "real_time_factor": run.real_time_factor,
        "metrics": run.metrics,
    }
    if run.error is not None:
        info["error"] = run.error
    write_json(out / "run.json", info)
    return out


@dataclass
class LocalizationRun:
    t: NDArray[np.float64]
    poses: NDArray[np.float64]
    odometry: NDArray[np.float64]
    counts: NDArray[np.int64]
    clouds: list[tuple[float, NDArray[np.float64]]]  # (time, particle poses) at a few moments
    seconds: float
    updates: int
    metrics: dict[str, Any] = field(default_factory=dict)
    interrupted: bool = False  # stopped early (Ctrl-C): the results cover the scans done
    error: str | None = None  # stopped early by an error (the message)

    @property
    def scans(self) -> int:
        return len(self.t)

    @property
    def scans_per_second(self) -> float:
        return len(self.t) / self.seconds if self.seconds > 0 else float("inf")


def run_localization(
    frames: Sequence[Frame],
    grid: OccupancyGrid,
    config: "LocalizerConfig",
    initial: tuple[NDArray[np.float64], NDArray[np.float64]] | None,
    progress: Progress | None = None,
    snapshots: int = 4,
) -> LocalizationRun:
    """Localize a frame stream on ``grid``: around ``initial`` = (pose, std), or globally if None."""
    from pfslam.geometry import compose, relative
    from pfslam.localize import Localizer

    loc = Localizer(grid, config)
    if initial is None:
        loc.initialize_global()
    else:
        loc.initialize_around(*initial)
    n = len(frames)
    t = np.empty(n)
    poses = np.empty((n, 3))
    odom = np.empty((n, 3))
    counts = np.empty(n, dtype=np.int64)
    spread = np.empty(n)  # position standard deviation of the estimate (m)
    marks = set(np.linspace(0, n - 1, snapshots).round().astype(int).tolist()) if snapshots else set()
    clouds = []
    interrupted, error = False, None
    done = 0
    start = time.perf_counter()
    i, f = 0, None
    try:
        for i, f in enumerate(frames):
            if i in marks and loc.particles is not None:
                clouds.append((f.t, loc.particles.poses.copy()))
            est = loc.step(f)
            t[i], poses[i], counts[i] = est.t, est.pose, loc.n
            spread[i] = float(np.sqrt(max(loc.cov[0, 0] + loc.cov[1, 1], 0.0)))
            if i == 0 or f.odom is None or frames[i - 1].odom is None:
                odom[i] = 0.0 if i == 0 else odom[i - 1]
            else:
                odom[i] = compose(odom[i - 1], relative(frames[i - 1].odom, f.odom))
            done = i + 1
            if progress is not None and (i % 50 == 0 or i == n - 1):
                progress(i + 1, n)
    except (KeyboardInterrupt, Exception) as e:  # keep what was computed; the caller writes it, then reports
        interrupted, error = stop_reason(e, i, f)
    seconds = time.perf_counter() - start
    t, poses, odom, counts, spread = t[:done], poses[:done], odom[:done], counts[:done], spread[:done]
    # Draw the odometry from the first moment the estimate is settled (for a global start
    # the first estimates are guesses), so the two can be compared by eye.
    settled = np.nonzero(spread < 0.25)[0]
    a = int(settled[0]) if len(settled) else 0
    if done:
        odom = compose(poses[a], relative(odom[a], odom))
    return LocalizationRun(t, poses, odom, counts, clouds, seconds, loc.updates, interrupted=interrupted, error=error)


def write_localization_outputs(
    run: LocalizationRun,
    grid: OccupancyGrid,
    config: "LocalizerConfig",
    out: str | Path,
    input_info: dict[str, Any],
    truth: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    truth_label: str = "ground truth",
) -> Path:
    """Write trajectory.tum, localization.png and run.json into ``out``."""
    from dataclasses import asdict

    from pfslam.viz import plot_map

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_tum(out / "trajectory.tum", run.t, run.poses)
    trajs = [("odometry", run.odometry, "tab:orange"), ("estimate", run.poses, "tab:blue")]
    if truth is not None:
        trajs.insert(0, (truth_label, truth[1], "tab:green"))

    def clouds(ax: Any) -> None:
        for k, (tc, p) in enumerate(run.clouds):
            p = p[:: max(1, len(p) // 3000)]
            ax.scatter(p[:, 0], p[:, 1], s=2, alpha=0.35, color=f"C{4 + k % 5}", linewidths=0,
                       label=f"particles at {tc - run.t[0]:.0f} s", zorder=1.5)

    plot_map(grid, out / "localization.png", trajs, title="pfslam localization", extra=clouds)
    info = {
        "pfslam_version": __version__,
        "input": input_info,
        "config": asdict(config),
        "scans_processed": len(run.t),
        "updates": run.updates,
        "seconds": run.seconds,
        "scans_per_second": run.scans_per_second,
        "particles_first_last": [int(run.counts[0]), int(run.counts[-1])] if len(run.counts) else None,
        "interrupted": run.interrupted,
        "metrics": run.metrics,
    }
    if run.error is not None:
        info["error"] = run.error
    write_json(out / "run.json", info)
    return out
