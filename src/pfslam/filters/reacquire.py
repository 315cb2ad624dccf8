"""Finding the robot in its own map again after a blind stretch.

Where the scans hold too few hits to match (an open lawn or square wider than the laser's
reach), every particle follows the odometry (``rbpf.blind_follow``), and its heading drifts
with the odometry's: a few hundred metres at 0.05 deg/m leave the robot tens of metres and
degrees off when it sees walls again. No particle is there, so the proposal, which searches
centimetres around each particle, cannot bring it back; the filter would map the walls it
passed before a second time, in the wrong place.

So the first scans that see again after a stretch of ``rbpf.reacquire_m`` or more are searched
for in the best particle's map over a window as wide as the stretch could have drifted
(:func:`window`), by branch and bound on a coarse picture of the map (:meth:`~pfslam.maps.tiled.TiledMaps.walls`,
cells :data:`FACTOR` map cells wide), and taken only where the match is good and unique: no
place half a metre or 5 degrees away scores nearly as well (:func:`~pfslam.kernels.bnb.window_match`'s
ambiguity). The particles are moved rigidly to it; where no such match is found, they stay.

The path the particles followed since they last matched is bent to end there (:func:`bend`):
the heading's error spread over the stretch a metre alike, as an odometry's heading bias grows,
and what is left of the position's a metre alike too. A constant bias is undone exactly; the
path then has no jump for the back end to take as a motion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pfslam.geometry import compose, relative, wrap_angle
from pfslam.kernels.bnb import MAX_DEPTH, ScoreGrid, score_field, window_match
from pfslam.maps.tiled import TiledMaps
from pfslam.sensor import one_per_cell
from pfslam.types import Array

FACTOR = 4  # the search's cells: this many map cells wide (0.2 m at 0.05 m)
POINTS = 400  # scan points searched at most (one per search cell, evenly subsampled)
MIN_POINTS = 20  # fewer points than this are not searched
SCALE_PER_M = 0.02  # m of position error per blind metre besides the heading's (the odometry's scale)
MIN_SCORE = 0.3  # the match's mean score (0..1) on the coarse field (the scan may see much that is new)
AMBIGUITY = 0.85  # refused if a place 0.5 m or 5 deg away scores this fraction of the best
NOTHING_NEAR = "no walls mapped near"  # why a search found nothing where the map holds nothing
EDGE_CELLS = 2  # a match this many cells from the window's side (or EDGE_DEG from its last heading) ...
EDGE_DEG = 0.5  # ... is refused: the best place may lie beyond it


@dataclass(frozen=True)
class Reacquired:
    """A search's answer: where the best particle is (world frame; None if not found), its
    score, the window searched and why it was not found (empty if it was)."""

    pose: Array | None
    score: float
    window_m: float
    window_deg: float
    why: str = ""


def window(blind_m: float, deg_per_m: float, max_m: float, max_deg: float) -> tuple[float, float]:
    """How far (m, deg) a path that followed the odometry for ``blind_m`` metres may be off: its
    heading by ``deg_per_m`` a metre, its position by what that heading error adds up to along
    the way (half the last one's sideways throw) and the odometry's scale; at most ``max_m``,
    ``max_deg``."""
    deg = min(max_deg, deg_per_m * blind_m)
    m = blind_m * (SCALE_PER_M + 0.5 * np.sin(np.deg2rad(deg)))
    return float(min(max_m, m)), float(deg)


def reacquire(maps: TiledMaps, i: int, guess: Array, hits: Array, window_m: float, window_deg: float) -> Reacquired:
    """Where the scan's ``hits`` (robot frame) fit map ``i`` within ``window_m`` / ``window_deg``
    of ``guess`` (its pose by the odometry), if they fit there well and nowhere else nearly as
    well (see the module notes)."""
    res = maps.resolution * FACTOR
    pts = one_per_cell(np.asarray(hits, dtype=float), res)
    if len(pts) > POINTS:
        pts = pts[np.linspace(0, len(pts) - 1, POINTS).round().astype(np.intp)]
    if len(pts) < MIN_POINTS:
        return Reacquired(None, 0.0, window_m, window_deg, "too few hits")
    reach = float(np.hypot(pts[:, 0], pts[:, 1]).max()) + window_m + res
    box = (guess[0] - reach, guess[1] - reach, guess[0] + reach, guess[1] + reach)
    occ, origin = maps.walls(i, box, FACTOR)
    made = score_field(occ, origin, res, res, MAX_DEPTH)
    if made is None:
        return Reacquired(None, 0.0, window_m, window_deg, NOTHING_NEAR)
    why: list[str] = []
    found = window_match(
        ScoreGrid(*made), np.ascontiguousarray(pts), guess, window_m, window_deg, MIN_SCORE, res,
        ambiguity=AMBIGUITY, why=why,
    )  # fmt: skip
    if found is None:
        return Reacquired(None, 0.0, window_m, window_deg, "ambiguous" if why else "no place fits well")
    pose, score = found
    off = np.abs(pose[:2] - guess[:2])
    if off.max() >= window_m - EDGE_CELLS * res or abs(float(wrap_angle(pose[2] - guess[2]))) >= np.deg2rad(
        window_deg - EDGE_DEG
    ):
        # the best place inside the window, not necessarily the best place: the robot may be beyond
        return Reacquired(None, score, window_m, window_deg, "at the window's edge")
    return Reacquired(pose, score, window_m, window_deg)


def bend(path: Array, end: Array) -> Array:
    """The path ``path`` ((N + 1, 3): from where the particles last matched, ``path[0]``, which
    stays, to ``path[-1]``) bent to end at ``end``: its heading turned by a share of the end's
    heading error in proportion to each step's length (by step, where it did not move), then its
    positions moved by a share of what is left, by the travel to each."""
    path = np.asarray(path, dtype=float)
    if len(path) < 2:
        return path.copy()
    steps = relative(path[:-1], path[1:])
    length = np.hypot(steps[:, 0], steps[:, 1])
    total = float(length.sum())
    share = length / total if total > 1e-9 else np.full(len(steps), 1.0 / len(steps))
    steps[:, 2] += float(wrap_angle(end[2] - path[-1, 2])) * share
    out = np.empty_like(path)
    out[0] = path[0]
    for k, u in enumerate(steps):
        out[k + 1] = compose(out[k], u)
    out[1:, :2] += np.cumsum(share)[:, None] * (np.asarray(end[:2], dtype=float) - out[-1, :2])
    out[1:, 2] = wrap_angle(out[1:, 2])
    return out
