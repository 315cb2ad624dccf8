"""Runs that stop early keep their results; output and map problems are caught before a run;
messages are printed literally and on one line."""

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from pfslam.cli import app
from pfslam.config import SlamConfig
from pfslam.frames import Frame
from pfslam.grid import MapTooLarge, OccupancyGrid
from pfslam.io.thor import write_thor
from pfslam.pipeline import run_localization, run_slam, stop_reason, write_json, write_slam_outputs

runner = CliRunner()


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
    run = run_slam(frames, SlamConfig(particles=20))
    assert run.scans == 40 and not run.interrupted
    assert "scan 41" in run.error and "map would grow" in run.error
    write_slam_outputs(run, tmp_path / "o", {"log": "x"})
    info = json.loads((tmp_path / "o" / "run.json").read_text())
    assert info["scans_processed"] == 40 and "scan 41" in info["error"]
    rows = [ln for ln in (tmp_path / "o" / "trajectory.tum").read_text().splitlines() if not ln.startswith("#")]
    assert len(rows) == 40


def test_map_growth_is_bounded():
    g = OccupancyGrid(shape=(100, 100))
    with pytest.raises(MapTooLarge, match="map would grow"):
        g.ensure_contains(0.0, 0.0, 1e6, 1.0)
    assert g.shape == (100, 100)


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
    from pfslam.localize import Localizer, LocalizerConfig

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
    run = run_localization(_frames(20), g, LocalizerConfig(particles=200, kld=False),
                           (np.zeros(3), np.array([0.05, 0.05, 0.02])))
    assert run.interrupted and run.error is None and run.scans == 5 and len(run.poses) == 5


def test_run_json_has_no_nan(tmp_path):
    write_json(tmp_path / "r.json", {"a": float("nan"), "b": [np.float32(1.5), np.inf], "c": np.arange(2)})
    assert json.loads((tmp_path / "r.json").read_text()) == {"a": None, "b": [1.5, None], "c": [0, 1]}


def _thor(tmp_path, scans):
    lp = tmp_path / "train_lidar0.mat"
    n = len(scans)
    write_thor(lp, None, t=100 + np.arange(n) / 40, scans=np.asarray(scans, np.float32), pose=np.zeros((n, 3)))
    return lp


def _one_line_error(res, *words):
    text = res.stderr if hasattr(res, "stderr") else res.output
    assert res.exit_code == 2, (res.exit_code, res.output)
    lines = [ln for ln in text.strip().splitlines() if ln.strip() and not ln.startswith("warning:")]
    assert len(lines) == 1 and "Traceback" not in res.output, text
    for w in words:
        assert w in lines[0], (w, lines[0])


def test_a_log_without_any_return_is_an_error(tmp_path):
    lp = _thor(tmp_path, np.zeros((5, 1081)))
    res = runner.invoke(app, ["slam", str(lp), "-o", str(tmp_path / "o")])
    _one_line_error(res, "train_lidar0.mat", "valid return")


def test_output_folder_is_checked_before_the_run(tmp_path):
    lp = _thor(tmp_path, np.ones((3, 1081)))
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    res = runner.invoke(app, ["slam", str(lp), "-o", str(blocker)])
    _one_line_error(res, "a_file", "not a folder")


def test_file_names_with_brackets_are_printed_as_they_are(tmp_path):
    name = tmp_path / "x[/]y[bold].mat"
    res = runner.invoke(app, ["slam", str(name), "-o", str(tmp_path / "o")])
    _one_line_error(res, "x[/]y[bold].mat", "not found")


@pytest.mark.parametrize(("yaml_text", "words"), [
    ("image: m.pgm\nresolution: .inf\norigin: [0, 0, 0]\n", ["finite positive"]),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0.5]\n", ["yaw"]),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\noccupied_thresh: 0.1\nfree_thresh: 0.5\n",
     ["free_thresh < occupied_thresh"]),
])
def test_bad_map_yaml(tmp_path, yaml_text, words):
    (tmp_path / "m.pgm").write_bytes(b"P5 2 2 255\n" + bytes([254, 254, 0, 205]))
    (tmp_path / "map.yaml").write_text(yaml_text)
    lp = _thor(tmp_path, np.ones((3, 1081)))
    res = runner.invoke(app, ["localize", str(lp), "--map", str(tmp_path / "map.yaml"), "-o", str(tmp_path / "o")])
    _one_line_error(res, "map.yaml", *words)


def test_localize_with_unmatched_ground_truth_still_writes(tmp_path):
    from pfslam.io.trajectory import write_tum

    g = OccupancyGrid(origin=(-2.0, -2.0), shape=(80, 80))
    g.logodds[:] = -10
    g.logodds[40, :] = 10
    g.save_ros(tmp_path / "map", crop=False)
    lp = _thor(tmp_path, np.ones((3, 1081)))
    write_tum(tmp_path / "gt.tum", np.array([5.0, 6.0]), np.zeros((2, 3)))
    res = runner.invoke(app, ["localize", str(lp), "--map", str(tmp_path / "map.yaml"), "--initial-pose", "0,1,0",
                              "-g", str(tmp_path / "gt.tum"), "-o", str(tmp_path / "o")])
    assert res.exit_code == 0, res.output
    assert "not scored" in res.output and (tmp_path / "o" / "run.json").is_file()


def test_usage_errors_are_one_line():
    r = subprocess.run([sys.executable, "-m", "pfslam.cli", "slam", "--no-such-option", "x"],
                       capture_output=True, text=True)
    assert r.returncode == 2
    lines = [ln for ln in r.stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and "--no-such-option" in lines[0] and "slam --help" in lines[0], r.stderr


def test_ctrl_c_during_the_scoring_after_the_run_keeps_the_results(tmp_path, monkeypatch):
    import pfslam.evaluate

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(pfslam.evaluate, "map_agreement", interrupted)
    lp = _thor(tmp_path, np.full((8, 1081), 3.0))
    res = runner.invoke(app, ["slam", str(lp), "-o", str(tmp_path / "o")])
    assert res.exit_code == 130, res.output
    info = json.loads((tmp_path / "o" / "run.json").read_text())
    assert info["interrupted"] is True and info["scans_processed"] == 8
    assert (tmp_path / "o" / "map.pgm").is_file()


@pytest.mark.parametrize("args", [["-n", "100000000000"], ["--max-particles", "100000000000"]])
def test_absurd_particle_counts_are_refused(tmp_path, args):
    lp = _thor(tmp_path, np.ones((3, 1081)))
    g = OccupancyGrid(origin=(-2.0, -2.0), shape=(80, 80))
    g.logodds[:] = -10
    g.save_ros(tmp_path / "map", crop=False)
    res = runner.invoke(app, ["localize", str(lp), "--map", str(tmp_path / "map.yaml"), *args, "-o", str(tmp_path / "o")])
    _one_line_error(res, "particles", "10000000")


def test_a_folder_given_as_a_file_is_named_as_such(tmp_path):
    (tmp_path / "est.tum").mkdir()
    res = runner.invoke(app, ["evaluate", str(tmp_path / "est.tum"), str(tmp_path / "est.tum")])
    _one_line_error(res, "est.tum", "folder")


@pytest.mark.parametrize(("args", "words"), [
    (["-n", "1000", "--max-particles", "10"], ["--particles", "more than --max-particles"]),
    (["-n", "0"], ["--particles", "at least 1"]),
])
def test_localize_particle_options_are_consistent(tmp_path, args, words):
    lp = _thor(tmp_path, np.ones((3, 1081)))
    g = OccupancyGrid(origin=(-2.0, -2.0), shape=(80, 80))
    g.logodds[:] = -10
    g.save_ros(tmp_path / "map", crop=False)
    res = runner.invoke(app, ["localize", str(lp), "--map", str(tmp_path / "map.yaml"), *args, "-o", str(tmp_path / "o")])
    _one_line_error(res, *words)


def test_evaluate_refuses_two_references(tmp_path):
    from pfslam.io.trajectory import write_tum

    for name in ("a.tum", "b.tum"):
        write_tum(tmp_path / name, np.arange(5.0), np.zeros((5, 3)))
    res = runner.invoke(app, ["evaluate", str(tmp_path / "a.tum"), str(tmp_path / "a.tum"), "-r", str(tmp_path / "b.tum")])
    _one_line_error(res, "b.tum", "once")
