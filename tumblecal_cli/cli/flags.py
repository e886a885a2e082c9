"""Options and choices that several commands share, defined once."""

from __future__ import annotations

import os
from enum import StrEnum
from typing import TYPE_CHECKING, Annotated, TypedDict

import typer

from tumblecal_cli.core import catalog
from tumblecal_cli.errors import InputError

EXIT_CODES = """\
Exit status, the first that applies: 2 usage or input error (bad file, bad option, wrong
number of files, a units mistake); 3 capture rejected by a quality check (moved, not the
pose it claims, saturated, too short, upside down); 1 calibrated but outside its limits;
0 pass. The calibration is written on 0 and 1, nothing on 2 or 3."""

#: The word every --json output gives its exit status as ("status"; the number is "exit_status").
STATUS_WORDS = {0: "pass", 1: "fail", 2: "error", 3: "rejected"}


class SensorKind(StrEnum):
    accelerometer = "accelerometer"
    magnetometer = "magnetometer"
    gyroscope = "gyroscope"


class TimeUnit(StrEnum):
    auto = "auto"
    s = "s"
    ms = "ms"
    us = "us"
    ns = "ns"


#: The panel of the options that say how to read a file (its columns, header, time, span).
READ_PANEL = "Reading the files"

Sensor = Annotated[
    SensorKind,
    typer.Option(
        "--sensor",
        help="Which sensor; picks the columns when a file holds several triplets (acc*, gyr*, mag*).",
    ),
]

Columns = Annotated[
    str | None,
    typer.Option(
        "--columns",
        metavar="X,Y,Z",
        help="The sensor columns, X,Y,Z: header names or 0-based indices. Default: detected.",
        rich_help_panel=READ_PANEL,
    ),
]

AxesOption = Annotated[
    str | None,
    typer.Option(
        "--axes",
        metavar="A,B,C",
        help="The body's x, y, z as signed sensor axes (-y,-x,+z): faces and corrected readings are the body's, "
        "offsets the sensor's.",
        rich_help_panel=READ_PANEL,
    ),
]

NoHeader = Annotated[
    bool,
    typer.Option(
        "--no-header",
        help="The first line is data. 3 columns are x,y,z; 4 are t,x,y,z.",
        rich_help_panel=READ_PANEL,
    ),
]

TimeColumn = Annotated[
    str | None,
    typer.Option(
        "--time-column",
        metavar="NAME",
        help="The time column (default: t, time, timestamp, time_s or ts).",
        rich_help_panel=READ_PANEL,
    ),
]

TimeUnitOption = Annotated[
    TimeUnit,
    typer.Option(
        "--time-unit",
        help="Unit of the time column. auto: from its name (timestamp_ms, t_us), else from its spacing "
        "(a step of 1-1000 is ms, to 1e6 us, to 1e9 ns), with a note.",
        rich_help_panel=READ_PANEL,
    ),
]


class DecimalMark(StrEnum):
    point = "."
    comma = ","


SkipRows = Annotated[
    int | None,
    typer.Option(
        "--skip-rows",
        metavar="N",
        min=0,
        help="Lines before the header to skip. Default: a station's metadata lines (fewer fields than the "
        "header, e.g. Fs,100) are found and skipped, with a note.",
        rich_help_panel=READ_PANEL,
    ),
]

Decimal = Annotated[
    DecimalMark | None,
    typer.Option(
        "--decimal",
        help="The numbers' decimal mark. Default: ',' when every number of a ; or tab separated file has one "
        "(European spreadsheet exports), else '.'.",
        rich_help_panel=READ_PANEL,
    ),
]

DropIncomplete = Annotated[
    bool,
    typer.Option(
        "--drop-incomplete",
        help="Drop a last line cut short (a logger stopped mid-write) with a warning, instead of exit 2.",
        rich_help_panel=READ_PANEL,
    ),
]

Rate = Annotated[
    float | None,
    typer.Option(
        "--rate",
        metavar="HZ",
        help="Sample rate in Hz: durations when there is no time column; a log's time, instead of its time column.",
    ),
]

Quiet = Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing on stderr unless there is an error.")]

Verbose = Annotated[
    bool, typer.Option("--verbose", "-v", help="Also print the detail: per pose (and per block of a log) its figures.")
]

StreamOption = Annotated[
    str | None,
    typer.Option(
        "--stream",
        metavar="NAME[:INSTANCE]",
        help="A log's stream, where it holds several: sensor_accel:1 in a PX4 ULog, IMU:1 in an ArduPilot DataFlash "
        "log, /imu/data_raw in a ROS bag (`tumblecal logs FILE` lists them). A stream that carries several sensors "
        "(sensor_combined, IMU, a bag's Imu topic) gives the one --sensor names. "
        "[default: the log's one raw stream of --sensor]",
        rich_help_panel=READ_PANEL,
    ),
]

AllowCorrected = Annotated[
    bool,
    typer.Option(
        "--allow-corrected",
        help="Read a stream the autopilot has already corrected (PX4's sensor_combined, vehicle_imu; ArduPilot's "
        "IMU, ACC, GYR and MAG unless the log's PARM holds no calibration; a bag's imu/data): refused "
        "without it, as a fit of it calibrates the residual, not the sensor.",
        rich_help_panel=READ_PANEL,
    ),
]


class StreamArguments(TypedDict):
    """The pipeline's keyword arguments for a log's stream (``source``)."""

    stream: str | None
    allow_corrected: bool


def source(stream: str | None, allow_corrected: bool) -> StreamArguments:
    """--stream and --allow-corrected as the pipeline's keyword arguments."""
    return {"stream": stream, "allow_corrected": allow_corrected}


#: --location, --gravity and --date: the reference where the unit is (docs/real-world.md)
PLACE_PANEL = "The reference where you are"

Location = Annotated[
    str | None,
    typer.Option(
        "--location",
        metavar="LAT,LON[,HEIGHT_M]",
        help="Where the unit was calibrated (degrees north, east; metres above the WGS-84 ellipsoid): the "
        "reference becomes local gravity (WGS-84 normal gravity) in g or m/s^2, or with --date a magnetometer's "
        "Earth field (the World Magnetic Model of that date) in uT or gauss. Instead of --reference.",
        rich_help_panel=PLACE_PANEL,
    ),
]

Gravity = Annotated[
    float | None,
    typer.Option(
        "--gravity",
        metavar="M/S2",
        help="Local gravity as measured, in m/s^2: the reference in the calibration's units (g or m/s^2). "
        "Instead of --reference and --location.",
        rich_help_panel=PLACE_PANEL,
    ),
]

Date = Annotated[
    str | None,
    typer.Option(
        "--date",
        metavar="YYYY-MM-DD",
        help="With --location, the day a magnetometer was logged: the Earth's field of that day, of the World "
        "Magnetic Model release that holds then (WMM2010, WMM2015v2, WMM2020, WMM2025: 2010-01-01 to 2029-12-31).",
        rich_help_panel=PLACE_PANEL,
    ),
]


class FieldModelName(StrEnum):
    wmm = "wmm"
    wmmhr = "wmmhr"


FieldModel = Annotated[
    FieldModelName | None,
    typer.Option(
        "--field-model",
        help="With --location and --date, the magnetic model: wmm (the World Magnetic Model, degree 12, the "
        "release of the date) or wmmhr (its high-resolution model WMMHR2025, degree 133: 2025-01-01 to "
        "2029-12-31). [default: wmm]",
        rich_help_panel=PLACE_PANEL,
    ),
]

RowsArePoses = Annotated[
    bool | None,
    typer.Option(
        "--rows-are-poses/--no-rows-are-poses",
        help="Each row of the file is one pose (a table of averaged orientations, one row each). Without either, "
        "an unlabelled file with no time column whose rows turn from one to the next by more than 10° is taken "
        "so, with a note. [default: by the rows]",
        show_default=False,
        rich_help_panel=READ_PANEL,
    ),
]

Start = Annotated[
    str | None,
    typer.Option(
        "--start",
        metavar="S|Nr",
        help="Read from here on: seconds from the capture's first reading (by its time column, or --rate), or "
        "a 0-based data row with an r (1200r: the rows the notes and a calibration's poses give). [default: "
        "the first reading]",
        rich_help_panel=READ_PANEL,
    ),
]

End = Annotated[
    str | None,
    typer.Option(
        "--end",
        metavar="S|Nr",
        help="Read up to here, this reading included: seconds or a data row, as --start. [default: the last reading]",
        rich_help_panel=READ_PANEL,
    ),
]


if TYPE_CHECKING:  # the one member the code names; the others are the catalog's

    class MethodName(StrEnum):
        auto = "auto"

else:
    #: The ``--method`` choices: auto, then every solver of core.catalog in its order (a row
    #: registered before the command line is imported is offered too).
    MethodName = StrEnum("MethodName", {name: name for name in ("auto", *catalog.names())})


def method_help() -> str:
    """``--method``'s help: auto, then the catalog's solvers by name."""
    return (
        "The solver: auto (the summary says what it chose and why: docs/commands/solve.md), "
        + ", ".join(catalog.names())
        + "."
    )


class PlaneName(StrEnum):
    xy = "xy"
    xz = "xz"
    yz = "yz"


if TYPE_CHECKING:  # the checks are core.catalog's

    class CheckName(StrEnum):
        coverage = "coverage"

else:
    #: The ``--no-check`` choices: every quality check of core.catalog.
    CheckName = StrEnum("CheckName", {name.replace("-", "_"): name for name in catalog.check_names()})


JsonSummary = Annotated[
    bool,
    typer.Option(
        "--json",
        help="Print a machine-readable summary on stdout: status, verdict or rejections (with codes), "
        "parameters, uncertainties.",
    ),
]

LIMITS_PANEL = "Limits (exit 1)"


def limit_option(flag: str, metavar: str, help: str) -> object:  # Typer's OptionInfo, for Annotated
    return typer.Option(flag, metavar=metavar, help=help, rich_help_panel=LIMITS_PANEL)


LimitsFile = Annotated[
    str | None,
    limit_option(
        "--limits",
        "FILE",
        "Limits file (YAML/JSON: offset, gain_error, cross_axis, noise, residual...: docs/production-test.md).",
    ),
]

MaxOffset = Annotated[
    str | None,
    limit_option(
        "--max-offset", "V|X,Y,Z", "limit.offset.*: bound on |offset| per axis, raw units (overrides the limits file)."
    ),
]

MaxGainError = Annotated[
    str | None,
    limit_option(
        "--max-gain-error",
        "F|X,Y,Z",
        "limit.gain.*: bound on |gain / nominal - 1|, e.g. 0.03 for 3% (overrides the limits file).",
    ),
]

NominalGain = Annotated[
    str | None,
    limit_option(
        "--nominal-gain",
        "G|X,Y,Z",
        "The gain a perfect unit has, raw units per output unit: 1, or 2048 for counts at 2048 LSB/g.",
    ),
]

CHECKS_PANEL = "Quality checks (exit 3)"

SOLVER_PANEL = "Solver details"

UNIT_PANEL = "Traceability"

#: The records database a run also records into (docs/records.md); TUMBLECAL_RECORD gives its default.
RecordDb = Annotated[
    str | None,
    typer.Option(
        "--record",
        metavar="DB",
        envvar="TUMBLECAL_RECORD",
        show_envvar=False,
        help="Also record the result in the records database DB (a SQLite file, made if new, or a "
        "postgresql:// URL), in the same run: if it cannot be recorded, exit 2 and no file is written. "
        "[env: TUMBLECAL_RECORD]",
        rich_help_panel=UNIT_PANEL,
    ),
]

LotName = Annotated[
    str | None,
    typer.Option(
        "--lot", metavar="TEXT", help="The production lot, as --record records it.", rich_help_panel=UNIT_PANEL
    ),
]

LOG_PANEL = "Finding the still blocks of a log (segment, solve --log)"


def log_option(flag: str, metavar: str, help: str, panel: str | None = LOG_PANEL) -> object:  # as limit_option
    return typer.Option(flag, metavar=metavar, help=help, rich_help_panel=panel)


Turns = Annotated[
    str | None,
    log_option(
        "--turns",
        "LABEL=AXIS,...",
        "A gyroscope's known turns (method ferraris-turns, with --sensor gyroscope and --pose-column): the "
        "sections of the label column that turn the unit about a sensor axis, e.g. x_rot=+x,y_rot=+y,z_rot=+z. "
        "The --pose-map faces give the bias and the g-sensitivity (the accelerometer columns of the same log).",
    ),
]

TurnAngle = Annotated[
    float | None,
    log_option(
        "--turn-angle",
        "DEG",
        "The angle of each --turns section in degrees, signed by the right-hand rule about its axis (the sign "
        "the gyroscope reads), e.g. 360; imucal's expected_angle is the same number.",
    ),
]

AccelCal = Annotated[
    str | None,
    log_option(
        "--accel-cal",
        "FILE",
        "A gyroscope's hand turns (method rotations, with --sensor gyroscope and --log): the accelerometer "
        "calibration that gives each still block's gravity direction; the gyroscope is integrated over each "
        "rotation between still blocks. No labels, no known angles.",
    ),
]

AlignTo = Annotated[
    str | None,
    log_option(
        "--align-to",
        "ACCEL_CAL",
        "A magnetometer's capture that holds the accelerometer's columns too: rotate the magnetometer's axes "
        "onto those of this accelerometer calibration (its matrix times the rotation `tumblecal align` finds "
        "from the still blocks), and report the heading error that removes.",
    ),
]

Window = Annotated[
    float | None,
    log_option(
        "--window",
        "S|N",
        "Rolling window of the stillness detector: seconds when the log has a time column or --rate, "
        "else samples. [default: 0.5 s, or 25 samples]",
    ),
]

Threshold = Annotated[
    float | None,
    log_option(
        "--threshold",
        "V",
        "A sample is still when the rolling standard deviation (root of the three axes' variances, raw "
        "units) is below V. [default: 3 x the log's noise floor, its 10th percentile; printed]",
    ),
]

MinDuration = Annotated[
    float | None,
    log_option(
        "--min-duration",
        "S|N",
        "Drop still blocks shorter than this (seconds, else samples). [default: 1 s, or 50 samples]",
    ),
]

Trim = Annotated[
    float | None,
    log_option(
        "--trim",
        "S|N",
        "Cut this much off each end of a still period (seconds, else samples). [default: half the window]",
    ),
]

PoseColumn = Annotated[
    str | None,
    log_option(
        "--pose-column",
        "NAME",
        "Take the blocks from a label column instead of the detector: each run of one label is a block.",
    ),
]

PoseMap = Annotated[
    str | None,
    log_option(
        "--pose-map",
        "LABEL=FACE,...",
        "The face of each label of --pose-column, e.g. x_p=+x,x_a=-x,y_p=+y,y_a=-y,z_p=+z,z_a=-z "
        "(labels that are faces need none; unmapped labels, such as rotations, are dropped).",
    ),
]

MaxSpool = Annotated[
    str | None,
    log_option(
        "--max-spool",
        "SIZE",
        "A log from stdin or a pipe (it cannot be read twice) is copied to $TMPDIR: stop with exit 2 when the "
        "copy would grow past SIZE, in bytes or with K, M, G or T (500M, 4G). A log in a file is not copied. "
        "[default: 4G, or the free space in $TMPDIR less a margin (256M, or a tenth of it) when that is less]",
    ),
]


class RegisterSign(StrEnum):
    subtract = "subtract"
    add = "add"


REGISTERS_PANEL = "Registers (--format registers)"


class FileShape(TypedDict):
    """The pipeline's keyword arguments for the shape of a capture file (``file_shape``)."""

    skip_rows: int | None
    decimal: str | None
    drop_incomplete: bool


def file_shape(skip_rows: int | None, decimal: DecimalMark | None, drop_incomplete: bool) -> FileShape:
    """--skip-rows, --decimal and --drop-incomplete as the pipeline's keyword arguments."""
    return {"skip_rows": skip_rows, "decimal": decimal and decimal.value, "drop_incomplete": drop_incomplete}


def check_plot_target(plot: str, output: str, json_summary: bool, inputs: list[str]) -> None:
    """Refuse a --plot path that cannot work, before any work (matplotlib missing is one): the
    check of every command that draws (solve, thermal, report, verify, segment, noise)."""
    from tumblecal_cli.io.figures import plots
    from tumblecal_cli.io.outputs import check_not_input, check_writable

    plots.require()
    if plot == "-" and (output == "-" or json_summary):
        raise InputError("--plot - would share stdout with the data", hint="give --plot FILE.png")
    if plot != "-" and not plot.lower().endswith(".png"):
        raise InputError("--plot writes a PNG image: give a file name ending in .png", file=plot)
    if plot != "-" and output != "-" and os.path.abspath(plot) == os.path.abspath(output):
        raise InputError("--plot and -o name the same file", file=plot)
    check_not_input(plot, inputs, "--plot")
    check_writable(plot, "--plot")
