"""Checking a setting's value: integers, finite numbers in bounds, types, the modes' strings.

A config's numeric fields declare their bounds (:func:`bounded`); :func:`check_config`
checks a whole config (modes, types, then every declared bound, also of its sub-configs)."""

from __future__ import annotations

import math
import numbers
import operator
import re
from dataclasses import MISSING, dataclass, field, fields, is_dataclass
from typing import TYPE_CHECKING, TypeGuard, TypeVar, Union

from pfslam.config.choices import Choice
from pfslam.errors import ConfigError

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

T = TypeVar("T")
# The value of one setting as a file writes it: the modes (Enums) as their strings.
ConfigValue = Union[bool, int, float, str]

MAX_PARTICLES = 10_000_000  # about 240 MB of poses per copy: more is a typo, not a filter

# PyYAML reads 1e-3 (no dot) as a string; a float field takes such a number too.
_EXPONENT_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")
_OPS = {">": operator.gt, ">=": operator.ge, "<=": operator.le, "<": operator.lt}


def _shown(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _is_int(value: object) -> TypeGuard[int]:
    """An integer, not a bool (NumPy's integers too: an int to the type checker)."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _is_number(value: object) -> TypeGuard[float]:
    """A real number, not a bool (NumPy's too: a float to the type checker)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def check_int(name: str, value: object, lo: int = 0, hi: int | None = None) -> int:
    """``value`` if it is an integer in ``lo..hi`` (no upper bound if None), else a ConfigError naming ``name``."""
    if not _is_int(value) or value < lo or (hi is not None and value > hi):
        want = (
            "a non-negative integer"
            if lo == 0 and hi is None
            else f"an integer >= {lo}"
            if hi is None
            else f"an integer in {lo}..{hi}"
        )
        raise ConfigError(f"{name} must be {want}, not {_shown(value)}")
    return int(value)


def check_number(
    name: str,
    value: object,
    *,
    gt: float | None = None,
    ge: float | None = None,
    le: float | None = None,
    lt: float | None = None,
    what: str = "a finite number",
) -> float:
    """``value`` as a float if it is a finite number within the bounds given, else a ConfigError
    naming ``name`` (``what`` describes the number, e.g. "a finite number of seconds")."""
    limits = [(op, b) for op, b in ((">", gt), (">=", ge), ("<=", le), ("<", lt)) if b is not None]
    if not (_is_number(value) and math.isfinite(value) and all(_OPS[op](value, b) for op, b in limits)):
        text = " and ".join(f"{op} {b:g}" for op, b in limits)
        raise ConfigError(f"{name} must be {what}{' ' + text if text else ''}, not {_shown(value)}")
    return float(value)


def _check_type(key: str, value: object, want: type) -> None:
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


def check_fields(cfg: DataclassInstance, where: str = "") -> None:
    """Every field of the dataclass ``cfg`` (and of its sub-configs) has the type of its
    default: bools are bools, ints are integers (not bools), floats finite numbers."""
    for f in fields(cfg):
        default = f.default_factory() if f.default is MISSING else f.default  # type: ignore[operator]
        value = getattr(cfg, f.name)
        _check_type(f"{where}{f.name}", value, type(default))
        if is_dataclass(default):
            check_fields(value, f"{where}{f.name}.")


def _read_value(key: str, value: object, want: type) -> object:
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


def _coerce_choices(cfg: DataclassInstance, where: str = "") -> None:
    """Turn the strings given for mode fields (here and in sub-configs) into their Enum,
    or raise a ConfigError naming the key and the choices."""
    for f in fields(cfg):
        default = f.default_factory() if f.default is MISSING else f.default  # type: ignore[operator]
        value = getattr(cfg, f.name)
        if isinstance(default, Choice):
            object.__setattr__(cfg, f.name, _choice(f"{where}{f.name}", value, type(default)))
        elif is_dataclass(default) and is_section(value):
            _coerce_choices(value, f"{where}{f.name}.")


def _choice(key: str, value: object, want: type[Choice]) -> Choice:
    if isinstance(value, str):  # a mode is a string (anything else is no mode's value)
        try:
            return want(value)
        except ValueError:
            pass
    names = ", ".join(repr(m.value) for m in want)
    raise ConfigError(f"{key} must be one of {names}, not {_shown(value)}") from None


def is_section(value: object) -> TypeGuard[DataclassInstance]:
    """Whether a config's field holds a section (a sub-config: a dataclass; a field never holds a class)."""
    return is_dataclass(value)


def _doc(default: T, text: str) -> T:
    """A dataclass field with ``default`` and a note that ``pfslam dump-config`` prints beside it."""
    return field(default=default, metadata={"doc": text})


@dataclass(frozen=True)
class Bounds:
    """The values a numeric field takes (see :func:`bounded`): an integer field ``lo..hi``
    (no upper bound if None), as :func:`check_int` words it; a float field within ``gt``,
    ``ge``, ``le``, ``lt``, as :func:`check_number` words it, naming ``what``."""

    lo: int | None = None
    hi: int | None = None
    gt: float | None = None
    ge: float | None = None
    le: float | None = None
    lt: float | None = None
    what: str = "a finite number"
    unless: float | None = None  # a value let through as it is (-1: per log kind)
    error: str | None = None  # the text raised instead (older messages naming several fields)

    def check(self, key: str, value: object) -> None:
        """Nothing if ``value`` is within the bounds, else a ConfigError naming ``key``."""
        if self.unless is not None and value == self.unless:
            return
        try:
            if self.lo is not None:
                check_int(key, value, self.lo, self.hi)
            else:
                check_number(key, value, gt=self.gt, ge=self.ge, le=self.le, lt=self.lt, what=self.what)
        except ConfigError:
            if self.error is None:
                raise
            raise ConfigError(self.error) from None


def bounded(
    default: T,
    *,
    lo: int | None = None,
    hi: int | None = None,
    gt: float | None = None,
    ge: float | None = None,
    le: float | None = None,
    lt: float | None = None,
    what: str = "a finite number",
    unless: float | None = None,
    error: str | None = None,
    doc: str | None = None,
) -> T:
    """A dataclass field with ``default`` and its :class:`Bounds` (``lo``/``hi`` for an
    integer, ``gt``/``ge``/``le``/``lt`` for a float), which :func:`check_bounds` checks;
    ``doc`` is its note for ``pfslam dump-config`` (as :func:`_doc`)."""
    bounds = Bounds(lo, hi, gt, ge, le, lt, what, unless, error)
    return field(default=default, metadata={"bounds": bounds} if doc is None else {"bounds": bounds, "doc": doc})


def check_bounds(cfg: DataclassInstance, where: str = "") -> None:
    """Every declared bound of the dataclass ``cfg`` and of its sub-configs (whose keys are
    ``section.name``), in field order: a ConfigError for the first value out of bounds."""
    for f in fields(cfg):
        value = getattr(cfg, f.name)
        if is_section(value):
            check_bounds(value, f"{where}{f.name}.")
        elif "bounds" in f.metadata:
            f.metadata["bounds"].check(f"{where}{f.name}", value)


def check_config(cfg: DataclassInstance) -> None:
    """Validate a config built (its ``__post_init__``): the modes' strings become their Enums,
    then every field's type (:func:`check_fields`), then every bound (:func:`check_bounds`)."""
    _coerce_choices(cfg)
    check_fields(cfg)  # ints are integers, floats finite numbers, bools true or false
    check_bounds(cfg)
