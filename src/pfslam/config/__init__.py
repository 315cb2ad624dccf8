"""Every setting of pfslam in one place: typed, frozen configurations validated when they
are built, with YAML load/dump. The config used is saved with every result.

- :class:`SlamConfig` (sections ``map``, ``motion``, ``sensor``, ``local_search``),
  :class:`LocalizerConfig` and :class:`CalibrationConfig`;
- modes are Enums (:class:`ResampleMethod`, :class:`PoseEstimate`, :class:`ScoringMap`,
  :class:`SensorModel`) whose values are the strings written in files;
- a configuration file holds one of them at its top level, or several under the section
  names of :data:`SECTIONS` (``slam:``, ``localize:``, ``calibrate:``), as
  ``pfslam dump-config`` prints them;
- :func:`with_values` makes a changed copy (``{"local_search.enabled": True}``), validated
  like a file.
"""

from __future__ import annotations

from pfslam.config.checks import (  # noqa: F401
    _EXPONENT_NUMBER,
    _OPS,
    MAX_PARTICLES,
    Bounds,
    ConfigValue,
    T,
    _check_type,
    _choice,
    _coerce_choices,
    _doc,
    _is_int,
    _is_number,
    _read_value,
    _shown,
    bounded,
    check_bounds,
    check_config,
    check_fields,
    check_int,
    check_number,
    is_section,
)
from pfslam.config.choices import (  # noqa: F401
    Backend,
    Choice,
    OdomModel,
    PoseEstimate,
    ResampleMethod,
    RobustLoss,
    ScoringMap,
    SensorModel,
    SlamFilter,
)
from pfslam.config.files import (  # noqa: F401
    DEGREE_KEYS,
    RENAMED_KEYS,
    SECTION_OF,
    SECTIONS,
    _degrees_to_radians,
    _did_you_mean,
    _read_yaml,
    _with_notes,
    dotted_keys,
    dump_config,
    dump_sections,
    from_dict,
    load_config,
    to_dict,
    with_particle_counts,
    with_values,
)
from pfslam.config.policy import (  # noqa: F401
    DEFAULT_PARTICLES,
    FILTER_KEYS,
    FILTER_NAMES,
    SHARED_KEYS,
    TWINS,
    WHEELED_MATCH_PRIOR,
    _changed_keys,
    foreign_settings,
    resolve_filter,
)
from pfslam.config.settings import (  # noqa: F401
    CalibrationConfig,
    GraphConfig,
    LocalizerConfig,
    LocalSearchConfig,
    MapConfig,
    MotionConfig,
    RbpfConfig,
    SensorConfig,
    SlamConfig,
)
from pfslam.errors import ConfigError, InputError  # noqa: F401 (re-exported)

__all__ = [
    "Backend",
    "Bounds",
    "CalibrationConfig",
    "Choice",
    "ConfigError",
    "DEFAULT_PARTICLES",
    "DEGREE_KEYS",
    "FILTER_KEYS",
    "FILTER_NAMES",
    "GraphConfig",
    "LocalSearchConfig",
    "LocalizerConfig",
    "MAX_PARTICLES",
    "MapConfig",
    "MotionConfig",
    "OdomModel",
    "PoseEstimate",
    "RENAMED_KEYS",
    "RbpfConfig",
    "ResampleMethod",
    "RobustLoss",
    "SECTIONS",
    "SECTION_OF",
    "SHARED_KEYS",
    "ScoringMap",
    "SensorConfig",
    "SensorModel",
    "SlamConfig",
    "SlamFilter",
    "T",
    "TWINS",
    "WHEELED_MATCH_PRIOR",
    "bounded",
    "check_bounds",
    "check_config",
    "check_fields",
    "check_int",
    "check_number",
    "dotted_keys",
    "dump_config",
    "dump_sections",
    "foreign_settings",
    "from_dict",
    "load_config",
    "resolve_filter",
    "to_dict",
    "with_particle_counts",
    "with_values",
]
