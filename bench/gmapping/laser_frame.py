"""Which frame a corrected CARMEN log's poses are in: where the laser must sit for its scans to agree.

    python bench/gmapping/laser_frame.py                        # FR079 and belgioioso (PARAM -0.04 m), Intel
    python bench/gmapping/laser_frame.py --logs fr079 --offsets -0.04 0 0.04

A corrected log's FLASER records carry one pose twice (laser pose = robot pose), while some of them
keep the raw log's ``PARAM robot_frontlaser_offset`` (-0.04 m on FR079 and belgioioso). If the
poses were the robot's, with the laser that far ahead of it (behind, for a negative offset), the
scans would agree best when each is drawn from ``pose ⊕ (offset, 0, 0)``; if they are the laser's,
from the pose itself. The two differ only where the robot turns, so the test takes pairs of scans
at most 40 records and 2 m apart whose headings differ by 20-160 degrees (600 such pairs drawn
with seed 0), draws both from ``pose ⊕ (d, 0, 0)`` for each trial offset d, and scores each pair by
the mean distance from the second scan's points to the first's nearest (capped at 0.2 m: points
the other scan does not see). The offset of the smallest mean is where the laser is. Hits beyond
20 m are left out. Writes bench/gmapping/laser_frame.json (or --out).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
from _common import DATA, provenance  # noqa: E402

OFFSET_PARAM = "robot_frontlaser_offset"


def scan_points(frames: list[Any], reach: float = 20.0) -> list[np.ndarray]:
    """Each scan's hits (x, y) in the laser's frame, within ``reach``."""
    out = []
    for f in frames:
        r, a = np.asarray(f.ranges, dtype=float), np.asarray(f.angles, dtype=float)
        ok = np.isfinite(r) & (r > 0.05) & (r < reach)
        out.append(np.c_[r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok])])
    return out


def turning_pairs(poses: np.ndarray, pairs: int, seed: int) -> list[tuple[int, int]]:
    """Pairs (i, j), i < j < i + 40, at most 2 m apart, headings 20-160 degrees apart (``pairs`` drawn)."""
    from pfslam.geometry import wrap_angle

    found = []
    for i in range(len(poses)):
        j = np.arange(i + 1, min(len(poses), i + 40))
        turn = np.abs(wrap_angle(poses[j, 2] - poses[i, 2]))
        near = np.hypot(*(poses[j, :2] - poses[i, :2]).T) < 2.0
        keep = j[(turn > np.radians(20)) & (turn < np.radians(160)) & near]
        found += [(i, int(k)) for k in keep]
    if len(found) > pairs:
        pick = np.random.default_rng(seed).choice(len(found), pairs, replace=False)
        found = [found[k] for k in sorted(pick)]
    return found


def disagreement(poses: np.ndarray, points: list[np.ndarray], pairs: list[tuple[int, int]], offset: float) -> float:
    """Mean over ``pairs`` of the mean capped nearest-point distance (m), scans drawn from pose ⊕ (offset, 0, 0)."""
    from scipy.spatial import cKDTree

    from pfslam.geometry import compose, transform_points

    laser = compose(poses, np.array([offset, 0.0, 0.0]))
    scores = []
    for i, j in pairs:
        d, _ = cKDTree(transform_points(laser[i], points[i])).query(transform_points(laser[j], points[j]))
        scores.append(float(np.mean(np.minimum(d, 0.2))))
    return float(np.mean(scores))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--logs", nargs="+", default=["fr079", "belgioioso", "intel"], help="DATA/carmen/NAME.gfs.log.gz")
    ap.add_argument(
        "--offsets",
        nargs="+",
        type=float,
        default=[-0.08, -0.04, -0.02, -0.01, 0.0, 0.01, 0.02, 0.04, 0.08],
        help="trial laser offsets ahead of the pose (m)",
    )
    ap.add_argument("--pairs", type=int, default=600, help="pairs of scans drawn (default 600)")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().with_suffix(".json"))
    a = ap.parse_args()
    from pfslam.io.carmen import load_carmen

    rows = []
    for name in a.logs:
        log = load_carmen(DATA / "carmen" / f"{name}.gfs.log.gz")
        same = bool(np.allclose([f.mount[:3, 3][:2] for f in log.frames], 0.0))
        assert log.reference is not None
        pairs = turning_pairs(log.reference, a.pairs, seed=0)
        points = scan_points(log.frames)
        by_offset = {f"{d:+.3f}": round(disagreement(log.reference, points, pairs, d), 5) for d in a.offsets}
        best = min(by_offset, key=lambda k: by_offset[k])
        param = log.params.get(OFFSET_PARAM)
        rows.append(
            {
                "log": name,
                "scans": len(log.frames),
                "param_robot_frontlaser_offset": float(param) if param is not None else None,
                "laser_pose_equals_robot_pose": same,
                "pairs": len(pairs),
                "mean_nearest_point_distance_m_by_offset": by_offset,
                "best_offset_m": float(best),
            }
        )
        cells = ", ".join(f"{k} m {v * 100:.2f} cm" for k, v in by_offset.items())
        print(f"{name} (PARAM {param}, {len(pairs)} pairs): {cells}; best {best} m", flush=True)
    a.out.write_text(json.dumps({"provenance": provenance(), "rows": rows}, indent=2) + "\n")
    print(f"written {a.out}")


if __name__ == "__main__":
    main()
