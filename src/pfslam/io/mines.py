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
- **Ranges.** 0 is "no return" (+inf), and so is anything below ``MIN_RANGE`` (20 mm):
  the URG-04LX writes error codes (1, 2, 6, 7, 8, 10, 15 mm in exp2.dat) in place of
  readings it could not make. The sensor reports up to about 5.6 m but is specified to 4 m: readings past ``MAX_RANGE`` are kept as read and
  fall outside the Frame's valid window.
- **Wheels.** ``Frame.wheels`` is the travel of each wheel in metres since the first
  usable line: counts × ``COUNT_RAD`` × ``WHEEL_RADIUS`` (× ``wheel_scale``, a
  calibration factor, 1 by default). ``Frame.odom`` is None: the filter uses the wheels.
- **Robustness.** A malformed line (wrong number of fields, a non-numeric or non-finite
  value) is skipped, counted in ``counts["skipped_bad"]`` and reported in one warning with
  its first line number.
- **Time.** The rule all loaders share (:class:`pfslam.io.common.ScanClock`): a line whose
  time equals the latest accepted line's or is at most ``TIME_TOLERANCE`` (1 s) earlier is
  kept (not dropped) with its time clamped to the latest accepted time, counted in
  ``counts["time_clamped"]`` and reported in a warning; further back raises
  :class:`InputError` naming the line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pfslam.errors import ConfigError, InputError
from pfslam.frames import Frame
from pfslam.geometry import txyz, wrap_angle
from pfslam.io.common import NOMINAL_LASER_HEIGHT, LoadedLog, ScanClock, head_text, read_text_lines, reject_joint

Array = NDArray[np.float64]

WHEEL_RADIUS = 0.077  # m
HALF_AXLE = 0.165  # m, wheel to axle centre
AXLE = 2.0 * HALF_AXLE  # m, wheel to wheel
COUNT_RAD = math.radians(180.0 / 2000.0)  # wheel rotation (rad) per encoder count
LASER_X = 0.145  # m, laser ahead of the axle centre
MAX_RANGE = 4.0  # m, URG-04LX specification
MIN_RANGE = 0.02  # m, URG-04LX
MIN_RANGE_MM = 20.0  # readings below this are URG-04LX error codes
BEAMS = 682
FIRST_BEAM_DEG = -120.0
BEAM_STEP_DEG = 360.0 / 1024.0  # URG-04LX: 1024 steps per turn
FIELDS = 707  # time, ?, left, right, ..., 682 ranges from field 24, one trailing field
TIME_FIELD, LEFT_FIELD, RIGHT_FIELD = 0, 2, 3
FIRST_RANGE_FIELD = 24
ANGLES: Array = np.radians(FIRST_BEAM_DEG + BEAM_STEP_DEG * np.arange(BEAMS))


@dataclass
class MinesLog:
    """What :func:`load_mines` returns: frames, warnings, and ``counts`` (``lines`` read,
    ``scans`` used, ``skipped_bad``, and ``time_clamped`` where some were)."""

    frames: list[Frame]
    warnings: list[str] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)


def load_mines(path: str | Path, wheel_scale: float = 1.0) -> MinesLog:
    """Read a Mines rover log into Frames with wheel travel (m) and ranges (m).

    ``wheel_scale`` multiplies the wheel travel computed from the documented constants (a
    calibration factor for users who measured one; 1 by default).

    Raises:
        InputError: missing/unreadable/binary/corrupt gzip file, time going backwards by
            more than 1 s (names the line), or no usable line.
        ConfigError: a non-positive ``wheel_scale``.
    """
    if not (wheel_scale > 0 and math.isfinite(wheel_scale)):
        raise ConfigError(f"wheel_scale must be a positive number, not {wheel_scale}")
    p = Path(path)
    lines = read_text_lines(p)
    metres_per_count = COUNT_RAD * WHEEL_RADIUS * wheel_scale
    mount = txyz(LASER_X, 0.0, NOMINAL_LASER_HEIGHT)
    frames: list[Frame] = []
    counts = {"lines": 0, "scans": 0, "skipped_bad": 0}
    first_bad: tuple[int, str] | None = None
    base: Array | None = None
    clock = ScanClock(p)
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
        except (ValueError, OverflowError) as e:
            counts["skipped_bad"] += 1
            if first_bad is None:
                msg = str(e).splitlines()[0] if str(e) else type(e).__name__
                first_bad = (n, msg[:80])
            continue
        t = clock(float(head[0]) * 1e-6, f"line {n}")
        if base is None:
            base = head[1:].copy()
        wheels = (head[1:] - base) * metres_per_count
        r = np.where(mm >= MIN_RANGE_MM, mm / 1000.0, np.inf)
        frames.append(Frame(t=t, ranges=r, angles=ANGLES, wheels=wheels, mount=mount.copy(),
                            min_range=MIN_RANGE, max_range=MAX_RANGE))
    counts["scans"] = len(frames)
    warnings = []
    if first_bad is not None:
        warnings.append(
            f"{p}: skipped {counts['skipped_bad']} malformed line(s) (first: line {first_bad[0]}: {first_bad[1]})"
        )
    clock.report(warnings, counts)
    if not frames:
        raise InputError(p, f"no usable scans ({counts['lines']} lines, {counts['skipped_bad']} malformed)")
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


def read(path: Path, *, joint: str | Path | None = None, wheel_scale: float = 1.0) -> LoadedLog:
    """:func:`load_mines` as a :class:`LoadedLog` of format ``mines``. A joint file is an error."""
    reject_joint(joint)
    m = load_mines(path, wheel_scale=wheel_scale)
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
