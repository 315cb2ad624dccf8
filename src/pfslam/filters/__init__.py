"""The filters, behind one interface (:class:`~pfslam.filters.base.Filter`), no I/O:

- :mod:`~pfslam.filters.single`: SLAM with one map updated from the estimate;
- :mod:`~pfslam.filters.rbpf`: the Rao-Blackwellized filter, a map per particle;
- :mod:`~pfslam.filters.localize`: Monte Carlo localization on a known map;
- :mod:`~pfslam.filters.predict`: what they share (the prediction, the start, motion counters).

The names below are imported when first used, so importing one filter loads no other (the
localizer's SciPy statistics stay out of a SLAM run).

May import: maps, kernels, config, frames, geometry, particles, motion, sensor, errors.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

_EXPORTS = {
    "Filter": "pfslam.filters.base",
    "Localizer": "pfslam.filters.localize",
    "RaoBlackwellizedSlam": "pfslam.filters.rbpf",
    "SingleMapSlam": "pfslam.filters.single",
}
__all__ = list(_EXPORTS)


def __getattr__(name: str) -> object:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'pfslam.filters' has no attribute {name!r}")
    return getattr(importlib.import_module(_EXPORTS[name]), name)


if TYPE_CHECKING:  # for type checkers and editors: the same names, imported eagerly
    from pfslam.filters.base import Filter as Filter
    from pfslam.filters.localize import Localizer as Localizer
    from pfslam.filters.rbpf import RaoBlackwellizedSlam as RaoBlackwellizedSlam
    from pfslam.filters.single import SingleMapSlam as SingleMapSlam
