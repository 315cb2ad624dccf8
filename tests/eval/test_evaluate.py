"""Trajectory errors (ATE raw and SE(2)-aligned, RPE), association, the relations metric,
and their argument checks."""

import numpy as np
import pytest
from datafiles import need

from pfslam.errors import ConfigError
from pfslam.eval.metrics import align_se2, associate, relation_errors, trajectory_errors
from pfslam.geometry import compose

NAN, INF = float("nan"), float("inf")


def _traj(n=200, seed=0):
    rng = np.random.default_rng(seed)
    th = np.cumsum(rng.normal(0, 0.05, n))
    xy = np.cumsum(np.column_stack([np.cos(th), np.sin(th)]) * 0.1, axis=0)
    return np.arange(n) * 0.1, np.column_stack([xy, th])


def test_identical_is_zero():
    t, p = _traj()
    e = trajectory_errors(t, p, t, p)
    assert e.ate_rmse == 0 and e.ate_rmse_aligned < 1e-12 and e.rpe_trans_rmse < 1e-12


def test_alignment_removes_rigid_transform():
    t, p = _traj()
    g = np.array([3.0, -2.0, 0.7])
    moved = compose(g, p)
    e = trajectory_errors(t, moved, t, p)
    assert e.ate_rmse > 1.0
    assert e.ate_rmse_aligned < 1e-9
    assert e.rpe_trans_rmse < 1e-9  # RPE is invariant to a rigid transform
    assert np.allclose(compose(align_se2(moved, p), moved), p, atol=1e-9)


def test_constant_offset_ate():
    t, p = _traj()
    q = p.copy()
    q[:, 0] += 0.3
    e = trajectory_errors(t, q, t, p)
    assert e.ate_rmse == pytest.approx(0.3)


def test_associate_nearest_within_tolerance():
    i, j = associate(np.array([0.0, 1.0, 2.05, 5.0]), np.array([2.0, 0.01, 1.0]), max_dt=0.06)
    assert list(i) == [0, 1, 2] and list(j) == [1, 2, 0]


def test_relations_metric_zero_for_truth_and_exact_for_a_known_error(tmp_path):
    from pfslam.eval.metrics import read_relations, relation_errors
    from pfslam.geometry import compose, relative

    rng = np.random.default_rng(3)
    t = np.arange(50) * 0.5
    truth = np.zeros((50, 3))
    for i in range(1, 50):
        truth[i] = compose(truth[i - 1], [0.3, 0.0, rng.normal(0, 0.2)])
    pairs = [(i, i + 1) for i in range(0, 48, 2)] + [(3, 40)]
    lines = []
    offset = 1000.0
    for i, j in pairs:
        d = relative(truth[i], truth[j])
        lines.append(f"{t[i] + offset} {t[j] + offset} {d[0]} {d[1]} 0 0 0 {d[2]}")
    lines.append(f"{999.0 + offset} {t[1] + offset} 0 0 0 0 0 0")  # no pose at its first time: skipped
    p = tmp_path / "r.relations"
    p.write_text("\n".join(lines) + "\n")
    rel = read_relations(p)
    e = relation_errors(t, truth, rel, time_offset=offset)
    assert e.matched == len(pairs) and e.skipped == 1 and e.unmatched == 1 and e.same_pose == 0
    assert e.trans_mean < 1e-9 and e.rot_mean_deg < 1e-9
    # Rotate the whole estimate and shift it: relative motions are unchanged.
    moved = compose(np.array([5.0, -2.0, 1.0]), truth)
    assert relation_errors(t, moved, rel, time_offset=offset).trans_mean < 1e-9
    # A 0.1 m jump of every odd pose shows up on relations (2k, 2k+1) only.
    bumped = truth.copy()
    bumped[1::2, 0] += 0.1
    e = relation_errors(t, bumped, rel, time_offset=offset)
    assert e.trans_mean > 0.05 and e.rot_mean_deg < 1e-9
    # Without the time offset nothing matches.
    assert relation_errors(t, truth, rel).matched == 0


def _line(n=50):
    t = np.arange(n, dtype=float)
    return t, np.column_stack([t * 0.1, np.zeros(n), np.zeros(n)])


@pytest.mark.parametrize("delta", [0, -1, 2.5, True])
def test_rpe_delta_must_be_a_positive_integer(delta):
    t, p = _line()
    with pytest.raises(ConfigError, match="rpe_delta must be an integer >= 1"):
        trajectory_errors(t, p, t, p, rpe_delta=delta)
    assert trajectory_errors(t, p, t, p, rpe_delta=1).rpe_delta == 1


@pytest.mark.parametrize("max_dt", [0.0, -0.1, INF, NAN])
def test_max_dt_must_be_finite_and_positive(max_dt):
    t, p = _line()
    with pytest.raises(ConfigError, match="max_dt must be a finite number of seconds > 0"):
        trajectory_errors(t, p, t, p, max_dt=max_dt)
    with pytest.raises(ConfigError, match="max_dt"):
        associate(t, t, max_dt)
    with pytest.raises(ConfigError, match="max_dt"):
        relation_errors(t, p, np.array([[1.0, 2.0, 0.1, 0.0, 0.0]]), max_dt=max_dt)


def test_relation_time_offset_must_be_finite():
    t, p = _line()
    with pytest.raises(ConfigError, match="time_offset"):
        relation_errors(t, p, np.array([[1.0, 2.0, 0.1, 0.0, 0.0]]), time_offset=INF)


def test_a_relation_with_both_ends_on_the_same_pose_is_skipped_and_counted():
    """Two raw scans a few milliseconds apart that the estimate holds as one pose would score
    a false zero motion: such relations are skipped, counted apart from the unmatched ones."""
    t, p = _line()
    rel = np.array(
        [
            [3.0, 7.0, 0.4, 0.0, 0.0],  # 4 poses apart: matched, exact
            [5.0, 5.004, 0.01, 0.0, 0.0],  # both ends on pose 5: a false zero motion, skipped
            [20.0, 20.01, 0.02, 0.0, 0.0],  # the same
            [30.0, 99.5, 1.0, 0.0, 0.0],  # no pose at 99.5: unmatched
        ]
    )
    e = relation_errors(t, p, rel)
    assert (e.matched, e.skipped, e.unmatched, e.same_pose) == (1, 3, 1, 2)
    assert e.trans_mean < 1e-12
    e = relation_errors(t, p, rel[1:3])
    assert (e.matched, e.same_pose) == (0, 2) and np.isnan(e.trans_mean)


@pytest.mark.realdata
def test_intel_relations_counted_on_two_different_scans_only():
    """Intel: 75 of its 2,984 relations join raw scans milliseconds apart; in the 910-scan log
    both ends of some of them fall on the same scan. With the log's own poses, within 0.02 s:
    114 relations on two scans at the offset 976052857.33 s, 120 at 976052857.338 s."""
    from pfslam.eval.metrics import read_relations
    from pfslam.io.logs import load_log

    log = load_log(need("carmen/intel.gfs.log.gz"), odometry="synthetic")
    t = np.array([f.t for f in log.frames])
    rel = read_relations(need("carmen/intel.relations"))
    at_33 = relation_errors(t, log.reference, rel, time_offset=976052857.33, max_dt=0.02)
    at_338 = relation_errors(t, log.reference, rel, time_offset=976052857.338, max_dt=0.02)
    assert (at_33.matched, at_33.same_pose) == (114, 42)
    assert (at_338.matched, at_338.same_pose) == (120, 35)
    assert at_338.matched + at_338.skipped == len(rel) == 2984
    assert at_338.trans_mean == pytest.approx(0.0583, abs=5e-4)
    assert at_338.rot_mean_deg == pytest.approx(1.162, abs=5e-3)


def _agreement_by_distance_transform(frames, poses, splits=(0.25, 0.5, 0.75), tol=0.1, resolution=0.05, max_scans=2000):
    """Map agreement as first written: a full distance transform of each split's map."""
    from dataclasses import replace

    from pfslam.config import MapConfig
    from pfslam.geometry import transform_points
    from pfslam.maps.fields import wall_distance
    from pfslam.maps.grid import grid_from_config, integrate_scan
    from pfslam.sensor import scan_to_points

    n = min(len(frames), len(poses))
    step = max(1, -(-n // max_scans))
    frames = list(frames[:n:step])
    poses = np.asarray(poses, dtype=float)[:n:step]
    n = len(frames)
    mc = MapConfig()
    g = grid_from_config(replace(mc, resolution=resolution), centred=False)
    scans = [scan_to_points(f) for f in frames]
    hits = [transform_points(p, sp.hits) for sp, p in zip(scans, poses)]
    scores, done = [], 0
    for k in sorted(int(n * s) for s in splits):
        if k < 1 or k >= n:
            continue
        for i in range(done, k):
            integrate_scan(g, poses[i], scans[i])
        done = k
        occ = g.logodds > mc.l_occ / 3
        if not occ.any():
            continue
        seen = g.logodds != 0
        dist = wall_distance(occ, g.resolution)
        h, w = occ.shape
        fractions = []
        for pts in hits[k:]:
            rows, cols = g.world_to_cell(pts)
            inside = (rows >= 0) & (cols >= 0) & (rows < h) & (cols < w)
            rows, cols = rows[inside], cols[inside]
            known = seen[rows, cols]
            if known.any():
                fractions.append(float(np.mean(dist[rows[known], cols[known]] < tol)))
        if fractions:
            scores.append(float(np.mean(fractions)))
    return float(np.mean(scores)) if scores else float("nan")


@pytest.mark.parametrize("tol", [0.1, 0.17, 0.3])
def test_map_agreement_checks_neighbours_exactly_as_a_distance_transform(short_office, tol):
    """The one-pass map agreement (the cells within tol of each hit, no distance transform)
    gives the figure of the full distance transform to the last digit, on true, noisy and
    drifting poses, with and without thinning."""
    from pfslam.eval.metrics import map_agreement
    from pfslam.io.logs import load_log
    from pfslam.io.trajectory import read_tum

    log = load_log(short_office.lidar_path, short_office.joint_path)
    _, truth = read_tum(short_office.groundtruth_path)
    rng = np.random.default_rng(1)
    noisy = truth + rng.normal(0, [0.03, 0.03, 0.01], truth.shape)
    drift = truth.copy()
    drift[:, 2] += np.linspace(0, 0.2, len(truth))
    for poses in (truth, noisy, drift):
        for max_scans in (2000, 90):
            want = _agreement_by_distance_transform(log.frames, poses, tol=tol, max_scans=max_scans)
            got = map_agreement(log.frames, poses, tol=tol, max_scans=max_scans)
            assert got == pytest.approx(want, abs=1e-12), (got, want)
            assert 0.0 < got <= 1.0


def test_map_agreement_of_a_runaway_trajectory_is_nan_and_the_other_is_still_scored(short_office):
    """Odometry that drifts kilometres cannot be mapped (past the largest map): its map
    agreement is NaN, not an error that would lose the run's results."""
    from pfslam.config import SlamConfig, with_values
    from pfslam.io.logs import load_log
    from pfslam.pipeline import Scores, close_loops, run_slam
    from pfslam.pipeline.score import score_map_agreement

    frames = load_log(short_office.lidar_path, short_office.joint_path).frames[:120]
    run = close_loops(run_slam(frames, with_values(SlamConfig(), {"filter": "single", "particles": 10})))
    run.odometry = run.odometry.copy()
    run.odometry[:, 0] += np.linspace(0.0, 30_000.0, len(run.odometry))
    scores = Scores()
    score_map_agreement(run, frames, scores)
    assert np.isnan(scores.map_agreement["odometry"])
    assert 0.5 < scores.map_agreement["SLAM"] <= 1.0
