"""The 3 x 3 linear solve of the kernels' Gauss-Newton steps (x, y, theta), by cofactors:
``np.linalg.solve`` in a kernel costs a first run about 10 s of compiling (LAPACK's wrapper
and its error messages) for a system this small."""

from __future__ import annotations

import numba as nb
import numpy as np

from pfslam.types import Array


@nb.njit(cache=True)
def solve3(a: Array, b: Array) -> Array:
    """``x`` with ``a @ x = b`` for a 3 x 3 ``a`` (nonsingular; the callers damp theirs)."""
    c00 = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    c01 = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    c02 = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    det = a[0, 0] * c00 + a[0, 1] * c01 + a[0, 2] * c02
    inv = np.empty((3, 3))
    inv[0, 0] = c00
    inv[1, 0] = c01
    inv[2, 0] = c02
    inv[0, 1] = a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]
    inv[1, 1] = a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]
    inv[2, 1] = a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]
    inv[0, 2] = a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]
    inv[1, 2] = a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]
    inv[2, 2] = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    x = np.empty(3)
    for i in range(3):
        x[i] = (inv[i, 0] * b[0] + inv[i, 1] * b[1] + inv[i, 2] * b[2]) / det
    return x
