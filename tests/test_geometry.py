import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from pfslam import geometry as g

coord = st.floats(-50, 50, allow_nan=False)
ang = st.floats(-10, 10, allow_nan=False)
pose = st.tuples(coord, coord, ang).map(np.array)


@given(pose, pose)
def test_compose_relative_roundtrip(a, b):
    u = g.relative(a, b)
    back = g.compose(a, u)
    assert np.allclose(back[:2], b[:2], atol=1e-9)
    assert abs(g.wrap_angle(back[2] - b[2])) < 1e-9


@given(pose)
def test_inverse(p):
    q = g.compose(p, g.inverse(p))
    assert np.allclose(q[:2], 0, atol=1e-8)
    assert abs(g.wrap_angle(q[2])) < 1e-9


def test_compose_known_values():
    p = np.array([1.0, 2.0, np.pi / 2])
    u = np.array([1.0, 0.0, 0.0])
    assert np.allclose(g.compose(p, u), [1.0, 3.0, np.pi / 2])


def test_vectorised_over_particles():
    ps = np.array([[0, 0, 0], [1, 1, np.pi]], dtype=float)
    out = g.compose(ps, np.array([1.0, 0, 0]))
    assert np.allclose(out[:, :2], [[1, 0], [0, 1]])


def test_circular_mean_across_pi():
    m = g.circular_mean(np.deg2rad([-179.0, 179.0]))
    assert abs(abs(m) - np.pi) < 1e-9


def test_wrap_range():
    a = g.wrap_angle(np.linspace(-20, 20, 1001))
    assert a.min() >= -np.pi and a.max() < np.pi


def test_se3_rotations_are_right_handed():
    # Rz(90deg) takes +x to +y, Ry(90deg) takes +z to +x, Rx(90deg) takes +y to +z.
    assert np.allclose(g.rz(np.pi / 2) @ [1, 0, 0, 1], [0, 1, 0, 1])
    assert np.allclose(g.ry(np.pi / 2) @ [0, 0, 1, 1], [1, 0, 0, 1])
    assert np.allclose(g.rx(np.pi / 2) @ [0, 1, 0, 1], [0, 0, 1, 1])
