"""Synthetic drifting odometry from a reference trajectory, and the --odometry option."""

import numpy as np
import pytest
from datafiles import need

from pfslam.geometry import compose, relative
from pfslam.io.carmen import load_carmen
from pfslam.io.synthetic import DriftModel, parse_odometry_option, synthetic_odometry


def straight(length=100.0, n=201, start=(0.0, 0.0, 0.0)):
    local = np.column_stack([np.linspace(0, length, n), np.zeros(n), np.zeros(n)])
    return compose(np.asarray(start, float), local)


def position_rmse(a, b):
    return float(np.sqrt(np.mean(np.sum((a[:, :2] - b[:, :2]) ** 2, axis=1))))


def test_seeded_and_starts_at_the_reference():
    ref = straight(start=(3.0, -1.0, 0.7))
    a, b, c = synthetic_odometry(ref, 3), synthetic_odometry(ref, 3), synthetic_odometry(ref, 4)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    np.testing.assert_array_equal(a[0], ref[0])
    assert a.shape == ref.shape and np.all(np.abs(a[:, 2]) <= np.pi)


def test_noise_free_model_reproduces_the_reference():
    rng = np.random.default_rng(0)
    ref = np.cumsum(rng.normal(0, 0.3, (300, 3)), axis=0)
    zero = DriftModel(0, 0, 0, 0, 0, 0)
    out = synthetic_odometry(ref, 5, zero)
    np.testing.assert_allclose(out[:, :2], ref[:, :2], atol=1e-9)
    np.testing.assert_allclose(relative(out, ref)[:, 2], 0, atol=1e-9)


def test_standing_still_gives_no_drift():
    still = np.tile([[1.0, 2.0, 0.3]], (50, 1))
    for seed in range(5):
        np.testing.assert_array_equal(synthetic_odometry(still, seed), still)
    # Moving, stopping, moving: the pose stays put while the reference does.
    ref = np.vstack([straight(5, 11), np.tile(straight(5, 11)[-1], (20, 1)), straight(5, 11, (5, 0, 0))[1:]])
    out = synthetic_odometry(ref, 1)
    assert np.all(np.diff(out[10:31], axis=0) == 0)


def test_heading_bias_follows_the_model_on_a_straight_line():
    ref = straight(100.0)
    # Only the bias, no spread: the heading after 100 m is exactly +-0.25 deg/m * 100 m.
    bias_only = DriftModel(
        scale_sigma=0,
        heading_bias_deg_per_m=0.25,
        heading_bias_sigma=0,
        trans_noise=0,
        rot_noise_per_m=0,
        rot_noise_per_rad=0,
    )
    ends = [np.rad2deg(synthetic_odometry(ref, s, bias_only)[-1, 2]) for s in range(20)]
    np.testing.assert_allclose(np.abs(ends), 25.0, atol=1e-9)
    assert min(ends) < 0 < max(ends)  # the sign is drawn
    # The default model: E|heading| = 0.25 * 100 deg; the spread (30 % of the bias, plus
    # 0.5 deg/m white noise) averages out over 200 seeds to within a few degrees.
    default = np.array([np.rad2deg(synthetic_odometry(ref, s)[-1, 2]) for s in range(200)])
    assert 22.0 < np.mean(np.abs(default)) < 28.0
    assert 5.0 < np.std(np.abs(default)) < 12.0  # about sqrt(7.5^2 + 3.5^2) = 8.3 deg


def test_scale_error_is_one_draw_per_run():
    ref = straight(100.0)
    scale_only = DriftModel(
        scale_sigma=0.03,
        heading_bias_deg_per_m=0,
        heading_bias_sigma=0,
        trans_noise=0,
        rot_noise_per_m=0,
        rot_noise_per_rad=0,
    )
    s = np.array([synthetic_odometry(ref, k, scale_only)[-1, 0] / 100.0 for k in range(300)])
    assert abs(np.mean(s) - 1.0) < 0.006 and 0.025 < np.std(s) < 0.035
    one = synthetic_odometry(ref, 0, scale_only)
    np.testing.assert_allclose(np.diff(one[:, 0]), np.diff(one[:, 0])[0])  # the same factor all along


def test_bad_reference_shape():
    with pytest.raises(ValueError):
        synthetic_odometry(np.zeros((5, 2)), 0)
    assert synthetic_odometry(np.zeros((0, 3)), 0).shape == (0, 3)
    np.testing.assert_array_equal(synthetic_odometry(np.ones((1, 3)), 0), np.ones((1, 3)))


def test_parse_odometry_option():
    assert parse_odometry_option("synthetic:7") == ("synthetic", 7)
    assert parse_odometry_option("synthetic") == ("synthetic", 0)
    assert parse_odometry_option(" Synthetic:12 ") == ("synthetic", 12)
    assert parse_odometry_option("log") == ("log", 0)
    for bad in ["magic", "", "synthetic:", "synthetic:x", "synthetic:-1", "log:3"]:
        with pytest.raises(ValueError, match="synthetic"):
            parse_odometry_option(bad)


@pytest.mark.realdata
@pytest.mark.parametrize("name, lo", [("intel", 1.0), ("fr079", 1.0)])
def test_default_model_drifts_metres_on_the_real_references(name, lo):
    ref = load_carmen(need(f"carmen/{name}.gfs.log.gz")).reference
    ate = [position_rmse(synthetic_odometry(ref, s), ref) for s in range(5)]
    # Measured (default model, seeds 0..4): Intel 17.6 8.7 18.3 10.8 17.5 m,
    # FR079 15.1 8.9 11.6 13.4 19.8 m.
    assert min(ate) >= lo, ate
    assert max(ate) < 60.0, ate
