"""Running a filter over a frame stream: the step loop that keeps what was done when stopped, and
the :class:`Run` it produces."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from pfslam.config import LocalizerConfig, SlamConfig, SlamFilter, is_concrete, resolve_filter
from pfslam.filters.base import SETTLED_SPREAD, Filter, position_std
from pfslam.filters.health import NO_STATE, HealthTrace, State
from pfslam.frames import Estimate, Frame
from pfslam.geometry import compose, relative
from pfslam.io.common import num
from pfslam.maps.grid import OccupancyGrid, map_from_poses
from pfslam.types import Array

if TYPE_CHECKING:
    from pfslam.backend.loops import LoopClosure
    from pfslam.pipeline.closing import BackendStep
    from pfslam.pipeline.sessions import Resume, Session

Progress = Callable[[int, int], None]
# Called after each step with (step index, frame, filter, estimate), e.g. to draw the run as it goes.
Observer = Callable[[int, Frame, Filter, Estimate], None]
Truth = tuple[Array, Array]  # (times, poses)


# -- running a filter --------------------------------------------------------------------


def stop_reason(e: BaseException, i: int, frame: Frame | None) -> tuple[bool, str | None]:
    """Why a run loop stopped at frame ``i``: (interrupted, error message or None).

    Ctrl-C inside a Numba kernel surfaces as a SystemError caused by the KeyboardInterrupt;
    that is an interruption too. Any other error becomes a one-line message naming the scan,
    so the caller can write what was computed before it and then report it."""
    while e is not None:
        if isinstance(e, KeyboardInterrupt):
            return True, None
        if not isinstance(e, SystemError):
            break
        e = e.__cause__ or e.__context__  # type: ignore[assignment]
    where = f"scan {i + 1}" + (f" (t={num(frame.t)})" if frame is not None else "")
    text = str(e).splitlines()[0] if str(e) else type(e).__name__
    return False, f"stopped at {where}: {text}"


JUMP_BREAK = 1.0  # m: localization.png leaves a gap where the estimate jumps this much beyond the odometry's step


@dataclass
class Run:
    """What a filter run produced, for the scans it processed (all of them unless it was
    stopped early by Ctrl-C or an error)."""

    kind: str  # "slam" or "localization"
    t: Array
    poses: Array  # the filter's trajectory
    odometry: Array  # dead reckoning, in the filter's frame
    particles: NDArray[np.int64]  # particle count after each step
    grid: OccupancyGrid  # the map built (SLAM) or used (localization)
    config: SlamConfig | LocalizerConfig
    seconds: float
    resamples: int
    updates: int  # steps that weighed a scan
    clouds: list[tuple[float, Array]] = field(default_factory=list)  # (time, particle poses) at a few moments
    metrics: dict[str, Any] = field(default_factory=dict)
    # Localization: per step, the estimate's (3, 3) covariance (NaN where none) and whether it weighed a scan.
    covariances: Array | None = None
    updated: NDArray[np.bool_] | None = None
    health: HealthTrace | None = None  # localization: each step's health (see pfslam.filters.health)
    interrupted: bool = False  # stopped early (Ctrl-C): the results cover the scans done
    error: str | None = None  # stopped early by an error (the message): the results cover the scans done
    filter_info: dict[str, Any] = field(default_factory=dict)  # which filter, and what it counted
    # The loop-closing back end's step (SLAM with backend: graph): what it found, whether its
    # answer was kept; ``closure`` is its closure when the run's trajectory is the back end's.
    backend: BackendStep | None = None
    frames: Sequence[Frame] = ()  # the frames the filter stepped (SLAM: for the steps after it)
    notes: list[str] = field(default_factory=list)  # what the user must hear about the run (warnings)
    # Seconds of each phase of the command (start-up and imports, load, filter, back end, score,
    # write): the whole process's time, beside the filter loop's ``seconds``.
    phases: dict[str, float | None] = field(default_factory=dict)
    # SLAM: the session it leaves (for --resume), and the one it continued (None: a new map).
    session: Session | None = None
    resumed: Resume | None = None

    @property
    def closure(self) -> LoopClosure | None:
        """The back end's closure when the run's trajectory and map are its own."""
        return self.backend.closure if self.backend is not None and self.backend.kept else None

    @property
    def backend_seconds(self) -> float:
        return self.backend.seconds if self.backend is not None else 0.0

    @property
    def scans(self) -> int:
        return len(self.t)

    @property
    def scans_per_second(self) -> float:
        return self.scans / self.seconds if self.seconds > 0 else float("inf")

    @property
    def real_time_factor(self) -> float:
        span = float(self.t[-1] - self.t[0]) if len(self.t) > 1 else 0.0
        return span / self.seconds if self.seconds > 0 else float("inf")


@dataclass
class _Steps:
    """Per-step records of a run, preallocated for ``n`` steps."""

    odometry: Array
    particles: NDArray[np.int64]
    spread: Array  # position standard deviation of the estimate (m); NaN where the filter gives none
    covariance: Array  # (n, 3, 3) covariance of the estimate; NaN where the filter gives none
    updated: NDArray[np.bool_]  # the step weighed a scan
    seconds: Array  # each step's seconds
    health: HealthTrace  # localization: each step's health (NaN / no state for SLAM)
    done: int = 0
    resamples: int = 0
    updates: int = 0


def run_filter(
    filt: Filter,
    frames: Sequence[Frame],
    progress: Progress | None = None,
    snapshots: int = 0,
    observer: Observer | None = None,
) -> tuple[_Steps, list[tuple[float, Array]], float, bool, str | None]:
    """Step ``filt`` through ``frames``; stop early, keeping what was done, on Ctrl-C or an
    error. ``snapshots`` particle clouds are kept at evenly spread moments (filters with a
    ``particles`` set). ``observer(i, frames[i], filt, estimate)`` is called after each step
    (an error it raises stops the run like the filter's own). Returns (the per-step records,
    the clouds, the filter's seconds (the observer's time left out), interrupted, error)."""
    n = len(frames)
    steps = _Steps(
        np.empty((n, 3)),
        np.empty(n, dtype=np.int64),
        np.full(n, np.nan),
        np.full((n, 3, 3), np.nan),
        np.zeros(n, dtype=bool),
        np.zeros(n),
        HealthTrace.empty(n),
    )
    marks = set(np.linspace(0, n - 1, snapshots).round().astype(int).tolist()) if snapshots and n else set()
    clouds: list[tuple[float, Array]] = []
    interrupted, error = False, None
    watching = 0.0  # seconds spent in the observer
    start = time.perf_counter()
    i, frame = 0, None
    try:
        for i, frame in enumerate(frames):
            # (asked only when a cloud is kept: the Rao-Blackwellized filter builds its set anew)
            if i in marks and (particles := filt.particles) is not None:
                clouds.append((frame.t, particles.poses.copy()))
            began = time.perf_counter()
            est = filt.step(frame)
            steps.seconds[i] = time.perf_counter() - began
            steps.odometry[i] = filt.odom_pose
            steps.particles[i] = est.particles
            if est.covariance is not None:
                steps.spread[i] = position_std(est.covariance)
                steps.covariance[i] = est.covariance
            steps.updated[i] = est.updated
            if est.health is not None:
                steps.health.record(i, est.health)
            steps.resamples += int(est.resampled)
            steps.updates += int(est.updated)
            steps.done = i + 1
            if observer is not None:
                t_obs = time.perf_counter()
                observer(i, frame, filt, est)
                watching += time.perf_counter() - t_obs
            if progress is not None and (i % 50 == 0 or i == n - 1):
                progress(i + 1, n)
    except (KeyboardInterrupt, Exception) as e:  # keep what was computed; the caller writes it, then reports
        interrupted, error = stop_reason(e, i, frame)
    return steps, clouds, time.perf_counter() - start - watching, interrupted, error


def make_slam(config: SlamConfig, log_format: str | None = None, resume: Resume | None = None) -> Filter:
    """The SLAM filter ``pfslam slam`` runs for ``config`` on a log of ``log_format`` (None: not
    known; ``config`` made concrete for it if it is not, see :func:`concrete`): the single-map
    filter or the Rao-Blackwellized one (``filter: auto``: the latter, unless the local search
    is on); with ``resume``, starting where it says in its session's map."""
    config = concrete(config, log_format)
    start, prior = (resume.start, resume.session.grid) if resume is not None else (None, None)
    if config.filter == SlamFilter.RBPF:
        from pfslam.filters.rbpf import RaoBlackwellizedSlam

        return RaoBlackwellizedSlam(config, start=start, prior=prior)
    from pfslam.filters.single import SingleMapSlam

    return SingleMapSlam(config, start=start, prior=prior)


def concrete(config: SlamConfig, log_format: str | None = None) -> SlamConfig:
    """``config`` as it runs on a log of ``log_format``: kept if it is concrete already (as the
    commands make it, once, when the log is loaded), else made so
    (:func:`~pfslam.config.resolve_filter`)."""
    return config if is_concrete(config) else resolve_filter(config, log_format)


def run_slam(
    frames: Sequence[Frame],
    config: SlamConfig,
    progress: Progress | None = None,
    observer: Observer | None = None,
    log_format: str | None = None,
    resume: Resume | None = None,
) -> Run:
    """Run the SLAM filter :func:`make_slam` picks over every ``config.every``-th frame
    (``observer``: see :func:`run_filter`; its index counts the frames stepped): the filter's
    run, before any loop closing (:func:`~pfslam.pipeline.closing.close_loops`, the next step)
    and the session it leaves (:func:`~pfslam.pipeline.sessions.leave_session`). ``config``:
    made concrete for ``log_format`` if it is not (:func:`concrete`); the run's config is the
    one the filter ran with. ``resume``: the session it continues (see
    :mod:`~pfslam.pipeline.sessions`)."""
    config = concrete(config, log_format)
    slam = make_slam(config, resume=resume)
    stepped = frames[:: config.every]
    steps, _, seconds, interrupted, error = run_filter(slam, stepped, progress, observer=observer)
    k = steps.done
    t, poses = (x[:k] for x in slam.trajectory())
    run = Run(
        "slam",
        t,
        poses,
        steps.odometry[:k],
        steps.particles[:k],
        slam.map,
        config,
        seconds,
        steps.resamples,
        steps.updates,
        interrupted=interrupted,
        error=error,
    )
    run.frames, run.resumed = stepped[:k], resume
    if k and (steps.health.state[:k] != NO_STATE).any():
        run.health = steps.health.cut(k)
        run.updated = steps.updated[:k]
        run.metrics["health"] = health = run.health.summary(t, steps.updated[:k])
        run.notes += health_notes(health, "the SLAM run")
    run.filter_info = {
        "filter": str(config.filter),
        "particles": config.particles,
        "slowest_scan_ms": 1e3 * float(steps.seconds.max(initial=0.0)),
        "p99_scan_ms": 1e3 * float(np.percentile(steps.seconds[: steps.done], 99)) if steps.done else 0.0,
        **slam.diagnostics(),
    }
    blind = run.filter_info.get("longest_blind")
    if isinstance(blind, dict) and blind["metres"] >= BLIND_WARN_M and k:
        run.notes.append(
            f"for {blind['metres']:.0f} m ({blind['from_t'] - t[0]:.0f}-{blind['to_t'] - t[0]:.0f} s after the first "
            f"scan; {run.filter_info['blind_m']:.0f} m in all) the scans held too few hits within "
            f"{config.rbpf.map_range:g} m to pin the pose: there the path is the odometry's guess (less the errors "
            "the matched scans showed it to have), and the health cannot judge it"
        )
    run.notes += reacquire_notes(run.filter_info.get("reacquired"))
    return run


def reacquire_notes(records: object) -> list[str]:
    """What the filter's searches after blind stretches (:mod:`pfslam.filters.reacquire`) say a
    user must know: the stretches it found itself after (how far it moved), and, loudly, those
    it could not (the path after them may be as far off as the stretch drifted)."""
    if not isinstance(records, list):
        return []
    found = [r for r in records if r.get("found")]
    lost = [r for r in records if r.get("gave_up")]
    if records and not records[-1].get("found") and not records[-1].get("gave_up"):
        lost.append(records[-1])  # the log ended while the filter was still searching
    out = []
    if found:
        moves = ", ".join(f"{r['moved_m']:.1f} m / {r['turned_deg']:.1f}°" for r in found)
        out.append(
            f"after {len(found)} blind stretch(es) the filter found itself again in its own map and bent the "
            f"stretch to it (moved {moves})"
        )
    if lost:
        why = "; ".join(f"{r['adrift_m']:.0f} m: {r['why']}" for r in lost)
        out.append(
            f"after {len(lost)} blind stretch(es) the filter could not find itself again in its own map ({why}): "
            "the path after it may be as far off as the odometry drifted there"
        )
    return out


def run_localization(
    frames: Sequence[Frame],
    grid: OccupancyGrid,
    config: LocalizerConfig,
    initial: tuple[Array, Array] | None,
    progress: Progress | None = None,
    snapshots: int = 4,
    observer: Observer | None = None,
) -> Run:
    """Localize a frame stream on ``grid``: around ``initial`` = (pose, std), or globally if
    None (``observer``: see :func:`run_filter`)."""
    from pfslam.filters.localize import Localizer

    loc = Localizer(grid, config)
    if initial is None:
        loc.initialize_global()
    else:
        loc.initialize_around(*initial)
    steps, clouds, seconds, interrupted, error = run_filter(loc, frames, progress, snapshots, observer)
    k = steps.done
    t, poses = (x[:k] for x in loc.trajectory())
    odom = steps.odometry[:k]
    # Draw the odometry from the first moment the estimate is settled (for a global start
    # the first estimates are guesses), so the two can be compared by eye.
    settled = np.nonzero(steps.spread[:k] < SETTLED_SPREAD)[0]
    a = int(settled[0]) if len(settled) else 0
    if k:
        odom = compose(poses[a], relative(odom[a], odom))
    info = {
        "filter": "mcl",
        "global_start": initial is None,
        "first_particles": int(steps.particles[0]) if k else 0,
        **loc.diagnostics(),
    }
    run = Run(
        "localization",
        t,
        poses,
        odom,
        steps.particles[:k],
        grid,
        config,
        seconds,
        steps.resamples,
        steps.updates,
        clouds,
        covariances=steps.covariance[:k],
        updated=steps.updated[:k],
        health=steps.health.cut(k),
        interrupted=interrupted,
        error=error,
        filter_info=info,
    )
    run.metrics["uncertainty"] = uncertainty_summary(run)
    if k and run.health is not None:
        run.metrics["health"] = health = run.health.summary(t, steps.updated[:k])
        run.notes += health_notes(health)
    run.filter_info["settle"] = settle_summary(t, steps.spread[:k], steps.odometry[:k])
    thr, rose = spread_rose(steps.spread[:k])
    run.filter_info["spread_rose"] = {
        "threshold_m": thr,
        "stretches": int(np.count_nonzero(np.diff(np.r_[0, rose.astype(np.int8)]) == 1)),
        "seconds": float(np.sum(np.diff(t)[rose[:-1]])) if k > 1 else 0.0,
    }
    return run


# Why a run ends in each state, per kind of run (a state missing: nothing to say)
END_REASONS: dict[str, dict[str, str]] = {
    "the localization": {
        State.LOST.value: "its last scans contradict the map at the estimate: the estimate is not where the robot is",
        State.DEGRADED.value: "its last scans fit the map at the estimate only in part: the estimate may be off",
        State.AMBIGUOUS.value: "its particles still share look-alike places: the estimate is one of them",
    },
    "the SLAM run": {
        State.LOST.value: "its last scans contradict its own map: the path or the map broke near the end",
        State.DEGRADED.value: "its last scans fit its own map only in part: the path may have slipped near the end",
    },
}


def health_notes(health: dict[str, Any], who: str = "the localization") -> list[str]:
    """What the user must hear of a run's health (run.json's ``metrics.health``; ``who``: a key
    of :data:`END_REASONS`): one line if it ends in a state with a reason; for SLAM also if it
    was lost on the way (a stretch where its map and its path broke, which the end may not show)."""
    end = health.get("final_state")
    first = health.get("first_lost_s")
    low = health.get("lowest_quality")
    when = f"; first lost {first:.1f} s after the first scan" if first is not None else ""
    why = END_REASONS[who].get(str(end))
    if why is not None:
        return [f"{who} ends {end}: {why} (lowest quality {low}{when})"]
    lost_s = float(health.get("seconds_in_state", {}).get(State.LOST.value, 0.0))
    if who == "the SLAM run" and lost_s > 0:
        return [
            f"the SLAM run was lost for {lost_s:.1f} s (scans contradicting its own map; lowest quality {low}{when}): "
            "the map and the path may be broken there (see health.csv and the map's marks)"
        ]
    return []


BLIND_WARN_M = 10.0  # m: a blind stretch this long is worth a warning (see RaoBlackwellizedSlam.blind_m)


FIRST_MOTION = 0.02  # m (and rad): the odometry has moved once it is this far from its first pose


def settle_summary(t: Array, spread: Array, odometry: Array) -> dict[str, Any]:
    """When the estimate settled: from the first step after which its position spread stayed
    below :data:`~pfslam.filters.base.SETTLED_SPREAD` (where it has one), ``seconds``
    after the robot's first motion by its odometry (0 if the cloud settled before the robot
    moved; counted from the first scan if the robot never moved) and ``at_s`` after the
    first scan. None for both if it never settled."""
    if not len(t):
        return {"seconds": None, "at_s": None}
    unsettled = np.nonzero(~(spread < SETTLED_SPREAD) & np.isfinite(spread))[0]
    k = int(unsettled[-1]) + 1 if len(unsettled) else 0
    if k >= len(t) or not np.isfinite(spread[k:]).any():
        return {"seconds": None, "at_s": None}
    start = first_motion_time(t, odometry)
    return {"seconds": float(max(t[k] - start, 0.0)), "at_s": float(t[k] - t[0])}


def first_motion_time(t: Array, odometry: Array) -> float:
    """The time of the first step at which the odometry is :data:`FIRST_MOTION` from its
    first pose (the first time if it never moves)."""
    d = relative(odometry[0], odometry)
    moved = np.nonzero((np.hypot(d[:, 0], d[:, 1]) > FIRST_MOTION) | (np.abs(d[:, 2]) > FIRST_MOTION))[0]
    return float(t[moved[0]] if len(moved) else t[0])


def spread_rose(spread: Array) -> tuple[float | None, NDArray[np.bool_]]:
    """(threshold m, which steps exceed it): where the estimate's own uncertainty rose,
    i.e. its position spread exceeded twice its median over the settled steps (at most
    :data:`~pfslam.filters.base.SETTLED_SPREAD`). (None, all False) without a settled step."""
    settled = spread[spread < SETTLED_SPREAD]
    if not len(settled):
        return None, np.zeros(len(spread), bool)
    thr = float(min(2.0 * np.median(settled), SETTLED_SPREAD))
    return thr, np.nan_to_num(spread, nan=0.0) > thr


def uncertainty_summary(run: Run) -> dict[str, Any]:
    """Figures of the estimate's covariance over the steps that weighed a scan: how many,
    and the median, largest and last position standard deviation (m, sqrt(var x + var y))
    and heading standard deviation (deg). None for the figures of a run without updates."""
    cov = updated_covariances(run)[2]
    pos = np.sqrt(np.maximum(cov[:, 0, 0] + cov[:, 1, 1], 0.0))
    head = np.rad2deg(np.sqrt(np.maximum(cov[:, 2, 2], 0.0)))
    out: dict[str, Any] = {"updates": len(cov)}
    for name, v in (("position_std_m", pos), ("heading_std_deg", head)):
        some = len(v) > 0
        out.update(
            {
                f"{name}_median": float(np.median(v)) if some else None,
                f"{name}_max": float(v.max()) if some else None,
                f"{name}_last": float(v[-1]) if some else None,
            }
        )
    return out


def updated_covariances(run: Run) -> tuple[Array, Array, Array]:
    """(times, poses, covariances) of the steps of ``run`` that weighed a scan and have a covariance."""
    if run.covariances is None or run.updated is None:
        return np.empty(0), np.empty((0, 3)), np.empty((0, 3, 3))
    keep = run.updated & np.isfinite(run.covariances).all(axis=(1, 2))
    return run.t[keep], run.poses[keep], run.covariances[keep]


def build_map(frames: Sequence[Frame], poses: Array, config: SlamConfig | None = None) -> OccupancyGrid:
    """Map a frame stream from known poses (mapping only, no filter): ground truth or a
    reference (:func:`~pfslam.maps.grid.map_from_poses`, every scan in full)."""
    return map_from_poses(frames, poses, config)
