"""Continuous logs: read one, find its still blocks, pick the poses a solver needs
(``solve --log``), and cut it into one CSV per block (``segment``)."""

from __future__ import annotations

import contextlib
import csv
import io
import math
import os
import re
import secrets
import shutil
import sys
import tempfile
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field, replace
from typing import IO, TYPE_CHECKING, Unpack

import numpy as np

from tumblecal_cli.core import arrays, catalog, clock, gate, methods, model, solvers
from tumblecal_cli.core import blocks as seg_core
from tumblecal_cli.core.blocks import Block, Segmentation
from tumblecal_cli.errors import CaptureRejected, InputError
from tumblecal_cli.io import logs, sources
from tumblecal_cli.io.csv import capture, compressed, logread, readings
from tumblecal_cli.io.csv.readings import Log, Samples, check_rate
from tumblecal_cli.io.csv.sniff import HEAD_BYTES, sniff
from tumblecal_cli.io.figures import fitplots
from tumblecal_cli.io.logs import ROS as ROS_LOGS
from tumblecal_cli.io.outputs import (
    MAX_SPOOL,
    WRITE_ERRORS,
    atomic_output,
    remove_stale,
    spool_room,
    spreadsheet_safe,
    unsafe,
)
from tumblecal_cli.io.readspec import ReadKeywords, ReadSpec, read_spec
from tumblecal_cli.pipeline.frames import in_memory, written_table
from tumblecal_cli.pipeline.options import (
    CutKeywords,
    axes_given,
    keywords_known,
    path_of,
    size_option,
    size_text,
    triplet,
)
from tumblecal_cli.pipeline.options import pose_map as parse_pose_map

if TYPE_CHECKING:
    from tumblecal_cli.core.axes import Axes
    from tumblecal_cli.pipeline.frames import DataFrame

#: The longest --window, --min-duration or --trim taken, in seconds (116 days: longer than a log):
#: beyond it a value is a typo, and its samples overflow (the fastest --rate is readings.FASTEST).
LONGEST = 1e7


@dataclass
class Blocks:
    """A log read in and its still blocks: ``used`` names what each block was used for."""

    log: Log
    seg: Segmentation
    used: dict[int, str] = field(default_factory=dict)


@dataclass(frozen=True)
class PoseLabels:
    """A log's label column (--pose-column), what its labels name (--pose-map), and the axes
    those faces are told in (--axes: the body's; None: the sensor's)."""

    column: str | None = None
    mapping: Mapping[str, str] | str | None = None
    axes: Axes | None = None


@contextlib.contextmanager
def segmented(
    log: str,
    spec: ReadSpec,
    *,
    settings: seg_core.DetectorSettings,
    labels: PoseLabels | None = None,
    digest: bool = True,
    whole: bool = False,
    max_spool: int | str | None = None,
) -> Iterator[tuple[str, Log, Segmentation]]:
    """Read a log ('-': stdin, kept in a temporary file until the block ends, for a second
    read, up to ``max_spool`` bytes: read_twice) and find its blocks: (the path to read it
    again, readings.Log, segment.Segmentation).

    The Log holds each still block's first and last reading only, and reads a block's again when
    asked (io.csv.logread: while the path is there), unless ``whole`` asks for every reading (hand
    turns integrate what lies between), or the log must be read whole anyway (a label column,
    or what io.csv.logread does not take). ``labels``: a label column's (with --axes its faces
    are the body's, found as the sensor's directions along them; the blocks' stay the sensor's)."""
    labels = labels or PoseLabels()
    pose_column, pose_map = labels.column, labels.mapping
    sensor, rate = spec.sensor, spec.rate
    if sensor != "accelerometer":
        raise InputError(
            f"the still poses of a log are found and labelled by gravity: the accelerometer's, not the {sensor}'s",
            hint="cut the log with `tumblecal segment` (each block keeps every column), then solve the "
            f"{sensor}'s blocks with --poses and --sensor {sensor}",
        )
    if pose_map and not pose_column:
        raise InputError("--pose-map names the faces of a --pose-column's labels: give the column too")
    for option, value in (("--window", settings.window), ("--min-duration", settings.min_duration)):
        if value is not None and not 0 < value <= LONGEST:
            raise InputError(f"{option} must be a positive number of seconds up to {LONGEST:g}, got {value:g}")
    if settings.trim is not None and not 0 <= settings.trim <= LONGEST:
        raise InputError(f"--trim must be a number of seconds from 0 to {LONGEST:g}, got {settings.trim:g}")
    if settings.threshold is not None and not 0 <= settings.threshold < math.inf:
        raise InputError(f"--threshold must be a number from 0 up, got {settings.threshold:g}")
    check_rate(rate)
    size_option(max_spool, "--max-spool")
    with read_twice(log, spec, max_spool) as path:  # a pipe or FIFO is read once: kept for a second read
        streamed = pose_column is None and not whole and sources.reader_for(path) is None
        streamed = streamed and spec.span() == (None, None)  # --start/--end: read whole, then cut (readings.in_span)
        if streamed:  # a CSV log block by block, the still periods kept (io.csv.logread)
            name = "<stdin>" if log == "-" else log
            scanned = logread.scan_log(path, spec, settings=settings, name=name, digest=digest)
            if scanned is not None:
                data, seg = scanned
                yield path, data, review(data, seg, rate, settings)
                return
        data = readings.read_log(
            path,
            spec,
            label_column=pose_column,
            use_time=rate is None,
            name="<stdin>" if log == "-" else log,
            digest=digest,
        )
        model.in_range(data.values, data.layout.name)
        yield path, data, find_blocks(data, rate, labels, settings)


#: A clock with more time steps of 0 than this share, and steps shorter on average than the
#: median one by more than SHORTFALL, is not the samples' (core.clock.coarse): a warning names --rate.
ZERO_STEPS = clock.ZERO_STEPS
SHORTFALL = clock.SHORTFALL


def coarse_clock(seg: Segmentation) -> bool:
    """Whether the log's time column does not advance with its samples (a 3 kHz log stamped in
    whole milliseconds, a clock that stops)."""
    if seg.zero_steps <= ZERO_STEPS:
        return False
    return not seg.period or seg.mean_step is None or seg.mean_step < (1 - SHORTFALL) * seg.period


#: More still blocks of one or two samples than this (and most of those kept) is a wrong time scale.
MAX_TINY_BLOCKS = 50


def find_blocks(
    log: Log, rate: float | None, labels: PoseLabels | None, settings: seg_core.DetectorSettings
) -> Segmentation:
    """The blocks of a log read in: by the detector, or by its label column (``labels``)."""
    seconds = None if rate else log.seconds()
    seg = _blocks_of(log, seconds, rate, labels or PoseLabels(), settings)
    seg.gap_rows = [int(log.rows[g - 1]) for g in seg.gaps]
    if seconds is not None and seconds.size > 1:
        steps = np.diff(seconds)
        seg.zero_steps = int(np.count_nonzero(steps == 0)) / steps.size
        if seg.clock is not None and seg.clock.bursty:  # its steps that are not gaps: those over 3 periods too
            seg.mean_step = seg.clock.mean
        elif seg.period:
            seg.mean_step = float(steps[(steps >= 0) & (steps <= seg_core.GAP_FACTOR * seg.period)].mean())
    return review(log, seg, rate, settings)


def review(log: Log, seg: Segmentation, rate: float | None, settings: seg_core.DetectorSettings) -> Segmentation:
    """Notes on how the log's time was read, and exit 2 for a log whose time scale is wrong
    (hundreds of blocks of one or two samples)."""
    seconds = log.clock is not None and not rate
    name = log.layout.name
    if rate and log.clock is not None and log.layout.time is not None:
        column = log.layout.names[log.layout.time]
        seg.warnings.append(f"{name}: --rate {rate:g} is used, not the time column {column} (no gap or order check)")
    if seg.period is not None and seg.period >= 1.0 and seconds:  # slower than 1 Hz: not an IMU's clock
        seg.warnings.append(
            f"{name}: the time column advances {seg.period:.3g} s per sample ({1 / seg.period:.3g} Hz); "
            "if it is not in seconds, give --time-unit ms, us or ns"
        )
    if coarse_clock(seg) and seconds:
        seg.warnings.append(
            f"{name}: {seg.zero_steps:.0%} of the time column's steps are 0 (a clock coarser than the samples, "
            "or one that stops): the period, gaps and durations taken from it are not the samples'; "
            "give the sample rate with --rate HZ"
        )
    said = None if seg.clock is None or not seconds else clock.note(seg.clock, name, None)
    if said is not None and said not in log.layout.notes:  # how the log was read: said with its other notes
        log.layout.notes.append(said)
    if seg.period is None and (settings.window is not None or settings.min_duration is not None) and not rate:
        seg.warnings.append(f"{name}: no time column and no --rate: --window and --min-duration are in samples")
    tiny = sum(b.samples <= 2 for b in seg.blocks)
    if len(seg.blocks) > MAX_TINY_BLOCKS and (seg.window < 3 or tiny * 2 > len(seg.blocks)):
        # hundreds of "still poses" a few samples long: the time scale is wrong, not the poses
        every = f"a sample every {seg.period:.3g} s, " if seg.period else ""
        raise InputError(
            f"{len(seg.blocks)} still blocks, {tiny} of them one or two samples long ({every}a window of "
            f"{seg.window} sample{'s' if seg.window != 1 else ''}): the log's time scale is wrong, not its poses",
            file=name,
            hint="give the time column's unit (--time-unit ms, us or ns) or the sample rate (--rate HZ); "
            "--window and --min-duration set how long a still pose lasts",
        )
    return seg


def _blocks_of(
    log: Log,
    seconds: arrays.FloatArray | None,
    rate: float | None,
    told: PoseLabels,
    settings: seg_core.DetectorSettings,
) -> Segmentation:
    pose_column, axes = told.column, told.axes
    if pose_column is None:
        return seg_core.detect(log.values, seconds, rate, settings)
    mapping = parse_pose_map(told.mapping)
    labels = sorted(set(log.labels or []) - {""})
    unknown = [label for label in mapping if label not in labels]
    shown = ", ".join(labels[:12]) + (" ..." if len(labels) > 12 else "")
    absent = (  # a typo, or a face this log lacks (the capture's problem, judged as missing faces)
        f"{log.layout.name}: --pose-map names {', '.join(map(repr, unknown))}, not a label of column "
        f"{pose_column!r} (labels: {shown or 'none'})"
        if unknown
        else None
    )
    for label in labels:
        if label not in mapping:
            # a rotation, or a label --pose-map leaves out: its blocks are dropped
            with contextlib.suppress(ValueError):
                mapping[label] = model.parse_face(label)
    if not any(label in mapping for label in labels):
        raise InputError(
            f"no label in column {pose_column!r} names a face (labels: {shown or 'none'})",
            file=log.layout.name,
            hint="say which is which with --pose-map, e.g. x_p=+x,x_a=-x,y_p=+y,y_a=-y,z_p=+z,z_a=-z",
        )
    if axes is not None:  # the labels name the body's faces: the sensor's directions along them
        mapping = {label: axes.sensor_label(face) for label, face in mapping.items()}
    seg = seg_core.from_labels(log.values, log.labels or [], mapping, seconds, rate, settings)
    if absent:
        seg.warnings.append(absent)
    return seg


def enough_blocks(log: Log, seg: Segmentation, need: int) -> None:
    """A log with fewer kept blocks than ``need`` has nothing to calibrate from (exit 3)."""

    kept = seg.kept
    if len(kept) >= need:
        return
    why = seg.dropped_counts()
    found = f"{len(seg.blocks)} found" + (f", dropped: {why}" if why else "")
    if seg.threshold is None:
        hint = "label the static parts of the log in --pose-column (and map them with --pose-map)"
    elif coarse_clock(seg):  # the clock's, not the poses' fault
        hint = "the time column does not advance with the samples: give the sample rate with --rate HZ"
    elif not seg.blocks:
        hint = f"hold the unit still on each face, or raise --threshold (it was {seg.threshold:.4g})"
    else:
        hint = "hold each pose longer, or lower --min-duration; `tumblecal segment` lists every block"
    raise CaptureRejected(
        f"nothing to calibrate from: {len(kept)} still block{'' if len(kept) == 1 else 's'} kept ({found})",
        file=log.layout.name,
        hint=hint,
        code="log.blocks",
    )


def log_poses(
    log: Log, seg: Segmentation, method: str, up: str, sensor: str, full_scale: float | None = None
) -> tuple[str, list[str | None], list[Samples], list[str]]:
    """The method and the poses a log gives it: the best block of each face a face solver
    needs (Segmentation.best: the least tilted), or every kept block for an orientation-free
    one; and notes on that choice.

    ``auto`` with 12 or more kept blocks fits the sphere unless the six faces are there and
    agree (methods.auto_six): fewer faces, or faces placed by hand, and a face solver would take
    the tilt for cross-axis terms (seen on real logs: worse than no calibration)."""
    enough_blocks(log, seg, 1 if catalog.family(method) == "one-pose" else 2)
    best, kept = seg.best(), seg.kept
    notes: list[str] = []
    labels: list[str | None]
    many = len(kept) >= methods.SPHERE_MIN_POSES
    if method == "auto" and many:
        six = set(best) >= set(methods.SIX_FACES)
        ev = methods.face_evidence(np.array([best[f].mean for f in methods.SIX_FACES])) if six else None
        directions = np.array([b.mean - seg.centre for b in kept])
        directions /= np.maximum(np.linalg.norm(directions, axis=1), 1e-300)[:, None]
        fits = solvers.distinct_directions(directions) >= solvers.SPHERE_MIN_DIRECTIONS
        if ev is None:
            notes.append(
                f"auto fits the sphere to all {len(kept)} still blocks: faces found {' '.join(best) or 'none'}, "
                "not the six"
            )
            method = "sphere"
        elif ev.worst > methods.CONSISTENT_DEG and fits:  # else six-pose, or the magnitude fit (too few directions)
            notes.append(
                f"auto fits the sphere to all {len(kept)} still blocks: {ev.disagreeing()}, and a face solver "
                "takes each block as exactly on its face (--method six-pose-magnitude fits the six face blocks)"
            )
            method = "sphere"
    if catalog.orientation_free(method):
        chosen_blocks, labels = kept, [None] * len(kept)
    else:
        wanted = _wanted(method, up, best)
        chosen_blocks, labels = _face_blocks(log, seg, method, wanted, best), list(wanted)
        if method == "six-pose-diagonal":
            diagonal = methods.face_evidence(np.array([b.mean for b in chosen_blocks]))
            if diagonal.worst > methods.CONSISTENT_DEG:
                sphere = "; --method sphere fits tilted blocks" if many else ""
                notes.append(
                    f"{diagonal.disagreeing()}: {method} takes each block as exactly on its face, so the tilt goes "
                    f"into its parameters (six-pose-magnitude is immune to it){sphere}"
                )
    name, order = methods.pick(method, labels, sensor)
    samples = block_poses(log, chosen_blocks, name, full_scale)
    return name, [labels[k] for k in order], [samples[k] for k in order], notes


#: The readings of a log's blocks a solve reads again and holds at once (8 bytes a value): a
#: solver of means given more blocks than these takes each one's statistics from the scan.
BLOCK_BYTES = 32 << 20


def block_poses(log: Log, chosen: list[Block], method: str, full_scale: float | None = None) -> list[Samples]:
    """The poses of a log's ``chosen`` blocks: their readings read again (``Log.block``), or,
    where a log read block by block gives a solver of means more readings than BLOCK_BYTES
    (thousands of orientations), each block's statistics as the scan measured them
    (``Log.summarised``: the same to 1e-15), unless the readings are whole numbers (integer rails
    judged), the log has a temperature column, or a full scale is given (clipping judged on
    each block's own peak)."""
    row = catalog.find(method)
    many = 24 * sum(b.samples for b in chosen) > BLOCK_BYTES
    rails = log.extremes is None or gate.integer_rails([log.extremes]) is not None
    if not many or log.reread is None or row is None or row.takes != "means" or rails:
        return [log.block(b.number, b.first, b.last) for b in chosen]
    if log.temperature is not None or full_scale is not None:
        return [log.block(b.number, b.first, b.last) for b in chosen]
    return [log.summarised(b) for b in chosen]


def _wanted(method: str, up: str, best: Mapping[str, Block]) -> list[str]:
    """The faces a face solver takes from a log (auto: six, five or one per axis)."""
    if method == "auto":
        return list(methods.SIX_FACES if len(best) == 6 else best if len(best) == 5 else _per_axis(best))
    family = catalog.family(method)
    if family == "one-pose":
        return [up]
    if family == "three-pose":
        return _per_axis(best)
    if family == "six-pose":
        return list(methods.SIX_FACES)
    return list(best)


def _per_axis(best: Mapping[str, Block]) -> list[str]:
    """One face per axis for three-pose: the + face where the log has it, else the - face
    (a sensor that reads -1 g up gives -x -y -z blocks), else + (missing: _face_blocks says so)."""
    return [f"-{a}" if f"+{a}" not in best and f"-{a}" in best else f"+{a}" for a in "xyz"]


def _face_blocks(log: Log, seg: Segmentation, method: str, wanted: list[str], best: Mapping[str, Block]) -> list[Block]:
    """The best block of each wanted face, or exit 3 naming what is missing."""
    absent = [f for f in wanted if f not in best]
    if absent or len(wanted) < (methods.LEAST_SQUARES_MIN_POSES if method == "least-squares" else 1):
        faces = " ".join(best) or "none"
        need = {
            "auto": "one face per axis, five faces or all six (or 12 blocks for the sphere fit)",
            "least-squares": "four faces or more",
        }.get(method, " ".join(wanted))
        raise CaptureRejected(
            f"not the faces {method} needs ({need}); faces found: {faces}",
            file=log.layout.name,
            hint=(
                "map each face's label with --pose-map; `tumblecal segment -v` lists every block"
                if seg.threshold is None  # a labelled log
                else "rest the unit on each missing face for --min-duration; `tumblecal segment` lists every block"
            ),
            more=tuple(seg_core.missing(seg, absent or [f for f in methods.SIX_FACES if f not in best])),
            code="log.faces",
        )
    return [best[f] for f in wanted]


def body_faces(log: Log, seg: Segmentation, axes: Axes | None) -> Segmentation:
    """``seg`` with its blocks' faces named in the body's axes (--axes): the files and the
    index name them so, for ``solve --poses ... --axes``; the readings, and the blocks' means in
    the index, stay the sensor's."""
    if axes is None:
        return seg
    said = f"--axes {axes.text}: the faces are the body's (the readings and block means the sensor's)"
    if said not in log.layout.notes:
        log.layout.notes.append(said)
    blocks = [
        replace(b, nearest=axes.body_label(b.nearest), face=None if b.face is None else axes.body_label(b.face))
        for b in seg.blocks
    ]
    return replace(seg, blocks=blocks)


def block_files(seg: Segmentation) -> dict[int, str]:
    """The file each kept block is written to: xp.csv ... for the best of each face, blockNN.csv else."""
    alias = {face: name for name, face in model.FACE_ALIASES.items()}
    best = {b.number: alias[face] for face, b in seg.best().items()}
    width = max(2, len(str(len(seg.blocks))))
    return {
        b.number: f"{best[b.number]}.csv" if b.number in best else f"block{b.number:0{width}d}.csv" for b in seg.kept
    }


INDEX_COLUMNS = [
    "block",
    "file",
    "status",
    "reason",
    "first_row",
    "last_row",
    "start_time",
    "end_time",
    "samples",
    "duration_s",
    "mean_x",
    "mean_y",
    "mean_z",
    "std_x",
    "std_y",
    "std_z",
    "face",
    "nearest_face",
    "angle_deg",
    "label",
]


def index_rows(log: Log, seg: Segmentation, files: dict[int, str]) -> list[list[str]]:
    """segments.csv: one row per block found, kept or dropped (each cell as :func:`index_cells`
    writes it)."""
    rows = []
    for b in seg.blocks:
        times = ["", ""] if log.clock is None else [repr(log.time(b.first)), repr(log.time(b.last))]
        rows.append(
            [
                str(b.number),
                files.get(b.number, ""),
                "kept" if b.kept else "dropped",
                b.dropped or "",
                str(log.row(b.first)),
                str(log.row(b.last)),
                *times,
                str(b.samples),
                "" if b.duration is None else f"{b.duration:.6g}",
                *(repr(float(v)) for v in b.mean),
                *(f"{v:.6g}" for v in b.std),
                b.face or "",
                b.nearest,
                f"{b.angle_deg:.2f}",
                b.label or "",
            ]
        )
    return rows


def index_cells(rows: list[list[str]]) -> list[list[str]]:
    """segments.csv's cells as a spreadsheet shows them safely: a face (``+x``, ``-y``) or a
    label column's text (``=1+1``) would start a formula, and is written with a leading ``'``."""
    return [[spreadsheet_safe(c) for c in row] for row in rows]


#: A copy of a log read twice: ``tumblecal-PID-XXXXXXXX.csv`` in $TMPDIR.
SPOOL = re.compile(r"tumblecal-(\d+)-[0-9a-f]{8}\.csv")


@contextlib.contextmanager
def read_twice(log: str, spec: ReadSpec | None = None, max_spool: int | str | None = None) -> Iterator[str]:
    """The log as a file to read twice (to find the blocks, then to copy them): itself when it
    is a regular file, else (stdin '-', a pipe, a FIFO, a device) a copy in $TMPDIR, removed
    however the block ends. The copy is named before it is made, inside the try that removes it.

    The copy checks what it copies as it goes: its first block as the CSV reader would with
    ``spec`` (a first line over 1 MB, binary data: refused at once, not copied to the end of an
    endless stream), and its size, up to ``max_spool`` bytes (a size: 500M, 4G; None: MAX_SPOOL,
    or the room in $TMPDIR less a margin if that is less). Beyond it: exit 2. A ROS bag's chunks
    inflate up to the same ``max_spool`` (io.logs.ros.bounded) as it is read inside."""
    limit = size_option(max_spool, "--max-spool")
    if log != "-" and (capture.is_regular(log) or os.path.isdir(log)):  # a folder: a ROS 2 bag's (io.sources)
        with _inflating(log, limit):
            yield log
        return
    folder = tempfile.gettempdir()
    remove_stale(folder, SPOOL)  # the copies of runs killed with -9
    room = "set TMPDIR to a folder with room for the log"
    tmp = os.path.join(folder, f"tumblecal-{os.getpid()}-{secrets.token_hex(4)}.csv")
    try:
        try:
            out = open(tmp, "xb")  # noqa: SIM115
        except OSError as err:
            raise InputError(f"cannot make a temporary file: {err.strerror}", file=folder, hint=room) from None
        try:
            with out:  # (its close writes the last bytes: inside, so a full disk is caught as well)
                if log == "-":
                    _spool(sys.stdin.buffer, out, log, spec or ReadSpec(), limit)
                else:
                    with open(log, "rb") as f:
                        _spool(f, out, log, spec or ReadSpec(), limit)
        except OSError as err:
            if err.errno not in WRITE_ERRORS:  # the temporary folder's, not stdout's
                raise
            raise InputError(f"cannot keep the log for a second read: {err.strerror}", file=folder, hint=room) from None
        yield tmp
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


def _inflating(log: str, limit: int | None) -> contextlib.AbstractContextManager[None]:
    """A ROS bag's reading with what its chunks inflate bounded by ``limit`` (--max-spool) too;
    any other log's (and a bag's without --max-spool, bounded by its default) as it is."""
    reader = sources.reader_for(log) if limit is not None else None
    if reader is None or reader.kind != ROS_LOGS.kind:
        return contextlib.nullcontext()
    return logs.inflating_at_most(limit)


def _spool(source: IO[bytes], out: IO[bytes], log: str, spec: ReadSpec, limit: int | None) -> None:
    """Copy ``source`` into ``out`` (a file in $TMPDIR), checking it as it goes (read_twice)."""
    name = "<stdin>" if log == "-" else log
    first = b""
    while len(first) < HEAD_BYTES:  # the block the CSV reader sniffs (a pipe gives what it has)
        more = source.read(HEAD_BYTES - len(first))
        if not more:
            break
        first += more
    plain = compressed.kind_of(first) is None  # (compressed: its data is checked as it is read)
    if plain and sources.reader_for(out.name, lambda _: first[: sources.HEAD]) is None:  # read as CSV: checked as one
        sniff(name, first, at_eof=len(first) < HEAD_BYTES, no_header=spec.no_header, dialect=spec.dialect)
    folder = os.path.dirname(out.name)
    bound = limit if limit is not None else spool_room(folder)

    def beyond() -> InputError:
        return _spool_error(name, folder, bound, given=limit is not None)

    if len(first) > bound:
        raise beyond()
    out.write(first)
    shutil.copyfileobj(_Bounded(source, bound - len(first), beyond), out)


class _Bounded:
    """A stream read up to ``left`` more bytes: one more is ``error()``."""

    def __init__(self, source: IO[bytes], left: int, error: Callable[[], InputError]) -> None:
        self.source, self.left, self.error = source, left, error

    def read(self, size: int = -1) -> bytes:
        data = self.source.read(size)
        self.left -= len(data)
        if self.left < 0:
            raise self.error()
        return data


def _spool_error(name: str, folder: str, bound: int, *, given: bool) -> InputError:
    """The log goes on past the bound of its copy."""
    size, other = size_text(bound), "raise --max-spool"
    if given:
        what = f"more than --max-spool {size} to keep for a second read"
    elif bound < MAX_SPOOL:
        what = (
            f"more than {size} to keep for a second read "
            "(--max-spool's default: the free space in $TMPDIR less a margin)"
        )
        other = "set TMPDIR to a folder with more room"
    else:
        what = f"more than {size} to keep for a second read (--max-spool's default)"
    return InputError(
        f"{what}: an endless stream?",
        file=name,
        hint=f"a log from stdin or a pipe is copied to $TMPDIR ({folder}) to be read twice: "
        f"save it to a file and give its name, or {other}",
    )


def earlier_run(out_dir: str) -> tuple[bool, set[str]]:
    """Whether ``out_dir`` holds an earlier ``segment``'s index (segments.csv with its header),
    and the block files it lists that are still there: only names this command gives (xp.csv
    ... block07.csv), never another file of the folder."""
    index = os.path.join(out_dir, "segments.csv")
    try:
        with open(index, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            names = {unsafe(row.get("file") or "") for row in reader}
            ours = reader.fieldnames == INDEX_COLUMNS
    except (OSError, UnicodeDecodeError, csv.Error):
        return False, set()
    if not ours:
        return False, set()
    pattern = r"(?:[xyz][pn]|block\d{2,})\.csv"
    return True, {n for n in names if re.fullmatch(pattern, n) and os.path.exists(os.path.join(out_dir, n))}


@dataclass
class Segmented:
    """What :func:`segment` found and wrote: the blocks, the file each kept block goes to, the
    index (segments.csv's text), and what was written into ``out_dir`` (None: nothing asked)."""

    blocks: Blocks
    files: dict[int, str]
    index: str
    out_dir: str | None = None
    removed: int = 0  # block files of an earlier segmentation into out_dir, removed
    stale: int = 0  # staging folders of an earlier, killed segment run into out_dir, removed

    def table(self) -> DataFrame:
        """The index as a pandas DataFrame, one row per block found, kept or dropped (its faces
        and labels as found: ``+x``, not the ``'+x`` that keeps a spreadsheet from taking it for
        a formula)."""
        return written_table(self.index)


class SegmentKeywords(ReadKeywords, CutKeywords, total=False):
    """segment's options beside how the log is read and cut (docs/commands/segment.md)."""

    max_noise: float
    max_tilt: float
    nominal_offset: str | float | list[float] | None
    max_spool: int | str | None
    plot: str | None  # segment --plot: a PNG of the log with its blocks (needs tumblecal[plot])
    axes: str | None  # --axes: the faces named in the body's axes (core.axes)


def segment(
    log: str | os.PathLike[str] | DataFrame,
    *,
    out_dir: str | os.PathLike[str] | None = None,
    on_blocks: Callable[[Blocks, dict[int, str]], None] | None = None,
    **options: Unpack[SegmentKeywords],
) -> Segmented:
    """Find the still blocks of a continuous log ('-': stdin), and with ``out_dir`` write each
    kept block as a CSV of its own (the log's header and rows, unchanged) and segments.csv, the
    index. ``on_blocks`` sees the blocks as soon as they are found, before they are judged
    (none kept is exit 3; whether the faces kept are enough is solve's to judge) or written.
    ``log`` may be its data in memory: a DataFrame, or an (n, 3) array (``rate=`` gives its
    clock; (n, 4): t, x, y, z), whose blocks are written as CSVs of their readings."""

    keywords_known(options, SegmentKeywords, "segment")
    with in_memory(log, "segment reads a log: a file ('-': stdin), a DataFrame or an (n, 3) array") as path:
        return _segment(path, out_dir, on_blocks, options)


def _segment(
    log: str,
    out_dir: str | os.PathLike[str] | None,
    on_blocks: Callable[[Blocks, dict[int, str]], None] | None,
    options: SegmentKeywords,
) -> Segmented:
    """segment on a log's path (or the name its data in memory is held under)."""
    max_noise, max_tilt = options.get("max_noise", 0.02), options.get("max_tilt", 25.0)
    nominal_offset = options.get("nominal_offset")
    if out_dir is not None:
        out_dir = path_of(out_dir, "out_dir is a folder's path")
    size_option(options.get("max_spool"), "--max-spool")
    for option, value in (("--max-noise", max_noise), ("--max-tilt", max_tilt)):
        if not value > 0:
            raise InputError(f"{option} must be positive, got {value:g}")
    if out_dir is not None and os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise InputError("is a file, not a folder: --out-dir takes a folder", file=out_dir)
    axes = axes_given(options.get("axes"))
    settings = seg_core.DetectorSettings(
        window=options.get("window"),
        threshold=options.get("threshold"),
        min_duration=options.get("min_duration"),
        trim=options.get("trim"),
        max_noise=max_noise,
        max_tilt_deg=max_tilt,
        nominal_offset=None if nominal_offset is None else triplet(nominal_offset, "--nominal-offset"),
    )
    with segmented(
        log,
        read_spec(options),
        labels=PoseLabels(options.get("pose_column"), options.get("pose_map"), axes),
        settings=settings,
        digest=False,  # the block files are copies; nothing records the log's hash
        whole=options.get("plot") is not None,  # a figure draws every reading, not the still ones only
        max_spool=options.get("max_spool"),
    ) as (path, data, seg):
        seg = body_faces(data, seg, axes)
        found = Blocks(data, seg)
        files = block_files(seg)
        if on_blocks is not None:
            on_blocks(found, files)
        enough_blocks(data, seg, 1)
        if (plot := options.get("plot")) is not None:  # drawn before any block file is written
            clock = None if data.clock is None else (data.clock - data.clock[0]) * data.scale
            fitplots.segment_figure(plot, data.values, clock, seg, files, title=data.layout.name)
        text = io.StringIO()
        writer = csv.writer(text, lineterminator="\n")
        writer.writerow(INDEX_COLUMNS)
        writer.writerows(index_cells(index_rows(data, seg, files)))
        result = Segmented(found, files, text.getvalue(), out_dir)
        if out_dir is not None:
            result.stale = stale_staging(out_dir)
            result.removed = _write_blocks(log, path, found, files, result.index, out_dir)
    return result


def _table_blocks(data: Log, spans: list[tuple[int, int]], outputs: list[str]) -> None:
    """Each block of a log read from a source beside CSV (io.sources) as a CSV of its readings:
    the sensor triplet, and the time, temperature and label where the log has them (floats
    written as their shortest round-trip text)."""
    columns: list[list[str]] = [[repr(float(v)) for v in data.values[:, j]] for j in range(3)]
    if data.clock is not None:
        columns.append([repr(float(v)) for v in data.clock])
    if data.temperature is not None:
        columns.append([repr(float(v)) for v in data.temperature])
    if data.labels is not None:
        columns.append([label.replace(",", " ") for label in data.labels])
    header = ",".join(data.layout.names) + "\n"
    for (first, last), output in zip(spans, outputs, strict=True):
        rows = zip(*(c[first : last + 1] for c in columns), strict=True)
        with atomic_output(output) as out:
            out.write((header + "".join(",".join(row) + "\n" for row in rows)).encode())


def _write_blocks(log: str, path: str, found: Blocks, files: dict[int, str], index: str, out_dir: str) -> int:
    """Each kept block into ``out_dir`` and the index beside them; the number of an earlier
    segmentation's block files removed."""
    data, seg = found.log, found.seg
    if log != "-":
        for f in [*files.values(), "segments.csv"]:
            if _same_file(os.path.join(out_dir, f), log):
                raise InputError(f"--out-dir would overwrite the input with {f}", file=log)
    ours, listed = earlier_run(out_dir)
    foreign = [
        f
        for f in [*files.values(), "segments.csv"]
        if os.path.lexists(os.path.join(out_dir, f)) and f not in listed and not (f == "segments.csv" and ours)
    ]
    if foreign:  # a file of the user's, not one an earlier segment wrote: never replaced
        raise InputError(
            f"--out-dir already holds {', '.join(foreign)}, which no earlier `tumblecal segment` wrote there",
            file=out_dir,
            hint="give an empty or new --out-dir, or move those files",
        )
    earlier = {
        name
        for name in listed - set(files.values())
        if not _same_file(os.path.join(out_dir, name), log)  # never the log itself
    }
    created = not os.path.isdir(out_dir)
    os.makedirs(out_dir, exist_ok=True)
    kept = seg.kept
    names = ["segments.csv", *(files[b.number] for b in kept)]
    # everything is written into a staging folder first and published only when all of it is
    # there: a failure (a full disk, a bad row) leaves the folder as it was
    staging = tempfile.mkdtemp(prefix=f"{STAGING}{os.getpid()}-", dir=out_dir)
    published = False
    try:
        with atomic_output(os.path.join(staging, "segments.csv")) as out:
            out.write(index.encode())
        outputs = [os.path.join(staging, name) for name in names[1:]]
        lines = [data.line_span(b.first, b.last) for b in kept]
        if data.lines is not None:  # where each block's lines are in the file: copied as they are
            capture.copy_bytes(path, data.layout, [span for span in lines if span is not None], outputs)
        elif sources.reader_for(path) is not None:  # a source beside CSV: each block's readings as a CSV
            _table_blocks(data, [(b.first, b.last) for b in kept], outputs)
        else:
            capture.copy_rows(path, data.layout, [(data.row(b.first), data.row(b.last)) for b in kept], outputs)
        # the index first: a run stopped part-way leaves its blocks listed, so the next run
        # into this folder knows them for its own and replaces them
        for name in names:
            os.replace(os.path.join(staging, name), os.path.join(out_dir, name))
        published = True
    finally:
        shutil.rmtree(staging, ignore_errors=True)
        if created and not published:
            with contextlib.suppress(OSError):
                os.rmdir(out_dir)  # only if empty
    for name in sorted(earlier):  # a re-run replaces the earlier segmentation, never mixes with it
        with contextlib.suppress(FileNotFoundError):
            os.unlink(os.path.join(out_dir, name))
    return len(earlier)


def _same_file(path: str, log: str) -> bool:
    """Whether ``path`` is the log's file (stdin, or data in memory, is no file)."""
    try:
        return log != "-" and os.path.samefile(path, log)
    except OSError:
        return False


#: The name a segment run's staging folder starts with (inside --out-dir).
STAGING = ".tumblecal-segment-"


def stale_staging(out_dir: str) -> int:
    """Remove staging folders a killed segment run into ``out_dir`` left (``STAGING`` PID-...,
    of a process that is gone: never a segment run still writing there). The number removed."""

    return len(remove_stale(out_dir, re.compile(rf"{re.escape(STAGING)}(\d+)-\w+")))
