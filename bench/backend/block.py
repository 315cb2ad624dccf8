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

import argparse
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

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
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/sims/block", help="folder for the walks (default out/sims/block)")
    ap.add_argument("--seeds", type=int, default=20, help="seeds 0..N-1 (default 20)")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    root = Path(args.out)
    with ProcessPoolExecutor(args.workers) as pool:
        futures = [pool.submit(one, k, s, root) for k in KINDS for s in range(args.seeds)]
        for f in futures:
            print(f.result(), flush=True)


if __name__ == "__main__":
    main()
