"""ParticleSet (normalisation, N_eff, estimates) and the resampling schemes."""

import numpy as np
import pytest

from pfslam.particles import DRAWERS, ParticleSet, systematic_draw


def test_normalize_survives_huge_log_weights():
    ps = ParticleSet(np.zeros((3, 3)), np.array([1e6, 1e6 - 1.0, -1e6]))
    ps.normalize()
    w = ps.weights
    assert np.all(np.isfinite(w)) and abs(w.sum() - 1) < 1e-12
    assert w[0] == pytest.approx(1 / (1 + np.exp(-1)), rel=1e-9)


def test_n_eff_bounds():
    ps = ParticleSet(np.zeros((10, 3)))
    assert ps.n_eff() == pytest.approx(10)
    ps.log_weights = np.array([0.0] + [-np.inf] * 9)
    assert ps.n_eff() == pytest.approx(1)


@pytest.mark.parametrize("method", sorted(DRAWERS))
def test_resampling_is_unbiased(method):
    rng = np.random.default_rng(1)
    w = np.array([0.5, 0.3, 0.15, 0.05])
    counts = np.zeros(4)
    for _ in range(400):
        counts += np.bincount(DRAWERS[method](w, len(w), rng), minlength=4)
    assert np.allclose(counts / counts.sum(), w, atol=0.02)


def test_systematic_keeps_deterministic_share():
    rng = np.random.default_rng(2)
    w = np.array([0.5, 0.25, 0.25])
    for _ in range(50):
        idx = DRAWERS["systematic"](np.tile(w, 4) / 4, 12, rng)
        # 12 particles, weight 0.5/4 each of first kind -> exactly 1.5 copies, so 1 or 2
        c = np.bincount(idx, minlength=12)
        assert np.all(c[::3] >= 1) and np.all(c[::3] <= 2)


def test_weighted_mean_uses_circular_theta():
    poses = np.array([[0, 0, np.deg2rad(-179)], [2, 0, np.deg2rad(179)]], float)
    m = ParticleSet(poses).mean()
    assert m[0] == pytest.approx(1.0)
    assert abs(abs(m[2]) - np.pi) < 1e-9


def test_around_is_seeded():
    a = ParticleSet.around(np.zeros(3), 5, np.ones(3), np.random.default_rng(3)).poses
    b = ParticleSet.around(np.zeros(3), 5, np.ones(3), np.random.default_rng(3)).poses
    assert np.array_equal(a, b)


def test_log_sum_exp_matches_scipy_and_survives_extremes():
    from scipy.special import logsumexp

    from pfslam.particles import log_sum_exp

    rng = np.random.default_rng(4)
    for scale in (1.0, 1e3, 1e6):
        lw = rng.normal(0, scale, 200)
        lw[rng.random(200) < 0.2] = -np.inf
        assert np.isclose(log_sum_exp(lw), logsumexp(lw), rtol=1e-12, atol=1e-9)
    assert log_sum_exp(np.array([1000.0, 1000.0])) == pytest.approx(1000.0 + np.log(2.0))  # no overflow
    assert log_sum_exp(np.full(5, -np.inf)) == -np.inf
    ps = ParticleSet(np.zeros((3, 3)), np.array([-np.inf, 2000.0, np.nan]))
    ps.normalize()
    assert np.allclose(ps.weights, [0.0, 1.0, 0.0])


def test_systematic_draw_follows_the_weights():
    w = np.array([0.1, 0.0, 0.6, 0.3])
    idx = systematic_draw(w, 1000, np.random.default_rng(1))
    np.testing.assert_allclose(np.bincount(idx, minlength=4) / 1000, w, atol=0.002)
    assert DRAWERS["systematic"] is systematic_draw


def test_circular_mean_of_minus_179_and_179_is_180():
    ps = ParticleSet(np.array([[0, 0, np.deg2rad(-179)], [0, 0, np.deg2rad(179)]]))
    assert abs(abs(np.rad2deg(ps.mean()[2])) - 180) < 1e-9


@pytest.mark.parametrize("method", sorted(DRAWERS))
def test_every_resampling_scheme_draws_n_indices_by_weight(method):
    w = np.array([0.1, 0.0, 0.6, 0.3])
    idx = DRAWERS[method](w, 20000, np.random.default_rng(2))
    assert len(idx) == 20000 and np.all(np.bincount(idx, minlength=4)[1] == 0)
    np.testing.assert_allclose(np.bincount(idx, minlength=4) / 20000, w, atol=0.01)
