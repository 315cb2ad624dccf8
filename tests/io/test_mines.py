"""Mines rover loader and dead reckoning: hand-written lines, errors, garbage, the real exp2.dat."""

import tempfile
from pathlib import Path

import numpy as np
import pytest
from datafiles import need
from hypothesis import given, settings
from hypothesis import strategies as st

from pfslam.errors import InputError
from pfslam.frames import Frame
from pfslam.geometry import txyz
from pfslam.io.common import NOMINAL_LASER_HEIGHT
from pfslam.io.mines import (
    AXLE,
    BEAMS,
    COUNT_RAD,
    MAX_RANGE,
    WHEEL_RADIUS,
    dead_reckoning,
    load_mines,
)

M_PER_COUNT = COUNT_RAD * WHEEL_RADIUS


def mines_line(t_us: int, left: int, right: int, ranges_mm=None) -> str:
    if ranges_mm is None:
        ranges_mm = [0 if k % 3 == 0 else 7 if k == 4 else 1000 + k for k in range(BEAMS)]  # 7: an error code
    fields = [str(t_us), "14554", str(left), str(right)] + ["7"] * 20 + [str(r) for r in ranges_mm] + ["99"]
    assert len(fields) == 707
    return " ".join(fields)


def mines_text(n: int = 5) -> str:
    return "\n".join(mines_line(1_000_000 + 100_000 * i, 500 + 10 * i, 500 + 12 * i) for i in range(n)) + "\n"


def write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "m.dat"
    p.write_text(text)
    return p


def test_hand_written_lines_exact_values(tmp_path):
    log = load_mines(write(tmp_path, mines_text()))
    f = log.frames
    assert len(f) == 5 and log.counts["scans"] == 5 and log.warnings == []
    assert f[0].t == pytest.approx(1.0) and f[1].t - f[0].t == pytest.approx(0.1)
    np.testing.assert_array_equal(f[0].wheels, [0.0, 0.0])  # relative to the first line
    np.testing.assert_allclose(f[4].wheels, np.array([40, 48]) * M_PER_COUNT)
    assert f[0].odom is None
    assert np.isinf(f[0].ranges[0]) and f[0].ranges[1] == pytest.approx(1.001) and f[0].ranges[2] == 1.002
    assert np.isinf(f[0].ranges[4])  # below 20 mm: a URG-04LX error code, no return
    assert len(f[0].ranges) == len(f[0].angles) == BEAMS
    np.testing.assert_allclose(np.rad2deg(f[0].angles[[0, 1]]), [-120, -120 + 360 / 1024])
    assert f[0].angles is f[1].angles
    np.testing.assert_allclose(f[0].mount, txyz(0.145, 0, NOMINAL_LASER_HEIGHT))
    assert f[0].max_range == MAX_RANGE == 4.0 and f[0].min_range == 0.02


def test_encoder_constants():
    # One wheel turn is 4000 counts and 2 pi 0.077 m.
    assert 4000 * M_PER_COUNT == pytest.approx(2 * np.pi * 0.077)
    assert AXLE == pytest.approx(0.33)


def test_time_going_backwards_names_the_line(tmp_path):
    lines = mines_text().splitlines()
    lines.insert(0, "# header comment")
    for k in (1, 2, 3):  # file lines 2..4 move 30 s later: file line 5 is 29.9 s back, and so is line 6
        f = lines[k].split(" ", 1)
        lines[k] = f"{int(f[0]) + 30_000_000} {f[1]}"
    with pytest.raises(InputError, match=r"line 5\b.*backwards by 29.900 s"):
        load_mines(write(tmp_path, "\n".join(lines)))
    lines[1], lines[2] = mines_text().splitlines()[:2]  # only file line 4 is late: one bad stamp, repaired
    log = load_mines(write(tmp_path, "\n".join(lines)))
    t = [x.t for x in log.frames]
    assert len(t) == 5 and np.all(np.diff(t) > 0) and log.counts["time_repaired"] == 1
    np.testing.assert_allclose([t[0], t[1], t[3], t[4]], [1.0, 1.1, 1.3, 1.4])
    assert 1.1 < t[2] < 1.3


def test_bad_lines_are_skipped_with_the_first_line_number(tmp_path):
    lines = mines_text(6).splitlines()
    lines[2] = " ".join(lines[2].split()[:-5])  # line 3: truncated
    lines[4] = lines[4].replace(" 1005 ", " nan ", 1)  # line 5: NaN range
    log = load_mines(write(tmp_path, "\n".join(lines)))
    assert len(log.frames) == 4 and log.counts["skipped_bad"] == 2
    assert len(log.warnings) == 1 and "line 3" in log.warnings[0]


@pytest.mark.parametrize("text", ["", "# nothing\n", "hello\n1 2 3\n", "1 2 3 4\n" * 3])
def test_no_usable_lines(tmp_path, text):
    with pytest.raises(InputError, match="no usable scans"):
        load_mines(write(tmp_path, text))


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        load_mines(tmp_path / "nope.dat")


GARBAGE_TOKENS = ["nan", "abc", "1e999", "-inf", "7", "-3", "0", "", "#"]


def garble(line: str, data) -> str:
    tok = line.split()
    for op, i in data.draw(st.lists(st.tuples(st.integers(0, 3), st.integers(0, 10_000)), max_size=3)):
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


@given(st.data())
@settings(max_examples=100, deadline=None)
def test_garbled_mines_only_raises_input_error(data):
    lines = [garble(ln, data) if data.draw(st.booleans()) else ln for ln in mines_text(4).splitlines()]
    if data.draw(st.booleans()):
        lines = data.draw(st.permutations(lines))
    lines += data.draw(st.lists(st.text(max_size=60).filter(lambda s: "\n" not in s and "\r" not in s), max_size=2))
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "g.dat"
        p.write_text("\n".join(lines), encoding="utf-8", errors="replace")
        try:
            log = load_mines(p)
        except InputError:
            return
    for f in log.frames:
        assert len(f.ranges) == BEAMS and np.isfinite(f.wheels).all() and not np.isnan(f.ranges).any()


# --- dead reckoning ---------------------------------------------------------------------


def frames_from_wheels(w) -> list[Frame]:
    a = np.zeros(1)
    return [Frame(t=float(i), ranges=np.ones(1), angles=a, wheels=np.asarray(x, float)) for i, x in enumerate(w)]


def test_dead_reckoning_straight_and_turn_in_place():
    dr = dead_reckoning(frames_from_wheels([[0, 0], [1, 1], [2, 2]]))
    np.testing.assert_allclose(dr, [[0, 0, 0], [1, 0, 0], [2, 0, 0]], atol=1e-12)
    d = 0.25 * np.pi * AXLE  # each wheel: a quarter turn of the robot is pi/2 * axle/2
    dr = dead_reckoning(frames_from_wheels([[0, 0], [-d, d]]))
    np.testing.assert_allclose(dr[1], [0, 0, np.pi / 2], atol=1e-12)


def test_dead_reckoning_arcs_are_exact():
    # Constant wheel speeds: a circle of radius R, whatever the step size.
    dl, dr_ = 0.9, 1.1
    dth = (dr_ - dl) / AXLE
    radius = 0.5 * (dl + dr_) / dth
    steps = np.arange(11)[:, None] * np.array([[dl, dr_]]) / 10
    fine = dead_reckoning(frames_from_wheels(steps))
    coarse = dead_reckoning(frames_from_wheels(steps[[0, -1]]))
    np.testing.assert_allclose(fine[-1], coarse[-1], atol=1e-12)
    th = np.arange(11) * dth / 10
    np.testing.assert_allclose(fine[:, 0], radius * np.sin(th), atol=1e-12)
    np.testing.assert_allclose(fine[:, 1], radius * (1 - np.cos(th)), atol=1e-12)
    np.testing.assert_allclose(fine[:, 2], th, atol=1e-12)
    assert dead_reckoning([]).shape == (0, 3)


# --- the real log -----------------------------------------------------------------------


@pytest.mark.realdata
def test_real_exp2():
    log = load_mines(need("mines/exp2.dat"))
    f = log.frames
    assert len(f) == 641 and log.counts["skipped_bad"] == 0
    assert all(len(x.ranges) == BEAMS for x in f)
    t = np.array([x.t for x in f])
    assert 62 < t[-1] - t[0] < 64 and np.all(np.diff(t) > 0)
    w = np.array([x.wheels for x in f])
    np.testing.assert_array_equal(w[0], [0, 0])
    # Monotone-ish: both wheels end about 21.5 m ahead (measured 21.47 / 21.70 m); steps back
    # of more than 1 cm are rare (measured 2 % of steps: turns on the spot) and no wheel ever
    # falls more than 0.4 m behind its furthest point (measured 0.24 / 0.40 m).
    assert 20 < w[-1, 0] < 23 and 20 < w[-1, 1] < 23
    assert ((np.diff(w, axis=0) < -0.01).mean(axis=0) < 0.05).all()
    assert (np.maximum.accumulate(w, axis=0) - w).max() < 0.6
    dr = dead_reckoning(f)
    length = np.sum(np.hypot(*np.diff(dr[:, :2], axis=0).T))
    assert 18 < length < 27  # measured 22.2 m
    r = np.concatenate([x.ranges for x in f])
    assert np.isinf(r).mean() > 0.3  # many zeros (no return)
    assert 0.02 <= r[np.isfinite(r)].min() and r[np.isfinite(r)].max() < 5.6


@pytest.mark.parametrize("name", ["rover.log", "rover.txt", "rover"])
def test_mines_log_is_recognised_by_its_content(tmp_path, name):
    from pfslam.io.logs import detect_format, load_log

    p = tmp_path / name
    p.write_text("# recorded on the rover\n" + mines_text(4))
    assert detect_format(p) == "mines"
    assert len(load_log(p).frames) == 4
    p.write_text("1 2 3\n4 5 6\n")  # numbers, but not Mines lines
    with pytest.raises(InputError, match="unknown log format"):
        detect_format(p)
