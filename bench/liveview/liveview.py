"""What watching a run costs: `pfslam demo`'s SLAM (the 3-minute simulated office loop, seed 0,
7,200 scans) with no view, with --video (MP4, GIF) and with --rerun-save, in one process on
the same frames; and the run loop's own cost per step with and without an observer.

    python bench/liveview/liveview.py          # prints one JSON object (about 2 minutes)

Figures: the filter's scans per second (the views' time left out, as run.json reports it),
the wall time of the whole run, the views' own time, frames drawn and file sizes; and the commit,
machine and date that made them (``provenance``)."""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/, for the shared helpers
from _common import provenance  # noqa: E402


def loop_overhead(observer: object, steps: int = 200_000) -> float:
    """Nanoseconds per step of run_filter around a filter that does nothing (best of 5)."""
    from pfslam.frames import Estimate, Frame
    from pfslam.pipeline import run_filter

    class Idle:
        map = None
        odom_pose = np.zeros(3)
        est = Estimate(t=0.0, pose=np.zeros(3), n_eff=1.0, particles=1)

        def step(self, frame: Frame) -> Estimate:
            return self.est

        def trajectory(self) -> tuple[np.ndarray, np.ndarray]:
            return np.zeros(0), np.zeros((0, 3))

    frames = [Frame(t=float(i), ranges=np.ones(3), angles=np.zeros(3)) for i in range(steps)]
    best = np.inf
    for _ in range(5):
        t0 = time.perf_counter()
        run_filter(Idle(), frames, observer=observer)  # type: ignore[arg-type]
        best = min(best, time.perf_counter() - t0)
    return best / steps * 1e9


def main() -> None:
    from pfslam.config import SlamConfig
    from pfslam.frames import frame_times
    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import read_tum
    from pfslam.pipeline import run_slam
    from pfslam.tools.simulate import simulate
    from pfslam.views.live import ViewRequest

    tmp = Path(tempfile.mkdtemp(prefix="pfslam_liveview_"))
    res = simulate("office", 180.0, seed=0, out_dir=tmp / "log")
    frames = load_log(res.lidar_path, res.joint_path).frames
    truth = read_tum(res.groundtruth_path)
    cfg = SlamConfig()
    run_slam(frames[:200], cfg)  # compile and warm up
    out: dict[str, object] = {
        "provenance": provenance(),
        "scans": len(frames),
        "loop_ns_per_step": {"no observer": loop_overhead(None), "no-op observer": loop_overhead(lambda *a: None)},
    }
    for name, request in [
        ("none", None),
        ("none (again)", None),
        ("mp4", ViewRequest(video=tmp / "run.mp4")),
        ("gif", ViewRequest(video=tmp / "run.gif")),
        ("rrd", ViewRequest(rerun_save=tmp / "run.rrd")),
    ]:
        live = (
            None
            if request is None
            else request.open(frame_times(frames), truth, cfg.sensor.ground_z, "slam", "pfslam demo")
        )
        t0 = time.perf_counter()
        run = run_slam(frames, cfg, observer=live)
        if live is not None:
            live.close()
        row: dict[str, object] = {
            "scans_per_s": round(run.scans_per_second, 1),
            "wall_s": round(time.perf_counter() - t0, 2),
        }
        if live is not None:
            view = live.views[0]
            path = request.video or request.rerun_save
            row.update(view_s=round(view.seconds, 2), file_mb=round(path.stat().st_size / 1e6, 2), report=view.report())
        out[name] = row
        print(name, row, file=sys.stderr)
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
