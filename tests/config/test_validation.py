"""Bad configuration values give one clear error naming the key, not a traceback: at
construction (configs are frozen and validated in ``__post_init__``), through
:func:`~pfslam.config.with_values`, and in a file (an InputError naming the file too)."""

import dataclasses

import pytest

from pfslam.config import CalibrationConfig, LocalizerConfig, MapConfig, SlamConfig, load_config, with_values
from pfslam.errors import ConfigError, InputError
from pfslam.tools.simulate import simulate
from pfslam.tools.wheeled import simulate_wheeled

NAN, INF = float("nan"), float("inf")


def _load(tmp_path, text):
    f = tmp_path / "c.yaml"
    f.write_text(text)
    return load_config(f)


def _built(cls, key, value):
    """``cls()`` with ``key`` (dotted for a section) set to ``value`` by construction, with
    no conversion on the way (dataclasses.replace runs the validation again)."""
    *section, name = key.split(".")
    if not section:
        return dataclasses.replace(cls(), **{name: value})
    base = cls()
    sub = getattr(base, section[0])
    # The section alone is a plain record; the whole config checks it.
    return dataclasses.replace(base, **{section[0]: dataclasses.replace(sub, **{name: value})})


# -- seeds ----------------------------------------------------------------------------------


def test_negative_seed_is_a_config_error_everywhere(tmp_path):
    with pytest.raises(ConfigError, match="seed must be a non-negative integer, not -1"):
        SlamConfig(seed=-1)
    with pytest.raises(InputError, match="c.yaml: seed must be a non-negative integer, not -1"):
        _load(tmp_path, "seed: -1\n")
    with pytest.raises(ConfigError, match="seed must be a non-negative integer"):
        LocalizerConfig(seed=-1)
    with pytest.raises(ConfigError, match="seed must be a non-negative integer, not -1"):
        with_values(LocalizerConfig(), {"seed": -1})
    with pytest.raises(ConfigError, match="seed must be a non-negative integer"):
        simulate("office", 1.0, seed=-1, out_dir=tmp_path / "sim")
    assert not (tmp_path / "sim").exists()  # rejected before anything is written
    with pytest.raises(ConfigError, match="seed"):
        simulate_wheeled(duration_s=1.0, seed=-1)


# -- reading YAML -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, match",
    [
        ("particles: .inf\n", "particles must be an integer, not inf"),
        ("particles: true\n", "particles must be an integer, not True"),
        ("particles: 10.7\n", "particles must be an integer, not 10.7"),
        ("particles: '100'\n", "particles must be an integer"),
        ('local_search:\n  enabled: "no"\n', "local_search.enabled must be true or false, not 'no'"),
        ("local_search:\n  enabled: 1\n", "local_search.enabled must be true or false, not 1"),
        ("map:\n  resolution: true\n", "map.resolution must be a finite number, not True"),
        ("map:\n  resolution: '0.05'\n", "map.resolution must be a finite number"),
        ("map:\n  resolution: .nan\n", "map.resolution must be a finite number, not nan"),
        ("estimate: 5\n", "estimate must be one of 'mean', 'best', not 5"),
        ("resample_method: nope\n", "resample_method must be one of 'systematic', .*'residual', not 'nope'"),
        ("sensor:\n  scoring_map: sharp\n", "sensor.scoring_map must be one of 'cells', 'field', 'auto', not 'sharp'"),
        ("search:\n  enabled: true\n", r"unknown config key 'search' \(renamed to 'local_search'\)"),
        ("sensor:\n  score: cells\n", r"unknown config key 'sensor.score' \(renamed to 'sensor.scoring_map'\)"),
        ("map: 5\n", "section 'map' must be a mapping"),
        ("- 1\n- 2\n", "config must be a mapping"),
        ("map:\n  resolution: " + "9" * 400 + "\n", "map.resolution: .* is out of range"),
    ],
)
def test_yaml_values_are_converted_strictly(tmp_path, text, match):
    with pytest.raises(InputError, match=match) as info:
        _load(tmp_path, text)
    assert info.value.path.endswith("c.yaml")


def test_yaml_conversions_that_lose_nothing_are_kept(tmp_path):
    c = _load(
        tmp_path, "particles: 100.0\nmap:\n  resolution: 1e-2\n  initial_size: 30\nlocal_search:\n  enabled: yes\n"
    )
    assert c.particles == 100 and type(c.particles) is int
    assert c.map.resolution == 0.01 and type(c.map.resolution) is float
    assert c.map.initial_size == 30.0 and type(c.map.initial_size) is float
    assert c.local_search.enabled is True
    assert dataclasses.replace(c) == c  # built again (and validated again), the same config


def test_non_utf8_config_names_the_file(tmp_path):
    f = tmp_path / "bad.yaml"
    f.write_bytes(b"particles: 10\n\xff\xfe garbage\n")
    with pytest.raises(InputError, match=r"bad\.yaml: not UTF-8 text \(byte 0xff"):
        load_config(f)


def test_config_folder_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="is a folder"):
        load_config(tmp_path)


# -- ranges -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "key, value, match",
    [
        ("particles", -1, "particles must be an integer in 0..10000000, not -1"),
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
        ("local_search.enabled", "no", "local_search.enabled must be true or false, not 'no'"),
        ("local_search.radius_cells", 1000, r"local_search.radius_cells must be an integer in 0..20, not 1000"),
        ("local_search.radius_cells", -3, "local_search.radius_cells"),
        ("local_search.theta_steps", 100000, r"local_search.theta_steps must be an integer in 0..45"),
        ("local_search.theta_step_deg", 0.0, "local_search.theta_step_deg must be a finite number > 0"),
        ("estimate", "median", "estimate must be one of 'mean', 'best', not 'median'"),
    ],
)
@pytest.mark.parametrize("how", ["constructed", "with_values"])
def test_slam_config_ranges(key, value, match, how):
    with pytest.raises(ConfigError, match=match):
        if how == "constructed":
            _built(SlamConfig, key, value)
        else:
            with_values(SlamConfig(), {key: value})


def test_slam_config_limits_themselves_are_valid():
    limits = {
        "resample_threshold": 1.0,
        "map.resolution": 0.001,
        "local_search.radius_cells": 20,
        "local_search.theta_steps": 45,
        "motion.sigma_x": 0.0,
    }
    cfg = with_values(SlamConfig(), limits)
    assert (cfg.resample_threshold, cfg.map.resolution, cfg.motion.sigma_x) == (1.0, 0.001, 0.0)
    assert (cfg.local_search.radius_cells, cfg.local_search.theta_steps) == (20, 45)
    built = SlamConfig(
        resample_threshold=1.0,
        map=MapConfig(resolution=0.001),
        local_search=dataclasses.replace(SlamConfig().local_search, radius_cells=20, theta_steps=45),
        motion=dataclasses.replace(SlamConfig().motion, sigma_x=0.0),
    )
    assert built == cfg


@pytest.mark.parametrize(
    "kw, match",
    [
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
        (dict(model="sonar"), "model must be one of 'likelihood_field', 'beam', not 'sonar'"),
        (dict(beams=0), "beams"),
    ],
)
def test_localizer_config_ranges(kw, match):
    with pytest.raises(ConfigError, match=match):
        LocalizerConfig(**kw)
    with pytest.raises(ConfigError, match=match):
        with_values(LocalizerConfig(), kw)


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(laser_max_range=0.0), "laser_max_range must be a distance in metres > 0, or -1"),
        (
            dict(laser_min_range=2.0, laser_max_range=1.5),
            r"laser_min_range \(2\) must be below laser_max_range \(1.5\)",
        ),
        (dict(laser_max_range=INF), "laser_max_range must be a finite number"),
        (dict(initial_std_theta=-0.1), "initial_std_theta must be a finite number >= 0"),
        (dict(initial_std_x=NAN), "initial_std_x"),
        (dict(update_min_a=-0.1), "update_min_a must be an angle in radians >= 0"),
        (dict(kld_bin_a=0.0), "kld_bin_a must be an angle in radians > 0"),
    ],
)
def test_localizer_laser_window_and_start_spread_ranges(kw, match):
    with pytest.raises(ConfigError, match=match):
        LocalizerConfig(**kw)
    with pytest.raises(ConfigError, match=match):
        with_values(LocalizerConfig(), kw)


def test_localizer_laser_window_limits_themselves_are_valid():
    c = LocalizerConfig(laser_min_range=0.0, laser_max_range=0.01, initial_std_x=0.0, update_min_a=0.0)
    assert (c.laser_min_range, c.laser_max_range, c.initial_std_x) == (0.0, 0.01, 0.0)
    assert LocalizerConfig(laser_min_range=5.0).laser_min_range == 5.0  # the maximum stays the sensor's


# -- declared bounds --------------------------------------------------------------------------


def _numeric_fields(cfg, where=""):
    """(dotted key, field) of every int or float field of ``cfg`` and of its sections."""
    for f in dataclasses.fields(cfg):
        value = getattr(cfg, f.name)
        if dataclasses.is_dataclass(value):
            yield from _numeric_fields(value, f"{where}{f.name}.")
        elif type(value) in (int, float):
            yield f"{where}{f.name}", f


# Numeric fields with no bound of their own (a height, a threshold; the laser ranges'
# sign convention and order are checked across fields in LocalizerConfig.__post_init__).
UNBOUNDED = {
    SlamConfig: {"sensor.ground_z", "sensor.field_threshold"},
    LocalizerConfig: {"laser_min_range", "laser_max_range", "ground_z"},
    CalibrationConfig: set(),
}


@pytest.mark.parametrize("cls", list(UNBOUNDED))
def test_every_numeric_field_declares_its_bounds(cls):
    unbounded = {key for key, f in _numeric_fields(cls()) if "bounds" not in f.metadata}
    assert unbounded == UNBOUNDED[cls]


def test_bounds_are_checked_in_field_order_with_the_section_named():
    cfg = SlamConfig()
    # map comes before graph: its error is the one reported
    with pytest.raises(ConfigError, match=r"^map.resolution must be a finite number >= 0.001, not 0$"):
        SlamConfig(map=MapConfig(resolution=0), graph=dataclasses.replace(cfg.graph, passes=0))
    assert MapConfig(resolution=0).resolution == 0  # a section alone is a plain record


def test_bounds_let_a_special_value_through_and_keep_older_messages():
    rbpf = SlamConfig().rbpf
    assert SlamConfig(rbpf=dataclasses.replace(rbpf, match_prior=-1.0)).rbpf.match_prior == -1.0
    with pytest.raises(ConfigError, match=r"^rbpf.match_prior must be -1 \(per log kind\) or a number >= 0 and <= 100"):
        SlamConfig(rbpf=dataclasses.replace(rbpf, match_prior=-0.5))
    with pytest.raises(ConfigError, match=r"^kld_err must be in \(0, 1\) and kld_z in \(0.5, 1\)$"):
        LocalizerConfig(kld_z=0.5)
    with pytest.raises(ConfigError, match=r"^need 0 < recovery_alpha_slow < recovery_alpha_fast <= 1$"):
        LocalizerConfig(recovery_alpha_slow=0.2, recovery_alpha_fast=0.1)  # across fields
