"""Localization health on simulated humanoid walks (issue 46, deliverable 1): the state turns
lost when the robot is kidnapped and tracking once it is found; clean tracking raises no
alarm; a worn map with people walking lowers the quality without "lost".

Each seed is a 120-s THOR walk of the office world (``pfslam simulate``'s physics, seed K),
localized from a known start (``LocalizerConfig(seed=K)``, the defaults otherwise) in three ways:

- **clean**: the walk on its own map. Figures: RMSE, the updates in each state.
- **kidnap**: at 40 s the robot is carried at least 10 m to a later point of the walk (the first
  after 60 s), and its odometry does not notice. Figures: seconds from the kidnap until the
  state is first lost, until the estimate is within 0.3 m for good ("found"), and until the
  state is tracking again after that; the scans the state said tracking while the estimate
  was more than 0.3 m off.
- **worn**: the map with 15 % of its wall cells moved or removed (1-m pieces round random wall
  cells; half of them taken away, half moved 0.4 m in a random direction) and six people
  (0.25 m discs walking at 0.8 m/s, bouncing in the walk's bounding box) hiding beams.
  Figures: RMSE against the clean run's, the updates lost and degraded, the quality's 1st
  percentile and median.

    python bench/localize/health.py                        # seeds 0-9, writes bench/localize/health.json
    python bench/localize/health.py --seeds 0 1 --no-write # a quick look
    python bench/localize/health.py --before /tmp/old/src  # the same worlds on another tree (RMSEs only)
    python bench/localize/health.py --real                 # the real logs only (adds "real" to the json)

``--real``: Intel and FR079 mapped by ``pfslam slam LOG --odometry synthetic:0``, localized on
that map with ``synthetic:3`` from the map run's first pose, the log spliced at a third of its
scans to the first scan at least 8 m away and a tenth of the log later (the odometry unaware),
filter seeds 0-2; times against the map run's trajectory. Figures: seconds from the kidnap until
lost, until within 0.3 m for good, until tracking again; the updates not tracking before it.

The walks are cached under $PFSLAM_BENCH_CACHE (default: the temp folder).
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import subprocess
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
from _common import DATA, provenance  # noqa: E402

HERE = Path(__file__).resolve().parent
CACHE = Path(os.environ.get("PFSLAM_BENCH_CACHE", Path(tempfile.gettempdir()) / "pfslam-bench-health"))
DURATION = 120.0
KIDNAP_AT, KIDNAP_MIN = 40.0, 10.0  # s, m
WORN, SHIFT, PEOPLE = 0.15, 0.4, 6
WITHIN = 0.3


def walk(seed: int) -> tuple[list[Any], np.ndarray, Any]:
    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import read_tum
    from pfslam.maps.grid import OccupancyGrid
    from pfslam.tools.simulate import simulate

    d = CACHE / f"office{seed}"
    if not (d / "groundtruth.tum").exists():
        simulate("office", DURATION, seed=seed, out_dir=d)
    frames = list(load_log(d / "train_lidar0.mat", d / "train_joint0.mat").frames)
    return frames, read_tum(d / "groundtruth.tum")[1], OccupancyGrid.load_ros(d / "map.yaml")


def kidnapped(frames: list[Any], truth: np.ndarray) -> tuple[list[Any], np.ndarray, int]:
    from pfslam.geometry import compose, relative

    t = np.array([f.t for f in frames]) - frames[0].t
    k1 = int(np.searchsorted(t, KIDNAP_AT))
    far = np.hypot(*(truth[:, :2] - truth[k1, :2]).T) >= KIDNAP_MIN
    k2 = int(np.nonzero(far & (t > KIDNAP_AT + 20.0))[0][0])
    out, tr = list(frames[: k1 + 1]), list(truth[: k1 + 1])
    for j in range(k2 + 1, len(frames)):
        f = copy.copy(frames[j])
        f.odom = compose(frames[k1].odom, relative(frames[k2].odom, frames[j].odom))
        f.t = frames[k1].t + (frames[j].t - frames[k2].t)
        out.append(f)
        tr.append(truth[j])
    return out, np.array(tr), k1


def worn(grid: Any, rng: np.random.Generator) -> Any:
    from pfslam.maps.grid import OccupancyGrid

    occ = grid.thresholded() == 100
    r, c = np.nonzero(occ)
    new = grid.logodds.copy()
    blk = int(round(1.0 / grid.resolution))
    gone = 0
    while gone < WORN * len(r):
        k = rng.integers(len(r))
        r0, c0 = max(r[k] - blk // 2, 0), max(c[k] - blk // 2, 0)
        rr, cc = np.nonzero(occ[r0 : r0 + blk, c0 : c0 + blk])
        gone += len(rr)
        new[r0 + rr, c0 + cc] = -5.0
        if rng.random() < 0.5:  # moved, not taken away
            a = rng.uniform(0, 2 * np.pi)
            dr, dc = (int(round(SHIFT / grid.resolution * v)) for v in (np.sin(a), np.cos(a)))
            r2, c2 = r0 + rr + dr, c0 + cc + dc
            ok = (r2 >= 0) & (r2 < new.shape[0]) & (c2 >= 0) & (c2 < new.shape[1])
            new[r2[ok], c2[ok]] = 5.0
    return OccupancyGrid.from_logodds(
        new.astype(np.float32), grid.resolution, np.asarray(grid.origin), grid.l_occ, grid.l_free, grid.l_clamp
    )


def with_people(frames: list[Any], truth: np.ndarray, rng: np.random.Generator) -> list[Any]:
    """The frames with beams cut short where they meet a walking person (a disc)."""
    from pfslam.geometry import transform_points

    radius, speed = 0.25, 0.8
    lo, hi = truth[:, :2].min(0) - 1, truth[:, :2].max(0) + 1
    pos = rng.uniform(lo, hi, (PEOPLE, 2))
    vel = rng.normal(size=(PEOPLE, 2))
    vel *= speed / np.linalg.norm(vel, axis=1)[:, None]
    span, out = hi - lo, []
    for f, p in zip(frames, truth):
        rel = np.mod(pos + vel * (f.t - frames[0].t) - lo, 2 * span)
        people = lo + np.where(rel > span, 2 * span - rel, rel)
        m, a, r = f.mount, np.asarray(f.angles, float), np.asarray(f.ranges, float)
        ok = np.isfinite(r) & (r > f.min_range) & (r < f.max_range)
        xyz = m[:3, :2] @ np.vstack([np.where(ok, r, 0) * np.cos(a), np.where(ok, r, 0) * np.sin(a)]) + m[:3, 3:4]
        s = transform_points(p, m[:2, 3][None])[0]
        v = transform_points(p, xyz[:2].T) - s
        length2 = np.maximum((v**2).sum(1), 1e-12)
        frac = np.ones(len(r))
        for c in people:
            along = ((c - s) @ v.T) / length2
            d2 = ((s + along[:, None] * v - c) ** 2).sum(1)
            enter = along - np.sqrt(np.maximum(radius**2 - d2, 0) / length2)
            hit = ok & (d2 < radius**2) & (enter > 0.02) & (enter < frac)
            frac = np.where(hit, enter, frac)
        g = copy.copy(f)
        g.ranges = (r * frac).astype(np.asarray(f.ranges).dtype)
        out.append(g)
    return out


def localize(frames: list[Any], truth: np.ndarray, grid: Any, seed: int) -> dict[str, Any]:
    from pfslam.config import LocalizerConfig
    from pfslam.filters.localize import Localizer

    loc = Localizer(grid, LocalizerConfig(seed=seed))
    loc.initialize_around(truth[0], [0.1, 0.1, np.deg2rad(3)])
    t, err, upd, q, st = [], [], [], [], []
    for f, g in zip(frames, truth):
        e = loc.step(f)
        h = getattr(e, "health", None)  # (None on a tree without the health)
        t.append(f.t - frames[0].t)
        err.append(float(np.hypot(*(e.pose[:2] - g[:2]))))
        upd.append(e.updated)
        q.append(h.quality if h is not None else np.nan)
        st.append(h.state.value if h is not None else "")
    return {
        "t": np.array(t),
        "err": np.array(err),
        "updated": np.array(upd),
        "quality": np.array(q),
        "state": np.array(st),
        "injected": loc.injected,
    }


def _states(r: dict[str, Any]) -> dict[str, int]:
    u = r["updated"]
    return {s: int(np.sum(u & (r["state"] == s))) for s in ("tracking", "degraded", "lost", "ambiguous")}


def _rmse(r: dict[str, Any]) -> float:
    return float(np.sqrt(np.mean(r["err"] ** 2)))


def one_seed(seed: int) -> dict[str, Any]:
    frames, truth, grid = walk(seed)
    clean = localize(frames, truth, grid, seed)
    seq, tr, k1 = kidnapped(frames, truth)
    kid = localize(seq, tr, grid, seed)
    rng = np.random.default_rng(100 + seed)
    bad_map = worn(grid, rng)
    w = localize(with_people(frames, truth, rng), truth, bad_map, seed)
    t, kt = kid["t"], kid["t"][k1]
    after = t > kt
    off = np.nonzero(after & (kid["err"] > WITHIN))[0]
    found = float(t[off[-1]] - kt) if len(off) else 0.0
    lost = np.nonzero(after & (kid["state"] == "lost"))[0]
    back = np.nonzero(after & (t - kt > found) & (kid["state"] == "tracking"))[0]
    q = w["quality"][w["updated"]]
    return {
        "seed": seed,
        "clean": {"rmse": _rmse(clean), "updates_in_state": _states(clean), "injected": clean["injected"]},
        "kidnap": {
            "jump_m": float(np.hypot(*(tr[k1 + 1, :2] - tr[k1, :2]))),
            "to_lost_s": float(t[lost[0]] - kt) if len(lost) else None,
            "found_s": found,
            "to_tracking_s": float(t[back[0]] - kt) if len(back) else None,
            "tracking_while_off_scans": int(np.sum(after & (kid["state"] == "tracking") & (kid["err"] > WITHIN))),
            "lost_before_kidnap": int(np.sum(~after & (kid["state"] == "lost"))),
        },
        "worn": {
            "rmse": _rmse(w),
            "rmse_ratio": _rmse(w) / _rmse(clean),
            "updates_in_state": _states(w),
            "quality_p1": float(np.percentile(q, 1)) if np.isfinite(q).all() else None,
            "quality_median": float(np.median(q)) if np.isfinite(q).all() else None,
            "clean_quality_median": float(np.nanmedian(clean["quality"][clean["updated"]])),
            "injected": w["injected"],
        },
    }


def real_kidnap(log: str, seed: int) -> dict[str, Any]:
    """One real log kidnapped (see ``--real``)."""
    from pfslam.config import LocalizerConfig
    from pfslam.filters.localize import Localizer
    from pfslam.geometry import compose, relative
    from pfslam.io.trajectory import read_tum
    from pfslam.maps.grid import OccupancyGrid
    from pfslam.pipeline.report import Quiet
    from pfslam.pipeline.steps import LogInput, load

    path = DATA / "carmen" / f"{log}.gfs.log.gz"
    m = CACHE / f"{log}_map"
    if not (m / "map.yaml").exists():
        cmd = [sys.executable, "-m", "pfslam.cli", "slam", str(path), "--odometry", "synthetic:0", "-o", str(m)]
        subprocess.run(cmd, check=True, capture_output=True)
    frames = list(load(LogInput.of(path, None, odometry="synthetic:3"), Quiet()).frames)
    tm, ref = read_tum(m / "trajectory.tum")
    t = np.array([f.t for f in frames])
    truth = ref[np.clip(np.searchsorted(tm, t), 0, len(tm) - 1)]
    n = len(frames)
    k1 = n // 3
    far = np.hypot(*(truth[:, :2] - truth[k1, :2]).T) >= 8.0
    k2 = int(np.nonzero(far & (np.arange(n) > k1 + n // 10))[0][0])
    seq, tr = frames[: k1 + 1], list(truth[: k1 + 1])
    for j in range(k2 + 1, n):
        f = copy.copy(frames[j])
        f.odom = compose(frames[k1].odom, relative(frames[k2].odom, frames[j].odom))
        f.t = frames[k1].t + (frames[j].t - frames[k2].t)
        seq.append(f)
        tr.append(truth[j])
    loc = Localizer(OccupancyGrid.load_ros(m / "map.yaml"), LocalizerConfig(seed=seed))
    loc.initialize_around(tr[0], [0.1, 0.1, 0.05])
    st, err = [], []
    for f, g in zip(seq, tr):
        e = loc.step(f)
        st.append(e.health.state.value if e.health is not None else "")
        err.append(float(np.hypot(*(e.pose[:2] - g[:2]))))
    states, errors = np.array(st), np.array(err)
    ts = np.array([f.t for f in seq]) - seq[k1].t
    after = ts > 0
    lost = np.nonzero(after & (states == "lost"))[0]
    off = np.nonzero(after & (errors > WITHIN))[0]
    found = float(ts[off[-1]]) if len(off) else 0.0
    back = np.nonzero(after & (ts > found) & (states == "tracking"))[0]
    return {
        "log": log,
        "seed": seed,
        "jump_m": float(np.hypot(*(truth[k2, :2] - truth[k1, :2]))),
        "to_lost_s": float(ts[lost[0]]) if len(lost) else None,
        "found_s": found,
        "to_tracking_s": float(ts[back[0]]) if len(back) else None,
        "not_tracking_before": f"{int(np.sum(~after & (states != 'tracking')))} of {int(np.sum(~after))}",
    }


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    clean_alarm = [r["clean"]["updates_in_state"] for r in rows]
    k = [r["kidnap"] for r in rows]
    w = [r["worn"] for r in rows]
    updates = sum(sum(c.values()) for c in clean_alarm)
    return {
        "seeds": [r["seed"] for r in rows],
        "clean_lost_or_degraded_updates": f"{sum(c['lost'] + c['degraded'] for c in clean_alarm)} of {updates}",
        "kidnap_to_lost_s_max": max((x["to_lost_s"] for x in k if x["to_lost_s"] is not None), default=None),
        "kidnap_never_lost": sum(x["to_lost_s"] is None for x in k),
        "kidnap_found_s_max": max(x["found_s"] for x in k),
        "kidnap_to_tracking_s_max": max((x["to_tracking_s"] or np.inf) for x in k),
        "worn_lost_updates": sum(x["updates_in_state"]["lost"] for x in w),
        "worn_rmse_ratio_range": [min(x["rmse_ratio"] for x in w), max(x["rmse_ratio"] for x in w)],
        "worn_quality_median_range": [
            min(x["quality_median"] or 0 for x in w),
            max(x["quality_median"] or 0 for x in w),
        ],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="*", default=list(range(10)))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--before", help="another tree's src: run the same worlds there (RMSEs, injections)")
    ap.add_argument("--real", action="store_true", help="the real logs kidnapped, only")
    a = ap.parse_args()
    if a.real:
        out = HERE / "health.json"
        result = json.loads(out.read_text()) if out.exists() else {}
        rows = [real_kidnap(log, seed) for log in ("intel", "fr079") for seed in (0, 1, 2)]
        for r in rows:
            print(json.dumps(r), flush=True)
        result["real"] = {"runs": rows, "provenance": provenance()}
        if not a.no_write:
            out.write_text(json.dumps(result, indent=1) + "\n")
        return
    if a.before:
        env = {**os.environ, "PYTHONPATH": a.before}
        args = [sys.executable, __file__, "--no-write", "--workers", str(a.workers), "--seeds", *map(str, a.seeds)]
        subprocess.run(args, env=env, check=True)
        return
    with ProcessPoolExecutor(a.workers) as pool:
        rows = list(pool.map(one_seed, a.seeds))
    for r in rows:
        print(json.dumps(r), flush=True)
    result = {"summary": summary(rows), "seeds": rows, "provenance": provenance()}
    print(json.dumps(result["summary"], indent=1))
    if not a.no_write:
        (HERE / "health.json").write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
