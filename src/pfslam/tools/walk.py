"""The walk of a simulated robot: the route through a world (:func:`routed`), how the robot
moves along it (:class:`Gait`, :data:`GAITS`), the path it follows as primitives (pauses,
straight walks, corner arcs, turns in place: :func:`build_path`, :func:`eval_path`), and a
humanoid's gait sway and heading wobble on top (:func:`truth_at`). Shared by the humanoid
(:mod:`pfslam.tools.simulate`) and the wheeled (:mod:`pfslam.tools.wheeled`) simulators."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pfslam.errors import ConfigError
from pfslam.geometry import wrap_angle
from pfslam.tools.simcommon import HEADING_BIAS_PER_M
from pfslam.tools.worlds import World
from pfslam.types import Array

WALK_SPEED = 0.5  # m/s
ARC_RADIUS = 0.8  # m, corner fillet radius
MAX_ARC_TURN = np.deg2rad(100.0)  # sharper corners are turned in place
TURN_RATE = 0.6  # rad/s, peak yaw rate of a turn in place
GAIT_PERIOD = 1.6  # s
SWAY_AMPLITUDE = 0.03  # m, lateral gait sway
WOBBLE_AMPLITUDE = 0.01  # rad, heading wobble at the gait period


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


# --- path -----------------------------------------------------------------------------


@dataclass
class Prim:
    """One piece of a path from time ``t0`` for ``dur`` seconds: a pause, a straight walk
    (line), a corner arc or a turn in place."""

    kind: str  # "pause", "line", "arc", "turn"
    t0: float
    dur: float
    p0: Array  # start position (2,)
    h0: float  # start heading
    dh: float = 0.0  # total heading change (arc, turn)
    center: Array | None = None  # arc centre
    radius: float = 0.0
    speed: float = WALK_SPEED  # m/s along lines and arcs
    leg: int = 0  # the route's leg it is on or ends, counted on over the laps (the second lap's first: P)


def build_path(
    world: World,
    duration: float,
    rng: np.random.Generator,
    gait: Gait = GAITS["calm"],
    speed: float = WALK_SPEED,
    *,
    stand_s: float | None = None,
) -> list[Prim]:
    """Primitives (pauses, straight walks, corner arcs, turns in place) covering ``duration``,
    walked at ``speed`` (m/s). The walk starts standing for 4.5-5.5 s (drawn from ``rng``), or
    for ``stand_s`` seconds if given (0: walking from the start); the draw is made either way,
    so the pauses and turns after it are the same, only sooner or later."""
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
    prims: list[Prim] = []
    t = 0.0
    pos = wp[0].copy()
    h = float(seg_h[0])
    first = float(rng.uniform(4.5, 5.5))
    if stand_s is not None:
        first = float(stand_s)
    if first > 0.0:
        prims.append(Prim("pause", t, first, pos.copy(), h))
        t += first
    i = 0
    leg = 0  # i counted on over the laps
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
                prims.append(Prim("line", t, f * length / speed, start.copy(), float(seg_h[i]), speed=speed, leg=leg))
                t += f * length / speed
                d = float(rng.uniform(2.0, 5.0))
                prims.append(Prim("pause", t, d, mid.copy(), float(seg_h[i]), leg=leg))
                t += d
                start, length = mid, (1.0 - f) * length
            prims.append(Prim("line", t, length / speed, start.copy(), float(seg_h[i]), speed=speed, leg=leg))
            t += length / speed
        pos = end
        h = float(seg_h[i])
        dth = float(turn[nxt])
        if arc_len[nxt] > 0.0:
            sgn = 1.0 if dth > 0 else -1.0
            center = pos + gait.arc_radius * np.array([-np.sin(h), np.cos(h)]) * sgn
            dur = gait.arc_radius * abs(dth) / speed
            prims.append(Prim("arc", t, dur, pos.copy(), h, dth, center, gait.arc_radius, speed, leg))
            t += dur
        elif abs(dth) > 1e-9:
            dur = abs(dth) * np.pi / (2.0 * gait.turn_rate)
            prims.append(Prim("turn", t, dur, pos.copy(), h, dth, leg=leg))
            t += dur
        if rng.random() < 0.3:
            d = float(rng.uniform(2.0, 5.0))
            end_pos = wp[nxt] + arc_len[nxt] * seg_dir[nxt] / seg_len[nxt]
            prims.append(Prim("pause", t, d, end_pos.copy(), float(seg_h[nxt]), leg=leg))
            t += d
        i = nxt
        leg += 1
    return prims


def lap_end(prims: list[Prim], legs: int, laps: int = 1) -> float:
    """When the walk ``prims`` along a route of ``legs`` legs has been round it ``laps`` times:
    the end of the last straight of the lap's last leg (back at the start, or where the corner
    there begins); inf if the walk ends before that."""
    last = laps * legs - 1
    ends = [q.t0 + q.dur for q in prims if q.leg == last and q.kind == "line"]
    return max(ends, default=float("inf"))  # (a leg's straights are laid down together)


def eval_path(prims: list[Prim], tau: Array) -> tuple[Array, Array]:
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


def gait_envelope(prims: list[Prim], tau: Array, total: float) -> Array:
    """Smoothly 0 while standing, 1 while walking or turning (0.6 s ramps)."""
    dt = 0.01
    grid = np.arange(-1.0, total + 2.0, dt)
    _, mv = eval_path(prims, np.clip(grid, 0.0, None))
    mv = np.where(grid < 0.0, 0.0, mv.astype(float))
    win = np.hanning(int(round(0.6 / dt)) + 1)
    env = np.convolve(mv, win / win.sum(), mode="same")
    return np.interp(tau, grid, env)


def turning(prims: list[Prim], tau: Array, total: float) -> Array:
    """Smoothly 1 during corners (arcs and turns in place), 0 elsewhere (0.8 s ramps)."""
    dt = 0.01
    grid = np.arange(-1.0, total + 2.0, dt)
    starts = np.array([q.t0 for q in prims])
    idx = np.clip(np.searchsorted(starts, np.clip(grid, 0.0, None), side="right") - 1, 0, len(prims) - 1)
    turning = np.array([q.kind in ("arc", "turn") for q in prims])[idx].astype(float)
    win = np.hanning(int(round(0.8 / dt)) + 1)
    return np.interp(tau, grid, np.convolve(turning, win / win.sum(), mode="same"))


def truth_at(prims: list[Prim], tau: Array, total: float, phase: float, gait: Gait = GAITS["calm"]) -> Array:
    """True world poses at ``tau``: the nominal path plus gait sway and heading wobble."""
    nom, _ = eval_path(prims, tau)
    env = gait_envelope(prims, tau, total)
    w = 2.0 * np.pi / GAIT_PERIOD
    lat = gait.sway * env * np.sin(w * tau + phase)
    out = nom.copy()
    out[:, 0] -= lat * np.sin(nom[:, 2])
    out[:, 1] += lat * np.cos(nom[:, 2])
    out[:, 2] = wrap_angle(nom[:, 2] + gait.wobble * env * np.cos(w * tau + phase))
    return out
