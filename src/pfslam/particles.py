"""ParticleSet: poses, log-weights, normalisation, resampling, estimates."""

from __future__ import annotations

from typing import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.special import logsumexp

from pfslam.geometry import circular_mean, wrap_angle

Array = NDArray[np.float64]


def systematic_indices(w: Array, rng: np.random.Generator) -> NDArray[np.intp]:
    """Low-variance (systematic) resampling: one uniform draw, N evenly spaced pointers."""
    from pfslam.kernels import systematic_kernel

    return systematic_kernel(np.ascontiguousarray(w, dtype=float), float(rng.random()), len(w))


def stratified_indices(w: Array, rng: np.random.Generator) -> NDArray[np.intp]:
    """Stratified resampling: one uniform draw inside each of N equal strata."""
    n = len(w)
    u = (rng.random(n) + np.arange(n)) / n
    return _search(w, u)


def multinomial_indices(w: Array, rng: np.random.Generator) -> NDArray[np.intp]:
    """Multinomial resampling: N independent draws."""
    return _search(w, np.sort(rng.random(len(w))))


def residual_indices(w: Array, rng: np.random.Generator) -> NDArray[np.intp]:
    """Residual resampling: floor(N w) copies each, the rest drawn multinomially."""
    n = len(w)
    counts = np.floor(n * w).astype(np.intp)
    idx = np.repeat(np.arange(n), counts)
    rest = n - len(idx)
    if rest > 0:
        r = n * w - counts
        r = r / r.sum()
        idx = np.concatenate([idx, _search(r, np.sort(rng.random(rest)))])
    return idx


def _search(w: Array, u: Array) -> NDArray[np.intp]:
    c = np.cumsum(w)
    c[-1] = 1.0
    return np.minimum(np.searchsorted(c, u, side="right"), len(w) - 1)


RESAMPLERS: dict[str, Callable[[Array, np.random.Generator], NDArray[np.intp]]] = {
    "systematic": systematic_indices,
    "stratified": stratified_indices,
    "multinomial": multinomial_indices,
    "residual": residual_indices,
}


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
    def around(cls, pose: Array, n: int, std: Array, rng: np.random.Generator) -> "ParticleSet":
        """N particles drawn from a Gaussian around ``pose`` (std may be zero)."""
        p = np.asarray(pose, dtype=float) + rng.normal(size=(n, 3)) * np.asarray(std, dtype=float)
        p[:, 2] = wrap_angle(p[:, 2])
        return cls(p)

    def normalize(self) -> float:
        """Normalise log-weights (log-sum-exp); return the log of the total before normalising."""
        lw = np.where(np.isfinite(self.log_weights), self.log_weights, -np.inf)
        total = float(logsumexp(lw)) if np.any(np.isfinite(lw)) else -np.inf
        if not np.isfinite(total):
            self.log_weights = np.full(len(self), -np.log(len(self)))
            return total
        self.log_weights = lw - total
        return total

    @property
    def weights(self) -> Array:
        return np.exp(self.log_weights - logsumexp(self.log_weights))

    def n_eff(self) -> float:
        w = self.weights
        return float(1.0 / np.sum(w * w))

    def resample(self, rng: np.random.Generator, method: str = "systematic") -> NDArray[np.intp]:
        idx = RESAMPLERS[method](self.weights, rng)
        self.poses = self.poses[idx]
        self.log_weights = np.full(len(self), -np.log(len(self)))
        return idx

    def best(self) -> Array:
        return self.poses[int(np.argmax(self.log_weights))].copy()

    def mean(self) -> Array:
        w = self.weights
        return np.array(
            [np.sum(w * self.poses[:, 0]), np.sum(w * self.poses[:, 1]), circular_mean(self.poses[:, 2], w)]
        )

    def covariance(self) -> Array:
        w = self.weights
        m = self.mean()
        d = self.poses - m
        d[:, 2] = wrap_angle(d[:, 2])
        return (d * w[:, None]).T @ d
