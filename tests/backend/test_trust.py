"""The back end is trusted only where it makes the map agree better: a closure that makes the
map agree less is not kept, the run keeps the filter's answer and says so in one line."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import pfslam.backend.loops as loops_module
from pfslam.backend.loops import ClosureStats, LoopClosure, build_graph
from pfslam.backend.nodes import Nodes
from pfslam.backend.search import Loop
from pfslam.config import Backend, GraphConfig, SlamConfig
from pfslam.geometry import compose, relative
from pfslam.pipeline import close_loops
from pfslam.pipeline.run import run_slam


def bent_closure(poses: np.ndarray, degrees: float) -> LoopClosure:
    """A closure as a false loop would make it: the path turned by ``degrees`` from its middle."""
    out = poses.copy()
    mid = len(poses) // 2
    pivot = poses[mid]
    out[mid:] = compose(compose(pivot, np.array([0.0, 0.0, np.deg2rad(degrees)])), relative(pivot, poses[mid:]))
    nodes = Nodes(np.array([0, len(poses) - 1]), poses[[0, -1]], [], np.zeros((2, 3, 3)))
    lp = Loop(0, 1, 0, np.zeros(3), 0.9)
    return LoopClosure(
        out, nodes, build_graph(nodes, GraphConfig()), out[[0, -1]], [lp], ClosureStats(nodes=2, loops_in_graph=1)
    )


@pytest.mark.parametrize("degrees", [8.0, 0.0])
def test_a_closure_that_makes_the_map_agree_less_is_not_kept(short_office, monkeypatch, degrees) -> None:
    from pfslam.io.logs import load_log

    log = load_log(short_office.lidar_path, short_office.joint_path)
    cfg = SlamConfig(seed=1)
    alone = run_slam(log.frames, replace(cfg, backend=Backend.NONE), log_format=log.format)
    monkeypatch.setattr(
        loops_module,
        "close_loops",
        lambda frames, poses, config, progress=None, before=None: bent_closure(poses, degrees),
    )
    run = close_loops(run_slam(log.frames, cfg, log_format=log.format))
    step = run.backend
    assert step is not None and step.agreement_filter is not None and step.agreement_backend is not None
    if degrees:
        assert step.agreement_backend < step.agreement_filter
        assert not step.kept and run.closure is None
        assert np.array_equal(run.poses, alone.poses)  # the filter's answer, to the bit
        assert np.array_equal(run.grid.logodds, alone.grid.logodds)
        assert len(run.notes) == 1 and "loop closing not kept" in run.notes[0] and "\n" not in run.notes[0]
        assert "1 by this check" in run.notes[0]
    else:  # the same trajectory agrees as well: kept
        assert step.kept and run.closure is not None and not run.notes
    d = step.as_dict()
    assert d["kept"] == step.kept and d["map_agreement_filter"] == step.agreement_filter
    # the check can be turned off: then the closure stands, whatever it does to the map
    off = close_loops(
        run_slam(log.frames, replace(cfg, graph=GraphConfig(check_agreement=False)), log_format=log.format)
    )
    assert off.backend is not None and off.backend.kept and off.backend.agreement_filter is None


def test_the_change_in_map_agreement_comes_with_its_error(short_office) -> None:
    """The check's figure: a trajectory bent by 8 degrees half way agrees less than the truth by
    many standard errors; the same trajectory twice changes nothing; the per-split fractions
    give the very figure map_agreement reports."""
    from pfslam.eval.metrics import agreement_change, agreement_fractions, agreement_of, map_agreement
    from pfslam.io.logs import load_log

    frames = load_log(short_office.lidar_path, short_office.joint_path).frames
    truth = short_office.truth
    bent = bent_closure(truth, 8.0).poses
    fa, fb = agreement_fractions(frames, truth), agreement_fractions(frames, bent)
    assert agreement_of(fa) == map_agreement(frames, truth)
    change, se = agreement_change(fa, fb)
    assert change == pytest.approx(agreement_of(fb) - agreement_of(fa))
    assert change < -2 * se < 0
    assert agreement_change(fa, fa) == (0.0, 0.0)


def test_when_far_loops_make_the_map_worse_the_near_ones_are_kept_alone(short_office, monkeypatch) -> None:
    """A closure whose one far loop bends the path (the map agrees less) but which also has near
    loops (within the local window of where the filter put their nodes): the run keeps a
    closure of the near loops alone, solved from the filter's poses, and says so."""
    from pfslam.io.logs import load_log

    log = load_log(short_office.lidar_path, short_office.joint_path)
    cfg = SlamConfig(seed=1)

    def closure(frames, poses, config, progress=None, before=None):
        c = bent_closure(poses, 8.0)
        n = len(poses)
        idx = np.linspace(0, n - 1, 12).round().astype(np.int64)
        nodes = Nodes(idx, poses[idx], [], np.zeros((len(idx), 3, 3)))
        near = [Loop(k, k + 2, 0, relative(poses[idx[k]], poses[idx[k + 2]]), 0.9) for k in range(0, 9, 3)]
        far = Loop(0, 11, 0, np.array([0.0, 0.0, 0.0]), 0.9)
        loops = near + [far]
        stats = ClosureStats(nodes=len(idx), loops_in_graph=len(loops))
        return LoopClosure(c.poses, nodes, build_graph(nodes, config.graph, loops), c.poses[idx], loops, stats)

    monkeypatch.setattr(loops_module, "close_loops", closure)
    run = close_loops(run_slam(log.frames, cfg, log_format=log.format))
    step = run.backend
    assert step is not None and step.kept and step.closure is not None
    assert len(step.closure.loops) == 3 and step.closure.stats.refused_far == 1
    assert len(run.notes) == 1 and "near loops only" in run.notes[0]
    # the near loops agree with the filter: its trajectory, about
    alone = run_slam(log.frames, replace(cfg, backend=Backend.NONE), log_format=log.format)
    assert np.abs(run.poses[:, :2] - alone.poses[:, :2]).max() < 0.01


def test_the_report_names_every_check_that_refused_a_loop() -> None:
    from pfslam.backend.loops import ClosureStats

    s = ClosureStats(refused_ambiguous=1, refused_gate=12, refused_pairs=3, loops_dropped=2)
    assert s.refused == 18
    assert s.refusals() == (
        "1 ambiguous, 12 off the filter's path, 3 at odds with their neighbours, 2 dropped by the solve"
    )
    assert s.refusals().count(",") == 3  # (the checks that are off by default only when they refused)
    assert "2 unchained" in ClosureStats(refused_unchained=2).refusals()
    spread = ClosureStats(refused_spread=3)
    assert spread.refused == 3 and "3 with look-alikes all round" in spread.refusals()
