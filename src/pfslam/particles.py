"""ParticleSet: poses, log-weights, normalisation, resampling, estimates."""

from __future__ import annotations

from typing import Callable

import numpy as np
from numpy.typing import NDArray

from pfslam.geometry import circular_mean, wrap_angle
from pfslam.kernels.resample import systematic_kernel
from pfslam.types import Array


def systematic_draw(w: Array, n: int, rng: np.random.Generator) -> NDArray[np.int64]:
    """``n`` indices by low-variance (systematic) resampling: one uniform draw, ``n`` evenly
    spaced pointers."""
    out = np.empty(int(n), dtype=np.int64)
    systematic_kernel(np.ascontiguousarray(w, dtype=float), float(rng.random()), out)
    return out


def stratified_draw(w: Array, n: int, rng: np.random.Generator) -> NDArray[np.intp]:
    """``n`` indices, one uniform pointer inside each of ``n`` equal strata."""
    return _first_above(np.asarray(w, float), (rng.random(n) + np.arange(n)) / n)


def multinomial_draw(w: Array, n: int, rng: np.random.Generator) -> NDArray[np.intp]:
    """``n`` independent draws (returned in sorted order)."""
    return _first_above(np.asarray(w, float), np.sort(rng.random(n)))


def residual_draw(w: Array, n: int, rng: np.random.Generator) -> NDArray[np.intp]:
    """floor(n w) copies of each particle, the remainder drawn multinomially."""
    w = np.asarray(w, float)
    counts = np.floor(n * w).astype(np.intp)
    idx = np.repeat(np.arange(len(w)), counts)
    rest = n - len(idx)
    if rest > 0:
        r = n * w - counts
        idx = np.concatenate([idx, _first_above(r / r.sum(), np.sort(rng.random(rest)))])
    return idx


def _first_above(w: Array, u: Array) -> NDArray[np.intp]:
    """For each pointer in ``u``, the first index whose cumulative weight exceeds it."""
    c = np.cumsum(w)
    c[-1] = 1.0
    return np.minimum(np.searchsorted(c, u, side="right"), len(w) - 1)


# Resampling schemes: ``n`` indices from weights ``w`` (SLAM draws N; KLD-sampling any count).
DRAWERS: dict[str, Callable[[Array, int, np.random.Generator], NDArray[np.intp]]] = {
    "systematic": systematic_draw,
    "stratified": stratified_draw,
    "multinomial": multinomial_draw,
    "residual": residual_draw,
}


def log_sum_exp(lw: Array) -> float:
    """log(sum(exp(lw))), shifted by the largest value so nothing overflows; -inf when every
    entry is -inf. (SciPy's ``logsumexp`` gives the same but costs about 50 us per call on
    100 values, against 2 us here; the filters call this several times per scan.)"""
    m = float(np.max(lw))
    if not np.isfinite(m):
        return m
    return m + float(np.log(np.sum(np.exp(lw - m))))


class ParticleSet:
    """N planar poses with log-weights."""

    def __init__(self, poses: Array, log_weights: Array | None = None) -> None:
        self.poses = np.array(poses, dtype=float).reshape(-1, 3)
        n = len(self.poses)
        if log_weights is None:
            log_weights = np.full(n, -np.log(n))
        self.log_weights = np.asarray(log_weights, dtype=float).copy()

    def __len__(self) -> int:
        return len(self.poses)

    @classmethod
    def around(cls, pose: Array, n: int, std: Array, rng: np.random.Generator) -> ParticleSet:
        """N particles drawn from a Gaussian around ``pose`` (std may be zero)."""
        p = np.asarray(pose, dtype=float) + rng.normal(size=(n, 3)) * np.asarray(std, dtype=float)
        p[:, 2] = wrap_angle(p[:, 2])
        return cls(p)

    def normalize(self) -> float:
        """Normalise log-weights (log-sum-exp); return the log of the total before normalising."""
        lw = np.where(np.isfinite(self.log_weights), self.log_weights, -np.inf)
        total = log_sum_exp(lw)
        if not np.isfinite(total):
            self.log_weights = np.full(len(self), -np.log(len(self)))
            return total
        self.log_weights = lw - total
        return total

    @property
    def weights(self) -> Array:
        return np.exp(self.log_weights - log_sum_exp(self.log_weights))

    def n_eff(self) -> float:
        w = self.weights
        return float(1.0 / np.sum(w * w))

    def resample(self, rng: np.random.Generator, method: str = "systematic") -> NDArray[np.intp]:
        idx = DRAWERS[method](self.weights, len(self), rng)
        self.poses = self.poses[idx]
        self.log_weights = np.full(len(self), -np.log(len(self)))
        return idx

    def best(self) -> Array:
        return self.poses[int(np.argmax(self.log_weights))].copy()

    def mean(self) -> Array:
        return self._mean(self.weights)

    def covariance(self) -> Array:
        return self.mean_and_covariance()[1]

    def mean_and_covariance(self) -> tuple[Array, Array]:
        """:meth:`mean` and :meth:`covariance` with the weights and the mean computed once
        (the localizer's estimate at every update)."""
        w = self.weights
        m = self._mean(w)
        d = self.poses - m
        d[:, 2] = wrap_angle(d[:, 2])
        return m, (d * w[:, None]).T @ d

    def _mean(self, w: Array) -> Array:
        return np.array(
            [np.sum(w * self.poses[:, 0]), np.sum(w * self.poses[:, 1]), circular_mean(self.poses[:, 2], w)]
        )
