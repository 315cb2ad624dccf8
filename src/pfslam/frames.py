"""The records that flow between loaders, filters and writers."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray


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
    ranges: NDArray[np.float64]
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
