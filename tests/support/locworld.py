"""A small synthetic world for localization tests, independent of the simulator: a 10 x 8 m
room (0.05 m cells) with an off-centre block and a pillar, so no rotation or mirror maps it
onto itself; 360-degree scans ray-cast from the true poses, odometry that agrees with them."""

from __future__ import annotations

import numpy as np

from pfslam.frames import Frame
from pfslam.geometry import relative, wrap_angle
from pfslam.kernels.likelihood import cast_ray
from pfslam.maps.grid import OccupancyGrid

ANGLES = np.linspace(-np.pi, np.pi, 120, endpoint=False)
MOUNT = np.eye(4)
MOUNT[2, 3] = 0.5  # the sensor 0.5 m above the floor


def room() -> OccupancyGrid:
    g = OccupancyGrid(resolution=0.05, origin=(-1.0, -1.0), shape=(200, 240))  # x -1..11, y -1..9
    g.logodds[:] = -10
    g.logodds[20, 20:221] = g.logodds[180, 20:221] = 10  # walls y = 0 and y = 8
    g.logodds[20:181, 20] = g.logodds[20:181, 220] = 10  # walls x = 0 and x = 10
    g.logodds[60:111, 60:101] = 10  # a block x 2..4, y 2..4.5
    g.logodds[130:139, 160:169] = 10  # a pillar near (7.2, 5.7)
    return g


def scan(g: OccupancyGrid, pose, t: float, odom) -> Frame:
    """The frame seen from ``pose`` at time ``t`` (noise-free ranges), carrying ``odom``."""
    occ = np.ascontiguousarray((g.thresholded() == 100).astype(np.uint8))
    r = np.array(
        [
            cast_ray(occ, g.origin[0], g.origin[1], 1 / g.resolution, pose[0], pose[1], np.cos(b), np.sin(b), 30.0)
            for b in pose[2] + ANGLES
        ]
    )
    return Frame(t=t, ranges=r, angles=ANGLES.copy(), odom=np.asarray(odom, float), mount=MOUNT, max_range=30.0)


def drive(waypoints, step: float = 0.08, turn: float = np.deg2rad(10)) -> np.ndarray:
    """Poses turning in place towards each next waypoint, then driving to it in ``step`` m steps."""
    w = np.asarray(waypoints, float)
    th = float(np.arctan2(w[1, 1] - w[0, 1], w[1, 0] - w[0, 0]))
    out = [[w[0, 0], w[0, 1], th]]
    for a, b in zip(w[:-1], w[1:]):
        want = float(np.arctan2(b[1] - a[1], b[0] - a[0]))
        d_th = float(wrap_angle(want - th))
        n_turn = int(np.ceil(abs(d_th) / turn))
        out += [[a[0], a[1], float(wrap_angle(th + d_th * j / n_turn))] for j in range(1, n_turn + 1)]
        th = want
        n = int(np.ceil(np.hypot(*(b - a)) / step))
        out += [[*(a + (b - a) * k / n), th] for k in range(1, n + 1)]
    return np.array(out)


def frames_along(g: OccupancyGrid, truth: np.ndarray, dt: float = 0.1) -> list[Frame]:
    """Frames along the true poses; the odometry is the truth seen from the first pose."""
    odom = relative(truth[0], truth)
    return [scan(g, p, k * dt, o) for k, (p, o) in enumerate(zip(truth, odom))]
