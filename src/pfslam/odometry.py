"""Synthetic odometry for logs whose poses are already corrected (reference trajectories).

The filter must never see the reference poses. Instead it gets odometry that drifts like
a wheeled robot's, derived from the reference motion with a seeded error model:

- a per-run translation scale error ``s ~ N(1, scale_sigma)``;
- a heading bias of ``b`` rad per metre travelled, ``|b| = heading_bias_deg_per_m``
  times ``(1 + N(0, heading_bias_sigma))``, of random sign (a wheel-radius mismatch);
- white noise proportional to the motion: ``trans_noise`` m per metre on x and y,
  ``rot_noise_per_m`` deg per metre and ``rot_noise_per_rad`` rad per rad turned on theta.

Increments ``u_i = ref_{i-1} ⊖ ref_i`` become ``(s·u_x + n_x, s·u_y + n_y, u_θ + b·d + n_θ)``
with ``d = |u_xy|``, and are chained from the reference's first pose. A robot standing
still gets no error at all.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from pfslam.geometry import compose, relative

Array = NDArray[np.float64]


@dataclass
class DriftModel:
    scale_sigma: float = 0.02
    heading_bias_deg_per_m: float = 0.25
    heading_bias_sigma: float = 0.3
    trans_noise: float = 0.02
    rot_noise_per_m: float = 0.5
    rot_noise_per_rad: float = 0.05

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def synthetic_odometry(reference: Array, seed: int = 0, model: DriftModel | None = None) -> Array:
    """Drifting odometry (N, 3) from a reference trajectory (N, 3), seeded."""
    m = model or DriftModel()
    ref = np.asarray(reference, dtype=float)
    rng = np.random.default_rng(seed)
    scale = 1.0 + rng.normal(0.0, m.scale_sigma)
    sign = rng.choice([-1.0, 1.0])
    bias = sign * np.deg2rad(m.heading_bias_deg_per_m) * (1.0 + rng.normal(0.0, m.heading_bias_sigma))
    u = relative(ref[:-1], ref[1:])
    d = np.hypot(u[:, 0], u[:, 1])
    rot = np.abs(u[:, 2])
    noise = rng.normal(size=u.shape)
    v = np.empty_like(u)
    v[:, 0] = scale * u[:, 0] + noise[:, 0] * m.trans_noise * d
    v[:, 1] = scale * u[:, 1] + noise[:, 1] * m.trans_noise * d
    v[:, 2] = u[:, 2] + bias * d + noise[:, 2] * (np.deg2rad(m.rot_noise_per_m) * d + m.rot_noise_per_rad * rot)
    out = np.empty_like(ref)
    out[0] = ref[0]
    for i in range(len(v)):
        out[i + 1] = compose(out[i], v[i])
    return out


def parse_odometry_option(text: str) -> tuple[str, int]:
    """``"log"`` → ("log", 0); ``"synthetic"`` → ("synthetic", 0); ``"synthetic:7"`` → ("synthetic", 7)."""
    s = text.strip().lower()
    if s == "log":
        return "log", 0
    if s == "synthetic":
        return "synthetic", 0
    if s.startswith("synthetic:"):
        try:
            return "synthetic", int(s.split(":", 1)[1])
        except ValueError:
            pass
    raise ValueError(f"--odometry must be 'log', 'synthetic' or 'synthetic:SEED', not {text!r}")
