"""Typed configuration with YAML load/dump. The config used is saved with every result."""

from __future__ import annotations

import math
import numbers
import operator
import re
from dataclasses import MISSING, asdict, dataclass, field, fields, is_dataclass
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

        check_fields(self)  # ints are integers, floats finite numbers, bools true or false
        check_int("particles", self.particles, 1, MAX_PARTICLES)
        check_int("seed", self.seed, 0)
        check_int("every", self.every, 1)
        check_number("resample_threshold", self.resample_threshold, ge=0.0, le=1.0)
        if self.resample_method not in DRAWERS:
            raise ConfigError(f"resample_method must be one of {sorted(DRAWERS)}")
        if self.estimate not in ("best", "mean"):
            raise ConfigError("estimate must be 'best' or 'mean'")
        m, mo, se, sr = self.map, self.motion, self.sensor, self.search
        check_number("map.resolution", m.resolution, ge=0.001)
        check_number("map.initial_size", m.initial_size, gt=0.0)
        # A hit must raise a cell towards occupied and a beam passing through lower it.
        check_number("map.l_occ", m.l_occ, gt=0.0)
        check_number("map.l_free", m.l_free, lt=0.0)
        check_number("map.l_clamp", m.l_clamp, gt=0.0)
        for name in ("sigma_x", "sigma_y", "sigma_theta_deg", "trans_k", "rot_k", "k_left", "k_right"):
            check_number(f"motion.{name}", getattr(mo, name), ge=0.0)
        check_number("motion.ref_interval", mo.ref_interval, gt=0.0)
        check_number("motion.axle", mo.axle, gt=0.0)
        check_int("sensor.max_hits", se.max_hits, 1)
        check_number("sensor.saturation", se.saturation, gt=0.0)
        check_number("sensor.temperature", se.temperature, gt=0.0)
        check_number("sensor.free_weight", se.free_weight, ge=0.0, le=1.0)
        if se.score not in ("auto", "field", "cells"):
            raise ConfigError("sensor.score must be 'auto', 'field' or 'cells'")
        for name in ("field_auto_m", "field_auto_deg", "field_refresh_m", "field_refresh_deg"):
            check_number(f"sensor.{name}", getattr(se, name), ge=0.0)
        check_number("sensor.field_sigma", se.field_sigma, gt=0.0)
        check_int("sensor.field_refresh_scans", se.field_refresh_scans, 1)
        # (2r+1)^2 (2k+1) offsets per particle: bounded so a typo cannot hang the run.
        check_int("search.radius_cells", sr.radius_cells, 0, 20)
        check_int("search.theta_steps", sr.theta_steps, 0, 45)
        check_number("search.theta_step_deg", sr.theta_step_deg, gt=0.0)
        return self


T = TypeVar("T")

MAX_PARTICLES = 10_000_000  # about 240 MB of poses per copy: more is a typo, not a filter

# PyYAML reads 1e-3 (no dot) as a string; a float field takes such a number too.
_EXPONENT_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")
_OPS = {">": operator.gt, ">=": operator.ge, "<=": operator.le, "<": operator.lt}


def _shown(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _is_int(value: Any) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def check_int(name: str, value: Any, lo: int = 0, hi: int | None = None) -> int:
    """``value`` if it is an integer in ``lo..hi`` (no upper bound if None), else a ConfigError naming ``name``."""
    if not _is_int(value) or value < lo or (hi is not None and value > hi):
        want = ("a non-negative integer" if lo == 0 and hi is None else
                f"an integer >= {lo}" if hi is None else f"an integer in {lo}..{hi}")
        raise ConfigError(f"{name} must be {want}, not {_shown(value)}")
    return int(value)


def check_number(name: str, value: Any, *, gt: float | None = None, ge: float | None = None,
                 le: float | None = None, lt: float | None = None, what: str = "a finite number") -> float:
    """``value`` as a float if it is a finite number within the bounds given, else a ConfigError
    naming ``name`` (``what`` describes the number, e.g. "a finite number of seconds")."""
    limits = [(op, b) for op, b in ((">", gt), (">=", ge), ("<=", le), ("<", lt)) if b is not None]
    if not (_is_number(value) and math.isfinite(value) and all(_OPS[op](value, b) for op, b in limits)):
        text = " and ".join(f"{op} {b:g}" for op, b in limits)
        raise ConfigError(f"{name} must be {what}{' ' + text if text else ''}, not {_shown(value)}")
    return float(value)


def _check_type(key: str, value: Any, want: type) -> None:
    if want is bool:
        ok, text = isinstance(value, bool), "true or false"
    elif want is int:
        ok, text = _is_int(value), "an integer"
    elif want is float:
        ok, text = _is_number(value) and math.isfinite(value), "a finite number"
    else:
        ok, text = isinstance(value, want), "a string" if want is str else f"a {want.__name__}"
    if not ok:
        raise ConfigError(f"{key} must be {text}, not {_shown(value)}")


def check_fields(cfg: Any, where: str = "") -> None:
    """Every field of the dataclass ``cfg`` (and of its sub-configs) has the type of its
    default: bools are bools, ints are integers (not bools), floats finite numbers."""
    for f in fields(cfg):
        default = f.default_factory() if f.default is MISSING else f.default  # type: ignore[misc]
        value = getattr(cfg, f.name)
        _check_type(f"{where}{f.name}", value, type(default))
        if is_dataclass(default):
            check_fields(value, f"{where}{f.name}.")


def _read_value(key: str, value: Any, want: type) -> Any:
    """A YAML value for a field of type ``want``, converted only where nothing is lost: an
    integral float (100.0) for an int, an int or 1e-3 for a float; no other conversions."""
    if want is int and _is_number(value) and not _is_int(value) and float(value).is_integer():
        value = int(value)
    elif want is float and isinstance(value, str) and _EXPONENT_NUMBER.fullmatch(value.strip()):
        value = float(value)
    elif want is float and _is_int(value):
        value = float(value)
    _check_type(key, value, want)
    return value


def to_dict(cfg: Any) -> dict[str, Any]:
    return asdict(cfg)


def from_dict(cls: type[T], data: dict[str, Any], where: str = "") -> T:
    """Build a dataclass from a nested dict; unknown keys and values of the wrong type are an error."""
    if not isinstance(data, dict):
        what = f"section '{where.rstrip('.')}'" if where else "config"
        raise ConfigError(f"{what} must be a mapping of keys to values, not {_shown(data)}")
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
            try:
                kwargs[key] = _read_value(f"{where}{key}", value, type(current))
            except OverflowError:
                raise ConfigError(f"{where}{key}: {_shown(value)} is out of range") from None
    return cls(**kwargs)


def load_config(path: str | Path, cls: type[T] = SlamConfig) -> T:  # type: ignore[assignment]
    p = Path(path)
    if p.is_dir():
        raise InputError(p, "is a folder, not a config file")
    if not p.is_file():
        raise InputError(p, "config file not found")
    try:
        data = yaml.safe_load(p.read_text(encoding="utf-8")) or {}
    except UnicodeDecodeError as e:
        raise InputError(p, f"not UTF-8 text (byte {e.object[e.start]:#04x} at offset {e.start})") from None
    except yaml.YAMLError as e:
        raise InputError(p, f"not valid YAML ({str(e).splitlines()[0]})") from None
    try:
        return from_dict(cls, data)
    except ConfigError as e:
        raise InputError(p, str(e)) from None


def dump_config(cfg: Any) -> str:
    return yaml.safe_dump(to_dict(cfg), sort_keys=False)
