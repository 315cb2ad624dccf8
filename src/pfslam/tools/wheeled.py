"""Wheeled robots for the simulator: a differential-drive robot with a planar lidar, in
memory (:func:`simulate_wheeled`, wheel travel as the Mines rover logs it) or driving a
world's route and written as a ROS bag with ground truth (:func:`simulate_wheeled_bag`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pfslam.config import check_int, check_number
from pfslam.errors import ConfigError
from pfslam.geometry import relative, wrap_angle
from pfslam.tools.buildings import lap_length
from pfslam.tools.campus import DRIVE_SPEED, SICK_BEAMS, SICK_FOV_DEG, SICK_RANGE
from pfslam.tools.places import world_named
from pfslam.tools.raycast import _raycast_scans
from pfslam.tools.simcommon import MAX_DURATION, check_common, simulated_odometry, world_map
from pfslam.tools.walk import Gait, build_path, eval_path, lap_end, routed
from pfslam.tools.worlds import World
from pfslam.types import Array


@dataclass
class WheeledLog:
    """A simulated wheeled-robot log (see :func:`simulate_wheeled`)."""

    frames: list  # list[Frame] with cumulative wheel travel
    truth: Array  # (N, 3) true robot pose when each scan was taken, start-relative
    axle: float


def simulate_wheeled(
    world: str = "office",
    duration_s: float = 20.0,
    seed: int = 0,
    *,
    rate_hz: float = 10.0,
    speed: float = 0.4,
    axle: float = 0.33,
    wheel_scale: float = 1.0,
    turn_scale: float = 1.0,
    scan_latency: float = 0.0,
    beams: int = 480,
    fov_deg: float = 240.0,
    max_range: float = 8.0,
    range_noise: float = 0.01,
) -> WheeledLog:
    """A differential-drive robot weaving along the world's first corridor leg, in memory.

    The robot drives at ``speed`` with a heading that swings by about +-20 deg; a planar
    lidar (``beams`` over ``fov_deg``, at 0.3 m height on the axle centre) scans at
    ``rate_hz``. The log's wheel travel is miscalibrated on purpose: the true centre
    travel is divided by ``wheel_scale`` and the true wheel difference by ``turn_scale``
    (so a calibration should find those scales), and each scan's time stamp is
    ``scan_latency`` seconds later than the moment it was taken, while the wheel travel is
    the one at the time stamp.
    """
    from pfslam.frames import Frame

    w = world_named(world, seed)
    check_common(duration_s, seed, rate_hz, range_noise)
    check_number("speed", speed, ge=0.0, le=5.0, what="a finite speed in m/s")
    check_number("axle", axle, gt=0.0, what="a finite distance in metres")
    check_number("wheel_scale", wheel_scale, gt=0.0)
    check_number("turn_scale", turn_scale, gt=0.0)
    check_number("scan_latency", scan_latency, ge=-5.0, le=5.0, what="a finite number of seconds")
    check_int("beams", beams, 1)
    check_number("fov_deg", fov_deg, gt=0.0, le=360.0)
    check_number("max_range", max_range, gt=0.0, what="a finite distance in metres")
    rng = np.random.default_rng(seed)
    dt = 1e-3
    steps = int(round((duration_s + abs(scan_latency) + 1.0) / dt))
    tt = np.arange(steps + 1) * dt
    period = float(rng.uniform(3.0, 5.0))
    omega = np.deg2rad(20.0) * 2 * np.pi / period * np.cos(2 * np.pi * tt / period)
    heading = w.start[2] + np.concatenate([[0.0], np.cumsum(omega[:-1]) * dt])
    x = w.start[0] + np.concatenate([[0.0], np.cumsum(speed * np.cos(heading[:-1])) * dt])
    y = w.start[1] + np.concatenate([[0.0], np.cumsum(speed * np.sin(heading[:-1])) * dt])
    centre = speed * tt
    half = 0.5 * axle * (heading - heading[0])
    wl, wr = centre / wheel_scale - half / turn_scale, centre / wheel_scale + half / turn_scale

    n = int(round(duration_s * rate_hz))
    taken = 0.5 + np.arange(n) / rate_hz  # when each scan was taken
    stamp = taken + scan_latency
    pose = np.column_stack([np.interp(taken, tt, x), np.interp(taken, tt, y), np.interp(taken, tt, heading)])
    wheels = np.column_stack([np.interp(stamp, tt, wl), np.interp(stamp, tt, wr)])
    angles = np.deg2rad(np.linspace(-fov_deg / 2, fov_deg / 2, beams))
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    rots = np.zeros((n, 3, 3))
    rots[:, 0, 0], rots[:, 0, 1], rots[:, 1, 0], rots[:, 1, 1], rots[:, 2, 2] = c, -s, s, c, 1.0
    origins = np.column_stack([pose[:, :2], np.full(n, 0.3)])
    scans = _raycast_scans(
        np.ascontiguousarray(origins),
        np.ascontiguousarray(rots),
        angles,
        np.ascontiguousarray(w.segments),
        float(w.wall_height),
        float(max_range),
    )
    scans = np.asarray(scans, dtype=float)
    hit = scans < max_range
    scans = np.where(hit, scans + rng.normal(0.0, range_noise, scans.shape), 0.0)
    mount = np.eye(4)
    mount[2, 3] = 0.3
    frames = [
        Frame(
            t=float(stamp[k]),
            ranges=scans[k],
            angles=angles,
            wheels=wheels[k].copy(),
            mount=mount.copy(),
            min_range=0.05,
            max_range=max_range,
        )
        for k in range(n)
    ]
    pose[:, 2] = wrap_angle(pose[:, 2])
    return WheeledLog(frames, relative(pose[0], pose), axle)


#: How a wheeled robot drives a route: no sway or wobble, every corner an arc (an about-turn in place).
WHEELED = Gait(sway=0.0, wobble=0.0, roll_deg=0.0, pitch_deg=0.0, arc_radius=0.6, max_arc_turn=np.pi)
BAGS = {"ros1": "log.bag", "ros2": "log", "mcap": "log.mcap"}  # the bag's name in the output folder, per storage
LASER_MOUNT = (0.15, 0.0, 0.3)  # m: the lidar ahead of the axle centre, above the floor
PAUSE_MAX_S = 10.0  # s: the longest a walk pauses at a corner and part way along the leg after it


@dataclass(frozen=True)
class Drive:
    """How ``pfslam simulate --robot wheeled`` drives a world when not told otherwise: the
    laser's reach (m), beams and field of view (deg), the speed (m/s), the duration (s; None:
    one lap of the route, see :func:`simulate_wheeled_bag`) and the odometry's heading bias
    (deg per metre driven)."""

    max_range: float = 20.0
    beams: int = 720
    fov_deg: float = 270.0
    speed: float = 0.6
    duration_s: float | None = 180.0
    heading_bias_deg_per_m: float = 0.3


#: Worlds driven otherwise than :class:`Drive`'s defaults: the campus once round at 1 m/s with
#: a SICK LMS (361 beams over 180 deg, 80 m), as the Freiburg campus robot, its odometry's
#: heading drifting 0.05 deg per metre (the indoor 0.3 would turn it 500 deg and more over the
#: 1.2-2 km lap; at 0.05 that is 60-100 deg).
DRIVES: dict[str, Drive] = {
    "campus": Drive(SICK_RANGE, SICK_BEAMS, SICK_FOV_DEG, DRIVE_SPEED, None, heading_bias_deg_per_m=0.05)
}


def drive(world: str) -> Drive:
    """How ``pfslam simulate --robot wheeled`` drives ``world`` by default (see :data:`DRIVES`)."""
    return DRIVES.get(world, Drive())


@dataclass
class WheeledBag:
    """What :func:`simulate_wheeled_bag` wrote and the arrays behind it."""

    bag: Path
    groundtruth_path: Path
    t: Array  # (N,) scan times (s)
    truth: Array  # (N, 3) true poses relative to the first one
    odom: Array  # (N, 3) odometry as written to /tf (starts at 0)


def simulate_wheeled_bag(
    world: str = "block",
    duration_s: float | None = 300.0,
    seed: int = 0,
    out_dir: str | Path = "sim",
    *,
    storage: str = "ros1",
    rate_hz: float = 10.0,
    speed: float = 0.6,
    beams: int = 720,
    fov_deg: float = 270.0,
    max_range: float = 20.0,
    range_noise: float = 0.01,
    heading_bias_deg_per_m: float = 0.3,
    odometry_scale: float | None = None,
    route: str = "loop",
    stand_s: float | None = None,
    laser_x: float | None = None,
) -> WheeledBag:
    """A differential-drive robot driving the world's route (as :func:`~pfslam.tools.simulate.simulate`
    walks it, corners as arcs, pausing now and then), written as a ROS bag with its ground truth.

    A planar lidar (``beams`` over ``fov_deg``, ``max_range``; no return written as +inf, as
    ROS drivers do) scans at ``rate_hz`` from :data:`LASER_MOUNT` (or ``laser_x`` metres ahead of
    the axle centre instead: 0 above it, at the same height). The odometry is the truth
    corrupted by a seeded scale error (or ``odometry_scale``), a heading bias of
    ``heading_bias_deg_per_m`` (sign random) and white noise, recorded as the ``odom`` ->
    ``base_link`` link of ``/tf`` (no odometry topic). ``route``: as
    :func:`~pfslam.tools.simulate.simulate`'s, and so are ``world`` (``"random"``: the random
    building of ``seed``) and ``stand_s`` (how long the robot stands before it drives off,
    default 4.5-5.5 s). ``duration_s`` None: one lap of the route, the log ending as the robot
    gets back to where it set off (a ConfigError if that takes longer than
    :data:`~pfslam.tools.simcommon.MAX_DURATION`). Writes into ``out_dir``: the bag
    (:data:`BAGS`: ``log.bag`` for ``ros1``, the ROS 2 folder ``log`` for ``ros2``,
    ``log.mcap``), ``groundtruth.tum`` (start-relative) and the world's true ``map.yaml``."""
    from pfslam.frames import Frame
    from pfslam.io.bagwrite import write_bag
    from pfslam.io.trajectory import write_tum

    w = routed(world_named(world, seed), route)
    check_common(MAX_DURATION if duration_s is None else duration_s, seed, rate_hz, range_noise)
    if storage not in BAGS:
        raise ConfigError(f"unknown bag storage {storage!r}; use {', '.join(BAGS)}")
    check_number("speed", speed, gt=0.0, le=5.0, what="a finite speed in m/s")
    check_int("beams", beams, 2)
    check_number("fov_deg", fov_deg, gt=0.0, le=360.0)
    check_number("max_range", max_range, gt=0.0, le=100.0, what="a finite distance in metres")
    check_number("heading_bias_deg_per_m", heading_bias_deg_per_m, ge=0.0, le=10.0)
    if odometry_scale is not None:
        check_number("odometry_scale", odometry_scale, ge=0.5, le=2.0)
    if stand_s is not None:
        check_number("stand_s", stand_s, ge=0.0, le=MAX_DURATION, what="a finite number of seconds")
    lx, _, lz = LASER_MOUNT
    if laser_x is not None:
        lx = check_number("laser_x", laser_x, ge=-1.0, le=1.0, what="a finite distance in metres")
    rng = np.random.default_rng(seed)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    bag = out / BAGS[storage]
    if bag.exists():
        raise ConfigError(f"{bag} exists already")

    span = _lap_bound(w, speed, stand_s) if duration_s is None else duration_s
    n = max(2, int(round(span * rate_hz)))
    tau = np.arange(n) / rate_hz + rng.uniform(-0.002, 0.002, n)
    tau[0] = 0.0
    prims = build_path(w, float(tau[-1]) + 1.0, rng, WHEELED, speed, stand_s=stand_s)
    if duration_s is None:  # one lap: up to the moment the robot is back
        end = lap_end(prims, len(w.waypoints))
        if end > MAX_DURATION:
            raise ConfigError(
                f"one lap of the {w.name} route ({lap_length(w):.0f} m at {speed:g} m/s) takes more than "
                f"{MAX_DURATION:g} s: give a duration or a higher speed"
            )
        tau = tau[tau <= end]
        n = len(tau)
    truth_world, _ = eval_path(prims, tau)
    truth_world[:, :2] += rng.uniform(-0.025, 0.025, 2)  # off the world's grid (see simulate)
    odom = simulated_odometry(truth_world, rng, True, float(np.deg2rad(heading_bias_deg_per_m)), odometry_scale)

    mount = np.eye(4)
    mount[:3, 3] = (lx, 0.0, lz)
    angles = np.deg2rad(np.linspace(-fov_deg / 2, fov_deg / 2, beams))
    c, s = np.cos(truth_world[:, 2]), np.sin(truth_world[:, 2])
    rots = np.zeros((n, 3, 3))
    rots[:, 0, 0], rots[:, 0, 1], rots[:, 1, 0], rots[:, 1, 1], rots[:, 2, 2] = c, -s, s, c, 1.0
    origins = np.column_stack(
        [truth_world[:, 0] + c * lx, truth_world[:, 1] + s * lx, np.full(n, lz)]  # (the mount's y is 0)
    )
    scans = np.asarray(
        _raycast_scans(
            np.ascontiguousarray(origins),
            np.ascontiguousarray(rots),
            angles,
            np.ascontiguousarray(w.segments),
            float(w.wall_height),
            float(max_range),
        ),
        dtype=float,
    )
    hit = scans < max_range
    scans = np.where(hit, scans + rng.normal(0.0, range_noise, scans.shape), np.inf)
    t = 1.7e9 + float(rng.uniform(0.0, 86400.0)) + tau
    frames = [
        Frame(
            t=float(t[k]),
            ranges=scans[k],
            angles=angles,
            odom=odom[k],
            mount=mount,
            min_range=0.05,
            max_range=max_range,
        )
        for k in range(n)
    ]
    write_bag(bag, frames, odom, storage, odom_in_tf=True)
    truth = relative(truth_world[0], truth_world)
    truth[:, 2] = wrap_angle(truth[:, 2])
    gt = out / "groundtruth.tum"
    write_tum(gt, t, truth)
    world_map(w, truth_world[0]).save_ros(out / "map", crop=False)
    return WheeledBag(bag, gt, t, truth, odom)


def _lap_bound(w: World, speed: float, stand_s: float | None) -> float:
    """A time (s) by which a wheeled robot has been once round the route of ``w`` at ``speed``
    whatever its pauses (:func:`~pfslam.tools.walk.build_path`'s: a corner's arc is shorter than
    the straights it cuts, an about-turn is turned in place), at most MAX_DURATION."""
    turn = np.pi * np.pi / (2.0 * WHEELED.turn_rate)  # an about-turn in place
    stand = 5.5 if stand_s is None else stand_s
    return min(MAX_DURATION, lap_length(w) / speed + stand + len(w.waypoints) * (PAUSE_MAX_S + turn) + 1.0)
