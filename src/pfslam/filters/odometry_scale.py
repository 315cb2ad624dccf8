"""The odometry's scale as the localizer learns it (:class:`OdometryScale`): how much longer
or shorter the odometry reads than the robot moves, from the filter's own corrections; and
how fast the particles' own scales wander after a global start (:data:`SCALE_DRIFT`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pfslam.types import Array

SCALE_DRIFT = 0.002  # per sqrt(m) travelled: how fast each particle's own odometry scale wanders (a random walk)


@dataclass
class OdometryScale:
    """How much longer (or shorter) the odometry reads than the robot moves, learnt from the
    filter's own corrections: between two updates of a settled filter, the estimate's motion
    projected on the reported motion's direction (translation), and its turn against the
    reported turn where the robot turned (rotation). Each scale is the ratio of the
    reported to the corrected amounts summed with exponential forgetting over ``window`` m
    of travel (rad of turn), starting from 1 with ``window`` / 20 of weight, within
    1 -+ ``bound``.

    The filter divides the odometry by the scales, so a settled estimate's corrections
    shrink as the scale nears the truth: the ratio of corrected to reported motion is
    a fixed-point iteration that moves the scale part of the way each window. A corridor
    hardly corrects the along-track position, but its ends, doors and corners do, and
    without the scale the cloud runs ahead by the odometry's error in between.
    """

    window: float = 20.0
    bound: float = 0.2
    min_turn: float = float(np.radians(1.5))  # rad: smaller turns (a gait's wobble) do not count
    reported_t: float = 1.0
    corrected_t: float = 1.0
    reported_r: float = 1.0
    corrected_r: float = 1.0
    count: int = 0  # increments counted

    def __post_init__(self) -> None:
        self.reported_t = self.corrected_t = self.window / 20.0
        self.reported_r = self.corrected_r = self.window / 20.0

    def add(self, reported: Array, corrected: Array) -> None:
        """Count one motion between updates: ``reported`` by the odometry, ``corrected`` by
        the estimate (both (dx, dy, dtheta) in the first pose's frame)."""
        trans = float(np.hypot(reported[0], reported[1]))
        if trans > 1e-6:
            along = float(reported[0] * corrected[0] + reported[1] * corrected[1]) / trans
            k = float(np.exp(-trans / self.window))
            self.reported_t = k * self.reported_t + trans
            self.corrected_t = k * self.corrected_t + along
        turn = abs(float(reported[2]))
        if turn >= self.min_turn:
            k = float(np.exp(-turn / self.window))
            self.reported_r = k * self.reported_r + turn
            self.corrected_r = k * self.corrected_r + float(corrected[2]) * float(np.sign(reported[2]))
        self.count += 1

    def restart(self, translation: float) -> None:
        """Forget the translation counted so far: start again from ``translation`` (within
        1 -+ ``bound``) with ``window`` / 20 of weight."""
        w = self.window / 20.0
        self.reported_t = w * float(np.clip(translation, 1.0 - self.bound, 1.0 + self.bound))
        self.corrected_t = w

    def _ratio(self, reported: float, corrected: float) -> float:
        lo, hi = 1.0 - self.bound, 1.0 + self.bound
        return hi if corrected <= reported / hi else float(np.clip(reported / corrected, lo, hi))

    @property
    def translation(self) -> float:
        """Reported / true distance (1.04: the odometry reads 4 % long)."""
        return self._ratio(self.reported_t, self.corrected_t)

    @property
    def rotation(self) -> float:
        """Reported / true turn."""
        return self._ratio(self.reported_r, self.corrected_r)
