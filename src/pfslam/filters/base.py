"""What every filter offers the pipeline, whichever filter it is."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from pfslam.frames import Estimate, Frame
from pfslam.maps.grid import OccupancyGrid
from pfslam.particles import ParticleSet
from pfslam.types import Array, JSONObject

SETTLED_SPREAD = 0.25  # m: an estimate this concentrated (position std) is tracking, not searching


def position_std(cov: Array) -> float:
    """The position standard deviation (m) of an (x, y, theta) covariance: sqrt(var x + var y)."""
    return float(np.sqrt(max(cov[0, 0] + cov[1, 1], 0.0)))


@runtime_checkable
class Filter(Protocol):
    """A particle filter driven one frame at a time.

    ``step`` takes the next frame and returns the estimate for it; ``map`` is the map the
    filter holds now (built so far for SLAM, the given one for localization);
    ``odom_pose`` is the noise-free dead reckoning of the odometry in the filter's frame;
    ``trajectory()`` is the filter's answer for every frame stepped so far, as (times (N,),
    poses (N, 3)): a filter may revise earlier poses (a loop closed), so the pipeline asks
    for it at the end instead of collecting the per-step estimates; ``particles`` the
    particles now (None before the first step; a filter may build the set when asked);
    ``diagnostics()`` what the filter counted, for run.json.
    """

    def step(self, frame: Frame) -> Estimate: ...

    @property
    def map(self) -> OccupancyGrid: ...

    @property
    def odom_pose(self) -> Array: ...

    def trajectory(self) -> tuple[Array, Array]: ...

    @property
    def particles(self) -> ParticleSet | None: ...

    def diagnostics(self) -> JSONObject: ...


class EstimateLog:
    """The per-step estimates of a filter that does not revise its past, kept compactly
    (grown by doubling) for :meth:`Filter.trajectory`."""

    def __init__(self) -> None:
        self._t = np.empty(256)
        self._poses = np.empty((256, 3))
        self._n = 0

    def add(self, t: float, pose: Array) -> None:
        if self._n == len(self._t):
            self._t = np.resize(self._t, 2 * self._n)
            self._poses = np.resize(self._poses, (2 * self._n, 3))
        self._t[self._n] = t
        self._poses[self._n] = pose
        self._n += 1

    def __len__(self) -> int:
        return self._n

    def arrays(self) -> tuple[Array, Array]:
        return self._t[: self._n].copy(), self._poses[: self._n].copy()


class OneMapFilter:
    """The :class:`Filter` interface of a filter that holds one map and whose trajectory is
    its per-step estimates: subclasses set ``grid``, keep ``_odom_pose`` and add each
    step's estimate to ``_estimates``."""

    def __init__(self, grid: OccupancyGrid, odom_pose: Array | None = None) -> None:
        self.grid = grid
        self._odom_pose = np.zeros(3) if odom_pose is None else np.asarray(odom_pose, dtype=float)
        self._estimates = EstimateLog()

    @property
    def map(self) -> OccupancyGrid:
        return self.grid

    @property
    def odom_pose(self) -> Array:
        """Noise-free dead reckoning of the odometry, in the filter's frame."""
        return self._odom_pose

    def trajectory(self) -> tuple[Array, Array]:
        return self._estimates.arrays()

    def diagnostics(self) -> JSONObject:
        return {}
