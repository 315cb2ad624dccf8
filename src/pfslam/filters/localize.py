"""Monte Carlo localization on a known occupancy grid (no I/O).

Steps, each a method of :class:`Localizer`: initialise (around a pose, or uniformly
over free space), predict (odometry model with alpha1..alpha4, or differential drive),
update (likelihood field at the beam end points), normalise in log space, estimate
(weighted mean, circular mean for theta, covariance), health (how well the scan fits the
map at the estimate: :mod:`pfslam.filters.health`), resample (systematic; KLD-sampling adapts
the particle count; while the health says lost and the short-term average likelihood is below
the long-term one, random particles are injected, for a kidnapped robot). A global start
seeds the particles from the first scan (:mod:`pfslam.filters.globalstart`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pfslam.config import LocalizerConfig, OdomModel
from pfslam.errors import InputError
from pfslam.filters.base import SETTLED_SPREAD, OneMapFilter, position_std
from pfslam.filters.globalstart import GlobalStart
from pfslam.filters.health import Health, HealthMonitor, State, scan_fit
from pfslam.filters.odometry_scale import SCALE_DRIFT, OdometryScale
from pfslam.filters.predict import WHEELS_STILL, MotionSince, Prediction
from pfslam.filters.sensor_model import LikelihoodField, laser_window, model_range
from pfslam.frames import Estimate, Frame
from pfslam.geometry import compose, relative, wrap_angle
from pfslam.kernels import Kernels, kernels_for
from pfslam.kernels.likelihood import neighbourhood_masses
from pfslam.maps.grid import OccupancyGrid
from pfslam.motion import AmclOdometryMotion, DiffDriveMotion, OmniOdometryMotion
from pfslam.particles import DRAWERS, ParticleSet
from pfslam.sensor import scan_to_points, subsample
from pfslam.types import Array, JSONObject

AMBIGUOUS_MASS = 0.5  # the estimate's neighbourhood holds less of the weight: other places share it
GLOBAL_CAP = 2_000_000  # particles at most in a global initialisation (48 MB of poses)


def kld_bound(k: int, err: float, z_quantile: float) -> int:
    """Fox's KLD-sampling bound: particles needed for ``k`` occupied histogram bins."""
    if k <= 1:
        return 1
    from scipy.stats import norm  # here, not at import: it costs seconds that SLAM runs need not pay

    z = norm.ppf(z_quantile)
    a = 2.0 / (9.0 * (k - 1))
    return int(np.ceil((k - 1) / (2.0 * err) * (1.0 - a + np.sqrt(a) * z) ** 3))


def kld_bounds(k: NDArray[np.int64], err: float, z_quantile: float) -> NDArray[np.int64]:
    """:func:`kld_bound` for an array of bin counts."""
    k = np.asarray(k, dtype=float)
    from scipy.stats import norm  # here, not at import: it costs seconds that SLAM runs need not pay

    z = norm.ppf(z_quantile)
    km1 = np.maximum(k - 1.0, 1.0)
    a = 2.0 / (9.0 * km1)
    n = np.ceil(km1 / (2.0 * err) * (1.0 - a + np.sqrt(a) * z) ** 3)
    return np.where(k <= 1, 1, n).astype(np.int64)


@dataclass
class _Recovery:
    """Short- and long-term averages of the measurement likelihood (exponential, with the
    start-up bias removed so the long-term average is a true mean from the first update)."""

    alpha_slow: float = 0.001
    alpha_fast: float = 0.1
    ratio: float = 1.0  # inject only once w_fast < ratio * w_slow
    raw_slow: float = 0.0
    raw_fast: float = 0.0
    count: int = 0

    def add(self, avg: float) -> None:
        self.count += 1
        self.raw_slow += self.alpha_slow * (avg - self.raw_slow)
        self.raw_fast += self.alpha_fast * (avg - self.raw_fast)

    @property
    def w_slow(self) -> float:
        return self.raw_slow / (1.0 - (1.0 - self.alpha_slow) ** self.count) if self.count else 0.0

    @property
    def w_fast(self) -> float:
        return self.raw_fast / (1.0 - (1.0 - self.alpha_fast) ** self.count) if self.count else 0.0

    @property
    def p_random(self) -> float:
        """Fraction of particles to draw at random: max(0, 1 - w_fast / (ratio * w_slow)).
        AMCL's rule is ``ratio`` 1; below 1 the jitter of a filter that is not lost (w_fast
        within a few per cent of w_slow, above and below) injects nothing."""
        return max(0.0, 1.0 - self.w_fast / (self.ratio * self.w_slow)) if self.w_slow > 0 else 0.0


def check_start_pose(grid: OccupancyGrid, pose: Array, occupied: NDArray[np.bool_] | None = None) -> None:
    """Raise InputError if ``pose`` (x, y, theta) is off ``grid`` or in an occupied cell
    (``occupied``: the grid's occupied cells, if known): a start pose checked on the map alone,
    before any filter is built."""
    pose = np.asarray(pose, float).reshape(-1)
    if pose.shape != (3,) or not np.all(np.isfinite(pose)):
        raise InputError("initial pose", f"expected three finite numbers x, y, theta, got {pose.tolist()}")
    occ = occupied if occupied is not None else grid.thresholded() == 100
    r, c = grid.world_to_cell(pose[None, :2])
    h, w = occ.shape
    if not (0 <= r[0] < h and 0 <= c[0] < w):
        x0, y0 = float(grid.origin[0]), float(grid.origin[1])
        x1, y1 = x0 + w * grid.resolution, y0 + h * grid.resolution
        raise InputError(
            "initial pose",
            f"({pose[0]:.2f}, {pose[1]:.2f}) is outside the map (x {x0:.2f}..{x1:.2f}, y {y0:.2f}..{y1:.2f})",
        )
    if occ[r[0], c[0]]:
        raise InputError("initial pose", f"({pose[0]:.2f}, {pose[1]:.2f}) is in an occupied cell")


class Localizer(OneMapFilter):
    """Monte Carlo localization with KLD-sampling and random-particle recovery."""

    def __init__(
        self, grid: OccupancyGrid, config: LocalizerConfig | None = None, kernels: Kernels | str = "numba"
    ) -> None:
        self.config = c = config if config is not None else LocalizerConfig()
        super().__init__(grid)  # dead reckoning from the first frame, which sits at 0, 0, 0
        self.rng = np.random.default_rng(c.seed)
        self.field = LikelihoodField.from_grid(
            grid, c.sigma_hit, c.z_hit, c.z_rand, c.max_dist, model_range(c), c.interpolate
        )
        self._base_field = self.field  # the configured width: the recovery's measure of fit
        t = grid.thresholded()
        self._free = np.argwhere(t == 0)
        self._occupied = t == 100
        self._occ_u8 = np.ascontiguousarray(self._occupied.astype(np.uint8))
        alphas = (c.alpha1, c.alpha2, c.alpha3, c.alpha4)
        odometry = (
            OmniOdometryMotion(*alphas, alpha5=c.alpha5)
            if c.odom_model is OdomModel.OMNI
            else AmclOdometryMotion(*alphas)
        )
        self.prediction = Prediction(odometry, DiffDriveMotion(c.axle, c.k_left, c.k_right))
        self.kernels = kernels_for(kernels)
        self.particles: ParticleSet | None = None
        self.recovery = _Recovery(c.recovery_alpha_slow, c.recovery_alpha_fast, c.recovery_ratio)
        self._prev: Frame | None = None
        self._anchor: Frame | None = None  # the frame the particles were last moved to
        self._last_pts: Array | None = None  # the end points of the last update (robot frame)
        self._sigma = c.sigma_hit  # the field's width as it adapts (see adapt_sigma)
        self.injected = 0  # particles injected by the recovery, in all
        self.recoveries = 0  # resamplings that injected particles
        self._since_update = MotionSince()  # counts toward the update gate
        self._increment = np.zeros(3)  # the last noise-free motion
        self.pose = np.zeros(3)
        self.cov = np.zeros((3, 3))
        self.updates = 0
        self.odom_scale = OdometryScale(c.odom_scale_window, c.odom_scale_bound)
        self._reported = np.zeros(3)  # the odometry's motion the particles last moved by (not scaled)
        self._settled_pose: Array | None = None  # the last update's estimate, if settled
        self._scales = np.ones(0)  # each particle's own factor on the learnt translation scale
        self._factor = 1.0  # the factors' mean in the estimate's neighbourhood, at the last update
        self._factor_std = 0.0  # and their spread there
        self._was_settled = False  # whether the last update's estimate was settled
        self._global = False  # started globally (each particle then carries its own scale)
        self._mass = 1.0  # the weight in the estimate's neighbourhood, at the last update
        self.health_monitor = HealthMonitor(c.health_tracking, c.health_lost)
        self.health: Health | None = None  # the last update's (see :meth:`check_health`)
        self._start: GlobalStart | None = None  # a global start's search and modes (see globalstart)

    # -- initialisation ----------------------------------------------------------------

    def random_free_poses(self, n: int) -> Array:
        if len(self._free) == 0:
            raise InputError("map", "the map has no free cells")
        idx = self.rng.integers(0, len(self._free), n)
        rc = self._free[idx].astype(float) + self.rng.random((n, 2))
        res = self.grid.resolution
        return np.column_stack(
            [
                self.grid.origin[0] + rc[:, 1] * res,
                self.grid.origin[1] + rc[:, 0] * res,
                self.rng.uniform(-np.pi, np.pi, n),
            ]
        )

    def check_pose(self, pose: Array) -> None:
        """Raise InputError if ``pose`` is off the map or in an occupied cell."""
        check_start_pose(self.grid, pose, self._occupied)

    def initialize_around(self, pose: Array, std: Array) -> None:
        pose = np.asarray(pose, float)
        self.check_pose(pose)
        self._global, self._start = False, None
        self.particles = ParticleSet.around(pose, self.config.particles, std, self.rng)
        self._scales = self.random_scales(self.config.particles)

    @property
    def per_particle_scale(self) -> bool:
        """Whether each particle carries its own translation scale: after a global start
        (``odom_scale_adapt`` and ``odom_scale_spread`` > 0). From a known start one scale is
        learnt once settled: there the particles' own scales cost accuracy (Mines on its SLAM
        map 0.056 -> 0.067 m, Intel 0.065 -> 0.070 m) and a tracking filter settles at once."""
        return self._global and self.config.odom_scale_adapt and self.config.odom_scale_spread > 0

    def random_scales(self, n: int) -> Array:
        """``n`` factors on the translation scale drawn uniformly within 1 -+
        ``odom_scale_spread`` (all 1 without per-particle scales)."""
        if not self.per_particle_scale:
            return np.ones(n)
        b = self.config.odom_scale_spread
        return self.rng.uniform(1.0 - b, 1.0 + b, n)

    @property
    def scales(self) -> Array:
        """Each particle's own factor on the learnt translation scale (the particle's scale,
        reported / true distance, is the learnt one times it). Particles set from outside
        (``particles`` assigned) get fresh ones, drawn as at the start."""
        ps = self._require_particles()
        if len(self._scales) != len(ps):
            self._scales = self.random_scales(len(ps))
        return self._scales

    def diagnostics(self) -> JSONObject:
        out: JSONObject = {"recoveries": self.recoveries, "injected_particles": self.injected}
        if self.config.odom_scale_adapt:
            out["odometry_scale"] = {
                "translation": round(self.translation_scale, 5),
                **(
                    {"translation_std": round(self.odom_scale.translation * self._factor_std, 5)}
                    if self.per_particle_scale
                    else {}
                ),
                "rotation": round(self.odom_scale.rotation, 5),
                "motions_counted": self.odom_scale.count,
            }
        if self.config.sigma_hit_adapt and self.config.model == "likelihood_field":
            out["sigma_hit"] = round(self.sigma_hit, 4)  # the width fitted by the end
        if self._start is not None:
            out["global_start"] = self._start.as_dict()
        return out

    @property
    def translation_scale(self) -> float:
        """The odometry's translation scale divided out now: the one learnt from the
        corrections, times the mean of the particles' own factors near the estimate."""
        return self.odom_scale.translation * (self._factor if self.per_particle_scale else 1.0)

    @property
    def global_count(self) -> int:
        """Particles a global initialisation spreads: ``global_density`` per m2 of free space,
        at least ``global_particles``, at most :data:`GLOBAL_CAP`."""
        area = len(self._free) * self.grid.resolution**2
        return int(max(self.config.global_particles, min(round(self.config.global_density * area), GLOBAL_CAP)))

    def initialize_global(self) -> None:
        """Start anywhere on the map: with ``global_start`` bnb the particles are placed at the
        first update, round the places where its scan fits the map best (see
        :mod:`~pfslam.filters.globalstart`; uniform over free space if it fits nowhere);
        with uniform, now, uniformly over free space."""
        if len(self._free) == 0:
            raise InputError("map", "the map has no free cells")
        self._global = True
        self._start = GlobalStart(str(self.config.global_start))
        self.particles = ParticleSet(np.zeros((1, 3))) if self._start.mode == "bnb" else None
        if self.particles is None:
            self._start.pending = False
            self._spread_uniformly()

    def _spread_uniformly(self) -> None:
        self.particles = ParticleSet(self.random_free_poses(self.global_count))
        self._scales = self.random_scales(len(self.particles))

    def _start_from_scan(self, hits: Array) -> None:
        """A pending global start (see :meth:`initialize_global`): seed from the first scan."""
        if self._start is not None and self._start.pending and not self._start.seed(self, hits):
            self._spread_uniformly()

    def _start_update(self, frame: Frame) -> bool:
        """Whether to update at ``frame`` without the motion the gate wants: while a global start is
        ambiguous, the scans of a robot standing still (its sensor turning) may tell its places apart."""
        return self._start is not None and self._start.wants_update(frame.t)

    @property
    def ambiguous(self) -> bool:
        """Whether the filter cannot yet tell where the robot is: after a global start, until
        one place has won (see :class:`~pfslam.filters.globalstart.GlobalStart`); and whenever
        the estimate's neighbourhood held less than :data:`AMBIGUOUS_MASS` of the particles'
        weight at the last update (places apart share it)."""
        return (self._start is not None and self._start.ambiguous) or self._mass < AMBIGUOUS_MASS

    @property
    def n(self) -> int:
        """The current particle count (0 before an initialisation)."""
        return 0 if self.particles is None else len(self.particles)

    @property
    def covariance(self) -> Array:
        """Covariance (x, y, theta) of the particles around the estimate, from the last update."""
        return self.cov.copy()

    def _require_particles(self) -> ParticleSet:
        if self.particles is None:
            raise RuntimeError("call initialize_around() or initialize_global() first")
        return self.particles

    # -- the steps -----------------------------------------------------------------------

    def predict(self, frame: Frame) -> None:
        """Follow the odometry from the previous frame to ``frame`` without noise: the
        dead-reckoned estimate and the motion counted toward the update gate. The particles
        themselves wait (see :meth:`move_particles`)."""
        self._require_particles()
        if self._prev is None:
            self._anchor = frame
            return
        u = self.prediction.increment(self._prev, frame)
        if u is None:
            return
        self._odom_pose = compose(self._odom_pose, u)
        self._since_update.add(u)
        self._increment = self._scaled(u)

    def _scaled(self, u: Array) -> Array:
        """The increment ``u`` with the odometry's estimated scales divided out."""
        if not self.config.odom_scale_adapt:
            return u
        st, sr = self.translation_scale, self.odom_scale.rotation
        return np.array([u[0] / st, u[1] / st, u[2] / sr])

    def move_particles(self, frame: Frame) -> None:
        """Move the particles by the whole motion since they were last moved, with the motion
        model's noise drawn once, as AMCL does at each filter update. Drawing it at every
        frame instead would make the cloud's spread grow with the scan rate, and with the
        jitter a 40 Hz odometry has from one frame to the next."""
        ps = self._require_particles()
        self._reported = np.zeros(3)
        if self._anchor is not None and self._anchor is not frame:
            if self.config.odom_scale_adapt:
                self._move_scaled(ps, self._anchor, frame)
            else:
                poses, u, _ = self.prediction(ps.poses, self._anchor, frame, self.rng)
                if u is not None:
                    ps.poses = poses
        self._anchor = frame

    def _move_scaled(self, ps: ParticleSet, prev: Frame, frame: Frame) -> None:
        """:class:`Prediction`'s move with the odometry's estimated scales divided out: the
        wheels' mean travel by the translation scale and their difference by the rotation
        scale, or the odometry increment's translation and turn. With per-particle scales
        each particle divides the translation by its own scale, which then drifts by
        :data:`SCALE_DRIFT` per square root of the metres reported."""
        pr = self.prediction
        u = pr.increment(prev, frame)
        if u is None:
            return
        self._reported = u
        own = self.per_particle_scale
        st: float | Array = self.odom_scale.translation * self.scales if own else self.odom_scale.translation
        sr = self.odom_scale.rotation
        travel = pr._wheel_travel(prev, frame)
        if travel is not None:
            dl, dr = travel
            if abs(dl) < WHEELS_STILL and abs(dr) < WHEELS_STILL:
                return
            mid, half = 0.5 * (dl + dr) / st, 0.5 * (dr - dl) / sr
            ps.poses = pr.wheels.apply(ps.poses, mid - half, mid + half, self.rng)
        elif own:
            # Each particle's extra travel (u's translation times 1 / scale - 1) in its own
            # frame, then the motion model's move by u at scale 1 (its noise sized by u).
            poses = ps.poses.copy()
            extra = 1.0 / st - 1.0
            c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
            poses[:, 0] += extra * (c * u[0] - s * u[1])
            poses[:, 1] += extra * (s * u[0] + c * u[1])
            turn = np.array([u[0], u[1], u[2] / sr])
            ps.poses = pr.odometry.apply(poses, turn, max(frame.t - prev.t, 0.0), self.rng)
        else:
            ps.poses = pr.odometry.apply(ps.poses, self._scaled(u), max(frame.t - prev.t, 0.0), self.rng)
        if own:
            b = max(self.config.odom_scale_bound, self.config.odom_scale_spread)
            step = SCALE_DRIFT * np.sqrt(float(np.hypot(u[0], u[1])))
            self._scales = np.clip(self.scales + step * self.rng.normal(size=len(ps)), 1.0 - b, 1.0 + b)

    def _learn_scale(self) -> None:
        """Count the motion since the last update in :attr:`odom_scale`, when the estimate
        was settled at both updates and moved by no more than 5 cm (0.1 rad) or half the
        motion off the odometry's (a jump between places is no correction of the scale)."""
        if not self.config.odom_scale_adapt:
            return
        prev, self._settled_pose = self._settled_pose, None
        settled = position_std(self.cov) < SETTLED_SPREAD
        was, self._was_settled = self._was_settled, settled
        if not settled:
            return
        own = self.per_particle_scale
        if own and (not was or self._jumped(prev)):
            # Just settled, or moved to another place: what was learnt was learnt elsewhere
            # (on a hypothesis now given up), and the few particles that survived the search
            # carry whichever factors they were drawn with. Start again from 1 with the
            # factors drawn afresh, so the scale is learnt here, from a cloud that spans it.
            self.odom_scale.restart(1.0)
            self._scales = self.random_scales(self.n)
            self._factor, self._factor_std = 1.0, self.config.odom_scale_spread / np.sqrt(3.0)
        self._settled_pose = self.pose.copy()
        self._count_motion(prev)
        if own:  # the learnt scale holds the mean from now on; the factors keep their spread
            self._scales = self.scales / self._factor
            self._factor_std /= self._factor
            self._factor = 1.0

    def _jumped(self, prev: Array | None) -> bool:
        """Whether the estimate moved from ``prev`` (the last settled estimate) more than
        :data:`SETTLED_SPREAD` off the odometry's motion: the cloud changed places."""
        if prev is None:
            return False
        d, want = relative(prev, self.pose), self._scaled(self._reported)
        return bool(np.hypot(d[0] - want[0], d[1] - want[1]) > SETTLED_SPREAD)

    def _count_motion(self, prev: Array | None) -> None:
        """Count the motion from the settled estimate ``prev`` to this one in
        :attr:`odom_scale` (see :meth:`_learn_scale`)."""
        u = self._reported
        if prev is None or not np.any(u):
            return
        d = relative(prev, self.pose)
        want = self._scaled(u)
        trans = float(np.hypot(u[0], u[1]))
        if np.hypot(d[0] - want[0], d[1] - want[1]) > max(0.05, 0.5 * trans):
            return
        if abs(wrap_angle(d[2] - want[2])) > max(0.1, 0.5 * abs(float(u[2]))):
            return
        self.odom_scale.add(u, d)

    def update(self, pts: Array, sensor_xy: Array | None = None, max_range: float = 30.0) -> None:
        """Weigh by the sensor model (likelihood field at the end points, or the beam model
        from the sensor position ``sensor_xy`` in the robot frame); track the average likelihood."""
        self._require_particles()
        assert self.particles is not None
        c = self.config
        if c.model == "beam":
            sxy = np.zeros(2) if sensor_xy is None else np.asarray(sensor_xy, float)
            g = self.grid
            ll = self.kernels.beam(
                np.ascontiguousarray(self.particles.poses),
                sxy,
                np.ascontiguousarray(pts, dtype=float),
                self._occ_u8,
                float(g.origin[0]),
                float(g.origin[1]),
                1.0 / g.resolution,
                float(max_range),
                c.sigma_hit,
                c.z_hit,
                c.z_short,
                c.lambda_short,
                c.z_rand,
            )
        else:
            ll = self.field(self.particles.poses, pts, self.kernels)
        self._last_pts = np.ascontiguousarray(pts, dtype=float)
        if c.recovery:
            self.recovery.add(self._fit(ll, pts))
        self.particles.log_weights = self.particles.log_weights + ll / c.beam_temperature
        self.particles.normalize()

    def _fit(self, ll: Array, pts: Array) -> float:
        """How well the best tenth of the particles explains the scan ``pts`` whose log
        likelihoods are ``ll`` (geometric-mean likelihood per beam), for the recovery. The
        best tenth, not all: freshly injected random particles would otherwise keep the
        average low and the injection going after a recovery. Measured with the configured
        width: a field narrowed by ``sigma_hit_adapt`` scores every end point off a wall
        lower, which the averages would read as a worse fit (w_fast falls before w_slow)
        and answer with particles at random places."""
        assert self.particles is not None
        top = max(1, len(ll) // 10)
        best = np.argpartition(ll, len(ll) - top)[-top:]
        ll_top = ll[best]
        if self.config.model != "beam" and self.field is not self._base_field:
            ll_top = self._base_field(self.particles.poses[best], pts, self.kernels)
        return float(np.mean(np.exp(ll_top / max(len(pts), 1))))

    def adapt_sigma(self) -> None:
        """Match the likelihood field's width to how far the last update's end points lie from
        the map's walls at a settled estimate (a step of :meth:`step`, after :meth:`estimate`):
        1.5 x the scale of their half-normal (their median / 0.6745), averaged over updates,
        between 0.5 and 1.5 x ``sigma_hit`` (from which it starts).
        A map drawn from exact poses, or Intel's Rao-Blackwellized map, leaves residuals of a
        few centimetres and narrows the kernel to about 0.11 m (at 0.2 m the estimate ran 4-5
        cm ahead of the map's own run); the Mines rover's blurred SLAM map keeps it near 0.12 m."""
        c = self.config
        if not c.sigma_hit_adapt or c.model != "likelihood_field" or self._last_pts is None:
            return
        if position_std(self.cov) >= SETTLED_SPREAD:
            return
        d = self.field.distances(self.pose, self._last_pts)
        if len(d) < 10:
            return
        # The scale of the distances' half-normal from their median (0.6745 of it), not
        # their spread within a few present widths: that gate narrows with the width, and
        # the fit with it, until a bent map's far walls no longer count at all.
        rms = float(np.median(d)) / 0.6745
        want = float(np.clip(1.5 * rms, 0.5 * c.sigma_hit, 1.5 * c.sigma_hit))
        self._sigma += 0.1 * (want - self._sigma)
        if abs(self._sigma - self.field.sigma_hit) > 0.1 * self.field.sigma_hit:
            self.field = self.field.with_sigma(self._sigma)

    @property
    def sigma_hit(self) -> float:
        """The likelihood field's width now (m; see ``sigma_hit_adapt``)."""
        return self.field.sigma_hit

    def estimate(self, radius: float = 1.0) -> tuple[Array, Array]:
        """Weighted mean (circular mean for theta) and covariance of the particles near one of
        the heaviest (within ``radius`` m and 45 deg): the neighbourhood of most weight, so a
        few scattered particles (just injected, or a second mode) neither drag the estimate
        between places nor take it over."""
        ps = self._require_particles()
        w = ps.weights
        p = ps.poses
        # The neighbourhood with the most weight among those of the 20 heaviest particles
        # (AMCL takes the cluster of most weight): one heavy particle alone, just injected
        # by the recovery at a look-alike place, does not carry the estimate away from the
        # hundreds that track the robot.
        top = np.argpartition(w, -20)[-20:] if len(w) > 20 else np.arange(len(w))
        centres = top[np.argsort(w[top])]
        masses = neighbourhood_masses(np.ascontiguousarray(p), np.ascontiguousarray(w), centres, radius, np.pi / 4)
        self._mass = float(masses.max()) / max(float(w.sum()), 1e-300)
        c = p[centres[int(np.argmax(masses))]]
        near = (np.hypot(p[:, 0] - c[0], p[:, 1] - c[1]) <= radius) & (np.abs(wrap_angle(p[:, 2] - c[2])) <= np.pi / 4)
        sub = ParticleSet(p[near], ps.log_weights[near])
        if self.per_particle_scale:
            ws, sc = sub.weights, self.scales[near]
            self._factor = float(np.sum(ws * sc))
            self._factor_std = float(np.sqrt(max(float(np.sum(ws * (sc - self._factor) ** 2)), 0.0)))
        return sub.mean_and_covariance()

    @property
    def lost(self) -> bool:
        """Whether the last update's health said lost: the only time the recovery injects
        particles. The likelihood's averages alone (AMCL's trigger) fall as well when the robot
        walks past walls the map lacks, or people hide the walls: on simulated office walks
        with 15 % of the map's walls moved or taken away their guesses carried the estimate to
        look-alike rooms, 2.1-6.5 m RMSE (0.006-0.008 m on the whole map); guesses only near
        the estimate (2 m, at most 5 % of the particles) still took 3 of 10 walks 1.5-2 m off."""
        return self.health is not None and self.health.state is State.LOST

    def check_health(self, sensor_xy: Array) -> Health:
        """The last update's scan against the map at the estimate (see
        :mod:`pfslam.filters.health`); kept in :attr:`health`."""
        f = self._base_field
        assert self._last_pts is not None and f.dist is not None
        explained, contradicted = scan_fit(
            f.dist,
            self._occ_u8,
            f.origin,
            f.resolution,
            self.pose,
            self._last_pts,
            sensor_xy,
            self.config.health_tolerance,
        )
        self.health = self.health_monitor(explained, contradicted, self.ambiguous)
        return self.health

    def resample(self) -> bool:
        """Resample when N_eff < resample_threshold * N; return whether it did.

        With ``kld`` on, ``max_particles`` candidates are drawn (``resample_method``) and
        shuffled, and the new set is the shortest prefix that meets Fox's KLD bound for the
        number of (x, y, theta) bins it occupies (at least ``min_particles``). With
        ``recovery`` on, Binomial(max_particles, max(0, 1 - w_fast / w_slow)) particles
        drawn uniformly over free space replace part of the set.
        """
        c = self.config
        ps = self._require_particles()
        if self._start is not None and (done := self._start.after_update(self)) is not None:
            return done
        if ps.n_eff() >= c.resample_threshold * len(ps):
            return False
        w = ps.weights
        own = self.per_particle_scale  # (else every particle's factor is 1: nothing to carry)
        if c.kld:
            idx = DRAWERS[c.resample_method](w, c.max_particles, self.rng)
            idx = idx[self.rng.permutation(len(idx))]
            cand = ps.poses[idx]
            n = self._kld_count(cand)
            new, idx = cand[:n], idx[:n]
        else:
            idx = DRAWERS[c.resample_method](w, len(ps), self.rng)
            new = ps.poses[idx]
        scales = self.scales[idx] if own else None
        if c.recovery:
            # Random particles over free space, as a fraction of the largest particle count,
            # so a lost filter gets enough guesses to find the robot again.
            k = int(self.rng.binomial(c.max_particles, min(self.recovery.p_random, 1.0))) if self.lost else 0
            if k:
                keep = max(min(len(new), c.max_particles - k), 1)
                new = np.concatenate([new[:keep], self.recovery_poses(k)])
                if scales is not None:
                    scales = np.concatenate([scales[:keep], self.random_scales(k)])
                self.injected += k
                self.recoveries += 1
        self.particles = ParticleSet(np.ascontiguousarray(new))
        if scales is not None:
            self._scales = np.ascontiguousarray(scales)
        return True

    def recovery_poses(self, k: int) -> Array:
        """``k`` poses for a lost filter: ``recovery_candidates`` x ``k`` poses drawn uniformly
        over free space, weighed by the last scan, and ``k`` of them drawn by weight (a
        mixture proposal that samples from the sensor model, as in Thrun et al.'s Mixture-MCL).
        Uniform guesses alone would almost never land near the robot: on a 600 m2 floor one
        in about 100,000 falls within 0.2 m and 5 deg of it."""
        m = k * self.config.recovery_candidates
        cand = self.random_free_poses(m)
        if self._last_pts is None or m == k:
            return cand
        ll = self.field(cand, self._last_pts, self.kernels) / self.config.beam_temperature
        w = np.exp(ll - ll.max())
        return cand[DRAWERS[self.config.resample_method](w / w.sum(), k, self.rng)]

    def _kld_count(self, cand: Array) -> int:
        """Walk the (shuffled) candidate poses ``cand``, counting the (x, y, theta) bins they
        occupy, until the KLD bound is met."""
        c = self.config
        bins = np.column_stack(
            [
                np.floor(cand[:, 0] / c.kld_bin_xy),
                np.floor(cand[:, 1] / c.kld_bin_xy),
                np.floor(wrap_angle(cand[:, 2]) / c.kld_bin_a),
            ]
        ).astype(np.int64)
        keys = (bins[:, 0] * 1_000_003 + bins[:, 1]) * 1_009 + bins[:, 2]
        _, first = np.unique(keys, return_index=True)
        is_first = np.zeros(len(keys), dtype=bool)
        is_first[first] = True
        k = np.cumsum(is_first)
        need = np.maximum(c.min_particles, kld_bounds(k, c.kld_err, c.kld_z))
        ok = np.nonzero(np.arange(1, len(keys) + 1) >= need)[0]
        n = int(ok[0]) + 1 if len(ok) else len(keys)
        return min(n, c.max_particles)

    def step(self, frame: Frame) -> Estimate:
        """Predict from the previous frame; after ``update_min_d`` m or ``update_min_a`` rad
        of motion since the last update (and at the first frame) weigh by the frame's scan
        (``beams`` end points evenly subsampled, readings outside ``laser_min_range`` ..
        ``laser_max_range`` dropped), estimate and resample. Between updates the
        estimate is dead-reckoned with the odometry. Needs an ``initialize_*`` call first."""
        if self.particles is None:
            raise RuntimeError("call initialize_around() or initialize_global() before step()")
        c = self.config
        self._increment = np.zeros(3)
        self.predict(frame)
        updated = resampled = False
        first = self.updates == 0
        if first or self._since_update.reached(c.update_min_d, c.update_min_a) or self._start_update(frame):
            seen = laser_window(frame, c)
            sp = scan_to_points(seen, ground_z=c.ground_z)
            if len(sp.hits):
                if first:
                    self._start_from_scan(sp.hits)
                self.move_particles(frame)
                self.update(subsample(sp.hits, c.beams), sp.sensor_xy, min(seen.max_range, model_range(c)))
                self.pose, self.cov = self.estimate()
                self.check_health(sp.sensor_xy)
                self._learn_scale()
                self.adapt_sigma()
                resampled = self.resample()
                updated = True
                self.updates += 1
                self._since_update.reset()
        if not updated:
            self.pose = compose(self.pose, self._increment)  # between updates: dead-reckon the estimate
        self._prev = frame
        self._estimates.add(frame.t, self.pose)
        return Estimate(
            t=frame.t,
            pose=self.pose.copy(),
            n_eff=self.particles.n_eff(),
            resampled=resampled,
            updated=updated,
            particles=self.n,
            covariance=self.cov.copy(),
            health=self.health,
        )
