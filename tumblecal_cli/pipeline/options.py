"""The options of solve and the commands that share them, checked and resolved once.

``SolveOptions`` is solve's options, grouped; ``SolveOptions.of`` is the one mapper from their
flat values (the command line's long options in snake case: ``FLAT``, and ``SolveKeywords`` for
the Python API) that the command line, batch and ``solve``/``solve_log`` all go through.
:func:`settings` turns them into what the pipeline needs, or raises the one InputError a bad
option deserves before any file is read (batch checks them once, before any unit).
"""

from __future__ import annotations

import math
import os
import re
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from typing import TYPE_CHECKING, TypedDict, cast

from tumblecal_cli.core import axes, catalog, gate, model, quantities
from tumblecal_cli.core.model import SENSORS
from tumblecal_cli.errors import InputError, control_character, said
from tumblecal_cli.io.calfiles import limitfile
from tumblecal_cli.io.calfiles.calfile import Unit
from tumblecal_cli.io.calfiles.limitfile import (
    Triplet as Triplet,  # re-exported: solve, segment and exchange read them here
)
from tumblecal_cli.io.calfiles.limitfile import triplet as triplet
from tumblecal_cli.io.readspec import READ_NAMES, Dialect, ReadKeywords, ReadSpec, read_spec

if TYPE_CHECKING:
    from tumblecal_cli.core.arrays import FloatArray
    from tumblecal_cli.core.axes import Axes
    from tumblecal_cli.core.gate import Limits
    from tumblecal_cli.io.calfiles.calfile import Calibration, Unit


@dataclass(frozen=True)
class LogOptions:
    """How a continuous log is cut (solve --log): its still blocks found (``window``,
    ``threshold``, ``min_duration``, ``trim``) or taken from a label column (``pose_column``,
    ``pose_map``); a gyroscope's known turns (``turns``, ``turn_angle``) or hand turns
    (``accel_cal``); the most of a log from stdin or a pipe kept for its second read
    (``max_spool``, a size: bytes or ``"500M"``; None: ``outputs.MAX_SPOOL`` or the room in $TMPDIR);
    a magnetometer's alignment to an accelerometer calibration's axes (``align_to``,
    pipeline.align)."""

    window: float | None = None
    threshold: float | None = None
    min_duration: float | None = None
    trim: float | None = None
    pose_column: str | None = None
    pose_map: str | Mapping[str, str] | None = None
    turns: str | Mapping[str, str] | None = None
    turn_angle: float | None = None
    accel_cal: str | None = None
    max_spool: int | str | None = None
    align_to: str | None = None  # a magnetometer's: the accelerometer calibration whose axes it is rotated onto


@dataclass(frozen=True)
class CheckOptions:
    """The quality checks a capture must pass (exit 3, docs/production-test.md)."""

    max_noise: float | None = None
    max_tilt: float = 25.0
    nominal_offset: Triplet | None = None
    full_scale: float | None = None
    min_samples: int = 10
    fixture_tolerance: float = 1.0
    gain_tolerance: float = 0.02
    no_checks: bool = False
    no_check: Sequence[str] = ()
    no_trim: bool = False  # a pose file that moved is rejected whole, not solved from its still run


@dataclass(frozen=True)
class LimitOptions:
    """The limits a unit is judged by (exit 1): a limits ``file`` and the flags over it."""

    file: str | None = None
    max_offset: Triplet | None = None
    max_gain_error: Triplet | None = None
    nominal_gain: Triplet | None = None


@dataclass(frozen=True)
class UnitOptions:
    """Who and what is calibrated (traceability)."""

    serial: str | None = None
    station: str | None = None
    operator: str | None = None
    meta: Sequence[str] | Mapping[str, str] = ()


@dataclass(frozen=True)
class SolveOptions:
    """solve's options (docs/commands/solve.md), grouped: how the files are ``read``, how a ``log`` is
    cut, the ``checks`` (exit 3), the ``limits`` (exit 1) and the ``unit``; the method's own
    options at the top. :meth:`of` makes them of the flat values the command line, batch and
    the Python API give (``SolveKeywords``)."""

    method: str = "auto"
    reference: float | None = None
    up: str | None = None
    tilt_compensate: bool = False
    bias_spread: float | None = None
    plane: str | None = None
    units: str | None = None
    input_units: str | None = None
    rows_are_poses: bool | None = None  # each row of the capture a pose (None: when it looks so)
    no_robust: bool = False  # a fit over samples keeps its outliers (plain least squares)
    axes: str | None = None  # the body's axes in the sensor's (-y,-x,+z): core.axes, folded into the matrix
    spin: tuple[str, ...] = ()  # a gyroscope's RATE=FILE items (pipeline.solve.spins)
    location: str | None = None  # LAT,LON[,HEIGHT_M]: the reference from the place (pipeline.places)
    gravity: float | None = None  # local gravity in m/s^2, given
    date: str | None = None  # YYYY-MM-DD: a magnetometer's Earth field on that day
    field_model: str | None = None  # that field's model: wmm (None) or wmmhr (core.earth.FIELD_MODELS)
    read: ReadSpec = field(default_factory=ReadSpec)
    log: LogOptions = field(default_factory=LogOptions)
    checks: CheckOptions = field(default_factory=CheckOptions)
    limits: LimitOptions = field(default_factory=LimitOptions)
    unit: UnitOptions = field(default_factory=UnitOptions)

    @classmethod
    def of(cls, given: Mapping[str, object]) -> SolveOptions:
        """The one mapper from solve's flat option values to SolveOptions: the options named as
        the command line names them (``reference=``, ``max_noise=``, ``limits=`` for a limits
        file, ``serial=`` ...; ``SolveKeywords``), what is not given left at its default. An enum
        is its value; a repeatable option (``meta``, ``no_check``) takes a list, and None for
        none (the command line's when it is not given). A name it does not know is a TypeError,
        as for a function's keyword."""
        for name in given:
            if name not in FLAT:
                raise TypeError(f"SolveOptions.__init__() got an unexpected keyword argument {name!r}")
        choices_and_numbers(given)  # before a Dialect judges --skip-rows and --decimal, as checked() does
        groups: dict[str, dict[str, object]] = {g: {} for g in ("", "read", *GROUPS)}
        for name, value in given.items():
            value = getattr(value, "value", value)
            if name in REPEATABLE and (value is None or isinstance(value, list | tuple)):  # each an enum's or text
                value = tuple(getattr(v, "value", v) for v in value or ())
            group, key = FLAT[name]
            groups["read" if group == "dialect" else group][key] = value
        read = read_spec(cast(ReadKeywords, groups.pop("read")))
        parts = {g: kind(**groups.pop(g)) for g, kind in GROUPS.items()}
        return cls(**groups.pop(""), read=read, **parts)  # type: ignore[arg-type]

    def flat(self) -> dict[str, object]:
        """Each option by the command line's name (as :meth:`of` takes them)."""
        out: dict[str, object] = {}
        for name, (group, key) in FLAT.items():
            holder = self if not group else self.read.dialect if group == "dialect" else getattr(self, group)
            out[name] = getattr(holder, key)
        return out


#: The groups of SolveOptions besides ``read`` (a ReadSpec), each a dataclass of flat options.
GROUPS: dict[str, type] = {"log": LogOptions, "checks": CheckOptions, "limits": LimitOptions, "unit": UnitOptions}
#: The flat names that are not their field's name: ``limits=`` is the limits group's file.
RENAMED = {("limits", "file"): "limits"}
#: The options given once per item, repeatable on the command line (a tuple in SolveOptions).
REPEATABLE = ("meta", "no_check", "spin")
#: Each option's flat name (the command line's long option in snake case) and where SolveOptions
#: keeps it: its group ("" the top; "read" and "dialect" the ReadSpec's) and its field there. A
#: field added to SolveOptions or one of its groups (or a keyword to io.readspec.ReadKeywords) is
#: an option here; SolveKeywords names it for the Python API (tests/test_options.py holds the two
#: and the command's parameters to each other).
FLAT: dict[str, tuple[str, str]] = {
    **{f.name: ("", f.name) for f in fields(SolveOptions) if f.name != "read" and f.name not in GROUPS},
    **{name: ("dialect" if name in {f.name for f in fields(Dialect)} else "read", name) for name in READ_NAMES},
    **{RENAMED.get((g, f.name), f.name): (g, f.name) for g, kind in GROUPS.items() for f in fields(kind)},
}


class CutKeywords(TypedDict, total=False):
    """How a continuous log is cut into still blocks (LogOptions), as solve and segment take it."""

    window: float | None
    threshold: float | None
    min_duration: float | None
    trim: float | None
    pose_column: str | None
    pose_map: str | Mapping[str, str] | None


class SolveKeywords(ReadKeywords, CutKeywords, total=False):
    """solve's and solve_log's keyword options (and run_batch's ``options``): the command line's
    long options in snake case, each a flat name of :data:`FLAT` (how the file is read:
    ``ReadKeywords``)."""

    method: str
    reference: float | None
    up: str | None
    tilt_compensate: bool
    bias_spread: float | None
    plane: str | None
    units: str | None
    input_units: str | None
    rows_are_poses: bool | None
    no_robust: bool
    axes: str | None
    spin: str | Sequence[str] | None
    location: str | None
    gravity: float | None
    date: str | None
    field_model: str | None
    # how a continuous log is cut (LogOptions): CutKeywords, and
    turns: str | Mapping[str, str] | None
    turn_angle: float | None
    accel_cal: str | os.PathLike[str] | None
    max_spool: int | str | None
    align_to: str | None
    # the quality checks (CheckOptions)
    max_noise: float | None
    max_tilt: float
    nominal_offset: Triplet | None
    full_scale: float | None
    min_samples: int
    fixture_tolerance: float
    gain_tolerance: float
    no_checks: bool
    no_check: str | Sequence[str] | None
    no_trim: bool
    # the limits (LimitOptions; ``limits`` its file)
    limits: str | None
    max_offset: Triplet | None
    max_gain_error: Triplet | None
    nominal_gain: Triplet | None
    # the unit (UnitOptions)
    serial: str | None
    station: str | None
    operator: str | None
    meta: str | Sequence[str] | Mapping[str, str] | None


#: The units a size may be given in (--max-spool 500M): powers of 1024.
SIZE_UNITS = {"": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}


def size_option(value: int | str | None, flag: str) -> int | None:
    """A size option (``flag``) in bytes: a whole number of bytes, or text with a unit: ``500M``,
    ``4G``, ``1.5GB`` (K, M, G, T: powers of 1024). None stays None."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | str):
        raise InputError(f"{flag} takes a size: bytes, or with K, M, G or T (500M, 4G), got {value!r}")
    if isinstance(value, str):
        found = re.fullmatch(r"\s*(\d+(?:\.\d*)?|\.\d+)\s*([kmgt]?)(?:i?b)?\s*", value, re.IGNORECASE)
        if found is None:
            raise InputError(f"{flag} takes a size: bytes, or with K, M, G or T (500M, 4G), got {value!r}")
        value = int(float(found.group(1)) * SIZE_UNITS[found.group(2).lower()])
    if value <= 0:
        raise InputError(f"{flag} must be more than 0 bytes, got {value}")
    return value


def size_text(size: int) -> str:
    """A size as :func:`size_option` takes it, to three digits: 2M, 4G, 1.5G, 812 bytes."""
    for unit in "TGMK":
        if size >= SIZE_UNITS[unit.lower()]:
            value = size / SIZE_UNITS[unit.lower()]
            return f"{value:.3g}{unit}" if value < 100 else f"{value:.0f}{unit}"
    return f"{size} bytes"


def keywords_known(given: Mapping[str, object], known: type, function: str) -> None:
    """A keyword that ``known`` (a TypedDict) does not hold is a TypeError, as Python says it of
    a function's unknown keyword."""
    names = known.__required_keys__ | known.__optional_keys__  # type: ignore[attr-defined]
    for key in given:
        if key not in names:
            raise TypeError(f"{function}() got an unexpected keyword argument {key!r}")


@dataclass(frozen=True)
class Settings:
    """SolveOptions resolved: the method asked for, the --up face, the reference, the nominal
    offset (None: not given), the limits, the unit block and the label -> face map of a log."""

    method: str
    up: str
    reference: float
    centre: FloatArray | None
    limits: Limits
    unit: Unit
    pose_map: dict[str, str]


#: The options only a continuous log takes (solve --log).
LOG_ONLY = tuple(f.name for f in fields(LogOptions) if f.name != "align_to")
#: ... of which these find the still blocks that --align-to aligns on, in a pose file too.
ALIGN_BLOCKS = ("window", "threshold", "min_duration", "trim")
#: The choices of the options that take one (the command line's own enums).
CHOICES = {
    "time_unit": ("auto", "s", "ms", "us", "ns"),
    "decimal": (".", ","),
    "plane": ("xy", "xz", "yz"),
    "field_model": ("wmm", "wmmhr"),
}
CHECK_NAMES = catalog.check_names()
NUMBERS = (
    "reference",
    "gravity",
    "bias_spread",
    "rate",
    "window",
    "threshold",
    "min_duration",
    "trim",
    "max_noise",
    "max_tilt",
    "full_scale",
    "fixture_tolerance",
    "gain_tolerance",
    "turn_angle",
)


def choices_and_numbers(given: Mapping[str, object]) -> None:
    """Each choice one of its own, each number a number, among the options ``given`` by the
    command line's names (the checks the parser makes)."""
    for name, allowed in {"method": ("auto", *catalog.names()), "sensor": SENSORS, **CHOICES}.items():
        value = given.get(name)
        if value is not None and value not in allowed:
            raise InputError(f"--{name.replace('_', '-')}: {value!r} is not one of {', '.join(allowed)}")
    for name in NUMBERS:
        value = given.get(name)
        if value is not None and (isinstance(value, bool) or not isinstance(value, int | float)):
            raise InputError(f"--{name.replace('_', '-')} takes a number, got {value!r}")


def checked(options: SolveOptions) -> SolveOptions:
    """The checks the command line's parser makes, for options given in Python: each choice
    one of its own, numbers numbers, ranges kept; a lone string where a list goes is one item."""

    choices_and_numbers(options.flat())
    if options.rows_are_poses is not None and not isinstance(options.rows_are_poses, bool):
        raise InputError(f"rows_are_poses is True, False or None (decide by the rows), got {options.rows_are_poses!r}")
    checks = options.checks
    if isinstance(checks.min_samples, bool) or not isinstance(checks.min_samples, int) or checks.min_samples < 1:
        raise InputError(f"--min-samples takes a whole number of 1 or more, got {checks.min_samples!r}")
    if not 0 <= checks.fixture_tolerance <= 30:
        raise InputError(f"--fixture-tolerance is 0 to 30 degrees, got {checks.fixture_tolerance:g}")
    if not (math.isfinite(checks.gain_tolerance) and 0 <= checks.gain_tolerance < 1):
        tolerance = checks.gain_tolerance
        raise InputError(f"--gain-tolerance is a fraction from 0 to below 1 (0.02: ±2 %), got {tolerance:g}")
    if not checks.max_tilt <= 180:
        raise InputError(f"--max-tilt is at most 180 degrees, got {checks.max_tilt:g}")
    no_check = [checks.no_check] if isinstance(checks.no_check, str) else list(checks.no_check)
    for name in no_check:
        if name not in CHECK_NAMES:
            raise InputError(f"--no-check: {name!r} is not one of {', '.join(CHECK_NAMES)}")
    meta = [options.unit.meta] if isinstance(options.unit.meta, str) else options.unit.meta
    axes_given(options.axes)
    return replace(options, checks=replace(checks, no_check=tuple(no_check)), unit=replace(options.unit, meta=meta))


def axes_given(text: object, flag: str = "--axes") -> Axes | None:
    """``--axes`` (the body's x, y and z as signed sensor axes: ``-y,-x,+z``) as core.axes.Axes;
    None when not given or the identity (+x,+y,+z states nothing)."""
    if text is None:
        return None
    if not isinstance(text, str):
        raise InputError(f"{flag} takes text such as -y,-x,+z, not a {type(text).__name__}")
    try:
        found = axes.parse(text)
    except ValueError as err:
        raise InputError(f"{flag} {text!r}: {err}") from None
    return None if found.identity else found


def in_axes(cal: Calibration, text: str | None) -> Calibration:
    """``cal`` correcting into the body's axes of --axes (core.axes), when it states none of its
    own; one that does is refused (its axes are the sensor's mounting, given once)."""
    if text is None:
        return cal
    axes = axes_given(text)
    if cal.axes is not None and cal.axes != axes:
        raise InputError(
            f"corrects into its own axes {cal.axes.text} already: --axes {text} would turn them again",
            file=cal.path,
            hint="leave --axes out (the calibration's axes apply), or solve again with the axes wanted",
        )
    return cal if axes is None else cal.in_axes(axes)


def settings(options: SolveOptions, *, log: bool) -> Settings:
    """The checks of solve's options that no pose file is needed for: the log's options, --meta,
    the method, --up, the reference, the nominal offset and the limits (``options`` as
    :func:`checked` returns them)."""
    if not log:
        aligns = options.log.align_to is not None
        given = [
            f"--{name.replace('_', '-')}"
            for name in LOG_ONLY
            if getattr(options.log, name) is not None and not (aligns and name in ALIGN_BLOCKS)
        ]
        if given:
            raise InputError(f"{given[0]} is for a continuous log (--log), not --poses files")
    mapping = pose_map(options.log.pose_map)
    size_option(options.log.max_spool, "--max-spool")
    who = unit_block(options.unit.serial, options.unit.station, options.unit.operator, options.unit.meta)
    method, sensor = options.method, options.read.sensor
    chosen = "one-pose-tilt" if options.tilt_compensate and method == "auto" else method
    if options.tilt_compensate and chosen != "one-pose-tilt":
        raise InputError(f"--tilt-compensate is the one-pose-tilt method, not {chosen}")
    up_face = face(options.up or "+z", "--up")
    turn_options(options, log=log)
    if method == "gyro-bias" and sensor != "gyroscope":  # one error, not one per unit
        raise InputError(said("gyro.sensor", sensor=sensor))
    for option, value in (
        ("--max-noise", options.checks.max_noise),
        ("--max-tilt", options.checks.max_tilt),
        ("--full-scale", options.checks.full_scale),
    ):
        if value is not None and not value > 0:
            raise InputError(f"{option} must be positive, got {value:g}")
    ref = options.reference if options.reference is not None else (0.0 if sensor == "gyroscope" else 1.0)
    if not math.isfinite(ref) or ref < 0 or (ref == 0 and sensor != "gyroscope"):
        raise InputError(
            f"--reference must be a positive number, got {ref:g}",
            hint="the stimulus magnitude: 1 (g), 9.80665 (m/s^2), 16384 (counts); 0 only for --sensor gyroscope",
        )
    if 0 < ref < sys.float_info.min:  # subnormal: the gains (readings / reference) overflow
        raise InputError(
            f"--reference {ref:g} is too small to divide by (the smallest is {sys.float_info.min:.3g})",
            hint="the stimulus magnitude in the corrected output's units: 1 (g), 9.80665 (m/s^2), 16384 (counts)",
        )
    for flag, named in (("--units", options.units), ("--input-units", options.input_units)):
        measure = None if named is None else quantities.UNITS.get(named.strip())
        if measure is not None and measure.quantity != quantities.QUANTITY[sensor]:
            raise InputError(
                f"{flag} {named} is a unit of {measure.quantity}, and {_a(sensor)} measures "
                f"{quantities.QUANTITY[sensor]}",
                hint=f"{_a(sensor)}'s units: {', '.join(quantities.COMMON[quantities.QUANTITY[sensor]])}"
                + ("" if sensor == "magnetometer" else f"; or --sensor {_sensor_of(measure.quantity)}"),
            )
    if sensor == "gyroscope" and ref != 0:  # at rest it reads no rate, and turns give their own angles
        raise InputError(
            f"--reference is a gyroscope's reading at rest, which is 0, got {ref:g}",
            hint="leave --reference out for --sensor gyroscope: its gains come from known rates (--spin 45rpm=FILE) "
            "or turns (--turns, --accel-cal)",
        )
    centre = (
        None if options.checks.nominal_offset is None else triplet(options.checks.nominal_offset, "--nominal-offset")
    )
    bounds = limits(
        options.limits.file,
        options.limits.max_offset,
        options.limits.max_gain_error,
        options.limits.nominal_gain,
        nominal_offset=centre,
    )
    return Settings(chosen, up_face, ref, centre, bounds, who, mapping)


def _a(sensor: str) -> str:
    return f"{'an' if sensor[0] in 'aeiou' else 'a'} {sensor}"


def _sensor_of(quantity: str) -> str:
    return next(k for k, v in quantities.QUANTITY.items() if v == quantity)


def turn_options(options: SolveOptions, *, log: bool) -> None:
    """--turns and --turn-angle: a gyroscope's labelled turns in one log, the angle known;
    --accel-cal: its hand turns between still poses."""

    if options.log.accel_cal is not None and options.read.sensor == "magnetometer":  # its dip check
        if not log or options.log.pose_column is not None or options.log.turns is not None:
            raise InputError(
                "--accel-cal: a magnetometer's dip check takes one continuous --log with both sensors, its still "
                "blocks found (no --pose-column)"
            )
        return
    if options.log.accel_cal is not None or options.method == "rotations":
        if options.log.accel_cal is None:
            raise InputError(
                "rotations takes the gravity directions from an accelerometer calibration: give --accel-cal"
            )
        if (
            options.read.sensor != "gyroscope"
            or options.log.turns is not None
            or options.method not in ("auto", "rotations")
        ):
            raise InputError(
                "--accel-cal is for a gyroscope's hand turns: --sensor gyroscope with --log, without --turns "
                "(method rotations)"
            )
        if not log or options.log.pose_column is not None:
            raise InputError(
                "--accel-cal: the hand turns of one continuous --log, its still blocks found (no --pose-column)"
            )
        return
    if options.log.turns is None and catalog.family(options.method) != "turns":
        if options.log.turn_angle is not None:
            raise InputError("--turn-angle is the angle of the --turns sections: give --turns too")
        return
    if options.log.turns is None:
        raise InputError(
            f"{options.method} takes the turns of a labelled log: give --turns LABEL=AXIS,... and --turn-angle",
            hint="e.g. --turns x_rot=+x,y_rot=+y,z_rot=+z --turn-angle 360",
        )
    if options.method != "auto" and catalog.family(options.method) != "turns":
        raise InputError(f"--turns is for the ferraris-turns method, not {options.method}")
    if options.read.sensor != "gyroscope":
        raise InputError(f"--turns calibrates a gyroscope: give --sensor gyroscope (not {options.read.sensor})")
    if not log or options.log.pose_column is None:
        raise InputError(
            "--turns names sections of a labelled log: give it with --log and its label column with --pose-column",
            hint="e.g. --log session.csv --pose-column part --pose-map x_p=+x,x_a=-x,... --turns x_rot=+x,...",
        )
    angle = options.log.turn_angle
    if angle is None or not (math.isfinite(angle) and 0 < abs(angle) <= 3600):
        raise InputError(
            "--turn-angle: the signed angle of each turn in degrees (right-hand rule about its axis), "
            f"0 < |angle| <= 3600, got {'nothing' if angle is None else f'{angle:g}'}",
            hint="e.g. --turn-angle 360 (or -360: the sign the gyroscope reads turning, as imucal's expected_angle)",
        )
    if not pose_map(options.log.turns, "--turns"):
        raise InputError("--turns names no section: give LABEL=AXIS pairs, e.g. x_rot=+x,y_rot=+y,z_rot=+z")


def method_options(name: str, ref: float, plane: str | None, bias_spread: float | None) -> None:
    """The options that only some methods take, once the method is known."""
    if ref == 0 and not catalog.at_rest(name):
        raise InputError(
            f"--reference 0 (a gyroscope at rest) gives {name} no stimulus to fit gains or directions to",
            hint="use --method gyro-bias for the zero-rate bias, or give the files' rates with --spin RATE=FILE "
            "(45rpm=a.csv)",
        )
    for flag, given, wanted in (("--plane", plane, "minmax"), ("--bias-spread", bias_spread, "one-pose-tilt")):
        if given is not None and name != wanted:
            raise InputError(f"{flag} is for the {wanted} method, not {name}")
    if bias_spread is not None and not (math.isfinite(bias_spread) and bias_spread >= 0):
        raise InputError(f"--bias-spread must be a number of 0 or more (the bias's 1-sigma spread), got {bias_spread}")


def face(text: str, option: str) -> str:
    """A face (+x ... -z, or an alias) given to ``option``."""

    try:
        return model.parse_face(text)
    except ValueError as err:
        raise InputError(f"{option}: {err}") from None


def pose_map(value: str | Mapping[str, str] | None, option: str = "--pose-map") -> dict[str, str]:
    """--pose-map ``x_p=+x,x_a=-x,...`` (or a mapping) as {label: face}; ``option`` names the
    option in errors (--turns takes the same LABEL=AXIS pairs)."""

    items = [f"{k}={v}" for k, v in value.items()] if isinstance(value, Mapping) else (value or "").split(",")
    out: dict[str, str] = {}
    for item in items:
        if not item.strip():
            continue
        label, sep, name = item.partition("=")
        if not sep or not label.strip():
            pairs = "LABEL=FACE pairs, e.g. x_p=+x,x_a=-x"
            if option == "--turns":
                pairs = "LABEL=AXIS pairs, e.g. x_rot=+x,y_rot=+y"
            raise InputError(f"{option} {item!r}: write {pairs}")
        try:
            face = model.parse_face(name)
        except ValueError as err:
            raise InputError(f"{option} {item}: {err}") from None
        if out.get(label.strip(), face) != face:  # which would it be?
            raise InputError(f"{option} gives label {label.strip()!r} twice: {out[label.strip()]} and {face}")
        out[label.strip()] = face
    return out


def limits(
    path: str | None,
    max_offset: Triplet | None,
    max_gain_error: Triplet | None,
    nominal_gain: Triplet | None,
    *,
    nominal_offset: FloatArray | None = None,
) -> Limits:
    """The limits of a limits file, with the flags taking precedence (``nominal_offset``, solve's
    --nominal-offset: the centre of the offset limit unless the file names one)."""

    bounds: dict[str, object] = dict(limitfile.load_limits(path)) if path else {}
    for key in (*limitfile.NOISE_LIMITS, *limitfile.ALIGN_LIMITS, *limitfile.CURRENT_LIMITS):  # ... and theirs
        bounds.pop(key, None)
    if nominal_offset is not None:
        bounds.setdefault("nominal_offset", nominal_offset)
    for key, given, option in (
        ("offset", max_offset, "--max-offset"),
        ("gain_error", max_gain_error, "--max-gain-error"),
        ("nominal_gain", nominal_gain, "--nominal-gain"),
    ):
        if given is not None:
            value = triplet(given, option)
            if (value <= 0).any():
                raise InputError(f"{option} must be positive, got {given!r}")
            if not (value <= 1e100).all():  # (1e308 overflowed the units check)
                raise InputError(f"{option} must be a number up to 1e100, got {given!r}")
            bounds[key] = value
    return gate.Limits(**bounds, nominal_gain_given="nominal_gain" in bounds)  # type: ignore[arg-type]


def unit_block(
    serial: str | None, station: str | None, operator: str | None, meta: Sequence[str] | Mapping[str, str]
) -> Unit:
    """The unit block of a calibration; --meta items are KEY=VALUE."""

    for flag, value in (("--serial", serial), ("--station", station), ("--operator", operator)):
        identifier(value, flag)
    pairs: dict[str, str] = {}
    if isinstance(meta, Mapping):
        pairs = {str(k): str(v) for k, v in meta.items()}
    for item in [] if isinstance(meta, Mapping) else meta:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise InputError(f"--meta takes KEY=VALUE, got {item!r}")
        pairs[key.strip()] = value
    for key, value in pairs.items():
        identifier(key, "--meta")
        identifier(value, "--meta")
    return Unit(serial, station, operator, pairs)


def identifier(value: str | None, flag: str) -> None:
    """A serial, a station ... is one line of text: a control character (a newline, NUL) in it
    would split a summary row or an error message."""
    if value is not None and not isinstance(value, str):
        raise InputError(f"{flag} is text, not a {type(value).__name__}: {value!r}")
    bad = None if value is None else control_character(value)
    if bad is not None:
        raise InputError(f"{flag} {value!r} holds a control character (U+{ord(bad):04X})")


def path_of(value: object, what: str) -> str:
    """A path given as text or os.PathLike; anything else is an InputError saying ``what``."""
    if isinstance(value, str | os.PathLike):
        return os.fspath(value)
    raise InputError(f"{what}, not a {type(value).__name__}")
