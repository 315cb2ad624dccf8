"""The records that flow between loaders, filters and writers."""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, BinaryIO, Iterator, Protocol, Sequence, cast, overload

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from pfslam.filters.health import Health


@dataclass(slots=True)
class Frame:
    """One time-ordered sensor record, independent of the file format.

    A log holds tens of thousands of frames, so they are kept compact: no per-instance
    dictionary (slots), and loaders share one ``angles`` array (and one ``mount``, where it
    does not change) between the frames that have the same, rather than a copy each. Shared
    arrays are never modified in place; ``ranges`` may be float32 (THOR) or float64 (text
    logs, whose decimal readings float32 would round).

    Attributes:
        t: time stamp in seconds; strictly increasing along a log (the loaders repair
            repeated or backward stamps).
        ranges: (K,) ranges in metres; NaN, inf, or out-of-window values mean no return.
        angles: (K,) beam angles in the sensor frame, radians.
        odom: (3,) odometry pose ``[x, y, theta]`` at ``t``, or None.
        wheels: (2,) cumulative left/right wheel travel in metres at ``t``, or None.
        mount: (4, 4) transform from the robot base frame (on the floor, +x forward,
            +y left, +z up) to the sensor frame at ``t``.
        min_range, max_range: the sensor's valid window (exclusive), metres.
    """

    t: float
    ranges: NDArray[np.floating]
    angles: NDArray[np.float64]
    odom: NDArray[np.float64] | None = None
    wheels: NDArray[np.float64] | None = None
    mount: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))
    min_range: float = 0.1
    max_range: float = 30.0


@dataclass
class Estimate:
    """What a filter step returns."""

    t: float
    pose: NDArray[np.float64]
    n_eff: float
    resampled: bool = False
    updated: bool = True  # the scan was weighed (not only dead-reckoned)
    particles: int = 0  # particles after the step
    covariance: NDArray[np.float64] | None = None  # (3, 3) of x, y, theta, where the filter gives one
    health: Health | None = None  # localization: how well the last update's scan fits the map


# --- a log's frames stored by column ----------------------------------------------------------


class RangeRows(Protocol):
    """A log's ranges as :class:`Frames` reads them, one scan's readings at a time: an (N, K)
    array, :class:`FileRows`, or a loader's own rows (the ROS bag reader's)."""

    def __len__(self) -> int: ...

    def __getitem__(self, i: int, /) -> NDArray[np.floating]: ...


class FileRows:
    """The rows of a log's ranges, read from a file when asked for, not kept in memory.

    Row ``i`` is ``counts[i]`` items of ``dtypes[kinds[i]]`` at byte ``offsets[i]`` of
    ``file`` (kept open: the file a loader checked, or a temporary copy of a compressed
    variable's inflated bytes), returned as float32."""

    def __init__(
        self,
        file: BinaryIO,
        offsets: NDArray[np.int64],
        counts: NDArray[np.int64],
        kinds: NDArray[np.uint8],
        dtypes: Sequence[np.dtype[np.generic]],
    ) -> None:
        self.file = file
        self.fd = file.fileno()
        self.offsets, self.counts, self.kinds, self.dtypes = offsets, counts, kinds, list(dtypes)

    def __len__(self) -> int:
        return len(self.offsets)

    def __getitem__(self, i: int) -> NDArray[np.float32]:
        dt = self.dtypes[self.kinds[i]]
        n = int(self.counts[i])
        data = os.pread(self.fd, n * dt.itemsize, int(self.offsets[i]))
        if len(data) != n * dt.itemsize:
            raise OSError(f"{getattr(self.file, 'name', 'the log')}: the file changed while it was read")
        return np.frombuffer(data, dt).astype(np.float32)


class Frames(Sequence[Frame]):
    """A log's frames kept by column: one array each of times, odometry, wheel travel and
    sensor mounts, and the ranges as an (N, K) array or :class:`FileRows` (a long log that
    stays on disk). A :class:`Frame` is made when one is asked for (its arrays are views or
    fresh reads), so a 30,000-scan log costs a few hundred bytes a scan besides its ranges.
    Slicing gives a :class:`Frames` of the same kind; :meth:`with_column` a copy with one
    column replaced. Columns are never modified in place."""

    def __init__(
        self,
        t: NDArray[np.float64],
        ranges: RangeRows,
        angles: NDArray[np.float64],
        *,
        odom: NDArray[np.float64] | None = None,
        wheels: NDArray[np.float64] | None = None,
        mounts: NDArray[np.float64] | None = None,
        min_range: float = 0.1,
        max_range: float = 30.0,
        rows: NDArray[np.int64] | None = None,
    ) -> None:
        self.t = np.asarray(t, dtype=float)
        n = len(self.t)
        self.ranges = ranges
        self.rows = np.arange(n, dtype=np.int64) if rows is None else rows
        self.angles = angles
        self.odom, self.wheels = odom, wheels
        self.mounts = np.eye(4) if mounts is None else mounts
        self.min_range, self.max_range = min_range, max_range
        for name in ("odom", "wheels"):
            v = getattr(self, name)
            if v is not None and len(v) != n:
                raise ValueError(f"{name} has {len(v)} rows for {n} frames")
        if self.mounts.ndim == 3 and len(self.mounts) != n:
            raise ValueError(f"mounts has {len(self.mounts)} rows for {n} frames")

    def __len__(self) -> int:
        return len(self.t)

    def _frame(self, i: int) -> Frame:
        return Frame(
            t=float(self.t[i]),
            ranges=self.ranges[int(self.rows[i])],
            angles=self.angles,
            odom=None if self.odom is None else self.odom[i],
            wheels=None if self.wheels is None else self.wheels[i],
            mount=self.mounts[i] if self.mounts.ndim == 3 else self.mounts,
            min_range=self.min_range,
            max_range=self.max_range,
        )

    @overload
    def __getitem__(self, i: int) -> Frame: ...

    @overload
    def __getitem__(self, i: slice) -> Frames: ...

    def __getitem__(self, i: int | slice) -> Frame | Frames:
        if isinstance(i, slice):
            return Frames(
                self.t[i],
                self.ranges,
                self.angles,
                odom=None if self.odom is None else self.odom[i],
                wheels=None if self.wheels is None else self.wheels[i],
                mounts=self.mounts[i] if self.mounts.ndim == 3 else self.mounts,
                min_range=self.min_range,
                max_range=self.max_range,
                rows=self.rows[i],
            )
        n = len(self.t)
        k = int(i)
        if k < 0:
            k += n
        if not 0 <= k < n:
            raise IndexError(f"frame {i} of {n}")
        return self._frame(k)

    def __iter__(self) -> Iterator[Frame]:
        for i in range(len(self.t)):
            yield self._frame(i)

    def with_column(self, name: str, values: NDArray[np.float64]) -> Frames:
        """A copy with the ``odom`` or ``wheels`` column replaced by ``values`` (one row a frame)."""
        out = self[:]
        if name not in ("odom", "wheels"):
            raise ValueError(f"not a replaceable column: {name}")
        v = np.asarray(values, dtype=float)
        if len(v) != len(self):
            raise ValueError(f"{name} has {len(v)} rows for {len(self)} frames")
        setattr(out, name, v)
        return out


def frame_times(frames: Sequence[Frame]) -> NDArray[np.float64]:
    """The time stamps of ``frames`` (a list or :class:`Frames`; the latter without reading ranges)."""
    if isinstance(frames, Frames):
        return frames.t.copy()
    return np.array([f.t for f in frames], dtype=float)


def frame_column(frames: Sequence[Frame], name: str) -> list[NDArray[np.float64] | None]:
    """Each frame's ``odom``, ``wheels`` or ``mount`` (None where a frame has none), without
    reading the ranges of a :class:`Frames`."""
    if isinstance(frames, Frames):
        if name == "mount":
            m = frames.mounts
            return list(m) if m.ndim == 3 else [m] * len(frames)
        v = getattr(frames, name)
        return [None] * len(frames) if v is None else list(v)
    return [getattr(f, name) for f in frames]


def with_column(frames: Sequence[Frame], name: str, values: NDArray[np.float64]) -> Sequence[Frame]:
    """``frames`` with each frame's ``odom`` or ``wheels`` replaced by a row of ``values``."""
    if isinstance(frames, Frames):
        return frames.with_column(name, values)
    return [replace(f, **cast("dict[str, Any]", {name: np.array(v, dtype=float)})) for f, v in zip(frames, values)]
