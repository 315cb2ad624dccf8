"""Loaders on bad input: corrupt .mat and gzip files, messy time stamps, implausible odometry."""

import gzip
import zlib

import numpy as np
import pytest
import scipy.io as sio

from pfslam.errors import InputError
from pfslam.frames import Frame
from pfslam.io import carmen, common, mines
from pfslam.io.carmen import load_carmen
from pfslam.io.common import SCAN_TIME_TOLERANCE, TIME_TOLERANCE, check_odometry
from pfslam.io.logs import detect_format, load_log
from pfslam.io.mines import BEAMS, load_mines
from pfslam.io.thor import load_thor, write_thor

# --- small files ------------------------------------------------------------------------


def thor(tmp_path, t, pose=None, joint_ts=None, name="train_lidar0.mat", **kw):
    t = np.asarray(t, dtype=float)
    n = len(t)
    if pose is None and "delta_pose" not in kw:
        pose = np.column_stack([np.linspace(0, 0.5, n), np.zeros(n), np.zeros(n)])
    lp, jp = tmp_path / name, tmp_path / "train_joint0.mat"
    scans = np.full((n, 1081), 3.0, np.float32)
    if joint_ts is not None:
        m = len(joint_ts)
        kw.update(joint_ts=np.asarray(joint_ts, float), head_angles=np.vstack([np.linspace(0, 0.3, m), np.zeros(m)]))
    write_thor(lp, jp if joint_ts is not None else None, t=t, scans=scans, pose=pose, **kw)
    return lp, jp


def flaser(t, x=0.0, y=0.0, lx=None):
    lx = x if lx is None else lx
    return f"FLASER 2 1.0 1.0 {lx} {y} 0 {x} {y} 0 {t} h {t}"


def write_carmen(tmp_path, lines, name="log.txt"):
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


def mines_line(t_s, left=500, right=500):
    fields = [str(round(t_s * 1e6)), "14554", str(left), str(right)] + ["7"] * 20 + ["1000"] * BEAMS + ["99"]
    return " ".join(fields)


def write_mines(tmp_path, lines, name="m.dat"):
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


# --- 1. unreadable .mat files -----------------------------------------------------------


def test_mat_shorter_than_its_header_is_input_error(tmp_path):
    lp, jp = thor(tmp_path, 100 + np.arange(5) / 40, joint_ts=100 + np.arange(10) / 50)
    short = tmp_path / "short.mat"
    short.write_bytes(lp.read_bytes()[:100])  # starts with "MATLAB" but scipy raised IndexError
    with pytest.raises(InputError, match="not a readable MATLAB file") as e:
        load_log(short)
    assert "short.mat" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(InputError, match="not a readable MATLAB file") as e:
        load_log(lp, short)  # the same as a joint file
    assert "short.mat" in str(e.value)


@pytest.mark.parametrize(
    "exc",
    [
        IndexError("index out of range"),
        ValueError("bad\nsecond line"),
        TypeError("x"),
        zlib.error("Error -3"),
        EOFError(),
        MemoryError(),
    ],
)
def test_any_loadmat_failure_becomes_one_line_input_error(tmp_path, monkeypatch, exc):
    """SciPy reads the joint file (the lidar file is read record by record without it)."""
    lp, jp = thor(tmp_path, 100 + np.arange(3) / 40, joint_ts=100 + np.arange(10) / 50)

    def broken(*a, **k):
        raise exc

    monkeypatch.setattr("scipy.io.loadmat", broken)
    assert len(load_thor(lp).frames) == 3
    with pytest.raises(InputError, match="not a readable MATLAB file") as e:
        load_thor(lp, jp)
    assert type(exc).__name__ in str(e.value) and jp.name in str(e.value) and "\n" not in str(e.value)


def test_compressed_mat_with_corrupt_body_is_input_error(tmp_path):
    p = tmp_path / "c.mat"
    sio.savemat(p, {"lidar": np.zeros((50, 50))}, do_compression=True)
    raw = bytearray(p.read_bytes())
    raw[140:] = b"\xff" * (len(raw) - 140)  # keep the 128-byte header and the tag; break the zlib data
    p.write_bytes(bytes(raw))
    with pytest.raises(InputError, match="not a readable MATLAB file"):
        load_log(p)


# --- 2. corrupt gzip --------------------------------------------------------------------


def corrupt_gz(text: str) -> bytes:
    good = gzip.compress(text.encode())
    return good[:10] + b"\xff" * 200  # valid gzip header, deflate data with an invalid block type


def test_gzip_with_corrupt_body_is_input_error_everywhere(tmp_path):
    text = "\n".join(flaser(10 + i) for i in range(20))
    g = tmp_path / "log.gz"
    g.write_bytes(corrupt_gz(text))
    for load in (detect_format, load_log, load_carmen, load_mines):
        with pytest.raises(InputError, match="corrupt gzip data") as e:
            load(g)
        assert "log.gz" in str(e.value)
    # Truncated (EOFError) too, and a Mines file read as gzip.
    m = tmp_path / "m.dat.gz"
    m.write_bytes(gzip.compress("\n".join(mines_line(1 + i / 10) for i in range(30)).encode())[:300])
    for load in (load_log, load_mines):
        with pytest.raises(InputError, match="corrupt gzip data"):
            load(m)


# --- 3. time stamps: one rule for all loaders ----------------------------------------------

MESSY = [10.0, 10.5, 10.2, 10.5, 11.0, 11.0, 11.3]  # a swapped pair, a duplicate, a repeat
GOOD = [0, 1, 4, 6]  # the scans whose stamps advance: they keep them


def load_times(tmp_path, fmt, times):
    if fmt == "thor":
        return load_log(thor(tmp_path, times)[0])
    if fmt == "carmen":
        return load_log(write_carmen(tmp_path, [flaser(t) for t in times]))
    return load_log(write_mines(tmp_path, [mines_line(t) for t in times]))


@pytest.mark.parametrize("fmt", ["thor", "carmen", "mines"])
def test_messy_time_stamps_are_kept_strictly_increasing_with_one_warning(tmp_path, fmt):
    log = load_times(tmp_path, fmt, MESSY)
    t = np.array([f.t for f in log.frames])
    assert len(t) == len(MESSY) and np.all(np.diff(t) > 0)  # every scan kept, in file order
    np.testing.assert_allclose(t[GOOD], np.array(MESSY)[GOOD], atol=1e-6)  # good stamps unaltered
    assert t[2] < 11.0 and t[5] < 11.3  # the others between their neighbours
    w = [x for x in log.warnings if "time stamp" in x]
    assert len(w) == 1 and "3 " in w[0].split(": ")[1][:12] and "0.300 s" in w[0]


@pytest.mark.parametrize(
    "fmt, where, tolerance",
    [
        ("thor", r"lidar\{4\}", TIME_TOLERANCE),
        ("carmen", r"line 4\b", SCAN_TIME_TOLERANCE),
        ("mines", r"line 4\b", SCAN_TIME_TOLERANCE),
    ],
)
def test_time_jumping_back_past_the_tolerance_names_the_scan(tmp_path, fmt, where, tolerance):
    assert (
        TIME_TOLERANCE == 1.0
        and SCAN_TIME_TOLERANCE == 10.0
        and carmen.SCAN_TIME_TOLERANCE is common.SCAN_TIME_TOLERANCE
    )
    back = 12.0 - 0.99 * tolerance
    ok = load_times(tmp_path, fmt, [10.0, 11.0, 12.0, back, back + 0.5, 13.0])
    assert len(ok.frames) == 6 and np.all(np.diff([f.t for f in ok.frames]) > 0)
    back = 12.0 - 1.01 * tolerance
    with pytest.raises(InputError, match=where + rf".*backwards by {1.01 * tolerance:.3f} s") as e:
        load_times(tmp_path, fmt, [10.0, 11.0, 12.0, back, back + 0.5, 13.0])
    assert str(tmp_path) in str(e.value)


def test_joint_duplicates_and_swaps_are_dropped_but_a_big_jump_is_an_error(tmp_path):
    t = 100 + np.arange(20) / 40
    jt = np.linspace(99.9, 100.6, 30)
    jt[10] = jt[9]  # duplicate
    jt[20], jt[21] = jt[21], jt[20]  # swapped pair
    lp, jp = thor(tmp_path, t, joint_ts=jt)
    log = load_thor(lp, jp)
    w = [x for x in log.warnings if "joint sample" in x]
    assert len(w) == 1 and "dropped 2 joint sample(s)" in w[0] and "train_joint0.mat" in w[0]
    assert len(log.frames) == 20
    jt[25] = jt[24] - 1.5  # far back: an error naming the sample
    lp, jp = thor(tmp_path, t, joint_ts=jt)
    with pytest.raises(InputError, match="not increasing at sample 26") as e:
        load_thor(lp, jp)
    assert "train_joint0.mat" in str(e.value)


# --- 4. format detection past a long header ------------------------------------------------


def test_carmen_detected_after_long_comment_and_unknown_record_header(tmp_path):
    head = ["# " + "x" * 100] * 60 + ["SYNC 1 2 3 0.1 host 0.1"] * 3000  # about 100 kB before any record
    p = write_carmen(tmp_path, head + [flaser(10 + i) for i in range(5)], name="long.log")
    assert detect_format(p) == "carmen"
    log = load_log(p)
    assert log.format == "carmen" and len(log.frames) == 5
    q = write_carmen(tmp_path, head, name="nothing.log")
    with pytest.raises(InputError, match="unknown log format"):
        detect_format(q)


# --- 5. joint file of another run ------------------------------------------------------------


def test_joint_file_not_overlapping_the_lidar_is_an_error(tmp_path):
    t = 100 + np.arange(20) / 40
    lp, jp = thor(tmp_path, t, joint_ts=np.linspace(1000, 1010, 30))
    with pytest.raises(InputError, match="do not overlap the lidar") as e:
        load_log(lp, jp)
    assert str(e.value).startswith(str(jp))
    lp, jp = thor(tmp_path, t, joint_ts=np.linspace(100.3, 110, 30))  # partial overlap: a warning only
    assert any("cover only" in w for w in load_log(lp, jp).warnings)


# --- 6. implausible odometry and mounts --------------------------------------------------------


def test_thor_pose_jump_is_an_error(tmp_path):
    t = 100 + np.arange(8) / 40
    pose = np.zeros((8, 3))
    pose[3, 0] = 1e7
    with pytest.raises(InputError, match=r"odometry jumps 10000000 m in 0.025 s between scans 3 and 4"):
        load_log(thor(tmp_path, t, pose=pose)[0])


def test_ucsd_delta_pose_overflowing_to_inf_is_an_error(tmp_path):
    t = 100 + np.arange(4) / 40
    dp = np.zeros((4, 3))
    dp[1:3, 0] = 1e308  # each finite, the accumulated pose is not
    with pytest.raises(InputError, match=r"scan 3 .*not finite"):
        load_log(thor(tmp_path, t, delta_pose=dp)[0])


def test_carmen_pose_jump_and_far_laser_are_errors(tmp_path):
    lines = [flaser(10 + i, x=0.1 * i) for i in range(6)]
    lines[4] = flaser(14, x=1e7)
    with pytest.raises(InputError, match="odometry jumps .* between scans 4 and 5 .t=13.000"):
        load_log(write_carmen(tmp_path, lines))
    lines[4] = flaser(14, x=0.4, lx=1e7)  # laser pose far from the odometry pose
    with pytest.raises(InputError, match="scan 5 .*mounted"):
        load_log(write_carmen(tmp_path, lines))


def test_fast_but_plausible_motion_passes(tmp_path):
    # 90 m in 1 s (under 100 m) and 400 m in 10 s (under 50 m/s) are not jumps.
    lines = [flaser(0, x=0), flaser(1, x=90), flaser(11, x=490)]
    assert len(load_log(write_carmen(tmp_path, lines)).frames) == 3
    lines.append(flaser(12, x=591))  # 101 m in 1 s
    with pytest.raises(InputError, match="odometry jumps 101 m in 1.000 s between scans 3 and 4"):
        load_log(write_carmen(tmp_path, lines))


def test_param_laser_offset_too_large_names_the_param(tmp_path):
    lines = ["PARAM robot_frontlaser_offset 1e9 0 host 0"] + [flaser(10 + i) for i in range(3)]
    with pytest.raises(InputError, match="PARAM robot_frontlaser_offset 1e9"):
        load_log(write_carmen(tmp_path, lines))
    lines[0] = "PARAM robot_frontlaser_offset -9.5 0 host 0"  # plausible: read (RAWLASER1 records use it)
    assert len(load_log(write_carmen(tmp_path, lines)).frames) == 3


def test_mines_encoder_jump_and_huge_wheel_scale_are_errors(tmp_path):
    lines = [mines_line(1 + i / 10, 500 + 10 * i, 500 + 12 * i) for i in range(6)]
    p = write_mines(tmp_path, lines)
    assert len(load_log(p).frames) == 6
    with pytest.raises(InputError, match="odometry jumps .* between scans 1 and 2"):
        load_log(p, wheel_scale=1e12)
    lines[3] = mines_line(1.3, 10**12, 10**12)
    with pytest.raises(InputError, match="odometry jumps .* between scans 3 and 4"):
        load_log(write_mines(tmp_path, lines))


def test_non_finite_wheels_name_the_scan():
    frames = [
        Frame(t=float(i), ranges=np.ones(1), angles=np.zeros(1), wheels=np.array([0.0, w]))
        for i, w in enumerate([0.0, 0.1, np.nan])
    ]
    with pytest.raises(InputError, match=r"x.dat: scan 3 \(t=2.000\): wheel travel is not finite"):
        check_odometry("x.dat", frames)


# --- 7. --wheel-scale ---------------------------------------------------------------------------


@pytest.mark.parametrize("scale", [float("inf"), float("nan"), 0.0, -2.0])
def test_wheel_scale_must_be_finite_and_positive(tmp_path, scale):
    p = write_mines(tmp_path, [mines_line(1 + i / 10) for i in range(3)])
    with pytest.raises(InputError) as e:
        load_log(p, wheel_scale=scale)
    assert str(e.value) == f"{p}: --wheel-scale must be a finite positive number, not {scale}"
    assert mines.load_mines(p, wheel_scale=2.0).frames  # the loader itself still takes a finite scale
