"""A scan as points in the robot frame: range window, ground removal, subsampling."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pfslam.frames import Frame
from pfslam.types import Array


@dataclass
class ScanPoints:
    """A scan in the robot base frame, after range filtering and ground removal.

    Attributes:
        hits: (M, 2) obstacle points (x, y) in the robot frame.
        floor: (F, 2) floor hits (free space up to them, never obstacles).
        sensor_xy: (2,) the sensor's position in the robot frame.
    """

    hits: Array
    floor: Array
    sensor_xy: Array


def scan_to_points(
    frame: Frame,
    ground_z: float = 0.15,
    beam_step: int = 1,
) -> ScanPoints:
    """Project a frame's valid beams through its mount to the robot base frame.

    Beams outside (min_range, max_range), NaN or inf are dropped. Points whose height
    above the floor is below ``ground_z`` are floor hits.
    """
    r = np.asarray(frame.ranges, dtype=float)[::beam_step]
    a = np.asarray(frame.angles, dtype=float)[::beam_step]
    ok = np.isfinite(r) & (r > frame.min_range) & (r < frame.max_range)
    r, a = r[ok], a[ok]
    m = frame.mount
    # Sensor-frame point (r cos a, r sin a, 0) through the 4x4 mount.
    px, py = r * np.cos(a), r * np.sin(a)
    xyz = m[:3, :2] @ np.vstack([px, py]) + m[:3, 3:4]
    ground = xyz[2] < ground_z
    pts = xyz[:2].T
    return ScanPoints(
        hits=np.ascontiguousarray(pts[~ground]),
        floor=np.ascontiguousarray(pts[ground]),
        sensor_xy=m[:2, 3].copy(),
    )


LEVEL = 0.087  # sin 5 deg: a laser whose scan plane tilts less than this is level


def open_beams(frame: Frame, reach: float) -> Array:
    """The beams of ``frame`` that returned nothing (+inf, or at or beyond its maximum range;
    NaN and readings too short are not: they say nothing) as points ``reach`` metres from the
    sensor along each (robot frame, (K, 2)): the space up to there is free. None of a laser
    whose scan plane is not level (a tilted beam that returned nothing may have passed over
    what stands there): (0, 2). (The CARMEN loader writes a reading too near to read, 0, as
    +inf too, so on CARMEN logs those count as well: one reason ``rbpf.no_return_m`` is off by
    default.)"""
    m = frame.mount
    r = np.asarray(frame.ranges, dtype=float)
    if reach <= 0 or abs(m[2, 0]) > LEVEL or abs(m[2, 1]) > LEVEL:
        return np.zeros((0, 2))
    with np.errstate(invalid="ignore"):
        none = (r == np.inf) | (r >= frame.max_range)
    if not none.any():
        return np.zeros((0, 2))
    a = np.asarray(frame.angles, dtype=float)[none]
    d = (m[:2, :2] @ np.vstack([np.cos(a), np.sin(a)])).T
    d /= np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)[:, None]
    return np.ascontiguousarray(m[:2, 3] + reach * d)


def beam_ends(hits: Array, floor: Array, sensor: Array, max_reach: float) -> tuple[Array, NDArray[np.bool_]]:
    """A scan's beam end points for a map update, hits then floor hits (robot or world frame,
    ``sensor`` in the same), and which end in a wall: a hit farther than ``max_reach`` from
    the sensor is pulled in to ``max_reach`` and clears free space up to there, no wall."""
    reach = np.hypot(hits[:, 0] - sensor[0], hits[:, 1] - sensor[1]) if len(hits) else np.zeros(0)
    far = reach > max_reach
    ends = hits.copy()
    if far.any():
        v = ends[far] - sensor
        ends[far] = sensor + v * (max_reach / reach[far])[:, None]
    return np.vstack([ends, floor]), np.concatenate([~far, np.zeros(len(floor), bool)])


def subsample(pts: Array, k: int) -> Array:
    """At most ``k`` points, evenly spaced along the scan."""
    if k <= 0 or len(pts) <= k:
        return pts
    idx = np.linspace(0, len(pts) - 1, k).round().astype(np.intp)
    return np.ascontiguousarray(pts[idx])


def cell_keys(points: Array, cell: float) -> NDArray[np.int64]:
    """One key per cell of a grid ``cell`` wide for each of ``points`` ((N, 2))."""
    ij = np.floor(points / cell).astype(np.int64)
    return ij[:, 0] * 2_000_003 + ij[:, 1]


def one_per_cell(points: Array, cell: float) -> Array:
    """The first of ``points`` ((N, 2)) in each cell of a grid ``cell`` wide, in their order."""
    if not len(points):
        return points
    _, first = np.unique(cell_keys(points, cell), return_index=True)
    return points[np.sort(first)]
