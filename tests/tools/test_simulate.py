"""The THOR simulator: ray casting, path, odometry drift, clocks and the written files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pfslam.errors import ConfigError
from pfslam.geometry import compose
from pfslam.tools.raycast import raycast, raycast_numpy
from pfslam.tools.simulate import simulate
from pfslam.tools.wheeled import simulate_wheeled
from pfslam.tools.worlds import WORLDS

NAN, INF = float("nan"), float("inf")

HAVE_THOR = (Path(__file__).resolve().parents[2] / "src" / "pfslam" / "io" / "thor.py").is_file()


def _seg_dist(pts: np.ndarray, segs: np.ndarray) -> np.ndarray:
    """(N,) distance from each point to the nearest segment."""
    a, b = segs[None, :, :2], segs[None, :, 2:]
    e = b - a
    p = pts[:, None, :]
    u = np.clip(np.sum((p - a) * e, axis=2) / np.maximum(np.sum(e * e, axis=2), 1e-12), 0.0, 1.0)
    q = a + u[..., None] * e
    return np.min(np.linalg.norm(p - q, axis=2), axis=1)


@pytest.fixture(scope="module")
def office_run(office_sim):
    """The seed-0 office log of the session (tests/conftest.py)."""
    return office_sim


@pytest.mark.parametrize("world", sorted(WORLDS))
def test_raycast_kernel_matches_numpy(world: str) -> None:
    w = WORLDS[world]
    rng = np.random.default_rng(1)
    lo, hi = w.segments[:, [0, 1]].min(axis=0), w.segments[:, [0, 1]].max(axis=0)
    for _ in range(10):
        origin = np.r_[rng.uniform(lo, hi), rng.uniform(0.5, 2.0)]
        d = rng.normal(size=(500, 3))
        d[:, 2] *= 0.3
        d[:10] = [0.0, 0.0, -1.0]  # straight down
        d[10:20, 2] = 0.0  # level
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        a = raycast(origin, d, w.segments, w.wall_height)
        b = raycast_numpy(origin, d, w.segments, w.wall_height)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)
        assert np.all(a <= 30.0)


def test_level_beam_hits_wall_at_known_distance() -> None:
    segs = np.array([[5.0, -10.0, 5.0, 10.0]])
    d = np.array([[1.0, 0.0, 0.0], [np.cos(0.3), np.sin(0.3), 0.0], [-1.0, 0.0, 0.0]])
    r = raycast([1.0, 0.0, 1.41], d, segs, 2.5)
    np.testing.assert_allclose(r[:2], [4.0, 4.0 / np.cos(0.3)], atol=1e-12)
    assert r[2] == 30.0  # nothing behind: no return, exactly max range
    # A wall lower than the beam is flown over.
    assert raycast([1.0, 0.0, 1.41], d[:1], segs, 1.0)[0] == 30.0


def test_pitched_beam_hits_floor() -> None:
    a = np.deg2rad(30.0)
    d = np.array([[np.cos(a), 0.0, -np.sin(a)]])
    r = raycast([0.0, 0.0, 1.41], d, np.zeros((0, 4)))[0]
    assert r * np.cos(a) == pytest.approx(1.41 / np.tan(a), abs=1e-9)
    assert raycast_numpy([0.0, 0.0, 1.41], d, np.zeros((0, 4)))[0] == pytest.approx(r)


def test_odometry_drifts_and_path_is_clear(office_run) -> None:
    r = office_run
    drift = np.rad2deg(np.unwrap(r.odom[:, 2]) - np.unwrap(r.truth[:, 2]))
    assert abs(drift[-1]) >= 10.0
    np.testing.assert_allclose(r.odom[0], 0.0)
    np.testing.assert_allclose(r.truth[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(r.truth_world[0], r.world.start, atol=0.026)  # sub-cell start offset
    assert _seg_dist(r.truth_world[:, :2], r.world.segments).min() >= 0.3
    # Gait sway: a few cm of lateral oscillation while walking the first straight (y = 4.25).
    walk = (r.t - r.t[0] < 25.0) & (r.truth_world[:, 0] > 11.0)
    lat = r.truth_world[walk, 1] - r.truth_world[0, 1]
    assert 0.02 < lat.max() <= 0.031 and -0.031 <= lat.min() < -0.02


@pytest.mark.parametrize("seed", [1, 2])
def test_corridor_drift_and_clearance(tmp_path: Path, seed: int) -> None:
    r = simulate("corridor", 180.0, seed=seed, out_dir=tmp_path)
    drift = np.rad2deg(np.unwrap(r.odom[:, 2]) - np.unwrap(r.truth[:, 2]))
    assert abs(drift[-1]) >= 10.0
    assert _seg_dist(r.truth_world[:, :2], r.world.segments).min() >= 0.3
    assert r.truth_world[:, 0].max() > 35.0  # out to the far end and back


def test_office_path_closes_a_loop(office_run) -> None:
    xy = office_run.truth_world[:, :2]
    travelled = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))]
    later = travelled > 30.0
    assert np.any(later)
    assert np.min(np.linalg.norm(xy[later] - xy[0], axis=1)) < 1.0
    # A stationary stretch of about 5 s at the start.
    still = np.linalg.norm(xy - xy[0], axis=1) < 1e-9
    assert 4.0 < office_run.t[np.argmin(still)] - office_run.t[0] < 6.5


def test_simulate_writes_files(short_office) -> None:
    r = short_office  # simulate("office", 10.0, seed=3, ...), shared with the command-line tests
    for p in (
        r.lidar_path,
        r.joint_path,
        r.groundtruth_path,
        r.world_groundtruth_path,
        r.lidar_path.parent / "map.yaml",
        r.lidar_path.parent / "map.pgm",
    ):
        assert p.is_file()
    assert len(r.t) == 400
    assert np.all(np.diff(r.t) > 0) and 1.4e9 < r.t[0] < 1.5e9
    gt = np.loadtxt(r.groundtruth_path)
    assert gt.shape == (400, 8)
    np.testing.assert_allclose(gt[0, 1:3], 0.0, atol=1e-9)
    gtw = np.loadtxt(r.world_groundtruth_path)
    np.testing.assert_allclose(gtw[:, 1:3], r.truth_world[:, :2], atol=1e-8)
    if not HAVE_THOR:
        return
    from scipy.io import loadmat

    m = loadmat(r.lidar_path)
    rec = m["lidar"][0][5][0][0]
    assert rec["scan"].shape == (1, 1081)
    assert rec["scan"].dtype == np.float32
    assert rec["pose"].shape == (1, 3) and rec["rpy"].shape == (1, 3)
    assert rec["t"][0, 0] == pytest.approx(r.t[5])
    np.testing.assert_allclose(rec["pose"][0], r.odom[5])
    scans = np.stack([m["lidar"][0][i][0][0]["scan"][0] for i in range(len(r.t))])
    assert np.mean(scans == 30.0) < 0.5 and np.mean(scans == 0.0) < 0.01
    assert np.mean((scans > 0.1) & (scans < 30.0)) > 0.5
    j = loadmat(r.joint_path)
    ts = j["ts"][0]
    assert np.all(np.diff(ts) > 0)
    assert j["head_angles"].shape == (2, len(ts)) and j["rpy"].shape == (3, len(ts))
    assert ts[0] < r.t[0] and ts[-1] > r.t[-1]  # covers the lidar log
    assert not np.any(np.isin(np.round(r.t, 6), np.round(ts, 6)))  # a different clock
    assert abs(np.median(np.diff(ts)) - 0.025) > 0.005
    hp = j["head_angles"][1]
    assert np.all(hp >= 0.0) and np.all(hp <= np.deg2rad(20.0) + 1e-12)


@pytest.mark.skipif(not HAVE_THOR, reason="pfslam.io.thor not present")
def test_ucsd_layout_and_constant_head(tmp_path: Path) -> None:
    from scipy.io import loadmat

    r = simulate("corridor", 5.0, seed=4, out_dir=tmp_path, layout="ucsd", head_pitch=0.2, range_noise=0.0)
    m = loadmat(r.lidar_path)
    recs = [m["lidar"][0][i][0][0] for i in range(len(r.t))]
    assert "pose" not in recs[0].dtype.names
    d = np.stack([q["delta_pose"][0] for q in recs])
    np.testing.assert_allclose(d[0], 0.0)
    np.testing.assert_allclose(np.cumsum(d[:, :2], axis=0), r.odom[:, :2], atol=1e-9)
    j = loadmat(r.joint_path)
    np.testing.assert_allclose(j["head_angles"][0], 0.0)
    np.testing.assert_allclose(j["head_angles"][1], 0.2)


def test_unknown_world(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="office"):
        simulate("mars", 1.0, out_dir=tmp_path)


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(duration_s=INF), "duration must be a finite number of seconds > 0 and <= 3600, not inf"),
        (dict(duration_s=NAN), "duration must be a finite number of seconds"),
        (dict(duration_s=0.0), "duration"),
        (dict(head_pitch=NAN), "head_pitch must be a finite angle in radians"),
        (dict(head_pitch=3.0), "head_pitch"),
        (dict(rate_hz=INF), "rate_hz"),
        (dict(range_noise=NAN), "range_noise"),
        (dict(dropout=NAN), "dropout"),
    ],
)
def test_simulate_rejects_bad_numbers(tmp_path, kw, match):
    with pytest.raises(ConfigError, match=match):
        simulate("office", **{"duration_s": 1.0, **kw}, out_dir=tmp_path / "sim")
    assert not (tmp_path / "sim").exists()


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(axle=0.0), "axle"),
        (dict(speed=NAN), "speed"),
        (dict(beams=0), "beams"),
        (dict(scan_latency=INF), "scan_latency"),
        (dict(wheel_scale=0.0), "wheel_scale"),
        (dict(fov_deg=NAN), "fov_deg"),
    ],
)
def test_simulate_wheeled_rejects_bad_numbers(kw, match):
    with pytest.raises(ConfigError, match=match):
        simulate_wheeled(duration_s=1.0, **kw)


def test_rough_gait_sways_more_and_looks_at_the_floor_in_corners(tmp_path):
    from scipy.io import loadmat

    from pfslam.io.thor import thor_mounts

    calm = simulate("office", 60.0, seed=2, out_dir=tmp_path / "c")
    rough = simulate("office", 60.0, seed=2, out_dir=tmp_path / "r", gait="rough")
    drift = [abs(float(np.rad2deg(np.angle(np.exp(1j * (r.odom[-1, 2] - r.truth[-1, 2])))))) for r in (calm, rough)]
    assert drift[1] > 3 * drift[0]  # 0.8 deg/m against 0.1
    # The corners, from the true path: where it turns faster than 0.6 rad/s (a turn in place
    # peaks at 1.2; the walk's wobble stays near 0.1).
    rate = np.gradient(np.unwrap(rough.truth[:, 2]), rough.t)
    fast = np.abs(rate) > 0.6
    edges = np.flatnonzero(np.diff(np.r_[0, fast.astype(int), 0]))
    corners = list(zip(edges[::2], edges[1::2]))
    assert corners
    # The head, as the log's joint file records it.
    joint = loadmat(rough.joint_path)
    ts, head_pitch = joint["ts"].ravel(), joint["head_angles"][1]
    for a, b in corners:
        # Turned in place, not on an arc (a 0.4 m arc moves 0.6 m through a right angle): the
        # robot moves no more than its sway while it turns.
        assert np.hypot(*(rough.truth[b - 1, :2] - rough.truth[a, :2])) < 0.25, (rough.t[a] - rough.t[0], a, b)
        # In the middle of every turn the head pitches down to ~40 deg, so most beams hit the floor.
        mid = a + int(np.argmax(np.abs(rate[a:b])))
        pitch = float(np.interp(rough.t[mid], ts, head_pitch))
        assert np.rad2deg(pitch) == pytest.approx(40.0, abs=1.0)
        lidar = thor_mounts(0.0, 0.0, 0.0, pitch)[0]
        assert lidar[2, 3] / np.tan(pitch) < 2.0  # the beam straight ahead meets the floor within 2 m
    with pytest.raises(ConfigError, match="unknown gait"):
        simulate("office", 5.0, out_dir=tmp_path / "x", gait="wobbly")


# --- the aliasing worlds: places that repeat -------------------------------------------------

ALIASING = ("pillars", "rooms", "twins")


def _level_scan(world: str, x: float, y: float, heading: float) -> tuple[np.ndarray, np.ndarray]:
    """A level 270 deg scan (1081 beams, 1.2 m above the floor, no noise) at a pose of the
    world: the ranges and the (1081, 2) points they hit."""
    w = WORLDS[world]
    a = heading + np.deg2rad(np.linspace(-135.0, 135.0, 1081))
    r = raycast([x, y, 1.2], np.column_stack([np.cos(a), np.sin(a), np.zeros_like(a)]), w.segments, w.wall_height)
    return r, np.column_stack([x + r * np.cos(a), y + r * np.sin(a)])


def test_aliasing_worlds_exist() -> None:
    for name in ALIASING:
        w = WORLDS[name]
        assert w.name == name
        np.testing.assert_allclose(w.start[:2], w.waypoints[0])
        d = w.waypoints[1] - w.waypoints[0]
        assert w.start[2] == pytest.approx(np.arctan2(d[1], d[0]))  # facing along the first leg
        wp = np.vstack([w.waypoints, w.waypoints[:1]])
        assert 50.0 < np.sum(np.linalg.norm(np.diff(wp, axis=0), axis=1)) < 75.0  # one loop in 180 s


@pytest.mark.parametrize("gait", ["calm", "rough"])
@pytest.mark.parametrize("world", sorted(WORLDS))
def test_route_keeps_clear_of_walls(tmp_path: Path, world: str, gait: str) -> None:
    """The whole 180 s walk (230 s in the block building and the colonnade, whose laps are 96
    and 98 m; seed 1, 5 scans/s: truth poses 0.1 m apart) stays 0.6 m from every wall, sway
    included; the loops are walked round and back to the start."""
    long = world in ("block", "colonnade")
    r = simulate(world, 230.0 if long else 180.0, seed=1, out_dir=tmp_path, rate_hz=5.0, gait=gait)
    xy = r.truth_world[:, :2]
    assert _seg_dist(xy, r.world.segments).min() >= 0.6
    if world in ("corridor", "bare"):  # out and back
        return
    wp = np.vstack([r.world.waypoints, r.world.waypoints[:1]])
    loop = np.sum(np.linalg.norm(np.diff(wp, axis=0), axis=1))
    travelled = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))]
    assert travelled[-1] > loop + 2.0
    later = travelled > loop / 2.0
    assert np.min(np.linalg.norm(xy[later] - xy[0], axis=1)) < 0.5


def test_pillars_corridor_looks_the_same_one_pillar_on() -> None:
    """Along a long corridor a scan 3 m (one pillar) further on is the same but for the few
    beams that reach the corridor's ends; half a spacing on the pillars and door recesses have
    swapped sides. The north corridor is the south one turned round."""
    for x, heading in ((9.0, 0.0), (10.7, 0.3), (12.0, np.pi)):
        here, _ = _level_scan("pillars", x, 1.3, heading)
        on, _ = _level_scan("pillars", x + 3.0, 1.3, heading)
        half, _ = _level_scan("pillars", x + 1.5, 1.3, heading)
        north, _ = _level_scan("pillars", 27.0 - x, 8.7, heading + np.pi)
        assert np.median(np.abs(on - here)) < 0.05
        assert np.mean(np.abs(on - here) > 0.05) < 0.1
        assert np.median(np.abs(north - here)) < 0.05
        assert np.median(np.abs(half - here)) > 0.3
        assert np.mean(np.abs(half - here) > 0.05) > 0.5


def test_rooms_look_alike() -> None:
    """The same pose in two neighbouring rooms sees the same room (every beam that ends inside
    both rooms has the same range); half a room on it does not."""
    for k in (1, 3):
        x0 = 1.0 + 5.0 * k
        for dx, y, heading in ((2.5, 4.3, 0.7), (1.8, 5.8, -2.0)):
            a, pa = _level_scan("rooms", x0 + dx, y, heading)
            b, pb = _level_scan("rooms", x0 + 5.0 + dx, y, heading)
            c, _ = _level_scan("rooms", x0 + 2.5 + dx, y, heading)
            inside = (
                (pa[:, 0] > x0 - 0.01)
                & (pa[:, 0] < x0 + 5.01)
                & (pa[:, 1] > 2.59)
                & (pa[:, 1] < 7.61)
                & (pb[:, 0] > x0 + 4.99)
                & (pb[:, 0] < x0 + 10.01)
                & (pb[:, 1] > 2.59)
                & (pb[:, 1] < 7.61)
            )
            assert inside.mean() > 0.5
            assert np.median(np.abs(a - b)[inside]) < 0.05
            assert np.max(np.abs(a - b)[inside]) < 0.01
            assert np.median(np.abs(a - c)[inside]) > 0.5


def test_twins_corridors_look_alike() -> None:
    """Corridors A (south) and C (6.4 m north of it) are walked the same way and look the same
    from their middle part; each also repeats every 3 m."""
    for x in (7.0, 8.5, 9.3):
        a, _ = _level_scan("twins", x, 1.3, 0.0)
        c, _ = _level_scan("twins", x, 7.7, 0.0)
        on, _ = _level_scan("twins", x + 3.0, 1.3, 0.0)
        half, _ = _level_scan("twins", x + 1.5, 1.3, 0.0)
        assert np.median(np.abs(c - a)) < 0.05 and np.mean(np.abs(c - a) > 0.05) < 0.05
        assert np.median(np.abs(on - a)) < 0.05
        assert np.median(np.abs(half - a)) > 0.3


def test_simulate_command_odometry_scale(tmp_path: Path) -> None:
    """`pfslam simulate --odometry-scale X`: the odometry's travel is X times the true one
    (over the whole walk, the white noise aside); a bad value or one with --no-drift is a
    one-line error."""
    from clirun import invoke, one_line_error

    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import read_tum

    res, err = invoke("simulate", "-o", tmp_path / "w", "--duration", 20, "--odometry-scale", 1.1, "--seed", 2)
    assert res.exit_code == 0, (res.output, err)
    odom = np.array(
        [f.odom for f in load_log(tmp_path / "w" / "train_lidar0.mat", tmp_path / "w" / "train_joint0.mat").frames]
    )
    _, truth = read_tum(tmp_path / "w" / "groundtruth.tum")
    travel = lambda p: float(np.hypot(*np.diff(p[:, :2], axis=0).T).sum())  # noqa: E731
    assert travel(odom) / travel(truth) == pytest.approx(1.1, abs=0.02)
    one_line_error(*invoke("simulate", "-o", tmp_path / "x", "--odometry-scale", 3.0), "odometry_scale")
    one_line_error(*invoke("simulate", "-o", tmp_path / "y", "--odometry-scale", 1.1, "--no-drift"), "--no-drift")


@pytest.mark.parametrize("storage", ["ros1", "ros2"])
def test_wheeled_bag_drives_the_route_with_odometry_in_tf(tmp_path: Path, storage: str) -> None:
    """A wheeled robot's bag of the block building: its scans and its odometry (the odom ->
    base_link link of /tf, no odometry topic) read back as written, the ground truth at the
    scans' times, and the laser's returns where the world's walls are."""
    from rosbags.highlevel import AnyReader

    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import read_tum
    from pfslam.tools.wheeled import LASER_MOUNT, simulate_wheeled_bag

    res = simulate_wheeled_bag("block", 30.0, seed=2, out_dir=tmp_path, storage=storage, rate_hz=5.0)
    with AnyReader([res.bag]) as reader:
        topics = {c.topic for c in reader.connections}
    assert "/odom" not in topics and {"/scan", "/tf", "/tf_static"} <= topics
    log = load_log(res.bag)
    f = log.frames
    assert len(f) == 150 and log.warnings == []
    np.testing.assert_allclose(f.odom, res.odom, atol=1e-9)
    np.testing.assert_allclose(f[0].mount[:3, 3], LASER_MOUNT)
    t, truth = read_tum(res.groundtruth_path)
    np.testing.assert_allclose(t, f.t, atol=1e-6)
    assert np.hypot(*truth[-1, :2]) > 10.0  # it drove along the corridor, 0.6 m/s less its pauses
    drift = np.hypot(*(res.odom[-1, :2] - truth[-1, :2]))
    assert 0.01 < drift < 2.0  # the odometry drifts, a little over 30 s
    # the first scan: at the start, 1.5 m from the corridor's walls on either side
    r, a = f[0].ranges, f[0].angles
    side = np.abs(np.abs(a) - np.pi / 2) < 0.01
    np.testing.assert_allclose(r[side], 1.5, atol=0.1)


def test_a_wheeled_robot_turns_about_at_a_corridors_end(tmp_path: Path) -> None:
    """Out and back along the bare corridor (waypoints at either end): the robot turns round in
    place at the far end and drives back, inside the corridor all the way."""
    from pfslam.tools.wheeled import simulate_wheeled_bag

    res = simulate_wheeled_bag("bare", 60.0, seed=0, out_dir=tmp_path, speed=4.0, rate_hz=5.0)
    w = WORLDS["bare"]
    xy = compose(w.start, res.truth)[:, :2]  # (the walk starts within 2.5 cm of the world's start)
    assert _seg_dist(xy, w.segments).min() > 0.5  # never through a wall
    far = int(np.argmax(xy[:, 0]))
    assert xy[far, 0] > 95.0 and xy[-1, 0] < xy[far, 0] - 20.0  # to the far end and back
    assert np.all(np.abs(xy[:, 1]) < 1.2)


def test_simulate_command_wheeled(tmp_path: Path) -> None:
    """`pfslam simulate --robot wheeled`: a bag (here MCAP) with its ground truth and map, with
    the odometry 5 % long as asked; the humanoid's options and an unknown robot or bag kind are
    one-line errors."""
    from clirun import invoke, one_line_error

    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import read_tum

    out = tmp_path / "w"
    res, err = invoke(
        "simulate", "--robot", "wheeled", "--bag", "mcap", "-o", out, "--duration", 20, "--odometry-scale", 1.05
    )
    assert res.exit_code == 0, (res.output, err)
    assert sorted(p.name for p in out.iterdir()) == ["groundtruth.tum", "log.mcap", "map.pgm", "map.yaml"]
    odom = load_log(out / "log.mcap").frames.odom
    _, truth = read_tum(out / "groundtruth.tum")
    travel = lambda p: float(np.hypot(*np.diff(p[:, :2], axis=0).T).sum())  # noqa: E731
    assert travel(odom) / travel(truth) == pytest.approx(1.05, abs=0.02)
    one_line_error(*invoke("simulate", "--robot", "wheeled", "-o", tmp_path / "a", "--gait", "rough"), "--gait")
    one_line_error(*invoke("simulate", "--robot", "legged", "-o", tmp_path / "b"), "--robot")
    one_line_error(*invoke("simulate", "--robot", "wheeled", "--bag", "zip", "-o", tmp_path / "c"), "zip")
    one_line_error(*invoke("simulate", "-o", tmp_path / "d", "--max-range", 5.6), "--max-range")
    # a short-range laser in the open hall (a 10 s log): no return beyond its reach, and many
    # beams with none at all (ranges in metres; nothing here is timed)
    reach = 5.6
    res, err = invoke("simulate", "--robot", "wheeled", "--world", "hall", "--max-range", reach, "-o", tmp_path / "e",
                      "--duration", 10)  # fmt: skip
    assert res.exit_code == 0, (res.output, err)
    f = load_log(tmp_path / "e" / "log.bag").frames
    ranges_m = np.concatenate([fr.ranges for fr in f])
    assert f[0].max_range == pytest.approx(reach)
    assert ranges_m.max() < reach + 0.1  # (range noise: 1 cm)
    on_a_wall = ranges_m < reach - 0.1  # (a beam with no return reads the laser's reach)
    assert 0.1 < on_a_wall.mean() < 0.8
