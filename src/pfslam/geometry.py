"""SE(2) and SE(3) helpers.

Poses are arrays ``[..., 3]`` of ``(x, y, theta)``. Every function is vectorised
over leading dimensions.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


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


def quat_matrix(q: ArrayLike) -> Array:
    """3x3 rotation matrices ``[..., 3, 3]`` of quaternions ``[..., (x, y, z, w)]`` (normalised
    first; a zero quaternion is the identity)."""
    q = np.asarray(q, dtype=float)
    n = np.sqrt(np.sum(q * q, axis=-1, keepdims=True))
    q = np.where(n > 0, q / np.where(n > 0, n, 1.0), np.array([0.0, 0.0, 0.0, 1.0]))
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(q.shape[:-1] + (3, 3))
    out[..., 0, 0] = 1.0 - 2.0 * (y * y + z * z)
    out[..., 0, 1] = 2.0 * (x * y - w * z)
    out[..., 0, 2] = 2.0 * (x * z + w * y)
    out[..., 1, 0] = 2.0 * (x * y + w * z)
    out[..., 1, 1] = 1.0 - 2.0 * (x * x + z * z)
    out[..., 1, 2] = 2.0 * (y * z - w * x)
    out[..., 2, 0] = 2.0 * (x * z - w * y)
    out[..., 2, 1] = 2.0 * (y * z + w * x)
    out[..., 2, 2] = 1.0 - 2.0 * (x * x + y * y)
    return out


def matrix_quat(r: ArrayLike) -> Array:
    """Unit quaternion ``(x, y, z, w)`` (with ``w >= 0``) of a 3x3 rotation matrix (Shepperd's
    method: the largest of the four squared components is taken first, so it is accurate for
    every rotation, half turns included)."""
    m = np.asarray(r, dtype=float)[:3, :3]
    tr = float(np.trace(m))
    d = (tr, float(m[0, 0]), float(m[1, 1]), float(m[2, 2]))
    k = int(np.argmax(d))
    if k == 0:
        s = 2.0 * np.sqrt(1.0 + tr)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    elif k == 1:
        s = 2.0 * np.sqrt(max(1.0 + m[0, 0] - m[1, 1] - m[2, 2], 0.0))
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif k == 2:
        s = 2.0 * np.sqrt(max(1.0 + m[1, 1] - m[0, 0] - m[2, 2], 0.0))
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(max(1.0 + m[2, 2] - m[0, 0] - m[1, 1], 0.0))
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    out = np.array(q, dtype=float)
    out /= np.linalg.norm(out)
    return -out if out[3] < 0 else out


def slerp(q0: ArrayLike, q1: ArrayLike, f: ArrayLike) -> Array:
    """Quaternions ``[..., 4]`` a fraction ``f`` of the way from ``q0`` to ``q1`` along the
    shorter arc (``f = 0`` gives ``q0`` itself; nearly equal rotations are blended linearly)."""
    q0 = np.asarray(q0, dtype=float)
    q1 = np.asarray(q1, dtype=float)
    f = np.asarray(f, dtype=float)[..., None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0, -q1, q1)
    dot = np.clip(np.abs(dot), 0.0, 1.0)
    theta = np.arccos(dot)
    sin = np.sin(theta)
    near = sin < 1e-9
    safe = np.where(near, 1.0, sin)
    a = np.where(near, 1.0 - f, np.sin((1.0 - f) * theta) / safe)
    b = np.where(near, f, np.sin(f * theta) / safe)
    out = a * q0 + b * q1
    out = out / np.linalg.norm(out, axis=-1, keepdims=True)
    return np.where(f == 0, q0, out)
