"""ROS bags: ROS 1 ``.bag`` files, ROS 2 bags (a folder with ``metadata.yaml`` and sqlite3
``.db3`` or MCAP storage) and bare ``.mcap`` files, read with the pure-Python ``rosbags``
library (``rosbags.highlevel.AnyReader``); :mod:`pfslam.io.bagwrite` writes them (with the
writers of ``rosbags.rosbag1`` and ``rosbags.rosbag2``), :mod:`pfslam.io.transforms` holds the
``/tf`` tree both use.

What is read:

- **Scans**: ``sensor_msgs/msg/LaserScan`` on one topic (``scan_topic``, or the bag's only
  LaserScan topic). Beam ``k`` points at ``angle_min + k * angle_increment`` in the scan's
  ``header.frame_id``. Readings follow REP 117: +inf (nothing within range), -inf (too close)
  and NaN (no reading) are no returns and stay in ``Frame.ranges``, where the filters drop
  them like every reading outside ``(range_min, range_max)``, the window that becomes
  ``Frame.min_range`` / ``max_range`` (when a scan's window differs from the others', its
  readings outside its own window are +inf and the frames get the widest window). The
  ranges go, as float32, to a temporary file as they are read and come back one scan at a
  time (:class:`~pfslam.frames.FileRows`), as the decimals they were written from
  (:func:`ranges_as_written`): a long bag takes no more memory than a short one. A scan
  whose beams (count, angles) or frame differ from the first scan's is skipped and counted
  in one warning.
- **Time**: a message's ``header.stamp``, or the bag's record time where that stamp is zero.
  The scans' times go through the rule all loaders share
  (:func:`pfslam.io.times.repair_times`: a stamp that repeats, steps back by at most the time
  tolerance or jumps out alone is repaired and reported; stamps that carry no timing give way
  to the bag's record times).
- **Odometry**: ``nav_msgs/msg/Odometry`` on ``odom_topic`` (or the bag's only Odometry
  topic): the pose of its ``child_frame_id`` in its ``header.frame_id``; without an Odometry
  topic (or with ``odom_topic="/tf"``), the transform from ``odom_frame`` (``odom``) to the
  base frame in ``/tf``, chained through any frames between them. Either is interpolated at
  each scan's time (position linearly, rotation along the shorter arc) and held at its first
  or last value outside its time span (one warning when a scan lies more than 0.1 s outside).
  The planar pose is (x, y, the heading of the base's x axis).
- **Base frame**: ``base_frame`` if given, else the Odometry's ``child_frame_id``, else the
  first of ``base_footprint`` (on the floor: what :class:`~pfslam.frames.Frame` means by the
  robot base) and ``base_link`` that the transforms name.
- **Laser mount**: the transform from the base frame to the scan's frame, chained through
  ``/tf_static`` and ``/tf`` (a link that ``/tf`` moves makes the mount change per scan; it
  then overrides a ``/tf_static`` entry for the same link). A laser mounted upside down (roll
  pi) simply has that in its 4x4 mount. A level laser (its beams within 1 mm per metre of the
  horizontal) lower than ``NOMINAL_LASER_HEIGHT`` above the base frame is raised to it: a
  base frame is not always on the floor, and a level laser's beams never hit the floor, so
  that no beam is mistaken for a floor hit. With no transform between the two frames, the
  laser is taken to sit level at the robot's centre (one warning).
- Frame names lose a leading ``/`` (ROS 1 tf). Messages are read one at a time: the bag's
  raw messages are never kept, and the transforms are read in a first pass so that only the
  links on the chains used are kept in the second.

Bad input -- a missing or ambiguous topic, a topic of another type, no scans, a bag that is
corrupt, truncated or holds messages that cannot be decoded -- is an :class:`InputError`
with one line naming the file; the library never prints.
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
from array import array
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO, cast

import numpy as np
from numpy.typing import NDArray

from pfslam.errors import InputError
from pfslam.frames import FileRows, Frames
from pfslam.io.common import NOMINAL_LASER_HEIGHT, SCAN_TIME_TOLERANCE, LoadedLog, num, reject_joint
from pfslam.io.rosmessages import LaserScan, Odometry, TFMessage, Time
from pfslam.io.times import repair_times
from pfslam.io.transforms import TfTree, frame_name, rigid, ros_transform
from pfslam.types import Array

if TYPE_CHECKING:
    from rosbags.highlevel import AnyReader
    from rosbags.interfaces import Connection

SCAN_TYPE = "sensor_msgs/msg/LaserScan"
ODOM_TYPE = "nav_msgs/msg/Odometry"
TF_TYPES = ("tf2_msgs/msg/TFMessage", "tf/msg/tfMessage")
TF_TOPIC, TF_STATIC_TOPIC = "/tf", "/tf_static"
BASE_FRAMES = ("base_footprint", "base_link")  # the default base frame: the first the transforms name
ODOM_FRAME = "odom"
ROS1_MAGIC = b"#ROSBAG V2.0"
MCAP_MAGIC = b"\x89MCAP0\r\n"
SQLITE_MAGIC = b"SQLite format 3\x00"
LEVEL_TILT = 1e-3  # a laser is level when its beams leave the horizontal by less than this (m per m)
OUTSIDE_ODOMETRY = 0.1  # s a scan may lie outside the odometry's time span before a warning
ANGLE_TOLERANCE = 1e-6  # rad: beams this close to the first scan's are the same beams
RANGE_DECIMALS = 3  # a float32 reading is read as the decimal number of up to this many places (m) it holds
ANGLE_DECIMALS = 4  # ... and a beam angle as the number of up to this many decimal places of degrees
STORAGES = ("ros1", "ros2", "mcap")  # what write_bag writes: a ROS 1 .bag, a ROS 2 sqlite3 folder, a bare .mcap


# --- detection ---------------------------------------------------------------------------------


def is_ros2_folder(path: Path) -> bool:
    """Whether ``path`` is a ROS 2 bag: a folder holding its ``metadata.yaml``."""
    return path.is_dir() and (path / "metadata.yaml").is_file()


def detect(path: Path, head: bytes) -> bool:
    """Whether ``path`` is a ROS bag: a ROS 1 or MCAP header, a ROS 2 bag folder (with
    ``metadata.yaml``), its ``metadata.yaml`` or a ``.db3`` storage file (``head``: the
    file's first bytes as stored; empty for a folder)."""
    if path.is_dir():
        return is_ros2_folder(path)
    if head.startswith(ROS1_MAGIC) or head.startswith(MCAP_MAGIC):
        return True
    if head.startswith(SQLITE_MAGIC):
        return path.suffix == ".db3"
    return path.name == "metadata.yaml" and b"rosbag2_bagfile_information" in head


def _source(path: Path) -> tuple[Path, str]:
    """What to open for ``path`` and the kind of bag: ``rosbag1``, ``rosbag2-sqlite3``,
    ``rosbag2-mcap`` or ``mcap`` (a bare MCAP file). A ROS 2 bag's ``metadata.yaml`` or
    storage file opens its folder."""
    if path.is_file() and (path.name == "metadata.yaml" or path.suffix in (".db3", ".mcap")):
        if is_ros2_folder(path.parent):
            path = path.parent
    if path.is_dir():
        mcap = any(p.suffix == ".mcap" for p in path.iterdir())
        return path, "rosbag2-mcap" if mcap else "rosbag2-sqlite3"
    try:
        with open(path, "rb") as f:
            head = f.read(16)
    except OSError as e:
        raise InputError(path, f"cannot read the file ({e.strerror or e})") from None
    if head.startswith(ROS1_MAGIC):
        return path, "rosbag1"
    if head.startswith(SQLITE_MAGIC):
        return path, "rosbag2-sqlite3"
    return path, "mcap"


@contextlib.contextmanager
def _suffixed(path: Path, kind: str) -> Iterator[Path]:
    """``path``, or a link to it whose name ends as the reader needs (``.bag`` for ROS 1,
    ``.mcap`` / ``.db3`` for a bare storage file): the library picks the reader by suffix."""
    want = {"rosbag1": ".bag", "mcap": ".mcap", "rosbag2-sqlite3": ".db3"}.get(kind)
    if path.is_dir() or want is None or path.suffix == want:
        yield path
        return
    with tempfile.TemporaryDirectory(prefix="pfslam-bag-") as d:
        link = Path(d) / f"log{want}"
        os.symlink(path.resolve(), link)
        yield link


def _bag_errors() -> tuple[type[BaseException], ...]:
    """What ``rosbags`` and the storage libraries under it raise for a bag they cannot read."""
    import sqlite3
    import struct
    import zlib

    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as Reader1Error
    from rosbags.rosbag2 import ReaderError as Reader2Error
    from rosbags.serde import SerdeError
    from rosbags.typesys import TypesysError

    try:  # the sqlite3 storage reads through apsw
        import apsw

        storage: tuple[type[BaseException], ...] = (apsw.Error,)
    except ImportError:
        storage = ()
    return (
        AnyReaderError,
        Reader1Error,
        Reader2Error,
        SerdeError,
        TypesysError,
        sqlite3.Error,
        *storage,
        struct.error,
        zlib.error,
        OSError,
        EOFError,
        ValueError,
        KeyError,
        IndexError,
        TypeError,
        AttributeError,
        AssertionError,
        RuntimeError,
        OverflowError,
    )


def _one_line(e: BaseException) -> str:
    text = " ".join(str(e).split()) or type(e).__name__
    return text if len(text) <= 160 else text[:157] + "..."


# --- time ----------------------------------------------------------------------------------------


def stamp_seconds(stamp: Time, bag_ns: int) -> float:
    """Seconds of a ``builtin_interfaces/Time`` (``sec``, ``nanosec``), or of the bag's
    record time ``bag_ns`` (ns) when the stamp is zero. Divided as integers, so a time
    written from a float comes back as the same float."""
    ns = int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
    return (ns if ns != 0 else int(bag_ns)) / 1_000_000_000


def split_seconds(t: float) -> tuple[int, int]:
    """``t`` (s, not negative) as whole seconds and nanoseconds."""
    sec = math.floor(t)
    ns = round((t - sec) * 1e9)
    if ns >= 1_000_000_000:
        sec, ns = sec + 1, ns - 1_000_000_000
    return int(sec), int(ns)


# --- float32 fields as the numbers they were written from ----------------------------------------


def ranges_as_written(
    r: NDArray[np.float32], decimals: int = RANGE_DECIMALS
) -> NDArray[np.float32] | NDArray[np.float64]:
    """A scan's float32 readings as the decimal numbers they were written from: when every
    finite reading is the float32 of a number of at most ``decimals`` places, those numbers
    (float64), else the readings as they are (float32).

    Lasers measure in whole millimetres (or coarser) and a text log prints a few decimals: the
    readings are then exactly the numbers measured or written -- what the other loaders read
    from text -- and not those numbers plus float32's rounding (up to 1e-6 m on a 10 m
    reading, which a particle filter turns into a different run). Two numbers 1 mm apart
    never share a float32 below 8,000 m, so the numbers are unique. A scan of arbitrary
    float32 values (a simulation's) almost never passes for decimals and stays as it is."""
    r = np.asarray(r, dtype=np.float32)
    x = r.astype(float)
    out = x.copy()
    todo = np.isfinite(x)
    for k in range(decimals + 1):
        if not todo.any():
            return out
        scale = 10.0**k
        v = np.rint(x * scale) / scale
        with np.errstate(invalid="ignore"):
            ok = todo & (v.astype(np.float32) == r)
        out[ok] = v[ok]
        todo &= ~ok
    return r if todo.any() else out


def angle_as_written(a: float, decimals: int = ANGLE_DECIMALS) -> float:
    """A float32 angle (rad) as the radians of the number of degrees with the fewest decimal
    places (up to ``decimals``) whose float32 it is (-pi/2 for float32(-pi/2), where float32
    alone is 4.4e-8 rad off), else as it is."""
    if not math.isfinite(a):
        return a
    a32 = np.float32(a)
    deg = math.degrees(a)
    for k in range(decimals + 1):
        v = math.radians(round(deg, k))
        if np.float32(v) == a32:
            return v
    return a


class DecimalRows:
    """A bag's scans as :class:`~pfslam.frames.Frames` asks for them, one row at a time: the
    float32 ``rows``, readings outside the scan's own window (``lo[i]``, ``hi[i]``) set to
    +inf where that is narrower than the frames' (``rmin``, ``rmax``), then
    :func:`ranges_as_written`."""

    def __init__(self, rows: FileRows, lo: Array, hi: Array, rmin: float, rmax: float) -> None:
        self.rows, self.lo, self.hi = rows, lo, hi
        self.narrower = (lo != rmin) | (hi != rmax)

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, i: int) -> NDArray[np.float32] | NDArray[np.float64]:
        r = np.array(self.rows[i], dtype=np.float32)
        if self.narrower[i]:
            with np.errstate(invalid="ignore"):
                r[(r < self.lo[i]) | (r > self.hi[i])] = np.inf
        return ranges_as_written(r)


# --- reading ----------------------------------------------------------------------------------


@dataclass
class _Scans:
    """The scans of the chosen topic, checked and stored as they are read: the ranges of
    each, as float32, appended to a temporary file (``k`` per scan)."""

    path: Path
    topic: str
    file: BinaryIO | None = None
    k: int = 0
    n: int = 0
    stamps: array = field(default_factory=lambda: array("d"))
    bag_t: array = field(default_factory=lambda: array("d"))
    windows: array = field(default_factory=lambda: array("d"))  # range_min, range_max per scan
    angle_min: float = 0.0
    increment: float = 0.0
    frame_id: str = ""
    skipped: int = 0
    first_skip: str = ""
    seen: int = 0

    def add(self, msg: LaserScan, bag_ns: int) -> None:
        self.seen += 1
        r = np.asarray(msg.ranges, dtype=np.float32)
        a0, inc = float(msg.angle_min), float(msg.angle_increment)
        frame = frame_name(msg.header.frame_id)
        if self.file is None:
            if len(r) == 0:
                return self._skip("no ranges")
            if not (
                math.isfinite(a0)
                and math.isfinite(inc)
                and (inc != 0.0 or len(r) == 1)
                and abs(inc) * (len(r) - 1) <= 2.0 * math.pi * 1.01
            ):
                raise InputError(
                    self.path,
                    f"scan {self.seen} on {self.topic}: beam angles out of range (angle_min "
                    f"{num(a0, 6)} rad, angle_increment {num(inc, 6)} rad x {len(r)} beams)",
                )
            self.file = tempfile.TemporaryFile(prefix="pfslam-scans-")
            self.k = len(r)
            self.angle_min, self.increment, self.frame_id = a0, inc, frame
        else:
            k = self.k
            if len(r) != k:
                return self._skip(f"{len(r)} beams, not {k}")
            if abs(a0 - self.angle_min) > ANGLE_TOLERANCE or abs(inc - self.increment) * k > ANGLE_TOLERANCE:
                return self._skip("other beam angles")
            if frame != self.frame_id:
                return self._skip(f"frame {frame[:40]!r}, not {self.frame_id[:40]!r}")
        self.file.write(r.astype("<f4").tobytes())
        self.stamps.append(stamp_seconds(msg.header.stamp, bag_ns))
        self.bag_t.append(bag_ns / 1_000_000_000)
        self.windows.extend((float(msg.range_min), float(msg.range_max)))
        self.n += 1
        return None

    def _skip(self, why: str) -> None:
        self.skipped += 1
        if not self.first_skip:
            self.first_skip = f"scan {self.seen}: {why}"

    @property
    def angles(self) -> Array:
        return cast(Array, angle_as_written(self.angle_min) + angle_as_written(self.increment) * np.arange(self.k))

    def rows(self) -> FileRows:
        """The ranges written, read back one scan at a time."""
        assert self.file is not None
        self.file.flush()
        n, k = self.n, self.k
        return FileRows(
            self.file,
            np.arange(n, dtype=np.int64) * (4 * k),
            np.full(n, k, dtype=np.int64),
            np.zeros(n, dtype=np.uint8),
            [np.dtype("<f4")],
        )


def _topics(reader: AnyReader) -> tuple[dict[str, str], dict[str, int]]:
    """Topic -> message type (the first connection's), and topic -> messages."""
    types: dict[str, str] = {}
    counts: dict[str, int] = {}
    for c in reader.connections:
        types.setdefault(c.topic, c.msgtype)
        counts[c.topic] = counts.get(c.topic, 0) + int(c.msgcount)
    return types, counts


def _listing(topics: dict[str, str], limit: int = 8) -> str:
    items = [f"{t} ({m})" for t, m in sorted(topics.items())]
    more = f", ... {len(items) - limit} more" if len(items) > limit else ""
    return ", ".join(items[:limit]) + more if items else "none"


def _pick_topic(
    path: Path, topics: dict[str, str], counts: dict[str, int], wanted: str | None, msgtype: str, flag: str
) -> str | None:
    """The topic of ``msgtype`` to read: ``wanted`` (checked), else the only one with messages;
    None if there is none."""
    of_type = sorted(t for t, m in topics.items() if m == msgtype and counts[t])
    if wanted is not None:
        name = wanted if wanted in topics or wanted.startswith("/") else f"/{wanted}"
        if name not in topics:
            raise InputError(path, f"{flag} {wanted}: no such topic ({msgtype} topics: {', '.join(of_type) or 'none'})")
        if topics[name] != msgtype:
            raise InputError(path, f"{flag} {wanted}: the topic holds {topics[name]}, not {msgtype}")
        if not counts[name]:
            raise InputError(path, f"{flag} {wanted}: the topic holds no messages")
        return name
    if len(of_type) > 1:
        raise InputError(path, f"{len(of_type)} {msgtype} topics ({', '.join(of_type)}): choose one with {flag}")
    return of_type[0] if of_type else None


def _first(reader: AnyReader, conns: list[Connection]) -> tuple[object, int] | None:
    """The first message (decoded: of the connections' type) and its record time on ``conns``."""
    gen = reader.messages(connections=conns)
    try:
        for conn, bag_ns, raw in gen:
            return reader.deserialize(raw, conn.msgtype), bag_ns
    finally:
        gen.close()
    return None


@dataclass
class BagLog:
    """What :func:`load_bag` returns: the frames, the kind of bag, warnings, and what was read
    (``topics``: scan and odometry topic, ``frames``: base, laser, odometry frame)."""

    frames: Frames
    kind: str
    warnings: list[str]
    scan_topic: str
    odometry: str  # the odometry topic, or "/tf"
    base_frame: str
    laser_frame: str
    odom_frame: str


def load_bag(
    path: str | Path,
    *,
    scan_topic: str | None = None,
    odom_topic: str | None = None,
    base_frame: str | None = None,
    odom_frame: str | None = None,
    time_tolerance: float = SCAN_TIME_TOLERANCE,
) -> BagLog:
    """Read a ROS bag into :class:`Frames` (see the module notes for what is read and chosen).

    Raises:
        InputError: a missing, corrupt or truncated bag, messages that cannot be decoded, a
            missing or ambiguous topic, no scans, no odometry, time stamps stepping back by
            more than ``time_tolerance`` (and staying back).
    """
    p = Path(path)
    if not p.exists():
        raise InputError(p, "file not found")
    src, kind = _source(p)
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    errors = _bag_errors()
    try:
        with _suffixed(src, kind) as opened:
            reader = AnyReader([opened], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
            with reader:
                return _read(p, kind, reader, scan_topic, odom_topic, base_frame, odom_frame, time_tolerance)
    except InputError:
        raise
    except errors as e:
        raise InputError(p, f"cannot read the bag ({_one_line(e)})") from None


def _read(
    p: Path,
    kind: str,
    reader: AnyReader,
    scan_topic: str | None,
    odom_topic: str | None,
    base_frame: str | None,
    odom_frame: str | None,
    time_tolerance: float,
) -> BagLog:
    topics, counts = _topics(reader)
    scan = _pick_topic(p, topics, counts, scan_topic, SCAN_TYPE, "--scan-topic")
    if scan is None:
        raise InputError(p, f"no {SCAN_TYPE} topic with messages (topics: {_listing(topics)})")
    by_tf = odom_topic is not None and odom_topic.strip("/") == "tf"
    odom = None if by_tf else _pick_topic(p, topics, counts, odom_topic, ODOM_TYPE, "--odom-topic")
    conns = {t: [c for c in reader.connections if c.topic == t] for t in topics}
    tf_topics = [t for t in topics if t.strip("/") in ("tf", "tf_static") and topics[t] in TF_TYPES]
    tf_conns = [c for t in tf_topics for c in conns[t]]
    scan_conns = conns[scan]
    first = _first(reader, scan_conns)
    if first is None:
        raise InputError(p, f"no scans on {scan}")
    laser = frame_name(cast("LaserScan", first[0]).header.frame_id)

    # Pass 1: the tree of frames (and the fixed transforms).
    tree = TfTree()
    for conn, _, raw in reader.messages(connections=tf_conns):
        static = conn.topic.lstrip("/") == "tf_static"
        for tr in cast("TFMessage", reader.deserialize(raw, conn.msgtype)).transforms:
            parent, child = frame_name(tr.header.frame_id), frame_name(tr.child_frame_id)
            if static:
                tree.set_static(parent, child, rigid(*ros_transform(tr.transform)))
            else:
                tree.link(parent, child, moving=True)
    odom_child = ""
    if odom is not None:
        m = _first(reader, conns[odom])
        if m is None:
            raise InputError(p, f"no messages on {odom}")
        first_odom = cast("Odometry", m[0])
        odom_frame = frame_name(first_odom.header.frame_id) or odom_frame or ODOM_FRAME
        odom_child = frame_name(first_odom.child_frame_id)
    else:
        odom_frame = odom_frame or ODOM_FRAME
    if base_frame is None:
        named = tree.frames()
        base_frame = odom_child or next((f for f in BASE_FRAMES if f in named), BASE_FRAMES[-1])
    base_frame = frame_name(base_frame)
    if odom is not None:
        tree.replace(odom_frame, odom_child or base_frame)
    elif tree.path(odom_frame, base_frame) is None:
        how = f"no {ODOM_TYPE} topic and " if odom_topic is None else ""
        raise InputError(
            p,
            f"no odometry: {how}no transform from '{odom_frame}' to '{base_frame}' in /tf "
            f"(frames: {', '.join(sorted(tree.frames())[:12]) or 'none'}; see --odom-frame, "
            f"--base-frame, --odom-topic)",
        )
    odom_link = odom_child or base_frame  # the link an odometry topic moves
    wanted = tree.moving_on(base_frame, laser) | tree.moving_on(odom_frame, base_frame)
    if odom is not None:
        wanted.discard(odom_link)

    # Pass 2: scans, odometry and the moving links on the chains used.
    scans = _Scans(p, scan)
    read_conns = (
        scan_conns
        + (conns[odom] if odom is not None else [])
        + ([c for c in tf_conns if c.topic.lstrip("/") == "tf"] if wanted else [])
    )
    for conn, bag_ns, raw in reader.messages(connections=read_conns):
        msg = reader.deserialize(raw, conn.msgtype)
        bag_t = bag_ns / 1_000_000_000
        if conn.topic == scan:
            scans.add(cast("LaserScan", msg), bag_ns)
        elif conn.topic == odom:
            odometry = cast("Odometry", msg)
            pose = odometry.pose.pose
            pos, q = pose.position, pose.orientation
            tree.add_sample(
                odom_link,
                stamp_seconds(odometry.header.stamp, bag_ns),
                bag_t,
                (float(pos.x), float(pos.y), float(pos.z)),
                (float(q.x), float(q.y), float(q.z), float(q.w)),
            )
        else:
            for tr in cast("TFMessage", msg).transforms:
                child = frame_name(tr.child_frame_id)
                if child in wanted and tree.parent.get(child) == frame_name(tr.header.frame_id):
                    tree.add_sample(child, stamp_seconds(tr.header.stamp, bag_ns), bag_t, *ros_transform(tr.transform))
    return _frames(p, kind, scans, tree, scan, odom, base_frame, laser, odom_frame, time_tolerance)


def _frames(
    p: Path,
    kind: str,
    scans: _Scans,
    tree: TfTree,
    scan: str,
    odom: str | None,
    base: str,
    laser: str,
    odom_frame: str,
    time_tolerance: float,
) -> BagLog:
    """Frames from what was read: times repaired, odometry and mounts looked up, windows set."""
    n = scans.n
    if n == 0 or scans.file is None:
        raise InputError(p, f"no usable scans on {scan} ({scans.seen} message(s))")
    warnings: list[str] = []
    if scans.skipped:
        warnings.append(
            f"{p}: skipped {scans.skipped} of {scans.seen} scan(s) on {scan} unlike the first "
            f"(first: {scans.first_skip})"
        )

    def where(i: int) -> str:
        return f"scan {i + 1} on {scan}"

    times = repair_times(p, [("header.stamp", np.frombuffer(scans.stamps, dtype=float))], where, time_tolerance)
    by_bag = False  # the odometry is looked up by record time (and the scans timed by it)
    if times.from_order and n > 1:  # the header stamps carry no timing: the record times may
        recorded = repair_times(p, [("record time", np.frombuffer(scans.bag_t, dtype=float))], where, time_tolerance)
        if not recorded.from_order:
            warnings.append(
                f"{p}: the scans' header stamps carry no timing ({times.distinct} distinct value(s) for "
                f"{n} scans): their record times in the bag are used"
            )
            times, by_bag = recorded, True
    times.report(p, warnings)
    t = times.times

    moving = tree.moving_on(odom_frame, base)
    if any(not len(tree.samples.get(c, ())) for c in moving):
        raise InputError(p, f"no odometry: {odom or TF_TOPIC} has no sample of '{odom_frame}' -> '{base}'")
    spans = [tree.span(c, by_bag) for c in moving]
    if spans:
        first, last = max(s[0] for s in spans), min(s[1] for s in spans)
        out = int(np.count_nonzero((t < first - OUTSIDE_ODOMETRY) | (t > last + OUTSIDE_ODOMETRY)))
        if out:
            warnings.append(
                f"{p}: {out} of {n} scan(s) lie outside the odometry's time span ({num(first)} to "
                f"{num(last)} s): its first or last pose is held there"
            )
    with np.errstate(all="ignore"):  # a corrupt transform overflows: the odometry check names it
        odom_t = tree.lookup(odom_frame, base, t, by_bag_time=by_bag)
        mounts = tree.lookup(base, laser, t, by_bag_time=by_bag) if laser != base else np.eye(4)
    assert odom_t is not None  # connected: checked when the odometry was chosen
    if odom_t.ndim == 2:
        odom_t = np.broadcast_to(odom_t, (n, 4, 4))
    odometry = np.column_stack([odom_t[:, 0, 3], odom_t[:, 1, 3], np.arctan2(odom_t[:, 1, 0], odom_t[:, 0, 0])])

    if mounts is None:
        warnings.append(
            f"{p}: no transform from '{base}' to the scans' frame '{laser}' in /tf_static or /tf: "
            "the laser is taken to sit level at the robot's centre"
        )
        mounts = np.eye(4)
    mounts = _raise_level(np.array(mounts, dtype=float))

    lo, hi = _windows(p, np.frombuffer(scans.windows, dtype=float).reshape(-1, 2), warnings)
    rmin, rmax = float(lo.min()), float(hi.max())
    frames = Frames(
        t,
        DecimalRows(scans.rows(), lo, hi, rmin, rmax),
        scans.angles,
        odom=odometry,
        mounts=mounts,
        min_range=rmin,
        max_range=rmax,
    )
    return BagLog(frames, kind, warnings, scan, odom or TF_TOPIC, base, laser, odom_frame)


def _raise_level(mounts: Array) -> Array:
    """Mounts of a level laser lower than ``NOMINAL_LASER_HEIGHT`` raised to it (see the module notes)."""
    tilt = np.abs(mounts[..., 2, :2]).max(axis=-1)
    low = (tilt < LEVEL_TILT) & (mounts[..., 2, 3] < NOMINAL_LASER_HEIGHT)
    if np.any(low):
        mounts[..., 2, 3] = np.where(low, NOMINAL_LASER_HEIGHT, mounts[..., 2, 3])
    return mounts


def _windows(p: Path, win: Array, warnings: list[str]) -> tuple[Array, Array]:
    """Each scan's valid window from its ``range_min``/``range_max`` (as written): a bad value
    (not finite, negative, a maximum not above the minimum) gives way to (0, inf)."""
    lo = np.asarray(ranges_as_written(win[:, 0].astype(np.float32)), dtype=float)
    hi = np.asarray(ranges_as_written(win[:, 1].astype(np.float32)), dtype=float)
    bad_lo = ~(np.isfinite(lo) & (lo >= 0))
    lo[bad_lo] = 0.0
    bad_hi = ~(np.isfinite(hi) & (hi > lo))
    hi[bad_hi] = np.inf
    bad = bad_lo | bad_hi
    if bad.any():
        i = int(np.argmax(bad))
        warnings.append(
            f"{p}: {int(np.count_nonzero(bad))} scan(s) carry no valid range_min/range_max (first: "
            f"range_min {num(win[i, 0])}, range_max {num(win[i, 1])}): every finite reading above 0 m "
            "is used"
        )
    return lo, hi


# --- the registry's entry point ---------------------------------------------------------------


def read(
    path: Path,
    *,
    joint: str | Path | None = None,
    wheel_scale: float = 1.0,
    time_tolerance: float = SCAN_TIME_TOLERANCE,
    scan_topic: str | None = None,
    odom_topic: str | None = None,
    base_frame: str | None = None,
    odom_frame: str | None = None,
) -> LoadedLog:
    """:func:`load_bag` as a :class:`LoadedLog` of format ``rosbag1``, ``rosbag2-sqlite3``,
    ``rosbag2-mcap`` or ``mcap``. A joint file is an error; ``wheel_scale`` does not apply."""
    reject_joint(joint)
    b = load_bag(
        path,
        scan_topic=scan_topic,
        odom_topic=odom_topic,
        base_frame=base_frame,
        odom_frame=odom_frame,
        time_tolerance=time_tolerance,
    )
    return LoadedLog(frames=b.frames, format=b.kind, warnings=b.warnings)
