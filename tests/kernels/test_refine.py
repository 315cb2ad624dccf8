"""The match refined on the smooth score (kernels/refine.py) and the improved proposal's
fusion (filters/proposal.py): what a scan pins is what the walls pin."""

from __future__ import annotations

import numpy as np
import pytest

from pfslam.filters.proposal import normaliser
from pfslam.geometry import transform_points
from pfslam.maps.tiled import TiledMaps
from tests.support.wallpoints import walls

# Walls on cell centres (the grid's origin is -20 m, cells 0.05 m: x = 0.025 + 0.05 k).
ROOM = [
    (-2.975, -1.975, 3.025, -1.975),
    (3.025, -1.975, 3.025, 2.025),
    (3.025, 2.025, -2.975, 2.025),
    (-2.975, 2.025, -2.975, -1.975),
]
CORRIDOR = [(-14.975, -1.025, 15.025, -1.025), (-14.975, 1.025, 15.025, 1.025)]
TRUTH = np.array([0.3, 0.1, 0.05])


def _mapped(segments, n=3):
    """``n`` identical maps of the walls, each written from the truth five times over."""
    maps = TiledMaps(n, origin=(-20.0, -20.0))
    pts = transform_points(np.array([0.0, 0.0, -TRUTH[2]]), walls(segments) - TRUTH[:2])  # robot frame
    for _ in range(5):
        maps.update_all(np.tile(TRUTH, (n, 1)), np.zeros(2), pts, np.ones(len(pts), dtype=bool))
    pts = pts[np.hypot(pts[:, 0], pts[:, 1]) < 12.0]  # the scan's reach: no wall's end in it
    return maps, pts[:: max(1, len(pts) // 300)]


def _refine(maps, pts, starts, iterations=10):
    poses = np.array(starts, dtype=float)
    scores, info = maps.refine(poses, pts, 0.05, iterations, poses.copy(), 0.0, 1.0, 1.0, 0.05, np.deg2rad(3.0))
    return poses, scores, info


def test_in_a_room_the_refinement_finds_the_pose_to_a_fraction_of_a_cell():
    maps, pts = _mapped(ROOM)
    starts = TRUTH + np.array([[0.02, -0.015, 0.01], [-0.025, 0.02, -0.015], [0.0, 0.03, 0.0]])
    poses, scores, info = _refine(maps, pts, starts)
    err = poses - TRUTH
    assert np.abs(err[:, :2]).max() < 0.005  # m: a tenth of a cell
    assert np.degrees(np.abs(err[:, 2]).max()) < 0.1
    assert np.all(scores > 0.9 * len(pts))  # nearly every hit on its wall
    assert np.all(np.linalg.eigvalsh(info[:, :2, :2])[:, 0] > 0.2 * len(pts))  # both directions pinned


def test_along_a_bare_corridor_it_pins_across_and_says_it_does_not_pin_along():
    """The corridor runs along x: an offset along it is left where it is (the score is flat
    there, not a field of bumps at cell centres), one across it is corrected, and the
    information says so: along x next to nothing, across y one per hit."""
    maps, pts = _mapped(CORRIDOR)
    starts = TRUTH + np.array([[0.04, 0.02, 0.0], [-0.03, -0.025, 0.0], [0.012, 0.0, 0.0]])
    poses, _, info = _refine(maps, pts, starts)
    err = poses - TRUTH
    assert np.abs(err[:, 0] - (starts[:, 0] - TRUTH[0])).max() < 0.002  # along: not moved
    assert np.abs(err[:, 1]).max() < 0.004  # across: found
    assert np.all(info[:, 0, 0] < 0.01 * info[:, 1, 1])
    assert np.all(info[:, 1, 1] > 0.5 * len(pts))


def test_the_weight_is_the_odometrys_where_the_match_says_nothing_and_falls_with_a_pinned_slide():
    m = np.array([[1.0, 2.0, 0.1]] * 3)
    p = np.array([[1.05, 1.9, 0.12]] * 3)
    info = np.zeros((3, 3, 3))
    info[1] = np.diag([0.0, 1e4, 0.0])  # pins y, which the match moved 0.1 m from the odometry
    info[2] = np.diag([1e4, 0.0, 0.0])  # pins x, moved 0.05 m
    log_eta = normaliser(m, p, info, (0.02, 0.01))
    assert abs(log_eta[0]) < 1e-6  # no information: the integral of the odometry's Gaussian, 1
    assert log_eta[1] < log_eta[2] < log_eta[0] - 1.0


@pytest.mark.parametrize("seed", [0, 1])
def test_the_weight_is_the_integral_of_the_match_under_the_odometry(seed):
    """log η against a Monte Carlo mean of exp(-½ (x - m)ᵀ A (x - m)) over x drawn from the
    odometry's Gaussian."""
    rng = np.random.default_rng(seed)
    r = rng.normal(size=(3, 3))
    scale = np.diag([20.0, 20.0, 45.0])
    a = scale @ r @ r.T @ scale + np.diag([50.0, 10.0, 100.0])  # an information matrix
    m = np.array([[0.0, 0.0, 0.0]])
    p = np.array([[0.02, -0.03, 0.01]])
    sxy, sth = 0.04, 0.03
    log_eta = normaliser(m, p, a[None], (sxy, sth))
    x = p + rng.normal(size=(400_000, 3)) * np.array([sxy, sxy, sth])
    d = x - m
    mc = np.mean(np.exp(-0.5 * np.einsum("ni,ij,nj->n", d, a, d)))
    assert log_eta[0] == pytest.approx(np.log(mc), abs=0.01)
