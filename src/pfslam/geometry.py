"""SE(2) and SE(3) helpers.

Poses are arrays ``[..., 3]`` of ``(x, y, theta)``. Every function is vectorised
over leading dimensions.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from pfslam.types import Array

if TYPE_CHECKING:
    from scipy.spatial.transform import Rotation


def wrap_angle(a: ArrayLike) -> Array:
    """Wrap angles to [-pi, pi)."""
    a = np.asarray(a, dtype=float)
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def compose(p: ArrayLike, u: ArrayLike) -> Array:
    """p ⊕ u: apply the local-frame motion ``u`` to pose ``p``."""
    p = np.asarray(p, dtype=float)
    u = np.asarray(u, dtype=float)
    c, s = np.cos(p[..., 2]), np.sin(p[..., 2])
    x = p[..., 0] + c * u[..., 0] - s * u[..., 1]
    y = p[..., 1] + s * u[..., 0] + c * u[..., 1]
    th = wrap_angle(p[..., 2] + u[..., 2])
    return np.stack(np.broadcast_arrays(x, y, th), axis=-1)


def relative(a: ArrayLike, b: ArrayLike) -> Array:
    """b ⊖ a: the motion from pose ``a`` to pose ``b`` in ``a``'s local frame.

    ``compose(a, relative(a, b)) == b``.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    dx = b[..., 0] - a[..., 0]
    dy = b[..., 1] - a[..., 1]
    x = c * dx + s * dy
    y = -s * dx + c * dy
    th = wrap_angle(b[..., 2] - a[..., 2])
    return np.stack(np.broadcast_arrays(x, y, th), axis=-1)


def inverse(p: ArrayLike) -> Array:
    """The pose q with p ⊕ q = identity."""
    p = np.asarray(p, dtype=float)
    return relative(p, np.zeros_like(p))


def circular_mean(angles: ArrayLike, weights: ArrayLike | None = None) -> float:
    """Weighted mean of angles on the circle, in [-pi, pi)."""
    a = np.asarray(angles, dtype=float)
    w = np.ones_like(a) if weights is None else np.asarray(weights, dtype=float)
    s = float(np.sum(w * np.sin(a)))
    c = float(np.sum(w * np.cos(a)))
    return float(wrap_angle(np.arctan2(s, c)))


def transform_points(pose: ArrayLike, pts: ArrayLike) -> Array:
    """Points ``(M, 2)`` in the pose's frame to the world frame."""
    pose = np.asarray(pose, dtype=float)
    pts = np.asarray(pts, dtype=float)
    c, s = np.cos(pose[2]), np.sin(pose[2])
    out = np.empty_like(pts)
    out[:, 0] = pose[0] + c * pts[:, 0] - s * pts[:, 1]
    out[:, 1] = pose[1] + s * pts[:, 0] + c * pts[:, 1]
    return out


# --- SE(3) homogeneous transforms -----------------------------------------


def txyz(x: float, y: float, z: float) -> Array:
    """4x4 translation."""
    t = np.eye(4)
    t[:3, 3] = (x, y, z)
    return t


def rx(a: float) -> Array:
    """4x4 rotation about +x."""
    c, s = np.cos(a), np.sin(a)
    t = np.eye(4)
    t[1, 1], t[1, 2], t[2, 1], t[2, 2] = c, -s, s, c
    return t


def ry(a: float) -> Array:
    """4x4 rotation about +y."""
    c, s = np.cos(a), np.sin(a)
    t = np.eye(4)
    t[0, 0], t[0, 2], t[2, 0], t[2, 2] = c, s, -s, c
    return t


def rz(a: float) -> Array:
    """4x4 rotation about +z."""
    c, s = np.cos(a), np.sin(a)
    t = np.eye(4)
    t[0, 0], t[0, 1], t[1, 0], t[1, 1] = c, -s, s, c
    return t


# --- quaternions (x, y, z, w), as ROS writes them -----------------------------


def quat_yaw(q: ArrayLike) -> Array:
    """Heading (rad) of the rotation ``q = [..., (x, y, z, w)]``: the direction of its x axis
    in the horizontal plane, ``atan2(R[1, 0], R[0, 0])`` (the yaw of a ZYX roll-pitch-yaw).
    ``q`` need not be unit length (the formula is homogeneous in it)."""
    q = np.asarray(q, dtype=float)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.arctan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)


def _rotations(q: ArrayLike) -> Rotation:
    """SciPy rotations of quaternions ``[..., (x, y, z, w)]`` as one flat stack (normalised by
    SciPy; a zero quaternion is the identity)."""
    from scipy.spatial.transform import Rotation

    q = np.asarray(q, dtype=float).reshape(-1, 4)
    zero = ~np.any(q != 0.0, axis=1)
    return Rotation.from_quat(np.where(zero[:, None], np.array([0.0, 0.0, 0.0, 1.0]), q))


def quat_matrix(q: ArrayLike) -> Array:
    """3x3 rotation matrices ``[..., 3, 3]`` of quaternions ``[..., (x, y, z, w)]`` (normalised
    first; a zero quaternion is the identity)."""
    shape = np.shape(q)[:-1]
    return np.asarray(_rotations(q).as_matrix()).reshape(shape + (3, 3))


def matrix_quat(r: ArrayLike) -> Array:
    """Unit quaternion ``(x, y, z, w)`` of a 3x3 rotation matrix, with ``w >= 0`` (SciPy's
    canonical form: a half turn's first non-zero component positive)."""
    from scipy.spatial.transform import Rotation

    return np.asarray(Rotation.from_matrix(np.asarray(r, dtype=float)[:3, :3]).as_quat(canonical=True))


def slerp(q0: ArrayLike, q1: ArrayLike, f: ArrayLike) -> Array:
    """Quaternions ``[..., 4]`` a fraction ``f`` of the way from ``q0`` to ``q1`` along the
    shorter arc (``f = 0`` gives the rotation ``q0``): ``q0 · exp(f · log(q0⁻¹ q1))``."""
    from scipy.spatial.transform import Rotation

    shape = np.broadcast_shapes(np.shape(q0), np.shape(q1))
    r0 = _rotations(np.broadcast_to(q0, shape))
    r1 = _rotations(np.broadcast_to(q1, shape))
    frac = np.broadcast_to(np.asarray(f, dtype=float), shape[:-1]).reshape(-1, 1)
    out = r0 * Rotation.from_rotvec((r0.inv() * r1).as_rotvec() * frac)
    return np.asarray(out.as_quat()).reshape(shape)
