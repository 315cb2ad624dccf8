"""How well a scan fits one particle's map of tiles (pfslam.kernels.fit, through
:meth:`pfslam.maps.tiled.TiledMaps.fit`): explained where it was taken, contradicted when
placed wrong, new ground not judged, a no-return through a wall contradicted."""

import numpy as np
import pytest

from pfslam.maps.tiled import TiledMaps

RES = 0.05


def _room_scan(pose=(0.0, 0.0, 0.0), beams=360):
    """A 360-beam scan of a 6 x 4 m room centred on the origin, seen from ``pose``: the end
    points in the robot frame."""
    x, y, th = pose
    a = np.linspace(-np.pi, np.pi, beams, endpoint=False) + th
    dx, dy = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore"):
        tx = np.where(dx > 0, (3.0 - x) / dx, (-3.0 - x) / dx)
        ty = np.where(dy > 0, (2.0 - y) / dy, (-2.0 - y) / dy)
    r = np.minimum(np.abs(tx), np.abs(ty))
    world = np.column_stack([x + r * dx, y + r * dy])
    c, s = np.cos(th), np.sin(th)
    d = world - [x, y]
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])


@pytest.fixture(scope="module")
def room_map():
    maps = TiledMaps(1, resolution=RES)
    for pose in [(0.0, 0.0, 0.0), (1.0, 0.5, 0.3), (-1.0, -0.5, -0.2)]:
        ends = _room_scan(pose)
        p = np.array(pose)
        c, s = np.cos(p[2]), np.sin(p[2])
        world = np.column_stack([p[0] + c * ends[:, 0] - s * ends[:, 1], p[1] + s * ends[:, 0] + c * ends[:, 1]])
        maps.ensure_contains(-4, -3, 4, 3)
        for _ in range(3):  # the walls seen three times: sure
            maps.update(0, p[:2], world, np.ones(len(world), bool))
    return maps


def _fit(maps, pose, ends, hit=None, tol=0.15):
    hit = np.ones(len(ends), bool) if hit is None else hit
    return maps.fit(0, np.array(pose), np.zeros(2), ends, hit, tol, 6.0)


def test_a_scan_fits_its_own_map_where_it_was_taken(room_map):
    ends = _room_scan((0.5, 0.2, 0.1))
    judged, explained, contradicted = _fit(room_map, (0.5, 0.2, 0.1), ends)
    assert judged == len(ends)
    assert explained >= 0.97 * judged
    assert contradicted == 0


def test_the_scan_at_a_wrong_pose_passes_through_walls_and_ends_in_free_space(room_map):
    ends = _room_scan((0.5, 0.2, 0.1))
    judged, explained, contradicted = _fit(room_map, (1.5, -0.6, 0.1), ends)  # placed 1.3 m off
    assert judged > 0.8 * len(ends)
    assert explained < 0.5 * judged
    assert contradicted > 0.2 * judged
    # turned 90 deg: the long walls where the short ones are
    judged, explained, contradicted = _fit(room_map, (0.5, 0.2, 0.1 + np.pi / 2), ends)
    assert contradicted > 0.2 * judged


def test_new_ground_is_not_judged_and_a_no_return_through_a_wall_contradicts(room_map):
    # seen from 30 m away the map knows nothing of where the beams end: new ground
    assert _fit(room_map, (30.0, 0.0, 0.0), _room_scan())[0] == 0
    # beams that returned nothing, from the centre out to 5 m: each passes a wall it should have hit
    a = np.linspace(-np.pi, np.pi, 90, endpoint=False)
    far = 5.0 * np.column_stack([np.cos(a), np.sin(a)])
    judged, explained, contradicted = _fit(room_map, (0.0, 0.0, 0.0), far, np.zeros(90, bool))
    assert explained == 0 and contradicted == judged == 90
    # up to 1.5 m they pass nothing: not judged
    assert _fit(room_map, (0.0, 0.0, 0.0), far * 0.3, np.zeros(90, bool)) == (0, 0, 0)


def test_every_map_at_once_counts_what_each_contradicts(room_map):
    """seen_through (every particle's map in parallel) gives fit's contradicted count per map for
    beams taken as no-returns ending where the hits are: the scan where it was taken passes no
    wall, placed wrong it passes walls."""
    maps = TiledMaps(3, resolution=RES)
    maps.ensure_contains(-4, -3, 4, 3)
    maps.tables[:] = room_map.tables[0]  # three maps sharing the room's tiles (read only here)
    maps.pool, maps.near = room_map.pool, room_map.near
    ends = _room_scan((0.5, 0.2, 0.1))
    poses = np.array([(0.5, 0.2, 0.1), (1.5, -0.6, 0.1), (0.5, 0.2, 0.1 + np.pi / 2)])
    got = maps.seen_through(poses, np.zeros(2), ends, 0.15, 6.0)
    assert got[0] == 0 and got[1] > 0.2 * len(ends) and got[2] > 0.2 * len(ends)
    assert got.tolist() == [_fit(room_map, p, ends, np.zeros(len(ends), bool))[2] for p in poses]
