"""A video of a run (MP4 or GIF): the map as it is at each moment, the particles, the
scan's hits at the estimate, the trajectories so far and the time.

Frames are drawn with Matplotlib's Agg canvas (no window, no pyplot state) and written by
imageio: MP4 through PyAV (H.264, yuv420p: plays in browsers and players), GIF through
Pillow. Both are optional (``pip install 'pfslam[video]'``)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Callable, cast

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from numpy.typing import NDArray

from pfslam.errors import InputError
from pfslam.filters.base import Filter
from pfslam.frames import Estimate, Frame
from pfslam.types import Array
from pfslam.views.figures import map_image
from pfslam.views.trace import RunTrace, prepare_file, require, sample_steps

if TYPE_CHECKING:
    from imageio.plugins.pillow import PillowPlugin
    from imageio.plugins.pyav import PyAVPlugin
    from matplotlib.artist import Artist


FORMATS = (".mp4", ".gif")
DEFAULT_FPS = {".mp4": 20.0, ".gif": 10.0}
SIZE = {".mp4": 800, ".gif": 560}  # pixels, square; multiples of 16 (H.264 macroblocks)
SPEEDUP = 6.0  # the video plays the log this many times faster than real time ...
MAX_SECONDS = 40.0  # ... or faster, so that it lasts at most this long
HOLD_SECONDS = 1.5  # the last frame is shown this long
MAX_DRAWN_PARTICLES = 5000
MP4_CODECS = ("libx264", "h264", "mpeg4")  # the first PyAV can encode with


def check_video(path: Path, fps: float | None) -> None:
    """Before a run: the packages are there, the file name and frame rate make sense, its
    folder exists (ConfigError / InputError, one line each)."""
    require((("imageio", "imageio"), ("av", "av (PyAV)")), "video", "--video")
    if path.suffix.lower() not in FORMATS:
        raise InputError(path, f"--video writes .mp4 or .gif files, not '{path.suffix or path.name}'")
    if fps is not None and not (np.isfinite(fps) and 1.0 <= fps <= 60.0):
        raise InputError("--video-fps", f"must be a number of frames per second from 1 to 60, not {fps}")
    prepare_file(path, "video")


def log_seconds_per_frame(times: Array, fps: float) -> float:
    """Seconds of log per video frame: the log at ``SPEEDUP`` x real time, faster if the video
    would last more than ``MAX_SECONDS``."""
    span = float(times[-1] - times[0]) if len(times) > 1 else 0.0
    return max(SPEEDUP, span / MAX_SECONDS) / fps


class _Writer:
    """Frames to a file: MP4 with PyAV, GIF with Pillow (each frame quantised to 256 colours
    as it comes, so the frames Pillow holds until the end take a byte per pixel)."""

    def __init__(self, path: Path, fps: float) -> None:
        import imageio.v3 as iio

        self.gif = path.suffix.lower() == ".gif"
        self.file: PillowPlugin | PyAVPlugin  # Pillow for a GIF, PyAV for an MP4
        try:
            if self.gif:
                self.file = iio.imopen(path, "w", plugin="pillow", extension=".gif")
            else:
                self.file = iio.imopen(path, "w", plugin="pyav")
                self._open_stream(fps)
        except OSError as e:
            raise InputError(path, f"cannot write the video ({e.strerror or e})") from None
        self.fps = fps

    def _open_stream(self, fps: float) -> None:
        import av

        codec = next((c for c in MP4_CODECS if c in av.codecs_available), MP4_CODECS[-1])
        cast("PyAVPlugin", self.file).init_video_stream(codec, fps=fps, pixel_format="yuv420p")

    def write(self, img: NDArray[np.uint8]) -> None:
        if self.gif:
            cast("PillowPlugin", self.file).write(img, duration=round(1000.0 / self.fps), loop=0, bits=8)
        else:
            cast("PyAVPlugin", self.file).write_frame(img)

    def close(self) -> None:
        self.file.close()


class VideoRecorder:
    """A :class:`~pfslam.views.live.View` that renders sampled steps into a video file.

    ``fps`` frames per second of video, each ``log_seconds_per_frame`` of log apart;
    ``label``: the estimate's name in the legend ("SLAM", "estimate"); ``truth_label``: the
    ground truth's; ``static_map``: the map never changes (localization), so it is drawn
    once; ``progress(frames written, frames in all)`` is called as frames are written."""

    def __init__(
        self,
        path: Path,
        trace: RunTrace,
        fps: float | None = None,
        label: str = "SLAM",
        truth_label: str = "ground truth",
        title: str = "pfslam",
        static_map: bool = False,
        progress: Callable[[int, int], None] | None = None,
    ) -> None:
        self.path = Path(path)
        check_video(self.path, fps)
        suffix = self.path.suffix.lower()
        self.fps = float(fps) if fps is not None else DEFAULT_FPS[suffix]
        self.counts = sample_steps(trace.t, log_seconds_per_frame(trace.t, self.fps))
        self.hold = int(round(HOLD_SECONDS * self.fps))
        self.total = int(self.counts.sum()) + self.hold
        self.frames = 0  # frames written
        self.rendered = 0  # frames drawn (a frame shown for several video frames is drawn once)
        self.static_map = static_map
        self.progress = progress
        self.title = title
        self.label = label
        self.seconds = 0.0  # spent drawing and writing
        self.problem: str | None = None  # (a video shows all it was given, or fails)
        self._latest: tuple[int, Frame, Filter, Estimate] | None = None
        self._drawn = -1  # the last step drawn
        self._image: NDArray[np.uint8] | None = None
        self._box: list[float] | None = None  # x0, x1, y0, y1 shown
        self._seen: list[float] | None = None  # x0, x1, y0, y1 of everything drawn so far
        self._map_done = False
        self._map_box: tuple[float, float, float, float] | None = None
        self._figure(SIZE[suffix], truth_label, trace.truth is not None)
        self._writer = _Writer(self.path, self.fps)

    # -- drawing ----------------------------------------------------------------------

    def _figure(self, size: int, truth_label: str, has_truth: bool) -> None:
        """The figure, once. What changes from frame to frame is ``animated``: left out of the
        background (axes, ticks, legend), which is drawn again only when the view widens."""
        inches = 8.0  # the layout is made for 8 x 8 inches; the dpi gives the size in pixels
        self.fig = Figure(figsize=(inches, inches), dpi=size / inches)
        self.canvas = FigureCanvasAgg(self.fig)
        ax = self.ax = self.fig.add_axes((0.09, 0.07, 0.88, 0.82))
        ax.set_facecolor("0.8")  # unknown, like the map's unobserved cells
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        self.map_artist = ax.imshow(
            np.full((1, 1), 0.8),
            cmap="gray",
            vmin=0,
            vmax=1,
            origin="lower",
            extent=(0, 1, 0, 1),
            interpolation="nearest",
            zorder=0,
            animated=True,
        )
        self.truth_line = ax.plot(
            [], [], color="tab:green", lw=4.0, alpha=0.45, zorder=2, label=truth_label, animated=True
        )[0]
        self.odom_line = ax.plot([], [], color="tab:orange", lw=1.2, zorder=3, label="odometry", animated=True)[0]
        self.est_line = ax.plot([], [], color="tab:blue", lw=1.2, zorder=4, label=self.label, animated=True)[0]
        self.particle_dots = ax.scatter(
            np.empty(0),
            np.empty(0),
            s=5,
            color="tab:purple",
            alpha=0.5,
            linewidths=0,
            zorder=8,
            label="particles",
            animated=True,
        )
        self.scan_dots = ax.scatter(
            np.empty(0), np.empty(0), s=2, color="tab:red", linewidths=0, zorder=6, label="scan", animated=True
        )
        self.heading = ax.plot([], [], color="black", lw=2.0, zorder=7, animated=True)[0]
        keys: list[Artist] = [self.truth_line] if has_truth else []
        keys += [self.est_line, self.odom_line, self.particle_dots, self.scan_dots]
        self.fig.legend(
            handles=keys,
            loc="upper center",
            bbox_to_anchor=(0.53, 0.945),
            ncol=len(keys),
            fontsize=8,
            markerscale=3,
            frameon=False,
            handlelength=1.5,
            columnspacing=1.2,
        )
        self.caption = self.fig.text(0.09, 0.955, "", fontsize=11, family="monospace", animated=True)
        self.dynamic = [
            self.map_artist,
            self.truth_line,
            self.odom_line,
            self.est_line,
            self.scan_dots,
            self.heading,
            self.particle_dots,
        ]  # in drawing order
        self._background: object | None = None  # the canvas's pixels without the animated artists (Agg's region)

    def _fit(self, boxes: list[tuple[float, float, float, float]]) -> None:
        """Show everything drawn so far (the view never narrows, so the picture does not
        jump back and forth); when the view must widen, it takes a margin, so that it does
        not widen again every frame."""
        seen = self._seen
        x0 = min([b[0] for b in boxes] + ([seen[0]] if seen else []))
        x1 = max([b[1] for b in boxes] + ([seen[1]] if seen else []))
        y0 = min([b[2] for b in boxes] + ([seen[2]] if seen else []))
        y1 = max([b[3] for b in boxes] + ([seen[3]] if seen else []))
        self._seen = [x0, x1, y0, y1]
        box = self._box
        if box is not None and x0 >= box[0] and x1 <= box[1] and y0 >= box[2] and y1 <= box[3]:
            return
        pad = 0.1 * max(x1 - x0, y1 - y0, 4.0)
        x0, x1, y0, y1 = x0 - pad, x1 + pad, y0 - pad, y1 + pad
        # One metre as many pixels across as up: widen the narrower side to the axes' shape.
        bw, bh = self.ax.bbox.width, self.ax.bbox.height
        if (x1 - x0) * bh < (y1 - y0) * bw:
            extra = ((y1 - y0) * bw / bh - (x1 - x0)) / 2
            x0, x1 = x0 - extra, x1 + extra
        else:
            extra = ((x1 - x0) * bh / bw - (y1 - y0)) / 2
            y0, y1 = y0 - extra, y1 + extra
        self._box = [x0, x1, y0, y1]
        self.ax.set_xlim(x0, x1)
        self.ax.set_ylim(y0, y1)
        self._background = None

    def _draw(self, i: int, frame: Frame, filt: Filter, est: Estimate, trace: RunTrace) -> NDArray[np.uint8]:
        boxes = []
        if not (self.static_map and self._map_done):
            # The map as it is now: map_image makes a new image from the cells (a snapshot).
            img, extent, rows, _ = map_image(filt.map)
            self.map_artist.set_data(img)
            self.map_artist.set_extent(extent)
            self._map_done = True
            self._map_box = extent if len(rows) else None
        if self._map_box is not None:
            boxes.append(self._map_box)
        est_xy = trace.estimate(0, i)[:, :2]
        odom_xy = trace.odometry(0, i)[:, :2]
        truth_xy = trace.truth_between(-np.inf, trace.t[i])[:, :2]
        self.est_line.set_data(est_xy[:, 0], est_xy[:, 1])
        self.odom_line.set_data(odom_xy[:, 0], odom_xy[:, 1])
        self.truth_line.set_data(truth_xy[:, 0], truth_xy[:, 1])
        for xy in (est_xy, odom_xy, truth_xy):
            if len(xy):
                boxes.append((xy[:, 0].min(), xy[:, 0].max(), xy[:, 1].min(), xy[:, 1].max()))
        particles = filt.particles
        p = np.empty((0, 3)) if particles is None else particles.poses
        self.particle_dots.set_offsets(p[:: max(1, len(p) // MAX_DRAWN_PARTICLES), :2])
        pose = est.pose
        self.scan_dots.set_offsets(trace.hits(frame, pose))
        reach = 0.6
        self.heading.set_data(
            [pose[0], pose[0] + reach * np.cos(pose[2])], [pose[1], pose[1] + reach * np.sin(pose[2])]
        )
        self._fit(boxes)
        h = est.health  # localization: its health beside the count
        health = f"   {h.state.value} (quality {h.quality:.2f})" if h is not None else ""
        self.caption.set_text(
            f"{self.title}   t = {trace.t[i] - trace.t[0]:.1f} s   scan {i + 1}/{len(trace)}   particles {len(p)}{health}"
        )
        if self._background is None:
            self.canvas.draw()  # everything but the animated artists
            self._background = self.canvas.copy_from_bbox(self.fig.bbox)
        self.canvas.restore_region(self._background)
        for a in self.dynamic:
            self.ax.draw_artist(a)
        self.fig.draw_artist(self.caption)
        self.rendered += 1
        return np.ascontiguousarray(np.asarray(self.canvas.buffer_rgba())[:, :, :3])

    def _emit(self, img: NDArray[np.uint8], times: int) -> None:
        for _ in range(times):
            self._writer.write(img)
        self.frames += times
        if self.progress is not None:
            self.progress(self.frames, self.total)

    # -- the View interface -----------------------------------------------------------

    def step(self, i: int, frame: Frame, filt: Filter, est: Estimate, trace: RunTrace) -> None:
        self._latest = (i, frame, filt, est)
        k = int(self.counts[i])
        if k:
            t0 = time.perf_counter()
            self._image = self._draw(i, frame, filt, est, trace)
            self._drawn = i
            self._emit(self._image, k)
            self.seconds += time.perf_counter() - t0

    def close(self, trace: RunTrace) -> None:
        """Draw the last step if it was not (a run stopped early), hold it, close the file."""
        t0 = time.perf_counter()
        try:
            if self._latest is not None:
                i, frame, filt, est = self._latest
                if self._drawn != i:
                    self._image = self._draw(i, frame, filt, est, trace)
                    self._drawn = i
                    self._emit(self._image, 1)
                if self._image is not None:
                    self._emit(self._image, self.hold)
        finally:
            self._writer.close()
            if self.frames == 0:  # nothing was stepped: no file rather than an unplayable one
                self.path.unlink(missing_ok=True)
            self.seconds += time.perf_counter() - t0

    def report(self) -> str:
        size = self.path.stat().st_size / 1e6 if self.path.exists() else 0.0
        return (
            f"video: {self.path} ({self.frames} frames, {self.frames / self.fps:.1f} s at {self.fps:g} fps, "
            f"{size:.1f} MB; {self.rendered} drawn in {self.seconds:.1f} s)"
        )
