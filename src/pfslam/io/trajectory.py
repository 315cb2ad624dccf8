"""TUM trajectory files: ``timestamp tx ty tz qx qy qz qw`` per line.

2D poses are written with z = 0 and a rotation about +z only.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from pfslam.errors import InputError
from pfslam.io.common import num


def write_tum(path: str | Path, t: NDArray[np.float64], poses: NDArray[np.float64]) -> None:
    """Write (N,) times and (N, 3) poses as a TUM file, full precision."""
    t = np.asarray(t, dtype=float)
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    half = poses[:, 2] / 2.0
    with open(path, "w", encoding="utf-8") as f:
        f.write("# timestamp tx ty tz qx qy qz qw\n")
        for ti, (x, y, _), qz, qw in zip(t, poses, np.sin(half), np.cos(half)):
            f.write(f"{ti:.9f} {x:.9f} {y:.9f} 0 0 0 {qz:.12f} {qw:.12f}\n")


MAX_POSITION = 1e9  # m, larger coordinates are taken for a corrupt file
MAX_TIME = 1e12  # s
MAX_STEP_BACK = 1.0  # s, time stamps going back by more than this are an error


def read_tum(path: str | Path) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Read a TUM file; return (N,) times and (N, 3) planar poses (yaw from the quaternion).

    Every value must be finite, positions within +-1e9 m and times within +-1e12 s, and
    the quaternion not zero (it need not be normalised). Poses come back sorted by time:
    a time stamp may go back by up to 1 s (out-of-order lines are reordered, stably); one
    that goes back further is an InputError naming the line. Repeated time stamps are kept
    in file order (pfslam's own trajectories never repeat one: the loaders make scan times
    strictly increasing; other tools' files may). A UTF-8 byte order mark is skipped.
    Messages quote at most 20 characters of a field.
    """
    p = Path(path)
    if p.is_dir():
        raise InputError(p, "is a folder, not a file")
    if not p.is_file():
        raise InputError(p, "file not found" if not p.exists() else "not a regular file")
    rows = []
    lines = []
    with open(p, encoding="utf-8-sig", errors="replace") as f:
        for n, line in enumerate(f, 1):
            s = line.strip()
            if not s or s.startswith("#"):
                continue
            parts = s.replace(",", " ").split()
            if len(parts) != 8:
                raise InputError(p, f"line {n}: expected 8 fields (t x y z qx qy qz qw), got {len(parts)}")
            try:
                vals = [float(v) for v in parts]
            except ValueError:
                raise InputError(p, f"line {n}: not a number") from None
            if not np.all(np.isfinite(vals)):
                raise InputError(p, f"line {n}: NaN or inf value")
            if abs(vals[0]) > MAX_TIME:
                raise InputError(p, f"line {n}: time stamp {parts[0][:20]} is out of range (|t| > {MAX_TIME:g} s)")
            if max(abs(v) for v in vals[1:4]) > MAX_POSITION:
                raise InputError(p, f"line {n}: position out of range (|x|, |y| or |z| > {MAX_POSITION:g} m)")
            quat = vals[4:]
            if not any(quat):
                raise InputError(p, f"line {n}: the quaternion (qx qy qz qw) is zero")
            big = max(abs(v) for v in quat)
            rows.append(vals[:4] + [v / big for v in quat])  # scaled: no overflow in the yaw below
            lines.append(n)
    if not rows:
        raise InputError(p, "no poses in file")
    a = np.array(rows)
    back = np.maximum.accumulate(a[:, 0]) - a[:, 0]
    if back.max() > MAX_STEP_BACK:
        k = int(np.argmax(back > MAX_STEP_BACK))
        raise InputError(p, f"line {lines[k]}: time stamp goes back {num(back[k])} s (more than {MAX_STEP_BACK:g} s)")
    order = np.argsort(a[:, 0], kind="stable")
    a = a[order]
    qx, qy, qz, qw = a[:, 4], a[:, 5], a[:, 6], a[:, 7]
    # Scale-invariant form of atan2(2 (qw qz + qx qy), 1 - 2 (qy^2 + qz^2)): right for unnormalised quaternions.
    yaw = np.arctan2(2.0 * (qw * qz + qx * qy), qw * qw + qx * qx - qy * qy - qz * qz)
    return a[:, 0], np.column_stack([a[:, 1], a[:, 2], yaw])


COVARIANCE_COLUMNS = ("t", "x", "y", "theta", "xx", "xy", "xtheta", "yy", "ytheta", "thetatheta")


def write_covariance_csv(
    path: str | Path, t: NDArray[np.float64], poses: NDArray[np.float64], cov: NDArray[np.float64]
) -> None:
    """Write (N,) times, (N, 3) poses and their (N, 3, 3) covariances as CSV: a header of
    :data:`COVARIANCE_COLUMNS`, then per pose the time (s), x, y (m), theta (rad) and the six
    distinct entries of the covariance of (x, y, theta) (m^2, m rad, rad^2), full precision."""
    t = np.asarray(t, dtype=float)
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    cov = np.asarray(cov, dtype=float).reshape(-1, 3, 3)
    upper = cov[:, [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]]
    with open(path, "w", encoding="utf-8") as f:
        f.write(",".join(COVARIANCE_COLUMNS) + "\n")
        for ti, p, c in zip(t, poses, upper):
            f.write(f"{ti:.9f}," + ",".join(f"{v:.12g}" for v in (*p, *c)) + "\n")


HEALTH_COLUMNS = ("t", "updated", "quality", "state", "explained", "contradicted")


def write_health_csv(
    path: str | Path,
    t: NDArray[np.float64],
    updated: NDArray[np.bool_],
    quality: NDArray[np.float64],
    states: Sequence[str],
    explained: NDArray[np.float64],
    contradicted: NDArray[np.float64],
) -> None:
    """Write a localization's health per scan as CSV: a header of :data:`HEALTH_COLUMNS`, then
    per scan the time (s), whether it weighed the scan (1 / 0), the quality (0..1), the state
    (tracking, degraded, lost, ambiguous; empty before the first update) and the fractions of
    the beams the map explains and contradicts (empty before the first update). Between
    updates a scan carries the last update's figures."""

    def cell(v: float) -> str:
        return f"{v:.4f}" if np.isfinite(v) else ""

    with open(path, "w", encoding="utf-8") as f:
        f.write(",".join(HEALTH_COLUMNS) + "\n")
        for row in zip(t, updated, quality, states, explained, contradicted):
            ti, u, q, s, e, c = row
            f.write(f"{ti:.9f},{int(u)},{cell(q)},{s},{cell(e)},{cell(c)}\n")
