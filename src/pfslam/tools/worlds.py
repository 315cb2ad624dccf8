"""The simulator's built-in worlds: 2D floors of vertical walls, each with the closed route a
simulated robot walks (see :mod:`pfslam.tools.simulate`).

``office`` (the demo's floor), ``corridor`` (out and back along one corridor), and four
worlds whose places repeat, to fool a loop-closing back end: ``pillars`` (a corridor ring
with a pillar and a door every 3 m), ``rooms`` (six identical rooms in a row), ``twins``
(two identical corridors walked the same way, 6.4 m apart) and ``block`` (a 3 m corridor
all round a central block, runs of 32 and 16 m, most of them bare walls); and two where the
walls say little of where a scan was taken: ``bare`` (100 m of bare corridor, a door every
25 m) and ``hall`` (an open 30 x 20 m hall, for a short-range laser). :func:`~pfslam.tools.places.world_named`
also knows ``random``: a random building per seed (:mod:`pfslam.tools.buildings`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pfslam.types import Array


@dataclass
class World:
    """A 2D world of vertical walls.

    Attributes:
        name: the world's key in :data:`WORLDS`.
        segments: (K, 4) wall segments ``[x0, y0, x1, y1]`` in metres.
        wall_height: height of every wall (m); walls stand on the floor z = 0.
        start: (3,) the robot's start pose in the world frame.
        waypoints: (P, 2) the built-in path, walked as a closed polyline from
            ``waypoints[0]`` (which equals the start position).
    """

    name: str
    segments: Array
    wall_height: float = 2.5
    start: Array = field(default_factory=lambda: np.zeros(3))
    waypoints: Array = field(default_factory=lambda: np.zeros((1, 2)))


def _wall(x0: float, y0: float, x1: float, y1: float, gaps: tuple[tuple[float, float], ...] = ()) -> list[list[float]]:
    """A straight wall with door gaps ``(offset of the centre along the wall, width)``."""
    length = math.hypot(x1 - x0, y1 - y0)
    ux, uy = (x1 - x0) / length, (y1 - y0) / length
    cuts = [0.0]
    for c, w in sorted(gaps):
        cuts += [c - w / 2.0, c + w / 2.0]
    cuts.append(length)
    out = []
    for a, b in zip(cuts[0::2], cuts[1::2]):
        if b - a > 1e-9:
            out.append([x0 + ux * a, y0 + uy * a, x0 + ux * b, y0 + uy * b])
    return out


def _box(x0: float, y0: float, x1: float, y1: float) -> list[list[float]]:
    """The four sides of an axis-aligned rectangle (pillar, desk, cabinet)."""
    return [[x0, y0, x1, y0], [x1, y0, x1, y1], [x1, y1, x0, y1], [x0, y1, x0, y0]]


def _office() -> World:
    s: list[list[float]] = []
    # Outer wall of the floor, 30 x 20 m.
    s += _box(0.0, 0.0, 30.0, 20.0)
    # Corridor outer walls (x 3..27, y 3..17) with doors into the outer ring of rooms.
    s += _wall(3.0, 3.0, 27.0, 3.0, ((3.0, 1.0), (9.0, 1.0), (15.0, 1.2), (21.0, 1.0)))  # south
    s += _wall(3.0, 17.0, 27.0, 17.0, ((2.0, 1.0), (7.0, 1.0), (13.0, 1.6), (18.5, 1.0)))  # north
    s += _wall(3.0, 3.0, 3.0, 17.0, ((4.0, 1.0), (10.0, 1.0)))  # west
    s += _wall(27.0, 3.0, 27.0, 17.0, ((2.5, 1.0), (8.0, 1.0), (12.0, 0.9)))  # east
    # Partitions of the outer ring of rooms.
    for x in (9.0, 15.0, 21.0):
        s += _wall(x, 0.0, x, 3.0)
    for x in (7.0, 13.0, 19.0, 24.0):
        s += _wall(x, 17.0, x, 20.0)
    s += _wall(0.0, 10.0, 3.0, 10.0)
    for y in (8.0, 13.0):
        s += _wall(27.0, y, 30.0, y)
    # Central block (x 5.5..24.5, y 5.5..14.5): corridors 2.5 m wide all round.
    s += _wall(5.5, 5.5, 24.5, 5.5, ((2.5, 1.0), (9.5, 1.2), (15.5, 1.0)))  # south
    s += _wall(5.5, 14.5, 24.5, 14.5, ((3.5, 1.0), (8.5, 1.0), (16.5, 1.4)))  # north
    s += _wall(5.5, 5.5, 5.5, 14.5, ((6.5, 1.0),))  # west
    s += _wall(24.5, 5.5, 24.5, 14.5, ((2.0, 1.0),))  # east
    s += _wall(5.5, 10.0, 24.5, 10.0, ((9.5, 1.0), (15.0, 1.0)))
    s += _wall(11.5, 5.5, 11.5, 14.5, ((2.0, 0.9),))
    s += _wall(18.0, 5.5, 18.0, 14.5, ((7.0, 0.9),))
    # Desks and furniture inside the rooms.
    for x0, y0, x1, y1 in (
        (7.0, 7.0, 8.4, 7.7),
        (13.0, 7.5, 14.2, 8.1),
        (15.5, 7.0, 16.1, 8.4),
        (20.0, 6.5, 21.4, 7.2),
        (21.8, 8.2, 23.0, 8.8),
        (7.5, 12.0, 9.5, 12.7),
        (13.5, 11.5, 16.0, 12.3),
        (19.5, 12.5, 20.2, 13.8),
        (22.0, 11.2, 23.5, 11.8),
        (1.0, 1.0, 2.2, 1.6),
        (5.0, 0.8, 6.4, 1.4),
        (11.0, 1.2, 12.5, 1.8),
        (17.0, 0.6, 18.0, 2.0),
        (23.0, 1.0, 24.5, 1.6),
        (1.0, 12.5, 1.7, 14.5),
        (0.8, 5.0, 1.6, 6.5),
        (4.0, 18.3, 5.5, 19.0),
        (9.0, 18.5, 11.5, 19.2),
        (15.0, 18.2, 16.2, 19.4),
        (20.5, 18.4, 22.0, 19.0),
        (28.2, 4.0, 29.2, 5.5),
        (28.0, 10.0, 29.0, 10.8),
        (28.5, 15.0, 29.3, 17.0),
    ):
        s += _box(x0, y0, x1, y1)
    # Corridor clutter against the walls: pillars (0.3 m) and cabinets (0.4 m deep).
    for x0, y0, x1, y1 in (
        (7.0, 3.0, 7.3, 3.3),
        (13.0, 3.0, 13.3, 3.3),
        (19.5, 3.0, 20.5, 3.4),
        (25.0, 3.0, 25.3, 3.3),
        (9.5, 5.1, 10.5, 5.5),
        (14.0, 5.2, 14.3, 5.5),
        (22.5, 5.1, 23.5, 5.5),
        (8.5, 16.7, 8.8, 17.0),
        (14.5, 16.6, 15.5, 17.0),
        (21.0, 16.7, 21.3, 17.0),
        (25.5, 16.6, 26.5, 17.0),
        (7.5, 14.5, 8.5, 14.9),
        (12.0, 14.5, 12.3, 14.8),
        (18.5, 14.5, 18.8, 14.8),
        (23.5, 14.5, 24.0, 14.9),
        (3.0, 6.0, 3.3, 6.3),
        (3.0, 11.5, 3.4, 12.5),
        (3.0, 15.0, 3.3, 15.3),
        (5.1, 8.0, 5.5, 9.0),
        (26.7, 7.0, 27.0, 7.3),
        (26.6, 13.2, 27.0, 14.2),
        (24.5, 9.0, 24.8, 9.3),
        (24.5, 12.5, 24.9, 13.5),
    ):
        s += _box(x0, y0, x1, y1)
    # Walk the corridor loop counter-clockwise, starting mid-way along the south corridor.
    wp = np.array([[10.0, 4.25], [25.75, 4.25], [25.75, 15.75], [4.25, 15.75], [4.25, 4.25]])
    return World("office", np.array(s, dtype=float), 2.5, np.array([10.0, 4.25, 0.0]), wp)


def _corridor() -> World:
    s: list[list[float]] = []
    half = 1.2
    length = 40.0
    s += _wall(0.0, -half, 0.0, half)
    s += _wall(length, -half, length, half)
    south_gaps: list[tuple[float, float]] = []
    north_gaps: list[tuple[float, float]] = []
    k = 0
    for xc in np.arange(3.0, 38.0, 4.0):
        (north_gaps if k % 2 == 0 else south_gaps).append((float(xc), 1.0))
        k += 1
    # A side corridor (2 m wide) to the north at x = 21, and an open office to the south at x = 29.
    north_gaps.append((21.0, 2.0))
    south_gaps.append((29.0, 2.4))
    s += _wall(0.0, half, length, half, tuple(north_gaps))
    s += _wall(0.0, -half, length, -half, tuple(south_gaps))
    # Door recesses (0.3 m deep) behind every other gap.
    for xc, w in north_gaps[:-1]:
        s += _wall(xc - w / 2, half, xc - w / 2, half + 0.3)
        s += _wall(xc - w / 2, half + 0.3, xc + w / 2, half + 0.3)
        s += _wall(xc + w / 2, half + 0.3, xc + w / 2, half)
    for xc, w in south_gaps[:-1]:
        if 27.0 < xc < 34.0:  # behind the open office
            continue
        s += _wall(xc - w / 2, -half, xc - w / 2, -half - 0.3)
        s += _wall(xc - w / 2, -half - 0.3, xc + w / 2, -half - 0.3)
        s += _wall(xc + w / 2, -half - 0.3, xc + w / 2, -half)
    # Side corridor: 6 m deep, dead end, with a pillar.
    s += _wall(20.0, half, 20.0, half + 6.0)
    s += _wall(22.0, half, 22.0, half + 6.0)
    s += _wall(20.0, half + 6.0, 22.0, half + 6.0)
    s += _box(21.6, 4.0, 22.0, 4.6)
    # Open office 6 x 5 m with desks.
    s += _wall(27.8, -half, 27.8, -half - 5.0)
    s += _wall(33.8, -half, 33.8, -half - 5.0)
    s += _wall(27.8, -half - 5.0, 33.8, -half - 5.0)
    s += _box(28.5, -4.0, 29.7, -3.4) + _box(31.0, -3.0, 32.5, -2.4) + _box(32.8, -5.6, 33.4, -4.4)
    # Pillars and cabinets along the corridor walls.
    for x0 in (5.0, 11.0, 17.0, 25.0, 33.0):
        s += _box(x0, half - 0.3, x0 + 0.3, half)
    for x0 in (9.0, 15.0, 24.0, 36.0):
        s += _box(x0, -half, x0 + 0.8, -half + 0.4)
    wp = np.array([[2.0, 0.0], [38.0, 0.0]])
    return World("corridor", np.array(s, dtype=float), 2.5, np.array([2.0, 0.0, 0.0]), wp)


def _recessed_wall(
    x0: float, y0: float, x1: float, y1: float, doors: tuple[float, ...], width: float = 1.0, depth: float = 0.25
) -> list[list[float]]:
    """A straight wall with door recesses: at each offset in ``doors`` along the wall, a gap
    ``width`` wide closed by a back wall ``depth`` behind it (positive: to the left of the
    direction from (x0, y0) to (x1, y1), negative: to the right)."""
    length = math.hypot(x1 - x0, y1 - y0)
    ux, uy = (x1 - x0) / length, (y1 - y0) / length
    nx, ny = -uy * depth, ux * depth
    out = _wall(x0, y0, x1, y1, tuple((c, width) for c in doors))
    for c in doors:
        ax, ay = x0 + ux * (c - width / 2.0), y0 + uy * (c - width / 2.0)
        bx, by = x0 + ux * (c + width / 2.0), y0 + uy * (c + width / 2.0)
        out += [[ax, ay, ax + nx, ay + ny], [ax + nx, ay + ny, bx + nx, by + ny], [bx + nx, by + ny, bx, by]]
    return out


def _pillars() -> World:
    """A 27 x 10 m floor: a corridor ring (2.6 m wide) round a 21.8 x 4.8 m central block.

    Both long corridors repeat every 3 m: a 0.35 m pillar against one wall and a door recess
    opposite it, then the other way round 1.5 m on, over their whole length; the north
    corridor is the south one turned by 180 deg. Only the four corners (and the short end
    corridors) differ. The route walks the ring once counter-clockwise (63.6 m), starting in
    the south corridor.
    """
    s: list[list[float]] = []
    w, h, c = 27.0, 10.0, 2.6
    pill = 0.35
    xs_a = [4.5 + 3.0 * k for k in range(7)]  # 4.5 .. 22.5
    xs_b = [6.0 + 3.0 * k for k in range(6)]  # 6 .. 21
    # Outer walls: the long ones with door recesses (outwards) at xs_b.
    s += _recessed_wall(0.0, 0.0, w, 0.0, tuple(xs_b), 1.0, -0.3)  # south, recesses to y < 0
    s += _recessed_wall(w, h, 0.0, h, tuple(w - x for x in xs_b), 1.0, -0.3)  # north, recesses to y > h
    s += _wall(0.0, 0.0, 0.0, h)
    s += _recessed_wall(w, 0.0, w, h, (9.0,), 1.6, -1.0)  # east, a wide alcove in the north-east corner
    # Central block, with door recesses (into the block) opposite the outer walls' pillars.
    s += _recessed_wall(c, c, w - c, c, tuple(x - c for x in xs_a), 1.0, 0.3)  # south face
    s += _recessed_wall(w - c, h - c, c, h - c, tuple((w - c) - x for x in xs_a), 1.0, 0.3)  # north face
    s += _recessed_wall(c, h - c, c, c, (1.5,), 1.0, 0.3)  # west face, one door
    s += _wall(w - c, c, w - c, h - c)  # east face
    # Pillars: against the outer walls at xs_a, against the block at xs_b (and turned by 180 deg).
    for x in xs_a:
        s += _box(x - pill / 2, 0.0, x + pill / 2, pill)
        s += _box(w - x - pill / 2, h - pill, w - x + pill / 2, h)
    for x in xs_b:
        s += _box(x - pill / 2, c - pill, x + pill / 2, c)
        s += _box(w - x - pill / 2, h - c, w - x + pill / 2, h - c + pill)
    # The corners, each its own: a chamfer (south-west), a cabinet (south-east), the alcove
    # (north-east), a cabinet and a shelf (north-west); and a little on the short corridors.
    s += [[0.0, 0.9, 0.9, 0.0]]
    s += _box(26.1, 0.0, w, 0.6)
    s += _box(0.0, 8.3, 0.5, 9.5) + _box(1.2, 9.55, 2.2, h)
    s += _box(26.6, 4.0, w, 4.4) + _box(0.0, 3.5, 0.45, 4.7)
    wp = np.array([[6.0, 1.3], [w - 1.3, 1.3], [w - 1.3, h - 1.3], [1.3, h - 1.3], [1.3, 1.3]])
    return World("pillars", np.array(s, dtype=float), 2.5, np.array([6.0, 1.3, 0.0]), wp)


def _rooms() -> World:
    """Six identical 5 x 5 m rooms in a row north of a 32 m corridor (2.6 m wide).

    Every room has its door to the corridor 1.2 m from its west wall, a 1.5 m door in the
    middle of each side wall to its neighbours, a cabinet against its south wall and a desk
    by its north wall, all in the same places. The route walks east along the corridor, into
    the last room, west through all six rooms, out of the first and back along the corridor
    (57.6 m).
    """
    s: list[list[float]] = []
    length, c, room, n = 32.0, 2.6, 5.0, 6
    x0s = [1.0 + room * k for k in range(n)]
    top = c + room
    mid = c + room / 2.0
    # The corridor: south wall with some clutter of its own, end walls.
    s += _recessed_wall(0.0, 0.0, length, 0.0, (9.7, 21.0), 1.2, -0.3)
    s += _wall(0.0, 0.0, 0.0, c)
    s += _wall(length, 0.0, length, c)
    s += _box(3.5, 0.0, 4.7, 0.45) + _box(14.0, 0.0, 14.35, 0.35) + _box(25.5, 0.0, 27.0, 0.5)
    # The corridor's north wall, with every room's door 1.2 m from the room's west wall.
    s += _wall(0.0, c, length, c, tuple((x0 + 1.2, 1.5) for x0 in x0s))
    # The rooms' north wall and side walls (doors between neighbours in the middle).
    s += _wall(x0s[0], top, x0s[-1] + room, top)
    for k in range(n + 1):
        x = x0s[0] + room * k
        s += _wall(x, c, x, top, ((room / 2.0, 1.5),) if 0 < k < n else ())
    for x0 in x0s:
        s += _box(x0 + 3.2, c, x0 + 4.4, c + 0.5)  # cabinet
        s += _box(x0 + 2.9, top - 1.2, x0 + 4.3, top - 0.5)  # desk
        s += _box(x0 + 0.3, top - 0.6, x0 + 1.1, top)  # shelf
    xa, xb = x0s[0] + 1.2, x0s[-1] + 1.2
    wp = np.array([[5.0, c / 2.0], [xb, c / 2.0], [xb, mid], [xa, mid], [xa, c / 2.0]])
    return World("rooms", np.array(s, dtype=float), 2.5, np.array([5.0, c / 2.0, 0.0]), wp)


def _twins() -> World:
    """A 17 x 12.2 m building: three parallel corridors (A, B, C from the south, 2.6 m wide,
    3.2 m apart) walked as a serpentine, then a return corridor along the north and west.

    A and C have the same pattern (a 0.35 m pillar against the south wall and a door recess in
    the north wall every 3 m, the other way round 1.5 m on) and are both walked east, 6.4 m
    apart; B (walked west) and the return corridor have clutter of their own. Route 70.4 m.
    """
    s: list[list[float]] = []
    w, h, c, t = 17.0, 12.2, 2.6, 0.6
    pill = 0.35
    ya, yb, yc, yr = 0.0, c + t, 2 * (c + t), 3 * (c + t)  # south walls of A, B, C, R
    xe = w - c  # where the partitions A|B and C|R end (east turnarounds)
    xw = c + t + c  # where the partition B|C starts (west turnaround)
    xs_a = [4.0 + 3.0 * k for k in range(5)]  # 4 .. 16
    xs_b = [5.5 + 3.0 * k for k in range(4)]  # 5.5 .. 14.5
    s += _recessed_wall(0.0, ya, w, ya, tuple(xs_b), 1.0, -0.25)  # A south (outer wall)
    s += _wall(w, 0.0, w, h) + _wall(w, h, 0.0, h) + _wall(0.0, h, 0.0, 0.0)
    # The spine: partitions A|B and C|R joined by a wall west of B and C.
    north = tuple(x for x in xs_a if x + 0.6 < xe)
    s += _recessed_wall(c, c, xe, c, tuple(x - c for x in north), 1.0, 0.25)  # A north face
    s += [[xe, c, xe, c + t]]
    s += _wall(xe, yb, c + t, yb)  # B south face
    s += _wall(c + t, yb, c + t, yr - t)  # west of B and C
    s += _recessed_wall(c + t, yr - t, xe, yr - t, tuple(x - c - t for x in north), 1.0, 0.25)  # C north face
    s += [[xe, yr - t, xe, yr]]
    s += _wall(xe, yr, c, yr)  # R south face
    s += _wall(c, yr, c, c)  # east of the west corridor
    # Partition B|C, from the west turnaround to the east wall.
    s += _wall(xw, yc - t, w, yc - t)  # B north face
    s += [[xw, yc - t, xw, yc]]
    s += _recessed_wall(xw, yc, w, yc, tuple(x - xw for x in xs_b if x > xw + 0.6), 1.0, -0.25)  # C south face
    # Pillars: A and C alike (south wall at xs_a, north wall at xs_b).
    for y0 in (ya, yc):
        for x in xs_a:
            if y0 == ya or x > xw + 0.2:
                s += _box(x - pill / 2, y0, x + pill / 2, y0 + pill)
        for x in xs_b:
            if x < xe:
                s += _box(x - pill / 2, y0 + c - pill, x + pill / 2, y0 + c)
    # B, the return corridor and the west corridor: clutter of their own.
    s += _box(7.2, yb, 8.4, yb + 0.45) + _box(12.1, yb + c - 0.4, 12.5, yb + c)
    s += _box(w - 0.5, yb + 0.4, w, yb + 1.6)
    s += _box(5.0, h - 0.4, 6.6, h) + _box(10.3, yr, 10.7, yr + 0.4) + _box(13.5, h - 0.5, 14.2, h)
    s += _box(w - 0.6, h - 0.6, w, h)
    s += _box(0.0, 5.0, 0.45, 6.3) + _box(c - 0.35, 7.6, c, 7.95) + [[0.0, h - 0.9, 0.9, h]]
    xa, xb = c / 2.0, xe + c / 2.0
    wp = np.array(
        [
            [6.0, ya + c / 2],
            [xb, ya + c / 2],
            [xb, yb + c / 2],
            [xw - c / 2, yb + c / 2],
            [xw - c / 2, yc + c / 2],
            [xb, yc + c / 2],
            [xb, yr + c / 2],
            [xa, yr + c / 2],
            [xa, ya + c / 2],
        ]
    )
    return World("twins", np.array(s, dtype=float), 2.5, np.array([6.0, ya + c / 2, 0.0]), wp)


def _block() -> World:
    """A 35 x 19 m floor: a corridor 3 m wide all round a 29 x 13 m central block (walked
    runs of 32 and 16 m), three side rooms off the north corridor.

    Most of each corridor is bare parallel walls: a scan in the middle of a long run sees
    neither end within 15 m. What pins a place along a corridor is a handful of things beside
    the walked line that look alike: 0.4 m pillars and 1 m door notches (0.3 m deep) in the
    block every 8 m along the south corridor, a few more in the north and east ones, some
    clutter, and the side rooms' doors. The route walks the loop counter-clockwise from the
    south corridor (96 m a lap), as often as the walk lasts.
    """
    s: list[list[float]] = []
    w, h, c = 35.0, 19.0, 3.0
    pill = 0.4
    # Outer walls; the north one with a door into each side room.
    s += _wall(0.0, 0.0, w, 0.0)
    s += _wall(w, 0.0, w, h)
    s += _wall(w, h, 0.0, h, tuple((w - x, 1.0) for x in (9.5, 14.5, 19.5)))
    s += _wall(0.0, h, 0.0, 0.0)
    # The central block: notches into it every 8 m on the south face, a few on the others.
    s += _recessed_wall(c, c, w - c, c, tuple(x - c for x in (13.0, 21.0, 29.0)), 1.0, 0.3)  # south face
    s += _recessed_wall(w - c, c, w - c, h - c, (6.5,), 1.0, 0.3)  # east face
    s += _recessed_wall(w - c, h - c, c, h - c, tuple((w - c) - x for x in (7.0, 25.0)), 1.0, 0.3)  # north face
    s += _wall(c, h - c, c, c)  # west face
    # Pillars against the block (south corridor, every 8 m) and the outer north wall.
    for x in (9.0, 17.0, 25.0):
        s += _box(x - pill / 2, c - pill, x + pill / 2, c)
    for x in (5.0, 27.5):
        s += _box(x - pill / 2, h - pill, x + pill / 2, h)
    # Clutter beside the walked line.
    s += _box(4.0, 0.0, 5.2, 0.45)  # a cabinet, south corridor
    s += _box(w - 0.5, 12.0, w, 12.6)  # a bin, east corridor
    s += _box(0.0, 7.0, 0.5, 8.5)  # a cabinet, west corridor
    s += _box(c, 11.0, c + 0.4, 12.5)  # a bench against the block, west corridor
    # Three side rooms (5 x 5 m) north of the north corridor, a desk in each.
    s += _wall(8.0, h + 5.0, 23.0, h + 5.0)
    for x in (8.0, 13.0, 18.0, 23.0):
        s += _wall(x, h, x, h + 5.0)
    s += _box(9.0, 22.5, 10.4, 23.2) + _box(15.5, 21.0, 16.2, 22.4) + _box(19.0, 23.3, 21.0, h + 5.0)
    half = c / 2.0
    wp = np.array([[6.0, half], [w - half, half], [w - half, h - half], [half, h - half], [half, half]])
    return World("block", np.array(s, dtype=float), 2.5, np.array([6.0, half, 0.0]), wp)


def _colonnade() -> World:
    """A 36 x 20 m floor: a corridor 3 m wide all round a 30 x 14 m central block (walked runs
    of 33 and 17 m), lined with 0.5 m square pillars beside the walked line at uneven spacing
    (2.5-7 m), against the block and the outer walls, a few 1 m door notches between them,
    and bare walls otherwise.

    Along a corridor, what pins a scan is the pillars' faces: the face a pillar turns towards
    the robot and the one it turns away lie 0.5 m apart, so a scan that sees one pillar face
    fits a map of another 0.5 m along almost as well (issue 53's building, where a loop at
    the end of a lap slid by a pillar's width). The route drives the loop counter-clockwise
    from the south corridor (98 m a lap).
    """
    s: list[list[float]] = []
    w, h, c = 36.0, 20.0, 3.0
    pill = 0.5
    s += _wall(0.0, 0.0, w, 0.0)
    s += _wall(w, 0.0, w, h)
    s += _wall(w, h, 0.0, h)
    s += _wall(0.0, h, 0.0, 0.0)
    # the block: notches into it here and there
    s += _recessed_wall(c, c, w - c, c, tuple(x - c for x in (11.0, 24.5)), 1.0, 0.3)  # south face
    s += _recessed_wall(w - c, c, w - c, h - c, (8.0,), 1.0, 0.3)  # east face
    s += _recessed_wall(w - c, h - c, c, h - c, tuple((w - c) - x for x in (9.5, 27.0)), 1.0, 0.3)  # north face
    s += _wall(c, h - c, c, c)  # west face
    # 0.5 m pillars: against the block (south and north runs) and the outer walls, uneven spacing
    for x in (7.0, 13.5, 16.0, 21.5, 28.0):  # south corridor, against the block
        s += _box(x - pill / 2, c - pill, x + pill / 2, c)
    for x in (9.0, 19.0, 31.0):  # south corridor, against the outer wall
        s += _box(x - pill / 2, 0.0, x + pill / 2, pill)
    for y in (6.0, 12.5):  # east corridor, against the outer wall
        s += _box(w - pill, y - pill / 2, w, y + pill / 2)
    for x in (6.5, 12.0, 18.5, 25.0, 30.5):  # north corridor, against the block
        s += _box(x - pill / 2, h - c, x + pill / 2, h - c + pill)
    for x in (15.0, 22.0):  # north corridor, against the outer wall
        s += _box(x - pill / 2, h - pill, x + pill / 2, h)
    for y in (8.0, 14.5):  # west corridor, against the block
        s += _box(c, y - pill / 2, c + pill, y + pill / 2)
    half = c / 2.0
    wp = np.array([[6.0, half], [w - half, half], [w - half, h - half], [half, h - half], [half, half]])
    return World("colonnade", np.array(s, dtype=float), 2.5, np.array([6.0, half, 0.0]), wp)


def _bare() -> World:
    """A bare corridor 100 m long and 2.4 m wide, walked out and back: parallel walls with a
    door recess (1 m, 0.3 m deep) every 25 m, alternating sides, and nothing else. From its
    middle a 20 m laser sees one door or two and neither end: what pins a scan along the
    corridor is those few beams (the simulated analogue of MIT's infinite corridor)."""
    length, half = 100.0, 1.2
    s: list[list[float]] = []
    s += _wall(0.0, -half, 0.0, half)
    s += _wall(length, -half, length, half)
    s += _recessed_wall(0.0, half, length, half, (25.0, 75.0), 1.0, 0.3)  # north: recesses to the north
    s += _recessed_wall(length, -half, 0.0, -half, (length - 50.0,), 1.0, 0.3)  # south: to the south
    wp = np.array([[2.0, 0.0], [length - 2.0, 0.0]])
    return World("bare", np.array(s, dtype=float), 2.5, np.array([2.0, 0.0, 0.0]), wp)


def _hall() -> World:
    """An open hall 30 x 20 m with six 0.6 m pillars in two rows and a few crates, walked round
    a 20 x 10 m loop 5 m inside its walls: with a short-range laser (a 5.6 m Hokuyo URG) a scan
    sees the nearest wall, sometimes a corner, a pillar or two, and much of the time little
    else."""
    w, h = 30.0, 20.0
    s: list[list[float]] = []
    s += _wall(0.0, 0.0, w, 0.0, ((12.0, 2.0),))  # a wide door on the south side
    s += _wall(w, 0.0, w, h)
    s += _wall(w, h, 0.0, h)
    s += _wall(0.0, h, 0.0, 0.0)
    for x in (9.0, 15.0, 21.0):
        for y in (7.0, 13.0):
            s += _box(x - 0.3, y - 0.3, x + 0.3, y + 0.3)
    s += _box(26.5, 1.0, 28.0, 2.2) + _box(1.5, 15.0, 2.5, 17.5) + _box(12.0, 18.6, 14.0, 19.4)
    wp = np.array([[5.0, 5.0], [25.0, 5.0], [25.0, 15.0], [5.0, 15.0]])
    return World("hall", np.array(s, dtype=float), 2.5, np.array([5.0, 5.0, 0.0]), wp)


#: ``office`` (the demo's floor), ``corridor`` (out and back along one corridor), four
#: worlds whose places repeat, to fool a loop-closing back end: ``pillars``, ``rooms``,
#: ``twins`` and ``block`` (a corridor loop round a central block), and two where the walls
#: say little: ``bare`` (100 m of bare corridor, out and back) and ``hall`` (an open hall for
#: a short-range laser).
WORLDS: dict[str, World] = {
    w.name: w
    for w in (_office(), _corridor(), _pillars(), _rooms(), _twins(), _block(), _colonnade(), _bare(), _hall())
}
