"""apply's streaming writer: a capture written again with its sensor columns corrected.

``correct_stream`` skips the general reader for a regular file's blocks of plain lines: it
replaces the sensor cells' text in the block's own bytes (``io.csv.splice``, in worker processes
by ``io.rewrite.forked`` for a large file) and hands any other block to pyarrow's reader and writer
(``io.csv.capture``), which write the same bytes.
"""

from __future__ import annotations

import functools
import io
import itertools
import os
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from typing import IO, TYPE_CHECKING, TypeAlias

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pcsv

from tumblecal_cli.core.arrays import BoolArray, FloatArray
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.csv import capture
from tumblecal_cli.io.csv.capture import Capture, Source, note_dropped
from tumblecal_cli.io.csv.sniff import Layout, skipped
from tumblecal_cli.io.csv.splice import Correct, Correction, Splicer, cuts, splicer_for
from tumblecal_cli.io.rewrite import forked

if TYPE_CHECKING:
    from _typeshed import WriteableBuffer

#: A block's result: record batches the general rules read, or a spliced block's bytes and rows.
Item: TypeAlias = "pa.RecordBatch | tuple[memoryview, int]"
#: A job for the pool: a block's results, once called.
Job: TypeAlias = Callable[[], list[Item]]
#: The general rules for one block: (source, its first data row, its columns as text) -> results.
Convert: TypeAlias = Callable[[Capture, int, list[pa.Array]], list[Item]]
#: Where a block's results are written: the output, or a worker's ``forked.Parts``.
Sink: TypeAlias = "IO[bytes] | forked.Parts"


def correct_stream(
    cap: Capture,
    out: IO[bytes],
    correct: Correct,
    progress: Callable[[int], None] | None = None,
    more: Sequence[Correction] = (),
    temperature: int | None = None,
    *,
    splice: bool = True,
) -> int:
    """Write ``cap`` to ``out`` with its sensor columns replaced by ``correct(values)`` (and
    each triplet of ``more`` by its own correction: one pass for a whole IMU).

    With ``temperature`` (the index of the capture's temperature column) every correction is
    called as ``correct(values, temperature)``, the block's temperatures (n,) °C read alongside
    its sensor columns (``Capture.temperature_values``).

    Every other byte is copied: the preamble and header verbatim, other cells as their text,
    the line ending; a whitespace-separated file is written with single spaces. Rows whose
    sensor cells are all empty stay empty. Returns the number of data rows written.

    A file's blocks of plain lines are spliced (``io.csv.splice``: the sensor cells' text replaced
    in the block's own bytes); the rest, and every file read as a stream, go through pyarrow's
    reader and writer. Both write the same bytes; ``splice=False`` takes the general path only.
    """
    lay = cap.layout
    head = [lay.head]  # written with the first block: an error in it leaves `out` (stdout too) untouched
    options = pcsv.WriteOptions(include_header=False, delimiter=lay.delimiter or " ", quoting_style="none", eol=lay.eol)
    names = [str(i) for i in range(len(lay.names))]
    corrections = [(lay.sensor, correct), *more]

    def convert(source: Capture, first_row: int, cols: list[pa.Array]) -> list[Item]:
        for triplet, fn in corrections:
            values, empty = source.sensor_values([cols[i] for i in triplet], first_row, triplet)
            if temperature is None:
                fixed = fn(values)
            else:
                fixed = fn(values, source.temperature_values(cols[temperature], first_row, empty))
            for j, i in enumerate(triplet):  # the float -> shortest round-trip text: the costliest step
                cols[i] = pc.cast(_arrow_floats(fixed[:, j], empty), pa.string())
                if lay.decimal != ".":
                    cols[i] = pc.replace_substring(cols[i], ".", lay.decimal)
        return [pa.RecordBatch.from_arrays(cols, names=names)]

    def emit(items: list[Item], sink: Sink) -> int:
        return _emit(items, sink, options, lay)

    def write(items: list[Item]) -> int:
        if head:
            out.write(head.pop())
        return emit(items, out)

    plan = _splice_jobs(cap, corrections, convert, temperature) if splice else None
    splicer = splicer_for(cap, corrections, temperature, stream=True) if splice and plan is None else None
    try:
        if plan is not None:
            rows = _spliced(cap, *plan, write, emit, out, head)
        elif splicer is not None:
            rows = _stream_spliced(cap, splicer, convert, write)
        else:
            rows = _pipeline((functools.partial(convert, cap, first, cols) for first, cols in cap.batches()), write)
        cap.unchanged()  # truncated while read: a short output with exit 0 otherwise
    except InputError:
        if not head:  # rows are out (to stdout, which cannot take them back): say it is not all
            out.write(INCOMPLETE)
        raise
    if head:
        out.write(head.pop())
    if progress is not None:
        progress(rows)
    return rows


def _emit(items: list[Item], sink: Sink, options: pcsv.WriteOptions, lay: Layout) -> int:
    """Write a block's results (record batches, or spliced bytes and their number of rows) to
    ``sink``; returns the rows."""
    rows = 0
    for item in items:
        if isinstance(item, pa.RecordBatch):
            rows += _write_batch(item, sink, options, lay)
        else:
            sink.write(item[0])
            rows += item[1]
    return rows


def _pipeline(jobs: Iterator[Job], write: Callable[[list[Item]], int]) -> int:
    """Run ``jobs`` (each a block's work, called) on a pool and ``write`` their results in
    order: this thread reads block k+1 and writes block k-1 while the pool converts block k
    (pyarrow and numpy release the GIL). At most `ahead` blocks are in flight at once."""
    rows = 0
    workers = max(2, os.cpu_count() or 1)
    ahead = workers + 2  # two blocks more than workers: a worker done early finds the next one waiting
    pending: deque[Future[list[Item]]] = deque()
    with ThreadPoolExecutor(max_workers=workers) as pool:
        for job in jobs:
            pending.append(pool.submit(job))
            while len(pending) >= ahead or (pending and pending[0].done()):
                rows += write(pending.popleft().result())
        while pending:
            rows += write(pending.popleft().result())
    return rows


def _spliced(
    cap: Capture,
    jobs: Iterator[Job],
    spliced: Callable[[bytes, int], list[Item]],
    write: Callable[[list[Item]], int],
    emit: Callable[[list[Item], Sink], int],
    out: IO[bytes],
    head: list[bytes],
) -> int:
    """Run a regular file's jobs (``_splice_jobs``) on this process's threads, or a big file's
    blocks on worker processes, one per core, that write to ``out`` themselves (``io.rewrite.forked``).
    ``head`` is emptied once something is written."""

    path, start = cap.path, len(cap.layout.head)
    assert path is not None
    workers = forked.workers_for(path, os.path.getsize(path) - start) if _descriptor(out) else 0
    blocks = cuts(path, start, capture.BLOCK_BYTES) if workers else None
    if not blocks:
        return _pipeline(jobs, write)

    def render(block: bytes, at: int) -> tuple[list[bytes | memoryview], int]:  # in a worker: the block's bytes
        sink = forked.Parts()
        return sink.parts, emit(spliced(block, at), sink)

    return forked.pipeline(path, blocks, render, out, head[0], workers, written=head.pop)


def _stream_spliced(cap: Capture, splicer: Splicer, convert: Convert, write: Callable[[list[Item]], int]) -> int:
    """A stream's blocks of plain lines spliced on threads, in order, until one is not plain:
    from there on (that block, the ones read after it, the rest of the stream) the general
    rules, whose messages count data rows from the stream's first ("data row N": a stream has
    no second pass to find line numbers). Returns the rows written."""
    rows = 0
    workers = max(2, os.cpu_count() or 1)
    pending: deque[tuple[Future[tuple[memoryview, int] | None] | None, bytes]] = deque()
    blocks = _stream_blocks(cap.stream)

    def general(text: bytes, rows: int) -> int:  # the general rules from ``text`` on
        for other, _ in pending:
            if other is not None:
                other.cancel()
        rest = [text, *(b for _, b in pending)]
        pending.clear()
        return _stream_rest(cap, itertools.chain(rest, (b for b, _ in blocks)), rows, convert, write)

    with ThreadPoolExecutor(max_workers=workers) as pool:
        for item in itertools.chain(blocks, [None]):  # None: the end, every block still pending written
            if item is not None:
                block, plain = item
                pending.append((pool.submit(splicer.block, block) if plain else None, block))
            while pending and (
                item is None or len(pending) >= workers + 2 or pending[0][0] is None or pending[0][0].done()
            ):
                job, text = pending.popleft()
                done = job.result() if job is not None else None
                if done is None:
                    return rows + general(text, rows)
                rows += write([done])
    note_dropped(cap)
    return rows


def _stream_blocks(stream: Source | IO[bytes]) -> Iterator[tuple[bytes, bool]]:
    """A stream's bytes as blocks of whole lines (the last may lack its line end), each with
    whether it may be spliced: not a line longer than a block (the general reader says so)."""
    carry = b""
    while chunk := stream.read(capture.BLOCK_BYTES):
        cut = chunk.rfind(b"\n") + 1
        if cut == 0:
            carry += chunk
            if len(carry) >= capture.BLOCK_BYTES:
                yield carry, False
                carry = b""
            continue
        block, carry = b"".join((carry, memoryview(chunk)[:cut])), chunk[cut:]
        yield block, block.find(b"\n") < capture.BLOCK_BYTES  # its first line, which began in an earlier read
    if carry:
        yield carry, True


def _stream_rest(
    cap: Capture,
    blocks: Iterator[bytes],
    before: int,
    convert: Convert,
    write: Callable[[list[Item]], int],
) -> int:
    rest = _Rest(cap, _Chained(blocks), before)
    rows = _pipeline((functools.partial(convert, rest, first, cols) for first, cols in rest.batches()), write)
    note_dropped(cap)
    return rows


class _Chained(io.RawIOBase):
    """Blocks of bytes read as one stream."""

    def __init__(self, blocks: Iterator[bytes]) -> None:
        self._blocks = blocks
        self._buf = memoryview(b"")

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: WriteableBuffer) -> int:
        """As much as ``buffer`` holds, across blocks: pyarrow's streaming reader takes a read
        that is a lone line feed (the end of a CRLF cut at a block's last byte) for the end of
        the data, and drops what follows without a word (pyarrow 26)."""
        view = memoryview(buffer).cast("B")
        n = 0
        while n < len(view):
            if not len(self._buf):
                block = next(self._blocks, None)
                if block is None:
                    break
                self._buf = memoryview(block)
            k = min(len(view) - n, len(self._buf))
            view[n : n + k] = self._buf[:k]
            self._buf = self._buf[k:]
            n += k
        return n


class _Rest(Capture):
    """The rest of a stream after ``before`` data rows were spliced: its messages count from the first."""

    def __init__(self, cap: Capture, stream: Source, before: int) -> None:
        super().__init__(cap.layout, stream, cap.path, cap.hasher)  # (a path: a compressed file's)
        self._before = before

    def _locate(self, row: int, sensor_j: int, what: str, triplet: tuple[int, int, int] | None = None) -> InputError:
        return super()._locate(row + self._before, sensor_j, what, triplet)


def _descriptor(out: IO[bytes]) -> bool:
    """Whether ``out`` writes to a file descriptor (a worker process can write to it too)."""
    try:
        out.fileno()
    except (AttributeError, OSError, ValueError):  # io.UnsupportedOperation is both of the last two
        return False
    return True


def _splice_jobs(
    cap: Capture,
    corrections: Sequence[Correction],
    convert: Convert,
    temperature: int | None = None,
) -> tuple[Iterator[Job], Callable[[bytes, int], list[Item]]] | None:
    """The jobs that correct a regular file block by block, spliced where its lines are plain
    (``io.csv.splice``), else by the general rules, and the function of a block's job
    (``spliced(block, at)``); None when the file is not one to splice (a stream,
    whitespace-separated, CR line ends, a cut last line left out)."""
    splicer = splicer_for(cap, corrections, temperature)
    if splicer is None or cap.path is None:
        return None
    lay, path = cap.layout, cap.path

    def general(source: _Slice) -> list[Item]:
        return [item for first, cols in source.batches() for item in convert(source, first, cols)]

    def spliced(block: bytes, at: int) -> list[Item]:
        done = splicer.block(block)
        if done is not None:
            return [done]
        return general(_Slice(cap, pa.BufferReader(block), at))

    def jobs() -> Iterator[Job]:
        at = len(lay.head)
        with open(path, "rb") as f:
            f.seek(at)
            for block, plain in _stream_blocks(f):
                if not plain:  # a line longer than a block: the general rules for the rest of the file
                    rest = pa.OSFile(path)
                    rest.seek(at)
                    source = _Slice(cap, rest, at)
                    for first, cols in source.batches():
                        yield functools.partial(convert, source, first, cols)
                    return
                yield functools.partial(spliced, block, at)
                at += len(block)

    return jobs(), spliced


class _Slice(Capture):
    """Part of a capture's data section, from byte ``at`` of the file, read by the general
    rules: its errors name the file's lines."""

    def __init__(self, cap: Capture, stream: Source, at: int) -> None:
        super().__init__(cap.layout, stream, cap.path, cap.hasher)
        self._at = at

    def line_of_row(self, row: int) -> int | None:
        assert self._path is not None
        lay = self.layout
        with open(self._path, "rb") as f:
            f.seek(len(lay.head))
            before, left = 0, self._at - len(lay.head)  # lines before the slice (only on an error)
            while left > 0:
                chunk = f.read(min(left, capture.BLOCK_BYTES))
                before, left = before + chunk.count(b"\n"), left - len(chunk)
            i = 0
            for offset, raw in enumerate(f):
                if skipped(raw.decode("utf-8", errors="replace").rstrip("\r\n")):
                    continue
                if i == row:
                    return lay.data_line + before + offset
                i += 1
        return None


#: The last line of a corrected stream that stopped on a bad row after rows were written: one
#: field, so that a reader checking the header's field count refuses it, and no `#`, so that it is
#: not taken for a comment. Exit 2 says so too. (With -o the temporary file is thrown away.)
INCOMPLETE = b"\ntumblecal: output incomplete: the run stopped on an error (exit 2, see stderr)\n"


def _arrow_floats(values: FloatArray, null: BoolArray) -> pa.Array:
    """A float64 arrow array of ``values``, null where ``null`` is set."""
    validity = pa.py_buffer(np.packbits(~null, bitorder="little")) if null.any() else None
    data = pa.py_buffer(np.ascontiguousarray(values, dtype=np.float64))
    return pa.Array.from_buffers(pa.float64(), len(values), [validity, data])


def _write_batch(batch: pa.RecordBatch, out: Sink, options: pcsv.WriteOptions, lay: Layout) -> int:
    try:
        pcsv.write_csv(batch, out, options)
    except pa.ArrowInvalid:  # a text cell holds a quote: pyarrow will not write it unquoted
        _write_plain(batch, out, lay.delimiter or " ", lay.eol)
    return int(batch.num_rows)


def _write_plain(batch: pa.RecordBatch, out: Sink, delimiter: str, eol: str) -> None:
    columns = [[("" if v is None else v) for v in c.to_pylist()] for c in batch.columns]
    out.write("".join(delimiter.join(row) + eol for row in zip(*columns, strict=True)).encode())
