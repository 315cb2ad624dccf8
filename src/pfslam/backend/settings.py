"""What the back end reads of a SLAM run's settings: its own section, the map's cells and
log-odds, and the height under which hits are ground (no other setting reaches it)."""

from __future__ import annotations

from dataclasses import dataclass

from pfslam.config import GraphConfig, MapConfig, SlamConfig


@dataclass(frozen=True)
class BackendSettings:
    """The back end's part of a :class:`~pfslam.config.SlamConfig`."""

    graph: GraphConfig
    map: MapConfig
    ground_z: float  # m: hits below this are the floor (the sensor section's ground_z)

    @classmethod
    def of(cls, config: SlamConfig) -> BackendSettings:
        """The back end's part of ``config``."""
        return cls(config.graph, config.map, config.sensor.ground_z)
