"""apply: captures corrected with one or more calibrations, streamed file to file.

Everything but the sensor columns is copied as it was (``io.rewrite.writer.correct_stream``); the
sensor columns become ``M (raw - offset)`` (``core.model.apply``).
"""

from __future__ import annotations

import contextlib
import csv
import glob
import io
import mmap
import os
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from functools import partial
from typing import IO, TYPE_CHECKING, Unpack

import numpy as np
import pyarrow as pa
import pyarrow.csv as pcsv

from tumblecal_cli.core import current_fit, drift, model
from tumblecal_cli.errors import InputError, TumblecalError
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.io.calfiles.calfile import Calibration
from tumblecal_cli.io.csv import capture, sniff
from tumblecal_cli.io.csv.compressed import writing
from tumblecal_cli.io.outputs import atomic_output, check_not_input, check_writable
from tumblecal_cli.io.readspec import FileKeywords, file_spec
from tumblecal_cli.io.rewrite import writer as rewrite
from tumblecal_cli.pipeline.batch.cluster import engine
from tumblecal_cli.pipeline.frames import is_data
from tumblecal_cli.pipeline.options import in_axes, keywords_known, path_of

if TYPE_CHECKING:
    from tumblecal_cli.core.arrays import FloatArray
    from tumblecal_cli.io.calfiles.calfile import Calibration
    from tumblecal_cli.io.csv.capture import Capture
    from tumblecal_cli.io.csv.sniff import Layout
    from tumblecal_cli.io.csv.splice import Correct
    from tumblecal_cli.io.readspec import ReadSpec
    from tumblecal_cli.pipeline.frames import DataFrame


@dataclass
class Applied:
    """One capture corrected: its name, the rows written, the columns corrected, and notes."""

    capture: str
    rows: int
    columns: list[str]
    output: str  # "" when none was written (data in memory: its corrected copy is ``data``)
    notes: list[str] = field(default_factory=list)
    data: DataFrame = None  # the corrected DataFrame or array, for data in memory


class CorrectKeywords(FileKeywords, total=False):
    """correct's options beside the capture's shape (docs/commands/apply.md)."""

    output: str | os.PathLike[str]
    force: bool
    exclusive: bool
    on_note: Callable[[str], None] | None
    axes: str | None  # the body's axes in the sensor's (--axes): a calibration without its own corrects into them


def correct(
    capture: str | os.PathLike[str] | DataFrame,
    cal: Calibration | str | os.PathLike[str] | Sequence[Calibration | str | os.PathLike[str]],
    **options: Unpack[CorrectKeywords],
) -> Applied:
    """Correct one capture ('-': stdin) into ``output`` ('-': stdout), as ``tumblecal apply``:
    ``cal`` is one calibration (a file, or a Calibration) or several (one per sensor of the
    capture). ``on_note`` hears each note as it is found, before the capture is streamed.
    ``exclusive``: an ``output`` that exists, or appears while the capture is corrected, is an
    error and is left as it is (``--out-dir`` never replaces a file). ``capture`` may be data in
    memory, a DataFrame or an (n, 3) array: ``Applied.data`` is it corrected (written as a CSV to
    ``output`` only when one is named)."""

    keywords_known(options, CorrectKeywords, "correct")
    output, force, on_note = options.get("output", "-"), options.get("force", False), options.get("on_note")
    if is_data(capture):
        return _correct_data(capture, cal, options)
    capture = path_of(capture, "correct takes a capture: a file, a DataFrame or an (n, 3) array")
    paths = _calibrations(cal)
    if "-" in paths and capture == "-":
        raise InputError("--cal - and the capture cannot both be read from stdin", hint="give the capture as a file")
    if paths.count("-") > 1:
        raise InputError("only one --cal can be read from stdin ('-')")
    output = os.fspath(output)
    check_not_input(output, [capture, *(p for p in paths if isinstance(p, str))])
    check_writable(output)
    cals = [in_axes(calfile.resolve(path), options.get("axes")) for path in paths]
    claims_once(cals)
    notes: list[str] = []

    def note(text: str) -> None:  # said as soon as it is known: a long file takes a while
        notes.append(text)
        if on_note is not None:
            on_note(text)

    trusted(cals, force, note)
    spec = file_spec(options)
    picked = spec.columns
    if picked and len(cals) > 1:
        raise InputError("--columns names the columns of one calibration; with several --cal each uses its own")
    c = cals[0]
    with capture_for(c, capture, spec) as cap:
        for text in cap.layout.notes:
            note(text)
        used = cap.layout.sensor_names
        differ = [u.lower() for u in used] != [x.lower() for x in c.columns]
        if differ and (picked or not cap.layout.has_header):  # the user named them, or nothing is named
            note(
                f"{cap.layout.name}: correcting columns {', '.join(used)} "
                f"(the calibration was made from {', '.join(c.columns)})"
            )
        elif differ:
            raise InputError(
                f"the capture's {c.sensor} columns are {', '.join(used)}, "
                f"but {c.path} calibrates {c.sensor} columns {', '.join(c.columns)}",
                file=cap.layout.name,
                hint=f"if they are the same sensor, name them: --columns {','.join(used)}",
            )
        taken = set(cap.layout.sensor)
        more = [(columns_of(cap.layout, other, taken), other) for other in cals[1:]]
        time = cap.layout.time
        for triplet, by in [(cap.layout.sensor, c), *((t, o) for t, o in more)]:
            if time is not None and time in triplet:  # a calibration that would rewrite the clock
                raise InputError(
                    f"{by.path} calibrates column {cap.layout.names[time]}, the capture's time column",
                    file=cap.layout.name,
                    hint="a calibration corrects three sensor columns: check its 'columns' field",
                )
        said = len(cap.layout.notes)
        with atomic_output(output, exclusive=options.get("exclusive", False)) as out, writing(output, out) as sink:
            rows = _stream(cap, sink, c, more, note)  # compressed when the output's name ends .gz, .bz2 ...
        for text in cap.layout.notes[said:]:  # found while reading (a cut last line dropped)
            note(text)
        used = [n for t in [cap.layout.sensor, *(t for t, _ in more)] for n in (cap.layout.names[i] for i in t)]
    return Applied(cap.layout.name, rows, used, output, notes)


def trusted(cals: list[Calibration], force: bool, note: Callable[[str], None]) -> None:
    """A calibration whose unit failed its limits is refused, unless ``force`` (then a note)."""
    for c in cals:
        if c.failed and not force:
            calfile.refuse_failed(c, "correct with it", "apply")
        if c.failed:
            note(f"{c.path}: this unit failed its limits; correcting with it as --force asks")


def _correct_data(data: DataFrame, cal: object, options: CorrectKeywords) -> Applied:
    """correct on data in memory: its corrected copy in ``Applied.data`` (a DataFrame's other
    columns, index and dtypes untouched: Calibration.apply, each calibration its own columns),
    written as a CSV to ``output`` too when one is named (atomically; compressed by its name)."""
    cals = [in_axes(calfile.resolve(path), options.get("axes")) for path in _calibrations(cal)]
    claims_once(cals)
    notes: list[str] = []
    on_note = options.get("on_note")

    def note(text: str) -> None:
        notes.append(text)
        if on_note is not None:
            on_note(text)

    trusted(cals, options.get("force", False), note)
    array = isinstance(data, np.ndarray)
    if array and len(cals) > 1:
        raise InputError("an array holds one sensor's readings: correct it with one calibration")
    fixed = data
    for c in cals:
        fixed = c.apply(fixed)
    output = os.fspath(options.get("output", "-"))
    if output != "-":  # (for data in memory '-' is no file: the corrected data is returned)
        check_writable(output)
        table = pa.table({n: fixed[:, j] for j, n in enumerate("xyz")}) if array else pa.Table.from_pandas(fixed)
        header = io.StringIO()
        csv.writer(header, lineterminator="\n").writerow(table.column_names)  # (pyarrow would quote every name)
        with atomic_output(output, exclusive=options.get("exclusive", False)) as out, writing(output, out) as sink:
            sink.write(header.getvalue().encode())
            pcsv.write_csv(table, sink, pcsv.WriteOptions(include_header=False))
    name = "<array>" if array else "<DataFrame>"
    written = "" if output == "-" else output
    return Applied(name, len(fixed), [n for c in cals for n in c.columns], written, notes, data=fixed)


def expand(patterns: list[str]) -> list[str]:
    """The captures named: each a file, '-', or a glob pattern (``'logs/*.csv'``, ``**`` too) that
    is expanded here, so a pattern also works quoted or on a remote cluster's shared storage."""
    out: list[str] = []
    for pattern in patterns:
        if pattern == "-" or os.path.exists(pattern) or not glob.has_magic(pattern):
            out.append(pattern)
            continue
        found = sorted(glob.glob(pattern, recursive=True))
        if not found:
            raise InputError(f"no file matches {pattern}")
        out += found
    return out


def _calibrations(cal: object) -> list[Calibration | str]:
    """``cal`` as a list of Calibrations and paths (one, or one per sensor)."""

    one = isinstance(cal, str | os.PathLike | Calibration)
    given: list[object] = [cal] if one else list(cal) if isinstance(cal, Sequence) else []
    out: list[Calibration | str] = []
    for c in given:
        if not isinstance(c, str | os.PathLike | Calibration):
            break
        out.append(c if isinstance(c, Calibration) else os.fspath(c))
    if not given or len(out) != len(given):
        raise InputError(f"correct needs a calibration (a file, or a Calibration), not {cal!r:.60}")
    return out


class ManyKeywords(FileKeywords, total=False):
    """correct_many's options beside the captures' shape."""

    force: bool
    axes: str | None


def correct_many(
    inputs: Sequence[str],
    cal: Sequence[str],
    out_dir: str,
    *,
    scheduler: str | None = None,
    **options: Unpack[ManyKeywords],
) -> Iterator[tuple[str, int, str]]:
    """Correct each capture into ``out_dir`` under its own name, here or on a Dask cluster
    (``scheduler``): (capture, exit status, message) for each as it is done. A capture that
    fails is its own status and message; the others go on."""

    keywords_known(options, ManyKeywords, "correct_many")
    if "-" in inputs:
        raise InputError("stdin ('-') is one capture: with --out-dir give the captures as files")
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise InputError("is a file, not a folder: --out-dir takes a folder", file=out_dir)
    inputs = list(dict.fromkeys(inputs))  # a file named twice is corrected once
    outputs = [os.path.join(out_dir, os.path.basename(c)) for c in inputs]
    names: dict[str, str] = {}
    for c, o in zip(inputs, outputs, strict=True):
        if o in names:
            raise InputError(
                f"{names[o]} and {c} would both be written to {o}", hint="correct them into separate folders"
            )
        names[o] = c
        if os.path.exists(o):  # an input, or a file of someone else's: never replaced
            raise InputError(
                "already exists: --out-dir never replaces a file", file=o, hint="correct into a new or empty folder"
            )
    for path in cal:  # a bad calibration is one error, before any capture
        if path == "-":
            raise InputError("--cal - is read once: with several captures give the calibration as a file")
        calfile.load(path)
    # never replaced: a file that appears after the check above (another run correcting a capture
    # of the same name into this folder) is this capture's error, checked as it is published
    each: dict[str, object] = {"cal": list(cal), **options, "exclusive": True}
    if scheduler is not None:  # the workers do not share this working folder
        inputs, outputs = [os.path.abspath(c) for c in inputs], [os.path.abspath(o) for o in outputs]
        each["cal"] = [os.path.abspath(c) for c in cal]
    run = engine(1, scheduler)
    made = not os.path.isdir(out_dir)
    os.makedirs(out_dir, exist_ok=True)
    try:
        for (_, name, _), outcome in run(correct_one, [(each, c, o) for c, o in zip(inputs, outputs, strict=True)]):
            if isinstance(outcome, BaseException):  # a worker lost on the cluster
                failed = f"{name}: the worker correcting it failed: {type(outcome).__name__}: {outcome}"
                yield str(name), 2, failed
            else:
                yield outcome
    finally:  # a folder made for nothing (every capture failed, or Ctrl-C first) is not left behind
        if made:
            with contextlib.suppress(OSError):  # not empty: it holds what was written
                os.rmdir(out_dir)


def correct_one(options: dict[str, object], capture: str, output: str) -> tuple[str, int, str]:
    """Correct one capture as ``tumblecal apply`` does: (capture, exit status, message)."""
    try:
        correct(capture, output=output, **options)  # type: ignore[arg-type]
    except TumblecalError as err:
        return capture, err.exit_code, "; ".join([str(err), *err.more])
    except Exception as err:  # a bug: this file's error
        return capture, 2, f"internal error: {type(err).__name__}: {err}"
    return capture, 0, ""


def claims_once(cals: list[Calibration]) -> None:
    """Two calibrations for one column is a usage error: which correction would win?"""
    for k, a in enumerate(cals):
        for b in cals[k + 1 :]:
            shared = [n for n in a.columns if n.lower() in {m.lower() for m in b.columns}]
            if shared:
                raise InputError(
                    f"{a.path} and {b.path} both calibrate column{'s' if len(shared) > 1 else ''} {', '.join(shared)}",
                    hint="give one calibration per sensor",
                )


@contextlib.contextmanager
def capture_for(cal: Calibration, path: str, spec: ReadSpec) -> Iterator[Capture]:
    """A capture opened to be corrected by ``cal`` (read by ``spec``'s columns and dialect):
    one without that sensor's columns is an error naming both the capture and the calibration."""

    with contextlib.ExitStack() as stack:
        try:
            spec = replace(spec, sensor=cal.sensor, prefer=tuple(cal.columns))
            cap = stack.enter_context(capture.open_capture(path, spec))
        except InputError as err:
            if not err.message.startswith(f"no {cal.sensor} x,y,z columns found"):
                raise
            raise InputError(
                f"{err.message}, but {cal.path} calibrates {cal.sensor} columns {', '.join(cal.columns)}",
                file=err.file,
                hint="correct a capture of the sensor the calibration was made for, or name its columns with --columns",
            ) from None
        yield cap


def columns_of(layout: Layout, cal: Calibration, taken: set[int]) -> tuple[int, int, int]:
    """Where a second calibration's recorded columns are in the capture (by name only)."""

    lower = [n.lower() for n in layout.names]
    missing = [n for n in cal.columns if n.lower() not in lower]
    if missing:
        raise InputError(
            f"the capture has no column{'s' if len(missing) > 1 else ''} {', '.join(missing)}, "
            f"which {cal.path} calibrates",
            file=layout.name,
            hint="with several --cal, each calibration's recorded columns must be in the capture's header",
        )
    triplet = sniff.sensor_columns(layout, cal.sensor, cal.columns)
    if taken & set(triplet):
        raise InputError(f"{cal.path} calibrates columns another --cal already corrects", file=layout.name)
    taken.update(triplet)
    return triplet


def _correct(cal: Calibration, raw: FloatArray) -> FloatArray:

    return model.apply(raw, cal.offset, cal.matrix)


# -- temperature: each row corrected at its own temperature (core.drift.correct) -------------


def _stream(
    cap: Capture,
    out: IO[bytes],
    cal: Calibration,
    more: list[tuple[tuple[int, int, int], Calibration]],
    note: Callable[[str], None],
) -> int:
    """Stream ``cap`` corrected into ``out``: each calibration's columns by its own correction,
    at each row's temperature where it has a thermal block (one warning for the rows clamped)."""

    cals = [cal, *(o for _, o in more)]
    temperature = thermal_column(cap.layout, cals)
    clamped: list[int] = []  # rows outside a thermal block's range, per block of rows
    fixes: list[Correct] = []
    for x in cals:
        if x.thermal is not None:
            fixes.append(partial(_thermal, x, clamped))
        elif x.current is not None:
            fixes.append(partial(_at_current, x))
        elif temperature is not None:
            fixes.append(partial(_ignore_temperature, partial(_correct, x)))
        else:
            fixes.append(partial(_correct, x))
    watches = [Magnitudes(x.reference) if x.sensor in WATCHED and x.reference > 0 else None for x in cals]
    fixes = [f if w is None else w.watching(f) for f, w in zip(fixes, watches, strict=True)]
    pairs = [(t, f) for (t, _), f in zip(more, fixes[1:], strict=True)]
    rows = rewrite.correct_stream(cap, out, fixes[0], more=pairs, temperature=temperature)
    if sum(clamped):
        note(_clamped_warning(cap.layout, [x for x in cals if x.thermal is not None], sum(clamped)))
    for x, w in zip(cals, watches, strict=True):
        said = None if w is None else w.changed(cap.layout.name, x)
        if said is not None:
            note(said)
    return rows


#: The sensors whose corrected magnitude is the reference in any orientation: apply watches it.
WATCHED = ("accelerometer", "magnetometer")
#: A capture whose median corrected magnitude is further than this from the reference is said.
CHANGED = 0.10


class Magnitudes:
    """The median |corrected| / reference of a capture as it is corrected: a histogram of the
    ratio (log-spaced bins of 0.5 %, 1e-3 to 1e3), in memory shared with apply's forked workers
    (an anonymous shared mapping made before they fork), one row per process so that no two add
    into one row at once. Bounded memory whatever the capture's length."""

    BINS = 2764  # ln(1e6) / ln(1.005)
    ROWS = 64

    def __init__(self, reference: float) -> None:
        self.reference = reference
        self._map = mmap.mmap(-1, self.ROWS * self.BINS * 8)
        self.counts = np.frombuffer(self._map, dtype=np.int64).reshape(self.ROWS, self.BINS)

    def watching(self, fn: Correct) -> Correct:
        def watched(*args: FloatArray) -> FloatArray:
            fixed = fn(*args)
            self.add(fixed)
            return fixed

        return watched

    def add(self, fixed: FloatArray) -> None:
        with np.errstate(invalid="ignore", divide="ignore"):  # empty rows (NaN), a zero reading
            ratio = np.log(np.sqrt(np.einsum("ij,ij->i", fixed, fixed)) / self.reference)
        at = np.floor((ratio - np.log(1e-3)) / np.log(1.005))
        at = at[np.isfinite(at)].astype(np.int64).clip(0, self.BINS - 1)
        self.counts[os.getpid() % self.ROWS] += np.bincount(at, minlength=self.BINS)

    def median(self) -> float | None:
        """The median ratio (to the bin's centre, 0.25 %), None when no row was corrected."""
        total = self.counts.sum(axis=0)
        n = int(total.sum())
        if n == 0:
            return None
        k = int(np.searchsorted(np.cumsum(total), (n + 1) / 2))
        return float(1e-3 * 1.005 ** (k + 0.5))

    def changed(self, name: str, cal: Calibration) -> str | None:
        """A warning when the median is further than CHANGED from 1: a magnetometer's field or hard
        iron, or an accelerometer (its units, its unit), is not what the calibration was made for
        (a corrected median |B| of 458 µT against a 46 µT reference was written with exit 0)."""
        ratio = self.median()
        if ratio is None or abs(ratio - 1.0) <= CHANGED:
            return None
        units = f" {cal.units}" if cal.units else ""
        what = (
            "the field or the hard iron changed"
            if cal.sensor == "magnetometer"
            else "the sensor, its mounting or its units are not the calibration's"
        )
        return (
            f"warning: {name}: the corrected {cal.sensor} reads {ratio * cal.reference:.4g}{units} in median "
            f"magnitude, {ratio - 1:+.0%} from the calibration's {cal.reference:g}{units}: {what}: recalibrate"
        )


def thermal_column(layout: Layout, cals: Sequence[Calibration]) -> int | None:
    """The capture's temperature column for the calibrations with a ``thermal`` block (or its
    current column for those with a ``current`` block; None when none has either); a capture
    without it is an error naming the column."""
    names = {x.thermal.column for x in cals if x.thermal is not None}
    amperes = {x.current.column for x in cals if x.current is not None}
    if names and amperes:
        raise InputError(
            "one calibration corrects at each row's temperature, another at its current: apply reads one such column",
            file=layout.name,
            hint="correct the capture with each of them in its own run",
        )
    if amperes:
        layout.per_row_column, layout.per_row = _per_row_column(layout, amperes, "current"), "current"
    elif names:
        layout.per_row_column = _per_row_column(layout, names, "temperature")
    else:
        return None
    return layout.per_row_column


def _per_row_column(layout: Layout, names: set[str], what: str) -> int:
    """The index of the one ``what`` column (temperature, current: docs/current.md) the
    calibrations correct each row by, read where apply reads a temperature; an error naming it
    when they name more than one, or the capture has none."""
    if len(names) > 1:
        raise InputError(
            f"the calibrations read their {what}s from different columns: {', '.join(sorted(names))}",
            file=layout.name,
        )
    (name,) = names
    lower = [n.lower() for n in layout.names]
    if name.lower() not in lower:
        block = "thermal" if what == "temperature" else what
        raise InputError(
            f"the capture has no {what} column {name!r}, which the calibration's {block} block corrects with",
            file=layout.name,
            hint=f"columns: {', '.join(layout.names)}",
        )
    return lower.index(name.lower())


def _at_current(cal: Calibration, raw: FloatArray, amperes: FloatArray) -> FloatArray:

    assert cal.current is not None
    return current_fit.correct(raw, amperes, cal.offset, cal.matrix, cal.current.per_amp)


def _thermal(cal: Calibration, clamped: list[int], raw: FloatArray, temperature: FloatArray) -> FloatArray:

    assert cal.thermal is not None
    fixed, outside = drift.correct(raw, temperature, cal.offset, cal.matrix, cal.thermal.drift())
    clamped.append(outside)  # list.append is atomic: the blocks are converted in threads
    return fixed


def _ignore_temperature(
    fix: Callable[[FloatArray], FloatArray], raw: FloatArray, temperature: FloatArray
) -> FloatArray:
    return fix(raw)


def _clamped_warning(layout: Layout, cals: Sequence[Calibration], count: int) -> str:
    spans = sorted({(x.thermal.range[0], x.thermal.range[1]) for x in cals if x.thermal is not None})
    ranges = ", ".join(f"{low:g} to {high:g} °C" for low, high in spans)
    return (
        f"warning: {layout.name}: {count} row{'s' if count != 1 else ''} outside the calibrated temperature range "
        f"{ranges}, corrected at its nearest end (clamped, not extrapolated)"
    )
