"""Both filters satisfy the Filter protocol, and the pipeline's one run loop drives either."""

import numpy as np
import pytest

from pfslam.config import LocalizerConfig, SlamConfig
from pfslam.filters import Filter, Localizer, SingleMapSlam
from pfslam.maps.grid import OccupancyGrid
from pfslam.pipeline import run_filter


@pytest.fixture(scope="module")
def short(short_office):
    from pfslam.io.logs import load_log

    frames = load_log(short_office.lidar_path, short_office.joint_path).frames
    grid = OccupancyGrid.load_ros(short_office.lidar_path.parent / "map.yaml")
    return frames, grid, short_office.truth


def _localizer(grid, truth):
    loc = Localizer(grid, LocalizerConfig(seed=1, particles=300, min_particles=300))
    loc.initialize_around(truth[0], np.array([0.05, 0.05, 0.02]))
    return loc


def test_both_filters_are_filters(short):
    _, grid, truth = short
    assert isinstance(SingleMapSlam(SlamConfig(particles=5)), Filter)
    assert isinstance(_localizer(grid, truth), Filter)


def test_an_object_without_the_interface_is_not_a_filter():
    class StepOnly:
        def step(self, frame):
            return None

    assert not isinstance(StepOnly(), Filter)
    assert not isinstance(object(), Filter)


@pytest.mark.parametrize("kind", ["slam", "localization"])
def test_run_filter_drives_either_filter(short, kind):
    frames, grid, truth = short
    # The log starts with about 5 s standing still: take 3 s of walking.
    k = int(np.nonzero(np.hypot(*(truth[:, :2] - truth[0, :2]).T) > 0.02)[0][0])
    frames, truth = frames[k : k + 120], truth[k : k + 120]
    filt = SingleMapSlam(SlamConfig(particles=20)) if kind == "slam" else _localizer(grid, truth)
    seen = []
    steps, clouds, _, interrupted, error = run_filter(filt, frames, lambda i, n: seen.append((i, n)), snapshots=3)
    assert not interrupted and error is None
    assert steps.done == len(frames) and seen[-1] == (len(frames), len(frames))
    np.testing.assert_array_equal(steps.odometry[-1], filt.odom_pose)
    t, poses = filt.trajectory()
    np.testing.assert_array_equal(t, [f.t for f in frames])
    assert poses.shape == (len(frames), 3) and np.all(np.isfinite(poses))
    assert filt.map is (grid if kind == "localization" else filt.grid)
    if kind == "slam":
        assert np.all(steps.particles == 20) and np.all(np.isnan(steps.spread))  # SLAM gives no covariance
        assert steps.updates > 0 and filt.scans == len(frames)
        assert len(clouds) == 2  # no particles before the first step
    else:
        assert np.all(steps.particles >= 300) and np.all(np.isfinite(steps.spread)) and steps.updates > 0
        assert len(clouds) == 3 and [c[0] for c in clouds] == [frames[0].t, frames[60].t, frames[-1].t]
        # It tracks: the estimate stays near the truth over these 3 s.
        assert np.max(np.hypot(*(poses[:, :2] - truth[:, :2]).T)) < 0.2
