"""`pfslam demo` as a newcomer's first run meets it (an empty Numba cache: every kernel
compiled) and as every later run does (the cache filled), whole processes timed from outside.

Each cold run gets a fresh, empty NUMBA_CACHE_DIR; each warm run reuses the one its tree's
last cold run filled. Runs alternate between this tree and --compare's (the machine's drift
hits both alike); the figures are medians of --repeat runs.

    python bench/process/first_run.py --repeat 3 --compare /tmp/base/src

Writes bench/process/first_run.json (or --out) with the provenance.
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
from _common import ROOT, provenance  # noqa: E402

HERE = Path(__file__).resolve().parent


def run_once(src: Path, cache: Path, out: Path) -> float:
    """The wall clock (s) of one `pfslam demo` process with ``src`` on its path and ``cache`` as
    its Numba cache."""
    env = {**os.environ, "PYTHONPATH": str(src), "NUMBA_CACHE_DIR": str(cache)}
    start = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "pfslam.cli", "demo", "-o", str(out)], env=env, check=True, capture_output=True
    )
    return time.perf_counter() - start


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--compare", type=Path, help="another pfslam source tree (its src/)")
    ap.add_argument("--out", type=Path, default=HERE / "first_run.json")
    a = ap.parse_args()
    trees = {"this": ROOT / "src"} | ({"compare": a.compare.resolve()} if a.compare else {})
    times: dict[str, dict[str, list[float]]] = {k: {"cold": [], "warm": []} for k in trees}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(a.repeat):
            for name, src in trees.items():
                cache = Path(tmp) / f"cache-{name}-{r}"
                for kind in ("cold", "warm"):
                    s = run_once(src, cache, Path(tmp) / f"out-{name}")
                    times[name][kind].append(s)
                    print(f"{name} {kind} {s:.1f} s", flush=True)
    result = {
        "what": "pfslam demo (180 s THOR office walk, seed 0), whole process wall clock (s): cold = empty "
        "Numba cache, warm = the cache that run filled; medians of the runs listed",
        "runs": {
            k: {kind: {"median_s": statistics.median(v), "runs_s": v} for kind, v in t.items()}
            for k, t in times.items()
        },
        "provenance": provenance(),
        "compare_src": str(a.compare) if a.compare else None,
    }
    a.out.write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result["runs"], indent=1))


if __name__ == "__main__":
    main()
