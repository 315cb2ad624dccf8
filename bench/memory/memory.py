"""pfslam memory benchmark: peak resident memory of whole `pfslam slam` runs against the
length of the log (THOR format, simulated, seeded).

    python bench/memory/memory.py            # 7,500- and 30,000-scan logs, writes bench/memory/memory.json
    python bench/memory/memory.py --quick    # 1,875 and 7,500 scans

Each run is the real command in its own process; its peak RSS is the kernel's maximum
resident set size of that child (``wait4``), so it includes Python, NumPy, Numba and
Matplotlib (about 230 MB before a log is opened) and everything the run held at once.
A flat profile means the ratio between the long and the short log stays near 1: the
scans stay on disk and are read one at a time; what grows with the log is a few hundred
bytes per scan (times, odometry, mounts, the trajectory). The result records the commit, machine
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
COMPRESS = """
import sys, scipy.io as sio
m = {k: v for k, v in sio.loadmat(sys.argv[1]).items() if not k.startswith("__")}
sio.savemat(sys.argv[2], m, do_compression=True)
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="shorter logs (1,875 and 7,500 scans)")
    ap.add_argument("--out", type=Path, default=HERE / "memory.json")
    a = ap.parse_args()
    prov = provenance()
    # The parent stays small and imports nothing of pfslam: a child's maximum resident set
    # counts its parent's pages at the fork, so the logs are made in children too.
    lengths = (46.875, 187.5) if a.quick else (187.5, 750.0)  # seconds at 40 Hz
    rows = []
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        for seconds in lengths:
            sim = tmp / f"sim{int(seconds)}"
            subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "pfslam.cli",
                    "simulate",
                    "-o",
                    str(sim),
                    "--duration",
                    str(seconds),
                    "--seed",
                    "3",
                ],
                check=True,
                stdout=subprocess.DEVNULL,
            )
            for compressed in (False, True):
                lidar = sim / "train_lidar0.mat"
                if compressed:  # the real THOR files are compressed (MATLAB -v7)
                    lidar = tmp / f"z{int(seconds)}.mat"
                    subprocess.run(
                        [sys.executable, "-c", COMPRESS, str(sim / "train_lidar0.mat"), str(lidar)], check=True
                    )
                out = tmp / f"out{int(seconds)}{'z' if compressed else ''}"
                mb, s = peak_run(
                    [
                        sys.executable,
                        "-m",
                        "pfslam.cli",
                        "slam",
                        str(lidar),
                        "-j",
                        str(sim / "train_joint0.mat"),
                        "-g",
                        str(sim / "groundtruth.tum"),
                        "-o",
                        str(out),
                    ]
                )
                run = json.loads((out / "run.json").read_text())
                rows.append(
                    {
                        "scans": run["scans_processed"],
                        "compressed": compressed,
                        "peak_rss_mb": mb,
                        "seconds": s,
                        "scans_per_s": run["scans_per_second"],
                    }
                )
                print(
                    f"{rows[-1]['scans']:6d} scans ({'compressed' if compressed else 'plain'} .mat): "
                    f"peak RSS {mb:6.1f} MB, {s:5.1f} s",
                    flush=True,
                )
    for compressed in (False, True):
        short, long_ = [r for r in rows if r["compressed"] == compressed]
        ratio = long_["peak_rss_mb"] / short["peak_rss_mb"]
        long_["over_short"] = ratio
        print(
            f"{'compressed' if compressed else 'plain'}: {long_['scans']} scans / {short['scans']} scans = "
            f"{ratio:.2f}x the peak RSS",
            flush=True,
        )
    a.out.write_text(json.dumps({"provenance": prov, "runs": rows}, indent=2))
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
