"""What a scan pins of its pose, and the edges made from it: a corridor pins across, not
along; a room pins every way; the loops and sequential edges are loose where it pins nothing."""

from __future__ import annotations

import numpy as np
import pytest

from pfslam.backend.edges import loop_information, normals, scan_information, sequential_information
from pfslam.backend.graph import PoseGraph, solve
from pfslam.config import GraphConfig, RobustLoss


def corridor(half: float = 1.2, length: float = 12.0, step: float = 0.1) -> np.ndarray:
    """Hits on two parallel walls along x, the robot half way between them."""
    x = np.arange(-length / 2, length / 2, step)
    return np.vstack([np.column_stack([x, np.full_like(x, half)]), np.column_stack([x, np.full_like(x, -half)])])


def room(side: float = 5.0, step: float = 0.1) -> np.ndarray:
    s = np.arange(-side / 2, side / 2, step)
    h = np.full_like(s, side / 2)
    return np.vstack(
        [np.column_stack([s, h]), np.column_stack([s, -h]), np.column_stack([h, s]), np.column_stack([-h, s])]
    )


def stds(info: np.ndarray) -> np.ndarray:
    return np.sqrt(np.diag(np.linalg.inv(info)))


def test_normals_of_a_wall_face_across_it_and_corners_are_not_walls() -> None:
    pts = corridor()
    n, ok = normals(pts)
    assert ok.mean() > 0.95
    assert np.abs(n[ok, 1]) == pytest.approx(1.0, abs=1e-6)  # walls along x: normals along y
    scattered = np.random.default_rng(0).uniform(-0.2, 0.2, (30, 2))
    assert normals(scattered)[1].mean() < 0.3


def test_a_corridor_pins_the_pose_across_and_not_along() -> None:
    h = scan_information(corridor(), 0.05, 20)
    assert h[1, 1] > 1000 * max(h[0, 0], 1e-9)  # across (y) against along (x)
    assert h[0, 0] == pytest.approx(0.0, abs=1e-6)
    assert h[2, 2] > 0  # the walls' far ends turn with the robot
    r = scan_information(room(), 0.05, 20)
    ev = np.linalg.eigvalsh(r[:2, :2])
    assert ev.min() > 0.3 * ev.max()  # a room pins both ways
    # the effective count caps what many hits of one wall say
    assert scan_information(corridor(step=0.05), 0.05, 20)[1, 1] == pytest.approx(h[1, 1], rel=0.05)


def test_sequential_edges_are_loose_along_a_corridor_only() -> None:
    c = GraphConfig()
    step = np.array([[0.25, 0.0, 0.0]])
    base = c.node_sigma_m + c.node_sigma_per_m * 0.25
    cor = stds(sequential_information(scan_information(corridor(), c.scan_sigma_m, c.scan_points)[None], step, c)[0])
    assert cor[1] == pytest.approx(base, rel=0.25)  # across: about the settings' figure
    assert cor[0] > 0.9 * c.loose_along * base  # along: up to loose_along times looser
    rm = stds(sequential_information(scan_information(room(), c.scan_sigma_m, c.scan_points)[None], step, c)[0])
    assert rm[:2] == pytest.approx([base, base], rel=0.25)
    assert rm[0] < 0.5 * cor[0]  # a room pins along too
    # never surer than the settings, whatever the scan
    assert (cor[:2] >= base * 0.999).all() and (rm[:2] >= base * 0.999).all()


def test_a_loop_in_a_corridor_does_not_pull_along_it() -> None:
    """Two nodes 10 m apart along a corridor, the front end's path straight; a loop edge from
    the first to the second that says it is 1 m further along and 0.2 m across: solved, the path
    moves across (the loop's scan pins that) and hardly along."""
    c = GraphConfig()
    n = 41
    poses = np.column_stack([np.arange(n) * 0.25, np.zeros(n), np.zeros(n)])
    g = PoseGraph(poses.copy())
    z = np.tile([0.25, 0.0, 0.0], (n - 1, 1))
    scan = np.tile(scan_information(corridor(), c.scan_sigma_m, c.scan_points), (n - 1, 1, 1))
    k = np.arange(n - 1)
    g.add_many(k, k + 1, z, None, np.zeros(n - 1, bool), info=sequential_information(scan, z, c))
    loop = loop_information(scan_information(corridor(), c.scan_sigma_m, c.scan_points)[None], c)
    g.add_many(np.array([0]), np.array([n - 1]), np.array([[11.0, 0.2, 0.0]]), None, np.array([True]), info=loop)
    out, keep = solve(g, RobustLoss.CAUCHY, 3.0)
    assert keep.all()
    assert abs(out[-1, 0] - poses[-1, 0]) < 0.05  # along: the loop says little
    assert out[-1, 1] > 0.1  # across: it pulls
