"""The single-map filter: correlation-based particle-filter SLAM over one occupancy grid
updated from the estimated pose. One ``step(frame)`` per scan, no I/O."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pfslam.config import SensorConfig, SlamConfig, SlamFilter, for_filter
from pfslam.filters.base import OneMapFilter
from pfslam.filters.predict import MotionSince, slam_prediction, start_pose
from pfslam.frames import Estimate, Frame
from pfslam.geometry import compose
from pfslam.kernels import Kernels, kernels_for
from pfslam.maps.fields import gaussian_of_distance, wall_distance
from pfslam.maps.grid import OccupancyGrid, grid_from_config, integrate_scan
from pfslam.particles import ParticleSet
from pfslam.sensor import scan_to_points, subsample
from pfslam.types import Array


def zero_first_offsets(radius: int) -> NDArray[np.int64]:
    """0, -1, 1, -2, 2, ... radius: zero first so ties keep the particle where it is."""
    out = [0]
    for r in range(1, radius + 1):
        out += [-r, r]
    return np.array(out, dtype=np.int64)


class SmoothedWallMap:
    """The smoothed wall map big steps are scored on: exp(-d^2 / 2 sigma^2) of the distance
    d to the nearest wall cell, over the window the particles' hits can reach.

    It is rebuilt (a distance transform over that window plus 2 m) only after the robot
    moved or turned enough, every few scans, or when the hits leave the last window;
    otherwise the last one is reused."""

    SLACK_M = 2.0  # built this far beyond the window, so the next scans fit

    def __init__(self, config: SensorConfig) -> None:
        self.config = config
        self.values: NDArray[np.float32] | None = None
        self.origin = np.zeros(2)
        self.window: tuple[int, int, int, int] | None = None  # rows r0:r1, cols c0:c1 last built
        self.since_build = MotionSince()  # counts toward the next rebuild

    def _stale(self, grid: OccupancyGrid, win: tuple[int, int, int, int]) -> bool:
        c, fw = self.config, self.window
        inside = fw is not None and fw[0] <= win[0] and fw[1] >= win[1] and fw[2] <= win[2] and fw[3] >= win[3]
        return (
            self.values is None
            or self.values.shape != grid.logodds.shape
            or not np.array_equal(self.origin, grid.origin)
            or not inside
            or self.since_build.reached(c.field_refresh_m, np.deg2rad(c.field_refresh_deg), c.field_refresh_scans)
        )

    def get(self, grid: OccupancyGrid, poses: Array, pts: Array) -> NDArray[np.float32]:
        """The map for particles at ``poses`` whose hits are ``pts`` (robot frame)."""
        c = self.config
        reach = float(np.max(np.hypot(pts[:, 0], pts[:, 1]))) if len(pts) else 0.0
        lo = poses[:, :2].min(axis=0) - reach - 0.5
        hi = poses[:, :2].max(axis=0) + reach + 0.5
        (r0, r1), (c0, c1) = grid.world_to_cell(np.array([lo, hi]))
        h, w = grid.logodds.shape
        win = (max(int(r0), 0), min(int(r1) + 1, h), max(int(c0), 0), min(int(c1) + 1, w))
        if self._stale(grid, win):
            if self.values is None or self.values.shape != grid.logodds.shape:
                self.values = np.zeros(grid.logodds.shape, dtype=np.float32)
            elif self.window is not None:
                fw = self.window
                self.values[fw[0] : fw[1], fw[2] : fw[3]] = 0.0
            self.origin = grid.origin.copy()
            self.since_build.reset()
            m = int(np.ceil(self.SLACK_M / grid.resolution))
            r0, r1 = max(win[0] - m, 0), min(win[1] + m, h)
            c0, c1 = max(win[2] - m, 0), min(win[3] + m, w)
            self.window = (r0, r1, c0, c1)
            walls = grid.logodds[r0:r1, c0:c1] > c.field_threshold
            if walls.any():
                d = wall_distance(walls, grid.resolution)
                self.values[r0:r1, c0:c1] = gaussian_of_distance(d, c.field_sigma)
        assert self.values is not None
        return self.values


class SingleMapSlam(OneMapFilter):
    """Particle-filter SLAM over one occupancy grid updated from the estimated pose.

    Each step: move every particle by the odometry increment (or the wheel travel) with
    noise, score it by correlating its projected hits with the map (optionally over a local
    x/y/theta grid that also moves it to its best offset), add score / temperature to its
    log-weight, normalise, take the estimate, resample when N_eff is low, update the map.

    ``kernels``: the kernel set (``pfslam.kernels.NUMBA``, or ``NUMPY`` / "numpy" for the
    plain NumPy twins, e.g. for benchmarks).
    """

    def __init__(
        self,
        config: SlamConfig | None = None,
        kernels: Kernels | str = "numba",
        start: Array | None = None,
        prior: OccupancyGrid | None = None,
    ) -> None:
        """``start``: the first scan's pose (default: the odometry's); ``prior``: a map to
        continue (copied; same resolution)."""
        # Its own settings made concrete (particles 0: its default count).
        self.config = c = for_filter(config, SlamFilter.SINGLE)
        self.kernels = kernels_for(kernels)
        super().__init__(grid_from_config(c.map) if prior is None else prior.copy())  # dead reckoning: see step
        self._start = None if start is None else np.asarray(start, dtype=float).copy()
        self.rng = np.random.default_rng(c.seed)
        self.prediction = slam_prediction(c)
        self.wall_map = SmoothedWallMap(c.sensor)
        self.particles: ParticleSet | None = None
        self.pose = np.zeros(3)
        self._prev: Frame | None = None
        self._increment = np.zeros(3)  # the last noise-free odometry increment
        self._xy_offsets = zero_first_offsets(c.local_search.radius_cells)
        step = np.deg2rad(c.local_search.theta_step_deg)
        self._theta_offsets = zero_first_offsets(c.local_search.theta_steps).astype(float) * step
        self.scans = 0

    # -- pieces -------------------------------------------------------------------

    def _predict(self, frame: Frame) -> bool:
        """Move the particles; return True if the robot moved."""
        assert self.particles is not None and self._prev is not None
        poses, u, moved = self.prediction(self.particles.poses, self._prev, frame, self.rng)
        self.particles.poses = poses
        self._increment = np.zeros(3) if u is None else u
        if u is not None:
            self._odom_pose = compose(self._odom_pose, u)
        return moved

    def _big_step(self) -> bool:
        u, c = self._increment, self.config.sensor
        return bool(np.hypot(u[0], u[1]) > c.field_auto_m or abs(u[2]) > np.deg2rad(c.field_auto_deg))

    def _weigh(self, pts: Array) -> None:
        assert self.particles is not None
        c = self.config
        g = self.grid
        inv_res = 1.0 / g.resolution
        ox, oy = float(g.origin[0]), float(g.origin[1])
        scoring_map = c.sensor.scoring_map
        if scoring_map == "field" or (scoring_map == "auto" and self._big_step()):
            values, inv_sat, lo = self.wall_map.get(g, self.particles.poses, pts), 1.0, 0.0
        else:
            values, inv_sat, lo = g.logodds, 1.0 / c.sensor.saturation, -c.sensor.free_weight
        poses = np.ascontiguousarray(self.particles.poses)
        dxy, dth = self._xy_offsets, self._theta_offsets
        if c.local_search.enabled and (len(dxy) > 1 or len(dth) > 1):
            scores, best_x, best_y, best_theta = self.kernels.local_search(
                poses, pts, values, ox, oy, inv_res, inv_sat, lo, dxy, dth
            )
            poses = poses.copy()
            poses[:, 0] += dxy[best_x] * g.resolution
            poses[:, 1] += dxy[best_y] * g.resolution
            poses[:, 2] += dth[best_theta]
            self.particles.poses = poses
        else:
            scores = self.kernels.correlation(poses, pts, values, ox, oy, inv_res, inv_sat, lo)
        self.particles.log_weights = self.particles.log_weights + scores / c.sensor.temperature
        self.particles.normalize()

    # -- the step -----------------------------------------------------------------

    def step(self, frame: Frame) -> Estimate:
        c = self.config
        sp = scan_to_points(frame, ground_z=c.sensor.ground_z)
        resampled = False
        weighed = False
        if self.particles is None:
            start = start_pose(frame) if self._start is None else self._start.copy()
            self.particles = ParticleSet(np.tile(start, (c.particles, 1)))
            self.pose = start.copy()
            self._odom_pose = start.copy()
        else:
            moved = self._predict(frame)
            if moved and len(sp.hits):
                self._weigh(subsample(sp.hits, c.sensor.max_hits))
                weighed = True
            if weighed:
                self.pose = self.particles.best() if c.estimate == "best" else self.particles.mean()
            else:
                # No measurement: every particle moved by the same increment (no noise while
                # still), and after a resampling all weights are equal, so "best" would be an
                # arbitrary particle. Carry the last estimate forward instead.
                self.pose = compose(self.pose, self._increment)
        n_eff = self.particles.n_eff()
        if weighed and n_eff < c.resample_threshold * len(self.particles):
            self.particles.resample(self.rng, c.resample_method)
            resampled = True
        integrate_scan(self.grid, self.pose, sp, self.kernels.ray_update)
        self.wall_map.since_build.add(self._increment)
        self._prev = frame
        self.scans += 1
        self._estimates.add(frame.t, self.pose)
        return Estimate(
            t=frame.t,
            pose=self.pose.copy(),
            n_eff=n_eff,
            resampled=resampled,
            updated=weighed,
            particles=len(self.particles),
        )
