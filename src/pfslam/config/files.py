"""Configurations as dicts and YAML: read (old keys renamed, misspelt ones named), changed
copies (with_values), dumped with their notes; the sections of a file."""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Mapping
from dataclasses import fields, is_dataclass
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, cast

import yaml

from pfslam.config.checks import T, _choice, _read_value, _shown, check_number, is_section
from pfslam.config.choices import Choice
from pfslam.config.settings import CalibrationConfig, LocalizerConfig, SlamConfig
from pfslam.errors import ConfigError, InputError

if TYPE_CHECKING:
    from _typeshed import DataclassInstance


def to_dict(cfg: DataclassInstance) -> dict[str, object]:
    """The config as plain nested dicts (modes as their strings)."""
    out: dict[str, object] = {}
    for f in fields(cfg):
        v = getattr(cfg, f.name)
        out[f.name] = to_dict(v) if is_section(v) else v.value if isinstance(v, Enum) else v
    return out


def dotted_keys(cfg: DataclassInstance, where: str = "", leaves: bool = False) -> list[str]:
    """Every key of the dataclass ``cfg`` as written in files and in :func:`with_values`:
    ``particles``, ``map``, ``map.resolution``, ... (with ``leaves``: not the sections')."""
    out: list[str] = []
    for f in fields(cfg):
        value = getattr(cfg, f.name)
        if is_section(value):
            if not leaves:
                out.append(f"{where}{f.name}")
            out += dotted_keys(value, f"{where}{f.name}.", leaves)
        else:
            out.append(f"{where}{f.name}")
    return out


def _did_you_mean(key: str, known: list[str], extra: list[str] | None = None, where: str = "") -> str:
    """The hint " (did you mean 'X'?)" for an unknown ``key`` (under ``where``, a section's
    "name."), or "": the closest of ``known`` (dotted keys below ``where``) and ``extra``,
    compared whole and by its last part, so that a key put in the wrong section is found too."""
    names = [*known, *(extra or [])]
    close = difflib.get_close_matches(key, names, n=1, cutoff=0.75)
    if not close:  # the right name in the wrong place (``resolution`` for ``map.resolution``)
        leaf = key.rsplit(".", 1)[-1]
        by_leaf: dict[str, str] = {}
        for name in names:
            by_leaf.setdefault(name.rsplit(".", 1)[-1], name)
        close = [by_leaf[m] for m in difflib.get_close_matches(leaf, list(by_leaf), n=1, cutoff=0.75)]
    return f" (did you mean '{where}{close[0]}'?)" if close else ""


def from_dict(cls: type[T], data: object, where: str = "") -> T:
    """Build a dataclass from a nested dict (a file's, checked here: anything else is an error);
    unknown keys and values of the wrong type are an error."""
    if not isinstance(data, dict):
        what = f"section '{where.rstrip('.')}'" if where else "config"
        raise ConfigError(f"{what} must be a mapping of keys to values, not {_shown(data)}")
    known = {f.name: f for f in fields(cls)}  # type: ignore[arg-type]
    if cls in DEGREE_KEYS:
        data = _degrees_to_radians(data, DEGREE_KEYS[cls], where)
    kwargs: dict[str, object] = {}
    defaults = cast("DataclassInstance", cls())  # a config class (T is any type for its callers)
    for key, value in data.items():
        if key not in known:
            head, _, rest = f"{where}{key}".partition(".")  # under a section: its keys are the section's
            renamed = RENAMED_KEYS.get(f"{where}{key}") or (RENAMED_KEYS.get(rest) if head in SECTIONS else None)
            if renamed:
                hint = f" (renamed to '{renamed}')"
            elif not where and key in SECTIONS:
                hint = " (a section: a file with sections has nothing else at its top level)"
            else:
                # A flat file's top level may also have meant a section (``slma:``).
                extra = list(SECTIONS) if not where else []
                hint = _did_you_mean(str(key), dotted_keys(defaults), extra, where)
            raise ConfigError(f"unknown config key '{where}{key}'{hint}")
        current = getattr(defaults, key)
        if is_dataclass(current):
            kwargs[key] = from_dict(type(current), value, f"{where}{key}.")
        elif isinstance(current, Choice):
            kwargs[key] = _choice(f"{where}{key}", value, type(current))
        else:
            try:
                kwargs[key] = _read_value(f"{where}{key}", value, type(current))
            except OverflowError:
                raise ConfigError(f"{where}{key}: {_shown(value)} is out of range") from None
    return cls(**kwargs)


def _degrees_to_radians(data: Mapping[str, object], old_keys: dict[str, str], where: str) -> dict[str, object]:
    """``data`` with the older degree keys in ``old_keys`` (old -> new name) replaced by their
    radian successors, in place; ConfigError naming both if a file gives both, or naming the
    old key for a value that is not a number of degrees >= 0 (every such angle is)."""
    out: dict[str, object] = {}
    for key, value in data.items():
        new = old_keys.get(key)
        if new is None:
            out[key] = value
            continue
        if new in data:
            raise ConfigError(
                f"{where}{key} (degrees) and {where}{new} (radians) are the same setting: give only {where}{new}"
            )
        out[new] = math.radians(
            check_number(
                f"{where}{key}", _read_value(f"{where}{key}", value, float), ge=0.0, what="a finite number of degrees"
            )
        )
    return out


def with_values(cfg: T, values: Mapping[str, object]) -> T:
    """A copy of ``cfg`` with ``values`` (dotted keys for sections: ``"map.resolution"``)
    set, read and validated as a file's values are; ConfigError naming a bad key."""
    config = cast("DataclassInstance", cfg)  # a config (T is any type for its callers)
    data = to_dict(config)
    for key, value in values.items():
        *path, last = key.split(".")
        node = data
        for part in path:
            section = node.get(part)
            if not isinstance(section, dict):
                raise ConfigError(f"unknown config key '{key}'{_did_you_mean(key, dotted_keys(config, leaves=True))}")
            node = section
        if last not in node or isinstance(node[last], dict):
            raise ConfigError(f"unknown config key '{key}'{_did_you_mean(key, dotted_keys(config, leaves=True))}")
        node[last] = value.value if isinstance(value, Enum) else value
    return from_dict(type(cfg), data)


def with_particle_counts(
    cfg: LocalizerConfig,
    particles: int | None,
    max_particles: int | None,
) -> LocalizerConfig:
    """``cfg`` with the initial and the largest particle count changed (None: unchanged), the
    other counts following them (``min_particles`` at most either, ``global_particles`` at
    least the largest). ConfigError naming the option for a count below 1, or for an
    initial count above the largest when KLD-sampling keeps the count within it."""
    for name, v in (("--particles", particles), ("--max-particles", max_particles)):
        if v is not None and v < 1:
            raise ConfigError(f"{name} must be at least 1, not {v}")
    if particles is not None and max_particles is not None and particles > max_particles and cfg.kld:
        raise ConfigError(
            f"--particles {particles} is more than --max-particles {max_particles} "
            "(KLD-sampling keeps the count within it; --no-kld fixes the count)"
        )
    values: dict[str, int] = {}
    min_particles = cfg.min_particles
    if particles is not None:
        values["particles"] = particles
        min_particles = min(min_particles, particles)
    if max_particles is not None:
        values["max_particles"] = max_particles
        min_particles = min(min_particles, max_particles)
        values["global_particles"] = max(cfg.global_particles, max_particles)
    return with_values(cfg, {**values, "min_particles": min_particles}) if values else cfg


def _read_yaml(p: Path) -> object:
    if p.is_dir():
        raise InputError(p, "is a folder, not a config file")
    if not p.is_file():
        raise InputError(p, "config file not found")
    try:
        return yaml.safe_load(p.read_text(encoding="utf-8")) or {}
    except UnicodeDecodeError as e:
        raise InputError(p, f"not UTF-8 text (byte {e.object[e.start]:#04x} at offset {e.start})") from None
    except yaml.YAMLError as e:
        raise InputError(p, f"not valid YAML ({str(e).splitlines()[0]})") from None


def load_config(path: str | Path, cls: type[T] = SlamConfig, section_only: bool = False) -> T:  # type: ignore[assignment]
    """The ``cls`` configuration in the file ``path``: its section (see :data:`SECTIONS`) if
    the file has sections, else the whole file (with ``section_only``: the defaults); the
    defaults where the file is silent. A bad key or value is an InputError naming the file
    and the key."""
    p = Path(path)
    data = _read_yaml(p)
    try:
        if isinstance(data, dict) and data and set(data) <= set(SECTIONS):
            name = SECTION_OF[cls]
            return from_dict(cls, data.get(name) or {}, f"{name}.")
        if section_only:
            return cls()
        return from_dict(cls, data)
    except ConfigError as e:
        raise InputError(p, str(e)) from None


def _with_notes(text: str, cfg: DataclassInstance, indent: str) -> str:
    """``text`` (YAML of ``cfg`` alone, its keys at ``indent``) with each field's note (its
    ``doc`` metadata, also of the sub-configs' fields) as a comment at the end of its line,
    the comments aligned."""
    notes = {f.name: f.metadata["doc"] for f in fields(cfg) if "doc" in f.metadata}
    for f in fields(cfg):
        sub = getattr(cfg, f.name)
        if is_section(sub):
            notes.update({f"{f.name}.{g.name}": g.metadata["doc"] for g in fields(sub) if "doc" in g.metadata})
    if not notes:
        return text
    lines = text.splitlines()
    keyed = re.compile(rf"({re.escape(indent)}(?:  )?)(\w+):( |$)")
    width = max(len(ln) for ln in lines) + 2
    out = []
    section = ""
    for ln in lines:
        m = keyed.match(ln)
        note = None
        if m and m.group(1) == indent:
            section = m.group(2)
            note = notes.get(section)
        elif m:
            note = notes.get(f"{section}.{m.group(2)}")
        out.append(f"{ln.ljust(width)}# {note}" if note else ln)
    return "\n".join(out) + "\n"


def dump_config(cfg: DataclassInstance) -> str:
    """One configuration as YAML (its fields' notes as comments)."""
    return _with_notes(yaml.safe_dump(to_dict(cfg), sort_keys=False), cfg, "")


def dump_sections(*cfgs: DataclassInstance) -> str:
    """Several configurations as one YAML file, each under its section name (fields' notes
    as comments)."""
    return "".join(
        _with_notes(yaml.safe_dump({SECTION_OF[type(c)]: to_dict(c)}, sort_keys=False), c, "  ") for c in cfgs
    )


SECTIONS: dict[str, type] = {"slam": SlamConfig, "localize": LocalizerConfig, "calibrate": CalibrationConfig}
SECTION_OF: dict[type, str] = {v: k for k, v in SECTIONS.items()}
# Keys a config file may still carry from earlier versions, with their new names.
RENAMED_KEYS = {"search": "local_search", "sensor.score": "sensor.scoring_map", "rbpf.particles": "particles"}
# Keys in degrees that older files may carry (old -> new name), read as degrees and
# converted to their radian successors; a file giving both is an error.
DEGREE_KEYS: dict[type, dict[str, str]] = {
    LocalizerConfig: {"update_min_a_deg": "update_min_a", "kld_bin_deg": "kld_bin_a"},
}
