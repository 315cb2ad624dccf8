"""The Rao-Blackwellized filter: a Filter like the others; its trajectory is the best
particle's whole path (odometry between updates, the recorded poses at updates); it closes
a long loop the single-map filter cannot; its run records what it counted."""

import json

import numpy as np
import pytest

from pfslam.config import LocalSearchConfig, SlamConfig, with_values
from pfslam.errors import ConfigError
from pfslam.eval.metrics import trajectory_errors
from pfslam.filters import Filter
from pfslam.filters.rbpf import RaoBlackwellizedSlam
from pfslam.geometry import relative, wrap_angle
from pfslam.io.logs import load_log
from pfslam.pipeline import close_loops, make_slam, run_slam, write_outputs
from pfslam.pipeline.closing import run_backend
from pfslam.tools.simulate import simulate


def _cfg(**values):
    return with_values(SlamConfig(), {"filter": "rbpf", **values})


@pytest.fixture(scope="module")
def walk(short_office):
    log = load_log(short_office.lidar_path, short_office.joint_path)
    return log.frames, short_office


def test_it_is_a_filter_and_the_config_chooses_it():
    assert isinstance(RaoBlackwellizedSlam(_cfg()), Filter)
    assert isinstance(make_slam(_cfg()), RaoBlackwellizedSlam)
    assert isinstance(make_slam(SlamConfig()), RaoBlackwellizedSlam)  # auto: rbpf, with or without a log kind
    assert not isinstance(make_slam(SlamConfig(filter="single")), RaoBlackwellizedSlam)
    assert not isinstance(make_slam(SlamConfig(local_search=LocalSearchConfig(enabled=True))), RaoBlackwellizedSlam)


def test_the_trajectory_is_the_best_particles_path_with_odometry_between_updates(walk):
    frames, sim = walk
    # Resampling after every update: the best particle's ancestors are other particles.
    f = RaoBlackwellizedSlam(_cfg(**{"particles": 8, "rbpf.update_m": 0.2, "resample_threshold": 1.0}))
    updated, at_update = [], []  # per scan: whether it updated; per update: every particle's pose
    for fr in frames:
        updated.append(f.step(fr).updated)
        if updated[-1]:
            at_update.append(f.particles.poses)  # no odometry since the update: the poses it recorded
    t, poses = f.trajectory()
    assert len(t) == len(frames) and (np.diff(t) > 0).all()
    assert f.updates == len(at_update) > 5 and f.resamples > 5 and f.maps.unique_tiles > 0
    # Walk the ancestry by hand: the poses at the update scans are the best particle's. Who
    # descends from whom is the filter's own record (_node_parents): nothing public shows it.
    b = f._parents[f.best_index]  # (through the resampling that trajectory() finished)
    path = []
    for u in range(len(at_update) - 1, -1, -1):
        path.append(at_update[u][b])
        b = f._node_parents[u][b]
    first = np.array(updated)  # the scan of each update
    np.testing.assert_allclose(poses[first], np.array(path[::-1]), atol=1e-12)
    # Between updates the poses move exactly as the odometry does.
    odom = np.array([fr.odom for fr in frames])
    inner = np.nonzero(~first)[0]
    d_est = relative(poses[inner - 1], poses[inner])
    d_odo = relative(odom[inner - 1], odom[inner])
    np.testing.assert_allclose(d_est[:, :2], d_odo[:, :2], atol=1e-9)
    np.testing.assert_allclose(wrap_angle(d_est[:, 2] - d_odo[:, 2]), 0, atol=1e-9)
    # It follows the truth on this short walk.
    e = trajectory_errors(t, poses, sim.t, sim.truth)
    assert e.ate_rmse_aligned < 0.1
    # The map is that particle's.
    np.testing.assert_array_equal(f.map.logodds, f.maps.dense(f.best_index))


def test_the_path_ends_at_the_best_particle_when_the_last_scan_resampled(walk):
    frames, _ = walk
    cfg = _cfg(**{"particles": 8, "rbpf.update_m": 0.2, "resample_threshold": 1.0})
    first = RaoBlackwellizedSlam(cfg)
    ups = [k for k, fr in enumerate(frames) if first.step(fr).updated]
    assert len(ups) > 8
    for last in ups[4:]:  # runs that end at an update: trajectory() resamples first
        f = RaoBlackwellizedSlam(cfg)
        for fr in frames[: last + 1]:
            f.step(fr)
        before = f.resamples
        _, poses = f.trajectory()
        assert f.resamples == before + 1
        np.testing.assert_allclose(poses[-1], f.particles.poses[f.best_index], atol=1e-12, err_msg=f"ending at {last}")


def test_same_seed_same_result_other_seed_other_particles(walk):
    frames, _ = walk
    frames = frames[:300]
    runs = []
    for seed in (1, 1, 2):
        f = RaoBlackwellizedSlam(_cfg(seed=seed, **{"particles": 5}))
        for fr in frames:
            f.step(fr)
        runs.append(f.poses.copy())
    np.testing.assert_array_equal(runs[0], runs[1])
    assert not np.array_equal(runs[0], runs[2])


def test_run_json_records_the_filter_and_its_maps(walk, tmp_path):
    frames, _ = walk
    run = close_loops(run_slam(frames[:400], _cfg(**{"particles": 6})))
    write_outputs(run, tmp_path, {"log": "x"})
    info = json.loads((tmp_path / "run.json").read_text())
    assert info["filter"]["filter"] == "rbpf" and info["filter"]["map_updates"] == run.filter_info["map_updates"] > 0
    assert info["filter"]["unique_tiles"] > 0 and info["peak_rss_mb"] > 50
    assert info["config"]["filter"] == "rbpf" and info["config"]["particles"] == 6
    assert (tmp_path / "map.pgm").exists()


@pytest.mark.slow
def test_a_long_loop_with_heading_drift_is_closed(tmp_path):
    """A 150 m walk around the office (seed 2, 330 s) with odometry drifting 0.8 deg per metre:
    the Rao-Blackwellized filter's ATE is at most a third of the single-map filter's."""
    sim = simulate("office", 330.0, seed=2, out_dir=tmp_path / "loop", heading_bias_deg_per_m=0.8)
    walked = np.hypot(*np.diff(sim.truth[:, :2], axis=0).T).sum()
    assert walked >= 150.0
    drift = np.rad2deg(abs(wrap_angle(sim.odom[-1, 2] - sim.truth[-1, 2])))
    assert drift >= 30.0  # the odometry's heading is far off at the end
    frames = load_log(sim.lidar_path, sim.joint_path).frames
    # the filters alone
    single = run_slam(frames, SlamConfig(filter="single", backend="none"))
    rbpf = run_slam(frames, _cfg(backend="none"))
    e_single = trajectory_errors(single.t, single.poses, sim.t, sim.truth)
    e_rbpf = trajectory_errors(rbpf.t, rbpf.poses, sim.t, sim.truth)
    assert e_rbpf.ate_rmse <= e_single.ate_rmse / 3, (e_rbpf.ate_rmse, e_single.ate_rmse)
    assert e_rbpf.ate_rmse < 0.05
    # with the loop-closing back end (the default) the loop stays closed (behind the single-map
    # filter: test_single's office loop). The back end runs after the filter, whose run does
    # not depend on it: run_slam with backend graph is this filter run, then this step.
    closed, _ = run_backend(frames, rbpf.poses, rbpf.config)
    assert closed.kept and closed.closure is not None and closed.closure.stats.loops_in_graph > 100
    assert trajectory_errors(rbpf.t, closed.closure.poses, sim.t, sim.truth).ate_rmse < 0.05
    # The search budget (at most 300 nodes searched: every second one on this walk) closes
    # loops on those nodes only (the stride itself: test_registration's search_stride test).
    assert 300 < closed.closure.stats.nodes <= 600 and {lp.node % 2 for lp in closed.closure.loops} == {0}


def test_auto_picks_the_filter_and_the_match_prior_per_log_kind():
    from pfslam.config import WHEELED_MATCH_PRIOR, resolve_filter

    auto = with_values(SlamConfig(), {"filter": "auto"})
    assert SlamConfig().filter == "auto" and SlamConfig().rbpf.match_prior == -1.0  # the defaults: per log kind
    thor = resolve_filter(auto, "thor-penn")
    assert thor.filter == "rbpf" and thor.rbpf.match_prior == 0.0
    for kind in ("carmen", "mines", "rosbag1"):
        wheeled = resolve_filter(auto, kind)
        assert wheeled.filter == "rbpf" and wheeled.rbpf.match_prior == WHEELED_MATCH_PRIOR > 0
    unknown = resolve_filter(auto, None)  # the library without a log kind: the same filter, no prior
    assert unknown.filter == "rbpf" and unknown.rbpf.match_prior == 0.0 and unknown.particles == 30
    searching = with_values(auto, {"local_search.enabled": True})  # the single-map filter's option
    assert resolve_filter(searching, "thor-ucsd").filter == "single"
    single = with_values(SlamConfig(), {"filter": "single"})
    assert resolve_filter(single, "thor-penn").filter == "single"  # a concrete choice is kept
    assert resolve_filter(single, "thor-penn").particles == 100  # particles 0: the filter's own count
    given = with_values(SlamConfig(), {"rbpf.match_prior": 0.5})
    assert (
        resolve_filter(given, "carmen").rbpf.match_prior == 0.5 == resolve_filter(given, "thor-penn").rbpf.match_prior
    )
    with pytest.raises(ConfigError, match="rbpf.match_prior"):
        with_values(SlamConfig(), {"rbpf.match_prior": -0.5})


def test_the_map_range_is_the_log_kinds_unless_given():
    """A wheeled robot's level laser maps out to WHEELED_MAP_RANGE, a THOR head's (and a log of
    unknown kind) to THOR_MAP_RANGE; a range given is kept; a config with it open is not
    concrete."""
    from pfslam.config import THOR_MAP_RANGE, WHEELED_MAP_RANGE, is_concrete, resolve_filter

    auto = SlamConfig()
    assert auto.rbpf.map_range == -1.0 and WHEELED_MAP_RANGE > THOR_MAP_RANGE
    assert resolve_filter(auto, "thor-penn").rbpf.map_range == THOR_MAP_RANGE
    assert resolve_filter(auto, None).rbpf.map_range == THOR_MAP_RANGE
    for kind in ("carmen", "mines", "rosbag2-sqlite3"):
        assert resolve_filter(auto, kind).rbpf.map_range == WHEELED_MAP_RANGE
    given = with_values(auto, {"rbpf.map_range": 25.0})
    assert resolve_filter(given, "carmen").rbpf.map_range == 25.0 == resolve_filter(given, "thor-penn").rbpf.map_range
    assert not is_concrete(with_values(auto, {"filter": "rbpf", "particles": 30, "rbpf.match_prior": 0.1}))
    with pytest.raises(ConfigError, match="rbpf.map_range"):
        with_values(auto, {"rbpf.map_range": 0.0})


def test_the_motion_prior_keeps_a_match_near_where_the_odometry_puts_it():
    """A corner seen 0.15 m off from where the particle stands: the plain match slides all the
    way to it; with a tight motion prior (1 cm) the slide costs more than it gains."""
    from pfslam.maps.tiled import TiledMaps

    maps = TiledMaps(1, resolution=0.05)
    wall = np.vstack(
        [
            np.column_stack([np.full(40, 2.0), np.linspace(-1.0, 1.0, 40)]),
            np.column_stack([np.linspace(0.5, 2.0, 30), np.full(30, 1.0)]),
        ]
    )
    for _ in range(5):  # a few passes, so the cells are surely occupied
        maps.update(0, np.zeros(2), wall, np.ones(len(wall), bool))
    hits = wall - np.array([0.15, 0.0])  # seen from 0.15 m further along x
    moved = []
    for prior_w in (0.0, 20.0):
        poses = np.zeros((1, 3))
        maps.match(poses, hits, 0.05, 1, 0.05, np.deg2rad(3.0), 4, prior_w, 0.01, np.deg2rad(0.5))
        moved.append(poses[0, 0])
    assert moved[0] == pytest.approx(0.15, abs=0.03)
    assert abs(moved[1]) < 0.03


def test_wheel_travel_moves_it_on_wheel_logs():
    """Logs with wheel travel and no odometry pose (the Mines rover): the particles follow the
    wheels' arcs. (It had read only odometry poses, stood still on such logs and mapped
    every scan at the start.)"""
    from pfslam.tools.wheeled import simulate_wheeled

    log = simulate_wheeled("office", duration_s=20.0, seed=1)
    assert all(f.odom is None and f.wheels is not None for f in log.frames)
    f = RaoBlackwellizedSlam(_cfg(**{"particles": 8, "motion.axle": log.axle}))
    for fr in log.frames:
        f.step(fr)
    t, poses = f.trajectory()
    travelled = float(np.hypot(*(log.truth[-1, :2] - log.truth[0, :2])))
    assert travelled > 5.0
    assert np.hypot(*(poses[-1, :2] - log.truth[-1, :2])) < 0.1 * travelled


def test_with_see_through_a_particle_whose_map_has_a_wall_the_scan_saw_through_loses():
    """Two particles at one pose, both maps with the wall the scan hits 4 m ahead; the second's
    map also holds a wall 2 m ahead, which the scan saw through. rbpf.see_through weighs it
    down; without, both gain alike."""
    ys = np.linspace(-1.0, 1.0, 41) + 0.0125
    far = np.column_stack([np.full(41, 4.0125), ys])
    near = np.column_stack([np.full(161, 2.0125), np.linspace(-1.0, 1.0, 161)])  # (no gap between its cells)
    gains = {}
    for on in (False, True):
        slam = RaoBlackwellizedSlam(_cfg(**{"particles": 2, "rbpf.see_through": on}))
        for _ in range(3):  # (three passes: walls the maps are sure of)
            for i in (0, 1):
                slam.maps.update(i, np.zeros(2), far, np.ones(41, bool))
        for _ in range(3):
            slam.maps.update(1, np.zeros(2), near, np.ones(161, bool))
        _, gains[on] = slam._update(far.copy(), (far, np.zeros(2)) if on else None)
        np.testing.assert_allclose(slam.poses[0], slam.poses[1])  # (the same match for both)
    assert gains[False][0] == pytest.approx(gains[False][1])
    assert gains[True][0] == pytest.approx(gains[False][0])
    # each of the 41 beams crosses the near wall (at |y| <= 0.5): a floor each (its temperature 20)
    assert gains[True][1] == pytest.approx(gains[True][0] - 41 * np.log(1 / 0.05) / 20, abs=2 * np.log(1 / 0.05) / 20)
