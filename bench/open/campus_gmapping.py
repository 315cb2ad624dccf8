"""GMapping beside pfslam on the campus drives (issue 57): for each seed, the drive's bag as
``pfslam convert`` writes it (a plain CARMEN log: the same scans and the same drifting odometry
pfslam reads), GMapping's ``gfs_nogui`` on it with 30 particles and its range set 0.01 m below the
80 m no-return reading (bench/gmapping/gmapping.py builds it and runs it so), its path scored
against the drive's ground truth (SE(2)-aligned ATE RMSE, matched in time), beside pfslam's
from a ``pfslam sweep`` of bench/open/campus.yaml. GMapping takes 15-30 minutes a drive on one
core; a seed already scored in the output is not run again, and a run already in ``--work``
is scored without running it again.

    python bench/open/campus.py && pfslam sweep bench/open/campus.yaml -o out/campus
    python bench/open/campus_gmapping.py --sweep out/campus --seeds 0 1 2   # writes campus_gmapping.json
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "gmapping"))
from _common import ROOT, provenance  # noqa: E402
from gmapping import GMAPPING_BUILD, GMAPPING_SRC, ate, build_gmapping, no_return_value, run_gmapping  # noqa: E402

HERE = Path(__file__).resolve().parent
DRIVES = ROOT / "out" / "sims" / "campus"
PARTICLES = 30


def pfslam_runs(sweep: Path) -> dict[int, dict[str, float]]:
    """Each seed's aligned ATE in the sweep's results, by setting (backend graph and none)."""
    out: dict[int, dict[str, float]] = {}
    with (sweep / "results.csv").open() as f:
        for row in csv.DictReader(f):
            if row["status"] == "ok" and row["ate_aligned"]:
                out.setdefault(int(row["seed"]), {})[f"backend_{row['backend']}"] = float(row["ate_aligned"])
    return out


def gmapping_seed(seed: int, binary: Path, work: Path) -> dict[str, Any]:
    """GMapping on drive ``seed``, scored against its ground truth."""
    from pfslam.io.trajectory import read_tum

    drive = DRIVES / f"seed{seed}"
    log = work / f"campus{seed}.log"
    if not log.exists():
        subprocess.run(
            [sys.executable, "-m", "pfslam.cli", "convert", str(drive / "log.bag"), str(log)],
            check=True,
            stdout=subprocess.DEVNULL,
        )
    folder = work / f"gmapping{seed}"
    if (folder / "gmapping.txt").exists():  # a run made before (its path is scored again)
        rows = np.loadtxt(folder / "gmapping.txt", ndmin=2)
        run: dict[str, Any] = {"t": rows[:, 0], "poses": rows[:, 1:4], "wall_s": None}
    else:
        run = run_gmapping(binary, log, no_return_value(log), PARTICLES, folder)
    t_ref, ref = read_tum(drive / "groundtruth.tum")
    err, matched = ate(run["t"], run["poses"], t_ref, ref)
    wall = None if run["wall_s"] is None else round(run["wall_s"], 1)
    return {"ate_aligned_m": round(err, 3), "matched": matched, "wall_s": wall}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sweep", type=Path, required=True, help="a pfslam sweep of bench/open/campus.yaml")
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(10)))
    ap.add_argument("--work", type=Path, default=ROOT / "out" / "campus_gmapping", help="logs and GMapping's runs")
    ap.add_argument("--out", type=Path, default=HERE / "campus_gmapping.json")
    a = ap.parse_args()
    binary = build_gmapping(GMAPPING_SRC, GMAPPING_BUILD)
    a.work.mkdir(parents=True, exist_ok=True)
    doc = json.loads(a.out.read_text()) if a.out.exists() else {"gmapping": {}}
    for seed in a.seeds:
        if str(seed) in doc["gmapping"]:
            continue
        doc["gmapping"][str(seed)] = got = gmapping_seed(seed, binary, a.work)
        print(f"seed {seed}: GMapping {got['ate_aligned_m']} m ({got['wall_s']} s)", flush=True)
        a.out.write_text(json.dumps(doc, indent=1) + "\n")
    doc["pfslam"] = {str(k): v for k, v in sorted(pfslam_runs(a.sweep).items())}
    doc["about"] = __doc__.split("\n\n")[0]
    doc["provenance"] = provenance()
    a.out.write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
