"""CARMEN loader: hand-written logs with exact values, errors with line numbers, garbage, real logs."""

import gzip
import tempfile
from pathlib import Path

import numpy as np
import pytest
from datafiles import need
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pfslam.errors import ConfigError, InputError
from pfslam.geometry import compose, rz, txyz
from pfslam.io.carmen import NOMINAL_LASER_HEIGHT, flaser_angles, load_carmen

ROBOT = np.array([0.5, -0.25, 0.5])  # robot pose of the ROBOTLASER1 record
LASER = compose(ROBOT, np.array([0.25, 0.05, 0.1]))  # its laser: 0.25 ahead, 0.05 left, turned 0.1 rad
LX, LY, LT = (repr(float(v)) for v in LASER)

SMALL = f"""# a comment
PARAM robot_frontlaser_offset 0.1 0.5 host 0.5

ODOM 0.0 0.0 0.0 0 0 0 1.0 host 1.0
FLASER 4 1.0 2.0 81.83 3.0 1.0 2.0 0.5 1.0 2.0 0.5 2.0 host 2.0
WEIRDRECORD 1 2 3
NEFF 12.5 2.1 host 2.1
   # an indented comment
ROBOTLASER1 0 -1.5 3.0 1.0 20.0 0.01 0 4 1.5 2.5 19.995 0.7 0 {LX} {LY} {LT} 0.5 -0.25 0.5 0.1 0 0 0 0 3.0 host 3.0
ODOM 1.0 0.0 0.1 0 0 0 3.5 host 3.5
ODOM 2.0 0.0 0.3 0 0 0 4.5 host 4.5
RAWLASER1 0 -1.0 2.0 0.5 8.0 0.01 0 5 1 2 3 4 8 2 10 20 4.0 host 4.0
"""


def write(tmp_path: Path, text: str, name: str = "log.txt") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_hand_written_log_exact_values(tmp_path):
    log = load_carmen(write(tmp_path, SMALL))
    assert [f.t for f in log.frames] == [2.0, 3.0, 4.0]
    assert log.counts["unknown"] == 1  # WEIRDRECORD; NEFF (GMapping writes it) is known and unused
    assert log.skipped == {"NEFF": 1} and not any("NEFF" in w for w in log.warnings)
    assert log.counts["FLASER"] == 1 and log.counts["ROBOTLASER1"] == 1 and log.counts["RAWLASER1"] == 1
    assert log.counts["ODOM"] == 3 and log.counts["PARAM"] == 1 and log.counts["skipped_bad"] == 0
    assert log.params == {"robot_frontlaser_offset": "0.1"}
    assert any("WEIRDRECORD" in w for w in log.warnings)

    fl, rl, raw = log.frames
    # FLASER: 4 beams over 180 deg from -90 (even n: step fov/n); 81.83 is "no return".
    np.testing.assert_array_equal(fl.ranges, [1.0, 2.0, np.inf, 3.0])
    np.testing.assert_allclose(np.rad2deg(fl.angles), [-90, -45, 0, 45])
    np.testing.assert_array_equal(fl.odom, [1.0, 2.0, 0.5])
    assert fl.max_range == 80.0
    # Laser pose == odometry pose (corrected log): both are the laser's; the PARAM offset is not applied again.
    np.testing.assert_allclose(fl.mount, txyz(0.0, 0, NOMINAL_LASER_HEIGHT), atol=1e-12)

    # ROBOTLASER1: start + k * res; 19.995 >= 20 - 0.01 is "no return"; mount from the two poses.
    np.testing.assert_allclose(rl.angles, [-1.5, -0.5, 0.5, 1.5])
    np.testing.assert_array_equal(rl.ranges, [1.5, 2.5, np.inf, 0.7])
    np.testing.assert_array_equal(rl.odom, ROBOT)
    np.testing.assert_allclose(rl.mount, txyz(0.25, 0.05, NOMINAL_LASER_HEIGHT) @ rz(0.1), atol=1e-12)
    assert rl.max_range == 20.0

    # RAWLASER1: odometry interpolated between the ODOM records at 3.5 s and 4.5 s.
    np.testing.assert_allclose(raw.odom, [1.5, 0.0, 0.2], atol=1e-12)
    np.testing.assert_allclose(raw.angles, -1.0 + 0.5 * np.arange(5))
    np.testing.assert_array_equal(raw.ranges, [1, 2, 3, 4, np.inf])
    assert raw.max_range == 8.0
    np.testing.assert_allclose(raw.mount, txyz(0.1, 0, NOMINAL_LASER_HEIGHT), atol=1e-12)
    assert log.reference is None  # a RAWLASER scan carries no pose

    # The same file gzipped (even under a plain name) reads the same.
    g = tmp_path / "log.bin"
    g.write_bytes(gzip.compress(SMALL.encode()))
    log2 = load_carmen(g)
    for a, b in zip(log.frames, log2.frames):
        np.testing.assert_array_equal(a.ranges, b.ranges)
        np.testing.assert_array_equal(a.odom, b.odom)


def test_flaser_reference_mount_and_user_overrides(tmp_path):
    odom = np.array([1.0, 1.0, 0.3])
    laser = compose(odom, np.array([0.2, 0.0, 0.0]))
    lp = " ".join(repr(float(v)) for v in laser)
    text = (
        "PARAM robot_frontlaser_offset 0.1 0 h 0\n"
        "PARAM robot_front_laser_max 50.0 0 h 0\n"
        f"FLASER 5 1 49.9 49.995 60 0 {lp} 1.0 1.0 0.3 10.0 h 10.0\n"
        "FLASER 5 1 2 3 4 5 2 2 0 2 2 0 11.0 h 11.0\n"
    )
    log = load_carmen(write(tmp_path, text))
    a, b = log.frames
    np.testing.assert_allclose(a.mount[:3, 3], [0.2, 0.0, NOMINAL_LASER_HEIGHT], atol=1e-12)  # from the poses
    np.testing.assert_allclose(b.mount[:3, 3], [0.0, 0.0, NOMINAL_LASER_HEIGHT])  # equal poses: the laser's
    np.testing.assert_array_equal(a.ranges, [1, 49.9, np.inf, np.inf, np.inf])  # max 50 from the PARAM; 0 = none
    assert a.max_range == 50.0
    np.testing.assert_allclose(np.rad2deg(a.angles), [-90, -45, 0, 45, 90])  # odd n: both ends
    np.testing.assert_allclose(log.reference, [[1.0, 1.0, 0.3], [2.0, 2.0, 0.0]])

    user = load_carmen(write(tmp_path, text), fov_deg=100.0, max_range=3.5)
    np.testing.assert_allclose(np.rad2deg(user.frames[0].angles), [-50, -25, 0, 25, 50])
    np.testing.assert_array_equal(user.frames[1].ranges, [1, 2, 3, np.inf, np.inf])
    assert user.frames[1].max_range == 3.5
    with pytest.raises(ConfigError):
        load_carmen(write(tmp_path, text), fov_deg=0.0)


@pytest.mark.parametrize(
    "n, first, second, last",
    [(180, -90, -89, 89), (181, -90, -89, 90), (360, -90, -89.5, 89.5), (361, -90, -89.5, 90)],
)
def test_flaser_angle_rule(n, first, second, last):
    a = np.rad2deg(flaser_angles(n))
    assert len(a) == n
    np.testing.assert_allclose([a[0], a[1], a[-1]], [first, second, last], atol=1e-9)


def test_time_going_backwards_names_the_line(tmp_path):
    lines = [
        "FLASER 2 1 1 0 0 0 0 0 0 20.0 h 20.0",
        "# comment",
        "FLASER 2 1 1 0 0 0 0 0 0 22.0 h 22.0",
        "ODOM 0 0 0 0 0 0 1.0 h 1.0",  # ODOM time is not a scan time
        "FLASER 2 1 1 0 0 0 0 0 0 8.0 h 8.0",  # line 5: 14 s back ...
        "FLASER 2 1 1 0 0 0 0 0 0 8.5 h 8.5",  # ... and the clock stays back
    ]
    with pytest.raises(InputError, match=r"line 5\b.*backwards by 14.000 s") as e:
        load_carmen(write(tmp_path, "\n".join(lines) + "\n"))
    assert str(tmp_path) in str(e.value)
    # A larger tolerance repairs it: the scans keep their order, after the last good stamp.
    log = load_carmen(write(tmp_path, "\n".join(lines) + "\n"), time_tolerance=20.0)
    t = [f.t for f in log.frames]
    assert t[:2] == [20.0, 22.0] and 22.0 < t[2] < t[3]


def test_small_time_glitch_is_kept_between_its_neighbours(tmp_path):
    # The Intel log has four scans up to 0.86 s earlier than the one before (its poses move on).
    lines = [
        "FLASER 2 1 1 0 0 0 0 0 0 10.0 h 10.0",
        "FLASER 2 1 1 0 0 0 0 0 0 12.0 h 12.0",
        "FLASER 2 1 1 0 0 0 0 0 0 11.5 h 11.5",  # line 3
        "FLASER 2 1 1 0 0 0 0 0 0 12.0005 h 12.0005",  # less than 1 ms after: silently fine
        "FLASER 2 1 1 0 0 0 0 0 0 13.0 h 13.0",
    ]
    log = load_carmen(write(tmp_path, "\n".join(lines)))
    t = [f.t for f in log.frames]
    assert [t[0], t[1], t[3], t[4]] == [10.0, 12.0, 12.0005, 13.0]  # the good stamps are not altered
    assert 12.0 < t[2] < 12.0005  # the glitch: kept in file order, between its neighbours
    assert log.counts["time_repaired"] == 1
    w = [x for x in log.warnings if "time stamp" in x]
    assert len(w) == 1 and "line 3" in w[0] and "1 of 5 scan(s)" in w[0] and "0.500 s" in w[0]
    # A lone glitch is one bad stamp, whatever the tolerance: it is repaired, not fatal.
    assert len(load_carmen(write(tmp_path, "\n".join(lines)), time_tolerance=0.1).frames) == 5


def test_malformed_records_are_skipped_once_per_type(tmp_path):
    good = "FLASER 2 1 1 0 0 0 0 0 0 {t} h {t}"
    lines = [
        good.format(t=1.0),
        "FLASER 3 1 1 0 0 0 0 0 0 2.0 h 2.0",  # line 2: n inconsistent with the length
        "FLASER 2 1 nan 0 0 0 0 0 0 3.0 h 3.0",
        "FLASER 2 1 abc 0 0 0 0 0 0 3.0 h 3.0",
        "ODOM 0 0 1e999 0 0 0 4.0 h 4.0",  # line 5
        "ROBOTLASER1 0 -1 2 1 20 0 0 3 1 2 3 0 0 0 0 0 0 0 0 0 0 0 5.0 h 5.0",  # line 6: one short
        "FLASER",
        "PARAM lonely",
        good.format(t=6.0),
    ]
    log = load_carmen(write(tmp_path, "\n".join(lines)))
    assert [f.t for f in log.frames] == [1.0, 6.0]
    assert log.counts["skipped_bad"] == 7 and log.counts["FLASER"] == 2
    bad = [w for w in log.warnings if "malformed" in w]
    assert len(bad) == 4  # FLASER, ODOM, ROBOTLASER1, PARAM
    assert any("4 malformed FLASER" in w and "line 2" in w for w in bad)
    assert any("ODOM" in w and "line 5" in w for w in bad)
    assert any("ROBOTLASER1" in w and "line 6" in w for w in bad)


def test_rawlaser_before_first_odom_is_skipped(tmp_path):
    text = (
        "RAWLASER1 0 -1.0 2.0 0.5 8.0 0.01 0 2 1 2 0 1.0 h 1.0\n"
        "ODOM 1 2 0.5 0 0 0 2.0 h 2.0\n"
        "RAWLASER1 0 -1.0 2.0 0.5 8.0 0.01 0 2 1 2 0 3.0 h 3.0\n"
    )
    log = load_carmen(write(tmp_path, text))
    assert len(log.frames) == 1 and log.counts["before_first_odom"] == 1
    np.testing.assert_array_equal(log.frames[0].odom, [1, 2, 0.5])  # after the last ODOM: held


@pytest.mark.parametrize(
    "text",
    ["", "\n\n", "# only a comment\n", "ODOM 0 0 0 0 0 0 1 h 1\n", "FLASER 3 1 2\n", "NEFF 1 2 3\n"],
)
def test_no_usable_scans(tmp_path, text):
    with pytest.raises(InputError, match="no usable laser scans"):
        load_carmen(write(tmp_path, text))


def test_missing_binary_and_corrupt_files(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        load_carmen(tmp_path / "nope.log")
    with pytest.raises(InputError, match="not a file"):
        load_carmen(tmp_path)
    b = tmp_path / "bin.log"
    b.write_bytes(bytes(range(256)) * 40)
    with pytest.raises(InputError):
        load_carmen(b)
    b.write_bytes(b"\xff\xfe\xfa" * 2000)  # not UTF-8 at all
    with pytest.raises(InputError):
        load_carmen(b)
    g = tmp_path / "cut.log.gz"
    g.write_bytes(gzip.compress(SMALL.encode() * 50)[:200])  # truncated gzip
    with pytest.raises(InputError):
        load_carmen(g)


# --- garbage never gives a traceback ----------------------------------------------------

GARBAGE_TOKENS = ["nan", "abc", "1e999", "-inf", "inf", "7", "-3", "0", "1e308", "0x1f", "", "FLASER", "#"]


def garble(line: str, data) -> str:
    tok = line.split()
    ops = data.draw(st.lists(st.tuples(st.integers(0, 3), st.integers(0, 10_000)), max_size=4))
    for op, i in ops:
        if not tok:
            break
        i %= len(tok)
        if op == 0:
            del tok[i]
        elif op == 1:
            tok[i] = data.draw(st.sampled_from(GARBAGE_TOKENS))
        elif op == 2:
            tok = tok[:i]
        else:
            tok.insert(i, data.draw(st.sampled_from(GARBAGE_TOKENS)))
    return " ".join(tok)


def garbled_file(text: str, data) -> str:
    lines = [garble(ln, data) if data.draw(st.booleans()) else ln for ln in text.splitlines()]
    if data.draw(st.booleans()):
        lines = data.draw(st.permutations(lines))
    extra = data.draw(st.lists(st.text(max_size=80).filter(lambda s: "\n" not in s and "\r" not in s), max_size=3))
    for e in extra:
        lines.insert(data.draw(st.integers(0, len(lines))), e)
    return "\n".join(lines)


@given(st.data())
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_garbled_carmen_only_raises_input_error(data):
    text = garbled_file(SMALL, data)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "g.log"
        p.write_text(text, encoding="utf-8", errors="replace")
        try:
            log = load_carmen(p)
        except InputError:
            return
    assert log.frames
    t = [f.t for f in log.frames]
    assert t == sorted(t)
    for f in log.frames:
        assert len(f.ranges) == len(f.angles) > 0
        assert np.isfinite(f.odom).all() and np.isfinite(f.angles).all() and np.isfinite(f.mount).all()
        assert not np.isnan(f.ranges).any()


@given(st.binary(max_size=300))
@settings(max_examples=100, deadline=None)
def test_random_bytes_only_raise_input_error(blob):
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "b.log"
        p.write_bytes(blob)
        try:
            load_carmen(p)
        except InputError:
            pass


# --- the real logs -------------------------------------------------------------------------


@pytest.mark.realdata
def test_real_intel_log():
    log = load_carmen(need("carmen/intel.gfs.log.gz"))
    f = log.frames
    assert len(f) == 910 and log.counts["FLASER"] == 910
    assert all(len(x.ranges) == 180 for x in f)
    np.testing.assert_allclose(np.rad2deg(f[0].angles[[0, 1, -1]]), [-90, -89, 89])
    assert f[0].angles is f[-1].angles  # one shared array
    t = np.array([x.t for x in f])
    assert 2600 < t[-1] - t[0] < 2700 and np.all(np.diff(t) > 0)
    assert log.counts["time_repaired"] == 4  # four scans with a glitching clock, kept between their neighbours
    assert log.reference.shape == (910, 3)
    np.testing.assert_array_equal(log.reference, np.array([x.odom for x in f]))
    # No PARAM offset in this file and laser pose == odometry pose: the laser sits at the centre.
    np.testing.assert_allclose(f[0].mount[:3, 3], [0, 0, NOMINAL_LASER_HEIGHT])
    assert f[0].max_range == 80.0
    r = np.concatenate([x.ranges for x in f])
    assert np.isinf(r).sum() > 0 and np.nanmax(r[np.isfinite(r)]) < 80  # 81.83 → no return


@pytest.mark.realdata
def test_real_fr079_log():
    log = load_carmen(need("carmen/fr079.gfs.log.gz"))
    f = log.frames
    assert len(f) == 4791 and all(len(x.ranges) == 360 for x in f)
    np.testing.assert_allclose(np.rad2deg(f[0].angles[[0, 1, -1]]), [-90, -89.5, 89.5])
    assert log.params["robot_frontlaser_offset"] == "-0.04"
    np.testing.assert_allclose(f[0].mount[:3, 3], [0.0, 0, NOMINAL_LASER_HEIGHT])  # corrected: the laser's poses
    assert f[0].max_range == pytest.approx(80.99)  # PARAM robot_front_laser_max
    t = np.array([x.t for x in f])
    assert 1050 < t[-1] - t[0] < 1070 and np.all(np.diff(t) >= 0)
    r = np.concatenate([x.ranges for x in f])
    assert np.isinf(r).any() and r[np.isfinite(r)].max() < 80  # 81.91 → no return
    assert log.reference.shape == (4791, 3)


def test_run_json_says_which_frame_the_poses_are_in(tmp_path):
    """run.json's input.frames: the trajectory is the robot base's, the laser where the log's two
    poses put it in that frame (0.2 m ahead here; at the base itself where they are equal, as in
    a corrected log), the log's own poses the reference."""
    from pfslam.io.logs import load_log
    from pfslam.pipeline.steps import frames_info

    odom = np.array([1.0, 1.0, 0.3])
    laser = compose(odom, np.array([0.2, 0.0, np.deg2rad(5.0)]))
    lp = " ".join(repr(float(v)) for v in laser)
    ahead = write(tmp_path, f"FLASER 3 1 2 3 {lp} 1.0 1.0 0.3 10.0 h 10.0\nFLASER 3 1 2 3 2 2 0 2 2 0 11.0 h 11.0\n")
    info = frames_info(load_log(ahead))
    assert info["trajectory"] == "robot base" and "reference" in info
    np.testing.assert_allclose(info["laser_in_base"], [0.2, 0.0, 5.0], atol=1e-3)
    equal = tmp_path / "equal.log"
    equal.write_text("FLASER 3 1 2 3 2 2 0 2 2 0 11.0 h 11.0\nFLASER 3 1 2 3 2 2 0 2 2 0 12.0 h 12.0\n")
    np.testing.assert_allclose(frames_info(load_log(equal))["laser_in_base"], [0.0, 0.0, 0.0], atol=1e-12)
