"""The random buildings' walks behind bench/backend/buildings.yaml: for each seed K, the random
building K (pfslam.tools.buildings: a corridor loop round one block or a figure of eight round
two, 2-4 m wide, pillars, notches, doors and side rooms), walked once by the THOR humanoid and
driven once by a wheeled robot. The walk's seed is the building's, and so is the filter's in
the sweep. Written once under out/sims/buildings/{humanoid,wheeled}/seedK (run from the
repository root), with the parameters drawn for each walk in out/sims/buildings/walks.json.

Drawn from numpy.random.default_rng(K), in this order:

    humanoid  route loop or reverse; standing start 0-10 s; 1-3 laps at 0.5 m/s (fewer if
              the walk would pass HUMANOID_MAX_S; one lap fits, as a lap is at most 130 m);
              layout penn on even seeds, ucsd on odd ones (not drawn)
    wheeled   route; laser reach 10-30 m; field of view 180, 240, 270 or 360 deg (beams at
              0.375 deg, as the default 720 over 270); laser 0 m (over the axle) or 0.15-0.3 m
              ahead of it, half and half; standing start 0-10 s; 1-3 laps at 0.6 m/s; a ROS 1
              bag on even seeds, ROS 2 on odd ones (not drawn)

A walk lasts laps x lap / speed + the standing start + PAUSES_S per lap (the pauses the walk
makes at some corners and part-way along some runs). Each wheeled folder holds a link
``bag`` to its bag (log.bag or the ROS 2 folder log), so that the sweep spec names one path.

    python bench/backend/buildings.py --seeds 4     # seeds 0-3 of each kind
    python bench/backend/buildings.py               # seeds 0-99
    pfslam sweep bench/backend/buildings.yaml -o out/buildings
"""

from __future__ import annotations

import argparse
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from pfslam.tools.buildings import building, lap_length
from pfslam.tools.simcommon import MAX_DURATION
from pfslam.tools.walk import ROUTES
from pfslam.tools.wheeled import BAGS

HUMANOID_SPEED = 0.5  # m/s (pfslam.tools.walk.WALK_SPEED)
WHEELED_SPEED = 0.6  # m/s
PAUSES_S = 15.0  # s per lap: the walk's pauses (some corners, some runs)
HUMANOID_MAX_S = 300.0  # s: the longest humanoid walk
STAND_S = (0.0, 10.0)
LAPS = (1, 3)
RANGE_M = (10.0, 30.0)
FOVS_DEG = (180, 240, 270, 360)
LASER_X_M = (0.15, 0.3)
BEAM_DEG = 270.0 / 720.0  # the wheeled robot's default resolution


def _duration(laps: int, lap: float, speed: float, stand: float) -> float:
    return laps * (lap / speed + PAUSES_S) + stand


def plan(seed: int) -> dict[str, Any]:
    """The building of ``seed`` and the parameters of its two walks (all JSON values)."""
    b = building(seed)
    rng = np.random.default_rng(seed)
    lap = lap_length(b.world)  # (the reverse route is the same polyline, the other way round)
    about = {
        "name": b.world.name,
        "blocks": b.blocks,
        "width_m": b.width,
        "size_m": [round(v, 2) for v in b.size],
        "mirrored": b.mirrored,
        "lap_m": round(lap, 2),
        "runs_m": [round(r, 2) for r in b.runs()],
        "features": {k: sum(f.kind == k for f in b.features) for k in ("pillar", "notch", "room", "recess")},
        "longest_bare_m": round(b.bare(), 2),
    }
    # the humanoid
    route = str(rng.choice(ROUTES))
    stand = round(float(rng.uniform(*STAND_S)), 2)
    drawn = int(rng.integers(LAPS[0], LAPS[1] + 1))
    laps = drawn
    while laps > 1 and _duration(laps, lap, HUMANOID_SPEED, stand) > HUMANOID_MAX_S:
        laps -= 1
    humanoid = {
        "layout": "penn" if seed % 2 == 0 else "ucsd",
        "route": route,
        "stand_s": stand,
        "laps_drawn": drawn,
        "laps": laps,
        "speed_m_s": HUMANOID_SPEED,
        "duration_s": round(min(_duration(laps, lap, HUMANOID_SPEED, stand), HUMANOID_MAX_S, MAX_DURATION), 1),
    }
    # the wheeled robot
    route = str(rng.choice(ROUTES))
    max_range = round(float(rng.uniform(*RANGE_M)), 1)
    fov = int(rng.choice(FOVS_DEG))
    laser_x = 0.0 if rng.random() < 0.5 else round(float(rng.uniform(*LASER_X_M)), 3)
    stand = round(float(rng.uniform(*STAND_S)), 2)
    laps = int(rng.integers(LAPS[0], LAPS[1] + 1))
    beams = int(round(fov / BEAM_DEG))
    storage = "ros1" if seed % 2 == 0 else "ros2"
    wheeled = {
        "storage": storage,
        "bag": BAGS[storage],
        "route": route,
        "max_range_m": max_range,
        "fov_deg": fov,
        "beams": beams,
        "laser_x_m": laser_x,
        "stand_s": stand,
        "laps": laps,
        "speed_m_s": WHEELED_SPEED,
        "duration_s": round(min(_duration(laps, lap, WHEELED_SPEED, stand), MAX_DURATION), 1),
    }
    return {"building": about, "humanoid": humanoid, "wheeled": wheeled}


def one(kind: str, seed: int, p: dict[str, Any], root: Path) -> str:
    """Write one walk (if not there yet); a line saying what and how long it took."""
    from pfslam.tools.simulate import simulate
    from pfslam.tools.wheeled import simulate_wheeled_bag

    out = root / kind / f"seed{seed}"
    if (out / "groundtruth.tum").exists():
        return f"{kind} seed {seed}: {out} (there already)"
    t0 = time.perf_counter()
    if kind == "humanoid":
        simulate("random", p["duration_s"], seed, out, layout=p["layout"], route=p["route"], stand_s=p["stand_s"])
    else:
        fov = float(p["fov_deg"])
        if fov >= 360.0:  # all round: the last beam one step short of the first, not on it
            fov *= (p["beams"] - 1) / p["beams"]
        simulate_wheeled_bag(
            "random",
            p["duration_s"],
            seed,
            out,
            storage=p["storage"],
            route=p["route"],
            speed=p["speed_m_s"],
            beams=p["beams"],
            fov_deg=fov,
            max_range=p["max_range_m"],
            stand_s=p["stand_s"],
            laser_x=p["laser_x_m"],
        )
        link = out / "bag"
        if not link.is_symlink():
            os.symlink(p["bag"], link)  # relative: the bag beside it
    return f"{kind} seed {seed}: {out} ({p['duration_s']:g} s of walk in {time.perf_counter() - t0:.1f} s)"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/sims/buildings", help="folder for the walks (default out/sims/buildings)")
    ap.add_argument("--seeds", type=int, default=100, help="seeds 0..N-1 (default 100)")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    root = Path(args.out)
    plans = {seed: plan(seed) for seed in range(args.seeds)}
    root.mkdir(parents=True, exist_ok=True)
    manifest = {
        "about": "the walks of bench/backend/buildings.py: per seed, its building and each walk's parameters",
        "walks": {str(seed): p for seed, p in plans.items()},
    }
    (root / "walks.json").write_text(json.dumps(manifest, indent=1) + "\n")
    with ProcessPoolExecutor(args.workers) as pool:
        futures = [
            pool.submit(one, kind, seed, p[kind], root) for seed, p in plans.items() for kind in ("humanoid", "wheeled")
        ]
        for f in futures:
            print(f.result(), flush=True)


if __name__ == "__main__":
    main()
