"""What every log loader shares: file checks, text reading, the time-stamp rule, limits, the result.

A leaf module: it imports nothing from :mod:`pfslam.io`, so each loader module
(:mod:`pfslam.io.thor`, :mod:`pfslam.io.carmen`, :mod:`pfslam.io.mines`) imports from here
alone, and the registry :mod:`pfslam.io.logs` imports the loaders without a circle.
"""

from __future__ import annotations

import errno
import gzip
import math
import os
import zlib
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

import numpy as np
from numpy.typing import NDArray

from pfslam.errors import InputError
from pfslam.frames import Frame, frame_column, frame_times

TIME_TOLERANCE = 1.0  # s a joint sample (THOR) or a streamed scan (ScanClock) may fall back before it is an error
SCAN_TIME_TOLERANCE = 10.0  # s a scan's time stamp may step back (a clock step) and still be repaired
ABSURD_TIME = 1e11  # s (3,000 years): a stamp further from 0 than this is a corrupt record
DEFAULT_SCAN_INTERVAL = 0.2  # s between scans when no stamp says: 5 Hz, the classic CARMEN logs (FR079: 4.5 Hz)
INFORMATIVE_STEPS = 0.05  # stamps carry the timing if at least this fraction of scan-to-scan steps advance:
# stamps coarser than 20 scans are spread between their ticks; coarser still (csail: %g-rounded
# to 10,000 s, one tick in 406 scans) they say nothing of the interval between scans
REPEAT_STEP = 1e-3  # s added by ScanClock (streaming) to a scan whose stamp does not advance
DETECT_BYTES = 1 << 20  # how much of a text log format detection reads at first
DETECT_MAX_BYTES = 64 << 20  # how far a text format's detection may stream on through leading unknown lines
MAX_MOUNT_OFFSET = 10.0  # m; a sensor mounted further than this from the robot is a corrupt value
MAX_ODOM_STEP = 100.0  # m; odometry may always move this far between two scans ...
MAX_ODOM_SPEED = 50.0  # m/s; ... or this fast, whichever allows more
GZIP_ERRORS = (zlib.error, EOFError, OSError)  # gzip.BadGzipFile is an OSError
GZIP_MAGIC = b"\x1f\x8b"
BOM = "\ufeff"  # a UTF-8 byte order mark, as decoded
NOMINAL_LASER_HEIGHT = 0.3  # m above the floor for planar 2D lasers (floor cut is 0.15 m)


# --- the result ----------------------------------------------------------------------------


@dataclass
class LoadedLog:
    """What :func:`pfslam.io.logs.load_log` (and each loader module's ``read``) returns."""

    frames: Sequence[Frame]  # a list, or Frames (kept by column, ranges possibly on disk)
    format: str
    warnings: list[str] = field(default_factory=list)
    reference: NDArray[np.float64] | None = None  # (N, 3) poses the log carries, if corrected
    odometry: str = "log"  # where the frames' odometry came from
    skipped: dict[str, int] = field(default_factory=dict)  # records read but not used, by type (run.json)
    notes: list[str] = field(default_factory=list)  # what was done as asked (not a warning)


# --- files -----------------------------------------------------------------------------------


def check_file(path: Path, folder: bool = False) -> None:
    """Raise InputError unless ``path`` exists and is a file (or, with ``folder``, a folder:
    a log format whose logs are folders, a ROS 2 bag, decides on it)."""
    if not path.exists():
        raise InputError(path, "file not found")
    if not path.is_file() and not (folder and path.is_dir()):
        raise InputError(path, "not a file")


def read_bytes(path: Path, size: int = -1) -> bytes:
    """The first ``size`` bytes of ``path`` (all with -1); an OSError becomes a one-line InputError."""
    try:
        with open(path, "rb") as f:
            return f.read(size)
    except OSError as e:
        raise InputError(path, f"cannot read the file ({e.strerror or e})") from None


def read_head(path: Path) -> bytes:
    """The first ``DETECT_BYTES`` of ``path`` as stored (what format detection looks at)."""
    return read_bytes(path, DETECT_BYTES)


def is_gzip(data: bytes) -> bool:
    """Whether ``data`` starts with the gzip magic bytes."""
    return data[:2] == GZIP_MAGIC


def _corrupt_gzip(path: Path, e: BaseException) -> InputError:
    return InputError(path, f"corrupt gzip data: {str(e) or type(e).__name__}")


def gunzip_head(path: Path) -> bytes:
    """The first ``DETECT_BYTES`` of the decompressed content of the gzip file ``path``."""
    try:
        with gzip.open(path, "rb") as g:
            return g.read(DETECT_BYTES)
    except GZIP_ERRORS as e:
        raise _corrupt_gzip(path, e) from None


def read_text_lines(path: str | Path) -> list[str]:
    """Lines of a plain or gzip text file (gzip recognised by its magic bytes).

    Raises InputError for a missing, unreadable, corrupt or binary file.
    """
    p = Path(path)
    check_file(p)
    raw = read_bytes(p)
    if is_gzip(raw):
        try:
            raw = gzip.decompress(raw)
        except GZIP_ERRORS as e:
            raise _corrupt_gzip(p, e) from None
    if b"\x00" in raw:
        raise InputError(p, "binary data, not a text log")
    text = raw.decode("utf-8", errors="replace").removeprefix(BOM)
    bad = text.count("\ufffd")
    if bad > 16 and bad > 0.01 * len(text):
        raise InputError(p, "not a text log (mostly undecodable bytes)")
    return [ln.rstrip("\r") for ln in text.split("\n")]


def head_text(head: bytes) -> str:
    """A detection head as text (undecodable bytes replaced, a UTF-8 byte order mark dropped)."""
    return head.decode("utf-8", errors="replace").removeprefix(BOM)


def stream_text_lines(path: Path, budget: int = DETECT_MAX_BYTES) -> Iterator[str]:
    """The lines of a plain or gzip text file, read as they come (for format detection that
    has to look past the first ``DETECT_BYTES``), until about ``budget`` bytes of text were
    read; undecodable bytes replaced, a byte order mark dropped. A file that cannot be read
    or decompressed ends the lines (detection then fails as for any unknown file)."""
    try:
        raw = read_bytes(path, 2)
        opener = gzip.open if is_gzip(raw) else open
        with opener(path, "rb") as f:
            seen = 0
            while seen < budget:
                line = f.readline(DETECT_BYTES)  # a line longer than this comes in pieces
                if not line:
                    return
                text = line.decode("utf-8", errors="replace")
                yield text.removeprefix(BOM) if seen == 0 else text
                seen += len(line)
    except (InputError, *GZIP_ERRORS):
        return


def reject_joint(joint: str | Path | None) -> None:
    """The error a reader without head joints raises when it is given a joint file."""
    if joint is not None:
        raise InputError(joint, "a joint file only goes with a THOR lidar .mat file")


# --- memory --------------------------------------------------------------------------------


def release_free_memory() -> None:
    """Hand the memory a loader freed back to the system (glibc's ``malloc_trim``; nothing
    elsewhere). Parsing a log allocates far more, in many small pieces, than the frames keep;
    freed, those pieces stay in the process (and count in its resident size) until trimmed,
    while the run's own large arrays are mapped afresh beside them."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc
        pass


# --- numbers in messages ------------------------------------------------------------------


def num(v: float, decimals: int = 3) -> str:
    """``v`` for a message, never longer than about 20 characters: fixed-point with
    ``decimals`` decimals while that is short, else ``%.6g`` (a corrupt 1e300 is "1e+300",
    not 300 digits)."""
    v = float(v)
    if math.isfinite(v) and abs(v) < 1e12:
        return f"{v:.{decimals}f}"
    return f"{v:.6g}"


def absurd_time(t: float) -> bool:
    """Whether a time stamp is corrupt beyond repair: not finite or further than ``ABSURD_TIME`` from 0."""
    return not (math.isfinite(t) and abs(t) <= ABSURD_TIME)


# --- time stamps -------------------------------------------------------------------------------


@dataclass
class ScanTimes:
    """What :func:`repair_times` made of a log's scan time stamps.

    Attributes:
        times: (N,) strictly increasing scan times (s), in scan order.
        source: the name of the stamp used, or None when the times come from scan order.
        kept: scans whose stamp is used as it is.
        repaired: scans whose stamp repeats, steps back, jumps out alone or is missing,
            given a time between their neighbours'; ``kinds`` counts them by kind.
        extended: repaired scans after the last good stamp, placed ``interval`` apart.
        interval: the nominal time between scans (s): the median over consecutive good stamps
            of their step divided by the scans it spans, or ``default_interval`` when the
            stamps carry no timing.
        most_back: the largest step back (s) among the repaired scans.
        first: (where, stamp, previous good stamp) of the first repaired scan.
        distinct: distinct stamp values (for the message when they carry no timing).
    """

    times: NDArray[np.float64]
    source: str | None
    kept: int = 0
    repaired: int = 0
    extended: int = 0
    interval: float = DEFAULT_SCAN_INTERVAL
    most_back: float = 0.0
    first: tuple[str, float, float] | None = None
    distinct: int = 0
    kinds: dict[str, int] = field(default_factory=dict)

    _first_index: int = field(default=-1, repr=False)

    def _note(self, kind: str, i: int, where: str, t: float, prev: float) -> None:
        """Count a repaired scan (index ``i``); keep the earliest in the log as ``first``."""
        self.kinds[kind] = self.kinds.get(kind, 0) + 1
        if self.first is None or i < self._first_index:
            self.first, self._first_index = (where, t, prev), i

    @property
    def from_order(self) -> bool:
        return self.source is None

    def warning(self, path: str | Path) -> str | None:
        """The one line to tell the user, or None when every stamp was used as it is."""
        n = len(self.times)
        if self.from_order and n > 1:
            return (
                f"{path}: the scans' time stamps carry no timing ({self.distinct} distinct value(s) for {n} scans): "
                f"times taken from the scan order, {num(self.interval)} s apart from {num(self.times[0])} s"
            )
        if not self.repaired:
            return None
        where, t, prev = self.first if self.first is not None else ("?", math.nan, math.nan)
        kinds = ", ".join(
            f"{v} {k}" + (f" (at most {num(self.most_back)} s)" if k == "stepping back" else "")
            for k, v in self.kinds.items()
        )
        tail = f"; {self.extended} after the last good stamp, {num(self.interval)} s apart" if self.extended else ""
        return (
            f"{path}: {self.repaired} of {n} scan(s) whose time stamp did not advance ({kinds}) were given times "
            f"between their neighbours'{tail} (first at {where}: {num(t, 6)} s after {num(prev, 6)} s)"
        )

    def report(self, path: str | Path, warnings: list[str], counts: dict[str, int] | None = None) -> None:
        """Add the warning (if any) and ``counts["time_repaired"]`` / ``counts["time_from_order"]``."""
        w = self.warning(path)
        if w is not None:
            warnings.append(w)
        if counts is not None:
            if self.from_order and len(self.times) > 1:
                counts["time_from_order"] = len(self.times)
            elif self.repaired:
                counts["time_repaired"] = self.repaired


def _advancing_steps(s: NDArray[np.float64]) -> int:
    """Scan-to-scan steps whose stamp advances (NaN pairs do not count)."""
    with np.errstate(invalid="ignore"):
        return int(np.count_nonzero(np.diff(s) > 0))


def repair_times(
    path: str | Path,
    stamps: list[tuple[str, NDArray[np.float64]]],
    where: Callable[[int], str] = lambda i: f"scan {i + 1}",
    tolerance: float = SCAN_TIME_TOLERANCE,
    default_interval: float = DEFAULT_SCAN_INTERVAL,
) -> ScanTimes:
    """Strictly increasing scan times from the time stamps a log carries: the loaders' one rule.

    ``stamps`` holds one or more candidate stamps per scan (name, (N,) array; NaN where a
    scan has none or it is absurd), e.g. CARMEN's ``ipc_timestamp`` and
    ``logger_timestamp``: the one in which most steps advance is used (the first on a tie).

    - **No timing** (fewer than ``INFORMATIVE_STEPS`` of the steps advance: every stamp
      0, all the same, or so coarse that runs of more than 20 scans share one): the times
      are the first stamp plus ``default_interval`` per scan, in scan order.
    - **Timing** otherwise: a scan whose stamp advances past the latest good one keeps it
      (the stamps that are fine are never altered). The others -- a stamp that repeats, one
      that steps back by at most ``tolerance`` seconds (a clock glitch or step), one that
      jumps more than ``tolerance`` ahead of both neighbours alone, a missing one -- are
      placed after the previous good stamp, ``interval`` apart (the median time per scan
      between good stamps), squeezed evenly before the next good stamp if they would not fit.
      Stamps of a coarse clock (a tick every few scans) are thus spread between the ticks.

    Raises InputError naming the scan (``where(i)``) when a stamp steps back by more than
    ``tolerance`` and the following stamps stay back (not a lone outlier).
    """
    n = len(stamps[0][1]) if stamps else 0
    if n == 0:
        return ScanTimes(np.zeros(0), stamps[0][0] if stamps else None)
    name, s = max(((nm, np.asarray(a, dtype=float)) for nm, a in stamps), key=lambda c: _advancing_steps(c[1]))
    good = np.isfinite(s)
    distinct = len(np.unique(s[good]))
    if n == 1 or _advancing_steps(s) < INFORMATIVE_STEPS * (n - 1):
        t0 = float(s[good][0]) if good.any() else 0.0
        times = cast("NDArray[np.float64]", t0 + default_interval * np.arange(n))
        return ScanTimes(
            _strictly_increasing(times),
            None if n > 1 else name,
            kept=int(n == 1 and good[0]),
            interval=default_interval,
            distinct=distinct,
        )

    anchor = np.zeros(n, dtype=bool)
    out = ScanTimes(np.zeros(0), name, distinct=distinct)
    last, last_i = -math.inf, -1
    for j in range(n):
        v = s[j]
        if not good[j]:
            continue
        if v > last:
            # A lone outlier ahead: the next stamp falls back by more than the tolerance yet
            # not behind the latest good one.
            nxt = s[j + 1] if j + 1 < n else math.nan
            if last_i >= 0 and math.isfinite(nxt) and v - nxt > tolerance and nxt >= last:
                out._note("jumping out alone", j, where(j), float(v), float(last))
                continue
            anchor[j] = True
            last, last_i = v, j
            continue
        back = last - v
        nxt = s[j + 1] if j + 1 < n else math.nan
        if back > tolerance:
            if not nxt > last:  # the clock stays back: not one bad stamp
                raise InputError(
                    path,
                    f"{where(j)}: time goes backwards by {num(back)} s ({num(v, 6)} s after {num(last, 6)} s at "
                    f"{where(last_i)}; a step back of up to {num(tolerance, 1)} s is repaired: see the time tolerance)",
                )
            out._note("jumping out alone", j, where(j), float(v), float(last))
        elif back == 0.0:
            out._note("repeating", j, where(j), float(v), float(last))
        else:
            out.most_back = max(out.most_back, back)
            out._note("stepping back", j, where(j), float(v), float(last))
    for miss in np.flatnonzero(~good):
        prev = s[:miss][anchor[:miss]]
        out._note("missing", int(miss), where(int(miss)), math.nan, float(prev[-1]) if len(prev) else math.nan)
    idx = np.flatnonzero(anchor)
    t_a = s[idx]
    per_scan = np.diff(t_a) / np.diff(idx)  # between good stamps: a coarse clock's tick spread over its scans
    interval = float(np.median(per_scan)) if len(per_scan) else default_interval
    times = np.empty(n)
    times[idx] = t_a
    # Before the first good stamp (a lone outlier or missing stamps at the start).
    head = np.arange(idx[0])
    times[head] = t_a[0] - interval * (idx[0] - head)
    # Between two good stamps: interval apart, squeezed to fit.
    for k in range(len(idx) - 1):
        a, b = int(idx[k]), int(idx[k + 1])
        if b - a > 1:
            step = min(interval, (t_a[k + 1] - t_a[k]) / (b - a))
            times[a + 1 : b] = t_a[k] + step * np.arange(1, b - a)
    # After the last good stamp.
    a = int(idx[-1])
    times[a + 1 :] = t_a[-1] + interval * np.arange(1, n - a)
    out.times = _strictly_increasing(times)
    out.kept = len(idx)
    out.repaired = n - len(idx)
    out.extended = n - 1 - a
    out.interval = interval
    return out


def _strictly_increasing(times: NDArray[np.float64]) -> NDArray[np.float64]:
    """``times`` with any step that rounding left at zero moved on to the next float."""
    d = np.diff(times)
    if len(d) and not (d > 0).all():
        times = times.copy()
        for i in range(1, len(times)):
            if not times[i] > times[i - 1]:
                times[i] = np.nextafter(times[i - 1], math.inf)
    return times


class ScanClock:
    """Scan time stamps fed one at a time in file order (for a loader that builds its frames
    as it reads). A scan whose stamp is after the latest one given out keeps it. A scan whose
    stamp repeats or is at most ``tolerance`` seconds earlier (duplicates, jitter, a swapped
    pair) is a time-stamp glitch: it is kept, in file order, ``REPEAT_STEP`` after the latest
    time given out (so the times stay strictly increasing), counted in ``clamped`` and
    reported by :meth:`report`. A scan further back raises :class:`InputError` naming the
    file and the scan.

    :meth:`repaired` gives the times :func:`repair_times` (the rule the other loaders use:
    repeated stamps spread between their neighbours, a log without timing timed by scan
    order) makes of every stamp fed so far, for a loader that can set its times at the end.
    """

    def __init__(self, path: str | Path, tolerance: float = TIME_TOLERANCE) -> None:
        self.path, self.tolerance = path, tolerance
        self.last, self.last_where = -math.inf, ""
        self.given = -math.inf  # the latest time given out
        self.clamped, self.most_back = 0, 0.0
        self.first: tuple[str, float, float] | None = None
        self.stamps: list[float] = []
        self.wheres: list[str] = []

    def __call__(self, t: float, where: str) -> float:
        """The time to give the scan at ``where`` (e.g. "line 12") whose stamp is ``t``."""
        self.stamps.append(t)
        self.wheres.append(where)
        if t > self.last and t > self.given:
            self.last, self.last_where = t, where
            self.given = t
            return t
        back = self.last - t
        if back > self.tolerance:
            raise InputError(
                self.path,
                f"{where}: time goes backwards by {num(back)} s ({num(t, 6)} s after {num(self.last, 6)} s "
                f"at {self.last_where})",
            )
        self.clamped += 1
        self.most_back = max(self.most_back, back)
        if self.first is None:
            self.first = (where, t, self.last)
        self.given = max(self.given + REPEAT_STEP, float(np.nextafter(self.given, math.inf)))
        return self.given

    def repaired(self, tolerance: float = SCAN_TIME_TOLERANCE) -> ScanTimes:
        """:func:`repair_times` of every stamp fed so far (see the class notes)."""
        wheres = self.wheres
        return repair_times(self.path, [("time", np.asarray(self.stamps, dtype=float))], lambda i: wheres[i], tolerance)

    def report(self, warnings: list[str], counts: dict[str, int] | None = None) -> None:
        """Add the loader's warning (and ``counts["time_clamped"]``) if any scan was clamped."""
        if self.first is None:
            return
        where, t, prev = self.first
        warnings.append(
            f"{self.path}: {self.clamped} scan(s) whose time stamp did not increase (at most {num(self.most_back)} s "
            f"back in time) kept {num(REPEAT_STEP)} s after the previous scan (first at {where}: {num(t, 6)} s "
            f"after {num(prev, 6)} s)"
        )
        if counts is not None:
            counts["time_clamped"] = self.clamped


# --- no-return readings ---------------------------------------------------------------------

SENTINEL_SPAN = 0.5  # m: a no-return cluster lies within this of the log's largest reading
SENTINEL_GAP = 0.05  # m: values in the cluster are this close to the next one (readings are in cm or mm)
SENTINEL_MIN_READINGS = 10  # a cluster is at least this many readings ...
SENTINEL_MIN_SCANS = 3  # ... in this many scans ...
SENTINEL_MIN_BEAMS = 3  # ... on this many different beams (and 2 % of a scan's beams) ...
SENTINEL_RATIO = 10.0  # ... and this many times the readings in a band as wide just below it


@dataclass(frozen=True)
class Sentinel:
    """A log's own no-return value (:func:`find_sentinel`): readings at or above ``value``
    form a cluster at the top of the log's readings (up to ``top``): ``readings`` of them in
    ``scans`` scans."""

    value: float
    top: float
    readings: int
    scans: int


def find_sentinel(scans: list[NDArray[np.float64]]) -> Sentinel | None:
    """The value a laser writes for "no return", if the log shows one, else None.

    Lasers log their own no-return value (81.83 or 81.91 m for the classic SICK logs, 50 m,
    51.1 m, 32.767 m) rather than a fixed one. Such a value is the largest in the log and
    repeats across many scans and beams -- far more often than a real range at the edge of
    what the laser sees (those are a thin tail of single values). So the cluster is the run
    of values down from the largest reading while each is within ``SENTINEL_GAP`` of the
    next (at most ``SENTINEL_SPAN`` wide); it is a sentinel when it holds at least
    ``SENTINEL_MIN_READINGS`` readings in ``SENTINEL_MIN_SCANS`` scans on
    ``SENTINEL_MIN_BEAMS`` beams, and ``SENTINEL_RATIO`` times as many readings as a band as
    wide just below it. ``scans`` are the raw readings (m) of each scan; values that are not
    finite or not positive are ignored.
    """
    if not scans:
        return None
    r = np.concatenate([np.asarray(x, dtype=float).ravel() for x in scans])
    r = r[np.isfinite(r) & (r > 0)]
    if len(r) < SENTINEL_MIN_READINGS:
        return None
    top = float(r.max())
    values = np.unique(r[r >= top - SENTINEL_SPAN])[::-1]  # descending
    low = top
    for v in values[1:]:
        if low - v > SENTINEL_GAP:
            break
        low = float(v)
    inside = int(np.count_nonzero(r >= low))
    width = max(top - low, SENTINEL_GAP)
    below = int(np.count_nonzero((r >= low - width) & (r < low)))
    if inside < SENTINEL_MIN_READINGS or inside < SENTINEL_RATIO * max(below, 1):
        return None
    n_scans = 0
    beams: set[int] = set()
    widest = max(len(x) for x in scans)
    for x in scans:
        hit = np.flatnonzero(np.asarray(x) >= low)
        if len(hit):
            n_scans += 1
            if len(beams) < widest:
                beams.update(hit.tolist())
    if n_scans < SENTINEL_MIN_SCANS or len(beams) < max(SENTINEL_MIN_BEAMS, 0.02 * widest):
        return None
    return Sentinel(value=low, top=top, readings=inside, scans=n_scans)


def no_return_warning(path: str | Path, total: int, counts: dict[str, int], sentinel: Sentinel | None) -> str:
    """One line giving how many readings became no-returns and why (``counts``: reason ->
    readings; ``sentinel``: the log's own no-return value, if it was used as the maximum range)."""
    n = sum(counts.values())
    parts = ", ".join(f"{v:,} {k}" for k, v in counts.items() if v)
    text = f"{path}: {n:,} of {total:,} readings ({100.0 * n / max(total, 1):.1f} %) taken as no return ({parts})"
    if sentinel is not None:
        text += (
            f"; the log's own no-return value, {num(sentinel.value, 2)} m (a cluster of {sentinel.readings:,} "
            f"readings at {num(sentinel.value, 2)}-{num(sentinel.top, 2)} m in {sentinel.scans:,} scans), "
            f"is taken as the maximum range"
        )
    return text


# --- plausibility ------------------------------------------------------------------------------


def check_odometry(path: str | Path, frames: Sequence[Frame]) -> None:
    """Reject implausible odometry and mounts, which would make the map grow without bound.

    Raises InputError naming the scan (numbered from 1) when an odometry pose or wheel travel
    is not finite, when it moves more than ``max(MAX_ODOM_STEP, MAX_ODOM_SPEED * dt)`` metres
    between two consecutive scans (wheel travel: the wheel that moved most), or when a sensor
    mount lies more than ``MAX_MOUNT_OFFSET`` from the robot.
    """
    times = frame_times(frames)
    for name in ("odom", "wheels"):
        col = frame_column(frames, name)
        idx = [i for i, x in enumerate(col) if x is not None]
        if not idx:
            continue
        v = np.array([np.asarray(col[i], dtype=float) for i in idx])
        bad = ~np.isfinite(v).all(axis=1)
        if bad.any():
            i = idx[int(np.argmax(bad))]
            what = "odometry pose" if name == "odom" else "wheel travel"
            raise InputError(path, f"scan {i + 1} (t={num(times[i])}): {what} is not finite")
        if len(idx) < 2:
            continue
        step = np.hypot(*np.diff(v[:, :2], axis=0).T) if name == "odom" else np.abs(np.diff(v, axis=0)).max(axis=1)
        t = times[idx]
        dt = np.diff(t)
        over = step > np.maximum(MAX_ODOM_STEP, MAX_ODOM_SPEED * dt)
        if over.any():
            k = int(np.argmax(over))
            i, j = idx[k], idx[k + 1]
            raise InputError(
                path,
                f"odometry jumps {num(step[k], 0)} m in {num(dt[k])} s between scans {i + 1} and {j + 1} (t={num(t[k])})",
            )
    mounts = cast("list[NDArray[np.float64]]", frame_column(frames, "mount"))  # a mount is never None
    off = np.array([np.hypot(m[0, 3], m[1, 3]) for m in mounts])
    if len(off) and not (off <= MAX_MOUNT_OFFSET).all():
        i = int(np.argmax(~(off <= MAX_MOUNT_OFFSET)))
        raise InputError(
            path,
            f"scan {i + 1} (t={num(times[i])}): the sensor is mounted {off[i]:.3g} m from the robot "
            f"(more than {MAX_MOUNT_OFFSET:.0f} m: a corrupt pose or offset)",
        )


def prepare_output_dir(out: Path) -> None:
    """Create the output folder before a long run, so an unwritable one fails at once; one
    that cannot be made is an InputError with the system's reason."""
    try:
        if out.exists() and not out.is_dir():
            raise InputError(out, "the output folder exists and is not a folder")
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(out, f"cannot create the output folder: {_mkdir_failure(out, e)}") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError(out, "the output folder is not writable")


def _mkdir_failure(out: Path, e: OSError) -> str:
    """Why ``out`` could not be made, said of the folder it was to be made in: the system's
    reason ("Permission denied", "Read-only file system"), or, where the system's words
    mislead (making a folder in /proc is "No such file or directory"), what happened."""
    base = Path(os.path.abspath(out)).parent
    while not os.path.lexists(base) and base != base.parent:
        base = base.parent
    if not base.is_dir():
        return f"{base} is not a folder"
    if e.errno == errno.ENOENT:  # the folder to make it in exists: its file system takes no new folders
        kind = _file_system(base)
        return f"{base} takes no new folders" + (f" (a {kind} file system)" if kind else f" ({e.strerror})")
    return f"{e.strerror or e} in {base}"


def _file_system(path: Path) -> str | None:
    """The type of the file system ``path`` is on (Linux: from /proc/self/mounts), or None."""
    try:
        text = Path("/proc/self/mounts").read_text()
    except OSError:
        return None
    where = os.path.realpath(path)
    best, kind = "", None
    for line in text.splitlines():
        parts = line.split()
        if len(parts) < 3:
            continue
        point = parts[1].replace("\\040", " ")
        inside = where == point or where.startswith(point.rstrip("/") + "/")
        if inside and len(point) >= len(best):
            best, kind = point, parts[2]
    return kind


def missing_folders(out: Path) -> list[Path]:
    """The folders that making ``out`` would create: ``out`` and its missing parents, deepest first."""
    made: list[Path] = []
    p = Path(os.path.abspath(out))
    while not os.path.lexists(p) and p != p.parent:
        made.append(p)
        p = p.parent
    return made


def remove_if_empty(folders: list[Path]) -> None:
    """Remove each of ``folders`` (deepest first) that exists and is empty; stop at the first
    that is not (``os.rmdir`` never removes a folder holding anything)."""
    for d in folders:
        if not os.path.lexists(d):
            continue
        try:
            os.rmdir(d)
        except OSError:
            return
