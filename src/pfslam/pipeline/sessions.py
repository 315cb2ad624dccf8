"""Sessions, all in one place: a SLAM run's map kept on disk so that a later log can continue
it (``pfslam slam LOG --resume DIR``). Here the session is made from a run
(:func:`leave_session`), written and read (:func:`save_session`, :func:`load_session`: the only
code that touches its files), and continued: the settings fitted to its map and the new log's
start placed in it, given or found (:func:`continued`, :class:`StartMode`).

A session is what the next run needs and nothing it can do without: the map's log-odds (not
the trinary ``map.pgm``), the graph's nodes with their scans (the hits that make a submap and
the points matched against them, so the submaps are rebuilt without the old log), the pose
graph's edges with the loops marked, the settings and a format version. Plain files: a JSON
description and one NumPy ``.npz`` (read without pickle). Points are stored in millimetres
as 16-bit integers (hits within +-32 m of the robot: a lidar's reach), the map as float32.

The nodes of every run a session has seen are kept, each marked with its run (0 for the
first log, 1 for the log that resumed it, ...): a resumed run holds them where they are and
adds its own.
"""

from __future__ import annotations

import enum
import json
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
from numpy.typing import NDArray

from pfslam.backend.edges import loop_information
from pfslam.backend.graph import PoseGraph
from pfslam.backend.loops import LoopClosure, build_graph
from pfslam.backend.nodes import Nodes, SessionNodes, frame_scans, own_nodes, select_nodes
from pfslam.backend.search import start_tie
from pfslam.backend.settings import BackendSettings
from pfslam.config import SlamConfig, to_dict
from pfslam.errors import InputError
from pfslam.frames import Frame
from pfslam.maps.grid import OccupancyGrid
from pfslam.sensor import one_per_cell, scan_to_points
from pfslam.types import Array

if TYPE_CHECKING:
    from pfslam.backend.start import StartSearch
    from pfslam.pipeline.report import Reporter
    from pfslam.pipeline.run import Run


class StartMode(enum.Enum):
    """Where a run's first scan is placed: a new map (``none``: at the odometry's first pose),
    or in a session's map at a pose ``given`` (``--start``) or ``found`` by a global search."""

    NONE = "none"
    GIVEN = "given"
    FOUND = "found"


# -- the files --------------------------------------------------------------------------------

FORMAT = "pfslam-session"
VERSION = 1  # the format written; a session of a newer version is refused
FOLDER = "session"  # the session's folder inside a run's output folder
DESCRIPTION = "session.json"
ARRAYS = "session.npz"
MM = 1000.0  # stored points: integer millimetres
REACH_MM = 32_000  # |x|, |y| of a stored point at most (int16)


@dataclass
class Session:
    """A session (see the module notes): the map, the nodes, the graph's edges (indices into
    the nodes), the settings the runs used (``pfslam dump-config``'s ``slam`` section as a
    dict) and what each run was (log, scans, nodes, start)."""

    grid: OccupancyGrid
    nodes: SessionNodes
    graph: PoseGraph
    settings: dict[str, Any]
    runs: list[dict[str, Any]] = field(default_factory=list)

    @property
    def next_run(self) -> int:
        """The run number of a log that resumes this session."""
        return int(self.nodes.run.max()) + 1 if len(self.nodes) else len(self.runs)


def _packed(parts: Sequence[NDArray[np.floating]]) -> tuple[NDArray[np.int16], NDArray[np.int64]]:
    """Point sets as one int16 array of millimetres and the offsets of each set."""
    sizes = [len(p) for p in parts]
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    if not parts or offsets[-1] == 0:
        return np.zeros((0, 2), dtype=np.int16), offsets
    mm = np.round(np.concatenate([np.asarray(p, dtype=float).reshape(-1, 2) for p in parts]) * MM)
    return np.clip(mm, -REACH_MM, REACH_MM).astype(np.int16), offsets


def _unpacked(mm: NDArray[np.int16], offsets: NDArray[np.int64]) -> list[NDArray[np.float32]]:
    pts = (mm.astype(np.float32) / np.float32(MM)).reshape(-1, 2)
    return [pts[a:b] for a, b in zip(offsets[:-1], offsets[1:])]


def within_reach(points: NDArray[np.floating]) -> NDArray[np.floating]:
    """The points a session can store (within +-32 m of the robot on both axes)."""
    p = np.asarray(points).reshape(-1, 2)
    return p[(np.abs(p) < REACH_MM / MM).all(axis=1)]


def save_session(folder: str | Path, session: Session, extra: dict[str, Any] | None = None) -> Path:
    """Write ``session`` into ``folder`` (made if missing): session.json and session.npz."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    n = session.nodes
    g = session.grid
    points, point_at = _packed(n.points)
    hits, hit_at = _packed(n.hits)
    floor, floor_at = _packed(n.floor)
    arrays: dict[str, Any] = {
        "logodds": g.logodds.astype(np.float32),
        "origin": np.asarray(g.origin, dtype=float),
        "node_poses": n.poses,
        "node_info": n.info,
        "node_sensor": n.sensor,
        "node_times": n.times,
        "node_run": n.run.astype(np.int64),
        "points": points,
        "point_offsets": point_at,
        "hits": hits,
        "hit_offsets": hit_at,
        "floor": floor,
        "floor_offsets": floor_at,
        "edge_i": session.graph.i,
        "edge_j": session.graph.j,
        "edge_z": session.graph.z,
        "edge_info": session.graph.info,
        "edge_loop": session.graph.loop,
    }
    with open(folder / ARRAYS, "wb") as f:
        np.savez_compressed(f, **arrays)
    description = {
        "format": FORMAT,
        "version": VERSION,
        "map": {
            "resolution": g.resolution,
            "l_occ": g.l_occ,
            "l_free": g.l_free,
            "l_clamp": g.l_clamp,
            "shape": list(g.shape),
        },
        "nodes": len(n),
        "edges": len(session.graph.i),
        "loops": session.graph.loops,
        "runs": session.runs,
        "settings": session.settings,
        **(extra or {}),
    }
    (folder / DESCRIPTION).write_text(json.dumps(description, indent=2, allow_nan=False))
    return folder


def session_folder(path: str | Path) -> Path | None:
    """The session folder ``path`` names: ``path`` itself if it holds a session, else its
    ``session`` folder (a run's output folder); None if neither does."""
    path = Path(path)
    for cand in (path, path / FOLDER):
        if (cand / DESCRIPTION).is_file():
            return cand
    return None


def load_session(path: str | Path) -> Session:
    """The session in ``path`` (a session folder, or a run's output folder holding one); an
    :class:`~pfslam.errors.InputError` naming the folder and the problem if there is none, it
    is of a newer format, or it is broken."""
    path = Path(path)
    if not path.exists():
        raise InputError(path, "no such folder (give the output folder of an earlier pfslam slam run)")
    folder = session_folder(path)
    if folder is None:
        raise InputError(path, f"holds no session ({FOLDER}/{DESCRIPTION}: written by pfslam slam since version 0.9)")
    try:
        desc = json.loads((folder / DESCRIPTION).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise InputError(folder / DESCRIPTION, f"cannot be read ({e})") from None
    if not isinstance(desc, dict) or desc.get("format") != FORMAT:
        raise InputError(folder / DESCRIPTION, "is not a pfslam session")
    version = desc.get("version")
    if not isinstance(version, int) or version < 1:
        raise InputError(folder / DESCRIPTION, f"has no valid format version ({version!r})")
    if version > VERSION:
        raise InputError(
            folder / DESCRIPTION,
            f"was written by a newer pfslam (session format {version}; this one reads up to {VERSION}): upgrade pfslam",
        )
    try:
        with np.load(folder / ARRAYS, allow_pickle=False) as z:
            a = {k: z[k] for k in z.files}
        m = desc["map"]
        if not (np.ndim(a["logodds"]) == 2 and float(m["resolution"]) > 0 and float(m["l_clamp"]) > 0):
            raise ValueError("its map is not a grid")
        grid = OccupancyGrid.from_logodds(
            np.ascontiguousarray(a["logodds"], dtype=np.float32),
            float(m["resolution"]),
            np.asarray(a["origin"], dtype=float).reshape(2),
            float(m["l_occ"]),
            float(m["l_free"]),
            float(m["l_clamp"]),
        )
        k = len(a["node_poses"])
        nodes = SessionNodes(
            np.asarray(a["node_poses"], dtype=float).reshape(k, 3),
            _unpacked(a["points"], a["point_offsets"]),
            np.asarray(a["node_info"], dtype=float).reshape(k, 3, 3),
            _unpacked(a["hits"], a["hit_offsets"]),
            _unpacked(a["floor"], a["floor_offsets"]),
            np.asarray(a["node_sensor"], dtype=float).reshape(k, 2),
            np.asarray(a["node_times"], dtype=float).reshape(k),
            np.asarray(a["node_run"], dtype=np.int64).reshape(k),
        )
        graph = PoseGraph(nodes.poses.copy())
        if len(a["edge_i"]):
            graph.add_many(a["edge_i"], a["edge_j"], a["edge_z"], None, a["edge_loop"], info=a["edge_info"])
        sizes = {len(nodes.points), len(nodes.hits), len(nodes.floor)}
        if sizes != {k} or (len(graph.i) and max(graph.i.max(), graph.j.max()) >= k):
            raise ValueError("its nodes, scans and edges do not match")
        if not np.isfinite(nodes.poses).all() or not np.isfinite(grid.logodds).all():
            raise ValueError("it holds values that are not numbers")
    except InputError:
        raise
    except (OSError, KeyError, ValueError, TypeError, IndexError) as e:
        raise InputError(folder / ARRAYS, f"is broken or incomplete ({e})") from None
    settings: dict[str, Any] = desc["settings"] if isinstance(desc.get("settings"), dict) else {}
    runs: list[dict[str, Any]] = desc["runs"] if isinstance(desc.get("runs"), list) else []
    return Session(grid, nodes, graph, settings, runs)


# -- continuing a session ---------------------------------------------------------------------


@dataclass
class Resume:
    """A session a run continues: where it was read from, the session, the pose of the run's
    first scan in the session's map, and the global search that found it (None: given)."""

    folder: Path
    session: Session
    start: Array
    search: StartSearch | None = None

    @property
    def mode(self) -> StartMode:
        """How the start was placed: given, or found by the search."""
        return StartMode.GIVEN if self.search is None else StartMode.FOUND

    def as_dict(self) -> dict[str, Any]:
        """``run.json``'s ``session``: what was resumed and the start found (or given)."""
        start: dict[str, Any] = {
            "pose": [float(v) for v in self.start],
            "mode": self.mode.value,
            "given": self.search is None,
        }
        if self.search is not None:
            start.update({k: v for k, v in self.search.as_dict().items() if k != "pose"})
        return {"resumed": str(self.folder), "runs_before": len(self.session.runs), "start": start}


def session_config(cfg: SlamConfig, session: Session) -> tuple[SlamConfig, str | None]:
    """``cfg`` with the session map's resolution and log-odds (a map is continued as it was
    made), and a note if they differ from ``cfg``'s."""
    g = session.grid
    want = replace(cfg.map, resolution=g.resolution, l_occ=g.l_occ, l_free=g.l_free, l_clamp=g.l_clamp)
    if want == cfg.map:
        return cfg, None
    note = (
        f"the session's map has {g.resolution:g} m cells (log-odds {g.l_occ:g} / {g.l_free:g}, +-{g.l_clamp:g}): "
        "the run continues it with those, not the map settings given"
    )
    return replace(cfg, map=want), note


def place_start(
    log: object,
    folder: str | Path,
    session: Session,
    frames: Sequence[Frame],
    config: SlamConfig,
    start: Sequence[float] | None = None,
) -> Resume:
    """Where the log's first scan is in the session's map: ``start`` (x, y, degrees) if given,
    else a global search (:func:`~pfslam.backend.start.find_start`) of the first scan with
    hits; one that finds no place, or two alike, is an InputError naming ``--start``."""
    from pfslam.backend.start import find_start, map_field, start_points

    folder = Path(folder)
    if start is not None:
        x, y, deg = (float(v) for v in start)
        return Resume(folder, session, np.array([x, y, np.deg2rad(deg)]))
    settings = BackendSettings.of(config)
    field = map_field(session.grid, settings)
    pts = np.zeros((0, 2), dtype=np.float32)
    for frame in frames[:1]:
        pts = start_points(scan_to_points(frame, ground_z=config.sensor.ground_z), config.map.resolution)
    search = find_start(field, pts, settings)
    if not search.found:
        raise InputError(
            log,
            f"cannot place its first scan in the map of {folder}: {search.why_not()}; "
            "give where it starts with --start X,Y,DEG",
        )
    assert search.pose is not None
    return Resume(folder, session, search.pose, search)


def open_session(folder: str | Path | None) -> Session | None:
    """The session in ``folder`` (:func:`load_session`), None for a new map; read before
    anything else is done, so that a wrong folder is the first error."""
    return load_session(folder) if folder is not None else None


def continued(
    log: object,
    cfg: SlamConfig,
    folder: str | Path | None,
    session: Session | None,
    frames: Sequence[Frame],
    start: Sequence[float] | None,
    reporter: Reporter,
) -> tuple[SlamConfig, Resume | None]:
    """The settings and the start of a run that continues ``session`` (read from ``folder``);
    ``cfg`` and None for a new map."""
    if session is None or folder is None:
        return cfg, None
    cfg, note = session_config(cfg, session)
    if note is not None:
        reporter.warn(note)
    resumed = place_start(log, folder, session, frames[:: cfg.every], cfg, start)
    x, y, th = resumed.start
    how = "given" if resumed.search is None else f"found, score {resumed.search.score:.2f}"
    reporter.say(
        f"continuing the session in {folder}: the log starts at ({x:.2f}, {y:.2f}, {np.rad2deg(th):.1f} deg), {how}"
    )
    return cfg, resumed


# -- the session a run leaves -------------------------------------------------------------------


def _session_nodes(
    frames: Sequence[Frame], nodes: Nodes, poses: Array, config: BackendSettings, run: int
) -> SessionNodes:
    """``nodes`` (this run's, at their final ``poses``) with what a submap needs of each scan:
    its hits within ``graph.max_range`` and its floor points, one per map cell."""
    scan_of = frame_scans(frames, nodes, config)
    res = config.map.resolution
    hits, floor, sensor = [], [], []
    for k in range(len(nodes)):
        sp = scan_of(k)
        hits.append(within_reach(one_per_cell(sp.hits, res)).astype(np.float32))
        floor.append(within_reach(one_per_cell(sp.floor, res)).astype(np.float32))
        sensor.append(sp.sensor_xy)
    times = np.array([frames[int(s)].t for s in nodes.scan], dtype=float)
    return SessionNodes(
        np.asarray(poses, dtype=float).reshape(-1, 3),
        [np.asarray(p, dtype=np.float32) for p in nodes.points],
        nodes.information(),
        hits,
        floor,
        np.array(sensor, dtype=float).reshape(-1, 2),
        times,
        np.full(len(nodes), run, dtype=np.int64),
    )


def session_of_run(
    frames: Sequence[Frame],
    poses: Array,
    grid: OccupancyGrid,
    config: BackendSettings,
    settings: dict[str, Any],
    closure: LoopClosure | None = None,
    before: Session | None = None,
    run_info: dict[str, Any] | None = None,
) -> Session:
    """The session after a run over ``frames`` (the ones it stepped) whose answer is ``poses``
    and ``grid``: ``before``'s nodes and edges (a resumed run), then this run's nodes with the
    graph's edges of this run: the back end's ``closure`` if the run kept it, else the nodes
    along ``poses`` joined in sequence (and tied to ``before``'s nearest node at the start)."""
    run = before.next_run if before is not None else 0
    held = len(before.nodes) if before is not None else 0
    if closure is not None:
        own = own_nodes(closure.nodes)
        own_poses = closure.optimised[closure.nodes.held :]
        edges = closure.graph
    else:
        own = select_nodes(frames, poses, config)
        own_poses = own.poses
        edges = build_graph(own, config.graph)
        edges.i, edges.j = edges.i + held, edges.j + held
        if before is not None and len(before.nodes) and len(own):
            tie = start_tie(before.nodes.poses, own_poses[0], held)
            info = loop_information(own.information()[:1], config.graph)  # the start, as sure as a loop
            edges.add_many(np.array([tie.anchor]), np.array([held]), tie.pose[None], None, np.zeros(1, bool), info=info)
    mine = _session_nodes(frames, own, own_poses, config, run)
    nodes = before.nodes.joined(mine) if before is not None else mine
    graph = PoseGraph(nodes.poses.copy())
    if before is not None:
        b = before.graph
        graph.add_many(b.i, b.j, b.z, None, b.loop, info=b.info)
    graph.add_many(edges.i, edges.j, edges.z, None, edges.loop, info=edges.info)
    runs = [*(before.runs if before is not None else []), {"run": run, "nodes": len(own), **(run_info or {})}]
    return Session(grid, nodes, graph, settings, runs)


def leave_session(run: Run) -> Run:
    """The step after the back end: the session ``run`` leaves for the next log
    (:func:`session_of_run`) into ``run.session``; a run of fewer than two scans leaves none,
    and one that cannot be made is a note, the run's answer kept. Returns ``run``."""
    if run.scans <= 1 or not isinstance(run.config, SlamConfig):
        return run
    before = run.resumed.session if run.resumed is not None else None
    try:
        info = {"scans": run.scans, "start": [float(v) for v in run.poses[0]]}
        run.session = session_of_run(
            run.frames,
            run.poses,
            run.grid,
            BackendSettings.of(run.config),
            to_dict(run.config),
            run.closure,
            before,
            info,
        )
    except Exception as e:  # the run's answer is not lost to it
        run.notes.append(f"no session saved ({str(e).splitlines()[0] if str(e) else type(e).__name__})")
    return run


def write_session(out: Path, run: Run, extra: dict[str, Any]) -> dict[str, Any] | None:
    """Write the session ``run`` leaves into ``out``'s session folder (``extra`` into its
    description); ``run.json``'s ``session`` (None: the run left none)."""
    if run.session is None:
        return None
    save_session(out / FOLDER, run.session, extra)
    return {
        "folder": FOLDER,
        "nodes": len(run.session.nodes),
        "runs": len(run.session.runs),
        **(run.resumed.as_dict() if run.resumed is not None else {"start": {"mode": StartMode.NONE.value}}),
    }
