"""Rigid transforms as 4x4 matrices, and a tree of ROS ``/tf`` and ``/tf_static`` transforms
that chains them between two frames at a time (shared by the ROS bag reader and writer)."""

from __future__ import annotations

from array import array
from collections.abc import Sequence
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

from pfslam.geometry import quat_matrix, slerp
from pfslam.types import Array


def rigid(xyz: ArrayLike, q: ArrayLike) -> Array:
    """4x4 transforms ``[..., 4, 4]`` from translations ``[..., 3]`` and quaternions ``[..., 4]`` (x, y, z, w)."""
    xyz = np.asarray(xyz, dtype=float)
    r = quat_matrix(q)
    out = np.zeros(r.shape[:-2] + (4, 4))
    out[..., :3, :3] = r
    out[..., :3, 3] = xyz
    out[..., 3, 3] = 1.0
    return out


def rigid_inverse(m: Array) -> Array:
    """Inverse of rigid transforms ``[..., 4, 4]``."""
    r = np.swapaxes(m[..., :3, :3], -1, -2)
    out = np.zeros_like(m)
    out[..., :3, :3] = r
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", r, m[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def frame_name(name: str) -> str:
    return str(name).lstrip("/")


class TfTree:
    """The frames of a bag's transforms as a tree: each frame has one parent and the
    transform from the parent to it (the pose of the child in the parent frame), either
    fixed (``/tf_static``) or a time series (``/tf``, or an odometry topic), interpolated
    when looked up."""

    def __init__(self) -> None:
        self.parent: dict[str, str] = {}
        self.static: dict[str, Array] = {}  # child -> 4x4
        self.moving: set[str] = set()  # children whose link /tf (or odometry) moves
        self.samples: dict[str, array] = {}  # child -> (t, bag t, x, y, z, qx, qy, qz, qw) per sample

    def link(self, parent: str, child: str, moving: bool) -> bool:
        """Note the link parent -> child (the first parent named for a child is kept);
        whether it is the child's link."""
        have = self.parent.setdefault(child, parent)
        if have != parent:
            return False
        if moving:
            self.moving.add(child)
        return True

    def set_static(self, parent: str, child: str, transform: Array) -> None:
        if self.link(parent, child, moving=False):
            self.static[child] = transform

    def replace(self, parent: str, child: str) -> None:
        """Make ``parent`` -> ``child`` a moving link whatever the transforms said (an odometry topic)."""
        self.parent[child] = parent
        self.static.pop(child, None)
        self.moving.add(child)
        self.samples[child] = array("d")

    def add_sample(self, child: str, t: float, bag_t: float, xyz: Sequence[float], q: Sequence[float]) -> None:
        self.samples.setdefault(child, array("d")).extend((t, bag_t, *xyz, *q))

    def frames(self) -> set[str]:
        return set(self.parent) | set(self.parent.values())

    def _up(self, frame: str) -> list[str]:
        """``frame`` and its ancestors, up to the root."""
        out = [frame]
        while out[-1] in self.parent and len(out) <= len(self.parent):
            out.append(self.parent[out[-1]])
        return out

    def path(self, a: str, b: str) -> list[tuple[str, bool]] | None:
        """The links from frame ``a`` to frame ``b``, as (child, inverted) in the order their
        transforms multiply to give the pose of ``b`` in ``a``; None when they are not connected."""
        up_a, up_b = self._up(a), self._up(b)
        common = next((f for f in up_b if f in set(up_a)), None)
        if common is None:
            return None
        ka, kb = up_a.index(common), up_b.index(common)
        return [(c, True) for c in up_a[:ka]] + [(c, False) for c in reversed(up_b[:kb])]

    def span(self, child: str, by_bag_time: bool = False) -> tuple[float, float]:
        """First and last sample time of a moving link."""
        s = self._series(child)
        col = s[:, 1] if by_bag_time else s[:, 0]
        return float(col[0]), float(col[-1])

    def _series(self, child: str) -> Array:
        return np.frombuffer(self.samples.get(child, array("d")), dtype=float).reshape(-1, 9)

    def at(self, child: str, t: Array, by_bag_time: bool = False) -> Array:
        """The link's transforms (N, 4, 4) at times ``t``; a fixed link's (4, 4)."""
        s = self._series(child)
        if child not in self.moving or (not len(s) and child in self.static):
            return self.static[child]
        if not len(s):
            raise ValueError(f"no transform of '{self.parent[child]}' -> '{child}' was read")
        order = np.argsort(s[:, 1] if by_bag_time else s[:, 0], kind="stable")
        s = s[order]
        ts = s[:, 1] if by_bag_time else s[:, 0]
        n = len(ts)
        j = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, n - 1)
        k = np.minimum(j + 1, n - 1)
        dt = ts[k] - ts[j]
        f = np.where(dt > 0, (t - ts[j]) / np.where(dt > 0, dt, 1.0), 0.0)
        f = np.clip(f, 0.0, 1.0)
        xyz = s[j, 2:5] + f[:, None] * (s[k, 2:5] - s[j, 2:5])
        q = slerp(s[j, 5:9], s[k, 5:9], f)
        return rigid(xyz, q)

    def lookup(self, a: str, b: str, t: Array, by_bag_time: bool = False) -> Array | None:
        """The pose of frame ``b`` in frame ``a`` at times ``t``: (N, 4, 4) if a moving link is
        on the way, else (4, 4); None when the two frames are not connected."""
        steps = self.path(a, b)
        if steps is None:
            return None
        out: Array = np.eye(4)
        for child, inverted in steps:
            m = self.at(child, t, by_bag_time)
            out = out @ (rigid_inverse(m) if inverted else m)
        return out

    def moving_on(self, a: str, b: str) -> set[str]:
        """The moving links on the way from ``a`` to ``b``."""
        return {c for c, _ in (self.path(a, b) or []) if c in self.moving}


class Vector3(Protocol):
    """A ``geometry_msgs/Vector3`` (or ``Point``) as rosbags decodes it."""

    x: float
    y: float
    z: float


class Quaternion(Protocol):
    """A ``geometry_msgs/Quaternion`` as rosbags decodes it."""

    x: float
    y: float
    z: float
    w: float


class Transform(Protocol):
    """A ``geometry_msgs/Transform`` as rosbags decodes it."""

    translation: Vector3
    rotation: Quaternion


def ros_transform(tr: Transform) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
    """(translation, rotation) of a ``geometry_msgs/Transform``."""
    v, q = tr.translation, tr.rotation
    return (float(v.x), float(v.y), float(v.z)), (float(q.x), float(q.y), float(q.z), float(q.w))
