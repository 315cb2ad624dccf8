"""TUM trajectory files: ``timestamp tx ty tz qx qy qz qw`` per line.

2D poses are written with z = 0 and a rotation about +z only.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pfslam.errors import InputError


def write_tum(path: str | Path, t: NDArray[np.float64], poses: NDArray[np.float64]) -> None:
    """Write (N,) times and (N, 3) poses as a TUM file, full precision."""
    t = np.asarray(t, dtype=float)
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    half = poses[:, 2] / 2.0
    with open(path, "w", encoding="utf-8") as f:
        f.write("# timestamp tx ty tz qx qy qz qw\n")
        for ti, (x, y, _), qz, qw in zip(t, poses, np.sin(half), np.cos(half)):
            f.write(f"{ti:.9f} {x:.9f} {y:.9f} 0 0 0 {qz:.12f} {qw:.12f}\n")


def read_tum(path: str | Path) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Read a TUM file; return (N,) times and (N, 3) planar poses (yaw from the quaternion)."""
    p = Path(path)
    if not p.is_file():
        raise InputError(p, "file not found")
    rows = []
    with open(p, encoding="utf-8", errors="replace") as f:
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
            rows.append(vals)
    if not rows:
        raise InputError(p, "no poses in file")
    a = np.array(rows)
    qx, qy, qz, qw = a[:, 4], a[:, 5], a[:, 6], a[:, 7]
    yaw = np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    return a[:, 0], np.column_stack([a[:, 1], a[:, 2], yaw])
