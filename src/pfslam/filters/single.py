"""Correlation-based particle-filter SLAM: one ``step(frame)`` per scan, no I/O."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import distance_transform_edt

from pfslam.config import SlamConfig
from pfslam.frames import Estimate, Frame
from pfslam.geometry import compose, relative, transform_points
from pfslam.grid import OccupancyGrid
from pfslam.motion import DiffDriveMotion, OdometryMotion
from pfslam.particles import ParticleSet
from pfslam.kernels import correlation_kernel, correlation_numpy, ray_update_numpy, search_kernel, search_numpy
from pfslam.sensor import ScanPoints, scan_to_points

Array = NDArray[np.float64]


def subsample(pts: Array, k: int) -> Array:
    """At most ``k`` points, evenly spaced along the scan."""
    if k <= 0 or len(pts) <= k:
        return pts
    idx = np.linspace(0, len(pts) - 1, k).round().astype(np.intp)
    return np.ascontiguousarray(pts[idx])


def offsets(radius: int) -> NDArray[np.int64]:
    """0, -1, 1, -2, 2, ...: zero first so ties keep the particle where it is."""
    out = [0]
    for r in range(1, radius + 1):
        out += [-r, r]
    return np.array(out, dtype=np.int64)


def integrate_scan(grid: OccupancyGrid, pose: Array, sp: ScanPoints) -> None:
    """Ray-update ``grid`` with one scan seen from ``pose``: hits occupied, floor hits free."""
    origin = transform_points(pose, sp.sensor_xy[None])[0]
    pts = np.concatenate([sp.hits, sp.floor]) if len(sp.floor) else sp.hits
    if len(pts):
        hit = np.zeros(len(pts), dtype=bool)
        hit[: len(sp.hits)] = True
        grid.update(origin, transform_points(pose, pts), hit)


class Slam:
    """Particle-filter SLAM over one occupancy grid updated from the estimated pose.

    Each step: move every particle by the odometry increment (or the wheel travel) with
    noise, score it by correlating its projected hits with the map (optionally over a local
    x/y/theta grid that also moves it to its best offset), add score / temperature to its
    log-weight, normalise, take the estimate, resample when N_eff is low, update the map.
    """

    def __init__(self, config: SlamConfig | None = None, backend: str = "numba") -> None:
        """``backend="numpy"`` runs the plain NumPy twins of the kernels (for benchmarks)."""
        if backend not in ("numba", "numpy"):
            raise ValueError("backend must be 'numba' or 'numpy'")
        self.config = (config or SlamConfig()).validate()
        c = self.config
        self.rng = np.random.default_rng(c.seed)
        half = c.map.initial_size / 2
        n = int(np.ceil(c.map.initial_size / c.map.resolution))
        self.grid = OccupancyGrid(
            resolution=c.map.resolution,
            l_occ=c.map.l_occ,
            l_free=c.map.l_free,
            l_clamp=c.map.l_clamp,
            origin=(-half, -half),
            shape=(n, n),
        )
        self._correlate = correlation_kernel if backend == "numba" else correlation_numpy
        self._search = search_kernel if backend == "numba" else search_numpy
        if backend == "numpy":
            self.grid.ray_update = ray_update_numpy
        self.odometry_motion = OdometryMotion(
            sigma=(c.motion.sigma_x, c.motion.sigma_y, float(np.deg2rad(c.motion.sigma_theta_deg))),
            ref_interval=c.motion.ref_interval,
            trans_k=c.motion.trans_k,
            rot_k=c.motion.rot_k,
        )
        self.diff_motion = DiffDriveMotion(axle=c.motion.axle, k_left=c.motion.k_left, k_right=c.motion.k_right)
        self.particles: ParticleSet | None = None
        self.pose = np.zeros(3)
        self.odom_pose = np.zeros(3)  # noise-free dead reckoning in the map frame, from the first odometry pose
        self._prev: Frame | None = None
        self._u = np.zeros(3)  # the last noise-free odometry increment
        self._field: NDArray[np.float32] | None = None  # smoothed wall map for scoring
        self._field_origin = np.zeros(2)
        self._field_window: tuple[int, int, int, int] | None = None  # rows r0:r1, cols c0:c1 last built
        self._since_field = np.zeros(3)  # motion (m), turn (rad), scans since it was built
        self._dcells = offsets(c.search.radius_cells)
        step = np.deg2rad(c.search.theta_step_deg)
        self._dthetas = offsets(c.search.theta_steps).astype(float) * step
        self.scans = 0

    # -- pieces -------------------------------------------------------------------

    def _predict(self, frame: Frame) -> bool:
        """Move the particles; return True if the robot moved."""
        assert self.particles is not None and self._prev is not None
        prev = self._prev
        dt = max(frame.t - prev.t, 0.0)
        if frame.wheels is not None and prev.wheels is not None:
            dl, dr = (np.asarray(frame.wheels) - np.asarray(prev.wheels)).tolist()
            self._u = DiffDriveMotion.arc(np.zeros((1, 3)), np.array(dl), np.array(dr), self.diff_motion.axle)[0]
            self.odom_pose = compose(self.odom_pose, self._u)
            if abs(dl) < 1e-6 and abs(dr) < 1e-6:
                return False
            self.particles.poses = self.diff_motion.apply(self.particles.poses, dl, dr, self.rng)
            return True
        if frame.odom is None or prev.odom is None:
            self._u = np.zeros(3)
            return False
        u = relative(prev.odom, frame.odom)
        self._u = u
        self.odom_pose = compose(self.odom_pose, u)
        self.particles.poses = self.odometry_motion.apply(self.particles.poses, u, dt, self.rng)
        return not self.odometry_motion.is_still(u)

    def _weigh(self, pts: Array) -> None:
        assert self.particles is not None
        c = self.config
        g = self.grid
        inv_res = 1.0 / g.resolution
        ox, oy = float(g.origin[0]), float(g.origin[1])
        big_step = bool(np.hypot(self._u[0], self._u[1]) > c.sensor.field_auto_m
                        or abs(self._u[2]) > np.deg2rad(c.sensor.field_auto_deg))
        if c.sensor.score == "field" or (c.sensor.score == "auto" and big_step):
            values, inv_sat, lo = self._scoring_field(pts), 1.0, 0.0
        else:
            values, inv_sat, lo = g.logodds, 1.0 / c.sensor.saturation, -c.sensor.free_weight
        poses = np.ascontiguousarray(self.particles.poses)
        if c.search.enabled and (len(self._dcells) > 1 or len(self._dthetas) > 1):
            best, bx, by, bt = self._search(
                poses, pts, values, ox, oy, inv_res, inv_sat, lo, self._dcells, self._dthetas
            )
            poses = poses.copy()
            poses[:, 0] += self._dcells[bx] * g.resolution
            poses[:, 1] += self._dcells[by] * g.resolution
            poses[:, 2] += self._dthetas[bt]
            self.particles.poses = poses
            scores = best
        else:
            scores = self._correlate(poses, pts, values, ox, oy, inv_res, inv_sat, lo)
        self.particles.log_weights = self.particles.log_weights + scores / c.sensor.temperature
        self.particles.normalize()

    def _scoring_field(self, pts: Array) -> NDArray[np.float32]:
        """The smoothed wall map the particles are scored on: exp(-d^2 / 2 sigma^2) of the
        distance d to the nearest wall cell, over the window the particles' hits can reach.

        It is rebuilt (a distance transform over that window plus 2 m) only after the robot
        moved or turned enough, every few scans, or when the hits leave the last window;
        otherwise the last one is reused."""
        c = self.config.sensor
        g = self.grid
        assert self.particles is not None
        poses = self.particles.poses
        reach = float(np.max(np.hypot(pts[:, 0], pts[:, 1]))) if len(pts) else 0.0
        lo = poses[:, :2].min(axis=0) - reach - 0.5
        hi = poses[:, :2].max(axis=0) + reach + 0.5
        (r0, r1), (c0, c1) = g.world_to_cell(np.array([lo, hi]))
        h, w = g.logodds.shape
        win = (max(int(r0), 0), min(int(r1) + 1, h), max(int(c0), 0), min(int(c1) + 1, w))
        fw = self._field_window
        inside = fw is not None and fw[0] <= win[0] and fw[1] >= win[1] and fw[2] <= win[2] and fw[3] >= win[3]
        stale = (
            self._field is None
            or self._field.shape != g.logodds.shape
            or not np.array_equal(self._field_origin, g.origin)
            or not inside
            or self._since_field[2] >= c.field_refresh_scans
            or self._since_field[0] >= c.field_refresh_m
            or self._since_field[1] >= np.deg2rad(c.field_refresh_deg)
        )
        if stale:
            if self._field is None or self._field.shape != g.logodds.shape:
                self._field = np.zeros(g.logodds.shape, dtype=np.float32)
            elif fw is not None:
                self._field[fw[0] : fw[1], fw[2] : fw[3]] = 0.0
            self._field_origin = g.origin.copy()
            self._since_field[:] = 0.0
            m = int(np.ceil(2.0 / g.resolution))  # 2 m of slack so the next scans fit
            r0, r1 = max(win[0] - m, 0), min(win[1] + m, h)
            c0, c1 = max(win[2] - m, 0), min(win[3] + m, w)
            self._field_window = (r0, r1, c0, c1)
            occ = g.logodds[r0:r1, c0:c1] > c.field_threshold
            if occ.any():
                d = distance_transform_edt(~occ) * g.resolution
                self._field[r0:r1, c0:c1] = np.exp(-0.5 * (d / c.field_sigma) ** 2)
        return self._field

    def _update_map(self, sp: ScanPoints) -> None:
        integrate_scan(self.grid, self.pose, sp)

    # -- the step -----------------------------------------------------------------

    def step(self, frame: Frame) -> Estimate:
        c = self.config
        sp = scan_to_points(frame, ground_z=c.sensor.ground_z)
        resampled = False
        weighed = False
        if self.particles is None:
            # The map frame is the odometry frame at the first scan (the origin for wheel logs).
            start = np.zeros(3) if frame.odom is None else np.asarray(frame.odom, dtype=float)
            self.particles = ParticleSet(np.tile(start, (c.particles, 1)))
            self.pose = start.copy()
            self.odom_pose = start.copy()
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
                self.pose = compose(self.pose, self._u)
        n_eff = self.particles.n_eff()
        if weighed and n_eff < c.resample_threshold * len(self.particles):
            self.particles.resample(self.rng, c.resample_method)
            resampled = True
        self._update_map(sp)
        self._since_field += [np.hypot(self._u[0], self._u[1]), abs(self._u[2]), 1.0]
        self._prev = frame
        self.scans += 1
        return Estimate(t=frame.t, pose=self.pose.copy(), n_eff=n_eff, resampled=resampled, updated=weighed)
