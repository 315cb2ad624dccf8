"""Does the scan match know what it pins? (issue 44) Each simulated walk's scans are matched
against a map drawn from the ground truth, from starts off the truth (3 cm and 1.5 deg,
Gaussian), by the filter's hill climb and then its Gauss-Newton steps on the smooth score
(kernels/refine.py); each match's error against the truth is set beside the covariance its
information predicts (``(info / lsigma^2)^-1``: every hit independent, of the likelihood's
width).

Reports per walk the RMS error along the robot's heading and across it, the climb's alone and
the refined one's, the predicted standard deviations (medians) and the fraction of refined
matches inside the 95 % ellipse of their prediction (chi-square, 3 degrees of freedom):
near 0.95 when the information is calibrated, above when it is conservative.

    python bench/scanmatch/scanmatch.py                 # the bare corridor and the open hall
    python bench/scanmatch/match_calibration.py         # writes bench/scanmatch/match_calibration.json

The result records the commit, machine and date that made it (``provenance``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
from _common import ROOT, provenance  # noqa: E402

HERE = Path(__file__).resolve().parent
CHI2_3_95 = 7.815


def walk(bag: Path, truth_tum: Path, every: int, starts: int, seed: int) -> dict[str, float]:
    from pfslam.config import SlamConfig, resolve_filter
    from pfslam.geometry import wrap_angle
    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import read_tum
    from pfslam.maps.tiled import TiledMaps
    from pfslam.sensor import beam_ends, scan_to_points, subsample

    log = load_log(bag, None)
    cfg = resolve_filter(SlamConfig(), log.format)  # the filter's settings for this kind of log
    c, m = cfg.rbpf, cfg.map
    frames = log.frames
    gt_t, gt = read_tum(truth_tum)
    heading = np.unwrap(gt[:, 2])
    rng = np.random.default_rng(seed)
    maps = TiledMaps(starts, resolution=m.resolution, l_occ=m.l_occ, l_free=m.l_free, l_clamp=m.l_clamp)
    sd = np.array([0.03, 0.03, np.deg2rad(1.5)])
    rows = []
    for k, f in enumerate(frames[::every]):
        truth = np.array(
            [np.interp(f.t, gt_t, gt[:, 0]), np.interp(f.t, gt_t, gt[:, 1]), np.interp(f.t, gt_t, heading)]
        )
        sp = scan_to_points(f, ground_z=cfg.sensor.ground_z)
        if not len(sp.hits):
            continue
        if k >= 10:
            pts = np.ascontiguousarray(subsample(sp.hits, c.match_hits))
            poses = truth + rng.normal(size=(starts, 3)) * sd
            maps.match(poses, pts, c.sigma, c.radius, c.lstep, np.deg2rad(c.astep_deg), c.refinements)
            climbed = poses.copy()
            _, info = maps.refine(
                poses, pts, c.sigma, max(c.refine, 3), poses.copy(), 0.0, 1.0, 1.0, c.lstep, np.deg2rad(c.astep_deg)
            )
            for e_climb, pose, a in zip(climbed - truth, poses, info / c.lsigma**2):
                e = pose - truth
                e[2] = wrap_angle(e[2])
                e_climb[2] = wrap_angle(e_climb[2])
                ch, sh = np.cos(truth[2]), np.sin(truth[2])
                rot = np.array([[ch, sh, 0.0], [-sh, ch, 0.0], [0.0, 0.0, 1.0]])  # world -> along/across
                cov = rot @ np.linalg.inv(a + np.eye(3) * 1e-9) @ rot.T
                rows.append((*(rot @ e_climb)[:2], *(rot @ e), float(e @ a @ e), *np.sqrt(np.diag(cov))))
        ends, hit = beam_ends(sp.hits, sp.floor, sp.sensor_xy, c.map_range)
        maps.update_all(np.tile(truth, (starts, 1)), sp.sensor_xy, ends, hit)
    r = np.array(rows)
    return {
        "matches": len(r),
        "climb_along_rms_m": float(np.sqrt(np.mean(r[:, 0] ** 2))),
        "climb_across_rms_m": float(np.sqrt(np.mean(r[:, 1] ** 2))),
        "refined_along_rms_m": float(np.sqrt(np.mean(r[:, 2] ** 2))),
        "refined_across_rms_m": float(np.sqrt(np.mean(r[:, 3] ** 2))),
        "refined_heading_rms_deg": float(np.degrees(np.sqrt(np.mean(r[:, 4] ** 2)))),
        "predicted_along_sd_median_m": float(np.median(r[:, 6])),
        "predicted_across_sd_median_m": float(np.median(r[:, 7])),
        "inside_95_percent_ellipse": float(np.mean(r[:, 5] < CHI2_3_95)),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--sims", type=Path, default=ROOT / "out" / "sims" / "scanmatch", help="bench/scanmatch/scanmatch.py's walks"
    )
    ap.add_argument("--seeds", type=int, default=2, help="walks 0..N-1 of each world (default 2)")
    ap.add_argument("--every", type=int, default=2, help="every k-th scan matched and mapped (default 2)")
    ap.add_argument("--starts", type=int, default=8, help="starts off the truth per scan (default 8)")
    ap.add_argument("--out", type=Path, default=HERE / "match_calibration.json")
    args = ap.parse_args()
    prov = provenance()
    results = {}
    for world in ("bare", "hall"):
        for seed in range(args.seeds):
            run = args.sims / world / f"seed{seed}"
            if not (run / "groundtruth.tum").exists():
                raise SystemExit(f"{run}: no walk there (run python bench/scanmatch/scanmatch.py first)")
            res = walk(run / "log.bag", run / "groundtruth.tum", args.every, args.starts, seed)
            results[f"{world}/seed{seed}"] = res
            print(f"{world} seed {seed}: " + ", ".join(f"{k} {v:.4g}" for k, v in res.items()), flush=True)
    args.out.write_text(json.dumps({"provenance": prov, "walks": results}, indent=2) + "\n")


if __name__ == "__main__":
    main()
