"""Real-world log trouble the loaders must survive without a wrong answer: time stamps that
are zero, constant, coarse, stepping back or absurd; a laser's own no-return value; a byte
order mark; a long header; numbers in messages."""

import gzip
import re

import numpy as np
import pytest
from carmen_sim import BEAMS, write_corrected_log

from pfslam.errors import InputError
from pfslam.frames import Frame
from pfslam.io.carmen import load_carmen
from pfslam.io.common import DEFAULT_SCAN_INTERVAL, DETECT_BYTES, SCAN_TIME_TOLERANCE, check_odometry, num
from pfslam.io.logs import detect_format, load_log
from pfslam.io.mines import load_mines
from pfslam.io.readings import find_sentinel
from pfslam.io.times import repair_times
from pfslam.io.trajectory import read_tum, write_tum
from pfslam.pipeline.run import stop_reason

N = 80


def times_of(log):
    return np.array([f.t for f in log.frames])


def time_warnings(log):
    return [w for w in log.warnings if "whose time stamp" in w or "carry no timing" in w]


# --- time stamps without timing ---------------------------------------------------------------


@pytest.mark.parametrize(
    "name, stamp, distinct",
    [
        ("zero", lambda i: 0.0, 1),  # orebro
        ("constant", lambda i: 1018930000.0, 1),  # belgioioso
        ("coarse", lambda i: f"{1134860000 + 150 * i:.6g}", 2),  # csail: %g rounds to 10,000 s
    ],
)
def test_stamps_without_timing_are_replaced_by_the_scan_order(tmp_path, name, stamp, distinct):
    p = tmp_path / f"{name}.log"
    write_corrected_log(p, stamp, n=N)
    log = load_log(p)
    t = times_of(log)
    assert len(t) == N and np.all(np.diff(t) > 0)
    np.testing.assert_allclose(np.diff(t), DEFAULT_SCAN_INTERVAL, rtol=1e-6)
    assert t[0] == float(stamp(0))  # from the first stamp on
    w = time_warnings(log)
    assert len(w) == 1 and f"{distinct} distinct value(s) for {N} scans" in w[0] and "scan order" in w[0]
    assert load_carmen(p).counts["time_from_order"] == N


def test_a_coarse_clock_is_spread_between_its_ticks():
    """40 Hz scans stamped by a clock of 0.1 s: four scans share each stamp."""
    true = 1000.0 + np.arange(400) / 40.0
    r = repair_times("x.log", [("t", np.floor(true * 10.0 + 1e-9) / 10.0)])
    assert np.all(np.diff(r.times) > 0) and r.source == "t"
    np.testing.assert_allclose(r.times, true, atol=1e-9)
    assert r.repaired == 300 and r.kinds == {"repeating": 300}


def test_the_informative_stamp_wins_ipc_or_logger(tmp_path):
    lines = [f"FLASER 2 1.0 1.0 {0.1 * i} 0 0 {0.1 * i} 0 0 0 host {50.0 + 0.25 * i}" for i in range(10)]
    p = tmp_path / "logger.log"
    p.write_text("\n".join(lines) + "\n")
    log = load_carmen(p)
    np.testing.assert_allclose(times_of(log), 50.0 + 0.25 * np.arange(10))  # the logger's clock, as is
    assert not any("time stamp" in w for w in log.warnings)


# --- stepping back, outliers, absurd stamps ----------------------------------------------------


def test_a_step_back_of_1_4_s_is_repaired_with_one_warning(tmp_path):
    """infinite-corridor steps back 1.37 s: it used to be rejected outright."""
    good = 100.0 + 0.5 * np.arange(N)
    stamps = good - np.where(np.arange(N) >= 40, 1.9, 0.0)  # scan 40 is 1.4 s before scan 39, and the clock stays
    p = tmp_path / "back.log"
    write_corrected_log(p, lambda i: stamps[i], n=N)
    log = load_log(p)
    t = times_of(log)
    assert len(t) == N and np.all(np.diff(t) > 0)
    kept = stamps > np.maximum.accumulate(np.concatenate([[-np.inf], stamps[:-1]]))
    np.testing.assert_array_equal(t[kept], stamps[kept])  # the stamps that were fine are not altered
    assert (~kept).sum() == 3  # scans 40 to 42 are behind scan 39
    assert t[39] < t[40] < t[41] < t[42] < t[43] == stamps[43]
    w = time_warnings(log)
    assert len(w) == 1 and "3 of 80 scan(s)" in w[0] and "at most 1.400 s" in w[0] and "line 41" in w[0]
    # With a tolerance below the step it is an error naming the line (the CLI's --time-tolerance).
    with pytest.raises(InputError, match=r"line 41: time goes backwards by 1.400 s"):
        load_log(p, time_tolerance=1.0)


def test_one_absurd_stamp_is_one_skipped_record(tmp_path):
    stamps = [f"{100.0 + 0.5 * i!r}" for i in range(N)]
    stamps[30] = "1e300"
    p = tmp_path / "absurd.log"
    write_corrected_log(p, lambda i: stamps[i], n=N)
    log = load_carmen(p)
    assert len(log.frames) == N - 1 and log.counts["skipped_bad"] == 1 and log.counts["FLASER"] == N - 1
    w = [x for x in log.warnings if "malformed FLASER" in x]
    assert len(w) == 1 and "line 31" in w[0] and "absurd time stamp 1e+300" in w[0]
    np.testing.assert_allclose(times_of(log), np.delete(100.0 + 0.5 * np.arange(N), 30))
    assert not time_warnings(log)


def test_a_lone_outlier_ahead_is_repaired_not_taken_as_the_clock():
    s = np.array([10.0, 10.5, 11.0, 5000.0, 11.5, 12.0])
    r = repair_times("x.log", [("t", s)])
    np.testing.assert_array_equal(r.times[[0, 1, 2, 4, 5]], s[[0, 1, 2, 4, 5]])
    assert 11.0 < r.times[3] < 11.5 and r.repaired == 1 and r.warning("x.log") is not None


def test_repeated_stamps_are_spread_and_the_end_extended_at_the_nominal_step():
    s = np.array([1.0, 1.1, 1.2, 1.2, 1.2, 1.5, 1.6, 1.6, 1.6])
    r = repair_times("x.log", [("t", s)])
    assert np.all(np.diff(r.times) > 0) and r.repaired == 4 and r.extended == 2
    np.testing.assert_allclose(r.times, [1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8])


def test_times_stay_strictly_increasing_where_floats_run_out():
    s = np.array([1e9, 1e9, np.nextafter(1e9, np.inf), 1e9 + 1.0])
    t = repair_times("x.log", [("t", s)]).times
    assert np.all(np.diff(t) > 0)


def test_a_persistent_step_back_past_the_tolerance_is_an_error_naming_the_scan():
    s = np.array([10.0, 11.0, 12.0, 0.5, 1.0, 1.5])
    with pytest.raises(InputError, match=r"scan 4: time goes backwards by 11.500 s"):
        repair_times("x.log", [("t", s)])
    assert SCAN_TIME_TOLERANCE == 10.0
    assert np.all(np.diff(repair_times("x.log", [("t", s)], tolerance=12.0).times) > 0)


# --- a laser's own no-return value --------------------------------------------------------------


def test_a_sentinel_of_50_m_is_no_return(tmp_path):
    """The laser writes 50.0 for beams with no echo (max range of the world: 8 m)."""
    p = tmp_path / "sentinel.log"
    write_corrected_log(p, lambda i: 100.0 + 0.5 * i, n=N, no_return=50.0, max_range=8.0)
    raw = np.array([ln.split()[2 : 2 + BEAMS] for ln in p.read_text().splitlines()], dtype=float)
    assert (raw == 50.0).sum() > 1000 and raw[raw < 50].max() < 8.0
    log = load_carmen(p)
    r = np.array([f.ranges for f in log.frames])
    assert np.all(np.isinf(r[raw == 50.0]))  # every sentinel reading is a no return, none a wall
    np.testing.assert_array_equal(r[raw < 50.0], raw[raw < 50.0])  # every real reading kept
    assert log.frames[0].max_range == 50.0
    w = [x for x in log.warnings if "no return" in x]
    assert len(w) == 1 and "50.00 m" in w[0] and f"{int((raw == 50).sum()):,} at the log's no-return value" in w[0]
    assert log.counts["no_return"] == (raw == 50.0).sum()
    # The user's max_range rules: no detection then.
    assert load_carmen(p, max_range=60.0).frames[0].max_range == 60.0


def test_long_real_returns_are_not_a_sentinel():
    """A thin tail of long single readings (a laser without a sentinel, e.g. Intel's up to
    25 m) is kept: no cluster at the top."""
    rng = np.random.default_rng(0)
    scans = [np.concatenate([rng.uniform(0.5, 8.0, 170), rng.uniform(8.0, 25.0, 10)]).round(2) for _ in range(200)]
    assert find_sentinel(scans) is None
    # ... but a value repeated at the top on many beams of many scans is one.
    for s in scans[::3]:
        s[rng.choice(180, 6, replace=False)] = 51.12
    found = find_sentinel(scans)
    assert found is not None and found.value == 51.12 and found.scans == len(scans[::3])
    # A far wall seen by one beam while the robot stands still is not.
    still = [np.concatenate([rng.uniform(0.5, 8.0, 179), [24.5]]).round(2) for _ in range(100)]
    assert find_sentinel(still) is None


def test_mines_min_and_max_range(tmp_path):
    fields = ["1000000", "0", "500", "500"] + ["0"] * 20
    ranges = ["0", "7", "30", "3999", "4000", "5500"] + ["1000"] * 676
    p = tmp_path / "m.dat"
    p.write_text(" ".join(fields + ranges + ["99"]) + "\n")
    r = load_mines(p).frames[0].ranges
    assert np.isinf(r[[0, 1, 4, 5]]).all() and r[2] == 0.03 and r[3] == 3.999
    r = load_mines(p, min_range=0.05, max_range=5.6).frames[0].ranges
    assert np.isinf(r[[0, 1, 2]]).all() and r[4] == 4.0 and r[5] == 5.5


def test_carmen_min_range(tmp_path):
    p = tmp_path / "min.log"
    p.write_text("FLASER 4 0.0 0.05 0.3 2.0 0 0 0 0 0 0 1.0 h 1.0\n")
    assert np.isinf(load_carmen(p).frames[0].ranges[0]) and load_carmen(p).frames[0].ranges[1] == 0.05
    r = load_carmen(p, min_range=0.1).frames[0].ranges
    assert np.isinf(r[:2]).all() and list(r[2:]) == [0.3, 2.0]


# --- files: byte order mark, long headers -------------------------------------------------------


def test_a_byte_order_mark_loses_no_record(tmp_path):
    p = tmp_path / "bom.log"
    write_corrected_log(p, lambda i: 10.0 + i, n=5, prefix=b"\xef\xbb\xbf")
    assert detect_format(p) == "carmen"
    log = load_log(p)
    assert len(log.frames) == 5 and log.frames[0].t == 10.0 and not log.warnings
    g = tmp_path / "bom.log.gz"
    g.write_bytes(gzip.compress(p.read_bytes()))
    assert len(load_log(g).frames) == 5


def test_a_byte_order_mark_in_a_tum_file(tmp_path):
    write_tum(tmp_path / "a.tum", np.array([1.0, 2.0]), np.array([[1.0, 2.0, 0.3], [2.0, 3.0, 0.4]]))
    q = tmp_path / "bom.tum"
    q.write_bytes(b"\xef\xbb\xbf" + (tmp_path / "a.tum").read_bytes())
    t, poses = read_tum(q)
    np.testing.assert_array_equal(t, [1.0, 2.0])
    np.testing.assert_allclose(poses, [[1.0, 2.0, 0.3], [2.0, 3.0, 0.4]])
    q.write_bytes(b"\xef\xbb\xbf1 0 0 0 0 0 0 1\n")  # a BOM before the first pose, no header
    assert read_tum(q)[0].tolist() == [1.0]


@pytest.mark.parametrize("gz", [False, True])
def test_carmen_is_detected_past_a_first_mib_of_other_records(tmp_path, gz):
    head = ["SYNC 1 2 3 0.1 host 0.1"] * (DETECT_BYTES // 20) + ["# a comment"]
    p = tmp_path / ("long.log.gz" if gz else "long.log")
    text = "\n".join(head + [f"FLASER 2 1 1 0 0 0 0 0 0 {10 + i} h {10 + i}" for i in range(3)]) + "\n"
    assert len(text) > 1.2 * DETECT_BYTES
    p.write_bytes(gzip.compress(text.encode()) if gz else text.encode())
    assert detect_format(p) == "carmen"
    assert len(load_log(p).frames) == 3
    q = tmp_path / "none.log"
    q.write_text("\n".join(head) + "\n")  # nothing known anywhere: still unknown
    with pytest.raises(InputError, match="unknown log format"):
        detect_format(q)


# --- numbers in messages ---------------------------------------------------------------------------

LONG_NUMBER = re.compile(r"[-+0-9.eE]{21,}")


def test_messages_never_print_a_number_longer_than_20_characters(tmp_path):
    messages = []
    huge = "1" + "0" * 299  # a 300-digit stamp: about 1e299
    # CARMEN: a huge but finite stamp is absurd, one bad record; a step back of 1e11 s.
    p = tmp_path / "a.log"
    p.write_text(f"FLASER 2 1 1 0 0 0 0 0 0 {huge} h {huge}\nFLASER 2 1 1 0 0 0 0 0 0 5 h 5\n")
    messages += load_carmen(p).warnings
    p.write_text(
        "FLASER 2 1 1 0 0 0 0 0 0 99999999999 h 99999999999\n"
        "FLASER 2 1 1 0 0 0 0 0 0 -99999999999 h -99999999999\n"
        "FLASER 2 1 1 0 0 0 0 0 0 -99999999998 h -99999999998\n"
    )
    with pytest.raises(InputError) as e:
        load_carmen(p)
    messages.append(str(e.value))
    # Odometry that jumps by 1e300 m.
    frames = [
        Frame(t=1e11, ranges=np.ones(2), angles=np.zeros(2), odom=np.zeros(3)),
        Frame(t=1e11 + 1, ranges=np.ones(2), angles=np.zeros(2), odom=np.array([1e300, 0.0, 0.0])),
    ]
    with pytest.raises(InputError) as e:
        check_odometry("x.log", frames)
    messages.append(str(e.value))
    # TUM: a 300-digit time stamp and a huge step back.
    q = tmp_path / "t.tum"
    q.write_text(f"{huge} 0 0 0 0 0 0 1\n")
    with pytest.raises(InputError) as e:
        read_tum(q)
    messages.append(str(e.value))
    # A run stopped at a frame with an absurd time.
    messages.append(stop_reason(ValueError("boom"), 3, frames[0])[1])
    messages.append(stop_reason(ValueError("boom"), 3, Frame(t=1e300, ranges=np.ones(1), angles=np.zeros(1)))[1])
    for m in messages:
        assert not LONG_NUMBER.search(m), m
    assert "1e+300" in messages[-1] and "absurd time stamp 1e+299" in messages[0]
    assert num(1e300) == "1e+300" and num(12.5) == "12.500" and len(num(-9.99e11, 6)) <= 20


@pytest.mark.parametrize("bad", [0.0, -1.0, float("inf"), float("nan")])
def test_the_time_tolerance_must_be_a_positive_number(tmp_path, bad):
    p = tmp_path / "a.log"
    p.write_text("FLASER 2 1 1 0 0 0 0 0 0 1.0 h 1.0\n")
    with pytest.raises(InputError, match=r"--time-tolerance must be a finite positive number"):
        load_log(p, time_tolerance=bad)


def test_a_laser_record_with_absurd_beam_angles_is_one_malformed_record(tmp_path):
    """Found by the garbled-CARMEN fuzz test: a resolution of 1e308 made beam angles of inf."""
    good = "RAWLASER1 0 -1.5 3.14 {res} 81.9 0.01 0 4 1.5 2.5 3.0 0.7 0 {t} h {t}"
    p = tmp_path / "angles.log"
    p.write_text(
        "ODOM 0 0 0 0 0 0 0.5 h 0.5\n"
        + good.format(res=0.785, t=1.0)
        + "\n"
        + good.format(res="1e308", t=2.0)
        + "\n"
        + good.format(res=0.785, t=3.0)
        + "\n"
    )
    log = load_carmen(p)
    assert len(log.frames) == 2 and log.counts["skipped_bad"] == 1
    assert all(np.isfinite(f.angles).all() for f in log.frames)
    assert any("line 3" in w and "beam angles out of range" in w for w in log.warnings)
