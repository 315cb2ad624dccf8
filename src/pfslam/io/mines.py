"""Mines ParisTech rover logs (``.dat``): wheel encoders + a Hokuyo URG-04LX.

One line per scan, whitespace separated: field 0 the time in microseconds, fields 2 and
3 the cumulative left and right encoder counts, fields 24..705 the 682 ranges in mm
(0 = no return) over 240 deg from -120 deg, field 706 not a range.

The beam step is the URG-04LX's 360/1024 deg; the first beam is at -120 deg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pfslam.errors import InputError
from pfslam.frames import Frame
from pfslam.io.carmen import NOMINAL_LASER_HEIGHT, read_text_lines
from pfslam.geometry import txyz
from pfslam.motion import DiffDriveMotion

Array = NDArray[np.float64]

WHEEL_RADIUS = 0.077  # m
HALF_AXLE = 0.165  # m
AXLE = 2 * HALF_AXLE
COUNT_RAD = math.radians(180.0 / 2000.0)  # wheel rotation per encoder count
LASER_X = 0.145  # m ahead of the axle centre
BEAMS = 682
FIRST_RANGE_FIELD = 24
MIN_FIELDS = FIRST_RANGE_FIELD + BEAMS
MAX_RANGE = 4.0  # URG-04LX
MIN_RANGE = 0.02
ANGLES: Array = math.radians(-120.0) + math.radians(360.0 / 1024.0) * np.arange(BEAMS)


@dataclass
class MinesLog:
    frames: list[Frame]
    counts: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


def load_mines(path: str | Path, wheel_scale: float = 1.0) -> MinesLog:
    """Read a Mines rover log: wheel travel (m) and ranges per line.

    ``wheel_scale`` multiplies the wheel travel computed from the documented constants
    (a calibration factor; scan matching on ``exp2.dat`` measures about 2, see the README).
    """
    p = Path(path)
    lines = read_text_lines(p)
    mount = txyz(LASER_X, 0.0, NOMINAL_LASER_HEIGHT)
    frames: list[Frame] = []
    counts = {"lines": 0, "skipped_bad": 0}
    first_bad: tuple[int, str] | None = None
    base: tuple[float, float] | None = None
    last_t = -math.inf
    for n, line in enumerate(lines, 1):
        tok = line.split()
        if not tok or tok[0].startswith("#"):
            continue
        counts["lines"] += 1
        try:
            if len(tok) < MIN_FIELDS:
                raise ValueError(f"{len(tok)} fields, expected at least {MIN_FIELDS}")
            t_us = float(tok[0])
            left, right = float(tok[2]), float(tok[3])
            r = np.array(tok[FIRST_RANGE_FIELD : FIRST_RANGE_FIELD + BEAMS], dtype=float) / 1000.0
            if not (math.isfinite(t_us) and math.isfinite(left) and math.isfinite(right)):
                raise ValueError("NaN/inf time or encoder count")
        except (ValueError, OverflowError) as e:
            counts["skipped_bad"] += 1
            if first_bad is None:
                first_bad = (n, str(e).splitlines()[0][:80])
            continue
        t = t_us * 1e-6
        if t < last_t:
            raise InputError(p, f"line {n}: time goes backwards ({t:.6f} s after {last_t:.6f} s)")
        last_t = t
        if base is None:
            base = (left, right)
        wheels = np.array([left - base[0], right - base[1]]) * (COUNT_RAD * WHEEL_RADIUS * wheel_scale)
        r = np.where(np.isfinite(r) & (r > 0), r, np.inf)
        frames.append(Frame(t=t, ranges=r, angles=ANGLES, wheels=wheels, mount=mount, min_range=MIN_RANGE,
                            max_range=MAX_RANGE))
    warnings = []
    if first_bad is not None:
        warnings.append(f"{p}: skipped {counts['skipped_bad']} malformed lines (first: line {first_bad[0]}: {first_bad[1]})")
    if not frames:
        raise InputError(p, f"no usable scans ({counts['lines']} lines, {counts['skipped_bad']} malformed)")
    return MinesLog(frames=frames, counts=counts, warnings=warnings)


def dead_reckoning(frames: list[Frame], axle: float = AXLE) -> Array:
    """(N, 3) poses from the wheel travel alone (exact arcs), starting at the origin."""
    out = np.zeros((len(frames), 3))
    for i in range(1, len(frames)):
        d = np.asarray(frames[i].wheels) - np.asarray(frames[i - 1].wheels)
        out[i] = DiffDriveMotion.arc(out[i - 1 : i], d[0:1], d[1:2], axle)[0]
    return out
