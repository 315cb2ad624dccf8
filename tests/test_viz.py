"""The map picture: cropped to the observed cells; a map too large to draw cell by cell is
pooled into blocks in which a wall always shows."""

import numpy as np

from pfslam.grid import OccupancyGrid
from pfslam.viz import MAX_IMAGE_CELLS, _map_image, plot_map


def _grid(h, w, res=0.05):
    g = OccupancyGrid(res, origin=(-1.0, 2.0), shape=(h, w))
    return g


def test_a_small_map_is_drawn_cell_by_cell_and_cropped():
    g = _grid(60, 80)
    g.logodds[10:20, 5:30] = -4.0  # free
    g.logodds[15, 5:30] = 9.0  # a wall
    img, extent, rows, cols = _map_image(g)
    assert img.shape == (10, 25)
    want = 1.0 - g.probabilities()[10:20, 5:30]
    np.testing.assert_allclose(img, want)
    assert extent == (-1.0 + 5 * 0.05, -1.0 + 30 * 0.05, 2.0 + 10 * 0.05, 2.0 + 20 * 0.05)
    assert rows[0] == 10 and cols[-1] == 29


def test_a_huge_map_is_pooled_and_every_wall_stays_dark():
    rng = np.random.default_rng(0)
    h, w = 900, 9000  # 8.1 M cells: pooled by 5 along both axes
    g = _grid(h, w)
    g.logodds[:, :] = -5.0
    g.logodds[400:500, :] = 0.0  # an unobserved band
    r = rng.integers(0, h - 100, 400)
    walls = (np.where(r >= 400, r + 100, r), rng.integers(0, w, 400))
    g.logodds[walls] = 7.0  # single-cell walls, which plain scaling would lose
    img, extent, _, _ = _map_image(g)
    k = -(-w // MAX_IMAGE_CELLS)
    assert max(img.shape) <= MAX_IMAGE_CELLS and img.shape == (-(-h // k), -(-w // k))
    assert (img[walls[0] // k, walls[1] // k] < 0.01).all()
    assert (img[400 // k: 500 // k] == 0.8).all()  # unknown stays unknown (k divides 400 and 500)
    dark = img < 0.5
    assert dark.sum() <= len(walls[0])  # no wall where there is none
    assert extent[1] - extent[0] >= w * g.resolution


def test_plot_map_writes_a_picture_of_a_huge_map(tmp_path):
    g = _grid(400, 12000)
    g.logodds[100:300, :] = -3.0
    g.logodds[200, :] = 5.0
    poses = np.column_stack([np.linspace(0, 500, 50), np.full(50, 12.0), np.zeros(50)])
    plot_map(g, tmp_path / "m.png", [("SLAM", poses, "tab:blue")], title="t")
    assert (tmp_path / "m.png").stat().st_size > 10_000
