"""Seeing a run: `--video` (MP4, GIF) and `--rerun-save` on short demos, read back with the
packages that play them (PyAV, Pillow, the rerun SDK); the one-line errors when the
optional packages are missing or a name is wrong; the sampling and the trace behind them."""

import json
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from pfslam.cli import app
from pfslam.frames import Estimate
from pfslam.io.trajectory import read_tum
from pfslam.views.trace import RunTrace, sample_steps

av = pytest.importorskip("av")
iio = pytest.importorskip("imageio.v3")
rr_chunk = pytest.importorskip("rerun.chunk")

runner = CliRunner()
DEMO_SECONDS = 8.0  # of log: 320 scans, the last 2.7 s walking


def _one_line_error(res, *words):
    assert res.exit_code == 2, (res.exit_code, res.output)
    lines = [ln for ln in res.stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in res.output, res.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])


@pytest.fixture(scope="module")
def demo_mp4_rrd(tmp_path_factory):
    """One short demo asked for an MP4 and a rerun recording at once, with the single-map
    filter: its live track is the trajectory it writes. (The Rao-Blackwellized filter, the
    demo's default, writes its best particle's whole path at the end, which its live track,
    the best particle of each moment, need not be.)"""
    out = tmp_path_factory.mktemp("demo_views")
    res = runner.invoke(
        app,
        [
            "demo",
            "--duration",
            str(DEMO_SECONDS),
            "--filter",
            "single",
            "-o",
            str(out / "run"),
            "--video",
            str(out / "run.mp4"),
            "--rerun-save",
            str(out / "run.rrd"),
        ],
    )
    assert res.exit_code == 0, res.output
    return out, res.output


# -- the video ---------------------------------------------------------------------------


def test_demo_mp4_plays_at_six_times_real_time(demo_mp4_rrd):
    out, text = demo_mp4_rrd
    with av.open(str(out / "run.mp4")) as c:
        s = c.streams.video[0]
        assert (s.codec_context.name, s.codec_context.pix_fmt) == ("h264", "yuv420p")  # what players take
        assert float(s.average_rate) == 20.0
    frames = iio.imread(out / "run.mp4", plugin="pyav")
    assert frames.shape[1:] == (800, 800, 3) and frames.dtype == np.uint8
    # 8 s of log at 6x real time, then the last frame held 1.5 s.
    t = read_tum(out / "run" / "trajectory.tum")[0]
    assert abs(len(frames) / 20.0 - ((t[-1] - t[0]) / 6.0 + 1.5)) <= 2 / 20.0
    first, last = frames[0].astype(int), frames[-1].astype(int)
    assert np.abs(first - last).mean() > 1.0  # the map grew, the robot moved
    distinct = {frames[k].tobytes() for k in range(0, len(frames) - 30)}
    assert len(distinct) >= 10  # each sampled moment drawn anew
    assert f"video: {out / 'run.mp4'} ({len(frames)} frames" in text


def test_demo_gif(tmp_path):
    res = runner.invoke(
        app,
        [
            "demo",
            "--duration",
            "3",
            "--filter",
            "single",
            "-o",
            str(tmp_path / "run"),
            "--video",
            str(tmp_path / "run.gif"),
            "--video-fps",
            "5",
        ],
    )
    assert res.exit_code == 0, res.output
    frames = iio.imread(tmp_path / "run.gif", plugin="pillow")
    # 3 s of log at 6x: three frames 0.6 s of log apart; the last one held 1.5 s as repeated frames
    # (which a GIF's reader may fold into one frame of a longer duration).
    assert frames.shape[1:3] == (560, 560) and len(frames) >= 3
    assert np.abs(frames[0].astype(int) - frames[-1].astype(int)).mean() > 1.0
    meta = iio.immeta(tmp_path / "run.gif", plugin="pillow", index=0)
    assert meta["duration"] == 200 and meta["loop"] == 0  # 5 frames per second, playing in a loop


def test_a_run_stopped_early_still_gives_a_playable_video(short_office, tmp_path):
    """Ctrl-C in the run: the video holds the steps done, its last frame drawn, and plays."""
    from pfslam.config import SlamConfig
    from pfslam.frames import frame_times
    from pfslam.io.logs import load_log
    from pfslam.pipeline import run_slam
    from pfslam.views.live import ViewRequest

    frames = load_log(short_office.lidar_path, short_office.joint_path).frames
    live = ViewRequest(video=tmp_path / "stopped.mp4").open(frame_times(frames), None, 0.15, "slam", "test")

    def stop_at_101(i, frame, filt, est):
        live(i, frame, filt, est)
        if i == 100:
            raise KeyboardInterrupt

    run = run_slam(frames, SlamConfig(filter="single", particles=10), observer=stop_at_101)
    live.close()
    assert run.interrupted and run.scans == 101
    got = iio.imread(tmp_path / "stopped.mp4", plugin="pyav")
    full = sample_steps(frame_times(frames), 6.0 / 20.0)
    assert len(got) == full[:101].sum() + 1 + 30  # the steps' frames, the last step, the 1.5 s hold
    assert live.views[0].rendered == np.count_nonzero(full[:101]) + 1


def test_a_video_that_cannot_be_finished_is_an_error_after_the_results(tmp_path, monkeypatch):
    import pfslam.views.video

    def full_disk(self):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(pfslam.views.video._Writer, "close", full_disk)
    res = runner.invoke(
        app, ["demo", "--duration", "2", "-o", str(tmp_path / "run"), "--video", str(tmp_path / "run.mp4")]
    )
    assert res.exit_code == 2 and "Traceback" not in res.output
    errors = [ln for ln in res.stderr.splitlines() if ln.startswith("error:")]
    assert len(errors) == 1 and "run.mp4" in errors[0] and "No space left on device" in errors[0], res.stderr
    assert (tmp_path / "run" / "trajectory.tum").is_file() and (tmp_path / "run" / "map.png").is_file()
    assert "No space left on device" in (tmp_path / "run" / "run.json").read_text()


# -- the rerun recording -----------------------------------------------------------------


def _chunks(path):
    """entity path -> the record batches of its chunks, in the file's order."""
    out = {}
    for ch in rr_chunk.RrdReader(path).store().stream():
        out.setdefault(ch.entity_path, []).append(ch.to_record_batch())
    return out


def _column(batches, name):
    return [v for b in batches for v in b.column(b.schema.names.index(name)).to_pylist()]


def test_rerun_recording_holds_the_run(demo_mp4_rrd):
    out, text = demo_mp4_rrd
    reader = rr_chunk.RrdReader(out / "run.rrd")
    assert len(reader.recordings()) == 1 and len(reader.blueprints()) == 1  # the layout travels with it
    schema = reader.store().schema()
    world = {
        "/world",
        "/world/map",
        "/world/particles",
        "/world/scan",
        "/world/robot",
        "/world/trajectory/estimate",
        "/world/trajectory/odometry",
        "/world/trajectory/truth",
    }
    assert world | {"/stats/particles", "/stats/n_eff"} <= set(schema.entity_paths())
    chunks = _chunks(out / "run.rrd")
    # Steps logged at 10 Hz of log time, on the two time lines.
    t, poses = read_tum(out / "run" / "trajectory.tum")
    steps = _column(chunks["/world/particles"], "scan")
    assert steps[0] == 0 and steps[-1] == len(t) - 1  # from the first step to the last
    gaps, scan = np.diff(t[steps]), np.max(np.diff(t))
    assert np.all(gaps[:-1] > 0.1 - scan) and np.all(gaps < 0.1 + scan)  # 0.1 s apart, to a scan
    seconds = [x.total_seconds() for x in _column(chunks["/world/particles"], "scan_time")]
    np.testing.assert_allclose(seconds, t[steps] - t[0], atol=1e-6)
    cfg = json.loads((out / "run" / "run.json").read_text())["config"]
    n = cfg["rbpf"]["particles"] if cfg["filter"] == "rbpf" else cfg["particles"]  # the demo's filter: auto
    assert all(len(p) == n for p in _column(chunks["/world/particles"], "Points2D:positions"))
    # The estimate's pieces, each from the end of the last, join up into the trajectory written.
    pieces = [np.array(strips[0]) for strips in _column(chunks["/world/trajectory/estimate"], "LineStrips2D:strips")]
    for a, b in zip(pieces, pieces[1:]):
        assert np.array_equal(a[-1], b[0])
    joined = np.concatenate([pieces[0]] + [p[1:] for p in pieces[1:]])
    np.testing.assert_allclose(joined, poses[:, :2], atol=1e-5)  # float32 in the recording
    assert np.ptp(poses[:, 0]) > 0.5  # the robot walked
    # The map, refreshed every second of log and at the end, placed in the world by its transform.
    at = _column(chunks["/world/map"], "scan")
    gaps = np.diff(t[at])
    assert at[0] == 0 and at[-1] == len(t) - 1 and np.all(np.abs(gaps[:-1] - 1.0) < scan)
    grey = np.array(_column(chunks["/world/map"], "Image:buffer")[-1][0], dtype=np.uint8)
    assert (grey < 50).sum() > 100 and (grey > 250).sum() > 1000  # walls and free space
    assert len(_column(chunks["/world/map"], "Transform3D:translation")) == len(at)
    assert "rerun: " in text and str(out / "run.rrd") in text


def test_rerun_live_goes_to_the_viewer_sink(tmp_path, monkeypatch):
    """--rerun: the recording goes to a viewer (here a file stands in for the spawned one)."""
    import rerun as rr

    import pfslam.views.rerunview as rv

    def fake_connect(spawn, save):
        assert spawn and save is None
        return [rr.FileSink(str(tmp_path / "viewer.rrd"))]

    monkeypatch.setattr(rv, "connect", fake_connect)
    res = runner.invoke(app, ["demo", "--duration", "2", "-o", str(tmp_path / "run"), "--rerun"])
    assert res.exit_code == 0, res.output
    assert "/world/map" in rr_chunk.RrdReader(tmp_path / "viewer.rrd").store().schema().entity_paths()


# -- errors before the run ---------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "missing", "extra"),
    [
        (["--video", "v.mp4"], "av", "video"),
        (["--video", "v.gif"], "imageio", "video"),
        (["--rerun-save", "x.rrd"], "rerun", "viz"),
        (["--rerun"], "rerun", "viz"),
    ],
)
def test_a_missing_optional_package_is_one_line_before_any_work(tmp_path, monkeypatch, args, missing, extra):
    monkeypatch.setitem(sys.modules, missing, None)  # import fails as if it were not installed
    monkeypatch.chdir(tmp_path)
    res = runner.invoke(app, ["demo", "--duration", "2", "-o", "out", *args])
    _one_line_error(res, f"pip install 'pfslam[{extra}]'", missing)
    assert not (tmp_path / "out").exists()  # nothing simulated, nothing written


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--video", "v.avi"], ["v.avi", ".mp4 or .gif"]),
        (["--video", "v.mp4", "--video-fps", "0"], ["--video-fps", "from 1 to 60"]),
        (["--video-fps", "10"], ["--video-fps", "--video"]),
        (["--rerun-save", "x.txt"], ["x.txt", ".rrd"]),
    ],
)
def test_bad_view_options_are_one_line_before_any_work(tmp_path, monkeypatch, args, words):
    monkeypatch.chdir(tmp_path)
    res = runner.invoke(app, ["demo", "--duration", "2", "-o", "out", *args])
    _one_line_error(res, *words)
    assert not (tmp_path / "out").exists()


def test_slam_and_localize_take_the_view_options():
    for cmd in ("slam", "localize", "demo"):
        res = runner.invoke(app, [cmd, "--help"], env={"COLUMNS": "200"})
        for opt in ("--video ", "--video-fps", "--rerun ", "--rerun-save"):
            assert opt in res.output, (cmd, opt)


# -- sampling and the trace --------------------------------------------------------------


def test_samples_fall_on_the_last_step_at_or_before_their_moment():
    t = np.array([0.0, 1.0, 2.0, 8.0, 10.0, 10.2])
    counts = sample_steps(t, 2.5)  # moments 0, 2.5, 5, 7.5, 10
    assert list(counts) == [1, 0, 3, 0, 1, 1]  # 2.5, 5 and 7.5 show the step at 2 s; the last step always
    assert list(sample_steps(t[:1], 2.5)) == [1]
    assert list(sample_steps(np.arange(5.0), 0.5)) == [2, 2, 2, 2, 1]  # a step shown by several frames


def test_trace_draws_the_odometry_from_the_first_settled_estimate():
    class Filt:
        odom_pose = np.zeros(3)

    trace = RunTrace(np.arange(4.0))
    f = Filt()
    spread = [2.0, 0.1, 0.1, 0.1]  # unsettled, then settled (localization's covariance)
    odom = [[0, 0, 0], [1, 0, 0], [2, 0, np.pi / 2], [2, 1, np.pi / 2]]
    for i in range(4):
        f.odom_pose = np.array(odom[i], float)
        cov = np.diag([spread[i] ** 2 / 2, spread[i] ** 2 / 2, 0.01])
        trace.add(i, f, Estimate(t=float(i), pose=np.array([5.0, 5.0 + i, 0.0]), n_eff=1.0, covariance=cov))
        if i == 0:
            assert len(trace.odometry(0, 0)) == 0  # not settled yet: no odometry drawn
    assert trace.anchor == 1
    # From step 1 on, the odometry's motion (1 m ahead, turn left, 1 m ahead) starts at the estimate (5, 6).
    np.testing.assert_allclose(trace.odometry(0, 3)[:, :2], [[5, 6], [6, 6], [6, 7]], atol=1e-12)
    # SLAM gives no covariance: its odometry is drawn from the first step.
    slam = RunTrace(np.arange(2.0))
    slam.add(0, f, Estimate(t=0.0, pose=f.odom_pose.copy(), n_eff=1.0))
    assert slam.anchor == 0


def test_rerun_recording_ends_with_the_path_the_rbpf_writes(tmp_path):
    """The Rao-Blackwellized filter writes its final best particle's whole path; the
    recording ends with that path, which the live track need not be."""
    res = runner.invoke(
        app,
        [
            "demo",
            "--duration",
            "8",
            "--filter",
            "rbpf",
            "-o",
            str(tmp_path / "run"),
            "--rerun-save",
            str(tmp_path / "run.rrd"),
        ],
    )
    assert res.exit_code == 0, res.output
    chunks = _chunks(tmp_path / "run.rrd")
    finals = [np.array(s[0]) for s in _column(chunks["/world/trajectory/final"], "LineStrips2D:strips")]
    assert len(finals) == 1
    _, poses = read_tum(tmp_path / "run" / "trajectory.tum")
    np.testing.assert_allclose(finals[0], poses[:, :2], atol=1e-5)  # float32 in the recording


def test_a_localize_recording_holds_its_health(short_office, tmp_path):
    """`pfslam localize --rerun-save`: the quality of every step logged under /health, the
    state in a text log when it changes (here once: tracking from the first update)."""
    d = short_office.lidar_path.parent
    out = tmp_path / "loc"
    res = runner.invoke(
        app,
        [
            "localize",
            str(short_office.lidar_path),
            "--joint",
            str(short_office.joint_path),
            "--map",
            str(d / "map.yaml"),
            "--initial-pose",
            ",".join(f"{v:g}" for v in (*short_office.truth[0, :2], np.rad2deg(short_office.truth[0, 2]))),
            "--rerun-save",
            str(tmp_path / "loc.rrd"),
            "-o",
            str(out),
        ],
    )
    assert res.exit_code == 0, res.output
    chunks = _chunks(tmp_path / "loc.rrd")
    quality = [q for v in _column(chunks["/health/quality"], "Scalars:scalars") for q in v]
    assert len(quality) == len(_column(chunks["/world/particles"], "scan")) > 50
    assert min(quality) > 0.5 and max(quality) <= 1.0
    assert _column(chunks["/health/state"], "TextLog:text") == [["tracking"]]
