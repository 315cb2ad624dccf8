"""Monte Carlo localization: the pieces, then tracking, global localization, kidnapping, KLD."""

import copy

import numpy as np
import pytest

from pfslam.errors import InputError
from pfslam.geometry import compose, relative, wrap_angle
from pfslam.grid import OccupancyGrid
from pfslam.io.logs import load_log
from pfslam.kernels import likelihood_kernel, likelihood_numpy
from pfslam.localize import LikelihoodField, Localizer, LocalizerConfig, kld_bound, systematic_draw
from pfslam.motion import AmclOdometryMotion
from pfslam.particles import ParticleSet
from pfslam.simulate import simulate


def _room():
    g = OccupancyGrid(origin=(-1.0, -1.0), shape=(200, 240))  # 12 x 10 m
    g.logodds[:] = -10
    g.logodds[20, 20:220] = g.logodds[180, 20:220] = 10
    g.logodds[20:181, 20] = g.logodds[20:181, 220] = 10
    g.logodds[80:120, 100:140] = 10  # a block in the middle
    return g


@pytest.mark.parametrize("seed", range(3))
def test_likelihood_kernel_matches_numpy(seed):
    rng = np.random.default_rng(seed)
    logp = rng.normal(-2, 1, (80, 90)).astype(np.float32)
    poses = np.column_stack([rng.uniform(0, 4, 50), rng.uniform(0, 4, 50), rng.uniform(-3, 3, 50)])
    pts = rng.uniform(-3, 3, (60, 2))
    args = (poses, pts, logp, -0.2, 0.1, 20.0, -7.0)
    # The kernel sums in float32 across SIMD lanes, the twin in float64.
    np.testing.assert_allclose(likelihood_kernel(*args), likelihood_numpy(*args), rtol=1e-6)


def test_likelihood_field_peaks_on_walls_and_falls_with_distance():
    g = _room()
    f = LikelihoodField.from_grid(g, sigma_hit=0.2, max_dist=2.0)
    row = f.logp[100, 20:60]  # from the west wall into the room
    assert row[0] == f.logp.max()
    assert np.all(np.diff(row[:40]) <= 1e-6) and row[39] < row[0] - 5
    assert f.floor <= f.logp.min() + 1e-6


def test_circular_mean_of_minus_179_and_179_is_180():
    ps = ParticleSet(np.array([[0, 0, np.deg2rad(-179)], [0, 0, np.deg2rad(179)]]))
    assert abs(abs(np.rad2deg(ps.mean()[2])) - 180) < 1e-9


def test_global_init_uniform_over_free_space_and_errors():
    g = _room()
    loc = Localizer(g, LocalizerConfig(global_particles=20000))
    loc.initialize_global()
    p = loc.particles.poses
    r, c = g.world_to_cell(p[:, :2])
    assert np.all(g.thresholded()[r, c] == 0)
    assert np.allclose(loc.particles.weights, 1 / 20000)
    assert np.hypot(np.mean(np.cos(p[:, 2])), np.mean(np.sin(p[:, 2]))) < 0.03
    with pytest.raises(InputError, match="outside the map"):
        loc.initialize_around([50.0, 0.0, 0.0], [0.1, 0.1, 0.1])
    with pytest.raises(InputError, match="occupied"):
        loc.initialize_around([0.025, 4.0, 0.0], [0.1, 0.1, 0.1])  # on the west wall
    full = OccupancyGrid(origin=(0, 0), shape=(10, 10))
    full.logodds[:] = 10
    with pytest.raises(InputError, match="no free cells"):
        Localizer(full).initialize_global()


def test_amcl_motion_model():
    rng = np.random.default_rng(0)
    p = np.tile([1.0, 2.0, 0.3], (2000, 1))
    u = np.array([0.5, 0.05, 0.2])
    exact = AmclOdometryMotion(0, 0, 0, 0).apply(p, u, rng)
    np.testing.assert_allclose(exact, compose(p, u), atol=1e-12)
    m = AmclOdometryMotion()
    short = m.apply(p, u * 0.2, rng)
    long = m.apply(p, u, rng)
    assert np.std(long[:, 0]) > 2 * np.std(short[:, 0])
    np.testing.assert_allclose(np.mean(long, axis=0), compose(p[0], u), atol=0.02)
    back = m.apply(p, np.array([-0.5, 0.0, 0.0]), rng)  # reversing is not a half turn
    assert np.all(np.abs(wrap_angle(back[:, 2] - 0.3)) < 0.6)
    np.testing.assert_allclose(m.apply(p, np.zeros(3), rng), p, atol=1e-12)


def test_kld_bound_and_systematic_draw():
    assert kld_bound(1, 0.05, 0.99) == 1
    assert kld_bound(2, 0.05, 0.99) < kld_bound(50, 0.05, 0.99) < kld_bound(500, 0.05, 0.99)
    w = np.array([0.1, 0.0, 0.6, 0.3])
    idx = systematic_draw(w, 1000, np.random.default_rng(1))
    np.testing.assert_allclose(np.bincount(idx, minlength=4) / 1000, w, atol=0.002)


@pytest.fixture(scope="module")
def office(tmp_path_factory):
    d = tmp_path_factory.mktemp("loc")
    res = simulate("office", 180.0, seed=4, out_dir=d)
    return res, load_log(res.lidar_path, res.joint_path).frames, OccupancyGrid.load_ros(d / "map.yaml")


def _errors(est, truth):
    pos = np.hypot(*(est[:, :2] - truth[:, :2]).T)
    head = np.rad2deg(np.abs(wrap_angle(est[:, 2] - truth[:, 2])))
    return pos, head


def test_tracking_from_a_known_start(office):
    res, frames, grid = office
    odo_drift = np.rad2deg(abs(wrap_angle(res.odom[-1, 2] - res.truth[-1, 2])))
    assert odo_drift > 10
    loc = Localizer(grid, LocalizerConfig(seed=1))
    loc.initialize_around(res.truth[0], [0.1, 0.1, np.deg2rad(3)])
    est = np.array([loc.step(f).pose for f in frames])
    pos, head = _errors(est, res.truth)
    assert np.sqrt(np.mean(pos**2)) <= 0.10
    assert np.sqrt(np.mean(head**2)) <= 2.0
    # KLD: the particle count settles at the lower end once the filter has converged.
    assert loc.n <= 0.2 * loc.config.max_particles


def test_global_localization_converges(tmp_path):
    converged = 0
    for seed in range(10):
        res = simulate("office", 40.0, seed=seed, out_dir=tmp_path / str(seed))
        frames = load_log(res.lidar_path, res.joint_path).frames
        grid = OccupancyGrid.load_ros(tmp_path / str(seed) / "map.yaml")
        loc = Localizer(grid, LocalizerConfig(seed=seed))
        loc.initialize_global()
        counts = []
        est = []
        for f in frames:
            est.append(loc.step(f).pose)
            counts.append(loc.n)
        pos, _ = _errors(np.array(est), res.truth)
        moved = np.nonzero(np.hypot(*(res.truth[:, :2] - res.truth[0, :2]).T) > 0.05)[0][0]
        t_move = res.t - res.t[moved]
        bad = np.nonzero(pos > 0.3)[0]
        t_conv = t_move[bad[-1]] if len(bad) else t_move[0]
        converged += int(t_conv <= 30.0)
        if seed == 0:  # KLD: from the global spread down towards the minimum
            assert max(counts) >= 0.9 * loc.config.max_particles and counts[-1] <= 0.2 * loc.config.max_particles
    print(f"global localization converged in {converged}/10 seeds")
    assert converged >= 9


def _kidnapped(res, frames, jump_at=40.0, min_jump=10.0):
    t = res.t - res.t[0]
    g = res.truth
    k1 = int(np.searchsorted(t, jump_at))
    d = np.hypot(*(g[:, :2] - g[k1, :2]).T)
    k2 = int(np.nonzero((d >= min_jump) & (t > jump_at + 30))[0][0])
    out, truth = list(frames[: k1 + 1]), list(g[: k1 + 1])
    for j in range(k2 + 1, len(frames)):
        f = copy.copy(frames[j])  # the robot is carried away: its odometry does not notice
        f.odom = compose(frames[k1].odom, relative(frames[k2].odom, frames[j].odom))
        f.t = frames[k1].t + (frames[j].t - frames[k2].t)
        out.append(f)
        truth.append(g[j])
    return out, np.array(truth), k1, d[k2]


@pytest.mark.parametrize("recovery", [True, False])
def test_kidnapped_robot(office, recovery):
    res, frames, grid = office
    seq, truth, k1, jump = _kidnapped(res, frames)
    assert jump >= 10.0
    loc = Localizer(grid, LocalizerConfig(seed=2, recovery=recovery))
    loc.initialize_around(truth[0], [0.1, 0.1, np.deg2rad(3)])
    est = np.array([loc.step(f).pose for f in seq])
    pos, _ = _errors(est, truth)
    t = np.array([f.t for f in seq]) - seq[k1].t
    assert pos[:k1].max() < 0.3
    after = np.nonzero((t > 0) & (pos > 0.3))[0]
    back_within = t[after[-1]] if len(after) else 0.0
    if recovery:
        assert back_within <= 30.0 and pos[-1] < 0.3
    else:
        assert pos[t > 30.0].mean() > 1.0


def test_vectorised_kld_bounds_match_the_scalar_formula():
    from pfslam.localize import kld_bounds

    ks = np.array([1, 2, 3, 10, 77, 500])
    np.testing.assert_array_equal(kld_bounds(ks, 0.05, 0.99), [kld_bound(int(k), 0.05, 0.99) for k in ks])


def test_beam_kernel_matches_twin_and_casts_exact_ranges():
    from pfslam.kernels import beam_kernel, beam_numpy, cast_ray

    occ = np.zeros((100, 100), np.uint8)
    occ[:, 70] = 1  # a wall at x = 3.5 m (0.05 m cells from the origin)
    occ[20, :] = 1
    assert cast_ray(occ, 0.0, 0.0, 20.0, 1.0, 2.5, 1.0, 0.0, 30.0) == pytest.approx(2.5)
    assert cast_ray(occ, 0.0, 0.0, 20.0, 1.0, 2.5, -1.0, 0.0, 30.0) == 30.0  # leaves the grid
    rng = np.random.default_rng(0)
    poses = np.column_stack([rng.uniform(1, 3, 20), rng.uniform(1.5, 4, 20), rng.uniform(-3, 3, 20)])
    pts = rng.uniform(-2, 2, (30, 2))
    args = (poses, np.array([0.1, 0.0]), pts, occ, 0.0, 0.0, 20.0, 30.0, 0.1, 0.8, 0.1, 0.5, 0.1)
    np.testing.assert_allclose(beam_kernel(*args), beam_numpy(*args), atol=1e-9)


def test_beam_model_tracks_too(office):
    res, frames, grid = office
    loc = Localizer(grid, LocalizerConfig(seed=1, model="beam"))
    loc.initialize_around(res.truth[0], [0.1, 0.1, np.deg2rad(3)])
    n = 2400
    est = np.array([loc.step(f).pose for f in frames[:n]])
    pos, head = _errors(est, res.truth[:n])
    assert np.sqrt(np.mean(pos**2)) <= 0.10 and np.sqrt(np.mean(head**2)) <= 2.0


def test_predict_uses_wheel_travel_when_frames_have_it():
    from pfslam.frames import Frame

    g = _room()
    loc = Localizer(g, LocalizerConfig(seed=0, k_left=0.0, k_right=0.0, axle=0.5))
    loc.initialize_around([2.0, 2.0, 0.0], [0.0, 0.0, 0.0])
    f0 = Frame(t=0.0, ranges=np.array([]), angles=np.array([]), wheels=np.array([0.0, 0.0]))
    f1 = Frame(t=0.1, ranges=np.array([]), angles=np.array([]), wheels=np.array([0.4, 0.6]))
    loc._prev = f0
    loc.predict(f1)
    from pfslam.motion import DiffDriveMotion

    want = DiffDriveMotion.arc(np.array([[2.0, 2.0, 0.0]]), np.array(0.4), np.array(0.6), 0.5)[0]
    np.testing.assert_allclose(loc.particles.poses, np.tile(want, (len(loc.particles), 1)), atol=1e-12)
    loc2 = Localizer(g, LocalizerConfig(seed=0, axle=0.5))
    loc2.initialize_around([2.0, 2.0, 0.0], [0.0, 0.0, 0.0])
    loc2._prev = f0
    loc2.predict(f1)
    assert np.std(loc2.particles.poses[:, 2]) > 0.01  # wheel noise proportional to travel


# --- a self-contained synthetic world: a room with an off-centre block, ray-cast scans --------
#
# Independent of the simulator: a 10 x 8 m room (0.05 m cells) with a block and a pillar placed
# so that no rotation or mirror maps the room onto itself; scans of 181 beams over 360 deg are
# ray-cast from the true poses (sensor 0.5 m above the floor); odometry drifts (3 % scale,
# 1.5 deg of heading per metre, plus noise).

from dataclasses import asdict  # noqa: E402

import yaml  # noqa: E402

from pfslam.errors import ConfigError  # noqa: E402
from pfslam.frames import Frame  # noqa: E402
from pfslam.kernels import cast_ray  # noqa: E402
from pfslam.localize import DRAWERS  # noqa: E402

_ANGLES = np.linspace(-np.pi, np.pi, 181, endpoint=False)
_MOUNT = np.eye(4)
_MOUNT[2, 3] = 0.5


def _asym_room():
    g = OccupancyGrid(resolution=0.05, origin=(-1.0, -1.0), shape=(200, 240))  # x -1..11, y -1..9
    g.logodds[:] = -10
    g.logodds[20, 20:221] = g.logodds[180, 20:221] = 10  # walls y = 0 and y = 8
    g.logodds[20:181, 20] = g.logodds[20:181, 220] = 10  # walls x = 0 and x = 10
    g.logodds[60:111, 60:101] = 10  # block x 2..4, y 2..4.5
    g.logodds[130:139, 160:169] = 10  # pillar near (7.2, 5.7)
    return g


def _path(waypoints, step=0.08, turn=np.deg2rad(10)):
    """Turn in place towards each next waypoint, then drive to it in steps of ``step`` m."""
    w = np.asarray(waypoints, float)
    th = np.arctan2(w[1, 1] - w[0, 1], w[1, 0] - w[0, 0])
    out = [[w[0, 0], w[0, 1], th]]
    for a, b in zip(w[:-1], w[1:]):
        want = np.arctan2(b[1] - a[1], b[0] - a[0])
        d_th = float(wrap_angle(want - th))
        steps = int(np.ceil(abs(d_th) / turn))
        for j in range(1, steps + 1):
            out.append([a[0], a[1], float(wrap_angle(th + d_th * j / steps))])
        th = want
        n = int(np.ceil(np.hypot(*(b - a)) / step))
        for k in range(1, n + 1):
            p = a + (b - a) * k / n
            out.append([p[0], p[1], th])
    return np.array(out)


def _odometry(truth, rng, jumps=()):
    """Drifting odometry (starting at the origin of its own frame); at the indices in ``jumps``
    the robot is carried away and its odometry does not notice."""
    odom = [np.zeros(3)]
    for k in range(1, len(truth)):
        u = relative(truth[k - 1], truth[k])
        d = float(np.hypot(u[0], u[1]))
        if k in jumps or (d == 0 and u[2] == 0):
            u = np.zeros(3)
        else:
            u = np.array([1.03 * u[0], u[1], u[2] + np.deg2rad(1.5) * d])
            u = u + rng.normal(size=3) * [0.003, 0.002, np.deg2rad(0.3)]
        odom.append(compose(odom[-1], u))
    return np.array(odom)


def _frames(grid, truth, odom, rng, dt=0.1):
    occ = np.ascontiguousarray((grid.thresholded() == 100).astype(np.uint8))
    ox, oy = grid.origin
    out = []
    for k, p in enumerate(truth):
        a = p[2] + _ANGLES
        r = np.array([cast_ray(occ, ox, oy, 1 / grid.resolution, p[0], p[1], np.cos(b), np.sin(b), 30.0) for b in a])
        r = r + rng.normal(size=len(r)) * 0.01
        out.append(Frame(t=k * dt, ranges=r, angles=_ANGLES.copy(), odom=odom[k], mount=_MOUNT, max_range=30.0))
    return out


_LOOP = [(1.0, 1.0), (8.5, 1.0), (8.5, 6.8), (1.0, 6.8), (1.0, 1.5)]


@pytest.fixture(scope="module")
def world():
    g = _asym_room()
    truth = _path(_LOOP)
    rng = np.random.default_rng(7)
    odom = _odometry(truth, rng)
    return g, truth, _frames(g, truth, odom, rng)


def test_synthetic_world_is_sane(world):
    g, truth, frames = world
    r, c = g.world_to_cell(truth[:, :2])
    assert np.all(g.thresholded()[r, c] == 0)
    odom = np.array([f.odom for f in frames])
    dead = compose(truth[0], relative(odom[0], odom))  # odometry placed at the true start
    assert np.hypot(*(dead[-1, :2] - truth[-1, :2])) > 1.0  # it drifts
    sp = frames[0]
    assert np.all(np.isfinite(sp.ranges)) and sp.ranges.max() < 12.0


def test_synthetic_tracking_with_drifting_odometry(world):
    g, truth, frames = world
    loc = Localizer(g, LocalizerConfig(seed=0))
    loc.initialize_around(truth[0], [0.1, 0.1, np.deg2rad(3)])
    est = np.array([loc.step(f).pose for f in frames])
    pos, head = _errors(est, truth)
    assert pos[-1] < 0.15 and np.sqrt(np.mean(pos**2)) < 0.1
    assert np.sqrt(np.mean(head**2)) < 2.0
    cov = loc.covariance
    assert cov.shape == (3, 3) and np.all(np.linalg.eigvalsh(cov) >= -1e-12) and np.trace(cov[:2, :2]) < 0.05


def test_synthetic_global_localization_and_kld(world):
    g, truth, frames = world
    cfg = LocalizerConfig(seed=3)
    loc = Localizer(g, cfg)
    loc.initialize_global()
    assert loc.n == cfg.global_particles
    est, counts = [], []
    for f in frames:
        est.append(loc.step(f).pose)
        counts.append(loc.n)
    pos, _ = _errors(np.array(est), truth)
    bad = np.nonzero(pos > 0.3)[0]
    assert len(bad) == 0 or bad[-1] < 60  # converged within 60 steps (about 4 m) and stayed
    assert pos[-1] < 0.15
    # KLD: down to min_particles (a 360 deg scan in this room leaves a single mode at once).
    assert max(counts[5:]) < 0.3 * cfg.max_particles and counts[-1] == cfg.min_particles


def test_kld_count_is_max_for_a_spread_set_and_min_for_a_tight_one():
    g = _asym_room()
    cfg = LocalizerConfig(seed=0, recovery=False, global_particles=20000)
    loc = Localizer(g, cfg)
    loc.initialize_global()
    rng = np.random.default_rng(0)
    loc.particles.log_weights = rng.normal(size=loc.n) * 2.0  # uneven: N_eff << N
    loc.particles.normalize()
    assert loc.resample() and loc.n == cfg.max_particles  # thousands of occupied bins
    loc.initialize_around([5.0, 6.0, 1.0], [0.05, 0.05, 0.02])
    loc.particles.log_weights = rng.normal(size=loc.n) * 2.0
    loc.particles.normalize()
    assert loc.resample() and loc.n == cfg.min_particles  # a handful of bins
    loc.particles.log_weights[:] = -np.log(loc.n)
    assert not loc.resample()  # N_eff = N: nothing to do


@pytest.fixture(scope="module")
def kidnapping():
    g = _asym_room()
    a = _path([(1.0, 1.0), (8.5, 1.0), (8.5, 6.8)])  # east, then north
    b = _path([(4.5, 6.8), (1.0, 6.8), (1.0, 1.0), (6.0, 1.0)])  # carried 4 m west, turned round
    truth = np.vstack([a, b])
    rng = np.random.default_rng(11)
    odom = _odometry(truth, rng, jumps={len(a)})
    return g, truth, _frames(g, truth, odom, rng), len(a)


@pytest.mark.parametrize("recovery", [True, False])
def test_synthetic_kidnapped_robot(kidnapping, recovery):
    g, truth, frames, k = kidnapping
    assert np.hypot(*(truth[k, :2] - truth[k - 1, :2])) >= 4.0
    loc = Localizer(g, LocalizerConfig(seed=5, recovery=recovery))
    loc.initialize_around(truth[0], [0.1, 0.1, np.deg2rad(3)])
    est = np.array([loc.step(f).pose for f in frames])
    pos, _ = _errors(est, truth)
    assert pos[:k].max() < 0.3
    after = pos[k:]
    if recovery:
        bad = np.nonzero(after > 0.3)[0]
        assert bad[-1] < 40 and after[-1] < 0.15  # back within 40 steps (about 3 m) for good
    else:
        assert np.mean(after[80:]) > 1.0


def test_step_before_initialisation_is_a_clear_error(world):
    g, _, frames = world
    loc = Localizer(g)
    with pytest.raises(RuntimeError, match="initialize"):
        loc.step(frames[0])
    with pytest.raises(InputError, match="three finite numbers"):
        loc.check_pose([1.0, 2.0])


def test_config_validates_and_round_trips_through_yaml():
    cfg = LocalizerConfig(particles=300, resample_method="stratified")
    back = LocalizerConfig(**yaml.safe_load(yaml.safe_dump(asdict(cfg))))
    assert back == cfg and back.validate() is back
    for bad in (dict(min_particles=600, max_particles=500), dict(resample_method="magic"), dict(beam_temperature=0),
                dict(recovery_alpha_slow=0.2, recovery_alpha_fast=0.1), dict(kld_err=0.0), dict(alpha3=-0.1)):
        with pytest.raises(ConfigError):
            LocalizerConfig(**bad).validate()


@pytest.mark.parametrize("method", sorted(DRAWERS))
def test_every_resampling_scheme_draws_n_indices_by_weight(method):
    w = np.array([0.1, 0.0, 0.6, 0.3])
    idx = DRAWERS[method](w, 20000, np.random.default_rng(2))
    assert len(idx) == 20000 and np.all(np.bincount(idx, minlength=4)[1] == 0)
    np.testing.assert_allclose(np.bincount(idx, minlength=4) / 20000, w, atol=0.01)


def test_localizer_runs_with_other_resampling_schemes(world):
    g, truth, frames = world
    for method in ("stratified", "residual"):
        loc = Localizer(g, LocalizerConfig(seed=1, resample_method=method))
        loc.initialize_around(truth[0], [0.1, 0.1, np.deg2rad(3)])
        est = np.array([loc.step(f).pose for f in frames[:120]])
        pos, _ = _errors(est, truth[:120])
        assert pos.max() < 0.3


def test_amcl_motion_is_exact_without_noise_backwards_and_sideways():
    rng = np.random.default_rng(0)
    p = np.array([[1.0, 2.0, 0.3], [-1.0, 0.5, 3.0]])
    m = AmclOdometryMotion(0, 0, 0, 0)
    for u in ([-0.5, 0.1, 0.3], [0.0, 0.004, 0.0], [0.003, -0.002, 0.01], [-0.2, -0.3, -2.5]):
        np.testing.assert_allclose(m.apply(p, np.array(u), rng), compose(p, np.array(u)), atol=1e-12)
    # Sub-centimetre sideways jitter does not turn into heading noise of alpha1 * 90 deg.
    q = AmclOdometryMotion().apply(np.tile([0.0, 0.0, 0.0], (2000, 1)), np.array([0.0, 0.005, 0.0]), rng)
    assert np.std(q[:, 2]) < 0.01
