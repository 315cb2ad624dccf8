"""SLAM health (issue 57): how well each update's scan fits the best particle's own map
(:meth:`pfslam.maps.tiled.TiledMaps.fit`), the state it gives, and the warning a run that broke
on the way ends with."""

import numpy as np
import pytest

from pfslam.config import SlamConfig, with_values
from pfslam.frames import Frame
from pfslam.io.logs import load_log
from pfslam.maps.tiled import TiledMaps
from pfslam.pipeline import run_slam

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


@pytest.fixture(scope="module")
def office_log(short_office):
    return load_log(short_office.lidar_path, short_office.joint_path)


def _cfg():
    return with_values(SlamConfig(), {"filter": "rbpf", "backend": "none"})


def test_a_walk_in_a_known_building_tracks_and_says_nothing(office_log):
    run = run_slam(office_log.frames, _cfg())
    h = run.metrics["health"]
    assert h["final_state"] == "tracking"
    assert h["updates_in_state"]["lost"] == 0
    assert h["median_quality"] > 0.8
    assert not [n for n in run.notes if "SLAM run" in n]


def test_a_walk_whose_scans_turn_half_way_is_lost_there_and_says_so(office_log):
    """The scans of the walk's second half turned by 60 deg (a laser knocked on its mount): no
    pose explains them in the map the first half drew, and the run must say so."""
    frames = list(office_log.frames)
    half = len(frames) // 2
    turned = []
    for k, f in enumerate(frames):
        if k >= half:
            f = Frame(f.t, f.ranges, f.angles + np.deg2rad(60.0), f.odom, f.wheels, f.mount, f.min_range, f.max_range)
        turned.append(f)
    run = run_slam(turned, _cfg())
    h = run.metrics["health"]
    assert h["final_state"] == "lost" and h["updates_in_state"]["tracking"] == 0
    assert h["first_lost_s"] >= frames[half].t - frames[0].t - 1.0
    assert [n for n in run.notes if "SLAM run" in n]


def test_a_stretch_whose_scans_see_nothing_is_counted_blind_and_said(office_log, monkeypatch):
    """The walk's second half with every beam a no-return: the filter can only follow the
    odometry there, and the run says for how far."""
    import pfslam.pipeline.run as run_module

    frames = list(office_log.frames)
    half = len(frames) // 2
    blank = [
        f if k < half else Frame(f.t, np.full_like(f.ranges, np.inf), f.angles, f.odom, f.wheels, f.mount, f.min_range, f.max_range)
        for k, f in enumerate(frames)
    ]  # fmt: skip
    seen = run_slam(frames, _cfg())
    assert seen.filter_info["blind_m"] == 0.0
    monkeypatch.setattr(run_module, "BLIND_WARN_M", 0.5)
    run = run_slam(blank, _cfg())
    odo = run.odometry
    travel = float(np.sum(np.hypot(*np.diff(odo[half - 1 :, :2], axis=0).T)))
    assert 0.5 * travel < run.filter_info["blind_m"] <= travel + 0.5  # (and what it drove since its last update)
    assert run.filter_info["longest_blind"]["from_t"] >= frames[half - 1].t
    assert [n for n in run.notes if "too few hits" in n]


def test_with_blind_follow_a_blind_stretch_follows_the_odometry_exactly(office_log):
    """The walk's second half with all but 10 beams a no-return (fewer hits than a match
    needs): with ``rbpf.blind_follow`` every particle follows the odometry there, so the path
    moves as the odometry does, to the bit; without, the updates' noise and matches move it
    otherwise."""
    from pfslam.geometry import relative

    frames = list(office_log.frames)
    half = len(frames) // 2

    def few(f):
        r = np.full_like(f.ranges, np.inf)
        keep = np.linspace(0, len(r) - 1, 10).astype(int)
        r[keep] = f.ranges[keep]
        return Frame(f.t, r, f.angles, f.odom, f.wheels, f.mount, f.min_range, f.max_range)

    sparse = [f if k < half else few(f) for k, f in enumerate(frames)]
    moved = {}
    for follow in (False, True):
        cfg = with_values(SlamConfig(), {"filter": "rbpf", "backend": "none", "rbpf.blind_follow": follow})
        run = run_slam(sparse, cfg)
        assert run.filter_info["blind_m"] > 0.5
        a, b = half + 5, len(frames) - 1
        moved[follow] = relative(run.poses[a], run.poses[b]) - relative(run.odometry[a], run.odometry[b])
    np.testing.assert_allclose(moved[True], 0.0, atol=1e-9)
    assert np.abs(moved[False]).max() > 1e-4
