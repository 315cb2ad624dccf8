"""The run loop's observer: called after each step with the step's index, frame, filter and
estimate; an error it raises stops the run like the filter's own."""

import numpy as np
import pytest

from pfslam.config import LocalizerConfig, SlamConfig
from pfslam.frames import Frame
from pfslam.maps.grid import OccupancyGrid
from pfslam.pipeline import run_localization, run_slam


def _frames(n: int) -> list[Frame]:
    """A robot driving along +x in a 2 m wide corridor, 40 Hz, one wall hit each side per scan."""
    angles = np.array([np.pi / 2, -np.pi / 2, 0.0])
    return [
        Frame(
            t=0.025 * i, ranges=np.array([1.0, 1.0, 8.0 - 0.02 * i]), angles=angles, odom=np.array([0.02 * i, 0.0, 0.0])
        )
        for i in range(n)
    ]


def _corridor_map() -> OccupancyGrid:
    g = OccupancyGrid(0.05, origin=(-2.0, -2.0), shape=(80, 240))
    g.logodds[:] = -5.0
    g.logodds[[19, 60], :] = 50.0  # walls at y = -1.025 and 1.025
    g.logodds[:, 200:] = 50.0  # the corridor's end at x = 8
    return g


class Recorder:
    def __init__(self):
        self.calls = []

    def __call__(self, i, frame, filt, est):
        self.calls.append((i, frame.t, filt, est.t, est.pose.copy(), filt.odom_pose.copy()))


@pytest.mark.parametrize("every", [1, 3])
def test_slam_observer_is_called_once_per_step_with_its_index(every):
    frames = _frames(20)
    seen = Recorder()
    run = run_slam(frames, SlamConfig(filter="single", particles=10, every=every), observer=seen)
    stepped = frames[::every]
    assert [c[0] for c in seen.calls] == list(range(len(stepped)))  # the index counts the steps taken
    assert [c[1] for c in seen.calls] == [f.t for f in stepped] == [c[3] for c in seen.calls]
    assert len({id(c[2]) for c in seen.calls}) == 1  # one filter, the one that ran
    np.testing.assert_array_equal([c[4] for c in seen.calls], run.poses)  # the estimate of that very step
    np.testing.assert_array_equal([c[5] for c in seen.calls], run.odometry)


def test_localization_observer_sees_the_localizer():
    from pfslam.filters.localize import Localizer

    seen = Recorder()
    run = run_localization(
        _frames(12),
        _corridor_map(),
        LocalizerConfig(particles=200, kld=False),
        (np.zeros(3), np.array([0.05, 0.05, 0.02])),
        observer=seen,
    )
    assert [c[0] for c in seen.calls] == list(range(12)) and run.scans == 12
    assert isinstance(seen.calls[0][2], Localizer)
    np.testing.assert_array_equal([c[4] for c in seen.calls], run.poses)


def test_an_observer_error_stops_the_run_and_keeps_the_steps_before_it():
    def fail_at_5(i, frame, filt, est):
        if i == 5:
            raise OSError("No space left on device")

    frames = _frames(20)
    run = run_slam(frames, SlamConfig(filter="single", particles=10), observer=fail_at_5)
    assert run.scans == 6  # the sixth step was done; its observer failed
    assert run.error == f"stopped at scan 6 (t={frames[5].t:.3f}): No space left on device"


def test_no_observer_runs_as_before():
    frames = _frames(15)
    a = run_slam(frames, SlamConfig(filter="single", particles=10, seed=4))
    b = run_slam(frames, SlamConfig(filter="single", particles=10, seed=4), observer=lambda *args: None)
    np.testing.assert_array_equal(a.poses, b.poses)  # watching changes nothing
    np.testing.assert_array_equal(a.grid.logodds, b.grid.logodds)
