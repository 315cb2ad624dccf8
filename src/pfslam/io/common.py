"""What every log loader shares: file checks, text reading, the time-stamp rule, limits, the result.

A leaf module: it imports nothing from :mod:`pfslam.io`, so each loader module
(:mod:`pfslam.io.thor`, :mod:`pfslam.io.carmen`, :mod:`pfslam.io.mines`) imports from here
alone, and the registry :mod:`pfslam.io.logs` imports the loaders without a circle.
"""

from __future__ import annotations

import gzip
import math
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pfslam.errors import InputError
from pfslam.frames import Frame

TIME_TOLERANCE = 1.0  # s a scan's time stamp may fall back (a clock glitch) before it is an error
DETECT_BYTES = 1 << 20  # how much of a text log format detection reads, at most
MAX_MOUNT_OFFSET = 10.0  # m; a sensor mounted further than this from the robot is a corrupt value
MAX_ODOM_STEP = 100.0  # m; odometry may always move this far between two scans ...
MAX_ODOM_SPEED = 50.0  # m/s; ... or this fast, whichever allows more
GZIP_ERRORS = (zlib.error, EOFError, OSError)  # gzip.BadGzipFile is an OSError
GZIP_MAGIC = b"\x1f\x8b"
NOMINAL_LASER_HEIGHT = 0.3  # m above the floor for planar 2D lasers (floor cut is 0.15 m)


# --- the result ----------------------------------------------------------------------------


@dataclass
class LoadedLog:
    """What :func:`pfslam.io.logs.load_log` (and each loader module's ``read``) returns."""

    frames: list[Frame]
    format: str
    warnings: list[str] = field(default_factory=list)
    reference: NDArray[np.float64] | None = None  # (N, 3) poses the log carries, if corrected
    odometry: str = "log"  # where the frames' odometry came from


# --- files -----------------------------------------------------------------------------------


def check_file(path: Path) -> None:
    """Raise InputError unless ``path`` exists and is a file."""
    if not path.exists():
        raise InputError(path, "file not found")
    if not path.is_file():
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
    text = raw.decode("utf-8", errors="replace")
    bad = text.count("\ufffd")
    if bad > 16 and bad > 0.01 * len(text):
        raise InputError(p, "not a text log (mostly undecodable bytes)")
    return [ln.rstrip("\r") for ln in text.split("\n")]


def head_text(head: bytes) -> str:
    """A detection head as text (undecodable bytes replaced)."""
    return head.decode("utf-8", errors="replace")


def reject_joint(joint: str | Path | None) -> None:
    """The error a reader without head joints raises when it is given a joint file."""
    if joint is not None:
        raise InputError(joint, "a joint file only goes with a THOR lidar .mat file")


# --- time stamps -------------------------------------------------------------------------------


class ScanClock:
    """The loaders' one rule for scan time stamps, fed one scan at a time in file order.

    A scan whose time is after the latest accepted scan's is accepted. A scan whose time
    equals it or is at most ``tolerance`` seconds earlier (duplicates, jitter, a swapped
    pair: the real Intel log has four, of 0.05 to 0.86 s) is a time-stamp glitch: it is
    kept, in file order, with its time clamped to the latest accepted time, counted in
    ``clamped`` and reported by :meth:`report`. A scan further back raises
    :class:`InputError` naming the file and the scan.
    """

    def __init__(self, path: str | Path, tolerance: float = TIME_TOLERANCE) -> None:
        self.path, self.tolerance = path, tolerance
        self.last, self.last_where = -math.inf, ""
        self.clamped, self.most_back = 0, 0.0
        self.first: tuple[str, float, float] | None = None

    def __call__(self, t: float, where: str) -> float:
        """The time to give the scan at ``where`` (e.g. "line 12") whose stamp is ``t``."""
        if t > self.last:
            self.last, self.last_where = t, where
            return t
        back = self.last - t
        if back > self.tolerance:
            raise InputError(
                self.path,
                f"{where}: time goes backwards by {back:.3f} s ({t:.6f} s after {self.last:.6f} s "
                f"at {self.last_where})",
            )
        self.clamped += 1
        self.most_back = max(self.most_back, back)
        if self.first is None:
            self.first = (where, t, self.last)
        return self.last

    def report(self, warnings: list[str], counts: dict[str, int] | None = None) -> None:
        """Add the loader's warning (and ``counts["time_clamped"]``) if any scan was clamped."""
        if self.first is None:
            return
        where, t, prev = self.first
        warnings.append(
            f"{self.path}: {self.clamped} scan(s) whose time stamp did not increase (at most {self.most_back:.3f} s "
            f"back in time) kept with the previous scan's time (first at {where}: {t:.6f} s after {prev:.6f} s)"
        )
        if counts is not None:
            counts["time_clamped"] = self.clamped


# --- plausibility ------------------------------------------------------------------------------


def check_odometry(path: str | Path, frames: list[Frame]) -> None:
    """Reject implausible odometry and mounts, which would make the map grow without bound.

    Raises InputError naming the scan (numbered from 1) when an odometry pose or wheel travel
    is not finite, when it moves more than ``max(MAX_ODOM_STEP, MAX_ODOM_SPEED * dt)`` metres
    between two consecutive scans (wheel travel: the wheel that moved most), or when a sensor
    mount lies more than ``MAX_MOUNT_OFFSET`` from the robot.
    """
    for name in ("odom", "wheels"):
        idx = [i for i, f in enumerate(frames) if getattr(f, name) is not None]
        if not idx:
            continue
        v = np.array([np.asarray(getattr(frames[i], name), dtype=float) for i in idx])
        bad = ~np.isfinite(v).all(axis=1)
        if bad.any():
            i = idx[int(np.argmax(bad))]
            what = "odometry pose" if name == "odom" else "wheel travel"
            raise InputError(path, f"scan {i + 1} (t={frames[i].t:.3f}): {what} is not finite")
        if len(idx) < 2:
            continue
        step = np.hypot(*np.diff(v[:, :2], axis=0).T) if name == "odom" else np.abs(np.diff(v, axis=0)).max(axis=1)
        t = np.array([frames[i].t for i in idx])
        dt = np.diff(t)
        over = step > np.maximum(MAX_ODOM_STEP, MAX_ODOM_SPEED * dt)
        if over.any():
            k = int(np.argmax(over))
            i, j = idx[k], idx[k + 1]
            raise InputError(
                path,
                f"odometry jumps {step[k]:.0f} m in {dt[k]:.3f} s between scans {i + 1} and {j + 1} (t={t[k]:.3f})",
            )
    off = np.array([np.hypot(f.mount[0, 3], f.mount[1, 3]) for f in frames])
    if len(off) and not (off <= MAX_MOUNT_OFFSET).all():
        i = int(np.argmax(~(off <= MAX_MOUNT_OFFSET)))
        raise InputError(
            path, f"scan {i + 1} (t={frames[i].t:.3f}): the sensor is mounted {off[i]:.3g} m from the robot "
            f"(more than {MAX_MOUNT_OFFSET:.0f} m: a corrupt pose or offset)"
        )
