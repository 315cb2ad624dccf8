"""What the bench scripts share: where the repository is, and the provenance every result records.

A script in a claim's folder (bench/CLAIM/script.py) imports this module after putting bench/ on
its path::

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from _common import DATA, ROOT, provenance  # noqa: E402

and writes ``"provenance": provenance()`` into the JSON it writes, so that a figure can be traced to
the code (commit, and whether src/ differed from it), the machine and the day that made it.
"""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
import time
from pathlib import Path
from typing import Any

BENCH = Path(__file__).resolve().parent
ROOT = BENCH.parent
DATA = Path(os.environ.get("PFSLAM_DATA") or ROOT.parent / "shared" / "data")  # the recordings, never copied here


def cpu_model() -> str:
    """The processor's model name as /proc/cpuinfo gives it (else what platform knows)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def machine() -> str:
    """One line naming the machine: CPU model and logical cores, e.g. 'Intel(R) Xeon(R) Processor, 2 cores'."""
    return f"{cpu_model()}, {os.cpu_count()} cores"


def _git(*args: str) -> str | None:
    try:
        proc = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return None
    return proc.stdout if proc.returncode == 0 else None


def peak_run(args: list[str]) -> tuple[float, float]:
    """(peak RSS in MB, seconds) of one child process running ``args``: the kernel's maximum resident
    set size of that child (``wait4``), so a parent that stays small leaves the figure to the child."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    seconds = time.perf_counter() - t0
    err = proc.stderr.read().decode() if proc.stderr else ""
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(args)} failed:\n{err}")
    return usage.ru_maxrss / 1024.0, seconds


def provenance(src: Path | None = None) -> dict[str, Any]:
    """Where a result comes from: the commit checked out (git rev-parse HEAD), the pfslam measured
    (``src``, by default the work tree's src/) and, when that is the work tree's, its files that
    differed from the commit when the bench ran; the machine (CPU model and cores), Python, the
    load average and the date (ISO, UTC)."""
    src = (src or ROOT / "src").resolve()
    out: dict[str, Any] = {"commit": (_git("rev-parse", "HEAD") or "unknown").strip()}
    if src == (ROOT / "src").resolve():
        changed = _git("status", "--porcelain", "--", "src")
        out["src_uncommitted"] = [line[3:] for line in changed.splitlines() if line.strip()] if changed else []
    else:
        out["pfslam_src"] = str(src)
    return {
        **out,
        "machine": machine(),
        "python": platform.python_version(),
        "load_average_at_start": [round(x, 2) for x in os.getloadavg()],
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
    }


def write_walks(doc: str, one: Any, kinds: tuple[str, ...], default_out: str, seeds: int = 20) -> None:
    """The command line of a script that writes simulated walks once (``doc``: its help):
    ``one(kind, seed, root)`` for every kind and seed 0..N-1 on a pool of processes (``one`` a
    module-level function, so that the pool can send it), printing the line each returns."""
    import argparse
    from concurrent.futures import ProcessPoolExecutor

    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=default_out, help=f"folder for the walks (default {default_out})")
    ap.add_argument("--seeds", type=int, default=seeds, help=f"seeds 0..N-1 (default {seeds})")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    root = Path(args.out)
    with ProcessPoolExecutor(args.workers) as pool:
        futures = [pool.submit(one, k, s, root) for k in kinds for s in range(args.seeds)]
        for f in futures:
            print(f.result(), flush=True)
