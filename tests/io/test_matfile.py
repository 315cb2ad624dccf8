"""The MATLAB v5 check before SciPy parses a file (pfslam.io.matfile): valid files load as
``loadmat`` loads them; corrupt ones, including those that crash SciPy's reader, are one-line
InputErrors naming the place; a seeded fuzz of byte-mutated THOR files never gets further."""

import os
import pickle
import struct
import zlib
from pathlib import Path

import matfuzz
import numpy as np
import pytest
import scipy.io as sio
import scipy.sparse

from pfslam.errors import InputError
from pfslam.io import matfile
from pfslam.io.matfile import check_mat5, load_mat
from pfslam.io.thor import load_thor


def _same(a, b):
    """Deep equality of what loadmat returns (arrays of objects and records included)."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a if not k.startswith("__"))
    if scipy.sparse.issparse(a):
        return scipy.sparse.issparse(b) and (a != b).nnz == 0
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype.names:
        return (
            a.dtype == b.dtype
            and a.shape == b.shape
            and all(_same(x[f], y[f]) for x, y in zip(a.ravel(), b.ravel()) for f in a.dtype.names)
        )
    if a.dtype == object:
        return a.shape == b.shape and all(_same(x, y) for x, y in zip(a.ravel(), b.ravel()))
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a, b, equal_nan=a.dtype.kind in "fc")


VARIABLES = {
    "d": np.arange(12.0).reshape(3, 4),
    "s": np.float32([[1.5, -2.0]]),
    "i8": np.int8([[-3, 4, 5]]),
    "u16": np.uint16([[7]]),
    "i64": np.int64([[2**40, -1]]),
    "c": np.array([[1 + 2j, 3 - 4j]]),
    "b": np.array([[True, False, True]]),
    "text": "hello THOR",
    "empty": np.zeros((0, 3)),
    "cells": np.array([[np.zeros((1, 2)), "x", np.array([[1, 2]], np.uint8)]], dtype=object),
    "rec": {"t": 1.25, "scan": np.ones((1, 5), np.float32), "name": "a"},
    "nested": np.array([[{"inner": np.array([[{"deep": 3.0}]], dtype=object)}]], dtype=object),
    "three_d": np.arange(24.0).reshape(2, 3, 4),
}


@pytest.mark.parametrize("compressed", [False, True], ids=["plain", "compressed"])
def test_valid_files_load_as_loadmat_loads_them(tmp_path, compressed):
    p = tmp_path / "v.mat"
    sio.savemat(p, VARIABLES, do_compression=compressed)
    got = load_mat(p)
    assert _same(got, sio.loadmat(p))
    plain, child = check_mat5(p, p.read_bytes())
    assert not child
    assert (plain == p.read_bytes()) is (not compressed)  # compressed variables are handed over inflated


def _scipy_matlab_files():
    folder = Path(os.path.dirname(sio.matlab.__file__)) / "tests" / "data"
    return sorted(folder.glob("*.mat")) if folder.is_dir() else []


def test_every_matlab_written_v5_file_scipy_reads_is_accepted():
    """SciPy's own test files, written by MATLAB 5.3 to 8 on several systems (both byte
    orders, compressed v7, cells, structs, objects, sparse, function handles, empty arrays):
    every one that ``loadmat`` reads passes the check (and, but for the classes a child
    process parses, loads the same)."""
    files = _scipy_matlab_files()
    if not files:
        pytest.skip("SciPy's test data is not installed")
    checked = 0
    for f in files:
        data = f.read_bytes()
        if not data.startswith(b"MATLAB") or b"MATLAB 7.3" in data[:128]:
            continue  # MATLAB v4 and HDF5 files are no v5 files
        try:
            ref = sio.loadmat(f)
        except Exception:  # noqa: BLE001 - SciPy's deliberately broken files
            continue
        plain, child = check_mat5(f, data)
        if child:  # objects, sparse, function handles: accepted, and parsed in a child (tested below)
            checked += 1
            continue
        got = load_mat(f)
        assert got.keys() == ref.keys(), f.name
        for k in got:  # what loadmat returns has no simple equality: compare the pickles
            assert pickle.dumps(got[k]) == pickle.dumps(ref[k]), (f.name, k)
        checked += 1
    assert checked >= 50


def _lidar(tmp_path, compressed=False):
    paths = matfuzz.thor_pair(tmp_path, n=5)
    return paths["lidar_z" if compressed else "lidar"]


def _tags(data, start=128):
    """(offset, type, size) of every full-format element tag in a plain file, in order."""
    out, p = [], start
    while p + 8 <= len(data):
        t, n = struct.unpack_from("<II", data, p)
        out.append((p, t, n))
        p += 8 if t == 14 else 8 + n + (-n) % 8 if not t >> 16 else 8
    return out


def _corrupt(tmp_path, data, name="bad.mat"):
    p = tmp_path / name
    p.write_bytes(bytes(data))
    with pytest.raises(InputError) as e:
        load_mat(p)
    msg = str(e.value)
    assert name in msg and "\n" not in msg and msg.count("not a readable MATLAB file") == 1, msg
    return msg


def test_an_element_type_scipy_has_no_dtype_for_is_refused(tmp_path):
    """The crash seen in the fuzz: a data element's type out of SciPy's table (here a scan's)."""
    data = bytearray(_lidar(tmp_path).read_bytes())
    p = next(p for p, t, n in _tags(bytes(data)) if t == 7 and n == 4 * 1081)  # the first scan's data (single)
    struct.pack_into("<I", data, p, 182)
    msg = _corrupt(tmp_path, data)
    assert "variable 'lidar' > cell 1 > field 'scan'" in msg and "data type 182" in msg


@pytest.mark.parametrize("compressed", [False, True], ids=["plain", "compressed"])
def test_truncated_files_are_refused(tmp_path, compressed):
    data = _lidar(tmp_path, compressed).read_bytes()
    for cut in (130, len(data) // 2, len(data) - 1):
        _corrupt(tmp_path, data[:cut])


def test_header_damage_is_refused(tmp_path):
    data = bytearray(_lidar(tmp_path).read_bytes())
    bad = data.copy()
    bad[126:128] = b"XX"
    assert "byte-order mark" in _corrupt(tmp_path, bad)
    bad = data.copy()
    bad[124:126] = b"\x07\x00"
    assert "version" in _corrupt(tmp_path, bad)
    bad = data.copy()
    struct.pack_into("<I", bad, 128, 3)  # the variable's tag: neither miMATRIX nor miCOMPRESSED
    assert "data type 3" in _corrupt(tmp_path, bad)
    assert "stray bytes" in _corrupt(tmp_path, data + b"\x01\x02\x03")


def _dims_offset(data):
    """Offset of the first variable's dimensions data (after its tag, flags, dims tag)."""
    return 128 + 8 + 16 + 8


def test_negative_and_absurd_dimensions_are_refused(tmp_path):
    data = bytearray(_lidar(tmp_path).read_bytes())
    bad = data.copy()
    struct.pack_into("<i", bad, _dims_offset(data) + 4, -5)
    assert "negative dimensions" in _corrupt(tmp_path, bad)
    bad = data.copy()
    struct.pack_into("<ii", bad, _dims_offset(data), 2**31 - 1, 2**31 - 1)
    assert "absurd dimensions" in _corrupt(tmp_path, bad)
    bad = data.copy()
    struct.pack_into("<ii", bad, _dims_offset(data), 1, 6)  # 6 cells where the file holds 5
    assert "cell" in _corrupt(tmp_path, bad)


def test_corrupt_compressed_data_is_refused(tmp_path):
    data = bytearray(_lidar(tmp_path, compressed=True).read_bytes())
    bad = data.copy()
    bad[-3] ^= 0xFF  # the zlib checksum
    assert "compressed data" in _corrupt(tmp_path, bad)
    # A well-formed zlib stream whose content is damaged: checked like a plain variable.
    inner = bytearray(zlib.decompress(bytes(data[136:])))
    p = next(p for p, t, n in _tags(bytes(inner), 0) if t == 7 and n == 4 * 1081)
    struct.pack_into("<I", inner, p, 11)
    z = zlib.compress(bytes(inner))
    bad = data[:128] + struct.pack("<II", 15, len(z)) + z
    assert "field 'scan'" in _corrupt(tmp_path, bad)
    # A compressed variable that inflates to more than its matrix tag declares.
    inner = bytes(zlib.decompress(bytes(data[136:])))
    z = zlib.compress(inner + bytes(8))
    assert "declares" in _corrupt(tmp_path, data[:128] + struct.pack("<II", 15, len(z)) + z)


def test_a_matrix_whose_contents_overrun_its_tag_is_refused(tmp_path):
    data = bytearray(_lidar(tmp_path).read_bytes())
    p = next(p for p, t, n in _tags(bytes(data)) if t == 14 and p > 128)  # the first cell
    n = struct.unpack_from("<I", data, p + 4)[0]
    struct.pack_into("<I", data, p + 4, n - 8)
    _corrupt(tmp_path, data)


def test_unusual_classes_are_read_in_a_child_process(tmp_path):
    """A sparse matrix (no THOR file has one) is parsed in a child process: it loads."""
    p = tmp_path / "s.mat"
    sp = scipy.sparse.csc_matrix(np.array([[0, 1.5], [2.0, 0]]))
    sio.savemat(p, {"sp": sp, "x": np.ones((1, 2))})
    plain, child = check_mat5(p, p.read_bytes())
    assert child
    got = load_mat(p)
    assert (got["sp"] != sp).nnz == 0 and np.array_equal(got["x"], [[1.0, 1.0]])


def test_a_child_that_crashes_is_a_corrupt_file(tmp_path, monkeypatch):
    p = tmp_path / "s.mat"
    sio.savemat(p, {"sp": scipy.sparse.eye(3, format="csc")})
    monkeypatch.setattr(matfile, "_CHILD", "import ctypes; ctypes.string_at(0)")  # a segmentation fault
    with pytest.raises(InputError, match=r"s\.mat: not a readable MATLAB file: corrupt .mat file \(the reader crashed"):
        load_mat(p)


def test_fuzz_byte_mutated_thor_files_load_or_are_input_errors(tmp_path):
    """200 seeded mutants (random bytes, truncation, inserted and deleted runs, header damage)
    of a THOR lidar and joint file, plain and compressed: each loads (with the other file of
    the pair intact) or is an InputError naming the file; none crashes the test process.
    ``PFSLAM_FUZZ_COUNT=2000`` runs the full count (about a minute)."""
    paths = matfuzz.thor_pair(tmp_path)
    outcome = {"loaded": 0, "refused": 0}
    count = int(os.environ.get("PFSLAM_FUZZ_COUNT", "200"))
    for i, (which, kind, data) in enumerate(matfuzz.mutants(paths, count, seed=2024)):
        bad = tmp_path / f"m{i}_{which}.mat"
        bad.write_bytes(data)
        lidar, joint = (bad, paths["joint"]) if which.startswith("lidar") else (paths["lidar"], bad)
        try:
            log = load_thor(lidar, joint)
        except InputError as e:
            assert bad.name in str(e) and "\n" not in str(e), (kind, str(e))
            outcome["refused"] += 1
        else:
            assert len(log.frames)
            for f in log.frames:  # the ranges are read again from the file: every one readable
                assert f.ranges.shape == (1081,)
            outcome["loaded"] += 1
        bad.unlink()
    assert outcome["loaded"] >= 10 and outcome["refused"] >= 50, outcome
