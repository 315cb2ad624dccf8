"""Finding the robot in its own map again after a blind stretch (issue 57): the window a
stretch may have drifted, the search over a particle's map, the stretch's path bent to its
end, and the filter that does it."""

import re

import numpy as np
import pytest

from pfslam.config import SlamConfig, with_values
from pfslam.filters.rbpf import RaoBlackwellizedSlam
from pfslam.filters.reacquire import bend, reacquire, window
from pfslam.frames import Frame
from pfslam.geometry import compose, relative, transform_points, wrap_angle
from pfslam.maps.tiled import TiledMaps
from pfslam.tools.raycast import raycast
from pfslam.tools.worlds import WORLDS

BEAMS = 361
ANGLES = np.deg2rad(np.linspace(-90.0, 90.0, BEAMS))
MOUNT = np.eye(4)
MOUNT[2, 3] = 0.3  # a level laser 0.3 m above the floor
REACH = 30.0


def ranges(segments: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Noise-free ranges from ``pose`` (inf where nothing is hit within REACH)."""
    a = pose[2] + ANGLES
    dirs = np.column_stack([np.cos(a), np.sin(a), np.zeros(BEAMS)])
    r = raycast(np.array([pose[0], pose[1], 0.3]), dirs, segments, 2.5, REACH)
    return np.where(r >= REACH, np.inf, r)


def hits(segments: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """The scan's hits in the robot frame."""
    r = ranges(segments, pose)
    ok = np.isfinite(r)
    return np.column_stack([r[ok] * np.cos(ANGLES[ok]), r[ok] * np.sin(ANGLES[ok])])


def mapped(segments: np.ndarray, poses: np.ndarray) -> TiledMaps:
    """One map drawn from scans at ``poses``."""
    maps = TiledMaps(1, capacity=4096)
    for p in poses:
        h = transform_points(p, hits(segments, p))
        maps.ensure_contains(*(h.min(axis=0) - 1), *(h.max(axis=0) + 1))
        maps.update(0, p[:2], h, np.ones(len(h), dtype=bool))
    return maps


def test_the_window_grows_with_the_stretch_and_stops_at_its_caps():
    m10, d10 = window(10.0, 0.5, 100.0, 45.0)
    m100, d100 = window(100.0, 0.5, 100.0, 45.0)
    assert d10 == pytest.approx(5.0) and d100 == pytest.approx(45.0)
    assert 0.2 < m10 < m100  # the heading's sideways throw and the scale's
    assert window(1000.0, 0.5, 100.0, 45.0) == (100.0, 45.0)


def test_bending_undoes_a_constant_heading_bias_exactly():
    rng = np.random.default_rng(1)
    steps = np.column_stack([np.full(300, 0.3), np.zeros(300), rng.normal(0.0, 0.02, 300)])
    truth, odom = [np.zeros(3)], [np.zeros(3)]
    for u in steps:
        truth.append(compose(truth[-1], u))
        odom.append(compose(odom[-1], u + [0.0, 0.0, np.deg2rad(0.2) * 0.3]))  # 0.2 deg/m
    truth, odom = np.array(truth), np.array(odom)
    assert np.abs(odom - truth)[:, :2].max() > 5.0
    bent = bend(odom, truth[-1])
    np.testing.assert_allclose(bent, truth, atol=1e-9)
    # a stretch that did not move, turned: the heading spread by step, the start kept
    still = np.zeros((5, 3))
    out = bend(still, np.array([0.0, 0.0, 0.4]))
    np.testing.assert_allclose(out[:, 2], [0.0, 0.1, 0.2, 0.3, 0.4])
    np.testing.assert_allclose(out[:, :2], 0.0, atol=1e-12)


def test_a_scan_is_found_metres_and_degrees_off_and_not_beyond_the_window():
    office = WORLDS["office"]
    start = np.array([office.start[0], office.start[1], 0.0])
    poses = np.array([compose(start, [0.5 * k, 0.0, 0.0]) for k in range(30)])
    maps = mapped(office.segments, poses)
    truth = poses[12]
    off = compose(truth, [-4.0, 3.0, np.deg2rad(-12.0)])  # where the odometry says it is
    got = reacquire(maps, 0, off, hits(office.segments, truth), 8.0, 20.0)
    assert got.pose is not None, got.why
    d = relative(truth, got.pose)
    assert np.hypot(d[0], d[1]) < 0.15 and abs(np.rad2deg(d[2])) < 0.5
    # a window too small to hold the truth: no answer, not the best place inside it
    small = reacquire(maps, 0, off, hits(office.segments, truth), 2.0, 20.0)
    assert small.pose is None and small.why
    # nothing mapped near: nothing found
    far = reacquire(maps, 0, compose(truth, [500.0, 0.0, 0.0]), hits(office.segments, truth), 8.0, 20.0)
    assert far.pose is None and far.why == "no walls mapped near"


def test_a_bare_corridor_is_ambiguous_along_it_and_not_taken():
    walls = np.array([[-50.0, -1.5, 50.0, -1.5], [-50.0, 1.5, 50.0, 1.5]])
    poses = np.array([[x, 0.0, 0.0] for x in np.arange(-20.0, 20.0, 0.5)])
    maps = mapped(walls, poses)
    truth = np.array([0.0, 0.0, 0.0])
    got = reacquire(maps, 0, np.array([3.0, 0.5, 0.05]), hits(walls, truth), 8.0, 10.0)
    assert got.pose is None and got.why == "ambiguous"


def _drive(points: list[tuple[float, float]], step: float) -> np.ndarray:
    """Poses along the polyline ``points``, ``step`` apart, heading along it."""
    out = []
    for a, b in zip(points[:-1], points[1:]):
        a, b = np.asarray(a, float), np.asarray(b, float)
        n = int(np.ceil(np.hypot(*(b - a)) / step))
        th = float(np.arctan2(*(b - a)[::-1]))
        out += [[*(a + (b - a) * k / n), th] for k in range(n)]
    return np.array(out)


@pytest.fixture(scope="module")
def blind_loop():
    """The office's south corridor driven east, then 60 m blind (every beam a no-return:
    out through a door onto open ground and back) with the odometry's heading drifting
    0.4 deg/m there (24 deg in all), then the corridor again: frames and the true poses."""
    office = WORLDS["office"]
    x0, y0 = float(office.start[0]), float(office.start[1])
    seen = _drive([(x0, y0), (x0 + 12.0, y0)], 0.1)
    blind = _drive([(x0 + 12.0, y0), (x0 + 2.0, y0), (x0 + 2.0, y0 - 25.0), (x0 + 2.0, y0)], 0.1)
    again = _drive([(x0 + 2.0, y0), (x0 + 12.0, y0)], 0.1)
    truth = np.vstack([seen, blind, again])
    is_blind = np.r_[np.zeros(len(seen)), np.ones(len(blind)), np.zeros(len(again))].astype(bool)
    steps = relative(truth[:-1], truth[1:])
    odom = [truth[0]]
    for u, b in zip(steps, is_blind[1:]):
        drift = np.deg2rad(0.4) * np.hypot(u[0], u[1]) if b else 0.0
        odom.append(compose(odom[-1], u + [0.0, 0.0, drift]))
    frames = []
    for k, (p, o, b) in enumerate(zip(truth, odom, is_blind)):
        r = np.full(BEAMS, np.inf) if b else ranges(office.segments, p)
        frames.append(Frame(0.1 * k, r, ANGLES, np.asarray(o), None, MOUNT, 0.0, REACH))
    return frames, truth, is_blind


def _cfg(**settings: object) -> SlamConfig:
    """The tests' settings (a small filter mapping the laser's whole reach), with ``settings``."""
    base = {"filter": "rbpf", "particles": 8, "rbpf.map_range": REACH, "seed": 0}
    return with_values(SlamConfig(), {**base, **settings})


def _run(frames, reacquire_m: float, **settings: object) -> tuple[RaoBlackwellizedSlam, np.ndarray]:
    slam = RaoBlackwellizedSlam(_cfg(**{"rbpf.reacquire_m": reacquire_m, **settings}), start=frames[0].odom)
    for f in frames:
        slam.step(f)
    return slam, slam.trajectory()[1]


def test_after_a_blind_stretch_the_filter_finds_itself_again_and_bends_the_stretch(blind_loop):
    frames, truth, is_blind = blind_loop
    off, path_off = _run(frames, 0.0)
    on, path_on = _run(frames, 20.0)
    assert not off.reacquired
    [found] = [r for r in on.reacquired if r["found"]]
    assert found["adrift_m"] > 55.0
    end_off = np.hypot(*(path_off[-1, :2] - truth[-1, :2]))
    end_on = np.hypot(*(path_on[-1, :2] - truth[-1, :2]))
    assert end_off > 1.0  # left where the odometry put it, the filter maps the corridor twice
    assert end_on < 0.1
    assert abs(float(wrap_angle(path_on[-1, 2] - truth[-1, 2]))) < np.deg2rad(1.0)
    # the blind stretch bent to both of its ends: nearer the truth than the odometry put it
    odom = np.array([f.odom for f in frames])
    err_odom = np.hypot(*(odom[is_blind, :2] - truth[is_blind, :2]).T)
    err_on = np.hypot(*(path_on[is_blind, :2] - truth[is_blind, :2]).T)
    assert err_on.max() < 0.5 * err_odom.max()


def test_a_stretch_it_cannot_find_itself_after_is_said_loudly(blind_loop):
    """A window too narrow for the drift (0.01 deg/m allowed, 0.4 deg/m there): every search
    after the stretch is refused, the filter goes on from where the odometry put it, and the
    run says so; where it is found, the run says how far it moved."""
    from pfslam.pipeline import run_slam

    frames, _, _ = blind_loop
    narrow = run_slam(frames, _cfg(backend="none", **{"rbpf.reacquire_deg_per_m": 0.01}))
    tries = narrow.filter_info["reacquired"]
    assert len(tries) >= 3 and not any(r["found"] for r in tries)  # (one per 2 m, until the log ends)
    [said] = [n for n in narrow.notes if "could not find itself" in n]
    assert 60 <= int(re.search(r"\((\d+) m: ", said).group(1)) <= 72  # the stretch and the tries after it
    found = run_slam(frames, _cfg(backend="none"))
    assert [n for n in found.notes if "found itself again" in n and "moved 4.4 m" in n]
    assert not [n for n in found.notes if "could not find itself" in n]


def test_a_log_that_starts_blind_searches_once_and_maps_on(blind_loop):
    """Nothing mapped before the stretch: one search finds no wall within its reach, and the
    filter maps on from there instead of searching 24 m more in vain."""
    frames, _, is_blind = blind_loop
    slam, _ = _run(frames[int(np.argmax(is_blind)) :], 20.0)
    [only] = slam.reacquired
    assert only["why"] == "no walls mapped near" and only["gave_up"]


def test_without_blind_follow_nothing_is_adrift_and_nothing_searched(blind_loop):
    """``rbpf.blind_follow`` off: blind scans are matched and weighed as any (their noise moves
    the path), so the filter never counts itself adrift and never searches."""
    frames, _, _ = blind_loop
    slam, _ = _run(frames, 20.0, **{"rbpf.blind_follow": False})
    assert slam.blind_m > 55.0 and slam.reacquired == []
