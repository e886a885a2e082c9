"""apply's fast path: corrected sensor cells spliced into the capture's own bytes.

A block of whole lines (about 1 MiB) is corrected without reading its other cells at all:
numpy finds the line ends and the delimiters, pyarrow parses the sensor cells alone, and the
output is the block's bytes with those cells' text replaced (``pyarrow.compute.take`` over
the pieces: the text before a sensor cell, the new text, the text after it). So the other
cells keep their bytes by construction, and memory is bounded by the block whatever the
number of columns.

It takes a block only when every line is plain: the header's number of delimiters on every
line, one line ending throughout (the file's), no ``#``, valid UTF-8, sensor cells that are
numbers (``1.5`` or ``"1.5"``) or all empty in a row. ``Splicer.block`` returns None for
anything else, and the caller reads that block by the general rules (``rewrite.correct_stream``),
which also make every error message: what this path writes is what the general path writes,
byte for byte.

Floats are spelled as pyarrow's cast spells them (shortest round-trip digits; ``1e-7``,
``1e+10``, ``0.00001``, ``2``). orjson spells them alike wherever 1e-5 <= |x| < 1e10 and x is
not a whole number, about 5x faster, so it writes those and pyarrow the rest (checked once a
process against pyarrow on a sample, else pyarrow writes all).
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, TypeAlias

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
from numpy.typing import NDArray

from tumblecal_cli.core.arrays import BoolArray, FloatArray, IntArray
from tumblecal_cli.io.csv.capture import Capture, DataStream

if TYPE_CHECKING:
    from _typeshed import ReadableBuffer

Offsets = NDArray[np.int32]  # byte offsets in a block, and pyarrow's string offsets
#: Where a correction's columns are among the sensor columns: a slice when they are next to each other.
Columns: TypeAlias = "slice[int, int, None] | list[int]"
#: A correction of (n, k) readings: ``fn(values)``, or ``fn(values, temperature)`` (n,) °C when
#: there is a temperature column: which of the two is known at run time only, hence ``...``.
Correct: TypeAlias = Callable[..., FloatArray]
#: The columns a correction takes (in file order), and the correction.
Correction = tuple[tuple[int, int, int], Correct]

#: Where orjson and pyarrow spell a float alike: LOW <= |x| < HIGH, and not a whole number.
LOW, HIGH = 1e-5, 1e10
#: Past this share of floats that orjson does not spell like pyarrow, a block is all pyarrow's.
PATCH_SHARE = 0.05


class Splicer:
    """Corrects blocks of plain lines of one capture layout (see the module's docstring)."""

    def __init__(
        self,
        ncols: int,
        delimiter: str,
        eol: str,
        decimal: str,
        corrections: Sequence[Correction],
        temperature: int | None = None,
        also: Sequence[int] = (),
    ) -> None:
        """``temperature``: the index of a temperature column, parsed too (not rewritten) and
        given to each correction as ``fn(values, temperature)`` (a thermal calibration).
        ``also``: more columns parsed by ``read`` (a log's time column)."""
        _keep_freed_memory()
        _orjson_agrees()  # once, before any worker is forked (io.rewrite.forked): they inherit the answer
        self.ncols = ncols
        self.delimiter = ord(delimiter)
        self.crlf = eol == "\r\n"
        self.eol = eol.encode()
        self.decimal = decimal
        self.fields = sorted({c for cols, _ in corrections for c in cols})  # sensor columns, in file order
        # the columns parsed, in file order (the cells' offsets must grow): the sensor columns and
        # a temperature column; where each sensor column and the temperature are among them
        self.parsed = sorted(set(self.fields) | ({temperature} if temperature is not None else set()) | set(also))
        self.sensors = [self.parsed.index(c) for c in self.fields]
        self.temperature = None if temperature is None else self.parsed.index(temperature)
        at = {c: k for k, c in enumerate(self.fields)}
        self.corrections = [(_as_slice([at[c] for c in cols]), fn) for cols, fn in corrections]
        straight = len(self.corrections) == 1 and self.corrections[0][0] == slice(0, len(self.fields))
        self.whole = self.corrections[0][1] if straight else None
        self.runs = [(0, 0)]  # sensor columns next to each other: written as one piece
        for j in range(1, len(self.fields)):
            if self.fields[j] == self.fields[j - 1] + 1:
                self.runs[-1] = (self.runs[-1][0], j)
            else:
                self.runs.append((j, j))

    def block(self, buf: bytes) -> tuple[memoryview, int] | None:
        """(the corrected bytes, the number of rows) of ``buf``, whole lines; None when a line
        is not plain (the general reader takes the block)."""
        if not buf.endswith(b"\n"):  # the file's last line, without its line end
            buf += self.eol
        found = self._cells(buf)
        if found is None:
            return None
        cells = found[0]
        n, s = cells.shape[0], len(self.fields)
        blank = cells[:, 1::2] == cells[:, 0::2]  # (n, parsed columns)
        empty = blank if self.temperature is None else blank[:, self.sensors]  # (n, s)
        if self.temperature is not None and (blank[:, self.temperature] & ~empty.all(axis=1)).any():
            return None  # a row with readings but no temperature: the general path names it
        values = self._parse(buf, cells, blank, empty)
        if values is None:
            return None
        extra: tuple[FloatArray, ...] = ()
        if self.temperature is not None:
            extra = (values[:, self.temperature],)
            if (~np.isfinite(extra[0]) & ~empty.all(axis=1)).any():
                return None  # a reading at no temperature (nan, inf): the general path names it
            values = values[:, self.sensors]
            cells = cells.reshape(n, -1, 2)[:, self.sensors, :].reshape(n, 2 * s)
        if self.whole is not None:  # one sensor, its columns in file order: no copies
            fixed = np.ascontiguousarray(self.whole(values, *extra), dtype=np.float64)
        else:
            fixed = np.empty((n, s))
            for where, fn in self.corrections:
                fixed[:, where] = fn(values[:, where], *extra)
        parts, bounds, skip = self._format(fixed.ravel(), empty.ravel())
        groups = self.runs if skip else [(j, j) for j in range(s)]
        return _splice(buf, cells, parts, bounds, skip, groups), n

    def read(self, buf: bytes) -> tuple[FloatArray, BoolArray, IntArray] | None:
        """The parsed columns of ``buf``'s lines (n, len(self.parsed), NaN where a cell is
        empty), whether each line's sensor cells are all empty (n,), and where each line ends
        (its line feed's offset); None when a line is not plain, or some of a sensor's cells of
        a line are empty and some not (the general reader names it)."""
        if not buf.endswith(b"\n"):
            buf += self.eol
        found = self._cells(buf)
        if found is None:
            return None
        cells, newline = found
        blank = cells[:, 1::2] == cells[:, 0::2]
        empty = blank[:, self.sensors]
        values = self._parse(buf, cells, blank, empty)
        if values is None:
            return None
        return values, empty.all(axis=1), newline

    def _cells(self, buf: bytes) -> tuple[Offsets, IntArray] | None:
        """Each line's parsed cells (n, 2 x parsed): start and end offsets in ``buf``, cell by
        cell, and each line's line feed; None when a line is not plain."""
        if b"#" in buf or not _utf8(buf):
            return None
        data = np.frombuffer(buf, dtype=np.uint8)
        newline = np.flatnonzero(data == 10)
        n = newline.size
        if self.crlf:
            if buf.count(b"\r") != n or newline[0] == 0 or not (data[newline - 1] == 13).all():
                return None
            ends = newline - 1
        elif b"\r" in buf:
            return None
        else:
            ends = newline
        k = self.ncols - 1
        delimiters = np.flatnonzero(data == self.delimiter)
        if delimiters.size != n * k:
            return None
        at = delimiters.reshape(n, k)
        if not (at[1:, 0] > newline[:-1]).all() or not (at[:, -1] < ends).all():  # so k on every line
            return None
        cells = np.empty((n, 2 * len(self.parsed)), dtype=np.int32)
        for j, c in enumerate(self.parsed):
            if c:
                np.add(at[:, c - 1], 1, out=cells[:, 2 * j])
            else:
                cells[0, 0] = 0
                np.add(newline[:-1], 1, out=cells[1:, 0])
            cells[:, 2 * j + 1] = at[:, c] if c < k else ends
        return cells, newline

    def _parse(self, buf: bytes, cells: Offsets, blank: BoolArray, empty: BoolArray) -> FloatArray | None:
        """The parsed cells as floats (n, parsed columns): NaN where ``blank``; None when some
        of a row's cells of one sensor are ``empty`` and some not, or a cell is not a number."""
        n, s = blank.shape
        m = n * s
        if blank.any():
            for where, _ in self.corrections:
                some = empty[:, where]
                if (some.any(axis=1) & ~some.all(axis=1)).any():
                    return None
            valid = np.zeros(2 * m - 1, dtype=bool)
            valid[0::2] = ~blank.ravel()
            bits = pa.py_buffer(np.packbits(valid, bitorder="little"))
        else:
            bits = _every_other_bit(2 * m - 1)
        if b'"' in buf:  # numbers in double quotes ("1.5"): the text inside them is parsed
            cells = _inside_quotes(buf, cells)
        # cell, gap, cell, gap ...: the gaps null, so that the cast parses the cells alone, in place
        pieces = pa.Array.from_buffers(pa.string(), 2 * m - 1, [bits, pa.py_buffer(cells.ravel()), pa.py_buffer(buf)])
        if self.decimal != ".":
            pieces = pc.replace_substring(pieces, self.decimal, ".")
        try:
            parsed = pc.cast(pieces, pa.float64())
        except pa.ArrowInvalid:
            return None
        values = _floats(parsed)[0::2].reshape(n, s)
        if blank.any():
            values = np.where(blank, np.nan, values)
        return values

    def _format(self, values: FloatArray, empty: BoolArray) -> tuple[list[ReadableBuffer], Offsets | IntArray, int]:
        """The text of ``values`` (empty where ``empty``) as pyarrow spells them: (the parts of
        a buffer, and value v's offsets in it: ``bounds[v] + skip`` to ``bounds[v + 1]``). With
        ``skip`` 1 the values are one delimiter apart (orjson's text), with 0 back to back."""
        with np.errstate(invalid="ignore"):
            size = np.abs(values)
            alike = size >= LOW  # NaN: neither this nor the next, so not spelled alike
            alike &= size < HIGH
            alike &= values != np.trunc(values)
        wrong = np.flatnonzero(~alike)
        if wrong.size <= PATCH_SHARE * values.size and _orjson_agrees():
            return self._format_orjson(values, empty, wrong)
        text = pc.cast(_arrow_floats(values, empty), pa.string())
        if self.decimal != ".":
            text = pc.replace_substring(text, ".", self.decimal)
        data = text.buffers()[2]  # None when every value is empty
        return [data] if data is not None else [], _offsets(text), 0

    def _format_orjson(
        self, values: FloatArray, empty: BoolArray, wrong: IntArray
    ) -> tuple[list[ReadableBuffer], IntArray, int]:
        import orjson

        text = orjson.dumps(values, option=orjson.OPT_SERIALIZE_NUMPY)  # b"[v,v,v,...]"
        commas = np.empty(values.size + 1, dtype=np.int64)
        commas[0] = 0
        commas[-1] = len(text) - 1
        commas[1:-1] = np.flatnonzero(np.frombuffer(text, dtype=np.uint8) == 44)
        parts: list[ReadableBuffer] = [text]
        if wrong.size:  # pyarrow's spelling (or nothing) in place of orjson's
            spelled = _arrow_floats(values[wrong], empty[wrong])
            right = [(s or "").encode() for s in pc.cast(spelled, pa.string()).to_pylist()]
            start, end = commas[wrong] + 1, commas[wrong + 1]
            whole, at = memoryview(text), 0
            parts = []
            for a, b, r in zip(start.tolist(), end.tolist(), right, strict=True):
                parts += [whole[at:a], r]
                at = b
            parts.append(whole[at:])
            shift = np.zeros(values.size + 1, dtype=np.int64)
            shift[wrong + 1] = np.array([len(r) for r in right]) - (end - start)
            commas += np.cumsum(shift)
        if self.delimiter != 44 or self.decimal != ".":
            chars = np.frombuffer(b"".join(parts), dtype=np.uint8).copy()
            if self.decimal != ".":
                chars[chars == 46] = ord(self.decimal)
            chars[commas[1:-1]] = self.delimiter
            parts = [chars.data]  # its bytes, no copy
        return parts, commas, 1


def _splice(
    buf: bytes,
    cells: Offsets,
    parts: list[ReadableBuffer],
    bounds: Offsets | IntArray,
    skip: int,
    groups: list[tuple[int, int]],
) -> memoryview:
    """``buf`` with each line's sensor cells (``cells``, n x 2s offsets) replaced by their new
    text (value v of the buffer ``parts`` joined: ``bounds[v] + skip`` to ``bounds[v + 1]``):
    the bytes themselves. Each of ``groups`` (first cell, last cell) is one piece."""
    n, s, g = cells.shape[0], cells.shape[1] // 2, len(groups)
    m = n * s
    offsets = np.empty(4 * n * g + 2, dtype=np.int32)
    offsets[0] = 0  # the block's text: before the first group, the group, between groups, ...
    offsets[2 * n * g + 1] = len(buf)  # ... after the last group; then the new text's groups
    old = offsets[1 : 2 * n * g + 1].reshape(n, g, 2)
    new = offsets[2 * n * g + 2 :].reshape(n, g, 2)
    for j, (a, b) in enumerate(groups):
        old[:, j, 0] = cells[:, 2 * a]
        old[:, j, 1] = cells[:, 2 * b + 1]
        np.add(bounds[a:m:s], len(buf) + skip, out=new[:, j, 0], casting="unsafe")
        np.add(bounds[b + 1 : m + 1 : s], len(buf), out=new[:, j, 1], casting="unsafe")
    whole = _strings(b"".join([buf, *parts]), offsets)
    order = np.empty(2 * n * g + 1, dtype=np.int64)  # text between groups, new group, ..., the end
    order[0::2] = _every_other(n * g + 1)
    np.add(_every_other(n * g), 2 * n * g + 2, out=order[1::2])
    out = pc.take(whole, _ints(order))
    at = _offsets(out)
    return memoryview(out.buffers()[2])[at[0] : at[-1]]


def _inside_quotes(buf: bytes, cells: Offsets) -> Offsets:
    """The cells' offsets (n, 2 x parsed), a cell in double quotes (``"1.5"``) taken as the text
    inside them (to parse: the new text replaces the whole cell, its quotes too)."""
    data = np.frombuffer(buf, dtype=np.uint8)
    start, end = cells[:, 0::2], cells[:, 1::2]
    last = len(buf) - 1
    quoted = (end - start >= 2) & (data[np.minimum(start, last)] == 34) & (data[np.maximum(end - 1, 0)] == 34)
    inside = cells.copy()
    inside[:, 0::2] += quoted
    inside[:, 1::2] -= quoted
    return inside


def _as_slice(where: list[int]) -> Columns:
    """Positions a, a+1, a+2 as a slice (a view, not a copy, of the values), else as they are."""
    return slice(where[0], where[-1] + 1) if where == list(range(where[0], where[-1] + 1)) else where


_BITS: list[pa.Buffer] = [pa.py_buffer(b"\x55" * (1 << 18))]


def _every_other_bit(n: int) -> pa.Buffer:
    """A validity bitmap of n values, every other one valid (0, 2, 4, ...)."""
    if (n + 7) // 8 > _BITS[0].size:
        _BITS[0] = pa.py_buffer(b"\x55" * (n // 4 + 1))
    return _BITS[0]


_EVEN: list[IntArray] = [np.arange(0, 2 << 20, 2, dtype=np.int64)]


def _every_other(n: int) -> IntArray:
    """0, 2, 4, ... (n values): a view of one array, made again only when a block needs more."""
    if n > _EVEN[0].size:
        _EVEN[0] = np.arange(0, 4 * n, 2, dtype=np.int64)
    return _EVEN[0][:n]


def _ints(values: IntArray) -> pa.Array:
    """An int64 arrow array of ``values`` (``pa.array`` would import pandas where it is installed)."""
    data = np.ascontiguousarray(values, dtype=np.int64)
    return pa.Array.from_buffers(pa.int64(), len(data), [None, pa.py_buffer(data)])


def _strings(data: bytes, offsets: Offsets) -> pa.Array:
    """A string array over ``data`` whose values are between consecutive ``offsets`` (no copy)."""
    return pa.Array.from_buffers(pa.string(), len(offsets) - 1, [None, pa.py_buffer(offsets), pa.py_buffer(data)])


def _offsets(text: pa.Array) -> Offsets:
    return np.frombuffer(text.buffers()[1], dtype=np.int32, count=len(text) + 1, offset=text.offset * 4)


def _floats(arr: pa.Array) -> FloatArray:
    if len(arr) == 0:
        return np.empty(0)
    return np.frombuffer(arr.buffers()[1], dtype=np.float64, count=len(arr), offset=arr.offset * 8)


def _arrow_floats(values: FloatArray, null: BoolArray) -> pa.Array:
    validity = pa.py_buffer(np.packbits(~null, bitorder="little")) if null.any() else None
    data = pa.py_buffer(np.ascontiguousarray(values, dtype=np.float64))
    return pa.Array.from_buffers(pa.float64(), len(values), [validity, data])


def _utf8(buf: bytes) -> bool:
    if buf.isascii():
        return True
    try:
        buf.decode("utf-8")
    except UnicodeDecodeError:
        return False
    return True


@functools.cache
def _keep_freed_memory() -> None:
    """Have glibc's malloc serve the blocks' buffers (a few MB each, freed and taken again for
    every block) from memory it keeps, not from fresh mappings: fresh pages fault in one by one,
    and that was a third of the CPU time (330k page faults on a 4M-row file). Peak memory stays
    that of a few blocks. A no-op where malloc is not glibc's."""
    import ctypes

    try:  # the C library the process runs with (find_library would run ldconfig: a subprocess)
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return
    m_trim_threshold, m_mmap_threshold = -1, -3
    mallopt(m_mmap_threshold, 64 << 20)  # sizes below this come from the heap, not a new mapping
    mallopt(m_trim_threshold, 256 << 20)  # and freed memory is kept for the next block


@functools.cache
def _orjson_agrees() -> bool:
    """Whether orjson spells floats in [LOW, HIGH) that are not whole numbers as pyarrow does
    (checked on a sample once a process; False without orjson)."""
    try:
        import orjson
    except ImportError:
        return False
    k = np.arange(1, 4001)
    sample = (k * 0.7390851332151607 % 1 - 0.5) * 10.0 ** (k % 16 - 5)  # every scale, digits of all lengths
    sample = np.concatenate([sample, [LOW, -LOW, 0.1, 0.3, 1 / 3, 2 / 3, 1e-4, 9999999999.5, 123456.789]])
    size = np.abs(sample)
    sample = sample[(size >= LOW) & (size < HIGH) & (sample != np.trunc(sample))]
    ours = orjson.dumps(sample, option=orjson.OPT_SERIALIZE_NUMPY)[1:-1].split(b",")
    theirs = pc.cast(_arrow_floats(sample, np.zeros(sample.size, dtype=bool)), pa.string()).to_pylist()
    return bool([t.decode() for t in ours] == theirs)


#: A block is cut at the last line end in this much before its end: a longer line, no workers.
WINDOW = 64 << 10


def cuts(path: str, start: int, block: int) -> list[tuple[int, int]] | None:
    """The file's bytes from ``start`` as the blocks a reader of ``block`` bytes at a time
    makes of them (each read's whole lines, the part line carried into the next): (offset,
    length) each. It reads only the ``WINDOW`` at each end of a read; None when either holds no
    line end (a line too long to find the cuts from there)."""
    window = min(WINDOW, block // 2)
    blocks = []
    with open(path, "rb") as f:
        fd = f.fileno()
        size = os.fstat(fd).st_size
        at = start
        for read in range(start, size, block):
            end = min(read + block, size)
            if os.pread(fd, window, read).find(b"\n") < 0:
                return None
            tail = os.pread(fd, window, max(read, end - window))
            cut = max(read, end - window) + tail.rfind(b"\n") + 1
            if cut <= max(read, end - window):
                return None
            blocks.append((at, cut - at))
            at = cut
        if at < size:  # the last line, without its line end
            blocks.append((at, size - at))
    return blocks


def splicer_for(
    cap: Capture,
    corrections: Sequence[Correction],
    temperature: int | None = None,
    also: Sequence[int] = (),
    *,
    stream: bool = False,
) -> Splicer | None:
    """An ``io.csv.splice.Splicer`` for ``cap`` (its arguments), when its lines can be spliced: a
    one-character delimiter, LF or CRLF line ends, and read as a regular file by pyarrow (or,
    with ``stream``, as a stream: stdin, a pipe, a compressed file's data); else None
    (whitespace-separated, CR line ends, a cut last line left out: the general rules)."""

    lay = cap.layout
    if lay.delimiter is None or len(lay.delimiter) != 1 or lay.eol not in ("\n", "\r\n"):
        return None
    if stream and ((cap.path is not None and lay.compression is None) or not isinstance(cap.stream, DataStream)):
        return None
    if not stream and (cap.path is None or not isinstance(cap.stream, pa.OSFile)):
        return None
    return Splicer(len(lay.names), lay.delimiter, lay.eol, lay.decimal, corrections, temperature, also)


def reader_for(cap: Capture, also: Sequence[int] = ()) -> Splicer | None:
    """``splicer_for`` a reader of ``cap`` (the log reader's, noise's): its sensor's cells, and
    those of ``also``, parsed where they lie, none rewritten."""
    return splicer_for(cap, [(cap.layout.sensor, _unchanged)], also=also)


def _unchanged(values: FloatArray) -> FloatArray:
    return values
