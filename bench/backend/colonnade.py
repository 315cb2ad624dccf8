"""The colonnade's one-lap drives behind bench/backend/colonnade.yaml (issue 53): a 3 m corridor
loop round a central block lined with 0.5 m pillars at uneven spacing (a pillar's two faces lie
half a metre apart: a scan that sees one fits the other almost as well), driven once round by a
wheeled robot with a 270 deg, 25 m laser, written as ROS 1 (counter-clockwise) and ROS 2
(clockwise) bags with the odometry in /tf. The walk, the odometry's drift and the filter's seed
are the same number. Written once under out/sims/onelap/colonnade/KIND/seedK (run from the
repository root).

    python bench/backend/colonnade.py               # seeds 0-19 of each kind
    pfslam sweep bench/backend/colonnade.yaml -o out/colonnade
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
from _common import write_walks  # noqa: E402

KINDS = ("ros1", "ros2")
DRIVE_S = 192.0  # s: one lap (98 m at 0.6 m/s) with the standing start and the pauses
RANGE_M = 25.0


def one(kind: str, seed: int, root: Path) -> str:
    from pfslam.tools.wheeled import simulate_wheeled_bag

    out = root / kind / f"seed{seed}"
    if not (out / "groundtruth.tum").exists():
        route = "reverse" if kind == "ros2" else "loop"
        simulate_wheeled_bag("colonnade", DRIVE_S, seed, out, storage=kind, max_range=RANGE_M, route=route)
    return f"{kind} seed {seed}: {out}"


def main() -> None:
    write_walks(__doc__ or "", one, KINDS, "out/sims/onelap/colonnade")


if __name__ == "__main__":
    main()
