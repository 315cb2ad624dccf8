"""MATLAB v5 ``.mat`` files, checked before SciPy parses them (a leaf: it imports only
:mod:`pfslam.errors`; :mod:`pfslam.io.thor` reads its files through :func:`load_mat`, and
its long logs through :mod:`pfslam.io.matrecords`, which walks them with :class:`Walker`).

SciPy's ``loadmat`` is not hardened against corrupt files: its Cython reader looks a data
element's type up in a fixed table without a bounds check and trusts the sizes it reads,
so a few flipped bytes can crash the whole process (a segmentation fault, no exception).
:func:`load_mat` therefore walks the file's structure first, in Python, and SciPy only
sees a file that passed:

- the 128-byte header: version 0x0100 and an ``IM``/``MI`` byte-order mark;
- every top-level element is an ``miMATRIX`` or an ``miCOMPRESSED`` one whose declared
  size fits in the file; a compressed one is decompressed with :mod:`zlib` in full (its
  checksum verified, nothing left over, at most ``MAX_VARIABLE_BYTES``) and must hold
  exactly one ``miMATRIX`` element, checked the same way;
- inside a matrix, recursively: the array flags, the dimensions (1 to 32, none negative,
  their product not absurd for the bytes there are), the name, then per class the data
  elements (each of a type SciPy knows for that role, each within its parent, padded to
  8 bytes), their sizes against the dimensions (numeric data: exactly ``prod(dims)``
  items, real and imaginary), the cells, the struct field names and fields, and the
  matrix ending exactly where its tag says.

The checked file is handed to SciPy from memory (the bytes that were checked, with the
compressed variables already inflated, so nothing is decompressed twice). The classes a
THOR file never holds and whose reading goes beyond this walk (sparse, object, function
handle, opaque) are parsed in a child process instead, where a crash is caught and
reported as a corrupt file. Any problem is an :class:`InputError` naming the file, the
variable and the place in it.
"""

from __future__ import annotations

import io
import pickle
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pfslam.errors import InputError

NOT_READABLE = "not a readable MATLAB file"  # how every error about a file's content begins
HEADER_BYTES = 128
MAX_DIMS = 32  # SciPy's limit (numpy's)
MAX_DEPTH = 64  # nesting of cells and structs
MAX_VARIABLE_BYTES = 1 << 31  # MATLAB's -v7 format cannot hold a larger variable either
SLACK_ELEMENTS = 1 << 16  # element count allowed beyond the bytes there are (empty char, fieldless struct)

# Data element types (miINT8 ...) with the item sizes SciPy has a dtype for.
MI_INT8, MI_UINT8, MI_UINT16, MI_INT32, MI_UINT32 = 1, 2, 4, 5, 6
MI_MATRIX, MI_COMPRESSED, MI_UTF8 = 14, 15, 16
ITEM_SIZE = {1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 6: 4, 7: 4, 9: 8, 12: 8, 13: 8, 16: 1, 17: 2, 18: 4}
CHAR_TYPES = frozenset({MI_INT8, MI_UINT8, MI_UINT16, 16, 17, 18})
STRING_TYPES = frozenset({MI_INT8, MI_UTF8})
# Array classes (mxCELL_CLASS ...).
CELL, STRUCT, OBJECT, CHAR, SPARSE, FUNCTION, OPAQUE = 1, 2, 3, 4, 5, 16, 17
NUMERIC = frozenset(range(6, 16))  # double, single, int8 ... uint64
CHILD_CLASSES = frozenset({OBJECT, SPARSE, FUNCTION, OPAQUE})  # parsed in a child process

# The child: reads the checked bytes from stdin, writes ("ok", variables) or ("error", text).
_CHILD = """\
import io, pickle, sys, warnings
warnings.simplefilter("ignore")
from scipy.io import loadmat
data = sys.stdin.buffer.read()
try:
    out = ("ok", loadmat(io.BytesIO(data)))
except Exception as e:
    out = ("error", type(e).__name__ + (": " + str(e).strip().splitlines()[0] if str(e).strip() else ""))
sys.stdout.buffer.write(pickle.dumps(out, protocol=pickle.HIGHEST_PROTOCOL))
"""


class Corrupt(Exception):
    """A structural problem; ``where`` collects the place, innermost first."""

    def __init__(self, problem: str) -> None:
        super().__init__(problem)
        self.problem = problem
        self.where: list[str] = []


class Walker:
    """Walks one buffer (the file, or one inflated variable) of byte order ``order``."""

    def __init__(self, buf: bytes, order: str) -> None:
        self.buf = buf
        self.order = order
        self.u32 = struct.Struct(order + "I").unpack_from
        self.tag = struct.Struct(order + "II").unpack_from
        self.needs_child = False
        # While one cell is walked, the (start, length) of every byte the walk's decisions
        # read (tags, flags, dimensions, names): cells equal in those bytes are equally valid.
        self.rec: list[tuple[int, int]] | None = None
        self.array: NDArray[np.uint8] | None = None  # the buffer as bytes for numpy, made when needed

    def element(self, p: int, end: int, meta: bool = False) -> tuple[int, int, int, int]:
        """The data element at ``p`` (ending by ``end``): (type, bytes, data start, next element).
        ``meta``: its data steers the walk (recorded with the tag)."""
        if p + 8 > end:
            raise Corrupt(f"an element tag at byte {p} runs past the end of its container ({end - p} bytes left)")
        mtype, count = self.tag(self.buf, p)
        small = mtype >> 16
        if small:  # small data element: type and size in the first 4 bytes, data in the next 4
            if self.rec is not None:
                self.rec.append((p, 8))
            if small > 4:
                raise Corrupt(f"a small data element at byte {p} declares {small} bytes (at most 4)")
            return mtype & 0xFFFF, small, p + 4, p + 8
        nxt = p + 8 + count + (-count) % 8
        if nxt > end:
            raise Corrupt(
                f"a data element at byte {p} declares {count} bytes, more than its container holds ({end - p - 8})"
            )
        if self.rec is not None:
            self.rec.append((p, 8 + count if meta else 8))
        return mtype, count, p + 8, nxt

    def string(self, p: int, end: int, what: str) -> tuple[bytes, int]:
        """An int8 string element (a name): (its bytes, next element)."""
        mtype, count, d, nxt = self.element(p, end, meta=True)
        if mtype not in STRING_TYPES:
            raise Corrupt(f"{what} has data type {mtype}, not a string (miINT8)")
        return self.buf[d : d + count], nxt

    def numeric(self, p: int, end: int, items: int | None, what: str) -> int:
        """A numeric data element of ``items`` items (None: any); the next element."""
        mtype, count, _, nxt = self.element(p, end)
        size = ITEM_SIZE.get(mtype)
        if size is None:
            raise Corrupt(f"{what} has data type {mtype}, not a numeric one")
        if items is not None and count != items * size:
            raise Corrupt(f"{what} holds {count} bytes, not the {items} items of {size} bytes its dimensions need")
        return nxt

    def matrix(self, p: int, end: int, depth: int) -> tuple[str, int]:
        """The ``miMATRIX`` element at ``p``: (its name, the next element)."""
        if p + 8 > end:
            raise Corrupt(f"a matrix tag at byte {p} runs past the end of its container")
        mtype, count = self.tag(self.buf, p)
        if self.rec is not None:
            self.rec.append((p, 8))
        if mtype != MI_MATRIX:
            raise Corrupt(f"expected a matrix (miMATRIX) at byte {p}, found data type {mtype}")
        stop = p + 8 + count
        if stop > end:
            raise Corrupt(f"a matrix at byte {p} declares {count} bytes, more than its container holds ({end - p - 8})")
        if count == 0:
            return "", stop  # an empty matrix
        if depth > MAX_DEPTH:
            raise Corrupt(f"cells or structs nested more than {MAX_DEPTH} deep")
        q = p + 8
        ftype, fcount, fd, q = self.element(q, stop, meta=True)
        if ftype != MI_UINT32 or fcount != 8:
            raise Corrupt(f"the array flags of a matrix at byte {p} are malformed")
        flags = self.u32(self.buf, fd)[0]
        cls, is_complex = flags & 0xFF, bool(flags & 0x800)
        self.needs_child = self.needs_child or cls in CHILD_CLASSES
        name = ""
        try:
            if cls == OPAQUE:
                for _ in range(3):
                    _, q = self.string(q, stop, "an opaque object's name")
                _, q = self.matrix(q, stop, depth + 1)
            else:
                q, n = self.dims(q, stop)
                raw, q = self.string(q, stop, "the array name")
                name = raw.decode("latin1")
                q = self.content(cls, is_complex, n, q, stop, depth)
        except Corrupt as e:
            if name:
                e.where.append(f"variable '{name}'" if depth == 0 else f"'{name}'")
            raise
        if q != stop:
            raise Corrupt(f"a matrix at byte {p} declares {count} bytes but its contents take {q - p - 8}")
        return name, stop

    def same_cells(self, start: int, size: int, rec: list[tuple[int, int]], most: int) -> int:
        """How many of the ``most`` cells of ``size`` bytes that follow the one walked at
        ``start`` (which read the bytes ``rec``) equal it in those bytes, in a row."""
        if most <= 0:
            return 0
        if self.array is None:
            self.array = np.frombuffer(self.buf, dtype=np.uint8)
        idx = np.concatenate([np.arange(a - start, a - start + n) for a, n in rec])
        first = self.array[start + idx]
        done = 0
        while done < most:  # in blocks, so a mismatch early in a long array costs little
            k = min(most - done, max(64, done))
            starts = start + size * np.arange(done + 1, done + k + 1)
            ok = (self.array[starts[:, None] + idx[None, :]] == first).all(axis=1)
            if not ok.all():
                return done + int(np.argmin(ok))
            done += k
        return done

    def dims(self, p: int, end: int) -> tuple[int, int]:
        """The dimensions element: (next element, number of elements)."""
        mtype, count, d, nxt = self.element(p, end, meta=True)
        if mtype not in (MI_INT32, MI_UINT32) or count % 4 or not 4 <= count <= 4 * MAX_DIMS:
            raise Corrupt(f"malformed dimensions (type {mtype}, {count} bytes)")
        dims = struct.unpack_from(f"{self.order}{count // 4}i", self.buf, d)
        if min(dims) < 0:
            raise Corrupt(f"negative dimensions {list(dims)}")
        n = 1
        for v in dims:
            n *= v
        if n > len(self.buf) + SLACK_ELEMENTS:
            raise Corrupt(f"absurd dimensions {list(dims)} ({n} elements in {len(self.buf)} bytes)")
        return nxt, n

    def content(self, cls: int, is_complex: bool, n: int, q: int, stop: int, depth: int) -> int:
        """What follows a matrix's name, for class ``cls`` with ``n`` elements; the next element."""
        if cls in NUMERIC:
            q = self.numeric(q, stop, n, "the real part")
            return self.numeric(q, stop, n, "the imaginary part") if is_complex else q
        if cls == CELL:
            if 8 * n > stop - q:
                raise Corrupt(f"a cell array of {n} cells in {stop - q} bytes")
            i = 0
            while i < n:
                start = q
                outer, self.rec = self.rec, ([] if self.rec is None else self.rec)
                try:
                    _, q = self.matrix(q, stop, depth + 1)
                except Corrupt as e:
                    e.where.append(f"cell {i + 1}")
                    raise
                finally:
                    rec, self.rec = self.rec, outer
                i += 1
                if outer is None and i < n:  # not inside a cell that is being recorded itself
                    same = self.same_cells(start, q - start, rec, min(n - i, (stop - q) // (q - start)))
                    i += same
                    q += same * (q - start)
            return q
        if cls in (STRUCT, OBJECT):
            if cls == OBJECT:
                _, q = self.string(q, stop, "the class name")
            mtype, count, d, q = self.element(q, stop, meta=True)
            if mtype not in (MI_INT32, MI_UINT32) or count != 4:
                raise Corrupt(f"malformed field name length (type {mtype}, {count} bytes)")
            width = struct.unpack_from(self.order + "i", self.buf, d)[0]
            names, q = self.string(q, stop, "the field names")
            if width < 1 or len(names) % width:
                raise Corrupt(f"{len(names)} bytes of field names are not a whole number of {width}-byte names")
            fields = [names[k : k + width].split(b"\0", 1)[0].decode("latin1") for k in range(0, len(names), width)]
            if fields and 8 * n * len(fields) > stop - q:
                raise Corrupt(f"a struct array of {n} x {len(fields)} fields in {stop - q} bytes")
            for i in range(n if fields else 0):
                for f in fields:
                    try:
                        _, q = self.matrix(q, stop, depth + 1)
                    except Corrupt as e:
                        e.where.append(f"field '{f}'" + (f" of element {i + 1}" if n > 1 else ""))
                        raise
            return q
        if cls == CHAR:
            mtype, count, _, q = self.element(q, stop)
            if mtype not in CHAR_TYPES:
                raise Corrupt(f"character data of type {mtype}")
            if count == 0 and n > SLACK_ELEMENTS or 0 < count < n:
                raise Corrupt(f"{count} bytes of characters for {n} characters")
            return q
        if cls == SPARSE:
            for part in ("row indices", "column index", "values") + (("imaginary values",) if is_complex else ()):
                q = self.numeric(q, stop, None, f"the sparse {part}")
            return q
        if cls == FUNCTION:
            _, q = self.matrix(q, stop, depth + 1)
            return q
        raise Corrupt(f"unknown array class {cls}")


def byte_order(path: Path, data: bytes) -> str:
    """The byte order of a v5 file from its header (InputError if it is not one)."""
    if len(data) < HEADER_BYTES:
        raise InputError(path, f"{NOT_READABLE}: {len(data)} bytes, shorter than the 128-byte header")
    mark = data[126:128]
    if mark not in (b"IM", b"MI"):
        raise InputError(path, f"{NOT_READABLE}: the header's byte-order mark is {mark!r}, not 'IM' or 'MI'")
    order = "<" if mark == b"IM" else ">"
    version = struct.unpack_from(order + "H", data, 124)[0]
    if version == 0x0200:
        raise InputError(path, "MATLAB v7.3 (HDF5) files are not supported; re-save it with save(..., '-v7')")
    if version != 0x0100:
        raise InputError(path, f"{NOT_READABLE}: header version 0x{version:04x}, not 0x0100 (MATLAB 5 to 7)")
    return order


def _inflate(data: bytes, p: int, count: int) -> bytes:
    """The content of the miCOMPRESSED element whose data starts at ``p``: one whole zlib stream."""
    d = zlib.decompressobj()
    try:
        head = d.decompress(memoryview(data)[p : p + count], 8)
        if len(head) < 8:
            raise Corrupt("compressed data too short to hold a matrix tag")
        size = 8 + struct.unpack_from("<I" if data[126:128] == b"IM" else ">I", head, 4)[0]
        if size > MAX_VARIABLE_BYTES:
            raise Corrupt(f"a compressed variable declares {size} bytes (more than MATLAB's 2 GiB)")
        rest = d.decompress(d.unconsumed_tail, size - 8 + 1)
    except zlib.error as e:
        raise Corrupt(f"corrupt compressed data ({e})") from None
    if len(head) + len(rest) != size or d.unconsumed_tail:
        raise Corrupt(f"compressed data does not hold the {size} bytes its matrix tag declares")
    if not d.eof:
        try:
            d.flush()
        except zlib.error as e:
            raise Corrupt(f"corrupt compressed data ({e})") from None
        if not d.eof:
            raise Corrupt("compressed data ends before its zlib stream does (truncated?)")
    if d.unused_data:
        raise Corrupt(f"{len(d.unused_data)} bytes after the end of a compressed variable's zlib stream")
    return head + rest


def check_mat5(path: Path, data: bytes) -> tuple[bytes, bool]:
    """Check a whole MATLAB v5 file (see the module notes); raise InputError if it is corrupt.

    Returns the file with every compressed variable inflated (what SciPy is given) and
    whether some variable has a class that only a child process may parse."""
    order = byte_order(path, data)
    out: list[bytes | tuple[int, int]] = [(0, HEADER_BYTES)]
    needs_child = inflated = False
    p, k = HEADER_BYTES, 0
    while p < len(data):
        k += 1
        name = ""
        try:
            if p + 8 > len(data):
                raise Corrupt(f"{len(data) - p} stray bytes at the end of the file")
            mtype, count = struct.unpack_from(order + "II", data, p)
            if mtype not in (MI_MATRIX, MI_COMPRESSED):
                raise Corrupt(f"a variable of data type {mtype}, neither a matrix (14) nor compressed (15)")
            if count == 0 or p + 8 + count > len(data):
                raise Corrupt(
                    f"a variable declares {count} bytes, but {len(data) - p - 8} are left in the file"
                    if count
                    else "an empty variable"
                )
            if mtype == MI_COMPRESSED:
                buf = _inflate(data, p + 8, count)
                walker = Walker(buf, order)
                name, end = walker.matrix(0, len(buf), 0)
                if end != len(buf):
                    raise Corrupt(f"{len(buf) - end} bytes after the matrix in a compressed variable")
                out.append(buf)
                inflated = True
            else:
                walker = Walker(data, order)
                name, end = walker.matrix(p, p + 8 + count, 0)
                out.append((p, end))
            needs_child = needs_child or walker.needs_child
        except Corrupt as e:
            where = e.where[::-1]
            if not where or not where[0].startswith("variable"):
                where.insert(0, f"variable {k}")
            raise InputError(path, f"{NOT_READABLE}: {' > '.join(where)}: {e.problem}") from None
        p += 8 + count
    if not inflated:
        return data, needs_child
    return b"".join(data[x[0] : x[1]] if isinstance(x, tuple) else x for x in out), needs_child


def _loadmat_in_child(path: Path, data: bytes) -> dict[str, object]:
    """``loadmat`` of ``data`` in a child Python; a crash there is a corrupt-file InputError."""
    try:
        res = subprocess.run([sys.executable, "-c", _CHILD], input=data, capture_output=True, check=False)
    except OSError as e:
        raise InputError(path, f"cannot start a process to read the file ({e.strerror or e})") from None
    if res.returncode != 0:
        how = f"signal {-res.returncode}" if res.returncode < 0 else f"exit code {res.returncode}"
        raise InputError(path, f"{NOT_READABLE}: corrupt .mat file (the reader crashed: {how})")
    try:
        status, value = pickle.loads(res.stdout)
    except Exception:  # noqa: BLE001 - anything unreadable from the child is a failed read
        raise InputError(path, f"{NOT_READABLE}: corrupt .mat file (the reader returned nothing)") from None
    if status != "ok":
        raise InputError(path, f"{NOT_READABLE}: {value}")
    return value


def load_mat(path: Path) -> dict[str, object]:
    """The variables of a MATLAB v5/v7 file as ``scipy.io.loadmat`` returns them, after the
    checks of the module notes. Raises InputError (naming ``path``) for a missing, HDF5,
    non-MATLAB or corrupt file; never lets a corrupt file crash the process."""
    if not path.exists():
        raise InputError(path, "file not found")
    if not path.is_file():
        raise InputError(path, "not a file")
    try:
        with open(path, "rb") as f:
            head = f.read(HEADER_BYTES)
            if head[:4] == b"\x89HDF" or b"MATLAB 7.3" in head:
                raise InputError(path, "MATLAB v7.3 (HDF5) files are not supported; re-save it with save(..., '-v7')")
            if not head.startswith(b"MATLAB"):
                raise InputError(path, "not a MATLAB .mat file (no 'MATLAB' header)")
            f.seek(0)
            data = f.read()
    except OSError as e:
        raise InputError(path, f"cannot read the file ({e.strerror or e})") from None
    plain, needs_child = check_mat5(path, data)
    del data
    if needs_child:
        return _loadmat_in_child(path, plain)
    from scipy.io import loadmat

    try:
        return loadmat(io.BytesIO(plain))
    except Exception as e:  # noqa: BLE001 - scipy raises many kinds (ValueError, TypeError, ...) on odd files
        msg = str(e).strip().splitlines()[0] if str(e).strip() else ""
        raise InputError(path, f"{NOT_READABLE}: {type(e).__name__}{': ' + msg if msg else ''}") from None
