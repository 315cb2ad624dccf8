"""The odometry's errors fitted from matched updates and taken out (pfslam.filters.drift)."""

import numpy as np
import pytest

from pfslam.filters.drift import DriftFit


def _odometry(m: np.ndarray, scale: float, turn: float, bias: float, rng: np.random.Generator) -> np.ndarray:
    """The odometry's increments for the true ones ``m``: distances ``scale`` long, turns
    ``turn`` times, ``bias`` rad of creep a metre, a little noise."""
    d = np.hypot(m[:, 0], m[:, 1])
    u = m.copy()
    u[:, :2] *= scale
    u[:, 2] = turn * m[:, 2] + bias * d + rng.normal(0.0, 0.001, len(m))
    return u


def _walk(n: int, rng: np.random.Generator) -> np.ndarray:
    """True increments of 0.5 m updates, turning now and then."""
    th = np.where(rng.random(n) < 0.1, rng.normal(0.0, 0.5, n), rng.normal(0.0, 0.02, n))
    return np.column_stack([np.full(n, 0.5), rng.normal(0.0, 0.01, n), th])


def test_the_scale_the_turns_and_the_creep_are_found_and_undone():
    rng = np.random.default_rng(0)
    m = _walk(400, rng)  # 200 m
    u = _odometry(m, 1.04, 0.97, np.deg2rad(0.1), rng)
    fit = DriftFit()
    for a, b in zip(u, m):
        fit.add(a, b)
    scale, turn, bias = fit.fitted()
    assert scale == pytest.approx(1.04, abs=0.005)
    assert turn == pytest.approx(0.97, abs=0.01)
    assert np.rad2deg(bias) == pytest.approx(0.1, abs=0.02)
    undone = np.array([fit.undo(a) for a in u])
    # the heading's error summed along the walk (the noise is left, the creep and turns' scale gone)
    raw = abs(float(np.sum(u[:, 2] - m[:, 2])))
    assert abs(float(np.sum(undone[:, 2] - m[:, 2]))) < 0.1 * raw
    np.testing.assert_allclose(undone[:, :2], m[:, :2], rtol=0.01, atol=1e-3)


def test_without_turns_only_the_scale_and_the_creep_are_fitted():
    rng = np.random.default_rng(1)
    m = np.column_stack([np.full(200, 0.5), np.zeros(200), np.zeros(200)])  # 100 m straight
    u = _odometry(m, 0.97, 1.1, np.deg2rad(-0.2), rng)
    fit = DriftFit()
    for a, b in zip(u, m):
        fit.add(a, b)
    scale, turn, bias = fit.fitted()
    assert scale == pytest.approx(0.97, abs=0.005) and turn == 1.0
    assert np.rad2deg(bias) == pytest.approx(-0.2, abs=0.02)


def test_too_little_travel_or_an_implausible_fit_leaves_the_odometry_as_it_is():
    rng = np.random.default_rng(2)
    m = _walk(40, rng)  # 20 m: not enough
    fit = DriftFit()
    for a, b in zip(_odometry(m, 1.05, 1.0, 0.0, rng), m):
        fit.add(a, b)
    assert fit.fitted() == (1.0, 1.0, 0.0)
    u = np.array([0.5, 0.01, 0.1])
    np.testing.assert_array_equal(fit.undo(u), u)
    wild = DriftFit()  # a wheel spinning on ice: the distances read half again too long
    for a, b in zip(_odometry(_walk(200, rng), 1.5, 1.0, 0.0, rng), _walk(200, rng)):
        wild.add(a, b)
    assert wild.fitted()[0] == 1.0
