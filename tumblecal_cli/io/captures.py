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

pyarrow is the engine because it streams, imports in 0.2 s (pandas takes 0.45 s here) and
writes floats as their shortest round-trip text; README "Dependencies" has the measurements.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
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

    @property
    def sensor_names(self) -> list[str]:
        return [self.names[i] for i in self.sensor]


class _DataStream(io.RawIOBase):
    """The data section as a byte stream, for stdin and whitespace-separated files: the
    sniffed remainder of the first block, then the rest; hashes what it reads (stdin has no
    second pass) and squeezes runs of whitespace to single spaces for pyarrow."""

    def __init__(self, first: bytes, rest: IO[bytes], hasher: Any, squeeze: bool, owns: bool = False) -> None:
        self._rest = rest
        self._owns = owns  # close ``rest`` too (a file we opened; never stdin)
        self._hasher = hasher
        self._squeeze = squeeze
        self._carry = b""
        self._buf = self._transform(first, final=False)
        self._eof = False

    def _transform(self, chunk: bytes, final: bool) -> bytes:
        if not self._squeeze:
            return chunk
        chunk = self._carry + chunk
        cut = len(chunk) if final else chunk.rfind(b"\n") + 1
        self._carry = chunk[cut:]
        return _WS_EDGE.sub(b"", _WS_RUN.sub(b" ", chunk[:cut]))

    def readable(self) -> bool:
        return True

    def close(self) -> None:
        if self._owns:
            self._rest.close()
        super().close()

    def readinto(self, buffer: Any) -> int:
        view = memoryview(buffer)
        while not self._buf and not self._eof:
            chunk = self._rest.read(max(len(view), 1 << 16))
            self._hasher.update(chunk)
            self._eof = not chunk
            self._buf = self._transform(chunk, final=self._eof)
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
                raise self._locate(first_row + i, j, f"not a number: {quoted(text[i].as_py())}", triplet)
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
) -> Capture:
    """Open ``path`` ('-' for stdin), sniff its layout and find its sensor and time columns.

    ``columns`` (from ``--columns``) overrides detection; ``prefer`` (a calibration's
    recorded columns) is used when all three are present; ``extra`` names one more column to
    read (as text); ``name`` is how messages name the file (default: the path).
    """
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
        layout, consumed = _sniff(name, first, at_eof=len(first) < HEAD_BYTES, no_header=no_header)
        layout.sensor, layout.time = _pick_columns(layout, sensor, columns, prefer, time_column)
        lower = [n.lower() for n in layout.names]
        layout.temperature = next((i for i, n in enumerate(lower) if n in TEMPERATURE_NAMES), None)
        if extra is not None:
            layout.extra = _column(layout, extra, "column")
    except InputError:
        if f is not sys.stdin.buffer:
            f.close()
        raise
    stream: Any
    regular = path != "-" and stat.S_ISREG(os.fstat(f.fileno()).st_mode)  # not a pipe, FIFO or device
    if regular and layout.delimiter is not None:
        # a regular file: pyarrow reads it natively from the end of the header (1.7x faster)
        f.close()
        stream = pa.OSFile(path)
        stream.seek(consumed)
    else:
        stream = _DataStream(first[consumed:], f, hasher, squeeze=layout.delimiter is None, owns=path != "-")
    return Capture(layout, stream, path if regular else None, hasher)  # a pipe is read once


def _sniff(name: str, first: bytes, *, at_eof: bool, no_header: bool) -> tuple[Layout, int]:
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
    offset = bom  # bytes consumed so far
    k = 0
    while k < len(lines) and _skipped(lines[k]):
        offset += len(lines[k].encode())
        k += 1
    if k == len(lines):
        raise InputError("no data: the file holds only blank or # comment lines", file=name)
    content = [ln.rstrip("\r\n") for ln in lines[k : k + 50] if not _skipped(ln)]
    delimiter = _detect_delimiter(content)
    cells = [c.strip().strip('"').strip() for c in _split(content[0], delimiter)]
    eol = "\r\n" if lines[k].endswith("\r\n") else "\r" if lines[k].endswith("\r") else "\n"  # CR alone: old Macs
    header = not no_header and any(c and not re.match(_NUMBER, c) for c in cells)
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
    )
    return layout, offset


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
    rows: np.ndarray[Any, np.dtype[np.int64]]  # data row (0-based) of each reading
    clock: FloatArray | None
    labels: list[str] | None
    sha256: str
    temperature: FloatArray | None = None
    scale: float = 1.0

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
    time_unit: str = "s",
    rate: float | None = None,
    prefer: Sequence[str] | None = None,
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
    time_unit: str = "s",
    label_column: str | None = None,
    use_time: bool = True,
    name: str | None = None,
    digest: bool = True,
    prefer: Sequence[str] | None = None,
) -> Log:
    """Read a whole capture into memory (a log to segment, or a pose file). With ``use_time``
    its time column must hold numbers that never go backwards (else a time cell that is not a
    number leaves ``clock`` unknown); ``label_column`` is read as text; ``digest`` off leaves
    ``sha256`` empty (a second pass over the file saved)."""
    with open_capture(
        path,
        sensor=sensor,
        columns=columns,
        prefer=prefer,
        no_header=no_header,
        time_column=time_column,
        name=name,
        extra=label_column,
    ) as cap:
        lay = cap.layout
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
                temps.append(cols[k])
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
                t = np.concatenate([_floats(pc.cast(c, pa.float64(), safe=False)) for _, c in times])[mask]
            except pa.ArrowInvalid:  # a time cell that is not a number: the duration is unknown
                t = None
        temperature = None
        if temps:
            with contextlib.suppress(pa.ArrowInvalid):  # a cell that is not a number: the temperature is unknown
                temperature = np.concatenate([_floats(pc.cast(c, pa.float64(), safe=False)) for c in temps])[mask]
        text = None if lay.extra is None else [str(labels[i] or "").strip() for i in used]
        sha256 = cap.sha256() if digest else ""
    return Log(lay, values if every else values[mask], used, t, text, sha256, temperature, _TIME_SCALE[time_unit])


def _times(cap: Capture, times: list[tuple[int, pa.Array]], mask: BoolArray | None) -> FloatArray:
    """A log's time column on the rows ``mask`` keeps (all when None): numbers that never go
    backwards, else an error naming the line. Rows without sensor values are not judged: an
    interleaved logger stamps each sensor's rows with its own clock."""
    lay = cap.layout
    assert lay.time is not None
    parts = []
    for first_row, text in times:
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
    take ``head`` bytes: every line that is not blank or a # comment (the reader's rules)."""
    newline = np.flatnonzero(data[head:] == 10) + head
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
    correct: Callable[[FloatArray], FloatArray],
    progress: Callable[[int], None] | None = None,
    more: Sequence[tuple[tuple[int, int, int], Callable[[FloatArray], FloatArray]]] = (),
) -> int:
    """Write ``cap`` to ``out`` with its sensor columns replaced by ``correct(values)`` (and
    each triplet of ``more`` by its own correction: one pass for a whole IMU).

    Every other byte is copied: the preamble and header verbatim, other cells as their text,
    the line ending; a whitespace-separated file is written with single spaces. Rows whose
    sensor cells are all empty stay empty. Returns the number of data rows written.
    """
    lay = cap.layout
    head = [lay.head]  # written with the first block: an error in it leaves `out` (stdout too) untouched
    options = pcsv.WriteOptions(include_header=False, delimiter=lay.delimiter or " ", quoting_style="none", eol=lay.eol)
    names = [str(i) for i in range(len(lay.names))]

    def convert(first_row: int, cols: list[pa.Array]) -> pa.RecordBatch:
        for triplet, fn in [(lay.sensor, correct), *more]:
            values, empty = cap.sensor_values([cols[i] for i in triplet], first_row, triplet)
            fixed = fn(values)
            for j, i in enumerate(triplet):  # the float -> shortest round-trip text: the costliest step
                cols[i] = pc.cast(_arrow_floats(fixed[:, j], empty), pa.string())
        return pa.RecordBatch.from_arrays(cols, names=names)

    def write(batch: pa.RecordBatch) -> int:
        if head:
            out.write(head.pop())
        return _write_batch(batch, out, options, lay)

    # A pipeline: this thread parses block k+1 and writes block k-1 while the pool converts
    # block k (pyarrow releases the GIL). At most `ahead` blocks are in memory at once.
    rows = 0
    ahead = max(2, os.cpu_count() or 1)
    pending: deque[Future[pa.RecordBatch]] = deque()
    with ThreadPoolExecutor(max_workers=ahead) as pool:
        try:
            for first_row, cols in cap.batches():
                pending.append(pool.submit(convert, first_row, cols))
                while len(pending) >= ahead or (pending and pending[0].done()):
                    rows += write(pending.popleft().result())
            while pending:
                rows += write(pending.popleft().result())
        except InputError:
            if not head:  # rows are out (to stdout, which cannot take them back): say it is not all
                out.write(INCOMPLETE)
            raise
        if head:
            out.write(head.pop())
        if progress is not None:
            progress(rows)
    return rows


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


def read_table(path: str, *, no_header: bool = False) -> tuple[Layout, list[str], list[pa.Array]]:
    """Every column of a capture, by the rules solve and apply read it by: (layout, names,
    columns, each int64, float64 or text). The sensor columns are checked as apply checks them
    (a cell that is not a number is an error naming its line and column)."""
    with open_capture(path, no_header=no_header) as cap:
        parts: list[list[pa.Array]] = [[] for _ in cap.layout.names]
        for first, cols in cap.batches():
            cap.sensor_values([cols[i] for i in cap.layout.sensor], first)
            for k, col in enumerate(cols):
                parts[k].append(col)
    out: list[pa.Array] = []
    for chunks in parts:
        text = pa.chunked_array(chunks, type=pa.string()).combine_chunks() if chunks else pa.array([], pa.string())
        trimmed = pc.utf8_trim_whitespace(text)
        for kind in (pa.int64(), pa.float64()):
            try:
                out.append(pc.cast(pc.if_else(pc.equal(trimmed, ""), None, trimmed), kind))
                break
            except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
                continue
        else:
            out.append(text)
    return cap.layout, list(cap.layout.names), out
