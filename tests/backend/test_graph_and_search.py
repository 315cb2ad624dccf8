"""The loop-closing back end: the pose graph and its robust solve, g2o files, the loop
search on a known offset, and what it does to a run (nothing without loops; not moved by
false loops)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from datafiles import need

from pfslam.backend.graph import PoseGraph, read_g2o, solve, whitened, write_g2o
from pfslam.backend.loops import place_scans
from pfslam.backend.nodes import build_submap, frame_scans, select_nodes
from pfslam.backend.settings import BackendSettings
from pfslam.config import Backend, GraphConfig, RobustLoss, SlamConfig
from pfslam.geometry import compose, relative
from pfslam.kernels.bnb import window_match
from pfslam.pipeline import close_loops
from pfslam.pipeline.run import run_slam

SIG = np.array([0.02, 0.02, np.deg2rad(0.5)])
LOOP_SIG = np.array([0.05, 0.05, np.deg2rad(1.0)])


def square_loop(rng: np.random.Generator, n_side: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """True poses around a 5 m square, and dead reckoning of noisy steps with a heading bias."""
    steps = []
    for _ in range(4):
        steps += [np.array([0.5, 0.0, 0.0])] * (n_side - 1) + [np.array([0.5, 0.0, np.pi / 2])]
    true = [np.zeros(3)]
    odo = [np.zeros(3)]
    for u in steps:
        true.append(compose(true[-1], u))
        noisy = u + rng.normal(0, [0.005, 0.005, 0.003]) + np.array([0.0, 0.0, 0.004])
        odo.append(compose(odo[-1], noisy))
    return np.array(true), np.array(odo)


def odometry_graph(true: np.ndarray, odo: np.ndarray) -> PoseGraph:
    g = PoseGraph(odo.copy())
    k = np.arange(len(odo) - 1)
    g.add_many(k, k + 1, relative(odo[:-1], odo[1:]), np.tile(SIG, (len(k), 1)), np.zeros(len(k), bool))
    return g


@pytest.mark.parametrize("loss", list(RobustLoss))
def test_a_true_loop_edge_pulls_the_drift_back(loss: RobustLoss) -> None:
    true, odo = square_loop(np.random.default_rng(0))
    g = odometry_graph(true, odo)
    for a, b in ((0, len(true) - 1), (1, len(true) - 2), (2, len(true) - 3)):
        g.add(a, b, relative(true[a], true[b]), LOOP_SIG, True)
    out, keep = solve(g, loss, 3.0)
    before = np.hypot(*(odo[:, :2] - true[:, :2]).T).max()
    after = np.hypot(*(out[:, :2] - true[:, :2]).T).max()
    assert before > 0.3
    assert after < 0.25 * before
    assert keep.all()
    assert out[0] == pytest.approx(odo[0])  # the first pose stays


def test_graduated_non_convexity_drops_false_loops_that_cauchy_would_follow() -> None:
    true, odo = square_loop(np.random.default_rng(1))
    g = odometry_graph(true, odo)
    n = len(true)
    g.add(0, n - 1, relative(true[0], true[n - 1]), LOOP_SIG, True)
    good, _ = solve(g, RobustLoss.GNC, 3.0)
    rng = np.random.default_rng(2)
    for _ in range(6):  # wrong loops, several metres off
        a, b = sorted(rng.choice(n, 2, replace=False))
        g.add(int(a), int(b), np.array([rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-1, 1)]), LOOP_SIG, True)
    out, keep = solve(g, RobustLoss.GNC, 3.0)
    assert keep[0] and not keep[1:].any()
    assert np.abs(out[:, :2] - good[:, :2]).max() < 0.01


def test_whitened_errors_are_zero_on_the_edges_own_poses() -> None:
    true, odo = square_loop(np.random.default_rng(3))
    g = odometry_graph(true, odo)
    assert whitened(g, odo).max() < 1e-9
    assert whitened(g, true).max() > 0.1


def test_g2o_round_trip(tmp_path) -> None:
    true, odo = square_loop(np.random.default_rng(4), 4)
    g = odometry_graph(true, odo)
    g.add(0, 12, relative(true[0], true[12]), LOOP_SIG, True)
    p = write_g2o(tmp_path / "g.g2o", g, true)
    lines = p.read_text().splitlines()
    assert lines[0].startswith("VERTEX_SE2 0 ")
    assert sum(x.startswith("EDGE_SE2 ") for x in lines) == len(g.i)
    # an edge line: ids, measurement, upper triangle of the information (6 numbers)
    assert len(lines[len(true)].split()) == 12
    back = read_g2o(p)
    assert back.poses == pytest.approx(true, abs=1e-6)
    assert back.z == pytest.approx(g.z, abs=1e-6)
    assert back.sigma == pytest.approx(g.sigma, rel=1e-4)
    assert back.loop.tolist() == g.loop.tolist()


def test_scans_between_nodes_follow_both_nodes() -> None:
    front = np.array([[0.1 * k, 0.0, 0.0] for k in range(11)])
    from pfslam.backend.nodes import Nodes

    nodes = Nodes(np.array([0, 10]), front[[0, 10]], [])
    shifted = front[[0, 10]] + np.array([[0.0, 0.0, 0.0], [0.0, 0.2, 0.0]])
    out = place_scans(nodes, front, shifted)
    assert out[0] == pytest.approx(front[0])
    assert out[10] == pytest.approx(shifted[1])
    assert out[5, 1] == pytest.approx(0.1)  # half way: half the correction
    assert place_scans(nodes, front, front[[0, 10]]) == pytest.approx(front)


# -- on logs -------------------------------------------------------------------------------


def test_a_run_without_loops_keeps_the_front_end_trajectory(short_office) -> None:
    """Ten seconds of walking never returns anywhere: no loop, the trajectory is the filter's
    to the bit, and the map is the filter's trajectory mapped again."""
    from pfslam.io.logs import load_log

    log = load_log(short_office.lidar_path, short_office.joint_path)
    cfg = SlamConfig(seed=1)
    none = run_slam(log.frames, replace(cfg, backend=Backend.NONE), log_format=log.format)
    graph = close_loops(run_slam(log.frames, cfg, log_format=log.format))
    assert graph.closure is not None and graph.closure.stats.loops_in_graph == 0
    assert np.array_equal(graph.poses, none.poses)
    assert np.array_equal(graph.grid.logodds, none.grid.logodds)
    assert graph.closure.stats.nodes > 4  # (a node every half metre)


def test_a_known_offset_is_found_by_the_wide_search(office_log) -> None:
    """A node's scan matched against a submap of the office from a guess 1.2 m and 14 deg off:
    the search lands within 3 cm and 0.5 deg of where the filter placed it."""
    cfg = SlamConfig(seed=0)
    frames = office_log.frames[:1200]
    run = run_slam(frames, replace(cfg, backend=Backend.NONE), log_format=office_log.format)
    settings = BackendSettings.of(cfg)
    nodes = select_nodes(frames, run.poses, settings)
    sub = build_submap(frame_scans(frames, nodes, settings), nodes, 0, 20, settings, 6)
    assert sub is not None
    i = 12
    truth = relative(nodes.poses[0], nodes.poses[i])
    guess = compose(truth, np.array([1.0, -0.7, np.deg2rad(14.0)]))
    m = window_match(sub, nodes.points[i], guess, 2.0, 20.0, 0.5, cfg.map.resolution, True)
    assert m is not None
    d = relative(truth, m[0])
    assert np.hypot(d[0], d[1]) < 0.03 and abs(np.rad2deg(d[2])) < 0.5
    # outside the window it is not found
    far = compose(truth, np.array([3.5, 0.0, 0.0]))
    assert window_match(sub, nodes.points[i], far, 1.0, 5.0, 0.6, cfg.map.resolution) is None


@pytest.mark.realdata
def test_false_loops_do_not_move_a_real_run() -> None:
    """A real run's graph (orebro, CARMEN) with 5 % more loop edges at random wrong poses: the
    solve that sorts the loops (graduated non-convexity) moves the trajectory by less than 1 cm."""
    from pfslam.io.logs import load_log

    log = load_log(need("carmen/orebro.gfs.log.gz"))
    cfg = SlamConfig(seed=0)
    run = close_loops(run_slam(log.frames, cfg, log_format=log.format))
    assert run.backend is not None and run.backend.closure is not None
    graph = run.backend.closure.graph
    assert graph.loops > 20
    loss = RobustLoss.GNC
    clean, _ = solve(graph, loss, cfg.graph.loss_scale)
    rng = np.random.default_rng(0)
    n = len(graph.poses)
    k = max(1, int(0.05 * len(graph.i)))
    a = rng.integers(0, n, k)
    b = rng.integers(0, n, k)
    z = np.column_stack([rng.uniform(-5, 5, k), rng.uniform(-5, 5, k), rng.uniform(-np.pi, np.pi, k)])
    graph.add_many(a, b, z, np.tile(LOOP_SIG, (k, 1)), np.ones(k, bool))
    noisy, keep = solve(graph, loss, cfg.graph.loss_scale)
    assert not keep[-k:].any()
    assert np.hypot(*(noisy[:, :2] - clean[:, :2]).T).max() < 0.01


def test_graph_settings_are_checked() -> None:
    from pfslam.errors import ConfigError

    with pytest.raises(ConfigError, match="graph.min_score"):
        SlamConfig(graph=GraphConfig(min_score=1.5))
    with pytest.raises(ConfigError, match="backend"):
        SlamConfig(backend="pose-graph")  # type: ignore[arg-type]


def test_graph_settings_without_the_graph_are_refused() -> None:
    from pfslam.config import resolve_filter
    from pfslam.errors import ConfigError

    with pytest.raises(ConfigError, match=r"graph.window_m is not read with backend: none"):
        resolve_filter(SlamConfig(backend=Backend.NONE, graph=GraphConfig(window_m=3.0)))
    assert resolve_filter(SlamConfig(graph=GraphConfig(window_m=3.0))).graph.window_m == 3.0


def test_the_cli_writes_the_graph_and_says_what_it_did(short_office, tmp_path) -> None:
    """`pfslam slam` writes graph.g2o (the optimised nodes and every edge) and the back end's
    figures in run.json; --backend none writes neither."""
    import json

    from clirun import invoke

    out = tmp_path / "g"
    r, err = invoke("slam", short_office.lidar_path, "-j", short_office.joint_path, "-o", out)
    assert r.exit_code == 0, err
    assert "loop closing:" in r.output
    info = json.loads((out / "run.json").read_text())
    b = info["backend"]
    assert b["nodes"] > 4 and b["loops_tried"] >= b["loops_in_graph"] >= 0 and b["seconds"] > 0
    g = read_g2o(out / "graph.g2o")
    assert len(g.poses) == b["nodes"] and g.loops == b["loops_in_graph"]
    assert info["config"]["backend"] == "graph"
    # the command's phases: the filter loop as the run measured it; the back end a step of its
    # own (how long each takes is measured in bench/, not here)
    ph = info["seconds_by_phase"]
    assert set(ph) >= {"load", "filter", "backend", "session", "score", "write"}
    assert ph["filter"] == info["seconds"]  # the same measure, written twice (no time compared)
    out2 = tmp_path / "n"
    r, err = invoke("slam", short_office.lidar_path, "-j", short_office.joint_path, "-o", out2, "--backend", "none")
    assert r.exit_code == 0, err
    assert not (out2 / "graph.g2o").exists() and "backend" not in json.loads((out2 / "run.json").read_text())


def test_loop_edges_are_checked_against_a_truth() -> None:
    """run.json's loop_edges: of the loops whose nodes the truth covers, those farther than
    0.2 m or 3 deg from the truth's relative pose."""
    from types import SimpleNamespace

    from pfslam.backend.loops import LoopClosure
    from pfslam.backend.nodes import Nodes
    from pfslam.backend.search import Loop
    from pfslam.pipeline.closing import BackendStep
    from pfslam.pipeline.score import score_loops

    t = np.arange(10.0)
    truth_poses = np.array([[0.3 * k, 0.1 * k, 0.05 * k] for k in range(10)])
    nodes = Nodes(np.array([0, 4, 9]), truth_poses[[0, 4, 9]], [])
    right = relative(truth_poses[0], truth_poses[9])
    sure = np.diag([1e4, 1e4, 1e5])  # what each match pins: 1 cm, 0.2 deg
    turned = relative(truth_poses[4], truth_poses[9])
    loops = [
        Loop(0, 2, 0, right, 0.9, sure),
        Loop(0, 2, 1, compose(right, np.array([0.5, 0.0, 0.0])), 0.8, sure),
        # 4 deg off, but with look-alikes 5 deg either way: off, and as unsure as it says
        Loop(1, 2, 1, compose(turned, np.array([0.0, 0.0, np.deg2rad(4.0)])), 0.7, sure, np.diag([0, 0, 0.0076])),
    ]
    closure = LoopClosure(truth_poses, nodes, PoseGraph(nodes.poses), nodes.poses, loops)
    run = SimpleNamespace(backend=BackendStep(closure, 0.0, kept=True), t=t, metrics={}, config=SlamConfig())
    score_loops(run, (t, truth_poses))  # type: ignore[arg-type]
    assert run.metrics["loop_edges"] == {
        "found": 3,
        "found_off": 2,
        "solved": 3,
        "solved_off": 2,
        "solved_off_beyond_own": 1,
        "kept": 3,
        "kept_off": 2,
        "unchecked": 0,
    }
    # the loops found before the checks are scored too; a refused answer keeps none
    closure.found = [*loops, Loop(1, 2, 0, compose(right, np.array([0.0, 0.3, 0.0])), 0.6)]
    run.backend.kept = False
    score_loops(run, (t, truth_poses))  # type: ignore[arg-type]
    e = run.metrics["loop_edges"]
    assert (e["found"], e["found_off"], e["solved_off"], e["kept"], e["kept_off"]) == (4, 3, 2, 0, 0)
    # a truth that covers only the first half checks no loop
    run.metrics = {}
    score_loops(run, (t[:5], truth_poses[:5]))  # type: ignore[arg-type]
    assert run.metrics["loop_edges"]["unchecked"] == 4 and run.metrics["loop_edges"]["found_off"] == 0
