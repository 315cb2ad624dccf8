"""What an adaptive particle count (KLD-sampling) would choose in the Rao-Blackwellized filter.

At every resampling of a `pfslam slam` run (default settings, synthetic odometry seed 0) the
resampled cloud is binned in (x, y, heading) at several bin sizes, and Fox's KLD bound
(err 0.05, z 0.99: AMCL's quantile) is read for the bins it occupies; the surviving lineages
(distinct parents) are counted too. The filter is watched by wrapping its ``settle`` (the
step that resamples); its outputs are not changed.

    python bench/defaults/particle_bins.py                 # Intel and FR079 from ../shared/data
    python bench/defaults/particle_bins.py --logs intel

Prints one table per log and writes bench/defaults/particle_bins.json (or --out), with the commit,
machine and date that made it (``provenance``).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
from _common import DATA, provenance  # noqa: E402

HERE = Path(__file__).resolve().parent
BINS = ((0.05, 1.0), (0.1, 2.0), (0.25, 5.0), (0.5, 10.0))  # (m, deg): the matcher's step .. AMCL's


def watch(log: Path) -> dict[str, object]:
    """Bin counts of the resampled clouds of one run of ``log``."""
    import pfslam
    from pfslam.filters import rbpf
    from pfslam.filters.localize import kld_bounds

    seen: dict[str, list[int]] = {f"{m} m / {d} deg": [] for m, d in BINS}
    lineages: list[int] = []
    settle = rbpf.RaoBlackwellizedSlam.settle

    def watched(self: rbpf.RaoBlackwellizedSlam) -> bool:
        did = settle(self)
        if did:
            p = self.poses
            for (m, d), counts in zip(BINS, seen.values()):
                b = np.floor(np.column_stack([p[:, 0] / m, p[:, 1] / m, np.rad2deg(p[:, 2]) / d]))
                counts.append(len(np.unique(b, axis=0)))
            lineages.append(len(np.unique(self._parents)))
        return did

    rbpf.RaoBlackwellizedSlam.settle = watched  # type: ignore[method-assign]
    try:
        with tempfile.TemporaryDirectory() as tmp:
            pfslam.slam(log, out=tmp, odometry="synthetic:0")
    finally:
        rbpf.RaoBlackwellizedSlam.settle = settle  # type: ignore[method-assign]
    out: dict[str, object] = {"resamplings": len(lineages), "lineages_median": float(np.median(lineages))}
    for name, counts in seen.items():
        k = np.array(counts)
        n = kld_bounds(k, 0.05, 0.99)
        out[name] = {
            "bins_median": float(np.median(k)),
            "one_bin_fraction": round(float(np.mean(k == 1)), 3),
            "kld_median": float(np.median(n)),
            "kld_below_30_fraction": round(float(np.mean(n < 30)), 3),
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--logs", nargs="+", default=["intel", "fr079"])
    ap.add_argument("--out", type=Path, default=HERE / "particle_bins.json")
    a = ap.parse_args()
    result: dict[str, object] = {"provenance": provenance()}
    for name in a.logs:
        log = DATA / "carmen" / f"{name}.gfs.log.gz"
        result[name] = watch(log)
        print(name, json.dumps(result[name], indent=1))
    a.out.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
