"""pfslam: 2D LIDAR particle-filter SLAM and Monte Carlo localization.

The Python API. A whole run, exactly as ``pfslam slam`` / ``pfslam localize`` does it (the
same files, byte for byte)::

    import pfslam

    outcome = pfslam.slam("train_lidar0.mat", "out", joint="train_joint0.mat")
    outcome.run.poses, outcome.scores.errors  # also in out/: map, trajectory.tum, run.json

Or step a filter yourself::

    from pfslam import SlamConfig, load_log, make_slam, write_tum

    log = load_log("train_lidar0.mat", joint="train_joint0.mat")  # THOR, CARMEN, Mines, ROS bags
    slam = make_slam(SlamConfig(particles=30, seed=0), log.format)  # the filter pfslam slam picks
    for frame in log.frames:
        slam.step(frame)
    t, poses = slam.trajectory()
    slam.map.save_ros("map")  # map.pgm + map.yaml
    write_tum("trajectory.tum", t, poses)

- Logs: :func:`load_log` (any supported format, detected from the file) gives a
  :class:`LoadedLog` whose ``frames`` are :class:`Frame` records; :func:`simulate` writes a
  THOR-format log with ground truth.
- Filters (each with ``step(frame) -> Estimate``, ``map``, ``odom_pose``, ``trajectory()``,
  ``particles``, ``diagnostics()``): :class:`Slam` (the single-map particle filter),
  :class:`RaoBlackwellizedSlam` (a map per particle; ``make_slam(config, log.format)`` builds
  the one ``pfslam slam`` runs: ``filter: auto`` is this one unless the local search is on) and
  :class:`Localizer` (Monte Carlo localization on a known :class:`OccupancyGrid`, e.g.
  ``OccupancyGrid.load_ros("map.yaml")``).
- Settings: :class:`SlamConfig`, :class:`LocalizerConfig`, :class:`CalibrationConfig`
  (frozen dataclasses, checked when built; :func:`load_config` reads a YAML file).
- Whole runs as the command line does them: :func:`slam`, :func:`localize` (load, correct,
  run, score, write); the filter loop alone: :func:`run_slam`, :func:`run_localization`;
  :func:`write_outputs`.
- Results: :func:`trajectory_errors` (ATE, RPE), :func:`relation_errors` (the SLAM
  benchmark's relations), :func:`map_agreement` (needs no ground truth),
  :func:`read_tum` / :func:`write_tum`.
- Errors: :class:`PfslamError`, and :class:`InputError` for a file that cannot be used.

Names are imported when first used, so ``import pfslam`` stays light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

__version__ = "0.1.0"

_EXPORTS = {
    "Slam": ("pfslam.filters.single", "SingleMapSlam"),
    "SingleMapSlam": ("pfslam.filters.single", "SingleMapSlam"),
    "RaoBlackwellizedSlam": ("pfslam.filters.rbpf", "RaoBlackwellizedSlam"),
    "make_slam": ("pfslam.pipeline", "make_slam"),
    "resolve_filter": ("pfslam.config", "resolve_filter"),
    "Localizer": ("pfslam.filters.localize", "Localizer"),
    "SlamConfig": ("pfslam.config", "SlamConfig"),
    "LocalizerConfig": ("pfslam.config", "LocalizerConfig"),
    "CalibrationConfig": ("pfslam.config", "CalibrationConfig"),
    "load_config": ("pfslam.config", "load_config"),
    "load_log": ("pfslam.io.logs", "load_log"),
    "LoadedLog": ("pfslam.io.common", "LoadedLog"),
    "Frame": ("pfslam.frames", "Frame"),
    "Frames": ("pfslam.frames", "Frames"),
    "Estimate": ("pfslam.frames", "Estimate"),
    "OccupancyGrid": ("pfslam.maps.grid", "OccupancyGrid"),
    "simulate": ("pfslam.tools.simulate", "simulate"),
    "slam": ("pfslam.pipeline", "slam"),
    "localize": ("pfslam.pipeline", "localize"),
    "run_slam": ("pfslam.pipeline", "run_slam"),
    "run_localization": ("pfslam.pipeline", "run_localization"),
    "write_outputs": ("pfslam.pipeline", "write_outputs"),
    "trajectory_errors": ("pfslam.eval.metrics", "trajectory_errors"),
    "relation_errors": ("pfslam.eval.metrics", "relation_errors"),
    "map_agreement": ("pfslam.eval.metrics", "map_agreement"),
    "read_tum": ("pfslam.io.trajectory", "read_tum"),
    "write_tum": ("pfslam.io.trajectory", "write_tum"),
    "PfslamError": ("pfslam.errors", "PfslamError"),
    "InputError": ("pfslam.errors", "InputError"),
}

__all__ = ["__version__", *_EXPORTS]


def __getattr__(name: str) -> object:
    """Import an exported name from its module on first use (PEP 562)."""
    try:
        module, attr = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module 'pfslam' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))


if TYPE_CHECKING:  # for type checkers and editors: the same names, imported eagerly
    from pfslam.config import (
        CalibrationConfig,
        LocalizerConfig,
        SlamConfig,
        load_config,
        resolve_filter,
    )
    from pfslam.errors import InputError, PfslamError
    from pfslam.eval.metrics import map_agreement, relation_errors, trajectory_errors
    from pfslam.filters.localize import Localizer
    from pfslam.filters.rbpf import RaoBlackwellizedSlam
    from pfslam.filters.single import SingleMapSlam
    from pfslam.filters.single import SingleMapSlam as Slam
    from pfslam.frames import Estimate, Frame, Frames
    from pfslam.io.common import LoadedLog
    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import read_tum, write_tum
    from pfslam.maps.grid import OccupancyGrid
    from pfslam.pipeline import localize, make_slam, run_localization, run_slam, slam, write_outputs
    from pfslam.tools.simulate import simulate
