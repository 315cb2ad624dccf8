import numpy as np
import pytest

from pfslam.errors import InputError
from pfslam.io.trajectory import read_tum, write_tum


def test_tum_roundtrip(tmp_path):
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.01, 0.1, 50)) + 1.4e9
    poses = np.column_stack([rng.normal(size=50), rng.normal(size=50), rng.uniform(-3.1, 3.1, 50)])
    write_tum(tmp_path / "a.tum", t, poses)
    t2, p2 = read_tum(tmp_path / "a.tum")
    assert np.allclose(t2, t, atol=1e-8)
    assert np.allclose(p2, poses, atol=1e-8)


def test_tum_bad_line(tmp_path):
    f = tmp_path / "b.tum"
    f.write_text("0 1 2 3\n")
    with pytest.raises(InputError, match="line 1"):
        read_tum(f)
