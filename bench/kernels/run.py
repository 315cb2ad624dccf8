"""pfslam benchmark: throughput of SLAM and of its kernels on fixed, seeded simulated logs.

    python bench/kernels/run.py            # full run, writes bench/kernels/results.json
    python bench/kernels/run.py --quick    # a smaller run for a quick look

Every figure is a throughput (scans per second, real-time factor, particle-beam
evaluations per second, cell updates per second) or a ratio to the NumPy twins of the
kernels, measured in the same run on the same input. The result records the commit, machine and
date that made it (``provenance``).
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

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
from _common import DATA, cpu_model, provenance  # noqa: E402

HERE = Path(__file__).resolve().parent


def sim_log(tmp: Path, seconds: float, seed: int = 7):
    from pfslam.io.logs import load_log
    from pfslam.tools.simulate import simulate

    res = simulate("office", seconds, seed=seed, out_dir=tmp / f"sim_{int(seconds)}")
    return load_log(res.lidar_path, res.joint_path).frames


def slam_rate(
    frames,
    particles: int,
    search: bool,
    backend: str = "numba",
    max_hits: int | None = None,
    resolution: float | None = None,
) -> dict:
    from pfslam.config import SlamConfig, with_values
    from pfslam.filters.single import SingleMapSlam

    values = {
        "particles": particles,
        "seed": 1,
        "local_search.enabled": search,
        "sensor.max_hits": max_hits,
        "map.resolution": resolution,
    }
    cfg = with_values(SlamConfig(), {k: v for k, v in values.items() if v is not None})
    s = SingleMapSlam(cfg, kernels=backend)
    s.step(frames[0])
    t0 = time.perf_counter()
    for f in frames[1:]:
        s.step(f)
    dt = time.perf_counter() - t0
    n = len(frames) - 1
    span = frames[-1].t - frames[1].t
    return {
        "particles": particles,
        "search": search,
        "backend": backend,
        "scans": n,
        "max_hits": cfg.sensor.max_hits,
        "resolution": cfg.map.resolution,
        "map_cells": int(s.grid.logodds.size),
        "scans_per_s": n / dt,
        "real_time_factor": span / dt,
    }


def wheeled_rate() -> dict | None:
    """SLAM on the real wheeled-robot logs in ../shared/data (PFSLAM_DATA), if present."""
    from pfslam.io.logs import load_log

    data = DATA
    out = {}
    for name, rel, kw in (
        ("mines_exp2 (wheel encoders)", "mines/exp2.dat", {}),
        ("fr079 (CARMEN, synthetic odometry)", "carmen/fr079.gfs.log.gz", {"odometry": "synthetic"}),
    ):
        p = data / rel
        if not p.exists():
            continue
        frames = load_log(p, **kw).frames
        r = slam_rate(frames, 100, False)
        out[name] = r
        print(f"SLAM on {name}: {r['scans_per_s']:.0f} scans/s ({r['real_time_factor']:.0f}x real time)", flush=True)
    return out or None


def _per_call(fn, args, budget: float = 0.3) -> float:
    """Seconds per call: the best of three timed batches of about ``budget`` / 3 seconds."""
    fn(*args)
    t0 = time.perf_counter()
    fn(*args)
    reps = max(1, int(budget / 3 / max(time.perf_counter() - t0, 1e-7)))
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        for _ in range(reps):
            fn(*args)
        best = min(best, (time.perf_counter() - t0) / reps)
    return best


def kernel_rates(frames) -> list[dict]:
    """Every kernel against its NumPy twin on the same input (100 particles unless said)."""
    from pfslam.config import SlamConfig
    from pfslam.kernels import likelihood as KL
    from pfslam.kernels import raycast as KR
    from pfslam.kernels import resample as KP
    from pfslam.kernels import scoring as KS
    from pfslam.pipeline import build_map
    from pfslam.sensor import scan_to_points

    cfg = SlamConfig()
    grid = build_map(frames[:400], np.array([f.odom for f in frames[:400]]), cfg)
    sp = scan_to_points(frames[300])
    pts = np.ascontiguousarray(sp.hits[:400])
    rng = np.random.default_rng(0)
    ox, oy, inv = float(grid.origin[0]), float(grid.origin[1]), 1.0 / grid.resolution

    def poses(n):
        return np.column_stack([rng.normal(0, 0.05, n), rng.normal(0, 0.05, n), rng.normal(0, 0.01, n)])

    sc = cfg.local_search
    dcells = np.array([0] + [s * k for k in range(1, sc.radius_cells + 1) for s in (-1, 1)], dtype=np.int64)
    dthetas = np.deg2rad(sc.theta_step_deg) * np.array(
        [0] + [s * k for k in range(1, sc.theta_steps + 1) for s in (-1, 1)], dtype=float
    )
    logp = np.log(np.clip(grid.logodds / 6.0 + 0.5, 1e-3, 1.0)).astype(np.float32)
    w100, w10k = rng.random(100), rng.random(10_000)
    corr = (grid.logodds, ox, oy, inv, 1 / cfg.sensor.saturation, 0.0)
    cases = [
        (
            "correlation scoring",
            "100 particles x 400 hits",
            "particle-beam evaluations",
            100 * 400,
            KS.correlation_kernel,
            KS.correlation_numpy,
            (poses(100), pts) + corr,
        ),
        (
            "local x/y/theta search",
            f"100 particles x 400 hits x {len(dcells) ** 2 * len(dthetas)} offsets",
            "particle-beam evaluations",
            100 * 400 * len(dcells) ** 2 * len(dthetas),
            KS.local_search_kernel,
            KS.local_search_numpy,
            (poses(100), pts) + corr + (dcells, dthetas),
        ),
        (
            "likelihood-field lookup",
            "100 particles x 400 beams",
            "particle-beam evaluations",
            100 * 400,
            KL.likelihood_kernel,
            KL.likelihood_numpy,
            (poses(100), pts, logp, ox, oy, inv, -7.0),
        ),
        (
            "likelihood-field lookup",
            "5,000 particles x 60 beams",
            "particle-beam evaluations",
            5000 * 60,
            KL.likelihood_kernel,
            KL.likelihood_numpy,
            (poses(5000), pts[::7][:60], logp, ox, oy, inv, -7.0),
        ),
        (
            "systematic resampling",
            "100 particles",
            "particles",
            100,
            KP.systematic_kernel,
            KP.systematic_numpy,
            (w100 / w100.sum(), 0.37, np.empty(100, np.int64)),
        ),
        (
            "systematic resampling",
            "10,000 particles",
            "particles",
            10_000,
            KP.systematic_kernel,
            KP.systematic_numpy,
            (w10k / w10k.sum(), 0.37, np.empty(10_000, np.int64)),
        ),
    ]
    out = []
    for name, shape, unit, work, kern, twin, args in cases:
        tk, tt = _per_call(kern, args), _per_call(twin, args)
        out.append(
            {
                "kernel": name,
                "input": shape,
                "unit": unit,
                "numba_per_s": work / tk,
                "numpy_per_s": work / tt,
                "ratio": tt / tk,
            }
        )
    # Ray update: cells crossed per scan counted exactly; the twin is a loop over beams.
    ends = np.ascontiguousarray(sp.hits + 0.0)
    hit = np.ones(len(ends), bool)
    cells = sum(abs(int(np.floor(e[0] / 0.05))) + abs(int(np.floor(e[1] / 0.05))) + 1 for e in ends)
    lo = grid.logodds.copy()
    stamp = np.zeros(lo.shape, np.int32)
    counter = iter(range(2, 10**9))

    def ray(fn):
        return lambda: fn(lo, ox, oy, inv, 0.0, 0.0, ends, hit, 3.0, -1.0, 120.0, stamp, next(counter))

    tk, tt = _per_call(ray(KR.ray_update_kernel), ()), _per_call(ray(KR.ray_update_numpy), (), budget=1.0)
    out.append(
        {
            "kernel": "ray update of the grid",
            "input": f"one scan, {len(ends)} beams",
            "unit": "cell updates",
            "numba_per_s": cells / tk,
            "numpy_per_s": cells / tt,
            "ratio": tt / tk,
        }
    )
    return out


def localization_rates(frames, tmp: Path) -> list[dict]:
    """Updates per second of Monte Carlo localization (fixed particle count, 60 beams)."""
    from pfslam.config import LocalizerConfig
    from pfslam.filters.localize import Localizer
    from pfslam.maps.grid import OccupancyGrid

    grid = (
        OccupancyGrid.load_ros(tmp / "sim_120" / "map.yaml")
        if (tmp / "sim_120").exists()
        else OccupancyGrid.load_ros(tmp / "sim_30" / "map.yaml")
    )
    rows = []
    for n in (500, 5000, 50000):
        cfg = LocalizerConfig(
            particles=n,
            kld=False,
            recovery=False,
            update_min_d=0.0,
            update_min_a=0.0,
            beams=60,
            min_particles=min(500, n),
            max_particles=max(5000, n),
        )
        for backend in ("numba", "numpy"):
            loc = Localizer(grid, cfg, kernels=backend)
            loc.initialize_around(np.zeros(3), np.array([0.1, 0.1, 0.05]))
            loc.step(frames[0])
            use = frames[1:200] if backend == "numba" else frames[1:20]
            t0 = time.perf_counter()
            for f in use:
                loc.step(f)
            dt = time.perf_counter() - t0
            rows.append(
                {
                    "particles": n,
                    "backend": backend,
                    "beams": 60,
                    "updates_per_s": len(use) / dt,
                    "particle_beam_evals_per_s": len(use) * n * 60 / dt,
                }
            )
            print(f"localization {n:6d} particles ({backend}): {rows[-1]['updates_per_s']:8.1f} updates/s", flush=True)
    return rows


def long_run(frames) -> dict:
    """Per-scan time at the start and the end of a long run, and the peak RSS."""
    from pfslam.config import SlamConfig
    from pfslam.filters.single import SingleMapSlam

    s = SingleMapSlam(SlamConfig(seed=1))
    times = np.empty(len(frames))
    for i, f in enumerate(frames):
        t0 = time.perf_counter()
        s.step(f)
        times[i] = time.perf_counter() - t0
    k = min(1000, len(frames) // 3)
    first, last = times[1 : k + 1].mean(), times[-k:].mean()
    return {
        "scans": len(frames),
        "first_ms": 1e3 * first,
        "last_ms": 1e3 * last,
        "last_over_first": last / first,
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "map_cells": int(s.grid.logodds.size),
    }


STARTUP = """
import time, sys
t0 = time.perf_counter()
from pfslam.io.logs import load_log
from pfslam.filters.single import SingleMapSlam
frames = load_log(sys.argv[1], sys.argv[2]).frames
s = SingleMapSlam()
s.step(frames[0]); s.step(frames[1])
print(time.perf_counter() - t0)
"""


def startup(tmp: Path) -> dict:
    from pfslam.tools.simulate import simulate

    res = simulate("office", 10.0, seed=1, out_dir=tmp / "startup")
    cache = tmp / "numba_cache"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    out = {}
    for label in ("cold_cache_s", "warm_cache_s"):
        t0 = time.perf_counter()
        r = subprocess.run(
            [sys.executable, "-c", STARTUP, str(res.lidar_path), str(res.joint_path)],
            env=env,
            capture_output=True,
            text=True,
            check=True,
        )
        out[label] = time.perf_counter() - t0
        out[label.replace("_s", "_inside_s")] = float(r.stdout.strip().splitlines()[-1])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer scans, no long run")
    ap.add_argument("--out", type=Path, default=HERE / "results.json")
    a = ap.parse_args()
    import numba

    res: dict = {
        "provenance": provenance(),
        "machine": {
            "python": platform.python_version(),
            "cpu": cpu_model(),
            "cores": os.cpu_count(),
            "numba": numba.__version__,
            "numpy": np.__version__,
            "numba_threads": numba.get_num_threads(),
        },
    }
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        res["startup"] = startup(tmp)
        print(
            f"start-up to the first SLAM step: cold numba cache {res['startup']['cold_cache_s']:.1f} s, "
            f"warm {res['startup']['warm_cache_s']:.1f} s",
            flush=True,
        )
        frames = sim_log(tmp, 30.0 if a.quick else 120.0)
        rows = []
        from pfslam.config import SlamConfig

        sc = SlamConfig().local_search
        grid = (2 * sc.radius_cells + 1) ** 2 * (2 * sc.theta_steps + 1)  # offsets tried per particle
        for n in (30, 100, 300, 1000):
            for search in (False, True):
                k = len(frames) if n * (grid if search else 1) <= 3000 else min(len(frames), 600)
                rows.append(slam_rate(frames[:k], n, search))
                print(
                    f"SLAM {n:5d} particles search={search!s:5}: {rows[-1]['scans_per_s']:8.1f} scans/s "
                    f"({rows[-1]['real_time_factor']:.1f}x real time)",
                    flush=True,
                )
        twin = slam_rate(frames[:120], 100, False, backend="numpy")
        fast = slam_rate(frames[:120], 100, False)
        twin["numba_ratio"] = fast["scans_per_s"] / twin["scans_per_s"]
        rows.append(twin)
        print(
            f"SLAM 100 particles, NumPy twins: {twin['scans_per_s']:.1f} scans/s "
            f"(Numba is {twin['numba_ratio']:.0f}x faster)",
            flush=True,
        )
        res["slam"] = rows
        growth = []
        for hits in (100, 200, 400, 800):
            growth.append(slam_rate(frames[:1200], 100, False, max_hits=hits))
            print(f"SLAM 100 particles, {hits:4d} hits scored: {growth[-1]['scans_per_s']:8.1f} scans/s", flush=True)
        for res_m in (0.1, 0.05, 0.025):
            growth.append(slam_rate(frames[:1200], 100, False, resolution=res_m))
            print(
                f"SLAM 100 particles, {res_m} m cells ({growth[-1]['map_cells']} cells): "
                f"{growth[-1]['scans_per_s']:8.1f} scans/s",
                flush=True,
            )
        res["slam_growth"] = growth
        res["wheeled"] = wheeled_rate()
        res["localization"] = localization_rates(frames, tmp)
        res["kernels"] = kernel_rates(frames)
        for r in res["kernels"]:
            print(
                f"{r['kernel']:24s} {r['input']:42s} Numba {r['numba_per_s'] / 1e6:9.1f} M {r['unit']}/s, "
                f"NumPy twin {r['numpy_per_s'] / 1e6:8.2f} M/s: {r['ratio']:6.1f}x",
                flush=True,
            )
        if not a.quick:
            long_frames = sim_log(tmp, 750.0, seed=3)  # 30,000 scans at 40 Hz
            res["long_run"] = long_run(long_frames)
            print(json.dumps(res["long_run"], indent=1), flush=True)
    a.out.write_text(json.dumps(res, indent=2))
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
