"""Writing a log as a ROS bag: a ROS 1 ``.bag``, a ROS 2 sqlite3 folder or a bare ``.mcap``
(:func:`write_bag`, for ``pfslam convert``), with ``rosbags``' writers; what
:mod:`pfslam.io.rosbag` reads back as the same frames."""

from __future__ import annotations

import contextlib
import math
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np

from pfslam.errors import InputError
from pfslam.frames import Frame, frame_column, frame_times
from pfslam.geometry import matrix_quat
from pfslam.io.common import num
from pfslam.io.rosbag import ANGLE_TOLERANCE, ODOM_TYPE, SCAN_TYPE, STORAGES, TF_STATIC_TOPIC, TF_TOPIC, split_seconds
from pfslam.types import Array

if TYPE_CHECKING:
    from rosbags.typesys.store import MsgType  # an instance of a typestore's message class


class _Messages:
    """Builds and serializes the messages a bag is written with (ROS 1 or ROS 2 types)."""

    def __init__(self, ros1: bool) -> None:
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore

        self.ros1 = ros1
        self.store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
        if "tf2_msgs/msg/TFMessage" not in self.store.types:
            self.store.register(
                get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage")
            )
        self.T = self.store.types
        self.seq = 0

    def serialize(self, msg: MsgType) -> memoryview:
        if self.ros1:
            return self.store.serialize_ros1(msg, msg.__msgtype__)
        return self.store.serialize_cdr(msg, msg.__msgtype__)

    def header(self, sec: int, ns: int, frame: str) -> MsgType:
        T = self.T
        stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=ns)
        if self.ros1:
            self.seq += 1
            return T["std_msgs/msg/Header"](seq=self.seq, stamp=stamp, frame_id=frame)
        return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def vector(self, v: Sequence[float] | Array) -> MsgType:
        return self.T["geometry_msgs/msg/Vector3"](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def quaternion(self, q: Sequence[float] | Array) -> MsgType:
        return self.T["geometry_msgs/msg/Quaternion"](x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))

    def scan(self, header: MsgType, f: Frame, a0: float, inc: float, interval: float) -> MsgType:
        r = np.asarray(f.ranges, dtype=np.float32)
        return self.T["sensor_msgs/msg/LaserScan"](
            header=header,
            angle_min=a0,
            angle_max=a0 + inc * (len(r) - 1),
            angle_increment=inc,
            time_increment=0.0,
            scan_time=interval,
            range_min=float(f.min_range),
            range_max=float(f.max_range),
            ranges=r,
            intensities=np.zeros(0, dtype=np.float32),
        )

    def odometry(self, header: MsgType, child: str, pose: Array) -> MsgType:
        T = self.T
        c, s = math.cos(0.5 * pose[2]), math.sin(0.5 * pose[2])
        position = T["geometry_msgs/msg/Point"](x=float(pose[0]), y=float(pose[1]), z=0.0)
        p = T["geometry_msgs/msg/Pose"](position=position, orientation=self.quaternion((0.0, 0.0, s, c)))
        zero = self.vector((0.0, 0.0, 0.0))
        still = T["geometry_msgs/msg/Twist"](linear=zero, angular=zero)
        return T["nav_msgs/msg/Odometry"](
            header=header,
            child_frame_id=child,
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=p, covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=still, covariance=np.zeros(36)),
        )

    def tf(self, *links: tuple[MsgType, str, Array]) -> MsgType:
        """A TFMessage of ``(header, child frame, 4 x 4 transform)`` links."""
        T = self.T
        out = []
        for header, child, mount in links:
            tr = T["geometry_msgs/msg/Transform"](
                translation=self.vector(mount[:3, 3]), rotation=self.quaternion(matrix_quat(mount))
            )
            out.append(T["geometry_msgs/msg/TransformStamped"](header=header, child_frame_id=child, transform=tr))
        return T["tf2_msgs/msg/TFMessage"](transforms=out)


def planar_matrix(pose: Array) -> Array:
    """The 4 x 4 transform of a planar pose (x, y, theta)."""
    c, s = math.cos(float(pose[2])), math.sin(float(pose[2]))
    out = np.eye(4)
    out[:2, :2] = [[c, -s], [s, c]]
    out[:2, 3] = pose[:2]
    return out


def beam_layout(angles: Array) -> tuple[float, float] | None:
    """(first angle, step) when the beams are evenly spaced (as a LaserScan holds them), else None."""
    a = np.asarray(angles, dtype=float)
    if len(a) == 0:
        return None
    inc = float((a[-1] - a[0]) / (len(a) - 1)) if len(a) > 1 else 0.0
    if np.abs(a - (a[0] + inc * np.arange(len(a)))).max() > ANGLE_TOLERANCE:
        return None
    return float(a[0]), inc


def write_bag(
    path: str | Path,
    frames: Sequence[Frame],
    odometry: Array,
    storage: str,
    *,
    scan_topic: str = "/scan",
    odom_topic: str = "/odom",
    laser_frame: str = "laser",
    base_frame: str = "base_link",
    odom_frame: str = "odom",
    odom_in_tf: bool = False,
) -> list[str]:
    """Write ``frames`` as a bag at ``path`` (which must not exist): ``storage`` ``ros1`` (a
    ``.bag`` file), ``ros2`` (a ROS 2 folder, sqlite3) or ``mcap`` (a bare ``.mcap`` file).

    Topics: ``scan_topic`` (LaserScan in ``laser_frame``), ``odom_topic`` (Odometry, the pose
    ``odometry[i]`` of ``base_frame`` in ``odom_frame``), ``/tf_static`` (``base_frame`` ->
    ``laser_frame``: the first frame's mount) and, when the mount changes from frame to frame,
    ``/tf`` with that link at every scan. With ``odom_in_tf`` the odometry is the
    ``odom_frame`` -> ``base_frame`` link of ``/tf`` at every scan instead of a topic of its
    own (as many robots record it). Every message is stamped with its frame's time (header and
    record time). Returns the warnings (times moved to be non-negative).

    Raises InputError for beams that are not evenly spaced or a frame without odometry.
    """
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2

    if storage not in STORAGES:
        raise ValueError(f"storage must be one of {', '.join(STORAGES)}, not {storage!r}")
    out = Path(path)
    warnings: list[str] = []
    n = len(frames)
    if n == 0:
        raise InputError(out, "no frames to write")
    odometry = np.asarray(odometry, dtype=float)
    if odometry.shape != (n, 3):
        raise InputError(out, f"odometry has shape {odometry.shape} for {n} frames")
    t = frame_times(frames)
    shift = 0.0
    if t[0] < 0:
        shift = float(math.ceil(-t[0]))
        warnings.append(f"{out}: the log's times start before 0 s; written {num(shift, 0)} s later")
    mounts = cast("list[Array]", frame_column(frames, "mount"))  # a mount is never None
    moving = any(not np.array_equal(m, mounts[0]) for m in mounts)
    interval = float(np.median(np.diff(t))) if n > 1 else 0.0

    with contextlib.ExitStack() as stack:
        if storage == "ros1":
            writer: Writer1 | Writer2 = Writer1(out)
        else:
            target = out
            if storage == "mcap":  # written as a ROS 2 folder beside the target, its storage file moved out
                tmp = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix=".pfslam-", dir=out.parent)))
                target = tmp / (out.stem or "bag")
            plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
            writer = Writer2(target, version=9, storage_plugin=plugin)
        m = _Messages(ros1=storage == "ros1")
        with writer:
            if isinstance(writer, Writer1):  # storage ros1: /tf_static latched, as ROS 1 records it
                c_static = writer.add_connection(
                    TF_STATIC_TOPIC, "tf2_msgs/msg/TFMessage", typestore=m.store, latching=1
                )
            else:
                c_static = writer.add_connection(TF_STATIC_TOPIC, "tf2_msgs/msg/TFMessage", typestore=m.store)
            c_scan = writer.add_connection(scan_topic, SCAN_TYPE, typestore=m.store)
            c_odom = None if odom_in_tf else writer.add_connection(odom_topic, ODOM_TYPE, typestore=m.store)
            c_tf = (
                writer.add_connection(TF_TOPIC, "tf2_msgs/msg/TFMessage", typestore=m.store)
                if moving or odom_in_tf
                else None
            )
            layout = None
            for i, f in enumerate(frames):
                if layout is None:
                    layout = beam_layout(f.angles)
                    if layout is None:
                        raise InputError(out, "the beams are not evenly spaced: a LaserScan cannot hold them")
                sec, ns = split_seconds(float(t[i]) + shift)
                stamp = sec * 1_000_000_000 + ns
                if i == 0:
                    writer.write(
                        c_static,
                        stamp,
                        m.serialize(m.tf((m.header(sec, ns, base_frame), laser_frame, np.asarray(mounts[0])))),
                    )
                if c_odom is not None:
                    writer.write(
                        c_odom, stamp, m.serialize(m.odometry(m.header(sec, ns, odom_frame), base_frame, odometry[i]))
                    )
                if c_tf is not None:
                    links = [(m.header(sec, ns, base_frame), laser_frame, np.asarray(f.mount))] if moving else []
                    if odom_in_tf:
                        links.append((m.header(sec, ns, odom_frame), base_frame, planar_matrix(odometry[i])))
                    writer.write(c_tf, stamp, m.serialize(m.tf(*links)))
                writer.write(c_scan, stamp, m.serialize(m.scan(m.header(sec, ns, laser_frame), f, *layout, interval)))
        if storage == "mcap":
            written = next(target.glob("*.mcap"))
            shutil.move(str(written), str(out))
    return warnings
