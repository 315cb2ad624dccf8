"""Frames kept by column (pfslam.frames.Frames) behave as the list of Frame objects they
stand for: indexing, slicing, iteration, replacing a column; the helpers read columns of
either kind without reading ranges."""

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pfslam.frames import Frame, Frames, frame_column, frame_times, with_column


def _both(n=12, k=5, shared_mount=False):
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.01, 0.1, n))
    ranges = rng.uniform(0.5, 9, (n, k)).astype(np.float32)
    angles = np.linspace(-1, 1, k)
    odom = rng.normal(size=(n, 3))
    mounts = np.eye(4) if shared_mount else np.tile(np.eye(4), (n, 1, 1)) + rng.normal(0, 0.01, (n, 4, 4))
    cols = Frames(t, ranges, angles, odom=odom, mounts=mounts, min_range=0.2, max_range=8.0)
    listed = [
        Frame(
            t=float(t[i]),
            ranges=ranges[i],
            angles=angles,
            odom=odom[i],
            mount=mounts if shared_mount else mounts[i],
            min_range=0.2,
            max_range=8.0,
        )
        for i in range(n)
    ]
    return cols, listed


def _same(a: Frame, b: Frame) -> bool:
    return (
        a.t == b.t
        and np.array_equal(a.ranges, b.ranges)
        and np.array_equal(a.angles, b.angles)
        and np.array_equal(a.odom, b.odom)
        and a.wheels is None
        and b.wheels is None
        and np.array_equal(a.mount, b.mount)
        and a.min_range == b.min_range
        and a.max_range == b.max_range
    )


@settings(max_examples=60, deadline=None)
@given(
    start=st.none() | st.integers(-15, 15),
    stop=st.none() | st.integers(-15, 15),
    step=st.none() | st.integers(1, 4),
    shared=st.booleans(),
)
def test_slices_of_frames_are_slices_of_the_list(start, stop, step, shared):
    cols, listed = _both(shared_mount=shared)
    part, want = cols[start:stop:step], listed[start:stop:step]
    assert isinstance(part, Frames) and len(part) == len(want)
    assert all(_same(a, b) for a, b in zip(part, want))
    if len(want):  # a slice of a slice
        assert all(_same(a, b) for a, b in zip(part[::2], want[::2]))
        assert _same(part[-1], want[-1])
    np.testing.assert_array_equal(frame_times(part), [f.t for f in want])


def test_indexing_iteration_and_bounds():
    cols, listed = _both()
    assert len(cols) == len(listed)
    assert all(_same(cols[i], listed[i]) for i in range(-len(listed), len(listed)))
    assert all(_same(a, b) for a, b in zip(cols, listed))
    with pytest.raises(IndexError):
        cols[len(listed)]
    with pytest.raises(IndexError):
        cols[-len(listed) - 1]


def test_a_replaced_column_leaves_the_original_alone():
    cols, listed = _both()
    new = np.arange(len(listed) * 3, dtype=float).reshape(-1, 3)
    changed = with_column(cols[2:], "odom", new[2:])
    assert [list(f.odom) for f in changed] == new[2:].tolist()
    assert _same(cols[3], listed[3])  # untouched
    changed_list = with_column(listed, "odom", new)
    assert all(_same(a, replace(b, odom=r)) for a, b, r in zip(changed_list, listed, new))
    with pytest.raises(ValueError, match="rows"):
        cols.with_column("odom", new[:3])
    with pytest.raises(ValueError, match="replaceable"):
        cols.with_column("t", new)


def test_columns_of_lists_and_frames_agree():
    for shared in (False, True):
        cols, listed = _both(shared_mount=shared)
        for name in ("odom", "wheels", "mount"):
            a, b = frame_column(cols, name), frame_column(listed, name)
            assert len(a) == len(b)
            assert all((x is None and y is None) or np.array_equal(x, y) for x, y in zip(a, b))
