"""CARMEN text logs (plain or gzip): FLASER, ROBOTLASER1, RAWLASER1..4, ODOM, PARAM.

Records, one per line, all ending with ``ipc_timestamp ipc_hostname logger_timestamp``;
the time of a record is its ``ipc_timestamp`` (the third field from the end):

- ``FLASER n r1..rn x y theta odom_x odom_y odom_theta`` + time: the first pose is the
  laser's, the second the robot's odometry pose.
- ``ROBOTLASER1 type start fov res max_range accuracy remission_mode n r1..rn
  n_rem rem1.. laser_x laser_y laser_theta robot_x robot_y robot_theta tv rv
  fwd_safety side_safety turn_axis`` + time.
- ``RAWLASER1..4 type start fov res max_range accuracy remission_mode n r1..rn
  n_rem rem1..`` + time: no pose; the odometry is interpolated from the ``ODOM`` records.
- ``ODOM x y theta tv rv accel`` + time; ``PARAM name value`` + time.
- Lines starting with ``#`` and blank lines are skipped. Record types that CARMEN's logger or
  GMapping write but pfslam does not use (:data:`UNUSED_RECORDS`: ``SYNC``, ``TRUEPOS``, the
  rear laser ``RLASER``, GPS, sonar, ... and GMapping's ``NEFF``, ``ODO_UPDATE``, ...) are
  skipped quietly and counted by type in ``CarmenLog.skipped`` (``run.json`` lists them);
  other record types are skipped too, counted in ``counts["unknown"]`` and reported in one
  warning.

Choices (the format leaves them open):

- **FLASER beam angles.** The record carries only the beam count ``n``; the field of
  view (180 deg unless ``fov_deg`` says otherwise) starts at ``-fov/2``. For an even ``n``
  (180, 360) the step is ``fov/n``: the last beam is one step short of ``+fov/2`` (180 beams
  → -90..+89 deg). For an odd ``n`` (181, 361) the step is ``fov/(n-1)``: both ends are
  included (181 beams → -90..+90 deg). ROBOTLASER1/RAWLASER records give
  ``start + k·res``.
- **No return.** A reading at or beyond ``max_range - 0.01`` m, or at or below
  ``min_range`` (0 by default: 0 and negative readings), becomes ``+inf``. ``max_range`` is
  the user's value if given; else the record's own (ROBOTLASER1, RAWLASER); for FLASER the
  PARAM ``robot_front_laser_max`` (or ``laser_front_laser_max_range``) if the log has one,
  else 80 m: the classic logs write 81.83 / 81.91 m for "no return". Lasers also log their
  own no-return value (50 m, 51.1 m, 32.767 m): a cluster of readings at the top of the
  log's values, far more frequent than any real range there
  (:func:`pfslam.io.readings.find_sentinel`); when the log has one below that maximum, it is
  the maximum (not when the user gave ``max_range``). ``Frame.max_range`` is the maximum
  used. The no-returns are counted in ``counts["no_return"]``; one warning says how many
  and why when the log's own value was used or negative readings were met.
- **Laser mount.** The laser pose in the robot frame is ``relative(odom, laser)``. Where
  the two poses are equal (corrected logs: a SLAM system wrote its answer into both) both
  are the laser's, a FLASER record's first pose by definition, and the laser sits at the
  pose: the PARAM ``robot_frontlaser_offset`` would move it a second time (on FR079, -0.04 m:
  measured worse for pfslam and GMapping alike). RAWLASER1 uses that PARAM; RAWLASER2..4
  sit at the robot centre (the log does not say where they are). The laser sits
  ``NOMINAL_LASER_HEIGHT`` above the floor so that no beam of a level planar laser is
  mistaken for a floor hit.
- **Time.** The rule all loaders share (:func:`pfslam.io.times.repair_times`), applied
  to the ``ipc_timestamp`` or, if more of its steps advance, the ``logger_timestamp`` of
  the scans: a scan whose stamp repeats, steps back by at most ``time_tolerance`` (10 s)
  or jumps out alone (the real Intel log has four, of 0.05 to 0.86 s back, while its poses
  move on) is kept, in file order, with a time between its neighbours', counted in
  ``counts["time_repaired"]`` and reported in one warning. Stamps that carry no timing
  (every one 0 or the same, or printed so coarsely that runs of 20 scans share one) give way to
  the scan order at 5 Hz from the first stamp (``counts["time_from_order"]``; RAWLASER
  scans then take the last ODOM record before them in the file). Stepping back further
  (and staying back) raises :class:`InputError` naming the line. A record whose time
  stamps are both absurd (beyond 1e11 s) is a malformed record. The times of the frames
  are always strictly increasing.
- **Mount offset.** A ``robot_frontlaser_offset`` larger than 10 m is an :class:`InputError`.
- **Robustness.** A malformed known record (too few fields, a non-numeric or non-finite
  value, a count that does not match the line length) is skipped, counted in
  ``counts["skipped_bad"]`` and reported once per record type with its first line number.
  Only :class:`InputError` is ever raised for the file's content.
"""

from __future__ import annotations

import gzip
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

import numpy as np

from pfslam.errors import ConfigError, InputError
from pfslam.frames import Frame, frame_times
from pfslam.geometry import compose, relative, rz, txyz, wrap_angle
from pfslam.io.common import (
    DETECT_BYTES,
    MAX_MOUNT_OFFSET,
    NOMINAL_LASER_HEIGHT,
    SCAN_TIME_TOLERANCE,
    LoadedLog,
    absurd_time,
    head_text,
    num,
    read_text_lines,
    reject_joint,
    stream_text_lines,
)
from pfslam.io.readings import Sentinel, find_sentinel, no_return_warning
from pfslam.io.times import repair_times
from pfslam.types import Array

FLASER_MAX_RANGE = 80.0  # m; the classic logs write 81.83 / 81.91 m for "no return"
MAX_RANGE_MARGIN = 0.01  # m; readings >= max_range - margin are "no return"
FLASER_FOV_DEG = 180.0
MAX_FOV = 2.0 * math.pi * 1.01  # rad: a record whose beams span more is corrupt (its angles could overflow)
RAWLASER_RECORDS = ("RAWLASER1", "RAWLASER2", "RAWLASER3", "RAWLASER4")
LASER_RECORDS = ("FLASER", "ROBOTLASER1") + RAWLASER_RECORDS
PARSED_RECORDS = LASER_RECORDS + ("ODOM", "PARAM")
# Records that CARMEN's logger (logger/writelog.c: its header lists them) or GMapping's
# output stream (gridslamprocessor) write and pfslam does not use: skipped without a warning.
# TRUEPOS is a simulator's true pose; ROBOTLASER2, RLASER, LASER3/4 are the other lasers.
UNUSED_RECORDS = frozenset(
    {
        "SYNC", "TRUEPOS", "COMMENT", "GLOBALPOS", "POSITIONLASER", "SCANMARK", "ROBOTLASER2",
        "RLASER", "LASER3", "LASER4", "REMISSIONFLASER", "REMISSIONRLASER", "REMISSIONLASER3",
        "REMISSIONLASER4", "NMEAGGA", "NMEARMC", "SONAR", "BUMPER", "IMU", "ARM", "VECTORMOVE",
        "ROBOTVELOCITY", "FOLLOWTRAJECTORY", "BASEVELOCITY",
        "NEFF", "ODO_UPDATE", "SM_UPDATE", "LASER_READING", "FRAME", "RESAMPLE", "SIMULATOR_POS",
    }
)  # fmt: skip
FLASER_MAX_PARAMS = ("robot_front_laser_max", "laser_front_laser_max_range")
FRONT_OFFSET_PARAM = "robot_frontlaser_offset"


@dataclass
class CarmenLog:
    """What :func:`load_carmen` returns.

    Attributes:
        frames: one Frame per usable laser scan, in file order.
        reference: (N, 3) the robot pose each scan record carries (FLASER: the odometry
            pose; ROBOTLASER1: the robot pose), or None when some scan carries none
            (RAWLASER). In corrected logs these are the SLAM-corrected poses.
        counts: records read per type, plus ``unknown``, ``skipped_bad`` and where they
            occur ``before_first_odom``, ``time_repaired`` or ``time_from_order``, and
            ``no_return`` (readings taken as no return).
        warnings: one line per kind of problem met.
        params: the PARAM settings, name → value text.
        skipped: records of the :data:`UNUSED_RECORDS` types met, by type (no warning).
    """

    frames: list[Frame]
    reference: Array | None
    counts: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    params: dict[str, str] = field(default_factory=dict)
    skipped: dict[str, int] = field(default_factory=dict)


def flaser_angles(n: int, fov_deg: float = FLASER_FOV_DEG) -> Array:
    """Beam angles (rad) of an n-beam FLASER scan: see the module notes."""
    fov = math.radians(fov_deg)
    if n <= 1:
        return np.full(max(n, 0), -fov / 2.0)
    step = fov / (n - 1) if n % 2 == 1 else fov / n
    return cast(Array, -fov / 2.0 + step * np.arange(n))


class _Bad(Exception):
    """A malformed record (caught inside the loader, never escapes)."""


def _num(tok: str) -> float:
    try:
        v = float(tok)
    except ValueError:
        raise _Bad(f"non-numeric field {tok[:20]!r}") from None
    if not math.isfinite(v):
        raise _Bad(f"non-finite field {tok[:20]!r}")
    return v


def _stamp(tok: str) -> float:
    """A time stamp field; NaN when it is not a number or absurd (see ``absurd_time``)."""
    try:
        v = float(tok)
    except ValueError:
        return math.nan
    return math.nan if absurd_time(v) else v


def _count(tok: str) -> int:
    v = _num(tok)
    if v < 0 or v != int(v):
        raise _Bad(f"bad count {tok[:20]!r}")
    return int(v)


def _nums(tokens: list[str]) -> Array:
    try:
        a = np.array(tokens, dtype=float)
    except (ValueError, OverflowError):
        raise _Bad("non-numeric value") from None
    if not np.isfinite(a).all():
        raise _Bad("non-finite value")
    return a


def _param_float(params: dict[str, str], names: tuple[str, ...]) -> float | None:
    for name in names:
        try:
            v = float(params[name])
        except (KeyError, ValueError):
            continue
        if math.isfinite(v):
            return v
    return None


@dataclass
class _Scan:
    line: int
    kind: str
    t: float  # ipc_timestamp (NaN if absurd); the repaired time once the log is read
    t_logger: float  # logger_timestamp (NaN if absurd or not a number)
    ranges: Array  # raw readings
    angles: Array
    rmax: float | None  # the record's own maximum (None for FLASER)
    odom: Array | None  # the robot pose (None for RAWLASER: interpolated later)
    mount_xyt: Array | None  # laser in the robot frame (None: from PARAMs later)


def load_carmen(
    path: str | Path,
    *,
    fov_deg: float | None = None,
    max_range: float | None = None,
    min_range: float = 0.0,
    time_tolerance: float = SCAN_TIME_TOLERANCE,
) -> CarmenLog:
    """Read a CARMEN log (plain or gzip) into Frames: odometry pose and laser mount per scan.

    Args:
        fov_deg: field of view of FLASER scans (default 180 deg).
        max_range: sensor maximum (m) for every scan, overriding the log's (and its detected
            no-return value).
        min_range: readings at or below this (m) are no returns (default 0: only 0 and
            negative readings).
        time_tolerance: how far (s) the time stamps may step back and be repaired; further
            back (and staying back) is an error.

    Raises:
        InputError: missing/unreadable/binary/corrupt gzip file, time stamps stepping back
            by more than ``time_tolerance``, an implausible PARAM laser offset, or no usable
            laser scan at all.
        ConfigError: a non-positive ``fov_deg``, ``max_range`` or ``time_tolerance``, a
            negative ``min_range`` or one not below ``max_range``.
    """
    if fov_deg is not None and not (0.0 < fov_deg <= 360.0):
        raise ConfigError(f"fov_deg must be in (0, 360], not {fov_deg}")
    if max_range is not None and not (max_range > 0.0 and math.isfinite(max_range)):
        raise ConfigError(f"max_range must be a positive number, not {max_range}")
    if not (min_range >= 0.0 and math.isfinite(min_range)) or (max_range is not None and min_range >= max_range):
        raise ConfigError(f"min_range must be a number >= 0 and below max_range, not {min_range}")
    if not (time_tolerance > 0.0 and math.isfinite(time_tolerance)):
        raise ConfigError(f"time_tolerance must be a positive number of seconds, not {time_tolerance}")
    p = Path(path)
    lines = read_text_lines(p)
    fov = FLASER_FOV_DEG if fov_deg is None else float(fov_deg)

    counts: dict[str, int] = {"unknown": 0, "skipped_bad": 0}
    bad_first: dict[str, tuple[int, str]] = {}
    bad_n: dict[str, int] = {}
    unknown_types: dict[str, int] = {}
    unused: dict[str, int] = {}
    params: dict[str, str] = {}
    scans: list[_Scan] = []
    odom_t: list[float] = []
    odom_p: list[Array] = []
    odom_line: list[int] = []
    angle_cache: dict[tuple[float, ...], Array] = {}

    def angles_for(key: tuple[float, ...]) -> Array:
        a = angle_cache.get(key)
        if a is None:
            if key[0] == 0.0:  # FLASER: (0, n, fov)
                a = flaser_angles(int(key[1]), key[2])
            else:  # (1, n, start, res)
                a = cast(Array, key[2] + key[3] * np.arange(int(key[1])))
            angle_cache[key] = a
        return a

    for n, line in enumerate(lines, 1):
        tok = line.split()
        if not tok or tok[0].startswith("#"):
            continue
        kind = tok[0]
        if kind not in PARSED_RECORDS:
            if kind in UNUSED_RECORDS:
                unused[kind] = unused.get(kind, 0) + 1
                continue
            counts["unknown"] += 1
            if len(unknown_types) < 8 or kind in unknown_types:
                unknown_types[kind[:24]] = unknown_types.get(kind[:24], 0) + 1
            continue
        try:
            if kind == "PARAM":
                if len(tok) < 3:
                    raise _Bad("too few fields")
                params[tok[1]] = tok[2]
            elif kind == "ODOM":
                if len(tok) != 10:
                    raise _Bad(f"{len(tok)} fields, expected 10")
                pose = _nums(tok[1:4])
                t = _num(tok[-3])
                if absurd_time(t):
                    raise _Bad(f"absurd time stamp {num(t)}")
                odom_t.append(t)
                odom_p.append(pose)
                odom_line.append(n)
            else:
                scan = _parse_scan(kind, tok, n, fov, angles_for)
                if kind in RAWLASER_RECORDS and not odom_t:
                    counts["before_first_odom"] = counts.get("before_first_odom", 0) + 1
                    continue
                scans.append(scan)
            counts[kind] = counts.get(kind, 0) + 1
        except _Bad as e:
            counts["skipped_bad"] += 1
            bad_n[kind] = bad_n.get(kind, 0) + 1
            bad_first.setdefault(kind, (n, str(e)))
        except (ValueError, IndexError, OverflowError) as e:  # defensive
            counts["skipped_bad"] += 1
            bad_n[kind] = bad_n.get(kind, 0) + 1
            bad_first.setdefault(kind, (n, f"malformed record ({type(e).__name__})"))

    warnings = [
        f"{p}: skipped {bad_n[k]} malformed {k} record(s) (first on line {ln}: {why})"
        for k, (ln, why) in bad_first.items()
    ]
    times = None
    if scans:
        times = repair_times(
            p,
            [
                ("ipc_timestamp", np.array([sc.t for sc in scans])),
                ("logger_timestamp", np.array([sc.t_logger for sc in scans])),
            ],
            lambda i: f"line {scans[i].line}",
            time_tolerance,
        )
        for sc, t in zip(scans, times.times):
            sc.t = float(t)
        times.report(p, warnings, counts)
    if counts.get("before_first_odom"):
        warnings.append(f"{p}: skipped {counts['before_first_odom']} RAWLASER scan(s) before the first ODOM")
    if counts["unknown"]:
        kinds = ", ".join(f"{k} {v}" for k, v in unknown_types.items())
        warnings.append(f"{p}: skipped {counts['unknown']} record(s) of unknown types ({kinds})")
    if not scans:
        summary = ", ".join(f"{k} {v}" for k, v in sorted({**counts, **unused}.items()) if v) or "no records"
        raise InputError(p, f"no usable laser scans ({summary})")

    assert times is not None
    odometry = _Odometry(odom_t, odom_p, odom_line, by_order=times.from_order)
    frames, reference, no_return = _build_frames(p, scans, params, odometry, max_range, min_range, counts)
    if no_return is not None:
        warnings.append(no_return)
    return CarmenLog(
        frames=frames, reference=reference, counts=counts, warnings=warnings, params=params, skipped=unused
    )


def _parse_scan(kind: str, tok: list[str], n: int, fov: float, angles_for) -> _Scan:  # noqa: ANN001
    """One laser record → _Scan; raises _Bad when malformed."""
    if len(tok) < 6:
        raise _Bad("too few fields")
    try:
        t_ipc = float(tok[-3])
    except ValueError:
        raise _Bad(f"non-numeric field {tok[-3][:20]!r}") from None
    t, t_logger = (math.nan if absurd_time(t_ipc) else t_ipc), _stamp(tok[-1])
    if math.isnan(t) and math.isnan(t_logger):  # one corrupt record: skipped, not the log
        raise _Bad(f"absurd time stamp {num(t_ipc)}")
    if kind == "FLASER":
        k = _count(tok[1])
        if k == 0 or len(tok) != 2 + k + 6 + 3:
            raise _Bad(f"{len(tok)} fields for {tok[1][:12]} ranges (expected {2 + k + 6 + 3})")
        r = _nums(tok[2 : 2 + k])
        poses = _nums(tok[2 + k : 2 + k + 6])
        laser, odom = poses[:3], poses[3:]
        return _Scan(n, kind, t, t_logger, r, angles_for((0.0, float(k), fov)), None, odom, relative(odom, laser))
    # ROBOTLASER1 / RAWLASERx: type start fov res max accuracy mode n r.. n_rem rem.. [poses ..]
    if len(tok) < 10:
        raise _Bad("too few fields")
    head = _nums(tok[2:8])
    start, res, rmax = float(head[0]), float(head[2]), float(head[3])
    k = _count(tok[8])
    if k == 0 or len(tok) < 9 + k + 1:
        raise _Bad(f"{len(tok)} fields for {tok[8][:12]} ranges")
    if not (abs(start) <= 2.0 * math.pi and abs(res) * (k - 1) <= MAX_FOV):
        raise _Bad(f"beam angles out of range (start {num(start)} rad, {num(res, 6)} rad x {k} beams)")
    r = _nums(tok[9 : 9 + k])
    n_rem = _count(tok[9 + k])
    tail = 6 + 5 + 3 if kind == "ROBOTLASER1" else 3
    expected = 9 + k + 1 + n_rem + tail
    if len(tok) != expected:
        raise _Bad(f"{len(tok)} fields for {k} ranges and {n_rem} remissions (expected {expected})")
    angles = angles_for((1.0, float(k), start, res))
    if kind == "ROBOTLASER1":
        i = 10 + k + n_rem
        poses = _nums(tok[i : i + 11])[:6]
        laser, robot = poses[:3], poses[3:]
        return _Scan(n, kind, t, t_logger, r, angles, rmax, robot, relative(robot, laser))
    return _Scan(n, kind, t, t_logger, r, angles, rmax, None, None)


@dataclass
class _Odometry:
    """The ODOM records (for RAWLASER scans, which carry no pose): time, pose, line."""

    t: list[float]
    poses: list[Array]
    lines: list[int]
    by_order: bool  # the scan times come from scan order: match by line, not by time

    def at(self, scans: list[_Scan]) -> Array:
        """Odometry poses for ``scans``: linear in time between ODOM records, held at the
        ends; when the scans' time stamps carry no timing, the last ODOM record before each
        scan in the file."""
        op = np.asarray(self.poses, dtype=float)
        if self.by_order:
            k = np.searchsorted(np.asarray(self.lines), [s.line for s in scans]) - 1
            return op[np.clip(k, 0, len(op) - 1)]
        ts = np.array([s.t for s in scans])
        ot = np.asarray(self.t, dtype=float)
        order = np.argsort(ot, kind="stable")
        ot, op = ot[order], op[order]
        th = np.unwrap(op[:, 2])
        out = np.empty((len(ts), 3))
        out[:, 0] = np.interp(ts, ot, op[:, 0])
        out[:, 1] = np.interp(ts, ot, op[:, 1])
        out[:, 2] = wrap_angle(np.interp(ts, ot, th))
        return out


def _build_frames(
    path: Path,
    scans: list[_Scan],
    params: dict[str, str],
    odometry: _Odometry,
    user_max: float | None,
    min_range: float,
    counts: dict[str, int],
) -> tuple[list[Frame], Array | None, str | None]:
    """Frames, the reference poses (None with RAWLASER scans) and the no-return warning (None
    unless the log's own no-return value was used or negative readings met)."""
    front = _param_float(params, (FRONT_OFFSET_PARAM,)) or 0.0
    if abs(front) > MAX_MOUNT_OFFSET:
        raise InputError(
            path,
            f"PARAM {FRONT_OFFSET_PARAM} {params[FRONT_OFFSET_PARAM][:20]}: a laser more than "
            f"{MAX_MOUNT_OFFSET:.0f} m from the robot centre is not plausible",
        )
    flaser_max = user_max
    if flaser_max is None:
        pm = _param_float(params, FLASER_MAX_PARAMS)
        flaser_max = pm if pm is not None and pm > 0 else FLASER_MAX_RANGE
    sentinel: Sentinel | None = None if user_max is not None else find_sentinel([sc.ranges for sc in scans])

    raw = [i for i, sc in enumerate(scans) if sc.odom is None]
    if raw:
        for i, pose in zip(raw, odometry.at([scans[i] for i in raw])):
            sc = scans[i]
            sc.odom = pose
            sc.mount_xyt = np.array([front if sc.kind == "RAWLASER1" else 0.0, 0.0, 0.0])

    frames: list[Frame] = []
    mounts: dict[tuple[float, float, float], Array] = {}  # one array per distinct mount
    dropped = {
        "at or beyond the maximum range": 0,
        "at the log's no-return value": 0,
        "at or below the minimum range": 0,
        "negative": 0,
    }
    total = 0
    used_sentinel = False
    for sc in scans:
        assert sc.odom is not None and sc.mount_xyt is not None
        if sc.kind == "FLASER":
            rmax = flaser_max
        elif user_max is not None:
            rmax = user_max
        else:
            rmax = sc.rmax if sc.rmax is not None and sc.rmax > 0 else FLASER_MAX_RANGE
        r = sc.ranges
        over = r >= rmax - MAX_RANGE_MARGIN
        dropped["at or beyond the maximum range"] += int(np.count_nonzero(over))
        if sentinel is not None and sentinel.value < rmax:  # the log's own value is lower: it rules
            rmax = sentinel.value
            at_sentinel = (r >= rmax - MAX_RANGE_MARGIN) & ~over
            n_at = int(np.count_nonzero(at_sentinel))
            if n_at:
                used_sentinel = True
                dropped["at the log's no-return value"] += n_at
                over |= at_sentinel
        under = r <= min_range
        negative = r < 0.0
        dropped["at or below the minimum range"] += int(np.count_nonzero(under & ~negative))
        dropped["negative"] += int(np.count_nonzero(negative))
        total += len(r)
        m = sc.mount_xyt
        if sc.kind in ("FLASER", "ROBOTLASER1") and np.allclose(m, 0.0, atol=1e-9):
            m = np.zeros(3)  # corrected log: both poses are the laser's (its first pose by definition)
        key = (float(m[0]), float(m[1]), float(m[2]))
        mount = mounts.get(key)
        if mount is None:
            mount = mounts[key] = txyz(key[0], key[1], NOMINAL_LASER_HEIGHT) @ rz(key[2])
        r = np.where(over | under, np.inf, r)
        frames.append(
            Frame(
                t=float(sc.t),
                ranges=r,
                angles=sc.angles,
                odom=np.asarray(sc.odom, dtype=float),
                mount=mount,
                min_range=min_range,
                max_range=float(rmax),
            )
        )
    reference = None if raw else np.array([sc.odom for sc in scans], dtype=float)
    counts["no_return"] = sum(dropped.values())
    warning = None
    if used_sentinel or dropped["negative"]:
        warning = no_return_warning(path, total, dropped, sentinel if used_sentinel else None)
    return frames, reference, warning


_RECORD_NAME = re.compile(r"[A-Z][A-Z0-9_]*$")


def _is_record(line: str) -> bool:
    tok = line.split(None, 1)
    return bool(tok) and tok[0] in PARSED_RECORDS


def detect(path: Path, head: bytes) -> bool:
    """Whether a record this module reads (``PARSED_RECORDS``) starts a line of the file.

    ``head`` is the file's first bytes (decompressed if gzip). Comments, blank lines and
    other records before the first known one are passed over: if the head holds only those
    (lines starting with ``#`` or an upper-case record name such as ``SYNC``), the file is
    read on, line by line, for up to ``DETECT_MAX_BYTES``."""
    lines = head_text(head).splitlines()
    if any(_is_record(ln) for ln in lines):
        return True
    if len(head) < DETECT_BYTES:  # the whole file was seen
        return False
    body = [ln.split(None, 1)[0] for ln in lines[:-1] if ln.strip() and not ln.lstrip().startswith("#")]
    if not all(_RECORD_NAME.match(tok) for tok in body):
        return False
    return any(_is_record(ln) for ln in stream_text_lines(path))


def read(
    path: Path,
    *,
    joint: str | Path | None = None,
    wheel_scale: float = 1.0,
    time_tolerance: float = SCAN_TIME_TOLERANCE,
) -> LoadedLog:
    """:func:`load_carmen` with its defaults (and ``time_tolerance``) as a :class:`LoadedLog`
    of format ``carmen``, with the poses the scans carry (if all do) as ``reference``. A joint
    file is an error; ``wheel_scale`` does not apply."""
    reject_joint(joint)
    c = load_carmen(path, time_tolerance=time_tolerance)
    return LoadedLog(
        frames=c.frames, format="carmen", warnings=list(c.warnings), reference=c.reference, skipped=dict(c.skipped)
    )


# --- writing ---------------------------------------------------------------------------------

NO_RETURN_DEFAULT = 81.83  # m: what a log without a finite maximum range writes for "no return"
LEVEL_TILT = 1e-3  # a laser whose beams leave the horizontal by less than this (m per m) is level


def _decimal(v: float, places: int = 4) -> str:
    """``v`` with at most ``places`` decimals, trailing zeros dropped ("1.09", "2", "0.0131")."""
    text = f"{v:.{places}f}"
    return text.rstrip("0").rstrip(".") if "." in text else text


def _planar(frame: Frame) -> tuple[Array, Array, Array, bool]:
    """A frame's scan as a level, upright laser's: (ranges, angles, laser pose x, y, theta in
    the robot frame, tilted). A laser mounted upside down sees beam angle ``a`` at ``-a``: its
    beams are reversed and their angles negated. A tilted laser keeps its planar pose only."""
    m = np.asarray(frame.mount, dtype=float)
    r, a = np.asarray(frame.ranges, dtype=float), np.asarray(frame.angles, dtype=float)
    tilted = bool(max(abs(m[2, 0]), abs(m[2, 1])) >= LEVEL_TILT)
    if not tilted and m[2, 2] < 0:
        r, a = r[::-1], -a[::-1]
    return r, a, np.array([m[0, 3], m[1, 3], math.atan2(m[1, 0], m[0, 0])]), tilted


def write_carmen(
    path: str | Path, frames: Sequence[Frame], odometry: Array, *, source: str = "", host: str = "pfslam"
) -> list[str]:
    """Write ``frames`` as a CARMEN log (gzip when the name ends in ``.gz``): one ``FLASER``
    line per frame whose beams are a FLASER scan's (:func:`flaser_angles`), else one
    ``ROBOTLASER1`` line (its own start angle, resolution and maximum range); the robot pose
    is ``odometry[i]``, the laser pose that composed with the frame's planar mount. Readings
    outside the frame's (min_range, max_range) are written as the maximum range ("no return";
    ``NO_RETURN_DEFAULT`` without a finite one), which ``PARAM robot_front_laser_max`` gives.
    Returns the warnings (a tilted laser, whose tilt CARMEN cannot hold)."""
    out = Path(path)
    n = len(frames)
    odometry = np.asarray(odometry, dtype=float)
    if odometry.shape != (n, 3):
        raise InputError(out, f"odometry has shape {odometry.shape} for {n} frames")
    t = frame_times(frames)
    tilted = 0
    opener = gzip.open if out.name.lower().endswith(".gz") else open
    with opener(out, "wt", encoding="utf-8") as f:
        if source:
            f.write(f"# CARMEN log written by pfslam convert from {source}\n")
        for i, frame in enumerate(frames):
            r, a, mount, tilt = _planar(frame)
            tilted += tilt
            rmax = float(frame.max_range)
            no_return = rmax if math.isfinite(rmax) else NO_RETURN_DEFAULT
            if i == 0:
                f.write(f"PARAM robot_front_laser_max {_decimal(no_return)} {t[0]:.6f} {host} {t[0]:.6f}\n")
            with np.errstate(invalid="ignore"):
                ok = np.isfinite(r) & (r > frame.min_range) & (r < rmax)
            readings = " ".join(_decimal(v) for v in np.where(ok, r, no_return))
            robot = odometry[i]
            laser = compose(robot, mount)
            poses = " ".join(f"{v:.6f}" for v in (*laser, *robot))
            stamp = f"{t[i]:.6f} {host} {t[i]:.6f}"
            k = len(r)
            if k > 1 and np.allclose(a, flaser_angles(k), atol=1e-6, rtol=0.0):
                f.write(f"FLASER {k} {readings} {poses} {stamp}\n")
                continue
            res = float((a[-1] - a[0]) / (k - 1)) if k > 1 else 0.0
            if k > 1 and np.abs(a - (a[0] + res * np.arange(k))).max() > 1e-6:
                raise InputError(out, "the beams are not evenly spaced: a CARMEN record cannot hold them")
            f.write(
                f"ROBOTLASER1 0 {a[0]:.9f} {res * (k - 1):.9f} {res:.9f} {_decimal(no_return)} 0.01 0 {k} "
                f"{readings} 0 {poses} 0 0 0 0 0 {stamp}\n"
            )
    if tilted:
        return [
            f"{out}: {tilted} of {n} scan(s) come from a tilted laser: a CARMEN log keeps only its planar pose "
            "(x, y, heading), so its floor hits will read as walls"
        ]
    return []
