"""Continuing a saved session with a new log (``pfslam slam LOG --resume DIR``): the session
read, the settings made to fit its map, and the new log's start placed in the old map."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from pfslam.backend.session import Session
from pfslam.config import SlamConfig
from pfslam.errors import InputError
from pfslam.frames import Frame
from pfslam.sensor import scan_to_points
from pfslam.types import Array

if TYPE_CHECKING:
    from pfslam.backend.start import StartSearch


@dataclass
class Resume:
    """A session a run continues: where it was read from, the session, the pose of the run's
    first scan in the session's map, and the global search that found it (None: given)."""

    folder: Path
    session: Session
    start: Array
    search: StartSearch | None = None

    def as_dict(self) -> dict[str, Any]:
        """``run.json``'s ``session``: what was resumed and the start found (or given)."""
        start: dict[str, Any] = {"pose": [float(v) for v in self.start], "given": self.search is None}
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
    field = map_field(session.grid, config)
    pts = np.zeros((0, 2), dtype=np.float32)
    for frame in frames[:1]:
        pts = start_points(scan_to_points(frame, ground_z=config.sensor.ground_z), config.map.resolution)
    search = find_start(field, pts, config)
    if not search.found:
        raise InputError(
            log,
            f"cannot place its first scan in the map of {folder}: {search.why_not()}; "
            "give where it starts with --start X,Y,DEG",
        )
    assert search.pose is not None
    return Resume(folder, session, search.pose, search)
