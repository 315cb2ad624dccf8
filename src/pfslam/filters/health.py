"""Localization health: how well a scan fits the map at the estimate, and what that says.

Two fractions of the beams an update weighed, both at the estimate (no ground truth):

* **explained**: the end points within ``tolerance`` of a mapped wall. People, furniture moved
  in and walls taken away since the map was drawn lower it, as a wrong pose does.
* **contradicted**: the beams that cross a mapped wall more than ``tolerance`` before their end
  and end away from any mapped wall: the map says they could not have got there. People and new
  furniture only shorten beams and a wall taken away is no longer in the map, so they leave it
  low; a wall or a cupboard moved since makes the beams that pass where it was end at another
  mapped wall, mostly, and count as explained. At a wrong pose a large part of the beams pass
  through walls into open space. With the sensor off the map or inside a wall every beam
  contradicts it.

The quality is ``explained - 3 x contradicted``, clipped to [0, 1]: 1 for a scan the map
explains beam for beam, 0 at a wrong place. The state follows the median quality of the last
:data:`WINDOW` updates (one odd scan raises no alarm): ``lost`` below ``lost``; else
``ambiguous`` while the particles' weight is shared by places apart (a global start among
look-alike places), however well the estimate's place fits; else ``degraded`` below
``degraded`` and ``tracking`` at or above it.

Measured on simulated humanoid walks (bench/localize/health.py): see docs/localization.md.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from pfslam.kernels.likelihood import scan_fit_kernel
from pfslam.types import Array

WINDOW = 3  # updates whose median quality sets the state
CONTRADICTION_WEIGHT = 3.0  # a beam through a wall into open space counts 3 x against the fit


class State(StrEnum):
    """What the localizer's health says of its estimate."""

    TRACKING = "tracking"
    DEGRADED = "degraded"
    LOST = "lost"
    AMBIGUOUS = "ambiguous"


@dataclass(frozen=True)
class Health:
    """One update's health: ``quality`` in [0, 1], the ``state``, and the two fractions the
    quality is made of (see the module's text). ``smoothed`` is the quality the state follows."""

    quality: float
    state: State
    explained: float
    contradicted: float
    smoothed: float


def scan_fit(
    dist: np.ndarray,
    occ: np.ndarray,
    origin: Array,
    resolution: float,
    pose: Array,
    pts: Array,
    sensor_xy: Array,
    tolerance: float,
) -> tuple[float, float]:
    """(explained, contradicted) of the end points ``pts`` (robot frame) seen from the sensor
    at ``sensor_xy`` (robot frame) at ``pose``, on a map whose distances to the nearest wall
    are ``dist`` (m, capped) and whose occupied cells are ``occ`` (uint8)."""
    n = len(pts)
    if n == 0:
        return 0.0, 0.0
    near, through, blocked = scan_fit_kernel(
        dist,
        occ,
        float(origin[0]),
        float(origin[1]),
        1.0 / resolution,
        np.asarray(pose, dtype=np.float64),
        np.ascontiguousarray(np.asarray(pts, dtype=np.float64)[:, :2]),
        np.asarray(sensor_xy, dtype=np.float64),
        float(tolerance),
    )
    # A sensor off the map or inside a wall: no beam could have been seen from there.
    return near / n, 1.0 if blocked else through / n


def _median(values: deque[float]) -> float:
    """The median of a few numbers (np.median costs 20 us; it runs at every update)."""
    v = sorted(values)
    k = len(v) // 2
    return v[k] if len(v) % 2 else 0.5 * (v[k - 1] + v[k])


def quality_of(explained: float, contradicted: float) -> float:
    """The quality in [0, 1] of a scan with these fractions (see the module's text)."""
    return min(max(explained - CONTRADICTION_WEIGHT * contradicted, 0.0), 1.0)


class HealthMonitor:
    """The state from each update's quality: the median of the last ``window`` (default
    :data:`WINDOW`) against ``degraded`` and ``lost`` (0 <= lost <= degraded <= 1)."""

    def __init__(self, degraded: float, lost: float, window: int = WINDOW) -> None:
        self.degraded, self.lost = degraded, lost
        self._recent: deque[float] = deque(maxlen=window)

    def __call__(self, explained: float, contradicted: float, ambiguous: bool) -> Health:
        q = quality_of(explained, contradicted)
        self._recent.append(q)
        m = _median(self._recent)
        if m < self.lost:
            state = State.LOST
        elif ambiguous:
            state = State.AMBIGUOUS
        elif m < self.degraded:
            state = State.DEGRADED
        else:
            state = State.TRACKING
        return Health(q, state, explained, contradicted, m)


NO_STATE = -1  # a step before the first update: no health yet
STATE_CODES = {s: k for k, s in enumerate(State)}


@dataclass
class HealthTrace:
    """A run's health per step (each step carries its last update's): the quality, the state
    (its index in :class:`State`, :data:`NO_STATE` before the first update), and the two
    fractions; NaN where there is none yet."""

    quality: Array
    state: np.ndarray
    explained: Array
    contradicted: Array

    @classmethod
    def empty(cls, n: int) -> HealthTrace:
        return cls(np.full(n, np.nan), np.full(n, NO_STATE, np.int8), np.full(n, np.nan), np.full(n, np.nan))

    def record(self, i: int, h: Health) -> None:
        self.quality[i], self.state[i] = h.quality, STATE_CODES[h.state]
        self.explained[i], self.contradicted[i] = h.explained, h.contradicted

    def cut(self, k: int) -> HealthTrace:
        """The first ``k`` steps."""
        return HealthTrace(self.quality[:k], self.state[:k], self.explained[:k], self.contradicted[:k])

    def state_names(self) -> list[str]:
        """Each step's state by name ("" before the first update)."""
        names = list(State)
        return ["" if s == NO_STATE else names[s].value for s in self.state]

    def summary(self, t: Array, updated: np.ndarray) -> dict[str, object]:
        """run.json's ``health``: seconds in each state (a step's state holds until the next
        step), the updates in each, when it was first lost (s after the first scan; None if
        never), the lowest quality and when, the median quality and the state at the end."""
        n = len(t)
        dt = np.diff(t, append=t[-1]) if n else np.zeros(0)
        names = list(State)
        seconds = {s.value: float(np.sum(dt[self.state == k])) for k, s in enumerate(names)}
        counts = {s.value: int(np.sum(updated & (self.state == k))) for k, s in enumerate(names)}
        lost = np.nonzero(self.state == STATE_CODES[State.LOST])[0]
        q = np.where(updated, self.quality, np.nan)
        has = np.isfinite(q)
        low = int(np.nanargmin(q)) if has.any() else None
        last = int(self.state[-1]) if n else NO_STATE
        return {
            "seconds_in_state": seconds,
            "updates_in_state": counts,
            "first_lost_s": float(t[lost[0]] - t[0]) if len(lost) else None,
            "lowest_quality": None if low is None else round(float(q[low]), 4),
            "lowest_quality_at_s": None if low is None else float(t[low] - t[0]),
            "median_quality": round(float(np.median(q[has])), 4) if has.any() else None,
            "final_state": None if last == NO_STATE else names[last].value,
        }
