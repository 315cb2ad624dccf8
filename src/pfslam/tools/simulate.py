"""A THOR humanoid simulator: synthetic THOR-format logs with ground truth.

The robot walks a built-in path through a 2D world of vertical walls. A head-mounted
Hokuyo (1081 beams over 270 deg) is ray cast in 3D against the walls and the floor,
through the same mount chain the loader uses (body roll/pitch, neck yaw, head pitch),
so pitched-down beams hit the floor. The odometry is the truth corrupted by a seeded
scale error, a heading bias and white noise.

Outputs (see :func:`simulate`): ``train_lidar0.mat``, ``train_joint0.mat``,
``groundtruth.tum`` (start-relative: the first pose is (0, 0, 0), the frame the SLAM
map starts in) and ``groundtruth_world.tum`` (world frame).

The walk (route, gaits, path) is :mod:`pfslam.tools.walk`'s, the odometry's errors, the
argument checks and the true map :mod:`pfslam.tools.simcommon`'s (both shared with the
wheeled robots of :mod:`pfslam.tools.wheeled`); here: the head and body motion, the 3D ray
cast through the THOR mount chain, and the files.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pfslam.config import check_number
from pfslam.errors import ConfigError
from pfslam.geometry import relative, wrap_angle
from pfslam.tools.places import world_named
from pfslam.tools.raycast import MAX_RANGE, _raycast_scans
from pfslam.tools.simcommon import MAX_DURATION as MAX_DURATION  # pfslam simulate's limit, checked by check_common
from pfslam.tools.simcommon import check_common, simulated_odometry, world_map
from pfslam.tools.walk import GAIT_PERIOD, GAITS, Gait, Prim, build_path, gait_envelope, routed, truth_at, turning
from pfslam.tools.worlds import World
from pfslam.types import Array

# --- head and body ---------------------------------------------------------------------


@dataclass
class _Motion:
    """Seeded parameters of the head and body motion, evaluated at any time."""

    prims: list[Prim]
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
            dip = turning(self.prims, tau, self.total)
            pitch = pitch + dip * (np.deg2rad(self.gait.head_floor_deg) - pitch)
        return yaw, pitch

    def body(self, tau: Array) -> tuple[Array, Array]:
        env = gait_envelope(self.prims, tau, self.total)
        w = 2.0 * np.pi / GAIT_PERIOD
        g = self.gait
        roll = np.deg2rad(0.3) + np.deg2rad(g.roll_deg) * env * np.sin(w * tau + self.phase)
        pitch = np.deg2rad(0.5) + np.deg2rad(g.pitch_deg) * env * np.sin(2.0 * w * tau + 0.3)
        return roll, pitch


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
    stand_s: float | None = None,
) -> SimResult:
    """Simulate a THOR walk and write its lidar/joint ``.mat`` files and ground truth.

    Args:
        world: a key of :data:`~pfslam.tools.worlds.WORLDS`, or ``"random"``: the random
            building of ``seed`` (:func:`~pfslam.tools.buildings.random_building`).
        duration_s: length of the log (s, at most :data:`~pfslam.tools.simcommon.MAX_DURATION`); starts with
            about 5 s standing still (``stand_s``).
        seed: seeds the path's pauses, the motion phases, the odometry errors and noise (and
            the building, in the world ``"random"``).
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
        gait: a key of :data:`~pfslam.tools.walk.GAITS`: ``calm`` (the demo) or ``rough`` (strong sway, fast
            turns in place with the head pitched down to the floor, 0.8 deg/m drift).
        odometry_scale: with ``drift``, the odometry's translation scale (reported / true
            distance; 1.04 reads 4 % long) instead of a seeded random one.
        route: ``"loop"`` (the world's path from its first waypoint) or ``"reverse"`` (the
            same corridors the other way round, from the waypoint half way along): a second
            walk through the same building, to continue a session with.
        stand_s: how long the robot stands still before it walks off (s, 0 allowed); default
            4.5-5.5 s, seeded.
    """
    from pfslam.io.thor import THOR_ANGLES, thor_mounts, write_thor
    from pfslam.io.trajectory import write_tum

    w = routed(world_named(world, seed), route)
    if layout not in ("penn", "ucsd"):
        raise ConfigError(f"unknown layout {layout!r}; use 'penn' or 'ucsd'")
    check_common(duration_s, seed, rate_hz, range_noise)
    if head_pitch is not None:
        check_number("head_pitch", head_pitch, ge=-np.pi / 2, le=np.pi / 2, what="a finite angle in radians")
    check_number("dropout", dropout, ge=0.0, lt=1.0)
    if stand_s is not None:
        check_number("stand_s", stand_s, ge=0.0, le=MAX_DURATION, what="a finite number of seconds")
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

    prims = build_path(w, float(tau[-1]) + 1.0, rng, g, stand_s=stand_s)
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

    truth_world = truth_at(prims, tau, total, phase, g)
    # A robot never starts exactly on the world's grid: shift the path by a seeded
    # fraction of a map cell so walls do not all fall on cell boundaries of the map frame.
    truth_world[:, :2] += rng.uniform(-0.025, 0.025, 2)
    truth = relative(truth_world[0], truth_world)
    odom = simulated_odometry(truth_world, rng, drift, bias, odometry_scale)

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
