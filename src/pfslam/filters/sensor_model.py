"""The localizer's sensor model: the likelihood field (log p of a beam's end point from its
distance to the nearest wall, precomputed once per map) and the window of ranges it reads."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from pfslam.config import LocalizerConfig
from pfslam.frames import Frame
from pfslam.geometry import transform_points
from pfslam.kernels import Kernels, kernels_for
from pfslam.maps.fields import wall_distance
from pfslam.maps.grid import OccupancyGrid
from pfslam.types import Array

MODEL_RANGE = 30.0  # m: the beam model's and z_rand's range when laser_max_range is not set (at most the sensor's)


def laser_window(frame: Frame, config: LocalizerConfig) -> Frame:
    """``frame`` with its valid range window narrowed to ``config.laser_min_range`` /
    ``laser_max_range`` where they are set (>= 0): readings outside are no returns. The
    window only narrows: readings outside the sensor's own window stay no returns."""
    lo, hi = config.laser_min_range, config.laser_max_range
    if lo < 0 and hi < 0:
        return frame
    return replace(
        frame, min_range=max(frame.min_range, lo), max_range=frame.max_range if hi < 0 else min(frame.max_range, hi)
    )


def model_range(config: LocalizerConfig) -> float:
    """The range (m) of the beam model's ray casts and of z_rand's uniform density:
    ``laser_max_range`` if set, else :data:`MODEL_RANGE` (a frame's own maximum caps it)."""
    return config.laser_max_range if config.laser_max_range > 0 else MODEL_RANGE


@dataclass
class LikelihoodField:
    """log p(end point | map) on the grid: a Gaussian of the distance to the nearest
    occupied cell plus a random-measurement floor; precomputed once per map.

    ``log p = log(z_hit * exp(-d^2 / (2 sigma_hit^2)) + z_rand / max_range)`` with the
    distance ``d`` (m) to the nearest occupied cell (``thresholded() == 100``) capped at
    ``max_dist``. Unknown cells are treated like free cells (no penalty): maps written by
    SLAM have unknown space right behind their walls, where end points of a slightly
    misplaced particle land, and the distance to that wall already scores them. End
    points off the map count ``floor``, the value at ``max_dist``.
    """

    logp: NDArray[np.float32]
    origin: Array
    resolution: float
    floor: float  # log p of an end point off the map or beyond max_dist
    dist: NDArray[np.float32] | None = None  # the capped distances the field was made from (m)
    sigma_hit: float = 0.2
    z_hit: float = 0.95
    rand: float = 0.05 / 30.0  # z_rand / max_range
    max_dist: float = 2.0
    interpolate: bool = False  # read bilinearly between cell centres (see likelihood_kernel)
    padded: NDArray[np.float32] | None = None  # logp with a border of one floor cell (interpolate)

    @classmethod
    def from_grid(
        cls,
        grid: OccupancyGrid,
        sigma_hit: float = 0.2,
        z_hit: float = 0.95,
        z_rand: float = 0.05,
        max_dist: float = 2.0,
        max_range: float = 30.0,
        interpolate: bool = False,
    ) -> LikelihoodField:
        d = np.minimum(wall_distance(grid.thresholded() == 100, grid.resolution), max_dist).astype(np.float32)
        field = cls(
            np.empty(0, np.float32),
            grid.origin.copy(),
            grid.resolution,
            0.0,
            d,
            sigma_hit,
            z_hit,
            z_rand / max_range,
            max_dist,
            interpolate,
        )
        return field.with_sigma(sigma_hit)

    def with_sigma(self, sigma_hit: float) -> LikelihoodField:
        """The same field with the Gaussian's width ``sigma_hit`` (m)."""
        assert self.dist is not None
        p = self.z_hit * np.exp(-0.5 * (self.dist / np.float32(sigma_hit)) ** 2) + np.float32(self.rand)
        floor = float(np.log(self.z_hit * np.exp(-0.5 * (self.max_dist / sigma_hit) ** 2) + self.rand))
        logp = np.log(p).astype(np.float32)
        padded = np.pad(logp, 1, constant_values=np.float32(floor)) if self.interpolate else None
        return LikelihoodField(
            logp,
            self.origin,
            self.resolution,
            floor,
            self.dist,
            sigma_hit,
            self.z_hit,
            self.rand,
            self.max_dist,
            self.interpolate,
            padded,
        )

    def _cells(self, pose: Array, pts: Array) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.bool_]]:
        w = transform_points(np.asarray(pose, float), np.asarray(pts, float))
        c = np.floor((w[:, 0] - self.origin[0]) / self.resolution).astype(np.intp)
        r = np.floor((w[:, 1] - self.origin[1]) / self.resolution).astype(np.intp)
        h, wd = self.logp.shape
        return c, r, (r >= 0) & (r < h) & (c >= 0) & (c < wd)

    def distances(self, pose: Array, pts: Array) -> Array:
        """Distance (m, capped at max_dist) from each end point ``pts`` (robot frame) seen
        from ``pose`` to the nearest occupied cell; max_dist off the map."""
        assert self.dist is not None
        c, r, ok = self._cells(pose, pts)
        out = np.full(len(c), self.max_dist)
        out[ok] = self.dist[r[ok], c[ok]]
        return out

    def __call__(self, poses: Array, pts: Array, kernels: Kernels | str = "numba") -> Array:
        """log p of the end points ``pts`` (robot frame) summed, for each of ``poses``; with
        ``interpolate`` read bilinearly between cell centres (off the map: ``floor``)."""
        field, shift = (self.logp, 0.0) if self.padded is None else (self.padded, self.resolution)
        return kernels_for(kernels).likelihood(
            np.ascontiguousarray(poses, dtype=float),
            np.ascontiguousarray(pts, dtype=float),
            field,
            float(self.origin[0]) - shift,
            float(self.origin[1]) - shift,
            1.0 / self.resolution,
            self.floor,
            self.padded is not None,
        )
