"""The point-to-line refinement a loop and a step are measured with: below a cell on an exact
surface, what it pins (across a corridor, not along), held at its guess where it pins nothing,
and unbiased by how a scan samples the walls."""

from __future__ import annotations

import numpy as np
import pytest
from wallpoints import walls

from pfslam.backend.nodes import cell_means
from pfslam.backend.submaps import Surface, refine, surface_information
from pfslam.geometry import relative
from pfslam.sensor import one_per_cell

ROOM = [(-3, -2, 4, -2), (4, -2, 4, 3), (4, 3, -3, 3), (-3, 3, -3, -2), (1.0, -2, 1.0, -1.2), (1.0, -1.2, 1.6, -1.2)]
CORRIDOR = [(-8, -1.2, 8, -1.2), (-8, 1.2, 8, 1.2)]


def scan(world: np.ndarray, pose: np.ndarray, rng: np.random.Generator, noise: float = 0.005) -> np.ndarray:
    """The world's points seen from ``pose`` (robot frame), with range-like noise."""
    local = relative(pose, np.column_stack([world, np.zeros(len(world))]))[:, :2]
    return local + rng.normal(0.0, noise, local.shape)


def test_a_room_match_lands_below_a_cell_from_a_guess_ten_centimetres_off() -> None:
    rng = np.random.default_rng(0)
    world = walls(ROOM)
    surface = Surface.of(world)  # the map: the room's walls in its own frame
    true = np.array([0.4, 0.3, np.deg2rad(7.0)])
    pts = cell_means(scan(world, true, rng), 0.025)
    guess = true + np.array([0.08, -0.06, np.deg2rad(1.5)])
    r = refine(surface, pts, guess, 20, guess, (0.5, 10.0))
    err = relative(true, r.pose)
    assert np.hypot(err[0], err[1]) < 0.005 and abs(np.rad2deg(err[2])) < 0.05
    assert r.paired > 0.8 * len(pts) and r.rms < 0.02
    # what it claims: a room pins every way, to well under a centimetre
    sd = np.sqrt(np.diag(np.linalg.inv(r.info)))
    assert (sd[:2] < 0.01).all() and np.rad2deg(sd[2]) < 0.2


def test_a_corridor_match_pins_across_and_stays_at_its_guess_along() -> None:
    """Bare parallel walls: across and in heading the match finds the truth; along, the points
    say nothing and the pose stays where it was guessed (its prior), and the information says
    so (about nil along)."""
    rng = np.random.default_rng(1)
    world = walls(CORRIDOR)
    surface = Surface.of(world)
    true = np.array([0.0, 0.2, np.deg2rad(2.0)])
    pts = cell_means(scan(world, true, rng), 0.025)
    guess = np.array([0.3, 0.1, np.deg2rad(1.0)])  # 0.3 m along, 0.1 m across, 1 deg off
    r = refine(surface, pts, guess, 20, guess, (0.05, 1.0))
    assert r.pose[1] == pytest.approx(true[1], abs=0.005)
    assert r.pose[2] == pytest.approx(true[2], abs=np.deg2rad(0.1))
    assert r.pose[0] == pytest.approx(guess[0], abs=0.02)  # along: held at the guess
    info = r.info
    assert info[1, 1] > 300 * max(info[0, 0], 1e-12)  # (along: only the walls' noise tilts their normals)


def test_the_first_hit_of_each_cell_would_turn_a_match_their_mean_does_not() -> None:
    """A scan's sweep enters each cell from one side: its first point there sits on that side,
    which for the whole scan is a small turn. Matched on the previous scan's surface, the first
    points turn the match by a tenth of a degree or more over many pairs; the cells' means by
    far less."""
    rng = np.random.default_rng(2)
    world = walls(ROOM, step=0.002)
    surface = Surface.of(world)
    errs = {"first": [], "mean": []}
    for _ in range(12):
        true = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-0.3, 0.3)])
        local = scan(world, true, rng, 0.002)
        order = np.argsort(np.arctan2(local[:, 1], local[:, 0]))  # the sweep, counterclockwise
        local = local[order]
        for name, pts in (("first", one_per_cell(local, 0.05)), ("mean", cell_means(local, 0.025))):
            r = refine(surface, pts, true, 20, true, (0.05, 1.0))
            errs[name].append(relative(true, r.pose)[2])
    assert abs(np.mean(errs["mean"])) < 0.3 * abs(np.mean(errs["first"]))


def test_what_a_scan_pins_from_its_own_walls() -> None:
    corridor = surface_information(walls(CORRIDOR), 0.05, 20)
    assert corridor[1, 1] > 1e3 * max(corridor[0, 0], 1e-12)  # across, not along
    room = surface_information(walls(ROOM), 0.05, 20)
    ev = np.linalg.eigvalsh(room[:2, :2])
    assert ev.min() > 0.2 * ev.max()
    assert surface_information(np.zeros((0, 2)), 0.05, 20) == pytest.approx(np.zeros((3, 3)))
    # foliage (hits scattered as densely across as along): the few that happen to line up pin
    # far less than a room's walls
    bush = np.random.default_rng(0).uniform(-0.5, 0.5, (400, 2)) + [3.0, 0.0]
    assert np.linalg.eigvalsh(surface_information(bush, 0.05, 20)[:2, :2]).max() < 0.25 * ev.max()
