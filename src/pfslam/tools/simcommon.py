"""What the humanoid (:mod:`pfslam.tools.simulate`) and the wheeled
(:mod:`pfslam.tools.wheeled`) simulators share besides the walk (:mod:`pfslam.tools.walk`):
their common arguments' checks, the odometry dead-reckoned from the truth with seeded errors
(:func:`simulated_odometry`), and the world's true map (:func:`world_map`)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from pfslam.config import check_int, check_number
from pfslam.geometry import relative, wrap_angle
from pfslam.tools.worlds import World
from pfslam.types import Array

if TYPE_CHECKING:
    from pfslam.maps.grid import OccupancyGrid

HEADING_BIAS_PER_M = np.deg2rad(0.1)  # rad per metre walked (sign random)
TURN_SCALE_ERROR = 0.02  # relative yaw-rate error, same sign as the heading bias
MAX_DURATION = 3600.0  # s, longer logs would need several GB of memory


def check_common(duration_s: float, seed: int, rate_hz: float, range_noise: float) -> None:
    """Arguments shared by :func:`~pfslam.tools.simulate.simulate` and the wheeled simulators of
    :mod:`pfslam.tools.wheeled` (ConfigError if bad)."""
    check_number("duration", duration_s, gt=0.0, le=MAX_DURATION, what="a finite number of seconds")
    check_int("seed", seed, 0)
    check_number("rate_hz", rate_hz, gt=0.0, le=100.0, what="a finite scan rate in Hz")
    check_number("range_noise", range_noise, ge=0.0, le=1.0, what="a finite distance in metres")


# --- odometry --------------------------------------------------------------------------


def simulated_odometry(
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
