"""How a run talks to a person and how it ended: the :class:`Reporter` it tells (the command
line's prints; :class:`Quiet` keeps), and the :class:`Outcome` it returns."""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, ContextManager, Iterator, Protocol, TypeVar

from pfslam.eval.table import WITHIN_M
from pfslam.pipeline.run import (
    Progress,
    Run,
)
from pfslam.pipeline.score import Scores

if TYPE_CHECKING:
    from pfslam.tools.calibrate import Calibration

T = TypeVar("T")
Bars = list[tuple[str, int, str]]  # (label, total, unit counted) per progress bar


class Reporter(Protocol):
    """Where a run tells a person what happens: warnings, lines to show (``say``: results;
    ``note``: what is being done), the calibration it measured, its figures, and progress bars (one per (label, total, unit), each moved by
    the (done, total) callback the context gives)."""

    def warn(self, text: str) -> None: ...

    def say(self, text: str) -> None: ...

    def note(self, text: str) -> None: ...

    def calibration(self, cal: Calibration) -> None: ...

    def scores(self, scores: Scores) -> None: ...

    def progress(self, bars: Bars) -> ContextManager[list[Progress]]: ...


class Quiet:
    """A :class:`Reporter` for scripts and tests: keeps the warnings and lines, shows nothing."""

    def __init__(self) -> None:
        self.warnings: list[str] = []
        self.lines: list[str] = []

    def warn(self, text: str) -> None:
        self.warnings.append(text)

    def say(self, text: str) -> None:
        self.lines.append(text)

    def note(self, text: str) -> None:
        self.lines.append(text)

    def calibration(self, cal: Calibration) -> None:
        pass

    def scores(self, scores: Scores) -> None:
        pass

    @contextlib.contextmanager
    def progress(self, bars: Bars) -> Iterator[list[Progress]]:
        yield [lambda done, total: None for _ in bars]


@dataclass
class Outcome:
    """How a run ended: the :class:`Run` (``error``/``interrupted`` say if it stopped early),
    its figures, where its results are, and the stop signals received while they were written."""

    run: Run
    scores: Scores
    out: Path
    log: object = None  # the log it ran on (for messages)
    signals: list[int] = field(default_factory=list)

    def summary(self) -> str:
        """One line on what was done, for a run that ended normally."""
        run = self.run
        speed = f"{run.scans} scans in {run.seconds:.1f} s ({run.scans_per_second:.0f} scans/s, "
        if run.kind == "slam":
            loops = ""
            if run.backend is not None and run.backend.closure is not None:
                b = run.backend.closure.stats
                loops = (
                    f"; loop closing: {b.loops_in_graph} loops over {b.nodes} nodes ({b.refused} refused: "
                    f"{b.refusals()})"
                    f"{'' if run.backend.kept else ', not kept'}, {run.backend_seconds:.1f} s"
                )
            return f"{speed}{run.real_time_factor:.1f}x real time){loops}{self._health()}; results in {self.out}/"
        counts = f"particles {run.particles[0]} -> {run.particles[-1]}" if run.scans else ""
        return f"{speed}{run.updates} updates, {counts}){self._health()}{self._on_the_robot()}; results in {self.out}/"

    def _health(self) -> str:
        """A run's health in a few words: the share of its time tracking, the time
        lost if any, the lowest quality ("" without a health)."""
        h = self.run.metrics.get("health")
        if not h:
            return ""
        sec = h["seconds_in_state"]
        total = sum(sec.values())
        share = 100.0 * sec["tracking"] / total if total > 0 else 100.0
        lost = f", lost {sec['lost']:.1f} s" if sec["lost"] > 0 else ""
        return f"; health: tracking {share:.0f} % of the time{lost}, lowest quality {h['lowest_quality']}"

    def _on_the_robot(self) -> str:
        """A localization scored against a ground truth: from when it stayed on the robot,
        or that it ended off it ("" without a truth)."""
        est = self.run.metrics.get("estimate") or {}
        if "within_after_s" not in est:
            return ""
        w, m = est["within_after_s"], est.get("within_m", WITHIN_M)
        if w is None:
            return f"; ENDED MORE THAN {m:g} m OFF THE GROUND TRUTH"
        return f"; within {m:g} m of the ground truth from {w:.1f} s after the first motion on"
