"""A small corrected CARMEN log made from the simulator's office world, with the time stamps
(and the no-return value) a test asks for: the messy real logs (orebro: every stamp 0,
belgioioso: one value, csail: %g-rounded stamps, infinite-corridor: a step back) in a few
kilobytes. Importable from every test folder (``pythonpath = ["tests"]``)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from pfslam.tools.raycast import raycast
from pfslam.tools.worlds import WORLDS

BEAMS = 181  # FLASER: -90..+90 deg, both ends included


def corridor_poses(n: int = 80, step: float = 0.3) -> np.ndarray:
    """(n, 3) poses along the office's south corridor, then left up the east one, with a
    slight weave: a path with a turn, so the map has two legs."""
    w = WORLDS["office"]
    x, y, th = float(w.start[0]), float(w.start[1]), 0.0
    out = []
    for i in range(n):
        out.append((x, y, th))
        if x < 25.0:
            th = 0.05 * np.sin(i / 3.0)
        else:
            th = min(th + 0.35, np.pi / 2)
        x += step * np.cos(th)
        y += step * np.sin(th)
    return np.array(out)


def scan_ranges(pose: np.ndarray, max_range: float = 30.0) -> np.ndarray:
    """Noise-free FLASER ranges from ``pose`` in the office world; ``max_range`` where nothing is hit."""
    w = WORLDS["office"]
    a = pose[2] + np.deg2rad(np.linspace(-90.0, 90.0, BEAMS))
    dirs = np.column_stack([np.cos(a), np.sin(a), np.zeros(BEAMS)])
    return raycast(np.array([pose[0], pose[1], 0.3]), dirs, w.segments, w.wall_height, max_range)


def write_corrected_log(
    path: Path,
    stamps: Callable[[int], object],
    n: int = 80,
    no_return: float = 81.83,
    max_range: float = 30.0,
    header: str = "",
    prefix: bytes = b"",
) -> np.ndarray:
    """Write a corrected FLASER log (laser pose == robot pose == the true pose) whose scan
    ``i`` carries the time stamp ``stamps(i)`` (a number, or the text to write) as both its
    ipc and logger stamp; beams that hit nothing within ``max_range`` read ``no_return``.
    ``header`` lines go first, ``prefix`` bytes (a byte order mark) before everything.
    Returns the (n, 3) poses."""
    poses = corridor_poses(n)
    lines = [header] if header else []
    for i, p in enumerate(poses):
        r = scan_ranges(p, max_range)
        r = np.where(r >= max_range, no_return, r)
        t = stamps(i)
        ts = t if isinstance(t, str) else repr(float(t))
        pose = f"{p[0]:.4f} {p[1]:.4f} {p[2]:.5f}"
        lines.append(f"FLASER {BEAMS} {' '.join(f'{v:.2f}' for v in r)} {pose} {pose} {ts} sim {ts}")
    path.write_bytes(prefix + ("\n".join(lines) + "\n").encode())
    return poses
