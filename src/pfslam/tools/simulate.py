"""A THOR humanoid simulator: synthetic THOR-format logs with ground truth.

The robot walks a built-in path through a 2D world of vertical walls. A head-mounted
Hokuyo (1081 beams over 270 deg) is ray cast in 3D against the walls and the floor,
through the same mount chain the loader uses (body roll/pitch, neck yaw, head pitch),
so pitched-down beams hit the floor. The odometry is the truth corrupted by a seeded
scale error, a heading bias and white noise.

Outputs (see :func:`simulate`): ``train_lidar0.mat``, ``train_joint0.mat``,
``groundtruth.tum`` (start-relative: the first pose is (0, 0, 0), the frame the SLAM
map starts in) and ``groundtruth_world.tum`` (world frame).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pfslam.config import check_int, check_number
from pfslam.errors import ConfigError
from pfslam.geometry import relative, wrap_angle
from pfslam.tools.raycast import MAX_RANGE, _raycast_scans
from pfslam.tools.worlds import World, world_named
from pfslam.types import Array

if TYPE_CHECKING:
    from pfslam.maps.grid import OccupancyGrid


WALK_SPEED = 0.5  # m/s
ARC_RADIUS = 0.8  # m, corner fillet radius
MAX_ARC_TURN = np.deg2rad(100.0)  # sharper corners are turned in place
TURN_RATE = 0.6  # rad/s, peak yaw rate of a turn in place
GAIT_PERIOD = 1.6  # s
SWAY_AMPLITUDE = 0.03  # m, lateral gait sway
WOBBLE_AMPLITUDE = 0.01  # rad, heading wobble at the gait period
HEADING_BIAS_PER_M = np.deg2rad(0.1)  # rad per metre walked (sign random)
TURN_SCALE_ERROR = 0.02  # relative yaw-rate error, same sign as the heading bias


@dataclass(frozen=True)
class Gait:
    """How the humanoid walks, turns and moves its head (see :data:`GAITS`).

    Attributes:
        sway: lateral gait sway amplitude (m).
        wobble: heading wobble at the gait period (rad).
        roll_deg, pitch_deg: body roll / pitch amplitude while walking (deg).
        arc_radius: corner fillet radius (m); corners sharper than ``max_arc_turn`` (rad)
            are turned in place at a peak yaw rate of ``turn_rate`` (rad/s).
        head_floor_deg: head pitch (deg, down) the head swings to during every corner, so
            the lidar sees mostly floor while the robot turns; None: no such dip.
        head_pitch_deg, head_pitch_period: the head nods slowly between these pitches
            (deg, down) with this period (s).
        heading_bias_deg_per_m: the odometry's default heading bias (deg per metre walked).
    """

    sway: float = SWAY_AMPLITUDE
    wobble: float = WOBBLE_AMPLITUDE
    roll_deg: float = 1.5
    pitch_deg: float = 1.0
    arc_radius: float = ARC_RADIUS
    max_arc_turn: float = MAX_ARC_TURN
    turn_rate: float = TURN_RATE
    head_floor_deg: float | None = None
    head_pitch_deg: tuple[float, float] = (2.0, 18.0)
    head_pitch_period: float = 37.0
    heading_bias_deg_per_m: float = float(np.rad2deg(HEADING_BIAS_PER_M))


#: ``calm``: the demo's walk. ``rough``: a humanoid as real ones walk a corridor loop:
#: 6 cm sway, 3 deg roll, corners turned in place at 1.2 rad/s peak while the head pitches
#: down to 40 deg (mostly floor in view), the head nodding between 10 and 45 deg down
#: every 20 s, and odometry drifting 0.8 deg per metre.
GAITS: dict[str, Gait] = {
    "calm": Gait(),
    "rough": Gait(
        sway=0.06,
        wobble=0.025,
        roll_deg=3.0,
        pitch_deg=2.0,
        arc_radius=0.4,
        max_arc_turn=0.0,
        turn_rate=1.2,
        head_floor_deg=40.0,
        head_pitch_deg=(10.0, 45.0),
        head_pitch_period=20.0,
        heading_bias_deg_per_m=0.8,
    ),
}


# --- path -----------------------------------------------------------------------------


@dataclass
class _Prim:
    kind: str  # "pause", "line", "arc", "turn"
    t0: float
    dur: float
    p0: Array  # start position (2,)
    h0: float  # start heading
    dh: float = 0.0  # total heading change (arc, turn)
    center: Array | None = None  # arc centre
    radius: float = 0.0
    speed: float = WALK_SPEED  # m/s along lines and arcs


def _build_path(
    world: World, duration: float, rng: np.random.Generator, gait: Gait = GAITS["calm"], speed: float = WALK_SPEED
) -> list[_Prim]:
    """Primitives (pauses, straight walks, corner arcs, turns in place) covering ``duration``,
    walked at ``speed`` (m/s)."""
    wp = np.asarray(world.waypoints, dtype=float)
    p = len(wp)
    seg_dir = np.array([wp[(i + 1) % p] - wp[i] for i in range(p)])
    seg_len = np.linalg.norm(seg_dir, axis=1)
    seg_h = np.arctan2(seg_dir[:, 1], seg_dir[:, 0])
    # Corner i sits at waypoint i, between segment i-1 and segment i.
    turn = np.array([float(wrap_angle(seg_h[i] - seg_h[i - 1])) for i in range(p)])
    turn[np.abs(np.abs(turn) - np.pi) < 1e-6] = np.pi  # about-turns always to the left
    # (an about-turn is always made in place: as an arc it would start infinitely far back)
    arcs = (np.abs(turn) > 1e-9) & (np.abs(turn) <= gait.max_arc_turn) & (np.abs(turn) < np.pi - 1e-6)
    arc_len = np.where(arcs, gait.arc_radius * np.tan(np.where(arcs, np.abs(turn), 0.0) / 2.0), 0.0)
    prims: list[_Prim] = []
    t = 0.0
    pos = wp[0].copy()
    h = float(seg_h[0])
    first = float(rng.uniform(4.5, 5.5))
    prims.append(_Prim("pause", t, first, pos.copy(), h))
    t += first
    i = 0
    first_leg = True
    while t < duration + 1.0:
        # Straight walk along segment i, stopping short of the next corner's arc.
        start = wp[i] + (0.0 if first_leg else arc_len[i]) * seg_dir[i] / seg_len[i]
        nxt = (i + 1) % p
        end = wp[nxt] - arc_len[nxt] * seg_dir[i] / seg_len[i]
        first_leg = False
        length = float(np.linalg.norm(end - start))
        if length > 1e-9:
            # Now and then stop part-way for a moment.
            if length > 6.0 and rng.random() < 0.25:
                f = float(rng.uniform(0.3, 0.7))
                mid = start + f * (end - start)
                prims.append(_Prim("line", t, f * length / speed, start.copy(), float(seg_h[i]), speed=speed))
                t += f * length / speed
                d = float(rng.uniform(2.0, 5.0))
                prims.append(_Prim("pause", t, d, mid.copy(), float(seg_h[i])))
                t += d
                start, length = mid, (1.0 - f) * length
            prims.append(_Prim("line", t, length / speed, start.copy(), float(seg_h[i]), speed=speed))
            t += length / speed
        pos = end
        h = float(seg_h[i])
        dth = float(turn[nxt])
        if arc_len[nxt] > 0.0:
            sgn = 1.0 if dth > 0 else -1.0
            center = pos + gait.arc_radius * np.array([-np.sin(h), np.cos(h)]) * sgn
            dur = gait.arc_radius * abs(dth) / speed
            prims.append(_Prim("arc", t, dur, pos.copy(), h, dth, center, gait.arc_radius, speed))
            t += dur
        elif abs(dth) > 1e-9:
            dur = abs(dth) * np.pi / (2.0 * gait.turn_rate)
            prims.append(_Prim("turn", t, dur, pos.copy(), h, dth))
            t += dur
        if rng.random() < 0.3:
            d = float(rng.uniform(2.0, 5.0))
            end_pos = wp[nxt] + arc_len[nxt] * seg_dir[nxt] / seg_len[nxt]
            prims.append(_Prim("pause", t, d, end_pos.copy(), float(seg_h[nxt])))
            t += d
        i = nxt
    return prims


def _eval_path(prims: list[_Prim], tau: Array) -> tuple[Array, Array]:
    """Nominal poses (N, 3) at times ``tau`` (s since start) and the moving flag (N,)."""
    starts = np.array([q.t0 for q in prims])
    idx = np.clip(np.searchsorted(starts, tau, side="right") - 1, 0, len(prims) - 1)
    out = np.empty((len(tau), 3))
    moving = np.zeros(len(tau), dtype=bool)
    for k, q in enumerate(prims):
        sel = idx == k
        if not np.any(sel):
            continue
        s = np.clip(tau[sel] - q.t0, 0.0, q.dur)
        if q.kind == "pause":
            out[sel, 0], out[sel, 1], out[sel, 2] = q.p0[0], q.p0[1], q.h0
        elif q.kind == "line":
            out[sel, 0] = q.p0[0] + q.speed * s * np.cos(q.h0)
            out[sel, 1] = q.p0[1] + q.speed * s * np.sin(q.h0)
            out[sel, 2] = q.h0
        elif q.kind == "arc":
            assert q.center is not None
            frac = s / q.dur
            phi0 = np.arctan2(q.p0[1] - q.center[1], q.p0[0] - q.center[0])
            phi = phi0 + q.dh * frac
            out[sel, 0] = q.center[0] + q.radius * np.cos(phi)
            out[sel, 1] = q.center[1] + q.radius * np.sin(phi)
            out[sel, 2] = q.h0 + q.dh * frac
        else:  # turn in place, smooth yaw-rate profile
            out[sel, 0], out[sel, 1] = q.p0[0], q.p0[1]
            out[sel, 2] = q.h0 + q.dh * 0.5 * (1.0 - np.cos(np.pi * s / q.dur))
        moving[sel] = q.kind != "pause"
    out[:, 2] = wrap_angle(out[:, 2])
    return out, moving


def _gait_envelope(prims: list[_Prim], tau: Array, total: float) -> Array:
    """Smoothly 0 while standing, 1 while walking or turning (0.6 s ramps)."""
    dt = 0.01
    grid = np.arange(-1.0, total + 2.0, dt)
    _, mv = _eval_path(prims, np.clip(grid, 0.0, None))
    mv = np.where(grid < 0.0, 0.0, mv.astype(float))
    win = np.hanning(int(round(0.6 / dt)) + 1)
    env = np.convolve(mv, win / win.sum(), mode="same")
    return np.interp(tau, grid, env)


def _turning(prims: list[_Prim], tau: Array, total: float) -> Array:
    """Smoothly 1 during corners (arcs and turns in place), 0 elsewhere (0.8 s ramps)."""
    dt = 0.01
    grid = np.arange(-1.0, total + 2.0, dt)
    starts = np.array([q.t0 for q in prims])
    idx = np.clip(np.searchsorted(starts, np.clip(grid, 0.0, None), side="right") - 1, 0, len(prims) - 1)
    turning = np.array([q.kind in ("arc", "turn") for q in prims])[idx].astype(float)
    win = np.hanning(int(round(0.8 / dt)) + 1)
    return np.interp(tau, grid, np.convolve(turning, win / win.sum(), mode="same"))


def _truth_at(prims: list[_Prim], tau: Array, total: float, phase: float, gait: Gait = GAITS["calm"]) -> Array:
    """True world poses at ``tau``: the nominal path plus gait sway and heading wobble."""
    nom, _ = _eval_path(prims, tau)
    env = _gait_envelope(prims, tau, total)
    w = 2.0 * np.pi / GAIT_PERIOD
    lat = gait.sway * env * np.sin(w * tau + phase)
    out = nom.copy()
    out[:, 0] -= lat * np.sin(nom[:, 2])
    out[:, 1] += lat * np.cos(nom[:, 2])
    out[:, 2] = wrap_angle(nom[:, 2] + gait.wobble * env * np.cos(w * tau + phase))
    return out


# --- head and body ---------------------------------------------------------------------


@dataclass
class _Motion:
    """Seeded parameters of the head and body motion, evaluated at any time."""

    prims: list[_Prim]
    total: float
    phase: float
    neck_phase: float
    pitch_phase: float
    looks: Array  # (L, 3) look-around: centre time, amplitude (rad), half-width (s)
    head_pitch: float | None
    gait: Gait = GAITS["calm"]

    def head(self, tau: Array) -> tuple[Array, Array]:
        if self.head_pitch is not None:
            return np.zeros_like(tau), np.full_like(tau, self.head_pitch)
        yaw = np.deg2rad(15.0) * np.sin(2.0 * np.pi * tau / 20.0 + self.neck_phase)
        for c, a, hw in self.looks:
            yaw += a * np.exp(-0.5 * ((tau - c) / hw) ** 2)
        lo, hi = np.deg2rad(self.gait.head_pitch_deg)
        pitch = 0.5 * (lo + hi) + 0.5 * (hi - lo) * np.sin(
            2.0 * np.pi * tau / self.gait.head_pitch_period + self.pitch_phase
        )
        if self.gait.head_floor_deg is not None:  # looking down at the floor through every corner
            dip = _turning(self.prims, tau, self.total)
            pitch = pitch + dip * (np.deg2rad(self.gait.head_floor_deg) - pitch)
        return yaw, pitch

    def body(self, tau: Array) -> tuple[Array, Array]:
        env = _gait_envelope(self.prims, tau, self.total)
        w = 2.0 * np.pi / GAIT_PERIOD
        g = self.gait
        roll = np.deg2rad(0.3) + np.deg2rad(g.roll_deg) * env * np.sin(w * tau + self.phase)
        pitch = np.deg2rad(0.5) + np.deg2rad(g.pitch_deg) * env * np.sin(2.0 * w * tau + 0.3)
        return roll, pitch


# --- odometry --------------------------------------------------------------------------


def _odometry(
    truth: Array,
    rng: np.random.Generator,
    drift: bool,
    bias_per_m: float = HEADING_BIAS_PER_M,
    scale_override: float | None = None,
) -> Array:
    """Dead reckoning from the truth: seeded scale error, heading bias and white noise.

    Starts at (0, 0, 0). With ``drift``: translation scale ``1 + e`` (e ~ N(0, 0.03),
    |e| >= 0.02; ``scale_override`` instead if given, the draws made all the same), a
    heading bias of ``bias_per_m`` (default 0.1 deg) per metre walked and a 2 % yaw-rate
    error (both of one random sign). Always: white noise proportional to each increment, so
    the odometry stands exactly still while the robot does (as the real THOR odometry).
    """
    inc = relative(truth[:-1], truth[1:])
    trans = np.hypot(inc[:, 0], inc[:, 1])
    rot = np.abs(inc[:, 2])
    scale, bias, rscale = 1.0, 0.0, 1.0
    if drift:
        e = float(rng.normal(0.0, 0.03))
        sign = float(rng.choice([-1.0, 1.0]))
        if abs(e) < 0.02:
            e = 0.02 * float(rng.choice([-1.0, 1.0]))
        scale = 1.0 + e if scale_override is None else scale_override
        bias = sign * bias_per_m
        rscale = 1.0 + sign * TURN_SCALE_ERROR
    sig_t = 0.05 * trans
    sig_r = 0.05 * rot + 0.002 * trans
    noisy = np.empty_like(inc)
    noisy[:, 0] = inc[:, 0] * scale + rng.normal(0.0, 1.0, len(inc)) * sig_t
    noisy[:, 1] = inc[:, 1] * scale + rng.normal(0.0, 1.0, len(inc)) * sig_t
    noisy[:, 2] = inc[:, 2] * rscale + bias * trans + rng.normal(0.0, 1.0, len(inc)) * sig_r
    odom = np.zeros_like(truth)
    x, y, th = 0.0, 0.0, 0.0
    for i, (ux, uy, ut) in enumerate(noisy, start=1):  # cumulative compose, exact order
        c, s = math.cos(th), math.sin(th)
        x, y, th = x + c * ux - s * uy, y + s * ux + c * uy, th + ut
        odom[i] = (x, y, th)
    odom[:, 2] = wrap_angle(odom[:, 2])
    return odom


# --- the simulator -------------------------------------------------------------------------


@dataclass
class SimResult:
    """What :func:`simulate` wrote and the arrays behind it.

    Attributes:
        lidar_path, joint_path: the THOR ``.mat`` files (``map.yaml`` / ``map.pgm`` beside
            them hold the world's true map in the ground truth's frame).
        groundtruth_path: TUM ground truth in the start-relative frame (first pose 0).
        world_groundtruth_path: TUM ground truth in the world frame.
        t: (N,) scan times (absolute, s).
        truth: (N, 3) true poses relative to the first one.
        truth_world: (N, 3) true poses in the world frame.
        odom: (N, 3) odometry (starts at 0), as written to the lidar file.
        world: the simulated world.
    """

    lidar_path: Path
    joint_path: Path
    groundtruth_path: Path
    world_groundtruth_path: Path
    t: Array
    truth: Array
    truth_world: Array
    odom: Array
    world: World


MAX_DURATION = 3600.0  # s, longer logs would need several GB of memory


def _check_common(duration_s: float, seed: int, rate_hz: float, range_noise: float) -> None:
    """Arguments shared by :func:`simulate` and :func:`simulate_wheeled` (ConfigError if bad)."""
    check_number("duration", duration_s, gt=0.0, le=MAX_DURATION, what="a finite number of seconds")
    check_int("seed", seed, 0)
    check_number("rate_hz", rate_hz, gt=0.0, le=100.0, what="a finite scan rate in Hz")
    check_number("range_noise", range_noise, ge=0.0, le=1.0, what="a finite distance in metres")


ROUTES = ("loop", "reverse")


def routed(w: World, route: str) -> World:
    """The world with the route asked for: ``"loop"`` its own, ``"reverse"`` the same corridors
    the other way round from the waypoint half way along (a ConfigError for another)."""
    if route not in ROUTES:
        raise ConfigError(f"unknown route {route!r}; use {' or '.join(repr(r) for r in ROUTES)}")
    if route == "reverse":
        wp = np.asarray(w.waypoints, dtype=float)[::-1]
        w = replace(w, waypoints=np.roll(wp, -(len(wp) // 2), axis=0))
    return w


def simulate(
    world: str = "office",
    duration_s: float = 180.0,
    seed: int = 0,
    out_dir: str | Path = "sim",
    *,
    rate_hz: float = 40.0,
    head_pitch: float | None = None,
    layout: str = "penn",
    range_noise: float = 0.01,
    drift: bool = True,
    dropout: float = 0.002,
    heading_bias_deg_per_m: float | None = None,
    gait: str = "calm",
    odometry_scale: float | None = None,
    route: str = "loop",
) -> SimResult:
    """Simulate a THOR walk and write its lidar/joint ``.mat`` files and ground truth.

    Args:
        world: a key of :data:`WORLDS`.
        duration_s: length of the log (s, at most :data:`MAX_DURATION`); starts with
            about 5 s standing still.
        seed: seeds the path's pauses, the motion phases, the odometry errors and noise.
        out_dir: folder for ``train_lidar0.mat``, ``train_joint0.mat``,
            ``groundtruth.tum`` and ``groundtruth_world.tum`` (created).
        rate_hz: lidar scan rate (times jitter by up to 1 ms).
        head_pitch: if given, a constant head pitch (rad, positive = down, within
            +-pi/2) and zero neck yaw; otherwise both vary slowly.
        layout: ``"penn"`` (global ``pose``) or ``"ucsd"`` (``delta_pose``, the
            difference of consecutive global poses, first row 0).
        range_noise: sigma of the Gaussian range noise on hits (m).
        drift: systematic odometry errors (scale, heading bias); white noise stays.
        dropout: fraction of beams returning 0 (no reading).
        heading_bias_deg_per_m: the odometry's heading bias with ``drift`` (deg per metre
            walked, sign random; default the gait's: 0.1 calm, 0.8 rough).
        gait: a key of :data:`GAITS`: ``calm`` (the demo) or ``rough`` (strong sway, fast
            turns in place with the head pitched down to the floor, 0.8 deg/m drift).
        odometry_scale: with ``drift``, the odometry's translation scale (reported / true
            distance; 1.04 reads 4 % long) instead of a seeded random one.
        route: ``"loop"`` (the world's path from its first waypoint) or ``"reverse"`` (the
            same corridors the other way round, from the waypoint half way along): a second
            walk through the same building, to continue a session with.
    """
    from pfslam.io.thor import THOR_ANGLES, thor_mounts, write_thor
    from pfslam.io.trajectory import write_tum

    w = routed(world_named(world), route)
    if layout not in ("penn", "ucsd"):
        raise ConfigError(f"unknown layout {layout!r}; use 'penn' or 'ucsd'")
    _check_common(duration_s, seed, rate_hz, range_noise)
    if head_pitch is not None:
        check_number("head_pitch", head_pitch, ge=-np.pi / 2, le=np.pi / 2, what="a finite angle in radians")
    check_number("dropout", dropout, ge=0.0, lt=1.0)
    if gait not in GAITS:
        raise ConfigError(f"unknown gait {gait!r}; known gaits: {', '.join(GAITS)}")
    g = GAITS[gait]
    bias = float(np.deg2rad(g.heading_bias_deg_per_m))
    if heading_bias_deg_per_m is not None:
        check_number("heading_bias_deg_per_m", heading_bias_deg_per_m, ge=0.0, le=10.0)
        bias = float(np.deg2rad(heading_bias_deg_per_m))
    if odometry_scale is not None:
        check_number("odometry_scale", odometry_scale, ge=0.5, le=2.0)
    rng = np.random.default_rng(seed)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)

    # Clocks: lidar at rate_hz with +-1 ms jitter; joints at ~100 Hz on their own clock.
    n = max(2, int(round(duration_s * rate_hz)))
    t0 = 1.4268e9 + float(rng.uniform(0.0, 86400.0))
    tau = np.arange(n) / rate_hz + rng.uniform(-0.001, 0.001, n)
    tau[0] = 0.0
    jstart = -float(rng.uniform(0.1, 0.6))
    jdt = 1.0 / 99.7
    m = int(np.ceil((tau[-1] + 0.5 - jstart) / jdt)) + 1
    jtau = jstart + np.arange(m) * jdt + rng.uniform(-0.002, 0.002, m)

    prims = _build_path(w, float(tau[-1]) + 1.0, rng, g)
    total = prims[-1].t0 + prims[-1].dur
    phase = float(rng.uniform(0.0, 2.0 * np.pi))
    n_looks = max(1, int(duration_s // 30))
    looks = np.column_stack(
        [
            rng.uniform(8.0, max(9.0, duration_s - 3.0), n_looks),
            np.deg2rad(rng.uniform(25.0, 45.0, n_looks)) * rng.choice([-1.0, 1.0], n_looks),
            rng.uniform(0.8, 1.5, n_looks),
        ]
    )
    motion = _Motion(
        prims,
        total,
        phase,
        float(rng.uniform(0, 2 * np.pi)),
        float(rng.uniform(0, 2 * np.pi)),
        looks,
        None if head_pitch is None else float(head_pitch),
        g,
    )

    truth_world = _truth_at(prims, tau, total, phase, g)
    # A robot never starts exactly on the world's grid: shift the path by a seeded
    # fraction of a map cell so walls do not all fall on cell boundaries of the map frame.
    truth_world[:, :2] += rng.uniform(-0.025, 0.025, 2)
    truth = relative(truth_world[0], truth_world)
    odom = _odometry(truth_world, rng, drift, bias, odometry_scale)

    # Sensor poses and the 3D ray cast.
    neck, hp = motion.head(tau)
    roll, pitch = motion.body(tau)
    mounts = thor_mounts(roll, pitch, neck, hp)  # (N, 4, 4) floor-under-robot -> lidar
    c, s = np.cos(truth_world[:, 2]), np.sin(truth_world[:, 2])
    base_r = np.zeros((n, 3, 3))
    base_r[:, 0, 0], base_r[:, 0, 1], base_r[:, 1, 0], base_r[:, 1, 1], base_r[:, 2, 2] = c, -s, s, c, 1.0
    rots = np.ascontiguousarray(base_r @ mounts[:, :3, :3])
    origins = np.ascontiguousarray(np.einsum("nij,nj->ni", base_r, mounts[:, :3, 3]))
    origins[:, :2] += truth_world[:, :2]
    angles = np.ascontiguousarray(THOR_ANGLES, dtype=np.float64)
    scans = _raycast_scans(origins, rots, angles, np.ascontiguousarray(w.segments), float(w.wall_height), MAX_RANGE)
    hit = scans < MAX_RANGE
    if range_noise > 0:
        noise = rng.standard_normal(scans.shape, dtype=np.float32) * np.float32(range_noise)
        scans = np.where(hit, np.minimum(scans + noise, np.float32(MAX_RANGE)), scans)
    if dropout > 0:
        scans[rng.random(scans.shape) < dropout] = 0.0
    scans = scans.astype(np.float32, copy=False)

    # Body IMU: roll, pitch and the odometry heading, at scan and joint times.
    rpy = np.column_stack([roll, pitch, odom[:, 2]])
    jneck, jhp = motion.head(jtau)
    jroll, jpitch = motion.body(jtau)
    jyaw = wrap_angle(np.interp(jtau, tau, np.unwrap(odom[:, 2])))

    t = t0 + tau
    if layout == "penn":
        odo_kw = {"pose": odom}
    else:
        d = np.zeros_like(odom)
        d[1:] = np.diff(odom, axis=0)
        d[1:, 2] = wrap_angle(d[1:, 2])
        odo_kw = {"delta_pose": d}
    lidar_path = out / "train_lidar0.mat"
    joint_path = out / "train_joint0.mat"
    write_thor(
        lidar_path,
        joint_path,
        t=t,
        scans=scans,
        rpy=rpy,
        res=0.0044,
        joint_ts=t0 + jtau,
        head_angles=np.vstack([jneck, jhp]),
        joint_rpy=np.vstack([jroll, jpitch, jyaw]),
        **odo_kw,
    )
    gt_path = out / "groundtruth.tum"
    gtw_path = out / "groundtruth_world.tum"
    write_tum(gt_path, t, truth)
    write_tum(gtw_path, t, truth_world)
    world_map(w, truth_world[0]).save_ros(out / "map", crop=False)
    return SimResult(lidar_path, joint_path, gt_path, gtw_path, t, truth, truth_world, odom, w)


def world_map(world: World, frame_pose: Array, resolution: float = 0.05, margin: float = 1.0) -> OccupancyGrid:
    """The world's true map as an occupancy grid in the frame of ``frame_pose`` (the frame the
    SLAM map and ``groundtruth.tum`` use when it is the start pose): wall cells occupied,
    everything else inside the walls' bounding box free. The grid is laid out so that the
    cell centres fall on the walls of a world drawn on a ``resolution`` lattice (the built-in
    worlds): a wall on a cell boundary would fill the cell beside it, and a likelihood field
    read at cell centres would place every such wall half a cell (2.5 cm) off in x and y."""
    from pfslam.maps.grid import OccupancyGrid

    seg = np.asarray(world.segments, dtype=float)
    pts = []
    for x0, y0, x1, y1 in seg:
        n = max(2, int(np.ceil(np.hypot(x1 - x0, y1 - y0) / (resolution / 4))) + 1)
        a = np.linspace(0.0, 1.0, n)
        pts.append(np.column_stack([x0 + a * (x1 - x0), y0 + a * (y1 - y0)]))
    world_pts = np.concatenate(pts)
    local = relative(np.asarray(frame_pose, float), np.column_stack([world_pts, np.zeros(len(world_pts))]))[:, :2]
    lo = local.min(axis=0) - margin - 0.5 * resolution
    hi = local.max(axis=0) + margin
    shape = (int(np.ceil((hi[1] - lo[1]) / resolution)), int(np.ceil((hi[0] - lo[0]) / resolution)))
    g = OccupancyGrid(resolution=resolution, origin=(float(lo[0]), float(lo[1])), shape=shape)
    g.logodds[:] = -10.0
    r, c = g.world_to_cell(local)
    g.logodds[r, c] = 10.0
    return g
