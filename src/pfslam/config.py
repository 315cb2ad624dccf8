"""Typed configuration with YAML load/dump. The config used is saved with every result."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, is_dataclass
from pathlib import Path
from typing import Any, TypeVar

import yaml

from pfslam.errors import ConfigError, InputError


@dataclass
class MapConfig:
    resolution: float = 0.05  # m per cell
    l_occ: float = 3.0  # log-odds added to the cell a beam ends in
    l_free: float = -1.0  # log-odds added to each cell a beam passes through
    l_clamp: float = 120.0  # cells are clamped to +-l_clamp
    initial_size: float = 20.0  # m, the grid grows as needed


@dataclass
class MotionConfig:
    sigma_x: float = 0.01  # m per ref_interval
    sigma_y: float = 0.01  # m per ref_interval
    sigma_theta_deg: float = 0.5  # deg per ref_interval
    ref_interval: float = 0.25  # s (10 scans at 40 Hz)
    trans_k: float = 0.0  # extra x/y noise per metre travelled (m/m), added in quadrature
    rot_k: float = 0.0  # extra heading noise per radian turned (rad/rad)
    axle: float = 0.33  # m, differential drive only
    k_left: float = 0.05  # wheel travel noise per metre, differential drive only
    k_right: float = 0.05


@dataclass
class SensorConfig:
    ground_z: float = 0.15  # m, points lower than this are floor hits
    max_hits: int = 400  # hits used to score a particle (evenly subsampled)
    saturation: float = 6.0  # log-odds at which a cell counts fully as wall (+1) or free (-1)
    temperature: float = 2.0  # log-weight = score / temperature
    free_weight: float = 0.0  # score "cells": a hit in confirmed free space scores -free_weight (0..1)
    # "cells": the map's cell values (sharp; best when scans are dense, e.g. 40 Hz);
    # "field": a smoothed wall map exp(-d^2 / 2 sigma^2) (a wide basin, for big steps);
    # "auto": "field" for steps that moved more than field_auto_m or turned more than
    # field_auto_deg since the last scan, "cells" otherwise.
    score: str = "auto"
    field_auto_m: float = 0.2
    field_auto_deg: float = 5.0
    field_sigma: float = 0.1  # m, width of the smoothed wall map
    field_threshold: float = 1.0  # log-odds above which a cell counts as wall for the field
    field_refresh_m: float = 0.25  # rebuild the field after this much motion (m) ...
    field_refresh_deg: float = 5.0  # ... or turn (deg) ...
    field_refresh_scans: int = 40  # ... or this many scans, whichever comes first


@dataclass
class SearchConfig:
    # Each particle also tries the offsets of a local grid and moves to its best one: the
    # filter then follows motions the odometry gets wrong by up to radius_cells cells and
    # theta_steps * theta_step_deg degrees per scan (fast turns with slipping wheels),
    # at (2r+1)^2 (2k+1) times the scoring cost.
    enabled: bool = False
    radius_cells: int = 2  # x/y offsets of -r..r cells
    theta_steps: int = 4  # heading offsets of -k..k steps
    theta_step_deg: float = 1.0


@dataclass
class SlamConfig:
    particles: int = 100
    seed: int = 0
    every: int = 1  # process every k-th scan
    resample_threshold: float = 0.5  # resample when N_eff < threshold * N
    resample_method: str = "systematic"
    estimate: str = "mean"  # mean (weighted, circular theta) | best
    map: MapConfig = field(default_factory=MapConfig)
    motion: MotionConfig = field(default_factory=MotionConfig)
    sensor: SensorConfig = field(default_factory=SensorConfig)
    search: SearchConfig = field(default_factory=SearchConfig)

    def validate(self) -> "SlamConfig":
        from pfslam.particles import DRAWERS

        if self.particles < 1:
            raise ConfigError("particles must be at least 1")
        if self.every < 1:
            raise ConfigError("every must be at least 1")
        if self.resample_method not in DRAWERS:
            raise ConfigError(f"resample_method must be one of {sorted(DRAWERS)}")
        if self.estimate not in ("best", "mean"):
            raise ConfigError("estimate must be 'best' or 'mean'")
        if self.map.resolution <= 0:
            raise ConfigError("map.resolution must be positive")
        if self.sensor.score not in ("auto", "field", "cells"):
            raise ConfigError("sensor.score must be 'auto', 'field' or 'cells'")
        if self.sensor.field_sigma <= 0 or self.sensor.field_refresh_scans < 1:
            raise ConfigError("sensor.field_sigma must be positive and sensor.field_refresh_scans at least 1")
        if not 0.0 <= self.sensor.free_weight <= 1.0:
            raise ConfigError("sensor.free_weight must be between 0 and 1")
        if self.sensor.temperature <= 0 or self.sensor.saturation <= 0:
            raise ConfigError("sensor.temperature and sensor.saturation must be positive")
        return self


T = TypeVar("T")


def to_dict(cfg: Any) -> dict[str, Any]:
    return asdict(cfg)


def from_dict(cls: type[T], data: dict[str, Any], where: str = "") -> T:
    """Build a dataclass from a nested dict; unknown keys are an error."""
    if not isinstance(data, dict):
        raise ConfigError(f"{where or 'config'}: expected a mapping")
    known = {f.name: f for f in fields(cls)}  # type: ignore[arg-type]
    kwargs: dict[str, Any] = {}
    defaults = cls()
    for key, value in data.items():
        if key not in known:
            raise ConfigError(f"unknown config key '{where}{key}'")
        current = getattr(defaults, key)
        if is_dataclass(current):
            kwargs[key] = from_dict(type(current), value, f"{where}{key}.")
        else:
            want = type(current)
            try:
                kwargs[key] = value if isinstance(value, want) else want(value)
            except (TypeError, ValueError):
                raise ConfigError(f"config key '{where}{key}': cannot read {value!r} as {want.__name__}") from None
    return cls(**kwargs)


def load_config(path: str | Path, cls: type[T] = SlamConfig) -> T:  # type: ignore[assignment]
    p = Path(path)
    if not p.is_file():
        raise InputError(p, "config file not found")
    try:
        data = yaml.safe_load(p.read_text(encoding="utf-8")) or {}
    except yaml.YAMLError as e:
        raise InputError(p, f"not valid YAML ({str(e).splitlines()[0]})") from None
    try:
        return from_dict(cls, data)
    except ConfigError as e:
        raise InputError(p, str(e)) from None


def dump_config(cfg: Any) -> str:
    return yaml.safe_dump(to_dict(cfg), sort_keys=False)
