"""Where places repeat, the back end's answer is never worse than the filter's: the simulated
twins world (two identical corridors walked the same way 6.4 m apart) fools the loop search,
and the checks of each loop against the front end's path and the other loops keep those loops
out of the graph."""

from __future__ import annotations

import numpy as np
import pytest

import pfslam.backend.loops as loops_module
from pfslam.config import SlamConfig
from pfslam.eval.metrics import trajectory_errors
from pfslam.pipeline import close_loops
from pfslam.pipeline.run import run_slam
from pfslam.pipeline.score import score_loops


@pytest.mark.slow
def test_loops_an_identical_corridor_fakes_are_kept_out(tmp_path, monkeypatch) -> None:
    from pfslam.io.logs import load_log
    from pfslam.tools.simulate import simulate

    sim = simulate("twins", 180.0, seed=0, out_dir=tmp_path / "twins", rate_hz=20.0)
    log = load_log(sim.lidar_path, sim.joint_path)
    truth = (sim.t, sim.truth)
    seen: dict[str, object] = {}
    real = loops_module.close_loops

    def recording(frames, poses, config, progress=None, before=None):
        seen["front"] = poses.copy()
        seen["closure"] = c = real(frames, poses, config, progress, before)
        return c

    monkeypatch.setattr(loops_module, "close_loops", recording)
    run = close_loops(run_slam(log.frames, SlamConfig(seed=0), log_format=log.format))
    # the search was fooled: loops off the truth by metres were found ...
    score_loops(run, truth)
    edges = run.metrics["loop_edges"]
    assert edges["found_off"] >= 5, edges
    # ... and the checks against the path and each other kept every one of them out of the
    # graph: the answer is the back end's whole (no fallback), and better than the filter's
    assert run.backend is not None and run.backend.kept and run.notes == []
    assert edges["solved_off"] == edges["kept_off"] == 0 and edges["kept"] > 10, edges
    stats = run.backend.closure.stats if run.backend.closure is not None else None
    assert stats is not None and stats.refused_gate + stats.refused_pairs > 0
    alone = trajectory_errors(run.t, np.asarray(seen["front"]), *truth).ate_rmse_aligned
    assert trajectory_errors(run.t, run.poses, *truth).ate_rmse_aligned < alone - 0.005
