"""Systematic resampling kernel and its NumPy twin."""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

from pfslam.types import Array

# --- systematic resampling -----------------------------------------------------------------


@nb.njit(cache=True)
def systematic_kernel(w: Array, u0: float, out: NDArray[np.int64]) -> None:
    """Systematic (low-variance) resampling into ``out``: pointer ``i`` is (u0 + i) / n with
    offset ``u0`` in [0, 1) and n = len(out), and gets the first index whose cumulative weight
    exceeds it (the last index if none does). One walk along the weights, O(N + n), no
    allocation; ``w`` must sum to 1."""
    m = w.shape[0]
    n = out.shape[0]
    inv_n = 1.0 / n
    last = m - 1
    j = 0
    c = w[0]  # cumulative weight up to and including j
    for i in range(n):
        u = (u0 + i) * inv_n
        while j < last and c <= u:
            j += 1
            c += w[j]
        out[i] = j


def systematic_numpy(w: Array, u0: float, out: NDArray[np.int64]) -> None:
    """NumPy twin of :func:`systematic_kernel` (binary search of every pointer)."""
    c = np.cumsum(np.asarray(w, dtype=float))
    c[-1] = 1.0
    u = (u0 + np.arange(len(out))) * (1.0 / len(out))
    np.minimum(np.searchsorted(c, u, side="right"), len(c) - 1, out=out)
