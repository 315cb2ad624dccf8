"""Continuing a map with a second log (``pfslam slam LOG --resume DIR``): a second walk through
the simulated office, the other way round from half way along, resumed onto the first walk's
session; a log of another building refused."""

from __future__ import annotations

import json

import numpy as np
import pytest
from clirun import invoke, one_line_error

from pfslam.eval.metrics import align_se2
from pfslam.geometry import compose, relative
from pfslam.io.trajectory import read_tum
from pfslam.pipeline.prepare import map_file


@pytest.fixture(scope="module")
def walks(tmp_path_factory):
    """Two walks through the office (the second reversed) and a walk through the corridor
    world, at 20 Hz; the first walk's SLAM run."""
    from pfslam.tools.simulate import simulate

    root = tmp_path_factory.mktemp("sessions")
    a = simulate("office", 70.0, seed=1, out_dir=root / "simA", rate_hz=20.0)
    b = simulate("office", 50.0, seed=2, out_dir=root / "simB", rate_hz=20.0, route="reverse")
    res, err = invoke("slam", a.lidar_path, "-j", a.joint_path, "-o", root / "outA")
    assert res.exit_code == 0, err
    return root, a, b


def _truth_in_first_frame(root, times):
    """The second walk's true poses at ``times`` in the first run's map frame."""
    ta, ga = read_tum(root / "simA" / "groundtruth.tum")
    _, gwa = read_tum(root / "simA" / "groundtruth_world.tum")
    tb, gwb = read_tum(root / "simB" / "groundtruth_world.tum")
    frame = compose(gwa[0], relative(ga[0], np.zeros(3)))  # where the first run's frame is in the world
    return relative(frame, gwb[np.clip(np.searchsorted(tb, times - 1e-4), 0, len(tb) - 1)])


def test_a_second_walk_continues_the_first_ones_map(walks) -> None:
    root, a, b = walks
    res, err = invoke("slam", b.lidar_path, "-j", b.joint_path, "--resume", root / "outA", "-o", root / "outB")
    assert res.exit_code == 0, err
    info = json.loads((root / "outB" / "run.json").read_text())
    start = info["session"]["start"]
    assert start["found"] and start["mode"] == "found" and not start["given"] and start["score"] >= 0.6
    first = json.loads((root / "outA" / "run.json").read_text())["session"]
    assert first["start"] == {"mode": "none"} and "resumed" not in first
    assert info["session"]["resumed"] == str(root / "outA") and info["session"]["runs"] == 2
    # the second walk in the first run's frame (the first run's trajectory fitted to its truth,
    # the same fit applied to the second's), as near the truth as the first run is
    ta, ea = read_tum(root / "outA" / "trajectory.tum")
    tga, ga = read_tum(root / "simA" / "groundtruth.tum")
    fit = align_se2(ea, ga[np.clip(np.searchsorted(tga, ta - 1e-4), 0, len(tga) - 1)])
    tb, eb = read_tum(root / "outB" / "trajectory.tum")
    err_b = np.hypot(*(compose(fit, eb)[:, :2] - _truth_in_first_frame(root, tb)[:, :2]).T)
    assert np.sqrt((err_b**2).mean()) <= 0.03, np.sqrt((err_b**2).mean())
    # the merged session: the first run's nodes as they were, then the second's; graph.g2o has both
    a_nodes = json.loads((root / "outA" / "session" / "session.json").read_text())["nodes"]
    merged = json.loads((root / "outB" / "session" / "session.json").read_text())
    assert merged["nodes"] > a_nodes and [r["run"] for r in merged["runs"]] == [0, 1]
    vertices = [ln for ln in (root / "outB" / "graph.g2o").read_text().splitlines() if ln.startswith("VERTEX")]
    assert len(vertices) == merged["nodes"]
    # loops between the sessions were found (the walks share every corridor)
    assert info["backend"]["loops_in_graph"] > 0 and info["backend"]["kept"]
    # a localization can use the folder as its map
    assert map_file(root / "outB") == root / "outB" / "map.yaml"


def test_a_resumed_run_scores_only_its_own_loops_against_its_truth(walks, tmp_path) -> None:
    """The second walk's truth covers its own nodes, not the first walk's held ones: the loops
    onto those are left unchecked, not scored against the second walk's last pose."""
    root, _, b = walks
    out = tmp_path / "outG"
    truth = root / "simB" / "groundtruth.tum"
    res, err = invoke(
        "slam", b.lidar_path, "-j", b.joint_path, "--resume", root / "outA", "--ground-truth", truth, "-o", out
    )
    assert res.exit_code == 0, err
    info = json.loads((out / "run.json").read_text())
    edges = info["metrics"]["loop_edges"]
    assert info["backend"]["loops_in_graph"] > 0
    # (the walks share every corridor: most loops reach back to the first walk's nodes)
    assert 0 < edges["unchecked"] <= edges["found"]
    assert edges["found_off"] <= max(1, (edges["found"] - edges["unchecked"]) // 10), edges
    assert "ate_rmse" in json.dumps(info["metrics"])  # the trajectory itself is scored


def test_a_log_of_another_building_is_refused_in_one_line(walks, tmp_path) -> None:
    from pfslam.tools.simulate import simulate

    root, _, _ = walks
    c = simulate("corridor", 20.0, seed=3, out_dir=tmp_path / "simC", rate_hz=20.0)
    res, err = invoke("slam", c.lidar_path, "-j", c.joint_path, "--resume", root / "outA", "-o", tmp_path / "outC")
    one_line_error(res, err, "--start", "cannot place its first scan")
    assert not (tmp_path / "outC").exists()


def test_resuming_from_a_folder_without_a_session_is_one_line(walks, tmp_path) -> None:
    _, a, _ = walks
    res, err = invoke("slam", a.lidar_path, "-j", a.joint_path, "--resume", tmp_path, "-o", tmp_path / "out")
    one_line_error(res, err, str(tmp_path), "holds no session")
    assert not (tmp_path / "out").exists()
    res, err = invoke("slam", a.lidar_path, "-j", a.joint_path, "--start", "1,2,3", "-o", tmp_path / "out")
    one_line_error(res, err, "--start", "--resume")
