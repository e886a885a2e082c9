"""``tumblecal batch``: the units and the summary.

A unit is a serial number and its inputs (pose files, or one log). Each unit is solved by the
pipeline's ``solve.calibrate``, in this process, in ``--jobs`` worker processes, or on a Dask
cluster (``pipeline.batch.cluster``); its calibration is published as ``<serial>_<UTC time>.json``
next to the others (never replacing a file, so a unit's history stays), and it becomes one row of
``summary.csv``. A unit that fails becomes a row with its exit status and message; it never stops the batch.

It imports neither numpy nor Typer at import time, so a worker pays for numpy once, on its
first unit, and never for the command line.
"""

from __future__ import annotations

import contextlib
import csv
import io
import os
import re
import signal
import sys
import threading
import time
import unicodedata
from collections.abc import Callable, Iterator, Mapping
from concurrent.futures.process import BrokenProcessPool
from contextlib import AbstractContextManager
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, TypeAlias, TypedDict, Unpack

from tumblecal_cli.core import lot
from tumblecal_cli.core.model import face_of_name
from tumblecal_cli.errors import STOPS, InputError, TumblecalError, control_character
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.io.outputs import remove_stale
from tumblecal_cli.pipeline import places
from tumblecal_cli.pipeline.batch.cluster import engine
from tumblecal_cli.pipeline.batch.summary import (
    LONGEST_SERIAL,
    NONE3,
    SUMMARY,
    VERDICTS,
    Row,
    SummaryFile,
    Triple,
    pose_files,
    read_summary,
    status,
)
from tumblecal_cli.pipeline.frames import written_table
from tumblecal_cli.pipeline.options import SolveOptions, checked, keywords_known, path_of, settings
from tumblecal_cli.pipeline.solve import solving as solve

if TYPE_CHECKING:
    import signal
    from types import FrameType

    from tumblecal_cli.core.arrays import FloatArray
    from tumblecal_cli.io.calfiles.calfile import Calibration
    from tumblecal_cli.pipeline.frames import DataFrame
    from tumblecal_cli.pipeline.options import SolveOptions

#: A signal's handler, as the signal module gives and takes it.
Handler: TypeAlias = "Callable[[int, FrameType | None], object] | int | signal.Handlers | None"

#: Files a unit folder's poses (or log) may be in; anything else there is left alone.
DATA_SUFFIXES = (".csv", ".tsv", ".txt", ".dat")
STAGING = ".partial.json"


@dataclass(frozen=True)
class BatchUnit:
    """One unit: its serial and its inputs, each ``FILE`` or ``LABEL=FILE`` as ``--poses`` takes."""

    serial: str
    inputs: tuple[str, ...]
    problem: str | None = None  # why it cannot be solved as found (no files): its row's error
    #: The inputs as found, when ``inputs`` are made absolute for a cluster (:func:`absolute`): what
    #: its calibration, its row and its errors name, as a batch run here does.
    found: tuple[str, ...] = ()


# -- finding the units -------------------------------------------------------------------------


def find_units(source: str, *, log: bool, out_dir: str | None = None) -> tuple[list[BatchUnit], list[str]]:
    """The units of a folder (one folder per unit, or with ``log`` one log per unit) or of a
    manifest CSV, sorted by serial; and notes for people about what was left out. ``out_dir``,
    when it is one of the folder's folders, is not a unit."""
    if source == "-" or os.path.isfile(source):  # '-': a manifest on stdin, its files relative to here
        units, notes = _manifest_units(source, log=log)
        if not units:
            raise InputError("the manifest lists no units, only its header", file=source)
    elif os.path.isdir(source):
        units, notes = _folder_units(source, log=log, skip=out_dir)
    else:
        raise InputError("no such folder or manifest file", file=source)
    if not units:
        layout = "one log per unit (<serial>.csv or <serial>/log.csv)" if log else "one folder of pose files per unit"
        raise InputError(f"no units found: expected {layout}", file=source, hint="see 'tumblecal batch --help'")
    return sorted(units, key=lambda u: u.serial), notes


def _data_files(folder: str) -> list[str]:
    """The data files of a folder, but not a batch summary."""
    try:
        listed = os.listdir(folder)
    except OSError as err:
        raise InputError(f"cannot list the folder: {err.strerror}", file=folder) from None
    names = sorted(
        n for n in listed if not n.startswith(".") and os.path.splitext(n)[1].lower() in DATA_SUFFIXES and n != SUMMARY
    )
    return [os.path.join(folder, n) for n in names if os.path.isfile(os.path.join(folder, n))]


def _face_of(path: str) -> str | None:
    """The face a pose file's name gives (x.csv, xp.csv, +x.csv, xn.csv ...), or None."""
    return _face(os.path.basename(path).split(".", 1)[0])


def _face(text: str) -> str | None:
    """The face a label names (x, xp, +x, xn ...), or None."""

    return face_of_name(text)


def _folder_units(folder: str, *, log: bool, skip: str | None) -> tuple[list[BatchUnit], list[str]]:
    units: list[BatchUnit] = []
    notes: list[str] = []
    loose = _data_files(folder)
    for name in sorted(os.listdir(folder)):
        path = os.path.join(folder, name)
        if name.startswith(".") or not os.path.isdir(path):
            continue
        if skip is not None and os.path.exists(skip) and os.path.samefile(path, skip):
            continue  # the batch's own output folder
        if os.path.exists(os.path.join(path, SUMMARY)):
            notes.append(f"{path}: a batch's output folder (it has a {SUMMARY}); skipped")
            continue
        files = _data_files(path)
        if not files:  # the unit's error (run_unit), not a silent gap in the lot
            what = "log" if log else "pose"
            units.append(BatchUnit(name, (), f"no {what} files ({', '.join(DATA_SUFFIXES)}) in {path}"))
            continue
        if log:
            units.append(BatchUnit(name, tuple(files)))  # more than one: the unit's error, not the batch's
            continue
        faces = [_face_of(f) for f in files]  # all None: unlabelled, in name order
        if any(faces) and not all(faces):  # x.csv y.csv z.csv notes.txt: the poses are the named ones
            stray = [os.path.basename(f) for f, face in zip(files, faces, strict=True) if face is None]
            notes.append(f"{path}: {', '.join(stray)} ignored (not named by a face like the unit's other files)")
            files, faces = [f for f, face in zip(files, faces, strict=True) if face], [f for f in faces if f]
        units.append(BatchUnit(name, tuple(f"{face}={f}" if face else f for face, f in zip(faces, files, strict=True))))
    if log:
        units += [BatchUnit(os.path.splitext(os.path.basename(f))[0], (f,)) for f in loose]
        seen: dict[str, int] = {}
        for u in units:
            seen[u.serial] = seen.get(u.serial, 0) + 1
        twice = sorted(s for s, n in seen.items() if n > 1)
        if twice:
            raise InputError(f"serial {twice[0]} is both a folder and a log file of that name", file=folder)
    elif loose:
        notes.append(f"{folder}: {len(loose)} files beside the unit folders ignored (each unit is a folder)")
    return units, notes


#: A manifest is read whole, and each unit's pose files are held together while it is solved:
#: the most of each that a batch takes (README "batch"), so that its memory is bounded.
MANIFEST_BYTES = 16 << 20
UNIT_FILES = 1000


def _manifest_units(path: str, *, log: bool) -> tuple[list[BatchUnit], list[str]]:
    """A manifest: a header ``serial,...``, then a serial and its files per row. A file is
    relative to the manifest's folder; a column headed by a face (x, +x, xp ...) labels its files."""
    try:
        if path == "-":
            data = sys.stdin.buffer.read(MANIFEST_BYTES + 1)
        else:
            with open(path, "rb") as f:
                data = f.read(MANIFEST_BYTES + 1)
        if len(data) > MANIFEST_BYTES:
            raise InputError(
                f"the manifest is larger than {MANIFEST_BYTES >> 20} MiB: a batch reads it whole",
                file=path,
                hint="split the lot into several manifests, each run with its own --out-dir",
            )
        text = data.decode("utf-8-sig")  # a spreadsheet's byte-order mark
        first = text.split("\n", 1)[0]
        delimiter = ";" if ";" in first and "," not in first else ","  # a spreadsheet in a comma-decimal locale
        rows = list(csv.reader(io.StringIO(text, newline=""), delimiter=delimiter))
    except (OSError, UnicodeDecodeError, csv.Error) as err:
        raise InputError(f"cannot read the manifest: {err}", file=path) from None
    lines = [(n, row) for n, row in enumerate(rows, 1) if any(c.strip() for c in row) and not row[0].startswith("#")]
    if not lines or lines[0][1][0].strip().lower() != "serial":
        raise InputError(
            "a manifest starts with a header whose first column is 'serial'",
            file=path,
            line=lines[0][0] if lines else 1,
            hint="serial,x,y,z  then one row per unit: A17,A17/x.csv,A17/y.csv,A17/z.csv",
        )
    header = [_face(h.strip()) for h in lines[0][1]]
    base = "" if path == "-" else os.path.dirname(path)
    units: list[BatchUnit] = []
    where: dict[str, tuple[int, str]] = {}
    notes: list[str] = []
    for n, row in lines[1:]:
        serial = row[0].strip()
        if not serial or "/" in serial or "\\" in serial or serial.startswith("."):
            raise InputError(f"serial {serial!r} cannot name a file", file=path, line=n, column=1)
        if control_character(serial):  # it would split a summary row or a line
            raise InputError(f"serial {serial!r} holds a control character", file=path, line=n, column=1)
        if len(serial.encode()) > LONGEST_SERIAL:  # the calibration is named after it
            raise InputError(
                f"serial of {len(serial.encode())} bytes: a file is named after it (at most {LONGEST_SERIAL})",
                file=path,
                line=n,
                column=1,
            )
        alike = unicodedata.normalize("NFKC", serial)  # SN + KELVIN SIGN is SNK to a reader (and to some disks)
        if alike in where:
            line, other = where[alike]
            said = serial if other == serial else f"{serial!a} is {other!a} in look-alike characters: it"
            raise InputError(f"serial {said} is also on line {line}", file=path, line=n, column=1)
        if alike != serial:
            notes.append(f"{path}: serial {serial!a} on line {n} is written in look-alike characters of {alike}")
        where[alike] = (n, serial)
        files = sum(1 for cell in row[1:] if cell.strip())
        if files > UNIT_FILES:
            raise InputError(
                f"{files:,} files on the row of {serial!r}: a unit is at most {UNIT_FILES:,} pose files, "
                "solved together, each held in memory until the unit is",
                file=path,
                line=n,
                hint="many orientations of one unit: one table of orientations (a row each), or one log (--log)",
            )
        items: list[str] = []
        for k, cell in enumerate(row[1:], 1):
            cell = cell.strip()
            if not cell:
                continue
            label, sep, rest = cell.partition("=")
            if sep and label and _looks_like_label(label):
                items.append(f"{_face(label) or label}={_resolve(base, rest)}")
            else:
                face = header[k] if k < len(header) and not log else None
                items.append(f"{face}={_resolve(base, cell)}" if face else _resolve(base, cell))
        problem = None if items else f"no files on its row of the manifest (line {n})"  # that unit's error
        units.append(BatchUnit(serial, tuple(items), problem))
    return units, notes


def absolute(item: str) -> str:
    """A pose item (``FILE`` or ``LABEL=FILE``) with its file as an absolute path: what is sent
    to a cluster, whose workers do not share this process's working folder."""
    label, sep, rest = item.partition("=")
    if sep and label and _looks_like_label(label):
        return f"{label}={os.path.abspath(rest)}"
    return item if item == "-" else os.path.abspath(item)


def _looks_like_label(text: str) -> bool:
    return _face(text) is not None or text.count(",") == 2


def _resolve(base: str, name: str) -> str:
    return name if os.path.isabs(name) else os.path.join(base, name)


# -- one unit ----------------------------------------------------------------------------------


def run_unit(
    unit: BatchUnit, options: SolveOptions, out_dir: str, log: bool, token: str, epoch: str | None = None
) -> dict[str, object]:
    """Solve one unit as ``tumblecal solve`` does, into a hidden staging file of this batch
    (``token``); its summary row, as plain data (it crosses from a worker process or a Dask
    worker, whose tumblecal may be another version: :meth:`Row.received`). The parent publishes
    the file (:func:`finish`) as it records the row, so an interrupted batch leaves no
    calibration without a row. Never raises for the unit's own errors: they are its row's status
    and message. ``epoch``: the caller's ``SOURCE_DATE_EPOCH`` ("" when unset), which a Dask
    worker's own environment does not hold."""

    reset = calfile.CALLER_EPOCH.set(epoch)
    try:
        return vars(_run_unit(unit, options, out_dir, log, token))
    finally:
        calfile.CALLER_EPOCH.reset(reset)


def _run_unit(unit: BatchUnit, options: SolveOptions, out_dir: str, log: bool, token: str) -> Row:

    staging = os.path.join(out_dir, f".{unit.serial}.{token}{STAGING}")
    row = Row(unit.serial, list(unit.found or unit.inputs))
    names = {_file(a): _file(f) for a, f in zip(unit.inputs, unit.found, strict=True)} if unit.found else {}
    if unit.problem is not None:
        return _failed(row, InputError(unit.problem))
    if log and len(unit.inputs) != 1:
        return _failed(row, InputError(f"--log takes one log per unit; {unit.serial} has {len(unit.inputs)} files"))
    try:
        mine = replace(options, unit=replace(options.unit, serial=unit.serial))
        solved = solve.calibrate(mine, log=unit.inputs[0]) if log else solve.calibrate(mine, poses=list(unit.inputs))
        if solved.error is not None:
            raise solved.error
        assert solved.calibration is not None
        solved.calibration = as_found(solved.calibration, names)
        solved.calibration.save(staging)
    except TumblecalError as err:
        if err.file == staging:  # its calibration could not be written (a full disk): not done
            return replace(_failed(row, err), unwritten=True)
        return _as_found_text(_failed(row, err), names)
    except Exception as err:  # a bug: this unit's error, with what to report
        return _failed(row, InputError(f"internal error: {type(err).__name__}: {err}"))
    cal, status = solved.calibration, solved.status
    failures = cal.verdict.failures if cal.verdict is not None else ()
    # why a unit failed its limits, as its row's message (the file holds the whole verdict)
    messages = [f"{f.code}: {f.message}" for f in failures]
    unc = cal.uncertainty
    return replace(
        row,
        status=status,
        verdict=VERDICTS[status],
        codes=list(dict.fromkeys(f.code for f in failures)),
        staging=staging,
        poses=pose_files(cal.poses),  # not a summary column: for duplicate_of
        message="; ".join(messages) if messages else None,
        method=cal.method,
        created=cal.created,
        offset=_triple(cal.offset),
        gain=_triple(cal.gain),
        offset_se=_triple(unc.get("offset")),
        gain_se=_triple(unc.get("gain")),
    )


def _triple(values: FloatArray | None) -> Triple:
    """A calibration's (3,) parameter for its row (None: not solved)."""
    if values is None:
        return NONE3
    x, y, z = (float(v) for v in values)
    return x, y, z


def _file(item: str) -> str:
    """The file of a pose item, ``FILE`` or ``LABEL=FILE``."""
    label, sep, rest = item.partition("=")
    return rest if sep and label and _looks_like_label(label) else item


def as_found(cal: Calibration, names: Mapping[str, str]) -> Calibration:
    """``cal`` with the pose files (and a log's name) it records as ``names`` maps them: a
    cluster's worker reads absolute paths, and records the files as a batch run here would."""
    if not names:
        return cal

    poses = tuple(replace(p, file=names.get(str(p.file), p.file)) for p in cal.poses)
    segmentation = cal.segmentation
    if segmentation is not None and segmentation.log in names:
        segmentation = replace(segmentation, log=names[str(segmentation.log)])
    return replace(cal, poses=poses, segmentation=segmentation)


def _as_found_text(row: Row, names: Mapping[str, str]) -> Row:
    """A failed row's messages naming the files as found (the longest path first: no path is
    replaced inside a longer one)."""
    message, messages = row.message, row.messages
    for path in sorted(names, key=len, reverse=True):
        message = None if message is None else message.replace(path, names[path])
        messages = None if messages is None else [m.replace(path, names[path]) for m in messages]
    row.message, row.messages = message, messages
    return row


def mark_duplicates(rows: list[Row], out_dir: str) -> list[str]:
    """Set each row's ``duplicate_of``: the other serials whose calibration records a pose file
    with the same sha256 (a copy of one unit's capture given as another's); a warning for each
    such file, naming the serials and the file. A row from an earlier run (``--resume``) has its
    poses read back from its calibration file."""

    records = []
    for row in rows:
        if row.poses is None and row.file:
            row.poses = _recorded_poses(os.path.join(out_dir, row.file))
        records += [(row.serial, sha, file) for sha, file in row.poses or []]
    found = lot.duplicates(records)
    others = lot.duplicate_of(found)
    for row in rows:
        row.duplicate_of = others.get(row.serial) or None
    return lot.duplicate_warnings(found)


def _recorded_poses(path: str) -> list[tuple[str, str]]:
    """The (sha256, file) of the poses a published calibration records; none if it is unreadable."""

    try:
        return pose_files(calfile.load(path).poses)
    except TumblecalError:
        return []


@contextlib.contextmanager
def held_signals() -> Iterator[None]:
    """Hold Ctrl-C, SIGTERM and SIGHUP until the block is done, then act on the first as it would have
    acted: a stop between publishing a calibration and recording its row would leave a
    calibration that no row names. A block that raises ends the batch anyway: its error is the
    one told. (Outside the main thread signals are left alone.)"""

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[tuple[int, FrameType | None]] = []
    previous: dict[signal.Signals, Handler] = {}

    def hold(number: int, frame: FrameType | None) -> None:
        caught.append((number, frame))

    try:
        for signum in STOPS:
            handler = signal.getsignal(signum)
            if handler is not None:  # None: set outside Python, and it could not be put back
                previous[signum] = handler  # before the swap: a stop in between still puts it back
                signal.signal(signum, hold)
        yield
    finally:
        _put_back(list(previous.items()))
    for number, frame in caught[:1]:
        handler = previous[signal.Signals(number)]
        if callable(handler):
            handler(number, frame)
        elif handler == signal.SIG_DFL:
            signal.raise_signal(number)


def _put_back(handlers: list[tuple[signal.Signals, Handler]]) -> None:
    """Each signal's handler put back, the later ones even if a stop lands after the first."""

    if handlers:
        try:
            signal.signal(*handlers[0])
        finally:
            _put_back(handlers[1:])


#: Keeps each calibration a batch publishes elsewhere as well (``--record``): given the staged
#: file and the unit's status, a block around its publishing, to which the published file is
#: added; an error in it (the record refused) leaves the unit unpublished.
Keeper = Callable[[str, int], AbstractContextManager[list[str]]]


def finish(row: Row, out_dir: str, keep: Keeper | None = None) -> Row:
    """Publish a row's staged calibration under its name (with ``keep``: inside its block); the
    row with ``file`` set."""
    staging, row.staging = row.staging, None
    if staging is not None:
        try:
            with contextlib.nullcontext([]) if keep is None else keep(staging, row.status) as published:
                row.file = publish(staging, out_dir, row.serial, row.created or "")
                published.append(os.path.join(out_dir, row.file))
        finally:
            with contextlib.suppress(OSError):
                os.unlink(staging)
    return row


def failed_row(unit: BatchUnit, err: BaseException) -> Row:
    """The row of a unit whose worker failed (a Dask worker lost, tumblecal missing there)."""
    message = f"the worker running it failed: {type(err).__name__}: {err}"
    return _failed(Row(unit.serial, list(unit.found or unit.inputs)), InputError(message))


def stale_staging(out_dir: str) -> list[str]:
    """Remove the staging files a killed batch left in ``out_dir`` (``.SERIAL.PID-NS.partial.json``
    of a process that is gone; never another name); a note when there were any."""

    removed = len(remove_stale(out_dir, re.compile(rf"\..+\.(\d+)-\d+{re.escape(STAGING)}")))
    return [f"removed {removed} staging file(s) a killed batch left in {out_dir}"] if removed else []


def clean_staging(out_dir: str, token: str) -> None:
    """Remove this batch's staging files that no row published (an interrupted batch)."""
    with contextlib.suppress(OSError):
        for name in os.listdir(out_dir):
            if name.startswith(".") and name.endswith(f".{token}{STAGING}"):
                with contextlib.suppress(OSError):
                    os.unlink(os.path.join(out_dir, name))


def _failed(row: Row, err: TumblecalError) -> Row:
    """``row`` as its unit's error makes it."""
    row.status = err.exit_code
    row.verdict = VERDICTS.get(err.exit_code, "error")
    row.codes = list(dict.fromkeys(err.codes))  # each once, in the order found
    row.message = "; ".join([str(err), *err.more])
    row.messages = [str(err), *err.more]  # for people, one per line (not a summary column)
    return row


def publish(staging: str, out_dir: str, serial: str, created: str) -> str:
    """Give a finished calibration its name, ``<serial>_<UTC>.json``, never replacing a file
    (``_2``, ``_3`` ... when that name is taken); the name."""
    stamp = created.replace("-", "").replace(":", "") or "undated"
    for k in range(1, 10_000):
        name = f"{serial}_{stamp}{'' if k == 1 else f'_{k}'}.json"
        path = os.path.join(out_dir, name)
        try:
            os.link(staging, path)  # atomic, and fails if the name exists
            return name
        except FileExistsError:
            continue
        except OSError:  # a file system without hard links: reserve the name, then move onto it
            try:
                os.close(os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666))
            except FileExistsError:
                continue
            os.replace(staging, path)
            return name
    raise InputError(f"too many calibrations of {serial} at {created}", file=out_dir)


@dataclass
class Plan:
    """What a batch is about to do: its units, those done already (``--resume``), and notes."""

    units: list[BatchUnit]
    todo: list[BatchUnit]
    notes: list[str]
    summary: str


@dataclass
class Batched:
    """A batch's outcome: its exit status, the summary's rows, and the count of each verdict."""

    status: int
    rows: list[Row]
    counts: dict[str, int]
    summary: str
    warnings: list[str] = field(default_factory=list)  # the same pose file under two serials

    def table(self) -> DataFrame:
        """summary.csv as a pandas DataFrame (its text as the units gave it: a serial ``=1+1``,
        not the ``'=1+1`` that keeps a spreadsheet from taking it for a formula)."""
        with open(self.summary, encoding="utf-8", newline="") as f:
            return written_table(f.read())


class BatchKeywords(TypedDict, total=False):
    """How a batch runs: each unit a ``log`` (else pose files), ``jobs`` processes at a time or
    on the Dask cluster at ``scheduler``, ``resume`` an earlier run; ``on_start`` sees the plan,
    ``on_unit`` each unit's row, ``keep`` each calibration as it is published (``Keeper``)."""

    log: bool
    jobs: int
    resume: bool
    scheduler: str | None
    on_start: Callable[[Plan], None] | None
    on_unit: Callable[[Row], None] | None
    keep: Keeper | None


def run_batch(
    source: str,
    out_dir: str,
    options: SolveOptions | Mapping[str, object] | None = None,  # SolveOptions.of checks the names
    **how: Unpack[BatchKeywords],
) -> Batched:
    """Calibrate every unit of ``source`` (a folder of units or a manifest CSV) as solve would
    with ``options``: each unit's calibration into ``out_dir`` as ``<serial>_<UTC time>.json``
    and its row into ``out_dir/summary.csv``. ``on_start`` sees the plan before any unit,
    ``on_unit`` each unit's row as it is recorded."""
    keywords_known(how, BatchKeywords, "run_batch")
    log, jobs, resume = how.get("log", False), how.get("jobs", 1), how.get("resume", False)
    scheduler, on_start, on_unit = how.get("scheduler"), how.get("on_start"), how.get("on_unit")

    source = path_of(source, "run_batch takes a folder of units or a manifest file")
    out_dir = path_of(out_dir, "run_batch writes into a folder (out_dir)")
    if options is not None and not isinstance(options, SolveOptions | Mapping):
        raise InputError(f"run_batch's options are a SolveOptions or a mapping, not a {type(options).__name__}")
    options = checked(options if isinstance(options, SolveOptions) else SolveOptions.of(options or {}))
    if out_dir == "-":
        raise InputError("--out-dir takes a folder: the calibrations are files, not a stream on stdout")
    settings(options, log=log)  # a bad option: one error, not one per unit
    o = options  # ... as a bad --location, --gravity or --date (a log's stream units are known when it is read)
    places.local_reference(places.Asked(o.read.sensor, o.units, None, o.location, o.gravity, o.date, o.reference))
    calfile.created()  # so is a bad SOURCE_DATE_EPOCH
    units, notes = find_units(source, log=log, out_dir=out_dir)
    if scheduler is not None:  # the workers do not share this working folder
        units = [BatchUnit(u.serial, tuple(absolute(i) for i in u.inputs), u.problem, u.inputs) for u in units]
        out_dir = os.path.abspath(out_dir)
        if options.limits.file:
            options = replace(options, limits=replace(options.limits, file=os.path.abspath(options.limits.file)))
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise InputError("is a file, not a folder: --out-dir takes a folder", file=out_dir)
    summary_path = os.path.join(out_dir, SUMMARY)
    rows: list[Row] = []
    if os.path.exists(summary_path):
        if not resume:
            raise InputError(
                "a batch summary is already here",
                file=summary_path,
                hint="--resume continues it; or use another --out-dir",
            )
        rows, repaired = read_summary(summary_path)
        notes += repaired
    notes += stale_staging(out_dir)
    done = {r.serial for r in rows}
    todo = [u for u in units if u.serial not in done]
    if on_start is not None:
        on_start(Plan(units, todo, notes, summary_path))
    run = engine(jobs, scheduler)  # connects to a cluster: before writing anything
    os.makedirs(out_dir, exist_ok=True)
    token = f"{os.getpid()}-{time.time_ns()}"  # names this batch's staging files
    summary = SummaryFile(out_dir, rows)
    try:
        epoch = os.environ.get("SOURCE_DATE_EPOCH", "")  # the caller's, wherever the units run
        work = [(u, options, out_dir, log, token, epoch) for u in todo]
        for (unit, *_), outcome in run(run_unit, work):
            with held_signals():  # a calibration is published with its row, or not at all
                if isinstance(outcome, BaseException):
                    row = failed_row(unit, outcome)
                else:
                    row = finish(Row.received(outcome), out_dir, how.get("keep"))
                if row.unwritten:  # the disk refused: stop here, and leave the unit to --resume
                    raise InputError(
                        f"{row.serial}: {row.message}; {len(summary.rows) - len(done)} of {len(todo)} units done",
                        hint="free some space, then run the same command with --resume: the units done are kept",
                    )
                summary.add(row)
            if on_unit is not None:
                on_unit(row)
    except BrokenProcessPool:
        raise InputError(
            f"a worker process died (killed, or out of memory) after {len(summary.rows) - len(done)} of "
            f"{len(todo)} units",
            hint="the summary keeps the units done: run the same command with --resume",
        ) from None
    finally:
        warnings = mark_duplicates(summary.rows, out_dir)  # before the summary is written whole
        summary.close()
        clean_staging(out_dir, token)
    counts = {v: sum(r.verdict == v for r in summary.rows) for v in VERDICTS.values()}
    return Batched(status(summary.rows), summary.rows, counts, summary_path, warnings)
