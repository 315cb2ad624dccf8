"""Config files on the command line: `localize --config` (sectioned or flat), `dump-config`,
and a run's own config.yaml reproducing the run."""

import json

import pytest
import yaml
from clirun import invoke as _invoke
from clirun import one_line_error as _one_line_error
from typer.testing import CliRunner

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


@pytest.mark.parametrize(
    "text, words",
    [
        ("localize:\n  beams: 0\n", ["beams"]),
        ("beams: abc\n", ["beams", "integer", "'abc'"]),
        ("localize:\n  model: foo\n", ["localize.model", "'likelihood_field'", "'beam'", "'foo'"]),
        ("localize:\n  bogus: 1\n", ["localize.bogus"]),
    ],
)
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


def test_dump_config_lists_the_amcl_settings_and_an_edited_dump_drives_the_run(short_log, tmp_path):
    res = runner.invoke(app, ["dump-config", "localize"])
    assert res.exit_code == 0, res.output
    notes = {ln.split(":")[0]: ln.split("#", 1)[1] for ln in res.stdout.splitlines()}
    for key, amcl in (
        ("beams", "laser_max_beams"),
        ("laser_min_range", "laser_min_range"),
        ("laser_max_range", "laser_max_range"),
        ("z_hit", "laser_z_hit"),
        ("z_rand", "laser_z_rand"),
        ("sigma_hit", "laser_sigma_hit"),
        ("max_dist", "laser_likelihood_max_dist"),
        ("update_min_d", "update_min_d"),
        ("update_min_a", "update_min_a"),
        ("recovery_alpha_slow", "recovery_alpha_slow"),
        ("recovery_alpha_fast", "recovery_alpha_fast"),
        ("kld_err", "kld_err"),
        ("kld_z", "kld_z"),
        ("initial_std_x", "initial_cov_xx"),
        ("initial_std_theta", "initial_cov_aa"),
    ):
        assert f"AMCL {amcl}" in notes[key], (key, notes[key])
    assert "rad" in notes["update_min_a"] and "rad" in notes["kld_bin_a"] and "rad" in notes["initial_std_theta"]
    # Edited like a user would (turn thresholds in radians), the dump is read back and used.
    runs = {}
    for name, (d, a) in {"default": (None, None), "lazy": ("1.0", "1.5")}.items():
        text = res.stdout
        if d is not None:
            text = (
                "\n".join(
                    f"update_min_d: {d}"
                    if ln.startswith("update_min_d:")
                    else f"update_min_a: {a}  # rad"
                    if ln.startswith("update_min_a:")
                    else ln
                    for ln in text.splitlines()
                )
                + "\n"
            )
        f = tmp_path / f"{name}.yaml"
        f.write_text(text)
        out = tmp_path / name
        r, err = _localize(short_log, out, "--config", f)
        assert r.exit_code == 0, (r.output, err)
        saved = load_config(out / "config.yaml", LocalizerConfig)
        assert saved == load_config(f, LocalizerConfig)
        runs[name] = (saved, json.loads((out / "run.json").read_text())["updates"])
    assert runs["default"][0] == LocalizerConfig()
    assert (runs["lazy"][0].update_min_d, runs["lazy"][0].update_min_a) == (1.0, 1.5)
    # 10 s of walking: dozens of updates at 5 cm / 3 deg; at 1 m / 1.5 rad only a few.
    assert runs["default"][1] >= 20 and runs["lazy"][1] <= runs["default"][1] / 4, runs


def test_initial_std_from_the_config_file_and_the_option_in_degrees(short_log, tmp_path):
    import math

    f = tmp_path / "loc.yaml"
    f.write_text("localize:\n  initial_std_x: 0.3\n  initial_std_y: 0.2\n  initial_std_theta: 0.2\n")
    results = {}
    for name, extra in {
        "file": ("--config", f),
        "option": ("--initial-std", f"0.3,0.2,{math.degrees(0.2)!r}"),
        "both": ("--config", f, "--initial-std", "0.05,0.05,2"),
        "default": (),
    }.items():
        out = tmp_path / name
        r, err = _localize(short_log, out, "--initial-pose", "1,1,0", *extra)
        assert r.exit_code == 0, (r.output, err)
        results[name] = (
            load_config(out / "config.yaml", LocalizerConfig).initial_std,
            (out / "trajectory.tum").read_bytes(),
        )
    assert results["file"][0] == (0.3, 0.2, 0.2)
    assert results["option"][0] == pytest.approx((0.3, 0.2, 0.2), abs=1e-12)  # degrees on the command line
    assert results["both"][0] == pytest.approx((0.05, 0.05, math.radians(2.0)))  # the option wins
    assert results["default"][0] == pytest.approx((0.1, 0.1, math.radians(5.0)))
    # The spread is what the particles start with: the same spread, the same run.
    assert results["file"][1] == results["option"][1]
    assert results["file"][1] != results["default"][1] and results["both"][1] != results["file"][1]


def test_a_negative_initial_std_is_one_line(short_log, tmp_path):
    res, err = _localize(short_log, tmp_path / "o", "--initial-std", "0.1,-0.1,5")
    _one_line_error(res, err, "--initial-std", "negative")
    res, err = _localize(short_log, tmp_path / "o", "--initial-std", "0.1,0.1")
    _one_line_error(res, err, "--initial-std", "SX,SY,STHETA_DEG")


# -- a run's own config.yaml ---------------------------------------------------------------------


def test_slam_config_yaml_of_a_run_reproduces_the_run(short_office, tmp_path):
    lidar, joint = short_office.lidar_path, short_office.joint_path
    first, again, plain = tmp_path / "first", tmp_path / "again", tmp_path / "plain"
    res, err = _invoke(
        "slam",
        lidar,
        "--joint",
        joint,
        "-o",
        first,
        "-n",
        "30",
        "--seed",
        "3",
        "--every",
        "2",
        "--filter",
        "single",
        "--score",
        "cells",
    )  # --score is the single-map filter's
    assert res.exit_code == 0, (res.output, err)
    saved = load_config(first / "config.yaml", SlamConfig)
    assert (saved.particles, saved.seed, saved.every, saved.sensor.scoring_map) == (30, 3, 2, "cells")
    assert saved.filter == "single"
    assert list(yaml.safe_load((first / "config.yaml").read_text())) == ["slam"]
    res, err = _invoke("slam", lidar, "--joint", joint, "-o", again, "--config", first / "config.yaml")
    assert res.exit_code == 0, (res.output, err)
    assert (again / "trajectory.tum").read_bytes() == (first / "trajectory.tum").read_bytes()
    assert (again / "config.yaml").read_bytes() == (first / "config.yaml").read_bytes()
    # Control: the settings matter, so the equality above says the file carried them.
    res, err = _invoke("slam", lidar, "--joint", joint, "-o", plain)
    assert res.exit_code == 0, (res.output, err)
    assert (plain / "trajectory.tum").read_bytes() != (first / "trajectory.tum").read_bytes()


@pytest.mark.parametrize(
    "text, words",
    [
        ("calibrate:\n  gap: 0\n", ["cal.yaml", "gap must be an integer >= 1, not 0"]),
        ("max_latency: 9.0\n", ["cal.yaml", "max_latency"]),
        ("calibrate:\n  sigma: 1\n", ["cal.yaml", "calibrate.sigma"]),
    ],
)
def test_calibrate_config_file_errors_are_one_line(tmp_path, text, words):
    f = tmp_path / "cal.yaml"
    f.write_text(text)
    res, err = _invoke("calibrate", tmp_path / "log.dat", "--config", f)  # the config is read first
    _one_line_error(res, err, *words)
