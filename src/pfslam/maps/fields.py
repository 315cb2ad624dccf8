"""Wall fields: the distance from every cell to the nearest wall, and the smoothed wall map
exp(-d^2 / 2 sigma^2) built on it (SLAM's wide-basin scoring, calibration's scan matching,
localization's likelihood field, the map-agreement check)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import distance_transform_edt

from pfslam.kernels.bnb import field_kernel, pyramid_kernel
from pfslam.types import Array


def wall_distance(walls: NDArray[np.bool_], resolution: float) -> Array:
    """Distance (m) from every cell to the nearest ``walls`` cell (inf everywhere if none)."""
    if not walls.any():
        return np.full(walls.shape, np.inf)
    return distance_transform_edt(~walls) * resolution


def gaussian_of_distance(d: Array, sigma: float) -> Array:
    """exp(-d^2 / 2 sigma^2): 1 on a wall, falling off over ``sigma`` metres."""
    return np.exp(-0.5 * (d / sigma) ** 2)


def score_field(
    occ: NDArray[np.bool_], origin: Array, res: float, sigma: float, depth: int
) -> tuple[NDArray[np.float32], NDArray[np.float32], float, float] | None:
    """The score field exp(-d^2 / 2 sigma^2) of the occupied cells ``occ`` of a grid (its
    lower-left corner at ``origin``, cells ``res`` wide), cropped to them with a margin of 3
    sigma, its max-pooled pyramid of ``depth`` levels, and the crop's lower-left corner (x, y);
    None if no cell is occupied. What the branch-and-bound searches match scans on."""
    if not occ.any():
        return None
    rows, cols = np.nonzero(occ)
    margin = int(np.ceil(3 * sigma / res)) + 1
    r0, r1 = max(rows.min() - margin, 0), min(rows.max() + margin + 1, occ.shape[0])
    c0, c1 = max(cols.min() - margin, 0), min(cols.max() + margin + 1, occ.shape[1])
    sig = sigma / res
    fld = field_kernel(np.ascontiguousarray(occ[r0:r1, c0:c1]), sig, int(np.ceil(3 * sig)))
    return fld, pyramid_kernel(fld, depth), float(origin[0] + c0 * res), float(origin[1] + r0 * res)
