"""CARMEN and Mines loaders, synthetic odometry: hand-written files, garbage, and the real logs."""

import gzip

import numpy as np
import pytest
from datafiles import need
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pfslam.errors import InputError
from pfslam.eval.metrics import trajectory_errors
from pfslam.io.carmen import load_carmen
from pfslam.io.logs import load_log
from pfslam.io.mines import BEAMS, COUNT_RAD, WHEEL_RADIUS, dead_reckoning, load_mines
from pfslam.io.synthetic import parse_odometry_option, synthetic_odometry

SMALL = """# a comment
PARAM robot_frontlaser_offset 0.1 1.0 host 1.0
PARAM robot_front_laser_max 50.0 1.0 host 1.0
ODOM 0.0 0.0 0.0 0 0 0 1.0 host 1.0
FLASER 4 1.0 2.0 80.5 3.0 1.0 2.0 0.5 1.0 2.0 0.5 2.0 host 2.0
WEIRDRECORD 1 2 3
ROBOTLASER1 0 -1.5 3.0 1.0 20.0 0.01 0 4 1.5 2.5 20.0 0.7 0 0.2193956405 0.1198563847 0.5 0.0 0.0 0.5 0 0 0 0 0 3.0 host 3.0
ODOM 1.0 0.0 0.1 0 0 0 3.5 host 3.5
RAWLASER1 0 -1.0 2.0 0.5 8.0 0.01 0 5 1 2 3 4 8 0 4.0 host 4.0
"""


def test_hand_written_carmen(tmp_path):
    p = tmp_path / "small.log"
    p.write_text(SMALL)
    log = load_carmen(p)
    assert [round(f.t, 3) for f in log.frames] == [2.0, 3.0, 4.0]
    assert log.counts["unknown"] == 1 and log.counts["FLASER"] == 1
    f0, f1, f2 = log.frames
    np.testing.assert_allclose(f0.ranges[:2], [1.0, 2.0])
    assert np.isinf(f0.ranges[2]) and f0.ranges[3] == 3.0  # 80.5 >= PARAM max 50: no return
    np.testing.assert_allclose(np.rad2deg(f0.angles), [-90, -45, 0, 45])  # 4 beams over 180 deg
    np.testing.assert_allclose(f0.odom, [1.0, 2.0, 0.5])
    assert f0.mount[0, 3] == pytest.approx(0.0)  # laser pose == odometry: both the laser's, no PARAM offset
    np.testing.assert_allclose(f1.angles, [-1.5, -0.5, 0.5, 1.5])
    assert np.isinf(f1.ranges[2])  # 20.0 == max_range
    np.testing.assert_allclose(f1.mount[:2, 3], [0.25, 0.0], atol=1e-9)  # laser 0.25 m ahead
    np.testing.assert_allclose(f2.odom, [1.0, 0.0, 0.1])  # latest ODOM before the RAWLASER
    np.testing.assert_allclose(f2.angles, -1.0 + 0.5 * np.arange(5))
    assert np.isinf(f2.ranges[4])
    # The same file gzipped reads the same.
    g = tmp_path / "small.log.gz"
    g.write_bytes(gzip.compress(SMALL.encode()))
    assert len(load_carmen(g).frames) == 3


def test_time_going_backwards_is_reported_with_its_line(tmp_path):
    lines = SMALL.splitlines()
    lines.append("FLASER 2 1.0 1.0 0 0 0 0 0 0 3.5 host 3.5")  # line 10: 0.5 s earlier than 4.0
    p = tmp_path / "back.log"
    p.write_text("\n".join(lines) + "\n")
    log = load_carmen(p)
    assert len(log.frames) == 4 and log.frames[-1].t > log.frames[-2].t  # kept, after the previous scan
    assert any("line 10" in w for w in log.warnings)
    lines[-1] = "FLASER 2 1.0 1.0 0 0 0 0 0 0 -11.5 host -11.5"  # 15.5 s back, and the last: not a glitch
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match="line 10"):
        load_carmen(p)


@pytest.mark.parametrize("text", ["", "# only a comment\n", "ODOM 0 0 0 0 0 0 1 h 1\n", "FLASER 3 1 2\n"])
def test_no_usable_scans(tmp_path, text):
    p = tmp_path / "empty.log"
    p.write_text(text)
    with pytest.raises(InputError, match="no usable laser scans"):
        load_carmen(p)


def test_missing_and_binary_files(tmp_path):
    with pytest.raises(InputError, match="not found"):
        load_carmen(tmp_path / "nope.log")
    b = tmp_path / "bin.log"
    b.write_bytes(b"\x00\x01\x02" * 100)
    with pytest.raises(InputError):
        load_carmen(b)


def _garble(line: str, data) -> str:
    tok = line.split()
    ops = data.draw(st.lists(st.tuples(st.integers(0, 3), st.integers(0, 400)), max_size=4))
    for op, i in ops:
        if not tok:
            break
        i %= len(tok)
        if op == 0:
            del tok[i]
        elif op == 1:
            tok[i] = data.draw(st.sampled_from(["nan", "abc", "1e999", "-inf", "", "7"]))
        elif op == 2:
            tok = tok[:i]
        else:
            tok.insert(i, "0.5")
    return " ".join(tok)


@given(st.data())
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_garbled_carmen_never_crashes(tmp_path, data):
    lines = [_garble(ln, data) if data.draw(st.booleans()) else ln for ln in SMALL.splitlines()]
    lines += data.draw(st.lists(st.text(max_size=60).filter(lambda s: "\n" not in s and "\r" not in s), max_size=3))
    p = tmp_path / "g.log"
    p.write_text("\n".join(lines), encoding="utf-8", errors="replace")
    try:
        log = load_carmen(p)
    except InputError:
        return
    for f in log.frames:
        assert len(f.ranges) == len(f.angles) and np.isfinite(f.odom).all()


MINES_LINE = "{t} 14554 {l} {r} " + " ".join(["0"] * 20) + " {ranges} 0"


def _mines_text(n=5):
    out = []
    for i in range(n):
        ranges = " ".join(str(1000 + k) if k % 3 else "0" for k in range(BEAMS))
        out.append(MINES_LINE.format(t=1_000_000 + 100_000 * i, l=500 + 10 * i, r=500 + 12 * i, ranges=ranges))
    return "\n".join(out) + "\n"


def test_hand_written_mines(tmp_path):
    p = tmp_path / "m.dat"
    p.write_text(_mines_text())
    log = load_mines(p)
    f = log.frames
    assert len(f) == 5 and f[1].t - f[0].t == pytest.approx(0.1)
    np.testing.assert_allclose(f[4].wheels, np.array([40, 48]) * COUNT_RAD * WHEEL_RADIUS)
    assert np.isinf(f[0].ranges[0]) and f[0].ranges[1] == pytest.approx(1.001)
    assert len(f[0].angles) == BEAMS and np.rad2deg(f[0].angles[0]) == pytest.approx(-120)
    assert f[0].mount[0, 3] == pytest.approx(0.145)
    assert load_log(p).format == "mines"


def test_mines_time_backwards_and_garbage(tmp_path):
    lines = _mines_text().splitlines()
    f = lines[2].split(" ", 1)
    lines[2] = f"{int(f[0]) - 30_000_000} {f[1]}"  # line 3 goes 30 s back (small glitches are repaired)
    lines[3:] = [f"{int(ln.split(' ', 1)[0]) - 30_000_000} {ln.split(' ', 1)[1]}" for ln in lines[3:]]  # and stays
    p = tmp_path / "m.dat"
    p.write_text("\n".join(lines))
    with pytest.raises(InputError, match="line 3"):
        load_mines(p)
    p.write_text("hello\n1 2 3\n")
    with pytest.raises(InputError, match="no usable scans"):
        load_mines(p)


@given(st.data())
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_garbled_mines_never_crashes(tmp_path, data):
    lines = [_garble(ln, data) for ln in _mines_text(3).splitlines()]
    p = tmp_path / "g.dat"
    p.write_text("\n".join(lines))
    try:
        log = load_mines(p)
    except InputError:
        return
    assert all(len(f.ranges) == BEAMS for f in log.frames)


def test_synthetic_odometry_is_seeded_and_drifts_only_when_moving():
    ref = np.zeros((200, 3))
    ref[:, 0] = np.linspace(0, 100, 200)  # 100 m straight
    a, b, c = synthetic_odometry(ref, 3), synthetic_odometry(ref, 3), synthetic_odometry(ref, 4)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    np.testing.assert_allclose(a[0], ref[0])
    heading = abs(np.rad2deg(a[-1, 2]))
    assert 5 < heading < 60  # about 0.25 deg/m over 100 m
    still = np.tile([[1.0, 2.0, 0.3]], (50, 1))
    np.testing.assert_allclose(synthetic_odometry(still, 1), still)
    assert parse_odometry_option("synthetic:7") == ("synthetic", 7)
    assert parse_odometry_option("log") == ("log", 0)
    with pytest.raises(ValueError):
        parse_odometry_option("magic")


@pytest.mark.realdata
def test_real_intel_and_fr079_logs():
    intel = load_log(need("carmen/intel.gfs.log.gz"), odometry="synthetic:0")
    assert len(intel.frames) == 910 and len(intel.frames[0].ranges) == 180
    assert any("line" in w and "back" in w for w in intel.warnings)  # 4 scans step back in time
    t = np.array([f.t for f in intel.frames])
    assert 2600 < t[-1] - t[0] < 2700
    odo = np.array([f.odom for f in intel.frames])
    assert trajectory_errors(t, odo, t, intel.reference).ate_rmse >= 1.0
    fr = load_carmen(need("carmen/fr079.gfs.log.gz"))
    assert len(fr.frames) == 4791 and len(fr.frames[0].ranges) == 360
    assert fr.frames[0].mount[0, 3] == pytest.approx(0.0)  # corrected: its poses are the laser's (PARAM -0.04 unused)
    np.testing.assert_allclose(np.rad2deg(fr.frames[0].angles[[0, 1]]), [-90, -89.5])


@pytest.mark.realdata
def test_real_mines_log():
    log = load_mines(need("mines/exp2.dat"))
    assert len(log.frames) == 641 and 62 < log.frames[-1].t - log.frames[0].t < 64
    dr = dead_reckoning(log.frames)
    length = np.sum(np.hypot(*np.diff(dr[:, :2], axis=0).T))
    assert 15 < length < 30
