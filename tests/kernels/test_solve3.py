"""The kernels' 3 x 3 solve (pfslam.kernels.solve3) against NumPy's."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pfslam.kernels.solve3 import solve3


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), scale=st.sampled_from([1e-6, 1.0, 1e6]))
def test_it_solves_as_numpy_does_on_damped_normal_equations(seed, scale):
    rng = np.random.default_rng(seed)
    j = rng.normal(size=(20, 3)) * [1.0, 1.0, 10.0]
    a = scale * (j.T @ j + 1e-3 * np.eye(3))  # (the shape of the Gauss-Newton steps' systems)
    b = rng.normal(size=3) * scale
    np.testing.assert_allclose(solve3(a, b), np.linalg.solve(a, b), rtol=1e-8, atol=1e-12)


def test_a_general_system_too():
    a = np.array([[0.0, 2.0, 1.0], [1.0, 0.0, 3.0], [4.0, -1.0, 0.0]])
    b = np.array([1.0, 2.0, 3.0])
    np.testing.assert_allclose(a @ solve3(a, b), b, atol=1e-12)
