"""The weight of the improved proposal (Grisetti, Stachniss and Burgard 2007): a particle
matched to its map is weighed by the integral of the scan's likelihood under the odometry's
Gaussian, not by the likelihood at its match alone. With the likelihood read as a Gaussian
about the match ``m`` of information ``A`` (what the scan pins: large across walls, next to
nothing along a bare corridor), ``L(x) ≈ L(m) exp(-½ (x - m)ᵀ A (x - m))``, and the
odometry's prediction ``p`` of information ``B``, the integral is

    log η = log L(m) - ½ log |A + B| + ½ log |B| - ½ dᵀ A (A + B)⁻¹ B d,   d = m - p.

So a match that moved far from the odometry in a direction the scan pins is weighed down,
one that slid along a direction it does not pin is not, and a sharp match is not rewarded
for its sharpness alone.
"""

from __future__ import annotations

import numpy as np

from pfslam.geometry import wrap_angle
from pfslam.types import Array

_FLOOR = np.diag([1e-6, 1e-6, 1e-6])  # a hair of information, against a singular sum


def normaliser(matched: Array, predicted: Array, info: Array, odom_sigmas: tuple[float, float]) -> Array:
    """``log η - log L(m)`` (see the module notes) for each particle: its match ``matched``
    (n, 3) of information ``info`` (n, 3, 3, per m² and rad²), the odometry's prediction
    ``predicted`` (n, 3) with standard deviations ``odom_sigmas`` (x/y m, theta rad)."""
    sxy, sth = odom_sigmas
    b = np.diag([1.0 / sxy**2, 1.0 / sxy**2, 1.0 / sth**2])
    d = matched - predicted
    d[:, 2] = wrap_angle(d[:, 2])
    total = info + b + _FLOOR
    toward = np.linalg.solve(total, b @ d[:, :, None])[:, :, 0]  # (A + B)⁻¹ B d
    quad = np.einsum("ni,nij,nj->n", d, info, toward)
    return -0.5 * np.linalg.slogdet(total)[1] + 0.5 * float(np.linalg.slogdet(b)[1]) - 0.5 * quad
