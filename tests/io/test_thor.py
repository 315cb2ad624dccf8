import numpy as np
import pytest
import scipy.io as sio

from pfslam.errors import InputError
from pfslam.geometry import rx, ry, rz, txyz
from pfslam.io.thor import THOR_ANGLES, load_thor, thor_mount, thor_mounts, write_thor
from pfslam.sensor import scan_to_points


def test_mount_matches_the_chain_in_datasets_md():
    roll, pitch, neck, head = 0.03, -0.02, 0.4, 0.3
    want = txyz(0, 0, 0.93) @ ry(pitch) @ rx(roll) @ txyz(0, 0, 0.33) @ rz(neck) @ ry(head) @ txyz(0, 0, 0.15)
    np.testing.assert_allclose(thor_mount(roll, pitch, neck, head), want, atol=1e-12)
    many = thor_mounts(np.array([0.0, roll]), np.array([0.0, pitch]), np.array([0.0, neck]), np.array([0.0, head]))
    np.testing.assert_allclose(many[1], want, atol=1e-12)
    assert many[0][2, 3] == pytest.approx(1.41)


def test_angles_cover_the_utm30lx_field_of_view():
    assert len(THOR_ANGLES) == 1081
    assert np.rad2deg(THOR_ANGLES[0]) == pytest.approx(-135)
    assert np.rad2deg(THOR_ANGLES[540]) == pytest.approx(0)
    assert np.rad2deg(THOR_ANGLES[1] - THOR_ANGLES[0]) == pytest.approx(0.25)


def _write(tmp_path, n=20, layout="penn", joint=True, **over):
    rng = np.random.default_rng(1)
    t = 1.4268e9 + np.arange(n) / 40.0
    pose = np.column_stack([np.linspace(0, 1, n), np.zeros(n), np.linspace(0, 0.2, n)])
    scans = rng.uniform(1, 5, (n, 1081)).astype(np.float32)
    kw = dict(t=t, scans=scans, rpy=np.zeros((n, 3)))
    if layout == "penn":
        kw["pose"] = pose
    else:
        kw["delta_pose"] = np.vstack([pose[:1], np.diff(pose, axis=0)])
    jt = np.linspace(t[0] - 0.3, t[-1] + 0.3, 3 * n)
    head = np.vstack([np.linspace(0, 0.5, 3 * n), np.full(3 * n, 0.2)])
    kw.update(joint_ts=jt, head_angles=head, joint_rpy=np.zeros((3, 3 * n)))
    kw.update(over)
    lp, jp = tmp_path / "train_lidar0.mat", tmp_path / "train_joint0.mat"
    write_thor(lp, jp if joint else None, **kw)
    return lp, jp, t, pose, jt, head


@pytest.mark.parametrize("layout", ["penn", "ucsd"])
def test_round_trip_both_layouts(tmp_path, layout):
    lp, jp, t, pose, jt, head = _write(tmp_path, layout=layout)
    m = sio.loadmat(lp)
    rec = m["lidar"][0][3][0][0]
    assert rec["scan"].shape == (1, 1081) and rec["t"].shape == (1, 1)
    log = load_thor(lp, jp)
    assert log.layout == layout
    assert len(log.frames) == len(t)
    np.testing.assert_allclose([f.t for f in log.frames], t)
    np.testing.assert_allclose(np.array([f.odom for f in log.frames]), pose, atol=1e-9)
    # Joint values are interpolated at the scan times (a different clock).
    f = log.frames[7]
    want = thor_mount(0, 0, np.interp(t[7], jt, head[0]), 0.2)
    np.testing.assert_allclose(f.mount, want, atol=1e-9)
    assert not log.warnings


def test_no_joint_file_warns_once_and_keeps_head_level(tmp_path):
    lp, *_ = _write(tmp_path, joint=False)
    log = load_thor(lp)
    assert len(log.warnings) == 1 and "level" in log.warnings[0]
    np.testing.assert_allclose(log.frames[0].mount, thor_mount(), atol=1e-12)


def test_pitched_head_makes_floor_hits(tmp_path):
    n = 3
    scans = np.full((n, 1081), 2.0, np.float32)  # 2 m at 45 deg down from 1.41 m: below the floor
    lp, jp = tmp_path / "l.mat", tmp_path / "j.mat"
    t = np.arange(n) / 40.0 + 100
    write_thor(
        lp,
        jp,
        t=t,
        scans=scans,
        pose=np.zeros((n, 3)),
        joint_ts=np.array([99.0, 101.0]),
        head_angles=np.array([[0.0, 0.0], [np.pi / 4, np.pi / 4]]),
    )
    f = load_thor(lp, jp).frames[1]
    sp = scan_to_points(f, ground_z=0.15)
    ahead = np.abs(f.angles) < np.deg2rad(30)
    assert len(sp.floor) >= ahead.sum()


def _bad(tmp_path, lidar):
    p = tmp_path / "bad.mat"
    sio.savemat(p, {"lidar": lidar})
    return p


def _cells(recs):
    c = np.empty((1, len(recs)), dtype=object)
    for i, r in enumerate(recs):
        c[0, i] = r
    return c


def _rec(i, scan=None, **over):
    r = {
        "t": np.array([[100.0 + i / 40]]),
        "pose": np.zeros((1, 3)),
        "scan": (np.ones((1, 1081), np.float32) if scan is None else scan),
    }
    r.update(over)
    return r


@pytest.mark.parametrize(
    "recs, words",
    [
        ([{"t": np.array([[1.0]]), "pose": np.zeros((1, 3))}], "no field 'scan'"),
        ([_rec(0), _rec(1, scan=np.ones((1, 1000), np.float32))], "1000 ranges"),
        ([_rec(0, scan=np.full((1, 500), 1.0, np.float32))], "expected 1081"),
        ([_rec(80), _rec(0)], "backwards"),  # 2 s back; small glitches are clamped
        ([{"t": np.array([[1.0]]), "scan": np.ones((1, 1081))}], "no odometry"),
    ],
)
def test_bad_lidar_files(tmp_path, recs, words):
    p = _bad(tmp_path, _cells(recs))
    with pytest.raises(InputError) as e:
        load_thor(p)
    assert words in str(e.value) and "bad.mat" in str(e.value)


def test_invalid_readings_are_no_returns_counted_in_one_warning(tmp_path):
    """NaN, +-inf, negative, zero and beyond-maximum readings stay in the frames (the filters
    drop them); one warning for the log gives every count; the valid beams are untouched."""
    n = 40
    scans = np.full((n, 1081), 4.0, np.float32)
    scans[:, 540] = np.inf  # one +inf ("no return" in ROS) in every scan
    scans[3, 10], scans[17, 11], scans[30, 12] = np.nan, np.nan, np.nan
    scans[5, 20], scans[6, 21] = -1.0, -0.5
    scans[7, 30] = -np.inf
    scans[8, 40] = 0.0
    scans[9, 50] = 31.5
    lp, jp, *_ = _write(tmp_path, n=n, scans=scans)
    log = load_thor(lp, jp)
    assert len(log.frames) == n
    assert len(log.warnings) == 1, log.warnings
    w = log.warnings[0]
    for part in (
        "train_lidar0.mat",
        "48 readings in 40 of 40 scans",
        "3 NaN",
        "40 +inf",
        "1 -inf",
        "2 negative",
        "1 zero",
        "1 beyond 30 m",
        "no returns",
    ):
        assert part in w, (part, w)
    np.testing.assert_array_equal(log.frames[3].ranges, scans[3])  # kept as read, NaN included
    for f, s in zip(log.frames, scans):
        pts = scan_to_points(f)
        assert len(pts.hits) + len(pts.floor) == int((np.isfinite(s) & (s > 0.1) & (s < 30.0)).sum())


def test_zeros_and_readings_past_the_maximum_alone_warn_nothing(tmp_path):
    """Zeros (the UTM-30LX's error code, the simulator's dropouts) and readings at or past 30 m
    are how THOR logs say "no return": no warning for them alone."""
    n = 10
    scans = np.full((n, 1081), 4.0, np.float32)
    scans[:, 0], scans[:, 1], scans[:, 2] = 0.0, 30.0, 45.0
    lp, jp, *_ = _write(tmp_path, n=n, scans=scans)
    assert load_thor(lp, jp).warnings == []


def test_not_a_mat_file(tmp_path):
    p = tmp_path / "scan.mat"
    p.write_text("hello")
    with pytest.raises(InputError, match="not a MATLAB"):
        load_thor(p)


def test_joint_ts_not_increasing(tmp_path):
    lp, _, t, *_ = _write(tmp_path)
    jp = tmp_path / "j.mat"
    ts = np.linspace(t[0], t[-1], 10)
    ts[5] = ts[3] - 2.0  # 2 s back: an error (a duplicate or a small step back is dropped)
    sio.savemat(jp, {"ts": ts[None], "head_angles": np.zeros((2, 10))})
    with pytest.raises(InputError, match="not increasing") as e:
        load_thor(lp, jp)
    assert "j.mat" in str(e.value)


def test_joint_file_missing_variable(tmp_path):
    lp, *_ = _write(tmp_path)
    jp = tmp_path / "j.mat"
    sio.savemat(jp, {"ts": np.arange(3.0)[None]})
    with pytest.raises(InputError, match="head_angles"):
        load_thor(lp, jp)


# --- the one-pass reader (ranges left on disk) against SciPy's whole-file reading ---------


def _compressed(path):
    m = {k: v for k, v in sio.loadmat(path).items() if not k.startswith("__")}
    out = path.with_name("z_" + path.name)
    sio.savemat(out, m, do_compression=True)
    return out


def _assert_same_logs(a, b):
    assert len(a.frames) == len(b.frames) and a.layout == b.layout and a.warnings == b.warnings
    for x, y in zip(a.frames, b.frames):
        assert x.t == y.t and x.ranges.dtype == y.ranges.dtype == np.float32
        np.testing.assert_array_equal(x.ranges, y.ranges)
        np.testing.assert_array_equal(x.odom, y.odom)
        np.testing.assert_array_equal(x.mount, y.mount)
        np.testing.assert_array_equal(x.angles, y.angles)


@pytest.mark.parametrize("layout", ["penn", "ucsd"])
@pytest.mark.parametrize("compressed", [False, True], ids=["plain", "compressed"])
def test_the_one_pass_reader_reads_what_scipy_reads(tmp_path, monkeypatch, layout, compressed):
    from pfslam.frames import FileRows
    from pfslam.io import thor

    lp, jp, *_ = _write(tmp_path, n=30, layout=layout)
    if compressed:
        lp = _compressed(lp)
    streamed = load_thor(lp, jp)
    assert isinstance(streamed.frames.ranges, FileRows)  # not held in memory
    monkeypatch.setattr(thor, "_stream_lidar", lambda path: None)
    _assert_same_logs(streamed, load_thor(lp, jp))


@pytest.mark.parametrize("compressed", [False, True], ids=["plain", "compressed"])
def test_records_of_other_types_and_nesting_read_alike(tmp_path, monkeypatch, compressed):
    """Cells wrapped in 1x1 cells, fields in another order, a text field, a double scan, an
    integer time stamp and a small (4-byte) pose element: read as SciPy reads them."""
    from pfslam.io import thor

    rng = np.random.default_rng(4)
    recs = []
    for i in range(12):
        rec = {
            "name": "utm",
            "scan": rng.uniform(0.5, 20, (1, 1081)) if i % 2 else rng.uniform(0.5, 20, (1, 1081)).astype(np.float32),
            "pose": np.array([[0.1 * i, 0.0, 0.01 * i]]),
            "t": np.array([[1000 + i]], dtype=np.uint32),
        }
        if i == 5:
            rec["scan"][0, 7] = np.nan
        recs.append(rec)
    cells = np.empty((1, len(recs)), dtype=object)
    for i, r in enumerate(recs):
        inner = np.empty((1, 1), dtype=object)
        inner[0, 0] = r
        cells[0, i] = inner if i % 3 == 0 else r
    p = tmp_path / "odd.mat"
    sio.savemat(p, {"lidar": cells, "other": np.arange(5.0)}, do_compression=compressed)
    streamed = load_thor(p)
    monkeypatch.setattr(thor, "_stream_lidar", lambda path: None)
    ref = load_thor(p)
    _assert_same_logs(streamed, ref)
    assert any("1 NaN" in w for w in streamed.warnings)


def test_a_struct_array_is_read_by_scipy_and_gives_the_same_frames(tmp_path):
    from pfslam.frames import FileRows

    lp, jp, *_ = _write(tmp_path, n=10)
    cells = sio.loadmat(lp)["lidar"]
    fields = cells[0, 0].dtype.names
    arr = np.zeros((1, cells.shape[1]), dtype=[(f, object) for f in fields])
    for i in range(cells.shape[1]):
        for f in fields:
            arr[0, i][f] = cells[0, i][0, 0][f]
    sp = tmp_path / "structs.mat"
    sio.savemat(sp, {"lidar": arr})
    a, b = load_thor(lp, jp), load_thor(sp, jp)
    assert isinstance(a.frames.ranges, FileRows) and isinstance(b.frames.ranges, np.ndarray)
    _assert_same_logs(a, b)


def test_loading_keeps_no_ranges_in_memory(tmp_path):
    """4,000 scans hold 17 MB of ranges; loading them allocates less than a fifth of that at its
    peak (times, odometry, mounts: a few hundred bytes a scan), and no more for a compressed
    file (inflated to a temporary file, not to memory)."""
    import tracemalloc

    n = 4000
    lp, jp, *_ = _write(tmp_path, n=n)
    ranges_bytes = n * 1081 * 4
    for path in (lp, _compressed(lp)):
        tracemalloc.start()
        log = load_thor(path, jp)
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        assert len(log.frames) == n
        assert peak < ranges_bytes / 5, (path.name, peak, ranges_bytes)
        del log
