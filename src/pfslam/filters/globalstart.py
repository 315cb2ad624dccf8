"""A global start from the map: the first scan matched over the whole map and every heading
by branch and bound (the back end's wide search, :class:`~pfslam.kernels.bnb.WindowSearch`, on a
score field of the map's occupied cells), its best few distinct places taken as candidates,
and the particles seeded round them (:class:`GlobalStart`).

Where several places fit alike (twin rooms, a row of doors), each candidate is a *mode*
whose particles carry its label. Until one mode has won, the modes are resampled each on
its own (:meth:`GlobalStart.resample`): each keeps at least :data:`MODE_MIN` particles
whatever its share, so neither KLD-sampling's shrinking count nor genetic drift can kill a
place that fits as well as the others; a mode's share of the weight is its posterior
probability, tempered at each update (``P <- P^`` :data:`FORGET`, renormalised), so that
what decides between places is what the scans have recently told apart, not the sum of
thousands of tiny differences while both see the same walls. A mode is given up once its
probability falls under :data:`DROP`. The start is :attr:`~GlobalStart.ambiguous` if
more than one place was found, while more than one mode lives, and until the last one's
cloud has been settled for :data:`SETTLED_UPDATES` updates in a row.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from pfslam.filters.base import SETTLED_SPREAD, position_std
from pfslam.geometry import wrap_angle
from pfslam.kernels.bnb import WindowSearch, refine_kernel, score_field
from pfslam.maps.grid import OccupancyGrid
from pfslam.particles import DRAWERS, ParticleSet
from pfslam.sensor import one_per_cell
from pfslam.types import Array, JSONObject

if TYPE_CHECKING:
    from pfslam.filters.localize import Localizer

FIELD_SIGMA = 0.075  # m: the score field's width round the map's walls (the back end's field_sigma)
DEPTH = 7  # pyramid levels: the coarsest block 64 cells wide
ROTATIONS = 400  # headings tried, once round
START_POINTS = 400  # scan points matched at most (one per two-cell square, evenly subsampled)
MIN_POINTS = 10  # fewer points than this: no search (the start falls back to the uniform spread)
MIN_SCORE = 0.25  # a best place scoring under this (mean field value 0..1) is no start at all
KEEP = 0.75  # a place scoring at least this fraction of the best is a candidate ...
CANDIDATES = 48  # ... of these many at most (a ring of pillars has 20 alike)
MAX_MATCHES = 1_000_000  # matches (cell and heading) scoring that well kept at most, the best places among them
AWAY_M = 0.5  # m: a place this far from another (or AWAY_DEG turned) is another place
AWAY_DEG = 5.0
SEED_STD = (0.05, 0.05, np.deg2rad(2.0))  # m, m, rad: the particles' spread round a candidate
MODE_MIN = 200  # particles a living mode keeps at least
FORGET = 0.9  # a mode's probability is tempered by this power at each update
DROP = 1e-3  # a mode whose probability falls under this is given up
SETTLED_UPDATES = 5  # updates in a row the last mode must be settled before the start is found
STILL_UPDATE_S = 0.1  # s: while ambiguous, an update at least this often, moving or not


@dataclass
class MapField:
    """The map's score field exp(-d^2 / 2 sigma^2) round its occupied cells, cropped to them,
    with its max-pooled pyramid (lower-left corner of cell (0, 0) at ``ox``, ``oy``)."""

    field: NDArray[np.float32]
    pyramid: NDArray[np.float32]
    ox: float
    oy: float
    res: float

    @classmethod
    def of(cls, grid: OccupancyGrid) -> MapField | None:
        """The field of ``grid``'s occupied cells (``thresholded() == 100``, so a trinary
        map_server map serves as well); None if none is occupied."""
        made = score_field(grid.thresholded() == 100, grid.origin, grid.resolution, FIELD_SIGMA, DEPTH)
        if made is None:
            return None
        return cls(*made, grid.resolution)


def start_points(hits: Array, res: float) -> NDArray[np.float64]:
    """The scan's hits (robot frame) matched: the first in each square two cells wide, at
    most :data:`START_POINTS` of them evenly spread."""
    h = one_per_cell(np.asarray(hits, dtype=float).reshape(-1, 2), 2 * res)
    if len(h) > START_POINTS:
        h = h[np.linspace(0, len(h) - 1, START_POINTS).round().astype(np.int64)]
    return np.ascontiguousarray(h)


def find_places(mf: MapField, pts: Array) -> list[tuple[Array, float]]:
    """The distinct places (pose, score) where the points ``pts`` (robot frame) fit the map,
    best first: the best match over the whole map and every heading (branch and bound), then
    every match scoring :data:`KEEP` times it (one more search, pruned by that score alone),
    of which the best, and the best at least :data:`AWAY_M` or :data:`AWAY_DEG` from each
    taken, are refined below a cell (2 x :data:`CANDIDATES` at most); those that still score
    :data:`KEEP` times the best. Empty if no match scores :data:`MIN_SCORE`."""
    p = np.asarray(pts, dtype=float)
    if len(p) < MIN_POINTS:
        return []
    res = mf.res
    h, w = mf.field.shape
    centre = np.array([mf.ox + w * res / 2, mf.oy + h * res / 2])
    window = int(np.ceil(max(h, w) / 2)) + 1
    step = 2 * np.pi / ROTATIONS
    angles = step * np.arange(-ROTATIONS // 2, ROTATIONS // 2)
    search = WindowSearch(mf.pyramid, p, centre[0], centre[1], angles, window, mf.ox, mf.oy, res)
    away, away_rot = int(round(AWAY_M / res)), int(np.ceil(np.deg2rad(AWAY_DEG) / step))
    found = search.best(MIN_SCORE)
    if found is None:
        return []
    # Every match that scores KEEP x the best, then the best of them away from those taken.
    scores, cells, _ = search.every(KEEP * found.score, MAX_MATCHES)
    order = np.argsort(-scores, kind="stable")
    cells = cells[order].astype(np.int64)
    taken: list[tuple[int, int, int]] = []
    while len(cells) and len(taken) < 2 * CANDIDATES:
        kk, dc, dr = cells[0]
        taken.append((int(kk), int(dc), int(dr)))
        dk = np.abs(cells[:, 0] - kk)
        dk = np.minimum(dk, ROTATIONS - dk)
        near = (dk <= away_rot) & (np.abs(cells[:, 1] - dc) <= away) & (np.abs(cells[:, 2] - dr) <= away)
        cells = cells[~near]
    places: list[tuple[Array, float]] = []
    for kk, dc, dr in taken:
        guess = np.array([centre[0] + dc * res, centre[1] + dr * res, angles[kk]])
        pose, score = refine_kernel(mf.field, p, guess, mf.ox, mf.oy, res, res, step, 5)
        pose[2] = wrap_angle(pose[2])
        if not any(_same(pose, q) for q, _ in places):  # (refined onto a place taken: the same place)
            places.append((pose, float(score)))
    places.sort(key=lambda x: -x[1])
    return [x for x in places if x[1] >= KEEP * places[0][1]]


def _same(a: Array, b: Array) -> bool:
    return bool(np.hypot(a[0] - b[0], a[1] - b[1]) < AWAY_M and abs(wrap_angle(a[2] - b[2])) < np.deg2rad(AWAY_DEG))


@dataclass
class GlobalStart:
    """The state of a global start: ``pending`` until the first scan is matched; then the
    candidates found (``places``), each particle's mode (``labels``, or None once one mode
    has won or the modes were given up) and whether the start is still ambiguous. For a
    uniform start (``mode`` "uniform", or the search's fallback) it is ambiguous until the
    cloud has been settled for :data:`SETTLED_UPDATES` updates in a row."""

    mode: str = "bnb"
    pending: bool = True
    places: list[tuple[Array, float]] = field(default_factory=list)
    labels: NDArray[np.int64] | None = None
    fallback: str = ""  # why a B&B start fell back to the uniform spread
    streak: int = 0  # updates in a row with one mode left and the cloud settled
    resolved: bool = False
    given_up: str = ""  # why the modes were given up before one won
    resolved_at_update: int | None = None
    more: bool = False  # more places fitted alike than CANDIDATES: the best of them were taken
    next_t: float = -np.inf  # the earliest time of the next update that the motion gate does not ask for

    @property
    def ambiguous(self) -> bool:
        return not self.resolved

    def wants_update(self, t: float) -> bool:
        """Whether to update at time ``t`` though the robot has not moved enough: while the
        modes of a B&B start are followed, every :data:`STILL_UPDATE_S` (a robot standing
        still turns its sensor, or waits for the others in its way to pass, and its scans may
        show more). A uniform start waits for motion, as AMCL does."""
        if self.labels is None or self.resolved or t < self.next_t:
            return False
        self.next_t = t + STILL_UPDATE_S
        return True

    def seed(self, loc: Localizer, hits: Array) -> bool:
        """Match the first scan's ``hits`` (robot frame) and seed ``loc``'s particles round
        the candidates; False (``fallback`` says why) if there is none to seed round."""
        self.pending = False
        mf = MapField.of(loc.grid)
        pts = start_points(hits, loc.grid.resolution)
        if mf is None:
            self.fallback = "the map has no occupied cells"
            return False
        if len(pts) < MIN_POINTS:
            self.fallback = f"the first scan has {len(pts)} usable points ({MIN_POINTS} needed)"
            return False
        places = find_places(mf, pts)
        self.places, self.more = places[:CANDIDATES], len(places) > CANDIDATES
        if not self.places:
            self.fallback = f"the first scan fits the map nowhere (no place scores {MIN_SCORE})"
            return False
        scores = np.array([s for _, s in self.places])
        total = max(loc.config.max_particles, MODE_MIN * len(scores))
        counts = np.maximum(MODE_MIN, np.floor(total * scores / scores.sum())).astype(np.int64)
        poses, labels = [], []
        for j, ((pose, _), n) in enumerate(zip(self.places, counts, strict=True)):
            poses.append(pose + loc.rng.normal(size=(int(n), 3)) * np.asarray(SEED_STD))
            labels.append(np.full(int(n), j, dtype=np.int64))
        all_poses = np.concatenate(poses)
        all_poses[:, 2] = wrap_angle(all_poses[:, 2])
        loc.particles = ParticleSet(np.ascontiguousarray(all_poses))
        loc._scales = loc.random_scales(len(all_poses))
        self.labels = np.concatenate(labels)
        if len(self.places) == 1:  # one place fits: nothing to tell apart
            self.resolved, self.labels, self.resolved_at_update = True, None, loc.updates + 1
        return True

    def after_update(self, loc: Localizer) -> bool | None:
        """At each update, before resampling: follow the modes (merge those that met, give up
        the improbable ones, decide whether one has won) and resample them each on its own
        while more than one is followed. True / False: resampled or not (the caller then does
        not resample); None: resample as usual."""
        if self.resolved:
            return None
        settled = position_std(loc.cov) < SETTLED_SPREAD
        if self.labels is None or self.given_up:  # a uniform start, or the modes given up
            self.streak = self.streak + 1 if settled else 0
            self._check_resolved(loc)
            return None
        ps = loc._require_particles()
        if len(self.labels) != len(ps):  # particles set from outside: modes no longer known
            self.given_up = "the particles were replaced"
            self.labels = None
            return None
        w = ps.weights
        labels = self._merged(ps.poses, w, self.labels)
        ids = np.unique(labels)
        mass = np.array([w[labels == j].sum() for j in ids])
        prob = mass**FORGET
        prob = prob / prob.sum() if prob.sum() > 0 else np.full(len(ids), 1.0 / len(ids))
        live = prob >= DROP
        ids, prob = ids[live], prob[live] / prob[live].sum()
        self.streak = self.streak + 1 if (len(ids) == 1 and settled) else 0
        if self._check_resolved(loc):
            return None
        return self._resample(loc, labels, ids, prob)

    def _check_resolved(self, loc: Localizer) -> bool:
        if self.streak >= SETTLED_UPDATES:
            self.resolved = True
            self.labels = None
            self.resolved_at_update = loc.updates + 1
        return self.resolved

    def _merged(self, poses: Array, w: Array, labels: NDArray[np.int64]) -> NDArray[np.int64]:
        """``labels`` with the modes whose weighted mean poses have come within
        :data:`AWAY_M` / :data:`AWAY_DEG` of each other merged (into the lower label)."""
        ids = np.unique(labels)
        if len(ids) < 2:
            return labels
        means = []
        for j in ids:
            m = labels == j
            ww = w[m] / max(float(w[m].sum()), 1e-300)
            a = float(np.arctan2(np.sum(ww * np.sin(poses[m, 2])), np.sum(ww * np.cos(poses[m, 2]))))
            means.append(np.array([np.sum(ww * poses[m, 0]), np.sum(ww * poses[m, 1]), a]))
        out = labels.copy()
        for a in range(len(ids)):
            for b in range(a):
                if _same(means[a], means[b]):
                    out[out == ids[a]] = ids[b]
                    break
        return out

    def _resample(self, loc: Localizer, labels: NDArray[np.int64], ids: NDArray[np.int64], prob: Array) -> bool:
        """Resample each living mode on its own: ``prob`` x the KLD count of particles (at
        least :data:`MODE_MIN`), drawn by their weights within the mode; each mode's new
        particles share its probability equally."""
        c = loc.config
        ps = loc._require_particles()
        if c.recovery and loc.recovery.p_random > 0:
            # The scans fit worse than they did: the robot may be at none of the candidates.
            # The recovery's injection takes over (and the start is then decided as a uniform one).
            self.given_up = "the recovery injected particles"
            self.labels = None
            return False
        w = ps.weights
        n_total = c.max_particles
        if c.kld:
            idx = DRAWERS[c.resample_method](w, c.max_particles, loc.rng)
            n_total = loc._kld_count(ps.poses[idx])
        own = loc.per_particle_scale
        scales = loc.scales
        picks, logw, labs = [], [], []
        for j, pj in zip(ids, prob, strict=True):
            members = np.nonzero(labels == j)[0]
            wj = w[members]
            wj = wj / wj.sum() if wj.sum() > 0 else np.full(len(members), 1.0 / len(members))
            n = max(MODE_MIN, round(float(pj) * n_total))
            picks.append(members[DRAWERS[c.resample_method](wj, n, loc.rng)])
            logw.append(np.full(n, np.log(pj / n)))
            labs.append(np.full(n, j, dtype=np.int64))
        idx = np.concatenate(picks)
        loc.particles = ParticleSet(np.ascontiguousarray(ps.poses[idx]), np.concatenate(logw))
        if own:
            loc._scales = np.ascontiguousarray(scales[idx])
        self.labels = np.concatenate(labs)
        return True

    def as_dict(self) -> JSONObject:
        out: JSONObject = {"mode": self.mode, "ambiguous": self.ambiguous}
        if self.mode == "bnb":
            out["candidates"] = len(self.places)
            out["best_score"] = round(self.places[0][1], 4) if self.places else None
            out["next_score"] = round(self.places[1][1], 4) if len(self.places) > 1 else None
            out["places"] = [[round(float(v), 3) for v in p] for p, _ in self.places]
            if self.more:
                out["more_places_than_followed"] = True
            if self.fallback:
                out["fallback"] = f"uniform spread: {self.fallback}"
        if self.given_up:
            out["modes_given_up"] = self.given_up
        out["resolved_at_update"] = self.resolved_at_update
        return out
