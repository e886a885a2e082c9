"""summary.csv, a batch's record of its units: one row per unit (:class:`Row`), appended as each
finishes and rewritten sorted at the end; each cell as a spreadsheet shows it safely; and read
back for ``--resume``.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
import stat
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from tumblecal_cli.errors import InputError, TumblecalError, control_character
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.io.outputs import atomic_output, spreadsheet_safe, unsafe

if TYPE_CHECKING:
    from tumblecal_cli.io.calfiles.calfile import Pose

SUMMARY = "summary.csv"
#: Lists in a summary cell (a unit's codes, its input files) are joined with this.
SEPARATOR = ";"
#: The columns of summary.csv, in order (docs/commands/batch.md).
SUMMARY_COLUMNS = [
    "serial",
    "status",
    "verdict",
    "codes",
    "file",
    "method",
    "offset_x",
    "offset_y",
    "offset_z",
    "gain_x",
    "gain_y",
    "gain_z",
    "offset_se_x",
    "offset_se_y",
    "offset_se_z",
    "gain_se_x",
    "gain_se_y",
    "gain_se_z",
    "created",
    "inputs",
    "message",
    "duplicate_of",
]
#: The columns of a summary an earlier version wrote (before duplicate_of): --resume takes it.
EARLIER_COLUMNS = SUMMARY_COLUMNS[:-1]
NUMBERS = {c for c in SUMMARY_COLUMNS if c[-2:] in ("_x", "_y", "_z")}
VERDICTS = {0: "pass", 1: "fail", 3: "rejected", 2: "error"}
#: Exit status of the whole batch: the first of these any unit has (docs/reference/exit-status.md).
PRECEDENCE = (2, 3, 1)


Triple = tuple[float | None, float | None, float | None]
NONE3: Triple = (None, None, None)


@dataclass
class Row:
    """A unit's row of summary.csv (SUMMARY_COLUMNS: ``offset`` is offset_x, offset_y, offset_z
    ...), and what the batch needs of it beside: ``messages`` for people, one per line; the
    ``staging`` file its calibration waits in; the ``poses`` (sha256, file) it records, for
    duplicate_of; ``unwritten`` when the disk refused its calibration."""

    serial: str
    inputs: list[str] = field(default_factory=list)
    status: int = 0
    verdict: str | None = None
    codes: list[str] = field(default_factory=list)
    file: str | None = None
    method: str | None = None
    offset: Triple = NONE3
    gain: Triple = NONE3
    offset_se: Triple = NONE3
    gain_se: Triple = NONE3
    created: str | None = None
    message: str | None = None
    duplicate_of: list[str] | None = None
    messages: list[str] | None = None
    staging: str | None = None
    poses: list[tuple[str, str]] | None = None
    unwritten: bool = False

    def value(self, column: str) -> object:
        """The value of a summary column (a number column, ``offset_x``, one of its triple)."""
        name, _, axis = column.rpartition("_")
        if column in NUMBERS:
            triple: Triple = getattr(self, name)
            return triple["xyz".index(axis)]
        return getattr(self, column)

    @classmethod
    def received(cls, fields: Mapping[str, object]) -> Row:
        """The row :func:`run_unit` sent (its fields by name)."""
        return cls(**fields)  # type: ignore[arg-type]  # a Row's own fields, made by vars()

    @classmethod
    def of(cls, row: Row | Mapping[str, object]) -> Row:
        """A row given by its summary columns (a mapping, as read from summary.csv)."""
        if isinstance(row, Row):
            return row

        def triple(name: str) -> Triple:
            values = [row.get(f"{name}_{a}") for a in "xyz"]
            x, y, z = (float(v) if isinstance(v, int | float | str) and v != "" else None for v in values)
            return x, y, z

        def texts(name: str) -> list[str] | None:
            value = row.get(name)
            return None if value is None else [str(v) for v in value] if isinstance(value, list) else [str(value)]

        def text(name: str) -> str | None:
            value = row.get(name)
            return None if value is None else str(value)

        status = row.get("status", 0)
        return cls(
            serial=str(row.get("serial", "")),
            inputs=texts("inputs") or [],
            status=int(status) if isinstance(status, int | str) else 0,
            verdict=text("verdict"),
            codes=texts("codes") or [],
            file=text("file"),
            method=text("method"),
            offset=triple("offset"),
            gain=triple("gain"),
            offset_se=triple("offset_se"),
            gain_se=triple("gain_se"),
            created=text("created"),
            message=text("message"),
            duplicate_of=texts("duplicate_of"),
        )


def cell(row: Row | Mapping[str, object], column: str) -> str:
    """A summary cell: numbers in full, lists joined, and any text a spreadsheet would take for a
    formula (a serial ``=1+1``, a file named ``=cmd|...`` in ``inputs`` or ``message``, the
    labelled inputs ``+x=x.csv``) with a leading ``'``; :func:`read_summary` takes it off."""

    value = Row.of(row).value(column)
    if value is None:
        return ""
    if isinstance(value, list):
        return spreadsheet_safe(SEPARATOR.join(str(v) for v in value))
    return spreadsheet_safe(repr(value) if isinstance(value, float) else str(value))


def _numbers(raw: Mapping[str, str], name: str) -> Triple:
    """A number column's three cells (offset_x, offset_y, offset_z), empty: None."""
    x, y, z = (float(raw[f"{name}_{a}"]) if raw[f"{name}_{a}"] else None for a in "xyz")
    return x, y, z


class SummaryFile:
    """summary.csv, appended to as each unit finishes (a crash keeps what was done, for
    --resume), and rewritten sorted by serial at the end."""

    def __init__(self, out_dir: str, rows: list[Row]) -> None:
        self.path = os.path.join(out_dir, SUMMARY)
        self.rows = rows
        self._file = open(self.path, "a", newline="", encoding="utf-8")  # noqa: SIM115 (closed in close)
        self._writer = csv.writer(self._file, lineterminator="\n")
        if self._file.tell() == 0:  # a new file (a resumed one has its header, rows or not)
            self._writer.writerow(SUMMARY_COLUMNS)
            self._file.flush()

    def add(self, row: Row) -> None:
        self.rows.append(row)
        self._writer.writerow([cell(row, c) for c in SUMMARY_COLUMNS])
        self._file.flush()

    def close(self) -> None:

        self._file.close()
        self.rows.sort(key=lambda r: r.serial)
        with atomic_output(self.path) as out:
            out.write(text(self.rows).encode())


def text(rows: Iterable[Row | Mapping[str, object]]) -> str:
    """summary.csv of ``rows`` (each a Row, or its summary columns)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(SUMMARY_COLUMNS)
    writer.writerows([cell(r, c) for c in SUMMARY_COLUMNS] for r in rows)
    return buffer.getvalue()


def status(rows: Iterable[Row | Mapping[str, object]]) -> int:
    """The batch's exit status: 2, 3, 1 or 0, the first that any unit has."""
    seen = {Row.of(r).status for r in rows}
    return next((s for s in PRECEDENCE if s in seen), 0)


#: The longest serial, in bytes: the calibration is named SERIAL_STAMP.json (a file name: 255).
LONGEST_SERIAL = 200


# -- read back for --resume ---------------------------------------------------------------------

#: A code a unit's row gives (``pose.orientation``, ``limit.offset.x``): dotted lower-case words.
CODE = re.compile(r"[a-z][a-z0-9_]*(?:\.[a-z0-9_]+)+")
#: What a row --resume cannot trust is told with. It is exit 2, and the unit is not redone on its
#: own: a summary that says what no batch wrote was edited or is another program's, and redoing
#: the unit quietly would bury that, and leave the row's file (../../etc/passwd, a calibration of
#: another serial) for the next reader to trust. Deleting the line is the one way to redo it.
UNTRUSTED = "--resume trusts only what a batch wrote: check that row; delete it and --resume again to redo its unit"


def read_summary(path: str) -> tuple[list[Row], list[str]]:
    """The rows of an existing summary.csv (for --resume), typed as run_unit makes them, and
    notes for people. Each row is one this batch could have written, or the summary is exit 2
    naming its line and cell (:func:`untrusted`); a last row cut short (a batch killed, or a disk
    full, while writing it) is dropped, with a note, so that its unit is done again. The file is
    rewritten (without that row, or from an earlier version's columns) only once every row is
    trusted: a summary refused is left as it was."""

    try:
        with open(path, "rb") as f:
            data = f.read()
        kept, notes = _without_torn_row(data, path)
        reader = csv.DictReader(io.StringIO(kept.decode("utf-8"), newline=""))
        if reader.fieldnames not in (SUMMARY_COLUMNS, EARLIER_COLUMNS):
            raise InputError(
                "not a tumblecal batch summary (its header differs)", file=path, line=1, hint="use another --out-dir"
            )
        raws = list(reader)
    except (OSError, UnicodeDecodeError, csv.Error) as err:
        raise InputError(f"cannot read the summary: {err}", file=path) from None
    rows: list[Row] = []
    lines: dict[str, int] = {}
    for n, raw in enumerate(raws, 2):
        row = _row(raw, path, n)
        if row.serial in lines:
            raise _refused(path, n, "serial", f"serial {row.serial} is also on line {lines[row.serial]}")
        lines[row.serial] = n
        wrong = untrusted(row, os.path.dirname(path))
        if wrong is not None:
            raise _refused(path, n, *wrong)
        rows.append(row)
    if kept != data or reader.fieldnames == EARLIER_COLUMNS:  # appended in this version's columns from here
        with atomic_output(path) as target:
            target.write(text(rows).encode())
    return rows, notes


def _without_torn_row(data: bytes, path: str) -> tuple[bytes, list[str]]:
    """A summary's bytes without a last row cut short, and a note when there was one. (Summary
    cells hold no line breaks: a row is a line.)"""
    whole = data.endswith(b"\n")
    lines = data.split(b"\n")[:-1] if whole else data.split(b"\n")
    header = lines[0].decode("utf-8", "replace") if lines else ""
    if len(lines) < 2 or header not in (",".join(SUMMARY_COLUMNS), ",".join(EARLIER_COLUMNS)):
        return data, []  # a header alone, or not a summary of ours: read_summary judges it
    try:
        cells = len(next(csv.reader([lines[-1].decode("utf-8")]), []))
    except (UnicodeDecodeError, csv.Error):
        cells = 0
    if whole and cells == header.count(",") + 1:
        return data, []
    note = f"{path}: its last row was cut short (a batch stopped while writing it): dropped, that unit is done again"
    return data[: len(data) - len(lines[-1]) - (1 if whole else 0)], [note]


def _row(raw: Mapping[str | None, object], path: str, n: int) -> Row:
    """Line ``n`` of a summary as a Row, each cell as it was before a leading ' kept a
    spreadsheet from taking it for a formula; its serial, status, verdict and codes checked."""
    if None in raw.values() or None in raw:  # fewer or more cells than the header
        raise InputError(
            "a row with the wrong number of cells (a batch killed while writing it?)",
            file=path,
            line=n,
            hint="delete that line and --resume again: that unit is redone",
        )
    cells = {c: unsafe(str(raw.get(c) or "")) for c in SUMMARY_COLUMNS}
    wrong = _untrusted_cells(cells)
    if wrong is not None:
        raise _refused(path, n, *wrong)
    try:
        return Row(
            serial=cells["serial"],
            inputs=[c for c in cells["inputs"].split(SEPARATOR) if c],
            status=int(cells["status"]),
            verdict=cells["verdict"] or None,
            codes=[c for c in cells["codes"].split(SEPARATOR) if c],
            file=cells["file"] or None,
            method=cells["method"] or None,
            offset=_numbers(cells, "offset"),
            gain=_numbers(cells, "gain"),
            offset_se=_numbers(cells, "offset_se"),
            gain_se=_numbers(cells, "gain_se"),
            created=cells["created"] or None,
            message=cells["message"] or None,
            duplicate_of=[c for c in cells["duplicate_of"].split(SEPARATOR) if c] or None,
        )
    except ValueError:
        raise InputError("a row this version did not write", file=path, line=n, hint=UNTRUSTED) from None


def _untrusted_cells(cells: Mapping[str, str]) -> tuple[str, str] | None:
    """Why a row's serial, status, verdict or codes are none a batch writes: (column, what), or None."""
    serial, status, verdict = cells["serial"], cells["status"], cells["verdict"]
    if (
        not serial
        or serial.startswith(".")
        or "/" in serial
        or "\\" in serial
        or control_character(serial)
        or len(serial.encode()) > LONGEST_SERIAL
    ):
        return "serial", f"serial {serial!r} cannot name a unit"
    if status not in ("0", "1", "2", "3"):
        return "status", f"status {status!r} is not one tumblecal writes (0, 1, 2 or 3)"
    if verdict != VERDICTS[int(status)]:
        return "verdict", f"verdict {verdict!r} is not status {status}'s ({VERDICTS[int(status)]})"
    code = next((c for c in cells["codes"].split(SEPARATOR) if c and not CODE.fullmatch(c)), None)
    if code is not None:
        return "codes", f"code {code!r} is not one tumblecal writes"
    return _untrusted_number(cells)


#: The number columns of a row: a calibration's offsets and gains, and their 1-sigma (0 or more).
NUMBER_COLUMNS = tuple(f"{name}_{axis}" for name in ("offset", "gain", "offset_se", "gain_se") for axis in "xyz")


def _untrusted_number(cells: Mapping[str, str]) -> tuple[str, str] | None:
    """The first number cell a batch cannot have written, and why: a batch writes a finite number
    (a 1-sigma of 0 or more) or nothing, never nan, inf or text (a row edited by hand)."""
    for column in NUMBER_COLUMNS:
        text = cells[column]
        if not text:
            continue
        try:
            value = float(text)
        except ValueError:
            return column, f"{column} {text!r} is not a number"
        if not math.isfinite(value):
            return column, f"{column} {text!r} is not a finite number, as a batch writes"
        if column.endswith(("_se_x", "_se_y", "_se_z")) and value < 0:
            return column, f"{column} {text!r} is a negative 1-sigma"
    return None


def untrusted(row: Row, out_dir: str) -> tuple[str, str] | None:
    """Why --resume cannot trust a row's calibration: (column, what), or None. A unit that passed
    or failed its limits names its calibration, ``<serial>_<UTC time>.json``: a plain name in
    ``out_dir`` (never a path out of it, never a link), a calibration that loads and is of that
    serial, by the row's method, with the row's verdict. A unit with an error or a rejected
    capture names none. Sets ``row.poses`` from the calibration (for duplicate_of)."""
    name, verdict = row.file, VERDICTS[row.status]
    if row.status in (2, 3):
        return ("file", f"status {row.status} ({verdict}) has no calibration: this row names {name}") if name else None
    if not name:
        return "file", f"status {row.status} ({verdict}) names its calibration in 'file': this row names none"
    path, wrong = _published(name, row.serial, out_dir)
    if wrong is not None:
        return "file", wrong
    try:
        cal = calfile.load(path)
    except TumblecalError as err:
        return "file", f"{name}: {err.message}"
    if cal.serial != row.serial:
        whose = f"the calibration of {cal.serial}" if cal.serial else "a calibration of no serial"
        return "file", f"{name} is {whose}, not of {row.serial}"
    if row.method != cal.method:
        return "method", f"method {row.method!r} is not its calibration's ({cal.method})"
    judged = 0 if cal.verdict is None or cal.verdict.passed else 1
    if row.status != judged:
        return "status", f"status {row.status} ({verdict}) is not its calibration's verdict ({VERDICTS[judged]})"
    row.poses = pose_files(cal.poses)
    return None


def _published(name: str, serial: str, out_dir: str) -> tuple[str, str | None]:
    """The path of a calibration a row names, and why it is none this batch published (or None):
    ``<serial>_<UTC time>.json``, a plain name in ``out_dir`` (never a path out of it), a regular
    file (a batch publishes by a hard link or a rename: a symbolic link or a FIFO is not its)."""
    path = os.path.join(out_dir, name)
    plain = os.path.basename(name) == name and "\\" not in name and not control_character(name)
    if not (plain and name.startswith(f"{serial}_") and name.endswith(".json")):
        return path, f"file {name!r} is not a calibration this batch wrote ({serial}_<UTC time>.json in this folder)"
    try:
        mode = os.lstat(path).st_mode
    except OSError:
        return path, f"file {name!r} is not in the folder (the unit's calibration is gone)"
    if not stat.S_ISREG(mode):
        what = "a symbolic link" if stat.S_ISLNK(mode) else "not a regular file"
        return path, f"file {name!r} is {what}, not a calibration this batch wrote"
    return path, None


def _refused(path: str, n: int, column: str, what: str) -> InputError:
    """The error of a row --resume cannot trust: the summary's line and the cell."""
    return InputError(what, file=path, line=n, column=SUMMARY_COLUMNS.index(column) + 1, hint=UNTRUSTED)


def pose_files(poses: Iterable[Pose]) -> list[tuple[str, str]]:
    """(sha256, file) of each pose a calibration records (a log's blocks share one)."""
    return list(dict.fromkeys((p.sha256, p.file or "") for p in poses if p.sha256))
