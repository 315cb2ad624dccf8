"""Loader registry: pick the reader from the file, return format-independent frames.

Each supported log format is one module with two functions,

- ``detect(path, head) -> bool``: whether ``path`` is in that format, given ``head``, its
  first :data:`~pfslam.io.common.DETECT_BYTES` (decompressed if the file is gzip, unless
  the entry says ``gunzip=False``: then as stored);
- ``read(path, *, joint=None, wheel_scale=1.0[, time_tolerance][, scan_topic, ...]) ->
  LoadedLog``: the frames (a reader that has no use for a joint file rejects one; a reader
  that takes ``time_tolerance`` or one of the :data:`READER_OPTIONS` is given it),

and one line in :data:`REGISTRY`. Detection asks the entries in order and the first that
accepts the file reads it. The loader modules import only :mod:`pfslam.io.common`, never
this module or each other. An entry with ``folders=True`` is also asked about a folder (a
ROS 2 bag); a folder no such entry accepts is "not a file".
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TypedDict, cast

from pfslam.errors import InputError
from pfslam.frames import with_column
from pfslam.io import carmen, mines, rosbag, thor
from pfslam.io.common import (
    SCAN_TIME_TOLERANCE,
    TIME_TOLERANCE,
    LoadedLog,
    check_file,
    check_odometry,
    gunzip_head,
    is_gzip,
    read_head,
    release_free_memory,
)
from pfslam.io.times import ScanClock

__all__ = [
    "FORMATS",
    "REGISTRY",
    "LogFormat",
    "LoadedLog",
    "SCAN_TIME_TOLERANCE",
    "ScanClock",
    "TIME_TOLERANCE",
    "check_odometry",
    "detect_format",
    "load_log",
]


@dataclass(frozen=True)
class LogFormat:
    """One entry of :data:`REGISTRY`."""

    name: str  # what detect_format returns
    detect: Callable[[Path, bytes], bool]
    read: Callable[..., LoadedLog]  # read(path, *, joint=None, wheel_scale=1.0)
    expected: str  # how the "unknown log format" error names the format
    gunzip: bool = True  # detect sees the head decompressed (text formats) or as stored (binary ones)
    folders: bool = False  # a log of this format may be a folder (detect then sees an empty head)


# In detection order: a MATLAB/HDF5 header or a .mat name, then a ROS bag's header (or a ROS 2
# bag folder), then a CARMEN record starting a line, then a .dat name or rows of 707 numbers.
REGISTRY: list[LogFormat] = [
    LogFormat("thor", thor.detect, thor.read, "a THOR .mat", gunzip=False),
    LogFormat("rosbag", rosbag.detect, rosbag.read, "a ROS bag", gunzip=False, folders=True),
    LogFormat("carmen", carmen.detect, carmen.read, "a CARMEN log"),
    LogFormat("mines", mines.detect, mines.read, "a Mines .dat file"),
]
FORMATS = tuple(entry.name for entry in REGISTRY)


class BagOptions(TypedDict, total=False):
    """The ROS bag options a command passes on to :func:`load_log` (None: not given)."""

    scan_topic: str | None
    odom_topic: str | None
    base_frame: str | None
    odom_frame: str | None


# Options load_log passes on to the readers that take them (None: not given).
READER_OPTIONS = {
    "scan_topic": "--scan-topic",
    "odom_topic": "--odom-topic",
    "base_frame": "--base-frame",
    "odom_frame": "--odom-frame",
}


def detect_format(path: Path) -> str:
    """Name of the reader for ``path``, from its first bytes and extension.

    A text log is CARMEN if a CARMEN record (FLASER, ODOM, PARAM, ...) starts a line within
    its first ``DETECT_BYTES`` (decompressed); comments, blank lines and other records before
    it are passed over.
    """
    return _detect(path).name


def _takes(read: Callable[..., LoadedLog], option: str) -> bool:
    """Whether a reader takes the keyword ``option``."""
    try:
        return option in inspect.signature(read).parameters
    except (TypeError, ValueError):
        return False


def _detect(path: Path) -> LogFormat:
    """The first entry of :data:`REGISTRY` that accepts ``path``."""
    if path.is_dir():
        for entry in REGISTRY:
            if entry.folders and entry.detect(path, b""):
                return entry
        raise InputError(path, "not a file")
    raw = read_head(path)
    head: bytes | None = None  # decompressed only once an entry needs it
    for entry in REGISTRY:
        if entry.gunzip and head is None:
            head = gunzip_head(path) if is_gzip(raw) else raw
        if entry.detect(path, cast(bytes, head) if entry.gunzip else raw):  # head is set for a gunzip entry
            return entry
    kinds = [entry.expected for entry in REGISTRY]
    expected = kinds[-1] if len(kinds) < 2 else f"{', '.join(kinds[:-1])} or {kinds[-1]}"
    raise InputError(path, f"unknown log format (expected {expected})")


def check_joint(log: Path, joint: str | Path | None, level_head: bool | None) -> None:
    """A THOR log's head angles come from its joint file: without one its scans would be
    mapped tilted. ``level_head`` False (the command line without --level-head) refuses such a
    log here, before anything is read; True runs it with the head level on purpose; None (the
    library's default) runs it with a warning. A THOR log is told by its content (a MATLAB
    file), so a file that is not one gets its reader's own error."""
    if level_head is None:
        return
    if joint is not None and level_head:
        raise InputError(Path("--level-head"), "give --joint or --level-head, not both")
    if joint is not None:
        return  # the reader checks the pair
    try:
        raw = read_head(log) if log.is_file() else b""
        head = gunzip_head(log) if is_gzip(raw) else raw
        is_thor = (head.startswith(b"MATLAB") or head[:4] == b"\x89HDF") and detect_format(log) == "thor"
    except (InputError, OSError):  # the reader says what is wrong with the file
        return
    if level_head and not is_thor:
        raise InputError(Path("--level-head"), f"applies to THOR logs (head angles), not to {log}")
    if is_thor and not level_head:
        guess = log.with_name(log.name.replace("lidar", "joint")) if "lidar" in log.name else None
        name = str(guess) if guess is not None and guess.is_file() else "JOINT.mat"
        raise InputError(
            log,
            f"a THOR log needs its joint file for the head's angles: pass --joint {name} "
            "(or --level-head to assume a level head)",
        )


def load_log(
    path: str | Path,
    joint: str | Path | None = None,
    odometry: str = "log",
    wheel_scale: float = 1.0,
    time_tolerance: float = SCAN_TIME_TOLERANCE,
    level_head: bool | None = None,
    max_scans: int | None = None,
    **options: str | None,
) -> LoadedLog:
    """Read any supported log into Frames.

    ``odometry``: "log" uses the log's own odometry; "synthetic[:SEED]" replaces it with
    drifting odometry derived from the poses a corrected log carries (see
    :mod:`pfslam.io.synthetic`); the reference poses themselves never reach the filter.
    ``time_tolerance``: how far (s) a log's time stamps may step back and be repaired
    (see :func:`pfslam.io.times.repair_times`); further back is an error. Given to the
    readers that take it (CARMEN, Mines, ROS bags).
    ``level_head``: a THOR log without its joint file on purpose (see :func:`check_joint`).
    ``max_scans``: read at most this many scans (a quick look at a long log; a warning says so).
    ``options``: the :data:`READER_OPTIONS` (``scan_topic``, ``odom_topic``, ``base_frame``,
    ``odom_frame``: ROS bags), given to the readers that take them; one given (not None) to a
    reader that does not take it is an error.
    """
    from pfslam.io.synthetic import parse_odometry_option, synthetic_odometry

    p = Path(path)
    check_file(p, folder=True)
    check_joint(p, joint, level_head)
    unknown = set(options) - set(READER_OPTIONS)
    if unknown:
        raise TypeError(f"load_log() got unexpected keyword argument(s): {', '.join(sorted(unknown))}")
    try:
        mode, seed = parse_odometry_option(odometry)
    except ValueError as e:
        raise InputError(p, str(e)) from None
    if not (wheel_scale > 0 and math.isfinite(wheel_scale)):
        raise InputError(p, f"--wheel-scale must be a finite positive number, not {wheel_scale}")
    if not (time_tolerance > 0 and math.isfinite(time_tolerance)):
        raise InputError(p, f"--time-tolerance must be a finite positive number of seconds, not {time_tolerance}")
    entry = _detect(p)
    extra: dict[str, object] = {"time_tolerance": time_tolerance} if _takes(entry.read, "time_tolerance") else {}
    if level_head:  # (check_joint refused it for any other log)
        extra["level_head"] = True
    for name, value in options.items():
        if value is None:
            continue
        if not _takes(entry.read, name):
            raise InputError(p, f"{READER_OPTIONS[name]} applies to ROS bags, not to {entry.expected}")
        extra[name] = value
    out = entry.read(p, joint=joint, wheel_scale=wheel_scale, **extra)
    if mode == "synthetic":
        if out.reference is None:
            raise InputError(p, "--odometry synthetic needs a log that carries reference poses (a CARMEN log)")
        out.frames = with_column(out.frames, "odom", synthetic_odometry(out.reference, seed))
        out.odometry = f"synthetic:{seed}"
    check_odometry(p, out.frames)
    if max_scans is not None and len(out.frames) > max_scans:
        out.warnings.append(f"{p}: only the first {max_scans} of {len(out.frames)} scans are read")
        out.frames = out.frames[:max_scans]
        if out.reference is not None:
            out.reference = out.reference[:max_scans]
    release_free_memory()
    return out
