"""The world a simulated walk goes through: a built-in one by its name
(:data:`~pfslam.tools.worlds.WORLDS`), ``random``, the random building of a seed
(:func:`~pfslam.tools.buildings.random_building`), or ``campus``, the outdoor campus of a seed
(:func:`~pfslam.tools.campus.campus_world`)."""

from __future__ import annotations

from pfslam.config import check_int
from pfslam.errors import ConfigError
from pfslam.tools.buildings import random_building
from pfslam.tools.campus import campus_world
from pfslam.tools.worlds import WORLDS, World


def world_named(name: str, seed: int = 0) -> World:
    """The built-in world ``name``, or for ``"random"`` the random building of ``seed``, for
    ``"campus"`` the campus of ``seed``; a ConfigError naming the known ones if there is none."""
    if name == "random":
        return random_building(check_int("seed", seed, 0))
    if name == "campus":
        return campus_world(check_int("seed", seed, 0))
    if name not in WORLDS:
        raise ConfigError(
            f"unknown world {name!r}; known worlds: {', '.join(sorted(WORLDS))}, campus (an outdoor campus per "
            "seed) and random (a random building per seed)"
        )
    return WORLDS[name]
