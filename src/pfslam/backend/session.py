"""A SLAM session kept on disk, so that a later log can continue the map (``pfslam slam
--resume DIR``).

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

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np
from numpy.typing import NDArray

from pfslam.backend.graph import PoseGraph
from pfslam.errors import InputError
from pfslam.maps.grid import OccupancyGrid
from pfslam.types import Array

FORMAT = "pfslam-session"
VERSION = 1  # the format written; a session of a newer version is refused
FOLDER = "session"  # the session's folder inside a run's output folder
DESCRIPTION = "session.json"
ARRAYS = "session.npz"
MM = 1000.0  # stored points: integer millimetres
REACH_MM = 32_000  # |x|, |y| of a stored point at most (int16)


@dataclass
class SessionNodes:
    """The graph's nodes of a session: their poses in the map's frame (as the session ended),
    the points each matches with (robot frame), what each scan pins of its pose (3 x 3), the
    scan's hits and floor points that build a submap (robot frame) and the sensor's place on
    the robot, the time of the scan, and the run each node came from."""

    poses: Array
    points: list[NDArray[np.float32]]
    info: Array
    hits: list[NDArray[np.float32]]
    floor: list[NDArray[np.float32]]
    sensor: Array
    times: Array
    run: NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.poses)

    def joined(self, other: SessionNodes) -> SessionNodes:
        """These nodes, then ``other``'s."""
        return SessionNodes(
            np.vstack([self.poses, other.poses]),
            self.points + other.points,
            np.concatenate([self.info, other.info]),
            self.hits + other.hits,
            self.floor + other.floor,
            np.vstack([self.sensor, other.sensor]),
            np.concatenate([self.times, other.times]),
            np.concatenate([self.run, other.run]),
        )


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
