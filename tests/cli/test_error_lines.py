"""Mistakes a newcomer makes, each answered with one line naming the file or option and what
to do, exit code 2, and no output folder left behind: a THOR log without its joint file, a
misspelt config or sweep key, an output folder the system refuses, option names as typed;
and the CARMEN records pfslam knows but does not use, skipped without a warning."""

import json
import os

import numpy as np
import pytest
from carmen_sim import write_corrected_log
from clirun import invoke, one_line_error

from pfslam.io.thor import write_thor


def _thor(tmp_path, n=3, joint=False, scans=None):
    """A tiny THOR lidar file (and its joint file beside it with ``joint``)."""
    lp, jp = tmp_path / "train_lidar0.mat", tmp_path / "train_joint0.mat"
    t = 100 + np.arange(n) / 40
    scans = np.ones((n, 1081), np.float32) if scans is None else scans
    extra = {"joint_ts": t, "head_angles": np.zeros((2, n))} if joint else {}
    write_thor(lp, jp if joint else None, t=t, scans=scans, pose=np.zeros((n, 3)), **extra)
    return lp, jp


def _only(tmp_path, *names):
    """Nothing but ``names`` in ``tmp_path`` (no output folder was left)."""
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(names)


# -- a THOR log without --joint ---------------------------------------------------------------


@pytest.mark.parametrize(
    "cmd",
    [
        ["slam", "-o", "OUT"],
        ["localize", "--map", "map.yaml", "-o", "OUT"],
        ["calibrate"],
        ["convert", "OUT.bag"],
    ],
)
def test_a_thor_log_without_its_joint_file_is_refused_naming_it(tmp_path, cmd):
    lp, jp = _thor(tmp_path, joint=True)
    args = [str(tmp_path / a) if a.isupper() or a.endswith(".yaml") or a == "OUT.bag" else a for a in cmd]
    res, err = invoke(args[0], lp, *args[1:])
    line = one_line_error(res, err, "train_lidar0.mat", "joint file", f"--joint {jp}", "--level-head")
    assert line.startswith("error: ")
    _only(tmp_path, lp.name, jp.name)


def test_without_a_joint_file_beside_it_the_line_says_what_to_pass(tmp_path):
    lp, _ = _thor(tmp_path)
    res, err = invoke("slam", lp, "-o", tmp_path / "out")
    one_line_error(res, err, "train_lidar0.mat", "--joint JOINT.mat", "--level-head")
    _only(tmp_path, lp.name)


def test_level_head_runs_a_thor_log_without_joints_on_purpose(tmp_path):
    # Past the joint check, the log is read: this one has no valid return at all.
    lp, _ = _thor(tmp_path, scans=np.zeros((3, 1081), np.float32))
    res, err = invoke("slam", lp, "--level-head", "-o", tmp_path / "out")
    note, error = err.strip().splitlines()  # a note (not a warning): the level head was asked for
    assert note.endswith("no joint file given: head assumed level (neck yaw 0, head pitch 0) (--level-head)")
    assert not note.startswith("warning")
    one_line_error(res, error, "train_lidar0.mat", "valid return")
    _only(tmp_path, lp.name)


def test_level_head_with_a_joint_file_or_on_another_log_is_refused(tmp_path):
    lp, jp = _thor(tmp_path, joint=True)
    res, err = invoke("slam", lp, "-j", jp, "--level-head", "-o", tmp_path / "out")
    one_line_error(res, err, "--level-head", "not both")
    log = tmp_path / "c.log"
    write_corrected_log(log, lambda i: 1.0 + i, n=3)
    res, err = invoke("slam", log, "--level-head", "-o", tmp_path / "out")
    one_line_error(res, err, "--level-head", "THOR logs", "c.log")
    _only(tmp_path, lp.name, jp.name, log.name)


# -- misspelt keys ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "key", "meant"),
    [
        ("particels: 10\n", "particels", "particles"),
        ("resolution: 0.05\n", "resolution", "map.resolution"),
        ("slam:\n  map:\n    resolutoin: 0.05\n", "slam.map.resolutoin", "slam.map.resolution"),
        ("slma:\n  particles: 10\n", "slma", "slam"),
    ],
)
def test_a_misspelt_config_key_gets_a_did_you_mean(tmp_path, text, key, meant):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(text)
    res, err = invoke("slam", tmp_path / "x.mat", "-c", cfg, "-o", tmp_path / "out")
    one_line_error(res, err, "c.yaml", f"unknown config key '{key}'", f"did you mean '{meant}'?")
    _only(tmp_path, "c.yaml")


def test_a_misspelt_sweep_spec_key_gets_a_did_you_mean(tmp_path):
    spec = tmp_path / "s.yaml"
    spec.write_text("logs:\n  - {name: a, path: a.log, jiont: b.mat}\nseeds: [0]\n")
    res, err = invoke("sweep", spec, "-o", tmp_path / "out")
    one_line_error(res, err, "s.yaml", "logs[0].jiont", "did you mean 'joint'?")
    spec.write_text("logs:\n  - {name: a, path: a.log}\nseed: [0]\n")
    res, err = invoke("sweep", spec, "-o", tmp_path / "out")
    one_line_error(res, err, "s.yaml", "seed: unknown key", "did you mean 'seeds'?")
    _only(tmp_path, "s.yaml")


# -- the output folder ------------------------------------------------------------------------


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc")
def test_an_output_folder_the_system_refuses_gets_its_real_reason(tmp_path):
    lp, _ = _thor(tmp_path)
    res, err = invoke("slam", lp, "--level-head", "-o", "/proc/pfslam_x/out")
    line = one_line_error(res, err, "/proc/pfslam_x/out", "cannot create the output folder")
    # root: /proc takes no new folders (the system says "No such file or directory"); others: no permission
    assert "/proc takes no new folders (a proc file system)" in line or "Permission denied in /proc" in line, line
    assert "No such file" not in line


def test_a_run_that_fails_on_its_input_leaves_no_output_folder(tmp_path):
    log = tmp_path / "bad.log"
    log.write_text("FLASER 3 1 2\n")  # a CARMEN record, malformed: no usable scan
    res, err = invoke("slam", log, "-o", tmp_path / "new" / "deeper" / "out")
    one_line_error(res, err, "bad.log", "no usable laser scans")
    _only(tmp_path, "bad.log")
    (tmp_path / "kept").mkdir()  # a folder that was there before stays, empty or not
    res, err = invoke("slam", log, "-o", tmp_path / "kept")
    one_line_error(res, err, "bad.log")
    assert (tmp_path / "kept").is_dir()


def test_a_run_interrupted_while_loading_leaves_no_output_folder(tmp_path, monkeypatch):
    import pfslam.pipeline.commands

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(pfslam.pipeline.commands, "load", interrupted)  # the step the commands call
    lp, jp = _thor(tmp_path, joint=True)
    res, err = invoke("slam", lp, "-j", jp, "-o", tmp_path / "out")
    assert res.exit_code == 130, err
    _only(tmp_path, lp.name, jp.name)


# -- option names as typed --------------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["slam", "LOG", "-n", "-1"], ["--particles must be an integer", "not -1"]),
        (["slam", "LOG", "--every", "0"], ["--every must be"]),
        (["slam", "LOG", "--score", "walls"], ["--score must be one of", "'walls'"]),
        (["slam", "LOG", "--estimate", "best"], ["--estimate is not read by", "use --filter single"]),
        (["localize", "LOG", "--map", "m.yaml", "--model", "sonar"], ["--model must be one of", "'sonar'"]),
    ],
)
def test_an_invalid_option_value_is_named_as_typed(tmp_path, args, words):
    lp, jp = _thor(tmp_path, joint=True)
    args = [str(lp) if a == "LOG" else a for a in args]
    res, err = invoke(*args, "-j", jp, "-o", tmp_path / "out")
    line = one_line_error(res, err, *words)
    assert line.startswith("error: --"), line
    _only(tmp_path, lp.name, jp.name)


def test_a_config_file_value_keeps_its_key_name(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("particles: -1\n")
    res, err = invoke("slam", tmp_path / "x.mat", "-c", cfg, "-o", tmp_path / "out")
    one_line_error(res, err, "c.yaml: particles must be an integer")


# -- CARMEN records pfslam does not use -------------------------------------------------------


def test_known_unused_carmen_records_are_counted_not_warned(tmp_path):
    from pfslam.io.logs import load_log

    log = tmp_path / "c.log"
    write_corrected_log(
        log,
        lambda i: 1.0 + i,
        n=6,
        header="SYNC tag 0.5 host 0.5\nNEFF 12.5\nNEFF 11.0\nTRUEPOS 0 0 0 0 0 0 0.7 host 0.7\nWEIRD 1 2",
    )
    loaded = load_log(log)
    assert loaded.skipped == {"SYNC": 1, "NEFF": 2, "TRUEPOS": 1}
    assert [w for w in loaded.warnings if "skipped" in w] == [f"{log}: skipped 1 record(s) of unknown types (WEIRD 1)"]


def test_run_json_lists_the_skipped_records(tmp_path):
    log = tmp_path / "c.log"
    write_corrected_log(log, lambda i: 1.0 + i, n=10, header="NEFF 12.5\nNEFF 11.0")
    res, err = invoke("slam", log, "--filter", "single", "--backend", "none", "-o", tmp_path / "out")
    assert res.exit_code == 0, err
    assert "NEFF" not in err
    info = json.loads((tmp_path / "out" / "run.json").read_text())
    assert info["input"]["skipped_records"] == {"NEFF": 2}


def test_evaluate_plot_folder_is_not_left_when_the_estimate_is_missing(tmp_path):
    from pfslam.io.trajectory import write_tum

    write_tum(tmp_path / "ref.tum", np.arange(5.0), np.zeros((5, 3)))
    res, err = invoke("evaluate", tmp_path / "est.tum", "-r", tmp_path / "ref.tum", "--plot", tmp_path / "pics")
    one_line_error(res, err, "est.tum", "not found")
    _only(tmp_path, "ref.tum")
