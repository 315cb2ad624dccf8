import pytest

from pfslam.config import SlamConfig, dump_config, load_config
from pfslam.errors import ConfigError, InputError


def test_roundtrip(tmp_path):
    c = SlamConfig(particles=7)
    c.search.radius_cells = 2
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


def test_validate():
    with pytest.raises(ConfigError):
        SlamConfig(resample_method="nope").validate()
