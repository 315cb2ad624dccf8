"""Which filter runs and with what: the per-log-kind settings made concrete (resolve_filter),
the particle counts per filter, the settings a filter does not read."""

from __future__ import annotations

from dataclasses import fields, replace
from typing import TYPE_CHECKING

from pfslam.config.checks import is_section
from pfslam.config.choices import Backend, SlamFilter
from pfslam.config.settings import GraphConfig, SlamConfig
from pfslam.errors import ConfigError

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

# The odometry prior's weight in the Rao-Blackwellized filter's match on wheeled logs
# (rbpf.match_prior: -1). Measured on Intel and FR079 with synthetic odometry, filter seeds
# 0-4, and on the Mines rover (see RbpfConfig.match_prior and the README).
WHEELED_MATCH_PRIOR = 0.1
# How far the Rao-Blackwellized filter maps a beam (rbpf.map_range: -1): a wheeled robot's level
# laser, and a THOR head's (or a log of unknown kind). See RbpfConfig.map_range.
WHEELED_MAP_RANGE = 40.0
THOR_MAP_RANGE = 20.0
# Particles per filter where ``particles`` is 0: the single-map filter's are poses on one
# map; each of the Rao-Blackwellized filter's carries a map of its own.
DEFAULT_PARTICLES = {SlamFilter.SINGLE: 100, SlamFilter.RBPF: 30}
# Settings only one filter reads (dotted keys; a section's name: all of it but the keys in
# SHARED_KEYS), with the other filter's twin where it has one.
FILTER_KEYS: dict[SlamFilter, tuple[str, ...]] = {
    SlamFilter.SINGLE: ("estimate", "motion", "sensor", "local_search"),
    SlamFilter.RBPF: ("rbpf",),
}
SHARED_KEYS = ("motion.axle", "sensor.ground_z", "local_search.enabled")
TWINS = {
    "sensor.temperature": "rbpf.temperature",
    "sensor.max_hits": "rbpf.match_hits",
    "motion.sigma_x": "rbpf.noise_xy_per_m",
    "motion.sigma_y": "rbpf.noise_xy_per_m",
    "motion.sigma_theta_deg": "rbpf.noise_theta_per_rad",
}
FILTER_NAMES = {SlamFilter.SINGLE: "the single-map filter", SlamFilter.RBPF: "the Rao-Blackwellized filter"}


def _changed_keys(cfg: DataclassInstance, default: DataclassInstance, where: str = "") -> list[str]:
    """The dotted keys where ``cfg`` differs from ``default``."""
    out: list[str] = []
    for f in fields(cfg):
        a, b = getattr(cfg, f.name), getattr(default, f.name)
        if is_section(a):
            out += _changed_keys(a, b, f"{where}{f.name}.")
        elif a != b:
            out.append(f"{where}{f.name}")
    return out


def foreign_settings(config: SlamConfig) -> list[str]:
    """The settings given (different from the defaults) that the filter of ``config`` (single
    or rbpf) does not read."""
    other = SlamFilter.RBPF if config.filter == SlamFilter.SINGLE else SlamFilter.SINGLE
    owned = FILTER_KEYS[other]
    return [
        k
        for k in _changed_keys(config, SlamConfig())
        if k not in SHARED_KEYS and any(k == o or k.startswith(o + ".") for o in owned)
    ]


def resolve_filter(config: SlamConfig, log_format: str | None = None) -> SlamConfig:
    """``config`` with its open settings made concrete for a log of ``log_format`` (what
    :func:`pfslam.io.logs.load_log` reports; None: not known), as ``pfslam slam`` runs it:

    * ``filter: auto`` becomes the Rao-Blackwellized filter, which measures best on every
      kind of log we have: it closes the THOR office loop on every seed where the single-map
      filter missed 3 of 20; on Intel and FR079 (synthetic odometry, seeds 0-4) it is more
      accurate on 9 of 10 runs and, with its parallel map update, as fast or faster where
      it counts (Intel 106 scans/s against 76); on the Mines rover its map agrees better
      (0.533 against 0.507). The local search is the single-map filter's: asked for, it
      picks that filter.
    * ``particles: 0`` becomes the filter's own count (:data:`DEFAULT_PARTICLES`).
    * ``rbpf.match_prior: -1`` becomes :data:`WHEELED_MATCH_PRIOR` on wheeled logs (it stops
      the first matches sliding along corridors while the robot turns in place) and 0 on
      THOR logs (where it holds back real corrections) or when the kind is not known (for
      the Rao-Blackwellized filter; the single-map filter's config keeps it open).
    * ``rbpf.map_range: -1`` becomes :data:`WHEELED_MAP_RANGE` on wheeled logs and
      :data:`THOR_MAP_RANGE` on THOR logs or when the kind is not known (likewise).

    A concrete choice is kept. A setting given (different from its default) that the filter
    which runs does not read is a ConfigError naming it and, where there is one, its twin:
    a file's ``sensor.temperature`` must not silently do nothing under the other filter."""
    config = _chosen(config)
    _check_read(config)
    if config.particles == 0:
        config = replace(config, particles=DEFAULT_PARTICLES[config.filter])
    thor = log_format is not None and log_format.startswith("thor")
    if config.filter == SlamFilter.RBPF and config.rbpf.match_prior == -1.0:
        prior = 0.0 if thor or log_format is None else WHEELED_MATCH_PRIOR
        config = replace(config, rbpf=replace(config.rbpf, match_prior=prior))
    if config.filter == SlamFilter.RBPF and config.rbpf.map_range == -1.0:
        reach = THOR_MAP_RANGE if thor or log_format is None else WHEELED_MAP_RANGE
        config = replace(config, rbpf=replace(config.rbpf, map_range=reach))
    return config


def _chosen(config: SlamConfig) -> SlamConfig:
    """``config`` with ``filter: auto`` made the filter that runs."""
    if config.filter == SlamFilter.AUTO:
        return replace(config, filter=SlamFilter.SINGLE if config.local_search.enabled else SlamFilter.RBPF)
    return config


def _check_read(config: SlamConfig) -> None:
    """A ConfigError for a setting given that the filter which runs does not read (see
    :func:`resolve_filter`)."""
    foreign = foreign_settings(config)
    if foreign:
        key, runs = foreign[0], FILTER_NAMES[config.filter]
        twins = {**{b: a for a, b in TWINS.items()}, **TWINS}
        twin = f" (its twin there is {twins[key]})" if key in twins else ""
        other = "single" if config.filter == SlamFilter.RBPF else "rbpf"
        raise ConfigError(f"{key} is not read by {runs}, the filter that runs{twin}; remove it, or set filter: {other}")
    if config.backend == Backend.NONE and (unread := _changed_keys(config.graph, GraphConfig(), "graph.")):
        raise ConfigError(f"{unread[0]} is not read with backend: none; remove it, or set backend: graph")


def check_settings(config: SlamConfig) -> None:
    """A ConfigError if ``config`` gives a setting the filter that runs would not read: the
    check :func:`resolve_filter` makes, before the log (and so its kind) is known."""
    _check_read(_chosen(config))


def is_concrete(config: SlamConfig) -> bool:
    """Whether ``config`` is as :func:`resolve_filter` leaves it: the filter chosen, its
    particle count set and, for the Rao-Blackwellized filter, its match prior and map range."""
    return (
        config.filter != SlamFilter.AUTO
        and config.particles != 0
        and not (config.filter == SlamFilter.RBPF and -1.0 in (config.rbpf.match_prior, config.rbpf.map_range))
    )


def for_filter(config: SlamConfig | None, slam_filter: SlamFilter) -> SlamConfig:
    """``config`` (None: the defaults) as ``slam_filter`` runs it: kept when it is that
    filter's and concrete (as the commands pass it), else made so for an unknown log kind."""
    c = config if config is not None else SlamConfig()
    if c.filter == slam_filter and is_concrete(c):
        return c
    return resolve_filter(replace(c, filter=slam_filter))
