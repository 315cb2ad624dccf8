"""Walks where the walls say little (issue 44, "a scan match that knows what it pins"), and
their errors along and across the way walked.

Two simulated worlds, each driven by the wheeled robot (ROS 1 bag, odometry in /tf, drifting
0.3 deg/m): ``bare``, 100 m of corridor 2.4 m wide with a door recess every 25 m, driven
out and back with a 20 m laser; and ``hall``, an open 30 x 20 m hall with six pillars,
driven twice round a 20 x 10 m loop 5 m inside its walls with a 5.6 m laser (a Hokuyo
URG's reach). The walk, the odometry's drift and the filter's seed are the same number.

    python bench/scanmatch/scanmatch.py                    # write the walks under out/sims/scanmatch
    pfslam sweep bench/scanmatch/scanmatch.yaml -o out/scanmatch
    python bench/scanmatch/scanmatch.py --errors out/scanmatch   # along / across errors of each run

``--errors`` splits each run's position error (its trajectory against the ground truth, both
start-relative, not aligned: the start is where both agree) into the part along the way the
robot was going and the part across it, and reports the RMS and the worst of each: along a
bare corridor a scan pins the pose across and hardly along.
"""

from __future__ import annotations

import argparse
import json
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

WALKS = {"bare": (360.0, 20.0), "hall": (240.0, 5.6)}  # world: (seconds, laser range m)


def one(world: str, seed: int, root: Path) -> str:
    from pfslam.tools.wheeled import simulate_wheeled_bag

    out = root / world / f"seed{seed}"
    seconds, reach = WALKS[world]
    if not (out / "groundtruth.tum").exists():
        simulate_wheeled_bag(world, seconds, seed, out, storage="ros1", max_range=reach)
    return f"{world} seed {seed}: {out}"


def along_across(est_t: np.ndarray, est: np.ndarray, t: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    """RMS and worst position error along the truth's heading and across it (m)."""
    from pfslam.eval.metrics import associate

    i, j = associate(est_t, t)
    d = est[i, :2] - truth[j, :2]
    c, s = np.cos(truth[j, 2]), np.sin(truth[j, 2])
    along = c * d[:, 0] + s * d[:, 1]
    across = -s * d[:, 0] + c * d[:, 1]
    return {
        "along_rms": float(np.sqrt(np.mean(along**2))),
        "along_max": float(np.abs(along).max()),
        "across_rms": float(np.sqrt(np.mean(across**2))),
        "across_max": float(np.abs(across).max()),
    }


def errors(sweep: Path) -> None:
    from pfslam.io.trajectory import read_tum

    rows = []
    for tum in sorted(sweep.glob("runs/**/trajectory.tum")):
        run = tum.parent
        log = Path(json.loads((run / "run.json").read_text())["input"]["log"])
        gt = log.parent / "groundtruth.tum"  # written beside each walk's bag
        if not gt.exists():
            continue
        t, est = read_tum(tum)
        tt, truth = read_tum(gt)
        e = along_across(t, est, tt, truth)
        to, odo = read_tum(run / "odometry.tum")
        e["odometry_along_rms"] = along_across(to, odo, tt, truth)["along_rms"]
        rows.append((str(run.relative_to(sweep / "runs")), e))
    if not rows:
        raise SystemExit(f"no run with a trajectory and a ground truth under {sweep / 'runs'}")
    print(
        f"{'run':32s} {'along rms':>10s} {'along max':>10s} {'across rms':>11s} {'across max':>11s} {'odometry along rms':>19s}"
    )
    for name, e in rows:
        print(
            f"{name:32s} {e['along_rms']:10.3f} {e['along_max']:10.3f} {e['across_rms']:11.3f} {e['across_max']:11.3f}"
            f" {e['odometry_along_rms']:19.3f}"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/sims/scanmatch", help="folder for the walks (default out/sims/scanmatch)")
    ap.add_argument("--seeds", type=int, default=5, help="seeds 0..N-1 (default 5)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--errors", type=Path, help="a sweep's output folder: print its runs' along / across errors")
    args = ap.parse_args()
    if args.errors is not None:
        errors(args.errors)
        return
    root = Path(args.out)
    with ProcessPoolExecutor(args.workers) as pool:
        futures = [pool.submit(one, w, s, root) for w in WALKS for s in range(args.seeds)]
        for f in futures:
            print(f.result(), flush=True)


if __name__ == "__main__":
    main()
