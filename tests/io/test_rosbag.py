"""ROS bags: read (ROS 1, ROS 2 sqlite3 and MCAP, bare .mcap), written by `pfslam convert`,
and bad bags as one-line errors. The bags are written here with rosbags itself (not with
pfslam's writer) unless the test is about the converter."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from clirun import invoke as _cli
from clirun import one_line_error as _one_line_error
from datafiles import need
from hypothesis import given, settings
from hypothesis import strategies as st

from pfslam.cli.options import MAX_SCANS_ENV
from pfslam.config import SlamConfig
from pfslam.errors import InputError
from pfslam.eval.metrics import trajectory_errors
from pfslam.geometry import compose, matrix_quat, quat_matrix, quat_yaw, rx, ry, rz, txyz
from pfslam.io.logs import detect_format, load_log
from pfslam.io.rosbag import angle_as_written, ranges_as_written, stamp_seconds
from pfslam.io.synthetic import synthetic_odometry
from pfslam.io.transforms import TfTree, rigid
from pfslam.pipeline import close_loops, run_slam
from pfslam.sensor import scan_to_points
from pfslam.tools.raycast import raycast
from pfslam.tools.worlds import WORLDS

BEAMS = 181
ANGLES = np.deg2rad(np.linspace(-90.0, 90.0, BEAMS))  # -90..+90 deg, the FLASER layout of 181 beams


# --- bags written with rosbags ----------------------------------------------------------------


class Bag:
    """Messages for a ROS 1 or ROS 2 bag, built from the rosbags type store, written in one go."""

    def __init__(self, kind: str) -> None:
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore

        self.kind = kind
        self.store = get_typestore(Stores.ROS1_NOETIC if kind == "ros1" else Stores.ROS2_HUMBLE)
        if "tf2_msgs/msg/TFMessage" not in self.store.types:  # the ROS 1 store lacks it
            self.store.register(
                get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage")
            )
        self.T = self.store.types
        self.messages: list[tuple[str, str, int, object]] = []

    def header(self, t: float, frame: str):
        sec = math.floor(t)
        stamp = self.T["builtin_interfaces/msg/Time"](sec=sec, nanosec=round((t - sec) * 1e9))
        if self.kind == "ros1":
            return self.T["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame)
        return self.T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def add(self, topic: str, t: float, msg, record_t: float | None = None) -> None:
        self.messages.append((topic, msg.__msgtype__, round((t if record_t is None else record_t) * 1e9), msg))

    def scan(
        self,
        topic: str,
        t: float,
        ranges,
        *,
        frame: str = "laser",
        angle_min: float = -math.pi / 2,
        increment: float = math.pi / 180,
        range_min: float = 0.05,
        range_max: float = 30.0,
        record_t=None,
    ):
        self.add(
            topic,
            t,
            self.T["sensor_msgs/msg/LaserScan"](
                header=self.header(t, frame),
                angle_min=angle_min,
                angle_max=angle_min + increment * (len(ranges) - 1),
                angle_increment=increment,
                time_increment=0.0,
                scan_time=0.2,
                range_min=range_min,
                range_max=range_max,
                ranges=np.asarray(ranges, dtype=np.float32),
                intensities=np.zeros(0, dtype=np.float32),
            ),
            record_t,
        )

    def transform(self, t: float, parent: str, child: str, xyz, q):
        T = self.T
        return T["geometry_msgs/msg/TransformStamped"](
            header=self.header(t, parent),
            child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](*map(float, xyz)),
                rotation=T["geometry_msgs/msg/Quaternion"](*map(float, q)),
            ),
        )

    def tf(self, topic: str, t: float, *transforms) -> None:
        self.add(topic, t, self.T["tf2_msgs/msg/TFMessage"](transforms=list(transforms)))

    def odom(self, topic: str, t: float, pose, *, frame: str = "odom", child: str = "base_link") -> None:
        T = self.T
        q = T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(pose[2] / 2), w=math.cos(pose[2] / 2))
        position = T["geometry_msgs/msg/Point"](x=float(pose[0]), y=float(pose[1]), z=0.0)
        p = T["geometry_msgs/msg/Pose"](position=position, orientation=q)
        zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        self.add(
            topic,
            t,
            T["nav_msgs/msg/Odometry"](
                header=self.header(t, frame),
                child_frame_id=child,
                pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=p, covariance=np.zeros(36)),
                twist=T["geometry_msgs/msg/TwistWithCovariance"](
                    twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=np.zeros(36)
                ),
            ),
        )

    def write(self, path: Path) -> Path:
        from rosbags.rosbag1 import Writer as Writer1
        from rosbags.rosbag2 import StoragePlugin
        from rosbags.rosbag2 import Writer as Writer2

        if self.kind == "ros1":
            writer = Writer1(path)
        else:
            plugin = StoragePlugin.MCAP if self.kind == "mcap" else StoragePlugin.SQLITE3
            writer = Writer2(path, version=9, storage_plugin=plugin)
        with writer:
            conns = {}
            for topic, msgtype, ns, msg in sorted(self.messages, key=lambda m: m[2]):
                if topic not in conns:
                    conns[topic] = writer.add_connection(topic, msgtype, typestore=self.store)
                data = (
                    self.store.serialize_ros1(msg, msgtype)
                    if self.kind == "ros1"
                    else self.store.serialize_cdr(msg, msgtype)
                )
                writer.write(conns[topic], ns, data)
        return path


def small_bag(kind: str = "ros1", n: int = 5, scan_topics=("/scan",), odom_topics=("/odom",)) -> Bag:
    """``n`` scans (4 beams) at 10 Hz on each scan topic, odometry moving 0.1 m per scan, the laser
    mounted 0.1 m ahead in /tf_static."""
    b = Bag(kind)
    b.tf("/tf_static", 1.0, b.transform(1.0, "base_link", "laser", (0.1, 0.0, 0.3), (0, 0, 0, 1)))
    for i in range(n):
        t = 1.0 + 0.1 * i
        for topic in odom_topics:
            b.odom(topic, t, (0.1 * i, 0.0, 0.0))
        for topic in scan_topics:
            b.scan(topic, t, [1.0, 2.0, 3.0, 4.0], angle_min=-0.3, increment=0.2)
    return b


# --- units: quaternions, the transform tree, float32 fields -----------------------------------


angle = st.floats(-math.pi + 1e-3, math.pi - 1e-3)


@settings(max_examples=200, deadline=None)
@given(roll=angle, pitch=st.floats(-1.5, 1.5), yaw=angle, scale=st.floats(0.1, 10.0), sign=st.sampled_from([1, -1]))
def test_the_yaw_of_a_quaternion_is_the_heading_of_its_x_axis(roll, pitch, yaw, scale, sign):
    r = rz(yaw) @ ry(pitch) @ rx(roll)
    q = matrix_quat(r)
    np.testing.assert_allclose(quat_matrix(q), r[:3, :3], atol=1e-9)
    # any length, either sign: the same rotation and the same heading
    assert math.isclose(float(quat_yaw(sign * scale * q)), yaw, abs_tol=1e-9)
    assert math.isclose(float(quat_yaw(q)), math.atan2(r[1, 0], r[0, 0]), abs_tol=1e-12)


def test_a_half_turn_quaternion_round_trips():
    for m in (rx(math.pi), ry(math.pi), rz(math.pi), rz(0.3) @ rx(math.pi)):
        np.testing.assert_allclose(quat_matrix(matrix_quat(m)), m[:3, :3], atol=1e-12)
    np.testing.assert_allclose(matrix_quat(rx(math.pi)), [1.0, 0.0, 0.0, 0.0], atol=1e-12)


def _random_transform(rng):
    q = rng.normal(size=4)
    return rigid(rng.normal(size=3), q / np.linalg.norm(q))


def test_tf_chains_through_the_common_ancestor():
    """map -> odom -> base_footprint -> base_link -> laser, and base_link -> imu: any two frames'
    transform is the product of the links between them, inverted going up."""
    rng = np.random.default_rng(4)
    links = {
        "odom": "map",
        "base_footprint": "odom",
        "base_link": "base_footprint",
        "laser": "base_link",
        "imu": "base_link",
    }
    tree = TfTree()
    mats = {}
    for child, parent in links.items():
        mats[child] = _random_transform(rng)
        tree.set_static(parent, child, mats[child])
    t = np.zeros(1)
    np.testing.assert_allclose(
        tree.lookup("odom", "laser", t), mats["base_footprint"] @ mats["base_link"] @ mats["laser"], atol=1e-12
    )
    np.testing.assert_allclose(tree.lookup("laser", "imu", t), np.linalg.inv(mats["laser"]) @ mats["imu"], atol=1e-12)
    np.testing.assert_allclose(tree.lookup("laser", "odom", t) @ tree.lookup("odom", "laser", t), np.eye(4), atol=1e-12)
    assert tree.path("laser", "laser") == []
    assert tree.lookup("laser", "elsewhere", t) is None
    # the first parent named for a frame is kept
    tree.set_static("imu", "base_link", np.eye(4))
    assert tree.parent["base_link"] == "base_footprint"


def test_a_moving_link_is_interpolated_and_held_at_its_ends():
    tree = TfTree()
    tree.link("odom", "base_link", moving=True)
    for t, x, yaw in [(1.0, 0.0, 0.0), (2.0, 1.0, math.pi / 2), (3.0, 1.0, math.pi)]:
        tree.add_sample("base_link", t, t, (x, 0.0, 0.0), (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)))
    m = tree.lookup("odom", "base_link", np.array([0.0, 1.5, 2.0, 2.75, 9.0]))
    np.testing.assert_allclose(m[:, 0, 3], [0.0, 0.5, 1.0, 1.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(
        np.arctan2(m[:, 1, 0], m[:, 0, 0]), [0.0, math.pi / 4, math.pi / 2, 7 * math.pi / 8, math.pi], atol=1e-9
    )
    # a sample time gives that sample exactly
    assert m[2, 0, 3] == 1.0


def test_float32_fields_read_as_the_decimals_they_were_written_from():
    written = np.array([1.09, 0.99, 12.345, 79.99, np.inf, np.nan, -np.inf])
    r = ranges_as_written(written.astype(np.float32))
    assert r.dtype == np.float64
    np.testing.assert_array_equal(r[:4], written[:4])  # exactly, not float32(1.09) = 1.0900000333786
    assert np.isposinf(r[4]) and np.isnan(r[5]) and np.isneginf(r[6])
    # a scan of arbitrary float32 values stays as it is
    rng = np.random.default_rng(0)
    raw = rng.uniform(0.1, 30.0, 1081).astype(np.float32)
    assert ranges_as_written(raw) is not None and ranges_as_written(raw).dtype == np.float32
    assert angle_as_written(float(np.float32(-math.pi / 2))) == -math.pi / 2
    assert angle_as_written(float(np.float32(math.radians(0.25)))) == math.radians(0.25)
    odd = float(np.float32(0.123456789))
    assert angle_as_written(odd) == odd


def test_a_zero_stamp_is_the_record_time():
    class Stamp:
        def __init__(self, sec, nanosec):
            self.sec, self.nanosec = sec, nanosec

    assert stamp_seconds(Stamp(0, 0), 2_500_000_000) == 2.5
    assert stamp_seconds(Stamp(32, 906800000), 1) == 32.9068
    assert stamp_seconds(Stamp(1_700_000_000, 1), 1) == 1_700_000_000 + 1e-9


# --- reading ------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["ros1", "ros2", "mcap"])
def test_each_kind_of_bag_is_read(tmp_path, kind):
    name = {"ros1": "a.bag", "ros2": "a", "mcap": "a"}[kind]
    path = small_bag(kind).write(tmp_path / name)
    assert detect_format(path) == "rosbag"
    log = load_log(path)
    assert log.format == {"ros1": "rosbag1", "ros2": "rosbag2-sqlite3", "mcap": "rosbag2-mcap"}[kind]
    f = log.frames
    assert len(f) == 5 and log.warnings == []
    np.testing.assert_allclose(f.t, 1.0 + 0.1 * np.arange(5))
    np.testing.assert_allclose(f.odom[:, 0], 0.1 * np.arange(5))
    np.testing.assert_allclose(f[0].angles, [-0.3, -0.1, 0.1, 0.3], atol=1e-7)
    assert f[2].ranges.tolist() == [1.0, 2.0, 3.0, 4.0]
    assert (f.min_range, f.max_range) == (0.05, 30.0)
    np.testing.assert_allclose(f[0].mount, txyz(0.1, 0.0, 0.3))
    if kind == "ros1":  # found by its header whatever its name
        other = tmp_path / "recording"
        other.write_bytes(path.read_bytes())
        assert detect_format(other) == "rosbag" and len(load_log(other).frames) == 5
    if kind == "ros2":  # its metadata.yaml or storage file opens the folder
        assert len(load_log(path / "metadata.yaml").frames) == len(load_log(next(path.glob("*.db3"))).frames) == 5
    if kind == "mcap":  # the storage file alone: a bare .mcap
        bare = next(path.glob("*.mcap"))
        assert load_log(bare).format == "rosbag2-mcap"  # inside its folder: the folder is read
        lone = tmp_path / "lone.mcap"
        lone.write_bytes(bare.read_bytes())
        assert load_log(lone).format == "mcap" and len(load_log(lone).frames) == 5


def test_rep117_no_returns_stay_and_the_scan_window_is_the_frames(tmp_path):
    b = Bag("ros1")
    b.tf("/tf_static", 1.0, b.transform(1.0, "base_link", "laser", (0.0, 0.0, 0.3), (0, 0, 0, 1)))
    for i in range(4):  # the last scan's window is narrower
        b.odom("/odom", 1.0 + i, (0.0, 0.0, 0.0))
        b.scan(
            "/scan",
            1.0 + i,
            [np.inf, -np.inf, np.nan, 0.01, 2.5, 9.0, 6.0],
            range_min=0.02,
            range_max=8.0 if i < 3 else 5.0,
            angle_min=-0.5,
            increment=0.2,
        )
    f = load_log(b.write(tmp_path / "r.bag")).frames
    r = f[0].ranges
    assert np.isposinf(r[0]) and np.isneginf(r[1]) and np.isnan(r[2]) and r[6] == 6.0
    assert (f.min_range, f.max_range) == (0.02, 8.0)
    pts = scan_to_points(f[0])
    np.testing.assert_allclose(pts.hits[0], [2.5 * math.cos(0.3), 2.5 * math.sin(0.3)], atol=1e-6)
    assert len(pts.hits) == 2  # 2.5 and 6 m: not 0.01 (below range_min), not 9 (beyond range_max)
    assert np.isposinf(f[3].ranges[6]) and len(scan_to_points(f[3]).hits) == 1  # 6 m is beyond 5


def test_stamps_zero_glitches_and_odometry_outside_the_scans(tmp_path):
    b = Bag("ros2")
    b.tf("/tf_static", 0.5, b.transform(0.5, "base_link", "laser", (0.0, 0.0, 0.3), (0, 0, 0, 1)))
    for i in range(20):
        b.odom("/odom", 2.0 + 0.1 * i, (float(i), 0.0, 0.0))
    stamps = [1.0 + 0.1 * i for i in range(20)]
    stamps[5] = stamps[4]  # a repeated stamp
    for i, t in enumerate(stamps):
        b.scan("/scan", 0.0 if i == 7 else t, [1.0, 2.0], record_t=1.0 + 0.1 * i, angle_min=0.0, increment=0.1)
    log = load_log(b.write(tmp_path / "g"))
    t = log.frames.t
    assert (np.diff(t) > 0).all()
    assert math.isclose(t[7], 1.7)  # a zero stamp: the record time
    assert any("did not advance" in w for w in log.warnings)
    assert any("outside the odometry's time span" in w for w in log.warnings)
    assert log.frames.odom[0, 0] == 0.0  # held at the first odometry pose


def _chained_tf_bag(kind: str, moving: bool = True, odometry_topic: bool = False) -> Bag:
    """odom -> base_footprint (moving, /tf at 2 Hz) -> base_link -> laser (upside down, 0.2 m ahead);
    with ``odometry_topic`` also /wheel_odom, standing still."""
    b = Bag(kind)
    if odometry_topic:
        for i in range(5):
            b.odom("/wheel_odom", 0.5 * i, (0.0, 0.0, 0.0), child="base_footprint")
    b.tf(
        "/tf_static",
        0.0,
        b.transform(0.0, "base_footprint", "base_link", (0.0, 0.0, 0.1), (0, 0, 0, 1)),
        b.transform(0.0, "base_link", "laser", (0.2, 0.0, 0.2), (1.0, 0.0, 0.0, 0.0)),
    )
    for i in range(5 if moving else 0):
        yaw = 0.2 * i
        b.tf(
            "/tf",
            0.5 * i,
            b.transform(
                0.5 * i, "odom", "base_footprint", (1.0 * i, 0.0, 0.0), (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
            ),
        )
    for i in range(4):
        b.scan("/scan", 0.25 + 0.5 * i, [1.0, np.inf, np.inf], angle_min=-0.5, increment=0.5)
    return b


def test_odometry_from_chained_tf_and_a_laser_upside_down(tmp_path):
    """The odometry is interpolated at the scans through the chain; a return on the right of the
    upside-down laser lies on the robot's left."""
    f = load_log(_chained_tf_bag("mcap").write(tmp_path / "tf")).frames
    np.testing.assert_allclose(f.odom, [[0.5 + i, 0.0, 0.1 + 0.2 * i] for i in range(4)], atol=1e-9)
    np.testing.assert_allclose(f[0].mount, txyz(0.2, 0.0, 0.3) @ rx(math.pi), atol=1e-12)
    np.testing.assert_allclose(scan_to_points(f[0]).hits, [[0.2 + math.cos(0.5), math.sin(0.5)]], atol=1e-7)
    with pytest.raises(
        InputError,
        match="no odometry: no nav_msgs/msg/Odometry topic and no transform from 'odom' to 'base_footprint' in /tf",
    ):
        load_log(_chained_tf_bag("ros1", moving=False).write(tmp_path / "no_odom.bag"))


def test_an_upside_down_laser_converts_to_carmen_as_an_upright_one(tmp_path):
    bag = _chained_tf_bag("ros1").write(tmp_path / "up.bag")
    res, text = _cli("convert", bag, tmp_path / "up.log")
    assert res.exit_code == 0, text
    a, b = load_log(bag).frames, load_log(tmp_path / "up.log").frames
    assert "ROBOTLASER1" in (tmp_path / "up.log").read_text()  # 3 beams over 60 deg: not a FLASER scan
    for fa, fb in zip(a, b):
        np.testing.assert_allclose(scan_to_points(fb).hits, scan_to_points(fa).hits, atol=1e-6)
        np.testing.assert_allclose(fb.odom, fa.odom, atol=1e-6)
    assert b[0].mount[2, 2] == 1.0  # upright in the CARMEN log


def test_odometry_topic_or_tf_and_another_base_frame(tmp_path):
    path = _chained_tf_bag("ros2", odometry_topic=True).write(tmp_path / "both")
    assert not load_log(path).frames.odom.any()  # the Odometry topic first: standing still
    f = load_log(path, odom_topic="/tf").frames
    np.testing.assert_allclose(f.odom[:, 0], 0.5 + np.arange(4), atol=1e-9)
    # from base_link (0.1 m up) the level laser is 0.2 m higher: raised to the nominal 0.3 m so
    # that no beam of it counts as a floor hit
    g = load_log(path, odom_topic="tf", base_frame="base_link").frames
    np.testing.assert_allclose(g.odom, f.odom, atol=1e-9)
    np.testing.assert_allclose(g[0].mount, txyz(0.2, 0.0, 0.3) @ rx(math.pi), atol=1e-12)
    assert len(scan_to_points(g[0]).hits) == 1
    with pytest.raises(InputError, match="no transform from 'elsewhere' to 'base_link' in /tf"):
        load_log(path, odom_topic="/tf", odom_frame="elsewhere", base_frame="base_link")


def test_no_scan_topic_and_messages_of_another_type(tmp_path):
    from rosbags.typesys import get_types_from_msg

    b = small_bag("ros2", scan_topics=())
    b.store.register(get_types_from_msg("float32[] ranges", "acme_msgs/msg/Sweep"))
    b.add("/sweep", 1.0, b.store.types["acme_msgs/msg/Sweep"](ranges=np.ones(3, dtype=np.float32)))
    path = b.write(tmp_path / "noscan")
    with pytest.raises(InputError) as e:
        load_log(path)
    assert str(e.value) == (
        f"{path}: no sensor_msgs/msg/LaserScan topic with messages (topics: /odom "
        "(nav_msgs/msg/Odometry), /sweep (acme_msgs/msg/Sweep), /tf_static "
        "(tf2_msgs/msg/TFMessage))"
    )
    with pytest.raises(
        InputError, match="--scan-topic /sweep: the topic holds acme_msgs/msg/Sweep, not sensor_msgs/msg/LaserScan"
    ):
        load_log(path, scan_topic="/sweep")


def test_scans_unlike_the_first_are_skipped(tmp_path):
    b = small_bag(n=4)
    b.scan("/scan", 1.35, [1.0, 2.0, 3.0])  # three beams, not four
    log = load_log(b.write(tmp_path / "s.bag"))
    assert len(log.frames) == 4
    assert log.warnings == [
        f"{tmp_path / 's.bag'}: skipped 1 of 5 scan(s) on /scan unlike the first (first: scan 5: 3 beams, not 4)"
    ]


def test_topic_and_frame_options(tmp_path):
    b = small_bag(scan_topics=("/front/scan", "/rear/scan"), odom_topics=("/odom", "/ekf/odom"))
    path = b.write(tmp_path / "two.bag")
    with pytest.raises(InputError) as e:
        load_log(path)
    assert str(e.value) == (
        f"{path}: 2 sensor_msgs/msg/LaserScan topics (/front/scan, /rear/scan): choose one with --scan-topic"
    )
    with pytest.raises(InputError, match="2 nav_msgs/msg/Odometry topics"):
        load_log(path, scan_topic="/rear/scan")
    log = load_log(path, scan_topic="rear/scan", odom_topic="/ekf/odom")  # the leading slash may be left out
    assert len(log.frames) == 5
    with pytest.raises(InputError, match=r"--scan-topic /odom: the topic holds nav_msgs/msg/Odometry"):
        load_log(path, scan_topic="/odom", odom_topic="/odom")
    with pytest.raises(
        InputError,
        match=r"--odom-topic /nope: no such topic \(nav_msgs/msg/Odometry topics: "
        r"/ekf/odom, /odom\)",
    ):
        load_log(path, scan_topic="/rear/scan", odom_topic="/nope")
    with pytest.raises(InputError, match="--base-frame applies to ROS bags, not to a CARMEN log"):
        p = tmp_path / "a.log"
        p.write_text("FLASER 1 1.0 0 0 0 0 0 0 1 h 1\n")
        load_log(p, base_frame="base_link")


# --- the command line ---------------------------------------------------------------------------


def test_cli_bad_bags_are_one_line(tmp_path):
    two = small_bag(scan_topics=("/scan", "/scan2")).write(tmp_path / "two.bag")
    res, text = _cli("slam", two, "-o", tmp_path / "o1")
    _one_line_error(res, text, "two.bag", "/scan, /scan2", "--scan-topic")
    res, text = _cli("slam", two, "--scan-topic", "/missing", "-o", tmp_path / "o2")
    _one_line_error(res, text, "--scan-topic /missing: no such topic")
    res, text = _cli("calibrate", two, "--scan-topic", "/scan", "--odom-topic", "/gone")
    _one_line_error(res, text, "--odom-topic /gone: no such topic")
    data = (tmp_path / "two.bag").read_bytes()
    for cut in (len(data) // 2, len(data) - 100, 40):
        bad = tmp_path / f"cut{cut}.bag"
        bad.write_bytes(data[:cut])
        res, text = _cli("slam", bad, "-o", tmp_path / f"o{cut}")
        _one_line_error(res, text, bad.name, "cannot read the bag")
    res, text = _cli("calibrate", tmp_path / "cut40.bag")
    _one_line_error(res, text, "cannot read the bag")
    folder = tmp_path / "plain"
    folder.mkdir()
    res, text = _cli("slam", folder, "-o", tmp_path / "o4")
    _one_line_error(res, text, "plain: not a file")


def test_cli_convert_writes_each_format_and_keeps_what_exists(tmp_path):
    src = small_bag(n=6).write(tmp_path / "src.bag")
    for name, fmt in (("o.bag", "rosbag1"), ("o2", "rosbag2-sqlite3"), ("o.mcap", "mcap"), ("o.log.gz", "carmen")):
        res, text = _cli("convert", src, tmp_path / name)
        assert res.exit_code == 0, text
        log = load_log(tmp_path / name)
        assert log.format == fmt and len(log.frames) == 6
        np.testing.assert_allclose(
            log.frames.t if hasattr(log.frames, "t") else [f.t for f in log.frames], 1.0 + 0.1 * np.arange(6), atol=1e-6
        )
        np.testing.assert_allclose(
            scan_to_points(log.frames[3]).hits, scan_to_points(load_log(src).frames[3]).hits, atol=1e-3
        )
    before = (tmp_path / "o.bag").stat().st_mtime_ns
    res, text = _cli("convert", src, tmp_path / "o.bag")
    _one_line_error(res, text, "o.bag", "exists already (--force replaces it)")
    assert (tmp_path / "o.bag").stat().st_mtime_ns == before
    res, text = _cli("convert", src, tmp_path / "o.bag", "--force", "--to", "ros1")
    assert res.exit_code == 0, text
    res, text = _cli("convert", src, tmp_path / "o.txt")
    _one_line_error(res, text, "give --to")
    res, text = _cli("convert", src, tmp_path, "--force")
    _one_line_error(res, text, "is a folder that is not a ROS 2 bag")
    assert not list(tmp_path.glob(".pfslam-*"))  # no half-written output left behind


def test_convert_thor_writes_the_moving_mount_in_tf(short_office, tmp_path):
    res, text = _cli("convert", short_office.lidar_path, tmp_path / "thor", "-j", short_office.joint_path)
    assert res.exit_code == 0, text
    a = load_log(short_office.lidar_path, short_office.joint_path).frames
    b = load_log(tmp_path / "thor").frames
    assert b.mounts.shape == (len(a), 4, 4)
    np.testing.assert_allclose(b.mounts, a.mounts, atol=1e-12)
    np.testing.assert_allclose(b.odom, a.odom, atol=1e-12)
    for i in (0, 200, len(a) - 1):  # arbitrary float32 readings come back as they are
        np.testing.assert_array_equal(b[i].ranges, a[i].ranges)


@pytest.mark.realdata
def test_convert_mines_writes_dead_reckoning(tmp_path):
    exp2 = need("mines/exp2.dat")
    res, text = _cli("convert", exp2, tmp_path / "m.bag")
    assert res.exit_code == 0 and "dead reckoning" in text, text
    from pfslam.io.mines import dead_reckoning

    np.testing.assert_allclose(
        load_log(tmp_path / "m.bag").frames.odom, dead_reckoning(load_log(exp2).frames), atol=1e-9
    )


# --- a tf-only, upside-down, +inf bag against the same data as a CARMEN log ---------------------


def _world_run(tmp_path):
    """A robot along the office corridor, scans at 5 Hz by a laser 0.2 m ahead mounted upside down
    (beam angle a looks at -a), odometry drifting (synthetic, seed 1) at 20 Hz in /tf only. The same
    scans (cm readings) and odometry (read at the scan times) go into a CARMEN log by hand."""
    w = WORLDS["office"]
    rng = np.random.default_rng(7)
    legs = []
    x, y, th = float(w.start[0]), float(w.start[1]), 0.0
    t_hi = np.arange(0.0, 45.0, 0.05)  # 20 Hz
    for t in t_hi:
        legs.append((x, y, th))
        v = 0.6 if x < 25.0 else 0.5
        th = 0.08 * math.sin(t / 2.0) if x < 25.0 else min(th + 0.02, math.pi / 2)
        x += v * 0.05 * math.cos(th)
        y += v * 0.05 * math.sin(th)
    truth_hi = np.array(legs)
    odom_hi = synthetic_odometry(truth_hi, seed=1)
    t_scan = np.arange(0.03, 44.8, 0.2)

    def at(poses, t):
        return np.column_stack(
            [
                np.interp(t, t_hi, poses[:, 0]),
                np.interp(t, t_hi, poses[:, 1]),
                np.interp(t, t_hi, np.unwrap(poses[:, 2])),
            ]
        )

    truth, odom = at(truth_hi, t_scan), at(odom_hi, t_scan)
    scans = []
    for p in truth:
        lx, ly, _ = compose(p, [0.2, 0.0, 0.0])
        world = p[2] - ANGLES  # upside down
        dirs = np.column_stack([np.cos(world), np.sin(world), np.zeros(BEAMS)])
        r = raycast(np.array([lx, ly, 0.3]), dirs, w.segments, w.wall_height, 30.0)
        r = np.round(np.where(r < 30.0, r + rng.normal(0.0, 0.01, BEAMS), np.inf), 2)
        scans.append(r)

    b = Bag("ros1")
    b.tf("/tf_static", 0.0, b.transform(0.0, "base_link", "laser", (0.2, 0.0, 0.3), (1.0, 0.0, 0.0, 0.0)))
    for t, p in zip(t_hi, odom_hi):
        b.tf(
            "/tf",
            100.0 + t,
            b.transform(
                100.0 + t, "odom", "base_link", (p[0], p[1], 0.0), (0.0, 0.0, math.sin(p[2] / 2), math.cos(p[2] / 2))
            ),
        )
    for t, r in zip(t_scan, scans):
        b.scan("/scan", 100.0 + t, r, angle_min=-math.pi / 2, increment=math.pi / 180, range_max=30.0)
    bag = b.write(tmp_path / "tfonly.bag")

    lines = []
    for t, p, r in zip(t_scan, odom, scans):
        upright = np.where(np.isfinite(r), r, 81.83)[::-1]  # beam -a of the upside-down laser is beam a
        laser = compose(p, [0.2, 0.0, 0.0])
        pose = " ".join(f"{v:.6f}" for v in (*laser, *p))
        lines.append(f"FLASER {BEAMS} {' '.join(f'{v:.2f}' for v in upright)} {pose} {100 + t:.6f} sim {100 + t:.6f}")
    log = tmp_path / "same.log"
    log.write_text("\n".join(lines) + "\n")
    return bag, log, 100.0 + t_scan, truth


def test_a_tf_only_upside_down_bag_maps_like_the_same_data_in_carmen(tmp_path):
    bag, carmen_log, t_truth, truth = _world_run(tmp_path)
    a, b = load_log(bag), load_log(carmen_log)
    assert a.format == "rosbag1" and a.warnings == []
    fa, fb = a.frames, b.frames
    assert len(fa) == len(fb) == len(truth)
    # the same points in the robot frame, the same odometry (read from /tf at the scan times)
    for i in (0, 60, 150):  # the upside-down laser's beams come in the other order
        np.testing.assert_allclose(scan_to_points(fa[i]).hits[::-1], scan_to_points(fb[i]).hits, atol=1e-5)
    np.testing.assert_allclose(fa.odom[:, :2], np.array([f.odom for f in fb])[:, :2], atol=1e-6)
    errs = {}
    for name, log in (("bag", a), ("carmen", b)):
        run = close_loops(run_slam(log.frames, SlamConfig(filter="single")))
        errs[name] = trajectory_errors(run.t, run.poses, t_truth, truth).ate_rmse_aligned
        odo = trajectory_errors(run.t, run.odometry, t_truth, truth).ate_rmse_aligned
        assert errs[name] < 0.5 * odo, (name, errs[name], odo)  # the scans correct the drift
    assert abs(errs["bag"] - errs["carmen"]) <= 0.1 * errs["carmen"], errs


# --- the real Intel log through every kind of bag ------------------------------------------------


@pytest.mark.realdata
@pytest.mark.slow
def test_intel_as_bags_gives_the_carmen_trajectory(tmp_path):
    """Intel written as each kind of bag: the ROS 1 bag loads to the CARMEN log's frames (every
    field of every frame, the times and odometry to rounding), the ROS 2 and MCAP bags to the
    very same frames as the ROS 1 bag, and ``pfslam slam`` on the ROS 1 bag gives the CARMEN
    log's trajectory (the same settings for both kinds of log, loops closed). The filter is
    deterministic: the same frames give the same trajectory, so its runs need neither the whole
    log (its first 200 scans: the back end finds loops in them too) nor the other two bags."""
    import dataclasses

    intel = need("carmen/intel.gfs.log.gz")
    bags = {"ros1": tmp_path / "intel.bag", "ros2": tmp_path / "intel_ros2", "mcap": tmp_path / "intel.mcap"}
    for path in bags.values():
        res, text = _cli("convert", intel, path, "--odometry", "synthetic:0")
        assert res.exit_code == 0, text
    first = load_log(bags["ros1"]).frames
    carmen = load_log(intel, odometry="synthetic:0").frames
    assert len(first) == len(carmen) == 910
    for a, b in zip(carmen, first):
        for f in dataclasses.fields(a):
            x, y = getattr(a, f.name), getattr(b, f.name)
            if f.name in ("t", "odom"):  # seconds and nanoseconds, metres as written
                np.testing.assert_allclose(y, x, rtol=0, atol=1e-9, err_msg=f"{f.name} at {a.t}")
            else:
                assert (x is None and y is None) or np.array_equal(x, y, equal_nan=True), (f.name, a.t)
    for k in ("ros2", "mcap"):
        other = load_log(bags[k]).frames
        assert len(other) == len(first) == 910, k
        for a, b in zip(first, other):
            for f in dataclasses.fields(a):
                x, y = getattr(a, f.name), getattr(b, f.name)
                assert (x is None and y is None) or np.array_equal(x, y, equal_nan=True), (k, f.name, a.t)
    scans = 200
    runs = {"carmen": [intel, "--odometry", "synthetic:0"], "ros1": [bags["ros1"]]}
    procs = {
        k: subprocess.Popen(
            [sys.executable, "-m", "pfslam.cli", "slam", *map(str, args), "-o", str(tmp_path / f"out_{k}")],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, MAX_SCANS_ENV: str(scans)},
        )
        for k, args in runs.items()
    }
    for k, p in procs.items():
        _, err = p.communicate(timeout=600)
        assert p.returncode == 0, (k, err)
    info = {k: json.loads((tmp_path / f"out_{k}" / "run.json").read_text()) for k in runs}
    assert info["ros1"]["config"] == info["carmen"]["config"]
    assert info["ros1"]["backend"]["loops_in_graph"] > 25, info["ros1"]["backend"]
    ref = np.loadtxt(tmp_path / "out_carmen" / "trajectory.tum")
    assert len(ref) == scans
    est = np.loadtxt(tmp_path / "out_ros1" / "trajectory.tum")
    assert est.shape == ref.shape
    np.testing.assert_allclose(est[:, 0], ref[:, 0], atol=1e-6)
    assert np.hypot(*(est[:, 1:3] - ref[:, 1:3]).T).max() <= 1e-3
    np.testing.assert_allclose(est[:, 3:], ref[:, 3:], atol=1e-3)
