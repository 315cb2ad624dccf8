"""Scans as points in the robot frame: range window, ground removal, subsampling."""

import numpy as np

from pfslam.frames import Frame
from pfslam.geometry import ry, txyz
from pfslam.sensor import open_beams, scan_to_points, subsample


def test_scan_to_points_filters_and_removes_ground():
    angles = np.deg2rad([-30.0, 0.0, 30.0, 60.0])
    ranges = np.array([2.0, np.nan, 0.05, 40.0])
    f = Frame(t=0.0, ranges=ranges, angles=angles, mount=txyz(0, 0, 1.0))
    sp = scan_to_points(f)
    assert sp.hits.shape == (1, 2)
    assert np.allclose(sp.hits[0], [2 * np.cos(-np.pi / 6), 2 * np.sin(-np.pi / 6)])
    # Lidar 1 m up pitched down 45 deg: a 1.414 m beam reaches the floor 1 m ahead.
    f2 = Frame(t=0.0, ranges=np.array([np.sqrt(2), 0.5]), angles=np.zeros(2), mount=txyz(0, 0, 1.0) @ ry(np.pi / 4))
    sp2 = scan_to_points(f2)
    assert sp2.floor.shape == (1, 2) and np.allclose(sp2.floor[0], [1, 0])
    assert sp2.hits.shape == (1, 2)


def test_subsample_keeps_at_most_k_points_evenly_spread_with_both_ends():
    pts = np.column_stack([np.arange(10.0), np.zeros(10)])
    out = subsample(pts, 4)
    np.testing.assert_array_equal(out[:, 0], [0.0, 3.0, 6.0, 9.0])
    assert out.flags.c_contiguous
    assert subsample(pts, 10) is pts and subsample(pts, 50) is pts
    assert subsample(pts, 0) is pts  # k <= 0: no limit


def test_beams_that_returned_nothing_clear_space_up_to_the_reach_and_only_on_a_level_laser():
    a = np.deg2rad([-90.0, 0.0, 45.0, 90.0, 135.0])
    r = np.array([np.inf, 30.0, np.nan, 2.0, 0.0])  # nothing; at max range; no reading; a hit; too near
    mount = txyz(0.2, 0.0, 0.3)
    f = Frame(t=0.0, ranges=r, angles=a, mount=mount, min_range=0.05, max_range=30.0)
    pts = open_beams(f, 5.0)
    np.testing.assert_allclose(pts, [[0.2, -5.0], [5.2, 0.0]], atol=1e-12)
    assert open_beams(f, 0.0).shape == (0, 2)
    tilted = Frame(t=0.0, ranges=r, angles=a, mount=mount @ ry(np.deg2rad(20.0)), min_range=0.05, max_range=30.0)
    assert open_beams(tilted, 5.0).shape == (0, 2)  # a beam pitched down that saw nothing says nothing of the plane
