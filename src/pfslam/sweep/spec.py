"""Sweep specs: the YAML a user writes (logs, seeds, settings), checked (:func:`load_spec`,
:func:`parse_spec`), and the names of its setting combinations (:func:`settings_text`,
:func:`settings_slug`); :mod:`pfslam.sweep.jobs` expands a spec into one job per log ×
setting combination × seed (see :mod:`pfslam.sweep`). Nothing here prints."""

from __future__ import annotations

import difflib
import hashlib
import itertools
import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Sequence, TypeGuard

import yaml

from pfslam.errors import ConfigError, InputError

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

    from pfslam.config import ConfigValue, LocalizerConfig, SlamConfig

SPEC_KEYS = ("logs", "seeds", "settings", "run")
LOG_KEYS = ("name", "path", "joint", "odometry", "ground_truth", "relations", "time_offset", "map", "args")
RANGE_KEYS = ("from", "to", "step")
# What each run is: the `pfslam` command it runs (and the config section its settings are keys of).
RUNS = ("slam", "localize")
# Options of `pfslam slam` / `pfslam localize` that the sweep sets itself: a log's `args` may not repeat them.
SWEEP_OPTIONS = (
    "-o",
    "--out",
    "-c",
    "--config",
    "--seed",
    "-j",
    "--joint",
    "-g",
    "--ground-truth",
    "--odometry",
    "-m",
    "--map",
)
MAX_VALUES = 10_000  # values of one range: more is a typo (a step of 0.0001)
MAX_RUNS = 100_000
# -- the spec ------------------------------------------------------------------------------


@dataclass(frozen=True)
class LogSpec:
    """One log of a spec; paths are absolute."""

    name: str
    path: Path
    joint: Path | None = None
    odometry: str = "log"  # may hold {seed}
    ground_truth: Path | None = None
    relations: Path | None = None
    time_offset: float = 0.0
    args: tuple[str, ...] = ()
    map: Path | None = None  # the map of a localize run (a map.yaml or a slam output folder); may hold {seed}


@dataclass(frozen=True)
class Spec:
    """A validated spec: logs, seeds, the values of each setting (in the spec's order) and
    what each run is (``slam`` or ``localize``)."""

    path: Path
    logs: tuple[LogSpec, ...]
    seeds: tuple[int, ...]
    settings: dict[str, tuple[ConfigValue, ...]] = field(default_factory=dict)
    run: str = "slam"

    @property
    def setting_keys(self) -> list[str]:
        return list(self.settings)

    def combinations(self) -> list[dict[str, ConfigValue]]:
        """Every combination of the settings' values (one empty one without settings)."""
        keys = list(self.settings)
        return [dict(zip(keys, values)) for values in itertools.product(*self.settings.values())]

    @property
    def runs(self) -> int:
        return len(self.logs) * len(self.seeds) * math.prod(len(v) for v in self.settings.values())


def _fail(spec: Path, key: str, problem: str) -> InputError:
    return InputError(spec, f"{key}: {problem}")


def _did_you_mean(key: object, known: tuple[str, ...]) -> str:
    """The hint ", did you mean 'X'?" for a misspelt ``key`` close to one of ``known``, else ""."""
    close = difflib.get_close_matches(str(key), known, n=1, cutoff=0.6)
    return f", did you mean '{close[0]}'?" if close else ""


def _shown(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _is_number(value: object) -> TypeGuard[float]:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def expand_range(spec: Path, key: str, value: Mapping[str, object], integer: bool = False) -> list[float]:
    """The values ``from``, ``from + step``, ... up to ``to`` inclusive (``step`` 1 if not
    given). Integers stay integers; float steps are rounded to 12 significant digits so
    ``{from: 0.1, to: 0.3, step: 0.1}`` gives 0.1, 0.2, 0.3."""
    unknown = [k for k in value if k not in RANGE_KEYS]
    if unknown:
        raise _fail(
            spec,
            key,
            f"unknown range key {unknown[0]!r}{_did_you_mean(unknown[0], RANGE_KEYS)} "
            "(a range has from, to and optionally step)",
        )
    for k in ("from", "to"):
        if k not in value:
            raise _fail(spec, key, f"a range needs '{k}' (a range is {{from: A, to: B, step: S}})")
    bounds: list[float] = []  # from, to, step: integers stay integers
    for k, v in (("from", value["from"]), ("to", value["to"]), ("step", value.get("step", 1))):
        if not _is_number(v) or not math.isfinite(v):
            raise _fail(spec, f"{key}.{k}", f"must be a finite number, not {_shown(v)}")
        if integer and not isinstance(v, int):
            raise _fail(spec, f"{key}.{k}", f"must be an integer, not {_shown(v)}")
        bounds.append(v)
    start, stop, step = bounds
    if step <= 0:
        raise _fail(spec, f"{key}.step", f"must be greater than 0, not {_shown(step)}")
    if stop < start:
        raise _fail(spec, key, f"'to' ({stop}) is below 'from' ({start})")
    count = int(math.floor((stop - start) / step + 1e-9)) + 1
    if count > MAX_VALUES:
        raise _fail(spec, key, f"the range has {count} values (at most {MAX_VALUES})")
    if all(isinstance(v, int) for v in (start, stop, step)):
        return [start + i * step for i in range(count)]
    return [float(f"{start + i * step:.12g}") for i in range(count)]


def _is_map_folder(p: Path) -> bool:
    """Whether ``p`` is a folder ``pfslam localize --map`` reads: a ``pfslam slam`` output
    folder (its map.yaml), or the session folder inside one."""
    return (p / "map.yaml").is_file() or ((p / "session.json").is_file() and (p.parent / "map.yaml").is_file())


def _path(spec: Path, key: str, value: object, what: str, bag_folder: bool = False, map_folder: bool = False) -> Path:
    """``value`` as an existing file's absolute path (relative to the spec's folder); with
    ``bag_folder`` a ROS 2 bag's folder is one too, with ``map_folder`` a slam output folder."""
    from pfslam.io.rosbag import is_ros2_folder

    if not isinstance(value, str) or not value.strip():
        raise _fail(spec, key, f"must be a path (a string), not {_shown(value)}")
    p = Path(value).expanduser()
    p = (spec.parent / p) if not p.is_absolute() else p
    p = Path(os.path.normpath(p.absolute()))
    if bag_folder and is_ros2_folder(p):
        return p
    if map_folder and p.is_dir():
        if _is_map_folder(p):
            return p
        raise _fail(spec, key, f"{p} is a folder without map.yaml (give a map.yaml or a pfslam slam output folder)")
    if p.is_dir():
        extra = " or a ROS 2 bag (no metadata.yaml in it)" if bag_folder else ""
        raise _fail(spec, key, f"{p} is a folder, not a {what}{extra}")
    if not p.is_file():
        raise _fail(spec, key, f"{what} not found: {p}")
    return p


def _sweep_option(arg: str) -> str | None:
    """The option of :data:`SWEEP_OPTIONS` that ``arg`` gives, in any of the forms the command
    line takes (``--out DIR``, ``--out=DIR``, ``-o DIR``, ``-oDIR``), or None."""
    if arg.startswith("--"):
        name = arg.split("=", 1)[0]
        return name if name in SWEEP_OPTIONS else None
    if arg.startswith("-") and len(arg) >= 2 and arg[:2] in SWEEP_OPTIONS:
        return arg[:2]
    return None


def _log_spec(spec: Path, i: int, entry: object, seeds: Sequence[int] = (0,), run: str = "slam") -> LogSpec:
    """Log ``i`` of the spec; its path, joint, ground truth and map may hold ``{seed}`` (a log
    per seed, such as simulated walks), checked for each of ``seeds``. A ``localize`` run
    needs a map; a ``slam`` run makes its own and may not have one."""
    from pfslam.io.synthetic import parse_odometry_option

    where = f"logs[{i}]"
    if not isinstance(entry, dict):
        raise _fail(spec, where, f"must be a mapping with name, path, ... not {_shown(entry)}")
    unknown = [k for k in entry if k not in LOG_KEYS]
    if unknown:
        hint = _did_you_mean(unknown[0], LOG_KEYS)
        raise _fail(spec, f"{where}.{unknown[0]}", f"unknown key{hint} (a log has {', '.join(LOG_KEYS)})")
    for k in ("name", "path"):
        if k not in entry:
            raise _fail(spec, where, f"needs '{k}'")
    name = entry["name"]
    if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9._-]*", name):
        raise _fail(spec, f"{where}.name", f"must be a plain name (letters, digits, . _ -), not {_shown(name)}")
    where = f"logs[{i}] ({name})"

    def path_of(key: str, what: str, bag_folder: bool = False, map_folder: bool = False) -> Path:
        value = entry[key]
        if not isinstance(value, str) or "{seed}" not in value:
            return _path(spec, f"{where}.{key}", value, what, bag_folder, map_folder)
        for seed in seeds:
            seeded = value.replace("{seed}", str(seed))
            _path(spec, f"{where}.{key} (seed {seed})", seeded, what, bag_folder, map_folder)
        p = Path(value).expanduser()
        return Path(os.path.normpath((spec.parent / p if not p.is_absolute() else p).absolute()))

    path = path_of("path", "log file", bag_folder=True)
    joint = path_of("joint", "joint file") if entry.get("joint") is not None else None
    gt = path_of("ground_truth", "ground truth file") if entry.get("ground_truth") is not None else None
    map_path = None
    if run == "localize":
        if entry.get("map") is None:
            raise _fail(spec, where, "needs 'map' with 'run: localize' (a map.yaml or a pfslam slam output folder)")
        map_path = path_of("map", "map file", map_folder=True)
    elif "map" in entry:
        raise _fail(spec, f"{where}.map", "only means something with 'run: localize' (a slam run makes its own map)")
    odometry = entry.get("odometry", "log")
    if not isinstance(odometry, str):
        raise _fail(
            spec, f"{where}.odometry", f"must be 'log', 'synthetic' or 'synthetic:SEED', not {_shown(odometry)}"
        )
    try:
        parse_odometry_option(odometry.replace("{seed}", "0"))
    except ValueError as e:
        raise _fail(spec, f"{where}.odometry", f"{e} ({{seed}} stands for the run's seed)") from None
    relations = None
    if entry.get("relations") is not None:
        from pfslam.eval.metrics import read_relations

        relations = _path(spec, f"{where}.relations", entry["relations"], "relations file")
        try:
            read_relations(relations)
        except InputError as e:
            raise _fail(spec, f"{where}.relations", str(e)) from None
    time_offset = entry.get("time_offset", 0.0)
    if not _is_number(time_offset) or not math.isfinite(time_offset):
        raise _fail(spec, f"{where}.time_offset", f"must be a finite number of seconds, not {_shown(time_offset)}")
    if "time_offset" in entry and relations is None:
        raise _fail(spec, f"{where}.time_offset", "only means something with 'relations'")
    args = entry.get("args") or []
    if not isinstance(args, list) or not all(
        isinstance(a, (str, int, float)) and not isinstance(a, bool) for a in args
    ):
        raise _fail(spec, f"{where}.args", f"must be a list of command-line arguments, not {_shown(args)}")
    args = [str(a) for a in args]
    for a in args:
        given = _sweep_option(a)
        if given is not None:
            raise _fail(spec, f"{where}.args", f"{given} is set by the sweep itself")
    return LogSpec(
        name=name,
        path=path,
        joint=joint,
        odometry=odometry,
        ground_truth=gt,
        relations=relations,
        time_offset=float(time_offset),
        args=tuple(args),
        map=map_path,
    )


def _seeds(spec: Path, value: object) -> tuple[int, ...]:
    seeds: Sequence[object]
    if isinstance(value, dict):
        seeds = expand_range(spec, "seeds", value, integer=True)
    elif isinstance(value, list):
        seeds = value
    elif isinstance(value, int) and not isinstance(value, bool):
        seeds = [value]
    else:
        raise _fail(spec, "seeds", f"must be a list of seeds or a range {{from: A, to: B}}, not {_shown(value)}")
    if not seeds:
        raise _fail(spec, "seeds", "no seeds")
    out: list[int] = []
    for s in seeds:
        if not isinstance(s, int) or isinstance(s, bool) or s < 0:
            raise _fail(spec, "seeds", f"a seed must be a non-negative integer, not {_shown(s)}")
        out.append(s)
    if len(set(out)) != len(out):
        raise _fail(spec, "seeds", "a seed is listed twice")
    return tuple(out)


def _config_value(cfg: DataclassInstance, key: str) -> ConfigValue:
    """The value at a dotted ``key`` of ``cfg`` (a setting, not a section) as written in files
    (modes as strings)."""
    from enum import Enum

    *sections, name = key.split(".")
    for part in sections:
        cfg = getattr(cfg, part)
    value = getattr(cfg, name)
    return value.value if isinstance(value, Enum) else value


def config_class(run: str) -> type[SlamConfig] | type[LocalizerConfig]:
    """The configuration a run's settings are keys of: SlamConfig, or LocalizerConfig for
    ``localize`` (its file section is ``pfslam dump-config localize``'s)."""
    from pfslam.config import LocalizerConfig, SlamConfig

    return LocalizerConfig if run == "localize" else SlamConfig


def _other_run_hint(key: str, run: str) -> str:
    """Why ``key``, unknown to ``run``'s config, is: a key of the other run's ("" if not, or
    if ``key`` is one of ``run``'s own)."""
    from pfslam.config import dotted_keys

    other = "slam" if run == "localize" else "localize"
    if key in dotted_keys(config_class(run)(), leaves=True) or key not in dotted_keys(
        config_class(other)(), leaves=True
    ):
        return ""
    if run == "localize":
        return " (a slam setting: a run: localize sweep sets keys of `pfslam dump-config localize`)"
    return " (a localize setting: add 'run: localize' to the spec)"


def _settings(spec: Path, value: object, run: str = "slam") -> dict[str, tuple[ConfigValue, ...]]:
    from pfslam.config import with_values

    if value is None:
        return {}
    if not isinstance(value, dict):
        raise _fail(spec, "settings", f"must be a mapping of config keys to lists of values, not {_shown(value)}")
    out: dict[str, tuple[ConfigValue, ...]] = {}
    base = config_class(run)()
    for key, values in value.items():
        where = f"settings.{key}"
        if not isinstance(key, str):
            raise _fail(spec, "settings", f"a key must be a config key (a string), not {_shown(key)}")
        if key == "seed":
            raise _fail(spec, where, "the seed of each run comes from 'seeds'")
        if isinstance(values, dict):
            values = expand_range(spec, where, values)
        elif not isinstance(values, list):
            values = [values]
        if not values:
            raise _fail(spec, where, "no values")
        canonical: list[ConfigValue] = []
        for v in values:
            try:
                cfg = with_values(base, {key: v})
            except ConfigError as e:
                raise _fail(spec, where, f"{e}{_other_run_hint(key, run)}") from None
            canonical.append(_config_value(cfg, key))
        if len(set(map(repr, canonical))) != len(canonical):
            raise _fail(spec, where, "a value is listed twice")
        out[key] = tuple(canonical)
    return out


def parse_spec(data: object, spec: Path) -> Spec:
    """Validate a spec's YAML data (``spec``: its file, for relative paths and messages)."""
    from pfslam.config import LocalizerConfig, SlamConfig, resolve_filter, with_values

    spec = Path(os.path.normpath(Path(spec).absolute()))
    if not isinstance(data, dict):
        raise InputError(spec, f"a sweep spec is a mapping with {', '.join(SPEC_KEYS)}, not {_shown(data)}")
    unknown = [k for k in data if k not in SPEC_KEYS]
    if unknown:
        hint = _did_you_mean(unknown[0], SPEC_KEYS)
        raise _fail(spec, str(unknown[0]), f"unknown key{hint} (a spec has {', '.join(SPEC_KEYS)})")
    run = data.get("run", "slam")
    if run not in RUNS:
        hint = _did_you_mean(run, RUNS) if isinstance(run, str) else ""
        raise _fail(spec, "run", f"must be {' or '.join(RUNS)}, not {_shown(run)}{hint}")
    logs_data = data.get("logs")
    if not isinstance(logs_data, list) or not logs_data:
        raise _fail(spec, "logs", "needs a list of logs (each with a name and a path)")
    seeds = _seeds(spec, data.get("seeds", [0]))
    logs = tuple(_log_spec(spec, i, entry, seeds, run) for i, entry in enumerate(logs_data))
    names = [log.name for log in logs]
    for n in names:
        if names.count(n) > 1:
            raise _fail(spec, "logs", f"the name {n!r} is used twice")
    settings = _settings(spec, data.get("settings"), run)
    out = Spec(path=spec, logs=logs, seeds=seeds, settings=settings, run=run)
    if out.runs > MAX_RUNS:
        raise _fail(spec, "settings", f"the grid has {out.runs} runs (at most {MAX_RUNS})")
    for combo in out.combinations():  # values valid one by one may still clash, or not reach the filter that runs
        try:
            if run == "localize":
                with_values(LocalizerConfig(), combo)
            else:
                resolve_filter(with_values(SlamConfig(), combo))
        except ConfigError as e:
            raise _fail(spec, "settings", f"{settings_slug(combo)}: {e}") from None
    return out


def load_spec(path: str | Path) -> Spec:
    """Read and validate a spec file; InputError naming the file and the key otherwise."""
    p = Path(path)
    if p.is_dir():
        raise InputError(p, "is a folder, not a sweep spec")
    if not p.is_file():
        raise InputError(p, "sweep spec not found")
    try:
        data = yaml.safe_load(p.read_text(encoding="utf-8"))
    except UnicodeDecodeError as e:
        raise InputError(p, f"not UTF-8 text (byte {e.object[e.start]:#04x} at offset {e.start})") from None
    except yaml.YAMLError as e:
        raise InputError(p, f"not valid YAML ({str(e).splitlines()[0]})") from None
    return parse_spec(data, p)


# -- a setting combination's names ---------------------------------------------------------


def _value_text(v: object) -> str:
    if hasattr(v, "item") and not isinstance(v, (str, bytes)):  # a NumPy scalar from a table
        v = v.item()
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    return str(v)


def settings_text(values: Mapping[str, object]) -> str:
    """``particles=20, local_search.enabled=false`` (``defaults`` without settings)."""
    return ", ".join(f"{k}={_value_text(v)}" for k, v in values.items()) or "defaults"


def settings_slug(values: Mapping[str, object]) -> str:
    """A folder name for a setting combination: ``particles=20,local_search.enabled=false``
    (``default`` without settings); characters unsafe in file names become ``_``."""
    if not values:
        return "default"
    text = ",".join(f"{k}={_value_text(v)}" for k, v in values.items())
    slug = re.sub(r"[^A-Za-z0-9._=,+-]", "_", text)
    if slug != text or len(slug) > 120:  # keep distinct combinations apart after the clean-up
        slug = f"{slug[:100]}~{hashlib.sha1(text.encode()).hexdigest()[:8]}"
    return slug
