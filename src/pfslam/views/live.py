"""Watching a run as it goes: a video of it (:mod:`pfslam.views.video`) and/or the rerun viewer
(:mod:`pfslam.views.rerunview`).

A :class:`LiveView` is the observer :func:`pfslam.pipeline.run_filter` calls after each
step: it records the run's trace and hands each step to its views, which draw only the
steps they sample, so watching costs little per scan; a run that asks for no view has no
observer at all. :class:`ViewRequest` is what a command was asked for: checked before the
run (missing packages, bad file names: one-line errors), opened when the run starts. No
printing here: the views report progress through a callback and problems as values."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Protocol

from pfslam.filters.base import Filter
from pfslam.frames import Estimate, Frame
from pfslam.types import Array
from pfslam.views.trace import RunTrace


class View(Protocol):
    """One way of watching a run: told of every step (it samples them), then closed once;
    ``report()`` says what it made, in a line; ``problem`` is set if it could not show all
    of it (and the run's results are still good)."""

    problem: str | None

    def step(self, i: int, frame: Frame, filt: Filter, est: Estimate, trace: RunTrace) -> None: ...

    def close(self, trace: RunTrace) -> None: ...

    def report(self) -> str: ...


@dataclass
class LiveView:
    """The observer for :func:`pfslam.pipeline.run_filter`: records the trace, then tells each view."""

    trace: RunTrace
    views: list[View] = field(default_factory=list)

    def __call__(self, i: int, frame: Frame, filt: Filter, est: Estimate) -> None:
        self.trace.add(i, filt, est)
        for v in self.views:
            v.step(i, frame, filt, est, self.trace)

    def close(self) -> None:
        """Close every view (also after one failed to: the first error is raised at the end)."""
        first: BaseException | None = None
        for v in self.views:
            try:
                v.close(self.trace)
            except BaseException as e:  # noqa: BLE001 - close the others, then raise it
                first = first or e
        if first is not None:
            raise first


@dataclass(frozen=True)
class ViewRequest:
    """The views a command was asked for: ``video`` (.mp4/.gif) at ``fps``, the rerun viewer
    (``rerun``) and/or a rerun recording (``rerun_save``, .rrd)."""

    video: Path | None = None
    fps: float | None = None
    rerun: bool = False
    rerun_save: Path | None = None

    def __bool__(self) -> bool:
        return self.video is not None or self.rerun or self.rerun_save is not None

    def check(self) -> None:
        """Before any work: the optional packages are installed, the names and the frame rate
        make sense, the files' folders exist (ConfigError / InputError, one line)."""
        if self.video is not None:
            from pfslam.views.video import check_video

            check_video(self.video, self.fps)
        elif self.fps is not None:
            from pfslam.errors import InputError

            raise InputError("--video-fps", "is the frame rate of --video, which was not given")
        if self.rerun or self.rerun_save is not None:
            from pfslam.views.rerunview import check_rerun

            check_rerun(self.rerun_save)

    def open(
        self,
        times: Array,
        truth: tuple[Array, Array] | None,
        ground_z: float,
        kind: str,
        title: str,
        truth_label: str = "ground truth",
        video_progress: Callable[[int, int], None] | None = None,
    ) -> LiveView:
        """The observer for a run over steps at ``times``; ``kind`` "slam" or "localization"
        (the localization map never changes, so it is drawn once)."""
        live = LiveView(RunTrace(times, truth, ground_z))
        static = kind == "localization"
        try:
            if self.video is not None:
                from pfslam.views.video import VideoRecorder

                live.views.append(
                    VideoRecorder(
                        self.video,
                        live.trace,
                        self.fps,
                        "SLAM" if kind == "slam" else "estimate",
                        truth_label,
                        title,
                        static,
                        video_progress,
                    )
                )
            if self.rerun or self.rerun_save is not None:
                from pfslam.views.rerunview import RerunLogger

                live.views.append(
                    RerunLogger(
                        live.trace, self.rerun, self.rerun_save, "SLAM" if kind == "slam" else "localization", static
                    )
                )
        except BaseException:
            live.close()  # what was opened (an empty video file is removed)
            raise
        return live
