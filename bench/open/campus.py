"""The campus drives behind bench/open/campus.yaml (issue 57): for each seed K, the outdoor
campus K (pfslam.tools.campus: about 250 x 250 m of buildings, trees, lamp poles, parked cars
and low walls, an open lawn wider than the laser's reach in the north-east, a 1.2-2 km route
round blocks and across the lawn) driven once round by a wheeled robot as `pfslam simulate
--world campus --robot wheeled --seed K` drives it: a SICK LMS (361 beams over 180 deg, 80 m),
1 m/s, the odometry's heading drifting 0.05 deg per metre, a ROS 1 bag with the odometry in
/tf. The drive's seed is the campus's, and so is the filter's in the sweep. Written once under
out/sims/campus/seedK (run from the repository root), with each campus's plan (lap, loops,
how much of the route is open ground, what stands on it) in out/sims/campus/campuses.json.

    python bench/open/campus.py --seeds 2      # seeds 0-1
    python bench/open/campus.py                # seeds 0-9
    pfslam sweep bench/open/campus.yaml -o out/campus

A drive takes about 10 s to simulate and 1 GB of memory while its true map is drawn (300 m
at 5 cm); it writes 65 MB (the bag and the map).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
from _common import provenance  # noqa: E402

from pfslam.tools.buildings import lap_length  # noqa: E402
from pfslam.tools.campus import campus, open_share, returns  # noqa: E402
from pfslam.tools.wheeled import drive  # noqa: E402


def plan(seed: int) -> dict[str, Any]:
    """The campus of ``seed`` as JSON values: its route and what stands on it."""
    c = campus(seed)
    w = c.world
    kinds = list(c.cells.values())
    return {
        "name": w.name,
        "lap_m": round(lap_length(w), 1),
        "waypoints": len(w.waypoints),
        "cells_driven_round": [list(cell) for cell in c.laps],
        "returns_100_400_m": len(returns(w.waypoints)),
        "open_share": round(open_share(w), 3),  # the route's share with < 80 segments within 80 m
        "segments": len(w.segments),
        "cells": {k: kinds.count(k) for k in ("building", "pair", "parking", "lawn")},
        "counts": c.counts,
    }


def one(seed: int, root: Path) -> str:
    """Drive campus ``seed`` once round (if not there yet); a line saying what and how long it took."""
    from pfslam.tools.wheeled import simulate_wheeled_bag

    out = root / f"seed{seed}"
    if (out / "groundtruth.tum").exists():
        return f"seed {seed}: {out} (there already)"
    d = drive("campus")
    t0 = time.perf_counter()
    res = simulate_wheeled_bag(
        "campus",
        d.duration_s,
        seed,
        out,
        max_range=d.max_range,
        beams=d.beams,
        fov_deg=d.fov_deg,
        speed=d.speed,
        heading_bias_deg_per_m=d.heading_bias_deg_per_m,
    )
    return f"seed {seed}: {out} ({len(res.t)} scans, {res.t[-1] - res.t[0]:.0f} s of drive in {time.perf_counter() - t0:.1f} s)"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/sims/campus", help="folder for the drives (default out/sims/campus)")
    ap.add_argument("--seeds", type=int, default=10, help="seeds 0..N-1 (default 10)")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    root = Path(args.out)
    root.mkdir(parents=True, exist_ok=True)
    manifest = {
        "about": "the drives of bench/open/campus.py: per seed, its campus (pfslam.tools.campus) and the drive",
        "drive": asdict(drive("campus")),
        "campuses": {str(seed): plan(seed) for seed in range(args.seeds)},
        "provenance": provenance(),
    }
    (root / "campuses.json").write_text(json.dumps(manifest, indent=1) + "\n")
    with ProcessPoolExecutor(args.workers) as pool:
        for f in [pool.submit(one, seed, root) for seed in range(args.seeds)]:
            print(f.result(), flush=True)


if __name__ == "__main__":
    main()
