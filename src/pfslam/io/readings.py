"""No-return readings: a log's own no-return value found among its largest readings (a cluster
of one value across scans and beams), and the one warning that counts the readings that are
no returns, by kind.

A leaf module, like :mod:`pfslam.io.common`: it imports nothing from :mod:`pfslam.io`."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pfslam.io.common import num

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
