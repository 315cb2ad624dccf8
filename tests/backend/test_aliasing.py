"""Where places repeat, the back end's answer is never worse than the filter's: the simulated
twins world (two identical corridors walked the same way 6.4 m apart) fools the loop search,
and the checks keep those loops out of the answer."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import pfslam.backend.loops as loops_module
from pfslam.config import SlamConfig
from pfslam.eval.metrics import trajectory_errors
from pfslam.pipeline.run import BackendStep, run_slam
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
    run = run_slam(log.frames, SlamConfig(seed=0), log_format=log.format)
    # the search was fooled: before the check, loops off the truth by metres were in its graph
    found = seen["closure"]
    probe = SimpleNamespace(backend=BackendStep(found, 0.0, kept=True), t=run.t, metrics={})
    score_loops(probe, truth)  # type: ignore[arg-type]
    assert probe.metrics["loop_edges"]["solved_off"] >= 10
    # ... and none of them is in the answer, which is no worse than the filter's alone
    score_loops(run, truth)
    assert run.backend is not None and run.backend.kept
    assert run.metrics["loop_edges"]["kept_off"] == 0 and run.metrics["loop_edges"]["kept"] > 20
    alone = trajectory_errors(run.t, np.asarray(seen["front"]), *truth).ate_rmse_aligned
    assert trajectory_errors(run.t, run.poses, *truth).ate_rmse_aligned <= alone + 0.005
    assert len(run.notes) == 1 and "near loops only" in run.notes[0]
