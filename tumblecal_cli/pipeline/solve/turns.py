"""solve --sensor gyroscope --log LOG --pose-column ... --turns ...: a gyroscope's bias,
g-sensitivity, scale and misalignment from one labelled log of the Ferraris procedure
(core.turn_fit). The log holds both triplets on the same rows: the accelerometer's columns say
which way gravity points (the six faces, and during each turn), the gyroscope's are calibrated.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from tumblecal_cli.core import blocks, clock, gate, model, stillness, turn_fit
from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.clock import Clock
from tumblecal_cli.core.gate import Finding
from tumblecal_cli.core.solvers import Fit
from tumblecal_cli.errors import CaptureRejected, InputError
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.io.csv import readings
from tumblecal_cli.pipeline.options import axes_given, pose_map
from tumblecal_cli.pipeline.segment import read_twice

if TYPE_CHECKING:
    from collections.abc import Mapping

    from tumblecal_cli.core.axes import Axes
    from tumblecal_cli.io.calfiles.calfile import Calibration, GSensitivity, Pose, Rotation, SegmentationPart, Turn
    from tumblecal_cli.io.csv.readings import Log
    from tumblecal_cli.pipeline.options import Settings, SolveOptions

SIX = ("+x", "-x", "+y", "-y", "+z", "-z")
#: A still face whose accelerometer varies more than this (1-sigma, g) was moved (the
#: accelerometer's own --max-noise default).
STILL_ACC_NOISE_G = 0.02
#: A still face whose calibrated gyroscope varies more than this (1-sigma, deg/s) was turned
#: (--max-noise overrides; at rest imucal's session reads 0.21 deg/s).
STILL_GYRO_NOISE_DPS = 1.0

HINTS = {
    "turns.faces": "label a still section for each of the six faces with --pose-map (x_p=+x,x_a=-x,...)",
    "turns.axes": "turn the unit about each of its three axes, and name each turn's section with --turns",
    "turns.angle": "check --turn-angle and its sign (right-hand rule about the named axis), and each turn's axis",
    "turns.moved": "hold the unit still on each face, or raise --max-noise (deg/s of the calibrated gyroscope)",
    "turns.gap": "log without gaps, or leave that turn out of --turns",
}


@dataclass
class Outcome:
    """What :func:`from_log` found (pipeline.solve makes it a Solved): ``status`` 0 pass, 1 outside
    the limits, 3 rejected (``error``, ``rejections``; ``draft`` what was solved anyway)."""

    status: int
    calibration: Calibration | None
    draft: Calibration | None = None
    rejections: list[Finding] = field(default_factory=list)
    error: CaptureRejected | None = None
    notes: list[str] = field(default_factory=list)
    failures: list[Finding] = field(default_factory=list)  # the limits it is outside


@dataclass(frozen=True)
class GyroMade:
    """What a gyroscope's calibration from turns was made of, beside its poses: the log's
    ``segmentation``, and its known ``turns`` and ``g_sensitivity`` or its hand ``rotations``."""

    segmentation: SegmentationPart
    turns: tuple[Turn, ...] | None = None
    g_sensitivity: GSensitivity | None = None
    rotations: tuple[Rotation, ...] | None = None


@dataclass(frozen=True)
class Section:
    """All rows of one label: indices into the log's readings, and their data rows."""

    label: str
    index: NDArray[np.int64]

    def rows(self, log: Log) -> tuple[int, int]:
        return int(log.rows[self.index[0]]), int(log.rows[self.index[-1]])


def from_log(log: str, options: SolveOptions, given: Settings) -> Outcome:
    """Read the log's two triplets, take its sections by label, solve and judge the gyroscope."""

    with read_twice(log, options.read, options.log.max_spool) as path:
        acc, gyr = (_read(path, log, options, sensor) for sensor in ("accelerometer", "gyroscope"))
    if not np.array_equal(acc.rows, gyr.rows):
        raise InputError(
            "the accelerometer and the gyroscope are not read on the same rows (an interleaved log?)",
            file=gyr.layout.name,
            hint="known turns need both triplets on every row of the log",
        )
    model.in_range(gyr.values, gyr.layout.name)
    return _solve(acc, gyr, options, given)


def _read(path: str, log: str, options: SolveOptions, sensor: str) -> Log:
    columns = options.read.columns if sensor == "gyroscope" else None
    return readings.read_log(
        path,
        replace(options.read, sensor=sensor, columns=columns),
        label_column=options.log.pose_column,
        use_time=options.read.rate is None,
        name="<stdin>" if log == "-" else log,
        digest=sensor == "gyroscope",
    )


def sections(log: Log) -> dict[str, Section]:
    """Every label's rows (all its runs, as imucal takes a label's rows)."""
    labels = np.asarray(log.labels or [], dtype=object)
    out = {}
    for label in dict.fromkeys(str(x) for x in labels):
        if label:
            out[label] = Section(label, np.flatnonzero(labels == label).astype(np.int64))
    return out


def seconds_per_sample(log: Log, rate: float | None, found: Clock | None = None) -> FloatArray:
    """The seconds each reading stands for: 1/--rate, else the time to the next reading (the
    last one the median step); without either the turns cannot be integrated (exit 2).

    A clock stamped on arrival in bursts (core.clock; ``found``, else judged here) says when a
    reading reached the host, not when it was taken: a reading just before a pause would stand
    for the whole pause and the rest of its burst for almost nothing, so each stands for the
    clock's mean period instead (the sample count at the mean rate, which is what the samples
    were taken at)."""
    if rate:
        return np.full(len(log.values), 1.0 / rate)
    t = log.seconds()
    if t is None:
        raise InputError(
            "integrating the turns needs the time between samples: the log has no time column",
            file=log.layout.name,
            hint="give the sample rate with --rate HZ (or the time column with --time-column)",
        )
    found, gaps = (found, None) if found is not None else blocks.clock_of(t)
    if found is not None and found.bursty:
        return np.full(len(log.values), found.period)
    step = np.append(np.diff(t), np.median(np.diff(t)) if t.size > 1 else 0.0)
    if found is not None and found.gaps:  # the reading before a gap stands for one period, not the gap
        gaps = blocks.clock_of(t)[1] if gaps is None else gaps
        step[gaps - 1] = found.period
    return step


def gapped(turns: dict[str, Section], log: Log, rate: float | None) -> tuple[list[Finding], list[str], Clock | None]:
    """Each turn whose samples span a gap in time (core.clock: its samples are not all there, and
    the gap is never integrated over), a note on a bursty clock, and the clock (None: --rate, or
    no time column)."""
    if rate:
        return [], [], None
    t = log.seconds()
    found, gaps = blocks.clock_of(t)
    said = None if found is None else clock.note(found, log.layout.name, None)
    out = []
    for label, section in turns.items():
        inside = gaps[np.isin(gaps - 1, section.index) & np.isin(gaps, section.index)]
        if inside.size:
            row = int(log.rows[inside[0] - 1])
            out.append(
                Finding(
                    "turns.gap",
                    f"turn {label} spans a gap in time (after data row {row}): "
                    "its samples are not all there to integrate",
                    int(inside.size),
                    0,
                )
            )
    return out, [said] if said else [], found


def _rejected(findings: list[Finding], name: str) -> CaptureRejected:
    first = findings[0]
    return CaptureRejected(
        first.message,
        file=name,
        hint=first.hint or HINTS[first.code],
        more=tuple(f.render() for f in findings[1:]),
        code=first.code,
        codes=tuple(f.code for f in findings),
    )


def _faces(found: dict[str, Section], mapped: Mapping[str, str], told: Axes | None) -> dict[str, str]:
    """Each face's label among the log's sections: --pose-map's, and labels that are faces (+x,
    xp) without an entry; with --axes they name the body's faces, keyed here by the sensor's."""
    faces = {face: label for label, face in mapped.items() if label in found}
    for label in found:
        face = _face(label)
        if face is not None and face not in faces:
            faces[face] = label
    return faces if told is None else {told.sensor_label(face): label for face, label in faces.items()}


def _solve(acc: Log, gyr: Log, options: SolveOptions, given: Settings) -> Outcome:
    name = gyr.layout.name
    found = sections(gyr)
    told = axes_given(options.axes)  # (--axes: the faces and turn axes named are the body's)
    faces = _faces(found, given.pose_map, told)
    shown = ", ".join(found) or "none"
    missing = [f for f in SIX if f not in faces]
    if missing:
        return Outcome(
            3,
            None,
            error=_rejected(
                [
                    Finding(
                        "turns.faces",
                        f"ferraris-turns needs a still section on each face; none for {' '.join(missing)} "
                        f"(labels of column {options.log.pose_column!r}: {shown})",
                        len(SIX) - len(missing),
                        len(SIX),
                    )
                ],
                name,
            ),
        )
    wanted = pose_map(options.log.turns, "--turns")
    if told is not None:
        wanted = {label: told.sensor_label(axis) for label, axis in wanted.items()}
    notes = [f"--turns names {label!r}, not a label of the log: left out" for label in wanted if label not in found]
    turns = {label: axis for label, axis in wanted.items() if label in found}
    axes = np.array([model.FACES[a] for a in turns.values()], dtype=np.float64).reshape(-1, 3)
    rank = turn_fit.axes_rank(axes)
    if rank < 3:
        which = ", ".join(f"{label} ({axis})" for label, axis in turns.items()) or "none found"
        return Outcome(
            3,
            None,
            notes=notes,
            error=_rejected(
                [
                    Finding(
                        "turns.axes",
                        f"turns {which}: rotations about {rank} independent axes; need 3",
                        rank,
                        3,
                    )
                ],
                name,
            ),
        )
    spans, said, timed = gapped({label: found[label] for label in turns}, gyr, options.read.rate)
    notes += said
    if spans:
        return Outcome(3, None, rejections=spans, error=_rejected(spans, name), notes=notes)
    dt = seconds_per_sample(gyr, options.read.rate, timed)
    still_sections, cut, restless = gyro_still([found[faces[f]] for f in SIX], gyr.values, dt, options.log.window)
    notes += cut
    still = turn_fit.FaceReadings(
        [acc.values[s.index] for s in still_sections], [gyr.values[s.index] for s in still_sections]
    )
    angle = float(options.log.turn_angle or 0.0)
    given_turns = [
        turn_fit.KnownTurn(
            acc.values[found[label].index], gyr.values[found[label].index], axis, angle, dt[found[label].index]
        )
        for label, axis in zip(turns, axes, strict=True)
    ]
    fit = turn_fit.ferraris(still, given_turns)
    rejections = _moved(fit, still, still_sections, options, restless) + _implausible(fit, turns, axes, angle)
    skip = options.checks.no_checks or "moved" in options.checks.no_check
    rejections = [r for r in rejections if not (skip and r.code == "turns.moved")]
    poses, made = _parts(fit, acc, gyr, still_sections, list(SIX), turns, given_turns)
    cal, failures = gyro_calibration(fit.solution, gyr, poses, fit.residual_deg, fit.cross_se, made, options, given)
    if rejections:
        return Outcome(3, None, draft=cal, rejections=rejections, error=_rejected(rejections, name), notes=notes)
    notes += [
        f"turn {label} about {axis}: {fit.measured_deg[k]:+.2f}° as calibrated, "
        f"{given_turns[k].dt.sum():.3g} s, residual {fit.residual_deg[k]:.2g}°"
        for k, (label, axis) in enumerate(turns.items())
    ]
    return Outcome(1 if failures else 0, cal, cal, notes=notes, failures=failures)


def gyro_still(
    sections: list[Section], gyr: FloatArray, dt: FloatArray, window_s: float | None
) -> tuple[list[Section], list[str], dict[str, Finding]]:
    """Each still face's rows cut to where the gyroscope is still (core.stillness): a label set a
    little before the unit came to rest, or after it was lifted, holds the slow end of a move,
    which the gyroscope reads (and the bias and g-sensitivity with it). Notes on what was cut,
    and a finding for each face where the gyroscope is not still: it never rests a window long
    (its rows are then kept whole), or it spreads more than ``SPREAD_FACTOR`` times its noise
    at rest (the faces' median), for :func:`_moved` to judge."""
    period = float(np.median(dt)) if len(dt) else 0.0
    seconds = window_s if window_s is not None else blocks.WINDOW[0]
    window = max(2, round(seconds / period)) if period > 0 else blocks.WINDOW[1]
    runs = [np.split(s.index, np.flatnonzero(np.diff(s.index) > 1) + 1) for s in sections]
    spans = [(int(r[0]), int(r[-1])) for rs in runs for r in rs]
    found = stillness.still(gyr, spans, window, window)
    out, notes, restless, first = [], [], {}, 0
    for section, rs in zip(sections, runs, strict=True):
        last, first = first, first + len(rs)
        kept = list(zip(found.parts[last:first], found.cut[last:first], strict=True))
        index = [np.arange(p[0], p[1] + 1) for p, _ in kept if p is not None]
        said = f"still section {section.label} moved: its gyroscope "
        if not index:
            what = f"is never at rest for {seconds:g} s (its rate stays beyond its noise)"
            restless[section.label] = Finding("turns.moved", said + what, 0.0, seconds)
            out.append(section)
            continue
        spread = float((gyr[np.concatenate(index)].std(axis=0) / np.maximum(found.noise, 1e-300)).max())
        if spread > stillness.SPREAD_FACTOR:
            what = f"spreads {spread:.3g} times its noise at rest on the other faces"
            restless[section.label] = Finding("turns.moved", said + what, spread, stillness.SPREAD_FACTOR)
        head, tail = sum(c[0] for _, c in kept), sum(c[1] for _, c in kept)
        if head or tail:
            notes.append(
                f"still section {section.label}: {head} samples cut at its start and {tail} at its end, "
                "where the gyroscope was turning"
            )
        out.append(Section(section.label, np.concatenate(index).astype(np.int64)))
    return out, notes, restless


def _face(label: str) -> str | None:
    try:
        return model.parse_face(label)
    except ValueError:
        return None


def _moved(
    fit: turn_fit.TurnsFit,
    still: turn_fit.FaceReadings,
    secs: list[Section],
    options: SolveOptions,
    restless: dict[str, Finding],
) -> list[Finding]:
    """Still faces whose accelerometer (g) or calibrated gyroscope (deg/s) varies as a moving
    unit's, or where the gyroscope is not still (``restless``: :func:`gyro_still`'s findings)."""
    bound = options.checks.max_noise if options.checks.max_noise is not None else STILL_GYRO_NOISE_DPS
    # raw units into deg/s by the turns' median gain: a turn gone wrong does not make every face "move"
    gain = float(np.median(np.abs(fit.solution.gain)))
    out = []
    for section, a_raw, g_raw in zip(secs, still.acc, still.gyr, strict=True):
        a = (a_raw - fit.acc_offset) @ fit.acc_matrix.T
        acc_std, gyro_std = float(a.std(axis=0).max()), float(g_raw.std(axis=0).max()) / gain
        if gyro_std > bound:
            what = f"its gyroscope varies {gyro_std:.3g} deg/s (1-sigma), above {bound:g}"
            out.append(Finding("turns.moved", f"still section {section.label} moved: {what}", gyro_std, bound))
        elif acc_std > STILL_ACC_NOISE_G:
            what = f"its accelerometer varies {acc_std:.3g} g (1-sigma), above {STILL_ACC_NOISE_G:g}"
            bound_g = STILL_ACC_NOISE_G
            out.append(Finding("turns.moved", f"still section {section.label} moved: {what}", acc_std, bound_g))
        elif section.label in restless:
            out.append(restless[section.label])
    return out


def _implausible(fit: turn_fit.TurnsFit, turns: dict[str, str], axes: FloatArray, angle: float) -> list[Finding]:
    """Turns whose integrated angle, at the gain of all the turns, is more than 25 % from --turn-angle."""
    measured = turn_fit.plausible_angles(fit.integrated, axes, np.full(len(axes), angle))
    out = []
    for (label, axis), got in zip(turns.items(), measured, strict=True):
        off = abs(got - angle) / abs(angle)
        if off > turn_fit.ANGLE_TOLERANCE:
            way = " (the other way round)" if got * angle < 0 else ""
            out.append(
                Finding(
                    "turns.angle",
                    f"turn {label}: integrated {got:+.0f}° about {axis}{way} where --turn-angle gives {angle:+g}°, "
                    f"{off:.0%} off (more than {turn_fit.ANGLE_TOLERANCE:.0%})",
                    float(got),
                    angle,
                )
            )
    return out


def _parts(
    fit: turn_fit.TurnsFit,
    acc: Log,
    gyr: Log,
    secs: list[Section],
    faces: list[str],
    turns: dict[str, str],
    given_turns: list[turn_fit.KnownTurn],
) -> tuple[list[Pose], GyroMade]:
    """The calibration's poses (the still sections) and what it was made of (the known turns,
    the g-sensitivity, the label column that found them)."""

    poses = [
        calfile.Pose(
            face=face,
            mean=gyr.values[s.index].mean(axis=0),
            samples=len(s.index),
            std=gyr.values[s.index].std(axis=0, ddof=1) if len(s.index) > 1 else np.zeros(3),
            file=gyr.layout.name,
            sha256=gyr.sha256,
            rows=s.rows(gyr),
            label=s.label,
            accelerometer_mean=acc.values[s.index].mean(axis=0),
        )
        for face, s in zip(faces, secs, strict=True)
    ]
    found = sections(gyr)
    made = GyroMade(
        segmentation=calfile.SegmentationPart(gyr.layout.name, gyr.sha256, "label column"),
        turns=tuple(
            calfile.Turn(
                label,
                axis,
                t.angle_deg,
                rows=found[label].rows(gyr),
                samples=len(t.gyr),
                duration_s=float(t.dt.sum()),
                integrated=fit.integrated[:, k],
                measured_deg=float(fit.measured_deg[k]),
                residual_deg=float(fit.residual_deg[k]),
            )
            for k, ((label, axis), t) in enumerate(zip(turns.items(), given_turns, strict=True))
        ),
        g_sensitivity=calfile.GSensitivity(
            fit.g_sensitivity,
            "raw units per g; column j: gravity along +j (not applied by apply)",
            calfile.Accelerometer(tuple(acc.layout.sensor_names), fit.acc_offset, fit.acc_matrix),
        ),
    )
    return poses, made


def gyro_calibration(
    solution: model.Solution,
    gyr: Log,
    poses: list[Pose],
    residual_deg: FloatArray,
    cross_se: FloatArray | None,
    made: GyroMade,
    options: SolveOptions,
    given: Settings,
) -> tuple[Calibration, list[Finding]]:
    """A gyroscope's calibration from known turns or hand turns: judged by the limits, built with
    its ``poses`` (the still sections or blocks) and what it was ``made`` of (the turns or
    rotations, the segmentation); and the limits it fails."""

    limits = given.limits.for_method(solution.method)
    failures = gate.verdict(solution.method, solution.offset, solution.matrix, [], limits)
    units = options.units or "deg/s"
    basis = calfile.Basis("gyroscope", given.reference, gyr.layout.sensor_names, units, options.input_units)
    cal = calfile.build(
        solution,
        basis,
        poses,
        fit=Fit(solution, residuals=residual_deg, cross_se=cross_se),
        unit=given.unit,
        verdict=calfile.Verdict(not failures, tuple(failures), limits),
        made=calfile.Made(made.segmentation, made.turns, made.g_sensitivity, made.rotations),
    )
    return cal, failures
