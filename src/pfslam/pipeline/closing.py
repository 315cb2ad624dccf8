"""The loop-closing back end as a step of ``pfslam slam`` after the filter's (``backend:
graph``): the loops closed over the filter's finished run, the map drawn anew from the closed
trajectory, and the check that keeps the back end's answer only where it makes the map agree
at least as well as the filter's alone."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from pfslam.backend.settings import BackendSettings
from pfslam.config import Backend, SlamConfig
from pfslam.frames import Frame
from pfslam.maps.grid import OccupancyGrid, map_from_poses
from pfslam.types import Array

if TYPE_CHECKING:
    from pfslam.backend.loops import LoopClosure
    from pfslam.pipeline.run import Progress, Run
    from pfslam.pipeline.sessions import Session


def close_loops(run: Run, progress: Progress | None = None) -> Run:
    """The back end over ``run``, the filter's (``progress``: its bar, one tick per submap
    searched): with ``backend: graph`` and a run of two scans or more that was neither
    stopped nor failed, the loops are closed (:func:`run_backend`) and, where the check keeps
    them, the run's trajectory and map become the back end's. What it found and why it was or
    was not kept go into ``run.backend`` and ``run.notes``. Returns ``run``."""
    config = run.config
    if not isinstance(config, SlamConfig) or config.backend != Backend.GRAPH:
        return run
    if run.scans <= 1 or run.interrupted or run.error is not None:
        # (a run stopped early keeps the filter's answer: the user asked it to stop, or it could not go on)
        return run
    before = run.resumed.session if run.resumed is not None else None
    step, closed = run_backend(run.frames, run.poses, config, progress, before)
    run.backend = step
    if step.kept and step.closure is not None:
        if closed is not None:
            run.grid = closed
        run.poses = step.closure.poses
    if step.note is not None:
        run.notes.append(step.note)
    run.interrupted = step.interrupted
    return run


@dataclass
class BackendStep:
    """The loop-closing back end's step of a SLAM run: its closure (None if it failed or was
    stopped), the seconds it took (search, solve, map and check), the map agreement of the
    filter's trajectory and of the back end's when they were compared, and whether the run
    keeps the back end's answer (``note`` says why not)."""

    closure: LoopClosure | None
    seconds: float
    agreement_filter: float | None = None
    agreement_backend: float | None = None
    agreement_se: float | None = None  # the standard error of their difference
    kept: bool = False
    interrupted: bool = False
    note: str | None = None

    def as_dict(self) -> dict[str, Any]:
        """``run.json``'s ``backend``: the closure's figures, the check and the seconds."""
        stats = self.closure.stats.as_dict() if self.closure is not None else {}
        return {
            **stats,
            "map_agreement_filter": self.agreement_filter,
            "map_agreement_backend": self.agreement_backend,
            "map_agreement_change_se": self.agreement_se,
            "kept": self.kept,
            "seconds": self.seconds,
        }

    def agreement_of_result(self) -> float | None:
        """The map agreement of the trajectory the run keeps, if the check computed it."""
        return self.agreement_backend if self.kept else self.agreement_filter


def run_backend(
    frames: Sequence[Frame],
    poses: Array,
    config: SlamConfig,
    closing: Progress | None = None,
    before: Session | None = None,
) -> tuple[BackendStep, OccupancyGrid | None]:
    """The loop-closing back end over a finished filter run (``frames`` the frames it stepped,
    ``poses`` its trajectory): the loops closed (:func:`~pfslam.backend.loops.close_loops`), the
    map re-drawn from the new trajectory, and, with ``graph.check_agreement``, the map
    agreement of both trajectories compared: a back end that makes the map agree less (by more
    than the figure's noise) is tried again with its near loops only
    (:func:`~pfslam.backend.loops.local_closure`), and failing that not kept: the filter's answer
    stands. ``note`` says which. Ctrl-C and errors inside it keep the filter's answer too.
    ``before``: the session a resumed run continues (its nodes held, its map the base).
    Returns the step and the back end's map (None if not kept)."""
    from concurrent.futures import ThreadPoolExecutor

    from pfslam.backend import loops

    began = time.perf_counter()
    step = BackendStep(None, 0.0)
    grid = None
    # The filter's side of the check needs only its trajectory: it is worked out beside the
    # search (whose single-threaded parts leave a core idle), and dropped if no loop is found.
    aside = ThreadPoolExecutor(1)
    try:
        pending = aside.submit(_AgreementCheck, frames, poses) if config.graph.check_agreement else None
        settings = BackendSettings.of(config)
        closure = loops.close_loops(frames, poses, settings, closing, before.nodes if before is not None else None)
        step.closure = closure
        if not closure.loops:  # its answer is the filter's trajectory and map, to the bit
            step.kept = True
        else:
            check = pending.result() if pending is not None else None
            worse = check is not None and check.worse(closure.poses, step)
            if worse and check is not None:
                full = closure.stats
                near = loops.local_closure(closure, poses, settings)
                if near is not None and not check.worse(near.poses, step):
                    step.closure = closure = near
                    step.note = (
                        f"loop closing kept its {near.stats.loops_in_graph} near loops only: with "
                        f"{full.loops_in_graph} loops, {near.stats.refused_far} of them far from where the "
                        f"filter was, the map agreed less than the filter's alone"
                    )
                    worse = False
            if worse:
                s = closure.stats
                step.note = (
                    f"loop closing not kept: its {s.loops_in_graph} loops make the map agree less "
                    f"({step.agreement_backend:.3f}) than the filter's alone ({step.agreement_filter:.3f}, "
                    f"+-{step.agreement_se or 0.0:.3f}), so the results are the filter's (all "
                    f"{s.loops_in_graph + s.refused} loops refused: {s.refusals()}, "
                    f"{s.loops_in_graph} by this check)"
                )
            else:
                base = before.grid if before is not None else None
                grid = map_from_poses(frames, closure.poses, config, as_filter=True, base=base)
                step.kept = True
    except KeyboardInterrupt:
        step.closure, step.kept, step.interrupted = None, False, True
        step.note = "loop closing interrupted: the results are the filter's, without it"
    except Exception as e:  # the filter's answer is not lost to a failure behind it
        first = str(e).splitlines()[0] if str(e) else type(e).__name__
        step.closure, step.kept = None, False
        step.note = f"loop closing failed ({first}): the results are the filter's, without it"
    finally:
        aside.shutdown(wait=False, cancel_futures=True)
    step.seconds = time.perf_counter() - began
    return step, grid


# The map agreement's own noise beside the standard error of the change: the same trajectory
# scores up to 1.5 % more or less as the map's cells shift by half a cell (four shifts measured
# on simulated walks, where the ground truth itself scored 1.2 % below the filter's answer at
# the map's own shift, and 0.6 % above it over the four); a filter's answer, drawn on that
# grid, has the grid's luck built in.
AGREEMENT_PHASE_NOISE = 0.015


class _AgreementCheck:
    """The map agreement (:func:`~pfslam.eval.metrics.map_agreement`) of the filter's trajectory
    over ``frames``, against which a back end's trajectory is checked."""

    def __init__(self, frames: Sequence[Frame], front: Array) -> None:
        from pfslam.eval.metrics import agreement_points

        self.frames = frames
        self.points = agreement_points(frames)
        self.front = self._fractions(front)

    def _fractions(self, poses: Array) -> list[Array | None] | None:
        from pfslam.eval.metrics import agreement_fractions
        from pfslam.maps.grid import MapTooLarge

        try:
            return agreement_fractions(self.frames, poses, points=self.points)
        except MapTooLarge:  # a trajectory beyond the largest map
            return None

    def worse(self, poses: Array, step: BackendStep) -> bool:
        """Whether ``poses`` make the map agree less than the filter's trajectory by more than
        the figure's own noise: two standard errors of the change
        (:func:`~pfslam.eval.metrics.agreement_change`) and :data:`AGREEMENT_PHASE_NOISE`. Both
        figures and the error go into ``step``."""
        from pfslam.eval.metrics import agreement_change, agreement_of

        back = self._fractions(poses)

        def finite(v: float) -> float | None:
            return v if np.isfinite(v) else None

        step.agreement_filter = finite(agreement_of(self.front)) if self.front is not None else None
        step.agreement_backend = finite(agreement_of(back)) if back is not None else None
        step.agreement_se = None
        if self.front is None or back is None or step.agreement_filter is None or step.agreement_backend is None:
            return False  # (cannot be checked: the back end's answer stands)
        step.agreement_se = finite(agreement_change(self.front, back)[1])
        drop = step.agreement_filter - step.agreement_backend
        return drop > 2.0 * (step.agreement_se or 0.0) + AGREEMENT_PHASE_NOISE
