"""Wall fields: the distance from every cell to the nearest wall, and the smoothed wall map
exp(-d^2 / 2 sigma^2) built on it (SLAM's wide-basin scoring, calibration's scan matching,
localization's likelihood field, the map-agreement check)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import distance_transform_edt

from pfslam.types import Array


def wall_distance(walls: NDArray[np.bool_], resolution: float) -> Array:
    """Distance (m) from every cell to the nearest ``walls`` cell (inf everywhere if none)."""
    if not walls.any():
        return np.full(walls.shape, np.inf)
    return distance_transform_edt(~walls) * resolution


def gaussian_of_distance(d: Array, sigma: float) -> Array:
    """exp(-d^2 / 2 sigma^2): 1 on a wall, falling off over ``sigma`` metres."""
    return np.exp(-0.5 * (d / sigma) ** 2)
