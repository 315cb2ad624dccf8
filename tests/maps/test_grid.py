"""The occupancy grid: exact ray updates, growth, ROS map files, building one from a config."""

import numpy as np
import pytest

from pfslam.config import MapConfig
from pfslam.errors import InputError
from pfslam.kernels.raycast import ray_update_numpy
from pfslam.maps.grid import MapTooLarge, OccupancyGrid, grid_from_config, integrate_scan
from pfslam.sensor import ScanPoints


def test_beam_along_a_row_counts_each_cell_once():
    g = OccupancyGrid(origin=(-2.0, -2.0), shape=(80, 100))
    g.update(np.array([0.025, 0.025]), np.array([[1.025, 0.025]]), np.array([True]))
    r, c = g.world_to_cell(np.array([[0.025, 0.025]]))
    row = g.logodds[r[0]]
    np.testing.assert_array_equal(row[c[0] : c[0] + 20], -1.0)
    assert row[c[0] + 20] == 3.0
    assert np.count_nonzero(g.logodds) == 21


def test_diagonal_beam_touches_cells_once_and_clamps():
    g = OccupancyGrid(origin=(-2.0, -2.0), shape=(120, 120))
    for _ in range(100):
        g.update(np.array([0.01, 0.02]), np.array([[2.33, 1.71]]), np.array([True]))
    vals = np.unique(g.logodds)
    assert set(vals.tolist()) == {-100.0, 0.0, 120.0}  # -1 once per beam per cell
    r, c = g.world_to_cell(np.array([[2.33, 1.71]]))
    assert g.logodds[r[0], c[0]] == 120.0


def test_hits_of_a_scan_are_not_erased_by_its_grazing_beams():
    g = OccupancyGrid(origin=(-1.0, -1.0), shape=(60, 200))
    # A wall along y = 1.0: a steep beam hits it near the robot, a grazing one far away
    # passes through the near hit's cell row before ending.
    ends = np.array([[0.3, 1.01], [6.0, 1.04]])
    g.update(np.zeros(2), ends, np.array([True, True]))
    r, c = g.world_to_cell(ends)
    assert g.logodds[r[0], c[0]] == 3.0 and g.logodds[r[1], c[1]] == 3.0


def test_growth_keeps_cells_at_their_world_position():
    g = OccupancyGrid(origin=(-1.0, -1.0), shape=(60, 60))
    p = np.array([[0.52, 0.33]])
    g.update(np.array([0.1, 0.1]), p, np.array([True]))
    before = g.logodds.copy()
    r0, c0 = g.world_to_cell(p)
    assert g.logodds[r0[0], c0[0]] == 3.0
    assert g.ensure_contains(-7.3, -4.4, 15.2, 12.9)
    assert g.shape[0] > 60 and g.shape[1] > 60
    r1, c1 = g.world_to_cell(p)
    assert g.logodds[r1[0], c1[0]] == 3.0
    # The old block is intact, just shifted by whole cells; the rest is unknown.
    dr, dc = r1[0] - r0[0], c1[0] - c0[0]
    np.testing.assert_array_equal(g.logodds[dr : dr + 60, dc : dc + 60], before)
    assert np.count_nonzero(g.logodds) == np.count_nonzero(before)
    # Updates far outside grow the grid to hold them.
    far = np.array([[-27.3, 32.9], [35.2, -24.4]])
    g.update(np.array([0.1, 0.1]), far, np.array([False, True]))
    assert g.contains(far).all()
    r2, c2 = g.world_to_cell(far[1:])
    assert g.logodds[r2[0], c2[0]] == 3.0


def _wall_grid():
    g = OccupancyGrid(origin=(-3.0, -2.0), shape=(80, 120))
    ys = np.linspace(-1.5, 1.5, 200)
    ends = np.column_stack([np.full_like(ys, 2.0 + 1e-3), ys])  # a wall at x = 2.0
    for _ in range(3):
        g.update(np.array([0.0, 0.0]), ends, np.ones(len(ends), bool))
    return g


def test_map_round_trip_and_wall_position(tmp_path):
    g = _wall_grid()
    yml, pgm = g.save_ros(tmp_path / "map")
    head = pgm.read_bytes()[:2]
    assert head == b"P5"
    text = yml.read_text()
    for key in (
        "image: map.pgm",
        "resolution:",
        "origin:",
        "negate: 0",
        "occupied_thresh: 0.65",
        "free_thresh: 0.196",
        "mode: trinary",
    ):
        assert key in text
    back = OccupancyGrid.load_ros(yml)
    crop = g.cropped(10)
    np.testing.assert_allclose(back.origin, crop.origin)
    np.testing.assert_array_equal(back.thresholded(), crop.thresholded())
    occ = np.argwhere(back.thresholded() == 100)
    xy = back.cell_to_world(occ[:, 0], occ[:, 1])
    assert len(xy) > 50
    assert np.all(np.abs(xy[:, 0] - 2.025) <= 0.05 / 2 + 1e-9)  # the cell [2.00, 2.05)


def test_pgm_top_row_is_the_largest_y(tmp_path):
    g = OccupancyGrid(origin=(-1.0, -1.0), shape=(80, 80))
    for _ in range(3):  # one -1 is not yet "free" (p = 0.27 > 0.196)
        g.update(np.array([1.01, 0.21]), np.array([[1.01, 1.91]]), np.array([True]))
    assert g.shape == (80, 80)
    _, pgm = g.save_ros(tmp_path / "m", crop=False)
    img = np.frombuffer(pgm.read_bytes()[-80 * 80 :], np.uint8).reshape(80, 80)
    col = int((1.01 + 1.0) / 0.05)
    assert img[80 - 1 - int((1.91 + 1.0) / 0.05), col] == 0  # occupied, near the top
    assert img[80 - 1 - int((1.0 + 1.0) / 0.05), col] == 254  # free below it
    assert img[0, 0] == 205 and img[-1, -1] == 205


def test_load_ros_errors(tmp_path):
    with pytest.raises(InputError, match="nope.yaml"):
        OccupancyGrid.load_ros(tmp_path / "nope.yaml")
    y = tmp_path / "m.yaml"
    y.write_text("image: missing.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    with pytest.raises(InputError, match="missing.pgm"):
        OccupancyGrid.load_ros(y)
    y.write_text("image: m.pgm\norigin: [0, 0, 0]\n")
    with pytest.raises(InputError, match="resolution"):
        OccupancyGrid.load_ros(y)
    (tmp_path / "m.pgm").write_bytes(b"P5\n10 10\n255\n" + bytes(20))
    y.write_text("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    with pytest.raises(InputError, match="truncated"):
        OccupancyGrid.load_ros(y)


@pytest.mark.parametrize(
    "image, words",
    [
        (
            b"P5\n9 10\n255\n" + bytes([254]) * 100,
            "PGM data longer than its header says: 100 bytes of pixels, while 9x10",
        ),
        (b"P5\n10 10\n255\n" + bytes([254]) * 101, "longer than its header says"),  # one stray byte
        (b"P5\n10 10\n65535\n" + bytes(199), "truncated PGM: 199 bytes of pixels, while 10x10 pixels of 2 byte(s)"),
        (b"P2\n3 2\n255\n" + b"254 " * 7, "PGM data longer than its header says: 7 pixels, while 3x2 are 6"),
        (b"P2\n3 2\n255\n" + b"254 " * 5, "truncated PGM: 5 pixels"),
    ],
)
def test_pgm_data_must_match_its_header_exactly(tmp_path, image, words):
    """A header narrower than its data used to be read row by row off the data: a sheared map."""
    (tmp_path / "m.pgm").write_bytes(image)
    y = tmp_path / "m.yaml"
    y.write_text("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    with pytest.raises(InputError) as e:
        OccupancyGrid.load_ros(y)
    assert str(e.value).startswith(str(tmp_path / "m.pgm") + ": ") and words in str(e.value), str(e.value)
    assert "\n" not in str(e.value)


def test_pgm_of_the_exact_size_loads(tmp_path):
    (tmp_path / "m.pgm").write_bytes(b"P5\n# c\n10 9\n255\n" + bytes([254]) * 90)
    (tmp_path / "p.pgm").write_bytes(b"P2\n3 2\n255\n254 0 205\n254 254 0\n")
    for name in ("m", "p"):
        y = tmp_path / f"{name}.yaml"
        y.write_text(f"image: {name}.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
        g = OccupancyGrid.load_ros(y)
        assert g.shape == ((9, 10) if name == "m" else (2, 3))


def test_map_growth_is_bounded():
    g = OccupancyGrid(shape=(100, 100))
    with pytest.raises(MapTooLarge, match="map would grow"):
        g.ensure_contains(0.0, 0.0, 1e6, 1.0)
    assert g.shape == (100, 100)


def test_grid_from_config_takes_the_cells_and_log_odds_of_the_map_config():
    c = MapConfig(resolution=0.1, l_occ=2.0, l_free=-0.5, l_clamp=50.0, initial_size=8.0)
    g = grid_from_config(c)
    assert g.shape == (80, 80) and g.resolution == 0.1
    np.testing.assert_allclose(g.origin, [-4.0, -4.0])  # centred on the map frame's origin
    assert (g.l_occ, g.l_free, g.l_clamp) == (2.0, -0.5, 50.0)
    empty = grid_from_config(c, centred=False)
    assert empty.shape == (0, 0) and empty.resolution == 0.1 and empty.l_occ == 2.0


def test_integrate_scan_marks_hits_occupied_and_floor_free_from_the_pose():
    sp = ScanPoints(hits=np.array([[1.0, 0.0]]), floor=np.array([[0.0, 0.6]]), sensor_xy=np.array([0.1, 0.0]))
    pose = np.array([1.0, 2.0, np.pi / 2])  # facing +y: the hit 1 m ahead is at (1, 3)
    g = grid_from_config(MapConfig(initial_size=10.0))
    twin = grid_from_config(MapConfig(initial_size=10.0))
    integrate_scan(g, pose, sp)
    integrate_scan(twin, pose, sp, ray_update=ray_update_numpy)
    np.testing.assert_array_equal(g.logodds, twin.logodds)
    r, c = g.world_to_cell(np.array([[1.0 + 1e-6, 3.0 + 1e-6], [0.4, 2.0 + 1e-6], [1.0 + 1e-6, 2.5]]))
    assert g.logodds[r[0], c[0]] == 3.0  # the hit
    assert g.logodds[r[1], c[1]] == -1.0  # the floor hit is free, never a wall
    assert g.logodds[r[2], c[2]] == -1.0  # on the beam from the sensor at (1, 2.1)
    assert np.count_nonzero(g.logodds > 0) == 1


def test_many_scans_in_one_call_give_the_cells_one_update_a_scan_gives():
    """update_scans (scans one after the other in one kernel call, the grid sized beforehand)
    against update per scan: the same cells, to the bit, hits of a scan kept from its own
    grazing beams but cleared by later scans'."""
    rng = np.random.default_rng(7)
    one, many = (OccupancyGrid(resolution=0.05, origin=(-10.0, -10.0), shape=(400, 400)) for _ in range(2))
    sensors, ends, hits, starts = [], [], [], [0]
    for _ in range(40):
        s = rng.uniform(-2, 2, 2)
        e = s + rng.uniform(-6, 6, (int(rng.integers(0, 60)), 2))
        h = rng.random(len(e)) < 0.7
        if len(e):
            one.update(s, e, h)
        sensors.append(s)
        ends.append(e)
        hits.append(h)
        starts.append(starts[-1] + len(e))
    many.update_scans(np.array(sensors), np.concatenate(ends), np.concatenate(hits), np.array(starts))
    assert one.shape == many.shape and (one.origin == many.origin).all()  # (nothing grew)
    assert np.abs(one.logodds).sum() > 0
    np.testing.assert_array_equal(one.logodds, many.logodds)
