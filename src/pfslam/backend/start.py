"""Where a new log starts in an old map: a global search of its first scan over the whole map
and every heading (branch and bound, as the back end's wide loop search), with the same
uniqueness check: a start is refused if another place half a metre or 5 degrees away fits
nearly as well (a corridor, a row of rooms alike)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pfslam.backend.settings import BackendSettings
from pfslam.backend.submaps import Submap, field_of
from pfslam.geometry import wrap_angle
from pfslam.kernels.bnb import MAX_DEPTH, MAX_ROTATIONS, WindowSearch, refine_kernel, window_match
from pfslam.maps.grid import OccupancyGrid
from pfslam.sensor import ScanPoints, one_per_cell
from pfslam.types import Array

START_POINTS = 400  # scan points matched (on a two-cell grid, evenly subsampled)
START_REACH = 30.0  # m: hits farther than this from the sensor are left out
AWAY_M = 0.5  # m: a start this far from the best one (or AWAY_DEG turned) is another place
AWAY_DEG = 5.0


@dataclass
class StartSearch:
    """The global search's answer: the best ``pose`` (None if no place fits at all) and its
    ``score`` (the scan's mean field value there, 0..1), the best place elsewhere
    (``next_pose``, ``next_score``; None if none scores half as well), and whether the best
    one is a start: ``score`` at least ``min_score`` and ``next_score`` under ``ambiguity``
    times it."""

    pose: Array | None
    score: float
    next_pose: Array | None
    next_score: float | None
    min_score: float
    ambiguity: float

    @property
    def next_distance_m(self) -> float | None:
        """How far the next best place is from the best one (m)."""
        if self.pose is None or self.next_pose is None:
            return None
        return float(np.hypot(*(self.next_pose[:2] - self.pose[:2])))

    @property
    def too_low(self) -> bool:
        return self.pose is None or self.score < self.min_score

    @property
    def ambiguous(self) -> bool:
        return self.next_score is not None and self.next_score >= self.ambiguity * self.score

    @property
    def found(self) -> bool:
        return not self.too_low and not self.ambiguous

    def why_not(self) -> str:
        """Why the start was not found (empty if it was)."""
        if self.pose is None:
            return "the first scan fits nowhere in the map"
        if self.too_low:
            return (
                f"the first scan fits the map nowhere well (best score {self.score:.2f}, {self.min_score:.2f} needed)"
            )
        if self.ambiguous and self.next_pose is not None:
            return (
                f"the first scan fits two places alike: ({self.pose[0]:.2f}, {self.pose[1]:.2f}) scores "
                f"{self.score:.2f} and ({self.next_pose[0]:.2f}, {self.next_pose[1]:.2f}) {self.next_score:.2f}"
            )
        return ""

    def as_dict(self) -> dict[str, object]:
        return {
            "pose": None if self.pose is None else [float(self.pose[0]), float(self.pose[1]), float(self.pose[2])],
            "score": self.score,
            "next_score": self.next_score,
            "next_distance_m": self.next_distance_m,
            "found": self.found,
        }


def start_points(sp: ScanPoints, res: float) -> NDArray[np.float32]:
    """The hits of a scan matched for a start: within :data:`START_REACH` of the sensor, one
    per cell of a grid two map cells wide, at most :data:`START_POINTS` evenly spread."""
    h = sp.hits
    if len(h):
        h = h[np.hypot(h[:, 0] - sp.sensor_xy[0], h[:, 1] - sp.sensor_xy[1]) <= START_REACH]
    h = one_per_cell(h, 2 * res)
    if len(h) > START_POINTS:
        h = h[np.linspace(0, len(h) - 1, START_POINTS).round().astype(np.int64)]
    return np.ascontiguousarray(h, dtype=np.float32)


def map_field(grid: OccupancyGrid, config: BackendSettings) -> Submap | None:
    """The whole map's score field (its occupied cells) and pyramid, for :func:`find_start`."""
    return field_of(grid.logodds > 0, grid.origin, grid.resolution, config.graph.field_sigma, MAX_DEPTH)


def find_start(field: Submap | None, pts: NDArray[np.float32], config: BackendSettings) -> StartSearch:
    """Where the scan points ``pts`` (robot frame) fit best in the map ``field``
    (:func:`map_field`), over the whole map and every heading; see :class:`StartSearch`."""
    c = config.graph
    res = config.map.resolution
    none = StartSearch(None, 0.0, None, None, c.wide_min_score, c.ambiguity)
    p = np.asarray(pts, dtype=np.float64)
    if field is None or len(p) < 10:
        return none
    h, w = field.field.shape
    centre = np.array([field.ox + w * res / 2, field.oy + h * res / 2])
    window = int(np.ceil(max(h, w) / 2)) + 1
    n_side = MAX_ROTATIONS // 2
    step = np.pi / n_side
    angles = step * np.arange(-n_side, n_side)  # every heading once
    search = WindowSearch(field.pyramid, p, centre[0], centre[1], angles, window, field.ox, field.oy, res)
    found = search.best(0.1)  # (scores below this are no start at all)
    if found is None:
        return none
    best = _polished(field, p, found.pose, res, step)
    away_turns = int(np.ceil(np.deg2rad(AWAY_DEG) / step))
    runner_up = search.elsewhere(found, 0.5 * found.score, int(round(AWAY_M / res)), away_turns)
    second = None
    if runner_up is not None:
        second = _polished(field, p, runner_up.pose, res, step)
        if np.hypot(*(second[0][:2] - best[0][:2])) < AWAY_M and abs(
            wrap_angle(second[0][2] - best[0][2])
        ) < np.deg2rad(AWAY_DEG):
            second = None  # (refined onto the best one: the same place)
    return StartSearch(
        best[0],
        best[1],
        None if second is None else second[0],
        None if second is None else second[1],
        c.wide_min_score,
        c.ambiguity,
    )


def _polished(field: Submap, p: Array, pose: Array, res: float, step: float) -> tuple[Array, float]:
    """A pose found on the coarse headings, searched again finely around it (a cell's
    heading step within the coarse step) and refined below a cell; its score."""
    fine = window_match(field, p.astype(np.float32), pose, 2 * res, float(np.rad2deg(step)), 0.0, res)
    if fine is not None:
        return fine
    pose, score = refine_kernel(field.field, p, pose, field.ox, field.oy, res, res / 2, step / 4, 4)
    pose[2] = wrap_angle(pose[2])
    return pose, float(score)
