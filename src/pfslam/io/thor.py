"""THOR humanoid logs: ``train_lidarN.mat`` + ``train_jointN.mat`` (reader and writer).

The lidar file holds a 1×N MATLAB cell array ``lidar`` of 1×1 structs with fields
``t`` (Unix time), ``scan`` (1×1081 ranges, -135..+135 deg in 0.25 deg steps) and the
odometry either as ``pose`` (global ``[x, y, theta]``, Penn layout) or as ``delta_pose``
(the change of that global pose since the previous scan, UCSD layout). ``res``, ``rpy``
and ``rsz`` are optional. Fields are looked up by name, never by position.

The joint file holds ``ts`` (1×M, its own clock), ``head_angles`` (2×M: neck yaw, head
pitch) and ``rpy`` (3×M body roll, pitch, yaw). Each scan gets the joint values
interpolated at its time stamp. The lidar's mount is then

    Tz(0.93) · Ry(pitch) · Rx(roll) · Tz(0.33) · Rz(neck_yaw) · Ry(head_pitch) · Tz(0.15)

from the floor under the robot to the lidar (the planar pose is applied by the filter).

Readings that are not valid ranges (NaN, +inf as ROS writes "no return", -inf, negative,
zero, beyond ``max_range``) are no returns: they stay in ``Frame.ranges``, where the filters
drop them like every reading outside (min_range, max_range). NaN, inf and negative readings
(values a THOR log does not use for a no return) are counted, with the zeros and the readings
beyond ``max_range``, in one warning for the log. Only a file or a record that cannot be read
is an error.

Corrupt files never reach SciPy's reader unchecked: :mod:`pfslam.io.matfile` walks the MATLAB
structure first (a corrupt file is an :class:`InputError`, not a crash).

Time stamps follow the rule all loaders share (:class:`pfslam.io.times.ScanClock`): a scan
whose ``t`` equals the latest accepted scan's or is at most 1 s earlier is kept (not
dropped) with its time clamped to the latest accepted time, and reported in a warning;
further back is an :class:`InputError` naming the scan. Joint samples whose ``ts`` does not
increase are dropped with a warning (they are only interpolated); one more than 1 s back is
an error, and so is a joint file whose time span does not overlap the lidar's at all.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO, Callable, Sequence, cast

import numpy as np
from numpy.typing import NDArray

from pfslam.errors import InputError
from pfslam.frames import FileRows, Frames
from pfslam.io.common import TIME_TOLERANCE, LoadedLog
from pfslam.io.matfile import load_mat
from pfslam.io.matrecords import FieldData, Layout, read_records
from pfslam.io.times import ScanClock
from pfslam.types import Array

THOR_BEAMS = 1081
THOR_ANGLES: Array = np.deg2rad(np.linspace(-135.0, 135.0, THOR_BEAMS))
COM_HEIGHT = 0.93  # centre of mass above the floor
HEAD_ABOVE_COM = 0.33
LIDAR_ABOVE_HEAD = 0.15
MIN_RANGE = 0.1
MAX_RANGE = 30.0
# What a THOR log read without its joint file is warned of (`pfslam ... --level-head` asks for it).
NO_JOINT_WARNING = "no joint file given: head assumed level (neck yaw 0, head pitch 0)"


def thor_mounts(
    roll: Array | float, pitch: Array | float, neck_yaw: Array | float, head_pitch: Array | float
) -> NDArray[np.float64]:
    """(N, 4, 4) transforms from the floor under the robot to the lidar, vectorised."""
    roll, pitch, neck_yaw, head_pitch = np.broadcast_arrays(
        *(np.atleast_1d(np.asarray(a, dtype=float)) for a in (roll, pitch, neck_yaw, head_pitch))
    )
    n = roll.shape[0]

    def rot(axis: str, a: Array) -> NDArray[np.float64]:
        c, s = np.cos(a), np.sin(a)
        m = np.zeros((n, 4, 4))
        m[:, 3, 3] = 1.0
        i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
        k = 3 - i - j
        m[:, k, k] = 1.0
        m[:, i, i] = c
        m[:, j, j] = c
        m[:, i, j] = -s
        m[:, j, i] = s
        return m

    def tz(z: float) -> NDArray[np.float64]:
        m = np.tile(np.eye(4), (n, 1, 1))
        m[:, 2, 3] = z
        return m

    chain = [
        lambda: rot("y", pitch),
        lambda: rot("x", roll),
        lambda: tz(HEAD_ABOVE_COM),
        lambda: rot("z", neck_yaw),
        lambda: rot("y", head_pitch),
        lambda: tz(LIDAR_ABOVE_HEAD),
    ]
    out = tz(COM_HEIGHT)
    for make in chain:  # one factor at a time: a long log's (N, 4, 4) arrays are not all held at once
        out = out @ make()
    return out


def thor_mount(roll: float = 0.0, pitch: float = 0.0, neck_yaw: float = 0.0, head_pitch: float = 0.0) -> Array:
    """The (4, 4) floor-to-lidar transform for one set of body and head angles."""
    return thor_mounts(roll, pitch, neck_yaw, head_pitch)[0]


@dataclass
class ThorLog:
    frames: Frames
    layout: str  # "penn" (pose) or "ucsd" (delta_pose)
    warnings: list[str] = field(default_factory=list)


# --- reading -------------------------------------------------------------------------


def _loadmat(path: Path) -> dict[str, object]:
    """The file's variables; corrupt files are InputErrors, never a crash (see :mod:`pfslam.io.matfile`)."""
    return load_mat(path)


def _records(path: Path, m: dict[str, object]) -> list[np.void]:
    """The per-scan structs of the ``lidar`` variable, whatever the container nesting."""
    names = [k for k in m if not k.startswith("__")]
    if "lidar" in m:
        var = m["lidar"]
    else:
        cands = [k for k in names if isinstance(v := m[k], np.ndarray) and (v.dtype == object or v.dtype.names)]
        if len(cands) != 1:
            raise InputError(path, f"no variable 'lidar' (variables: {', '.join(names) or 'none'})")
        var = m[cands[0]]
    if not isinstance(var, np.ndarray):
        raise InputError(path, "'lidar' is not a cell array of structs")
    out: list[np.void] = []
    for i, cell in enumerate(var.ravel(order="F")):
        rec = cell
        # Unwrap 1x1 cells / struct arrays down to the record.
        while isinstance(rec, np.ndarray):
            if rec.size != 1:
                raise InputError(path, f"lidar{{{i + 1}}} is not a 1x1 struct (shape {rec.shape})")
            rec = rec.ravel()[0]
        if not isinstance(rec, np.void) or rec.dtype.names is None:
            raise InputError(path, f"lidar{{{i + 1}}} is not a struct")
        out.append(rec)
    return out


def _as_floats(v: object) -> Array:
    try:
        return np.asarray(v, dtype=float).ravel()
    except (TypeError, ValueError):
        return np.full(1, np.nan)


Value = Callable[[str], "Array | None"]  # a record's field by name as floats; None if it has none


class _Scans:
    """The per-scan values of one lidar variable, checked record by record as they are read
    (the same checks whether the records come from :func:`pfslam.io.matrecords.read_records` or,
    for a file it does not take, from SciPy): times through the shared clock, odometry, body
    roll and pitch, and where each scan's ranges are (or the ranges themselves)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.clock = ScanClock(path)
        self.n = 0
        self.k = 0
        self.key = ""
        self.layout = ""
        self.angles: Array = THOR_ANGLES
        self.has_rpy = False
        self.t: list[float] = []
        self.odo: list[Array] = []
        self.rpy: list[Array] = []
        self.refs: list[tuple[int, int, int]] = []  # (offset, count, dtype kind) of each scan
        self.dtypes: list[np.dtype[np.generic]] = []
        self.scans: list[NDArray[np.float32]] = []  # the ranges, for records read into memory
        self.weird = False  # some reading is NaN, inf or negative (counted at the end)
        self.error: InputError | None = None  # the first problem, raised if this variable is the lidar's

    def add(self, i: int, names: Sequence[str], value: Value, scan: NDArray[np.generic] | None) -> bool:
        """Check and keep record ``i`` (``scan``: its ranges, None if not numeric); False
        once a record had a problem (kept in ``error``)."""
        if self.error is not None:
            return False
        try:
            self._add(i, names, value, scan)
        except InputError as e:
            self.error = e
            return False
        return True

    def _add(self, i: int, names: Sequence[str], value: Value, scan: NDArray[np.generic] | None) -> None:
        path = self.path
        if "scan" not in names:
            raise InputError(path, f"lidar{{{i + 1}}} has no field 'scan' (fields: {', '.join(names)})")
        if scan is None:
            raise InputError(path, f"lidar{{{i + 1}}}.scan is not numeric")
        if i == 0:
            self.k = k = scan.size
            res = value("res") if "res" in names else None
            if k == THOR_BEAMS:
                self.angles = THOR_ANGLES
            elif res is not None and res.size == 1 and np.isfinite(res[0]) and res[0] > 0:
                self.angles = cast(Array, (np.arange(k) - (k - 1) / 2.0) * float(res[0]))
            else:
                raise InputError(
                    path, f"lidar{{1}}.scan has {k} ranges, expected {THOR_BEAMS} (-135..135 deg in 0.25 deg steps)"
                )
            self.layout = "penn" if "pose" in names else "ucsd" if "delta_pose" in names else ""
            if not self.layout:
                raise InputError(
                    path, "lidar{1} has neither 'pose' (Penn layout) nor 'delta_pose' (UCSD layout): no odometry"
                )
            self.key = "pose" if self.layout == "penn" else "delta_pose"
            self.has_rpy = "rpy" in names
        if scan.size != self.k:
            raise InputError(
                path, f"lidar{{{i + 1}}}.scan has {scan.size} ranges, expected {self.k} like the first scan"
            )
        ti = value("t") if "t" in names else None
        if ti is None:
            raise InputError(path, f"lidar{{{i + 1}}} has no field 't' (time stamp)")
        if ti.size < 1 or not np.isfinite(ti[0]):
            raise InputError(path, f"lidar{{{i + 1}}}.t is not a finite number")
        self.t.append(self.clock(float(ti[0]), f"lidar{{{i + 1}}}"))
        p = value(self.key) if self.key in names else None
        if p is None:
            raise InputError(path, f"lidar{{{i + 1}}} has no field '{self.key}'")
        if p.size != 3 or not np.isfinite(p).all():
            raise InputError(path, f"lidar{{{i + 1}}}.{self.key} must be 3 finite numbers [x, y, theta]")
        self.odo.append(p)
        r = value("rpy") if self.has_rpy and "rpy" in names else None
        self.rpy.append(r if r is not None and r.size == 3 and np.isfinite(r).all() else np.zeros(3))
        with np.errstate(invalid="ignore"):
            lo, hi = scan.min(), scan.max()
        if not (lo >= 0 and hi < np.inf):  # NaN compares False
            self.weird = True
        self.n += 1


def _stream_lidar(path: Path) -> tuple[_Scans, FileRows] | None:
    """The lidar variable read in one pass (:func:`pfslam.io.matrecords.read_records`), its ranges
    left on disk; None for a file that pass does not take (then SciPy reads it)."""
    spill = tempfile.TemporaryFile(prefix="pfslam-thor-")
    found: dict[str, _Scans] = {}
    refs: dict[str, tuple[bool, dict[np.dtype[np.generic], int]]] = {}
    lookup: dict[int, tuple[Layout, dict[str, FieldData]]] = {}

    def visit(var: str, i: int, layout: Layout, buf: bytes, offset: int, spilled: bool) -> None:
        scans = found.get(var)
        if scans is None:
            scans = found[var] = _Scans(path)
            refs[var] = (spilled, {})
        if scans.error is not None:
            return
        entry = lookup.get(id(layout))
        if entry is None or entry[0] is not layout:
            entry = lookup[id(layout)] = (layout, {f.name: f for f in layout})
        fields = entry[1]
        sf = fields.get("scan")
        scan = None
        if sf is not None and sf.dtype is not None:
            scan = np.frombuffer(buf, sf.dtype, sf.count, sf.start)
        if scans.add(i, list(fields), lambda name: fields[name].values(buf), scan):
            assert sf is not None and sf.dtype is not None
            kinds = refs[var][1]
            kind = kinds.setdefault(sf.dtype, len(kinds))
            scans.refs.append((offset + sf.start, sf.count, kind))

    try:
        names = read_records(path, visit, spill)
    except BaseException:
        spill.close()
        raise
    if names is None:
        spill.close()
        return None
    var = "lidar" if "lidar" in names else next(iter(found)) if len(found) == 1 else None
    if var is None or var not in found:
        spill.close()
        return None
    scans = found[var]
    if scans.error is not None:
        spill.close()
        raise scans.error
    spilled, kinds = refs[var]
    if spilled:
        spill.flush()
        source: BinaryIO = spill
    else:
        spill.close()
        try:
            source = open(path, "rb")
        except OSError as e:
            raise InputError(path, f"cannot read the file ({e.strerror or e})") from None
    table = np.array(scans.refs, dtype=np.int64).reshape(-1, 3)
    dtypes = sorted(kinds, key=kinds.__getitem__)
    scans.refs = []
    return scans, FileRows(source, table[:, 0].copy(), table[:, 1].copy(), table[:, 2].astype(np.uint8), dtypes)


def _read_lidar(path: Path) -> tuple[_Scans, FileRows | NDArray[np.float32]]:
    """The lidar variable's checked per-scan values and its ranges (rows on disk, or an array)."""
    streamed = _stream_lidar(path)
    if streamed is not None:
        return streamed
    recs = _records(path, _loadmat(path))  # a layout the one-pass reader does not take
    scans = _Scans(path)
    for i, rec in enumerate(recs):
        names = list(rec.dtype.names or ())
        raw = None
        if "scan" in names:
            try:
                raw = np.asarray(rec["scan"], dtype=np.float32).ravel()
            except (TypeError, ValueError):
                raw = None

        def value(name: str, rec: np.void = rec) -> Array:
            return _as_floats(rec[name])

        if not scans.add(i, names, value, raw):
            assert scans.error is not None
            raise scans.error
        assert raw is not None
        scans.scans.append(raw)
    ranges = np.stack(scans.scans) if scans.scans else np.zeros((0, 0), np.float32)
    scans.scans = []
    return scans, ranges


def _no_returns(path: Path, rows: FileRows | NDArray[np.float32], n: int, max_range: float) -> str | None:
    """The one warning for readings that are not ranges (NaN, +inf as ROS writes "no return",
    -inf, negative), with the count of every kind of no return in the log; None if there are
    none of those. Zeros (the UTM-30LX's error code, and the simulator's dropouts) and readings
    beyond ``max_range`` are the format's own no returns: counted in that warning, never a
    reason for one. All stay in the ranges, where the filters drop every reading that is not
    finite or not inside (min_range, max_range)."""
    kinds = ("NaN", "+inf", "-inf", "negative", "zero", f"beyond {max_range:g} m")
    counts = dict.fromkeys(kinds, 0)
    bad_readings = bad_scans = 0
    with np.errstate(invalid="ignore"):
        for i in range(n):
            r = rows[i]
            finite = np.isfinite(r)
            for name, hit in zip(
                kinds, (np.isnan(r), np.isposinf(r), np.isneginf(r), (r < 0) & finite, r == 0, (r > max_range) & finite)
            ):
                counts[name] += int(hit.sum())
            bad = int((~(finite & (r > 0) & (r <= max_range))).sum())
            bad_readings += bad
            bad_scans += bad > 0
    if not any(counts[k] for k in kinds[:4]):
        return None
    what = ", ".join(f"{v} {k}" for k, v in counts.items() if v)
    return (
        f"{path}: {bad_readings} readings in {bad_scans} of {n} scans are not "
        f"valid ranges ({what}): taken as no returns"
    )


def load_thor(
    lidar_path: str | Path,
    joint_path: str | Path | None = None,
    *,
    min_range: float = MIN_RANGE,
    max_range: float = MAX_RANGE,
) -> ThorLog:
    """Read a THOR lidar file (and optionally its joint file) into :class:`Frames`; the
    ranges stay in the file (or a temporary copy of a compressed one) until a frame is read."""
    path = Path(lidar_path)
    scans, ranges = _read_lidar(path)
    n = scans.n
    if not n:
        raise InputError(path, "no scans in 'lidar'")
    warnings: list[str] = []
    scans.clock.report(warnings)
    t = np.asarray(scans.t, dtype=float)
    odo = np.array(scans.odo, dtype=float).reshape(n, 3)
    rpy = np.array(scans.rpy, dtype=float).reshape(n, 3)
    has_rpy, layout, angles = scans.has_rpy, scans.layout, scans.angles
    if scans.weird:
        no_return = _no_returns(path, ranges, n, max_range)
        if no_return:
            warnings.append(no_return)
    del scans
    if layout == "ucsd":
        with np.errstate(over="ignore"):  # an overflow to inf is reported by the odometry check
            odo = np.cumsum(odo, axis=0)

    neck = np.zeros(n)
    head = np.zeros(n)
    if joint_path is not None:
        jt, ja, jrpy, jwarn = _load_joint(Path(joint_path))
        warnings += jwarn
        lo, hi = max(t[0], jt[0]), min(t[-1], jt[-1])
        if hi < lo:
            raise InputError(
                joint_path,
                f"joint time stamps ({jt[0]:.3f} to {jt[-1]:.3f} s) do not overlap the lidar's "
                f"({t[0]:.3f} to {t[-1]:.3f} s in {path.name})",
            )
        if hi - lo < 0.5 * (t[-1] - t[0]):
            warnings.append(
                f"{joint_path}: joint time stamps cover only {max(hi - lo, 0):.1f} s of the "
                f"{t[-1] - t[0]:.1f} s lidar log; joint values are held at the ends"
            )
        neck = np.interp(t, jt, np.unwrap(ja[0]))
        head = np.interp(t, jt, ja[1])
        if not has_rpy and jrpy is not None:
            rpy[:, 0] = np.interp(t, jt, jrpy[0])
            rpy[:, 1] = np.interp(t, jt, jrpy[1])
            has_rpy = True
    else:
        warnings.append(f"{path}: {NO_JOINT_WARNING}")
    mounts = thor_mounts(rpy[:, 0], rpy[:, 1], neck, head)
    frames = Frames(t, ranges, angles, odom=odo, mounts=mounts, min_range=min_range, max_range=max_range)
    return ThorLog(frames=frames, layout=layout, warnings=warnings)


def _load_joint(path: Path) -> tuple[Array, Array, Array | None, list[str]]:
    """``ts``, ``head_angles``, ``rpy`` (or None) and warnings; samples whose time stamp does
    not increase are dropped, a step back of more than ``TIME_TOLERANCE`` is an error."""
    m = _loadmat(path)
    for name in ("ts", "head_angles"):
        if name not in m:
            raise InputError(path, f"no variable '{name}' in the joint file")
    try:
        ts = np.asarray(m["ts"], dtype=float).ravel()
        ha = np.asarray(m["head_angles"], dtype=float)
    except (TypeError, ValueError):
        raise InputError(path, "'ts' and 'head_angles' must be numeric") from None
    if ts.size == 0:
        raise InputError(path, "'ts' is empty")
    if not np.isfinite(ts).all():
        raise InputError(path, "'ts' has NaN/inf time stamps")
    if ha.ndim != 2 or 2 not in ha.shape:
        raise InputError(path, f"'head_angles' must be 2xM (neck yaw, head pitch), got shape {ha.shape}")
    if ha.shape[0] != 2:
        ha = ha.T
    if ha.shape[1] != ts.size:
        raise InputError(path, f"'head_angles' has {ha.shape[1]} samples but 'ts' has {ts.size}")
    if not np.isfinite(ha).all():
        raise InputError(path, "'head_angles' has NaN/inf values")
    prev = np.concatenate([[-np.inf], np.maximum.accumulate(ts)[:-1]])
    back = prev - ts  # > -0 where ts does not increase
    far = np.nonzero(back > TIME_TOLERANCE)[0]
    if len(far):
        j = int(far[0])
        raise InputError(
            path, f"'ts' is not increasing at sample {j + 1}: {back[j]:.3f} s back (ts={ts[j]:.6f} after {prev[j]:.6f})"
        )
    keep = back < 0
    warnings: list[str] = []
    if not keep.all():
        warnings.append(
            f"{path}: dropped {int((~keep).sum())} joint sample(s) whose time stamp did not increase (at most "
            f"{back.max():.3f} s back; first at sample {int(np.argmin(keep)) + 1})"
        )
    jrpy = None
    if "rpy" in m:
        try:
            r = np.asarray(m["rpy"], dtype=float)
        except (TypeError, ValueError):
            r = np.zeros(0)  # not numeric: ignored like a wrongly shaped one
        if r.ndim == 2 and r.shape[1] != ts.size and r.shape[0] == ts.size:
            r = r.T
        if r.ndim == 2 and r.shape == (3, ts.size) and np.isfinite(r).all():
            jrpy = r[:, keep]
    return ts[keep], ha[:, keep], jrpy, warnings


# --- the registry's entry points (see pfslam.io.logs) ---------------------------------


def detect(path: Path, head: bytes) -> bool:
    """Whether ``path`` is a THOR lidar file: a MATLAB v5 or HDF5 (v7.3) header, or a ``.mat``
    name. ``head`` is the file's first bytes as stored (not decompressed)."""
    return head.startswith(b"MATLAB") or head[:4] == b"\x89HDF" or path.name.lower().endswith(".mat")


def read(
    path: Path, *, joint: str | Path | None = None, level_head: bool = False, wheel_scale: float = 1.0
) -> LoadedLog:
    """:func:`load_thor` (with the joint file if given) as a :class:`LoadedLog` of format
    ``thor-penn`` or ``thor-ucsd``; ``wheel_scale`` does not apply (the log has no wheels).
    ``level_head``: no joint file on purpose (:func:`pfslam.io.logs.check_joint` refuses a THOR
    log without one otherwise), so the level head is said in a note, not a warning."""
    log = load_thor(path, joint)
    level = [w for w in log.warnings if level_head and w.endswith(NO_JOINT_WARNING)]
    return LoadedLog(
        frames=log.frames,
        format=f"thor-{log.layout}",
        warnings=[w for w in log.warnings if w not in level],
        notes=[f"{w} (--level-head)" for w in level],
    )


# --- writing -------------------------------------------------------------------------


def write_thor(
    lidar_path: str | Path,
    joint_path: str | Path | None,
    *,
    t: Array,
    scans: NDArray[np.float32],
    pose: Array | None = None,
    delta_pose: Array | None = None,
    rpy: Array | None = None,
    res: float | None = 0.0044,
    joint_ts: Array | None = None,
    head_angles: Array | None = None,
    joint_rpy: Array | None = None,
) -> None:
    """Write a lidar (and joint) ``.mat`` pair in the nesting of the real THOR files."""
    from scipy.io import savemat

    t = np.asarray(t, dtype=float)
    n = len(t)
    if (pose is None) == (delta_pose is None):
        raise ValueError("give exactly one of pose (Penn layout) or delta_pose (UCSD layout)")
    odo = np.asarray(pose if pose is not None else delta_pose, dtype=float)
    key = "pose" if pose is not None else "delta_pose"
    scans = np.asarray(scans, dtype=np.float32)
    cells = np.empty((1, n), dtype=object)
    for i in range(n):
        rec: dict[str, NDArray[np.generic]] = {"t": np.array([[t[i]]]), key: odo[i][None, :]}
        if res is not None:
            rec["res"] = np.array([[res]])
        if rpy is not None:
            rec["rpy"] = np.asarray(rpy[i], dtype=float)[None, :]
        rec["scan"] = scans[i][None, :]
        cells[0, i] = rec
    savemat(str(lidar_path), {"lidar": cells}, do_compression=False)
    if joint_path is not None:
        if joint_ts is None or head_angles is None:
            raise ValueError("a joint file needs joint_ts and head_angles")
        jt = np.asarray(joint_ts, dtype=float)[None, :]
        out = {"ts": jt, "head_angles": np.asarray(head_angles, dtype=float)}
        if joint_rpy is not None:
            out["rpy"] = np.asarray(joint_rpy, dtype=float)
        savemat(str(joint_path), out, do_compression=False)
