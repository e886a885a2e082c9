"""What people read, on stderr (and the data commands print on stdout): tables with Rich,
without colour when stderr is not a terminal or NO_COLOR is set."""

from __future__ import annotations

import contextlib
import json
import os
import re
import sys
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, NamedTuple, TypedDict

from tumblecal_cli.core.quantities import DIP_SAID
from tumblecal_cli.errors import PipeClosed, TumblecalError, one_line

if TYPE_CHECKING:
    from rich.console import Console
    from rich.table import Table

    from tumblecal_cli.core.arrays import FloatArray
    from tumblecal_cli.core.blocks import Block, Segmentation
    from tumblecal_cli.core.gate import Finding
    from tumblecal_cli.core.lot import ParameterRow, Report
    from tumblecal_cli.io.calfiles.calfile import Calibration
    from tumblecal_cli.io.calfiles.calparts import Pose
    from tumblecal_cli.io.csv.readings import Log
    from tumblecal_cli.pipeline.batch.summary import Row
    from tumblecal_cli.pipeline.noise import Noise
    from tumblecal_cli.pipeline.thermal import ThermalResult


class Shown(NamedTuple):
    """How much a command prints for people: nothing but errors (``quiet``), what the user acts
    on (the default), or that and the detail (``verbose``: per pose, per block)."""

    quiet: bool = False
    verbose: bool = False


def make_console(stderr: bool = True) -> Console:
    from rich.console import Console

    class Quiet(Console):
        def on_broken_pipe(self) -> None:  # Rich's own exits 1; a closed reader is exit 141 here (main)
            raise PipeClosed("output closed")

    console = Quiet(stderr=stderr, highlight=False, markup=False)  # paths and column names are not markup
    if not console.is_terminal and "COLUMNS" not in os.environ:  # a file or a pipe: no screen to fit, so no
        console.width = WIDE  # number cut short to "6.6e…" (a table is only as wide as its cells)
    return console


#: The width tables are laid out for when they go to a file or a pipe (COLUMNS wins).
WIDE = 1000


#: Whether this run has printed its --json document: the error boundary (cli.app.main) then
#: prints no error object after it (stdout holds one JSON document).
_printed = {"json": False}


def print_json(doc: Mapping[str, object]) -> None:
    _printed["json"] = True
    print_text(json.dumps(doc, indent=2, ensure_ascii=False) + "\n")


def json_printed(reset: bool = False) -> bool:
    """Whether print_json has run since the last reset (``reset``: start afresh, for a new run)."""
    printed = _printed["json"]
    if reset:
        _printed["json"] = False
    return printed


def status_word(status: int) -> str:
    """An exit status as --json says it: pass, fail, error or rejected."""
    from tumblecal_cli.cli.flags import STATUS_WORDS

    return STATUS_WORDS[status]


def error_json(status: int, error: Mapping[str, object]) -> None:
    """With --json, an error that ended the command (exit 2, or 3 with no summary) on stdout."""
    from tumblecal_cli.cli.flags import STATUS_WORDS

    print_json({"status": STATUS_WORDS.get(status, "error"), "exit_status": status, "error": error})


def print_csv(table: tuple[list[str], list[list[str]]]) -> None:
    """A header and rows as CSV on stdout (a cell with a comma quoted)."""
    import csv
    import io

    from tumblecal_cli.io.outputs import atomic_output, spreadsheet_safe

    header, rows = table
    text = io.StringIO()
    csv.writer(text, lineterminator="\n").writerows([header, *([spreadsheet_safe(c) for c in r] for r in rows)])
    with atomic_output("-") as out:
        out.write(text.getvalue().encode())


def alignment_line(record: Mapping[str, object]) -> str:
    """A calibration's ``alignment`` field (tumblecal align --aligned-mag) for people."""

    def number(key: str) -> float:
        value = record.get(key)
        return float(value) if isinstance(value, int | float) else float("nan")

    return (
        f"rotated {number('angle_deg'):.3f}° ± {number('angle_sigma_deg'):.3f}° onto the axes of {record.get('to')}; "
        f"dip {number('dip_deg'):.2f}° ± {number('dip_sigma_deg'):.2f}° ({DIP_SAID}); heading error removed up to "
        f"{number('heading_error_deg'):.2f}°"
    )


def note_line(note: str) -> str:
    """A note as printed: ``note: ...``, or a warning as it is (it starts with ``warning:``)."""
    return note if note.startswith("warning: ") else f"note: {note}"


def say(line: str) -> None:
    """One line for people on stderr, as it is: no styling to strip, so no Rich to import (a
    command that prints only such lines, like apply, starts 15 ms sooner)."""
    try:
        sys.stderr.write(line + "\n")
        sys.stderr.flush()
    except BrokenPipeError:
        raise PipeClosed("stderr closed") from None


def print_text(text: str) -> None:
    """Data on stdout; a reader that went away (``| head``) is exit 141, not a traceback."""
    try:
        sys.stdout.write(text)
        sys.stdout.flush()
    except BrokenPipeError:
        raise PipeClosed("stdout closed") from None


def summary(
    cal: Calibration,
    status: int,
    output: str | None,
    rejected: list[Finding],
    warned: list[Finding],
    notes: list[str],
) -> dict[str, object]:
    """The --json summary: the outcome, then the calibration's parameters and diagnostics."""
    from tumblecal_cli.cli.flags import STATUS_WORDS

    doc = cal.to_dict()
    head: dict[str, object] = {
        "status": STATUS_WORDS[status],
        "exit_status": status,
        "file": output,
        "rejections": [f.as_dict() for f in rejected],
        "verdict": None if rejected else doc["verdict"],
        "warnings": [f.as_dict() for f in warned],
        "notes": notes,
    }
    axes = ("axes",) if doc.get("axes") else ()  # --axes: the body's axes in the sensor's
    keys = ("sensor", "method", "reference", "units", "columns", *axes, "offset", "matrix", "gain", "uncertainty")
    placed = [k for k in ("gravity", "earth_field", "dip", "scale_factors") if k in doc]  # places; --spin's factors
    fitted = ("residuals", "coverage", "coverage_gaps", "outliers")  # how well the fit fits (null: not judged)
    return head | {k: doc.get(k) for k in (*keys, *placed, "tilt_sensitivity", *fitted, "poses", "unit")}


def rejected_head(err: TumblecalError) -> dict[str, object]:
    """The head of every summary (see _summary) for a rejection with no parameters to follow it."""
    head = {"status": "rejected", "exit_status": 3, "file": None, "rejections": [error_dict(err)]}
    return head | {"verdict": None, "warnings": [], "notes": []}


def error_dict(err: TumblecalError) -> dict[str, object]:
    return {"code": err.code, "file": err.file, "message": err.message}


def print_summary(
    cal: Calibration, console: Console, warned: list[Finding], notes: list[str], *, judged: bool, verbose: bool = True
) -> None:
    """The calibration for people: per axis offset and gain with their uncertainty and tilt
    sensitivity (``verbose``: per pose its statistics), then warnings, notes and the verdict."""
    tilt = cal.tilt_sensitivity
    print_fitted(console, lambda limit: _axes_table(cal, limit), [one_line(c) for c in cal.columns])
    if cal.axes is not None:
        console.print(f"axes {cal.axes.text}: offsets and gains in the sensor's axes, corrected into the body's")
    if cal.poses and verbose:  # an imported calibration has none
        print_fitted(console, lambda limit: _poses_table(cal, limit), [_pose_name(cal, p) for p in cal.poses])
    if cal.thermal is not None:
        print_drift(cal, console)
    if cal.current is not None:
        console.print(current_line(cal), soft_wrap=True)
    if any(cal.sensor_matrix[i][j] for i in range(3) for j in range(3) if i != j):
        import numpy as np

        from tumblecal_cli.core.gate import cross_term

        a = np.asarray(np.linalg.inv(cal.sensor_matrix), dtype=np.float64)
        terms = ", ".join(
            f"{'xyz'[i]}{'xyz'[j]} {cross_term(a, i, j):+.3%}" for i in range(3) for j in range(3) if i != j
        )
        tell(console, f"cross-axis terms (A = M⁻¹, each over its row's gain): {terms}")
    if cal.coverage is not None:
        tell(console, f"coverage: {cal.coverage:.0%} of the sphere's directions{_gaps(cal)}")
    for line in _place_lines(cal):
        console.print(wrapped(line, console.width, "  "), soft_wrap=True, markup=False)
    if tilt is not None and tilt.tolerance_deg is not None:
        tell(console, f"± tilt: worst-case shift if each pose is {tilt.tolerance_deg:g}° off level")
    if tilt is not None and tilt.gain_tolerance is not None:
        tell(console, _gain_tolerance_line(cal, tilt.gain_tolerance))
    for w in warned:
        tell(console, f"warning: {w.render()} ({w.code})", style="yellow")
    for note in notes:
        tell(console, note_line(note))
    if judged and cal.verdict is not None:
        _print_verdict(console, cal.verdict.passed, cal.verdict.limit_names, cal.verdict.failures)


def _place_lines(cal: Calibration) -> list[str]:
    """Where the reference came from (local gravity, the Earth's field) and the dip check."""
    if not any(k in cal.fields for k in ("gravity", "earth_field", "dip")):
        return []
    from tumblecal_cli.pipeline import places

    return places.lines_of(cal)


def _gaps(cal: Calibration) -> str:
    """The directions coverage misses, farthest first: ", nothing within 57° of +z, 48° of +x+z"."""
    gaps = [g for g in cal.coverage_gaps or () if g.direction is not None and g.nearest_deg is not None]
    if not gaps:
        return ""
    shown = ", ".join(f"{g.nearest_deg:.0f}° of {g.direction}" for g in gaps[:4])
    return f", nothing within {shown}{f' and {len(gaps) - 4} more' if len(gaps) > 4 else ''}"


def _gain_tolerance_line(cal: Calibration, tolerance: float) -> str:
    """A 1-pose up offset's ± tilt holds tolerance × reference for the up axis's unknown gain error."""
    face = (cal.poses[0].face if cal.poses else None) or ""
    axis = f"the {face[1:]} offset (up axis {face})" if len(face) == 2 else "the up axis's offset"
    reference = cal.reference
    return (
        f"± tilt of {axis} includes ±{tolerance * reference:.4g} (--gain-tolerance {tolerance:g} × reference "
        f"{reference:g}) for an unknown gain error of ±{tolerance:.2%}: one pose cannot tell it from an offset"
    )


def _g(v: float | None, digits: int = 6) -> str:
    return "" if v is None else f"{v:.{digits}g}"


def _axes_table(cal: Calibration, limit: int | None = None) -> Table:
    """Per axis: its column, offset and gain, each with its 1-sigma and tilt sensitivity."""
    from rich import box
    from rich.table import Table

    from tumblecal_cli.core import catalog

    se = cal.uncertainty
    tilt = (
        {}
        if cal.tilt_sensitivity is None
        else {"offset": cal.tilt_sensitivity.offset, "gain": cal.tilt_sensitivity.gain}
    )
    fixed = catalog.fixes_gains(cal.method)
    # numbers never wrap or shrink; a long column name is what gives way on a narrow terminal (print_fitted)
    axes = Table(title=f"{one_line(cal.method)} calibration", title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False)
    rows = []
    for i, axis in enumerate("xyz"):
        column = one_line(cal.columns[i])  # a column named with an ESC or a line break: escaped
        cells = [axis, column if limit is None else middle(column, limit)]
        for name, values in (("offset", cal.offset), ("gain", cal.gain)):
            if name == "gain" and fixed:
                cells += [_g(float(values[i])), "fixed", ""]
            else:
                cells += [_g(float(values[i])), _g(_at(se, name, i), 2), _g(_at(tilt, name, i), 2)]
        rows.append(cells)
    headings = ("axis", "column", "offset", "± 1σ", "± tilt", "gain", "± 1σ", "± tilt")
    shown = [j for j, name in enumerate(headings) if j < 2 or any(r[j] for r in rows)]  # no empty column
    for j in shown:
        axes.add_column(headings[j], justify="left" if j < 2 else "right", no_wrap=True)
    for r in rows:
        axes.add_row(*(r[j] for j in shown))
    return axes


def _pose_name(cal: Calibration, p: Pose) -> str:
    """A pose as the poses table names it: its file (``#N``: a log's block), or a row of a table."""
    if _one_row(cal, p):  # one row of a table of orientations (the note names its file)
        return f"row {p.rows[0] + 1}"  # type: ignore[index]
    return one_line(os.path.basename(p.file or "")) + (f" #{p.block}" if p.block is not None else "")


def _one_row(cal: Calibration, p: Pose) -> bool:
    shared = sum(q.file == p.file for q in cal.poses)
    return p.block is None and p.rows is not None and p.rows[0] == p.rows[1] and shared > 1


def _poses_table(cal: Calibration, limit: int | None = None) -> Table:
    """Per pose: its face, file, samples, angle from its face, mean and standard deviation."""
    from rich import box
    from rich.table import Table

    poses = Table(title="poses", title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False)
    for name in ("pose", "file", "n", "angle", "", "x", "y", "z"):
        poses.add_column(name, justify="left" if name in ("pose", "file", "") else "right", no_wrap=True)
    for p in cal.poses:
        name = _pose_name(cal, p)
        row = _one_row(cal, p)  # one line, no std
        poses.add_row(
            p.face or "?",
            name if limit is None else middle(name, limit),
            str(p.samples),
            "" if p.angle_deg is None else f"{p.angle_deg:.1f}°",
            "mean",
            *(_g(float(v)) for v in p.mean),
        )
        if p.std is not None and not row:  # a field of every file tumblecal writes; other writers may leave it out
            poses.add_row("", "", "", "", "std", *(f"{v:.3g}" for v in p.std), end_section=True)
    return poses


def _print_verdict(console: Console, passed: bool, limit_names: Iterable[str], failures: Iterable[Finding]) -> None:
    """The verdict for people: PASS or FAIL with the limits judged by, and each failure."""
    judged_by = ", ".join(k for k in limit_names if k not in ("nominal_gain", "nominal_offset"))
    limits = f"limits: {judged_by}" if judged_by else "no limits judged"
    if passed:
        tell(console, f"verdict: PASS ({limits})", style="bold green")
        return
    tell(console, f"verdict: FAIL ({limits})", style="bold red")
    for f in failures:
        where = f"{f.file}: " if f.file else ""
        tell(console, one_line(f"  {f.code}: {where}{f.message}"), style="red", indent="    ")


def print_whole(console: Console, table: Table) -> None:
    """A table of numbers that never shrinks them: on a terminal too narrow for its numbers, it
    is printed wider (the terminal wraps its lines) rather than cropping digits unmarked."""
    from rich.measure import Measurement

    needed = Measurement.get(console, console.options.update_width(1000), table).minimum  # unclamped
    width = console.width
    console.width = max(width, needed + 2)  # print() clamps its own width= to the console's; + the edges
    try:
        console.print(table)
    finally:
        console.width = width


def wrapped(text: str, width: int, indent: str = "  ") -> str:
    """``text`` wrapped at ``width`` between words, its later lines indented: a note on an
    80-column terminal, one line in a file or a pipe (width WIDE). A word longer than the width
    (a path) stays whole."""
    import textwrap

    if len(text) <= width:
        return text
    return textwrap.fill(
        text, width, subsequent_indent=indent, break_long_words=False, break_on_hyphens=False, drop_whitespace=True
    )


def tell(console: Console, text: str, style: str | None = None, indent: str = "  ") -> None:
    """A line for people (a note, a warning, the verdict), wrapped at the console's width."""
    console.print(wrapped(text, console.width, indent), style=style, soft_wrap=True)


def middle(name: str, width: int) -> str:
    """``name`` in at most ``width`` characters, shortened in the middle (``xsens…#1``): its
    start says what it is, its end which one (a block's number, a file's extension)."""
    if len(name) <= width:
        return name
    if width <= 1:
        return "…"[:width]
    tail = (width - 1) // 2
    return name[: width - 1 - tail] + "…" + name[len(name) - tail :]


#: The fewest characters a name is shortened to (``xsens…txt #1``): enough to tell names apart.
SHORTEST = 12


def print_fitted(console: Console, build: Callable[[int | None], Table], names: Sequence[str]) -> None:
    """A table whose ``names`` (a column of file or column names) give way first on a terminal
    too narrow for it: ``build(limit)`` makes the table with each name at most ``limit``
    characters (None: whole), shortened in the middle, never wrapped; the numbers stay whole
    (print_whole)."""
    from rich.measure import Measurement

    def natural(table: Table) -> int:  # its width with nothing wrapped or cut
        return Measurement.get(console, console.options.update_width(WIDE), table).maximum

    table = build(None)
    longest = max((len(n) for n in names), default=0)
    if natural(table) > console.width and longest > SHORTEST:
        table = build(max(SHORTEST, longest - (natural(table) - console.width)))
    width = console.width
    console.width = max(width, natural(table))  # what the names cannot give: the terminal wraps it
    try:
        console.print(table)
    finally:
        console.width = width


def iso_time(seconds: float) -> str | None:
    """A clock that counts from 1970 (years 2001-2286) as ISO 8601 in UTC, to the millisecond;
    None for any other clock."""
    from datetime import UTC, datetime

    if not 1e9 <= seconds < 1e10:
        return None
    return datetime.fromtimestamp(seconds, UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def _at(block: Mapping[str, FloatArray], name: str, i: int) -> float | None:
    values = block.get(name)
    return float(values[i]) if values is not None and values.shape == (3,) else None


def print_blocks(
    log: Log,
    seg: Segmentation,
    console: Console,
    *,
    used: dict[int, str],
    everything: bool,
    notes: bool = False,
    table: bool | None = True,
) -> None:
    """The blocks for people (the kept ones; ``everything``: the dropped too), how they were
    found, and a hint for each face without a block; ``notes``: first how the log was read
    (solve says that in its summary instead), and hints only for the faces a block was found
    near (segment cuts what there is: a face never held is no news there); ``table``: False,
    one line of counts instead of the table (solve without -v); None, the warnings alone (a
    rejected solve without -v: the rejection follows)."""
    from tumblecal_cli.core import blocks
    from tumblecal_cli.core import model as core

    name = log.layout.name
    for note in log.layout.notes if notes else []:
        tell(console, f"note: {note}")
    shown = seg.blocks if everything else seg.kept
    dropped = len(seg.blocks) - len(seg.kept)
    if table is None:
        _block_warnings(seg, console, name)
        return
    if not table:
        why = f" ({seg.dropped_counts()})" if dropped else ""
        found = f"{len(seg.kept)} of {count(len(seg.blocks), 'still block')} kept{why}; -v lists them"
        tell(console, f"{os.path.basename(name)}: {found}")
    elif shown:
        print_whole(console, _blocks_table(log, seg, shown, used, console.width))
    if dropped and not everything and table:
        tell(console, f"{dropped} more dropped ({seg.dropped_counts()}); -v lists them")
    if seg.threshold is not None and table:
        if seg.noise_floor is None:
            how = "given"
        elif seg.threshold == blocks.FLOOR_FACTOR * seg.noise_floor:
            how = f"{blocks.FLOOR_FACTOR:g} x the noise floor {seg.noise_floor:.4g}"
        else:  # readings that do not vary at all when still (blocks.detect)
            how = f"the noise floor is {seg.noise_floor:.4g}: still means no spread at all"
        window = f"{seg.window * seg.period:.3g} s" if seg.period else f"{seg.window} samples"
        tell(
            console,
            f"threshold {seg.threshold:.4g} ({how}; rolling std over {window}); "
            f"{len(seg.blocks)} block{'' if len(seg.blocks) == 1 else 's'} found, {len(seg.kept)} kept",
        )
    _block_warnings(seg, console, name)
    best = seg.best()
    tell(console, f"faces: {' '.join(f for f in core.FACES if f in best) or 'none'}")
    faces = [f for f in core.FACES if not notes or any(b.nearest == f for b in seg.blocks)]
    for hint in blocks.missing(seg, faces):
        tell(console, f"hint: {hint}")


def _block_warnings(seg: Segmentation, console: Console, name: str) -> None:
    for warning in seg.warnings:
        tell(console, f"warning: {warning}", style="yellow")
    if seg.gaps:
        first = f" (the first after data row {seg.gap_rows[0]})" if seg.gap_rows else ""
        gaps = f"{len(seg.gaps)} gap{'s' if len(seg.gaps) > 1 else ''} in time{first}"
        tell(console, f"warning: {name}: {gaps}; no block spans a gap", style="yellow")


def _blocks_table(log: Log, seg: Segmentation, shown: Sequence[Block], used: dict[int, str], width: int) -> Table:
    """Per block: its number, rows, start, length, face, angle, spread and what became of it."""
    from rich import box
    from rich.table import Table

    starts = [_start(log, seg, b) for b in shown]
    days = {t[:10] for t in starts if t.endswith("Z")}
    day = days.pop() if len(days) == 1 and all(t.endswith("Z") for t in starts) else None
    if day is not None:  # one day's epoch clock: the date once, in the title; each start its time of day
        starts = [t[11:-1] for t in starts]
    title = f"still blocks of {os.path.basename(log.layout.name)}" + (f", {day} UTC" if day else "")
    title = middle(title, width)
    table = Table(title=title, title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False, collapse_padding=True)
    for col in ("block", "rows", "start", "length", "face", "angle", "std", "status"):  # fits 80 columns
        table.add_column(col, justify="left" if col in ("face", "status", "rows") else "right", no_wrap=col != "status")
    for b, start in zip(shown, starts, strict=True):
        table.add_row(
            str(b.number),
            f"{log.row(b.first)}-{log.row(b.last)}",
            start,
            f"{b.duration:.3g} s" if b.duration is not None else str(b.samples),
            b.face or (f"({b.nearest})" if b.label is None else f"({b.label})"),
            f"{b.angle_deg:.1f}°",
            f"{float(b.std.max()):.3g}",
            used.get(b.number, "kept") if b.kept else f"dropped: {b.dropped}",
        )
    return table


def _start(log: Log, seg: Segmentation, b: Block) -> str:
    """When a block starts: an epoch clock's time in ISO 8601 (UTC), another clock's in seconds,
    or its reading over the rate (no time column)."""
    time = log.time(b.first)
    if time is not None:
        seconds = time * log.scale
        return iso_time(seconds) or f"{seconds:.6g} s"
    return "" if seg.period is None else f"{log.reading(b.first) * seg.period:.4g} s"


def count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def short_sensor(sensor: str) -> str:
    """ "accelerometer" as "acc.", and "accelerometer (raw -> g)" as "acc. (raw -> g)"."""
    name, _, units = sensor.partition(" (")
    return f"{name[:3]}." + (f" ({units}" if units else "")


def print_lot(result: Report, console: Console, plot: str | None, *, drift_given: bool) -> None:
    """The lot report for people: the parameter table, outliers, drift, pose files under two
    serials, unreadable files."""
    from rich import box
    from rich.table import Table

    from tumblecal_cli.core import lot

    def g(v: float | None, digits: int = 4) -> str:  # compact: 80 columns hold the table
        return "" if v is None else re.sub(r"e([-+])0*(\d)", r"e\1\2", f"{v:.{digits}g}").replace("e+", "e")

    def span(r: ParameterRow) -> str:
        if r.lower is None and r.upper is None:
            return ""
        if r.lower is not None and r.upper is not None and r.lower == -r.upper:
            return f"±{g(r.upper)}"
        return f"{g(r.lower)}..{g(r.upper)}"

    several = len({r.sensor for r in result.rows}) > 1
    table = Table(
        title=f"lot of {count(result.units, 'unit')} ({count(result.files, 'file')})",
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
        collapse_padding=True,
    )
    for name in ("parameter", "n", "mean", "std", "min", "max", "limits", "Cpk"):
        table.add_column(name, justify="left" if name == "parameter" else "right", no_wrap=True)
    for r in result.rows:
        low_cpk = result.min_cpk is not None and r.cpk is not None and r.cpk < result.min_cpk
        table.add_row(
            f"{short_sensor(r.sensor)} {r.parameter}" if several else r.parameter,
            str(r.count),
            g(r.mean),
            g(r.std, 2),
            g(r.min),
            g(r.max),
            span(r),
            ("" if r.cpk is None else f"{r.cpk:.2f}" if r.cpk < 100 else ">100") + (" <" if low_cpk else ""),
        )
    console.print(table)
    for r in result.rows:
        if r.outside:
            console.print(f"outside the limits: {r.parameter}: {', '.join(r.outside)}", style="red", soft_wrap=True)
        for unit, value, z in r.outliers:
            console.print(f"outlier: {unit}: {r.parameter} {g(value)} (t {z:+.1f})", style="red", soft_wrap=True)
    console.print(result.outlier_text, soft_wrap=True)
    changed = {d.serial for d in result.drift}
    flagged = [d for d in result.drift if d.flagged]
    if changed:
        line = f"drift: {len(changed)} unit{'s' if len(changed) > 1 else ''} calibrated more than once"
        line += (
            f"; {len(flagged)} change{'s' if len(flagged) != 1 else ''} beyond --max-drift"
            if drift_given
            else " (give --max-drift to flag changes)"
        )
        console.print(line, soft_wrap=True)
    for d in flagged:
        size = f"{d.relative:+.3%}" if d.relative is not None else f"{d.change:+.5g}"
        console.print(
            f"  {d.serial}: {d.parameter} changed {size} since {d.previous_created or os.path.basename(d.previous)}",
            style="red",
            soft_wrap=True,
        )
    for warning in lot.duplicate_warnings(result.duplicates):
        console.print(f"warning: {warning}", style="red", soft_wrap=True)
    if plot is not None and not result.unreadable:
        console.print(f"wrote {plot}", soft_wrap=True)
    verdict = "needs attention" if result.needs_attention else "in order"
    console.print(f"lot: {verdict}", style="bold red" if result.needs_attention else "bold green", soft_wrap=True)


def print_verify(
    cal: Calibration,
    rows: Sequence[Mapping[str, object]],
    overall: dict[str, float],
    ref: float,
    bound: float | None,
    failed: list[str],
) -> None:
    from rich import box
    from rich.table import Table

    console = make_console()
    units = f" {cal.units}" if cal.units else ""
    names = [one_line(os.path.basename(str(r["file"]))) for r in rows]

    def build(limit: int | None) -> Table:  # a long file name shortened in the middle (print_fitted)
        table = Table(
            title=f"{cal.method} calibration on {len(rows)} capture{'s' if len(rows) > 1 else ''}, "
            + ("each against its rate" if rows and "rate" in rows[0] else f"reference {ref:g}{units}"),
            title_justify="left",
            box=box.SIMPLE_HEAD,
            pad_edge=False,
        )
        for name in ("file", "n", "|mean| raw", "error", "|corrected|", "error", *([""] if failed else [])):
            table.add_column(name, justify="left" if name in ("file", "") else "right", no_wrap=True)
        for r, name in zip(rows, names, strict=True):
            before = "" if r["error_before"] is None else f"{r['error_before']:+.4g}"
            table.add_row(
                name if limit is None else middle(name, limit),
                str(r["samples"]),
                f"{r['norm_before']:.6g}",
                before,
                f"{r['norm_after']:.6g}",
                f"{r['error_after']:+.4g}",
                *(["FAIL" if r["file"] in failed else ""] if failed else []),
            )
        return table

    print_fitted(console, build, names)
    judged = f", limit ±{bound:g}" if bound is not None else ""
    verdict = "FAIL" if failed else "PASS" if bound is not None else "not judged"
    if "rms_error_before" in overall:
        console.print(
            f"norm error before calibration: RMS {overall['rms_error_before']:.3g}, "
            f"max {overall['max_error_before']:.3g}",
            soft_wrap=True,
        )
    console.print(
        f"norm error after calibration: RMS {overall['rms_error']:.3g}, max {overall['max_error']:.3g}{judged}: "
        f"{verdict}",
        soft_wrap=True,
    )


@contextlib.contextmanager
def batch_progress(console: Console, total: int, *, enabled: bool) -> Iterator[tuple[bool, Callable[[], None]]]:
    """A progress bar on stderr when it is a terminal: (shown, advance by one unit)."""
    if not (enabled and console.is_terminal and total):
        yield False, lambda: None
        return
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    columns = (TextColumn("batch"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
    with Progress(*columns, console=console, transient=True) as progress:
        task = progress.add_task("units", total=total)
        yield True, lambda: progress.advance(task)


def print_unit(row: Row, out_dir: str, console: Console, *, quiet: bool) -> None:
    """One line per unit: its verdict and file, or why it failed (``quiet``: only a unit with
    an error or a rejected capture, as ``solve -q`` still prints those)."""
    if quiet and row.status not in (2, 3):
        return
    codes = f" ({', '.join(row.codes)})" if row.codes else ""
    head = f"{row.serial}: {row.verdict}{codes}"
    if row.file:
        head += f" -> {os.path.join(out_dir, row.file)}"
    messages = row.messages or [row.message or ""]
    if len(messages) == 1 and not row.file:
        head, messages = f"{head}: {messages[0]}", []
    for line in [head, *(f"  {m}" for m in messages if not row.file)]:
        console.print(one_line(line), soft_wrap=True, markup=False, highlight=False)


def current_line(cal: Calibration) -> str:
    """A current block for people (docs/current.md): the corrected field's change per ampere, at
    the largest current fitted and as a share of the reference, and what share of the field's
    variation the current explained."""
    import numpy as np

    block = cal.current
    assert block is not None
    per_amp = float(np.linalg.norm(cal.matrix @ block.per_amp))
    largest = max(abs(block.range[0]), abs(block.range[1]))
    units = cal.units or "output units"
    sigma = block.extra.get("interference_sigma")
    plus = f" ± {sigma:.1%}" if isinstance(sigma, float) else ""
    share = f", {per_amp * largest / cal.reference:.1%}{plus} of the reference" if cal.reference else ""
    explained = block.extra.get("explained_total")
    said = f"; the current explained {explained:.1%} of the field's variation" if isinstance(explained, float) else ""
    return (
        f"current ({block.column!r}): the field moves {per_amp:.3g} {units}/A, "
        f"{per_amp * largest:.3g} {units} at {largest:.3g} A{share}{said}"
    )


def thermal_doc(done: ThermalResult) -> dict[str, object]:
    """The --json summary of ``tumblecal thermal``: the thermal block, the drift over the range, notes."""
    thermal = done.calibration.thermal
    assert thermal is not None  # what thermal() made
    return {
        "thermal": thermal.as_dict(),
        "drift": drift_rows(done.calibration),
        "warnings": [w.as_dict() for w in done.warnings],
        "notes": done.notes,
    }


class DriftRow(TypedDict):
    """An axis's drift over a thermal block's range (``drift_rows``)."""

    axis: str
    offset_drift: list[float]
    offset_drift_max: float
    offset_drift_per_degc: float
    gain_drift: list[float]
    gain_drift_kind: str


def drift_rows(cal: Calibration) -> list[DriftRow]:
    """Per axis: the offset drift (raw units) and gain drift (relative) at both ends of the thermal
    range against the reference temperature, and how the gain drift is known."""
    import numpy as np

    block = cal.thermal
    assert block is not None
    drift = block.drift()
    ends = np.array([drift.t_min, drift.t_max])
    off, gain = drift.at(ends)
    grid = np.linspace(drift.t_min, drift.t_max, 201)
    off_all, _ = drift.at(grid)
    span = max(drift.t_max - drift.t_min, 1e-12)
    rows: list[DriftRow] = []
    for j, axis in enumerate("xyz"):
        worst = float(np.abs(off_all[:, j]).max())
        rows.append(
            {
                "axis": axis,
                "offset_drift": [float(off[0, j]), float(off[1, j])],
                "offset_drift_max": worst,
                "offset_drift_per_degc": float(np.abs(np.diff(off_all[:, j])).max() / (span / 200)),
                "gain_drift": [float(gain[0, j]), float(gain[1, j])],
                "gain_drift_kind": block.gain_drift[j],
            }
        )
    return rows


def print_thermal(done: ThermalResult, console: Console) -> None:
    """``tumblecal thermal`` for people: the fit, the drift per axis over the range, notes."""
    fit = done.fit
    thermal = done.calibration.thermal
    assert thermal is not None  # what thermal() made
    drift = thermal.drift()
    how = "chosen by cross-validation over temperature" if fit.order_auto else "as given"
    cv = ", ".join(f"{k}: {v:.3g}" for k, v in fit.cv_error.items())
    console.print(
        f"thermal: order {drift.order} ({how}; prediction error by order {cv}), "
        f"{fit.cells} cells from {len(done.sweeps)} sweeps",
        soft_wrap=True,
    )
    print_drift(done.calibration, console)
    for w in done.warnings:
        tell(console, f"warning: {w.render()} ({w.code})", style="yellow")
    for note in done.notes:
        tell(console, f"note: {note}")


def print_drift(cal: Calibration, console: Console) -> None:
    """A thermal block for people: per axis the offset and gain drift at the ends of the range
    against T_ref, and the offset coefficients with their 1-sigma."""
    from rich.table import Table

    block = cal.thermal
    assert block is not None
    drift = block.drift()
    units = cal.input_units or "raw units"
    table = Table(
        title=f"temperature drift ({units}), {drift.t_min:.1f} to {drift.t_max:.1f} °C against {drift.t_ref:.2f} °C"
    )
    for name in ("axis", "offset drift", "max |drift|", "gain drift", "gain drift"):
        table.add_column(name, no_wrap=True)
    for row in drift_rows(cal):
        low, high = row["offset_drift"]
        g_low, g_high = row["gain_drift"]
        kind = row["gain_drift_kind"]
        gains = {"unobserved": "—", "folded": "in the offset"}.get(kind, f"{g_low:+.3%} .. {g_high:+.3%}")
        table.add_row(row["axis"], f"{low:+.3g} .. {high:+.3g}", f"{row['offset_drift_max']:.3g}", gains, kind)
    print_whole(console, table)
    se = block.extra.get("uncertainty")
    offset_se = se.get("offset") if isinstance(se, dict) else None
    for k in range(drift.order):
        terms = ", ".join(
            f"{'xyz'[j]} {block.offset[j][k]:+.4g}" + (f" ± {offset_se[j][k]:.2g}" if offset_se else "")
            for j in range(3)
        )
        console.print(f"offset per (T - T_ref)^{k + 1}: {terms}", soft_wrap=True)


@contextlib.contextmanager
def samples_progress(*, enabled: bool) -> Iterator[Callable[[int], None] | None]:
    """A count of the samples read so far on stderr when it is a terminal (a long capture takes
    a while): a callback taking that count, or None (Rich is not imported when not ``enabled``)."""
    console = make_console() if enabled else None
    if console is None or not console.is_terminal:
        yield None
        return
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    columns = (SpinnerColumn(), TextColumn("read {task.completed:,.0f} samples"), TimeElapsedColumn())
    with Progress(*columns, console=console, transient=True) as progress:
        task = progress.add_task("samples", total=None)
        yield lambda n: progress.update(task, completed=n)


def show_noise(done: Noise, *, json_summary: bool, shown: Shown, plot: str | None) -> None:
    """noise's figures: the --plot and the --json object (not for a rejected capture: it
    writes nothing), then the table, why a figure is not determined (-v: the cluster times
    each was read at), verdict and notes for people on stderr."""
    quiet = shown.quiet
    if plot is not None and done.error is None:
        from tumblecal_cli.core import allan
        from tumblecal_cli.io.figures import plots

        plots.require()
        plots.noise_figure(plot, done.curve, allan.figures(done.curve), done.units, title=done.file)
    if json_summary:
        print_json(done.to_dict())
    if quiet or done.error is not None:  # a rejected capture: its rejection alone, no figures before it
        return
    console = make_console()
    seconds = done.samples / done.rate
    span = f"{seconds / 3600:.3g} h" if seconds >= 3600 else f"{seconds:.4g} s"
    head = f"{done.file}: {count(done.samples, 'sample')} at {done.rate:g} Hz ({span})"
    console.print(head, soft_wrap=True)
    table, lines = _noise_table(done)
    print_whole(console, table)
    for line in lines:
        if shown.verbose or "not determined" in line:
            tell(console, line)
    for note in done.notes:
        tell(console, f"note: {note}")
    verdict = done.verdict()
    if verdict is not None:
        unjudged: dict[str, list[str]] = {}
        for item in verdict["not_judged"]:  # "random_walk.x"
            name, _, axis = item.partition(".")
            unjudged.setdefault(name, []).append(axis)
        for name, axes in unjudged.items():
            tell(
                console,
                f"warning: {name} has a limit but is not determined on {', '.join(axes)}: not judged there",
                style="yellow",
            )
        _print_verdict(console, bool(verdict["pass"]), verdict["limits"], done.failures)


def _noise_table(done: Noise) -> tuple[Table, list[str]]:
    """The figures per axis (value ± its 95 % uncertainty), and a line per figure saying the
    cluster times it was read from, or why it is not determined."""
    from rich.table import Table

    table = Table(box=None, pad_edge=False)
    table.add_column("figure")
    for axis in "xyz":
        table.add_column(axis, justify="right")
    table.add_column("units")
    lines = []
    for name, unit in zip(("noise_density", "bias_instability", "random_walk"), done.figure_units, strict=True):
        cells: list[str] = []
        read: dict[str, list[str]] = {}
        for axis, figs in zip("xyz", done.axes, strict=True):
            f = getattr(figs, name)
            cells.append("—" if f.value is None else f"{f.value:.3g}±{f.uncertainty:.1g}")
            if f.tau is None:
                text = f"not determined ({f.why})"
            else:
                text = f"τ = {f.tau[0]:.3g} s" if f.tau[0] == f.tau[1] else f"τ = {f.tau[0]:.3g}–{f.tau[1]:.3g} s"
            read.setdefault(text, []).append(axis)  # axes read alike: said once
        table.add_row(name.replace("_", " "), *cells, unit)
        lines.append(f"{name.replace('_', ' ')}: " + "; ".join(f"{''.join(a)} {t}" for t, a in read.items()))
    return table, lines
