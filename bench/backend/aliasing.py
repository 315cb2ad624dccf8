"""The simulated walks behind bench/backend/aliasing.yaml and bench/backend/demo_seeds.yaml: each world's
THOR log per seed (the walk, the odometry's drift and the filter's seed are the same number),
written once under out/sims/WORLD/seedK (run from the repository root).

    python bench/backend/aliasing.py                      # pillars, rooms, twins: seeds 0-9; office: 0-19
    pfslam sweep bench/backend/aliasing.yaml -o out/aliasing
    pfslam sweep bench/backend/demo_seeds.yaml -o out/demo_seeds
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

WORLDS = {"pillars": range(10), "rooms": range(10), "twins": range(10), "office": range(20)}


def one(world: str, seed: int, root: Path) -> str:
    from pfslam.tools.simulate import simulate

    out = root / world / f"seed{seed}"
    if not (out / "groundtruth.tum").exists():
        simulate(world, 180.0, seed, out)
    return f"{world} seed {seed}: {out}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/sims", help="folder for the walks (default out/sims)")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    root = Path(args.out)
    with ProcessPoolExecutor(args.workers) as pool:
        futures = [pool.submit(one, w, s, root) for w, seeds in WORLDS.items() for s in seeds]
        for f in futures:
            print(f.result(), flush=True)


if __name__ == "__main__":
    main()
