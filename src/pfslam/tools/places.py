"""The world a simulated walk goes through: a built-in one by its name
(:data:`~pfslam.tools.worlds.WORLDS`), or ``random``, the random building of a seed
(:func:`~pfslam.tools.buildings.random_building`)."""

from __future__ import annotations

from pfslam.config import check_int
from pfslam.errors import ConfigError
from pfslam.tools.buildings import random_building
from pfslam.tools.worlds import WORLDS, World


def world_named(name: str, seed: int = 0) -> World:
    """The built-in world ``name``, or for ``"random"`` the random building of ``seed``; a
    ConfigError naming the known ones if there is none."""
    if name == "random":
        return random_building(check_int("seed", seed, 0))
    if name not in WORLDS:
        raise ConfigError(
            f"unknown world {name!r}; known worlds: {', '.join(sorted(WORLDS))} and random (a random building per seed)"
        )
    return WORLDS[name]
