"""Mines ParisTech rover logs (``.dat``): wheel encoders + a Hokuyo URG-04LX.

One line per scan, whitespace separated, 707 fields:

- field 0: time stamp in microseconds;
- fields 2 and 3: cumulative left and right wheel encoder counts;
- fields 24..705: 682 ranges in millimetres over 240 deg, first beam at -120 deg,
  0 = no return;
- field 706: not a range (ignored). Other fields are ignored.

Choices:

- **Beam step.** The URG-04LX divides a full turn into 1024 steps, so the step is
  360/1024 deg (0.3516 deg); 682 beams then span 239.6 deg from -120 deg.
- **Ranges.** 0 is "no return" (+inf), and so is anything below ``min_range`` (20 mm by
  default): the URG-04LX writes error codes (1, 2, 6, 7, 8, 10, 15 mm in exp2.dat) in place
  of readings it could not make. The sensor reports up to about 5.6 m but is specified to
  ``max_range`` (4 m): readings at or past it are no returns (+inf) too, as are readings at
  or above a no-return value of the log's own (:func:`~pfslam.io.readings.find_sentinel`:
  exp2.dat has none). These are counted in ``counts``; one warning is given only for what
  the sensor's documentation does not explain (negative readings, a detected no-return
  value below ``max_range``).
- **Wheels.** ``Frame.wheels`` is the travel of each wheel in metres since the first
  usable line: counts × ``COUNT_RAD`` × ``WHEEL_RADIUS`` (× ``wheel_scale``, a
  calibration factor, 1 by default). ``Frame.odom`` is None: the filter uses the wheels.
- **Robustness.** A malformed line (wrong number of fields, a non-numeric or non-finite
  value) is skipped, counted in ``counts["skipped_bad"]`` and reported in one warning with
  its first line number.
- **Time.** The rule all loaders share (:func:`pfslam.io.times.repair_times`): a line
  whose stamp repeats, steps back by at most ``time_tolerance`` (10 s) or jumps out alone is
  kept (not dropped), in file order, with a time between its neighbours', counted in
  ``counts["time_repaired"]`` and reported in one warning; stamps that carry no timing at
  all are replaced by the line order at the nominal rate; stepping back further (and
  staying back) raises :class:`InputError` naming the line. A line whose stamp is absurd
  (beyond 1e11 s) is a malformed line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pfslam.errors import ConfigError, InputError
from pfslam.frames import Frame
from pfslam.geometry import txyz, wrap_angle
from pfslam.io.common import (
    NOMINAL_LASER_HEIGHT,
    SCAN_TIME_TOLERANCE,
    LoadedLog,
    absurd_time,
    head_text,
    num,
    read_text_lines,
    reject_joint,
)
from pfslam.io.readings import find_sentinel, no_return_warning
from pfslam.io.times import repair_times
from pfslam.types import Array

WHEEL_RADIUS = 0.077  # m
HALF_AXLE = 0.165  # m, wheel to axle centre
AXLE = 2.0 * HALF_AXLE  # m, wheel to wheel
COUNT_RAD = math.radians(180.0 / 2000.0)  # wheel rotation (rad) per encoder count
LASER_X = 0.145  # m, laser ahead of the axle centre
MAX_RANGE = 4.0  # m, URG-04LX specification
MIN_RANGE = 0.02  # m, URG-04LX: readings up to this are error codes (1..15 mm in exp2.dat)
BEAMS = 682
FIRST_BEAM_DEG = -120.0
BEAM_STEP_DEG = 360.0 / 1024.0  # URG-04LX: 1024 steps per turn
FIELDS = 707  # time, ?, left, right, ..., 682 ranges from field 24, one trailing field
TIME_FIELD, LEFT_FIELD, RIGHT_FIELD = 0, 2, 3
FIRST_RANGE_FIELD = 24
ANGLES: Array = np.radians(FIRST_BEAM_DEG + BEAM_STEP_DEG * np.arange(BEAMS))
NOMINAL_INTERVAL = 0.1  # s: the URG-04LX scans at 10 Hz


@dataclass
class MinesLog:
    """What :func:`load_mines` returns: frames, warnings, and ``counts`` (``lines`` read,
    ``scans`` used, ``skipped_bad``, ``no_return`` readings, and ``time_repaired`` or
    ``time_from_order`` where the time stamps needed it)."""

    frames: list[Frame]
    warnings: list[str] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)


def load_mines(
    path: str | Path,
    wheel_scale: float = 1.0,
    *,
    min_range: float = MIN_RANGE,
    max_range: float = MAX_RANGE,
    time_tolerance: float = SCAN_TIME_TOLERANCE,
) -> MinesLog:
    """Read a Mines rover log into Frames with wheel travel (m) and ranges (m).

    ``wheel_scale`` multiplies the wheel travel computed from the documented constants (a
    calibration factor for users who measured one; 1 by default). Readings at or below
    ``min_range`` or at or beyond ``max_range`` (m) are no returns. ``time_tolerance``: how
    far (s) the time stamps may step back and be repaired.

    Raises:
        InputError: missing/unreadable/binary/corrupt gzip file, time going backwards by
            more than ``time_tolerance`` (names the line), or no usable line.
        ConfigError: a non-positive ``wheel_scale``, ``max_range`` or ``time_tolerance``,
            or a ``min_range`` that is negative or not below ``max_range``.
    """
    if not (wheel_scale > 0 and math.isfinite(wheel_scale)):
        raise ConfigError(f"wheel_scale must be a positive number, not {wheel_scale}")
    if not (max_range > 0 and math.isfinite(max_range)):
        raise ConfigError(f"max_range must be a positive number, not {max_range}")
    if not (0.0 <= min_range < max_range):
        raise ConfigError(f"min_range must be a number >= 0 and below max_range, not {min_range}")
    if not (time_tolerance > 0 and math.isfinite(time_tolerance)):
        raise ConfigError(f"time_tolerance must be a positive number of seconds, not {time_tolerance}")
    p = Path(path)
    lines = read_text_lines(p)
    metres_per_count = COUNT_RAD * WHEEL_RADIUS * wheel_scale
    mount = txyz(LASER_X, 0.0, NOMINAL_LASER_HEIGHT)
    counts = {"lines": 0, "scans": 0, "skipped_bad": 0}
    first_bad: tuple[int, str] | None = None
    stamps: list[float] = []
    line_no: list[int] = []
    heads: list[Array] = []
    readings: list[Array] = []
    for n, line in enumerate(lines, 1):
        tok = line.split()
        if not tok or tok[0].startswith("#"):
            continue
        counts["lines"] += 1
        try:
            if len(tok) != FIELDS:
                raise ValueError(f"{len(tok)} fields, expected {FIELDS}")
            head = np.array([tok[TIME_FIELD], tok[LEFT_FIELD], tok[RIGHT_FIELD]], dtype=float)
            mm = np.array(tok[FIRST_RANGE_FIELD : FIRST_RANGE_FIELD + BEAMS], dtype=float)
            if not (np.isfinite(head).all() and np.isfinite(mm).all()):
                raise ValueError("non-finite value")
            if absurd_time(float(head[0]) * 1e-6):
                raise ValueError(f"absurd time stamp {num(head[0], 0)} us")
        except (ValueError, OverflowError) as e:
            counts["skipped_bad"] += 1
            if first_bad is None:
                msg = str(e).splitlines()[0] if str(e) else type(e).__name__
                first_bad = (n, msg[:80])
            continue
        stamps.append(float(head[0]) * 1e-6)
        line_no.append(n)
        heads.append(head[1:])
        readings.append(mm / 1000.0)
    warnings = []
    if first_bad is not None:
        warnings.append(
            f"{p}: skipped {counts['skipped_bad']} malformed line(s) (first: line {first_bad[0]}: {first_bad[1]})"
        )
    if not readings:
        raise InputError(p, f"no usable scans ({counts['lines']} lines, {counts['skipped_bad']} malformed)")
    times = repair_times(
        p, [("time", np.array(stamps))], lambda i: f"line {line_no[i]}", time_tolerance, NOMINAL_INTERVAL
    )
    times.report(p, warnings, counts)

    sentinel = find_sentinel(readings)
    rmax = max_range
    if sentinel is not None and sentinel.value < max_range:
        rmax = sentinel.value
    else:
        sentinel = None
    dropped = {
        "no return (0)": 0,
        "error codes": 0,
        "at or beyond the maximum range": 0,
        "at the log's no-return value": 0,
        "negative": 0,
    }
    base = heads[0]
    mount.setflags(write=False)  # one array shared by every frame
    frames: list[Frame] = []
    for t, wheel, r in zip(times.times, heads, readings):
        zero, negative = r == 0.0, r < 0.0
        under = (r <= min_range) & ~zero & ~negative
        over = r >= max_range
        at_sentinel = (r >= rmax) & ~over
        dropped["no return (0)"] += int(np.count_nonzero(zero))
        dropped["error codes"] += int(np.count_nonzero(under))
        dropped["negative"] += int(np.count_nonzero(negative))
        dropped["at or beyond the maximum range"] += int(np.count_nonzero(over))
        dropped["at the log's no-return value"] += int(np.count_nonzero(at_sentinel))
        r = np.where(zero | negative | under | over | at_sentinel, np.inf, r)
        frames.append(
            Frame(
                t=float(t),
                ranges=r,
                angles=ANGLES,
                wheels=(wheel - base) * metres_per_count,
                mount=mount,
                min_range=min_range,
                max_range=rmax,
            )
        )
    counts["scans"] = len(frames)
    counts["no_return"] = sum(dropped.values())
    if sentinel is not None or dropped["negative"]:
        warnings.append(no_return_warning(p, BEAMS * len(frames), dropped, sentinel))
    return MinesLog(frames=frames, warnings=warnings, counts=counts)


def detect(path: Path, head: bytes) -> bool:
    """Whether ``path`` is a Mines log: a ``.dat`` name, or first data lines of ``head`` (the
    file's first bytes, decompressed if gzip) that look like Mines records."""
    return path.name.lower().endswith(".dat") or _looks_like_mines(head_text(head))


def _looks_like_mines(text: str, lines: int = 5) -> bool:
    """Whether the first data lines are Mines rover records (whatever the file is called):
    rows of numbers, as many as a Mines line holds (time, encoders, ..., 682 ranges)."""
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


def read(
    path: Path,
    *,
    joint: str | Path | None = None,
    wheel_scale: float = 1.0,
    time_tolerance: float = SCAN_TIME_TOLERANCE,
) -> LoadedLog:
    """:func:`load_mines` as a :class:`LoadedLog` of format ``mines``. A joint file is an error."""
    reject_joint(joint)
    m = load_mines(path, wheel_scale=wheel_scale, time_tolerance=time_tolerance)
    return LoadedLog(frames=m.frames, format="mines", warnings=list(m.warnings))


def dead_reckoning(frames: list[Frame], axle: float = AXLE) -> Array:
    """(N, 3) axle-centre poses from the wheel travel alone, starting at the origin.

    Exact arcs: between two frames with wheel travels ``dl``, ``dr`` the heading turns by
    ``(dr - dl) / axle`` and the robot moves along the chord ``2 (ds / dth) sin(dth / 2)``
    (``ds = (dl + dr) / 2``; ``ds`` when ``dth`` is 0) at the mid heading.
    """
    if len(frames) == 0:
        return np.zeros((0, 3))
    if any(f.wheels is None for f in frames):
        raise ValueError("dead_reckoning needs wheel travel in every frame")
    w = np.array([np.asarray(f.wheels, dtype=float) for f in frames])
    d = np.diff(w, axis=0)
    ds = 0.5 * (d[:, 0] + d[:, 1])
    dth = (d[:, 1] - d[:, 0]) / axle
    half = 0.5 * dth
    # sin(h)/h, exact and safe at 0 (np.sinc is sin(pi x)/(pi x)).
    chord = ds * np.sinc(half / np.pi)
    heading = np.concatenate([[0.0], np.cumsum(dth)])
    mid = heading[:-1] + half
    out = np.zeros((len(frames), 3))
    out[1:, 0] = np.cumsum(chord * np.cos(mid))
    out[1:, 1] = np.cumsum(chord * np.sin(mid))
    out[:, 2] = wrap_angle(heading)
    return out
