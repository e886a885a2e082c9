"""solve: pose captures (or one continuous log) in, a judged Calibration out.

The steps, each a module of its own: read the poses (``io.csv.readings``, or ``pipeline.segment`` for a
log), average them (``core.model.pose_stats``), solve (``core.fits``, through core.catalog), check the captures
(``core.gate.check``, exit 3), judge the unit against its limits (``core.gate.verdict``, exit 1),
and build the calibration (``io.calfiles.calfile.build``). Nothing here prints or writes a file: the
command line renders a :class:`Solved`, and ``Solved.calibration.save`` writes it.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Unpack

import numpy as np

from tumblecal_cli.core import arrays, blocks, catalog, clock, fits, gate, methods, model
from tumblecal_cli.core.gate import Finding
from tumblecal_cli.core.model import face_of_name
from tumblecal_cli.core.quantities import REFERENCE_UNITS, STANDARD_GRAVITY
from tumblecal_cli.errors import CaptureRejected, InputError
from tumblecal_cli.io import sources
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.io.calfiles.calfile import Pose
from tumblecal_cli.pipeline import align as alignment
from tumblecal_cli.pipeline import options as opts
from tumblecal_cli.pipeline import places
from tumblecal_cli.pipeline import segment as segmenting
from tumblecal_cli.pipeline.exchange import tilt_notes
from tumblecal_cli.pipeline.frames import in_memory, read_pose, samples_of
from tumblecal_cli.pipeline.options import SolveKeywords, SolveOptions, method_options, path_of, triplet
from tumblecal_cli.pipeline.solve import maglog, rotations, spins, tables, trimming, turns
from tumblecal_cli.pipeline.solve.fitnotes import left_out, motion_notes, outlier_notes, reference_notes

if TYPE_CHECKING:
    from tumblecal_cli.core.arrays import FloatArray
    from tumblecal_cli.core.blocks import Segmentation
    from tumblecal_cli.core.gate import Corrected, Finding, Limits, PoseCheck
    from tumblecal_cli.core.model import PoseStats, Solution
    from tumblecal_cli.core.running import Summary
    from tumblecal_cli.io.calfiles import calfile
    from tumblecal_cli.io.calfiles.calfile import Calibration, Pose
    from tumblecal_cli.io.csv.readings import Log, Samples
    from tumblecal_cli.pipeline.frames import DataFrame
    from tumblecal_cli.pipeline.options import Settings, SolveOptions
    from tumblecal_cli.pipeline.segment import Blocks

#: What each quality check's rejection suggests doing about it.
REJECTION_HINTS = {
    "pose.short": "log the pose for longer, or lower --min-samples (1 for loggers that store one averaged row)",
    "pose.saturated": "the pose reaches the sensor's limits: use a wider range, or give the real one with --full-scale",
    "pose.orientation": "capture the pose again on its declared face, or raise --max-tilt for a tilted fixture",
    "pose.moved": "hold the unit still and capture the pose again, or raise --max-noise; a capture turned through "
    "orientations on purpose is a log: solve --log FILE finds its still stretches",
    "pose.upside_down": "give the files in the order +x +y +z, each with that axis pointing up",
}


@dataclass
class Solved:
    """The outcome of :func:`solve`.

    ``status``: 0 pass, 1 outside the limits, 3 rejected (a capture the checks do not trust,
    or too few poses; input errors raise instead). ``calibration`` is None when rejected;
    ``draft`` is what was solved from the rejected captures, for inspection (None when nothing
    was). ``rejections`` are the findings that rejected it, ``error`` the same as the exception
    the command line raises; ``failures`` the limits it is outside; ``warnings`` and ``notes``
    what a person should know. ``blocks``: a log's still blocks and what each was used for.
    """

    status: int
    calibration: Calibration | None
    draft: Calibration | None = None
    rejections: list[Finding] = field(default_factory=list)
    failures: list[Finding] = field(default_factory=list)
    warnings: list[Finding] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    error: CaptureRejected | None = None
    blocks: Blocks | None = None
    samples: list[Samples] = field(default_factory=list)  # the poses as read (raw units)
    limits: Limits | None = None  # the limits given (before the method's own applied)

    def __post_init__(self) -> None:  # a rejection that is no check's finding is said in rejections too
        e = self.error
        if self.status == 3 and not self.rejections and e is not None:
            self.rejections = [
                Finding(e.code or "capture.rejected", e.message, math.nan, math.nan, e.file, hint=e.hint)
            ]

    @property
    def passed(self) -> bool:
        return self.status == 0


#: Pose captures: files (one path, or a list of ``FILE`` / ``LABEL=FILE`` items), or data in
#: memory (a mapping of labels to DataFrames or (n, 3) arrays, a list of them, or one alone).
Poses = str | os.PathLike[str] | Sequence[object] | Mapping[str, object] | arrays.FloatArray


def solve(poses: Poses | None = None, **options: Unpack[SolveKeywords]) -> Solved:
    """Solve a calibration from pose captures, as ``tumblecal solve --poses`` does.

    ``poses``: the items of ``--poses`` (``FILE`` or ``LABEL=FILE``), or a mapping of labels
    (faces such as ``"+x"``, or ``"X,Y,Z"`` directions) to DataFrames or (n, 3) arrays; None with
    ``spin=`` (a gyroscope's ``RATE=FILE`` items, pipeline.solve.spins).
    ``options``: solve's long options in snake case (``reference=``, ``method=``,
    ``max_noise=``, ``limits=`` for a limits file, ``serial=`` ...; docs/python.md
    Python"). Input errors raise InputError; a rejected capture is ``status`` 3, not an error.
    """

    return calibrate(SolveOptions.of(options), poses=poses)


def solve_log(log: str | os.PathLike[str] | DataFrame, **options: Unpack[SolveKeywords]) -> Solved:
    """Solve a calibration from one continuous log ('-': stdin), as ``tumblecal solve --log``:
    the still blocks are found (or taken from ``pose_column``), the best of each face used.
    ``log`` may be its data in memory: a DataFrame, or an (n, 3) array (``rate=`` gives its
    clock; (n, 4): t, x, y, z), read as its file would be."""

    told = SolveOptions.of(options)
    with in_memory(log, "solve_log takes a log: a file, a DataFrame or an (n, 3) array") as path:
        return calibrate(told, log=path)


def calibrate(
    options: SolveOptions, *, poses: Poses | None = None, log: str | os.PathLike[str] | None = None
) -> Solved:
    """solve and solve_log, on options already gathered (the command line and batch call this);
    a magnetometer's with ``align_to`` then rotated onto that accelerometer's axes."""

    accel = options.log.align_to
    if accel is None:
        return _in_axes(_at_place(options, poses=poses, log=log), options)
    source = alignment.source_of(options.read.sensor, log if log is not None else poses)
    solved = _in_axes(_at_place(options, poses=poses, log=log), options)
    if solved.calibration is not None and "alignment" not in solved.calibration.fields:  # a log's is aligned already
        solved.calibration = _aligned(source, accel, solved.calibration, options, solved.notes)
    return solved


def _in_axes(solved: Solved, options: SolveOptions) -> Solved:
    """The calibration (and the draft) correcting into the body's axes of --axes (core.axes):
    solved in the sensor's, P folded into the matrix, the offsets left in the sensor's axes."""
    axes = opts.axes_given(options.axes)
    if axes is not None:
        solved.calibration = None if solved.calibration is None else solved.calibration.in_axes(axes)
        solved.draft = None if solved.draft is None else solved.draft.in_axes(axes)
    return solved


def _sensor_labels(labels: list[str | None], options: SolveOptions) -> tuple[list[str | None], str | None]:
    """The pose labels told in the body's axes (file names, LABEL=FILE, a table's order) as the
    sensor's directions they are, with --axes, and the note that says so."""
    axes = opts.axes_given(options.axes)
    if axes is None or not any(labels):
        return labels, None
    out = [None if label is None else axes.sensor_label(label) for label in labels]
    told = ", ".join(f"{a} as {b}" for a, b in zip(labels, out, strict=True) if a is not None and a != b)
    return out, f"--axes {axes.text}: the faces told in the body's axes, solved in the sensor's ({told})"


def _aligned(source: str, accel: str, cal: Calibration, options: SolveOptions, notes: list[str]) -> Calibration:
    """``cal`` (a magnetometer's) rotated onto the axes of the accelerometer calibration
    ``accel`` from ``source``'s still blocks (pipeline.align), and a note saying so."""
    settings = blocks.DetectorSettings(
        options.log.window, options.log.threshold, options.log.min_duration, options.log.trim
    )
    if options.checks.max_noise is not None:
        settings = replace(settings, max_noise=options.checks.max_noise)
    done = alignment.mag_to_accel(source, accel, cal, options.read, settings, accel_flag="--align-to")
    notes.append(alignment.solved_note(done))
    return alignment.aligned(done)


def _at_place(
    options: SolveOptions, *, poses: Poses | None = None, log: str | os.PathLike[str] | None = None
) -> Solved:
    """calibrate before any alignment: the reference of --location, --gravity and --date resolved
    (pipeline.places), the solve, and where the reference came from written beside it."""
    options = opts.checked(options)
    if options.spin:  # a gyroscope at known rates: its files are the --spin items (pipeline.solve.spins)
        if poses is not None or log is not None:
            raise InputError("--spin gives the gyroscope's files: not --poses or --log beside it")
        out = spins.solve_spins(options, opts.settings(options, log=False))
        return Solved(out.status, out.calibration, out.draft, out.rejections, out.failures, error=out.error,
                      notes=out.notes)  # fmt: skip
    files_or_data = None if poses is None else _poses_given(poses, options)
    path = (
        None if log is None else path_of(log, "solve_log takes a log file (data in memory: solve it as {label: data})")
    )
    if bool(files_or_data) == (path is not None):
        raise InputError(
            "give the pose files with --poses, or one continuous log with --log" + (", not both" if poses else ""),
            hint="see 'tumblecal solve --help'",
        )
    note = None
    first = path if path is not None else _first_file(files_or_data)
    if first is not None:  # pose files of a log's stream read in its units as a log is
        options, note = _stream_units(first, options)
    options, source = places.resolve(options, options.input_units)
    solved = _from_inputs(options, (files_or_data, poses), path, note, source)
    solved.calibration, solved.draft = places.stamp(solved.calibration, source), places.stamp(solved.draft, source)
    return solved


def _from_inputs(
    options: SolveOptions,
    given_poses: tuple[list[str] | Mapping[str, object] | None, Poses | None],
    path: str | None,
    note: str | None,
    source: places.ReferenceSource | None,
) -> Solved:
    """calibrate, its options resolved: ``given_poses`` the pose files or data (as read, and as given)."""
    files_or_data, poses = given_poses
    given = opts.settings(options, log=path is not None)
    if path is not None and options.read.sensor == "magnetometer":
        solved = _mag_from_log(path, options, given, source)
        solved.notes[:0] = [note] if note else []
        return solved
    if path is not None and (options.log.turns is not None or options.log.accel_cal is not None):  # a gyroscope's turns
        if options.log.turns is not None:
            out = turns.from_log(path, options, given)
        else:
            out = rotations.from_log(path, options, given)
        notes = [*([note] if note else []), *out.notes]
        return Solved(
            out.status, out.calibration, out.draft, out.rejections, out.failures, error=out.error, notes=notes
        )
    if path is not None:
        solved = _from_log(path, options, given)
        solved.notes[:0] = [note] if note else []
        return solved
    assert files_or_data is not None
    table, read = tables.take(poses, options, given)
    if table is not None:
        return _fit_poses(*_table_poses(table, options, given), options, given)
    name, labels, samples, placed = _read_poses(files_or_data, options, given, read)
    notes = [n for n in (placed.note, placed.axes_note) if n is not None]
    notes[:0] = [note] if note else []
    chosen = PoseSet(labels, samples, [s.readings for s in samples], notes or [], None, placed.by_name, placed.labelled)
    return _fit_or_trim(name, chosen, options, given)


def _fit_or_trim(name: str, poses: PoseSet, options: SolveOptions, given: Settings) -> Solved:
    """_fit_poses; and when the files as a whole are rejected (exit 3, or exit 2 from a check that
    reads their means, such as one-pose's units) and some moved, _fit_poses again on the still run
    of each that moved (pipeline.solve.trimming), with a note naming its rows: a file that passes
    whole is solved as it always was."""
    if name == "gyro-bias" and not options.checks.no_trim:  # the bias from each file's still run
        rests = trimming.gyro_rests(poses.samples, options)
        if rests is not None and rests.error is not None:
            return Solved(3, None, error=rests.error, notes=rests.notes, samples=poses.samples, limits=given.limits)
        if rests is not None:
            poses = replace(poses, samples=rests.samples, notes=[*poses.notes, *rests.notes])
    try:
        solved, failed = _fit_poses(name, poses, options, given), None
    except InputError as err:  # a units "mistake" may be the mean of a pose and its handling
        solved, failed = None, err
    trimmed = None
    if (solved is None or solved.status == 3) and trimming.applies(name, options, given):
        trimmed = trimming.still_runs(poses.samples, options, given)
    if trimmed is None:
        if failed is not None:
            raise failed
        assert solved is not None
        return solved
    if trimmed.error is not None:
        return Solved(3, None, error=trimmed.error, notes=trimmed.notes, samples=poses.samples, limits=given.limits)
    return _fit_poses(
        name, replace(poses, samples=trimmed.samples, notes=[*poses.notes, *trimmed.notes]), options, given
    )


def _first_file(given: list[str] | Mapping[str, object] | None) -> str | None:
    """The first pose file named by a path (None: data in memory only)."""
    items = list(given.values()) if isinstance(given, Mapping) else list(given or [])
    paths = [str(p) for p in items if isinstance(p, (str, os.PathLike))]
    if not paths:
        return None
    first = paths[0]  # a LABEL=FILE of the command line: its file
    return first.partition("=")[2] if "=" in first and not os.path.exists(first) else first


def _stream_units(path: str, options: SolveOptions) -> tuple[SolveOptions, str | None]:
    """The units of a log's stream (a PX4 ULog's: m/s^2, rad/s, gauss) as --input-units, unless
    given; an accelerometer in m/s^2 with no --reference is solved against standard gravity, so
    that the calibration corrects to m/s^2 as the autopilot does (a note says so)."""
    stream = sources.stream_of(path, options.read)
    if stream is None:
        return options, None
    reference, units, note = options.reference, options.units, None
    local = options.location is not None or options.gravity is not None  # pipeline.places sets it
    if options.read.sensor == "accelerometer" and stream.units == "m/s^2" and reference is None and not local:
        reference, units = STANDARD_GRAVITY, units or "m/s^2"
        note = (
            f"{stream.key} is in m/s^2: solved against standard gravity, --reference {STANDARD_GRAVITY:g}, "
            "corrected output in m/s^2 (give --reference 1 for g)"
        )
    return replace(options, reference=reference, units=units, input_units=options.input_units or stream.units), note


def _table_poses(table: tables.TablePoses, options: SolveOptions, given: Settings) -> tuple[str, PoseSet]:
    """The method and the poses of a table's rows: labelled as that many unlabelled files are
    (3: +x +y +z, 6: the six faces, in order; else none: sphere for 12 or more)."""
    labels, told = _sensor_labels(list(methods.default_labels(len(table.rows), given.up)), options)
    try:
        name, order = methods.pick(given.method, labels, options.read.sensor)
    except InputError as err:
        why = f"the table's {len(table.rows)} rows are {len(table.rows)} poses"
        raise InputError(err.message, file=err.file, hint=f"{why}; {err.hint}" if err.hint else why) from None
    method_options(name, given.reference, options.plane, options.bias_spread)
    rows = [table.rows[k] for k in order]
    labels = [None if catalog.orientation_free(name) else labels[k] for k in order]
    notes = [table.note, *([told] if told and not catalog.orientation_free(name) else [])]
    return name, PoseSet(labels, rows, [s.values for s in rows], notes, table=True)


def _poses_given(poses: object, options: SolveOptions) -> list[str] | Mapping[str, object]:
    """poses as files (one path, or a list of items) or as data in memory (a mapping of labels to
    data, or a list of data, labelled as unlabelled files are)."""

    if isinstance(poses, str | os.PathLike):
        return [os.fspath(poses)]
    if isinstance(poses, Mapping):
        return poses
    if hasattr(poses, "shape") or hasattr(poses, "columns"):  # one capture in memory: an array or a DataFrame
        poses = [poses]
    if not isinstance(poses, Sequence):
        raise InputError(
            f"poses are files, a list of data or a mapping of labels to data, not a {type(poses).__name__}"
        )
    items = list(poses)
    if all(isinstance(p, str | os.PathLike) for p in items):
        return [os.fspath(p) for p in items]
    labels = methods.default_labels(len(items), options.up or "+z")
    if any(label is None for label in labels):
        raise InputError(
            f"{len(items)} poses in memory need their labels: give a mapping, e.g. {{'+x': data, ...}}",
        )
    return {str(label): data for label, data in zip(labels, items, strict=True)}


def _read_poses(
    poses: list[str] | Mapping[str, object], options: SolveOptions, given: Settings, read: Samples | None = None
) -> tuple[str, list[str | None], list[Samples], Placed]:
    """The method, each pose's label and its samples, from files or from data in memory; and how
    the files got their faces. ``read``: the one pose file, read already."""

    if options.up is not None and len(poses) != 1:
        raise InputError(
            f"--up names the face of a single pose file, not of {len(poses)}",
            hint="label each file instead (+x=a.csv -x=b.csv ...), name them for their faces (xp.csv xn.csv ...), "
            "or give them in the order +x +y +z",
        )
    in_memory = isinstance(poses, Mapping)
    items: list[tuple[str | None, object]]
    placed = Placed([], labelled=True)  # in memory: the mapping's keys are the faces
    if isinstance(poses, Mapping):
        items = [(_label(str(label)), data) for label, data in poses.items()]
    else:
        placed = pose_items(poses, given.up, up_given=options.up is not None)
        items = list(placed.items)
    if not in_memory and sum(f == "-" for _, f in items) > 1:
        raise InputError("only one pose can be read from stdin ('-')")
    relabelled, axes_note = _sensor_labels([label for label, _ in items], options)
    items = [(label, data) for label, (_, data) in zip(relabelled, items, strict=True)]
    try:
        name, order = methods.pick(given.method, [label for label, _ in items], options.read.sensor)
    except InputError as err:
        if not placed.by_name:
            raise
        named = ", ".join(f"{os.path.basename(str(f))} {label}" for label, f in items)
        hint = f"the files' names gave the faces ({named})" + (f"; {err.hint}" if err.hint else "")
        raise InputError(err.message, file=err.file, hint=hint) from None
    if catalog.orientation_free(name):  # the faces are not used: neither a note nor a clash
        placed = Placed(placed.items, labelled=placed.labelled)
    elif placed.clash is not None:
        raise placed.clash
    else:
        placed = replace(placed, axes_note=axes_note)
    items = [items[k] for k in order]
    labels = [None if catalog.orientation_free(name) else label for label, _ in items]
    method_options(name, given.reference, options.plane, options.bias_spread)

    if in_memory:
        samples = [samples_of(str(label), data, options) for label, data in items]
    else:
        samples = [read if read is not None else read_pose(str(f), options) for _, f in items]
    return name, labels, samples, placed


def _label(text: str) -> str:

    try:
        return model.parse_label(text)
    except ValueError as err:
        raise InputError(f"pose {text!r}: {err}") from None


@dataclass
class Placed:
    """The ``--poses`` items as (label, file), and how unlabelled files got their faces."""

    items: list[tuple[str | None, str]]
    note: str | None = None  # said when the faces came from the files' names, not their places
    clash: InputError | None = None  # a name that says another face than its file's place gives
    labelled: bool = False  # every item came with its face (+x=FILE)
    axes_note: str | None = None  # --axes: the faces as the sensor's

    @property
    def by_name(self) -> bool:
        return self.note is not None


def pose_items(items: list[str], up: str, *, up_given: bool = False) -> Placed:
    """(label, file) of each --poses item, ``FILE`` or ``LABEL=FILE``. Labels are for every file
    or for none; unlabelled files take the faces their names give (:func:`named_faces`), else
    the labels of their count (methods.default_labels)."""

    out: list[tuple[str | None, str]] = []
    for item in items:
        label, sep, rest = item.partition("=")
        try:
            out.append((model.parse_label(label), rest) if sep and label else (None, item))
        except ValueError as err:
            if "," in label:  # meant as a direction: say what is wrong with it
                raise InputError(f"--poses {item}: {err}") from None
            out.append((None, item))  # a file name with '=' in it
    if any(label is None for label, _ in out) and any(label is not None for label, _ in out):
        raise InputError(
            "label every pose file or none (LABEL=FILE, e.g. +x=xp.csv)",
            hint="unlabelled files take the faces their names give (xp.csv xn.csv ..., each a different face), "
            "else by their count 1: --up, 3: +x +y +z, 6: +x -x +y -y +z -z",
        )
    if not out or out[0][0] is not None:
        return Placed(out, labelled=bool(out))
    return named_faces(items, methods.default_labels(len(out), up), up_given=up_given)


def face_of_file(path: str) -> str | None:
    """The face a file's name gives (x.csv, xp.csv, x_p.csv, +x.csv, xn.csv ...: core.model.face_of_name
    on the name up to its first dot), or None."""

    return face_of_name(os.path.basename(path).split(".", 1)[0])


def named_faces(files: list[str], placed: list[str | None], *, up_given: bool = False) -> Placed:
    """The faces of unlabelled files. When every file's name gives a face and no two the same
    (xn.csv xp.csv yn.csv ..., in the shell's order), the names give the faces, with a note if
    that differs from their places; otherwise their places do (``placed``: by their count),
    and a name that gives another face than its file's place is the clash to raise (exit 2)
    if the solver uses faces. --up (``up_given``) labels a single file: its name is not asked."""
    named = [face_of_file(f) for f in files]
    if up_given:
        return Placed(list(zip(placed, files, strict=True)))
    if all(named) and len(set(named)) == len(named):
        items = list(zip(named, files, strict=True))
        if named == placed:
            return Placed(items)
        said = ", ".join(f"{os.path.basename(f)} {n}" for n, f in items)
        return Placed(items, note=f"faces taken from the file names: {said}")
    clashes = [(f, n, p) for f, n, p in zip(files, named, placed, strict=True) if n and p and n != p]
    if not clashes:
        return Placed(list(zip(placed, files, strict=True)))
    twice = [n for n in dict.fromkeys(named) if n and named.count(n) > 1]
    if twice:
        both = " and ".join(os.path.basename(f) for f, n in zip(files, named, strict=True) if n == twice[0])
        why = f"; the names cannot give the faces: {both} both say {twice[0]}"
    else:
        why = "; the names cannot give the faces: not every file is named for one"
    lines = [f"{f}: its name says {n} but its place in --poses gives it {p}" for f, n, p in clashes]
    example = " ".join(f"{n}={f}" for f, n, _ in clashes[:2])
    return Placed(
        list(zip(placed, files, strict=True)),
        clash=InputError(
            lines[0].split(": ", 1)[1] + why,
            file=clashes[0][0],
            more=tuple(lines[1:]),
            hint=f"label every item with its face ({example} ...), or name each file for a different face",
        ),
    )


def _from_log(log: str, options: SolveOptions, given: Settings) -> Solved:
    """solve --log: the log's blocks, the poses they give the method, then the solve."""

    if given.method != "auto":
        method_options(given.method, given.reference, options.plane, options.bias_spread)
    settings = blocks.DetectorSettings(
        window=options.log.window,
        threshold=options.log.threshold,
        min_duration=options.log.min_duration,
        trim=options.log.trim,
        max_noise=options.checks.max_noise if options.checks.max_noise is not None else 0.02,
        max_tilt_deg=options.checks.max_tilt,
        nominal_offset=given.centre,
    )
    with segmenting.segmented(
        log,
        options.read,
        labels=segmenting.PoseLabels(  # (with --axes, a label column's faces are the body's)
            options.log.pose_column,
            given.pose_map if options.log.pose_map is not None else None,
            opts.axes_given(options.axes),
        ),
        settings=settings,
        max_spool=options.log.max_spool,
    ) as (_, data, seg):
        found = segmenting.Blocks(data, seg)
        try:  # while the log is there: a streamed log's blocks are read again (stdin's, from its copy)
            name, labels, samples, notes = segmenting.log_poses(
                data, seg, given.method, given.up, options.read.sensor, options.checks.full_scale
            )
        except CaptureRejected as err:
            return Solved(3, None, rejections=[], error=err, blocks=found)
    found.used = {
        int(s.block or 0): f"used: {label}" if label else "used" for s, label in zip(samples, labels, strict=True)
    }
    method_options(name, given.reference, options.plane, options.bias_spread)
    segmentation = _segmentation(data, seg)
    given = replace(given, centre=seg.centre)
    whole: list[FloatArray | Summary] = [data.values if data.extremes is None else data.extremes]  # the extremes
    solved = _fit_poses(name, PoseSet(labels, samples, whole, notes or [], segmentation), options, given)
    solved.blocks = found
    return solved


def _segmentation(data: Log, seg: Segmentation) -> calfile.SegmentationPart:
    """How the poses were found in a continuous log (the file's ``segmentation``)."""
    return calfile.SegmentationPart(
        data.layout.name,
        data.sha256,
        "detector" if seg.threshold is not None else "label column",
        window_samples=seg.window,
        sample_period_s=seg.period,
        threshold=seg.threshold,
        noise_floor=seg.noise_floor,
        min_samples=seg.min_samples,
        trim_samples=seg.trim,
        centre=seg.centre,
        blocks_found=len(seg.blocks),
        blocks_kept=len(seg.kept),
        gaps=len(seg.gaps),
        # a bursty clock's rate is its mean step's (core.clock): said with its steps and jitter
        extra={"clock": clock.as_dict(seg.clock)} if seg.clock is not None and seg.clock.bursty else {},
    )


def _mag_from_log(path: str, options: SolveOptions, given: Settings, source: places.ReferenceSource | None) -> Solved:
    """solve --sensor magnetometer --log: the ellipsoid fit to the magnetometer's samples of the
    still blocks its accelerometer finds (pipeline.solve.maglog), and their dip check."""
    found = maglog.read(path, options)
    name, _ = methods.pick(given.method, [None] * len(found.samples), "magnetometer")
    method_options(name, given.reference, options.plane, options.bias_spread)
    labels: list[str | None] = [None] * len(found.samples)
    segmentation = None if found.table else _segmentation(found.acc, found.seg)
    poses = PoseSet(labels, found.samples, [found.mag.values], found.notes, segmentation, table=found.table)
    solved = _fit_poses(name, poses, options, given)
    if not found.table:  # a table's rows are not a log's blocks to list
        solved.blocks = segmenting.Blocks(found.acc, found.seg)
        solved.blocks.used = {b.number: "used" for b in found.blocks}
    cal = places.stamp(solved.calibration, source)
    if cal is not None and options.log.align_to is not None:  # aligned first: the dips through the rotation
        cal = _aligned(path, options.log.align_to, cal, options, solved.notes)
    checked = None if cal is None else maglog.dip_check(found, cal, given.limits)
    if cal is not None and checked is not None:
        part, failures = checked
        cal = places.stamp(cal, places.ReferenceSource("dip", part))
        assert cal is not None
        if failures:
            verdict = cal.verdict or calfile.Verdict(limits=given.limits)
            cal = cal.with_verdict(replace(verdict, passed=False, failures=(*verdict.failures, *failures)))
            solved.failures += failures
            solved.status = solved.status or 1
    solved.calibration = cal
    return solved


@dataclass(frozen=True)
class PoseSet:
    """The poses a solver is given: their ``labels`` and ``samples``; ``whole``, every reading
    of the captures they came from (their integer rails are judged on it); ``notes`` on how they
    were chosen (a log's blocks) or labelled; a log's ``segmentation``; and whether the faces
    were told by the files' names (``by_name``) or by labels (``labelled``)."""

    labels: list[str | None]
    samples: list[Samples]
    whole: list[FloatArray | Summary]
    notes: list[str] = field(default_factory=list)
    segmentation: calfile.SegmentationPart | None = None
    by_name: bool = False
    labelled: bool = False
    table: bool = False  # the rows of a table of orientations, one reading each


def _fit_poses(name: str, poses: PoseSet, options: SolveOptions, given: Settings) -> Solved:
    """Average, solve, check and judge the poses; build the calibration."""
    labels, samples = poses.labels, poses.samples
    for s in samples:
        model.in_range(s.readings, s.name)
    ref = given.reference
    checks = _gate_options(poses, options, given)
    stats = [model.pose_stats(s.readings) for s in samples]
    names = [s.name for s in samples]
    one = names[0] if len(names) == 1 else None  # the capture a finding on the whole fit is about
    tilted: list[Finding] = []
    log_notes = list(poses.notes)  # how the blocks of a log were chosen, or the files labelled
    if name == "six-pose" and ref > 0:
        name, tilted = _six_faces(name, given.method == "auto", stats, names, log_notes)
    if catalog.family(name) == "one-pose":
        check_units(names[0], stats[0].mean - checks.nominal_offset, ref, samples[0].values, checks.nominal_offset)
    try:
        told = fits.SolverSettings(
            reference=ref,
            tolerance_deg=options.checks.fixture_tolerance,
            bias_spread=options.bias_spread if options.bias_spread is not None else 0.01 * ref,
            plane=options.plane,
            gain_tolerance=options.checks.gain_tolerance,
            robust=not options.no_robust,
        )
        fit = fits.fit(name, stats, [s.values for s in samples], labels, told, names)
    except CaptureRejected as err:
        return _rejected_fit(err, name, replace(poses, notes=log_notes), options, given)  # with auto's note
    solution = fit.solution
    judged = given.limits.gain_error is not None or given.limits.nominal_gain_given
    if ref > 0 and catalog.judges_gains(solution.method) and judged:
        gate.check_gains(solution.gain, ref, given.limits.nominal_gain)
    limits = given.limits.for_method(solution.method)
    measured = [
        gate.measure(n, f, s.readings, st, checks) for n, f, s, st in zip(names, labels, samples, stats, strict=True)
    ]
    if ref > 0:  # a gyroscope at rest has no direction to judge
        measured = gate.orient(measured, checks.nominal_offset, checks.max_tilt_deg)
    rejected, warned = gate.check(measured, solution, checks)
    rejected_cover, warned_cover = gate.check_coverage(fit.reach, solution.method, fit.coverage, checks.skip, one)
    rejected, warned = rejected + rejected_cover, warned + warned_cover + tilted + _mirrored(solution, checks)
    fixed = [
        gate.corrected(st.mean, st.std, f, solution.offset, solution.matrix, ref)
        for st, f in zip(stats, labels, strict=True)
    ]
    largest = None if fit.residuals is None or not len(fit.residuals) else float(abs(fit.residuals).max())
    pairs = list(zip(names, labels, fixed, strict=True))
    failures = (
        [] if rejected else gate.verdict(solution.method, solution.offset, solution.matrix, pairs, limits, largest)
    )
    basis = calfile.Basis(
        options.read.sensor,
        ref,
        samples[0].layout.sensor_names,
        options.units,
        options.input_units,
        tolerance_deg=options.checks.fixture_tolerance,
        gain_tolerance=options.checks.gain_tolerance if catalog.family(solution.method) == "one-pose" else None,
    )
    cal = calfile.build(
        solution,
        basis,
        [pose_record(s, m, c) for s, m, c in zip(samples, measured, fixed, strict=True)],
        fit=fit,
        unit=given.unit,
        verdict=calfile.Verdict(not failures, tuple(failures), limits),
        made=calfile.Made(poses.segmentation),
        outliers=left_out(fit, samples, ref),
    )
    read = list(dict.fromkeys(n for s in samples for n in s.layout.notes))  # how the files were read
    said = read + log_notes + tilt_notes(cal) + list(fit.notes) + outlier_notes(cal.outliers, cal.units)
    said += _solve_notes(stats, names, given.limits, solution.method, table=poses.table) + _units_notes(
        solution, options, ref
    )
    said += reference_notes(options.read.sensor, options.units, ref)
    said += motion_notes(options.read.sensor, fit, len(samples), ref)
    solved = Solved(0, cal, cal, [], failures, warned, said, samples=samples, limits=given.limits)
    if rejected:
        _reject(solved, rejected, limits)
    elif failures:
        solved.status = 1
    return solved


def _gate_options(poses: PoseSet, options: SolveOptions, given: Settings) -> gate.Options:
    """What the quality checks are told: the noise bound (a gyroscope's in its units, else a
    share of the reference), the tilt, the nominal offset, the full scale, the checks turned off."""
    ref, gyro = given.reference, options.read.sensor == "gyroscope"
    noise = options.checks.max_noise if options.checks.max_noise is not None else (None if gyro else 0.02)
    return gate.Options(
        noise_bound=None if noise is None else (noise if gyro else noise * ref),  # a gyroscope: in its units
        noise_rule="" if noise is None else (f"{noise:g}" if gyro else f"{noise:g} × reference {ref:g}"),
        max_tilt_deg=options.checks.max_tilt,
        nominal_offset=triplet("0", "--nominal-offset") if given.centre is None else given.centre,
        full_scale=options.checks.full_scale,
        min_samples=1 if poses.table else options.checks.min_samples,  # a table's row is one averaged reading
        skip=frozenset(
            (*gate.CHECKS, *gate.FIT_CHECKS)
            if options.checks.no_checks
            else [c.replace("-", "_") for c in options.checks.no_check]
        ),
        rails=gate.integer_rails(poses.whole),
        faces_by_name=poses.by_name,
        faces_labelled=poses.labelled,
    )


def _rejected_fit(err: CaptureRejected, name: str, poses: PoseSet, options: SolveOptions, given: Settings) -> Solved:
    """A solver that refused the poses: a pose on another face than declared reads as a tilt of
    60°, so the checks of the six-pose fit say which file and face, when they can; else the
    solver's own rejection, with a hint."""
    if err.code == "poses.tilted" and given.reference > 0:
        again = _fit_poses("six-pose", poses, options, replace(given, method="six-pose"))
        if again.status == 3 and {f.code for f in again.rejections} & {"pose.orientation", "pose.upside_down"}:
            return again
    if poses.by_name and err.code == "pose.upside_down":  # a three-pose gain of zero: not the files' order
        err.hint = gate.NAMED_HINT
    if poses.notes and name == "sphere":  # auto's choice: say why, and the way back
        err.hint = f"{err.hint + '; ' if err.hint else ''}{poses.notes[0]}"
    return Solved(3, None, error=err, samples=poses.samples, limits=given.limits)


def _mirrored(solution: Solution, checks: gate.Options) -> list[Finding]:
    """With the upside-down check off, a negative gain is still said (a warning per axis)."""
    if "upside_down" not in checks.skip or catalog.fixes_gains(solution.method):
        return []
    return [
        gate.Finding(
            "pose.upside_down",
            f"gain {g:.4g} on {axis} is negative: this calibration mirrors {axis} (a pose upside down or "
            "on the wrong face; the check that rejects it is off)",
            float(g),
            0.0,
        )
        for axis, g in zip("xyz", solution.gain.tolist(), strict=True)
        if g < 0
    ]


def _reject(solved: Solved, rejected: list[Finding], limits: Limits) -> None:
    """``solved`` rejected (exit 3): no calibration, and a draft that is never to be trusted (its
    verdict fails with the rejections, so apply and export refuse it without --force if saved)."""
    first = rejected[0]
    assert solved.calibration is not None
    solved.draft = solved.calibration.with_verdict(calfile.Verdict(False, tuple(rejected), limits))
    solved.status, solved.calibration, solved.rejections = 3, None, rejected
    solved.error = CaptureRejected(
        first.render(),
        hint=first.hint or REJECTION_HINTS[first.code],
        more=tuple(f.render() for f in rejected[1:]),
        code=first.code,
        codes=tuple(f.code for f in rejected),
    )


def _six_faces(
    name: str, auto: bool, stats: list[PoseStats], names: list[str], notes: list[str]
) -> tuple[str, list[Finding]]:
    """Six faces: auto chooses six-pose or six-pose-magnitude by how well opposite faces agree
    (methods.auto_six) and says why in ``notes``; an explicit six-pose on faces that disagree
    gets a warning (its cross-axis terms take the tilt)."""

    means = np.array([st.mean for st in stats])
    chosen, why = methods.auto_six(means)
    if auto:
        notes.append(why)
        return chosen, []
    if chosen == "six-pose":
        return name, []
    ev = methods.face_evidence(means)
    axis = max(ev.disagreement, key=lambda a: ev.disagreement[a])
    worst = ev.disagreement[axis]
    pair = [f"+{axis}", f"-{axis}"]
    files = " and ".join(f"{f} ({ev.angles[f]:.1f}° off)" for f in pair)
    return name, [
        Finding(
            "poses.hand_placed",
            f"the faces {files} disagree by {worst:.1f}° on the direction of {axis}: six-pose takes each pose as "
            "exactly on its face, so the tilt goes into its cross-axis terms and other orientations may read "
            "worse than uncalibrated; --method six-pose-magnitude is immune to it",
            worst,
            methods.CONSISTENT_DEG,
        )
    ]


#: A mean shorter than this share of its rows' magnitude is a mean over different orientations.
SHARED_DIRECTION = 0.8


def check_units(
    name: str, centred: FloatArray, reference: float, rows: FloatArray | None = None, centre: float | FloatArray = 0.0
) -> None:
    """A 1-pose mean (less --nominal-offset) far from --reference in magnitude: exit 2, with the
    reference the data suggests; but never from a mean over rows that point different ways
    (``rows``, less ``centre``: a table of orientations, a log), which is said instead. A row's
    magnitude is judged on the first rows (methods.TABLE_HEAD): it is the same in any orientation."""

    suggested = model.units_mistake(centred, reference)
    if suggested is None:
        return
    magnitude = float((centred**2).sum() ** 0.5)
    head = None if rows is None else rows[: methods.TABLE_HEAD] - centre
    typical = 0.0 if head is None else float(np.median(np.linalg.norm(head, axis=1)))
    if magnitude < SHARED_DIRECTION * typical:
        raise InputError(
            f"its rows point in different directions: their mean reads {magnitude:.4g} in magnitude, "
            f"a row {typical:.4g} (the median): not one pose",
            file=name,
            hint="a table of orientations, one row each: solve it with --rows-are-poses; "
            "a log of still poses: solve --log",
        )
    if suggested == 0:
        raise InputError(
            f"the pose reads {magnitude:.4g} in magnitude but --reference is {reference:g}",
            file=name,
            hint="a pose at rest reads the reference: is the sensor working, and are these its columns?",
        )
    units = REFERENCE_UNITS.get(suggested, "raw counts")
    raise InputError(
        f"the pose reads {magnitude:.4g} in magnitude but --reference is {reference:g}: a units mistake?",
        file=name,
        hint=f"the data looks like {units}: run with --reference {suggested:g} "
        "(the 1-pose solver has no gains, so --reference must be in the file's units)",
    )


def pose_record(s: Samples, m: PoseCheck, c: Corrected) -> Pose:
    """A pose's entry in the calibration file: what it was, what it measured, how it corrects."""

    return Pose(
        face=m.face,
        mean=m.stats.mean,
        samples=m.stats.samples,
        std=m.stats.std,
        file=s.layout.name,
        sha256=s.sha256,
        rows=s.rows,
        block=s.block,
        times=s.times,
        duration_s=s.duration,
        temperature=s.temperature,
        angle_deg=m.angle_deg,
        clipped=m.clipped,
        drift=m.drift,
        norm_error=c.norm_error,
        vector_error=c.vector_error,
    )


def _units_notes(solution: Solution, options: SolveOptions, reference: float) -> list[str]:
    """An accelerometer's gains that change its data's units from m/s^2 into g (or back) without
    a word of units from the user (--units, --input-units): one note (gate.units_note). Judged
    gains that are a units mistake are an error instead (gate.check_gains)."""
    if options.read.sensor != "accelerometer" or not catalog.judges_gains(solution.method):
        return []
    if options.units is not None or options.input_units is not None:
        return []
    note = gate.units_note(solution.gain, reference)
    return [] if note is None else [note]


def _solve_notes(
    stats: list[PoseStats], names: list[str], limits: Limits, method: str, *, table: bool = False
) -> list[str]:
    """What a person should know about how far the result can be trusted."""
    few = [(os.path.basename(name), st.samples) for name, st in zip(names, stats, strict=True) if st.samples < 3]
    effect = (
        "the uncertainty comes from the fit's residuals instead"
        if method in ("sphere", "ellipsoid")  # (their covariance takes the residuals' variance where noise is unknown)
        else "its uncertainty reads 0"
    )
    if table:  # every pose one reading: said once
        effect = effect.replace("its uncertainty", "the uncertainty")
        return [
            f"one reading per pose: the noise of each is unknown, so {effect}, and the moved check cannot judge them",
            *limits.not_applying_notes(method),
        ]
    notes = [
        f"{name} has {n} sample{'s' if n > 1 else ''}: its noise is unknown, "
        f"so {effect} and the moved check cannot judge it"
        for name, n in few[:3]
    ]
    if len(few) > 3:
        notes[2:] = [
            f"{len(few) - 2} more poses have fewer than 3 samples (noise unknown): {few[2][0]} ... {few[-1][0]}"
        ]
    notes += limits.not_applying_notes(method)
    return notes
