"""The localizer's AMCL-style settings as a filter sees them: the laser's range window, the
models' range, and the update thresholds in radians read from a config file."""

import math

import numpy as np
import pytest
from locworld import room, scan

from pfslam.config import LocalizerConfig, load_config
from pfslam.filters.localize import Localizer
from pfslam.filters.sensor_model import MODEL_RANGE, laser_window
from pfslam.frames import Frame
from pfslam.sensor import scan_to_points


def _turning_in_place(g, n=30, step=0.1):
    """The robot turns on the spot at (6, 6) by ``step`` rad a frame; its odometry agrees."""
    return [scan(g, [6.0, 6.0, k * step], 0.1 * k, [0.0, 0.0, k * step]) for k in range(n)]


def test_laser_window_narrows_the_sensors_window_only():
    f = Frame(t=0.0, ranges=np.array([0.05, 0.3, 1.0, 5.0, 12.0]), angles=np.zeros(5), min_range=0.1, max_range=10.0)
    assert laser_window(f, LocalizerConfig()) is f  # unset (-1): the sensor's own
    narrow = laser_window(f, LocalizerConfig(laser_min_range=0.5, laser_max_range=6.0))
    assert (narrow.min_range, narrow.max_range) == (0.5, 6.0)
    assert len(scan_to_points(narrow, ground_z=-1.0).hits) == 2  # 1.0 and 5.0
    assert len(scan_to_points(f, ground_z=-1.0).hits) == 3  # 0.3, 1.0 and 5.0
    wide = laser_window(f, LocalizerConfig(laser_min_range=0.0, laser_max_range=50.0))
    assert (wide.min_range, wide.max_range) == (0.1, 10.0)  # never wider than the sensor's
    only_max = laser_window(f, LocalizerConfig(laser_max_range=4.0))
    assert (only_max.min_range, only_max.max_range) == (0.1, 4.0)


def test_readings_beyond_laser_max_range_are_not_weighed():
    g = room()
    frames = _turning_in_place(g, n=3)
    near = float(np.nanmin(frames[0].ranges))
    assert near > 1.0  # every wall is farther than 1 m from (6, 6)
    for limit, weighed in ((-1.0, True), (1.0, False)):
        loc = Localizer(g, LocalizerConfig(seed=0, laser_max_range=limit))
        loc.initialize_around([6.0, 6.0, 0.0], [0.1, 0.1, 0.05])
        assert loc.step(frames[0]).updated is weighed


def test_laser_max_range_sets_the_likelihood_fields_random_floor():
    g = room()
    cfg = LocalizerConfig()
    far = Localizer(g, cfg).field.floor
    near = Localizer(g, LocalizerConfig(laser_max_range=5.0)).field.floor
    # Far from walls the field is z_rand / range (the Gaussian is ~e^-50 there).
    assert far == pytest.approx(math.log(cfg.z_rand / MODEL_RANGE), abs=1e-6)
    assert near == pytest.approx(math.log(cfg.z_rand / 5.0), abs=1e-6)


@pytest.mark.parametrize(
    "text, every",
    [
        ("localize:\n  update_min_d: 5.0\n  update_min_a: 0.25\n", 3),  # radians: every third 0.1 rad turn
        ("update_min_d: 5.0\nupdate_min_a: 0.05\n", 1),  # a flat file, radians too
        ("localize:\n  update_min_d: 5.0\n  update_min_a_deg: 25.0\n", 5),  # an older file: degrees, converted
    ],
)
def test_update_min_a_from_a_file_is_radians(tmp_path, text, every):
    f = tmp_path / "loc.yaml"
    f.write_text(text)
    cfg = load_config(f, LocalizerConfig)
    g = room()
    loc = Localizer(g, cfg)
    loc.initialize_around([6.0, 6.0, 0.0], [0.02, 0.02, 0.01])
    updated = [loc.step(fr).updated for fr in _turning_in_place(g, n=31)]
    # The first frame is weighed, then every ``every``-th 0.1 rad turn (sums of 0.1 may fall
    # a hair short of k * 0.1: allow one frame later).
    gaps = np.diff(np.nonzero(updated)[0])
    assert updated[0] and set(gaps.tolist()) <= {every, every + 1}, gaps
    assert 30 // (every + 1) <= sum(updated) - 1 <= 30 // every
