"""A session on disk (what --resume reads) and the global search that places a new log's start
in an old map."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pfslam.backend.graph import PoseGraph
from pfslam.backend.nodes import SessionNodes
from pfslam.backend.settings import BackendSettings
from pfslam.backend.start import find_start, map_field, start_points
from pfslam.config import SlamConfig
from pfslam.errors import InputError
from pfslam.geometry import relative
from pfslam.maps.grid import OccupancyGrid
from pfslam.pipeline.sessions import Session, load_session, save_session
from pfslam.sensor import ScanPoints


def _session(rng: np.random.Generator) -> Session:
    grid = OccupancyGrid.from_logodds(rng.normal(size=(30, 40)).astype(np.float32), 0.05, np.array([-1.2, 3.4]))
    k = 4
    pts = [rng.uniform(-20, 20, size=(rng.integers(5, 30), 2)).astype(np.float32) for _ in range(k)]
    nodes = SessionNodes(
        rng.normal(size=(k, 3)),
        pts,
        rng.normal(size=(k, 3, 3)),
        [p[::-1].copy() for p in pts],
        [p[:3].copy() for p in pts],
        rng.normal(size=(k, 2)),
        np.arange(k, dtype=float),
        np.array([0, 0, 1, 1]),
    )
    graph = PoseGraph(nodes.poses.copy())
    graph.add_many(
        np.array([0, 1, 0]), np.array([1, 2, 3]), rng.normal(size=(3, 3)), np.ones((3, 3)), np.array([0, 0, 1], bool)
    )
    return Session(grid, nodes, graph, {"particles": 30}, [{"run": 0, "scans": 10}, {"run": 1, "scans": 5}])


def test_a_session_reads_back_as_it_was_written(tmp_path) -> None:
    s = _session(np.random.default_rng(1))
    save_session(tmp_path / "run" / "session", s)
    back = load_session(tmp_path / "run")  # the run's folder names its session
    assert np.array_equal(back.grid.logodds, s.grid.logodds)
    assert np.allclose(back.grid.origin, s.grid.origin) and back.grid.resolution == s.grid.resolution
    assert np.allclose(back.nodes.poses, s.nodes.poses)
    for a, b in zip(
        back.nodes.points + back.nodes.hits + back.nodes.floor, s.nodes.points + s.nodes.hits + s.nodes.floor
    ):
        assert a.shape == b.shape and np.abs(a - b).max() <= 0.0005  # millimetres
    assert np.array_equal(back.nodes.run, s.nodes.run) and back.next_run == 2
    assert np.array_equal(back.graph.i, s.graph.i) and np.array_equal(back.graph.loop, s.graph.loop)
    assert np.allclose(back.graph.info, s.graph.info) and np.allclose(back.graph.z, s.graph.z)
    assert back.settings == {"particles": 30} and back.runs == s.runs


def test_a_session_from_a_newer_pfslam_or_broken_or_missing_is_refused_by_name(tmp_path) -> None:
    folder = save_session(tmp_path / "s", _session(np.random.default_rng(2)))
    desc = json.loads((folder / "session.json").read_text())
    (folder / "session.json").write_text(json.dumps({**desc, "version": 99}))
    with pytest.raises(InputError, match="newer pfslam"):
        load_session(folder)
    (folder / "session.json").write_text(json.dumps(desc))
    (folder / "session.npz").write_bytes(b"not a zip")
    with pytest.raises(InputError, match="session.npz: is broken"):
        load_session(folder)
    with pytest.raises(InputError, match="holds no session"):
        load_session(tmp_path)
    with pytest.raises(InputError, match="no such folder"):
        load_session(tmp_path / "nowhere")


def _room_scan(
    pose: np.ndarray, walls: list[tuple[float, float, float, float]], rng: np.random.Generator
) -> ScanPoints:
    """A 360-degree scan from ``pose`` of the wall segments (robot frame hits)."""
    angles = np.linspace(-np.pi, np.pi, 720, endpoint=False)
    hits = []
    for a in angles:
        d = np.array([np.cos(pose[2] + a), np.sin(pose[2] + a)])
        best = np.inf
        for x0, y0, x1, y1 in walls:
            e = np.array([x1 - x0, y1 - y0])
            m = np.array([[d[0], -e[0]], [d[1], -e[1]]])
            if abs(np.linalg.det(m)) < 1e-9:
                continue
            t, u = np.linalg.solve(m, np.array([x0 - pose[0], y0 - pose[1]]))
            if t > 0.1 and 0 <= u <= 1:
                best = min(best, t)
        if np.isfinite(best):
            r = best + rng.normal(0, 0.01)
            hits.append(relative(pose, np.array([pose[0] + r * d[0], pose[1] + r * d[1], 0.0]))[:2])
    return ScanPoints(np.array(hits), np.zeros((0, 2)), np.zeros(2))


def _map_of(walls, res: float = 0.05) -> OccupancyGrid:
    grid = OccupancyGrid.from_logodds(np.zeros((300, 400), np.float32), res, np.array([-2.5, -2.5]))
    for x0, y0, x1, y1 in walls:
        n = int(np.hypot(x1 - x0, y1 - y0) / (res / 2)) + 1
        xy = np.column_stack([np.linspace(x0, x1, n), np.linspace(y0, y1, n)])
        r, c = grid.world_to_cell(xy)
        grid.logodds[r, c] = 3.0
    return grid


# An L-shaped building with a side room: no two places look alike.
BUILDING = [(0, 0, 12, 0), (12, 0, 12, 4), (12, 4, 5, 4), (5, 4, 5, 9), (5, 9, 0, 9), (0, 9, 0, 0), (2, 5, 3.5, 5)]
# A long corridor of identical pillars every 2 m: every place has twins.
PILLARS = [(0, 0, 16, 0), (0, 3, 16, 3)] + [(x, 1.3, x + 0.3, 1.3) for x in range(2, 15, 2)]


def test_the_start_is_found_anywhere_in_the_map_at_any_heading() -> None:
    rng = np.random.default_rng(3)
    cfg = BackendSettings.of(SlamConfig())
    field = map_field(_map_of(BUILDING), cfg)
    for truth in (np.array([9.0, 2.0, 2.5]), np.array([2.5, 7.0, -1.2]), np.array([1.0, 2.0, 0.3])):
        sp = _room_scan(truth, BUILDING, rng)
        found = find_start(field, start_points(sp, cfg.map.resolution), cfg)
        assert found.found, found.why_not()
        assert found.pose is not None
        d = relative(truth, found.pose)
        assert np.hypot(d[0], d[1]) < 0.05 and abs(d[2]) < np.deg2rad(1.0), (truth, found.pose)


def test_a_start_among_twins_is_refused_not_guessed() -> None:
    rng = np.random.default_rng(4)
    cfg = BackendSettings.of(SlamConfig())
    field = map_field(_map_of(PILLARS), cfg)
    found = find_start(field, start_points(_room_scan(np.array([7.15, 2.2, 0.0]), PILLARS, rng), 0.05), cfg)
    assert not found.found and found.ambiguous, found.as_dict()
    assert found.next_distance_m is not None and found.next_distance_m >= 0.5
    assert "two places alike" in found.why_not()
