"""The ROS messages the bag reader uses, as rosbags decodes them: only the fields read, as
Protocols (a decoded message of the topic's type has them)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from pfslam.io.transforms import Quaternion, Transform, Vector3


class Time(Protocol):
    """A ``builtin_interfaces/Time``."""

    sec: int
    nanosec: int


class Header(Protocol):
    """A ``std_msgs/Header``."""

    stamp: Time
    frame_id: str


class LaserScan(Protocol):
    """A ``sensor_msgs/LaserScan``."""

    header: Header
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    ranges: NDArray[np.float32]


class Pose(Protocol):
    """A ``geometry_msgs/Pose``."""

    position: Vector3
    orientation: Quaternion


class PoseWithCovariance(Protocol):
    """A ``geometry_msgs/PoseWithCovariance``."""

    pose: Pose


class Odometry(Protocol):
    """A ``nav_msgs/Odometry``."""

    header: Header
    child_frame_id: str
    pose: PoseWithCovariance


class TransformStamped(Protocol):
    """A ``geometry_msgs/TransformStamped``."""

    header: Header
    child_frame_id: str
    transform: Transform


class TFMessage(Protocol):
    """A ``tf2_msgs/TFMessage`` (or ROS 1's ``tf/tfMessage``)."""

    transforms: Sequence[TransformStamped]
