"""Motion models: map (particles, odometry input, rng) to new particles."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pfslam.geometry import compose, wrap_angle
from pfslam.types import Array

# The motion-proportional floor of OdometryMotion's noise: what odometry errs by per metre
# and per radian whatever the time it took. A wheeled robot's dead reckoning is typically off
# by 1-2 % of the distance (wheel diameters, slip), a few per cent of each turn (wheel base,
# slip while turning) and a fraction of a degree of heading per metre (unequal wheels); the
# upper ends of those ranges are taken. (The synthetic odometry of pfslam.io.synthetic draws its
# white noise from the same figures.) The floor is a lower bound on the noise, not an addition.
FLOOR_TRANS_K = 0.02  # m of x/y noise per metre travelled
FLOOR_ROT_K = 0.05  # rad of heading noise per rad turned
FLOOR_ROT_PER_M = float(np.deg2rad(0.5))  # rad of heading noise per metre travelled


@dataclass
class OdometryMotion:
    """Apply the odometry increment ``u = o_t ⊖ o_{t-1}`` as ``p ⊕ (u + noise)``.

    The noise on each axis:

    - time: ``sigma`` is the standard deviation (x m, y m, theta rad) of the noise added over
      ``ref_interval`` seconds (10 scans at 40 Hz by default). It is a random walk, so it is
      scaled by ``sqrt(dt / ref_interval)`` for an increment spanning ``dt`` seconds (the
      disturbances of a walking robot's gait add up with time);
    - per metre and radian, in quadrature with that (off by default): ``trans_k`` m per
      metre travelled on x and y, ``rot_k`` rad per rad turned on theta, for logs with long
      gaps between scans (one scan per half metre, as in the classic CARMEN sets);
    - a floor in proportion to the motion: the noise on an axis is never below what
      odometry errs by over that motion (``floor_trans_k`` m per metre on x and y;
      ``floor_rot_k`` rad per rad turned and ``floor_rot_per_m`` rad per metre on theta, in
      quadrature). So a zero ``dt`` (a log whose time stamps are all the same) can never
      freeze the filter on the odometry. The floor is the larger of the two, not a sum:
      where the time term already exceeds it (a 40 Hz THOR log, Intel's 3 s steps) the noise
      is as it was, so those runs do not change.

    No noise is added while the increment is below ``eps_trans`` and ``eps_rot``.
    """

    sigma: tuple[float, float, float] = (0.01, 0.01, float(np.deg2rad(0.5)))
    ref_interval: float = 0.25
    eps_trans: float = 1e-4
    eps_rot: float = 1e-4
    trans_k: float = 0.0
    rot_k: float = 0.0
    floor_trans_k: float = FLOOR_TRANS_K
    floor_rot_k: float = FLOOR_ROT_K
    floor_rot_per_m: float = FLOOR_ROT_PER_M

    @classmethod
    def noise_free(cls) -> OdometryMotion:
        """The model without any noise (the increment applied exactly)."""
        return cls(sigma=(0.0, 0.0, 0.0), floor_trans_k=0.0, floor_rot_k=0.0, floor_rot_per_m=0.0)

    def is_still(self, u: Array) -> bool:
        return bool(np.hypot(u[0], u[1]) < self.eps_trans and abs(u[2]) < self.eps_rot)

    def noise_sigma(self, u: Array, dt: float) -> Array:
        """(3,) standard deviation of the noise on an increment ``u`` spanning ``dt`` seconds
        (zero while still)."""
        u = np.asarray(u, dtype=float)
        if self.is_still(u):
            return np.zeros(3)
        scale = np.sqrt(max(dt, 0.0) / self.ref_interval) if self.ref_interval > 0 else 1.0
        sig = np.asarray(self.sigma, dtype=float) * scale
        d, turn = float(np.hypot(u[0], u[1])), abs(float(u[2]))
        if self.trans_k > 0 or self.rot_k > 0:
            motion = np.array([self.trans_k * d, self.trans_k * d, self.rot_k * turn])
            sig = np.sqrt(sig**2 + motion**2)
        floor_xy = self.floor_trans_k * d
        floor = np.array([floor_xy, floor_xy, np.hypot(self.floor_rot_k * turn, self.floor_rot_per_m * d)])
        return np.maximum(sig, floor)

    def apply(self, poses: Array, u: Array, dt: float, rng: np.random.Generator) -> Array:
        u = np.asarray(u, dtype=float)
        if self.is_still(u):
            return compose(poses, u)
        noise = rng.normal(size=poses.shape) * self.noise_sigma(u, dt)
        return compose(poses, u + noise)


@dataclass
class DiffDriveMotion:
    """Differential drive: each wheel's travel drawn from N(ds, k * |ds|), then the arc update.

    ``axle`` is the distance between the wheels (m). Poses are those of the axle centre.
    """

    axle: float = 0.33
    k_left: float = 0.05
    k_right: float = 0.05

    @staticmethod
    def arc(poses: Array, dl: Array, dr: Array, axle: float) -> Array:
        ds = 0.5 * (dl + dr)
        dth = (dr - dl) / axle
        # Exact arc: move along the chord at the mid heading.
        small = np.abs(dth) < 1e-9
        chord = np.where(small, ds, 2.0 * ds / np.where(small, 1.0, dth) * np.sin(0.5 * dth))
        mid = poses[..., 2] + 0.5 * dth
        out = np.empty_like(poses)
        out[..., 0] = poses[..., 0] + chord * np.cos(mid)
        out[..., 1] = poses[..., 1] + chord * np.sin(mid)
        out[..., 2] = wrap_angle(poses[..., 2] + dth)
        return out

    def apply(self, poses: Array, dl: float | Array, dr: float | Array, rng: np.random.Generator) -> Array:
        """Move ``poses`` by the wheel travel ``dl``, ``dr`` (m; one for all, or one per pose)
        with noise proportional to each wheel's travel."""
        n = len(poses)
        l_ = dl + rng.normal(size=n) * self.k_left * np.abs(dl)
        r_ = dr + rng.normal(size=n) * self.k_right * np.abs(dr)
        return self.arc(poses, l_, r_, self.axle)


@dataclass
class AmclOdometryMotion:
    """The odometry motion model of probabilistic robotics (as in AMCL's "diff" model).

    The increment ``u = o_{t-1} ⊖ o_t`` is split into a turn ``rot1`` towards the
    direction of travel, a translation ``trans`` and a final turn ``rot2``; each is
    perturbed with a standard deviation of ``alpha1·|rot| + alpha2·trans`` (turns) and
    ``alpha3·trans + alpha4·(|rot1| + |rot2|)`` (translation). Driving backwards is a
    negative translation, not a half turn. No noise while the robot stands still.
    """

    alpha1: float = 0.2  # rad of turn noise per rad turned
    alpha2: float = 0.2  # rad of turn noise per metre travelled
    alpha3: float = 0.2  # m of translation noise per metre travelled
    alpha4: float = 0.2  # m of translation noise per rad turned
    eps_trans: float = 1e-4
    eps_rot: float = 1e-4

    def is_still(self, u: Array) -> bool:
        return bool(np.hypot(u[0], u[1]) < self.eps_trans and abs(u[2]) < self.eps_rot)

    def apply(self, poses: Array, u: Array, dt: float, rng: np.random.Generator) -> Array:
        """``dt`` is not used: the noise depends on the motion alone, as in AMCL."""
        u = np.asarray(u, dtype=float)
        trans = float(np.hypot(u[0], u[1]))
        if self.is_still(u):
            return compose(poses, u)
        rot1 = float(np.arctan2(u[1], u[0])) if trans > 0.0 else 0.0
        sign = 1.0
        if abs(rot1) > np.pi / 2:  # backwards
            rot1 = float(wrap_angle(rot1 - np.pi))
            sign = -1.0
        rot2 = float(wrap_angle(u[2] - rot1))
        # The split is exact (noise-free it reproduces compose(p, u)), but below 1 cm of
        # travel the direction of motion is mostly jitter: size the turn noise as if the
        # whole turn were rot2, or a sideways millimetre would add alpha1 * 90 deg of noise.
        n1, n2 = (abs(rot1), abs(rot2)) if trans > 0.01 else (0.0, abs(float(u[2])))
        n = len(poses)
        s1 = self.alpha1 * n1 + self.alpha2 * trans
        st = self.alpha3 * trans + self.alpha4 * (n1 + n2)
        s2 = self.alpha1 * n2 + self.alpha2 * trans
        r1 = rot1 + rng.normal(size=n) * s1
        tr = sign * trans + rng.normal(size=n) * st
        r2 = rot2 + rng.normal(size=n) * s2
        out = np.empty_like(poses)
        h = poses[:, 2] + r1
        out[:, 0] = poses[:, 0] + tr * np.cos(h)
        out[:, 1] = poses[:, 1] + tr * np.sin(h)
        out[:, 2] = wrap_angle(h + r2)
        return out


@dataclass
class OmniOdometryMotion(AmclOdometryMotion):
    """Odometry noise sized by the net motion, for robots that also move sideways (AMCL's
    "omni" family): a walking humanoid sways across its path, so the direction of travel
    swings by tens of degrees from one step to the next while the net turn is small.

    The increment ``u`` is perturbed in the frame of its direction of travel: along it by
    ``alpha3·trans + alpha4·|turn|``, across it by ``alpha5·trans + alpha4·|turn|`` (m), and
    the heading by ``alpha1·|turn| + alpha2·trans`` (rad), where ``trans`` is the distance
    and ``turn`` the net heading change of ``u``. Unlike :class:`AmclOdometryMotion`, a
    sideways step is not counted as two opposite turns (which, with AMCL's alpha4 of 0.2 m
    per rad, gives 17 cm of translation noise to a 1.25 cm step of a robot swaying 6 cm).
    No noise while the robot stands still.
    """

    alpha5: float = 0.1  # m of noise across the travel per metre travelled (alpha1..alpha4 as AMCL's)

    def apply(self, poses: Array, u: Array, dt: float, rng: np.random.Generator) -> Array:
        """``dt`` is not used: the noise depends on the motion alone, as in AMCL."""
        u = np.asarray(u, dtype=float)
        if self.is_still(u):
            return compose(poses, u)
        trans, turn = float(np.hypot(u[0], u[1])), abs(float(u[2]))
        n = len(poses)
        along = rng.normal(size=n) * (self.alpha3 * trans + self.alpha4 * turn)
        across = rng.normal(size=n) * (self.alpha5 * trans + self.alpha4 * turn)
        dth = rng.normal(size=n) * (self.alpha1 * turn + self.alpha2 * trans)
        b = float(np.arctan2(u[1], u[0])) if trans > 0.0 else 0.0
        cb, sb = np.cos(b), np.sin(b)
        noisy = np.empty((n, 3))
        noisy[:, 0] = u[0] + cb * along - sb * across
        noisy[:, 1] = u[1] + sb * along + cb * across
        noisy[:, 2] = u[2] + dth
        return compose(poses, noisy)
