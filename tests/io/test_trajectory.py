"""TUM trajectory files: round trip, bad lines, bad poses and times."""

import math
import warnings

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


def _tum(tmp_path, *rows):
    f = tmp_path / "t.tum"
    f.write_text("# timestamp tx ty tz qx qy qz qw\n" + "".join(r + "\n" for r in rows))
    return f


@pytest.mark.parametrize(
    "rows, match",
    [
        (("1 0 0 0 0 0 0 1", "2 1 0 0 0 0 0 0"), "line 3: the quaternion .* is zero"),
        (("1 0 0 0 0 0 0 1", "2 1e308 0 0 0 0 0 1"), "line 3: position out of range"),
        (("1 0 0 0 0 0 0 1", "2 0 -2e9 0 0 0 0 1"), "line 3: position out of range"),
        (("1e308 0 0 0 0 0 0 1",), "line 2: time stamp 1e308 is out of range"),
        (("5 0 0 0 0 0 0 1", "6 1 0 0 0 0 0 1", "4.5 2 0 0 0 0 0 1"), "line 4: time stamp goes back 1.500 s"),
    ],
)
def test_tum_rejects_bad_poses_and_times(tmp_path, rows, match):
    with pytest.raises(InputError, match=match):
        read_tum(_tum(tmp_path, *rows))


def test_tum_repeated_time_stamps_read_back(tmp_path):
    """A log with repeated scan times gives such a trajectory; it must read back as written."""
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
        t, p = read_tum(
            _tum(
                tmp_path,
                f"1 0 0 0 0 0 {s} {c}",
                f"2 0 0 0 0 0 {5 * s} {5 * c}",
                f"3 0 0 0 0 0 {1e300 * s} {1e300 * c}",
                f"4 0 0 0 0 0 {1e-300 * s} {1e-300 * c}",
            )
        )
    np.testing.assert_allclose(p[:, 2], 0.6, atol=1e-12)
