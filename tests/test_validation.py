"""Bad configuration values, arguments and trajectory files give one clear error, not a traceback."""

import math
import warnings

import numpy as np
import pytest

from pfslam.calibrate import CalibrationError, calibrate
from pfslam.config import SlamConfig, load_config
from pfslam.errors import ConfigError, InputError
from pfslam.evaluate import associate, relation_errors, trajectory_errors
from pfslam.io.trajectory import read_tum
from pfslam.localize import LocalizerConfig
from pfslam.simulate import simulate, simulate_wheeled

NAN, INF = float("nan"), float("inf")


def _load(tmp_path, text):
    f = tmp_path / "c.yaml"
    f.write_text(text)
    return load_config(f)


# -- seeds ----------------------------------------------------------------------------------


def test_negative_seed_is_a_config_error_everywhere(tmp_path):
    with pytest.raises(ConfigError, match="seed must be a non-negative integer, not -1"):
        SlamConfig(seed=-1).validate()
    with pytest.raises(ConfigError, match="seed must be a non-negative integer, not -1"):
        _load(tmp_path, "seed: -1\n").validate()
    with pytest.raises(ConfigError, match="seed must be a non-negative integer"):
        LocalizerConfig(seed=-1).validate()
    with pytest.raises(ConfigError, match="seed must be a non-negative integer"):
        simulate("office", 1.0, seed=-1, out_dir=tmp_path / "sim")
    assert not (tmp_path / "sim").exists()  # rejected before anything is written
    with pytest.raises(ConfigError, match="seed"):
        simulate_wheeled(duration_s=1.0, seed=-1)


# -- reading YAML -----------------------------------------------------------------------------


@pytest.mark.parametrize("text, match", [
    ("particles: .inf\n", "particles must be an integer, not inf"),
    ("particles: true\n", "particles must be an integer, not True"),
    ("particles: 10.7\n", "particles must be an integer, not 10.7"),
    ("particles: '100'\n", "particles must be an integer"),
    ("search:\n  enabled: \"no\"\n", "search.enabled must be true or false, not 'no'"),
    ("search:\n  enabled: 1\n", "search.enabled must be true or false, not 1"),
    ("map:\n  resolution: true\n", "map.resolution must be a finite number, not True"),
    ("map:\n  resolution: '0.05'\n", "map.resolution must be a finite number"),
    ("map:\n  resolution: .nan\n", "map.resolution must be a finite number, not nan"),
    ("estimate: 5\n", "estimate must be a string, not 5"),
    ("map: 5\n", "section 'map' must be a mapping"),
    ("- 1\n- 2\n", "config must be a mapping"),
    ("map:\n  resolution: " + "9" * 400 + "\n", "map.resolution: .* is out of range"),
])
def test_yaml_values_are_converted_strictly(tmp_path, text, match):
    with pytest.raises(InputError, match=match) as info:
        _load(tmp_path, text)
    assert info.value.path.endswith("c.yaml")


def test_yaml_conversions_that_lose_nothing_are_kept(tmp_path):
    c = _load(tmp_path, "particles: 100.0\nmap:\n  resolution: 1e-2\n  initial_size: 30\nsearch:\n  enabled: yes\n")
    assert c.particles == 100 and type(c.particles) is int
    assert c.map.resolution == 0.01 and type(c.map.resolution) is float
    assert c.map.initial_size == 30.0 and type(c.map.initial_size) is float
    assert c.search.enabled is True
    assert c.validate() is c


def test_non_utf8_config_names_the_file(tmp_path):
    f = tmp_path / "bad.yaml"
    f.write_bytes(b"particles: 10\n\xff\xfe garbage\n")
    with pytest.raises(InputError, match=r"bad\.yaml: not UTF-8 text \(byte 0xff"):
        load_config(f)


def test_config_folder_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="is a folder"):
        load_config(tmp_path)


# -- ranges -----------------------------------------------------------------------------------


@pytest.mark.parametrize("key, value, match", [
    ("particles", 0, "particles must be an integer in 1..10000000, not 0"),
    ("particles", True, "particles must be an integer, not True"),
    ("every", 0, "every must be an integer >= 1"),
    ("resample_threshold", 5.0, "resample_threshold must be a finite number >= 0 and <= 1, not 5.0"),
    ("resample_threshold", -1.0, "resample_threshold"),
    ("map.resolution", INF, "map.resolution must be a finite number, not inf"),
    ("map.resolution", 1e-6, "map.resolution must be a finite number >= 0.001"),
    ("map.resolution", 0.0, "map.resolution"),
    ("map.initial_size", 0.0, "map.initial_size must be a finite number > 0"),
    ("map.l_clamp", -1.0, "map.l_clamp must be a finite number > 0"),
    ("map.l_occ", NAN, "map.l_occ must be a finite number, not nan"),
    ("map.l_occ", -3.0, "map.l_occ must be a finite number > 0"),
    ("map.l_free", 1.0, "map.l_free must be a finite number < 0"),
    ("motion.sigma_x", -1.0, "motion.sigma_x must be a finite number >= 0"),
    ("motion.sigma_theta_deg", NAN, "motion.sigma_theta_deg"),
    ("motion.k_left", -1.0, "motion.k_left"),
    ("motion.rot_k", -0.1, "motion.rot_k"),
    ("motion.axle", 0.0, "motion.axle must be a finite number > 0"),
    ("motion.ref_interval", 0.0, "motion.ref_interval must be a finite number > 0"),
    ("sensor.ground_z", NAN, "sensor.ground_z must be a finite number"),
    ("sensor.max_hits", 0, "sensor.max_hits must be an integer >= 1"),
    ("sensor.temperature", NAN, "sensor.temperature"),
    ("sensor.saturation", 0.0, "sensor.saturation must be a finite number > 0"),
    ("sensor.field_threshold", NAN, "sensor.field_threshold"),
    ("sensor.field_sigma", 0.0, "sensor.field_sigma"),
    ("sensor.field_refresh_m", -1.0, "sensor.field_refresh_m"),
    ("sensor.field_refresh_scans", 0, "sensor.field_refresh_scans"),
    ("search.enabled", "no", "search.enabled must be true or false, not 'no'"),
    ("search.radius_cells", 1000, r"search.radius_cells must be an integer in 0..20, not 1000"),
    ("search.radius_cells", -3, "search.radius_cells"),
    ("search.theta_steps", 100000, r"search.theta_steps must be an integer in 0..45"),
    ("search.theta_step_deg", 0.0, "search.theta_step_deg must be a finite number > 0"),
])
def test_slam_config_ranges(key, value, match):
    cfg = SlamConfig()
    *section, name = key.split(".")
    setattr(getattr(cfg, section[0]) if section else cfg, name, value)
    with pytest.raises(ConfigError, match=match):
        cfg.validate()


def test_slam_config_limits_themselves_are_valid():
    cfg = SlamConfig(resample_threshold=1.0)
    cfg.map.resolution = 0.001
    cfg.search.radius_cells, cfg.search.theta_steps = 20, 45
    cfg.motion.sigma_x = 0
    assert cfg.validate() is cfg


@pytest.mark.parametrize("kw, match", [
    (dict(particles=0), "particles"),
    (dict(particles=True), "particles must be an integer"),
    (dict(sigma_hit=NAN), "sigma_hit must be a finite number, not nan"),
    (dict(max_dist=INF), "max_dist"),
    (dict(alpha1=NAN), "alpha1"),
    (dict(axle=INF), "axle"),
    (dict(ground_z=NAN), "ground_z"),
    (dict(z_short=-0.1), "z_short"),
    (dict(lambda_short=0.0), "lambda_short"),
    (dict(kld="yes"), "kld must be true or false"),
    (dict(update_min_d=NAN), "update_min_d"),
])
def test_localizer_config_ranges(kw, match):
    with pytest.raises(ConfigError, match=match):
        LocalizerConfig(**kw).validate()


# -- simulate, calibrate, evaluate ------------------------------------------------------------


@pytest.mark.parametrize("kw, match", [
    (dict(duration_s=INF), "duration must be a finite number of seconds > 0 and <= 3600, not inf"),
    (dict(duration_s=NAN), "duration must be a finite number of seconds"),
    (dict(duration_s=0.0), "duration"),
    (dict(head_pitch=NAN), "head_pitch must be a finite angle in radians"),
    (dict(head_pitch=3.0), "head_pitch"),
    (dict(rate_hz=INF), "rate_hz"),
    (dict(range_noise=NAN), "range_noise"),
    (dict(dropout=NAN), "dropout"),
])
def test_simulate_rejects_bad_numbers(tmp_path, kw, match):
    with pytest.raises(ConfigError, match=match):
        simulate("office", **{"duration_s": 1.0, **kw}, out_dir=tmp_path / "sim")
    assert not (tmp_path / "sim").exists()


@pytest.mark.parametrize("kw, match", [
    (dict(axle=0.0), "axle"), (dict(speed=NAN), "speed"), (dict(beams=0), "beams"),
    (dict(scan_latency=INF), "scan_latency"), (dict(wheel_scale=0.0), "wheel_scale"), (dict(fov_deg=NAN), "fov_deg"),
])
def test_simulate_wheeled_rejects_bad_numbers(kw, match):
    with pytest.raises(ConfigError, match=match):
        simulate_wheeled(duration_s=1.0, **kw)


@pytest.mark.parametrize("axle", [0.0, -1.0, NAN, INF])
def test_calibrate_axle_must_be_positive(axle):
    with pytest.raises(ConfigError, match="axle must be a finite distance in metres > 0"):
        calibrate([], axle=axle)
    with pytest.raises(CalibrationError, match="two scans"):  # a good axle gets to the next check
        calibrate([], axle=0.33)


def _line(n=50):
    t = np.arange(n, dtype=float)
    return t, np.column_stack([t * 0.1, np.zeros(n), np.zeros(n)])


@pytest.mark.parametrize("delta", [0, -1, 2.5, True])
def test_rpe_delta_must_be_a_positive_integer(delta):
    t, p = _line()
    with pytest.raises(ConfigError, match="rpe_delta must be an integer >= 1"):
        trajectory_errors(t, p, t, p, rpe_delta=delta)
    assert trajectory_errors(t, p, t, p, rpe_delta=1).rpe_delta == 1


@pytest.mark.parametrize("max_dt", [0.0, -0.1, INF, NAN])
def test_max_dt_must_be_finite_and_positive(max_dt):
    t, p = _line()
    with pytest.raises(ConfigError, match="max_dt must be a finite number of seconds > 0"):
        trajectory_errors(t, p, t, p, max_dt=max_dt)
    with pytest.raises(ConfigError, match="max_dt"):
        associate(t, t, max_dt)
    with pytest.raises(ConfigError, match="max_dt"):
        relation_errors(t, p, np.array([[1.0, 2.0, 0.1, 0.0, 0.0]]), max_dt=max_dt)


def test_relation_time_offset_must_be_finite():
    t, p = _line()
    with pytest.raises(ConfigError, match="time_offset"):
        relation_errors(t, p, np.array([[1.0, 2.0, 0.1, 0.0, 0.0]]), time_offset=INF)


# -- TUM files ----------------------------------------------------------------------------------


def _tum(tmp_path, *rows):
    f = tmp_path / "t.tum"
    f.write_text("# timestamp tx ty tz qx qy qz qw\n" + "".join(r + "\n" for r in rows))
    return f


@pytest.mark.parametrize("rows, match", [
    (("1 0 0 0 0 0 0 1", "2 1 0 0 0 0 0 0"), "line 3: the quaternion .* is zero"),
    (("1 0 0 0 0 0 0 1", "2 1e308 0 0 0 0 0 1"), "line 3: position out of range"),
    (("1 0 0 0 0 0 0 1", "2 0 -2e9 0 0 0 0 1"), "line 3: position out of range"),
    (("1e308 0 0 0 0 0 0 1",), "line 2: time stamp 1e308 is out of range"),
    (("5 0 0 0 0 0 0 1", "6 1 0 0 0 0 0 1", "4.5 2 0 0 0 0 0 1"), "line 4: time stamp goes back 1.500 s"),
])
def test_tum_rejects_bad_poses_and_times(tmp_path, rows, match):
    with pytest.raises(InputError, match=match):
        read_tum(_tum(tmp_path, *rows))


def test_tum_repeated_time_stamps_read_back(tmp_path):
    """A log with repeated scan times gives such a trajectory; it must read back as written."""
    from pfslam.io.trajectory import write_tum

    t_in = np.array([1.0, 2.0, 2.0, 3.0])
    p_in = np.column_stack([np.arange(4.0), np.zeros(4), np.array([0.0, 0.1, 0.2, 0.3])])
    write_tum(tmp_path / "r.tum", t_in, p_in)
    t, p = read_tum(tmp_path / "r.tum")
    np.testing.assert_array_equal(t, t_in)
    np.testing.assert_allclose(p, p_in, atol=1e-9)


def test_tum_small_steps_back_are_sorted(tmp_path):
    t, p = read_tum(_tum(tmp_path, "5 0 0 0 0 0 0 1", "6 1 0 0 0 0 0 1", "5.5 2 0 0 0 0 0 1"))
    np.testing.assert_array_equal(t, [5.0, 5.5, 6.0])
    np.testing.assert_array_equal(p[:, 0], [0.0, 2.0, 1.0])


def test_tum_quaternions_need_not_be_normalised(tmp_path):
    s, c = math.sin(0.3), math.cos(0.3)  # yaw 0.6
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow warnings from huge quaternions
        t, p = read_tum(_tum(tmp_path, f"1 0 0 0 0 0 {s} {c}", f"2 0 0 0 0 0 {5 * s} {5 * c}",
                             f"3 0 0 0 0 0 {1e300 * s} {1e300 * c}", f"4 0 0 0 0 0 {1e-300 * s} {1e-300 * c}"))
    np.testing.assert_allclose(p[:, 2], 0.6, atol=1e-12)
