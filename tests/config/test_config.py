"""pfslam.config: frozen configurations, modes as Enums, with_values, files with one
configuration or several sections, dump and load."""

import dataclasses

import pytest
import yaml

from pfslam.config import (
    SECTIONS,
    CalibrationConfig,
    LocalizerConfig,
    PoseEstimate,
    ResampleMethod,
    ScoringMap,
    SensorModel,
    SlamConfig,
    dump_config,
    dump_sections,
    from_dict,
    load_config,
    to_dict,
    with_values,
)
from pfslam.errors import ConfigError, InputError


def test_roundtrip(tmp_path):
    c = with_values(SlamConfig(particles=7), {"local_search.radius_cells": 3, "sensor.scoring_map": "cells"})
    assert c.local_search.radius_cells == 3 and c != SlamConfig(particles=7)
    f = tmp_path / "c.yaml"
    f.write_text(dump_config(c))
    d = load_config(f)
    assert d == c


def test_unknown_key_names_file(tmp_path):
    f = tmp_path / "c.yaml"
    f.write_text("sensor:\n  temprature: 3\n")
    with pytest.raises(InputError, match="sensor.temprature"):
        load_config(f)


def test_bad_type(tmp_path):
    f = tmp_path / "c.yaml"
    f.write_text("particles: many\n")
    with pytest.raises(InputError, match="particles"):
        load_config(f)


def test_a_bad_mode_is_refused_when_the_config_is_built():
    with pytest.raises(
        ConfigError,
        match="resample_method must be one of 'systematic', 'stratified', 'multinomial', 'residual', not 'nope'",
    ):
        SlamConfig(resample_method="nope")


# -- frozen, with_values -----------------------------------------------------------------------


@pytest.mark.parametrize("cls", [SlamConfig, LocalizerConfig, CalibrationConfig])
def test_a_config_cannot_be_assigned_to(cls):
    c = cls()
    first = dataclasses.fields(c)[0].name
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(c, first, 5)
    assert c == cls()


def test_the_sections_of_a_slam_config_are_frozen_too():
    c = SlamConfig()
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.map.resolution = 0.1  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.local_search.enabled = True  # type: ignore[misc]
    assert c == SlamConfig()


def test_with_values_makes_a_changed_copy():
    base = SlamConfig()
    c = with_values(base, {"local_search.enabled": True, "particles": 5, "map.resolution": 0.1})
    assert c.local_search.enabled is True and c.particles == 5 and c.map.resolution == 0.1
    assert base == SlamConfig()  # the original is untouched
    assert c.local_search.radius_cells == base.local_search.radius_cells and c.seed == base.seed
    assert with_values(base, {}) == base
    loc = with_values(LocalizerConfig(), {"beams": 30, "seed": 4})
    assert (loc.beams, loc.seed) == (30, 4) and isinstance(loc, LocalizerConfig)


@pytest.mark.parametrize("key", ["bogus", "map.bogus", "bogus.enabled", "map", "particles.x", "local_search"])
def test_with_values_rejects_unknown_keys_naming_them(key):
    with pytest.raises(ConfigError, match=f"unknown config key '{key}'"):
        with_values(SlamConfig(), {key: 1})


@pytest.mark.parametrize(
    "key, value, match",
    [
        ("particles", "many", "particles must be an integer, not 'many'"),
        ("particles", -1, "particles must be an integer in 0..10000000, not -1"),
        ("map.resolution", "fine", "map.resolution must be a finite number, not 'fine'"),
        ("local_search.enabled", "yes", "local_search.enabled must be true or false, not 'yes'"),
        ("sensor.scoring_map", "sharp", "sensor.scoring_map must be one of 'cells', 'field', 'auto', not 'sharp'"),
    ],
)
def test_with_values_rejects_bad_values_naming_the_key(key, value, match):
    with pytest.raises(ConfigError, match=match):
        with_values(SlamConfig(), {key: value})


@pytest.mark.parametrize(
    "data, old, new",
    [
        ({"sensor": {"score": "cells"}}, "sensor.score", "sensor.scoring_map"),
        ({"search": {"enabled": True}}, "search", "local_search"),
    ],
)
def test_an_old_key_gets_its_new_name(data, old, new):
    with pytest.raises(ConfigError, match=rf"unknown config key '{old}' \(renamed to '{new}'\)"):
        from_dict(SlamConfig, data)
    # with_values names the unknown key (without the hint: its keys come from code, not files).
    key = f"{old}.enabled" if old == "search" else old
    with pytest.raises(ConfigError, match=rf"unknown config key '{key}'"):
        with_values(SlamConfig(), {key: "cells"})


def test_an_old_key_in_a_file_names_the_file_and_the_new_key(tmp_path):
    f = tmp_path / "old.yaml"
    f.write_text("sensor:\n  score: cells\n")
    want = r"old.yaml: unknown config key 'sensor.score' \(renamed to 'sensor.scoring_map'\)"
    with pytest.raises(InputError, match=want):
        load_config(f)


# -- modes -------------------------------------------------------------------------------------


def test_a_string_mode_is_coerced_to_its_enum():
    c = SlamConfig(resample_method="stratified", estimate="best")
    assert c.resample_method is ResampleMethod.STRATIFIED and c.estimate is PoseEstimate.BEST
    assert c.resample_method == "stratified"  # still equal to the string files hold
    s = with_values(SlamConfig(), {"sensor.scoring_map": "field"})
    assert s.sensor.scoring_map is ScoringMap.FIELD
    loc = LocalizerConfig(model="beam")
    assert loc.model is SensorModel.BEAM and type(loc.model) is SensorModel
    assert with_values(LocalizerConfig(), {"model": SensorModel.BEAM}).model is SensorModel.BEAM
    # Dumped as the plain string, read back as the Enum.
    assert to_dict(c)["resample_method"] == "stratified" and type(to_dict(c)["resample_method"]) is str
    assert "resample_method: stratified" in dump_config(c)


# -- files with sections -------------------------------------------------------------------------


def test_localizer_config_round_trips_through_yaml():
    cfg = LocalizerConfig(particles=300, resample_method="stratified")
    back = from_dict(LocalizerConfig, yaml.safe_load(yaml.safe_dump(to_dict(cfg))))
    assert back == cfg and back.resample_method is ResampleMethod.STRATIFIED
    for bad in (
        dict(min_particles=600, max_particles=500),
        dict(resample_method="magic"),
        dict(beam_temperature=0),
        dict(recovery_alpha_slow=0.2, recovery_alpha_fast=0.1),
        dict(kld_err=0.0),
        dict(alpha3=-0.1),
    ):
        with pytest.raises(ConfigError):
            LocalizerConfig(**bad)
        with pytest.raises(ConfigError):
            from_dict(LocalizerConfig, {**to_dict(cfg), **bad})


def test_each_config_reads_its_own_section_of_a_sectioned_file(tmp_path):
    slam = SlamConfig(particles=7)
    loc = LocalizerConfig(beams=30, seed=4)
    cal = CalibrationConfig(gap=2)
    f = tmp_path / "all.yaml"
    f.write_text(dump_sections(slam, loc, cal))
    assert list(yaml.safe_load(f.read_text())) == ["slam", "localize", "calibrate"]
    assert load_config(f, SlamConfig) == slam
    assert load_config(f, LocalizerConfig) == loc
    assert load_config(f, CalibrationConfig) == cal
    # A section the file does not have: the defaults.
    f.write_text(dump_sections(slam))
    assert load_config(f, LocalizerConfig) == LocalizerConfig()
    assert load_config(f, CalibrationConfig, section_only=True) == CalibrationConfig()


def test_a_flat_file_is_one_config_and_section_only_ignores_it(tmp_path):
    f = tmp_path / "flat.yaml"
    f.write_text("beams: 30\nseed: 4\n")
    assert load_config(f, LocalizerConfig) == LocalizerConfig(beams=30, seed=4)
    f.write_text("gap: 2\n")
    assert load_config(f, CalibrationConfig) == CalibrationConfig(gap=2)
    assert load_config(f, CalibrationConfig, section_only=True) == CalibrationConfig()


def test_a_bad_value_in_a_section_names_the_file_and_the_section(tmp_path):
    f = tmp_path / "s.yaml"
    f.write_text("localize:\n  beams: 0\n")
    with pytest.raises(InputError, match="s.yaml: .*beams") as e:
        load_config(f, LocalizerConfig)
    assert e.value.path.endswith("s.yaml")
    f.write_text("slam:\n  map:\n    resolution: fine\n")
    with pytest.raises(InputError, match="slam.map.resolution must be a finite number, not 'fine'"):
        load_config(f, SlamConfig)
    f.write_text("localize:\n  model: foo\n")
    with pytest.raises(InputError, match="localize.model must be one of 'likelihood_field', 'beam', not 'foo'"):
        load_config(f, LocalizerConfig)


def test_dump_sections_and_from_dict_round_trip_every_default():
    data = yaml.safe_load(dump_sections(*(cls() for cls in SECTIONS.values())))
    assert list(data) == list(SECTIONS) == ["slam", "localize", "calibrate"]
    for name, cls in SECTIONS.items():
        assert from_dict(cls, data[name]) == cls()
        assert from_dict(cls, yaml.safe_load(dump_config(cls()))) == cls()


# -- the localizer's angles: radians in files, older degree keys converted ---------------------


def test_localizer_angles_are_radians_and_older_degree_keys_are_converted(tmp_path):
    import math

    cfg = LocalizerConfig()
    assert cfg.update_min_a == pytest.approx(math.radians(3.0)) and cfg.kld_bin_a == pytest.approx(math.radians(10.0))
    assert cfg.initial_std == (0.1, 0.1, pytest.approx(math.radians(5.0)))
    f = tmp_path / "old.yaml"
    for text in (
        "localize:\n  update_min_a_deg: 30\n  kld_bin_deg: 20.0\n",
        "update_min_a_deg: 30\nkld_bin_deg: 20.0\n",
    ):
        f.write_text(text)
        old = load_config(f, LocalizerConfig)
        assert old.update_min_a == pytest.approx(math.pi / 6) and old.kld_bin_a == pytest.approx(math.pi / 9)
        # Saved again, it holds the radian keys only and reads back the same.
        f.write_text(dump_sections(old))
        saved = yaml.safe_load(f.read_text())["localize"]
        assert saved["update_min_a"] == pytest.approx(0.5236, abs=1e-4) and not any("_deg" in k for k in saved)
        assert load_config(f, LocalizerConfig) == old
    f.write_text("localize:\n  update_min_a: 0.5\n")
    assert load_config(f, LocalizerConfig).update_min_a == 0.5  # as given: radians


@pytest.mark.parametrize(
    "text, match",
    [
        (
            "localize:\n  update_min_a_deg: 30\n  update_min_a: 0.5\n",
            r"localize.update_min_a_deg \(degrees\) and localize.update_min_a \(radians\) are the same setting",
        ),
        ("kld_bin_deg: wide\n", "kld_bin_deg must be a finite number, not 'wide'"),
        (
            "localize:\n  update_min_a_deg: -3\n",
            "localize.update_min_a_deg must be a finite number of degrees >= 0, not -3",
        ),
    ],
)
def test_older_degree_keys_are_checked_naming_the_key(tmp_path, text, match):
    f = tmp_path / "old.yaml"
    f.write_text(text)
    with pytest.raises(InputError, match=match):
        load_config(f, LocalizerConfig)


def test_dump_of_the_localizer_names_units_and_amcl_settings():
    text = dump_config(LocalizerConfig())
    lines = {ln.split(":")[0]: ln for ln in text.splitlines()}
    want = {
        "beams": "AMCL laser_max_beams",
        "laser_min_range": "AMCL laser_min_range",
        "laser_max_range": "AMCL laser_max_range",
        "z_hit": "AMCL laser_z_hit",
        "z_rand": "AMCL laser_z_rand",
        "sigma_hit": "AMCL laser_sigma_hit",
        "max_dist": "AMCL laser_likelihood_max_dist",
        "update_min_d": "AMCL update_min_d",
        "update_min_a": "rad",
        "kld_bin_a": "rad",
        "recovery_alpha_slow": "AMCL recovery_alpha_slow",
        "recovery_alpha_fast": "AMCL recovery_alpha_fast",
        "kld_err": "AMCL kld_err",
        "kld_z": "AMCL kld_z",
        "min_particles": "AMCL min_particles",
        "max_particles": "AMCL max_particles",
        "initial_std_x": "initial_cov_xx",
        "initial_std_theta": "initial_cov_aa",
    }
    for key, words in want.items():
        assert "#" in lines[key] and words in lines[key].split("#", 1)[1], lines[key]
    assert all("#" in ln for ln in text.splitlines())  # every localize key has its note
    # Under sections the same notes, and the comments change nothing that is read.
    both = dump_sections(SlamConfig(), LocalizerConfig())
    assert "  beams: 60" in both and "laser_max_beams" in both
    assert yaml.safe_load(both) == {"slam": to_dict(SlamConfig()), "localize": to_dict(LocalizerConfig())}


def test_dump_of_the_slam_config_notes_the_per_log_kind_settings_also_in_its_sub_sections():
    for text, indent in ((dump_config(SlamConfig()), ""), (dump_sections(SlamConfig()), "  ")):
        lines = text.splitlines()
        prior = [ln for ln in lines if ln.startswith(f"{indent}  match_prior:")]
        assert len(prior) == 1 and "per log kind" in prior[0].split("#", 1)[1]
        filt = [ln for ln in lines if ln.startswith(f"{indent}filter:")]
        assert len(filt) == 1 and "rbpf" in filt[0].split("#", 1)[1]
        # One particle count, noted as per filter; a sub-section's key of a noted name gets no note.
        count = [ln for ln in lines if ln.strip().startswith("particles:")]
        assert len(count) == 1 and "per filter" in count[0].split("#", 1)[1]
        assert all("#" not in ln for ln in lines if ln.strip().startswith("temperature:"))
        assert yaml.safe_load(text) in (to_dict(SlamConfig()), {"slam": to_dict(SlamConfig())})
