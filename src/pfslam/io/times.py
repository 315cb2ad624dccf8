"""Scan time stamps as loggers write them, repaired: the rule every loader shares (a stamp that
repeats, steps back a little or jumps out alone is repaired and counted; stamps that carry no
timing give way to the scan order), and the streaming clock.

A leaf module, like :mod:`pfslam.io.common`: it imports nothing from :mod:`pfslam.io`."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

import numpy as np
from numpy.typing import NDArray

from pfslam.errors import InputError
from pfslam.io.common import (
    DEFAULT_SCAN_INTERVAL,
    INFORMATIVE_STEPS,
    REPEAT_STEP,
    SCAN_TIME_TOLERANCE,
    TIME_TOLERANCE,
    num,
)


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
