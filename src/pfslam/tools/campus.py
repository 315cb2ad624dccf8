"""An outdoor campus for the simulator: :func:`campus_world` (the world ``campus`` of
:func:`~pfslam.tools.places.world_named`, one campus per seed), modelled on the University of
Freiburg campus log that GMapping's paper maps: about 250 x 250 m of buildings, streets and
lawns, a 1.75 km drive, a SICK LMS reaching 80 m (:data:`SICK_RANGE`).

The campus is a grid of streets, :data:`CELLS` x :data:`CELLS` cells between their centre
lines (:data:`SPACING` apart: 210-290 m from the first to the last), each street
:data:`HALF_STREET` from its centre line to the building line on either side. The north-east
2 x 2 cells are one lawn with no street through it, reaching :data:`LAWN_BEYOND` past the
grid to the north and east (145-190 m a side): from its far part, 90 m and more from any
building, a laser sees a few trees and lamp poles and most of its beams return nothing (the
open north-east of the Freiburg log). Every other cell holds one building, two side by side,
or a car park.

A building is a rectangle or an L, 20-60 m a side (:data:`BLOCK`), some of them turned by
8-35 deg (:data:`TURNED`, :data:`TURN_DEG`); along its facades, at random spacing with some
facades bare, recessed entrances, bays and flights of steps 0.5-3 m deep (:data:`RECESS`,
:data:`BAY`, :data:`STAIRS`). Along each side of each street, between two crossings: a row
of trees (trunks as 6-8 sided polygons, :data:`TREE`), of lamp poles (:data:`POLE`), of
parked cars (:data:`CAR`), a low wall with gates along the building line (:data:`WALL_PIECE`),
or nothing (:data:`VERGES`: the campus's outer streets mostly have its boundary wall on their
outer side). A car park: rows of cars nose in, a low wall round it. On the lawn: lamp poles
along its path, a few trees. Every wall stands :data:`WALL_HEIGHT` tall (facades, low walls,
cars and trunks alike: the laser is at 0.3 m).

The route (a closed polyline, :data:`ROUTE` long) drives along the streets' centre lines
round a chain of 3-5 neighbouring cells (:data:`LAPS`), each once round (a lap of 210-290 m
that comes back to where it began) and on round to a corner of the next; from the last, out
along a footpath across the lawn to a fork, round a loop through the lawn's far part
(:data:`LAWN_LOOP`), back to the fork and the streets, and along them to the start (part way
along a street, facing along it). So the route comes back to places it passed 100-400 m
before at least :data:`MIN_RETURNS` times. Trees, poles and cars that would stand within
:data:`CLEARANCE` of the route are left out; the rest of the campus keeps further away by
construction. Every number comes from ``numpy.random.default_rng(seed)``.

:func:`campus` returns the plan behind the world; :func:`route_points`, :func:`returns`,
:func:`segments_within` and :func:`open_share` measure a route's loops and how much a laser
sees along it.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np

from pfslam.tools.buildings import lap_length, segment_distances
from pfslam.tools.worlds import World
from pfslam.types import Array

CELLS = 4  # cells along each side of the street grid (the north-east 2 x 2 are the lawn)
LAWN_FROM = 2  # the lawn: cells (i, j) with i and j >= this
SPACING = (52.0, 72.0)  # m: between neighbouring streets' centre lines
HALF_STREET = (5.0, 8.0)  # m: a street's centre line to the building line either side (one per street)
LAWN_BEYOND = (40.0, 60.0)  # m: the lawn reaches this far north and east of the outermost streets' centre lines
BLOCK = (20.0, 60.0)  # m: a building's side
L_SHAPED = 0.35  # the share of buildings that are an L (a rectangle with a corner cut out)
L_CUT = (0.35, 0.6)  # the cut corner's share of either side
TURNED = 0.35  # the share of buildings turned off the street grid
TURN_DEG = (8.0, 35.0)  # deg, either way
PAIR = 0.35  # the share of cells (where two fit) with two buildings side by side
PAIR_GAP = (5.0, 9.0)  # m: between them
PARKING = 0.12  # the share of cells that are a car park
CORNER = 3.5  # m: no facade feature nearer a building's corner than this (> PROTRUDE: none meet there)
FEATURE_GAP = (3.0, 14.0)  # m: between facade features
BARE_FACADE = 0.2  # the share of facades with no feature
RECESS = ((1.0, 3.0), (0.5, 3.0))  # m: an entrance or niche set into a facade, width and depth
BAY = ((2.0, 8.0), (0.5, 3.0))  # m: a part of a facade standing out, width and depth
STAIRS = ((2.0, 5.0), (0.3, 0.6), (2, 4))  # m, m, count: a flight's width, each step's depth, the steps
STEP_INSET = 0.25  # m: each step narrower than the one below by this on either side
PROTRUDE = 3.0  # m: the deepest any feature stands out of its facade (BAY, STAIRS)
TREE = (0.2, 0.6)  # m: a trunk's width (a polygon of 6-8 sides)
TREE_PITCH = (7.0, 14.0)  # m: along a row of trees
POLE = (0.1, 0.2)  # m: a lamp pole's width (a hexagon)
POLE_PITCH = (25.0, 40.0)  # m: along a row of lamp poles
CAR = ((1.7, 1.9), (4.0, 4.9))  # m: a car's width and length
CAR_GAP = (0.7, 2.5)  # m: between parked cars, bumper to bumper
CAR_TAKEN = 0.75  # the share of parking places taken
STALL = (2.5, 5.0)  # m: a car park's place, width and depth
AISLE = 6.5  # m: a car park's aisle
WALL_PIECE = (6.0, 25.0)  # m: a low wall's stretch between two gates
GATE = (1.5, 4.0)  # m: a gate in a low wall
LAWN_TREES = (2, 6)  # scattered over the lawn
LAWN_POLE_PITCH = (50.0, 80.0)  # m: lamp poles along the lawn's path
LAWN_LOOP = (150.0, 400.0)  # m: the footpath's loop round the lawn's far part
LAPS = (3, 5)  # cells driven round
ROUTE = (1200.0, 1950.0)  # m: one lap of the whole route
MIN_RETURNS = 3  # times at least the route comes back to a place it passed 100-400 m before (see returns)
CLEARANCE = 1.5  # m: every segment keeps this far from the route
WALL_HEIGHT = 3.0  # m: every wall (facades, low walls, cars and trunks alike)


SICK_RANGE = 80.0  # m: the Freiburg campus robot's SICK LMS: its reach,
SICK_BEAMS = 361  # its beams,
SICK_FOV_DEG = 180.0  # over this field of view (half a degree apart)
DRIVE_SPEED = 1.0  # m/s: the robot's speed

Node = tuple[int, int]


@dataclass
class Campus:
    """A campus and the plan behind it (see :func:`campus`).

    Attributes:
        seed: its seed.
        xs, ys: the streets' centre lines (m): x of the streets along y, y of those along x.
        half_x, half_y: each street's half width (centre line to building line, m).
        cells: each cell's kind, by (i, j) (i along x): ``building``, ``pair``, ``parking`` or ``lawn``.
        lawn: the lawn's extent ``(x0, y0, x1, y1)`` (m).
        laps: the cells the route drives round, in order.
        counts: how many buildings (``turned`` of them off the grid, ``l_shaped`` an L), trees, poles,
            cars, and segments of each kind (``*_segments``) the campus has.
        world: the world (walls, route, start), named ``campus-SEED``.
    """

    seed: int
    xs: Array
    ys: Array
    half_x: Array
    half_y: Array
    cells: dict[Node, str]
    lawn: tuple[float, float, float, float]
    laps: list[Node]
    counts: dict[str, int]
    world: World


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    """A uniform draw rounded to the centimetre."""
    return round(float(rng.uniform(lo, hi)), 2)


def _polygon(cx: float, cy: float, width: float, sides: int, phase: float) -> Array:
    """A regular polygon ``width`` across (between opposite corners) round (cx, cy): its sides (sides, 4)."""
    a = phase + 2.0 * np.pi * np.arange(sides + 1) / sides
    px, py = cx + 0.5 * width * np.cos(a), cy + 0.5 * width * np.sin(a)
    return np.column_stack([px[:-1], py[:-1], px[1:], py[1:]])


def _rectangle(cx: float, cy: float, length: float, width: float, heading: float) -> Array:
    """A rectangle ``length`` along ``heading`` and ``width`` across, centred on (cx, cy): (4, 4)."""
    c, s = np.cos(heading), np.sin(heading)
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float) * [0.5 * length, 0.5 * width]
    pts = np.column_stack([cx + c * corners[:, 0] - s * corners[:, 1], cy + s * corners[:, 0] + c * corners[:, 1]])
    return np.hstack([pts, np.roll(pts, -1, axis=0)])


def _closed(pts: Array) -> Array:
    """The sides (N, 4) of the closed polygon through ``pts`` (N, 2)."""
    return np.hstack([pts, np.roll(pts, -1, axis=0)])


# --- buildings ------------------------------------------------------------------------------


def _facade(rng: np.random.Generator, a: Array, b: Array) -> list[Array]:
    """The points of a facade from corner ``a`` towards ``b`` (the next corner, not included),
    with its features; the building lies to the left (its outline counter-clockwise)."""
    length = float(np.hypot(*(b - a)))
    e = (b - a) / length
    n = np.array([e[1], -e[0]])  # outwards
    out = [a]
    if rng.random() < BARE_FACADE:
        return out
    u = CORNER + _u(rng, 0.0, FEATURE_GAP[1] / 2.0)
    while True:
        kind = str(rng.choice(["recess", "bay", "stairs"], p=[0.45, 0.3, 0.25]))
        if kind == "recess":
            w, d = _u(rng, *RECESS[0]), -_u(rng, *RECESS[1])
            profile = [(0.0, 0.0), (0.0, d), (w, d), (w, 0.0)]
        elif kind == "bay":
            w, d = _u(rng, *BAY[0]), _u(rng, *BAY[1])
            profile = [(0.0, 0.0), (0.0, d), (w, d), (w, 0.0)]
        else:
            w, step = _u(rng, *STAIRS[0]), _u(rng, *STAIRS[1])
            steps = int(rng.integers(STAIRS[2][0], STAIRS[2][1] + 1))
            profile = []  # out step by step on one side, along the top step, back down the other
            for k in range(steps):
                profile += [(k * STEP_INSET, k * step), (k * STEP_INSET, (k + 1) * step)]
            for k in reversed(range(steps)):
                profile += [(w - k * STEP_INSET, (k + 1) * step), (w - k * STEP_INSET, k * step)]
        if u + w > length - CORNER:
            break
        out += [a + e * (u + du) + n * dd for du, dd in profile]
        u += w + _u(rng, *FEATURE_GAP)
    return out


def _building(rng: np.random.Generator, area: tuple[float, float, float, float], counts: dict[str, int]) -> list[Array]:
    """A building within ``area`` (x0, y0, x1, y1: its features included): its facades' segments."""
    x0, y0, x1, y1 = area
    aw, ah = x1 - x0 - 2 * PROTRUDE, y1 - y0 - 2 * PROTRUDE
    turned = rng.random() < TURNED
    angle = float(np.deg2rad(_u(rng, *TURN_DEG))) * float(rng.choice([-1.0, 1.0])) if turned else 0.0
    w = _u(rng, BLOCK[0], max(BLOCK[0], min(BLOCK[1], aw)))
    h = _u(rng, BLOCK[0], max(BLOCK[0], min(BLOCK[1], ah)))
    c, s = abs(np.cos(angle)), abs(np.sin(angle))
    fit = min(aw / (w * c + h * s), ah / (w * s + h * c), 1.0)
    if fit * min(w, h) < BLOCK[0]:  # turned it would not fit: square to the streets
        angle, fit = 0.0, min(aw / w, ah / h, 1.0)
    w, h = round(w * fit, 2), round(h * fit, 2)
    pts = [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)]
    l_shaped = rng.random() < L_SHAPED
    if l_shaped:  # cut a corner out: the north-east one, or (mirrored, upside down) another
        cw, ch = round(w * _u(rng, *L_CUT), 2), round(h * _u(rng, *L_CUT), 2)
        pts = [(0.0, 0.0), (w, 0.0), (w, h - ch), (w - cw, h - ch), (w - cw, h), (0.0, h)]
        if rng.random() < 0.5:  # mirrored: the north-west corner cut instead
            pts = [(w - x, y) for x, y in reversed(pts)]
        if rng.random() < 0.5:  # upside down: a south corner cut
            pts = [(w - x, h - y) for x, y in pts]
    corners = np.array(pts) - [w / 2.0, h / 2.0]
    outline: list[Array] = []
    for k in range(len(corners)):
        outline += _facade(rng, corners[k], corners[(k + 1) % len(corners)])
    local = np.array(outline)
    cos, sin = np.cos(angle), np.sin(angle)
    xy = np.column_stack([cos * local[:, 0] - sin * local[:, 1], sin * local[:, 0] + cos * local[:, 1]])
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    room = np.array([x1 - x0, y1 - y0]) - (hi - lo)  # the slack left in the area, >= 0
    xy += np.array([x0, y0]) - lo + np.maximum(room, 0.0) * rng.uniform(0.2, 0.8, 2)
    counts["buildings"] += 1
    counts["turned"] += angle != 0.0
    counts["l_shaped"] += l_shaped
    return [_closed(xy)]


def _car_park(
    rng: np.random.Generator, area: tuple[float, float, float, float], counts: dict[str, int]
) -> tuple[list[Array], list[Array]]:
    """A car park filling ``area``: rows of cars nose in along its longer side, the rows back to
    back in pairs between aisles; a low wall round it with an entrance in one side. Its cars'
    segments, its wall's."""
    x0, y0, x1, y1 = area
    along_x = x1 - x0 >= y1 - y0
    length, depth = (x1 - x0, y1 - y0) if along_x else (y1 - y0, x1 - x0)

    def at(u: float, v: float) -> tuple[float, float]:
        return (x0 + u, y0 + v) if along_x else (x0 + v, y0 + u)

    cars: list[Array] = []
    v = 1.0 + AISLE  # an aisle along the wall first
    rows: list[float] = []  # each row's middle, across the car park
    while v + STALL[1] <= depth - 1.0 - AISLE:
        rows.append(v + STALL[1] / 2.0)
        v += STALL[1]
        if v + STALL[1] <= depth - 1.0 - AISLE:  # and one back to back with it
            rows.append(v + STALL[1] / 2.0)
            v += STALL[1]
        v += AISLE
    stalls = int((length - 2.0 - 2 * AISLE) // STALL[0])
    for mid in rows:
        for k in range(stalls):
            if rng.random() >= CAR_TAKEN:
                continue
            u = 1.0 + AISLE + (k + 0.5) * STALL[0] + _u(rng, -0.15, 0.15)
            cx, cy = at(u, mid + _u(rng, -0.1, 0.1))
            heading = (np.pi / 2.0 if along_x else 0.0) + float(np.deg2rad(_u(rng, -3.0, 3.0)))
            long = _u(rng, CAR[1][0], STALL[1] - 0.4)  # clear of the car nose to nose with it
            cars.append(_rectangle(cx, cy, long, _u(rng, *CAR[0]), heading))
            counts["cars"] += 1
    # the low wall, an entrance of two aisles' width in one side
    corners = np.array([at(0.5, 0.5), at(length - 0.5, 0.5), at(length - 0.5, depth - 0.5), at(0.5, depth - 0.5)])
    side = int(rng.integers(4))
    wall: list[Array] = []
    for k in range(4):
        a, b = corners[k], corners[(k + 1) % 4]
        if k == side:
            f = _u(rng, 0.3, 0.7)
            gap = 2 * AISLE / float(np.hypot(*(b - a)))
            wall.append(np.array([[*a, *(a + (f - gap / 2) * (b - a))], [*(a + (f + gap / 2) * (b - a)), *b]]))
        else:
            wall.append(np.array([[*a, *b]]))
    return cars, wall


# --- along the streets -----------------------------------------------------------------------


def _row(rng: np.random.Generator, kind: str, lo: float, hi: float, half: float, counts: dict[str, int]) -> list[Array]:
    """A street side's row of ``kind`` in a frame along the street: ``u`` from ``lo`` to ``hi``
    along it, ``v`` across (> 0, out from the centre line; ``half``: the building line's)."""
    out: list[Array] = []
    if kind == "trees":
        v, pitch = _u(rng, 3.0, half - 1.0), _u(rng, *TREE_PITCH)
        u = lo + _u(rng, 0.0, pitch / 2.0)
        while u <= hi:
            d = _u(rng, *TREE)
            out.append(_polygon(u, v + _u(rng, -0.3, 0.3), d, int(rng.integers(6, 9)), _u(rng, 0.0, np.pi)))
            counts["trees"] += 1
            u += pitch + _u(rng, -1.0, 1.0)
    elif kind == "poles":
        v, pitch = _u(rng, 2.5, half - 0.5), _u(rng, *POLE_PITCH)
        u = lo + _u(rng, 0.0, pitch / 2.0)
        while u <= hi:
            out.append(_polygon(u, v, _u(rng, *POLE), 6, 0.0))
            counts["poles"] += 1
            u += pitch
    elif kind == "cars":
        v = _u(rng, 2.9, min(4.0, half - 1.2))
        u = lo + _u(rng, 0.0, 3.0)
        while True:
            length = _u(rng, *CAR[1])
            if u + length > hi:
                break
            if rng.random() < CAR_TAKEN:
                heading = float(np.deg2rad(_u(rng, -2.0, 2.0)))
                out.append(_rectangle(u + length / 2.0, v + _u(rng, -0.15, 0.15), length, _u(rng, *CAR[0]), heading))
                counts["cars"] += 1
            u += length + _u(rng, *CAR_GAP)
    elif kind == "wall":
        v = half - 0.5
        u = lo
        while hi - u >= GATE[1]:  # (no stub of a wall at the end)
            end = min(hi, u + _u(rng, *WALL_PIECE))
            out.append(np.array([[u, v, end, v]]))
            u = end + _u(rng, *GATE)
    return out


#: What stands along a street side, by what lies behind it: weights of trees, poles, cars, a low wall, nothing.
VERGES = {
    "building": (0.3, 0.2, 0.25, 0.1, 0.15),
    "lawn": (0.35, 0.25, 0.0, 0.0, 0.4),
    "outside": (0.2, 0.1, 0.0, 0.5, 0.2),
}
VERGE_KINDS = ("trees", "poles", "cars", "wall", "none")
ONE = {"trees": "tree", "poles": "pole", "cars": "car"}  # a row's items


# --- the route ---------------------------------------------------------------------------------


def _corners(cell: Node) -> list[Node]:
    """A cell's corners (grid nodes), counter-clockwise from its south-west one."""
    i, j = cell
    return [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]


def _shortest(edges: dict[Node, list[Node]], pos: dict[Node, Array], a: Node, b: Node) -> list[Node]:
    """The shortest street path from node ``a`` to ``b`` (both ends included)."""
    best = {a: 0.0}
    prev: dict[Node, Node] = {}
    heap = [(0.0, a)]
    while heap:
        d, n = heapq.heappop(heap)
        if n == b:
            break
        if d > best[n]:
            continue
        for m in edges[n]:
            dm = d + float(np.hypot(*(pos[m] - pos[n])))
            if dm < best.get(m, np.inf) - 1e-9:
                best[m], prev[m] = dm, n
                heapq.heappush(heap, (dm, m))
    path = [b]
    while path[-1] != a:
        path.append(prev[path[-1]])
    return path[::-1]


def _chain(rng: np.random.Generator, built: list[Node], k: int) -> list[Node]:
    """``k`` distinct neighbouring built cells, the last one at a corner of the lawn."""
    ends = [c for c in built if (LAWN_FROM, LAWN_FROM) in _corners(c)]
    while True:
        chain = [ends[int(rng.integers(len(ends)))]]
        while len(chain) < k:
            i, j = chain[-1]
            nxt = [c for c in ((i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1)) if c in built and c not in chain]
            if not nxt:
                break
            chain.append(nxt[int(rng.integers(len(nxt)))])
        if len(chain) == k:
            return chain[::-1]


def _street_walk(rng: np.random.Generator, chain: list[Node]) -> tuple[list[Node], Node]:
    """The nodes of the drive round each cell of ``chain`` in turn, from a corner of the first,
    each lap carried on round to a corner the next cell shares; it ends at the lawn's corner
    node, the start node returned beside it."""
    start = _corners(chain[0])[int(rng.integers(4))]
    walk = [start]
    for m, cell in enumerate(chain):
        ring = _corners(cell)
        k = ring.index(walk[-1])
        ccw = [ring[(k + q) % 4] for q in range(5)]
        cw = ccw[::-1]
        prev = walk[-2] if len(walk) > 1 else None
        way = ccw if rng.random() < 0.5 else cw
        if way[1] == prev:  # not straight back the way it came
            way = cw if way is ccw else ccw
        walk += way[1:]
        target = {(LAWN_FROM, LAWN_FROM)} if m == len(chain) - 1 else set(_corners(chain[m + 1]))
        q = 0
        while way[q % 4] not in target:  # on round the cell the same way
            q += 1
            walk.append(way[q % 4])
    return walk, start


def _cancel_spurs(nodes: list[Node]) -> list[Node]:
    """The closed walk ``nodes`` (first == last) without its out-and-back bits (a -> b -> a)."""
    ring = nodes[:-1]
    changed = True
    while changed and len(ring) > 2:
        changed = False
        for k in range(len(ring)):
            if ring[k - 1] == ring[(k + 1) % len(ring)]:  # back the way it came at ring[k]
                drop = {k, (k + 1) % len(ring)}
                ring = [n for q, n in enumerate(ring) if q not in drop]
                changed = True
                break
    return ring + ring[:1]


def _simplify(wp: Array) -> Array:
    """The closed route ``wp`` without the points it goes straight through (its first kept)."""
    keep = [0]
    n = len(wp)
    for k in range(1, n):
        a, b, c = wp[keep[-1]], wp[k], wp[(k + 1) % n]
        cross = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])
        ahead = (b[0] - a[0]) * (c[0] - b[0]) + (b[1] - a[1]) * (c[1] - b[1])
        if abs(cross) > 1e-6 or ahead <= 0.0:
            keep.append(k)
    return wp[keep]


# --- the campus -----------------------------------------------------------------------------


def campus(seed: int) -> Campus:
    """The campus of ``seed``, with its plan (see the module's text)."""
    rng = np.random.default_rng(seed)
    xs = np.concatenate([[0.0], np.cumsum([_u(rng, *SPACING) for _ in range(CELLS)])])
    ys = np.concatenate([[0.0], np.cumsum([_u(rng, *SPACING) for _ in range(CELLS)])])
    hx = np.array([_u(rng, *HALF_STREET) for _ in range(CELLS + 1)])
    hy = np.array([_u(rng, *HALF_STREET) for _ in range(CELLS + 1)])
    east, north = xs[-1] + _u(rng, *LAWN_BEYOND), ys[-1] + _u(rng, *LAWN_BEYOND)
    lawn = (float(xs[LAWN_FROM] + hx[LAWN_FROM]), float(ys[LAWN_FROM] + hy[LAWN_FROM]), float(east), float(north))
    counts = dict.fromkeys(("buildings", "turned", "l_shaped", "trees", "poles", "cars"), 0)

    def kind(i: int, j: int) -> str:
        if not (0 <= i < CELLS and 0 <= j < CELLS):
            return "outside"
        return cells[(i, j)] if (i, j) in cells else "lawn"

    def area(i: int, j: int) -> tuple[float, float, float, float]:
        return (xs[i] + hx[i], ys[j] + hy[j], xs[i + 1] - hx[i + 1], ys[j + 1] - hy[j + 1])

    # The cells: buildings (one or two), car parks; the lawn.
    cells: dict[Node, str] = {}
    fixed: list[Array] = []  # facades and low walls
    loose: list[tuple[str, Array]] = []  # trees, poles and cars: left out where the route passes
    for i in range(CELLS):
        for j in range(CELLS):
            if i >= LAWN_FROM and j >= LAWN_FROM:
                cells[(i, j)] = "lawn"
                continue
            x0, y0, x1, y1 = area(i, j)
            gap = _u(rng, *PAIR_GAP)
            least = BLOCK[0] + 2 * PROTRUDE  # a building's area
            two = max(x1 - x0, y1 - y0) >= 2 * least + gap
            r = rng.random()
            if r < PARKING:
                cells[(i, j)] = "parking"
                cars, wall = _car_park(rng, (x0, y0, x1, y1), counts)
                fixed += wall
                loose += [("car", car) for car in cars]
            elif two and r < PARKING + PAIR:
                cells[(i, j)] = "pair"
                if x1 - x0 >= y1 - y0:
                    mid = _u(rng, x0 + least, x1 - gap - least)
                    halves = [(x0, y0, mid, y1), (mid + gap, y0, x1, y1)]
                else:
                    mid = _u(rng, y0 + least, y1 - gap - least)
                    halves = [(x0, y0, x1, mid), (x0, mid + gap, x1, y1)]
                for half in halves:
                    fixed += _building(rng, half, counts)
            else:
                cells[(i, j)] = "building"
                fixed += _building(rng, (x0, y0, x1, y1), counts)

    # The streets: a stretch between two crossings is a street if a built cell lies beside it.
    pos: dict[Node, Array] = {(i, j): np.array([xs[i], ys[j]]) for i in range(CELLS + 1) for j in range(CELLS + 1)}
    edges: dict[Node, list[Node]] = {n: [] for n in pos}
    for i in range(CELLS + 1):
        for j in range(CELLS + 1):
            for di, dj in ((1, 0), (0, 1)):
                if i + di > CELLS or j + dj > CELLS:
                    continue
                beside = [(i, j - 1), (i, j)] if di else [(i - 1, j), (i, j)]  # south, north / west, east
                kinds = [kind(*c) for c in beside]
                if all(k in ("lawn", "outside") for k in kinds):
                    continue
                edges[(i, j)].append((i + di, j + dj))
                edges[(i + di, j + dj)].append((i, j))
                if di:  # along x at ys[j], from xs[i] to xs[i + 1]
                    lo, hi = xs[i] + hx[i] + 1.5, xs[i + 1] - hx[i + 1] - 1.5
                    half = hy[j]
                else:
                    lo, hi = ys[j] + hy[j] + 1.5, ys[j + 1] - hy[j + 1] - 1.5
                    half = hx[i]
                for side, behind in zip((-1.0, 1.0), kinds):
                    weights = VERGES["building" if behind in ("pair", "parking") else behind]
                    what = VERGE_KINDS[int(rng.choice(len(VERGE_KINDS), p=weights))]
                    for item in _row(rng, what, lo, hi, half, counts):
                        u0, v0, u1, v1 = item[:, 0], side * item[:, 1], item[:, 2], side * item[:, 3]
                        if di:
                            seg = np.column_stack([u0, ys[j] + v0, u1, ys[j] + v1])
                        else:
                            seg = np.column_stack([xs[i] + v0, u0, xs[i] + v1, u1])
                        if what == "wall":
                            fixed.append(seg)
                        else:
                            loose.append((ONE[what], seg))

    # The route: round the chain of cells, round the lawn, back to the start.
    built = [c for c, k in cells.items() if k != "lawn"]
    hub = (LAWN_FROM, LAWN_FROM)
    ox, oy = pos[hub]
    lx, ly = east - ox, north - oy
    for _ in range(1000):
        chain = _chain(rng, built, int(rng.integers(LAPS[0], LAPS[1] + 1)))
        walk, start = _street_walk(rng, chain)
        # the lawn's path: out across it to a fork, round a loop through its far part, back from the fork
        fork = [ox + _u(rng, 0.3, 0.45) * lx, oy + _u(rng, 0.3, 0.45) * ly]
        loop = np.array(
            [
                [ox + _u(rng, 0.8, 0.92) * lx, oy + _u(rng, 0.45, 0.6) * ly],
                [ox + _u(rng, 0.8, 0.92) * lx, oy + _u(rng, 0.8, 0.92) * ly],
                [ox + _u(rng, 0.45, 0.6) * lx, oy + _u(rng, 0.8, 0.92) * ly],
            ]
        )
        if rng.random() < 0.5:
            loop = loop[::-1]
        if not LAWN_LOOP[0] <= _length(np.vstack([fork, loop])) <= LAWN_LOOP[1]:
            continue
        loop = np.vstack([fork, loop, fork])
        on_lawn = [(-1, k) for k in range(len(loop))]  # the loop's corners, as nodes off the grid
        pos.update(zip(on_lawn, loop))
        back = _shortest(edges, pos, hub, start)
        nodes = _cancel_spurs(walk + on_lawn + back)
        wp = _simplify(np.array([pos[n] for n in nodes[:-1]]))
        if ROUTE[0] <= _length(wp) <= ROUTE[1] and len(returns(wp)) >= MIN_RETURNS:
            break
    else:  # pragma: no cover - the draws above always find one within a few tries
        raise RuntimeError(f"no campus route of {ROUTE[0]:g}-{ROUTE[1]:g} m for seed {seed}")
    # Start part way along a street leg the route drives.
    n = len(wp)
    legs = [k for k in range(n) if np.hypot(*(wp[(k + 1) % n] - wp[k])) >= 20.0 and _on_street(wp[k], wp[(k + 1) % n])]
    leg = legs[int(rng.integers(len(legs)))]
    begin = wp[leg] + _u(rng, 0.3, 0.7) * (wp[(leg + 1) % n] - wp[leg])
    wp = np.vstack([begin, wp[leg + 1 :], wp[: leg + 1]])

    # The lawn: lamp poles along its path, a few trees scattered over it (none on another).
    lawn_items: list[Array] = []  # their centres
    side = float(rng.choice([-1.0, 1.0]))
    for a, b in zip(np.vstack([pos[hub], loop[:-1]]), loop):  # (the path back from the fork is the one out)
        e = (b - a) / np.hypot(*(b - a))
        pitch, u = _u(rng, *LAWN_POLE_PITCH), _u(rng, 15.0, 30.0)
        while u < np.hypot(*(b - a)) - 10.0:
            c = a + u * e + side * _u(rng, 2.0, 3.0) * np.array([-e[1], e[0]])
            loose.append(("pole", _polygon(float(c[0]), float(c[1]), _u(rng, *POLE), 6, 0.0)))
            lawn_items.append(c)
            counts["poles"] += 1
            u += pitch
    for _ in range(int(rng.integers(LAWN_TREES[0], LAWN_TREES[1] + 1))):
        c = np.array([_u(rng, lawn[0] + 3.0, lawn[2] - 3.0), _u(rng, lawn[1] + 3.0, lawn[3] - 3.0)])
        tree = _polygon(float(c[0]), float(c[1]), _u(rng, *TREE), int(rng.integers(6, 9)), _u(rng, 0.0, np.pi))
        if min((float(np.hypot(*(c - q))) for q in lawn_items), default=np.inf) >= 2.0:
            loose.append(("tree", tree))
            lawn_items.append(c)
            counts["trees"] += 1

    # Leave out what stands in the route's way.
    legs_xy = np.hstack([wp, np.roll(wp, -1, axis=0)])
    kept: list[tuple[str, Array]] = []
    for what, seg in loose:
        if segment_distances(legs_xy, seg).min() >= CLEARANCE:
            kept.append((what, seg))
        else:
            counts[what + "s"] -= 1
    every = [("wall", f) for f in fixed] + kept
    for what in ("wall", "tree", "pole", "car"):
        counts[f"{what}_segments"] = sum(len(f) for kind_, f in every if kind_ == what)
    segments = np.round(np.concatenate([f for _, f in every]), 4)
    d = wp[1] - wp[0]
    world = World(f"campus-{seed}", segments, WALL_HEIGHT, np.array([wp[0, 0], wp[0, 1], np.arctan2(d[1], d[0])]), wp)
    return Campus(seed, xs, ys, hx, hy, cells, lawn, chain, counts, world)


def _length(wp: Array) -> float:
    """The length of the closed route through ``wp`` (m)."""
    return lap_length(World("", np.zeros((0, 4)), waypoints=wp))


def _on_street(a: Array, b: Array) -> bool:
    """Whether the leg ``a`` - ``b`` runs along a street (along x or y), not across the lawn."""
    return bool(abs(a[0] - b[0]) < 1e-9 or abs(a[1] - b[1]) < 1e-9)


def campus_world(seed: int) -> World:
    """The campus of ``seed`` (named ``campus-SEED``; see the module's text)."""
    return campus(seed).world


# --- measuring a route ---------------------------------------------------------------------


def route_points(waypoints: Array, step: float = 1.0) -> tuple[Array, Array]:
    """Points (N, 2) every ``step`` metres along the closed route through ``waypoints`` from
    its first, and how far along it each lies (N,)."""
    wp = np.asarray(waypoints, dtype=float)
    ends = np.vstack([wp, wp[:1]])
    along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(ends, axis=0).T))])
    s = np.arange(0.0, along[-1], step)
    return np.column_stack([np.interp(s, along, ends[:, 0]), np.interp(s, along, ends[:, 1])]), s


def returns(
    waypoints: Array, lo: float = 100.0, hi: float = 400.0, near: float = 3.0, step: float = 2.0
) -> list[tuple[float, float]]:
    """Where the closed route comes back to a place it passed ``lo``-``hi`` metres of travel
    before (within ``near`` m), having gone at least ``lo / 4`` away from it in between (round
    something, not just out and back along a few metres): one ``(before, after)`` pair of
    distances along the route for each return (the first point of a stretch of points that
    each return to a place passed before)."""
    pts, s = route_points(waypoints, step)
    d = np.hypot(pts[:, None, 0] - pts[None, :, 0], pts[:, None, 1] - pts[None, :, 1])  # (after, before)
    gap = s[:, None] - s[None, :]
    ok = (d <= near) & (gap >= lo) & (gap <= hi)
    out: list[tuple[float, float]] = []
    previous = False
    for a in range(len(s)):
        hit = False
        for b in np.flatnonzero(ok[a]):
            if d[b, b : a + 1].max() >= lo / 4.0:
                hit = True
                if not previous:
                    out.append((float(s[b]), float(s[a])))
                break
        previous = hit
    return out


def segments_within(points: Array, segments: Array, reach: float) -> Array:
    """How many of ``segments`` (K, 4) come within ``reach`` of each of ``points`` (N, 2)."""
    p = np.asarray(points, dtype=float)[:, None, :]
    a, b = segments[None, :, :2], segments[None, :, 2:]
    e = b - a
    t = np.clip(np.sum((p - a) * e, axis=-1) / np.maximum(np.sum(e * e, axis=-1), 1e-18), 0.0, 1.0)
    return np.sum(np.linalg.norm(p - (a + t[..., None] * e), axis=-1) <= reach, axis=1)


def open_share(world: World, reach: float = SICK_RANGE, fewest: int = 80, step: float = 2.0) -> float:
    """The share of the route (by length) from where fewer than ``fewest`` segments lie within ``reach``."""
    pts, _ = route_points(world.waypoints, step)
    return float(np.mean(segments_within(pts, np.asarray(world.segments, dtype=float), reach) < fewest))
