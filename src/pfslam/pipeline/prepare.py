"""Preparing a run: the output folder, the log's checks, the odometry's corrections."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from pfslam.config import CalibrationConfig
from pfslam.errors import InputError
from pfslam.frames import Frame, frame_column, frame_times
from pfslam.pipeline.run import Array, Progress, Truth

if TYPE_CHECKING:
    from pfslam.io.common import LoadedLog
    from pfslam.tools.calibrate import Calibration

# -- preparing a run ---------------------------------------------------------------------


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
        raise InputError(
            log,
            f"none of its {len(frames)} scans has a valid return (every range is NaN, "
            "inf or outside the sensor's range)",
        )


def reference_truth(log_data: LoadedLog) -> Truth | None:
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


def map_file(path: str | Path) -> Path:
    """The map.yaml ``path`` names: itself, or for a folder (a ``pfslam slam`` output folder, or
    the session folder inside one) the map.yaml of that run; an InputError if it holds none."""
    path = Path(path)
    if not path.is_dir():
        return path
    for folder in (path, path.parent):
        if (folder / f"{MAP_FILE}.yaml").is_file() and (folder == path or (path / "session.json").is_file()):
            return folder / f"{MAP_FILE}.yaml"
    raise InputError(path, f"a folder without {MAP_FILE}.yaml (give a map.yaml or a pfslam slam output folder)")


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
        raise InputError(
            path,
            f"not found, but {folder / 'run.json'} says {Path(map_yaml).name} is a SLAM run's "
            "map: its start pose is read from this file (or give --initial-pose)",
        )
    try:
        _, poses = read_tum(path)
    except InputError as e:
        raise InputError(
            path, f"{e.problem} (the start of the map's run is read from it; or give --initial-pose)"
        ) from None
    return MapStart(poses[0].copy(), path)


def wheel_encoder_log(frames: Sequence[Frame]) -> bool:
    """Whether the log's motion comes from wheel encoders (wheel travel, no odometry pose),
    read from the columns (no scan is read)."""
    return any(w is not None for w in frame_column(frames, "wheels")) and all(
        o is None for o in frame_column(frames, "odom")
    )


def correct_odometry(
    log: object,
    frames: Sequence[Frame],
    scan_latency: float,
    calibrate: bool,
    axle: float,
    progress: Progress | None = None,
    config: CalibrationConfig | None = None,
) -> tuple[Sequence[Frame], dict[str, Any], Calibration | None]:
    """Apply ``scan_latency`` (read the odometry at t - S), then, with ``calibrate``, the
    odometry scale and latency measured from the scans (with ``config``). Returns (frames,
    what was applied for run.json, the :class:`~pfslam.tools.calibrate.Calibration` or None)."""
    from pfslam.tools.calibrate import (
        CalibrationError,
        apply_calibration,
        shift_odometry,
    )
    from pfslam.tools.calibrate import calibrate as measure

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
