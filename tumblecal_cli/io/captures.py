"""Captures (CSV sample logs) in and out: one set of rules (README "CSV captures"), one engine.

How a capture is read:

1. ``open_capture`` reads the first block itself and decides the layout: UTF-8 BOM, the
   preamble (blank and ``#`` lines), the delimiter (comma, semicolon, tab, or runs of
   whitespace), whether the first line is a header, the line ending, and which columns hold
   the sensor triplet and the time.
2. The data section (everything after the header) streams through pyarrow's CSV reader with
   every column read as *text* and quoting off, so cells we do not touch keep their exact
   bytes (``00001000`` stays ``00001000``). Only the three sensor columns are converted.
3. When pyarrow rejects something, ``_diagnose`` re-reads the file line by line with the same
   rules to name the line and column. That slow pass only runs after a failure.
4. ``apply`` (``correct_stream``) skips step 2 for a regular file's blocks of plain lines: it
   replaces the sensor cells' text in the block's own bytes (``io.splice``) and hands any
   other block to step 2, which writes the same bytes.

pyarrow is the engine because it streams, imports in 0.2 s (pandas takes 0.45 s here) and
writes floats as their shortest round-trip text; README "Dependencies" has the measurements.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import io
import itertools
import os
import re
import stat
import sys
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import IO, Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pcsv

from tumblecal_cli.errors import InputError

HEAD_BYTES = 1 << 20  # the sniffer looks at this much of the file


def quoted(cell: object, keep: int = 40) -> str:
    """A cell as an error message quotes it: ``repr``, cut to ``keep`` characters with its length."""
    text = str(cell)
    return repr(text) if len(text) <= keep else f"{text[:keep]!r}... ({len(text):,} characters)"


BLOCK_BYTES = 1 << 20  # pyarrow block size when streaming: bigger blocks raise peak memory
TIME_NAMES = ("t", "time", "timestamp", "time_s", "ts")
#: A temperature column, averaged per pose into the calibration file (traceability).
TEMPERATURE_NAMES = ("temp", "temperature", "temp_c", "temperature_c", "temp_degc", "t_degc", "die_temp")
FAMILIES = {  # --sensor -> words in a column stem that name it; a single letter only as a prefix
    "accelerometer": (("acc",), "a"),
    "gyroscope": (("gyr",), "g"),
    "magnetometer": (("mag",), "m"),
}
#: Words in a triplet's stem that name a filter's output (an estimate, gravity removed or
#: already compensated), not the sensor's own reading: when a family has several triplets,
#: these lose to the raw one (MicroStrain logs: scaledAccel* beside estCompensatedAccel*,
#: estLinearAccel*). A velocity increment (deltaVel*) is in no family at all.
DERIVED = ("est", "filt", "compensated", "linear", "gravity", "fused")
_NUMBER = r"(?i)^[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:e[+-]?\d+)?|nan|inf|infinity)$"
_WS_RUN = re.compile(rb"[ \t]+")
_WS_EDGE = re.compile(rb"^ | (?=\r?$)", re.MULTILINE)
_TIME_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_UNIT_WORDS = {"s": "seconds", "ms": "milliseconds", "us": "microseconds", "ns": "nanoseconds"}
#: A time column whose name carries its unit: ``timestamp_ms``, ``t_us``, ``time(ns)``, ``time [ms]``,
#: Arduino's ``millis``/``micros``.
_TIME_WITH_UNIT = re.compile(
    r"^(?:t|time|timestamp|ts)(?:[ _.\-]+[(\[]?|[(\[])(s|sec|ms|us|µs|ns)[)\]]?$|^(millis|micros)$"
)  # a separator or a bracket before the unit: `ts` and `times` are names, not t + s
#: A cell written with a decimal comma (``1,045729``, ``-0,5e-3``): European spreadsheet exports.
_COMMA_NUMBER = re.compile(r"^\s*[+-]?\d*,\d+(?:[eE][+-]?\d+)?\s*$")
MAX_PREAMBLE = 20  # metadata lines a station may write before its header


@dataclass(frozen=True)
class Dialect:
    """How a station wrote its file, where the sniffer should not guess (README "CSV captures"):
    ``skip_rows`` lines before the header (None: a metadata preamble is found by its field
    count), the ``decimal`` mark (None: a comma when every number of a ``;`` or tab separated
    file has one), and whether an incomplete last line (a logger stopped mid-write) is dropped."""

    skip_rows: int | None = None
    decimal: str | None = None
    drop_incomplete: bool = False

    def __post_init__(self) -> None:
        skip = self.skip_rows
        if skip is not None and (isinstance(skip, bool) or not isinstance(skip, int) or skip < 0):
            raise InputError(f"--skip-rows takes a whole number of 0 or more, got {skip!r}")
        if self.decimal not in (None, ".", ","):
            raise InputError(f"--decimal is '.' or ',', got {self.decimal!r}")


FloatArray = np.ndarray[Any, np.dtype[np.float64]]
BoolArray = np.ndarray[Any, np.dtype[np.bool_]]


@dataclass
class Layout:
    """What the sniffer decided about one capture."""

    name: str  # path as given, or "<stdin>"
    delimiter: str | None  # None: runs of spaces/tabs (written back as one space)
    names: list[str]  # column names (generated for headerless files)
    has_header: bool
    head: bytes  # preamble + header line, written back verbatim by apply
    data_line: int  # 1-based line number where the data section starts
    eol: str
    sensor: tuple[int, int, int] = (0, 1, 2)
    time: int | None = None
    temperature: int | None = None
    extra: int | None = None  # one more column read as text (a log's label column)
    notes: list[str] = field(default_factory=list)  # things a person should be told
    decimal: str = "."  # the decimal mark of the file's numbers ("," in European exports)
    time_unit: str | None = None  # the unit the time column's name gives (timestamp_ms), if any
    incomplete: bytes | None = None  # the last line, when it is cut short and dropped (--drop-incomplete)

    @property
    def sensor_names(self) -> list[str]:
        return [self.names[i] for i in self.sensor]


class _DataStream(io.RawIOBase):
    """The data section as a byte stream, for stdin and whitespace-separated files: the
    sniffed remainder of the first block, then the rest; hashes what it reads (stdin has no
    second pass) and squeezes runs of whitespace to single spaces for pyarrow."""

    def __init__(
        self,
        first: bytes,
        rest: IO[bytes],
        hasher: Any,
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
        return _WS_EDGE.sub(b"", _WS_RUN.sub(b" ", out)) if self._squeeze else out

    def readable(self) -> bool:
        return True

    def close(self) -> None:
        if self._owns:
            self._rest.close()
        super().close()

    def readinto(self, buffer: Any) -> int:
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

    def __init__(self, layout: Layout, stream: Any, path: str | None, hasher: Any) -> None:
        self.layout = layout
        self._stream = stream  # pyarrow's own file reader, or a _DataStream
        self._path = path  # None for stdin: no second pass is possible
        self._hasher = hasher

    def sha256(self) -> str:
        """Hash of every byte of the file (for stdin: once the data has been read)."""
        if self._path is None:
            return str(self._hasher.hexdigest())
        with open(self._path, "rb") as f:
            return hashlib.file_digest(f, "sha256").hexdigest()

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
        wanted = list(lay.sensor) + [i for i in (lay.time, lay.temperature, lay.extra) if i is not None]
        include = [keys[i] for i in wanted] if only_sensor else keys
        read = include if keys[0] in include else [keys[0], *include]  # column 0 tells comments
        bad_rows: list[str] = []

        def invalid(row: Any) -> str:
            if _skipped(row.text):
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
            _note_dropped(self)
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
            try:
                values[:, j] = _floats(pc.cast(text, pa.float64()))
                continue
            except pa.ArrowInvalid:
                pass
            text = pc.utf8_trim_whitespace(text)
            is_empty = pc.equal(pc.utf8_length(text), 0)
            bad = pc.and_(pc.invert(is_empty), pc.invert(pc.match_substring_regex(text, _NUMBER)))
            if pc.any(bad).as_py():
                i = int(pc.index(bad, True).as_py())
                cell = str(columns[j][i].as_py())
                err = self._locate(first_row + i, j, f"not a number: {quoted(cell)}", triplet)
                if _COMMA_NUMBER.match(cell) and self.layout.decimal == ".":
                    err.hint = "it has a decimal comma: give --decimal , (columns separated by ; or tabs)"
                raise err
            empty[:, j] = _bools(is_empty)
            values[:, j] = _floats(pc.cast(pc.replace_substring_regex(text, "^$", "nan"), pa.float64()))
        all_empty: BoolArray = empty[:, 0] & empty[:, 1] & empty[:, 2]
        partial = empty.any(axis=1) & ~all_empty
        if partial.any():
            i = int(np.argmax(partial))
            j = int(np.argmax(empty[i]))
            raise self._locate(
                first_row + i, j, "empty sensor cell in a row whose other sensor cells are filled", triplet
            )
        return values, all_empty

    def temperature_values(self, text: pa.Array, first_row: int, empty: BoolArray) -> FloatArray:
        """The temperature column of a block as floats (°C); a cell that is not a finite number,
        or an empty one, on a row with sensor values (``empty``: rows without), is an error naming
        its line and column."""
        values = self._temperatures(text, first_row, empty)
        odd = ~np.isfinite(values) & ~empty
        if odd.any():  # nan, inf: no temperature to correct the row at
            i = int(np.argmax(odd))
            where = (self.layout.temperature or 0,) * 3
            cell = quoted(str(text[i].as_py()))
            raise self._locate(first_row + i, 0, f"temperature is not a finite number: {cell}", where)
        return values

    def _temperatures(self, text: pa.Array, first_row: int, empty: BoolArray) -> FloatArray:
        lay = self.layout
        assert lay.temperature is not None
        with contextlib.suppress(pa.ArrowInvalid):  # every cell a number (the usual case): one cast
            return _floats(pc.cast(self.pointed(text), pa.float64()))
        where = (lay.temperature, lay.temperature, lay.temperature)
        trimmed = pc.utf8_trim_whitespace(self.pointed(text))
        blank = _bools(pc.equal(pc.utf8_length(trimmed), 0))
        missing = blank & ~empty
        if missing.any():
            i = int(np.argmax(missing))
            raise self._locate(first_row + i, 0, "empty temperature cell in a row with sensor values", where)
        try:
            return _floats(pc.cast(pc.replace_substring_regex(trimmed, "^$", "nan"), pa.float64()))
        except pa.ArrowInvalid:
            bad = pc.and_(
                pc.invert(pc.equal(pc.utf8_length(trimmed), 0)), pc.invert(pc.match_substring_regex(trimmed, _NUMBER))
            )
            i = int(pc.index(bad, True).as_py()) if pc.any(bad).as_py() else 0
            cell = str(text[i].as_py())
            raise self._locate(first_row + i, 0, f"temperature is not a number: {quoted(cell)}", where) from None

    def pointed(self, text: pa.Array) -> pa.Array:
        """Number cells with a decimal point (a decimal comma file's cells with it replaced)."""
        return text if self.layout.decimal == "." else pc.replace_substring(text, ",", ".")

    # -- error paths: find the line and column with the same rules, one line at a time --

    def _locate(self, row: int, sensor_j: int, what: str, triplet: tuple[int, int, int] | None = None) -> InputError:
        lay = self.layout
        column = lay.names[(triplet or lay.sensor)[sensor_j]]
        line = self._line_of_row(row)
        if line is None:
            return InputError(f"{what} in column {column!r} (data row {row + 1})", file=lay.name)
        return InputError(what, file=lay.name, line=line, column=column)

    def _data_lines(self) -> Iterator[tuple[int, str]]:
        """(line number, text) of each data line of the file, skipping blanks and comments."""
        assert self._path is not None
        lay = self.layout
        with open(self._path, "rb") as f:
            f.seek(len(lay.head))
            for offset, raw in enumerate(f):
                text = raw.decode("utf-8", errors="replace").rstrip("\r\n")
                if not _skipped(text):
                    yield lay.data_line + offset, text

    def _line_of_row(self, row: int) -> int | None:
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
                cells = _split(text, lay.delimiter)
                if len(cells) != len(lay.names):
                    return InputError(
                        f"row has {len(cells)} fields, the header has {len(lay.names)}",
                        file=lay.name,
                        line=line,
                    )
        if bad_row is not None:  # stdin: no second pass, so no line number
            return InputError(
                f"row has {len(_split(bad_row, lay.delimiter))} fields, the header has {len(lay.names)}: "
                f"{bad_row[:80]!r}",
                file=lay.name,
            )
        if "decode" in engine_message or "UTF8" in engine_message or "UTF-8" in engine_message:
            return InputError("not UTF-8 text (is it a binary file?)", file=lay.name)
        first = engine_message.splitlines()[0] if engine_message else "unreadable"
        return InputError(f"cannot parse: {first.removeprefix('CSV parse error: ')}", file=lay.name)


def open_capture(
    path: str,
    *,
    sensor: str = "accelerometer",
    columns: Sequence[str] | None = None,
    prefer: Sequence[str] | None = None,
    no_header: bool = False,
    time_column: str | None = None,
    name: str | None = None,
    extra: str | None = None,
    dialect: Dialect | None = None,
    temperature_column: str | None = None,
) -> Capture:
    """Open ``path`` ('-' for stdin), sniff its layout and find its sensor and time columns.

    ``columns`` (from ``--columns``) overrides detection; ``prefer`` (a calibration's
    recorded columns) is used when all three are present; ``extra`` names one more column to
    read (as text); ``name`` is how messages name the file (default: the path); ``dialect``
    what the user says of the file's shape (preamble, decimal mark, a cut last line).
    """
    dialect = dialect or Dialect()
    name = name or ("<stdin>" if path == "-" else path)
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
    try:
        layout, consumed = _sniff(name, first, at_eof=len(first) < HEAD_BYTES, no_header=no_header, dialect=dialect)
        layout.sensor, layout.time = _pick_columns(layout, sensor, columns, prefer, time_column)
        if layout.time is not None:
            layout.time_unit = _unit_of_name(layout.names[layout.time])
        lower = [n.lower() for n in layout.names]
        if temperature_column is not None:
            layout.temperature = _column(layout, temperature_column, "--temperature-column")
        else:
            layout.temperature = next((i for i, n in enumerate(lower) if n in TEMPERATURE_NAMES), None)
        if extra is not None:
            layout.extra = _column(layout, extra, "column")
        _no_column_twice(layout, sensor, columns, prefer, time_column, temperature_column)
    except InputError:
        if f is not sys.stdin.buffer:
            f.close()
        raise
    stream: Any
    regular = path != "-" and stat.S_ISREG(os.fstat(f.fileno()).st_mode)  # not a pipe, FIFO or device
    cut = regular and _cut_short(f, layout, consumed, dialect.drop_incomplete)
    if regular and layout.delimiter is not None and not cut:
        # a regular file: pyarrow reads it natively from the end of the header (1.7x faster)
        f.close()
        stream = pa.OSFile(path)
        stream.seek(consumed)
    else:
        drop = functools.partial(_incomplete, layout) if dialect.drop_incomplete else None
        squeeze = layout.delimiter is None
        stream = _DataStream(first[consumed:], f, hasher, squeeze=squeeze, owns=path != "-", drop_last=drop)
    return Capture(layout, stream, path if regular else None, hasher)  # a pipe is read once


def _incomplete(layout: Layout, line: bytes) -> bool:
    """Whether an unterminated last line was cut short by a logger stopped mid-write: fewer
    fields than the header, or a sensor cell empty or not a number. (A complete last line
    without a line end is common, and kept.)"""
    text = line.decode("utf-8", errors="replace").rstrip("\r\n")
    if _skipped(text):
        return False
    cells = _split(text, layout.delimiter)
    if len(cells) < len(layout.names):
        return True
    sensor = [cells[i].strip().replace(layout.decimal, ".") for i in layout.sensor]
    return any(not re.match(_NUMBER, c) for c in sensor) and not all(not c for c in sensor)


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


def _sniff(name: str, first: bytes, *, at_eof: bool, no_header: bool, dialect: Dialect) -> tuple[Layout, int]:
    """Decide the layout from the first block; returns it and the bytes it consumed."""
    if not first:
        raise InputError("empty file", file=name, hint="the capture has no bytes at all")
    if not at_eof and b"\n" not in first and b"\r" not in first:
        raise InputError(
            f"the first line is longer than {HEAD_BYTES // (1 << 20)} MB: not a capture's header or data",
            file=name,
            hint="is this a CSV capture?",
        )
    if b"\0" in first[:65536]:
        raise InputError("binary data, not a CSV text file", file=name)
    bom = 3 if first.startswith(b"\xef\xbb\xbf") else 0
    try:
        # a multi-byte character may be cut at the end of the block: decode whole lines only
        text = first[bom : first.rfind(b"\n") + 1 if not at_eof else len(first)].decode("utf-8")
    except UnicodeDecodeError as err:
        raise InputError(f"not UTF-8 text (byte {err.start + bom})", file=name) from None
    lines = text.splitlines(keepends=True)
    k = _first_content(name, lines, dialect.skip_rows or 0)
    notes: list[str] = []
    at = [i for i in range(k, min(len(lines), k + 200)) if not _skipped(lines[i])]  # the lines sniffed
    content = [lines[i].rstrip("\r\n") for i in at]
    delimiter = _detect_delimiter(content[:50])
    if dialect.skip_rows is None and not no_header:
        skip, delimiter = _preamble(content, delimiter)
        if skip:
            shown = "; ".join(quoted(c, 30) for c in content[: min(skip, 2)]) + (" ..." if skip > 2 else "")
            notes.append(
                f"{name}: {skip} line{'s' if skip > 1 else ''} before the header skipped "
                f"({f'lines {at[0] + 1}-{at[skip - 1] + 1}' if skip > 1 else f'line {at[0] + 1}'}: {shown}); "
                "--skip-rows N says how many"
            )
            k, content = at[skip], content[skip:]
    cells = [c.strip().strip('"').strip() for c in _split(content[0], delimiter)]
    eol = "\r\n" if lines[k].endswith("\r\n") else "\r" if lines[k].endswith("\r") else "\n"  # CR alone: old Macs
    header = not no_header and any(c and not re.match(_NUMBER, c) and not _COMMA_NUMBER.match(c) for c in cells)
    offset = bom + len("".join(lines[:k]).encode())  # bytes consumed so far
    if header:
        names = cells
        offset += len(lines[k].encode())
        k += 1
        if all(_skipped(ln) for ln in lines[k:]) and at_eof:
            raise InputError("a header but no data rows", file=name)
    elif len(cells) == 3:
        names = ["x", "y", "z"]
    elif len(cells) == 4:
        names = ["t", "x", "y", "z"]
    else:
        names = [str(i) for i in range(len(cells))]
    if len(names) < 3:
        raise InputError(
            f"{len(names)} column{'s' if len(names) != 1 else ''}, a capture needs at least 3 (delimiter {delimiter!r})"
            if delimiter
            else "only one column: no delimiter found",
            file=name,
            hint="separate columns with commas, semicolons, tabs or spaces",
        )
    layout = Layout(
        name=name,
        delimiter=delimiter,
        names=names,
        has_header=header,
        head=first[:offset],
        data_line=k + 1,
        eol=eol,
        notes=notes,
    )
    layout.decimal = _decimal(layout, content[1:] if header else content, dialect.decimal)
    return layout, offset


def _first_content(name: str, lines: Sequence[str], skip: int) -> int:
    """The index of the first line after ``skip`` lines (--skip-rows) that is not blank or a comment."""
    if skip and skip >= len(lines):
        raise InputError(
            f"--skip-rows {skip} skips every line of the file's first block ({len(lines)} lines)", file=name
        )
    k = skip
    while k < len(lines) and _skipped(lines[k]):
        k += 1
    if k == len(lines):
        raise InputError("no data: the file holds only blank or # comment lines", file=name)
    return k


def _preamble(content: Sequence[str], delimiter: str | None) -> tuple[int, str | None]:
    """How many of the first lines are a station's metadata (``Fs,100``, ``Device: X``), and the
    delimiter of the table after them: lines with fewer fields than the header that follows them,
    the header being a line of names with as many fields as most of the rows after it. Without
    such a header nothing is skipped (``--skip-rows`` says how many)."""
    for skip in range(min(MAX_PREAMBLE, len(content) - 1) + 1):
        rest = content[skip:]
        delim = delimiter if skip == 0 else _detect_delimiter(rest[:50])
        counts = [len(_split(ln, delim)) for ln in rest[:50]]
        width = max(set(counts), key=counts.count)
        if counts[0] != width or width < 3:
            continue  # not where the table starts
        if skip == 0 or any(len(_split(ln, delim)) >= width for ln in content[:skip]):
            return 0, delimiter
        cells = [c.strip().strip('"').strip() for c in _split(rest[0], delim)]
        named = all(c and not re.match(_NUMBER, c) and not _COMMA_NUMBER.match(c) for c in cells)
        return (skip, delim) if named else (0, delimiter)
    return 0, delimiter


def _decimal(layout: Layout, rows: Sequence[str], given: str | None) -> str:
    """The decimal mark: ``given`` (--decimal), else a comma when the file is separated by
    something else and every number cell of the rows sniffed that has a comma is one like
    ``1,045729`` and none has a point; else a point."""
    if given not in (None, ".", ","):
        raise InputError(f"--decimal must be '.' or ',', got {given!r}")
    if given == "," and layout.delimiter == ",":
        raise InputError(
            "--decimal , needs columns separated by something else than a comma",
            file=layout.name,
            hint="a comma-separated file writes its numbers with a point",
        )
    if given is not None or layout.delimiter == ",":
        return given or "."
    cells = [c for ln in rows for c in _split(ln, layout.delimiter)]
    commas = [c for c in cells if "," in c]
    if commas and all(_COMMA_NUMBER.match(c) for c in commas) and not any("." in c for c in cells):
        layout.notes.append(f"{layout.name}: numbers with a decimal comma (e.g. {commas[0].strip()!r}) read as such")
        return ","
    return "."


def _detect_delimiter(lines: Sequence[str]) -> str | None:
    """The delimiter found on every sample line, most often with the first line's count (a
    ragged row must not turn a CSV into one whitespace column: it is reported by line
    later), then the most columns; else whitespace (None)."""
    best: tuple[int, int, str] | None = None
    for cand in (",", "\t", ";"):
        counts = [ln.count(cand) for ln in lines]
        if min(counts) == 0:
            continue
        key = (sum(c == counts[0] for c in counts), counts[0], cand)
        if best is None or key[:2] > best[:2]:
            best = key
    if best and best[2] == ",":  # 0,01;1,0;-0,5: the commas are decimal marks of a ; or tab separated file
        for cand in ("\t", ";"):
            if len({ln.count(cand) for ln in lines}) == 1 and lines[0].count(cand) >= 2:
                cells = [c for ln in lines for c in ln.split(cand) if "," in c]
                if all(_COMMA_NUMBER.match(c) for c in cells):
                    return cand
    return best[2] if best else None


def _skipped(line: str) -> bool:
    """Blank and ``#`` comment lines are not data, wherever they are (README "CSV captures")."""
    text = line.strip()
    return not text or text.startswith("#")


def _split(line: str, delimiter: str | None) -> list[str]:
    return line.split() if delimiter is None else line.split(delimiter)


def _pick_columns(
    layout: Layout,
    sensor: str,
    columns: Sequence[str] | None,
    prefer: Sequence[str] | None,
    time_column: str | None,
) -> tuple[tuple[int, int, int], int | None]:
    names = layout.names
    lower = [n.lower() for n in names]

    def index_of(ref: str, what: str) -> int:
        return _column(layout, ref, what)

    time = index_of(time_column, "time column") if time_column else None
    if time is None:
        time = next((i for i, n in enumerate(lower) if n in TIME_NAMES), None)
    if time is None:
        time = next((i for i, n in enumerate(lower) if _unit_of_name(n)), None)
    if columns:
        if len(columns) != 3:
            raise InputError(f"--columns needs three columns (x,y,z), got {len(columns)}")
        picked = [index_of(c, "column") for c in columns]
        if len(set(picked)) != 3:
            raise InputError(f"--columns names the same column twice: {','.join(columns)}", file=layout.name)
        return (picked[0], picked[1], picked[2]), time
    if prefer and all(p.lower() in lower for p in prefer):
        picked = [lower.index(p.lower()) for p in prefer]
        return (picked[0], picked[1], picked[2]), time
    # never another sensor's triplet (gyr_x is not an accelerometer, even when it is alone)
    triplets = [t for t in _triplets(lower) if _family(t[0]) in (sensor, None)]
    if len(triplets) > 1:  # the --sensor family, else the unlabelled ones (x,y,z; x_g ...)
        triplets = [t for t in triplets if _family(t[0]) == sensor] or triplets
    if len(triplets) > 1:  # the sensor's own reading, not a filter's estimate of it
        triplets = [t for t in triplets if not _derived(t[0])] or triplets
    if len(triplets) == 1:
        return triplets[0][1], time
    listing = ", ".join(names)
    if not triplets:
        raise InputError(
            f"no {sensor} x,y,z columns found (columns: {listing})",
            file=layout.name,
            hint="name them with --columns X,Y,Z (header names or 0-based indices)",
        )
    found = "; ".join(",".join(names[i] for i in t[1]) for t in triplets)
    raise InputError(
        f"several {sensor} triplets could be meant: {found}",
        file=layout.name,
        hint="pick one with --columns X,Y,Z or --sensor",
    )


def _no_column_twice(
    layout: Layout,
    sensor: str,
    columns: Sequence[str] | None,
    prefer: Sequence[str] | None,
    time_column: str | None,
    temperature_column: str | None,
) -> None:
    """A sensor column that is also the time or the temperature column, by an option or a
    calibration's columns, or a label column (--pose-column) that is any of them: an error
    naming which (the column would be read twice, and corrected as a reading)."""
    names = layout.names
    if layout.temperature is not None and layout.temperature == layout.time:
        raise InputError(
            f"{'--temperature-column' if temperature_column else 'the temperature column'} names "
            f"{names[layout.time]!r}, the time column",
            file=layout.name,
            hint=f"name the temperature column with --temperature-column NAME (columns: {', '.join(names)})",
        )
    for role, index, option in (
        ("time", layout.time, time_column and "--time-column"),
        ("temperature", layout.temperature, temperature_column and "--temperature-column"),
    ):
        if index is None or index not in layout.sensor:
            continue
        column = names[index]
        if columns and not layout.has_header and not option:  # a headerless file's guess, not a name
            setattr(layout, role, None)  # the user's columns are the sensor's: no time (or temperature)
            continue
        if columns:
            message = f"--columns names {column!r}, the {role} column"
            hint = "name three sensor columns: --columns X,Y,Z"
        elif option:
            message = f"{option} names {column!r}, one of the {sensor} columns"
            hint = f"name the {role} column with {option} NAME"
        elif prefer:
            message = f"the calibration's columns include {column!r}, the capture's {role} column"
            hint = "a calibration corrects three sensor columns: check its 'columns' field"
        else:
            continue
        raise InputError(message, file=layout.name, hint=f"{hint} (columns: {', '.join(names)})")
    if layout.extra is not None:  # read as labels and as numbers
        taken = {i: f"one of the {sensor} columns" for i in layout.sensor}
        for role, index in (("time", layout.time), ("temperature", layout.temperature)):
            if index is not None:
                taken[index] = f"the {role} column"
        if layout.extra in taken:
            raise InputError(
                f"--pose-column names {names[layout.extra]!r}, {taken[layout.extra]}",
                file=layout.name,
                hint=f"name the column of pose labels (columns: {', '.join(names)})",
            )


def _unit_of_name(name: str) -> str | None:
    """The unit a time column's name gives: ``timestamp_ms`` -> ms, ``t_us`` -> us, ``millis`` -> ms."""
    match = _TIME_WITH_UNIT.match(name.strip().lower())
    if match is None:
        return None
    unit = match.group(1) or {"millis": "ms", "micros": "us"}[match.group(2)]
    return {"sec": "s", "µs": "us"}.get(unit, unit)


def _column(layout: Layout, ref: str, what: str) -> int:
    """The index of the column ``ref`` names (a header name, any case, or a 0-based index)."""
    lower = [n.lower() for n in layout.names]
    if ref.lower() in lower:
        return lower.index(ref.lower())
    if ref.isdigit() and int(ref) < len(layout.names):
        return int(ref)
    raise InputError(
        f"{what} {ref!r} not found (columns: {', '.join(layout.names)})",
        file=layout.name,
        hint="name a column by its header or its 0-based index",
    )


def _family(stem: str) -> str | None:
    """The sensor a triplet's stem names (``acc|``, ``a|``, ``gyro_|``...), or None."""
    for sensor, (words, letter) in FAMILIES.items():
        if any(w in stem for w in words) or stem == letter + "|":
            return sensor
    return None


def _derived(stem: str) -> bool:
    """Whether a triplet's stem names a derived quantity (``estlinearaccel|``), see DERIVED."""
    return any(word in stem for word in DERIVED)


def _triplets(lower: Sequence[str]) -> list[tuple[str, tuple[int, int, int]]]:
    """Every (stem, (ix, iy, iz)) where three names differ only in one x/y/z letter.

    The stem is prefix + "|" + suffix without separators: ``acc_x`` -> ``acc|``, ``x_g`` ->
    ``|g``, ``scaledAccelX`` -> ``scaledaccel|``, ``x`` -> ``|``.
    """
    groups: dict[str, dict[str, int]] = {}
    for i, n in enumerate(lower):
        for pos, ch in enumerate(n):
            if ch in "xyz":
                stem = n[:pos].rstrip("_-. ") + "|" + n[pos + 1 :].lstrip("_-. ")
                groups.setdefault(stem, {}).setdefault(ch, i)
    out = []
    for stem, axes in groups.items():
        if len(axes) == 3:
            out.append((stem, (axes["x"], axes["y"], axes["z"])))
    return sorted(out, key=lambda t: t[1])


# -- reading poses -------------------------------------------------------------------------


@dataclass(frozen=True)
class Samples:
    """The sensor readings of one capture (or of one block of a log), empty rows dropped."""

    layout: Layout
    values: FloatArray  # (n, 3) raw units
    rows: tuple[int, int]  # first and last data row used (0-based, inclusive)
    sha256: str
    duration: float | None  # seconds spanned by the time column (or --rate), if known
    temperature: float | None = None  # mean of the temperature column, if there is one
    block: int | None = None  # the block's number, for a pose cut from a log
    times: tuple[float, float] | None = None  # a block's first and last time, when the log has them

    @property
    def name(self) -> str:
        """How messages name this pose: its file, and its block when cut from a log."""
        return self.layout.name if self.block is None else f"{self.layout.name} block {self.block}"


@dataclass(frozen=True)
class Log:
    """A whole log in memory: the sensor readings of every non-empty row, with their data row,
    time (``clock``: the time column in its own unit, ``scale`` seconds each) and label."""

    layout: Layout
    values: FloatArray  # (n, 3)
    rows: np.ndarray[Any, np.dtype[np.int64]]  # data row (0-based) of each reading (int32 from io.logread)
    clock: FloatArray | None
    labels: list[str] | None
    sha256: str
    temperature: FloatArray | None = None
    scale: float = 1.0
    #: Each reading's line in the file: its first byte and the byte after its line end (a log
    #: read block by block, io.logread: its readings are those of the still periods only; int32
    #: for a file under 2 GiB, as its rows).
    lines: np.ndarray[Any, np.dtype[np.int64]] | None = None
    #: ... and then what the whole log's readings are judged by for their integer type
    #: (gate.integer_rails): the lowest, the highest, and one that is not a whole number if any;
    extremes: FloatArray | None = None
    #: and where each run of the readings kept starts among the whole log's and among these.
    runs: tuple[np.ndarray[Any, np.dtype[np.int64]], np.ndarray[Any, np.dtype[np.int64]]] | None = None

    def reading(self, position: int) -> int:
        """The index among the whole log's readings of the reading at ``position`` here (the
        same, unless the log was read block by block and only its still periods kept)."""
        if self.runs is None:
            return position
        from tumblecal_cli.core.scan import log_index

        return int(log_index(*self.runs, position))

    def seconds(self) -> FloatArray | None:
        """Seconds since the first reading (differences first: epoch nanoseconds keep their digits)."""
        return None if self.clock is None else (self.clock - self.clock[0]) * self.scale

    def block(self, number: int, first: int, last: int) -> Samples:
        """Readings ``first``..``last`` (inclusive) as a pose."""
        clock = self.clock
        times = None if clock is None else (float(clock[first]), float(clock[last]))
        temp = self.temperature
        return Samples(
            self.layout,
            self.values[first : last + 1],
            (int(self.rows[first]), int(self.rows[last])),
            self.sha256,
            None if clock is None else float(clock[last] - clock[first]) * self.scale,
            None if temp is None else float(temp[first : last + 1].mean()),
            block=number,
            times=times,
        )


def read_samples(
    path: str,
    *,
    sensor: str = "accelerometer",
    columns: Sequence[str] | None = None,
    no_header: bool = False,
    time_column: str | None = None,
    time_unit: str = "auto",
    rate: float | None = None,
    prefer: Sequence[str] | None = None,
    dialect: Dialect | None = None,
) -> Samples:
    """Read the sensor columns of a small capture (a pose file) into memory (``prefer``: a
    calibration's recorded columns, used when the file has them)."""
    log = read_log(
        path,
        sensor=sensor,
        columns=columns,
        no_header=no_header,
        time_column=time_column,
        time_unit=time_unit,
        use_time=False,
        prefer=prefer,
        dialect=dialect,
    )
    t, used = log.clock, log.rows
    duration = None
    if t is not None:
        duration = float(t[-1] - t[0]) * log.scale if np.isfinite(t[[0, -1]]).all() else None
    elif rate:
        duration = (used[-1] - used[0] + 1) / rate
    temp = log.temperature
    temperature = float(temp.mean()) if temp is not None and np.isfinite(temp).all() else None
    return Samples(log.layout, log.values, (int(used[0]), int(used[-1])), log.sha256, duration, temperature)


def read_log(
    path: str,
    *,
    sensor: str = "accelerometer",
    columns: Sequence[str] | None = None,
    no_header: bool = False,
    time_column: str | None = None,
    time_unit: str = "auto",
    label_column: str | None = None,
    use_time: bool = True,
    name: str | None = None,
    digest: bool = True,
    prefer: Sequence[str] | None = None,
    dialect: Dialect | None = None,
    temperature_column: str | None = None,
    need_temperature: bool = False,
) -> Log:
    """Read a whole capture into memory (a log to segment, or a pose file). With ``use_time``
    its time column must hold numbers that never go backwards (else a time cell that is not a
    number leaves ``clock`` unknown); ``label_column`` is read as text; ``digest`` off leaves
    ``sha256`` empty (a second pass over the file saved). ``need_temperature``: the temperature
    column (``temperature_column``, else one of TEMPERATURE_NAMES) must be there and hold a
    number on every row with sensor values (an error names the line and column)."""
    with open_capture(
        path,
        sensor=sensor,
        columns=columns,
        prefer=prefer,
        no_header=no_header,
        time_column=time_column,
        name=name,
        extra=label_column,
        dialect=dialect,
        temperature_column=temperature_column,
    ) as cap:
        lay = cap.layout
        if need_temperature:
            _require_temperature(lay)
        blocks, keep, times, temps, labels = [], [], [], [], []
        for first_row, cols in cap.batches(only_sensor=True):
            values, empty = cap.sensor_values(cols, first_row)
            bad = ~np.isfinite(values) & ~empty[:, None]
            if bad.any():  # nan/inf would poison the pose mean (apply passes them through)
                i, j = (int(k[0]) for k in np.nonzero(bad))
                raise cap._locate(first_row + i, j, f"not a finite number: {quoted(cols[j][i].as_py())}")
            blocks.append(values)
            keep.append(~empty)
            k = 3
            if lay.time is not None:
                times.append((first_row, cols[k]))
                k += 1
            if lay.temperature is not None:
                temps.append(cap.temperature_values(cols[k], first_row, empty) if need_temperature else cols[k])
                k += 1
            if lay.extra is not None:
                labels.extend(cols[k].to_pylist())
        values = np.concatenate(blocks) if len(blocks) > 1 else blocks[0] if blocks else np.empty((0, 3))
        mask = np.concatenate(keep) if keep else np.zeros(0, dtype=bool)
        every = bool(mask.all())  # no empty rows (the usual case): no copies to drop them
        used = np.flatnonzero(mask).astype(np.int64)
        if used.size == 0:
            raise InputError(
                "no rows with sensor values", file=lay.name, hint=f"columns read: {', '.join(lay.sensor_names)}"
            )
        t = None
        if times and use_time:
            t = _times(cap, times, None if every else mask)
        elif times:
            try:
                t = np.concatenate([_floats(pc.cast(cap.pointed(c), pa.float64(), safe=False)) for _, c in times])[mask]
            except pa.ArrowInvalid:  # a time cell that is not a number: the duration is unknown
                t = None
        temperature = _temperatures(cap, temps, mask) if temps else None
        text = None if lay.extra is None else [str(labels[i] or "").strip() for i in used]
        sha256 = cap.sha256() if digest else ""
    scale = _TIME_SCALE.get(time_unit, 1.0)
    if t is not None:
        try:
            scale = time_scale(lay, t, time_unit)
        except InputError:
            if use_time:
                raise
            scale = _TIME_SCALE[lay.time_unit or "s"]  # the time column is not used (--rate): no judgement
    return Log(lay, values if every else values[mask], used, t, text, sha256, temperature, scale)


def _require_temperature(lay: Layout) -> None:
    if lay.temperature is None:
        raise InputError(
            f"no temperature column (looked for {', '.join(TEMPERATURE_NAMES)})",
            file=lay.name,
            hint=f"name it with --temperature-column (columns: {', '.join(lay.names)})",
        )


def _temperatures(cap: Capture, temps: list[Any], mask: BoolArray) -> FloatArray | None:
    """The temperature column of the rows kept: blocks already read as numbers
    (``Capture.temperature_values``), or text, where a cell that is not a number leaves the
    temperature unknown (None)."""
    if isinstance(temps[0], np.ndarray):
        out: FloatArray = np.concatenate(temps)[mask]
        return out
    try:
        floats = [_floats(pc.cast(cap.pointed(c), pa.float64(), safe=False)) for c in temps]
    except pa.ArrowInvalid:
        return None
    found: FloatArray = np.concatenate(floats)[mask]
    return found


#: The seconds between samples of a sensor's log: 50 kHz to 0.1 Hz.
_PERIODS = (2e-5, 10.0)


def _epoch_unit(first: float, step: float) -> str | None:
    """The unit of a clock that counts from 1970 (years 2001-2286 in s, ms, µs or ns), when its
    spacing is a sensor's in that unit."""
    for unit, scale in _TIME_SCALE.items():
        if 1e9 <= first * scale < 1e10 and _PERIODS[0] <= step * scale <= _PERIODS[1]:
            return unit
    return None


def time_scale(layout: Layout, clock: FloatArray, unit: str) -> float:
    """Seconds per unit of a log's time column: ``unit`` (--time-unit) when given; with "auto",
    the unit its name gives (``timestamp_ms``) unless its spacing contradicts it, else the unit of
    an epoch clock (1.7e18: ns), else the unit its spacing implies (a median step under 0.2: s;
    to 200: ms; to 2e5: µs; to 2e8: ns: each unit right from 5 Hz to 5 kHz), with a note."""
    if unit != "auto":
        return _TIME_SCALE[unit]
    assert layout.time is not None
    column, named = layout.names[layout.time], layout.time_unit
    d = np.diff(clock[:100_001])
    d = d[d > 0]
    if d.size == 0:  # one reading, or a clock that never moves: nothing to judge by
        return _TIME_SCALE[named or "s"]
    step = float(np.median(d))
    spaced = _epoch_unit(float(clock[0]), step) or next(
        (u for u, top in (("s", 0.2), ("ms", 200.0), ("us", 2e5), ("ns", 2e8)) if step <= top), None
    )
    hint = "give --time-unit s, ms, us or ns (or --rate HZ to use the sample rate instead)"
    if named is not None:
        period = step * _TIME_SCALE[named]
        if _PERIODS[0] <= period <= _PERIODS[1]:
            return _TIME_SCALE[named]
        raise InputError(
            f"time column {column!r} is named in {_UNIT_WORDS[named]}, but it advances {step:g} per sample "
            f"(a sample every {period:.3g} s)" + (f"; its spacing suggests {_UNIT_WORDS[spaced]}" if spaced else ""),
            file=layout.name,
            hint=hint,
        )
    if spaced is None:
        raise InputError(
            f"time column {column!r} advances {step:g} per sample: not seconds, ms, µs or ns at a sensor's rate",
            file=layout.name,
            hint=hint,
        )
    if spaced != "s":
        rate = 1.0 / (step * _TIME_SCALE[spaced])
        layout.notes.append(
            f"{layout.name}: time column {column!r} read in {_UNIT_WORDS[spaced]}: it advances {step:g} per sample "
            f"({rate:.4g} Hz); if it is not, give --time-unit"
        )
    return _TIME_SCALE[spaced]


def block_rate(cap: Capture, column: pa.Array, empty: BoolArray, unit: str) -> float:
    """Samples per second from one block's time column (its median step, in the unit
    ``time_scale`` finds), to 9 digits: a still capture's rate when no --rate is given."""
    try:
        clock = _floats(pc.cast(cap.pointed(column), pa.float64()))
    except pa.ArrowInvalid:
        raise InputError(
            "the time column holds a cell that is not a number", file=cap.layout.name, hint="give --rate HZ"
        ) from None
    clock = clock[~empty] if empty.any() else clock
    step = float(np.median(np.diff(clock))) * time_scale(cap.layout, clock, unit) if clock.size > 1 else 0.0
    if not step > 0:
        raise InputError("the time column does not advance", file=cap.layout.name, hint="give --rate HZ")
    return float(f"{1.0 / step:.9g}")  # the median step's float noise, not the rate's


def _times(cap: Capture, times: list[tuple[int, pa.Array]], mask: BoolArray | None) -> FloatArray:
    """A log's time column on the rows ``mask`` keeps (all when None): numbers that never go
    backwards, else an error naming the line. Rows without sensor values are not judged: an
    interleaved logger stamps each sensor's rows with its own clock."""
    lay = cap.layout
    assert lay.time is not None
    parts = []
    for first_row, text in times:
        text = cap.pointed(text)
        try:
            parts.append(_floats(pc.cast(text, pa.float64())))
        except pa.ArrowInvalid:
            ok = pc.match_substring_regex(pc.utf8_trim_whitespace(text), _NUMBER)
            i = int(pc.index(ok, False).as_py())
            line = cap._line_of_row(first_row + i)
            raise InputError(
                f"time is not a number: {quoted(text[i].as_py())}",
                file=lay.name,
                line=line,
                column=lay.names[lay.time],
                hint="give the sample rate with --rate HZ instead of the time column (--time-column to pick another)",
            ) from None
    t = np.concatenate(parts)
    rows = np.arange(t.size) if mask is None else np.flatnonzero(mask)
    t = t if mask is None else t[mask]
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        k = int(back[0]) + 1
        line = cap._line_of_row(int(rows[k]))
        raise InputError(
            f"time goes backwards: {float(t[k])!r} after {float(t[k - 1])!r}",
            file=lay.name,
            line=line,
            column=lay.names[lay.time],
            hint="sort the log by time, or split it where the logger restarted",
        )
    return t


def copy_bytes(path: str, layout: Layout, spans: Sequence[tuple[int, int]], outputs: Sequence[str]) -> None:
    """Write bytes ``start``..``end`` of ``path`` (each span a block's whole lines) to its
    output after the file's own preamble and header, in pieces: memory stays that of a piece.
    The files are written on a few threads (making a file is most of the cost of a short one,
    and the kernel does it without the GIL); the first error is raised once all have ended."""
    from tumblecal_cli.io.outputs import atomic_output

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
    from tumblecal_cli.io.outputs import atomic_output

    data = np.fromfile(path, dtype=np.uint8)
    starts, ends = row_offsets(data, len(layout.head))
    for (first, last), output in zip(spans, outputs, strict=True):
        with atomic_output(output) as out:
            out.write(layout.head)
            out.write(data[starts[first] : ends[last]].data)  # the bytes themselves, no copy


def row_offsets(data: np.ndarray[Any, np.dtype[np.uint8]], head: int) -> tuple[Any, Any]:
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


# -- apply: stream a capture through a correction ------------------------------------------


def sensor_columns(layout: Layout, sensor: str, prefer: Sequence[str]) -> tuple[int, int, int]:
    """The indices of a calibration's recorded columns in a capture (found by the rules of
    ``--sensor`` when the names differ)."""
    return _pick_columns(layout, sensor, None, prefer, None)[0]


def correct_stream(
    cap: Capture,
    out: IO[bytes],
    correct: Callable[..., FloatArray],
    progress: Callable[[int], None] | None = None,
    more: Sequence[tuple[tuple[int, int, int], Callable[..., FloatArray]]] = (),
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

    A file's blocks of plain lines are spliced (``io.splice``: the sensor cells' text replaced
    in the block's own bytes); the rest, and every file read as a stream, go through pyarrow's
    reader and writer. Both write the same bytes; ``splice=False`` takes the general path only.
    """
    lay = cap.layout
    head = [lay.head]  # written with the first block: an error in it leaves `out` (stdout too) untouched
    options = pcsv.WriteOptions(include_header=False, delimiter=lay.delimiter or " ", quoting_style="none", eol=lay.eol)
    names = [str(i) for i in range(len(lay.names))]
    corrections = [(lay.sensor, correct), *more]

    def convert(source: Capture, first_row: int, cols: list[pa.Array]) -> list[Any]:
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

    def emit(items: list[Any], sink: Any) -> int:
        return _emit(items, sink, options, lay)

    def write(items: list[Any]) -> int:
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
            rows = _pipeline(((convert, cap, first_row, cols) for first_row, cols in cap.batches()), write)
    except InputError:
        if not head:  # rows are out (to stdout, which cannot take them back): say it is not all
            out.write(INCOMPLETE)
        raise
    if head:
        out.write(head.pop())
    if progress is not None:
        progress(rows)
    return rows


def _emit(items: list[Any], sink: Any, options: Any, lay: Layout) -> int:
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


def _pipeline(jobs: Iterator[tuple[Any, ...]], write: Callable[[list[Any]], int]) -> int:
    """Run ``jobs`` (a function and its arguments) on a pool and ``write`` their results in
    order: this thread reads block k+1 and writes block k-1 while the pool converts block k
    (pyarrow and numpy release the GIL). At most `ahead` blocks are in flight at once."""
    rows = 0
    workers = max(2, os.cpu_count() or 1)
    ahead = workers + 2  # two blocks more than workers: a worker done early finds the next one waiting
    pending: deque[Future[list[Any]]] = deque()
    with ThreadPoolExecutor(max_workers=workers) as pool:
        for fn, *args in jobs:
            pending.append(pool.submit(fn, *args))
            while len(pending) >= ahead or (pending and pending[0].done()):
                rows += write(pending.popleft().result())
        while pending:
            rows += write(pending.popleft().result())
    return rows


def _spliced(
    cap: Capture,
    jobs: Iterator[tuple[Any, ...]],
    spliced: Callable[[bytes, int], list[Any]],
    write: Callable[[list[Any]], int],
    emit: Callable[[list[Any], Any], int],
    out: IO[bytes],
    head: list[bytes],
) -> int:
    """Run a regular file's jobs (``_splice_jobs``) on this process's threads, or a big file's
    blocks on worker processes, one per core, that write to ``out`` themselves (``io.forked``).
    ``head`` is emptied once something is written."""
    from tumblecal_cli.io import forked

    path, start = cap._path, len(cap.layout.head)
    assert path is not None
    workers = forked.workers_for(path, os.path.getsize(path) - start) if _descriptor(out) else 0
    blocks = forked.cuts(path, start, BLOCK_BYTES) if workers else None
    if not blocks:
        return _pipeline(jobs, write)

    def render(block: bytes, at: int) -> tuple[list[Any], int]:  # in a worker: the block's bytes
        sink = forked.Parts()
        return sink.parts, emit(spliced(block, at), sink)

    return forked.pipeline(path, blocks, render, out, head[0], workers, written=head.pop)


def splicer_for(
    cap: Capture,
    corrections: Sequence[tuple[tuple[int, int, int], Callable[..., FloatArray]]],
    temperature: int | None = None,
    also: Sequence[int] = (),
    *,
    stream: bool = False,
) -> Any | None:
    """An ``io.splice.Splicer`` for ``cap`` (its arguments), when its lines can be spliced: a
    one-character delimiter, LF or CRLF line ends, and read as a regular file by pyarrow (or,
    with ``stream``, as a stream: stdin, a pipe); else None (whitespace-separated, CR line ends,
    a cut last line left out: the general rules)."""
    from tumblecal_cli.io.splice import Splicer

    lay = cap.layout
    if lay.delimiter is None or len(lay.delimiter) != 1 or lay.eol not in ("\n", "\r\n"):
        return None
    if stream and (cap._path is not None or not isinstance(cap._stream, _DataStream)):
        return None
    if not stream and (cap._path is None or not isinstance(cap._stream, pa.OSFile)):
        return None
    return Splicer(len(lay.names), lay.delimiter, lay.eol, lay.decimal, corrections, temperature, also)


def _stream_spliced(
    cap: Capture, splicer: Any, convert: Callable[[Capture, int, list[pa.Array]], list[Any]], write: Callable[..., int]
) -> int:
    """A stream's blocks of plain lines spliced on threads, in order, until one is not plain:
    from there on (that block, the ones read after it, the rest of the stream) the general
    rules, whose messages count data rows from the stream's first ("data row N": a stream has
    no second pass to find line numbers). Returns the rows written."""
    rows = 0
    workers = max(2, os.cpu_count() or 1)
    pending: deque[tuple[Future[Any] | None, bytes]] = deque()
    blocks = _stream_blocks(cap._stream)

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
    _note_dropped(cap)
    return rows


def _stream_blocks(stream: Any) -> Iterator[tuple[bytes, bool]]:
    """A stream's bytes as blocks of whole lines (the last may lack its line end), each with
    whether it may be spliced: not a line longer than a block (the general reader says so)."""
    carry = b""
    while chunk := stream.read(BLOCK_BYTES):
        cut = chunk.rfind(b"\n") + 1
        if cut == 0:
            carry += chunk
            if len(carry) >= BLOCK_BYTES:
                yield carry, False
                carry = b""
            continue
        block, carry = b"".join((carry, memoryview(chunk)[:cut])), chunk[cut:]
        yield block, block.find(b"\n") < BLOCK_BYTES  # its first line, which began in an earlier read
    if carry:
        yield carry, True


def _stream_rest(
    cap: Capture,
    blocks: Iterator[bytes],
    before: int,
    convert: Callable[[Capture, int, list[pa.Array]], list[Any]],
    write: Callable[..., int],
) -> int:
    rest = _Rest(cap, _Chained(blocks), before)
    rows = _pipeline(((convert, rest, first_row, cols) for first_row, cols in rest.batches()), write)
    _note_dropped(cap)
    return rows


def _note_dropped(cap: Capture) -> None:
    """The note for a last line --drop-incomplete dropped (what ``Capture.batches`` says)."""
    dropped = getattr(cap._stream, "dropped", None)
    if dropped is not None:
        shown = quoted(dropped.decode("utf-8", errors="replace"), 40)
        note = f"{cap.layout.name}: the last line is incomplete ({shown}), dropped (--drop-incomplete)"
        if note not in cap.layout.notes:
            cap.layout.notes.append(note)


class _Chained(io.RawIOBase):
    """Blocks of bytes read as one stream."""

    def __init__(self, blocks: Iterator[bytes]) -> None:
        self._blocks = blocks
        self._buf = memoryview(b"")

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
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

    def __init__(self, cap: Capture, stream: Any, before: int) -> None:
        super().__init__(cap.layout, stream, None, cap._hasher)
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
    corrections: Sequence[tuple[tuple[int, int, int], Callable[..., FloatArray]]],
    convert: Callable[[Capture, int, list[pa.Array]], list[Any]],
    temperature: int | None = None,
) -> tuple[Iterator[tuple[Any, ...]], Callable[[bytes, int], list[Any]]] | None:
    """The jobs that correct a regular file block by block, spliced where its lines are plain
    (``io.splice``), else by the general rules, and the function of a block's job
    (``spliced(block, at)``); None when the file is not one to splice (a stream,
    whitespace-separated, CR line ends, a cut last line left out)."""
    splicer = splicer_for(cap, corrections, temperature)
    if splicer is None or cap._path is None:
        return None
    lay, path = cap.layout, cap._path

    def general(source: _Slice) -> list[Any]:
        return [item for first, cols in source.batches() for item in convert(source, first, cols)]

    def spliced(block: bytes, at: int) -> list[Any]:
        done = splicer.block(block)
        if done is not None:
            return [done]
        return general(_Slice(cap, pa.BufferReader(block), at))

    def jobs() -> Iterator[tuple[Any, ...]]:
        at = len(lay.head)
        with open(path, "rb") as f:
            f.seek(at)
            for block, plain in _stream_blocks(f):
                if not plain:  # a line longer than a block: the general rules for the rest of the file
                    rest = pa.OSFile(path)
                    rest.seek(at)
                    source = _Slice(cap, rest, at)
                    for first, cols in source.batches():
                        yield convert, source, first, cols
                    return
                yield spliced, block, at
                at += len(block)

    return jobs(), spliced


class _Slice(Capture):
    """Part of a capture's data section, from byte ``at`` of the file, read by the general
    rules: its errors name the file's lines."""

    def __init__(self, cap: Capture, stream: Any, at: int) -> None:
        super().__init__(cap.layout, stream, cap._path, cap._hasher)
        self._at = at

    def _line_of_row(self, row: int) -> int | None:
        assert self._path is not None
        lay = self.layout
        with open(self._path, "rb") as f:
            f.seek(len(lay.head))
            before, left = 0, self._at - len(lay.head)  # lines before the slice (only on an error)
            while left > 0:
                chunk = f.read(min(left, BLOCK_BYTES))
                before, left = before + chunk.count(b"\n"), left - len(chunk)
            i = 0
            for offset, raw in enumerate(f):
                if _skipped(raw.decode("utf-8", errors="replace").rstrip("\r\n")):
                    continue
                if i == row:
                    return lay.data_line + before + offset
                i += 1
        return None


#: The last line of a corrected stream that stopped on a bad row after rows were written: one
#: field, so that a reader checking the header's field count refuses it, and no `#`, so that it is
#: not taken for a comment. Exit 2 says so too. (With -o the temporary file is thrown away.)
INCOMPLETE = b"\ntumblecal: output incomplete: the run stopped on an error (exit 2, see stderr)\n"


# numpy <-> arrow by their buffers: pyarrow's Array.to_numpy, pa.array and pa.scalar import
# pandas whenever it is installed (+0.2 s on every command; measured 0.57 s vs 0.36 s for
# `apply` on sample_data/capture.csv), and tumblecal does not use pandas.


def _floats(arr: pa.Array) -> FloatArray:
    """A float64 arrow array without nulls as a numpy array (zero copy)."""
    if len(arr) == 0:
        return np.empty(0)
    assert arr.type == pa.float64()
    assert arr.null_count == 0
    return np.frombuffer(arr.buffers()[1], dtype=np.float64, count=len(arr), offset=arr.offset * 8)


def _bools(arr: pa.Array) -> BoolArray:
    """A boolean arrow array without nulls as a numpy array."""
    if len(arr) == 0:
        return np.zeros(0, dtype=bool)
    assert arr.type == pa.bool_()
    assert arr.null_count == 0
    bits = np.unpackbits(np.frombuffer(arr.buffers()[1], dtype=np.uint8), bitorder="little")
    out: BoolArray = bits[arr.offset : arr.offset + len(arr)].astype(bool)
    return out


def _arrow_floats(values: FloatArray, null: BoolArray) -> pa.Array:
    """A float64 arrow array of ``values``, null where ``null`` is set."""
    validity = pa.py_buffer(np.packbits(~null, bitorder="little")) if null.any() else None
    data = pa.py_buffer(np.ascontiguousarray(values, dtype=np.float64))
    return pa.Array.from_buffers(pa.float64(), len(values), [validity, data])


def _write_batch(batch: pa.RecordBatch, out: IO[bytes], options: Any, lay: Layout) -> int:
    try:
        pcsv.write_csv(batch, out, options)
    except pa.ArrowInvalid:  # a text cell holds a quote: pyarrow will not write it unquoted
        _write_plain(batch, out, lay.delimiter or " ", lay.eol)
    return int(batch.num_rows)


def _write_plain(batch: pa.RecordBatch, out: IO[bytes], delimiter: str, eol: str) -> None:
    columns = [[("" if v is None else v) for v in c.to_pylist()] for c in batch.columns]
    out.write("".join(delimiter.join(row) + eol for row in zip(*columns, strict=True)).encode())


def is_regular(path: str) -> bool:
    """Whether ``path`` is a regular file (one that can be read twice), not a pipe, FIFO or device.
    A path that cannot be examined counts as regular: opening it says what is wrong."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        return True


def sensor_triplet(
    names: Sequence[str], *, sensor: str, columns: Sequence[str] | None, name: str, prefer: Sequence[str] | None = None
) -> tuple[int, int, int]:
    """The sensor columns among ``names`` by the rules a file's header is read by (data in
    memory: a DataFrame's columns); ``name`` says what messages call it."""
    layout = Layout(name, ",", [str(n) for n in names], True, b"", 1, "\n")
    return _pick_columns(layout, sensor, columns, prefer, None)[0]


def read_table(
    path: str, *, no_header: bool = False, dialect: Dialect | None = None
) -> tuple[Layout, list[str], list[pa.Array]]:
    """Every column of a capture, by the rules solve and apply read it by: (layout, names,
    columns, each int64, float64 or text). The sensor columns are checked as apply checks them
    (a cell that is not a number is an error naming its line and column)."""
    with open_capture(path, no_header=no_header, dialect=dialect) as cap:
        parts: list[list[pa.Array]] = [[] for _ in cap.layout.names]
        for first, cols in cap.batches():
            cap.sensor_values([cols[i] for i in cap.layout.sensor], first)
            for k, col in enumerate(cols):
                parts[k].append(col)
    out: list[pa.Array] = []
    for chunks in parts:
        text = pa.chunked_array(chunks, type=pa.string()).combine_chunks() if chunks else pa.array([], pa.string())
        trimmed = pc.utf8_trim_whitespace(cap.pointed(text))
        for kind in (pa.int64(), pa.float64()):
            try:
                out.append(pc.cast(pc.if_else(pc.equal(trimmed, ""), None, trimmed), kind))
                break
            except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
                continue
        else:
            out.append(text)
    return cap.layout, list(cap.layout.names), out
