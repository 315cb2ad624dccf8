"""Benchmark of the Rao-Blackwellized filter (`--filter rbpf`) against the single-map one:
whole `pfslam slam` processes on the THOR benchmark log (simulated, office, 120 s at 40 Hz,
seed 7), Intel and FR079 (synthetic odometry, seed 0), at 30, 100 and 300 particles.

    python bench/rbpf/rbpf.py            # writes bench/rbpf/rbpf.json (about 15 minutes)
    python bench/rbpf/rbpf.py --quick    # 30 particles only

Each row comes from the run's own run.json: scans per second and the real-time factor of
the filter loop, the slowest scan, the peak RSS of the process, the tiles in use at the
end, and where the filter's time went (prediction, matching, weighing, map update,
resampling). Accuracy comes with it (ATE against the truth or the log's reference). The result
records the commit, machine and date that made it (``provenance``) beside its ``rows``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
from _common import DATA, provenance  # noqa: E402

HERE = Path(__file__).resolve().parent


def run(args: list[str], out: Path) -> dict:
    subprocess.run(
        [sys.executable, "-m", "pfslam.cli", "slam", *args, "-o", str(out)],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    return json.loads((out / "run.json").read_text())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="30 particles only")
    ap.add_argument("--out", type=Path, default=HERE / "rbpf.json")
    a = ap.parse_args()
    prov = provenance()
    rows: list[dict] = []
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        sim = tmp / "thor"
        subprocess.run(
            [sys.executable, "-m", "pfslam.cli", "simulate", "-o", str(sim), "--duration", "120", "--seed", "7"],
            check=True,
            stdout=subprocess.DEVNULL,
        )
        logs = {
            "thor": [
                str(sim / "train_lidar0.mat"),
                "-j",
                str(sim / "train_joint0.mat"),
                "-g",
                str(sim / "groundtruth.tum"),
            ]
        }
        for name in ("intel", "fr079"):
            p = DATA / "carmen" / f"{name}.gfs.log.gz"
            if p.exists():
                logs[name] = [str(p), "--odometry", "synthetic:0"]
        for name, args in logs.items():
            for filt, counts in (("single", (100,)), ("rbpf", (30,) if a.quick else (30, 100, 300))):
                for n in counts:
                    info = run([*args, "--filter", filt, "--particles", str(n)], tmp / f"{name}_{filt}_{n}")
                    m = info["metrics"].get("SLAM", {})
                    f = info.get("filter", {})
                    row = {
                        "log": name,
                        "filter": filt,
                        "particles": n,
                        "scans": info["scans_processed"],
                        "scans_per_s": info["scans_per_second"],
                        "real_time_factor": info["real_time_factor"],
                        "slowest_scan_ms": f.get("slowest_scan_ms"),
                        "peak_rss_mb": info["peak_rss_mb"],
                        "unique_tiles": f.get("unique_tiles"),
                        "map_updates": f.get("map_updates"),
                        "seconds_by_part": f.get("seconds_by_part"),
                        "ate": m.get("ate_rmse"),
                        "ate_aligned": m.get("ate_rmse_aligned"),
                    }
                    rows.append(row)
                    # kept as it goes: a long run stopped keeps its rows
                    a.out.write_text(json.dumps({"provenance": prov, "rows": rows}, indent=2))
                    print(
                        f"{name:6s} {filt:6s} {n:4d} particles: {row['scans_per_s']:7.1f} scans/s "
                        f"({row['real_time_factor']:6.1f}x real time), slowest {row['slowest_scan_ms']:6.1f} ms, "
                        f"peak {row['peak_rss_mb']:6.0f} MB, tiles {row['unique_tiles']}, ATE aligned "
                        f"{row['ate_aligned']:.3f} m",
                        flush=True,
                    )
    a.out.write_text(json.dumps({"provenance": prov, "rows": rows}, indent=2))
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
