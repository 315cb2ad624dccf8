"""Sessions at length (issue 35): a 30,000-scan simulated THOR walk (750 s at 40 Hz) mapped,
its session's size on disk, then a second walk (the same building the other way round) resumed
onto it; the peak resident memory of both whole ``pfslam slam`` processes (the kernel's maximum
resident set of each child, as bench/memory/memory.py measures it).

    python bench/sessions/session_memory.py        # 30,000 scans, then 7,500 resumed
    python bench/sessions/session_memory.py --quick  # 7,500, then 1,875

Writes bench/sessions/session_memory.json (or --out), with the commit, machine and date (``provenance``).
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


def simulate(out: Path, seconds: float, seed: int, route: str) -> None:
    subprocess.run(
        [sys.executable, "-m", "pfslam.cli", "simulate", "-o", str(out), "--duration", str(seconds)]
        + ["--seed", str(seed), "--route", route],
        check=True,
        stdout=subprocess.DEVNULL,
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", type=Path, default=HERE / "session_memory.json")
    a = ap.parse_args()
    prov = provenance()
    first_s, second_s = (187.5, 46.875) if a.quick else (750.0, 187.5)
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        simulate(tmp / "simA", first_s, 3, "loop")
        simulate(tmp / "simB", second_s, 4, "reverse")
        rows = {}
        for name, sim, extra in (("first", "simA", []), ("resumed", "simB", ["--resume", str(tmp / "outA")])):
            out = tmp / ("outA" if name == "first" else "outB")
            mb, s = peak_run(
                [sys.executable, "-m", "pfslam.cli", "slam", str(tmp / sim / "train_lidar0.mat")]
                + ["-j", str(tmp / sim / "train_joint0.mat"), "-o", str(out), *extra]
            )
            run = json.loads((out / "run.json").read_text())
            size = sum(f.stat().st_size for f in (out / "session").iterdir()) / 2**20
            rows[name] = {"scans": run["scans_processed"], "peak_rss_mb": mb, "seconds": s, "session_mb": size}
            print(f"{name}: {run['scans_processed']} scans, peak RSS {mb:.1f} MB, {s:.1f} s, session {size:.1f} MB")
    ratio = rows["resumed"]["peak_rss_mb"] / rows["first"]["peak_rss_mb"]
    print(f"resumed / first peak RSS: {ratio:.2f}x")
    a.out.write_text(json.dumps({"provenance": prov, **rows, "resumed_over_first": ratio}, indent=2))


if __name__ == "__main__":
    main()
