"""What a localization run writes besides its trajectory: covariance.csv (the estimate's
uncertainty at each update, with its summary in run.json) and a localization.png whose
particle clouds lie over the track, whose legend covers none of the map, and whose
estimate is not drawn through walls where it jumps."""

import json

import numpy as np
import pytest
from locworld import drive, frames_along, room

from pfslam.config import LocalizerConfig
from pfslam.io.trajectory import read_tum
from pfslam.pipeline import run_localization, write_outputs
from pfslam.views.figures import CLOUD_ZORDER, break_jumps, jumps, map_figure


def global_run_truth():
    return drive([(1.0, 1.0), (8.5, 1.0), (8.5, 6.8)])


@pytest.fixture(scope="module")
def global_run(tmp_path_factory):
    g = room()
    truth = global_run_truth()
    # a global start spread over the room, whose cloud converges (a B&B start is settled at once)
    run = run_localization(frames_along(g, truth), g, LocalizerConfig(seed=0, global_start="uniform"), None)
    out = write_outputs(run, tmp_path_factory.mktemp("loc"), {"log": "room"}, truth=(run.t, truth))
    return run, out


def _read_covariances(path):
    lines = path.read_text().splitlines()
    assert lines[0] == "t,x,y,theta,xx,xy,xtheta,yy,ytheta,thetatheta"
    d = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])
    xx, xy, xt, yy, yt, tt = d[:, 4:].T
    cov = np.stack([np.stack([xx, xy, xt], -1), np.stack([xy, yy, yt], -1), np.stack([xt, yt, tt], -1)], 1)
    return d[:, 0], d[:, 1:4], cov


def test_covariance_csv_has_a_row_per_update_and_shrinks_as_a_global_start_converges(global_run):
    run, out = global_run
    t, poses, cov = _read_covariances(out / "covariance.csv")
    info = json.loads((out / "run.json").read_text())
    assert len(t) == run.updates == info["updates"] > 50
    assert np.all(np.isfinite(poses)) and np.all(np.isfinite(cov))
    assert np.all(np.linalg.eigvalsh(cov) >= -1e-12)  # positive semi-definite
    # The rows are the trajectory's poses at the updated steps.
    t_all, p_all = read_tum(out / "trajectory.tum")
    idx = np.searchsorted(t_all, t)
    np.testing.assert_allclose(t_all[idx], t, atol=1e-6)
    np.testing.assert_allclose(p_all[idx, :2], poses[:, :2], atol=1e-6)
    np.testing.assert_array_equal(idx, np.nonzero(run.updated)[0])
    std = np.sqrt(cov[:, 0, 0] + cov[:, 1, 1])
    assert std[0] > 2.0 * np.median(std[-20:]) and np.median(std[-20:]) < 0.1
    # run.json's summary is of the same numbers.
    u = info["metrics"]["uncertainty"]
    assert u["updates"] == len(t)
    assert u["position_std_m_max"] == pytest.approx(std.max(), rel=1e-6)
    assert u["position_std_m_median"] == pytest.approx(np.median(std), rel=1e-6)
    assert u["position_std_m_last"] == pytest.approx(std[-1], rel=1e-6)
    assert u["heading_std_deg_max"] == pytest.approx(np.rad2deg(np.sqrt(cov[:, 2, 2].max())), rel=1e-6)


def test_jumps_break_the_polyline_unless_the_odometry_moved_as_much():
    xy = np.array([[0.0, 0.0], [0.1, 0.0], [0.2, 0.0], [5.2, 3.0], [5.3, 3.0], [5.4, 3.0]])
    assert jumps(xy, 1.0).tolist() == [False, False, True, False, False]
    line = break_jumps(xy, 1.0)
    assert line.shape == (7, 2) and np.isnan(line[3]).all()
    np.testing.assert_array_equal(line[[0, 1, 2, 4, 5, 6]], xy)
    # The same step where the odometry moved 5 m too (a fast robot, a slow log): no break.
    motion = np.array([0.1, 0.1, 5.5, 0.1, 0.1])
    assert not jumps(xy, 1.0, motion).any()
    np.testing.assert_array_equal(break_jumps(xy, 1.0, motion), xy)
    assert break_jumps(xy[:1], 1.0).shape == (1, 2) and jumps(xy[:1], 1.0).shape == (0,)


def test_localization_figure_draws_clouds_over_the_track_a_gap_at_a_jump_and_the_legend_below():
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PathCollection

    g = room()
    truth = drive([(1.0, 1.0), (8.5, 1.0), (8.5, 6.8)])
    est = truth.copy()
    est[:40] += [3.0, 4.0, 0.0]  # lost for a while, then recovered: a 5 m jump at step 40
    odom = truth + [0.0, 0.05, 0.0]
    t = np.arange(len(truth)) * 0.1
    rng = np.random.default_rng(0)
    clouds = [(f"particles at {s} s", truth[k] + rng.normal(size=(500, 3)) * 0.2) for s, k in ((0, 0), (9, 90))]
    fig, ax = map_figure(
        g,
        [("ground truth", truth, "tab:green"), ("odometry", odom, "tab:orange"), ("estimate", est, "tab:blue")],
        times=t,
        timed="estimate",
        clouds=clouds,
        jump=1.0,
    )
    try:
        scatters = [c for c in ax.collections if isinstance(c, PathCollection)]
        tracks = [c for c in ax.collections if isinstance(c, LineCollection)] + [
            ln for ln in ax.lines if len(ln.get_xdata()) > 1
        ]
        assert len(scatters) == 2 and len(tracks) == 3
        assert min(s.get_zorder() for s in scatters) == CLOUD_ZORDER > max(tr.get_zorder() for tr in tracks)
        # The estimate has no segment across the jump; every other step is drawn.
        (lc,) = [c for c in ax.collections if isinstance(c, LineCollection)]
        seg = np.array(lc.get_segments())
        assert len(seg) == len(est) - 2 and np.hypot(*(seg[:, 1] - seg[:, 0]).T).max() < 1.0
        # The legend lies below the axes and their labels, over none of the map.
        fig.canvas.draw()
        r = fig.canvas.get_renderer()
        legend = ax.get_legend().get_window_extent(r)
        assert legend.y1 < ax.get_window_extent(r).y0 and legend.y1 <= ax.xaxis.get_tightbbox(r).y0  # x label too
        labels = [tx.get_text() for tx in ax.get_legend().get_texts()]
        assert labels[:3] == ["ground truth", "odometry", "estimate (by time)"]
        assert {"particles at 0 s", "particles at 9 s", "start", "end"} <= set(labels)
    finally:
        plt.close(fig)


def test_run_json_names_the_settle_time_and_the_picture_marks_where_the_spread_rose(global_run):
    """Issue 37: a global start's run.json says when it settled and which scale it learnt;
    the spread's rises are counted and drawn under the estimate, labelled in the legend."""
    from pfslam.views.figures import spread_marker

    run, out = global_run
    info = json.loads((out / "run.json").read_text())["filter"]
    # The scan it names is the update from which the cloud's spread (covariance.csv) stays
    # under SETTLED_SPREAD, any before it above (log time stamps, not a clock).
    from pfslam.filters.base import SETTLED_SPREAD

    t, _, cov = _read_covariances(out / "covariance.csv")
    spread = np.sqrt(cov[:, 0, 0] + cov[:, 1, 1])
    k = int(np.argmin(np.abs(t - run.t[0] - info["settle"]["at_s"])))
    assert np.all(spread[k:] < SETTLED_SPREAD) and (k == 0 or spread[k - 1] >= SETTLED_SPREAD)
    assert "translation" in info["odometry_scale"] and "translation_std" in info["odometry_scale"]
    assert info["spread_rose"]["threshold_m"] > 0 and info["spread_rose"]["stretches"] >= 1  # the search itself
    rose = np.zeros(len(run.poses), bool)
    rose[:5] = True
    fig, ax = map_figure(
        run.grid, [("estimate", run.poses, "tab:blue")], extra=spread_marker(run.poses[:, :2], rose, 0.1)
    )
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "particles' spread above 0.10 m" in labels


def test_within_after_counts_from_the_first_motion_to_the_last_time_off_the_robot():
    """metrics.estimate.within_after_s: seconds after the odometry's first motion from which
    the estimate stays within 0.3 m of the truth; 0 if it always was, None if it ends off."""
    from types import SimpleNamespace

    from pfslam.pipeline.score import within_after

    t = np.arange(0.0, 20.0, 0.5)
    truth = np.column_stack([np.clip(t - 2.0, 0.0, None) * 0.5, np.zeros_like(t), np.zeros_like(t)])
    odometry = truth * [1.05, 1.0, 1.0]  # moves from t = 2.5 on (the first pose more than 2 cm away)
    est = truth.copy()
    est[t < 7.0, 0] += 5.0  # a look-alike place until 7 s, then with the robot
    est[t == 12.0, 1] += 0.31  # one step off again at 12 s
    run = SimpleNamespace(t=t, poses=est, odometry=odometry)
    assert within_after(run, (t, truth)) == pytest.approx(12.5 - 2.5)
    est[t == 12.0, 1] -= 0.31
    assert within_after(run, (t, truth)) == pytest.approx(7.0 - 2.5)
    run.poses = truth + [0.2, 0.0, 0.0]
    assert within_after(run, (t, truth)) == 0.0
    est[-1, 1] += 1.0
    run.poses = est
    assert within_after(run, (t, truth)) is None


def test_the_summary_line_says_whether_a_scored_localization_ended_on_the_robot(tmp_path):
    """The run's last line: from when it stayed within 0.3 m of the ground truth, loudly when
    it ended further off, nothing without a truth."""
    from types import SimpleNamespace

    from pfslam.pipeline.report import Outcome

    def line(metrics):
        run = SimpleNamespace(
            kind="localization",
            scans=10,
            seconds=1.0,
            scans_per_second=10.0,
            updates=5,
            particles=[500, 500],
            metrics=metrics,
        )
        return Outcome(run, None, tmp_path).summary()  # type: ignore[arg-type]

    assert "from 4.5 s after the first motion" in line({"estimate": {"within_after_s": 4.5, "within_m": 0.3}})
    assert "ENDED MORE THAN 0.3 m OFF" in line({"estimate": {"within_after_s": None, "within_m": 0.3}})
    assert "ground truth" not in line({})
    health = {
        "seconds_in_state": {"tracking": 30.0, "degraded": 5.0, "lost": 5.0, "ambiguous": 0.0},
        "lowest_quality": 0.05,
    }
    assert "; health: tracking 75 % of the time, lost 5.0 s, lowest quality 0.05" in line({"health": health})
    health["seconds_in_state"].update(lost=0.0, degraded=0.0)
    assert "; health: tracking 100 % of the time, lowest quality 0.05" in line({"health": health})
    assert "health" not in line({})


def test_health_csv_and_run_json_say_how_well_each_scan_fit(global_run):
    """health.csv has a row per scan, never "tracking" where the estimate is off; run.json's
    metrics.health sums the same states."""
    run, out = global_run
    lines = (out / "health.csv").read_text().splitlines()
    assert lines[0] == "t,updated,quality,state,explained,contradicted"
    rows = [ln.split(",") for ln in lines[1:]]
    assert len(rows) == run.scans
    states = [r[3] for r in rows]
    assert set(states) <= {"tracking", "degraded", "lost", "ambiguous"}
    err = np.hypot(*(run.poses[:, :2] - global_run_truth()[:, :2]).T)
    assert states[-1] == "tracking" and not any(s == "tracking" and e > 0.3 for s, e in zip(states, err))
    q = np.array([float(r[2]) for r in rows])
    assert q[-1] > 0.9 and np.all((q >= 0) & (q <= 1))
    health = json.loads((out / "run.json").read_text())["metrics"]["health"]
    assert health["final_state"] == "tracking" and health["first_lost_s"] is None
    t = np.array([float(r[0]) for r in rows])
    assert sum(health["seconds_in_state"].values()) == pytest.approx(t[-1] - t[0])
    assert sum(health["updates_in_state"].values()) == run.updates
    assert health["lowest_quality"] == pytest.approx(min(float(r[2]) for r in rows if r[1] == "1"), abs=1e-4)
    assert not run.notes  # it ends tracking: nothing to warn of


def test_a_run_that_ends_lost_says_so():
    """Started 3 m off and turned with the recovery off, the filter never finds the robot: its
    health ends lost, and the run carries the one line the command prints."""
    g = room()
    truth = drive([(1.0, 1.0), (8.5, 1.0)])
    wrong = truth[0] + np.array([5.0, 4.0, 2.0])
    run = run_localization(
        frames_along(g, truth), g, LocalizerConfig(seed=0, recovery=False), (wrong, np.full(3, 0.02))
    )
    health = run.metrics["health"]
    assert health["final_state"] == "lost" and health["first_lost_s"] < 0.5
    assert [n for n in run.notes if n.startswith("the localization ends lost")]
