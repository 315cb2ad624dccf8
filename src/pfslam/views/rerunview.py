"""A run in the rerun viewer (https://rerun.io), live (``--rerun``) or saved to an ``.rrd``
file (``--rerun-save``): the map as it grows, the particles, the scan, the trajectories and
the particle count and N_eff, on the time lines ``scan_time`` (seconds since the first
scan) and ``scan`` (the step's index). Optional: ``pip install 'pfslam[viz]'``.

Entities, all in world metres under ``world`` (which mirrors y, so that the viewer's 2D
view, whose y axis points down, shows the map as map.png does):

- ``world/map``: the occupancy map as a grey image (white free, black occupied, grey
  unknown), placed by its transform (lower-left corner, cell size); refreshed every
  ``MAP_INTERVAL`` s of log (logged once, static, when the map does not change);
- ``world/particles``, ``world/scan``: Points2D; ``world/robot``: an Arrows2D at the estimate;
- ``world/trajectory/{estimate,odometry,truth}``: LineStrips2D, each logged piece the part
  since the last one (the blueprint shows each entity's pieces from the start to the cursor);
- ``stats/particles``, ``stats/n_eff``: Scalars.

Steps are logged ``LOG_HZ`` times per second of log at most."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.colors import to_rgb

from pfslam.errors import InputError
from pfslam.filters.base import Filter
from pfslam.frames import Estimate, Frame
from pfslam.views.figures import HEALTH_COLOURS, map_image
from pfslam.views.trace import RunTrace, prepare_file, require, sample_steps

if TYPE_CHECKING:
    from rerun import FileSink, GrpcSink
    from rerun.blueprint import Blueprint

    from pfslam.filters.health import State
    from pfslam.maps.grid import OccupancyGrid

LOG_HZ = 10.0  # steps logged per second of log, at most
MAP_INTERVAL = 1.0  # seconds of log between two logs of a growing map
MAX_LOGGED_PARTICLES = 10_000
TRAJECTORIES = {"estimate": (31, 119, 180), "odometry": (255, 127, 14), "truth": (44, 160, 44)}
# The robot's arrow by the localization's health, in localization.png's colours (black:
# tracking, or no health: SLAM).
HEALTH_RGB = {k: tuple(round(255 * v) for v in to_rgb(c)) for k, c in HEALTH_COLOURS.items()}
FINAL_COLOUR = (23, 190, 207)  # the trajectory the run writes, logged once at its end
TIMELINE = "scan_time"


def check_rerun(save: Path | None) -> None:
    """Before a run: rerun-sdk is installed and the .rrd file can be made (one-line errors)."""
    require((("rerun", "rerun-sdk"),), "viz", "--rerun-save" if save is not None else "--rerun")
    if save is not None:
        if save.suffix.lower() != ".rrd":
            raise InputError(save, f"--rerun-save writes an .rrd file, not '{save.suffix or save.name}'")
        prepare_file(save, "rerun recording")


def blueprint(label: str, truth: bool) -> Blueprint:
    """The layout: the world in a 2D view (trajectory pieces kept from the start to the
    cursor), the particle count and N_eff in a time series beside it, and a localization's
    health (its quality; its state in a text log when it changes) under them."""
    import rerun.blueprint as rrb

    so_far = rrb.VisibleTimeRanges(
        [
            rrb.VisibleTimeRange(
                line, start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.cursor_relative()
            )
            for line in (TIMELINE, "scan")
        ]
    )
    names = [n for n in TRAJECTORIES if truth or n != "truth"]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial2DView(
                origin="/",
                contents="/world/**",
                name=f"pfslam {label}",
                overrides={f"/world/trajectory/{n}": so_far for n in names},
            ),
            rrb.Vertical(
                rrb.TimeSeriesView(origin="/stats", name="particles, N_eff"),
                *([rrb.TimeSeriesView(origin="/health", name="health: quality")] if label == "localization" else []),
            ),
            column_shares=[3, 1],
        ),
        rrb.TimePanel(timeline=TIMELINE),
        collapse_panels=False,
    )


def connect(spawn: bool, save: Path | None) -> list[GrpcSink | FileSink]:
    """The sinks: a viewer (spawned, or the one already listening on rerun's port) and/or a file."""
    import rerun as rr

    sinks: list[GrpcSink | FileSink] = []
    if spawn:
        rr.spawn(connect=False)
        sinks.append(rr.GrpcSink())
    if save is not None:
        sinks.append(rr.FileSink(str(save)))
    return sinks


class RerunLogger:
    """A :class:`~pfslam.views.live.View` that logs sampled steps to rerun.

    ``label``: the run's name in the viewer ("SLAM", "localization"); ``static_map``: the
    map never changes (localization). After :meth:`close`, ``problem`` says why the viewer
    could not be reached, if it could not (the file, if asked for, is written anyway)."""

    def __init__(
        self,
        trace: RunTrace,
        spawn: bool = False,
        save: Path | None = None,
        label: str = "SLAM",
        static_map: bool = False,
    ) -> None:
        check_rerun(save)
        import rerun as rr

        self.rr = rr
        self.save = save
        self.static_map = static_map
        self.rec = rr.RecordingStream("pfslam")
        self.rec.set_log_time_enabled(False)  # the time lines are the log's, not the wall clock's
        self.rec.set_sinks(*connect(spawn, save), default_blueprint=blueprint(label, trace.truth is not None))
        self.rec.send_recording_name(f"pfslam {label}")
        self.rec.log("world", rr.Transform3D(scale=[1.0, -1.0, 1.0]), static=True)
        self.steps = sample_steps(trace.t, 1.0 / LOG_HZ) > 0
        self.map_steps = sample_steps(trace.t, MAP_INTERVAL) > 0
        self.logged = 0  # steps logged
        self.maps = 0  # maps logged
        self.problem: str | None = None
        self.seconds = 0.0  # spent logging
        self.spawn = spawn
        self._prev = -1  # the last step logged
        self._latest: tuple[int, Frame, Filter, Estimate] | None = None
        self._state: State | None = None  # the health's state last logged (localization)

    def _log_map(self, grid: OccupancyGrid, static: bool) -> None:
        rr = self.rr
        img, extent, _, _ = map_image(grid)  # a new image of the cells as they are now
        grey = np.round(img * 255.0).astype(np.uint8)
        h, w = grey.shape
        cell = (extent[1] - extent[0]) / w
        self.rec.log(
            "world/map",
            rr.Transform3D(translation=[extent[0], extent[2], 0.0], scale=[cell, cell, 1.0]),
            rr.Image(grey, color_model="L", draw_order=-10.0),
            static=static,
        )
        self.maps += 1

    def _log_step(self, i: int, frame: Frame, filt: Filter, est: Estimate, trace: RunTrace) -> None:
        rr, rec = self.rr, self.rec
        rec.set_time("scan", sequence=i)
        rec.set_time(TIMELINE, duration=float(trace.t[i] - trace.t[0]))
        if self.static_map:
            if self.maps == 0:
                self._log_map(filt.map, static=True)
        elif self.map_steps[i] or self.maps == 0:
            self._log_map(filt.map, static=False)
        particles = filt.particles
        if particles is not None:
            p = particles.poses
            rec.log(
                "world/particles",
                rr.Points2D(p[:: max(1, len(p) // MAX_LOGGED_PARTICLES), :2], colors=[(148, 103, 189)], radii=[0.03]),
            )
        rec.log("world/scan", rr.Points2D(trace.hits(frame, est.pose), colors=[(214, 39, 40)], radii=[0.02]))
        pose = est.pose
        h = est.health
        rec.log(
            "world/robot",
            rr.Arrows2D(
                origins=[pose[:2]],
                vectors=[[0.6 * np.cos(pose[2]), 0.6 * np.sin(pose[2])]],
                colors=[HEALTH_RGB.get(h.state.value, (0, 0, 0)) if h is not None else (0, 0, 0)],
            ),
        )
        a = max(self._prev, 0)  # each piece starts where the last one ended
        pieces = {
            "estimate": trace.estimate(a, i),
            "odometry": trace.odometry(a, i),
            "truth": trace.truth_between(trace.t[a], trace.t[i]),
        }
        for name, poses in pieces.items():
            if len(poses) >= 2:
                rec.log(
                    f"world/trajectory/{name}",
                    rr.LineStrips2D([poses[:, :2]], colors=[TRAJECTORIES[name]], radii=[0.03]),
                )
        rec.log("stats/particles", rr.Scalars(float(est.particles)))
        rec.log("stats/n_eff", rr.Scalars(float(est.n_eff)))
        if h is not None:  # localization: how well the scan fits the map, and what that says
            rec.log("health/quality", rr.Scalars(float(h.quality)))
            if h.state is not self._state:
                rec.log("health/state", rr.TextLog(h.state.value))
                self._state = h.state
        self._prev = i
        self.logged += 1

    # -- the View interface -----------------------------------------------------------

    def step(self, i: int, frame: Frame, filt: Filter, est: Estimate, trace: RunTrace) -> None:
        self._latest = (i, frame, filt, est)
        if self.steps[i]:
            t0 = time.perf_counter()
            self._log_step(i, frame, filt, est, trace)
            self.seconds += time.perf_counter() - t0

    def close(self, trace: RunTrace) -> None:
        """Log the last step if it was not (a run stopped early), then flush: the file is
        complete when this returns; a viewer that cannot be reached is noted in ``problem``."""
        t0 = time.perf_counter()
        if self._latest is not None and self._latest[0] != self._prev:
            self._log_step(*self._latest, trace)
        if self._latest is not None:
            self._log_final(self._latest[2])
        try:
            self.rec.flush(timeout_sec=30.0)
        except RuntimeError as e:  # the viewer did not answer; the file sink still has everything
            why = str(e).splitlines()[0] if str(e) else type(e).__name__
            saved = f"; {self.save} is written" if self.save is not None else ""
            self.problem = f"the rerun viewer could not be reached ({why}){saved}"
        self.rec.disconnect()
        self.seconds += time.perf_counter() - t0

    def _log_final(self, filt: Filter) -> None:
        """The trajectory the run writes (``trajectory.tum``), at the last step logged. The
        Rao-Blackwellized filter writes its final best particle's whole path, which its live
        track (the best particle of each moment) need not be: this shows the loop closed."""
        _, poses = filt.trajectory()
        if len(poses) >= 2:
            self.rec.log(
                "world/trajectory/final", self.rr.LineStrips2D([poses[:, :2]], colors=[FINAL_COLOUR], radii=[0.03])
            )

    def report(self) -> str:
        where = [
            w
            for w in (
                "the viewer" if self.spawn else "",
                f"{self.save} ({self.save.stat().st_size / 1e6:.1f} MB)" if self.save else "",
            )
            if w
        ]
        return (
            f"rerun: {self.logged} steps and {self.maps} maps logged in {self.seconds:.1f} s to {' and '.join(where)}"
        )
