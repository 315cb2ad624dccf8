"""Random buildings for the simulator: :func:`random_building` (the world ``random`` of
:func:`~pfslam.tools.places.world_named`, one building per seed).

A building is a corridor loop round one block (about 60 % of seeds) or round two blocks side
by side with a cross corridor between them, walked as a figure of eight through the cross
corridor; every corner is a right angle. One corridor width per building (2-4 m), straight
walked runs of 8-40 m, a lap of at most :data:`MAX_LAP` (so a humanoid walks one in under
300 s, pauses included). Along the walls that face the corridors (the outer walls and the
blocks' faces), at random spacing and at least a corridor width + 1 m from every corner:
pillars against the wall, notches in it, doors into side rooms (off the outer walls, some
with a piece of furniture) and doors into shallow recesses (in the blocks' faces), with long
bare stretches between them on most buildings. Half the buildings are mirrored about the
diagonal (x and y swapped), so some loops run clockwise. Every number comes from
``numpy.random.default_rng(seed)``.

:func:`building` returns the plan behind the world (width, runs, the features and where they
stand); :func:`route_clearance` measures how far the walked route keeps from the walls.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pfslam.geometry import wrap_angle
from pfslam.tools.worlds import World
from pfslam.types import Array

WIDTH = (2.0, 4.0)  # m: the corridors' width (one per building)
RUN = (8.0, 40.0)  # m: a straight walked run, corner to corner
MAX_LAP = 130.0  # m: the longest lap of the route (at 0.5 m/s 260 s, under 300 s with pauses)
TWO_BLOCKS = 0.4  # the share of buildings with two blocks
PILLAR = (0.3, 1.2)  # m: a pillar's width along its wall; square-ish, protruding <= width/2 - PILLAR_CLEAR
PILLAR_CLEAR = 0.5  # m: the walked centre line's clearance from the deepest pillar
NOTCH_WIDTH = (0.3, 1.2)  # m
NOTCH_DEPTH = (0.2, 0.5)  # m
DOOR = (0.8, 1.2)  # m: a door gap
ROOM = (3.0, 6.0)  # m: a side room's width (along its wall) and depth
RECESS_EXTRA = (0.4, 1.6)  # m: a recess behind a door in a block's face is this much wider than the door
RECESS_DEPTH = (0.4, 1.0)  # m
GAP = (0.5, 6.0)  # m: the spacing of features (its upper end drawn per building between 2 and 6 m)
LONG_GAP = (8.0, 14.0)  # m: a long bare stretch of wall
BARE = 8.0  # m: a wall without a feature this long is a bare stretch
CLEARANCE = 0.4  # m: every leg of the route keeps this far from every wall


@dataclass(frozen=True)
class Wall:
    """A straight wall along x (``horizontal``) or along y, at ``at`` on the other axis, from
    ``a`` to ``b`` along its own."""

    horizontal: bool
    at: float
    a: float
    b: float


@dataclass(frozen=True)
class Stretch:
    """The part of wall ``wall`` beside one straight run of corridor where features may stand:
    ``lo``..``hi`` along the wall (a corridor width + 1 m from the corners), the corridor on the
    side ``into`` (+1: towards larger values on the other axis, -1: smaller); ``outer``: an
    outer wall of the building (else a block's face)."""

    wall: int
    lo: float
    hi: float
    into: float
    outer: bool


@dataclass(frozen=True)
class Feature:
    """A feature on stretch ``stretch``: ``kind`` ``pillar`` (standing ``depth`` into the
    corridor), ``notch`` (a recess ``depth`` behind the wall), ``room`` (a side room ``depth``
    deep behind a door) or ``recess`` (a shallow recess behind a door). ``lo``..``hi``: its
    extent along the wall; ``door``: the door gap (``lo``..``hi`` for a notch); ``furniture``:
    a box in a room, ``(u0, d0, u1, d1)`` along the wall and behind it."""

    kind: str
    stretch: int
    lo: float
    hi: float
    depth: float
    door: tuple[float, float] | None = None
    furniture: tuple[float, float, float, float] | None = None


@dataclass
class Building:
    """A random building and the plan behind it (see :func:`building`).

    Attributes:
        seed: its seed.
        width: the corridors' width (m).
        blocks: 1 or 2.
        size: the outer walls' extent (m, x and y before any mirroring).
        mirrored: x and y swapped (walls, route and start) after the plan was laid out.
        walls, stretches, features: the plan, in the unmirrored frame.
        world: the world (walls, route, start), named ``random-SEED``.
    """

    seed: int
    width: float
    blocks: int
    size: tuple[float, float]
    mirrored: bool
    walls: list[Wall]
    stretches: list[Stretch]
    features: list[Feature]
    world: World

    def runs(self) -> list[float]:
        """The route's straight runs, corner to corner (m)."""
        return walked_runs(self.world.waypoints)

    def bare(self) -> float:
        """The longest stretch of a corridor wall with no feature on it (m), counted only
        where features may stand (so not the corners)."""
        best = 0.0
        for k, st in enumerate(self.stretches):
            edges = [st.lo]
            for f in sorted((f for f in self.features if f.stretch == k), key=lambda f: f.lo):
                best = max(best, f.lo - edges[-1])
                edges.append(f.hi)
            best = max(best, st.hi - edges[-1])
        return best


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    """A uniform draw rounded to the centimetre (still within ``lo``..``hi`` given in cm)."""
    return round(float(rng.uniform(lo, hi)), 2)


def building(seed: int) -> Building:
    """The random building of ``seed``, with its plan (see the module's text)."""
    rng = np.random.default_rng(seed)
    c = _u(rng, *WIDTH)
    two = bool(rng.random() < TWO_BLOCKS)
    if two:
        ry = _u(rng, RUN[0], min(RUN[1], (MAX_LAP - 4 * RUN[0]) / 4.0))  # the three runs across
        budget = (MAX_LAP - 4.0 * ry) / 2.0  # for the two blocks' runs along (each walked twice a lap)
        ra = _u(rng, RUN[0], min(RUN[1], budget - RUN[0]))
        rb = _u(rng, RUN[0], min(RUN[1], budget - ra))
        along = [ra, rb]
    else:
        rx = _u(rng, RUN[0], RUN[1])
        ry = _u(rng, RUN[0], min(RUN[1], MAX_LAP / 2.0 - rx))
        if rng.random() < 0.5:
            rx, ry = ry, rx
        along = [rx]
    # x of the outer walls and the blocks' sides: 0 | corridor | block | corridor | ... | w
    xs = [0.0]
    for r in along:
        xs += [xs[-1] + c, xs[-1] + r]  # a block spans run - c between two corridors
    w, h = xs[-1] + c, ry + c
    walls: list[Wall] = []
    stretches: list[Stretch] = []

    def wall(horizontal: bool, at: float, a: float, b: float) -> int:
        walls.append(Wall(horizontal, at, a, b))
        return len(walls) - 1

    def beside(k: int, lo: float, hi: float, into: float, outer: bool) -> None:
        """The stretch of wall ``k`` beside the corridor run between mouths ``lo`` and ``hi``."""
        stretches.append(Stretch(k, lo + c + 1.0, hi - c - 1.0, into, outer))

    south, north = wall(True, 0.0, 0.0, w), wall(True, h, 0.0, w)
    west, east = wall(False, 0.0, 0.0, h), wall(False, w, 0.0, h)
    beside(west, c, h - c, 1.0, True)
    beside(east, c, h - c, -1.0, True)
    for i in range(len(along)):
        x0, x1 = xs[2 * i + 1], xs[2 * i + 2]  # the block's sides
        beside(south, x0, x1, 1.0, True)
        beside(north, x0, x1, -1.0, True)
        beside(wall(True, c, x0, x1), x0, x1, -1.0, False)
        beside(wall(True, h - c, x0, x1), x0, x1, 1.0, False)
        beside(wall(False, x0, c, h - c), c, h - c, -1.0, False)
        beside(wall(False, x1, c, h - c), c, h - c, 1.0, False)
    features = _features(rng, c, stretches)

    half = c / 2.0
    xl, xr, yb, yt = half, w - half, half, h - half
    if two:
        xm = xs[2] + half  # the cross corridor's centre line
        start = round(xl + _u(rng, 0.25, 0.6) * (xm - xl), 2)
        route = [(start, yb), (xm, yb), (xm, yt), (xr, yt), (xr, yb), (xm, yb), (xm, yt), (xl, yt), (xl, yb)]
    else:
        start = round(xl + _u(rng, 0.25, 0.5) * (xr - xl), 2)
        route = [(start, yb), (xr, yb), (xr, yt), (xl, yt), (xl, yb)]
    segs = _segments(walls, stretches, features)
    wp = np.array(route, dtype=float)
    mirrored = bool(rng.random() < 0.5)
    if mirrored:
        segs, wp = segs[:, [1, 0, 3, 2]], wp[:, ::-1].copy()
    d = wp[1] - wp[0]
    world = World(f"random-{seed}", segs, 2.5, np.array([wp[0, 0], wp[0, 1], np.arctan2(d[1], d[0])]), wp)
    return Building(seed, c, 2 if two else 1, (w, h), mirrored, walls, stretches, features, world)


def random_building(seed: int) -> World:
    """The random building of ``seed`` (named ``random-SEED``; see the module's text)."""
    return building(seed).world


def _features(rng: np.random.Generator, c: float, stretches: list[Stretch]) -> list[Feature]:
    """Features along every stretch at random spacing, none overlapping another."""
    gap_hi = _u(rng, 2.0, GAP[1])  # how densely this building is dressed
    p_long = _u(rng, 0.1, 0.4)  # how often a long bare stretch comes between two features
    max_out = c / 2.0 - PILLAR_CLEAR  # a pillar's deepest: the walked centre line keeps PILLAR_CLEAR
    out: list[Feature] = []
    for k, st in enumerate(stretches):
        if st.hi - st.lo < PILLAR[0] or (st.hi - st.lo >= BARE and rng.random() < 0.15):  # too short, or left bare
            continue
        u = st.lo
        while True:
            long = rng.random() < p_long and st.hi - u >= LONG_GAP[1]  # (a short wall keeps a feature or two)
            u = round(u + (_u(rng, *LONG_GAP) if long else _u(rng, GAP[0], gap_hi)), 2)  # (to the cm)
            kind = str(rng.choice(["pillar", "notch", "room"] if st.outer else ["pillar", "notch", "recess"]))
            f: Feature
            if kind == "pillar":
                size = _u(rng, *PILLAR)
                depth = min(round(max(size * float(rng.uniform(0.75, 1.25)), 0.2), 2), max_out)
                f = Feature(kind, k, u, round(u + size, 2), depth)
            elif kind == "notch":
                size = _u(rng, *NOTCH_WIDTH)
                f = Feature(kind, k, u, round(u + size, 2), _u(rng, *NOTCH_DEPTH), (u, round(u + size, 2)))
            elif kind == "room":
                size, depth, door = _u(rng, *ROOM), _u(rng, *ROOM), _u(rng, *DOOR)
                d0 = round(u + _u(rng, 0.3, size - door - 0.3), 2)
                furniture = None
                if rng.random() < 0.6:  # a desk or a cabinet in the room's back half
                    fu = _u(rng, 0.5, min(1.8, size - 0.6))
                    fd = _u(rng, 0.5, min(1.2, depth / 2.0 - 0.3))
                    a = round(u + _u(rng, 0.3, size - 0.3 - fu), 2)
                    b = round(_u(rng, depth / 2.0, depth - 0.3 - fd), 2)
                    furniture = (a, b, round(a + fu, 2), round(b + fd, 2))
                f = Feature(kind, k, u, round(u + size, 2), depth, (d0, round(d0 + door, 2)), furniture)
            else:  # a door into a shallow recess in the block
                door = _u(rng, *DOOR)
                size = round(door + _u(rng, *RECESS_EXTRA), 2)
                d0 = round(u + _u(rng, 0.1, size - door - 0.1), 2)
                f = Feature(kind, k, u, round(u + size, 2), _u(rng, *RECESS_DEPTH), (d0, round(d0 + door, 2)))
            if f.hi > st.hi:
                break
            out.append(f)
            u = f.hi
    return out


def _segments(walls: list[Wall], stretches: list[Stretch], features: list[Feature]) -> Array:
    """The plan's wall segments (K, 4): the walls cut by the features' door gaps and notches,
    and the features' own walls."""
    gaps: list[list[tuple[float, float]]] = [[] for _ in walls]
    out: list[list[float]] = []

    def pt(st: Stretch, u: float, d: float) -> tuple[float, float]:
        """The point ``u`` along the stretch's wall, ``d`` from it into the corridor (< 0: behind)."""
        wl = walls[st.wall]
        v = wl.at + st.into * d
        return (u, v) if wl.horizontal else (v, u)

    def seg(st: Stretch, u0: float, d0: float, u1: float, d1: float) -> None:
        out.append([*pt(st, u0, d0), *pt(st, u1, d1)])

    for f in features:
        st = stretches[f.stretch]
        if f.door is not None:
            gaps[st.wall].append(f.door)
        d = f.depth if f.kind == "pillar" else -f.depth
        seg(st, f.lo, 0.0, f.lo, d)
        seg(st, f.lo, d, f.hi, d)
        seg(st, f.hi, d, f.hi, 0.0)
        if f.furniture is not None:
            u0, b0, u1, b1 = f.furniture
            seg(st, u0, -b0, u1, -b0)
            seg(st, u1, -b0, u1, -b1)
            seg(st, u1, -b1, u0, -b1)
            seg(st, u0, -b1, u0, -b0)
    for wl, cut in zip(walls, gaps):
        edges = [wl.a]
        for g0, g1 in sorted(cut):
            edges += [g0, g1]
        edges.append(wl.b)
        for a, b in zip(edges[0::2], edges[1::2]):
            if b - a > 1e-9:
                out.append([a, wl.at, b, wl.at] if wl.horizontal else [wl.at, a, wl.at, b])
    return np.array(out, dtype=float)


# --- the route's geometry -----------------------------------------------------------------


def walked_runs(waypoints: Array) -> list[float]:
    """The straight runs (m) of the closed route through ``waypoints``, corner to corner
    (legs in line with each other make one run)."""
    wp = np.asarray(waypoints, dtype=float)
    d = np.roll(wp, -1, axis=0) - wp  # leg i: waypoint i to i + 1
    length = np.hypot(d[:, 0], d[:, 1])
    heading = np.arctan2(d[:, 1], d[:, 0])
    corner = np.abs(wrap_angle(heading - np.roll(heading, 1))) > 1e-9  # at waypoint i
    if not corner.any():
        return [float(length.sum())]
    first = int(np.argmax(corner))
    runs: list[float] = []
    for j in range(len(wp)):
        i = (first + j) % len(wp)
        if corner[i]:
            runs.append(0.0)
        runs[-1] += float(length[i])
    return runs


def lap_length(world: World) -> float:
    """The length of one lap of the world's route (the closed polyline of its waypoints, m)."""
    wp = np.asarray(world.waypoints, dtype=float)
    return float(np.sum(np.linalg.norm(np.roll(wp, -1, axis=0) - wp, axis=1)))


def _point_segment(p: Array, a: Array, b: Array) -> Array:
    """Distances from points ``p`` (..., 2) to segments ``a``-``b`` (..., 2), broadcast."""
    e = b - a
    t = np.clip(np.sum((p - a) * e, axis=-1) / np.maximum(np.sum(e * e, axis=-1), 1e-18), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[..., None] * e), axis=-1)


def segment_distances(legs: Array, walls: Array) -> Array:
    """(P, K) distances between segments ``legs`` (P, 4) and ``walls`` (K, 4), each
    ``[x0, y0, x1, y1]``: 0 where they cross."""
    a0, a1 = legs[:, None, :2], legs[:, None, 2:]
    b0, b1 = walls[None, :, :2], walls[None, :, 2:]
    d = np.minimum.reduce(
        [_point_segment(a0, b0, b1), _point_segment(a1, b0, b1), _point_segment(b0, a0, a1), _point_segment(b1, a0, a1)]
    )

    def side(p: Array, q: Array, r: Array) -> Array:
        return np.sign(
            (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])
        )

    cross = (side(a0, a1, b0) * side(a0, a1, b1) < 0) & (side(b0, b1, a0) * side(b0, b1, a1) < 0)
    return np.where(cross, 0.0, d)


def route_clearance(world: World) -> float:
    """How close (m) the world's route (the closed polyline of its waypoints) comes to a wall."""
    wp = np.asarray(world.waypoints, dtype=float)
    legs = np.hstack([wp, np.roll(wp, -1, axis=0)])
    return float(segment_distances(legs, np.asarray(world.segments, dtype=float)).min())
