"""Localization throughput in beam-particle evaluations per second on one core, beside the
figure Beluga AMCL publishes (issue 46, deliverable 3).

Beluga reports about 0.85 ms per update at 1,000 particles and 100 beams on one core: about
1.2 x 10^8 beam-particle evaluations per second. Here the same count is taken of a whole
``Localizer.step`` (motion, sensor model, weights, estimate, resampling when due) on a
simulated office walk: a fixed particle count (no KLD), 100 beams, an update every scan, for
the likelihood field (as read by default, bilinearly, and by cell) and the beam model;
``particles x 100 x updates / seconds``. Each figure is a separate process with
``NUMBA_NUM_THREADS=1`` (one core), best of three rounds, the trees alternating round by
round when ``--before`` names another tree's src.

    python bench/localize/throughput.py                           # this tree
    python bench/localize/throughput.py --before /tmp/old/src     # and another, alternately

Writes bench/localize/throughput.json.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
from _common import ROOT, provenance  # noqa: E402

HERE = Path(__file__).resolve().parent
BELUGA = 1.2e8  # beam-particle evaluations per second on one core (0.85 ms at 1,000 x 100)
BEAMS = 100
MODELS = {
    "likelihood_field": {},
    "likelihood_field_cells": {"interpolate": False},
    "beam": {"model": "beam"},
}
CACHE = Path(tempfile.gettempdir()) / "pfslam-bench-throughput"


def work(particles: int, model: str, scans: int) -> dict[str, float]:
    """One measurement, in this process: evaluations per second over ``scans`` updates."""
    import numpy as np

    from pfslam.config import LocalizerConfig
    from pfslam.filters.localize import Localizer
    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import read_tum
    from pfslam.maps.grid import OccupancyGrid
    from pfslam.tools.simulate import simulate

    if not (CACHE / "map.yaml").exists():
        simulate("office", 60.0, seed=1, out_dir=CACHE)
    frames = load_log(CACHE / "train_lidar0.mat", CACHE / "train_joint0.mat").frames
    _, truth = read_tum(CACHE / "groundtruth.tum")
    cfg = LocalizerConfig(
        particles=particles,
        kld=False,
        recovery=False,
        update_min_d=0.0,
        update_min_a=0.0,
        beams=BEAMS,
        min_particles=min(500, particles),
        max_particles=max(5000, particles),
        **MODELS[model],
    )
    loc = Localizer(OccupancyGrid.load_ros(CACHE / "map.yaml"), cfg)
    loc.initialize_around(truth[0], np.array([0.1, 0.1, 0.05]))
    for f in frames[:10]:  # compile and warm up
        loc.step(f)
    use = frames[10 : 10 + scans]
    t0 = time.perf_counter()
    for f in use:
        loc.step(f)
    seconds = time.perf_counter() - t0
    return {"updates_per_s": len(use) / seconds, "evaluations_per_s": particles * BEAMS * len(use) / seconds}


def measure(src: str, particles: int, model: str, scans: int) -> dict[str, float]:
    """One measurement in a fresh process on ``src``'s code, on one core."""
    env = {**os.environ, "PYTHONPATH": src, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    arg = json.dumps([particles, model, scans])
    out = subprocess.run(
        [sys.executable, __file__, "--worker", arg], env=env, capture_output=True, text=True, check=True
    ).stdout
    return dict(json.loads(out.splitlines()[-1]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--before", help="another tree's src, measured alternately")
    ap.add_argument("--particles", type=int, nargs="+", default=[1000, 10000, 100000])
    ap.add_argument("--models", nargs="+", default=list(MODELS))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", type=Path, default=HERE / "throughput.json")
    a = ap.parse_args()
    if a.worker:
        particles, model, scans = json.loads(a.worker)
        print(json.dumps(work(particles, model, scans)))
        return
    trees = {"this": str(ROOT / "src"), **({"before": a.before} if a.before else {})}
    rows = []
    for model in a.models:
        for n in a.particles:
            scans = max(20, min(400, 4_000_000 // n))  # about the same work at every count
            best: dict[str, dict[str, float]] = {}
            for _ in range(a.rounds):
                for name, src in trees.items():
                    r = measure(src, n, model, scans)
                    if name not in best or r["evaluations_per_s"] > best[name]["evaluations_per_s"]:
                        best[name] = r
            row = {"model": model, "particles": n, "beams": BEAMS, "updates": scans}
            for name, r in best.items():
                row[f"{name}_evaluations_per_s"] = round(r["evaluations_per_s"])
                row[f"{name}_updates_per_s"] = round(r["updates_per_s"], 2)
                row[f"{name}_vs_beluga"] = round(r["evaluations_per_s"] / BELUGA, 2)
            rows.append(row)
            print(json.dumps(row))
    result = {"provenance": provenance(), "beluga_evaluations_per_s": BELUGA, "rows": rows}
    a.out.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
