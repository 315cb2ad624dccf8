"""Figures: the map with trajectories, a legend and a scale bar; an estimate's errors against a reference."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Sequence, cast

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
    from matplotlib.colors import Colormap


def _nice_length(span: float) -> float:
    """A round scale-bar length of about a fifth of ``span``."""
    target = max(span / 5.0, 1e-3)
    base = 10 ** np.floor(np.log10(target))
    for m in (5, 2, 1):
        if m * base <= target:
            return float(m * base)
    return float(base)


MAX_IMAGE_CELLS = 800  # the map image's longest side, about the axes' pixels; larger maps are pooled


def map_image(
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


# What is drawn over what: odometry (faint) under the truth (thin, dark) under the estimate,
# the start/end markers (hollow) over them, the particle clouds over everything but the scale bar.
ODOMETRY_ZORDER = 1.5
TRUTH_ZORDER = 2.0
ESTIMATE_ZORDER = 3.0
MARKER_ZORDER = 5.0
CLOUD_ZORDER = 6.0
TRUTH_COLOUR = "0.05"  # a truth or reference: thin and near black, so the estimate shows over it
ODOMETRY_COLOUR = "tab:orange"
# The estimate coloured by time runs from blue through purple to magenta: no black (the truth),
# no orange (the odometry), no green (a particle cloud), and dark enough on the white free space.
TIME_COLOURS = ("#1f3dff", "#7a2bd6", "#d0107f")
CLOUD_COLOURS = ("tab:green", "tab:red", "#00a0a0", "#8c6d00")  # green, red, teal, olive-brown
ODOMETRY_NEAR = 0.1  # odometry is drawn while it stays within this share of the view's span of the estimate


def time_colormap() -> Colormap:
    """The colour map of an estimate coloured by time (:data:`TIME_COLOURS`)."""
    from matplotlib.colors import LinearSegmentedColormap

    return LinearSegmentedColormap.from_list("pfslam_time", list(TIME_COLOURS))


def is_truth(label: str) -> bool:
    """A trajectory drawn as the truth: thin, dark, under the estimate."""
    return "truth" in label or "reference" in label


def odometry_near(odometry: NDArray[np.float64], estimate: NDArray[np.float64], near: float) -> int:
    """How many of the first poses of ``odometry`` to draw: up to the first one more than
    ``near`` m from the estimate's pose at the same step (both (N, >=2), one pose a step);
    all of them if it never goes that far, or if the two do not have a pose a step. Past
    that point the drifted odometry would only clutter the map."""
    odo = np.asarray(odometry, dtype=float)
    est = np.asarray(estimate, dtype=float)
    if len(odo) != len(est) or not len(odo):
        return len(odo)
    off = np.nonzero(np.hypot(*(odo[:, :2] - est[:, :2]).T) > near)[0]
    return int(off[0]) if len(off) else len(odo)


FILTER_NAMES = {
    "rbpf": "Rao-Blackwellized filter",
    "single": "single-map filter",
    "mcl": "Monte Carlo localization",
}


def run_title(
    kind: str,
    log: str | Path | None = None,
    filter_info: dict[str, Any] | None = None,
    metrics: dict[str, Any] | None = None,
    name: str = "SLAM",
    truth_label: str = "ground truth",
) -> str:
    """The title of a run's picture: the log, what ran (SLAM or localization, which filter,
    how many particles), and on a second line the estimate's aligned ATE against the truth
    (and the odometry's) and the map agreement, where known."""
    filter_info = filter_info or {}
    metrics = metrics or {}
    what = "SLAM map" if kind == "slam" else "localization"
    how = FILTER_NAMES.get(str(filter_info.get("filter")), str(filter_info.get("filter") or ""))
    n = filter_info.get("particles", filter_info.get("first_particles"))
    if how and n:
        how += f", {int(n)} particles"
    head = (f"{Path(str(log)).name}: " if log else "") + what + (f" ({how})" if how else "")
    figures = []
    mine = metrics.get(name) or {}
    if mine.get("ate_rmse_aligned") is not None:
        figures.append(f"ATE aligned vs {truth_label}: {name} {float(mine['ate_rmse_aligned']):.3f} m")
        odo = metrics.get("odometry") or {}
        if odo.get("ate_rmse_aligned") is not None:
            figures[-1] += f", odometry {float(odo['ate_rmse_aligned']):.2f} m"
    agreement = metrics.get("map_agreement") or {}
    if isinstance(agreement, dict) and agreement.get(name) is not None:
        figures.append(f"map agreement {float(agreement[name]):.2f}")
    return head + ("\n" + "; ".join(figures) if figures else "")


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
    from matplotlib.colors import to_hex
    from matplotlib.lines import Line2D
    from mpl_toolkits.axes_grid1 import make_axes_locatable

    img, extent, rows, cols = map_image(grid)
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
    # The odometry is drawn while it stays near the estimate: past that it only clutters.
    view_span = 1.0 if limits is None else max(limits[1] - limits[0], limits[3] - limits[2])
    near = ODOMETRY_NEAR * view_span
    # Measured from the truth where there is one (an estimate may be lost for a while), else the estimate.
    estimates = [np.asarray(p) for lab, p, _ in trajectories if is_truth(lab)] + [
        np.asarray(p) for lab, p, _ in trajectories if lab != "odometry" and not is_truth(lab)
    ]
    cmap = time_colormap()
    for label, poses, colour in trajectories:
        poses = np.asarray(poses)
        if len(poses) == 0:
            continue
        truth = is_truth(label)
        odometry = label == "odometry"
        z = TRUTH_ZORDER if truth else ODOMETRY_ZORDER if odometry else ESTIMATE_ZORDER
        shown = label
        if truth:
            colour = TRUTH_COLOUR
        elif odometry:
            colour = ODOMETRY_COLOUR
            if estimates:
                k = odometry_near(poses, estimates[0], near)
                if k < len(poses):
                    shown = f"odometry, until {near:.2g} m off (×)"
                    poses = poses[: max(k, 1)]
        # An estimate that jumps (a recovery) is drawn with a gap there, not a line through walls.
        broken = None
        if jump is not None and not truth and not odometry:
            broken = jumps(poses[:, :2], jump, _odometry_steps(trajectories, len(poses)))
        if label == timed and times is not None and len(times) == len(poses) and len(poses) > 1:
            seg = np.stack([poses[:-1, :2], poses[1:, :2]], axis=1)
            since = np.asarray(times, dtype=float) - float(times[0])
            mid = 0.5 * (since[:-1] + since[1:])
            if broken is not None:
                seg, mid = seg[~broken], mid[~broken]
            lc = LineCollection(seg, cmap=cmap, linewidths=1.6, zorder=z, label="_nolegend_")  # type: ignore[arg-type]  # the stub takes no (N, 2, 2) array
            lc.set_array(mid)
            lc.set_clim(0.0, max(float(since[-1]), 1e-9))
            ax.add_collection(lc)
            bar = fig.colorbar(lc, cax=make_axes_locatable(ax).append_axes("right", size="2.5%", pad=0.1))
            bar.set_label(f"{label}: time since start (s)")
            handles.append(Line2D([], [], color=cmap(0.5), lw=1.6, label=f"{label} (by time)"))
            colour = to_hex(cmap(1.0))  # its end marker
            start_colour = to_hex(cmap(0.0))
        else:
            xy = (
                poses[:, :2]
                if broken is None or jump is None
                else break_jumps(poses[:, :2], jump, _odometry_steps(trajectories, len(poses)))
            )
            (line,) = ax.plot(
                xy[:, 0],
                xy[:, 1],
                "--" if odometry else "-",
                color=colour,
                lw=0.9 if truth else 1.0 if odometry else 1.6,
                alpha=0.7 if odometry else 0.9 if truth else 1.0,
                label=shown,
                zorder=z,
            )
            handles.append(line)
            start_colour = colour
        if truth:  # starts and ends where the estimate does, or shows its distance from it
            continue
        # Hollow markers: a particle cloud or the track under them stays visible. The odometry
        # starts with the estimate: only its end is marked (a cross where it is left off).
        if not odometry:
            ax.plot(poses[0, 0], poses[0, 1], "o", mfc="none", mec=start_colour, mew=1.5, ms=8, zorder=MARKER_ZORDER)
        end = "x" if shown != label else "s"
        ax.plot(poses[-1, 0], poses[-1, 1], end, mfc="none", mec=colour, mew=1.5, ms=8, zorder=MARKER_ZORDER)
    # Particle clouds over the trajectories and markers, each ringed and labelled with its
    # time, so a tight cloud (at the start, at the end) is found at a glance.
    for k, (label, p) in enumerate(clouds):
        p = np.asarray(p)[:: max(1, len(p) // 3000)]
        if not len(p):
            continue
        colour = CLOUD_COLOURS[k % len(CLOUD_COLOURS)]
        ax.scatter(p[:, 0], p[:, 1], s=4, alpha=0.5, color=colour, linewidths=0, label=label, zorder=CLOUD_ZORDER)
        cx, cy = float(np.median(p[:, 0])), float(np.median(p[:, 1]))
        ax.plot(cx, cy, "o", mfc="none", mec=colour, mew=1.6, ms=16, zorder=CLOUD_ZORDER)
        ax.annotate(
            label.removeprefix("particles at "),
            (cx, cy),
            xytext=(9, 9) if k % 2 == 0 else (9, -17),  # above, below by turns: the first and last clouds often meet
            textcoords="offset points",
            fontsize=8,
            color=colour,
            fontweight="bold",
            zorder=CLOUD_ZORDER + 1,
            bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.75},
        )
        # The legend's sample: the ring the cloud is drawn in.
        handles.append(Line2D([], [], marker="o", ls="", ms=7, mfc="none", mec=colour, mew=1.6, label=label))
    if extra is not None:
        extra(ax)
    if limits is not None:
        ax.set_xlim(*limits[:2])
        ax.set_ylim(*limits[2:])
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    bar_len = _nice_length(x1 - x0)
    bx, by = x0 + 0.04 * (x1 - x0), y0 + 0.04 * (y1 - y0)
    ax.add_patch(Rectangle((bx, by), bar_len, 0.012 * (y1 - y0), color="0.1", zorder=10))
    ax.text(
        bx + bar_len / 2, by + 0.025 * (y1 - y0), f"{bar_len:g} m", ha="center", va="bottom", color="0.1", zorder=10
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
            Line2D([], [], marker="o", ls="", mfc="none", mec="0.2", mew=1.5, label="start"),
            Line2D([], [], marker="s", ls="", mfc="none", mec="0.2", mew=1.5, label="end"),
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
        )
    return fig, ax


SPREAD_COLOUR = "tab:red"  # under the estimate where the particles' spread rose


def spread_marker(xy: NDArray[np.float64], rose: NDArray[np.bool_], threshold: float) -> Callable[[plt.Axes], None]:
    """An ``extra`` for :func:`plot_map`: the (N, 2) positions ``xy`` of an estimate drawn
    thick, red and translucent under it where ``rose`` (N,) holds, i.e. where the estimate's
    own uncertainty (the particles' spread) exceeded ``threshold`` m; labelled in the legend."""

    def draw(ax: plt.Axes) -> None:
        from matplotlib.collections import LineCollection

        keep = rose[:-1] | rose[1:]
        seg = np.stack([xy[:-1], xy[1:]], axis=1)[keep]
        if len(seg):
            ax.add_collection(
                LineCollection(
                    seg,  # type: ignore[arg-type]  # the stub takes no (N, 2, 2) array
                    colors=SPREAD_COLOUR,
                    linewidths=7.0,
                    alpha=0.35,
                    capstyle="round",
                    zorder=ESTIMATE_ZORDER - 0.5,
                    label=f"particles' spread above {threshold:.2f} m",
                )
            )

    return draw


HEALTH_COLOURS = {"degraded": "tab:orange", "lost": "tab:red", "ambiguous": "tab:purple"}


def health_marker(xy: NDArray[np.float64], states: Sequence[str]) -> Callable[[plt.Axes], None]:
    """An ``extra`` for :func:`plot_map`: the (N, 2) positions ``xy`` of an estimate marked
    where its health ``states`` (N,) say degraded, lost or ambiguous (a dot each, in the
    state's colour, labelled in the legend)."""
    st = np.asarray(states)

    def draw(ax: plt.Axes) -> None:
        for name, colour in HEALTH_COLOURS.items():
            at = st == name
            if at.any():
                ax.scatter(
                    xy[at, 0],
                    xy[at, 1],
                    s=14,
                    color=colour,
                    alpha=0.6,
                    linewidths=0,
                    zorder=ESTIMATE_ZORDER + 0.5,
                    label=f"health: {name} ({int(at.sum())} scans)",
                )

    return draw


def both(*extras: Callable[[plt.Axes], None] | None) -> Callable[[plt.Axes], None] | None:
    """One ``extra`` for :func:`plot_map` that draws each of ``extras`` (None: none)."""
    given = [e for e in extras if e is not None]
    if not given:
        return None

    def draw(ax: plt.Axes) -> None:
        for e in given:
            e(ax)

    return draw


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

    ``trajectories`` holds (label, (N, 3) poses, colour) triples. A truth or reference (see
    :func:`is_truth`) is drawn thin and near black under the estimates; the odometry faint,
    dashed, under both and only while it stays within :data:`ODOMETRY_NEAR` of the view's
    span of the estimate (see :func:`odometry_near`; a cross where it is left off); an
    estimate on top, with a start (circle) and an end (square) marker, both hollow. The one
    labelled ``timed`` is coloured by ``times`` (one a pose) with a colour bar, in colours no
    other line or cloud uses (:data:`TIME_COLOURS`). The view holds the map and every
    trajectory but the odometry; outside the map is the unknown grey. ``clouds`` holds
    (label, (M, 3) particle poses) pairs, drawn over everything, each ringed and labelled.
    With ``jump`` (m), an estimate's step longer than ``jump`` plus the odometry's own step
    is left undrawn (see :func:`jumps`). The legend sits below the map, never over it.
    """
    fig, ax = map_figure(grid, trajectories, title, extra, times, timed, clouds, jump)
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    fig.savefig(path, bbox_inches="tight", pad_inches=0.15)  # the legend below the axes included
    plt.close(fig)
    return (x0, x1, y0, y1)


def _short(name: str) -> str:
    """A file's name with its folder (``run1/trajectory.tum``): the name alone is often the same
    for every run."""
    parts = Path(name).parts
    return "/".join(parts[-2:]) if len(parts) > 1 else name


def plot_errors(errors: PoseErrors, folder: str | Path, name: str = "estimate", reference: str = "") -> list[Path]:
    """evo-style pictures of an estimate against a reference, into ``folder``:
    ``trajectory_error.png`` (the aligned estimate coloured by its position error, over the
    reference drawn thin and dark) and ``error_over_time.png`` (that error against time,
    with its RMSE, median and maximum, the legend beside the plot). ``name`` and
    ``reference`` (file paths, shown with their folder) title both. Returns the files written."""
    from matplotlib.collections import LineCollection
    from matplotlib.colors import LinearSegmentedColormap

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    e, r, err = errors.aligned, errors.reference, errors.aligned_error
    out = [folder / "trajectory_error.png", folder / "error_over_time.png"]
    rmse, median, worst = float(np.sqrt(np.mean(err**2))), float(np.median(err)), float(err.max())
    what = _short(name) + (f" against {_short(reference)}" if reference else "")
    figures = f"ATE aligned {rmse:.3f} m (RMSE), max {worst:.3f} m, {len(err)} poses"

    fig, ax = plt.subplots(figsize=(8, 7), dpi=110)
    ax.plot(r[:, 0], r[:, 1], color=TRUTH_COLOUR, lw=0.8, alpha=0.8, label="reference", zorder=1)
    seg = np.stack([e[:-1, :2], e[1:, :2]], axis=1)
    # plasma without its near-black end: the reference is the black line
    cmap = LinearSegmentedColormap.from_list("errors", plt.get_cmap("plasma")(np.linspace(0.12, 0.92, 256)))
    lc = LineCollection(seg, cmap=cmap, linewidths=1.8, zorder=2)  # type: ignore[arg-type]  # the stub takes no (N, 2, 2) array
    lc.set_array(0.5 * (err[:-1] + err[1:]))
    lc.set_clim(0.0, max(worst, 1e-9))
    ax.add_collection(lc)
    bar = fig.colorbar(lc, ax=ax, fraction=0.04, pad=0.02)
    bar.set_label("position error after SE(2) alignment (m)")
    ax.plot(e[0, 0], e[0, 1], "o", mfc="none", mec="k", mew=1.5, ms=8, label="start", zorder=3)
    ax.plot(e[-1, 0], e[-1, 1], "s", mfc="none", mec="k", mew=1.5, ms=8, label="end", zorder=3)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{what}\n{figures}", fontsize=10)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.11), ncol=3, fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(out[0], bbox_inches="tight", pad_inches=0.15)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(10, 4), dpi=110)
    t = errors.t - errors.t[0]
    ax.plot(t, err, color="tab:blue", lw=0.9, label="position error", zorder=2)
    for value, what_line, style in ((rmse, "RMSE", "-"), (median, "median", "--")):
        ax.axhline(value, color="tab:red", ls=style, lw=1.0, label=f"{what_line} {value:.3f} m", zorder=3)
    i = int(np.argmax(err))
    ax.plot(t[i], err[i], "v", color="tab:red", ms=7, label=f"max {worst:.3f} m at {t[i]:.0f} s", zorder=4)
    ax.set_xlabel("time since start (s)")
    ax.set_ylabel("error after alignment (m)")
    ax.set_ylim(0, 1.08 * max(worst, 1e-9))
    ax.set_xlim(0, max(float(t[-1]), 1e-9))
    ax.grid(alpha=0.3)
    ax.set_title(f"{what}: position error over time", fontsize=10)
    # Beside the plot, clear of every peak.
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(out[1], bbox_inches="tight", pad_inches=0.15)
    plt.close(fig)
    return out
