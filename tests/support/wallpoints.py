"""Walls as dense points: what a perfect scan of a few segments would hit, for tests of scan
matching on a known surface."""

from __future__ import annotations

import numpy as np


def walls(segments: list[tuple[float, float, float, float]], step: float = 0.01) -> np.ndarray:
    """Points every ``step`` (m) along each segment ``(x0, y0, x1, y1)``, both ends included, (N, 2)."""
    out = []
    for x0, y0, x1, y1 in segments:
        n = max(2, int(np.hypot(x1 - x0, y1 - y0) / step))
        a = np.linspace(0.0, 1.0, n)
        out.append(np.column_stack([x0 + a * (x1 - x0), y0 + a * (y1 - y0)]))
    return np.vstack(out)
