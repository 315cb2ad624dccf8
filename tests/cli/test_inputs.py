"""Bad input to the commands: one line naming the file and the problem, exit code 2, no
traceback; and the small runs that must write their outputs."""

import numpy as np
import pytest
import scipy.io as sio
import yaml
from clirun import invoke as _run
from clirun import one_line_error as _assert_clean_error
from typer.testing import CliRunner

from pfslam.cli import app
from pfslam.io.thor import write_thor

runner = CliRunner()


def _cells(recs):
    c = np.empty((1, len(recs)), dtype=object)
    for i, r in enumerate(recs):
        c[0, i] = r
    return c


def _rec(i, scan=None, drop=()):
    r = {
        "t": np.array([[100.0 + i / 40]]),
        "pose": np.zeros((1, 3)),
        "scan": np.ones((1, 1081), np.float32) if scan is None else scan,
    }
    for k in drop:
        r.pop(k)
    return r


def test_missing_file(tmp_path):
    res, text = _run("slam", tmp_path / "nope.mat", "-o", tmp_path / "out")
    _assert_clean_error(res, text, "nope.mat", "not found")


def test_not_a_mat_file(tmp_path):
    p = tmp_path / "log.txt"
    p.write_text("1 2 3\n")
    res, text = _run("slam", p, "-o", tmp_path / "out")
    _assert_clean_error(res, text, "log.txt", "format")


def test_mat_extension_but_not_matlab(tmp_path):
    p = tmp_path / "fake.mat"
    p.write_bytes(b"\x00\x01garbage" * 10)
    res, text = _run("slam", p, "-o", tmp_path / "out")
    _assert_clean_error(res, text, "fake.mat", "MATLAB")


@pytest.mark.parametrize(
    "recs, words",
    [
        ([_rec(0, drop=("scan",))], ["no field 'scan'"]),
        ([_rec(0), _rec(1, scan=np.ones((1, 900), np.float32))], ["900 ranges"]),
    ],
    ids=["no-scan", "wrong-length"],
)
def test_bad_lidar_content(tmp_path, recs, words):
    p = tmp_path / "train_lidar9.mat"
    sio.savemat(p, {"lidar": _cells(recs)})
    res, text = _run("slam", p, "--level-head", "-o", tmp_path / "out")
    _assert_clean_error(res, text, "train_lidar9.mat", *words)


def test_invalid_beams_are_no_returns_and_the_run_goes_on(tmp_path):
    """One inf beam in every scan, a few NaN and negative ones: the log runs, with one warning
    giving the counts (they used to abort the whole log)."""
    import json

    n = 60
    scans = np.full((n, 1081), 3.0, np.float32)
    scans[:, 100] = np.inf
    scans[[4, 20, 41], 200] = np.nan
    scans[[7, 33], 300] = -1.0
    lp = tmp_path / "train_lidar0.mat"
    write_thor(lp, None, t=100 + np.arange(n) / 40, scans=scans, pose=np.zeros((n, 3)))
    res, text = _run("slam", lp, "--level-head", "-o", tmp_path / "out")
    assert res.exit_code == 0, text
    assert "Traceback" not in text
    warnings = [ln for ln in text.splitlines() if "not valid ranges" in ln]
    assert len(warnings) == 1, text
    for part in ("train_lidar0.mat", "65 readings in 60 of 60 scans", "3 NaN", "60 +inf", "2 negative"):
        assert part in warnings[0], (part, warnings[0])
    assert json.loads((tmp_path / "out" / "run.json").read_text())["scans_processed"] == n


def test_joint_ts_not_increasing(tmp_path):
    n = 5
    lp, jp = tmp_path / "train_lidar0.mat", tmp_path / "train_joint0.mat"
    write_thor(lp, None, t=100 + np.arange(n) / 40, scans=np.ones((n, 1081), np.float32), pose=np.zeros((n, 3)))
    sio.savemat(jp, {"ts": np.array([[100.0, 100.1, 98.05, 100.2]]), "head_angles": np.zeros((2, 4))})
    res, text = _run("slam", lp, "--joint", jp, "-o", tmp_path / "out")
    _assert_clean_error(res, text, "train_joint0.mat", "not increasing")


def test_bad_config_file(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("particles: 10\nbogus: 1\n")
    res, text = _run("slam", tmp_path / "x.mat", "--config", cfg, "-o", tmp_path / "out")
    _assert_clean_error(res, text, "c.yaml", "bogus")


def test_dump_config_round_trips_through_load(tmp_path):
    from pfslam.config import SlamConfig, load_config

    res = runner.invoke(app, ["dump-config"])
    assert res.exit_code == 0
    p = tmp_path / "c.yaml"
    p.write_text(res.stdout)
    assert load_config(p) == SlamConfig()  # the slam: section of the sectioned file


def test_evaluate_reference_and_relations(tmp_path):
    from pfslam.io.trajectory import write_tum

    t = np.arange(20) * 0.5
    poses = np.column_stack([t * 0.3, np.zeros(20), np.zeros(20)])
    write_tum(tmp_path / "est.tum", t, poses)
    write_tum(tmp_path / "ref.tum", t, poses + [0.1, 0.0, 0.0])
    (tmp_path / "r.rel").write_text(f"{100 + t[2]} {100 + t[6]} 0.6 0 0 0 0 0\n")
    res = runner.invoke(
        app,
        [
            "evaluate",
            str(tmp_path / "est.tum"),
            "-r",
            str(tmp_path / "ref.tum"),
            "--relations",
            str(tmp_path / "r.rel"),
            "--time-offset",
            "100",
        ],
    )
    assert res.exit_code == 0, res.output
    assert "0.100" in res.stdout  # raw ATE of a 0.1 m shift
    assert "1 matched" in res.stdout and "translation 0.0000" in res.stdout
    res, text = _run("evaluate", tmp_path / "est.tum", "--relations", tmp_path / "r.rel")
    _assert_clean_error(res, text, "r.rel", "time-offset")


def _small_map(tmp_path, free=True):
    from pfslam.maps.grid import OccupancyGrid

    g = OccupancyGrid(origin=(-2.0, -2.0), shape=(80, 80))
    g.logodds[:] = -10 if free else 10
    g.logodds[40, :] = 10  # a wall along y = 0.0..0.05
    g.save_ros(tmp_path / "map", crop=False)
    return tmp_path / "map.yaml"


def _tiny_thor(tmp_path):
    lp = tmp_path / "train_lidar0.mat"
    write_thor(lp, None, t=100 + np.arange(3) / 40, scans=np.ones((3, 1081), np.float32), pose=np.zeros((3, 3)))
    return lp


def test_localize_bad_inputs(tmp_path):
    lp = _tiny_thor(tmp_path)
    y = _small_map(tmp_path)
    res, text = _run("localize", lp, "--level-head", "--map", y, "--initial-pose", "50,0,0", "-o", tmp_path / "o")
    _assert_clean_error(res, text, "map.yaml", "outside the map")
    res, text = _run("localize", lp, "--level-head", "--map", y, "--initial-pose", "0.5,0.02,0", "-o", tmp_path / "o")
    _assert_clean_error(res, text, "map.yaml", "occupied")
    res, text = _run("localize", lp, "--level-head", "--map", y, "--initial-pose", "1,2", "-o", tmp_path / "o")
    _assert_clean_error(res, text, "--initial-pose", "three numbers")
    full = tmp_path / "full"
    full.mkdir()
    res, text = _run(
        "localize", lp, "--level-head", "--map", _small_map(full, free=False), "--global", "-o", tmp_path / "o"
    )
    _assert_clean_error(res, text, "map.yaml", "no free cells")
    (tmp_path / "map.pgm").unlink()
    res, text = _run("localize", lp, "--level-head", "--map", y, "-o", tmp_path / "o")
    _assert_clean_error(res, text, "map.pgm", "not found")


def test_localize_writes_its_outputs(tmp_path):
    import json

    lp = _tiny_thor(tmp_path)
    y = _small_map(tmp_path)
    res = runner.invoke(
        app,
        ["localize", str(lp), "--level-head", "--map", str(y), "--initial-pose", "0,1,0", "-o", str(tmp_path / "o")],
    )
    assert res.exit_code == 0, res.output
    for name in ("trajectory.tum", "odometry.tum", "covariance.csv", "config.yaml", "localization.png", "run.json"):
        assert (tmp_path / "o" / name).is_file()
    info = json.loads((tmp_path / "o" / "run.json").read_text())
    assert info["scans_processed"] == 3 and info["config"]["particles"] == 500
    rows = (tmp_path / "o" / "covariance.csv").read_text().splitlines()
    assert rows[0] == "t,x,y,theta,xx,xy,xtheta,yy,ytheta,thetatheta"
    assert len(rows) - 1 == info["updates"] == info["metrics"]["uncertainty"]["updates"] >= 1
    assert info["run"] == "localization"
    # config.yaml holds the localize: section only (no calibration was asked for).
    from pfslam.config import LocalizerConfig, load_config

    saved = yaml.safe_load((tmp_path / "o" / "config.yaml").read_text())
    assert list(saved) == ["localize"]
    assert load_config(tmp_path / "o" / "config.yaml", LocalizerConfig) == LocalizerConfig()


def test_unwritable_output_is_a_clean_error(tmp_path):
    lp = _tiny_thor(tmp_path)
    blocker = tmp_path / "file"
    blocker.write_text("x")
    res, text = _run("slam", lp, "--level-head", "-o", blocker / "out")
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert "file" in text


@pytest.mark.parametrize("search", [False, True])
def test_demo_scores_slam_against_ground_truth(tmp_path, search):
    import json

    out = tmp_path / "demo"
    args = ["demo", "--duration", "8", "-o", str(out)] + (["--search"] if search else [])
    r = runner.invoke(app, args)
    assert r.exit_code == 0, r.output
    run = json.loads((out / "run.json").read_text())
    saved = yaml.safe_load((out / "config.yaml").read_text())
    assert list(saved) == ["slam"] and run["run"] == "slam"
    assert saved["slam"]["local_search"]["enabled"] is search
    slam, odom = run["metrics"]["SLAM"], run["metrics"]["odometry"]
    assert slam["matched"] == 320 and slam["ate_rmse"] < odom["ate_rmse"]
    assert f"ATE SLAM {slam['ate_rmse']:.3f} m" in r.output
