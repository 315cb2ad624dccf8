"""Command-line runs: those that stop early keep their results; output and map problems are
caught before a run; messages are printed literally and on one line."""

import json
import subprocess
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from pfslam.cli import app
from pfslam.io.thor import write_thor
from pfslam.maps.grid import OccupancyGrid

runner = CliRunner()


def _thor(tmp_path, scans):
    lp = tmp_path / "train_lidar0.mat"
    n = len(scans)
    write_thor(lp, None, t=100 + np.arange(n) / 40, scans=np.asarray(scans, np.float32), pose=np.zeros((n, 3)))
    return lp


def _one_line_error(res, *words):
    text = res.stderr if hasattr(res, "stderr") else res.output
    assert res.exit_code == 2, (res.exit_code, res.output)
    lines = [
        ln
        for ln in text.strip().splitlines()
        if ln.strip() and not ln.startswith("warning:") and not ln.endswith("(--level-head)")
    ]
    assert len(lines) == 1 and "Traceback" not in res.output, text
    for w in words:
        assert w in lines[0], (w, lines[0])


def test_a_log_without_any_return_is_an_error(tmp_path):
    lp = _thor(tmp_path, np.zeros((5, 1081)))
    res = runner.invoke(app, ["slam", str(lp), "--level-head", "-o", str(tmp_path / "o")])
    _one_line_error(res, "train_lidar0.mat", "valid return")


def test_output_folder_is_checked_before_the_run(tmp_path):
    lp = _thor(tmp_path, np.ones((3, 1081)))
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    res = runner.invoke(app, ["slam", str(lp), "--level-head", "-o", str(blocker)])
    _one_line_error(res, "a_file", "not a folder")


def test_file_names_with_brackets_are_printed_as_they_are(tmp_path):
    name = tmp_path / "x[/]y[bold].mat"
    res = runner.invoke(app, ["slam", str(name), "-o", str(tmp_path / "o")])
    _one_line_error(res, "x[/]y[bold].mat", "not found")


@pytest.mark.parametrize(
    ("yaml_text", "words"),
    [
        ("image: m.pgm\nresolution: .inf\norigin: [0, 0, 0]\n", ["finite positive"]),
        ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0.5]\n", ["yaw"]),
        (
            "image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\noccupied_thresh: 0.1\nfree_thresh: 0.5\n",
            ["free_thresh < occupied_thresh"],
        ),
    ],
)
def test_bad_map_yaml(tmp_path, yaml_text, words):
    (tmp_path / "m.pgm").write_bytes(b"P5 2 2 255\n" + bytes([254, 254, 0, 205]))
    (tmp_path / "map.yaml").write_text(yaml_text)
    lp = _thor(tmp_path, np.ones((3, 1081)))
    res = runner.invoke(
        app, ["localize", str(lp), "--level-head", "--map", str(tmp_path / "map.yaml"), "-o", str(tmp_path / "o")]
    )
    _one_line_error(res, "map.yaml", *words)


def test_localize_with_unmatched_ground_truth_still_writes(tmp_path):
    from pfslam.io.trajectory import write_tum

    g = OccupancyGrid(origin=(-2.0, -2.0), shape=(80, 80))
    g.logodds[:] = -10
    g.logodds[40, :] = 10
    g.save_ros(tmp_path / "map", crop=False)
    lp = _thor(tmp_path, np.ones((3, 1081)))
    write_tum(tmp_path / "gt.tum", np.array([5.0, 6.0]), np.zeros((2, 3)))
    res = runner.invoke(
        app,
        [
            "localize",
            str(lp),
            "--level-head",
            "--map",
            str(tmp_path / "map.yaml"),
            "--initial-pose",
            "0,1,0",
            "-g",
            str(tmp_path / "gt.tum"),
            "-o",
            str(tmp_path / "o"),
        ],
    )
    assert res.exit_code == 0, res.output
    assert "not scored" in res.output and (tmp_path / "o" / "run.json").is_file()


def test_usage_errors_are_one_line():
    r = subprocess.run(
        [sys.executable, "-m", "pfslam.cli", "slam", "--no-such-option", "x"], capture_output=True, text=True
    )
    assert r.returncode == 2
    lines = [ln for ln in r.stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and "--no-such-option" in lines[0] and "slam --help" in lines[0], r.stderr


def test_ctrl_c_during_the_scoring_after_the_run_keeps_the_results(tmp_path, monkeypatch):
    import pfslam.eval.metrics

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(pfslam.eval.metrics, "map_agreement", interrupted)
    lp = _thor(tmp_path, np.full((8, 1081), 3.0))
    res = runner.invoke(app, ["slam", str(lp), "--level-head", "-o", str(tmp_path / "o")])
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
    res = runner.invoke(
        app,
        ["localize", str(lp), "--level-head", "--map", str(tmp_path / "map.yaml"), *args, "-o", str(tmp_path / "o")],
    )
    _one_line_error(res, "particles", "10000000")


def test_a_folder_given_as_a_file_is_named_as_such(tmp_path):
    (tmp_path / "est.tum").mkdir()
    res = runner.invoke(app, ["evaluate", str(tmp_path / "est.tum"), "-r", str(tmp_path / "est.tum")])
    _one_line_error(res, "est.tum", "folder")


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["-n", "1000", "--max-particles", "10"], ["--particles", "more than --max-particles"]),
        (["-n", "0"], ["--particles", "at least 1"]),
    ],
)
def test_localize_particle_options_are_consistent(tmp_path, args, words):
    lp = _thor(tmp_path, np.ones((3, 1081)))
    g = OccupancyGrid(origin=(-2.0, -2.0), shape=(80, 80))
    g.logodds[:] = -10
    g.save_ros(tmp_path / "map", crop=False)
    res = runner.invoke(
        app,
        ["localize", str(lp), "--level-head", "--map", str(tmp_path / "map.yaml"), *args, "-o", str(tmp_path / "o")],
    )
    _one_line_error(res, *words)


def test_evaluate_takes_the_reference_with_the_option_only(tmp_path):
    from pfslam.io.trajectory import write_tum

    for name in ("a.tum", "b.tum"):
        write_tum(tmp_path / name, np.arange(5.0), np.zeros((5, 3)))
    res = runner.invoke(app, ["evaluate", str(tmp_path / "a.tum"), str(tmp_path / "b.tum")])
    _one_line_error(res, "b.tum", "--reference")  # the reference is given one way: --reference REF
