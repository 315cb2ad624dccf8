"""What the views of a run (a video, the rerun viewer) draw besides the filter's state: the
run's trace (:class:`RunTrace`), which steps a view samples (:func:`sample_steps`), and the
checks a view makes before a run (its optional packages, its file's folder)."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from pfslam.errors import ConfigError, InputError
from pfslam.filters.base import SETTLED_SPREAD, Filter, position_std
from pfslam.frames import Estimate, Frame
from pfslam.geometry import compose, relative, transform_points
from pfslam.sensor import scan_to_points
from pfslam.types import Array


def require(modules: Sequence[tuple[str, str]], extra: str, option: str) -> None:
    """ConfigError (one line, naming the pip command) unless every (module, package) of
    ``modules`` imports."""
    for module, package in modules:
        try:
            importlib.import_module(module)
        except ImportError:
            raise ConfigError(
                f"{option} needs the optional package {package}, which is not installed: pip install 'pfslam[{extra}]'"
            ) from None


def prepare_file(path: Path, what: str) -> None:
    """Create the folder ``path`` goes into; InputError if it cannot be made or ``path`` is a folder."""
    if path.is_dir():
        raise InputError(path, f"the {what} file is a folder")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(path.parent, f"cannot create the folder for the {what} ({e.strerror or e})") from None


def sample_steps(times: Array, interval: float) -> NDArray[np.int64]:
    """How many samples, taken every ``interval`` seconds of log time from the first step on,
    fall on each step: a sample at time T shows the last step at or before T. The last step
    is always sampled once at least, so a view ends on the final state."""
    t = np.asarray(times, dtype=float)
    n = len(t)
    counts = np.zeros(n, dtype=np.int64)
    if n == 0:
        return counts
    span = float(t[-1] - t[0])
    k = int(np.floor(span / interval)) + 1 if interval > 0 and np.isfinite(span) else 1
    moments = t[0] + interval * np.arange(k)
    steps = np.clip(np.searchsorted(t, moments, side="right") - 1, 0, n - 1)
    np.add.at(counts, steps, 1)
    counts[-1] = max(counts[-1], 1)
    return counts


class RunTrace:
    """The run so far, for drawing: each step's time, estimate and dead-reckoned odometry,
    the ground truth (when known) and the scan in the world frame.

    The odometry is drawn from the first settled estimate on (for filters that give a
    covariance, a position spread under :data:`~pfslam.filters.base.SETTLED_SPREAD`; at once
    for the others), started at that estimate, as :func:`~pfslam.pipeline.run_localization`
    draws it: for SLAM the map frame is the odometry's, so this is the odometry itself."""

    def __init__(self, times: Array, truth: tuple[Array, Array] | None = None, ground_z: float = 0.15) -> None:
        self.t = np.asarray(times, dtype=float)
        n = len(self.t)
        self.poses = np.full((n, 3), np.nan)
        self.odom = np.full((n, 3), np.nan)
        self.truth = None if truth is None else (np.asarray(truth[0], float), np.asarray(truth[1], float))
        self.ground_z = ground_z
        self.anchor: int | None = None  # the step the odometry is drawn from
        self.last = -1  # the last step recorded

    def __len__(self) -> int:
        return len(self.t)

    def add(self, i: int, filt: Filter, est: Estimate) -> None:
        self.poses[i] = est.pose
        self.odom[i] = filt.odom_pose
        self.last = i
        if self.anchor is None:
            cov = est.covariance
            if cov is None or position_std(cov) < SETTLED_SPREAD:
                self.anchor = i

    def estimate(self, a: int, b: int) -> Array:
        """The estimates of steps a..b (inclusive)."""
        return self.poses[a : b + 1]

    def odometry(self, a: int, b: int) -> Array:
        """The odometry of steps a..b (inclusive) in the map frame, from the anchor on (empty before it)."""
        if self.anchor is None or b < self.anchor:
            return np.empty((0, 3))
        k = self.anchor
        return compose(self.poses[k], relative(self.odom[k], self.odom[max(a, k) : b + 1]))

    def truth_between(self, t0: float, t1: float) -> Array:
        """The true poses from the last one at or before ``t0`` to the last at or before ``t1``."""
        if self.truth is None:
            return np.empty((0, 3))
        tt, poses = self.truth
        a = max(int(np.searchsorted(tt, t0, side="right")) - 1, 0)
        b = int(np.searchsorted(tt, t1, side="right"))
        return poses[a:b]

    def hits(self, frame: Frame, pose: Array) -> Array:
        """The frame's obstacle hits in the world frame, the robot at ``pose``."""
        pts = scan_to_points(frame, ground_z=self.ground_z).hits
        return transform_points(pose, pts) if len(pts) else np.empty((0, 2))
