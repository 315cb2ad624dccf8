"""Loader registry: pick the reader from the file, return format-independent frames."""

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

FORMATS = ("thor", "carmen", "mines")
TIME_TOLERANCE = 1.0  # s a scan's time stamp may fall back (a clock glitch) before it is an error
DETECT_BYTES = 1 << 20  # how much of a text log format detection reads, at most
MAX_MOUNT_OFFSET = 10.0  # m; a sensor mounted further than this from the robot is a corrupt value
MAX_ODOM_STEP = 100.0  # m; odometry may always move this far between two scans ...
MAX_ODOM_SPEED = 50.0  # m/s; ... or this fast, whichever allows more
GZIP_ERRORS = (zlib.error, EOFError, OSError)  # gzip.BadGzipFile is an OSError


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


@dataclass
class LoadedLog:
    frames: list[Frame]
    format: str
    warnings: list[str] = field(default_factory=list)
    reference: NDArray[np.float64] | None = None  # (N, 3) poses the log carries, if corrected
    odometry: str = "log"  # where the frames' odometry came from


def detect_format(path: Path) -> str:
    """Name of the reader for ``path``, from its first bytes and extension.

    A text log is CARMEN if a CARMEN record (FLASER, ODOM, PARAM, ...) starts a line within
    its first ``DETECT_BYTES`` (decompressed); comments, blank lines and other records before
    it are passed over.
    """
    from pfslam.io.carmen import PARSED_RECORDS

    name = path.name.lower()
    try:
        with open(path, "rb") as f:
            head = f.read(DETECT_BYTES)
    except OSError as e:
        raise InputError(path, f"cannot read the file ({e.strerror or e})") from None
    if head.startswith(b"MATLAB") or head[:4] == b"\x89HDF" or name.endswith(".mat"):
        return "thor"
    if head[:2] == b"\x1f\x8b":
        try:
            with gzip.open(path, "rb") as g:
                head = g.read(DETECT_BYTES)
        except GZIP_ERRORS as e:
            raise InputError(path, f"corrupt gzip data: {str(e) or type(e).__name__}") from None
    text = head.decode("utf-8", errors="replace")
    if any(ln.split(None, 1)[0] in PARSED_RECORDS for ln in text.splitlines() if ln.strip()):
        return "carmen"
    if name.endswith(".dat") or _looks_like_mines(text):
        return "mines"
    raise InputError(path, "unknown log format (expected a THOR .mat, a CARMEN log or a Mines .dat file)")


def _looks_like_mines(text: str, lines: int = 5) -> bool:
    """Whether the first data lines are Mines rover records (whatever the file is called):
    rows of numbers, as many as a Mines line holds (time, encoders, ..., 682 ranges)."""
    from pfslam.io.mines import FIELDS

    rows = [ln.split() for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")][:lines]
    if not rows:
        return False
    for tok in rows:
        if len(tok) != FIELDS:
            return False
        try:
            [float(v) for v in tok]
        except ValueError:
            return False
    return True


def load_log(
    path: str | Path, joint: str | Path | None = None, odometry: str = "log", wheel_scale: float = 1.0
) -> LoadedLog:
    """Read any supported log into Frames.

    ``odometry``: "log" uses the log's own odometry; "synthetic[:SEED]" replaces it with
    drifting odometry derived from the poses a corrected log carries (see
    :mod:`pfslam.odometry`); the reference poses themselves never reach the filter.
    """
    from pfslam.odometry import parse_odometry_option, synthetic_odometry

    p = Path(path)
    if not p.exists():
        raise InputError(p, "file not found")
    if not p.is_file():
        raise InputError(p, "not a file")
    try:
        mode, seed = parse_odometry_option(odometry)
    except ValueError as e:
        raise InputError(p, str(e)) from None
    if not (wheel_scale > 0 and math.isfinite(wheel_scale)):
        raise InputError(p, f"--wheel-scale must be a finite positive number, not {wheel_scale}")
    fmt = detect_format(p)
    if joint is not None and fmt != "thor":
        raise InputError(joint, "a joint file only goes with a THOR lidar .mat file")
    if fmt == "thor":
        from pfslam.io.thor import load_thor

        log = load_thor(p, joint)
        out = LoadedLog(frames=log.frames, format=f"thor-{log.layout}", warnings=list(log.warnings))
    elif fmt == "carmen":
        from pfslam.io.carmen import load_carmen

        c = load_carmen(p)
        out = LoadedLog(frames=c.frames, format="carmen", warnings=list(c.warnings), reference=c.reference)
    else:
        from pfslam.io.mines import load_mines

        m = load_mines(p, wheel_scale=wheel_scale)
        out = LoadedLog(frames=m.frames, format="mines", warnings=list(m.warnings))
    if mode == "synthetic":
        if out.reference is None:
            raise InputError(p, "--odometry synthetic needs a log that carries reference poses (a CARMEN log)")
        odo = synthetic_odometry(out.reference, seed)
        for f, o in zip(out.frames, odo):
            f.odom = o
        out.odometry = f"synthetic:{seed}"
    check_odometry(p, out.frames)
    return out


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
