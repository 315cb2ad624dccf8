"""Issue 27: the odometry scale learnt while localizing, and the likelihood field read with
sub-cell (bilinear) interpolation."""

import numpy as np
import pytest
from locworld import drive, room, scan

from pfslam.config import ConfigError, LocalizerConfig
from pfslam.filters.localize import Localizer
from pfslam.filters.odometry_scale import OdometryScale
from pfslam.filters.sensor_model import LikelihoodField
from pfslam.geometry import compose, relative
from pfslam.kernels.likelihood import likelihood_kernel, likelihood_numpy


def test_scale_estimate_is_the_ratio_of_reported_to_corrected_motion_and_bounded():
    s = OdometryScale(window=20.0, bound=0.2)
    assert s.translation == s.rotation == 1.0  # the start
    step = np.array([0.05, 0.01, 0.0])
    for _ in range(2000):  # 100 m reported, the estimate moving 4 % less along it
        s.add(step, step / 1.04)
    assert s.translation == pytest.approx(1.04, abs=1e-3)
    assert s.rotation == 1.0  # no turn counted
    turn = np.array([0.0, 0.0, np.radians(3.0)])
    wobble = np.array([0.05, 0.0, np.radians(1.0)])  # a gait's wobble: below min_turn, not counted
    for _ in range(400):
        s.add(turn, turn / 0.97)
        s.add(wobble, wobble * 5.0)
    assert s.rotation == pytest.approx(0.97, abs=2e-3)
    far = OdometryScale(window=5.0, bound=0.2)
    for _ in range(500):
        far.add(step, step / 1.5)
        far.add(-turn, -turn * 2.0)
    assert far.translation == 1.2 and far.rotation == 0.8  # held at 1 -+ bound


def test_scale_settings_are_checked():
    with pytest.raises(ConfigError, match="odom_scale_bound"):
        LocalizerConfig(odom_scale_bound=0.6)
    with pytest.raises(ConfigError, match="odom_scale_window"):
        LocalizerConfig(odom_scale_window=0.0)


def test_localizer_learns_that_the_odometry_reads_4_percent_long():
    """One 28 m loop of the test room with the odometry's distances 4 % long: the scale
    estimate moves from 1 to about 1.04 (the rotation scale stays near 1), and the run
    reports it."""
    g = room()
    truth = drive([[1.0, 1.0], [9.0, 1.0], [9.0, 7.0], [1.0, 7.0], [1.0, 1.2]], step=0.15, turn=np.radians(15))
    inc = relative(truth[:-1], truth[1:])
    inc[:, :2] *= 1.04
    odom = [np.zeros(3)]
    for u in inc:
        odom.append(compose(odom[-1], u))
    frames = [scan(g, p, 0.1 * k, o) for k, (p, o) in enumerate(zip(truth, odom))]
    cfg = LocalizerConfig(seed=3, odom_scale_window=5.0, recovery=False, particles=300, min_particles=300, beams=40)
    loc = Localizer(g, cfg)
    loc.initialize_around(truth[0], np.array([0.05, 0.05, 0.03]))
    est = np.array([loc.step(f).pose for f in frames])
    assert 1.025 <= loc.odom_scale.translation <= 1.06, loc.odom_scale
    assert abs(loc.odom_scale.rotation - 1.0) <= 0.03, loc.odom_scale
    assert np.hypot(*(est[-1, :2] - truth[-1, :2])) <= 0.05
    info = loc.diagnostics()["odometry_scale"]
    assert info["translation"] == pytest.approx(loc.odom_scale.translation, abs=1e-5) and info["motions_counted"] > 100
    off = Localizer(g, LocalizerConfig(seed=3, odom_scale_adapt=False))
    assert "odometry_scale" not in off.diagnostics()


def _field_args(interp: bool, poses: np.ndarray, pts: np.ndarray):
    f = LikelihoodField.from_grid(room(), sigma_hit=0.2, interpolate=interp)
    return (poses, pts, f.logp, float(f.origin[0]), float(f.origin[1]), 1.0 / f.resolution, f.floor, interp)


def test_interpolated_field_is_continuous_across_cells_and_matches_its_twin():
    """A single end point 0.3 m in front of a robot facing the west wall (x = 0), moved
    through 6 cells in 1 mm steps: read per cell the log-likelihood jumps at every cell
    boundary; read bilinearly it changes by no more than its slope times a millimetre."""
    xs = np.arange(0.5, 0.8, 0.001)
    poses = np.column_stack([xs, np.full(len(xs), 4.01), np.full(len(xs), np.pi)])
    pts = np.array([[0.3, 0.0]])
    cell = likelihood_kernel(*_field_args(False, poses, pts))
    smooth = likelihood_kernel(*_field_args(True, poses, pts))
    assert np.abs(np.diff(cell)).max() > 0.1  # steps at the boundaries
    assert np.abs(np.diff(smooth)).max() < 0.02
    assert np.all(np.diff(smooth) < 1e-6)  # ever less likely as the end point leaves the wall
    # At cell centres both readings agree.
    centre = np.array([[0.3 + 0.025 + 0.05 * k, 4.025, np.pi] for k in range(5)])
    np.testing.assert_allclose(
        likelihood_kernel(*_field_args(True, centre, pts)),
        likelihood_kernel(*_field_args(False, centre, pts)),
        atol=1e-5,
    )
    # The NumPy twin, with points on and off the map.
    rng = np.random.default_rng(5)
    p = np.column_stack([rng.uniform(-2.0, 12.0, 300), rng.uniform(-2.0, 10.0, 300), rng.uniform(-np.pi, np.pi, 300)])
    q = rng.uniform(-3.0, 3.0, (40, 2))
    args = _field_args(True, p, q)
    np.testing.assert_allclose(likelihood_kernel(*args), likelihood_numpy(*args), rtol=1e-5, atol=1e-4)
