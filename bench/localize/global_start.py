"""How soon a global start finds the robot (issue 46, deliverable 2), against another tree:

- the 80 rough 200-s walks of bench/localize/localize.py's kinds ``global90 global97
  global104 global110`` (office world, odometry 0.9-1.1x the true travel, seeds 0-19 each):
  ``found_after_s``, the time after the first scan from which the estimate stays within
  0.3 m of the truth, and ``within_0.3m_by_1s``, how many walks stay within 0.3 m from 1 s
  after the first scan on;
- Intel: map from ``pfslam slam intel --odometry synthetic:0`` (cached as in localize.py),
  ``pfslam localize --global --odometry synthetic:3``, errors against the map's own run;
- the aliasing worlds ``twins``, ``rooms``, ``pillars`` (180-s walks, seeds 0-9; this tree
  only, it needs ``Localizer.ambiguous``): whether the health's state was ever "tracking" while
  the estimate was more than 0.3 m off the truth, the scans in each state, when it found the
  robot and when it stopped being ambiguous.

    git archive 82d7502 src | tar -x -C /tmp/before46     # the tree before (uniform spread)
    python bench/localize/global_start.py --before /tmp/before46/src   # writes bench/localize/global_start.json
    python bench/localize/global_start.py --only aliasing walk-ambiguity --no-before

(``walk-ambiguity``: the office walks stepped as the aliasing worlds are, the same check.)

Each run is a separate process with ``PYTHONPATH`` set to the tree's ``src``; ``--workers``
run at once. The walks are cached where localize.py caches them (``PFSLAM_BENCH_CACHE``).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
sys.path.insert(0, str(Path(__file__).resolve().parent))  # bench/localize/, for localize.py's walks
from _common import DATA, provenance  # noqa: E402
from localize import CACHE, MAIN_SRC, _cli, _sim, prepare  # noqa: E402
from localize import run_job as localize_job  # noqa: E402

HERE = Path(__file__).resolve().parent
WALK_KINDS = ["global90", "global97", "global104", "global110"]
WORLDS = ["twins", "rooms", "pillars"]
WITHIN_M = 0.3
BY_S = 1.0


def _found(tm: np.ndarray, err: np.ndarray) -> float:
    """The time (after the first scan) from which ``err`` stays within WITHIN_M; inf if never."""
    bad = np.nonzero((err > WITHIN_M) & (tm >= 0))[0]
    if not len(bad):
        return 0.0
    return float(tm[bad[-1] + 1]) if bad[-1] + 1 < len(tm) else float("inf")


def work_walk(kind: str, seed: int, over: dict[str, Any]) -> dict[str, Any]:
    from pfslam.config import LocalizerConfig
    from pfslam.pipeline import run_localization

    _, frames, grid, t, truth = _sim(kind, seed)
    run = run_localization(frames, grid, LocalizerConfig(**{"seed": seed, **over}), None)
    k = len(run.poses)
    err = np.hypot(*(run.poses[:, :2] - truth[:k, :2]).T)
    first = int(np.nonzero(run.updated)[0][0])
    tm = t[:k] - t[first]
    return {
        "found_after_s": _found(tm, err),
        "within_by_1s": bool(err[tm >= BY_S].max() <= WITHIN_M),
        "error_at_1s": float(err[np.searchsorted(tm, BY_S)]),
        "first_motion_s": _first_motion(kind, seed),
        "filter": run.filter_info,
    }


def _first_motion(kind: str, seed: int) -> float:
    """When the walk's robot first moves (2 cm from where it stood), after its first scan:
    the simulated walks stand still for about 5 s, their head looking at the floor 2 m ahead."""
    from pfslam.io.trajectory import read_tum

    t, truth = read_tum(CACHE / kind / str(seed) / "groundtruth.tum")
    return float(t[np.nonzero(np.hypot(*(truth[:, :2] - truth[0, :2]).T) > 0.02)[0][0]] - t[0])


def work_intel(over: dict[str, Any]) -> dict[str, Any]:
    from pfslam.eval.metrics import pose_errors
    from pfslam.io.trajectory import read_tum

    log = DATA / "carmen" / "intel.gfs.log.gz"
    m = CACHE / "intel_map"
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "l"
        cfg = []
        if over:
            (Path(d) / "c.yaml").write_text(
                "localize:\n" + "".join(f"  {k}: {json.dumps(v)}\n" for k, v in over.items())
            )
            cfg = ["-c", str(Path(d) / "c.yaml")]
        _cli("localize", log, "--map", m / "map.yaml", "--odometry", "synthetic:3", "--global", "-o", out, *cfg)
        t, poses = read_tum(out / "trajectory.tum")
        info = json.loads((out / "run.json").read_text())
    pe = pose_errors(t, poses, *read_tum(m / "trajectory.tum"))
    err = np.hypot(*(pe.estimate[:, :2] - pe.reference[:, :2]).T)
    tm = pe.t - t[0]
    return {
        "found_after_s": _found(tm, err),
        "within_by_1s": bool(err[tm >= BY_S].max() <= WITHIN_M),
        "rmse_vs_map_run": float(np.sqrt(np.mean(err**2))),
        "filter": info.get("filter", {}),
    }


def work_alias(world: str, seed: int, over: dict[str, Any]) -> dict[str, Any]:
    from pfslam.config import LocalizerConfig
    from pfslam.filters.localize import Localizer
    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import read_tum
    from pfslam.maps.grid import OccupancyGrid

    d = CACHE / "alias" / world / str(seed) if world in WORLDS else CACHE / world / str(seed)
    frames = load_log(d / "train_lidar0.mat", d / "train_joint0.mat").frames
    _, truth = read_tum(d / "groundtruth.tum")
    loc = Localizer(OccupancyGrid.load_ros(d / "map.yaml"), LocalizerConfig(**{"seed": seed, **over}))
    loc.initialize_global()
    tm, err, amb, said = [], [], [], []
    t0 = None
    for f, x in zip(frames, truth, strict=False):
        e = loc.step(f)
        if t0 is None and e.updated:
            t0 = f.t
        tm.append(f.t - (t0 if t0 is not None else f.t))
        err.append(float(np.hypot(*(e.pose[:2] - x[:2]))))
        amb.append(bool(loc.ambiguous))
        h = getattr(e, "health", None)  # the state the run reports (a tree without it: the flag alone)
        said.append(h.state.value if h is not None else ("ambiguous" if loc.ambiguous else "tracking"))
    tm_a, err_a, amb_a = np.array(tm), np.array(err), np.array(amb)
    tracking = np.array(said) == "tracking"
    wrong = tracking & (err_a > WITHIN_M) & (tm_a >= 0)
    resolved = np.nonzero(~amb_a & (tm_a >= 0))[0]
    return {
        "tracking_while_off": int(wrong.sum()),
        "worst_error_while_tracking": float(err_a[tracking].max()) if tracking.any() else None,
        "states": {k: int(np.sum(np.array(said) == k)) for k in ("tracking", "degraded", "lost", "ambiguous")},
        "found_after_s": _found(tm_a, err_a),
        "resolved_after_s": float(tm_a[resolved[0]]) if len(resolved) else None,
        "start": loc.diagnostics().get("global_start"),
    }


def worker(job: dict[str, Any]) -> dict[str, Any]:
    over = job.get("over", {})
    if job["what"] == "walk":
        return work_walk(job["kind"], job["seed"], over)
    if job["what"] == "intel":
        return work_intel(over)
    return work_alias(job["world"], job["seed"], over)


def run_job(src: str, job: dict[str, Any]) -> dict[str, Any]:
    return localize_job(src, job, script=__file__)


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The walks' figures: how many stay within 0.3 m from 1 s after the first scan on, and
    from 1 s after the first motion on; the times found (median, 95th percentile, largest)."""
    for r in rows:
        r.setdefault("first_motion_s", _first_motion(r["kind"], r["seed"]))
    found = [r["found_after_s"] for r in rows]
    after_motion = [max(r["found_after_s"] - r["first_motion_s"], 0.0) for r in rows]
    q = lambda v: [round(float(np.percentile(v, p)), 2) for p in (50, 95, 100)]  # noqa: E731
    return {
        "runs": rows,
        "within_0.3m_by_1s": f"{sum(r['within_by_1s'] for r in rows)} of {len(rows)}",
        "within_0.3m_by_1s_after_first_motion": f"{sum(x <= BY_S for x in after_motion)} of {len(rows)}",
        "found_after_s_median_p95_max": q(found),
        "found_after_first_motion_s_median_p95_max": q(after_motion),
    }


def prepare_alias(seeds: int) -> None:
    from pfslam.tools.simulate import simulate

    for world in WORLDS:
        for s in range(seeds):
            d = CACHE / "alias" / world / str(s)
            if not (d / "map.yaml").exists():
                simulate(world, 180.0, s, d)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--before", default="/tmp/before46/src", help="src folder of the tree to compare with")
    ap.add_argument("--src", default=str(MAIN_SRC), help="src folder of the tree under test")
    ap.add_argument("--only", nargs="*", default=["walks", "intel", "aliasing", "walk-ambiguity"])
    ap.add_argument("--seeds", type=int, default=20, help="walks per kind (seeds 0..N-1)")
    ap.add_argument("--alias-seeds", type=int, default=10, help="aliasing walks per world (seeds 0..N-1)")
    ap.add_argument("--after", default="{}", help="JSON config overrides for this tree's runs")
    ap.add_argument("--no-before", action="store_true", help="this tree only")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=HERE / "global_start.json")
    a = ap.parse_args()
    if a.worker:
        print(json.dumps(worker(json.loads(a.worker))))
        return
    over = json.loads(a.after)
    trees = [("after", a.src, over)] + ([] if a.no_before else [("before", a.before, {})])
    if "walks" in a.only or "intel" in a.only:
        kinds = WALK_KINDS if "walks" in a.only else []
        prepare(kinds, dict.fromkeys(kinds, list(range(a.seeds))), a.src)
    if "aliasing" in a.only:
        prepare_alias(a.alias_seeds)
    result: dict[str, Any] = json.loads(a.out.read_text()) if a.out.exists() else {}
    result.pop("provenance", None)
    result = {"provenance": {**provenance(Path(a.src)), "parts": a.only}, **result, "after_overrides": over}
    save = lambda: a.out.write_text(json.dumps(result, indent=1) + "\n")  # noqa: E731
    pool = ThreadPoolExecutor(a.workers)
    if "walks" in a.only:
        for name, src, ov in trees:
            jobs = [(k, s) for k in WALK_KINDS for s in range(a.seeds)]
            futs = [pool.submit(run_job, src, {"what": "walk", "kind": k, "seed": s, "over": ov}) for k, s in jobs]
            rows = [{"kind": k, "seed": s, **f.result()} for (k, s), f in zip(jobs, futs, strict=True)]
            result.setdefault("walks", {})[name] = summarise(rows)
            print("walks", name, {k: v for k, v in result["walks"][name].items() if k != "runs"}, flush=True)
            save()
    if "intel" in a.only:
        for name, src, ov in trees:
            result.setdefault("intel", {})[name] = r = run_job(src, {"what": "intel", "over": ov})
            print("intel", name, {k: v for k, v in r.items() if k != "filter"}, flush=True)
            save()
    if "walk-ambiguity" in a.only:  # the office walks stepped as the aliasing worlds are
        jobs = [(k, s) for k in WALK_KINDS for s in range(a.seeds)]
        futs = [pool.submit(run_job, a.src, {"what": "alias", "world": k, "seed": s, "over": over}) for k, s in jobs]
        rows = [{"kind": k, "seed": s, **f.result()} for (k, s), f in zip(jobs, futs, strict=True)]
        result["walk_ambiguity"] = {
            "runs": rows,
            "runs_tracking_while_off": sum(r["tracking_while_off"] > 0 for r in rows),
            "resolved_after_s_median_max": [
                round(float(np.percentile([r["resolved_after_s"] or np.inf for r in rows], q)), 2) for q in (50, 100)
            ],
        }
        print("walk-ambiguity", {k: v for k, v in result["walk_ambiguity"].items() if k != "runs"}, flush=True)
        save()
    if "aliasing" in a.only:
        jobs = [(w, s) for w in WORLDS for s in range(a.alias_seeds)]
        futs = [pool.submit(run_job, a.src, {"what": "alias", "world": w, "seed": s, "over": over}) for w, s in jobs]
        rows = [{"world": w, "seed": s, **f.result()} for (w, s), f in zip(jobs, futs, strict=True)]
        result["aliasing"] = {
            "runs": rows,
            "runs_tracking_while_off": sum(r["tracking_while_off"] > 0 for r in rows),
            "found_after_s_max": max(r["found_after_s"] for r in rows),
        }
        print("aliasing", {k: v for k, v in result["aliasing"].items() if k != "runs"}, flush=True)
        save()
    pool.shutdown()
    save()


if __name__ == "__main__":
    main()
