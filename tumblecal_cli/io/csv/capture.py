"""A capture opened for streaming: one set of rules, one engine (docs/reference/csv.md).

1. ``open_capture`` reads the first block itself and lets ``io.csv.sniff`` decide the layout and
   the sensor and time columns.
2. The data section (everything after the header) streams through pyarrow's CSV reader with
   every column read as *text* and quoting off, so cells we do not touch keep their exact
   bytes (``00001000`` stays ``00001000``). Only the three sensor columns are converted.
3. When pyarrow rejects something, ``Capture._diagnose`` re-reads the file line by line with
   the same rules to name the line and column. That slow pass only runs after a failure.

A compressed capture (gzip, bzip2, xz, zstd: ``io.csv.compressed``, known by its first bytes) is
read as a stream of its data, as stdin is; a second pass (an error's line) decompresses again.

pyarrow is the engine because it streams, imports in 0.2 s (pandas takes 0.45 s here) and
writes floats as their shortest round-trip text; README "Dependencies, and why" has the measurements.
Also here: copying byte ranges of a capture into new files (segment's blocks).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import io
import os
import re
import stat
import sys
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import IO, TYPE_CHECKING, Protocol, TypeAlias

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pcsv

from tumblecal_cli.core.arrays import BoolArray, FloatArray
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import sources
from tumblecal_cli.io.csv import compressed
from tumblecal_cli.io.csv.sniff import (
    COMMA_NUMBER,
    HEAD_BYTES,
    NUMBER,
    TEMPERATURE_NAMES,
    WS_EDGE,
    WS_RUN,
    Layout,
    bare,
    column_index,
    no_column_twice,
    pick_columns,
    quoted,
    skipped,
    sniff,
    split_fields,
    unit_of_name,
)
from tumblecal_cli.io.outputs import atomic_output
from tumblecal_cli.io.readspec import ReadSpec

if TYPE_CHECKING:
    from _typeshed import WriteableBuffer
    from numpy.typing import NDArray

BLOCK_BYTES = 1 << 20  # pyarrow block size when streaming: bigger blocks raise peak memory

#: What a capture's data section is read from: pyarrow's own file reader (a regular file), or a
#: file object of ours (``DataStream``; a stream's rest, ``io.rewrite.writer``).
Source: TypeAlias = "pa.NativeFile | io.RawIOBase"


class Hasher(Protocol):
    """What a capture's SHA-256 is taken with (``hashlib.sha256()``)."""

    def update(self, data: bytes, /) -> None: ...

    def hexdigest(self) -> str: ...


class DataStream(io.RawIOBase):
    """The data section as a byte stream, for stdin, compressed and whitespace-separated files:
    the sniffed remainder of the first block, then the rest; hashes what it reads (stdin has no
    second pass) and squeezes runs of whitespace to single spaces for pyarrow."""

    def __init__(
        self,
        first: bytes,
        rest: IO[bytes],
        hasher: Hasher,
        squeeze: bool,
        owns: bool = False,
        drop_last: Callable[[bytes], bool] | None = None,
    ) -> None:
        self._rest = rest
        self._owns = owns  # close ``rest`` too (a file we opened; never stdin)
        self._hasher = hasher
        self._squeeze = squeeze
        self._drop_last = drop_last  # whether an unterminated last line is dropped (--drop-incomplete)
        self.dropped: bytes | None = None  # the line it dropped
        self._carry = b""
        self._buf = self._transform(first, final=False)
        self._eof = False

    def _transform(self, chunk: bytes, final: bool) -> bytes:
        if not self._squeeze and self._drop_last is None:
            return chunk
        chunk = self._carry + chunk
        cut = len(chunk) if final else max(chunk.rfind(b"\n"), chunk.rfind(b"\r")) + 1
        self._carry, out = chunk[cut:], chunk[:cut]
        if final and self._drop_last is not None and out and not out.endswith((b"\n", b"\r")):
            start = max(out.rfind(b"\n"), out.rfind(b"\r")) + 1
            if self._drop_last(out[start:]):
                self.dropped, out = out[start:], out[:start]
        return WS_EDGE.sub(b"", WS_RUN.sub(b" ", out)) if self._squeeze else out

    def readable(self) -> bool:
        return True

    def close(self) -> None:
        if self._owns:
            self._rest.close()
        super().close()

    def readinto(self, buffer: WriteableBuffer) -> int:
        """As much as ``buffer`` holds, unless the stream ends (see ``_Chained.readinto``: a
        read of a lone line feed would end pyarrow's reading)."""
        view = memoryview(buffer).cast("B")
        while len(self._buf) < len(view) and not self._eof:
            chunk = self._rest.read(max(len(view), 1 << 16))
            self._hasher.update(chunk)
            self._eof = not chunk
            self._buf += self._transform(chunk, final=self._eof)
        n = min(len(view), len(self._buf))
        view[:n] = self._buf[:n]
        self._buf = self._buf[n:]
        return n


class Capture:
    """An opened capture: its layout and a one-shot stream of its data section."""

    def __init__(
        self, layout: Layout, stream: Source, path: str | None, hasher: Hasher, stamp: Stamp | None = None
    ) -> None:
        self.layout = layout
        self._stream = stream  # pyarrow's own file reader, or a DataStream
        self._path = path  # None for stdin: no second pass is possible
        self._hasher = hasher
        self._stamp = stamp  # the file as it was opened (a regular file's), for unchanged()

    @property
    def path(self) -> str | None:
        """The file's path (a compressed file's too); None for stdin: no second pass is possible."""
        return self._path

    @property
    def stream(self) -> Source:
        """The one-shot stream of the data section: pyarrow's own file reader, or a DataStream."""
        return self._stream

    @property
    def hasher(self) -> Hasher:
        """The sha256 of a stream's bytes as they are read (what ``sha256`` gives for stdin)."""
        return self._hasher

    def sha256(self) -> str:
        """Hash of every byte of the file (for stdin: once the data has been read)."""
        if self._path is None:
            return str(self._hasher.hexdigest())
        with open(self._path, "rb") as f:
            return hashlib.file_digest(f, "sha256").hexdigest()

    def unchanged(self) -> None:
        """Raise an InputError if the file is not the one opened: another file now (its inode),
        shorter, or of the same size written since (its time). Rows read from a file truncated
        or rewritten while it was read are not the file's, and an output made of them would be
        short with nothing said; a file that grew (a logger still writing) was read as it was."""
        if self._stamp is None or self._path is None:
            return
        try:
            now: Stamp | None = stamp(os.stat(self._path))
        except OSError:
            now = None
        was = self._stamp
        if changed(was, now):
            size = "gone" if now is None else f"{now[2]:,} bytes"
            raise InputError(
                f"the file changed while it was read ({was[2]:,} bytes when opened, now {size}): what was read "
                "is not the file",
                file=self.layout.name,
                hint="correct it once it is written whole (copy it aside first if a logger still writes it)",
            )

    def close(self) -> None:
        self._stream.close()

    def __enter__(self) -> Capture:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def batches(self, *, only_sensor: bool = False) -> Iterator[tuple[int, list[pa.Array]]]:
        """(first data row, columns as text) per block; ``only_sensor`` reads the sensor,
        time, temperature and extra columns alone (in that order, each if present)."""
        lay = self.layout
        keys = [str(i) for i in range(len(lay.names))]
        wanted = list(lay.sensor) + [i for i in (lay.time, lay.per_row_column, lay.extra) if i is not None]
        include = [keys[i] for i in wanted] if only_sensor else keys
        read = include if keys[0] in include else [keys[0], *include]  # column 0 tells comments
        bad_rows: list[str] = []

        def invalid(row: pcsv.InvalidRow) -> str:
            if skipped(row.text):
                return "skip"
            bad_rows.append(row.text)
            return "error"

        try:
            reader = pcsv.open_csv(
                self._stream,
                read_options=pcsv.ReadOptions(column_names=keys, block_size=BLOCK_BYTES, use_threads=False),
                parse_options=pcsv.ParseOptions(
                    delimiter=lay.delimiter or " ", quote_char=False, invalid_row_handler=invalid
                ),
                convert_options=pcsv.ConvertOptions(
                    column_types={k: pa.string() for k in keys},
                    include_columns=read,
                    strings_can_be_null=False,
                ),
            )
            row = 0
            for batch in reader:
                # a "# ..." line with as many delimiters as the header is parsed as a row: drop it
                # (a cheap substring test first; the anchored regex only when a '#' is there)
                if pc.any(pc.match_substring(batch.column(keys[0]), "#")).as_py():
                    batch = batch.filter(pc.invert(pc.match_substring_regex(batch.column(keys[0]), r"^\s*#")))
                yield row, [batch.column(k) for k in include]
                row += batch.num_rows
            note_dropped(self)
        except (pa.ArrowInvalid, UnicodeDecodeError) as err:
            raise self._diagnose(str(err), bad_rows[-1] if bad_rows else None) from None

    def sensor_values(
        self, columns: Sequence[pa.Array], first_row: int, triplet: tuple[int, int, int] | None = None
    ) -> tuple[FloatArray, BoolArray]:
        """The three sensor columns as an (n, 3) float array, and a mask of rows whose sensor
        cells are all empty (NaN in the array). A partly empty row or a cell that is not a
        number is an error naming its line and column. ``triplet``: the columns' indices in
        the file, when not the layout's sensor (for error messages)."""
        n = len(columns[0])
        values = np.empty((n, 3))
        empty = np.zeros((n, 3), dtype=bool)
        for j, text in enumerate(columns[:3]):
            text = self.pointed(text)
            if starts_quoted(text):
                text = unquote(text)
            try:
                values[:, j] = to_floats(pc.cast(text, pa.float64()))
                continue
            except pa.ArrowInvalid:
                pass
            text = unquote(text)  # (and trimmed)
            is_empty = pc.equal(pc.utf8_length(text), 0)
            bad = pc.and_(pc.invert(is_empty), pc.invert(pc.match_substring_regex(text, NUMBER)))
            if pc.any(bad).as_py():
                i = int(pc.index(bad, True).as_py())
                cell = str(columns[j][i].as_py())
                err = self._locate(first_row + i, j, f"not a number: {quoted(cell)}", triplet)
                if COMMA_NUMBER.match(cell) and self.layout.decimal == ".":
                    err.hint = "it has a decimal comma: give --decimal , (columns separated by ; or tabs)"
                raise err
            empty[:, j] = to_bools(is_empty)
            values[:, j] = to_floats(pc.cast(pc.replace_substring_regex(text, "^$", "nan"), pa.float64()))
        all_empty: BoolArray = empty[:, 0] & empty[:, 1] & empty[:, 2]
        partial = empty.any(axis=1) & ~all_empty
        if partial.any():
            i = int(np.argmax(partial))
            j = int(np.argmax(empty[i]))
            raise self._locate(
                first_row + i, j, "empty sensor cell in a row whose other sensor cells are filled", triplet
            )
        return values, all_empty

    def finite_values(self, columns: Sequence[pa.Array], first_row: int) -> tuple[FloatArray, BoolArray]:
        """``sensor_values``, where a cell of ±inf or nan is an error naming its line and column:
        one would poison a mean (``apply`` passes them through; solve, verify and noise do not)."""
        values, empty = self.sensor_values(columns, first_row)
        bad = ~np.isfinite(values) & ~empty[:, None]
        if bad.any():
            i, j = (int(k[0]) for k in np.nonzero(bad))
            raise self._locate(first_row + i, j, f"not a finite number: {quoted(columns[j][i].as_py())}")
        return values, empty

    def temperature_values(self, text: pa.Array, first_row: int, empty: BoolArray) -> FloatArray:
        """The temperature column of a block as floats (°C); a cell that is not a finite number,
        or an empty one, on a row with sensor values (``empty``: rows without), is an error naming
        its line and column."""
        values = self._temperatures(text, first_row, empty)
        odd = ~np.isfinite(values) & ~empty
        if odd.any():  # nan, inf: no temperature to correct the row at
            i = int(np.argmax(odd))
            where = (self.layout.per_row_column or 0,) * 3
            cell = quoted(str(text[i].as_py()))
            raise self._locate(first_row + i, 0, f"{self.layout.per_row} is not a finite number: {cell}", where)
        return values

    def _temperatures(self, text: pa.Array, first_row: int, empty: BoolArray) -> FloatArray:
        lay = self.layout
        assert lay.per_row_column is not None
        with contextlib.suppress(pa.ArrowInvalid):  # every cell a number (the usual case): one cast
            return to_floats(pc.cast(self.pointed(text), pa.float64()))
        where = (lay.per_row_column, lay.per_row_column, lay.per_row_column)
        trimmed = pc.utf8_trim_whitespace(unquote(self.pointed(text)))
        blank = to_bools(pc.equal(pc.utf8_length(trimmed), 0))
        missing = blank & ~empty
        if missing.any():
            i = int(np.argmax(missing))
            raise self._locate(first_row + i, 0, f"empty {lay.per_row} cell in a row with sensor values", where)
        try:
            return to_floats(pc.cast(pc.replace_substring_regex(trimmed, "^$", "nan"), pa.float64()))
        except pa.ArrowInvalid:
            bad = pc.and_(
                pc.invert(pc.equal(pc.utf8_length(trimmed), 0)), pc.invert(pc.match_substring_regex(trimmed, NUMBER))
            )
            i = int(pc.index(bad, True).as_py()) if pc.any(bad).as_py() else 0
            cell = str(text[i].as_py())
            raise self._locate(first_row + i, 0, f"{lay.per_row} is not a number: {quoted(cell)}", where) from None

    def pointed(self, text: pa.Array) -> pa.Array:
        """Number cells with a decimal point (a decimal comma file's cells with it replaced)."""
        return text if self.layout.decimal == "." else pc.replace_substring(text, ",", ".")

    # -- error paths: find the line and column with the same rules, one line at a time --

    def _locate(self, row: int, sensor_j: int, what: str, triplet: tuple[int, int, int] | None = None) -> InputError:
        lay = self.layout
        column = lay.names[(triplet or lay.sensor)[sensor_j]]
        line = self.line_of_row(row)
        if line is None:
            return InputError(f"{what} in column {column!r} (data row {row + 1})", file=lay.name)
        return InputError(what, file=lay.name, line=line, column=column)

    def _data_lines(self) -> Iterator[tuple[int, str]]:
        """(line number, text) of each data line of the file, skipping blanks and comments."""
        assert self._path is not None
        lay = self.layout
        with compressed.open_data(self._path, lay.name) as f:
            f.read(len(lay.head))
            for offset, raw in enumerate(f):
                text = raw.decode("utf-8", errors="replace").rstrip("\r\n")
                if not skipped(text):
                    yield lay.data_line + offset, text

    def line_of_row(self, row: int) -> int | None:
        """The file line of data row ``row`` (from 0), found by reading the file again; None for stdin."""
        if self._path is None:
            return None
        for i, (line, _) in enumerate(self._data_lines()):
            if i == row:
                return line
        return None

    def _diagnose(self, engine_message: str, bad_row: str | None = None) -> InputError:
        lay = self.layout
        if "straddl" in engine_message:  # pyarrow: a row longer than a whole block
            too_long = f"a row longer than {BLOCK_BYTES >> 20} MB: not a capture's row"
            if self._path is not None:
                for line, text in self._data_lines():
                    if len(text) >= BLOCK_BYTES:
                        return InputError(too_long, file=lay.name, line=line)
            return InputError(too_long, file=lay.name)
        if self._path is not None:
            for line, text in self._data_lines():
                cells = split_fields(text, lay.delimiter)
                if len(cells) != len(lay.names):
                    return InputError(
                        f"row has {len(cells)} fields, the header has {len(lay.names)}",
                        file=lay.name,
                        line=line,
                    )
        if bad_row is not None:  # stdin: no second pass, so no line number
            return InputError(
                f"row has {len(split_fields(bad_row, lay.delimiter))} fields, the header has {len(lay.names)}: "
                f"{bad_row[:80]!r}",
                file=lay.name,
            )
        if "decode" in engine_message or "UTF8" in engine_message or "UTF-8" in engine_message:
            return InputError("not UTF-8 text (is it a binary file?)", file=lay.name)
        first = engine_message.splitlines()[0] if engine_message else "unreadable"
        return InputError(f"cannot parse: {first.removeprefix('CSV parse error: ')}", file=lay.name)


def open_capture(
    path: str, spec: ReadSpec | None = None, *, name: str | None = None, extra: str | None = None
) -> Capture:
    """Open ``path`` ('-' for stdin), sniff its layout and find its sensor and time columns by
    ``spec`` (``columns`` overrides detection; ``prefer``, a calibration's recorded columns, is
    used when all three are present; ``dialect`` is what the user says of the file's shape);
    ``extra`` names one more column to read (as text); ``name`` is how messages name the file
    (default: the path).
    """
    spec = spec or ReadSpec()
    sensor, columns, prefer, time_column = spec.sensor, spec.columns, spec.prefer, spec.time_column
    temperature_column, dialect = spec.temperature_column, spec.dialect
    name = name or ("<stdin>" if path == "-" else path)
    if spec.stream is not None:
        raise InputError(
            f"--stream {spec.stream}: this file is read as a CSV capture, whose one stream is its columns",
            file=name,
            hint=f"--stream picks a stream of a log ({sources.kinds()}); --columns and --sensor pick a CSV's",
        )
    f, first, hasher, kind, regular = _opened(path, name)
    opened = stamp(os.stat(path)) if regular else None  # (a compressed file's f is its decompressor)
    try:
        layout, consumed = sniff(name, first, at_eof=len(first) < HEAD_BYTES, no_header=spec.no_header, dialect=dialect)
        layout.sensor, layout.time = pick_columns(layout, sensor, columns, prefer, time_column)
        if layout.time is not None:
            layout.time_unit = unit_of_name(layout.names[layout.time])
        lower = [n.lower() for n in layout.names]
        if temperature_column is not None:
            layout.per_row_column = column_index(layout, temperature_column, "--temperature-column")
        else:
            layout.per_row_column = next((i for i, n in enumerate(lower) if n in TEMPERATURE_NAMES), None)
        if extra is not None:
            layout.extra = column_index(layout, extra, "column")
        no_column_twice(layout, sensor, columns, prefer, time_column, temperature_column)
    except InputError:
        if f is not sys.stdin.buffer:
            f.close()
        raise
    stream: Source
    plain = regular and kind is None  # (a compressed file is read as a stream of its data)
    cut = plain and _cut_short(f, layout, consumed, dialect.drop_incomplete)
    if plain and layout.delimiter is not None and not cut:
        # a regular file: pyarrow reads it natively from the end of the header (1.7x faster)
        f.close()
        stream = pa.OSFile(path)
        stream.seek(consumed)
    else:
        drop = functools.partial(_incomplete, layout) if dialect.drop_incomplete else None
        squeeze = layout.delimiter is None
        read = hasher if kind is None else _Unhashed()  # (compressed: its bytes are hashed, not its data)
        owns = path != "-" or kind is not None
        stream = DataStream(first[consumed:], f, read, squeeze=squeeze, owns=owns, drop_last=drop)
    layout.compression = kind
    return Capture(layout, stream, path if regular else None, hasher, opened)  # a pipe is read once


#: A file as opened: (device, inode, size, modification time in ns).
Stamp: TypeAlias = tuple[int, int, int, int]


def stamp(st: os.stat_result) -> Stamp:
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)


def changed(was: Stamp, now: Stamp | None) -> bool:
    """Whether a file stamped ``was`` is another now (gone, another inode), shorter, or of the
    same size written since: what was read of it is not the file. A file that only grew (a log
    still being written) has not changed: what was read is still in it."""
    if now is None or now[:2] != was[:2]:
        return True
    return now[2] < was[2] or (now[2] == was[2] and now[3] != was[3])


class _Unhashed:
    """What a compressed capture's data is hashed with: nothing (its file's bytes are hashed)."""

    def update(self, data: bytes, /) -> None:
        pass

    def hexdigest(self) -> str:
        return ""


def _opened(path: str, name: str) -> tuple[IO[bytes], bytes, Hasher, str | None, bool]:
    """``path`` ('-': stdin) opened: (the file, its first block, the hash of the bytes read, its
    compression or None, whether it is a regular file). A compressed file is its decompressed
    data from here on (a stream's bytes hashed as the decompressor reads them)."""
    try:
        f: IO[bytes] = sys.stdin.buffer if path == "-" else open(path, "rb")  # noqa: SIM115
    except FileNotFoundError:
        raise InputError("no such file", file=name) from None
    except IsADirectoryError:
        raise InputError("is a directory, not a CSV file", file=name) from None
    except OSError as err:
        raise InputError(f"cannot open: {err.strerror}", file=name) from None
    hasher = hashlib.sha256()
    first = f.read(HEAD_BYTES)
    hasher.update(first)
    regular = path != "-" and stat.S_ISREG(os.fstat(f.fileno()).st_mode)  # not a pipe, FIFO or device
    kind = compressed.kind_of(first)
    if kind is None:
        return f, first, hasher, kind, regular
    if regular:
        f.seek(0)
        raw = f
    else:
        raw = io.BufferedReader(compressed.Replay(first, f, hasher.update))
    data = compressed.reader(kind, raw, name)
    try:
        first = data.read(HEAD_BYTES)
    except InputError:
        if f is not sys.stdin.buffer:
            data.close()
        raise
    return data, first, hasher, kind, regular


def _incomplete(layout: Layout, line: bytes) -> bool:
    """Whether an unterminated last line was cut short by a logger stopped mid-write: fewer
    fields than the header, or a sensor cell empty or not a number. (A complete last line
    without a line end is common, and kept.)"""
    text = line.decode("utf-8", errors="replace").rstrip("\r\n")
    if skipped(text):
        return False
    cells = split_fields(text, layout.delimiter)
    if len(cells) < len(layout.names):
        return True
    sensor = [bare(cells[i]).replace(layout.decimal, ".") for i in layout.sensor]
    return any(not re.match(NUMBER, c) for c in sensor) and not all(not c for c in sensor)


def _cut_short(f: IO[bytes], layout: Layout, consumed: int, drop: bool) -> bool:
    """Whether a regular file's last line is cut short (see ``_incomplete``): an error naming
    it, or with ``drop`` (--drop-incomplete) a note, and True (the line is left out as read)."""
    size = os.fstat(f.fileno()).st_size
    if size <= consumed:
        return False
    here, back = f.tell(), 65536
    while True:  # back from the end until the last line's start is in view (a wide row: further)
        start = max(consumed, size - back)
        f.seek(start)
        tail = f.read()
        if tail.endswith((b"\n", b"\r")):
            f.seek(here)
            return False
        cut = max(tail.rfind(b"\n"), tail.rfind(b"\r"))
        if cut >= 0 or start == consumed:
            break
        back *= 4
    f.seek(here)
    last = tail[cut + 1 :]
    if not _incomplete(layout, last):
        return False
    if drop:  # the stream leaves it out, and says so (Capture.batches)
        return True
    shown = quoted(last.decode("utf-8", errors="replace"), 40)
    f.seek(0)
    end = b"\r" if layout.eol == "\r" else b"\n"  # CR alone ends a line of an old Mac's file
    line = sum(chunk.count(end) for chunk in iter(functools.partial(f.read, 1 << 20), b"")) + 1
    f.close()
    raise InputError(
        f"last line incomplete: {shown} (a logger stopped mid-write?)",
        file=layout.name,
        line=line,
        hint="--drop-incomplete drops it with a warning",
    )


def copy_bytes(path: str, layout: Layout, spans: Sequence[tuple[int, int]], outputs: Sequence[str]) -> None:
    """Write bytes ``start``..``end`` of ``path`` (each span a block's whole lines) to its
    output after the file's own preamble and header, in pieces: memory stays that of a piece.
    The files are written on a few threads (making a file is most of the cost of a short one,
    and the kernel does it without the GIL); the first error is raised once all have ended."""

    def one(fd: int, start: int, end: int, output: str) -> None:
        with atomic_output(output) as out:
            out.write(layout.head)
            out.flush()
            while start < end:  # the kernel copies, file to file (read and written back where it cannot)
                done = _copy_range(fd, out, start, min(end - start, BLOCK_BYTES * 16))
                if not done:
                    raise InputError("the log got shorter while it was read", file=layout.name)
                start += done

    with open(path, "rb") as f, ThreadPoolExecutor(max_workers=4) as pool:
        jobs = [pool.submit(one, f.fileno(), a, b, o) for (a, b), o in zip(spans, outputs, strict=True)]
        try:
            for job in jobs:
                job.result()
        except BaseException:  # an error, Ctrl-C: the files not begun are not begun, those begun end
            for job in jobs:
                job.cancel()
            raise


def _copy_range(source: int, out: IO[bytes], at: int, size: int) -> int:
    """Copy up to ``size`` bytes of ``source`` from ``at`` to the end of ``out``: the bytes copied."""
    with contextlib.suppress(OSError, AttributeError):  # another file system, or no copy_file_range
        return os.copy_file_range(source, out.fileno(), size, at)
    piece = os.pread(source, size, at)
    out.write(piece)
    out.flush()
    return len(piece)


def copy_rows(path: str, layout: Layout, spans: Sequence[tuple[int, int]], outputs: Sequence[str]) -> None:
    """Write data rows ``first``..``last`` of each span to its output file, byte for byte, after
    the file's own preamble and header: each block a capture on its own. Atomic per file."""

    if layout.compression is None:
        data = np.fromfile(path, dtype=np.uint8)
    else:  # the lines of its data
        data = np.frombuffer(compressed.read_all(path), dtype=np.uint8)
    starts, ends = row_offsets(data, len(layout.head))
    for (first, last), output in zip(spans, outputs, strict=True):
        with atomic_output(output) as out:
            out.write(layout.head)
            out.write(data[starts[first] : ends[last]].data)  # the bytes themselves, no copy


def row_offsets(data: NDArray[np.uint8], head: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Byte offsets (start, end) of each data row of a file's bytes whose preamble and header
    take ``head`` bytes: every line that is not blank or a # comment (the reader's rules). A
    line ends at LF, CR LF or a CR alone (old Mac files, and files of mixed line ends)."""
    ending = data[head:] == 10
    cr = data[head:] == 13
    if cr.any():
        cr[:-1] &= ~ending[1:]  # a CR before an LF: the LF ends that line
        ending |= cr
    newline = np.flatnonzero(ending) + head
    starts = np.concatenate([[head], newline + 1])
    ends = np.concatenate([newline + 1, [data.size]])
    if starts[-1] >= data.size:  # the file ends with a newline: no line after it
        starts, ends = starts[:-1], ends[:-1]
    first = starts.copy()  # the first byte that is not a space or tab, line by line
    lead = data[np.minimum(first, data.size - 1)]
    todo = np.flatnonzero(((lead == 32) | (lead == 9)) & (first < ends))
    while todo.size:  # only lines that start with blanks, one blank a round
        first[todo] += 1
        lead[todo] = data[np.minimum(first[todo], data.size - 1)]
        todo = todo[((lead[todo] == 32) | (lead[todo] == 9)) & (first[todo] < ends[todo])]
    blank = (first >= ends) | (lead == 10) | (lead == 13)
    row = ~(blank | (lead == ord("#")))
    return starts[row], ends[row]


def note_dropped(cap: Capture) -> None:
    """The note for a last line --drop-incomplete dropped (what ``Capture.batches`` says)."""
    dropped = getattr(cap._stream, "dropped", None)
    if dropped is not None:
        shown = quoted(dropped.decode("utf-8", errors="replace"), 40)
        note = f"{cap.layout.name}: the last line is incomplete ({shown}), dropped (--drop-incomplete)"
        if note not in cap.layout.notes:
            cap.layout.notes.append(note)


def unquote(text: pa.Array) -> pa.Array:
    """Text cells without the blanks around them, and a cell in double quotes (``"1.5"``: some
    loggers and spreadsheet exports quote every cell) as the text inside (sniff.bare)."""
    trimmed = pc.utf8_trim_whitespace(text)
    quoted = pc.and_(pc.starts_with(trimmed, '"'), pc.ends_with(trimmed, '"'))
    quoted = pc.and_(quoted, pc.greater_equal(pc.binary_length(trimmed), 2))
    return pc.if_else(quoted, pc.utf8_trim_whitespace(pc.utf8_slice_codeunits(trimmed, 1, -1)), trimmed)


def cast_floats(text: pa.Array, *, safe: bool = True) -> pa.Array:
    """Number cells as float64, quoted ones (``"1.5"``) too: ArrowInvalid when a cell is not one."""
    if starts_quoted(text):
        text = unquote(text)
    try:
        return pc.cast(text, pa.float64(), safe=safe)
    except pa.ArrowInvalid:
        return pc.cast(unquote(text), pa.float64(), safe=safe)


def starts_quoted(text: pa.Array) -> bool:
    """Whether a column's first cell is in double quotes: then its others are too, as a rule (a
    cast that fails costs 30 times one that does not: the quotes are taken off first)."""
    return len(text) > 0 and str(text[0].as_py() or "").lstrip().startswith('"')


def to_floats(arr: pa.Array) -> FloatArray:
    """A float64 arrow array without nulls as a numpy array (zero copy)."""
    if len(arr) == 0:
        return np.empty(0)
    assert arr.type == pa.float64()
    assert arr.null_count == 0
    return np.frombuffer(arr.buffers()[1], dtype=np.float64, count=len(arr), offset=arr.offset * 8)


def to_bools(arr: pa.Array) -> BoolArray:
    """A boolean arrow array without nulls as a numpy array."""
    if len(arr) == 0:
        return np.zeros(0, dtype=bool)
    assert arr.type == pa.bool_()
    assert arr.null_count == 0
    bits = np.unpackbits(np.frombuffer(arr.buffers()[1], dtype=np.uint8), bitorder="little")
    out: BoolArray = bits[arr.offset : arr.offset + len(arr)].astype(bool)
    return out


def is_regular(path: str) -> bool:
    """Whether ``path`` is a regular file (one that can be read twice), not a pipe, FIFO or device.
    A path that cannot be examined counts as regular: opening it says what is wrong."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        return True


def read_table(path: str, spec: ReadSpec | None = None) -> tuple[Layout, list[str], list[pa.Array]]:
    """Every column of a capture, by the rules solve and apply read it by: (layout, names,
    columns, each int64, float64 or text). The sensor columns are checked as apply checks them
    (a cell that is not a number is an error naming its line and column)."""
    with open_capture(path, spec) as cap:
        parts: list[list[pa.Array]] = [[] for _ in cap.layout.names]
        for first, cols in cap.batches():
            cap.sensor_values([cols[i] for i in cap.layout.sensor], first)
            for k, col in enumerate(cols):
                parts[k].append(col)
    out: list[pa.Array] = []
    for chunks in parts:
        text = pa.chunked_array(chunks, type=pa.string()).combine_chunks() if chunks else pa.array([], pa.string())
        trimmed = pc.utf8_trim_whitespace(unquote(cap.pointed(text)))
        for kind in (pa.int64(), pa.float64()):
            try:
                out.append(pc.cast(pc.if_else(pc.equal(trimmed, ""), None, trimmed), kind))
                break
            except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
                continue
        else:
            out.append(text)
    return cap.layout, list(cap.layout.names), out
