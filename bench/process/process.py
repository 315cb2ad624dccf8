"""Whole `pfslam slam` processes, timed as a user waits for them.

Each run is a fresh process: its wall clock and peak memory are measured from outside
(os.wait4), its phases (start-up and imports, load, filter loop, back end, score, write)
read from its run.json (`seconds_by_phase`). Runs alternate between the logs (and, with
--compare, between two source trees) so that the machine's drift hits all alike; the
figure is the median of --repeat runs, after one untimed run of each tree.

    python bench/process/process.py                      # THOR 100 s (4,000 scans), Intel, FR079
    python bench/process/process.py --repeat 3 --compare /tmp/base/src   # against another tree
    python bench/process/process.py --repeat 3 --also "--backend none"   # this tree with and without the back end
    python bench/process/process.py --logs thor_4000 --compare /tmp/old/src  # one log only

Writes bench/process/process.json (or --out), with the commit, machine and date (``provenance``). The THOR-format log is simulated (office, 100 s, seed 0) into a
temporary folder; Intel and FR079 come from ../shared/data (or PFSLAM_DATA), with
synthetic odometry seed 0.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
from _common import DATA, ROOT, provenance  # noqa: E402

HERE = Path(__file__).resolve().parent


def logs(tmp: Path) -> dict[str, list[str]]:
    """The pfslam slam arguments of each benchmark log (those present)."""
    from pfslam.tools.simulate import simulate

    sim = simulate("office", 100.0, seed=0, out_dir=tmp / "thor100")
    out = {"thor_4000": [str(sim.lidar_path), "-j", str(sim.joint_path)]}
    for name in ("intel", "fr079"):
        p = DATA / "carmen" / f"{name}.gfs.log.gz"
        if p.exists():
            out[name] = [str(p), "--odometry", "synthetic:0"]
    return out


def run_once(args: list[str], src: Path, out: Path, extra: list[str] | None = None) -> dict[str, object]:
    """One pfslam slam process on ``src``'s code: wall seconds, peak RSS (MB), its phases."""
    env = {**os.environ, "PYTHONPATH": str(src)}
    began = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-m", "pfslam.cli", "slam", *args, *(extra or []), "-o", str(out)],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - began
    if status != 0:
        raise SystemExit(f"pfslam slam {' '.join(args)} failed: {proc.stderr.read().decode()[-500:]}")
    info = json.loads((out / "run.json").read_text())
    return {
        "wall_s": wall,
        "peak_rss_mb": usage.ru_maxrss / 1024,
        "loop_s": info.get("seconds"),
        "phases": info.get("seconds_by_phase"),
        "slowest_scan_ms": info.get("filter", {}).get("slowest_scan_ms"),
        "p99_scan_ms": info.get("filter", {}).get("p99_scan_ms"),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--compare", type=Path, help="another tree's src/ folder, run alternately")
    ap.add_argument("--also", help="more pfslam slam arguments: this tree run with them too, alternately")
    ap.add_argument("--logs", nargs="+", help="only these logs (thor_4000, intel, fr079)")
    ap.add_argument("--out", type=Path, default=HERE / "process.json")
    a = ap.parse_args()
    import shlex

    trees: dict[str, tuple[Path, list[str]]] = {"this": (ROOT / "src", [])}
    if a.compare:
        trees["compare"] = (a.compare.resolve(), [])
    if a.also:
        trees[f"this {a.also}"] = (ROOT / "src", shlex.split(a.also))
    results: dict[str, dict[str, list[dict[str, object]]]] = {}
    prov = provenance()
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        todo = logs(t)
        if a.logs:
            unknown = set(a.logs) - set(todo)
            if unknown:
                raise SystemExit(f"no such log: {', '.join(sorted(unknown))} (there are {', '.join(todo)})")
            todo = {k: v for k, v in todo.items() if k in a.logs}
        # A warm-up of each tree, not timed: its compiled kernels loaded (or compiled, the first
        # time a tree runs), the log in the page cache.
        first = next(iter(todo.values()))
        for k, (src, extra) in enumerate(trees.values()):
            run_once(first, src, t / f"warmup_{k}", extra)
        for r in range(a.repeat):
            for name, args in todo.items():
                for k, (tree, (src, extra)) in enumerate(trees.items()):
                    res = run_once(args, src, t / f"{name}_{k}_{r}", extra)
                    results.setdefault(name, {}).setdefault(tree, []).append(res)
                    print(
                        f"{name} {tree} run {r + 1}: {res['wall_s']:.2f} s wall, loop {res['loop_s']:.2f} s", flush=True
                    )
    summary: dict[str, object] = {"provenance": prov}
    summary |= {
        name: {
            tree: {
                "wall_s_median": statistics.median(float(x["wall_s"]) for x in runs),  # type: ignore[arg-type]
                "wall_s": [round(float(x["wall_s"]), 2) for x in runs],  # type: ignore[arg-type]
                "loop_s_median": statistics.median(float(x["loop_s"]) for x in runs),  # type: ignore[arg-type]
                "peak_rss_mb_max": max(float(x["peak_rss_mb"]) for x in runs),  # type: ignore[arg-type]
                "phases_last": runs[-1]["phases"],
                "slowest_scan_ms_max": max(float(x["slowest_scan_ms"] or 0) for x in runs),  # type: ignore[arg-type]
                "p99_scan_ms_max": max(float(x.get("p99_scan_ms") or 0) for x in runs),  # type: ignore[arg-type]
            }
            for tree, runs in by_tree.items()
        }
        for name, by_tree in results.items()
    }
    a.out.write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary, indent=2))


if __name__ == "__main__":
    main()
