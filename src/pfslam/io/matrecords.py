"""The records of a MATLAB v5 cell array, read in one pass (:func:`read_records`), for
:mod:`pfslam.io.thor`'s long logs; the checks are :mod:`pfslam.io.matfile`'s.

A long THOR log is one cell array of tens of thousands of small structs. Parsing it whole
(SciPy's way) holds the file, the inflated variable and a NumPy object per field at once:
several times the data. :func:`read_records` instead reads the file once, front to back
(a compressed variable inflated as it goes), checks each cell as :func:`pfslam.io.matfile.check_mat5`
does on its own bytes, and hands each struct's field layout to a callback; the bytes of a
record stay readable later at the offsets it was given (in the file itself, or for a
compressed variable in a temporary file its inflated bytes were copied to), so nothing
needs to stay in memory.
"""

from __future__ import annotations

import io
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO, Callable

import numpy as np
from numpy.typing import NDArray

from pfslam.errors import InputError
from pfslam.io.matfile import (
    CELL,
    HEADER_BYTES,
    MAX_DIMS,
    MAX_VARIABLE_BYTES,
    MI_COMPRESSED,
    MI_INT32,
    MI_MATRIX,
    MI_UINT32,
    NOT_READABLE,
    NUMERIC,
    OBJECT,
    STRING_TYPES,
    STRUCT,
    Corrupt,
    Walker,
    byte_order,
)

MI_TYPES: dict[int, str] = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 9: "f8", 12: "i8", 13: "u8"}


@dataclass(frozen=True)
class FieldData:
    """One field of a record: its numeric data at ``start`` (within the record's bytes),
    ``count`` items of ``dtype``; ``dtype`` is None for a field that is not numeric."""

    name: str
    dtype: np.dtype[np.generic] | None
    start: int
    count: int

    def values(self, buf: bytes) -> NDArray[np.float64]:
        """The field's values as floats (NaN for a field that is not numeric)."""
        if self.dtype is None:
            return np.full(1, np.nan)
        return np.frombuffer(buf, self.dtype, self.count, self.start).astype(float)


Layout = tuple[FieldData, ...]
Visit = Callable[[str, int, Layout, bytes, int, bool], None]  # (variable, index, layout, bytes, offset, in spill)


class _Stream:
    """Sequential reads of one top-level variable: a region of the file, or the zlib stream
    in it inflated as it is read (its bytes copied to ``spill``, so records can be read
    again later from there)."""

    CHUNK = 1 << 16

    def __init__(self, f: BinaryIO, start: int, length: int, compressed: bool, spill: BinaryIO | None) -> None:
        f.seek(start)
        self.f, self.left = f, length
        self.z = zlib.decompressobj() if compressed else None
        self.spill = spill if compressed else None
        self.base = start if not compressed else (spill.tell() if spill is not None else 0)
        self.buf = bytearray()
        self.pos = 0  # bytes handed out so far

    def _more(self, need: int) -> bytes:
        if self.z is None:
            data = self.f.read(min(self.left, max(need, self.CHUNK)))
            self.left -= len(data)
            return data
        while True:
            if self.z.unconsumed_tail:
                src = self.z.unconsumed_tail
            elif self.left > 0:
                src = self.f.read(min(self.left, self.CHUNK))
                self.left -= len(src)
                if not src:
                    self.left = 0
                    continue
            else:
                return b""
            try:
                out = self.z.decompress(src, max(need, self.CHUNK))
            except zlib.error as e:
                raise Corrupt(f"corrupt compressed data ({e})") from None
            if out:
                if self.spill is not None:
                    self.spill.write(out)
                return out
            if self.z.eof:
                return b""

    def read(self, n: int) -> bytes:
        while len(self.buf) < n:
            more = self._more(n - len(self.buf))
            if not more:
                raise Corrupt(
                    f"the data ends {n - len(self.buf)} bytes short of an element at byte {self.pos} (truncated?)"
                )
            self.buf += more
        out = bytes(self.buf[:n])
        del self.buf[:n]
        self.pos += n
        return out

    def finish(self, size: int) -> None:
        """A compressed variable must end with its zlib stream: nothing more, nothing missing."""
        if self.z is None:
            return
        if self.buf or self._more(1):
            raise Corrupt(f"compressed data does not hold the {size} bytes its matrix tag declares")
        if not self.z.eof:
            raise Corrupt("compressed data ends before its zlib stream does (truncated?)")
        if self.z.unused_data or self.left > 0:
            raise Corrupt(
                f"{len(self.z.unused_data) + self.left} bytes after the end of a compressed variable's zlib stream"
            )


def _element(s: _Stream, order: str) -> tuple[int, bytes]:
    """The next data element of the stream: (type, its data bytes)."""
    mtype, count = struct.unpack(order + "II", s.read(8))
    small = mtype >> 16
    if small:
        if small > 4:
            raise Corrupt(f"a small data element declares {small} bytes (at most 4)")
        return mtype & 0xFFFF, s.read(4)[:small]
    if count > MAX_VARIABLE_BYTES:
        raise Corrupt(f"a data element declares {count} bytes")
    return mtype, s.read(count + (-count) % 8)[:count]


def _record_layout(buf: bytes, order: str) -> Layout | None:
    """The fields of the 1x1 struct in this (checked) matrix, unwrapping 1x1 cells; None if
    it is not one, or if a field is itself a cell or struct (not a THOR record)."""
    tag = struct.Struct(order + "II").unpack_from

    def el(q: int) -> tuple[int, int, int, int]:  # (type, data start, bytes, next element)
        mtype, count = tag(buf, q)
        if mtype >> 16:
            return mtype & 0xFFFF, q + 4, mtype >> 16, q + 8
        return mtype, q + 8, count, q + 8 + count + (-count) % 8

    def head(p: int) -> tuple[int, int, int, int]:  # a matrix: (class, elements, after its name, end)
        _, count = tag(buf, p)
        if count == 0:
            return -1, 0, p + 8, p + 8
        _, fd, _, q = el(p + 8)
        cls = struct.unpack_from(order + "I", buf, fd)[0] & 0xFF
        _, dd, dn, q = el(q)
        n = int(np.prod(np.array(struct.unpack_from(f"{order}{dn // 4}i", buf, dd), dtype=object)))
        _, _, _, q = el(q)  # the name
        return cls, n, q, p + 8 + count

    p = 0
    while True:
        cls, n, q, stop = head(p)
        if n != 1 or cls not in (CELL, STRUCT):
            return None
        if cls == CELL:
            p = q
            continue
        _, wd, _, q = el(q)
        width = struct.unpack_from(order + "i", buf, wd)[0]
        _, nd, nn, q = el(q)
        names = buf[nd : nd + nn]
        fields = [names[k : k + width].split(b"\0", 1)[0].decode("latin1") for k in range(0, len(names), width)]
        out = []
        for name in fields:
            fcls, _, r, nxt = head(q)
            if fcls in (CELL, STRUCT, OBJECT):
                return None
            dtype: np.dtype[np.generic] | None = None
            start = count = 0
            if fcls in NUMERIC:
                mtype, start, size, _ = el(r)
                code = MI_TYPES.get(mtype)
                if code is not None:
                    dtype = np.dtype(order + code)
                    count = size // dtype.itemsize
            out.append(FieldData(name, dtype, start, count))
            q = nxt
        return tuple(out) if q == stop else None


def _read_cells(s: _Stream, order: str, name: str, n: int, end: int, visit: Visit) -> bool:
    """Check each of the ``n`` cells of variable ``name`` (ending at stream byte ``end``) and
    hand it to ``visit``; False if a cell is not a record this reader decodes."""
    spans: list[tuple[int, int]] = []
    sig = b""
    size = -1
    layout: Layout | None = None
    for i in range(n):
        try:
            at = s.pos
            head = s.read(8)
            mtype, count = struct.unpack(order + "II", head)
            if mtype != MI_MATRIX:
                raise Corrupt(f"expected a matrix (miMATRIX) at byte {at}, found data type {mtype}")
            if at + 8 + count > end:
                raise Corrupt(
                    f"a matrix at byte {at} declares {count} bytes, more than its container holds ({end - at - 8})"
                )
            buf = head + s.read(count)
            if len(buf) != size or b"".join(buf[a : a + k] for a, k in spans) != sig:
                walker = Walker(buf, order)
                walker.rec = []
                walker.matrix(0, len(buf), 1)
                if walker.needs_child:
                    return False
                spans, size = walker.rec, len(buf)
                sig = b"".join(buf[a : a + k] for a, k in spans)
                layout = _record_layout(buf, order)
                if layout is None:
                    return False
        except Corrupt as e:
            e.where.append(f"cell {i + 1}")
            raise
        assert layout is not None
        visit(name, i, layout, buf, s.base + at, s.z is not None)
    return True


def read_records(path: Path, visit: Visit, spill: BinaryIO | None = None) -> list[str] | None:
    """Read a MATLAB v5 file in one pass, checking it as :func:`check_mat5` does; hand every
    cell of every cell array whose cells are 1x1 structs of numeric (or text) fields to
    ``visit(variable, index, layout, bytes, offset, in_spill)``, where ``offset`` is where the
    record's bytes start in the file, or, for a compressed variable (``in_spill``), in ``spill`` (inflated bytes are
    copied there as they are read). Returns the names of the file's variables, or None if a
    cell array holds something else (nested structs, sparse matrices, ...): such a file is for
    :func:`load_mat`. Raises InputError (naming ``path`` and the place) for a corrupt file."""
    if not path.exists():
        raise InputError(path, "file not found")
    if not path.is_file():
        raise InputError(path, "not a file")
    names: list[str] = []
    try:
        f = open(path, "rb")
    except OSError as e:
        raise InputError(path, f"cannot read the file ({e.strerror or e})") from None
    with f:
        try:
            head = f.read(HEADER_BYTES)
            total = f.seek(0, io.SEEK_END)
        except OSError as e:
            raise InputError(path, f"cannot read the file ({e.strerror or e})") from None
        if head[:4] == b"\x89HDF" or b"MATLAB 7.3" in head:
            raise InputError(path, "MATLAB v7.3 (HDF5) files are not supported; re-save it with save(..., '-v7')")
        if not head.startswith(b"MATLAB"):
            raise InputError(path, "not a MATLAB .mat file (no 'MATLAB' header)")
        order = byte_order(path, head)
        p, k = HEADER_BYTES, 0
        while p < total:
            k += 1
            name = ""
            try:
                f.seek(p)
                tag = f.read(8)
                if len(tag) < 8:
                    raise Corrupt(f"{total - p} stray bytes at the end of the file")
                mtype, count = struct.unpack(order + "II", tag)
                if mtype not in (MI_MATRIX, MI_COMPRESSED):
                    raise Corrupt(f"a variable of data type {mtype}, neither a matrix (14) nor compressed (15)")
                if count == 0 or p + 8 + count > total:
                    raise Corrupt(
                        f"a variable declares {count} bytes, but {total - p - 8} are left in the file"
                        if count
                        else "an empty variable"
                    )
                compressed = mtype == MI_COMPRESSED
                s = _Stream(f, p + 8, count, compressed, spill)
                if compressed:
                    mtype, size = struct.unpack(order + "II", s.read(8))
                    if mtype != MI_MATRIX:
                        raise Corrupt(f"expected a matrix (miMATRIX) at byte 0, found data type {mtype}")
                    if size > MAX_VARIABLE_BYTES:
                        raise Corrupt(f"a compressed variable declares {size} bytes (more than MATLAB's 2 GiB)")
                else:  # stream positions count from the variable's tag, as when it is inflated
                    size = count
                    s.base, s.pos = p, 8
                name, is_records = _read_variable(s, order, size + 8, visit)
                if is_records is None:
                    return None
                s.finish(size)
            except Corrupt as e:
                where = e.where[::-1]
                if name and not (where and where[0].startswith("variable")):
                    where.insert(0, f"variable '{name}'")
                if not where or not where[0].startswith("variable"):
                    where.insert(0, f"variable {k}")
                raise InputError(path, f"{NOT_READABLE}: {' > '.join(where)}: {e.problem}") from None
            except OSError as e:
                raise InputError(path, f"cannot read the file ({e.strerror or e})") from None
            names.append(name)
            p += 8 + count
    return names


def _read_variable(s: _Stream, order: str, end: int, visit: Visit) -> tuple[str, bool | None]:
    """One top-level matrix whose tag has been read (its contents end at stream byte ``end``):
    (its name, whether its cells went to ``visit``; None: a cell array this reader cannot take)."""
    ftype, flags_raw = _element(s, order)
    if ftype != MI_UINT32 or len(flags_raw) != 8:
        raise Corrupt("the array flags of a matrix at byte 0 are malformed")
    cls = struct.unpack_from(order + "I", flags_raw)[0] & 0xFF
    if cls == CELL:
        dtype_, draw = _element(s, order)
        if dtype_ not in (MI_INT32, MI_UINT32) or len(draw) % 4 or not 4 <= len(draw) <= 4 * MAX_DIMS:
            raise Corrupt(f"malformed dimensions (type {dtype_}, {len(draw)} bytes)")
        dims = struct.unpack(f"{order}{len(draw) // 4}i", draw)
        if min(dims) < 0:
            raise Corrupt(f"negative dimensions {list(dims)}")
        n = int(np.prod(np.array(dims, dtype=object)))
        ntype, raw = _element(s, order)
        if ntype not in STRING_TYPES:
            raise Corrupt(f"the array name has data type {ntype}, not a string (miINT8)")
        name = raw.decode("latin1")
        if 8 * n > end - s.pos:
            raise Corrupt(f"a cell array of {n} cells in {end - s.pos} bytes")
        try:
            if not _read_cells(s, order, name, n, end, visit):
                return name, None
        except Corrupt as e:
            e.where.append(f"variable '{name}'")
            raise
        if s.pos != end:
            raise Corrupt(f"a matrix at byte 0 declares {end - 8} bytes but its contents take {s.pos - 8}")
        return name, True
    # Anything else is read whole and checked as check_mat5 does (the small variables of a
    # THOR file; a struct array, which load_mat reads).
    if end - s.pos < 0:
        raise Corrupt(f"a matrix declares {end - 8} bytes, too few for its array flags")
    rest = s.read(end - s.pos)
    buf = struct.pack(order + "II", MI_MATRIX, end - 8) + struct.pack(order + "II", MI_UINT32, 8) + flags_raw + rest
    walker = Walker(buf, order)
    name, _ = walker.matrix(0, len(buf), 0)
    if walker.needs_child or cls == STRUCT:
        return name, None
    return name, False
