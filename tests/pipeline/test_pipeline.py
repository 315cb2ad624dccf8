"""pfslam.pipeline without the command line: runs that stop early keep what they computed,
one writer for both filters, run.json without NaN, the shared run loop."""

import dataclasses
import json

import numpy as np
import pytest

from pfslam.config import LocalizerConfig, SlamConfig
from pfslam.filters.localize import Localizer
from pfslam.frames import Frame
from pfslam.maps.grid import OccupancyGrid
from pfslam.pipeline import close_loops, leave_session, run_localization, run_slam, write_outputs
from pfslam.pipeline.outputs import write_json
from pfslam.pipeline.run import stop_reason


def _frames(n=60):
    """A robot walking along +x between two walls 1 m to either side (a simple corridor)."""
    angles = np.linspace(-np.pi / 2, np.pi / 2, 181)
    out = []
    for i in range(n):
        x = 0.02 * i
        r = np.where(np.abs(np.sin(angles)) > 1e-3, 1.0 / np.maximum(np.abs(np.sin(angles)), 1e-3), 30.0)
        out.append(Frame(t=100.0 + i / 40, ranges=np.minimum(r, 29.0), angles=angles, odom=np.array([x, 0.0, 0.0])))
    return out


def test_an_error_mid_run_keeps_the_scans_before_it(tmp_path):
    frames = _frames()
    frames[40:] = [dataclasses.replace(f, odom=f.odom + [1e7, 0.0, 0.0]) for f in frames[40:]]
    run = leave_session(close_loops(run_slam(frames, SlamConfig(filter="single", particles=20))))
    assert run.scans == 40 and not run.interrupted
    assert "scan 41" in run.error and "map would grow" in run.error
    write_outputs(run, tmp_path / "o", {"log": "x"})
    info = json.loads((tmp_path / "o" / "run.json").read_text())
    assert info["scans_processed"] == 40 and "scan 41" in info["error"]
    rows = [ln for ln in (tmp_path / "o" / "trajectory.tum").read_text().splitlines() if not ln.startswith("#")]
    assert len(rows) == 40


def test_ctrl_c_inside_a_kernel_counts_as_an_interruption():
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as k:
            raise SystemError("<numba> returned a result with an exception set") from k
    except SystemError as e:
        assert stop_reason(e, 3, None) == (True, None)
    interrupted, msg = stop_reason(ValueError("boom\nsecond line"), 3, None)
    assert not interrupted and msg == "stopped at scan 4: boom"


def test_interrupted_localization_keeps_its_results(tmp_path, monkeypatch):
    g = OccupancyGrid(origin=(-2.0, -2.0), shape=(80, 80))
    g.logodds[:] = -10
    g.logodds[[19, 60], :] = 10  # walls at y = -1.05 and y = 1.0
    calls = {"n": 0}
    step = Localizer.step

    def stepping(self, frame):
        calls["n"] += 1
        if calls["n"] == 6:
            raise KeyboardInterrupt
        return step(self, frame)

    monkeypatch.setattr(Localizer, "step", stepping)
    run = run_localization(
        _frames(20), g, LocalizerConfig(particles=200, kld=False), (np.zeros(3), np.array([0.05, 0.05, 0.02]))
    )
    assert run.interrupted and run.error is None and run.scans == 5 and len(run.poses) == 5


def test_run_json_has_no_nan(tmp_path):
    write_json(tmp_path / "r.json", {"a": float("nan"), "b": [np.float32(1.5), np.inf], "c": np.arange(2)})
    assert json.loads((tmp_path / "r.json").read_text()) == {"a": None, "b": [1.5, None], "c": [0, 1]}


def _corridor_map():
    g = OccupancyGrid(origin=(-2.0, -2.0), shape=(80, 120))
    g.logodds[:] = -10
    g.logodds[[19, 60], :] = 10  # walls at y = -1.05 and y = 1.0
    return g


def test_one_writer_for_both_kinds_of_run(tmp_path):
    import yaml

    from pfslam.config import CalibrationConfig, load_config

    frames = _frames(30)
    loc = run_localization(
        frames,
        _corridor_map(),
        LocalizerConfig(particles=200, kld=False, seed=2),
        (np.zeros(3), np.array([0.05, 0.05, 0.02])),
    )
    slam = leave_session(close_loops(run_slam(frames, SlamConfig(filter="single", particles=10, seed=2))))
    assert (loc.kind, slam.kind) == ("localization", "slam") and loc.scans == slam.scans == 30
    cal = CalibrationConfig(gap=2)
    a = write_outputs(loc, tmp_path / "loc", {"log": "x"}, calibration=cal)
    b = write_outputs(slam, tmp_path / "slam", {"log": "x"}, truth=(slam.t, slam.poses))
    for out, run in ((a, loc), (b, slam)):
        for name in ("trajectory.tum", "odometry.tum", "config.yaml", "run.json"):
            assert (out / name).is_file(), (out, name)
        info = json.loads((out / "run.json").read_text())
        assert info["run"] == run.kind and info["scans_processed"] == 30
        rows = [ln for ln in (out / "odometry.tum").read_text().splitlines() if not ln.startswith("#")]
        assert len(rows) == 30
    assert (a / "localization.png").is_file() and not (a / "map.pgm").exists()
    assert (b / "map.pgm").is_file() and (b / "map.png").is_file() and not (b / "localization.png").exists()
    # config.yaml: the filter's section, plus calibrate: when the odometry was calibrated.
    assert list(yaml.safe_load((a / "config.yaml").read_text())) == ["localize", "calibrate"]
    assert load_config(a / "config.yaml", LocalizerConfig) == loc.config
    assert load_config(a / "config.yaml", CalibrationConfig) == cal
    assert list(yaml.safe_load((b / "config.yaml").read_text())) == ["slam"]
    assert load_config(b / "config.yaml", SlamConfig) == slam.config
    info = json.loads((a / "run.json").read_text())
    assert info["calibration_config"]["gap"] == 2 and info["particles_first_last"] == [200, 200]


def test_run_filter_stops_at_an_error_and_keeps_the_steps_before_it():
    from pfslam.filters.base import EstimateLog, Filter
    from pfslam.frames import Estimate
    from pfslam.pipeline import run_filter

    class Counting:
        """A minimal filter: dead reckoning, failing at its fourth scan."""

        def __init__(self):
            self._log, self.map, self.odom_pose = EstimateLog(), _corridor_map(), np.zeros(3)
            self.particles = None

        def step(self, frame):
            if len(self._log) == 3:
                raise ValueError("no more\nsecond line")
            self.odom_pose = np.asarray(frame.odom, float)
            self._log.add(frame.t, self.odom_pose)
            return Estimate(t=frame.t, pose=self.odom_pose.copy(), n_eff=1.0, particles=1)

        def trajectory(self):
            return self._log.arrays()

        def diagnostics(self):
            return {}

    f = Counting()
    assert isinstance(f, Filter)
    frames = _frames(10)
    steps, clouds, _, interrupted, error = run_filter(f, frames)
    assert not interrupted and error == f"stopped at scan 4 (t={frames[3].t:.3f}): no more"
    assert steps.done == 3 and clouds == []
    np.testing.assert_array_equal(steps.odometry[:3], [fr.odom for fr in frames[:3]])
    assert list(steps.particles[:3]) == [1, 1, 1] and steps.updates == 3


def test_run_rates():
    slam = leave_session(close_loops(run_slam(_frames(9), SlamConfig(filter="single", particles=5))))
    run = dataclasses.replace(slam, seconds=0.5)  # the rates from a known duration, not a measured one
    assert run.scans == 9 and len(run.poses) == 9
    assert run.scans_per_second == pytest.approx(18.0)
    assert run.real_time_factor == pytest.approx(0.2 / 0.5)  # 8 steps of 1/40 s in 0.5 s
    idle = dataclasses.replace(slam, seconds=0.0)
    assert idle.scans_per_second == float("inf") and idle.real_time_factor == float("inf")
