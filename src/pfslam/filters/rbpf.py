"""The Rao-Blackwellized filter (GMapping's family): every particle carries its own map
(:class:`~pfslam.maps.tiled.TiledMaps`, shared copy-on-write after resampling), its pose is
proposed by matching the scan to its own map, and the answer is the best particle's whole
path. One ``step(frame)`` per scan, no I/O.

Between map updates the particles follow the odometry. An update comes when the robot has
moved or turned enough since the last one (``RbpfConfig.update_m`` / ``update_deg``): the
odometry increment since the last update, with noise in proportion to it, moves each
particle; each is matched against its own map (hill climbing in x, y, theta, then
``rbpf.refine`` Gauss-Newton steps on the smooth score of :mod:`pfslam.kernels.refine`,
which also gives the match's information) and moved there; its log-weight gains the
log-likelihood of the scan at that pose (the nearest occupied cell in a small neighbourhood
of each hit: no distance transform), and with ``rbpf.weight: normaliser`` the integral of
the match's Gaussian under the odometry's (:mod:`pfslam.filters.proposal`); the weights
are normalised; each particle integrates the scan into its own map; and when the
effective sample size falls below half, systematic resampling copies the maps' tile tables.

Each update records every particle's pose and its parent, so the trajectory is the final
best particle's path from the first scan (its loop-closed history), with the scans between
updates placed by the odometry.

An update's work is split over two scans, as a robot's real-time budget wants it: the scan
that triggers it is matched and weighed at once; its integration into the maps and the
resampling are done at the start of the next scan (or when the map or the trajectory is
asked for). No map is read in between, so the answer is the same as doing it all at once.
"""

from __future__ import annotations

import bisect
import functools
import time

import numpy as np
from numpy.typing import NDArray

from pfslam.config import SlamConfig, SlamFilter, for_filter
from pfslam.config.choices import ParticleWeight
from pfslam.filters import proposal
from pfslam.filters.drift import DriftFit
from pfslam.filters.health import Health, HealthMonitor
from pfslam.filters.predict import slam_prediction, start_pose
from pfslam.filters.reacquire import NOTHING_NEAR, bend, reacquire, window
from pfslam.frames import Estimate, Frame
from pfslam.geometry import compose, inverse, relative, transform_points, wrap_angle
from pfslam.maps.grid import OccupancyGrid
from pfslam.maps.tiled import TiledMaps
from pfslam.particles import DRAWERS, ParticleSet
from pfslam.sensor import ScanPoints, beam_ends, open_beams, scan_to_points, subsample
from pfslam.types import Array, JSONObject

HEALTH_BEAMS = 360  # beams a scan's health is judged on at most (evenly subsampled)
HEALTH_WALL = 2.0  # a cell is a wall no beam passes from this many hits' log-odds (x map.l_occ)
HEALTH_MIN_JUDGED = 20  # an update's health counts if its map judges this many beams ...
HEALTH_MIN_SHARE = 0.2  # ... and this share of them (on new ground the health holds)
BLIND_HITS = 20  # a scan with fewer hits within map_range than this pins the pose no better than odometry
REACQUIRE_TRIES = 12  # searches after a blind stretch before the filter goes on from where the odometry puts it ...
SEEK_STEP_M = 2.0  # ... one per this much travel, the first at once
HEALTH_WINDOW = 5  # updates whose median quality sets the state (a person or a door passing spans two)


KERNEL_PARTS = 2  # load_kernels' parts, about alike to compile: the refinement's, the rest


@functools.cache
def load_kernels(part: int | None = None) -> None:
    """Run every kernel of an update once on a tiny input: Numba loads them (about 0.15 s,
    once per process) here rather than in the first scan that updates. ``part`` (0 to
    KERNEL_PARTS - 1): only those of that part (a first run compiles the parts side by side,
    see pfslam.pipeline.warm); None: all."""
    maps = TiledMaps(1, capacity=4)
    maps.update_all(np.zeros((1, 3)), np.zeros(2), np.array([[0.5, 0.0]]), np.array([True]))
    poses, pts = np.zeros((1, 3)), np.array([[0.5, 0.0]])
    if part in (None, 0):
        maps.refine(poses.copy(), pts, 0.05, 1, poses, 0.0, 0.01, 0.01, 0.05, 0.05)
    if part in (None, 1):
        maps.match(poses, pts, 0.05, 1, 0.05, float(np.deg2rad(3.0)), 1, 0.0, 0.01, 0.01)
        maps.loglik(poses, pts, 0.075, 1, 0.05)
        maps.update(0, np.zeros(2), pts, np.array([True]))
        maps.fit(0, np.zeros(3), np.zeros(2), pts, np.array([True]), 0.1, 6.0)
        # the resampling kernels (a throwaway generator: the filter's draws are unchanged)
        for draw in DRAWERS.values():
            draw(np.ones(1), 1, np.random.default_rng(0))


class RaoBlackwellizedSlam:
    """The Rao-Blackwellized particle filter (see the module notes)."""

    def __init__(
        self, config: SlamConfig | None = None, start: Array | None = None, prior: OccupancyGrid | None = None
    ) -> None:
        """``start``: the first scan's pose (default: the odometry's, see
        :func:`~pfslam.filters.predict.start_pose`); ``prior``: a map to continue (every
        particle's map starts as it; same resolution)."""
        load_kernels()
        # Settings a caller left open (particles 0, match_prior -1) take their value for an
        # unknown log kind, as resolve_filter gives them.
        self.config = for_filter(config, SlamFilter.RBPF)
        n = self.config.particles
        m = self.config.map
        self.rng = np.random.default_rng(self.config.seed)
        self.maps = TiledMaps(n, resolution=m.resolution, l_occ=m.l_occ, l_free=m.l_free, l_clamp=m.l_clamp)
        if prior is not None:
            self.maps.seed(prior.logodds, prior.origin)
        self._start = None if start is None else np.asarray(start, dtype=float).copy()
        self.poses = np.zeros((n, 3))
        self.log_w = np.full(n, -np.log(n))
        self.fitness = np.zeros(n)  # accumulated log-likelihood along each path
        self._odom_pose = np.zeros(3)
        self._prev_frame: Frame | None = None  # the last frame with odometry or wheel travel
        self._prediction = slam_prediction(self.config)  # for its noise-free increments
        self._since = np.zeros(3)  # odometry increment since the last update
        self._started = False
        # History: per update the particles' poses and parents; per scan its update and
        # the odometry since that update.
        self._node_poses: list[Array] = []
        self._node_parents: list[NDArray[np.int32]] = []
        self._parents = np.arange(n, dtype=np.int32)
        self._scan_t: list[float] = []
        self._scan_update: list[int] = []
        self._scan_rel: list[Array] = []
        self.updates = 0
        self.resamples = 0
        # Seconds spent in each part of the updates (for bench/): prediction, matching,
        # weighing, the health check, map update, resampling.
        self.timings = dict.fromkeys(("prediction", "matching", "weighing", "health", "map_update", "resampling"), 0.0)
        # An update's second half, done at the next scan: the scan to integrate (its beams'
        # ends and which end on a wall, from _beams; the sensor's position) and the
        # normalised weights to resample from.
        self._pending: tuple[Array, NDArray[np.bool_], Array, ParticleSet] | None = None
        # How well each update's scan fits the best particle's map (see pfslam.filters.health)
        self.health_monitor = HealthMonitor(
            self.config.rbpf.health_degraded, self.config.rbpf.health_lost, HEALTH_WINDOW
        )
        self.health: Health | None = None
        # Blind stretches: travel (odometry, m) at updates whose scan held fewer than BLIND_HITS
        # hits within map_range, where the path is the odometry's guess
        self.blind_m = 0.0
        self._sighted = np.zeros(3)  # the odometry's pose at the last scan that came to update
        self._blind = False  # whether that scan was blind
        self._stretch: list[float] = []  # the current blind stretch: first t, last t, metres
        self.longest_blind: tuple[float, float, float] = (0.0, 0.0, 0.0)  # metres, from t, to t
        # Travel (m) following the odometry since the last update that matched (blind updates, and
        # those searched for after them in vain), the searches left, and each search's answer
        self._adrift_m = 0.0
        self._last_m = 0.0  # the odometry's travel to the last scan that came to update
        self._tries = 0
        self._seek_m = np.inf  # travel since the last search (inf: the next update searches)
        self._anchor = 0  # the last update that matched
        # The odometry's errors, fitted from the matched updates (the best particle's motion
        # from the last one), taken out where the particles follow the odometry
        self.drift = DriftFit()
        self._last_best: Array | None = None
        self.reacquired: list[JSONObject] = []

    # -- the Filter interface ---------------------------------------------------------

    @property
    def odom_pose(self) -> Array:
        return self._odom_pose

    @property
    def particles(self) -> ParticleSet:
        """The particles now (a copy): their poses at the last update moved by the odometry
        since, and their log-weights."""
        return ParticleSet(compose(self.poses, self._since), self.log_w)

    @property
    def best_index(self) -> int:
        return int(np.argmax(self.fitness))

    @property
    def map(self) -> OccupancyGrid:
        """The best particle's map."""
        self.settle()
        m = self.config.map
        return OccupancyGrid.from_logodds(
            self.maps.dense(self.best_index), self.maps.resolution, self.maps.origin, m.l_occ, m.l_free, m.l_clamp
        )

    def diagnostics(self) -> JSONObject:
        """What its maps cost and where its time went."""
        return {
            "map_updates": int(self.updates),
            "unique_tiles": int(self.maps.unique_tiles),
            "tile_memory_mb": self.maps.nbytes / 2**20,
            "tiles_released_mb": self.maps.released_mb,
            "seconds_by_part": dict(self.timings),
            "blind_m": self.blind_m,
            "reacquired": list(self.reacquired),
            "odometry_fit": self.drift.as_dict(),
            "longest_blind": {
                "metres": self.longest_blind[0],
                "from_t": self.longest_blind[1],
                "to_t": self.longest_blind[2],
            },
        }

    def trajectory(self) -> tuple[Array, Array]:
        """The final best particle's path, every scan (see the module notes)."""
        self.settle()
        n_up = len(self._node_poses)
        path = np.zeros((n_up, 3))
        # (the best particle now, traced back through a resampling since the last update's record)
        b = int(self._parents[self.best_index])
        for u in range(n_up - 1, -1, -1):
            path[u] = self._node_poses[u][b]
            b = int(self._node_parents[u][b])
        t = np.array(self._scan_t)
        poses = np.empty((len(t), 3))
        for j, (u, rel) in enumerate(zip(self._scan_update, self._scan_rel)):
            poses[j] = compose(path[u], rel)
        return t, poses

    # -- the step ---------------------------------------------------------------------

    def _noise_sigmas(self, u: Array) -> tuple[float, float]:
        """The motion noise's standard deviations (x/y m, theta rad) for an increment ``u``."""
        c = self.config.rbpf
        d = float(np.hypot(u[0], u[1]))
        a = abs(float(wrap_angle(u[2])))
        return c.noise_xy_per_m * d + c.noise_xy_per_rad * a, c.noise_theta_per_rad * a + c.noise_theta_per_m * d

    def _noisy(self, u: Array, sxy: float, sth: float) -> Array:
        """Each particle's odometry increment ``u`` with noise of these standard deviations."""
        n = len(self.poses)
        noise = self.rng.normal(size=(n, 3)) * np.array([sxy, sxy, sth])
        return u + noise

    def _integrate(self, ends_r: Array, hit: NDArray[np.bool_], sensor: Array, only: int | None = None) -> None:
        """Ray-update every particle's map with a scan's beams (:meth:`_beams`) at its pose
        (``only``: that particle's)."""
        if only is None:
            self.maps.update_all(self.poses, sensor, ends_r, hit)
        else:
            p = self.poses[only]
            self.maps.update(only, transform_points(p, sensor[None, :])[0], transform_points(p, ends_r), hit)

    def settle(self) -> bool:
        """Finish the last update (see the module notes): integrate its scan into every
        particle's map, then resample if the effective sample size fell below the threshold.
        Returns whether it resampled."""
        if self._pending is None:
            return False
        ends, hit, sensor, weights = self._pending
        self._pending = None
        clock = time.perf_counter()
        self._integrate(ends, hit, sensor)
        clock = self._tick("map_update", clock)
        if weights.n_eff() >= self.config.resample_threshold * len(self.poses):
            return False
        idx = weights.resample(self.rng, self.config.resample_method)
        self.maps.resample(idx)
        self.poses, self.log_w = weights.poses, weights.log_weights
        self.fitness = self.fitness[idx]
        self._parents = idx.astype(np.int32)
        self.resamples += 1
        self._tick("resampling", clock)
        return True

    def step(self, frame: Frame) -> Estimate:
        c = self.config.rbpf
        resampled = self.settle()
        # The motion since the last frame with odometry: the odometry increment, or on wheel
        # logs the arc of the wheels' travel.
        u = None if self._prev_frame is None else self._prediction.increment(self._prev_frame, frame)
        if u is not None:
            self._since = compose(self._since, u)
            self._odom_pose = compose(self._odom_pose, u)
        if frame.odom is not None or frame.wheels is not None:
            self._prev_frame = frame
        updated = False
        n_eff = float(len(self.poses))
        if not self._started:
            start = start_pose(frame) if self._start is None else self._start
            self.poses[:] = start
            self._odom_pose = start.copy()
            self._sighted = start.copy()
            self._started = True
            self._record_update()
            # Every particle starts at the same pose with the same first scan: one map, shared.
            sp = self._points(frame)
            self._integrate(*self._beams(frame, sp), sp.sensor_xy, only=0)
            self.maps.resample(np.zeros(len(self.poses), dtype=np.intp))
            self._since = np.zeros(3)
            updated = True
        elif (
            np.hypot(self._since[0], self._since[1]) >= c.update_m
            or abs(wrap_angle(self._since[2])) >= np.deg2rad(c.update_deg)
        ) and self._note_sight(frame.t, sp := self._points(frame)):
            if c.blind_follow and self._blind:
                # nothing to match: every particle follows the odometry, none gains weight
                return self._follow(frame, sp, resampled, n_eff, True)
            if c.reacquire_m > 0 and self._adrift_m >= c.reacquire_m and self._tries > 0:
                # Searched for every SEEK_STEP_M while the tries last (the robot may come out of the
                # open far from where it went in); meanwhile following the odometry, not mapped: a
                # wall drawn from where the robot is not would be found at the next search.
                self._adrift_m += self._last_m
                self._seek_m += self._last_m
                if self._seek_m < SEEK_STEP_M:
                    return self._follow(frame, sp, resampled, n_eff, False)
                self._seek_m = 0.0
                if not self._reacquire(frame.t, sp):
                    # (with no wall mapped within the window's reach, nothing could be found further on)
                    self._tries = 0 if self.reacquired[-1]["why"] == NOTHING_NEAR else self._tries - 1
                    self.reacquired[-1]["gave_up"] = self._tries == 0
                    return self._follow(frame, sp, resampled, n_eff, False)
            self._adrift_m = 0.0
            pts = np.ascontiguousarray(subsample(sp.hits, c.match_hits))
            u = self._since
            ll, gain = self._update(pts, self._through(frame, sp, pts) if c.see_through else None)
            clock = time.perf_counter()
            self.fitness += ll
            best = self.poses[self.best_index].copy()
            if self._last_best is not None:
                self.drift.add(u, relative(self._last_best, best))
            self._last_best = best
            weights = ParticleSet(self.poses, self.log_w + gain)
            weights.normalize()
            self.log_w = weights.log_weights
            n_eff = weights.n_eff()
            self._since = np.zeros(3)
            self._record_update()
            self._anchor = len(self._node_poses) - 1
            clock = self._tick("weighing", clock)
            ends, hit = self._beams(frame, sp)
            self._check_health(sp, ends, hit)
            self._tick("health", clock)
            self._pending = (ends, hit, sp.sensor_xy, weights)
            updated = True
        return self._estimate(frame, resampled, updated, n_eff)

    def _follow(self, frame: Frame, sp: ScanPoints, resampled: bool, n_eff: float, mapped: bool) -> Estimate:
        """An update where every particle follows the odometry and none gains weight; its scan
        goes into the maps if ``mapped``. With ``rbpf.undo_drift``, the odometry's fitted errors
        are taken out of its increment (:mod:`pfslam.filters.drift`)."""
        u = self.drift.undo(self._since) if self.config.rbpf.undo_drift else self._since
        self.poses = compose(self.poses, u)
        self._last_best = None
        self._since = np.zeros(3)
        self._record_update()
        if mapped:
            self._pending = (*self._beams(frame, sp), sp.sensor_xy, ParticleSet(self.poses, self.log_w))
        return self._estimate(frame, resampled, True, n_eff)

    def _reacquire(self, t: float, sp: ScanPoints) -> bool:
        """Search for the scan ``sp`` in the best particle's map after a blind stretch
        (:mod:`pfslam.filters.reacquire`); where found, move every particle rigidly so the best
        one is there (the update then matches from there with no motion). Returns whether found."""
        c = self.config.rbpf
        clock = time.perf_counter()
        b = self.best_index
        guess = compose(self.poses[b], self._since)
        win_m, win_deg = window(self._adrift_m, c.reacquire_deg_per_m, c.reacquire_max_m, c.reacquire_max_deg)
        got = reacquire(self.maps, b, guess, sp.hits, win_m, win_deg)
        record: JSONObject = {
            "t": t,
            "adrift_m": self._adrift_m,
            "window_m": win_m,
            "window_deg": win_deg,
            "found": got.pose is not None,
            "score": got.score,
            "why": got.why,
        }
        if got.pose is not None:
            self._bend_history(b, guess, got.pose)
            # the rigid motion taking the best particle's guess to the match, for every particle
            fix = compose(got.pose, inverse(guess))
            self.poses = compose(fix, compose(self.poses, self._since))
            self._since = np.zeros(3)
            d = relative(guess, got.pose)
            record["moved_m"] = float(np.hypot(d[0], d[1]))
            record["turned_deg"] = float(np.rad2deg(d[2]))
            self._tries = 0
        record["seconds"] = time.perf_counter() - clock
        self.reacquired.append(record)
        return got.pose is not None

    def _bend_history(self, b: int, guess: Array, end: Array) -> None:
        """Bend the path recorded since the last update that matched so that particle ``b``'s,
        which reaches ``guess`` now, ends at ``end`` (:func:`~pfslam.filters.reacquire.bend`):
        every scan since placed where the bent path puts it, each update's poses moved by the
        motion that takes ``b``'s ancestor there (every particle alike)."""
        first = self._anchor
        who = [int(self._parents[b])]  # (b at the last update: a resampling since may have renumbered it)
        for u in range(len(self._node_poses) - 1, first, -1):  # its ancestors, newest first
            who.append(int(self._node_parents[u][who[-1]]))
        at = dict(zip(range(first, len(self._node_poses)), who[::-1]))  # update: b's ancestor there
        scans = range(bisect.bisect_left(self._scan_update, first), len(self._scan_t))  # (updates never go back)
        node = {u: self._node_poses[u][w] for u, w in at.items()}
        path = [node[first]] + [compose(node[self._scan_update[j]], self._scan_rel[j]) for j in scans] + [guess]
        bent = bend(np.array(path), end)[1:-1]
        moved = {first: node[first]}  # each update's pose of b's ancestor, bent
        for j, q in zip(scans, bent):
            u = self._scan_update[j]
            if u not in moved:  # the update's first scan places it
                moved[u] = compose(q, inverse(self._scan_rel[j]))
                fix = compose(moved[u], inverse(node[u]))
                self._node_poses[u] = compose(fix, self._node_poses[u])
            self._scan_rel[j] = relative(moved[u], q)

    def _estimate(self, frame: Frame, resampled: bool, updated: bool, n_eff: float) -> Estimate:
        """Record the scan (its update and the odometry since) and give the estimate."""
        self._scan_t.append(frame.t)
        self._scan_update.append(len(self._node_poses) - 1)
        self._scan_rel.append(self._since.copy())
        b = self.best_index
        pose = compose(self.poses[b], self._since)
        return Estimate(
            t=frame.t,
            pose=pose,
            n_eff=n_eff,
            resampled=resampled,
            updated=updated,
            particles=len(self.poses),
            health=self.health,
        )

    def _note_sight(self, t: float, sp: ScanPoints) -> bool:
        """Count the odometry's travel since the last scan that came to update as blind if this
        scan holds fewer than :data:`BLIND_HITS` hits the map can hold (within ``map_range``).
        Returns whether the scan updates: one with a hit, or with ``rbpf.blind_follow`` any (its
        particles follow the odometry, which a scan without a hit must not leave unrecorded)."""
        d = self._last_m = float(np.hypot(*(self._odom_pose[:2] - self._sighted[:2])))
        self._sighted = self._odom_pose.copy()
        reach = np.hypot(sp.hits[:, 0] - sp.sensor_xy[0], sp.hits[:, 1] - sp.sensor_xy[1])
        self._blind = int(np.count_nonzero(reach <= self.config.rbpf.map_range)) < BLIND_HITS
        if not self._blind:
            self._stretch = []
            return True
        self.blind_m += d
        if self.config.rbpf.blind_follow:  # (the particles follow the odometry: adrift)
            self._adrift_m += d
            self._tries = REACQUIRE_TRIES
            self._seek_m = np.inf
        if not self._stretch:
            self._stretch = [t, t, 0.0]
        self._stretch[1] = t
        self._stretch[2] += d
        if self._stretch[2] > self.longest_blind[0]:
            self.longest_blind = (self._stretch[2], self._stretch[0], self._stretch[1])
        return len(sp.hits) > 0 or self.config.rbpf.blind_follow

    def _beams(self, frame: Frame, sp: ScanPoints) -> tuple[Array, NDArray[np.bool_]]:
        """The scan's beams as the maps take them (robot frame; :func:`~pfslam.sensor.beam_ends`):
        its hits (walls where within ``map_range``), then its floor hits and its beams that
        returned nothing out to ``rbpf.no_return_m`` (at most ``map_range``;
        :func:`~pfslam.sensor.open_beams`), which clear free space; and which end on a wall."""
        c = self.config.rbpf
        reach = min(c.no_return_m, c.map_range)
        open_ = open_beams(frame, reach) if reach > 0 else np.zeros((0, 2))
        free = np.vstack([sp.floor, open_]) if len(open_) else sp.floor
        return beam_ends(sp.hits, free, sp.sensor_xy, c.map_range)

    def _check_health(self, sp: ScanPoints, ends: Array, hit: NDArray[np.bool_]) -> None:
        """How the best particle's map, before this scan goes in, judges the scan at its
        match (:meth:`~pfslam.maps.tiled.TiledMaps.fit`): its beams ``ends``/``hit`` as
        :meth:`_beams` gives them but the floor hits (they say nothing of walls); the health
        follows it where the map judges enough beams (on new ground it holds)."""
        c = self.config.rbpf
        n, f = len(sp.hits), len(sp.floor)
        ends, hit = np.concatenate([ends[:n], ends[n + f :]]), np.concatenate([hit[:n], hit[n + f :]])
        if len(ends) > HEALTH_BEAMS:
            k = np.linspace(0, len(ends) - 1, HEALTH_BEAMS).round().astype(np.intp)
            ends, hit = ends[k], hit[k]
        b = self.best_index
        wall = HEALTH_WALL * self.config.map.l_occ
        judged, explained, contradicted = self.maps.fit(
            b, self.poses[b], sp.sensor_xy, ends, hit, c.health_tolerance, wall
        )
        if judged >= max(HEALTH_MIN_JUDGED, HEALTH_MIN_SHARE * len(ends)):
            self.health = self.health_monitor(explained / judged, contradicted / judged, False)

    def _through(self, frame: Frame, sp: ScanPoints, pts: Array) -> tuple[Array, Array]:
        """The beams ``rbpf.see_through`` judges (robot frame): the matched hits ``pts`` and the
        beams that returned nothing out to ``rbpf.no_return_m`` (at most ``map_range``); and the
        sensor's position."""
        c = self.config.rbpf
        reach = min(c.no_return_m, c.map_range)
        open_ = open_beams(frame, reach) if reach > 0 else np.zeros((0, 2))
        return np.vstack([pts, open_]), sp.sensor_xy

    def _update(self, pts: Array, through: tuple[Array, Array] | None) -> tuple[Array, Array]:
        """Move and match every particle for a scan's hits ``pts`` (see the module notes);
        ``through``: the beams (:meth:`_through`) whose paths through a particle's map count
        against it (``rbpf.see_through``). Returns the log-likelihoods at the matches and the
        log-weights' gains."""
        c = self.config.rbpf
        clock = time.perf_counter()
        predicted = compose(self.poses, self._since)
        sxy, sth = self._noise_sigmas(self._since)
        self.poses = compose(self.poses, self._noisy(self._since, sxy, sth))
        clock = self._tick("prediction", clock)
        n = len(self.poses)
        if not self.maps.tables.shape[1]:
            return np.zeros(n), np.zeros(n)
        prior_xy, prior_th = max(sxy, 0.01), max(sth, float(np.deg2rad(0.5)))
        start = self.poses.copy()
        self.maps.match(
            self.poses,
            pts,
            c.sigma,
            c.radius,
            c.lstep,
            np.deg2rad(c.astep_deg),
            c.refinements,
            c.match_prior * c.temperature,
            prior_xy,
            prior_th,
        )
        normaliser = c.weight is ParticleWeight.NORMALISER
        if c.refine or normaliser:
            _, info = self.maps.refine(
                self.poses,
                pts,
                c.sigma,
                c.refine,
                start,
                c.match_prior * c.temperature,
                prior_xy,
                prior_th,
                c.lstep,
                float(np.deg2rad(c.astep_deg)),
            )
        clock = self._tick("matching", clock)
        ll = self.maps.loglik(self.poses, pts, c.lsigma, c.radius, c.floor)
        if through is not None:
            # a beam through a wall the particle's map is sure of: as a hit with no wall near
            wall = HEALTH_WALL * self.config.map.l_occ
            seen = self.maps.seen_through(self.poses, through[1], through[0], c.health_tolerance, wall)
            ll = ll + seen * np.log(c.floor)
        gain = ll / c.temperature
        if normaliser:
            # the match's information read as the weights read its likelihood: each hit's
            # Gaussian of width lsigma, tempered
            tempered = info / (c.lsigma**2 * c.temperature)
            gain = gain + proposal.normaliser(self.poses, predicted, tempered, (prior_xy, prior_th))
        self._tick("weighing", clock)
        return ll, gain

    def _points(self, frame: Frame) -> ScanPoints:
        """The scan's hits and floor points in the robot frame (only a scan that updates
        needs them: between updates a scan costs its odometry alone)."""
        return scan_to_points(frame, ground_z=self.config.sensor.ground_z)

    def _tick(self, part: str, since: float) -> float:
        now = time.perf_counter()
        self.timings[part] += now - since
        return now

    def _record_update(self) -> None:
        self._node_poses.append(self.poses.copy())
        self._node_parents.append(self._parents.copy())
        self._parents = np.arange(len(self.poses), dtype=np.int32)
        self.updates += 1
