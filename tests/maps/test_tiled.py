"""Per-particle maps on shared copy-on-write tiles (pfslam.maps.tiled) against dense maps kept
the naive way: after any sequence of scans written into any particle's map, resamplings
and growth, every particle's map equals its dense copy, cell for cell (one map written at a
time, or all at once in parallel from each particle's pose); scores read from the
tiles equal the dense kernels' scores; resampling copies tables, not cells."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pfslam.geometry import transform_points
from pfslam.kernels.raycast import ray_update_numpy
from pfslam.kernels.scoring import correlation_kernel, correlation_numpy
from pfslam.maps.tiled import TiledMaps

RES = 0.1


class Dense:
    """The naive model: one full array per particle on a fixed, large grid."""

    def __init__(self, n, origin=(-20.0, -20.0), size=400):
        self.origin = np.array(origin)
        self.maps = [np.zeros((size, size), np.float32) for _ in range(n)]
        self.stamp = np.zeros((size, size), np.int32)
        self.scan = 0

    def update(self, i, sensor, ends, hit):
        self.scan += 1
        ray_update_numpy(
            self.maps[i],
            self.origin[0],
            self.origin[1],
            1 / RES,
            sensor[0],
            sensor[1],
            ends,
            hit,
            3.0,
            -1.0,
            120.0,
            self.stamp,
            self.scan,
        )

    def resample(self, parents):
        self.maps = [self.maps[p].copy() for p in parents]

    def window(self, i, tiled):
        """Particle i's dense map over the tiled maps' grid (zero beyond the model's grid,
        which holds every cell a scan reached)."""
        dr, dc = np.round((tiled.origin - self.origin)[::-1] / RES).astype(int)
        h, w = tiled.shape
        out = np.zeros((h, w), np.float32)
        m = self.maps[i]
        r0, c0 = max(dr, 0), max(dc, 0)
        r1, c1 = min(dr + h, m.shape[0]), min(dc + w, m.shape[1])
        if r1 > r0 and c1 > c0:
            out[r0 - dr : r1 - dr, c0 - dc : c1 - dc] = m[r0:r1, c0:c1]
        return out


def _scan(rng, centre, reach):
    k = int(rng.integers(1, 40))
    sensor = centre + rng.uniform(-1, 1, 2)
    ang = rng.uniform(-np.pi, np.pi, k)
    rng_ = rng.uniform(0.05, reach, k)
    ends = sensor + np.column_stack([np.cos(ang), np.sin(ang)]) * rng_[:, None]
    return sensor, ends, rng.random(k) < 0.8


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    n=st.integers(1, 5),
    steps=st.integers(1, 25),
    shift=st.sampled_from([2, 3, 5]),
    release=st.sampled_from([0, 1 << 40]),
)
def test_every_tiled_map_equals_its_dense_copy(seed, n, steps, shift, release):
    """... with the free tiles' pages handed back at every resampling (``release`` 0: tiles of
    64 B to 4 KB, so a page may hold tiles in use beside free ones) or never."""
    rng = np.random.default_rng(seed)
    tiled = TiledMaps(n, resolution=RES, tile_shift=shift, capacity=2, release_bytes=release)
    dense = Dense(n)
    centre = np.zeros(2)
    for _ in range(steps):
        op = rng.random()
        if op < 0.4:
            i = int(rng.integers(n))
            sensor, ends, hit = _scan(rng, centre, reach=float(rng.uniform(0.3, 6.0)))
            tiled.update(i, sensor, ends, hit)
            dense.update(i, sensor, ends, hit)
        elif op < 0.65:  # one scan (robot frame) into every map, each from its particle's pose, in parallel
            sensor, ends, hit = _scan(rng, np.zeros(2), reach=float(rng.uniform(0.3, 6.0)))
            poses = np.column_stack([centre + rng.normal(0, 0.3, (n, 2)), rng.uniform(-np.pi, np.pi, n)])
            tiled.update_all(poses, sensor, ends, hit)
            for i in range(n):
                dense.update(i, transform_points(poses[i], sensor[None])[0], transform_points(poses[i], ends), hit)
        elif op < 0.9:
            parents = rng.integers(0, n, n)
            tiled.resample(parents)
            dense.resample(parents)
        else:
            centre = np.clip(centre + rng.uniform(-5, 5, 2), -12, 12)  # wander off: the grid grows
        for i in range(n):
            np.testing.assert_array_equal(tiled.dense(i), dense.window(i, tiled))
        # Bookkeeping: the references are the table entries, the free stack the rest.
        used = tiled.tables[tiled.tables >= 0]
        np.testing.assert_array_equal(tiled.refs, np.bincount(used, minlength=len(tiled.pool)))
        assert tiled.unique_tiles == len(np.unique(used))
        assert set(tiled.free[: tiled.nfree[0]].tolist()) == set(np.nonzero(tiled.refs == 0)[0].tolist())


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 6))
def test_scores_on_tiles_equal_the_dense_kernels(seed, n):
    rng = np.random.default_rng(seed)
    tiled = TiledMaps(n, resolution=RES, tile_shift=3)
    for _ in range(3 * n):
        i = int(rng.integers(n))
        tiled.update(i, *_scan(rng, np.zeros(2), reach=4.0))
    poses = np.column_stack([rng.normal(0, 1.0, n), rng.normal(0, 1.0, n), rng.uniform(-np.pi, np.pi, n)])
    pts = rng.uniform(-5, 5, (50, 2))
    got = tiled.correlation(poses, pts, 1 / 10.0, -1.0)
    ox, oy = tiled.origin
    for i in range(n):
        d = tiled.dense(i)  # integer-valued log-odds: sums are exact in any order
        assert got[i] == correlation_kernel(poses[i : i + 1], pts, d, ox, oy, 1 / RES, 1 / 10.0, -1.0)[0]
        assert got[i] == pytest.approx(
            correlation_numpy(poses[i : i + 1], pts, d, ox, oy, 1 / RES, 1 / 10.0, -1.0)[0], abs=1e-9
        )


def test_a_burst_of_copies_is_handed_back_after_resampling_and_the_maps_read_the_same():
    rng = np.random.default_rng(3)
    n = 8
    tiled = TiledMaps(n, resolution=RES, tile_shift=5, release_bytes=1 << 20)
    dense = Dense(n)
    for _ in range(12):  # every map diverges: each copies the tiles it writes
        sensor, ends, hit = _scan(rng, np.zeros(2), reach=15.0)
        poses = np.column_stack([rng.normal(0, 0.3, (n, 2)), rng.uniform(-np.pi, np.pi, n)])
        tiled.update_all(poses, sensor, ends, hit)
        for i in range(n):
            dense.update(i, transform_points(poses[i], sensor[None])[0], transform_points(poses[i], ends), hit)
    before = tiled.unique_tiles
    tiled.resample(np.zeros(n, dtype=np.intp))  # one survives: the others' tiles are freed
    dense.resample(np.zeros(n, dtype=np.intp))
    freed_mb = (before - tiled.unique_tiles) * 32 * 32 * 6 / 2**20
    assert freed_mb > 1.0
    assert 0.5 * freed_mb <= tiled.released_mb <= freed_mb + 0.01
    for _ in range(4):  # the tiles taken again read as written
        sensor, ends, hit = _scan(rng, np.zeros(2), reach=15.0)
        poses = np.column_stack([rng.normal(0, 0.3, (n, 2)), rng.uniform(-np.pi, np.pi, n)])
        tiled.update_all(poses, sensor, ends, hit)
        for i in range(n):
            dense.update(i, transform_points(poses[i], sensor[None])[0], transform_points(poses[i], ends), hit)
    for i in range(n):
        np.testing.assert_array_equal(tiled.dense(i), dense.window(i, tiled))


def test_resampling_copies_tables_and_writes_copy_only_the_tiles_they_touch():
    rng = np.random.default_rng(0)
    n = 100
    tiled = TiledMaps(n, resolution=0.05)
    for _ in range(30):  # particle 0 maps a hall 20 m across
        tiled.update(0, rng.uniform(-1, 1, 2), rng.uniform(-10, 10, (300, 2)), np.ones(300, bool))
    one = tiled.unique_tiles
    assert one > 150
    tiled.resample(np.zeros(n, dtype=np.intp))  # every particle a child of particle 0
    assert tiled.unique_tiles == one  # sharing costs no tiles
    assert (tiled.refs[tiled.refs > 0] == n).all()
    for i in range(n):  # each particle adds a short scan near the centre
        tiled.update(i, np.zeros(2), rng.uniform(-0.5, 0.5, (20, 2)), np.ones(20, bool))
    per_particle = (tiled.unique_tiles - one) / n
    assert per_particle <= 4  # a 1 m scan touches at most 2 x 2 tiles of 1.6 m
    assert tiled.unique_tiles < 0.05 * n * one  # far below n copies of the map
    assert tiled.nbytes < 0.05 * n * one * 32 * 32 * 6  # (log-odds float32 and near cache uint16)


@pytest.mark.parametrize("shift", [2, 5])
def test_all_at_once_equals_one_at_a_time_on_rays_along_grid_lines_and_through_tile_corners(shift):
    # Rays along cell and tile edges or through their corners are where the first pass's
    # tiles and the traversal's cells could disagree by a rounding. (Against the serial
    # update on the same grid: a dense grid with another origin rounds such points its own way.)
    n = 4
    side = RES * (1 << shift)
    par, ser = (TiledMaps(n, resolution=RES, tile_shift=shift, capacity=1) for _ in range(2))
    for maps in (par, ser):
        maps.ensure_contains(-12 * side, -12 * side, 12 * side, 12 * side)
    k = np.arange(-3, 4)
    ends = np.vstack(
        [
            np.column_stack([k * side, k * side]),
            np.column_stack([k * side, -k * side]),
            np.column_stack([k * side, np.zeros_like(k)]),
            np.column_stack([np.zeros_like(k), k * side]),
            np.column_stack([k * RES, 2 * side + 0 * k]),
        ]
    )
    hit = np.arange(len(ends)) % 3 != 0
    for step in range(6):
        poses = np.array([[side * i * (step - 2), -side * step, np.pi / 2 * (i % 4)] for i in range(n)])
        par.update_all(poses, np.zeros(2), ends, hit)
        for i in range(n):
            ser.update(i, poses[i, :2], transform_points(poses[i], ends), hit)
        if step % 2:
            for maps in (par, ser):
                maps.resample(np.array([0, 0, 1, 3]))
    assert par.shape == ser.shape and (par.origin == ser.origin).all()
    for i in range(n):
        assert np.abs(par.dense(i)).sum() > 0
        np.testing.assert_array_equal(par.dense(i), ser.dense(i))
    # (Rays exactly along tile edges make the first pass own the tiles on both sides: more
    # tiles here than the serial update takes, never fewer.)
    assert par.unique_tiles >= ser.unique_tiles


def test_the_near_cache_gives_the_uncached_match_after_writes_resampling_and_growth():
    """The match and the log-likelihood read each hit's nearest wall from the per-tile near
    cache (radius 1, occupied: above 0). Between matches the maps are written (walls that
    come and go), resampled (shared tiles copied on write) and grown: the answers stay those
    of the uncached search (an occupancy threshold a hair above 0 takes the uncached path;
    log-odds here are whole numbers, so it means the same cells)."""
    from pfslam.kernels.tiled import tiled_loglik_kernel, tiled_match_kernel

    rng = np.random.default_rng(4)
    maps = TiledMaps(4, resolution=0.05)
    room = np.array([[4.0, 3.0], [-4.0, 3.0], [-4.0, -3.0], [4.0, -3.0], [4.0, 3.0]])

    def wall_points(shift):
        pts = [np.linspace(a, b, 120) for a, b in zip(room[:-1], room[1:])]
        return np.vstack(pts) + shift

    checked = 0
    for step in range(12):
        ends = wall_points(
            rng.normal(0, 0.01, 2) + (0.0, 0.05 * step)
        )  # the room drifts a cell a scan: walls come and go
        for i in range(maps.n):
            maps.update(i, rng.normal(0, 0.1, 2), ends, np.ones(len(ends), bool))
        if step % 3 == 2:
            maps.resample(rng.integers(0, maps.n, maps.n))
        hits = ends[::5] - (0.0, 0.05 * step) + rng.normal(0, 0.02, (len(ends[::5]), 2))
        poses = np.column_stack([rng.normal(0, 0.05, (maps.n, 2)) + (0.0, 0.05 * step), rng.normal(0, 0.03, maps.n)])
        ox, oy = float(maps.origin[0]), float(maps.origin[1])
        got = {}
        for occ in (0.0, 1e-6):
            p = poses.copy()
            tiled_match_kernel(
                maps.tables, maps.pool, maps.near, maps.shift, p, hits, ox, oy, 0.05, 0.05, 1, occ, 0.05, 0.05, 4
            )
            ll = tiled_loglik_kernel(
                maps.tables, maps.pool, maps.near, maps.shift, p, hits, ox, oy, 0.05, 0.075, 1, occ, 0.05
            )
            got[occ] = (p, ll)
        np.testing.assert_array_equal(got[0.0][0], got[1e-6][0])
        np.testing.assert_array_equal(got[0.0][1], got[1e-6][1])
        checked += int(np.any(got[0.0][0] != poses))
    assert checked >= 10  # the matches moved the particles: the cache was read, not bypassed


def test_without_private_mappings_the_pool_is_numpys_and_nothing_is_handed_back(monkeypatch):
    """Where the system has no private anonymous mapping (Windows), the maps read the same and
    nothing claims to have been handed back."""
    import pfslam.maps.tiled as tiled_module

    monkeypatch.setattr(tiled_module, "_PRIVATE", None)
    rng = np.random.default_rng(5)
    n = 4
    tiled = TiledMaps(n, resolution=RES, tile_shift=5, release_bytes=0)
    assert tiled._pool_buf is None
    dense = Dense(n)
    for _ in range(6):
        sensor, ends, hit = _scan(rng, np.zeros(2), reach=10.0)
        poses = np.column_stack([rng.normal(0, 0.3, (n, 2)), rng.uniform(-np.pi, np.pi, n)])
        tiled.update_all(poses, sensor, ends, hit)
        for i in range(n):
            dense.update(i, transform_points(poses[i], sensor[None])[0], transform_points(poses[i], ends), hit)
        parents = rng.integers(0, n, n)
        tiled.resample(parents)
        dense.resample(parents)
    for i in range(n):
        np.testing.assert_array_equal(tiled.dense(i), dense.window(i, tiled))
    assert tiled.released_mb == 0.0
