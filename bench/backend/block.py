"""The block building's walks behind bench/backend/block.yaml (issue 43): a 3 m corridor all round a
central block (runs of 32 and 16 m, mostly bare walls, pillars and notches every 8 m along
one run), walked by the THOR humanoid (Penn layout, a lap and a bit; UCSD layout, the other way
round) and driven by a wheeled robot written as ROS 1 and ROS 2
bags with its odometry in /tf (two laps). The walk, the odometry's drift and the filter's
seed are the same number. Written once under out/sims/block/KIND/seedK (run from the
repository root).

    python bench/backend/block.py                  # seeds 0-19 of each kind
    pfslam sweep bench/backend/block.yaml -o out/block
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
from _common import write_walks  # noqa: E402

KINDS = ("penn", "ucsd", "ros1", "ros2")
HUMANOID_S = 230.0  # s: a lap (96 m at 0.5 m/s, with pauses) and a few metres more
WHEELED_S = 330.0  # s: two laps at 0.6 m/s


def one(kind: str, seed: int, root: Path) -> str:
    from pfslam.tools.simulate import simulate
    from pfslam.tools.wheeled import simulate_wheeled_bag

    out = root / kind / f"seed{seed}"
    if not (out / "groundtruth.tum").exists():
        if kind == "penn":
            simulate("block", HUMANOID_S, seed, out, layout="penn")
        elif kind == "ucsd":
            simulate("block", HUMANOID_S, seed, out, layout="ucsd", route="reverse")
        else:
            simulate_wheeled_bag(
                "block", WHEELED_S, seed, out, storage=kind, route="reverse" if kind == "ros2" else "loop"
            )
    return f"{kind} seed {seed}: {out}"


def main() -> None:
    write_walks(__doc__ or "", one, KINDS, "out/sims/block")


if __name__ == "__main__":
    main()
