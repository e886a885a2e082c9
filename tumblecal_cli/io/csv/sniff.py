"""A capture's layout, decided from its first block (docs/reference/csv.md).

``sniff`` reads the head of a file and decides: UTF-8 BOM, the preamble (blank and ``#``
lines), the delimiter (comma, semicolon, tab, or runs of whitespace), whether the first line is
a header, the line ending and the decimal mark; ``pick_columns`` finds the sensor triplet and
the time column by name (or by ``--columns``). ``Dialect`` is what the user says of a file's
shape where the sniffer should not guess. Nothing here reads past the head.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field

from tumblecal_cli.errors import InputError
from tumblecal_cli.io.csv import compressed
from tumblecal_cli.io.readspec import Dialect

HEAD_BYTES = 1 << 20  # the sniffer looks at this much of the file


def quoted(cell: object, keep: int = 40) -> str:
    """A cell as an error message quotes it: ``repr``, cut to ``keep`` characters with its length."""
    text = str(cell)
    return repr(text) if len(text) <= keep else f"{text[:keep]!r}... ({len(text):,} characters)"


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


NUMBER = r"(?i)^[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:e[+-]?\d+)?|nan|inf|infinity)$"


WS_RUN = re.compile(rb"[ \t]+")


WS_EDGE = re.compile(rb"^ | (?=\r?$)", re.MULTILINE)


TIME_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}


UNIT_WORDS = {"s": "seconds", "ms": "milliseconds", "us": "microseconds", "ns": "nanoseconds"}


#: A time column whose name carries its unit: ``timestamp_ms``, ``t_us``, ``time(ns)``, ``time [ms]``,
#: Arduino's ``millis``/``micros``.
_TIME_WITH_UNIT = re.compile(
    r"^(?:t|time|timestamp|ts)(?:[ _.\-]+[(\[]?|[(\[])(s|sec|ms|us|µs|ns)[)\]]?$|^(millis|micros)$"
)  # a separator or a bracket before the unit: `ts` and `times` are names, not t + s


#: A cell written with a decimal comma (``1,045729``, ``-0,5e-3``): European spreadsheet exports.
COMMA_NUMBER = re.compile(r"^\s*[+-]?\d*,\d+(?:[eE][+-]?\d+)?\s*$")


MAX_PREAMBLE = 20  # metadata lines a station may write before its header


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
    per_row_column: int | None = None  # the column each row is corrected at: a temperature, or a current (``per_row``)
    extra: int | None = None  # one more column read as text (a log's label column)
    notes: list[str] = field(default_factory=list)  # things a person should be told
    decimal: str = "."  # the decimal mark of the file's numbers ("," in European exports)
    time_unit: str | None = None  # the unit the time column's name gives (timestamp_ms), if any
    incomplete: bytes | None = None  # the last line, when it is cut short and dropped (--drop-incomplete)
    compression: str | None = None  # gzip, bzip2, xz or zstd: the file's data read decompressed (io.csv.compressed)
    per_row: str = "temperature"  # what the ``per_row_column`` holds, as messages name it

    @property
    def sensor_names(self) -> list[str]:
        return [self.names[i] for i in self.sensor]


def sniff(name: str, first: bytes, *, at_eof: bool, no_header: bool, dialect: Dialect) -> tuple[Layout, int]:
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
        raise InputError("binary data, not a CSV text file", file=name, hint=compressed.binary_hint(name, first))
    bom = 3 if first.startswith(b"\xef\xbb\xbf") else 0
    try:
        # a multi-byte character may be cut at the end of the block: decode whole lines only
        text = first[bom : first.rfind(b"\n") + 1 if not at_eof else len(first)].decode("utf-8")
    except UnicodeDecodeError as err:
        raise InputError(f"not UTF-8 text (byte {err.start + bom})", file=name) from None
    lines = text.splitlines(keepends=True)
    k = _first_content(name, lines, dialect.skip_rows or 0)
    notes: list[str] = []
    at = [i for i in range(k, min(len(lines), k + 200)) if not skipped(lines[i])]  # the lines sniffed
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
    cells = [c.strip().strip('"').strip() for c in split_fields(content[0], delimiter)]
    eol = "\r\n" if lines[k].endswith("\r\n") else "\r" if lines[k].endswith("\r") else "\n"  # CR alone: old Macs
    header = not no_header and any(c and not re.match(NUMBER, c) and not COMMA_NUMBER.match(c) for c in cells)
    offset = bom + len("".join(lines[:k]).encode())  # bytes consumed so far
    if header:
        names = cells
        offset += len(lines[k].encode())
        k += 1
        if all(skipped(ln) for ln in lines[k:]) and at_eof:
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
    while k < len(lines) and skipped(lines[k]):
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
        counts = [len(split_fields(ln, delim)) for ln in rest[:50]]
        width = max(set(counts), key=counts.count)
        if counts[0] != width or width < 3:
            continue  # not where the table starts
        if skip == 0 or any(len(split_fields(ln, delim)) >= width for ln in content[:skip]):
            return 0, delimiter
        cells = [c.strip().strip('"').strip() for c in split_fields(rest[0], delim)]
        named = all(c and not re.match(NUMBER, c) and not COMMA_NUMBER.match(c) for c in cells)
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
    cells = [bare(c) for ln in rows for c in split_fields(ln, layout.delimiter)]
    commas = [c for c in cells if "," in c]
    if commas and all(COMMA_NUMBER.match(c) for c in commas) and not any("." in c for c in cells):
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
                cells = [bare(c) for ln in lines for c in ln.split(cand) if "," in c]
                if all(COMMA_NUMBER.match(c) for c in cells):
                    return cand
    return best[2] if best else None


def bare(cell: str) -> str:
    """A cell's text without the blanks around it and the double quotes around those: some
    loggers and spreadsheet exports write every cell in quotes (``"1.033358"``)."""
    text = cell.strip()
    return text[1:-1].strip() if len(text) >= 2 and text[0] == text[-1] == '"' else text


def skipped(line: str) -> bool:
    """Blank and ``#`` comment lines are not data, wherever they are (docs/reference/csv.md)."""
    text = line.strip()
    return not text or text.startswith("#")


def split_fields(line: str, delimiter: str | None) -> list[str]:
    return line.split() if delimiter is None else line.split(delimiter)


def pick_columns(
    layout: Layout,
    sensor: str,
    columns: Sequence[str] | None,
    prefer: Sequence[str] | None,
    time_column: str | None,
) -> tuple[tuple[int, int, int], int | None]:
    names = layout.names
    lower = [n.lower() for n in names]

    def index_of(ref: str, what: str) -> int:
        return column_index(layout, ref, what)

    time = index_of(time_column, "time column") if time_column else None
    if time is None:
        time = next((i for i, n in enumerate(lower) if n in TIME_NAMES), None)
    if time is None:
        time = next((i for i, n in enumerate(lower) if unit_of_name(n)), None)
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


def no_column_twice(
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
    if layout.per_row_column is not None and layout.per_row_column == layout.time:
        raise InputError(
            f"{'--temperature-column' if temperature_column else 'the temperature column'} names "
            f"{names[layout.time]!r}, the time column",
            file=layout.name,
            hint=f"name the temperature column with --temperature-column NAME (columns: {', '.join(names)})",
        )
    for role, index, option in (
        ("time", layout.time, time_column and "--time-column"),
        ("temperature", layout.per_row_column, temperature_column and "--temperature-column"),
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
        for role, index in (("time", layout.time), ("temperature", layout.per_row_column)):
            if index is not None:
                taken[index] = f"the {role} column"
        if layout.extra in taken:
            raise InputError(
                f"--pose-column names {names[layout.extra]!r}, {taken[layout.extra]}",
                file=layout.name,
                hint=f"name the column of pose labels (columns: {', '.join(names)})",
            )


def unit_of_name(name: str) -> str | None:
    """The unit a time column's name gives: ``timestamp_ms`` -> ms, ``t_us`` -> us, ``millis`` -> ms."""
    match = _TIME_WITH_UNIT.match(name.strip().lower())
    if match is None:
        return None
    unit = match.group(1) or {"millis": "ms", "micros": "us"}[match.group(2)]
    return {"sec": "s", "µs": "us"}.get(unit, unit)


def column_index(layout: Layout, ref: str, what: str) -> int:
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


def sensor_columns(layout: Layout, sensor: str, prefer: Sequence[str]) -> tuple[int, int, int]:
    """The indices of a calibration's recorded columns in a capture (found by the rules of
    ``--sensor`` when the names differ)."""
    return pick_columns(layout, sensor, None, prefer, None)[0]


def sensor_triplet(
    names: Sequence[str], *, sensor: str, columns: Sequence[str] | None, name: str, prefer: Sequence[str] | None = None
) -> tuple[int, int, int]:
    """The sensor columns among ``names`` by the rules a file's header is read by (data in
    memory: a DataFrame's columns); ``name`` says what messages call it."""
    layout = Layout(name, ",", [str(n) for n in names], True, b"", 1, "\n")
    return pick_columns(layout, sensor, columns, prefer, None)[0]
