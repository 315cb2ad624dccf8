"""Sessions on real logs cut in two (issue 35): each shared CARMEN log with synthetic drifting
odometry (seed K) is cut at its middle scan; the second half's odometry is moved to start at
0,0,0 (a reboot). Three ``pfslam slam`` runs per log and seed, defaults only:

- A: the first half;
- B: the second half with ``--resume A`` (its start found in A's map);
- W: the whole log in one run.

Figures (printed, and written to --json with the commit, machine and date, ``provenance``):

- ``second_rmse`` / ``second_max``: B's trajectory against the reference in A's frame (A's
  trajectory fitted to the reference of the first half by SE(2), that fit applied to B's);
- ``whole_second_rmse``: the same for W (its first half fitted, the fit applied to its second);
- ``agreement_merged``: the map agreement of the whole log's scans seen from A's trajectory
  then B's; ``agreement_whole``: from W's; the target is merged >= whole - 0.02;
- the start B found (score, next best place) or the refusal.

    python bench/sessions/sessions.py --logs intel fr079 csail orebro --seeds 0 1 2 --out out/sessions
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
from _common import DATA, provenance  # noqa: E402

CARMEN = DATA / "carmen"


def cut(log: str, seed: int, root: Path) -> Path:
    """Write first.log, second.log (odometry rebased), whole.log and reference.tum under
    root/LOG/seedK (once)."""
    from pfslam.geometry import relative
    from pfslam.io.carmen import write_carmen
    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import write_tum
    from pfslam.pipeline.prepare import reference_truth

    out = root / log / f"seed{seed}"
    if (out / "reference.tum").exists():
        return out
    out.mkdir(parents=True, exist_ok=True)
    data = load_log(CARMEN / f"{log}.gfs.log.gz", odometry=f"synthetic:{seed}")
    frames = data.frames
    ref = reference_truth(data)
    assert ref is not None, "a corrected log with synthetic odometry carries its reference"
    odom = np.array([f.odom for f in frames], dtype=float)
    half = len(frames) // 2
    write_carmen(out / "whole.log", frames, odom, source=f"{log} synthetic:{seed}")
    write_carmen(out / "first.log", frames[:half], odom[:half], source=f"{log} synthetic:{seed}, first half")
    rebased = relative(odom[half], odom[half:])  # the robot switched off and on: odometry from 0,0,0
    write_carmen(out / "second.log", frames[half:], rebased, source=f"{log} synthetic:{seed}, second half")
    write_tum(out / "reference.tum", *ref)
    (out / "cut.json").write_text(json.dumps({"scans": len(frames), "half": half}))
    return out


def slam(args: list[str], out: Path) -> dict:
    if not (out / "run.json").exists():
        done = subprocess.run(
            [sys.executable, "-m", "pfslam.cli", "slam", *args, "-o", str(out)], capture_output=True, text=True
        )
        if done.returncode != 0:
            return {"error": (done.stderr.strip().splitlines() or ["?"])[-1]}
    return json.loads((out / "run.json").read_text())


def figures(folder: Path) -> dict:
    from pfslam.eval.metrics import align_se2, map_agreement
    from pfslam.geometry import compose
    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import read_tum

    tr, ref = read_tum(folder / "reference.tum")

    def at(t: np.ndarray) -> np.ndarray:
        return ref[np.clip(np.searchsorted(tr, t - 1e-4), 0, len(tr) - 1)]

    ta, a = read_tum(folder / "A" / "trajectory.tum")
    tb, b = read_tum(folder / "B" / "trajectory.tum")
    tw, w = read_tum(folder / "W" / "trajectory.tum")
    fit = align_se2(a, at(ta))
    err = np.hypot(*(compose(fit, b)[:, :2] - at(tb)[:, :2]).T)
    first = np.hypot(*(compose(fit, a)[:, :2] - at(ta)[:, :2]).T)
    # the same figure for one run over the whole log: its first half fitted, the fit applied to its second
    half = json.loads((folder / "cut.json").read_text())["half"]
    fit_w = align_se2(w[:half], at(tw[:half]))
    err_w = np.hypot(*(compose(fit_w, w[half:])[:, :2] - at(tw[half:])[:, :2]).T)
    frames = load_log(folder / "whole.log").frames
    merged = np.vstack([a, b])
    n = min(len(frames), len(merged), len(w))
    return {
        "first_rmse": float(np.sqrt((first**2).mean())),
        "second_rmse": float(np.sqrt((err**2).mean())),
        "second_p95": float(np.percentile(err, 95)),
        "second_max": float(err.max()),
        "whole_second_rmse": float(np.sqrt((err_w**2).mean())),
        "agreement_merged": float(map_agreement(frames[:n], merged[:n])),
        "agreement_whole": float(map_agreement(frames[:n], w[:n])),
    }


def one(log: str, seed: int, root: Path) -> dict:
    folder = cut(log, seed, root)
    row: dict = {"log": log, "seed": seed}
    row["A"] = slam([str(folder / "first.log")], folder / "A")
    row["W"] = slam([str(folder / "whole.log")], folder / "W")
    row["B"] = slam([str(folder / "second.log"), "--resume", str(folder / "A")], folder / "B")
    if "error" in row["B"] or "error" in row["A"]:
        row["refused"] = row["B"].get("error") or row["A"].get("error")
        return row
    row["start"] = row["B"].get("session", {}).get("start")
    row.update(figures(folder))
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--logs", nargs="+", default=["intel", "fr079", "csail", "orebro"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--out", default="out/sessions")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", default=None, help="write the rows here")
    args = ap.parse_args()
    prov = provenance()
    root = Path(args.out)
    rows = []
    with ThreadPoolExecutor(args.workers) as pool:
        for row in pool.map(lambda ls: one(*ls, root), [(lg, s) for lg in args.logs for s in args.seeds]):
            rows.append({k: v for k, v in row.items() if k not in ("A", "B", "W")})
            if "refused" in row:
                print(f"{row['log']} seed {row['seed']}: refused: {row['refused']}", flush=True)
                continue
            st = row["start"] or {}
            print(
                f"{row['log']:8s} seed {row['seed']}: second half {row['second_rmse']:.3f} m rmse "
                f"(p95 {row['second_p95']:.3f}, max {row['second_max']:.3f}; first half {row['first_rmse']:.3f}; "
                f"one run's second half {row['whole_second_rmse']:.3f}); "
                f"agreement merged {row['agreement_merged']:.3f} whole {row['agreement_whole']:.3f}; "
                f"start score {st.get('score', float('nan')):.2f}, next {st.get('next_score')}",
                flush=True,
            )
    if args.json:
        Path(args.json).write_text(json.dumps({"provenance": prov, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
