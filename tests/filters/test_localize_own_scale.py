"""Issue 37: each particle carries its own factor on the odometry's translation scale, so a
global start does not wait for the cloud to settle before the scale counts."""

from dataclasses import replace

import numpy as np
import pytest
from locworld import drive, room, scan

from pfslam.config import LocalizerConfig
from pfslam.filters.localize import Localizer
from pfslam.geometry import compose, relative
from pfslam.particles import ParticleSet
from pfslam.pipeline.run import settle_summary, spread_rose


def _frames(scale: float):
    """A 28 m loop of the test room whose odometry reports ``scale`` x the distance walked."""
    g = room()
    truth = drive([[1.0, 1.0], [9.0, 1.0], [9.0, 7.0], [1.0, 7.0], [1.0, 1.2]], step=0.15, turn=np.radians(15))
    inc = relative(truth[:-1], truth[1:])
    inc[:, :2] *= scale
    odom = [np.zeros(3)]
    for u in inc:
        odom.append(compose(odom[-1], u))
    return g, truth, [scan(g, p, 0.1 * k, o) for k, (p, o) in enumerate(zip(truth, odom))]


@pytest.mark.parametrize("scale", [0.9, 1.1])
def test_global_start_learns_a_scale_at_either_end_of_the_range(scale):
    """A global start behind odometry 10 % short or long: found, tracked to the end within
    5 cm, and the scale learnt within 0.03 of the truth; run.json's figures say so."""
    g, truth, frames = _frames(scale)
    cfg = LocalizerConfig(seed=2, odom_scale_window=5.0, beams=40, global_density=200.0)
    loc = Localizer(g, cfg)
    loc.initialize_global()
    est = np.array([loc.step(f).pose for f in frames])
    err = np.hypot(*(est[:, :2] - truth[:, :2]).T)
    assert err[len(err) // 4 :].max() <= 0.1, err.max()
    assert err[-1] <= 0.05
    info = loc.diagnostics()["odometry_scale"]
    assert abs(info["translation"] - scale) <= 0.03, info
    assert 0.0 <= info["translation_std"] < 0.05


def test_factors_are_drawn_within_the_spread_and_resampled_with_their_particles():
    cfg = LocalizerConfig(
        seed=1, kld=False, recovery=False, odom_scale_spread=0.1, global_particles=400, global_start="uniform"
    )
    loc = Localizer(room(), replace(cfg, global_density=1.0))
    loc.initialize_global()
    f = loc.scales
    assert len(f) == loc.n and f.min() >= 0.9 and f.max() <= 1.1 and f.std() > 0.04
    # All the weight on one particle: after resampling every particle carries its factor.
    logw = np.full(loc.n, -np.inf)
    logw[7] = 0.0
    loc.particles = ParticleSet(loc.particles.poses, logw)
    assert loc.resample()
    np.testing.assert_array_equal(loc.scales, np.full(loc.n, f[7]))
    # Particles set from outside with another count get factors of their own.
    loc.particles = ParticleSet(np.tile([2.0, 6.5, 0.0], (30, 1)))
    assert len(loc.scales) == 30
    # From a known start, or without per-particle factors, one scale is used and reported.
    for known, spread in ((True, 0.1), (False, 0.0)):
        one = Localizer(room(), replace(cfg, odom_scale_spread=spread))
        if known:
            one.initialize_around([2.0, 6.5, 0.0], [0.05, 0.05, 0.02])
        else:
            one.initialize_global()
        assert np.all(one.scales == 1.0)
        assert "translation_std" not in one.diagnostics()["odometry_scale"]


def test_settle_time_counts_from_the_first_motion_and_the_last_unsettled_step():
    t = np.arange(10.0)
    odom = np.zeros((10, 3))
    odom[3:, 0] = np.arange(1, 8) * 0.1  # moves from t = 3
    spread = np.array([0.4, 0.4, 0.1, 0.4, 0.3, 0.2, 0.1, 0.1, 0.1, 0.1])
    assert settle_summary(t, spread, odom) == {"seconds": 2.0, "at_s": 5.0}
    assert settle_summary(t, np.full(10, 0.1), odom) == {"seconds": 0.0, "at_s": 0.0}  # settled before it moved
    assert settle_summary(t, np.full(10, 0.4), odom) == {"seconds": None, "at_s": None}
    assert settle_summary(t, spread, np.zeros((10, 3)))["seconds"] == 5.0  # never moved: from the first scan


def test_spread_rose_is_twice_the_settled_median():
    spread = np.array([0.5, 0.05, 0.05, 0.06, 0.13, 0.05, np.nan])
    thr, rose = spread_rose(spread)
    assert thr == pytest.approx(0.1)
    np.testing.assert_array_equal(rose, [True, False, False, False, True, False, False])
    assert spread_rose(np.full(3, 0.4))[0] is None
