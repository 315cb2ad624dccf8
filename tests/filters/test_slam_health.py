"""SLAM health (issue 57): the state each update's fit to the best particle's own map gives
(the fit itself: tests/kernels/test_fit.py), the warning a run that broke on the way ends
with, and the blind stretches."""

import numpy as np
import pytest

from pfslam.config import SlamConfig, with_values
from pfslam.frames import Frame
from pfslam.io.logs import load_log
from pfslam.pipeline import run_slam


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
