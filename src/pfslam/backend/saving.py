"""What a SLAM run leaves for the next one: its session (:mod:`pfslam.backend.session`), made
from its scans, its final trajectory and map, and the back end's graph where it kept one."""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from pfslam.backend.edges import loop_information
from pfslam.backend.graph import PoseGraph
from pfslam.backend.loops import LoopClosure, build_graph
from pfslam.backend.nodes import Nodes, frame_scans, one_per_cell, own_nodes, select_nodes
from pfslam.backend.search import start_tie
from pfslam.backend.session import Session, SessionNodes, within_reach
from pfslam.config import SlamConfig
from pfslam.frames import Frame
from pfslam.maps.grid import OccupancyGrid
from pfslam.types import Array


def _session_nodes(frames: Sequence[Frame], nodes: Nodes, poses: Array, config: SlamConfig, run: int) -> SessionNodes:
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
    config: SlamConfig,
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
