"""The command line is a shell over the pipeline: ``pfslam slam LOG`` and the library call
``pfslam.slam(LOG)`` write the same files, byte for byte, on every kind of log; and a particle
count reaches the filter that runs through every door (-n, a config file, a sweep, the API)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from clirun import invoke
from datafiles import need

import pfslam
from pfslam.cli.options import MAX_SCANS_ENV
from pfslam.config import SlamConfig
from pfslam.errors import InputError
from pfslam.pipeline import Quiet
from pfslam.tools.convert import convert

SAME_FILES = ("trajectory.tum", "odometry.tum", "map.pgm", "map.yaml", "config.yaml")
# run.json figures that depend on the machine's speed and memory, not on the run's answer
TIMING = {"seconds_by_phase", "seconds", "scans_per_second", "real_time_factor", "peak_rss_mb"}
FILTER_TIMING = {"slowest_scan_ms", "p99_scan_ms", "seconds_by_part"}


def _run_json(folder: Path) -> dict:
    info = json.loads((folder / "run.json").read_text())
    for k in TIMING:
        info.pop(k)
    for k in FILTER_TIMING:
        info["filter"].pop(k, None)
    for k in [k for k in info.get("backend", {}) if "seconds" in k or k.startswith("slowest")]:
        info["backend"].pop(k)
    return info


def _assert_same_outputs(a: Path, b: Path) -> None:
    for name in SAME_FILES:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    assert _run_json(a) == _run_json(b)


@pytest.fixture(scope="module")
def logs(short_office, tmp_path_factory):
    """The short office walk as each kind of log: THOR .mat (+ joint), CARMEN, ROS 2 (MCAP)."""
    folder = tmp_path_factory.mktemp("kinds")
    carmen = folder / "office.log"
    mcap = folder / "office.mcap"
    for out in (carmen, mcap):
        convert(short_office.lidar_path, out, joint=short_office.joint_path)
    return {
        "thor": (short_office.lidar_path, short_office.joint_path),
        "carmen": (carmen, None),
        "rosbag": (mcap, None),
    }


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["thor", "carmen", "rosbag"])
def test_the_command_and_the_api_write_the_same_files(logs, kind, tmp_path):
    log, joint = logs[kind]
    extra = ["-j", joint] if joint else []
    res, err = invoke("slam", log, "-o", tmp_path / "cli", "--seed", 2, *extra)
    assert res.exit_code == 0, err
    quiet = Quiet()
    outcome = pfslam.slam(log, tmp_path / "api", joint=joint, config=SlamConfig(seed=2), reporter=quiet)
    assert outcome.run.error is None and not outcome.run.interrupted and outcome.out == tmp_path / "api"
    assert outcome.run.config.filter == "rbpf"  # the same filter the command picks (auto)
    _assert_same_outputs(tmp_path / "cli", tmp_path / "api")


@pytest.mark.realdata
@pytest.mark.slow
def test_the_command_and_the_api_agree_on_a_wheel_encoder_log_with_its_calibration(tmp_path):
    """The Mines rover's first 250 scans: the calibration a wheel log gets by default is the
    pipeline's decision, so the API calibrates it too, and says so through its reporter."""
    lines = need("mines/exp2.dat").read_text().splitlines(keepends=True)[:250]
    log = tmp_path / "exp2_head.dat"
    log.write_text("".join(lines))
    res, err = invoke("slam", log, "-o", tmp_path / "cli")
    assert res.exit_code == 0, err
    quiet = Quiet()
    pfslam.slam(log, tmp_path / "api", reporter=quiet)
    assert any("calibrating the odometry" in ln for ln in quiet.lines)
    _assert_same_outputs(tmp_path / "cli", tmp_path / "api")
    assert "calibration" in json.loads((tmp_path / "api" / "run.json").read_text())["input"]


def _particles(folder: Path) -> int:
    """The particle count the run's filter had, as run.json records it (from the filter)."""
    info = json.loads((folder / "run.json").read_text())
    assert info["config"]["particles"] == info["filter"]["particles"]
    return int(info["filter"]["particles"])


@pytest.mark.slow
@pytest.mark.parametrize("filter_name", ["rbpf", "single"])
def test_particles_reach_the_filter_that_runs_through_every_door(short_office, tmp_path, filter_name, monkeypatch):
    from pfslam.sweep import whole as sweep_run

    log, joint = short_office.lidar_path, short_office.joint_path
    # A particle count is the filter's from its start: 50 of the 400 scans show it (the sweep's too).
    monkeypatch.setenv(MAX_SCANS_ENV, "50")
    flt = ["--filter", filter_name]
    # 1. -n on the command line
    res, err = invoke("slam", log, "-j", joint, "-o", tmp_path / "option", "-n", 7, *flt)
    assert res.exit_code == 0, err
    # 2. a config file's particles (the dump-config layout, and a bare section)
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump({"slam": {"particles": 8, "filter": filter_name}}))
    res, err = invoke("slam", log, "-j", joint, "-o", tmp_path / "file", "-c", cfg)
    assert res.exit_code == 0, err
    # 3. a sweep's setting
    spec = tmp_path / "spec.yaml"
    spec.write_text(
        yaml.safe_dump(
            {
                "logs": [{"name": "o", "path": str(log), "joint": str(joint)}],
                "seeds": [0],
                "settings": {"particles": [9], "filter": [filter_name]},
            }
        )
    )
    res = sweep_run.run(sweep_run.plan(spec, tmp_path / "sweep"), workers=1)
    assert list(res.table["status"]) == ["ok"], res.table["message"].tolist()
    # 4. the API
    pfslam.slam(log, tmp_path / "api", joint=joint, config=SlamConfig(particles=10, filter=filter_name))
    run_dir = tmp_path / "sweep" / res.table["run_dir"].iloc[0]
    assert [
        _particles(tmp_path / "option"),
        _particles(tmp_path / "file"),
        _particles(run_dir),
        _particles(tmp_path / "api"),
    ] == [7, 8, 9, 10]
    # Without a count, each filter its own.
    assert pfslam.resolve_filter(SlamConfig(filter=filter_name)).particles == {"rbpf": 30, "single": 100}[filter_name]


def test_the_old_per_filter_key_is_refused_naming_the_key_that_sets_it(short_office, tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("slam:\n  rbpf:\n    particles: 12\n")
    res, err = invoke("slam", short_office.lidar_path, "-j", short_office.joint_path, "-o", tmp_path / "o", "-c", cfg)
    assert res.exit_code == 2 and "rbpf.particles" in err and "renamed to 'particles'" in err, err


@pytest.mark.parametrize(
    "setting, runs, twin",
    [
        ("sensor:\n    temperature: 3.0\n", "Rao-Blackwellized", "rbpf.temperature"),
        ("estimate: best\n", "Rao-Blackwellized", None),
        ("filter: single\n  rbpf:\n    sigma: 0.1\n", "single-map", None),
        ("filter: single\n  rbpf:\n    temperature: 5.0\n", "single-map", "sensor.temperature"),
    ],
)
def test_a_setting_the_running_filter_does_not_read_is_refused_naming_the_file_and_the_key(
    short_office, tmp_path, setting, runs, twin
):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("slam:\n  " + setting)
    res, err = invoke("slam", short_office.lidar_path, "-j", short_office.joint_path, "-o", tmp_path / "o", "-c", cfg)
    assert res.exit_code == 2, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and str(cfg) in lines[0] and runs in lines[0], err
    assert twin is None or twin in lines[0]
    with pytest.raises(InputError, match="the filter that runs"):  # the API refuses it the same way
        pfslam.slam(short_office.lidar_path, tmp_path / "api", joint=short_office.joint_path, config_file=cfg)


def test_settings_at_their_defaults_and_shared_ones_are_accepted_by_either_filter():
    for flt in ("rbpf", "single"):
        cfg = pfslam.resolve_filter(SlamConfig(filter=flt, seed=3, every=2, resample_threshold=0.4))
        assert cfg.filter == flt and cfg.seed == 3
    assert pfslam.resolve_filter(SlamConfig(motion=SlamConfig().motion.__class__(axle=0.5))).motion.axle == 0.5
    np.testing.assert_equal(pfslam.resolve_filter(SlamConfig(), "mines").rbpf.match_prior, 0.1)
