"""The prediction step every filter shares: move the particles by the motion between two
frames, with the noise of a motion model."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from pfslam.config import SlamConfig
from pfslam.frames import Frame
from pfslam.geometry import relative
from pfslam.motion import DiffDriveMotion, OdometryMotion
from pfslam.types import Array

WHEELS_STILL = 1e-6  # m of wheel travel below which a wheel counts as still


class OdometryModel(Protocol):
    """A motion model driven by the odometry increment ``u`` (robot frame) over ``dt`` s."""

    def is_still(self, u: Array) -> bool: ...

    def apply(self, poses: Array, u: Array, dt: float, rng: np.random.Generator) -> Array: ...


@dataclass
class Prediction:
    """Moves particles from one frame to the next.

    With wheel travel in both frames the differential-drive model ``wheels`` moves them
    (nothing while both wheels stand still); else, with an odometry pose in both, the
    increment ``u = o_prev ⊖ o_now`` moves them through ``odometry``; else they stay.
    """

    odometry: OdometryModel
    wheels: DiffDriveMotion

    @staticmethod
    def _wheel_travel(prev: Frame, frame: Frame) -> tuple[float, float] | None:
        """Left and right wheel travel from ``prev`` to ``frame``, or None without it."""
        if frame.wheels is None or prev.wheels is None:
            return None
        dl, dr = (np.asarray(frame.wheels) - np.asarray(prev.wheels)).tolist()
        return dl, dr

    def increment(self, prev: Frame, frame: Frame) -> Array | None:
        """The noise-free motion from ``prev`` to ``frame`` in ``prev``'s robot frame (the
        wheels' arc, else the odometry increment), or None without odometry."""
        travel = self._wheel_travel(prev, frame)
        if travel is not None:
            return DiffDriveMotion.arc(np.zeros((1, 3)), np.array(travel[0]), np.array(travel[1]), self.wheels.axle)[0]
        if frame.odom is None or prev.odom is None:
            return None
        return relative(prev.odom, frame.odom)

    def __call__(
        self, poses: Array, prev: Frame, frame: Frame, rng: np.random.Generator
    ) -> tuple[Array, Array | None, bool]:
        """(moved poses, the noise-free increment ``u`` or None without odometry, whether
        the robot moved)."""
        u = self.increment(prev, frame)
        if u is None:
            return poses, None, False
        travel = self._wheel_travel(prev, frame)
        if travel is not None:
            dl, dr = travel
            if abs(dl) < WHEELS_STILL and abs(dr) < WHEELS_STILL:
                return poses, u, False
            return self.wheels.apply(poses, dl, dr, rng), u, True
        dt = max(frame.t - prev.t, 0.0)
        return self.odometry.apply(poses, u, dt, rng), u, not self.odometry.is_still(u)


def slam_prediction(c: SlamConfig) -> Prediction:
    """SLAM's prediction: Gaussian increment noise per ``ref_interval`` (plus noise per metre
    and radian), or wheel-travel noise on wheel logs."""
    m = c.motion
    return Prediction(
        OdometryMotion(
            sigma=(m.sigma_x, m.sigma_y, float(np.deg2rad(m.sigma_theta_deg))),
            ref_interval=m.ref_interval,
            trans_k=m.trans_k,
            rot_k=m.rot_k,
        ),
        DiffDriveMotion(axle=m.axle, k_left=m.k_left, k_right=m.k_right),
    )


def start_pose(frame: Frame) -> Array:
    """Where a SLAM filter's map frame starts: the odometry frame at the first scan (the
    origin for wheel logs, whose frames carry wheel travel, not a pose)."""
    return np.zeros(3) if frame.odom is None else np.asarray(frame.odom, dtype=float).copy()


@dataclass
class MotionSince:
    """The path since some event (the last update, the last rebuild): metres travelled and
    radians turned, each the sum of the increments' lengths, and the scans counted."""

    travel: float = 0.0  # m
    turn: float = 0.0  # rad
    scans: int = 0

    def add(self, u: Array) -> None:
        """Count one increment ``u`` (robot frame)."""
        self.travel += float(np.hypot(u[0], u[1]))
        self.turn += abs(float(u[2]))
        self.scans += 1

    def reached(self, travel: float, turn: float, scans: int | None = None) -> bool:
        """Whether it travelled ``travel`` m, or turned ``turn`` rad, or counted ``scans`` scans."""
        return self.travel >= travel or self.turn >= turn or (scans is not None and self.scans >= scans)

    def reset(self) -> None:
        self.travel, self.turn, self.scans = 0.0, 0.0, 0
