"""pfslam ROS bag memory benchmark: peak resident memory of whole `pfslam slam BAG` runs on a
3,000- and a 30,000-scan ROS 1 bag (a simulated THOR log, 1,081 beams at 40 Hz, seeded,
written with `pfslam convert`: /scan, /odom, /tf_static and the head's /tf at every scan).

    python bench/memory/bag_memory.py            # 3,000 and 30,000 scans, writes bench/memory/bag_memory.json
    python bench/memory/bag_memory.py --quick    # 750 and 7,500 scans

Each run is the real command in its own process; its peak RSS is the kernel's maximum
resident set size of that child (``wait4``, :func:`_common.peak_run`), so it includes Python,
NumPy, Numba, Matplotlib and rosbags. The parent imports nothing of pfslam and makes the
logs and bags in children too (a child's maximum resident set counts its parent's pages at
the fork). A flat profile keeps the ratio between the long and the short bag near 1: the
bag's messages are read one at a time, never kept, and each scan's ranges go to a
temporary file as float32, read back one scan at a time. The result records the commit, machine
and date that made it (``provenance``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
from _common import peak_run, provenance  # noqa: E402

HERE = Path(__file__).resolve().parent
RATE = 40.0  # THOR scans per second


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="shorter bags (750 and 7,500 scans)")
    ap.add_argument("--out", type=Path, default=HERE / "bag_memory.json")
    a = ap.parse_args()
    prov = provenance()
    counts = (750, 7_500) if a.quick else (3_000, 30_000)
    pfslam = [sys.executable, "-m", "pfslam.cli"]
    rows = []
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        for n in counts:
            sim = tmp / f"sim{n}"
            subprocess.run(
                [*pfslam, "simulate", "-o", str(sim), "--duration", str(n / RATE), "--seed", "3"],
                check=True,
                stdout=subprocess.DEVNULL,
            )
            bag = tmp / f"log{n}.bag"
            convert_mb, convert_s = peak_run(
                [*pfslam, "convert", str(sim / "train_lidar0.mat"), str(bag), "-j", str(sim / "train_joint0.mat")]
            )
            out = tmp / f"out{n}"
            mb, s = peak_run([*pfslam, "slam", str(bag), "-o", str(out)])
            run = json.loads((out / "run.json").read_text())
            rows.append(
                {
                    "scans": run["scans_processed"],
                    "bag_mb": bag.stat().st_size / 1e6,
                    "peak_rss_mb": mb,
                    "seconds": s,
                    "scans_per_s": run["scans_per_second"],
                    "convert_peak_rss_mb": convert_mb,
                    "convert_seconds": convert_s,
                }
            )
            print(
                f"{rows[-1]['scans']:6d} scans ({rows[-1]['bag_mb']:.0f} MB bag): slam peak RSS {mb:6.1f} MB, "
                f"{s:5.1f} s; convert peak RSS {convert_mb:6.1f} MB, {convert_s:5.1f} s",
                flush=True,
            )
    short, long_ = rows
    long_["over_short"] = long_["peak_rss_mb"] / short["peak_rss_mb"]
    print(
        f"{long_['scans']} scans / {short['scans']} scans = {long_['over_short']:.2f}x the peak RSS of pfslam slam",
        flush=True,
    )
    a.out.write_text(json.dumps({"provenance": prov, "runs": rows}, indent=2))
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
