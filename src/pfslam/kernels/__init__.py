"""The hot loops as Numba kernels (``cache=True``), each with a plain NumPy twin that the
tests compare it with, grouped by what they serve:

- :mod:`~pfslam.kernels.raycast`: the map update (exact ray traversal, log-odds);
- :mod:`~pfslam.kernels.project`: points to grid cells in float32 (shared by the next two);
- :mod:`~pfslam.kernels.scoring`: SLAM's correlation scoring and local x/y/theta search;
- :mod:`~pfslam.kernels.likelihood`: localization's likelihood field and beam model;
- :mod:`~pfslam.kernels.resample`: systematic resampling.

A filter takes a :class:`Kernels` set (``NUMBA`` by default, ``NUMPY`` for the twins), so
the backend is chosen by what is passed in, never by patching an object.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from numpy.typing import NDArray

from pfslam.kernels.likelihood import (
    beam_kernel,
    beam_numpy,
    likelihood_kernel,
    likelihood_numpy,
)
from pfslam.kernels.raycast import ray_update_kernel, ray_update_numpy
from pfslam.kernels.scoring import (
    correlation_kernel,
    correlation_numpy,
    local_search_kernel,
    local_search_numpy,
)
from pfslam.types import Array

ScoreKernel = Callable[..., Array]  # one score (or log-likelihood) per pose: correlation, likelihood, beam
# the local search: the best score per pose and the x, y, theta steps that reach it
SearchKernel = Callable[..., tuple[Array, NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]]
RayKernel = Callable[..., None]  # the map update, in place


@dataclass(frozen=True)
class Kernels:
    """One implementation of every kernel the filters call."""

    name: str
    correlation: ScoreKernel
    local_search: SearchKernel
    ray_update: RayKernel
    likelihood: ScoreKernel
    beam: ScoreKernel


NUMBA = Kernels(
    "numba",
    correlation_kernel,
    local_search_kernel,
    ray_update_kernel,
    likelihood_kernel,
    beam_kernel,
)
NUMPY = Kernels("numpy", correlation_numpy, local_search_numpy, ray_update_numpy, likelihood_numpy, beam_numpy)
KERNEL_SETS = {k.name: k for k in (NUMBA, NUMPY)}


def kernels_for(kind: str | Kernels) -> Kernels:
    """The kernel set named ``kind`` ("numba" or "numpy"), or ``kind`` itself."""
    if isinstance(kind, Kernels):
        return kind
    try:
        return KERNEL_SETS[kind]
    except KeyError:
        raise ValueError(f"kernels must be one of {sorted(KERNEL_SETS)}, not {kind!r}") from None
