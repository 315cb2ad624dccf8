"""What every log loader shares: file checks, text reading, limits, plausibility, the result
(the time-stamp rule is :mod:`pfslam.io.times`, the no-return readings :mod:`pfslam.io.readings`,
output folders :mod:`pfslam.io.folders`).

A leaf module: it imports nothing from :mod:`pfslam.io`, so each loader module
(:mod:`pfslam.io.thor`, :mod:`pfslam.io.carmen`, :mod:`pfslam.io.mines`) imports from here
alone, and the registry :mod:`pfslam.io.logs` imports the loaders without a circle.
"""

from __future__ import annotations

import gzip
import math
import zlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

import numpy as np
from numpy.typing import NDArray

from pfslam.errors import InputError
from pfslam.frames import Frame, frame_column, frame_times

TIME_TOLERANCE = 1.0  # s a joint sample (THOR) or a streamed scan (ScanClock) may fall back before it is an error
SCAN_TIME_TOLERANCE = 10.0  # s a scan's time stamp may step back (a clock step) and still be repaired
ABSURD_TIME = 1e11  # s (3,000 years): a stamp further from 0 than this is a corrupt record
DEFAULT_SCAN_INTERVAL = 0.2  # s between scans when no stamp says: 5 Hz, the classic CARMEN logs (FR079: 4.5 Hz)
INFORMATIVE_STEPS = 0.05  # stamps carry the timing if at least this fraction of scan-to-scan steps advance:
# stamps coarser than 20 scans are spread between their ticks; coarser still (csail: %g-rounded
# to 10,000 s, one tick in 406 scans) they say nothing of the interval between scans
REPEAT_STEP = 1e-3  # s added by ScanClock (streaming) to a scan whose stamp does not advance
DETECT_BYTES = 1 << 20  # how much of a text log format detection reads at first
DETECT_MAX_BYTES = 64 << 20  # how far a text format's detection may stream on through leading unknown lines
MAX_MOUNT_OFFSET = 10.0  # m; a sensor mounted further than this from the robot is a corrupt value
MAX_ODOM_STEP = 100.0  # m; odometry may always move this far between two scans ...
MAX_ODOM_SPEED = 50.0  # m/s; ... or this fast, whichever allows more
GZIP_ERRORS = (zlib.error, EOFError, OSError)  # gzip.BadGzipFile is an OSError
GZIP_MAGIC = b"\x1f\x8b"
BOM = "\ufeff"  # a UTF-8 byte order mark, as decoded
NOMINAL_LASER_HEIGHT = 0.3  # m above the floor for planar 2D lasers (floor cut is 0.15 m)


# --- the result ----------------------------------------------------------------------------


@dataclass
class LoadedLog:
    """What :func:`pfslam.io.logs.load_log` (and each loader module's ``read``) returns."""

    frames: Sequence[Frame]  # a list, or Frames (kept by column, ranges possibly on disk)
    format: str
    warnings: list[str] = field(default_factory=list)
    reference: NDArray[np.float64] | None = None  # (N, 3) poses the log carries, if corrected
    odometry: str = "log"  # where the frames' odometry came from
    skipped: dict[str, int] = field(default_factory=dict)  # records read but not used, by type (run.json)
    notes: list[str] = field(default_factory=list)  # what was done as asked (not a warning)


# --- files -----------------------------------------------------------------------------------


def check_file(path: Path, folder: bool = False) -> None:
    """Raise InputError unless ``path`` exists and is a file (or, with ``folder``, a folder:
    a log format whose logs are folders, a ROS 2 bag, decides on it)."""
    if not path.exists():
        raise InputError(path, "file not found")
    if not path.is_file() and not (folder and path.is_dir()):
        raise InputError(path, "not a file")


def read_bytes(path: Path, size: int = -1) -> bytes:
    """The first ``size`` bytes of ``path`` (all with -1); an OSError becomes a one-line InputError."""
    try:
        with open(path, "rb") as f:
            return f.read(size)
    except OSError as e:
        raise InputError(path, f"cannot read the file ({e.strerror or e})") from None


def read_head(path: Path) -> bytes:
    """The first ``DETECT_BYTES`` of ``path`` as stored (what format detection looks at)."""
    return read_bytes(path, DETECT_BYTES)


def is_gzip(data: bytes) -> bool:
    """Whether ``data`` starts with the gzip magic bytes."""
    return data[:2] == GZIP_MAGIC


def _corrupt_gzip(path: Path, e: BaseException) -> InputError:
    return InputError(path, f"corrupt gzip data: {str(e) or type(e).__name__}")


def gunzip_head(path: Path) -> bytes:
    """The first ``DETECT_BYTES`` of the decompressed content of the gzip file ``path``."""
    try:
        with gzip.open(path, "rb") as g:
            return g.read(DETECT_BYTES)
    except GZIP_ERRORS as e:
        raise _corrupt_gzip(path, e) from None


def read_text_lines(path: str | Path) -> list[str]:
    """Lines of a plain or gzip text file (gzip recognised by its magic bytes).

    Raises InputError for a missing, unreadable, corrupt or binary file.
    """
    p = Path(path)
    check_file(p)
    raw = read_bytes(p)
    if is_gzip(raw):
        try:
            raw = gzip.decompress(raw)
        except GZIP_ERRORS as e:
            raise _corrupt_gzip(p, e) from None
    if b"\x00" in raw:
        raise InputError(p, "binary data, not a text log")
    text = raw.decode("utf-8", errors="replace").removeprefix(BOM)
    bad = text.count("\ufffd")
    if bad > 16 and bad > 0.01 * len(text):
        raise InputError(p, "not a text log (mostly undecodable bytes)")
    return [ln.rstrip("\r") for ln in text.split("\n")]


def head_text(head: bytes) -> str:
    """A detection head as text (undecodable bytes replaced, a UTF-8 byte order mark dropped)."""
    return head.decode("utf-8", errors="replace").removeprefix(BOM)


def stream_text_lines(path: Path, budget: int = DETECT_MAX_BYTES) -> Iterator[str]:
    """The lines of a plain or gzip text file, read as they come (for format detection that
    has to look past the first ``DETECT_BYTES``), until about ``budget`` bytes of text were
    read; undecodable bytes replaced, a byte order mark dropped. A file that cannot be read
    or decompressed ends the lines (detection then fails as for any unknown file)."""
    try:
        raw = read_bytes(path, 2)
        opener = gzip.open if is_gzip(raw) else open
        with opener(path, "rb") as f:
            seen = 0
            while seen < budget:
                line = f.readline(DETECT_BYTES)  # a line longer than this comes in pieces
                if not line:
                    return
                text = line.decode("utf-8", errors="replace")
                yield text.removeprefix(BOM) if seen == 0 else text
                seen += len(line)
    except (InputError, *GZIP_ERRORS):
        return


def reject_joint(joint: str | Path | None) -> None:
    """The error a reader without head joints raises when it is given a joint file."""
    if joint is not None:
        raise InputError(joint, "a joint file only goes with a THOR lidar .mat file")


# --- memory --------------------------------------------------------------------------------


def release_free_memory() -> None:
    """Hand the memory a loader freed back to the system (glibc's ``malloc_trim``; nothing
    elsewhere). Parsing a log allocates far more, in many small pieces, than the frames keep;
    freed, those pieces stay in the process (and count in its resident size) until trimmed,
    while the run's own large arrays are mapped afresh beside them."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc
        pass


# --- numbers in messages ------------------------------------------------------------------


def num(v: float, decimals: int = 3) -> str:
    """``v`` for a message, never longer than about 20 characters: fixed-point with
    ``decimals`` decimals while that is short, else ``%.6g`` (a corrupt 1e300 is "1e+300",
    not 300 digits)."""
    v = float(v)
    if math.isfinite(v) and abs(v) < 1e12:
        return f"{v:.{decimals}f}"
    return f"{v:.6g}"


def absurd_time(t: float) -> bool:
    """Whether a time stamp is corrupt beyond repair: not finite or further than ``ABSURD_TIME`` from 0."""
    return not (math.isfinite(t) and abs(t) <= ABSURD_TIME)


# --- plausibility ------------------------------------------------------------------------------


def check_odometry(path: str | Path, frames: Sequence[Frame]) -> None:
    """Reject implausible odometry and mounts, which would make the map grow without bound.

    Raises InputError naming the scan (numbered from 1) when an odometry pose or wheel travel
    is not finite, when it moves more than ``max(MAX_ODOM_STEP, MAX_ODOM_SPEED * dt)`` metres
    between two consecutive scans (wheel travel: the wheel that moved most), or when a sensor
    mount lies more than ``MAX_MOUNT_OFFSET`` from the robot.
    """
    times = frame_times(frames)
    for name in ("odom", "wheels"):
        col = frame_column(frames, name)
        idx = [i for i, x in enumerate(col) if x is not None]
        if not idx:
            continue
        v = np.array([np.asarray(col[i], dtype=float) for i in idx])
        bad = ~np.isfinite(v).all(axis=1)
        if bad.any():
            i = idx[int(np.argmax(bad))]
            what = "odometry pose" if name == "odom" else "wheel travel"
            raise InputError(path, f"scan {i + 1} (t={num(times[i])}): {what} is not finite")
        if len(idx) < 2:
            continue
        step = np.hypot(*np.diff(v[:, :2], axis=0).T) if name == "odom" else np.abs(np.diff(v, axis=0)).max(axis=1)
        t = times[idx]
        dt = np.diff(t)
        over = step > np.maximum(MAX_ODOM_STEP, MAX_ODOM_SPEED * dt)
        if over.any():
            k = int(np.argmax(over))
            i, j = idx[k], idx[k + 1]
            raise InputError(
                path,
                f"odometry jumps {num(step[k], 0)} m in {num(dt[k])} s between scans {i + 1} and {j + 1} (t={num(t[k])})",
            )
    mounts = cast("list[NDArray[np.float64]]", frame_column(frames, "mount"))  # a mount is never None
    off = np.array([np.hypot(m[0, 3], m[1, 3]) for m in mounts])
    if len(off) and not (off <= MAX_MOUNT_OFFSET).all():
        i = int(np.argmax(~(off <= MAX_MOUNT_OFFSET)))
        raise InputError(
            path,
            f"scan {i + 1} (t={num(times[i])}): the sensor is mounted {off[i]:.3g} m from the robot "
            f"(more than {MAX_MOUNT_OFFSET:.0f} m: a corrupt pose or offset)",
        )
