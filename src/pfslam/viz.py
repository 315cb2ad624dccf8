"""Figures: the map with trajectories, a legend and a scale bar."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Rectangle  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from pfslam.grid import OccupancyGrid  # noqa: E402


def _nice_length(span: float) -> float:
    """A round scale-bar length of about a fifth of ``span``."""
    target = max(span / 5.0, 1e-3)
    base = 10 ** np.floor(np.log10(target))
    for m in (5, 2, 1):
        if m * base <= target:
            return float(m * base)
    return float(base)


MAX_IMAGE_CELLS = 2048  # the map image's longest side; larger maps are pooled into blocks


def _map_image(grid: OccupancyGrid) -> tuple[NDArray[np.float64], tuple[float, float, float, float],
                                              NDArray[np.intp], NDArray[np.intp]]:
    """The map as a grey image (0 occupied ... 1 free, 0.8 unknown) cropped to its observed
    cells, its extent in metres, and the observed rows and columns. A map wider than
    ``MAX_IMAGE_CELLS`` is pooled into blocks that each show their most occupied cell, so
    walls stay visible and a map of 10^8 cells is drawn without an image of that size."""
    lo = grid.logodds
    known = lo != 0
    rows = np.nonzero(known.any(axis=1))[0]
    cols = np.nonzero(known.any(axis=0))[0]
    del known
    res = grid.resolution
    ox, oy = float(grid.origin[0]), float(grid.origin[1])
    if not len(rows):
        return (np.full(lo.shape, 0.8), (ox, ox + lo.shape[1] * res, oy, oy + lo.shape[0] * res), rows, cols)
    r0, r1, c0, c1 = int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
    crop = lo[r0:r1, c0:c1]
    k = -(-max(crop.shape) // MAX_IMAGE_CELLS)
    if k > 1:  # max log-odds per block: occupied over unknown (0) over free
        crop = np.maximum.reduceat(np.maximum.reduceat(crop, np.arange(0, crop.shape[0], k), axis=0),
                                   np.arange(0, crop.shape[1], k), axis=1)
    crop = crop.astype(float)
    img = np.where(crop == 0, 0.8, 1.0 - 1.0 / (1.0 + np.exp(-np.clip(crop, -50, 50))))
    extent = (ox + c0 * res, ox + (c0 + crop.shape[1] * k) * res, oy + r0 * res, oy + (r0 + crop.shape[0] * k) * res)
    return img, extent, rows, cols


def plot_map(
    grid: OccupancyGrid,
    path: str | Path,
    trajectories: Sequence[tuple[str, NDArray[np.float64], str]] = (),
    title: str = "",
    extra: callable | None = None,  # type: ignore[valid-type]
) -> None:
    """Save the map (white free, black occupied, grey unknown) with labelled trajectories.

    ``trajectories`` holds (label, (N, 3) poses, colour) triples.
    """
    img, extent, rows, cols = _map_image(grid)
    res = grid.resolution
    ox, oy = float(grid.origin[0]), float(grid.origin[1])
    fig, ax = plt.subplots(figsize=(9, 8), dpi=110)
    ax.set_facecolor("0.8")  # unknown, like the map's unobserved cells
    ax.imshow(img, cmap="gray", vmin=0, vmax=1, origin="lower", extent=extent, interpolation="nearest")
    xs: list[NDArray[np.float64]] = []
    ys: list[NDArray[np.float64]] = []
    if len(rows):
        xs.append(np.array([ox + cols[0] * res, ox + (cols[-1] + 1) * res]))
        ys.append(np.array([oy + rows[0] * res, oy + (rows[-1] + 1) * res]))
    for label, poses, colour in trajectories:
        poses = np.asarray(poses)
        if len(poses) == 0:
            continue
        wide = "truth" in label or "reference" in label  # drawn wide and pale, under the others
        ax.plot(poses[:, 0], poses[:, 1], color=colour, lw=4.0 if wide else 1.2, alpha=0.45 if wide else 1.0,
                label=label, zorder=2 if wide else 3)
        ax.plot(poses[0, 0], poses[0, 1], "o", color=colour, ms=4)
        xs.append(poses[:, 0])
        ys.append(poses[:, 1])
    if extra is not None:
        extra(ax)
    if xs:
        allx, ally = np.concatenate(xs), np.concatenate(ys)
        pad = 1.0
        ax.set_xlim(allx.min() - pad, allx.max() + pad)
        ax.set_ylim(ally.min() - pad, ally.max() + pad)
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    bar = _nice_length(x1 - x0)
    bx, by = x0 + 0.04 * (x1 - x0), y0 + 0.04 * (y1 - y0)
    ax.add_patch(Rectangle((bx, by), bar, 0.012 * (y1 - y0), color="tab:red", zorder=10))
    ax.text(bx + bar / 2, by + 0.025 * (y1 - y0), f"{bar:g} m", ha="center", va="bottom", color="tab:red", zorder=10)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    if title:
        ax.set_title(title)
    if trajectories:
        ax.legend(loc="upper right", fontsize=8, markerscale=4)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
