"""Config files on the command line: `localize --config` (sectioned or flat), `dump-config`,
and a run's own config.yaml reproducing the run."""

import json

import pytest
import yaml
from typer.testing import CliRunner

from clirun import invoke as _invoke
from clirun import one_line_error as _one_line_error
from pfslam.cli import app
from pfslam.config import SECTIONS, LocalizerConfig, SlamConfig, from_dict, load_config, to_dict

runner = CliRunner()


@pytest.fixture(scope="module")
def short_log(short_office):
    """(lidar .mat, joint .mat, map.yaml) of the 10 s simulated office log."""
    r = short_office
    return r.lidar_path, r.joint_path, r.lidar_path.parent / "map.yaml"


def _localize(short_log, out, *extra):
    lidar, joint, map_yaml = short_log
    return _invoke("localize", lidar, "--joint", joint, "--map", map_yaml, "-o", out, *extra)


# -- localize --config ---------------------------------------------------------------------------


@pytest.mark.parametrize("text, words", [
    ("localize:\n  beams: 0\n", ["beams"]),
    ("beams: abc\n", ["beams", "integer", "'abc'"]),
    ("localize:\n  model: foo\n", ["localize.model", "'likelihood_field'", "'beam'", "'foo'"]),
    ("localize:\n  bogus: 1\n", ["localize.bogus"]),
])
def test_localize_config_file_errors_are_one_line_naming_the_file_and_key(short_log, tmp_path, text, words):
    f = tmp_path / "loc.yaml"
    f.write_text(text)
    res, err = _localize(short_log, tmp_path / "o", "--config", f)
    line = _one_line_error(res, err, "loc.yaml", *words)
    assert line.startswith("error:")
    assert not (tmp_path / "o" / "run.json").exists()  # refused before any run


@pytest.mark.parametrize("sectioned", [True, False])
def test_localize_config_values_land_in_the_runs_config(short_log, tmp_path, sectioned):
    values = "beams: 30\nseed: 4\nparticles: 200\nmin_particles: 200\n"
    f = tmp_path / "loc.yaml"
    f.write_text("localize:\n" + "".join("  " + ln + "\n" for ln in values.splitlines()) if sectioned else values)
    if sectioned:  # other sections of the same file are not the localizer's business
        f.write_text(f.read_text() + "slam:\n  particles: 7\n")
    out = tmp_path / "o"
    res, err = _localize(short_log, out, "--config", f)
    assert res.exit_code == 0, (res.output, err)
    saved = yaml.safe_load((out / "config.yaml").read_text())
    assert list(saved) == ["localize"]
    assert saved["localize"]["beams"] == 30 and saved["localize"]["seed"] == 4
    assert saved["localize"]["particles"] == 200
    want = LocalizerConfig(beams=30, seed=4, particles=200, min_particles=200)
    assert load_config(out / "config.yaml", LocalizerConfig) == want
    info = json.loads((out / "run.json").read_text())
    assert info["run"] == "localization" and info["config"] == to_dict(want)
    assert info["scans_processed"] == 400


def test_localize_options_override_the_config_file(short_log, tmp_path):
    f = tmp_path / "loc.yaml"
    f.write_text("localize:\n  beams: 30\n  seed: 4\n  particles: 200\n  min_particles: 200\n")
    out = tmp_path / "o"
    res, err = _localize(short_log, out, "--config", f, "--seed", "9", "--model", "beam")
    assert res.exit_code == 0, (res.output, err)
    saved = load_config(out / "config.yaml", LocalizerConfig)
    assert (saved.seed, saved.model, saved.beams) == (9, "beam", 30)


# -- dump-config -----------------------------------------------------------------------------------


def test_dump_config_prints_every_section_and_each_round_trips_to_the_defaults():
    res = runner.invoke(app, ["dump-config"])
    assert res.exit_code == 0, res.output
    data = yaml.safe_load(res.stdout)
    assert isinstance(data, dict) and list(data) == ["slam", "localize", "calibrate"]
    for name, cls in SECTIONS.items():
        assert from_dict(cls, data[name]) == cls(), name
        assert data[name] == to_dict(cls())


@pytest.mark.parametrize("name", list(SECTIONS))
def test_dump_config_of_one_section_is_that_section_flat(name, tmp_path):
    res = runner.invoke(app, ["dump-config", name])
    assert res.exit_code == 0, res.output
    data = yaml.safe_load(res.stdout)
    cls = SECTIONS[name]
    assert data == to_dict(cls()) and name not in data
    assert from_dict(cls, data) == cls()
    f = tmp_path / "flat.yaml"
    f.write_text(res.stdout)
    assert load_config(f, cls) == cls()  # a flat file is read whole


def test_dump_config_of_an_unknown_section_is_one_line():
    res, err = _invoke("dump-config", "mapping")
    _one_line_error(res, err, "mapping", "slam", "localize", "calibrate")
    assert res.stdout == ""


# -- a run's own config.yaml ---------------------------------------------------------------------


def test_slam_config_yaml_of_a_run_reproduces_the_run(short_office, tmp_path):
    lidar, joint = short_office.lidar_path, short_office.joint_path
    first, again, plain = tmp_path / "first", tmp_path / "again", tmp_path / "plain"
    res, err = _invoke("slam", lidar, "--joint", joint, "-o", first, "-n", "30", "--seed", "3", "--every", "2",
                       "--score", "cells")
    assert res.exit_code == 0, (res.output, err)
    saved = load_config(first / "config.yaml", SlamConfig)
    assert (saved.particles, saved.seed, saved.every, saved.sensor.scoring_map) == (30, 3, 2, "cells")
    assert list(yaml.safe_load((first / "config.yaml").read_text())) == ["slam"]
    res, err = _invoke("slam", lidar, "--joint", joint, "-o", again, "--config", first / "config.yaml")
    assert res.exit_code == 0, (res.output, err)
    assert (again / "trajectory.tum").read_bytes() == (first / "trajectory.tum").read_bytes()
    assert (again / "config.yaml").read_bytes() == (first / "config.yaml").read_bytes()
    # Control: the settings matter, so the equality above says the file carried them.
    res, err = _invoke("slam", lidar, "--joint", joint, "-o", plain)
    assert res.exit_code == 0, (res.output, err)
    assert (plain / "trajectory.tum").read_bytes() != (first / "trajectory.tum").read_bytes()


@pytest.mark.parametrize("text, words", [
    ("calibrate:\n  gap: 0\n", ["cal.yaml", "gap must be an integer >= 1, not 0"]),
    ("max_latency: 9.0\n", ["cal.yaml", "max_latency"]),
    ("calibrate:\n  sigma: 1\n", ["cal.yaml", "calibrate.sigma"]),
])
def test_calibrate_config_file_errors_are_one_line(tmp_path, text, words):
    f = tmp_path / "cal.yaml"
    f.write_text(text)
    res, err = _invoke("calibrate", tmp_path / "log.dat", "--config", f)  # the config is read first
    _one_line_error(res, err, *words)
