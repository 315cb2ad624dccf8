"""pfslam benchmark: throughput of SLAM and of its kernels on fixed, seeded simulated logs.

    python bench/run.py            # full run, writes bench/results.json
    python bench/run.py --quick    # a smaller run for a quick look

Every figure is a throughput (scans per second, real-time factor, particle-beam
evaluations per second, cell updates per second) or a ratio to the NumPy twins of the
kernels, measured in the same run on the same input.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def sim_log(tmp: Path, seconds: float, seed: int = 7):
    from pfslam.io.logs import load_log
    from pfslam.simulate import simulate

    res = simulate("office", seconds, seed=seed, out_dir=tmp / f"sim_{int(seconds)}")
    return load_log(res.lidar_path, res.joint_path).frames


def slam_rate(frames, particles: int, search: bool, backend: str = "numba", max_hits: int | None = None,
              resolution: float | None = None) -> dict:
    from pfslam.config import SlamConfig
    from pfslam.slam import Slam

    cfg = SlamConfig(particles=particles, seed=1)
    cfg.search.enabled = search
    if max_hits is not None:
        cfg.sensor.max_hits = max_hits
    if resolution is not None:
        cfg.map.resolution = resolution
    s = Slam(cfg, backend=backend)
    s.step(frames[0])
    t0 = time.perf_counter()
    for f in frames[1:]:
        s.step(f)
    dt = time.perf_counter() - t0
    n = len(frames) - 1
    span = frames[-1].t - frames[1].t
    return {"particles": particles, "search": search, "backend": backend, "scans": n,
            "max_hits": cfg.sensor.max_hits, "resolution": cfg.map.resolution, "map_cells": int(s.grid.logodds.size),
            "scans_per_s": n / dt, "real_time_factor": span / dt}


def wheeled_rate() -> dict | None:
    """SLAM on the real wheeled-robot logs in ../shared/data (PFSLAM_DATA), if present."""
    from pfslam.io.logs import load_log

    data = Path(os.environ.get("PFSLAM_DATA", HERE.parent.parent / "shared" / "data"))
    out = {}
    for name, rel, kw in (("mines_exp2 (wheel encoders)", "mines/exp2.dat", {}),
                          ("fr079 (CARMEN, synthetic odometry)", "carmen/fr079.gfs.log.gz", {"odometry": "synthetic"})):
        p = data / rel
        if not p.exists():
            continue
        frames = load_log(p, **kw).frames
        r = slam_rate(frames, 100, False)
        out[name] = r
        print(f"SLAM on {name}: {r['scans_per_s']:.0f} scans/s ({r['real_time_factor']:.0f}x real time)", flush=True)
    return out or None


def kernel_rates(frames) -> dict:
    from pfslam.config import SlamConfig
    from pfslam.kernels import correlation_kernel, correlation_numpy, ray_update_kernel, ray_update_numpy
    from pfslam.pipeline import build_map
    from pfslam.sensor import scan_to_points

    grid = build_map(frames[:400], np.array([f.odom for f in frames[:400]]), SlamConfig())
    sp = scan_to_points(frames[300])
    pts = np.ascontiguousarray(sp.hits[:400])
    rng = np.random.default_rng(0)
    out = {}
    poses = np.column_stack([rng.normal(0, 0.05, 100), rng.normal(0, 0.05, 100), rng.normal(0, 0.01, 100)])
    args = (poses, pts, grid.logodds, float(grid.origin[0]), float(grid.origin[1]), 20.0, 1 / 6, 0.0)
    correlation_kernel(*args)
    for name, fn, reps in (("numba", correlation_kernel, 200), ("numpy", correlation_numpy, 20)):
        t0 = time.perf_counter()
        for _ in range(reps):
            fn(*args)
        out[f"correlation_{name}_evals_per_s"] = reps * len(poses) * len(pts) / (time.perf_counter() - t0)
    ends = np.ascontiguousarray(sp.hits + 0.0)
    hit = np.ones(len(ends), bool)
    cells = 0
    for e in ends:  # cells touched per scan, counted exactly
        cells += abs(int(np.floor(e[0] / 0.05))) + abs(int(np.floor(e[1] / 0.05))) + 1
    for name, fn, reps in (("numba", ray_update_kernel, 200), ("numpy", ray_update_numpy, 3)):
        lo = grid.logodds.copy()
        stamp = np.zeros(lo.shape, np.int32)
        fn(lo, float(grid.origin[0]), float(grid.origin[1]), 20.0, 0.0, 0.0, ends, hit, 3.0, -1.0, 120.0, stamp, 1)
        t0 = time.perf_counter()
        for r in range(reps):
            fn(lo, float(grid.origin[0]), float(grid.origin[1]), 20.0, 0.0, 0.0, ends, hit, 3.0, -1.0, 120.0, stamp,
               r + 2)
        out[f"ray_update_{name}_cells_per_s"] = reps * cells / (time.perf_counter() - t0)
    out["correlation_speedup"] = out["correlation_numba_evals_per_s"] / out["correlation_numpy_evals_per_s"]
    out["ray_update_speedup"] = out["ray_update_numba_cells_per_s"] / out["ray_update_numpy_cells_per_s"]
    return out


def localization_rates(frames, tmp: Path) -> list[dict]:
    """Updates per second of Monte Carlo localization (fixed particle count, 60 beams)."""
    from pfslam.grid import OccupancyGrid
    from pfslam.localize import Localizer, LocalizerConfig

    grid = OccupancyGrid.load_ros(tmp / "sim_120" / "map.yaml") if (tmp / "sim_120").exists() else \
        OccupancyGrid.load_ros(tmp / "sim_30" / "map.yaml")
    rows = []
    for n in (500, 5000, 50000):
        cfg = LocalizerConfig(particles=n, kld=False, recovery=False, update_min_d=0.0, update_min_a_deg=0.0,
                              beams=60, min_particles=min(500, n), max_particles=max(5000, n))
        for backend in ("numba", "numpy"):
            loc = Localizer(grid, cfg, backend=backend)
            loc.initialize_around(np.zeros(3), np.array([0.1, 0.1, 0.05]))
            loc.step(frames[0])
            use = frames[1:200] if backend == "numba" else frames[1:20]
            t0 = time.perf_counter()
            for f in use:
                loc.step(f)
            dt = time.perf_counter() - t0
            rows.append({"particles": n, "backend": backend, "beams": 60, "updates_per_s": len(use) / dt,
                         "particle_beam_evals_per_s": len(use) * n * 60 / dt})
            print(f"localization {n:6d} particles ({backend}): {rows[-1]['updates_per_s']:8.1f} updates/s", flush=True)
    return rows


def long_run(frames) -> dict:
    """Per-scan time at the start and the end of a long run, and the peak RSS."""
    from pfslam.config import SlamConfig
    from pfslam.slam import Slam

    s = Slam(SlamConfig(seed=1))
    times = np.empty(len(frames))
    for i, f in enumerate(frames):
        t0 = time.perf_counter()
        s.step(f)
        times[i] = time.perf_counter() - t0
    k = min(1000, len(frames) // 3)
    first, last = times[1 : k + 1].mean(), times[-k:].mean()
    return {"scans": len(frames), "first_ms": 1e3 * first, "last_ms": 1e3 * last, "last_over_first": last / first,
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
            "map_cells": int(s.grid.logodds.size)}


STARTUP = """
import time, sys
t0 = time.perf_counter()
from pfslam.io.logs import load_log
from pfslam.slam import Slam
frames = load_log(sys.argv[1], sys.argv[2]).frames
s = Slam()
s.step(frames[0]); s.step(frames[1])
print(time.perf_counter() - t0)
"""


def startup(tmp: Path) -> dict:
    from pfslam.simulate import simulate

    res = simulate("office", 10.0, seed=1, out_dir=tmp / "startup")
    cache = tmp / "numba_cache"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    out = {}
    for label in ("cold_cache_s", "warm_cache_s"):
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-c", STARTUP, str(res.lidar_path), str(res.joint_path)],
                           env=env, capture_output=True, text=True, check=True)
        out[label] = time.perf_counter() - t0
        out[label.replace("_s", "_inside_s")] = float(r.stdout.strip().splitlines()[-1])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer scans, no long run")
    ap.add_argument("--out", type=Path, default=HERE / "results.json")
    a = ap.parse_args()
    import numba

    res: dict = {"machine": {"python": platform.python_version(), "cpu": platform.processor() or platform.machine(),
                             "cores": os.cpu_count(), "numba": numba.__version__, "numpy": np.__version__,
                             "numba_threads": numba.get_num_threads()}}
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        res["startup"] = startup(tmp)
        print(f"start-up to the first SLAM step: cold numba cache {res['startup']['cold_cache_s']:.1f} s, "
              f"warm {res['startup']['warm_cache_s']:.1f} s", flush=True)
        frames = sim_log(tmp, 30.0 if a.quick else 120.0)
        rows = []
        from pfslam.config import SlamConfig

        sc = SlamConfig().search
        grid = (2 * sc.radius_cells + 1) ** 2 * (2 * sc.theta_steps + 1)  # offsets tried per particle
        for n in (30, 100, 300, 1000):
            for search in (False, True):
                k = len(frames) if n * (grid if search else 1) <= 3000 else min(len(frames), 600)
                rows.append(slam_rate(frames[:k], n, search))
                print(f"SLAM {n:5d} particles search={search!s:5}: {rows[-1]['scans_per_s']:8.1f} scans/s "
                      f"({rows[-1]['real_time_factor']:.1f}x real time)", flush=True)
        twin = slam_rate(frames[:120], 100, False, backend="numpy")
        fast = slam_rate(frames[:120], 100, False)
        twin["numba_ratio"] = fast["scans_per_s"] / twin["scans_per_s"]
        rows.append(twin)
        print(f"SLAM 100 particles, NumPy twins: {twin['scans_per_s']:.1f} scans/s "
              f"(Numba is {twin['numba_ratio']:.0f}x faster)", flush=True)
        res["slam"] = rows
        growth = []
        for hits in (100, 200, 400, 800):
            growth.append(slam_rate(frames[:1200], 100, False, max_hits=hits))
            print(f"SLAM 100 particles, {hits:4d} hits scored: {growth[-1]['scans_per_s']:8.1f} scans/s", flush=True)
        for res_m in (0.1, 0.05, 0.025):
            growth.append(slam_rate(frames[:1200], 100, False, resolution=res_m))
            print(f"SLAM 100 particles, {res_m} m cells ({growth[-1]['map_cells']} cells): "
                  f"{growth[-1]['scans_per_s']:8.1f} scans/s", flush=True)
        res["slam_growth"] = growth
        res["wheeled"] = wheeled_rate()
        res["localization"] = localization_rates(frames, tmp)
        res["kernels"] = kernel_rates(frames)
        print(json.dumps(res["kernels"], indent=1), flush=True)
        if not a.quick:
            long_frames = sim_log(tmp, 750.0, seed=3)  # 30,000 scans at 40 Hz
            res["long_run"] = long_run(long_frames)
            print(json.dumps(res["long_run"], indent=1), flush=True)
    a.out.write_text(json.dumps(res, indent=2))
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
