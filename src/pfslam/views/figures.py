"""Figures: the map with trajectories, a legend and a scale bar; an estimate's errors against a reference."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Sequence, cast

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Rectangle  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from pfslam.eval.metrics import PoseErrors  # noqa: E402
from pfslam.maps.grid import OccupancyGrid  # noqa: E402

if TYPE_CHECKING:
    from matplotlib.artist import Artist
    from matplotlib.backends.backend_agg import FigureCanvasAgg


def _nice_length(span: float) -> float:
    """A round scale-bar length of about a fifth of ``span``."""
    target = max(span / 5.0, 1e-3)
    base = 10 ** np.floor(np.log10(target))
    for m in (5, 2, 1):
        if m * base <= target:
            return float(m * base)
    return float(base)


MAX_IMAGE_CELLS = 800  # the map image's longest side, about the axes' pixels; larger maps are pooled


def _map_image(
    grid: OccupancyGrid,
) -> tuple[NDArray[np.float64], tuple[float, float, float, float], NDArray[np.intp], NDArray[np.intp]]:
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
        crop = np.maximum.reduceat(
            np.maximum.reduceat(crop, np.arange(0, crop.shape[0], k), axis=0), np.arange(0, crop.shape[1], k), axis=1
        )
    crop = crop.astype(float)
    img = np.where(crop == 0, 0.8, 1.0 - 1.0 / (1.0 + np.exp(-np.clip(crop, -50, 50))))
    extent = (ox + c0 * res, ox + (c0 + crop.shape[1] * k) * res, oy + r0 * res, oy + (r0 + crop.shape[0] * k) * res)
    return img, extent, rows, cols


CLOUD_ZORDER = 4.5  # particle clouds: above every trajectory line (2-4), under the start/end markers (5)


def jumps(xy: NDArray[np.float64], max_jump: float, motion: NDArray[np.float64] | None = None) -> NDArray[np.bool_]:
    """Which of the N-1 steps of the (N, 2) positions ``xy`` are jumps: longer than
    ``max_jump`` m plus ``motion`` (N-1,), the distance the robot moved over the step by
    its odometry (none given: 0), e.g. an estimate recovering after a kidnapping."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    step = np.hypot(*np.diff(xy, axis=0).T) if len(xy) > 1 else np.empty(0)
    allowed = max_jump + (0.0 if motion is None else np.asarray(motion, dtype=float))
    return step > allowed


def break_jumps(
    xy: NDArray[np.float64], max_jump: float, motion: NDArray[np.float64] | None = None
) -> NDArray[np.float64]:
    """The polyline through the (N, 2) positions ``xy`` with a NaN row inserted at each of
    its :func:`jumps`, so a plot draws no segment across a jump (through walls)."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    where = np.nonzero(jumps(xy, max_jump, motion))[0] + 1
    return np.insert(xy, where, np.nan, axis=0)


def _odometry_steps(trajectories: Sequence[tuple[str, NDArray[np.float64], str]], n: int) -> NDArray[np.float64] | None:
    """The distance the odometry moved at each of ``n - 1`` steps, if a trajectory labelled
    "odometry" of ``n`` poses is given."""
    for label, poses, _ in trajectories:
        p = np.asarray(poses, dtype=float)
        if label == "odometry" and len(p) == n and n > 1:
            return np.hypot(*np.diff(p[:, :2], axis=0).T)
    return None


def map_figure(
    grid: OccupancyGrid,
    trajectories: Sequence[tuple[str, NDArray[np.float64], str]] = (),
    title: str = "",
    extra: callable | None = None,  # type: ignore[valid-type]
    times: NDArray[np.float64] | None = None,
    timed: str | None = None,
    clouds: Sequence[tuple[str, NDArray[np.float64]]] = (),
    jump: float | None = None,
) -> tuple[plt.Figure, plt.Axes]:
    """The figure :func:`plot_map` saves (see there), with its map axes; the caller closes it."""
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D
    from mpl_toolkits.axes_grid1 import make_axes_locatable

    img, extent, rows, cols = _map_image(grid)
    xs: list[NDArray[np.float64]] = []
    ys: list[NDArray[np.float64]] = []
    if len(rows):
        xs.append(np.array(extent[:2]))
        ys.append(np.array(extent[2:]))
    for label, poses, _ in trajectories:
        if label != "odometry" and len(poses):
            xs.append(np.asarray(poses)[:, 0])
            ys.append(np.asarray(poses)[:, 1])
    limits = None
    if xs:
        allx, ally = np.concatenate(xs), np.concatenate(ys)
        pad = 0.03 * max(allx.max() - allx.min(), ally.max() - ally.min(), 1.0)
        limits = (allx.min() - pad, allx.max() + pad, ally.min() - pad, ally.max() + pad)
    ratio = 1.0 if limits is None else (limits[3] - limits[2]) / max(limits[1] - limits[0], 1e-9)
    fig, ax = plt.subplots(figsize=(9, float(np.clip(7.6 * ratio + 1.6, 4.0, 12.0))), dpi=110)
    ax.set_facecolor("0.8")  # unknown, like the map's unobserved cells
    ax.imshow(img, cmap="gray", vmin=0, vmax=1, origin="lower", extent=extent, interpolation="nearest")
    handles: list[Artist] = []
    for label, poses, colour in trajectories:
        poses = np.asarray(poses)
        if len(poses) == 0:
            continue
        wide = "truth" in label or "reference" in label  # drawn wide and pale, under the others
        z = 2 if wide else 3
        # An estimate that jumps (a recovery) is drawn with a gap there, not a line through walls.
        broken = None
        if jump is not None and not wide and label != "odometry":
            broken = jumps(poses[:, :2], jump, _odometry_steps(trajectories, len(poses)))
        if label == timed and times is not None and len(times) == len(poses) and len(poses) > 1:
            seg = np.stack([poses[:-1, :2], poses[1:, :2]], axis=1)
            since = np.asarray(times, dtype=float) - float(times[0])
            mid = 0.5 * (since[:-1] + since[1:])
            if broken is not None:
                seg, mid = seg[~broken], mid[~broken]
            lc = LineCollection(seg, cmap="viridis", linewidths=1.3, zorder=z + 1, label="_nolegend_")  # type: ignore[arg-type]  # the stub takes no (N, 2, 2) array
            lc.set_array(mid)
            lc.set_clim(0.0, max(float(since[-1]), 1e-9))
            ax.add_collection(lc)
            bar = fig.colorbar(lc, cax=make_axes_locatable(ax).append_axes("right", size="2.5%", pad=0.1))
            bar.set_label(f"{label}: time since start (s)")
            handles.append(Line2D([], [], color=plt.get_cmap("viridis")(0.6), lw=1.3, label=f"{label} (by time)"))
            colour = "black"
        else:
            style = "--" if label == "odometry" else "-"
            xy = (
                poses[:, :2]
                if broken is None or jump is None
                else break_jumps(poses[:, :2], jump, _odometry_steps(trajectories, len(poses)))
            )
            (line,) = ax.plot(
                xy[:, 0],
                xy[:, 1],
                style,
                color=colour,
                lw=2.6 if wide else 1.0,
                alpha=0.4 if wide else 0.9,
                label=label,
                zorder=z,
            )
            handles.append(line)
        ax.plot(poses[0, 0], poses[0, 1], "o", mfc="white", mec=colour, mew=1.2, ms=6, zorder=z + 2)
        ax.plot(poses[-1, 0], poses[-1, 1], "s", mfc="white", mec=colour, mew=1.2, ms=6, zorder=z + 2)
    # Particle clouds over the trajectories, so they show where they cover the track.
    for k, (label, p) in enumerate(clouds):
        p = np.asarray(p)[:: max(1, len(p) // 3000)]
        colour = f"C{4 + k % 5}"
        ax.scatter(p[:, 0], p[:, 1], s=2, alpha=0.35, color=colour, linewidths=0, label=label, zorder=CLOUD_ZORDER)
        # The legend's sample larger and opaque: the cloud's own dots are too faint to read there.
        handles.append(Line2D([], [], marker="o", ls="", ms=3.5, mew=0, color=colour, label=label))
    if extra is not None:
        extra(ax)
    if limits is not None:
        ax.set_xlim(*limits[:2])
        ax.set_ylim(*limits[2:])
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    bar_len = _nice_length(x1 - x0)
    bx, by = x0 + 0.04 * (x1 - x0), y0 + 0.04 * (y1 - y0)
    ax.add_patch(Rectangle((bx, by), bar_len, 0.012 * (y1 - y0), color="tab:red", zorder=10))
    ax.text(
        bx + bar_len / 2, by + 0.025 * (y1 - y0), f"{bar_len:g} m", ha="center", va="bottom", color="tab:red", zorder=10
    )
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    if title:
        ax.set_title(title)
    known = {h.get_label() for h in handles}
    handles += [
        h for h, lab in zip(*ax.get_legend_handles_labels()) if lab.startswith("particles") and lab not in known
    ]  # clouds an ``extra`` drew
    fig.tight_layout()
    if handles:
        handles += [
            Line2D([], [], marker="o", ls="", mfc="white", mec="0.2", label="start"),
            Line2D([], [], marker="s", ls="", mfc="white", mec="0.2", label="end"),
        ]
        # Below the axes and their x label: the legend covers none of the map.
        fig.canvas.draw()
        tight = ax.get_tightbbox(cast("FigureCanvasAgg", fig.canvas).get_renderer())  # the Agg backend's canvas
        assert tight is not None  # the axes are visible
        below = tight.y0
        top = float(ax.transAxes.inverted().transform((0.0, below))[1]) - 0.01
        ax.legend(
            handles=handles,
            loc="upper center",
            bbox_to_anchor=(0.5, top),
            ncol=min(len(handles), 4),
            fontsize=8,
            frameon=False,
            markerscale=1.5,
        )
    return fig, ax


def plot_map(
    grid: OccupancyGrid,
    path: str | Path,
    trajectories: Sequence[tuple[str, NDArray[np.float64], str]] = (),
    title: str = "",
    extra: callable | None = None,  # type: ignore[valid-type]
    times: NDArray[np.float64] | None = None,
    timed: str | None = None,
    clouds: Sequence[tuple[str, NDArray[np.float64]]] = (),
    jump: float | None = None,
) -> tuple[float, float, float, float]:
    """Save the map (white free, black occupied, grey unknown) with labelled trajectories;
    return the view drawn, (x0, x1, y0, y1) in metres.

    ``trajectories`` holds (label, (N, 3) poses, colour) triples; each gets a start (circle)
    and an end (square) marker. The one labelled ``timed`` is coloured by ``times`` (one a
    pose) with a colour bar. The view holds the map and every trajectory but the odometry,
    which is clipped where it drifts off the map; outside the map is the unknown grey.
    ``clouds`` holds (label, (M, 3) particle poses) pairs, drawn over the trajectories.
    With ``jump`` (m), an estimate's step longer than ``jump`` plus the odometry's own step
    is left undrawn (see :func:`jumps`). The legend sits below the map, never over it.
    """
    fig, ax = map_figure(grid, trajectories, title, extra, times, timed, clouds, jump)
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    fig.savefig(path, bbox_inches="tight", pad_inches=0.15)  # the legend below the axes included
    plt.close(fig)
    return (x0, x1, y0, y1)


def plot_errors(errors: PoseErrors, folder: str | Path, name: str = "estimate") -> list[Path]:
    """evo-style pictures of an estimate against a reference, into ``folder``:
    ``trajectory_error.png`` (the aligned estimate coloured by its position error over the
    reference) and ``error_over_time.png`` (that error against time, with its RMSE, median
    and maximum). Returns the files written."""
    from matplotlib.collections import LineCollection

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    e, r, err = errors.aligned, errors.reference, errors.aligned_error
    out = [folder / "trajectory_error.png", folder / "error_over_time.png"]

    fig, ax = plt.subplots(figsize=(8, 7), dpi=110)
    ax.plot(r[:, 0], r[:, 1], color="0.6", lw=2.5, alpha=0.7, label="reference", zorder=1)
    seg = np.stack([e[:-1, :2], e[1:, :2]], axis=1)
    lc = LineCollection(seg, cmap="plasma", linewidths=1.6, zorder=2)  # type: ignore[arg-type]  # the stub takes no (N, 2, 2) array
    lc.set_array(0.5 * (err[:-1] + err[1:]))
    ax.add_collection(lc)
    bar = fig.colorbar(lc, ax=ax, fraction=0.04, pad=0.02)
    bar.set_label("position error after SE(2) alignment (m)")
    ax.plot(e[0, 0], e[0, 1], "o", mfc="white", mec="k", ms=6, label="start", zorder=3)
    ax.plot(e[-1, 0], e[-1, 1], "s", mfc="white", mec="k", ms=6, label="end", zorder=3)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{name}: ATE {np.sqrt(np.mean(err**2)):.3f} m (RMSE, aligned), {len(err)} poses")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.11), ncol=3, fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(out[0], bbox_inches="tight", pad_inches=0.15)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(9, 4), dpi=110)
    t = errors.t - errors.t[0]
    ax.plot(t, err, color="tab:blue", lw=0.9, label="position error")
    for value, what, style in (
        (float(np.sqrt(np.mean(err**2))), "RMSE", "-"),
        (float(np.median(err)), "median", "--"),
        (float(err.max()), "max", ":"),
    ):
        ax.axhline(value, color="tab:red", ls=style, lw=1.0, label=f"{what} {value:.3f} m")
    ax.set_xlabel("time since start (s)")
    ax.set_ylabel("error after alignment (m)")
    ax.set_ylim(bottom=0)
    ax.set_title(name)
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(out[1])
    plt.close(fig)
    return out
