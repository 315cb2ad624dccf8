"""Submaps and the loop search's match: a grid's occupied cells as a score field
exp(-d^2 / 2 sigma^2) with its max-pooled pyramid (:func:`field_of`), and a scan's points
matched into it by branch and bound, then below a cell (:func:`match`, Cartographer's fast
correlative matcher). Used by the loop search (:mod:`pfslam.backend.loops`) and the start
search of a resumed session (:mod:`pfslam.backend.start`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pfslam.geometry import wrap_angle
from pfslam.kernels.bnb import bnb_kernel, field_kernel, pyramid_kernel, refine_kernel

Array = NDArray[np.float64]

MAX_DEPTH = 7  # pyramid levels: the coarsest cell is 64 x 64 fine cells (3.2 m at 0.05 m)
MAX_ROTATIONS = 401  # headings tried per search, whatever the window and the scan's reach


@dataclass
class Submap:
    """A submap's score field in the frame of its first node."""

    field: NDArray[np.float32]
    pyramid: NDArray[np.float32]
    ox: float
    oy: float


def field_of(occ: NDArray[np.bool_], origin: Array, res: float, sigma: float, depth: int) -> Submap | None:
    """The score field exp(-d^2 / 2 sigma^2) of the occupied cells ``occ`` of a grid (its
    lower-left corner at ``origin``), cropped to them, with its max-pooled pyramid; None if
    no cell is occupied."""
    if not occ.any():
        return None
    rows, cols = np.nonzero(occ)
    margin = int(np.ceil(3 * sigma / res)) + 1
    r0, r1 = max(rows.min() - margin, 0), min(rows.max() + margin + 1, occ.shape[0])
    c0, c1 = max(cols.min() - margin, 0), min(cols.max() + margin + 1, occ.shape[1])
    occ = occ[r0:r1, c0:c1]
    sig = sigma / res
    fld = field_kernel(np.ascontiguousarray(occ), sig, int(np.ceil(3 * sig)))
    ox = float(origin[0] + c0 * res)
    oy = float(origin[1] + r0 * res)
    return Submap(fld, pyramid_kernel(fld, depth), ox, oy)


def match(
    sub: Submap,
    pts: NDArray[np.float32],
    guess: Array,
    window_m: float,
    window_deg: float,
    min_score: float,
    res: float,
    coarse: bool = False,
    ambiguity: float = 0.0,
    why: list[str] | None = None,
) -> tuple[Array, float] | None:
    """The pose of a node's points in the submap's frame within ``window_m`` / ``window_deg``
    of ``guess``, by branch and bound then sub-cell refinement; None if the best match scores
    below ``min_score``. The headings are tried a step apart that moves the farthest point by
    at most a cell (``coarse``: two cells, and every other point searched; the refinement
    uses them all). With ``ambiguity`` > 0, a match is refused when another one at least half a
    metre or 5 degrees away scores ``ambiguity`` times as well (and ``"ambiguous"`` appended to
    ``why``)."""
    p = pts.astype(np.float64)
    reach = float(np.hypot(p[:, 0], p[:, 1]).max()) if len(p) else 0.0
    if reach <= 0:
        return None
    step = float(np.arccos(max(1.0 - res**2 / (2.0 * reach**2), -1.0))) * (2 if coarse else 1)
    half = np.deg2rad(window_deg)
    n_side = min(int(np.ceil(half / step)), MAX_ROTATIONS // 2) if half > 0 else 0
    step = half / n_side if n_side else step
    angles = guess[2] + step * np.arange(-n_side, n_side + 1)
    cs, sn = np.cos(angles)[:, None], np.sin(angles)[:, None]
    q = p[::2] if coarse else p
    x = guess[0] + cs * q[None, :, 0] - sn * q[None, :, 1]
    y = guess[1] + sn * q[None, :, 0] + cs * q[None, :, 1]
    cols = np.floor((x - sub.ox) / res).astype(np.int32)
    rows = np.floor((y - sub.oy) / res).astype(np.int32)
    window = int(round(window_m / res))
    depth = min(pyramid_depth(window), sub.pyramid.shape[0])
    score, k, dc, dr = bnb_kernel(sub.pyramid[:depth], cols, rows, window, float(min_score), -1, 0, 0, 0, 0)
    if k < 0:
        return None
    if ambiguity > 0:
        # The best match elsewhere (half a metre or 5 degrees away): a corridor's walls match as
        # well a few metres along it, and a loop taken there would tear the map.
        away = int(round(0.5 / res))
        second = bnb_kernel(
            sub.pyramid[:depth],
            cols,
            rows,
            window,
            ambiguity * score,
            k,
            dc,
            dr,
            away,
            int(np.ceil(np.deg2rad(5.0) / step)) if step > 0 else 0,
        )[0]
        if second >= 0:
            if why is not None:
                why.append("ambiguous")
            return None
    pose = np.array([guess[0] + dc * res, guess[1] + dr * res, angles[k]])
    pose, score = refine_kernel(sub.field, p, pose, sub.ox, sub.oy, res, res / 2, step, 4)
    if score < min_score:
        return None
    pose[2] = wrap_angle(pose[2])
    return pose, float(score)


def pyramid_depth(window: int) -> int:
    """Pyramid levels for a search of +-``window`` cells: the coarsest block about spans it."""
    return int(min(MAX_DEPTH, max(1, np.ceil(np.log2(2 * window + 1)))))
