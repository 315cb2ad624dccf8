"""The map picture: cropped to the observed cells; a map too large to draw cell by cell is
pooled into blocks in which a wall always shows."""

import numpy as np

from pfslam.maps.grid import OccupancyGrid
from pfslam.views.figures import MAX_IMAGE_CELLS, map_image, plot_map


def _grid(h, w, res=0.05):
    g = OccupancyGrid(res, origin=(-1.0, 2.0), shape=(h, w))
    return g


def test_a_small_map_is_drawn_cell_by_cell_and_cropped():
    g = _grid(60, 80)
    g.logodds[10:20, 5:30] = -4.0  # free
    g.logodds[15, 5:30] = 9.0  # a wall
    img, extent, rows, cols = map_image(g)
    assert img.shape == (10, 25)
    want = 1.0 - g.probabilities()[10:20, 5:30]
    np.testing.assert_allclose(img, want)
    assert extent == (-1.0 + 5 * 0.05, -1.0 + 30 * 0.05, 2.0 + 10 * 0.05, 2.0 + 20 * 0.05)
    assert rows[0] == 10 and cols[-1] == 29


def test_a_huge_map_is_pooled_and_every_wall_stays_dark():
    rng = np.random.default_rng(0)
    h, w = 960, 9600  # 9.2 M cells: pooled by 12 along both axes
    g = _grid(h, w)
    g.logodds[:, :] = -5.0
    g.logodds[480:600, :] = 0.0  # an unobserved band
    r = rng.integers(0, h - 120, 400)
    walls = (np.where(r >= 480, r + 120, r), rng.integers(0, w, 400))
    g.logodds[walls] = 7.0  # single-cell walls, which plain scaling would lose
    img, extent, _, _ = map_image(g)
    k = -(-w // MAX_IMAGE_CELLS)
    assert max(img.shape) <= MAX_IMAGE_CELLS and img.shape == (-(-h // k), -(-w // k))
    assert (img[walls[0] // k, walls[1] // k] < 0.01).all()
    assert k == 12 and (img[480 // k : 600 // k] == 0.8).all()  # unknown stays unknown
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


def test_the_view_holds_the_map_and_the_estimate_not_the_drifting_odometry(tmp_path):
    g = _grid(200, 200)  # 10 m x 10 m from (-1, 2)
    g.logodds[20:180, 20:180] = -3.0
    est = np.column_stack([np.linspace(1, 7, 40), np.linspace(4, 9, 40), np.zeros(40)])
    odo = est + np.column_stack([np.linspace(0, 60, 40), np.zeros(40), np.zeros(40)])  # drifts 60 m away
    x0, x1, y0, y1 = plot_map(
        g,
        tmp_path / "m.png",
        [("odometry", odo, "tab:orange"), ("SLAM", est, "tab:blue")],
        times=np.arange(40.0),
        timed="SLAM",
    )
    assert x0 < 0.0 and x1 > 7.0 and y0 < 3.0 and y1 > 10.0  # the map's observed cells and the estimate
    assert x1 < 15.0  # not stretched to the odometry (up to x = 67 m)


def test_error_pictures_show_the_errors_the_metrics_report(tmp_path):
    from pfslam.eval.metrics import pose_errors, trajectory_errors
    from pfslam.views.figures import plot_errors

    rng = np.random.default_rng(2)
    t = np.arange(300) * 0.1
    ref = np.column_stack([np.cos(t / 5) * 10, np.sin(t / 5) * 10, t / 5 + np.pi / 2])
    est = ref + rng.normal(0, [0.05, 0.05, 0.01], ref.shape)
    pe = pose_errors(t, est, t, ref)
    e = trajectory_errors(t, est, t, ref)
    assert np.sqrt(np.mean(pe.aligned_error**2)) == e.ate_rmse_aligned
    assert pe.aligned_error.max() == e.ate_max_aligned and len(pe.t) == e.matched == 300
    files = plot_errors(pe, tmp_path / "plots", name="est")
    assert [f.name for f in files] == ["trajectory_error.png", "error_over_time.png"]
    assert all(f.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f.stat().st_size > 20_000 for f in files)


def test_the_odometry_is_drawn_only_while_it_stays_near_the_estimate():
    from pfslam.views.figures import ODOMETRY_NEAR, map_figure, odometry_near

    est = np.column_stack([np.linspace(0, 8, 50), np.full(50, 5.0), np.zeros(50)])
    odo = est.copy()
    odo[:, 1] += np.linspace(0, 5, 50)  # drifts 5 m sideways
    assert odometry_near(odo, est, 1.0) == int(np.argmax(np.linspace(0, 5, 50) > 1.0))
    assert odometry_near(est, est, 0.1) == 50 and odometry_near(odo[:10], est, 0.1) == 10  # no pose a step
    g = _grid(200, 200)
    g.logodds[40:160, 20:180] = -3.0
    fig, ax = map_figure(
        g,
        [("ground truth", est, "tab:green"), ("odometry", odo, "tab:orange"), ("SLAM", est, "tab:blue")],
        times=np.arange(50.0),
        timed="SLAM",
    )
    (line,) = [ln for ln in ax.get_lines() if ln.get_label().startswith("odometry")]
    span = max(np.diff(ax.get_xlim())[0], np.diff(ax.get_ylim())[0])
    off = np.hypot(*(line.get_xydata() - est[: len(line.get_xydata()), :2]).T)
    assert 1 < len(off) < 50 and off.max() <= ODOMETRY_NEAR * span + 1e-9
    assert "m off" in line.get_label()
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_the_truth_is_thin_and_dark_under_the_estimate_and_clouds_lie_over_everything():
    from matplotlib.colors import to_rgb

    from pfslam.views.figures import CLOUD_COLOURS, ODOMETRY_COLOUR, TRUTH_COLOUR, map_figure, time_colormap

    g = _grid(100, 100)
    g.logodds[10:90, 10:90] = -3.0
    est = np.column_stack([np.linspace(0, 3, 20), np.full(20, 4.0), np.zeros(20)])
    cloud = np.column_stack([np.full(30, 0.0), np.full(30, 4.0), np.zeros(30)])
    fig, ax = map_figure(
        g, [("reference", est, "tab:green"), ("estimate", est, "tab:blue")], clouds=[("particles at 0 s", cloud)]
    )
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    assert lines["reference"].get_zorder() < lines["estimate"].get_zorder()
    assert lines["reference"].get_linewidth() < lines["estimate"].get_linewidth()
    assert np.mean(to_rgb(lines["reference"].get_color())) < 0.2  # dark, whatever colour it was given
    top = max(a.get_zorder() for a in ax.get_lines())  # the tracks and their start/end markers
    clouds = [c for c in ax.collections if c.get_label() == "particles at 0 s"]
    assert clouds and clouds[0].get_zorder() >= top
    # No time colour coincides with the truth's, the odometry's or a cloud's.
    times = time_colormap()(np.linspace(0, 1, 64))[:, :3]
    for other in (TRUTH_COLOUR, ODOMETRY_COLOUR, *CLOUD_COLOURS):
        assert np.linalg.norm(times - np.array(to_rgb(other)), axis=1).min() > 0.3, other
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_a_run_picture_is_titled_with_its_log_filter_and_figures():
    from pfslam.views.figures import run_title

    t = run_title(
        "slam",
        "/data/intel.gfs.log.gz",
        {"filter": "rbpf", "particles": 30},
        {
            "SLAM": {"ate_rmse_aligned": 0.0484},
            "odometry": {"ate_rmse_aligned": 6.47},
            "map_agreement": {"SLAM": 0.891},
        },
        "SLAM",
        "reference",
    )
    assert t.splitlines() == [
        "intel.gfs.log.gz: SLAM map (Rao-Blackwellized filter, 30 particles)",
        "ATE aligned vs reference: SLAM 0.048 m, odometry 6.47 m; map agreement 0.89",
    ]
    assert (
        run_title("localization", None, {"filter": "mcl"}, {}, "estimate") == "localization (Monte Carlo localization)"
    )


def test_the_sweep_summary_starts_its_axes_at_0_and_names_the_filter_that_ran(tmp_path, monkeypatch):
    import json

    import matplotlib.figure

    from pfslam.sweep.table import build_table, plot_summary

    rows = []
    for on in (False, True):
        for seed in (0, 1):
            d = f"runs/office/local_search.enabled={on}/seed{seed}"
            (tmp_path / d).mkdir(parents=True)
            (tmp_path / d / "run.json").write_text(json.dumps({"filter": {"filter": "single"}}))
            rows.append(
                {
                    "log": "office",
                    "seed": seed,
                    "settings": {"local_search.enabled": on},
                    "status": "ok",
                    "exit_code": 0,
                    "message": "",
                    "ate_aligned": 0.01 + 0.001 * seed,
                    "peak_rss_mb": 250.0 + seed,
                    "run_dir": d,
                }
            )
    df = build_table(rows, ["local_search.enabled"])
    seen = []
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", lambda fig, *a, **k: seen.append(fig))
    plot_summary(df, ["local_search.enabled"], tmp_path / "summary.png")
    (fig,) = seen
    axes = {ax.get_title(): ax for ax in fig.axes if ax.get_visible()}
    assert set(axes) == {"ATE aligned (m)", "peak RSS (MB)"}
    assert all(ax.get_ylim()[0] == 0.0 for ax in axes.values())  # 250-251 MB is not drawn as a 3x gap
    labels = [t.get_text() for t in axes["peak RSS (MB)"].get_xticklabels()]
    assert all("filter=single" in lab for lab in labels)
