"""Sessions where places repeat (issue 35): in each simulated aliasing world (pillars, rooms,
twins) and the office, a first walk (180 s) is mapped and a second walk (120 s, the same
building the other way round, from half way along) resumed onto it. For each, defaults only:

- the start: found (and how well), or refused;
- the loops between the two sessions in the answer's graph, and how many are off the truth
  (more than 0.2 m or 3 degrees from the true relative pose of their nodes);
- the second walk's error against the truth in the first run's frame (the first run's
  trajectory fitted to its truth by SE(2), the fit applied to the second's).

    python bench/sessions/session_aliasing.py --seeds 0 1 2 3 4 --out out/session_aliasing

--json FILE writes the rows, with the commit, machine and date that made them (``provenance``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
from _common import provenance  # noqa: E402

WORLDS = ("pillars", "rooms", "twins", "office")
OFF_M, OFF_DEG = 0.2, 3.0


def run(args: list[str], out: Path) -> str | None:
    """``pfslam ARGS -o OUT`` once; its error line, or None."""
    if (out / "run.json").exists() or (out / "train_lidar0.mat").exists():
        return None
    done = subprocess.run([sys.executable, "-m", "pfslam.cli", *args, "-o", str(out)], capture_output=True, text=True)
    return None if done.returncode == 0 else (done.stderr.strip().splitlines() or ["?"])[-1]


def one(world: str, seed: int, root: Path) -> dict:
    from pfslam.eval.metrics import align_se2
    from pfslam.geometry import compose, relative, wrap_angle
    from pfslam.io.trajectory import read_tum
    from pfslam.pipeline.sessions import load_session

    d = root / world / f"seed{seed}"
    run(["simulate", "--world", world, "--seed", str(seed), "--duration", "180"], d / "simA")
    run(
        ["simulate", "--world", world, "--seed", str(seed + 100), "--duration", "120", "--route", "reverse"], d / "simB"
    )
    lidar = [str(d / s / "train_lidar0.mat") for s in ("simA", "simB")]
    joint = [str(d / s / "train_joint0.mat") for s in ("simA", "simB")]
    run(["slam", lidar[0], "-j", joint[0]], d / "A")
    refused = run(["slam", lidar[1], "-j", joint[1], "--resume", str(d / "A")], d / "B")
    row: dict = {"world": world, "seed": seed}
    if refused is not None:
        return {**row, "refused": refused}
    ta, ga = read_tum(d / "simA" / "groundtruth.tum")
    _, gwa = read_tum(d / "simA" / "groundtruth_world.tum")
    tb, gwb = read_tum(d / "simB" / "groundtruth_world.tum")
    frame = compose(gwa[0], relative(ga[0], np.zeros(3)))
    gb = relative(frame, gwb)  # the second walk's truth in the first run's frame

    def at(t: np.ndarray, tt: np.ndarray, pp: np.ndarray) -> np.ndarray:
        return pp[np.clip(np.searchsorted(tt, t - 1e-4), 0, len(tt) - 1)]

    s = load_session(d / "B")
    n = s.nodes
    truth = np.where((n.run == 0)[:, None], at(n.times, ta, ga), at(n.times, tb, gb))
    g = s.graph
    across = g.loop & (n.run[g.i] != n.run[g.j])
    err = relative(relative(truth[g.i], truth[g.j]), g.z)
    off = across & ((np.hypot(err[:, 0], err[:, 1]) > OFF_M) | (np.abs(wrap_angle(err[:, 2])) > np.deg2rad(OFF_DEG)))
    te, ea = read_tum(d / "A" / "trajectory.tum")
    fit = align_se2(ea, at(te, ta, ga))
    tbe, eb = read_tum(d / "B" / "trajectory.tum")
    e2 = np.hypot(*(compose(fit, eb)[:, :2] - at(tbe, tb, gb)[:, :2]).T)
    info = json.loads((d / "B" / "run.json").read_text())
    return {
        **row,
        "start_score": info["session"]["start"].get("score"),
        "loops_across": int(across.sum()),
        "loops_across_off": int(off.sum()),
        "second_rmse": float(np.sqrt((e2**2).mean())),
        "second_max": float(e2.max()),
        "backend_kept": info.get("backend", {}).get("kept"),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--worlds", nargs="+", default=list(WORLDS))
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4])
    ap.add_argument("--out", default="out/session_aliasing")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    prov = provenance()
    root = Path(args.out)
    rows = []
    with ThreadPoolExecutor(args.workers) as pool:
        for row in pool.map(lambda ws: one(*ws, root), [(w, s) for w in args.worlds for s in args.seeds]):
            rows.append(row)
            if "refused" in row:
                print(f"{row['world']:8s} seed {row['seed']}: refused: {row['refused']}", flush=True)
            else:
                print(
                    f"{row['world']:8s} seed {row['seed']}: start {row['start_score']:.2f}; loops across "
                    f"{row['loops_across']} ({row['loops_across_off']} off); second walk {row['second_rmse']:.3f} m "
                    f"rmse (max {row['second_max']:.3f}); back end kept {row['backend_kept']}",
                    flush=True,
                )
    if args.json:
        Path(args.json).write_text(json.dumps({"provenance": prov, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
