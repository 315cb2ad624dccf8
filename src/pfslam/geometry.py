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
