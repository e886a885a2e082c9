"""The command line: parse, call io and core, tell people on stderr, map errors to exit codes.

numpy, pyarrow and the io modules are imported inside the commands, so ``tumblecal --help``
and ``--version`` pay only for Typer. Errors become exit codes in exactly one place, ``main``.
"""

from __future__ import annotations

import contextlib
import inspect  # Typer imports it anyway
import math
import os
import re
import sys
import time
from enum import StrEnum
from typing import TYPE_CHECKING, Annotated, Any

import typer
from typer.core import TyperCommand

from tumblecal_cli import __version__
from tumblecal_cli.errors import CaptureRejected, InputError, Interrupted, PipeClosed, TumblecalError

if TYPE_CHECKING:
    from collections.abc import Iterator

    from rich.console import Console

    from tumblecal_cli.captures import Samples
    from tumblecal_cli.core import FloatArray, PoseStats
    from tumblecal_cli.gate import Corrected, Finding, PoseCheck

EXIT_CODES = """\
Exit status, the first that applies: 2 usage or input error (bad file, bad option, wrong
number of files, a units mistake); 3 capture rejected by a quality check (moved, not the
pose it claims, saturated, too short, upside down); 1 calibrated but outside its limits;
0 pass. The calibration is written on 0 and 1, nothing on 2 or 3."""

# The solvers' matrices are 3x3 to 12x12: BLAS threads only cost start-up and spin (see core.apply).
# Set before numpy is first imported (lazily, inside the commands); a user's own setting wins.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

app = typer.Typer(
    name="tumblecal",
    help="Calibrate 3-axis sensors from static tumble poses, and correct captures with the result.",
    epilog=EXIT_CODES,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
    context_settings={"help_option_names": ["-h", "--help"]},
)
_state = {"debug": False}


class Command(TyperCommand):
    """Plain help, with the options grouped under the ``rich_help_panel`` each one names."""

    def format_options(self, ctx: Any, formatter: Any) -> None:
        sections: dict[str, list[tuple[str, str]]] = {}
        for param in self.get_params(ctx):
            record = param.get_help_record(ctx)
            if record is not None:
                kind = "Arguments" if param.param_type_name == "argument" else "Options"
                sections.setdefault(getattr(param, "rich_help_panel", None) or kind, []).append(record)
        for title, records in sorted(sections.items(), key=lambda kv: kv[0] != "Arguments"):
            with formatter.section(title):
                formatter.write_dl(records)


class ManyValuesCommand(Command):
    """Lets ``--poses a.csv b.csv c.csv`` take every file after one flag.

    Click options have a fixed arity, so before parsing, each value that follows ``--poses``
    (up to the next option) becomes its own ``--poses=VALUE``. ``-`` (stdin) is a value, and so
    is a labelled item whose label starts with '-' (``-x=xn.csv``).
    """

    many = ("--poses", "-p")

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        out: list[str] = []
        flag: str | None = None
        for arg in args:
            name = arg.split("=", 1)[0]
            if arg == "--":
                flag = None
            elif name in self.many:
                flag = name
                if "=" in arg:
                    out.append(arg)
                    continue
                if arg == name:
                    out.append(arg)
                    continue
            elif flag and (arg == "-" or not arg.startswith("-") or _is_labelled(arg)):
                if out[-1] == flag:  # the flag's own value: keep the flag, give it the value with '='
                    out.pop()
                out.append(f"--poses={arg}")  # '=' so that '-x=xn.csv' is a value, not an option
                continue
            else:
                flag = None
            out.append(arg)
        return super().parse_args(ctx, out)


def _is_labelled(arg: str) -> bool:
    """Whether ``arg`` looks like a pose item ``LABEL=FILE`` whose label starts with '-'
    (``-x=xn.csv``, ``-0.5,0,0.87=a.csv``), not an option. (A pattern, not core.parse_label:
    parsing the command line must not import numpy.) The label is validated later."""
    label, sep, _ = arg.partition("=")
    number = r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?"
    return bool(sep) and re.fullmatch(rf"[-+][xyz]|{number},{number},{number}", label.lower()) is not None


def _version(value: bool) -> None:
    if value:
        typer.echo(f"tumblecal {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool, typer.Option("--version", callback=_version, is_eager=True, help="Print the version and exit.")
    ] = False,
    debug: Annotated[bool, typer.Option("--debug", help="Show the traceback of an error.")] = False,
) -> None:
    _state["debug"] = debug


class SensorKind(StrEnum):
    accelerometer = "accelerometer"
    magnetometer = "magnetometer"
    gyroscope = "gyroscope"


class TimeUnit(StrEnum):
    s = "s"
    ms = "ms"
    us = "us"
    ns = "ns"


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
    ),
]
NoHeader = Annotated[
    bool,
    typer.Option("--no-header", help="The first line is data. 3 columns are x,y,z; 4 are t,x,y,z."),
]
TimeColumn = Annotated[
    str | None,
    typer.Option("--time-column", metavar="NAME", help="The time column (default: t, time, timestamp, time_s or ts)."),
]
TimeUnitOption = Annotated[TimeUnit, typer.Option("--time-unit", help="Unit of the time column.")]
Rate = Annotated[
    float | None,
    typer.Option(
        "--rate",
        metavar="HZ",
        help="Sample rate in Hz: durations when there is no time column; a log's time, instead of its time column.",
    ),
]
Quiet = Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing on stderr unless there is an error.")]


class MethodName(StrEnum):
    auto = "auto"
    one_pose = "one-pose"
    one_pose_tilt = "one-pose-tilt"
    three_pose = "three-pose"
    six_pose = "six-pose"
    six_pose_diagonal = "six-pose-diagonal"
    least_squares = "least-squares"
    sphere = "sphere"
    minmax = "minmax"
    ellipsoid = "ellipsoid"
    gyro_bias = "gyro-bias"


class PlaneName(StrEnum):
    xy = "xy"
    xz = "xz"
    yz = "yz"


class CheckName(StrEnum):
    moved = "moved"
    orientation = "orientation"
    saturated = "saturated"
    short = "short"
    upside_down = "upside-down"


JsonSummary = Annotated[
    bool,
    typer.Option(
        "--json",
        help="Print a machine-readable summary on stdout: status, verdict or rejections with their codes, "
        "parameters, uncertainties, per-pose diagnostics.",
    ),
]
LIMITS_PANEL = "Limits (exit 1)"


def _limit_option(flag: str, metavar: str, help: str) -> Any:
    return typer.Option(flag, metavar=metavar, help=help, rich_help_panel=LIMITS_PANEL)


LimitsFile = Annotated[
    str | None,
    _limit_option(
        "--limits",
        "FILE",
        "Limits file (YAML/JSON: offset, gain_error, nominal_gain, cross_axis, noise, residual; see README).",
    ),
]
MaxOffset = Annotated[
    str | None,
    _limit_option(
        "--max-offset", "V|X,Y,Z", "limit.offset.*: bound on |offset| per axis, raw units (overrides the limits file)."
    ),
]
MaxGainError = Annotated[
    str | None,
    _limit_option(
        "--max-gain-error",
        "F|X,Y,Z",
        "limit.gain.*: bound on |gain / nominal - 1|, e.g. 0.03 for 3% (overrides the limits file).",
    ),
]
NominalGain = Annotated[
    str | None,
    _limit_option(
        "--nominal-gain",
        "G|X,Y,Z",
        "The gain a perfect unit has, raw units per output unit: 1, or 2048 for counts at 2048 LSB/g.",
    ),
]


CHECKS_PANEL = "Quality checks (exit 3)"
UNIT_PANEL = "Traceability"
LOG_PANEL = "Finding the still blocks of a log (segment, solve --log)"


def _log_option(flag: str, metavar: str, help: str, panel: str | None = LOG_PANEL) -> Any:
    return typer.Option(flag, metavar=metavar, help=help, rich_help_panel=panel)


Window = Annotated[
    float | None,
    _log_option(
        "--window",
        "S|N",
        "Rolling window of the stillness detector: seconds when the log has a time column or --rate, "
        "else samples. [default: 0.5 s, or 25 samples]",
    ),
]
Threshold = Annotated[
    float | None,
    _log_option(
        "--threshold",
        "V",
        "A sample is still when the rolling standard deviation (root of the three axes' variances, raw "
        "units) is below V. [default: 3 x the log's noise floor, its 10th percentile; printed]",
    ),
]
MinDuration = Annotated[
    float | None,
    _log_option(
        "--min-duration",
        "S|N",
        "Drop still blocks shorter than this (seconds, else samples). [default: 1 s, or 50 samples]",
    ),
]
Trim = Annotated[
    float | None,
    _log_option(
        "--trim",
        "S|N",
        "Cut this much off each end of a still period (seconds, else samples). [default: half the window]",
    ),
]
PoseColumn = Annotated[
    str | None,
    _log_option(
        "--pose-column",
        "NAME",
        "Take the blocks from a label column instead of the detector: each run of one label is a block.",
    ),
]
PoseMap = Annotated[
    str | None,
    _log_option(
        "--pose-map",
        "LABEL=FACE,...",
        "The face of each label of --pose-column, e.g. x_p=+x,x_a=-x,y_p=+y,y_a=-y,z_p=+z,z_a=-z "
        "(labels that are faces need none; unmapped labels, such as rotations, are dropped).",
    ),
]


@app.command(cls=ManyValuesCommand, epilog=EXIT_CODES)
def solve(
    poses: Annotated[
        list[str] | None,
        typer.Option(
            "--poses",
            "-p",
            metavar="FILE...",
            help="Pose files, all after one --poses; each FILE or LABEL=FILE, LABEL a face (+x -x +y -y +z -z, "
            "xp ... zn) or a direction X,Y,Z (0.707,0,0.707=a.csv). Unlabelled: 1 file is the --up face, "
            "3 are +x +y +z, 6 are +x -x +y -y +z -z, in that order; 12 or more, orientation unknown "
            "(sphere). A magnetometer's: one or more captures turned through many orientations. '-' reads stdin.",
        ),
    ] = None,
    log: Annotated[
        str | None,
        typer.Option(
            "--log",
            metavar="FILE",
            help="Instead of --poses: one continuous log, cut into still blocks as `tumblecal segment` does. "
            "Face solvers take the best block of each face (the longest within --max-tilt, ties to the "
            "quieter); sphere takes every kept block. auto: six-pose for six faces, least-squares for five, "
            "else sphere for 12+ blocks, else three-pose. '-' reads stdin.",
        ),
    ] = None,
    window: Window = None,
    threshold: Threshold = None,
    min_duration: MinDuration = None,
    trim: Trim = None,
    pose_column: PoseColumn = None,
    pose_map: PoseMap = None,
    output: Annotated[
        str,
        typer.Option(
            "--output", "-o", metavar="FILE", help="Calibration file: .json, or .yaml/.yml for YAML; '-' is stdout."
        ),
    ] = "-",
    up: Annotated[
        str | None,
        typer.Option(
            "--up",
            metavar="FACE",
            help="1-pose: the sensor axis pointing up, which reads +reference: +x -x +y -y +z -z "
            "(or xp xn yp yn zp zn). A sensor that reads -1 g on the axis pointing up is the opposite face. "
            "[default: +z]",
            show_default=False,
        ),
    ] = None,
    reference: Annotated[
        float | None,
        typer.Option(
            "--reference",
            metavar="NUMBER",
            help="The stimulus magnitude in the units the corrected data should have: 1 (g), "
            "9.80665 (m/s^2), 16384 (LSB at +-2 g), the local field for a magnetometer. "
            "The 1-pose solver has no gains, so there it must be in the file's units. "
            "[default: 1, or 0 for a gyroscope]",
        ),
    ] = None,
    method: Annotated[
        MethodName,
        typer.Option(
            "--method",
            "-m",
            help="The solver (README: Choosing a solver). auto: one-pose for 1 file, three-pose for +x +y +z, "
            "six-pose for the six faces, least-squares for 5+ labelled, sphere for 12+ unlabelled; "
            "ellipsoid for a magnetometer, gyro-bias for a gyroscope.",
        ),
    ] = MethodName.auto,
    sensor: Sensor = SensorKind.accelerometer,
    tilt_compensate: Annotated[
        bool,
        typer.Option(
            "--tilt-compensate",
            help="1-pose: take the attitude from the readings, so fixture tilt leaves the up offset alone "
            "(method one-pose-tilt).",
        ),
    ] = False,
    bias_spread: Annotated[
        float | None,
        typer.Option(
            "--bias-spread",
            metavar="V",
            help="one-pose-tilt: the spread (1σ) of the horizontal offsets, in the file's units; it bounds "
            "the up offset's error. [default: 0.01 x reference]",
        ),
    ] = None,
    plane: Annotated[
        PlaneName | None,
        typer.Option("--plane", help="minmax: the capture turned in one plane only (2-D); that plane's axes."),
    ] = None,
    units: Annotated[
        str | None,
        typer.Option("--units", metavar="TEXT", help="Label of the corrected units (default 'g' for reference 1)."),
    ] = None,
    input_units: Annotated[
        str | None, typer.Option("--input-units", metavar="TEXT", help="Label of the raw units, e.g. counts.")
    ] = None,
    columns: Columns = None,
    no_header: NoHeader = False,
    time_column: TimeColumn = None,
    time_unit: TimeUnitOption = TimeUnit.s,
    rate: Rate = None,
    json_summary: JsonSummary = False,
    quiet: Quiet = False,
    plot: Annotated[
        str | None,
        typer.Option(
            "--plot",
            metavar="PNG",
            help="Also draw the poses' norms before and after calibration against the reference, with residual "
            "bars (a magnetometer: its samples in three planes with the fitted ellipse); needs tumblecal[plot].",
        ),
    ] = None,
    # -- quality checks (exit 3) --
    max_noise: Annotated[
        float | None,
        typer.Option(
            "--max-noise",
            metavar="FRACTION",
            help="pose.moved: reject a pose whose standard deviation, or drift between its first and last "
            "third, is above FRACTION x reference in corrected units. For a gyroscope it is in its units, "
            "and the check runs only when given; the turning captures of minmax and ellipsoid are not "
            "judged. [default: 0.02]",
            rich_help_panel=CHECKS_PANEL,
        ),
    ] = None,
    max_tilt: Annotated[
        float,
        typer.Option(
            "--max-tilt",
            metavar="DEGREES",
            max=180,
            help="pose.orientation: reject a pose further than this from the face it is declared as.",
            rich_help_panel=CHECKS_PANEL,
        ),
    ] = 25.0,
    nominal_offset: Annotated[
        str | None,
        typer.Option(
            "--nominal-offset",
            metavar="V|X,Y,Z",
            help="Raw value at zero stimulus, removed before judging a pose's direction "
            "(raw counts from an unsigned ADC sit near 32768). [default: 0; with --log, the per-axis "
            "midpoint of the block means]",
            rich_help_panel=CHECKS_PANEL,
        ),
    ] = None,
    full_scale: Annotated[
        float | None,
        typer.Option(
            "--full-scale",
            metavar="V",
            help="pose.saturated: reject a pose with any |sample| >= 0.98 V (raw units). Without it, "
            "integer data at the limits of a 16-bit type is clipped.",
            rich_help_panel=CHECKS_PANEL,
        ),
    ] = None,
    min_samples: Annotated[
        int,
        typer.Option(
            "--min-samples",
            metavar="N",
            min=1,
            help="pose.short: reject a pose with fewer rows (1 suits loggers that store one averaged row).",
            rich_help_panel=CHECKS_PANEL,
        ),
    ] = 10,
    fixture_tolerance: Annotated[
        float,
        typer.Option(
            "--fixture-tolerance",
            metavar="DEGREES",
            min=0,
            max=30,
            help="How far the fixture may be off level; sets tilt_sensitivity, the worst-case parameter shift.",
            rich_help_panel=CHECKS_PANEL,
        ),
    ] = 1.0,
    no_checks: Annotated[
        bool, typer.Option("--no-checks", help="Turn every quality check off.", rich_help_panel=CHECKS_PANEL)
    ] = False,
    skip: Annotated[
        list[CheckName] | None,
        typer.Option(
            "--no-check",
            metavar="CHECK",
            help="Turn one check off: moved, orientation, saturated, short or upside-down (repeatable).",
            rich_help_panel=CHECKS_PANEL,
        ),
    ] = None,
    # -- limits (exit 1) --
    limits_file: LimitsFile = None,
    max_offset: MaxOffset = None,
    max_gain_error: MaxGainError = None,
    nominal_gain: NominalGain = None,
    # -- traceability --
    serial: Annotated[
        str | None,
        typer.Option("--serial", metavar="TEXT", help="The unit's serial number.", rich_help_panel=UNIT_PANEL),
    ] = None,
    station: Annotated[
        str | None, typer.Option("--station", metavar="TEXT", help="The test station.", rich_help_panel=UNIT_PANEL)
    ] = None,
    operator: Annotated[
        str | None, typer.Option("--operator", metavar="TEXT", help="Who ran the test.", rich_help_panel=UNIT_PANEL)
    ] = None,
    meta: Annotated[
        list[str] | None,
        typer.Option(
            "--meta", metavar="KEY=VALUE", help="More about the unit (repeatable).", rich_help_panel=UNIT_PANEL
        ),
    ] = None,
) -> None:
    """Average each pose file, check it, solve for the offsets (and gains), judge the unit.

    Writes the calibration on exit 0 (pass) and 1 (outside its limits), nothing on 2 or 3.

    \b
      tumblecal solve --poses x.csv y.csv z.csv -o cal.json     # 3-pose
      tumblecal solve --poses z.csv -o cal.yaml                 # 1-pose, +z up
      tumblecal solve --poses z.csv --up=-x --reference 16384   # counts, -x up
      tumblecal solve -p x.csv y.csv z.csv -o cal.json --limits limits.yaml --serial A17 --json
      tumblecal solve --log session.csv --rate 102.4 --reference 9.81 -o cal.json   # one continuous log
    """
    from tumblecal_cli import calfile, captures, core, gate, solvers
    from tumblecal_cli import segment as seg_core
    from tumblecal_cli.files import check_not_input, check_writable

    if bool(poses) == (log is not None):
        raise InputError(
            "give the pose files with --poses, or one continuous log with --log" + (", not both" if poses else ""),
            hint="see 'tumblecal solve --help'",
        )
    chosen, up_face, ref, centre, limits_given = _solve_settings(
        log_given=log is not None,
        window=window,
        threshold=threshold,
        min_duration=min_duration,
        trim=trim,
        pose_column=pose_column,
        pose_map=pose_map,
        meta=meta,
        method=method,
        tilt_compensate=tilt_compensate,
        up=up,
        sensor=sensor,
        reference=reference,
        max_noise=max_noise,
        max_tilt=max_tilt,
        full_scale=full_scale,
        nominal_offset=nominal_offset,
        limits_file=limits_file,
        max_offset=max_offset,
        max_gain_error=max_gain_error,
        nominal_gain=nominal_gain,
    )
    name = chosen.value
    labels: list[str | None] = []
    files: list[str] = [] if log is None else [log]
    if poses:
        if up is not None and len(poses) != 1:
            raise InputError(
                f"--up names the face of a single pose file, not of {len(poses)}",
                hint="label each file instead (+x=xp.csv -x=xn.csv ...), or give them in the order +x +y +z",
            )
        items = _pose_items(poses, up_face)
        if sum(f == "-" for _, f in items) > 1:
            raise InputError("only one pose can be read from stdin ('-')")
        name, order = solvers.pick(chosen.value, [label for label, _ in items], sensor.value)
        items = [items[k] for k in order]
        labels = [None if name in solvers.ORIENTATION_FREE else label for label, _ in items]
        files = [f for _, f in items]
    if json_summary and output == "-":
        raise InputError("--json prints the summary on stdout, so the calibration needs -o FILE")
    check_not_input(output, [*files, *([limits_file] if limits_file else [])])
    check_writable(output)
    if plot is not None:
        _plot_target(plot, output, json_summary, [*files, *([limits_file] if limits_file else [])])
    gyro = sensor is SensorKind.gyroscope
    unit = _unit_block(serial, station, operator, meta or [])
    segmentation = None
    log_notes: list[str] = []  # how the blocks of a log were chosen
    whole: list[FloatArray] = []  # every reading of the unit: its integer type's rails
    if log is None:
        _method_options(name, ref, plane, bias_spread)
        picked = columns.split(",") if columns else None
        samples = [
            captures.read_samples(
                f,
                sensor=sensor.value,
                columns=picked,
                no_header=no_header,
                time_column=time_column,
                time_unit=time_unit.value,
                rate=rate,
            )
            for f in files
        ]
    else:
        if name != "auto":
            _method_options(name, ref, plane, bias_spread)
        settings = seg_core.Settings(
            window=window,
            threshold=threshold,
            min_duration=min_duration,
            trim=trim,
            max_noise=max_noise if max_noise is not None else 0.02,
            max_tilt_deg=max_tilt,
            nominal_offset=centre,
        )
        with _segmented(
            log,
            sensor=sensor.value,
            columns=columns,
            no_header=no_header,
            time_column=time_column,
            time_unit=time_unit.value,
            rate=rate,
            pose_column=pose_column,
            pose_map=pose_map,
            settings=settings,
        ) as (_, data, seg):
            pass  # every block is in memory: the log is not read again
        whole = [data.values]
        centre = seg.centre
        try:
            name, labels, samples, log_notes = _log_poses(data, seg, name, up_face, sensor.value)
        except CaptureRejected as err:
            if not quiet:
                _print_blocks(data, seg, _console(), used={}, everything=False)
            if json_summary:
                _print_json(_rejected_head(err))
            raise
        if not quiet:
            used = {
                int(s.block or 0): f"used: {label}" if label else "used"
                for s, label in zip(samples, labels, strict=True)
            }
            _print_blocks(data, seg, _console(), used=used, everything=False)
        _method_options(name, ref, plane, bias_spread)
        segmentation = {"log": data.layout.name, "sha256": data.sha256} | seg.as_dict()
    noise = max_noise if max_noise is not None else (None if gyro else 0.02)
    options = gate.Options(
        noise_bound=None if noise is None else (noise if gyro else noise * ref),  # a gyroscope: in its units
        noise_rule="" if noise is None else (f"{noise:g}" if gyro else f"{noise:g} × reference {ref:g}"),
        max_tilt_deg=max_tilt,
        nominal_offset=_triplet_option("0", "--nominal-offset") if centre is None else centre,
        full_scale=full_scale,
        min_samples=min_samples,
        skip=frozenset(gate.CHECKS if no_checks else [c.name for c in skip or []]),
        rails=gate.integer_rails(whole or [s.values for s in samples]),
    )
    stats = [core.pose_stats(s.values) for s in samples]
    names = [s.name for s in samples]
    if name in ("one-pose", "one-pose-tilt"):
        _check_units(names[0], stats[0].mean - options.nominal_offset, ref)
    try:
        fit = solvers.run(
            name,
            stats,
            [s.values for s in samples],
            labels,
            reference=ref,
            tolerance_deg=fixture_tolerance,
            bias_spread=bias_spread if bias_spread is not None else 0.01 * ref,
            plane=plane.value if plane else None,
            names=names,
        )
    except CaptureRejected as err:
        if log_notes and name == "sphere":  # auto's choice: say why, and the way back
            err.hint = f"{err.hint + '; ' if err.hint else ''}{log_notes[0]}"
        if json_summary:
            _print_json(_rejected_head(err))
        raise
    solution = fit.solution
    limits = limits_given.for_method(solution.method)
    measured = [
        gate.measure(n, f, s.values, st, options) for n, f, s, st in zip(names, labels, samples, stats, strict=True)
    ]
    if ref > 0:  # a gyroscope at rest has no direction to judge
        measured = gate.orient(measured, options.nominal_offset, options.max_tilt_deg)
    rejected, warned = gate.check(measured, solution, options)
    fixed = [
        gate.corrected(st.mean, st.std, f, solution.offset, solution.matrix, ref)
        for st, f in zip(stats, labels, strict=True)
    ]
    failures = (
        []
        if rejected
        else gate.verdict(
            solution.method,
            solution.offset,
            solution.matrix,
            list(zip(names, labels, fixed, strict=True)),
            limits,
            None if fit.residuals is None or not len(fit.residuals) else float(abs(fit.residuals).max()),
        )
    )
    doc = calfile.build(
        solution,
        sensor=sensor.value,
        reference=ref,
        units=units,
        input_units=input_units,
        columns=samples[0].layout.sensor_names,
        poses=[_pose_record(s, m, c) for s, m, c in zip(samples, measured, fixed, strict=True)],
        fit=fit,
        tolerance_deg=fixture_tolerance,
        unit=unit,
        verdict={"pass": not failures, "failures": [f.as_dict() for f in failures], "limits": limits.as_dict()},
        segmentation=segmentation,
    )
    notes = (
        log_notes
        + _tilt_notes(doc)
        + list(fit.notes)
        + _solve_notes(stats, names, limits_given=limits_given, method=solution.method)
    )
    if rejected:
        if not quiet:
            _print_summary(doc, _console(), warned, notes, judged=False)
        if json_summary:
            _print_json(_summary(doc, 3, None, rejected, warned, notes))
        first = rejected[0]
        raise CaptureRejected(
            first.render(),
            hint=first.hint or REJECTION_HINTS[first.code],
            more=tuple(f.render() for f in rejected[1:]),
            code=first.code,
            codes=tuple(f.code for f in rejected),
        )
    if plot is not None:  # drawn before the calibration is written: a failure leaves nothing behind
        _plot_solve(plot, doc, [s.values for s in samples], solution, limits_given, plane.value if plane else None)
    calfile.write(doc, output)
    status = 1 if failures else 0
    if not quiet:
        _print_summary(doc, _console(), warned, notes, judged=True)
        if output != "-":
            _console().print(f"wrote {output}", soft_wrap=True)
    if json_summary:
        _print_json(_summary(doc, status, output, [], warned, notes))
    if status:
        raise typer.Exit(status)


def _plot_target(plot: str, output: str, json_summary: bool, inputs: list[str]) -> None:
    """Refuse a --plot path that cannot work, before any work (matplotlib missing is one)."""
    from tumblecal_cli import plots
    from tumblecal_cli.files import check_not_input, check_writable

    plots.require()
    if plot == "-" and (output == "-" or json_summary):
        raise InputError("--plot - would share stdout with the data", hint="give --plot FILE.png")
    if plot != "-" and not plot.lower().endswith(".png"):
        raise InputError("--plot writes a PNG image: give a file name ending in .png", file=plot)
    if plot != "-" and output != "-" and os.path.abspath(plot) == os.path.abspath(output):
        raise InputError("--plot and -o name the same file", file=plot)
    check_not_input(plot, inputs, "--plot")
    check_writable(plot, "--plot")


def _plot_solve(
    plot: str, doc: dict[str, Any], raw: list[Any], solution: Any, limits: Any, plane: str | None = None
) -> None:
    """solve --plot: the poses' norms (seed 001's figure), or a magnetometer's rotation capture."""
    import numpy as np

    from tumblecal_cli import plots, solvers
    from tumblecal_cli.gate import FIXED_GAINS

    serial = (doc.get("unit") or {}).get("serial")
    title = f"{doc['sensor']}, {solution.method}" + (f", {serial}" if serial else "")
    units = doc.get("units")
    if solution.method in solvers.ROTATION:
        plots.rotation_figure(
            plot,
            np.concatenate(raw),
            solution.offset,
            solution.matrix,
            doc["reference"],
            units=units,
            title=title,
            plane=plane,
        )
        return
    if np.any(limits.nominal_gain != 1.0):  # given (--nominal-gain or the limits file)
        nominal = float(np.mean(limits.nominal_gain))
    else:  # else "before" is scaled by the mean solved gain: its shape, not its units
        nominal = 1.0 if solution.method in FIXED_GAINS else float(np.mean(solution.gain))
    names = [  # a log's blocks by number (they share the file), pose files by name
        " ".join(
            [
                *([p["pose"]] if p["pose"] else []),
                f"block {p['block']}" if "block" in p else os.path.basename(str(p["file"])),
            ]
        )
        for p in doc["poses"]
    ]
    means = np.array([p["mean"] for p in doc["poses"]], dtype=np.float64)
    plots.poses_figure(
        plot,
        names,
        means,
        solution.offset,
        solution.matrix,
        doc["reference"],
        nominal_gain=nominal,
        nominal_offset=limits.nominal_offset,  # --nominal-offset: unsigned counts' zero
        units=units,
        title=title,
    )


def _solve_settings(
    *,
    log_given: bool,
    window: float | None,
    threshold: float | None,
    min_duration: float | None,
    trim: float | None,
    pose_column: str | None,
    pose_map: str | None,
    meta: list[str] | None,
    method: MethodName,
    tilt_compensate: bool,
    up: str | None,
    sensor: SensorKind,
    reference: float | None,
    max_noise: float | None,
    max_tilt: float,
    full_scale: float | None,
    nominal_offset: str | None,
    limits_file: str | None,
    max_offset: str | None,
    max_gain_error: str | None,
    nominal_gain: str | None,
) -> tuple[MethodName, str, float, Any, Any]:
    """The checks of solve's options that no pose file is needed for (batch runs them once, before
    any unit): the log's options, --meta, the method, --up, the reference, the nominal offset and the limits."""
    if not log_given:
        log_only = (
            ("--window", window),
            ("--threshold", threshold),
            ("--min-duration", min_duration),
            ("--trim", trim),
            ("--pose-column", pose_column),
            ("--pose-map", pose_map),
        )
        given = [flag for flag, value in log_only if value is not None]
        if given:
            raise InputError(f"{given[0]} is for a continuous log (--log), not --poses files")
    _pose_map(pose_map)
    _unit_block(None, None, None, meta or [])
    chosen = MethodName.one_pose_tilt if tilt_compensate and method is MethodName.auto else method
    if tilt_compensate and chosen is not MethodName.one_pose_tilt:
        raise InputError(f"--tilt-compensate is the one-pose-tilt method, not {chosen.value}")
    up_face = _face(up or "+z", "--up")
    if method is MethodName.gyro_bias and sensor is not SensorKind.gyroscope:  # one error, not one per unit
        raise InputError(f"gyro-bias is a gyroscope's zero-rate bias: give --sensor gyroscope (not {sensor.value})")
    for option, value in (("--max-noise", max_noise), ("--max-tilt", max_tilt), ("--full-scale", full_scale)):
        if value is not None and not value > 0:
            raise InputError(f"{option} must be positive, got {value:g}")
    ref = reference if reference is not None else (0.0 if sensor is SensorKind.gyroscope else 1.0)
    if not math.isfinite(ref) or ref < 0 or (ref == 0 and sensor is not SensorKind.gyroscope):
        raise InputError(
            f"--reference must be a positive number, got {ref:g}",
            hint="the stimulus magnitude: 1 (g), 9.80665 (m/s^2), 16384 (counts); 0 only for --sensor gyroscope",
        )
    centre = None if nominal_offset is None else _triplet_option(nominal_offset, "--nominal-offset")
    limits = _limits(limits_file, max_offset, max_gain_error, nominal_gain, nominal_offset=centre)
    return chosen, up_face, ref, centre, limits


def _method_options(name: str, ref: float, plane: Any, bias_spread: float | None) -> None:
    """The options that only some methods take, once the method is known."""
    if ref == 0 and name not in ("one-pose", "minmax", "gyro-bias"):
        raise InputError(
            f"--reference 0 (a gyroscope at rest) gives {name} no stimulus to fit gains or directions to",
            hint="use --method gyro-bias for the zero-rate bias, or give the turning rate with --reference",
        )
    for flag, given, wanted in (("--plane", plane, "minmax"), ("--bias-spread", bias_spread, "one-pose-tilt")):
        if given is not None and name != wanted:
            raise InputError(f"{flag} is for the {wanted} method, not {name}")
    if bias_spread is not None and not (math.isfinite(bias_spread) and bias_spread >= 0):
        raise InputError(f"--bias-spread must be a number of 0 or more (the bias's 1-sigma spread), got {bias_spread}")


def _pose_items(items: list[str], up: str) -> list[tuple[str | None, str]]:
    """(label, file) of each --poses item, ``FILE`` or ``LABEL=FILE``; unlabelled files get the
    labels of their count (solvers.default_labels). Labels are for every file or for none."""
    from tumblecal_cli import core, solvers

    out: list[tuple[str | None, str]] = []
    for item in items:
        label, sep, rest = item.partition("=")
        try:
            out.append((core.parse_label(label), rest) if sep and label else (None, item))
        except ValueError as err:
            if "," in label:  # meant as a direction: say what is wrong with it
                raise InputError(f"--poses {item}: {err}") from None
            out.append((None, item))  # a file name with '=' in it
    if any(label is None for label, _ in out) and any(label is not None for label, _ in out):
        raise InputError(
            "label every pose file or none (LABEL=FILE, e.g. +x=xp.csv)",
            hint="unlabelled files are taken as 1: --up, 3: +x +y +z, 6: +x -x +y -y +z -z",
        )
    if out and out[0][0] is None:
        out = list(zip(solvers.default_labels(len(out), up), items, strict=True))
    return out


# -- continuous logs: segment and solve --log ------------------------------------------------


def _pose_map(text: str | None) -> dict[str, str]:
    """--pose-map ``x_p=+x,x_a=-x,...`` as {label: face}."""
    from tumblecal_cli import core

    out: dict[str, str] = {}
    for item in (text or "").split(","):
        if not item.strip():
            continue
        label, sep, face = item.partition("=")
        if not sep or not label.strip():
            raise InputError(f"--pose-map {item!r}: write LABEL=FACE pairs, e.g. x_p=+x,x_a=-x")
        try:
            out[label.strip()] = core.parse_face(face)
        except ValueError as err:
            raise InputError(f"--pose-map {item}: {err}") from None
    return out


@contextlib.contextmanager
def _segmented(
    log: str,
    *,
    sensor: str,
    columns: str | None,
    no_header: bool,
    time_column: str | None,
    time_unit: str,
    rate: float | None,
    pose_column: str | None,
    pose_map: str | None,
    settings: Any,
    digest: bool = True,
) -> Iterator[tuple[str, Any, Any]]:
    """Read a log ('-': stdin, kept in a temporary file until the block ends, for a second
    read) and find its blocks: (the path to read it again, captures.Log, segment.Segmentation)."""
    from tumblecal_cli import captures

    if sensor != "accelerometer":
        raise InputError(
            f"the still poses of a log are found and labelled by gravity: the accelerometer's, not the {sensor}'s",
            hint="cut the log with `tumblecal segment` (each block keeps every column), then solve the "
            f"{sensor}'s blocks with --poses and --sensor {sensor}",
        )
    if pose_map and not pose_column:
        raise InputError("--pose-map names the faces of a --pose-column's labels: give the column too")
    for option, value in (("--window", settings.window), ("--min-duration", settings.min_duration)):
        if value is not None and not value > 0:
            raise InputError(f"{option} must be positive, got {value:g}")
    for option, value in (("--threshold", settings.threshold), ("--trim", settings.trim)):
        if value is not None and not value >= 0:
            raise InputError(f"{option} must not be negative, got {value:g}")
    if rate is not None and not rate > 0:
        raise InputError(f"--rate must be positive, got {rate:g}")
    path = _spool_stdin() if log == "-" else log
    try:
        data = captures.read_log(
            path,
            sensor=sensor,
            columns=columns.split(",") if columns else None,
            no_header=no_header,
            time_column=time_column,
            time_unit=time_unit,
            label_column=pose_column,
            use_time=rate is None,
            name="<stdin>" if log == "-" else None,
            digest=digest,
        )
        yield path, data, _find_blocks(data, rate, pose_column, pose_map, settings)
    finally:
        if log == "-":
            os.unlink(path)


def _find_blocks(log: Any, rate: float | None, pose_column: str | None, pose_map: str | None, settings: Any) -> Any:
    """The blocks of a log read in: by the detector, or by its label column."""

    seconds = None if rate else log.seconds()
    seg = _blocks_of(log, seconds, rate, pose_column, pose_map, settings)
    name = log.layout.name
    if rate and log.clock is not None:
        column = log.layout.names[log.layout.time]
        seg.warnings.append(f"{name}: --rate {rate:g} is used, not the time column {column} (no gap or order check)")
    if seg.period is not None and seg.period >= 1.0 and seconds is not None:  # slower than 1 Hz: not an IMU's clock
        seg.warnings.append(
            f"{name}: the time column advances {seg.period:.3g} s per sample ({1 / seg.period:.3g} Hz); "
            "if it is not in seconds, give --time-unit ms, us or ns"
        )
    if seg.period is None and (settings.window is not None or settings.min_duration is not None) and not rate:
        seg.warnings.append(f"{name}: no time column and no --rate: --window and --min-duration are in samples")
    return seg


def _blocks_of(
    log: Any, seconds: Any, rate: float | None, pose_column: str | None, pose_map: str | None, settings: Any
) -> Any:
    from tumblecal_cli import core, segment

    if pose_column is None:
        return segment.detect(log.values, seconds, rate, settings)
    mapping = _pose_map(pose_map)
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
                mapping[label] = core.parse_face(label)
    if not any(label in mapping for label in labels):
        raise InputError(
            f"no label in column {pose_column!r} names a face (labels: {shown or 'none'})",
            file=log.layout.name,
            hint="say which is which with --pose-map, e.g. x_p=+x,x_a=-x,y_p=+y,y_a=-y,z_p=+z,z_a=-z",
        )
    seg = segment.from_labels(log.values, log.labels or [], mapping, seconds, rate, settings)
    if absent:
        seg.warnings.append(absent)
    return seg


def _enough_blocks(log: Any, seg: Any, need: int) -> None:
    """A log with fewer kept blocks than ``need`` has nothing to calibrate from (exit 3)."""

    kept = seg.kept
    if len(kept) >= need:
        return
    why = seg.dropped_counts()
    found = f"{len(seg.blocks)} found" + (f", dropped: {why}" if why else "")
    if seg.threshold is None:
        hint = "label the static parts of the log in --pose-column (and map them with --pose-map)"
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


#: A face block further than this from its face is not what a face solver assumes (exactly on
#: the face): with enough blocks, auto fits the sphere instead.
AUTO_FACE_TILT_DEG = 5.0


def _log_poses(
    log: Any, seg: Any, method: str, up: str, sensor: str
) -> tuple[str, list[str | None], list[Samples], list[str]]:
    """The method and the poses a log gives it: the best block of each face a face solver
    needs, or every kept block for an orientation-free one; and notes on that choice.

    ``auto`` with a hand-placed log (a face's block more than AUTO_FACE_TILT_DEG off its face)
    and 12 or more kept blocks fits the sphere: a face solver would take the tilt for cross-axis
    terms and correct other orientations worse than no calibration (seen on real logs)."""
    from tumblecal_cli import segment, solvers

    _enough_blocks(log, seg, 1 if method in ("one-pose", "one-pose-tilt") else 2)
    best, kept = seg.best(), seg.kept
    labels: list[str | None]
    notes: list[str] = []
    if method in solvers.ORIENTATION_FREE or (
        method == "auto" and len(best) < 5 and len(kept) >= solvers.SPHERE_MIN_POSES
    ):
        chosen, labels = kept, [None] * len(kept)
        method = "sphere" if method == "auto" else method
    else:
        wanted: list[str] = {
            "one-pose": [up],
            "one-pose-tilt": [up],
            "three-pose": list(solvers.THREE_FACES),
            "six-pose": list(solvers.SIX_FACES),
            "six-pose-diagonal": list(solvers.SIX_FACES),
        }.get(method, list(best))
        if method == "auto" and len(best) < 5:
            wanted = list(solvers.THREE_FACES)
        absent = [f for f in wanted if f not in best]
        if absent or len(wanted) < (solvers.LEAST_SQUARES_MIN_POSES if method == "least-squares" else 1):
            faces = " ".join(best) or "none"
            need = {
                "auto": "+x +y +z, five faces or all six (or 12 blocks for the sphere fit)",
                "least-squares": "five faces or more",
            }.get(method, " ".join(wanted))
            raise CaptureRejected(
                f"not the faces {method} needs ({need}); faces found: {faces}",
                file=log.layout.name,
                hint=(
                    "map each face's label with --pose-map; `tumblecal segment -v` lists every block"
                    if seg.threshold is None  # a labelled log
                    else "rest the unit on each missing face for --min-duration; `tumblecal segment` lists every block"
                ),
                more=tuple(segment.missing(seg, absent or [f for f in solvers.SIX_FACES if f not in best])),
                code="log.faces",
            )
        chosen, labels = [best[f] for f in wanted], list(wanted)
        if set(best) >= set(solvers.SIX_FACES) and method in ("auto", "six-pose", "six-pose-diagonal"):
            face, angle, number = _worst_face_tilt(best)
            if angle > AUTO_FACE_TILT_DEG:
                tilted = f"the {face} block ({number}) is {angle:.1f}° off its face"
                if method == "auto" and len(kept) >= solvers.SPHERE_MIN_POSES:
                    notes.append(
                        f"auto fits the sphere to all {len(kept)} still blocks: {tilted}, and six-pose takes "
                        "each block as exactly on its face (--method six-pose fits them anyway)"
                    )
                    chosen, labels, method = kept, [None] * len(kept), "sphere"
                elif method != "auto":
                    sphere = "; --method sphere fits tilted blocks" if len(kept) >= solvers.SPHERE_MIN_POSES else ""
                    notes.append(
                        f"{tilted}: {method} takes each block as exactly on its face, so the tilt goes into "
                        f"its parameters{sphere}"
                    )
    name, order = solvers.pick(method, labels, sensor)
    samples = [log.block(b.number, b.first, b.last) for b in chosen]
    return name, [labels[k] for k in order], [samples[k] for k in order], notes


def _worst_face_tilt(best: dict[str, Any]) -> tuple[str, float, int]:
    """The face block furthest from its face, as (face, degrees, block number), each direction
    taken about the midpoint of opposite faces' means (the offset cancels there, so a unit's
    own offset does not read as tilt)."""
    import numpy as np

    from tumblecal_cli import core

    centre = np.array([0.5 * (best[f"+{a}"].mean[i] + best[f"-{a}"].mean[i]) for i, a in enumerate("xyz")])
    worst = ("+x", 0.0, 0)
    for face, block in best.items():
        d = block.mean - centre
        if not np.any(d) or face not in core.FACES:
            continue
        angle = core.angle_deg(d, face)
        if angle > worst[1]:
            worst = (face, angle, int(block.number))
    return worst


def _block_files(seg: Any) -> dict[int, str]:
    """The file each kept block is written to: xp.csv ... for the best of each face, blockNN.csv else."""
    from tumblecal_cli import core

    alias = {face: name for name, face in core.FACE_ALIASES.items()}
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


def _index_rows(log: Any, seg: Any, files: dict[int, str]) -> list[list[str]]:
    """segments.csv: one row per block found, kept or dropped."""
    rows = []
    for b in seg.blocks:
        times = ["", ""] if log.clock is None else [repr(float(log.clock[b.first])), repr(float(log.clock[b.last]))]
        rows.append(
            [
                str(b.number),
                files.get(b.number, ""),
                "kept" if b.kept else "dropped",
                b.dropped or "",
                str(int(log.rows[b.first])),
                str(int(log.rows[b.last])),
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


def _print_blocks(log: Any, seg: Any, console: Console, *, used: dict[int, str], everything: bool) -> None:
    """The blocks for people (the kept ones; ``everything``: the dropped too), how they were
    found, and a hint for each face without a block."""
    from rich import box
    from rich.table import Table

    from tumblecal_cli import core, segment

    name = log.layout.name
    shown = seg.blocks if everything else seg.kept
    title = f"still blocks of {os.path.basename(name)}"
    table = Table(title=title, title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False, collapse_padding=True)
    for col in ("block", "rows", "start", "length", "face", "angle", "std", "status"):  # fits 80 columns
        table.add_column(col, justify="left" if col in ("face", "status", "rows") else "right", no_wrap=col != "status")
    for b in shown:
        if log.clock is not None:
            start = f"{float(log.clock[b.first]):.6g}"
        else:
            start = "" if seg.period is None else f"{b.first * seg.period:.4g} s"
        table.add_row(
            str(b.number),
            f"{int(log.rows[b.first])}-{int(log.rows[b.last])}",
            start,
            f"{b.duration:.3g} s" if b.duration is not None else str(b.samples),
            b.face or (f"({b.nearest})" if b.label is None else f"({b.label})"),
            f"{b.angle_deg:.1f}°",
            f"{float(b.std.max()):.3g}",
            used.get(b.number, "kept") if b.kept else f"dropped: {b.dropped}",
        )
    if shown:
        console.print(table)
    dropped = len(seg.blocks) - len(seg.kept)
    if dropped and not everything:
        console.print(f"{dropped} more dropped ({seg.dropped_counts()}); -v lists them", soft_wrap=True)
    if seg.threshold is not None:
        if seg.noise_floor is None:
            how = "given"
        elif seg.threshold == segment.FLOOR_FACTOR * seg.noise_floor:
            how = f"{segment.FLOOR_FACTOR:g} x the noise floor {seg.noise_floor:.4g}"
        else:  # readings that do not vary at all when still (segment.detect)
            how = f"the noise floor is {seg.noise_floor:.4g}: still means no spread at all"
        window = f"{seg.window * seg.period:.3g} s" if seg.period else f"{seg.window} samples"
        console.print(
            f"threshold {seg.threshold:.4g} ({how}; rolling std over {window}); "
            f"{len(seg.blocks)} block{'' if len(seg.blocks) == 1 else 's'} found, {len(seg.kept)} kept",
            soft_wrap=True,
        )
    for warning in seg.warnings:
        console.print(f"warning: {warning}", style="yellow", soft_wrap=True)
    if seg.gaps:
        console.print(
            f"warning: {name}: {len(seg.gaps)} gap{'s' if len(seg.gaps) > 1 else ''} in time (the first after data "
            f"row {int(log.rows[seg.gaps[0] - 1])}); no block spans a gap",
            style="yellow",
            soft_wrap=True,
        )
    best = seg.best()
    console.print(f"faces: {' '.join(f for f in core.FACES if f in best) or 'none'}", soft_wrap=True)
    for hint in segment.missing(seg, list(core.FACES)):
        console.print(f"hint: {hint}", soft_wrap=True)


def _spool_stdin() -> str:
    """stdin copied to a temporary file (a log is read twice: to find the blocks, then to copy them)."""
    import shutil
    import tempfile

    with tempfile.NamedTemporaryFile(prefix="tumblecal-", suffix=".csv", delete=False) as tmp:
        try:
            shutil.copyfileobj(sys.stdin.buffer, tmp)
        except BaseException:
            os.unlink(tmp.name)
            raise
    return tmp.name


REJECTION_HINTS = {
    "pose.short": "log the pose for longer, or lower --min-samples (1 for loggers that store one averaged row)",
    "pose.saturated": "the pose reaches the sensor's limits: use a wider range, or give the real one with --full-scale",
    "pose.orientation": "capture the pose again on its declared face, or raise --max-tilt for a tilted fixture",
    "pose.moved": "hold the unit still and capture the pose again, or raise --max-noise",
    "pose.upside_down": "give the files in the order +x +y +z, each with that axis pointing up",
}


def _face(text: str, option: str) -> str:
    from tumblecal_cli import core

    try:
        return core.parse_face(text)
    except ValueError as err:
        raise InputError(f"{option}: {err}") from None


def _triplet_option(text: str, option: str) -> Any:
    """A number or X,Y,Z from the command line, as a (3,) array."""
    import numpy as np

    parts = text.split(",")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) not in (1, 3) or not all(np.isfinite(values)):
        raise InputError(f"{option} takes one number or three (X,Y,Z), got {text!r}")
    return np.array(values * 3 if len(values) == 1 else values)


def _limits(
    path: str | None,
    max_offset: str | None,
    max_gain_error: str | None,
    nominal_gain: str | None,
    *,
    nominal_offset: Any = None,
) -> Any:
    """The limits of --limits FILE, with the flags taking precedence (``nominal_offset``, solve's
    --nominal-offset: the centre of the offset limit unless the file names one)."""
    from tumblecal_cli import calfile, gate

    bounds: dict[str, Any] = calfile.load_limits(path) if path else {}
    if nominal_offset is not None:
        bounds.setdefault("nominal_offset", nominal_offset)
    for key, text, option in (
        ("offset", max_offset, "--max-offset"),
        ("gain_error", max_gain_error, "--max-gain-error"),
        ("nominal_gain", nominal_gain, "--nominal-gain"),
    ):
        if text is not None:
            value = _triplet_option(text, option)
            if (value <= 0).any():
                raise InputError(f"{option} must be positive, got {text!r}")
            bounds[key] = value
    return gate.Limits(**bounds)


def _unit_block(serial: str | None, station: str | None, operator: str | None, meta: list[str]) -> dict[str, Any]:
    pairs: dict[str, str] = {}
    for item in meta:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise InputError(f"--meta takes KEY=VALUE, got {item!r}")
        pairs[key.strip()] = value
    return {"serial": serial, "station": station, "operator": operator, "meta": pairs}


def _check_units(name: str, centred: Any, reference: float) -> None:
    """A 1-pose mean (less --nominal-offset) far from --reference in magnitude: exit 2."""
    from tumblecal_cli import core

    suggested = core.units_mistake(centred, reference)
    if suggested is None:
        return
    magnitude = float((centred**2).sum() ** 0.5)
    if suggested == 0:
        raise InputError(
            f"the pose reads {magnitude:.4g} in magnitude but --reference is {reference:g}",
            file=name,
            hint="a pose at rest reads the reference: is the sensor working, and are these its columns?",
        )
    units = {1.0: "g", 9.80665: "m/s^2", 1000.0: "mg"}.get(suggested, "raw counts")
    raise InputError(
        f"the pose reads {magnitude:.4g} in magnitude but --reference is {reference:g}: a units mistake?",
        file=name,
        hint=f"the data looks like {units}: run with --reference {suggested:g} "
        "(the 1-pose solver has no gains, so --reference must be in the file's units)",
    )


def _pose_record(s: Samples, m: PoseCheck, c: Corrected) -> dict[str, Any]:
    """A pose's entry in the calibration file: what it was, what it measured, how it corrects."""
    record: dict[str, Any] = {
        "pose": m.face,
        "file": s.layout.name,
        "sha256": s.sha256,
        "rows": list(s.rows),
        **({} if s.block is None else {"block": s.block}),
        **({} if s.times is None else {"times": list(s.times)}),
        "samples": m.stats.samples,
        "mean": [float(v) for v in m.stats.mean],
        "std": [float(v) for v in m.stats.std],
    }
    if s.duration is not None:
        record["duration_s"] = s.duration
    if s.temperature is not None:
        record["temperature"] = s.temperature
    record["angle_deg"] = m.angle_deg
    record["clipped"] = m.clipped
    record["drift"] = [float(v) for v in m.drift]
    record["norm_error"] = c.norm_error
    record["vector_error"] = c.vector_error
    return record


def _tilt_notes(doc: dict[str, Any]) -> list[str]:
    """A note when fixture tilt, not noise, bounds how well the parameters are known."""
    tilt, se = doc.get("tilt_sensitivity"), doc["uncertainty"]
    if not tilt:
        return []
    dominated = [n for n in ("offset", "gain") if any(t > 3 * u for t, u in zip(tilt[n], se[n], strict=True))]
    if not dominated:
        return []
    worst = " and ".join(f"the {n}s by up to {max(tilt[n]):.2g} (noise: {max(se[n]):.2g})" for n in dominated)
    advice = "level the fixture better and state how well with --fixture-tolerance"
    if doc["method"] in ("one-pose", "three-pose"):
        advice += ", or capture the six faces (six-pose takes offsets and gains from vertical readings only)"
    return [
        f"fixture tilt, not noise, limits this calibration: {tilt['tolerance_deg']:g}° off level moves {worst}; "
        + advice
    ]


def _solve_notes(stats: list[PoseStats], names: list[str], *, limits_given: Any, method: str) -> list[str]:
    """What a person should know about how far the result can be trusted."""
    few = [(os.path.basename(name), st.samples) for name, st in zip(names, stats, strict=True) if st.samples < 3]
    effect = (
        "the uncertainty comes from the fit's residuals instead" if method == "sphere" else "its uncertainty reads 0"
    )
    notes = [
        f"{name} has {n} sample{'s' if n > 1 else ''}: its noise is unknown, "
        f"so {effect} and the moved check cannot judge it"
        for name, n in few[:3]
    ]
    if len(few) > 3:
        notes[2:] = [
            f"{len(few) - 2} more poses have fewer than 3 samples (noise unknown): {few[2][0]} ... {few[-1][0]}"
        ]
    notes += _limits_not_applying(limits_given, method)
    return notes


def _limits_not_applying(limits: Any, method: str) -> list[str]:
    """Notes for the limits given that do not apply to a method (gate.NOT_APPLYING)."""
    return [
        f"the {method} solver {why}, so the {name.replace('_', '-')} limit does not apply"
        for name, why in limits.not_applying(method).items()
    ]


def _summary(
    doc: dict[str, Any],
    status: int,
    output: str | None,
    rejected: list[Finding],
    warned: list[Finding],
    notes: list[str],
) -> dict[str, Any]:
    """The --json summary: the outcome, then the calibration's parameters and diagnostics."""
    head: dict[str, Any] = {
        "status": {0: "pass", 1: "fail", 3: "rejected"}[status],
        "exit_status": status,
        "file": output,
        "rejections": [f.as_dict() for f in rejected],
        "verdict": None if rejected else doc["verdict"],
        "warnings": [f.as_dict() for f in warned],
        "notes": notes,
    }
    keys = ("sensor", "method", "reference", "units", "columns", "offset", "matrix", "gain", "uncertainty")
    return head | {k: doc.get(k) for k in (*keys, "tilt_sensitivity", "poses", "unit")}


def _rejected_head(err: TumblecalError) -> dict[str, Any]:
    """The head of every summary (see _summary) for a rejection with no parameters to follow it."""
    head = {"status": "rejected", "exit_status": 3, "file": None, "rejections": [_error_dict(err)]}
    return head | {"verdict": None, "warnings": [], "notes": []}


def _error_dict(err: TumblecalError) -> dict[str, Any]:
    return {"code": err.code, "file": err.file, "message": err.message}


def _print_json(doc: dict[str, Any]) -> None:
    import json

    _print_text(json.dumps(doc, indent=2, ensure_ascii=False) + "\n")


def _print_text(text: str) -> None:
    """Data on stdout; a reader that went away (``| head``) is exit 141, not a traceback."""
    try:
        sys.stdout.write(text)
        sys.stdout.flush()
    except BrokenPipeError:
        raise PipeClosed("stdout closed") from None


@app.command(
    cls=Command,
    epilog="Exit status: 0 corrected; 2 usage or input error (nothing written, an existing output left as it was).",
)
def apply(
    capture: Annotated[
        list[str] | None,
        typer.Argument(
            metavar="CAPTURE...",
            help="The capture to correct; '-' (the default) reads stdin. Several captures, or a quoted glob "
            "('logs/*.csv', '**' too), need --out-dir.",
        ),
    ] = None,
    cal: Annotated[
        list[str],
        typer.Option(
            "--cal",
            "-c",
            metavar="FILE",
            help="Calibration file from 'tumblecal solve'. Repeat it to correct several sensors of one "
            "capture in one pass (accelerometer, gyroscope, magnetometer), each its own recorded columns "
            "(then --columns is refused).",
        ),
    ] = ...,  # type: ignore[assignment]
    output: Annotated[
        str, typer.Option("--output", "-o", metavar="FILE", help="Corrected capture; '-' (the default) is stdout.")
    ] = "-",
    columns: Columns = None,
    no_header: NoHeader = False,
    force: Annotated[
        bool,
        typer.Option("--force", help="Apply a calibration whose verdict failed (refused otherwise)."),
    ] = False,
    out_dir: Annotated[
        str | None,
        typer.Option(
            "--out-dir",
            "-d",
            metavar="DIR",
            help="Correct each capture into DIR under its own name (created if needed). A capture that fails "
            "is reported and the others go on.",
        ),
    ] = None,
    dask_scheduler: Annotated[
        str | None,
        typer.Option(
            "--dask-scheduler",
            metavar="ADDRESS",
            help="With --out-dir: correct the captures on a Dask distributed cluster, tcp://host:8786 "
            "(README: Dask). The captures, --cal and DIR must be at the same paths on every worker.",
        ),
    ] = None,
    quiet: Quiet = False,
) -> None:
    """Correct a capture: each sensor reading becomes M (raw - offset).

    Everything else is copied as it was: the header, the rows and their order, the text of
    every other column and the line endings. The sensor columns are the calibration's own
    (a capture without them is refused unless --columns names them), written with every
    digit needed to round-trip. A calibration whose unit failed its limits is refused
    unless --force.

    \b
      tumblecal apply --cal cal.json capture.csv -o corrected.csv
      cat capture.csv | tumblecal apply --cal cal.json > corrected.csv
      tumblecal apply --cal cal.json 'logs/*.csv' --out-dir corrected/
    """
    from functools import partial

    from tumblecal_cli import batch as batches
    from tumblecal_cli import calfile, captures
    from tumblecal_cli.files import atomic_output, check_not_input, check_writable

    inputs = batches.expand(capture or ["-"])
    if out_dir is not None or dask_scheduler is not None or len(inputs) > 1:
        if output != "-" and out_dir is not None:
            raise InputError("-o names one output; with --out-dir each capture is written into DIR under its own name")
        options = {"cal": cal, "columns": columns, "no_header": no_header, "force": force}
        _apply_many(inputs, options, out_dir, dask_scheduler, quiet=quiet)
        return
    one = inputs[0]
    if "-" in cal and one == "-":
        raise InputError("--cal - and the capture cannot both be read from stdin", hint="give the capture as a file")
    if cal.count("-") > 1:
        raise InputError("only one --cal can be read from stdin ('-')")
    check_not_input(output, [one, *cal])
    check_writable(output)
    cals = [calfile.load(path) for path in cal]
    _claims_once(cals)
    for c in cals:
        if c.failed and not force:
            _refuse_failed(c, "correct with it", "apply")
        if c.failed and not quiet:
            _console().print(
                f"note: {c.path}: this unit failed its limits; correcting with it as --force asks", soft_wrap=True
            )
    if columns and len(cals) > 1:
        raise InputError("--columns names the columns of one calibration; with several --cal each uses its own")
    picked = columns.split(",") if columns else None
    c = cals[0]
    with _capture_for(c, one, picked, no_header) as cap:
        used = cap.layout.sensor_names
        differ = [u.lower() for u in used] != [x.lower() for x in c.columns]
        if differ and (picked or not cap.layout.has_header):  # the user named them, or nothing is named
            if not quiet:
                _console().print(
                    f"note: {cap.layout.name}: correcting columns {', '.join(used)} "
                    f"(the calibration was made from {', '.join(c.columns)})",
                    soft_wrap=True,
                )
        elif differ:
            raise InputError(
                f"the capture's {c.sensor} columns are {', '.join(used)}, "
                f"but {c.path} calibrates {c.sensor} columns {', '.join(c.columns)}",
                file=cap.layout.name,
                hint=f"if they are the same sensor, name them: --columns {','.join(used)}",
            )
        taken = set(cap.layout.sensor)
        more = [(_columns_of(cap.layout, other, taken), other) for other in cals[1:]]
        with atomic_output(output) as out:
            rows = captures.correct_stream(
                cap, out, partial(_correct, c), more=[(t, partial(_correct, o)) for t, o in more]
            )
        used = [n for t in [cap.layout.sensor, *(t for t, _ in more)] for n in (cap.layout.names[i] for i in t)]
    if not quiet:
        target = "stdout" if output == "-" else output
        _console().print(f"corrected {rows} rows of {cap.layout.name} ({', '.join(used)}) -> {target}", soft_wrap=True)


def _apply_many(
    inputs: list[str], options: dict[str, Any], out_dir: str | None, scheduler: str | None, *, quiet: bool
) -> None:
    """apply over several captures, each into --out-dir under its own name, here or on Dask."""
    from tumblecal_cli import batch as batches
    from tumblecal_cli import calfile

    if out_dir is None:
        raise InputError(
            f"{len(inputs)} captures need --out-dir DIR (each is corrected into DIR under its own name)"
            if len(inputs) > 1
            else "--dask-scheduler corrects captures into --out-dir DIR"
        )
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
    for path in options["cal"]:  # a bad calibration is one error, before any capture
        if path == "-":
            raise InputError("--cal - is read once: with several captures give the calibration as a file")
        calfile.load(path)
    if scheduler is not None:  # the workers do not share this working folder
        inputs, outputs = [os.path.abspath(c) for c in inputs], [os.path.abspath(o) for o in outputs]
        options = dict(options, cal=[os.path.abspath(c) for c in options["cal"]])
    run = batches.engine(1, scheduler)
    os.makedirs(out_dir, exist_ok=True)
    failed = 0
    console = _console()
    for (_, name, _), outcome in run(
        batches.apply_one, [(options, c, o) for c, o in zip(inputs, outputs, strict=True)]
    ):
        if isinstance(outcome, BaseException):  # a worker lost on the cluster
            outcome = (name, 2, f"{name}: the worker correcting it failed: {type(outcome).__name__}: {outcome}")
        _, status, message = outcome
        if status:
            failed += 1
            _report(message, None)
        elif not quiet:
            console.print(
                f"corrected {name} -> {os.path.join(out_dir, os.path.basename(name))}",
                soft_wrap=True,
                markup=False,
                highlight=False,
            )
    if failed:
        raise InputError(f"{failed} of {len(inputs)} captures failed (above); the others are in {out_dir}")
    if not quiet:
        many = "s" if len(inputs) != 1 else ""
        console.print(f"corrected {len(inputs)} capture{many} into {out_dir}", soft_wrap=True, markup=False)


def _claims_once(cals: list[Any]) -> None:
    """Two calibrations for one column is a usage error: which correction would win?"""
    for k, a in enumerate(cals):
        for b in cals[k + 1 :]:
            shared = [n for n in a.columns if n.lower() in {m.lower() for m in b.columns}]
            if shared:
                raise InputError(
                    f"{a.path} and {b.path} both calibrate column{'s' if len(shared) > 1 else ''} {', '.join(shared)}",
                    hint="give one calibration per sensor",
                )


def _refuse_failed(cal: Any, doing: str, command: str) -> None:
    """A calibration whose verdict failed goes nowhere without --force (apply, export)."""
    failures = cal.doc["verdict"]["failures"]
    codes = ", ".join(str(f.get("code")) for f in failures if isinstance(f, dict))
    raise InputError(
        f"this unit failed its limits ({codes or 'verdict: fail'}): refusing to {doing}",
        file=cal.path,
        hint=f"pass --force to {command} it anyway",
    )


@contextlib.contextmanager
def _capture_for(cal: Any, path: str, picked: list[str] | None, no_header: bool) -> Iterator[Any]:
    """A capture opened to be corrected by ``cal``: one without that sensor's columns is an
    error naming both the capture and the calibration."""
    from tumblecal_cli import captures

    with contextlib.ExitStack() as stack:
        try:
            cap = stack.enter_context(
                captures.open_capture(path, sensor=cal.sensor, columns=picked, prefer=cal.columns, no_header=no_header)
            )
        except InputError as err:
            if not err.message.startswith(f"no {cal.sensor} x,y,z columns found"):
                raise
            raise InputError(
                f"{err.message}, but {cal.path} calibrates {cal.sensor} columns {', '.join(cal.columns)}",
                file=err.file,
                hint="correct a capture of the sensor the calibration was made for, or name its columns with --columns",
            ) from None
        yield cap


def _columns_of(layout: Any, cal: Any, taken: set[int]) -> tuple[int, int, int]:
    """Where a second calibration's recorded columns are in the capture (by name only)."""
    from tumblecal_cli import captures

    lower = [n.lower() for n in layout.names]
    missing = [n for n in cal.columns if n.lower() not in lower]
    if missing:
        raise InputError(
            f"the capture has no column{'s' if len(missing) > 1 else ''} {', '.join(missing)}, "
            f"which {cal.path} calibrates",
            file=layout.name,
            hint="with several --cal, each calibration's recorded columns must be in the capture's header",
        )
    triplet = captures.sensor_columns(layout, cal.sensor, cal.columns)
    if taken & set(triplet):
        raise InputError(f"{cal.path} calibrates columns another --cal already corrects", file=layout.name)
    taken.update(triplet)
    return triplet


def _correct(cal: Any, raw: Any) -> Any:
    from tumblecal_cli import core

    return core.apply(raw, cal.offset, cal.matrix)


@app.command(
    cls=Command, epilog="Exit status: 0 a valid calibration file; 2 an invalid one (the error names the field)."
)
def show(
    cal: Annotated[str, typer.Argument(metavar="CAL", help="Calibration file; '-' reads stdin.")],
    json_out: Annotated[bool, typer.Option("--json", help="Print the validated file as JSON instead.")] = False,
) -> None:
    """Validate a calibration file and print it for people.

    \b
      tumblecal show cal.json
      tumblecal show cal.yaml --json | jq .offset
    """
    from tumblecal_cli import calfile

    c = calfile.load(cal)
    if json_out:
        _print_json(c.doc)
        return
    console = _console(stderr=False)
    doc, unit = c.doc, c.doc.get("unit") or {}
    facts = [
        ("file", cal),
        (
            "sensor",
            f"{doc['sensor']}, {doc['method']}, reference {doc['reference']:g} {doc.get('units') or ''}".rstrip(),
        ),
        ("input units", doc.get("input_units")),
        ("unit", ", ".join(f"{k} {unit[k]}" for k in ("serial", "station", "operator") if unit.get(k))),
        ("meta", ", ".join(f"{k}={v}" for k, v in (unit.get("meta") or {}).items())),
        ("created", f"{doc.get('created', '')} by {doc.get('tool', '?')}"),
    ]
    for key, value in facts:
        if value:
            console.print(f"{key + ':':<12} {value}", soft_wrap=True)
    if any(doc["matrix"][i][j] for i in range(3) for j in range(3) if i != j):
        console.print("matrix M (corrected = M (raw - offset)):")
        for row in doc["matrix"]:
            console.print("  " + "  ".join(f"{v:>14.6g}" for v in row))
    notes = _tilt_notes(doc) if doc.get("tilt_sensitivity") and doc.get("uncertainty") else []
    _print_summary(doc, console, [], notes, judged=True)


@app.command(cls=Command, epilog="Exit status: 0 within the limits; 1 outside them; 2 usage or input error.")
def check(
    cal: Annotated[str, typer.Argument(metavar="CAL", help="Calibration file; '-' reads stdin.")],
    limits_file: LimitsFile = None,
    max_offset: MaxOffset = None,
    max_gain_error: MaxGainError = None,
    nominal_gain: NominalGain = None,
    json_summary: JsonSummary = False,
    quiet: Quiet = False,
) -> None:
    """Judge an existing calibration against limits again (the file is not changed).

    \b
      tumblecal check cal.json --limits limits.yaml
      tumblecal check cal.json --max-offset 0.05 --max-gain-error 0.02 --json
    """
    from tumblecal_cli import calfile, gate

    given = _limits(limits_file, max_offset, max_gain_error, nominal_gain)
    if not given.judges():
        raise InputError("no limits to judge against", hint="give --limits FILE, --max-offset or --max-gain-error")
    c = calfile.load(cal)
    method = str(c.doc["method"])
    recorded = ((c.doc.get("verdict") or {}).get("limits") or {}).get("nominal_offset")
    if recorded is not None and not any(given.nominal_offset):  # the centre solve judged it from
        import dataclasses

        import numpy as np

        given = dataclasses.replace(given, nominal_offset=np.array(recorded, dtype=float))
    limits = given.for_method(method)
    if not limits.judges():
        raise InputError(f"no limits to judge against: {'; '.join(_limits_not_applying(given, method))}", file=cal)
    if not c.doc.get("poses"):  # an imported calibration: its parameters can be judged, it has no poses
        if limits.noise is not None or limits.residual is not None:
            raise InputError(
                "has no poses to judge the noise and residual limits by",
                file=cal,
                hint="judge it by offset, gain_error and cross_axis only (a limits file without noise and residual)",
            )
        records = []
    else:
        records = calfile.pose_records(c)
    poses = [(p.file, p.face, gate.corrected(p.mean, p.std, p.face, c.offset, c.matrix, c.reference)) for p in records]
    residual = (c.doc.get("residuals") or {}).get("max")
    if method in gate.ROTATION and limits.residual is not None and residual is None:
        raise InputError(
            "has no fit residuals to judge the residual limit by",
            file=cal,
            hint="judge it without the residual limit, or solve the capture again",
        )
    failures = gate.verdict(method, c.offset, c.matrix, poses, limits, residual)
    verdict = {"pass": not failures, "failures": [f.as_dict() for f in failures], "limits": limits.as_dict()}
    notes = _limits_not_applying(given, method)
    if json_summary:  # the same summary as solve --json, judged afresh
        _print_json(_summary(c.doc | {"verdict": verdict}, int(bool(failures)), cal, [], [], notes))
    if not quiet:
        _print_summary(c.doc | {"verdict": verdict}, _console(), [], notes, judged=True)
    if failures:
        raise typer.Exit(1)


class ExportFormat(StrEnum):
    c_header = "c-header"
    registers = "registers"
    imucal_json = "imucal-json"
    ros_yaml = "ros-yaml"
    matlab = "matlab"


class ImportFormat(StrEnum):
    imucal_json = "imucal-json"
    ros_yaml = "ros-yaml"


class RegisterSign(StrEnum):
    subtract = "subtract"
    add = "add"


REGISTERS_PANEL = "Registers (--format registers)"


@app.command(cls=Command, epilog="Exit status: 0 written; 2 usage or input error (a value that does not fit is one).")
def export(
    cal: Annotated[str, typer.Argument(metavar="CAL", help="Calibration file; '-' reads stdin.")],
    fmt: Annotated[
        ExportFormat,
        typer.Option(
            "--format",
            "-f",
            help="c-header: C99/C++ header for firmware; registers: offset (and gain trim) register counts, CSV; "
            "imucal-json, ros-yaml, matlab: the peer tools' own files (README: export).",
        ),
    ],
    output: Annotated[
        str, typer.Option("--output", "-o", metavar="FILE", help="Where to write; '-' (the default) is stdout.")
    ] = "-",
    prefix: Annotated[
        str | None,
        typer.Option(
            "--prefix",
            metavar="NAME",
            help="c-header: the names' prefix, NAME_OFFSET, NAME_MATRIX, name_apply(). [default: tumblecal_accel, "
            "tumblecal_mag or tumblecal_gyro]",
        ),
    ] = None,
    lsb: Annotated[
        float | None,
        typer.Option(
            "--lsb", metavar="V", help="Raw units of one register count (> 0).", rich_help_panel=REGISTERS_PANEL
        ),
    ] = None,
    bits: Annotated[
        int,
        typer.Option("--bits", min=2, max=64, help="Register width in bits, signed.", rich_help_panel=REGISTERS_PANEL),
    ] = 16,
    register_sign: Annotated[
        RegisterSign,
        typer.Option(
            "--register-sign",
            help="What the part does with the offset register: subtract (output = raw - count x lsb, so "
            "count = round(offset / lsb)) or add (count = round(-offset / lsb)).",
            rich_help_panel=REGISTERS_PANEL,
        ),
    ] = RegisterSign.subtract,
    gain_step: Annotated[
        float | None,
        typer.Option(
            "--gain-step",
            metavar="F",
            help="The part has gain trim: the axis is multiplied by (1 + count x F). Adds gain_x..z rows.",
            rich_help_panel=REGISTERS_PANEL,
        ),
    ] = None,
    nominal_gain: Annotated[
        str | None,
        typer.Option(
            "--nominal-gain",
            metavar="G|X,Y,Z",
            help="The gain the trim aims at, raw units per output unit. [default: the calibration's "
            "limits.nominal_gain, else 1]",
            rich_help_panel=REGISTERS_PANEL,
        ),
    ] = None,
    force: Annotated[
        bool, typer.Option("--force", help="Export a calibration whose verdict failed (refused otherwise).")
    ] = False,
) -> None:
    """Write a calibration for firmware or for another tool.

    \b
      tumblecal export cal.json --format c-header -o imu_cal.h
      tumblecal export cal.json --format registers --lsb 0.98 --bits 16
      tumblecal export cal.json --format imucal-json -o imucal_cal.json
    """
    from tumblecal_cli import calfile, formats
    from tumblecal_cli.files import atomic_output, check_not_input, check_writable

    given = {"--lsb": lsb, "--gain-step": gain_step, "--nominal-gain": nominal_gain}
    if fmt is not ExportFormat.registers:
        if extra := [flag for flag, value in given.items() if value is not None]:
            raise InputError(f"{', '.join(extra)} {'is' if len(extra) == 1 else 'are'} for --format registers")
        if bits != 16 or register_sign is not RegisterSign.subtract:
            raise InputError("--bits and --register-sign are for --format registers")
    elif lsb is None:
        raise InputError("--format registers needs --lsb, the raw units of one register count")
    if fmt is not ExportFormat.c_header and prefix is not None:
        raise InputError("--prefix is for --format c-header")
    if nominal_gain is not None and gain_step is None:
        raise InputError("--nominal-gain is the gain trim's aim: it needs --gain-step")
    check_not_input(output, [cal])
    check_writable(output)
    c = calfile.load(cal)
    if c.failed and not force:
        _refuse_failed(c, "export it", "export")
    if fmt is ExportFormat.registers:
        if not (lsb is not None and math.isfinite(lsb) and lsb > 0):
            raise InputError(f"--lsb must be a positive number, got {lsb}")
        if gain_step is not None and not (math.isfinite(gain_step) and gain_step > 0):
            raise InputError(f"--gain-step must be a positive number, got {gain_step}")
        from tumblecal_cli.gate import FIXED_GAINS

        if gain_step is not None and c.doc["method"] in FIXED_GAINS:
            raise InputError(f"the {c.doc['method']} solver fixes the gains: there is no gain to trim", file=cal)
        recorded = ((c.doc.get("verdict") or {}).get("limits") or {}).get("nominal_gain")
        nominal = _triplet_option(nominal_gain or ",".join(map(str, recorded or [1, 1, 1])), "--nominal-gain")
        if not (nominal > 0).all():
            raise InputError(f"--nominal-gain must be positive, got {nominal_gain}")
        rows = formats.registers(
            c, lsb=lsb, bits=bits, sign=register_sign.value, gain_step=gain_step, nominal_gain=nominal
        )
        text = formats.registers_csv(rows)
    else:
        text = {
            ExportFormat.c_header: lambda: formats.c_header(c, prefix=prefix),
            ExportFormat.imucal_json: lambda: formats.imucal_json(c),
            ExportFormat.ros_yaml: lambda: formats.ros_yaml(c),
            ExportFormat.matlab: lambda: formats.matlab(c),
        }[fmt]()
    with atomic_output(output) as out:
        out.write(text.encode())


@app.command("import", cls=Command, epilog="Exit status: 0 written; 2 usage or input error.")
def import_(
    peer_file: Annotated[
        str, typer.Argument(metavar="FILE", help="An imucal JSON or ROS imu_calib YAML file; '-' reads stdin.")
    ],
    fmt: Annotated[
        ImportFormat | None,
        typer.Option("--from", help="The file's format. [default: recognised by its keys]"),
    ] = None,
    output: Annotated[
        str,
        typer.Option(
            "--output", "-o", metavar="FILE", help="Calibration file: .json, or .yaml/.yml for YAML; '-' is stdout."
        ),
    ] = "-",
    sensor: Annotated[
        SensorKind | None,
        typer.Option(
            "--sensor",
            help="Which sensor (an imucal file holds an accelerometer and a gyroscope). [default: what a tumblecal "
            "export recorded, else accelerometer]",
        ),
    ] = None,
    reference: Annotated[
        float | None,
        typer.Option(
            "--reference",
            metavar="V",
            help="The stimulus magnitude in the output units. [default: what a tumblecal export recorded, else 1 "
            "for g, 9.81 for imucal's m/s^2, 9.80665 for ROS, 0 for a gyroscope]",
        ),
    ] = None,
    columns: Annotated[
        str | None,
        typer.Option(
            "--columns",
            metavar="X,Y,Z",
            help="The sensor columns apply will correct. [default: what a tumblecal export recorded, else "
            "imucal's acc_x,acc_y,acc_z (gyr_x...) or x,y,z for ROS]",
        ),
    ] = None,
    serial: Annotated[
        str | None,
        typer.Option("--serial", metavar="TEXT", help="The unit's serial number. [default: what an export recorded]"),
    ] = None,
    quiet: Quiet = False,
) -> None:
    """Read another tool's calibration into a tumblecal calibration file, for apply, check and export.

    \b
      tumblecal import imucal_cal.json -o cal.json
      tumblecal import imu_calib.yaml --from ros-yaml -o cal.yaml
    """
    from tumblecal_cli import calfile, formats
    from tumblecal_cli.files import check_not_input, check_writable

    check_not_input(output, [peer_file])
    check_writable(output)
    raw = calfile.read_bytes(peer_file, "calibration file")
    as_yaml = not peer_file.lower().endswith(".json") and raw.lstrip()[:1] != b"{"  # ROS files are YAML, any name
    doc = calfile.parse_object(raw, peer_file, "calibration file", as_yaml=as_yaml)
    found = formats.detect(doc)
    name = fmt.value if fmt is not None else found
    if name is None or (found is not None and found != name):
        what = "neither an imucal JSON (cal_type, K_a …) nor a ROS imu_calib YAML (SM, bias)"
        raise InputError(
            f"{what} file" if found is None else f"the file is {found}, not {name}",
            file=peer_file,
            hint="tumblecal import reads --from imucal-json or ros-yaml",
        )
    text = raw.decode("utf-8-sig", "replace")
    peer = formats.read_peer(doc, name, peer_file, sensor.value if sensor else None, text)
    ref = reference if reference is not None else _peer_reference(peer, peer_file)
    if not (math.isfinite(ref) and (ref > 0 or (ref == 0 and peer.sensor == "gyroscope"))):
        raise InputError(f"--reference must be a positive number (0 for a gyroscope), got {ref}")
    if columns:
        picked = [c.strip() for c in columns.split(",")]
        if len(picked) != 3 or not all(picked) or len({c.lower() for c in picked}) != 3:
            raise InputError(f"--columns takes three different names X,Y,Z, got {columns!r}")
    elif peer.columns:
        picked = peer.columns
    elif name == "ros-yaml":
        picked = list("xyz")
    else:
        picked = [f"{'gyr' if peer.sensor == 'gyroscope' else 'acc'}_{a}" for a in "xyz"]
    cal = formats.imported(
        peer,
        path=peer_file,
        raw=raw,
        sensor=peer.sensor,
        reference=ref,
        columns=picked,
        unit=_unit_block(
            serial if serial is not None else peer.serial, peer.was.get("station"), peer.was.get("operator"), []
        ),
    )
    calfile.write(cal, output)
    if not quiet:
        console = _console()
        for note in peer.notes:
            console.print(f"note: {note}", soft_wrap=True)
        console.print(
            f"imported {name} {peer.sensor} calibration, reference {ref:g}"
            + (f": wrote {output}" if output != "-" else ""),
            soft_wrap=True,
        )


def _peer_reference(peer: Any, path: str) -> float:
    """The reference a peer file implies (README: import)."""
    if peer.reference is not None:
        return float(peer.reference)
    if peer.sensor == "gyroscope":
        return 0.0
    if peer.format == "ros-yaml" and peer.sensor == "accelerometer":
        return 9.80665  # imu_calib's do_calib: reference_acceleration defaults to 9.80665
    by_units = {"g": 1.0, "m/s^2": 9.81, "m/s2": 9.81}  # imucal's Ferraris default expected gravity 9.81
    if peer.units in by_units:
        return by_units[peer.units]
    raise InputError(
        f"cannot tell the reference of output units {peer.units!r}",
        file=path,
        hint="give --reference, the stimulus magnitude in the output units",
    )


REPORT_EXIT = """\
Exit status: 0 the lot is in order; 1 it needs attention (a unit outside --limits, an
outlier, a drift beyond --max-drift, or a Cpk below --min-cpk); 2 usage or input error (an unreadable file among
the rest: the report is still printed)."""


@app.command(cls=Command, epilog=REPORT_EXIT)
def report(
    paths: Annotated[
        list[str],
        typer.Argument(
            metavar="CALS...",
            help="Calibration files, or folders searched for *.json and *.yaml (hidden ones skipped).",
        ),
    ],
    limits_file: Annotated[
        str | None,
        typer.Option(
            "--limits",
            metavar="FILE",
            help="Limits file (as for solve): offset, gain_error with nominal_gain, and cross_axis give the "
            "specification limits Cpk is computed against.",
        ),
    ] = None,
    max_drift: Annotated[
        str | None,
        typer.Option(
            "--max-drift",
            metavar="KEY=V,...",
            help="Flag a unit whose latest calibration moved further than this from its previous one: "
            "offset=V (raw units), gain=F (fraction of the previous gain), cross=F (e.g. offset=0.01,gain=0.002).",
        ),
    ] = None,
    min_cpk: Annotated[
        float | None,
        typer.Option("--min-cpk", metavar="C", help="Flag a parameter whose Cpk is below C (1.33 is usual)."),
    ] = None,
    json_out: Annotated[
        bool, typer.Option("--json", help="Print the whole report as JSON on stdout instead of the CSV table.")
    ] = False,
    plot: Annotated[
        str | None,
        typer.Option(
            "--plot", metavar="PNG", help="Also draw a histogram per parameter, with its limits (needs [plot])."
        ),
    ] = None,
    quiet: Quiet = False,
) -> None:
    """Statistics of a production lot: per parameter count, mean, std, min/max, Cpk, outliers, drift.

    The lot is the latest calibration of each serial (unit.serial; files without one count
    once each); a serial calibrated more than once also gets the change since its previous
    calibration (by created). Outliers: |robust z| > 4 (median absolute deviation).
    CSV (or --json) on stdout, tables on stderr.

    \b
      tumblecal report cals/ --limits limits.yaml
      tumblecal report lot1/ lot2/ --max-drift offset=0.01,gain=0.002 --json
      tumblecal report cals/ --limits limits.yaml --plot lot.png
    """
    from tumblecal_cli import calfile, lot
    from tumblecal_cli.files import atomic_output

    if min_cpk is not None and not (math.isfinite(min_cpk) and min_cpk > 0):
        raise InputError(f"--min-cpk must be a positive number, got {min_cpk}")
    if min_cpk is not None and limits_file is None:
        raise InputError("--min-cpk needs --limits: Cpk is measured against the limits")
    drift_limits = lot.parse_max_drift(max_drift)
    limits = calfile.load_limits(limits_file) if limits_file else {}
    found = lot.find(paths, skip=limits_file)
    if plot is not None:
        from tumblecal_cli import plots

        _plot_target(plot, "-", False, [*found, *([limits_file] if limits_file else [])])
    entries, unreadable = lot.load_all(found)
    result = lot.summarise(entries, unreadable, limits, max_drift=drift_limits, min_cpk=min_cpk)
    if json_out:
        _print_json(result.as_dict())
    else:
        import csv
        import io

        header, rows = result.csv_rows()
        text = io.StringIO()
        csv.writer(text, lineterminator="\n").writerows([header, *rows])  # quotes a serial with a comma
        with atomic_output("-") as out:
            out.write(text.getvalue().encode())
    if plot is not None and not unreadable:  # exit 2 writes no file
        import numpy as np

        members = lot.lot(entries)
        histograms = [
            plots.Histogram(
                f"{row.parameter}" if len({r.sensor for r in result.rows}) == 1 else f"{row.sensor} {row.parameter}",
                np.array(
                    [e.values[row.parameter] for e in members if e.sensor == row.sensor and row.parameter in e.values]
                ),
                row.lower,
                row.upper,
            )
            for row in result.rows
        ]
        plots.lot_figure(plot, histograms, title=f"{result.units} units, {result.files} files")
    if not quiet:
        _print_lot(result, _console(), plot, drift_given=bool(drift_limits))
    if unreadable:  # an error line per file, after the report of the rest
        (first, why), rest = unreadable[0], unreadable[1:]
        raise InputError(
            why,
            file=first,
            more=tuple(f"{path}: {message}" for path, message in rest),
            hint=f"the report leaves out the {len(unreadable)} of {result.files} files that could not be read",
        )
    if result.needs_attention:
        raise typer.Exit(1)


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _short_sensor(sensor: str) -> str:
    """ "accelerometer" as "acc.", and "accelerometer (raw -> g)" as "acc. (raw -> g)"."""
    name, _, units = sensor.partition(" (")
    return f"{name[:3]}." + (f" ({units}" if units else "")


def _print_lot(result: Any, console: Console, plot: str | None, *, drift_given: bool) -> None:
    """The lot report for people: the parameter table, outliers, drift, unreadable files."""
    from rich import box
    from rich.table import Table

    def g(v: float | None, digits: int = 4) -> str:  # compact: 80 columns hold the table
        return "" if v is None else re.sub(r"e([-+])0*(\d)", r"e\1\2", f"{v:.{digits}g}").replace("e+", "e")

    def span(r: Any) -> str:
        if r.lower is None and r.upper is None:
            return ""
        if r.lower is not None and r.upper is not None and r.lower == -r.upper:
            return f"±{g(r.upper)}"
        return f"{g(r.lower)}..{g(r.upper)}"

    several = len({r.sensor for r in result.rows}) > 1
    table = Table(
        title=f"lot of {_count(result.units, 'unit')} ({_count(result.files, 'file')})",
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
            f"{_short_sensor(r.sensor)} {r.parameter}" if several else r.parameter,
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
            console.print(f"outlier: {unit}: {r.parameter} {g(value)} (robust z {z:+.1f})", style="red", soft_wrap=True)
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
    if plot is not None and not result.unreadable:
        console.print(f"wrote {plot}", soft_wrap=True)
    verdict = "needs attention" if result.needs_attention else "in order"
    console.print(f"lot: {verdict}", style="bold red" if result.needs_attention else "bold green", soft_wrap=True)


@app.command(
    cls=Command,
    epilog="Exit status: 0 every capture within --max-norm-error (or none given); 1 some capture outside it; "
    "2 usage or input error; 3 a capture that is not static (above --max-noise).",
)
def verify(
    captures_: Annotated[
        list[str],
        typer.Argument(
            metavar="CAPTURE", help="Static captures the calibration was not fitted on, one or more; '-' reads stdin."
        ),
    ],
    cal: Annotated[
        str, typer.Option("--cal", "-c", metavar="FILE", help="Calibration file from 'tumblecal solve'.")
    ] = ...,  # type: ignore[assignment]
    reference: Annotated[
        float | None,
        typer.Option(
            "--reference", metavar="NUMBER", help="The magnitude each capture should read. [default: the calibration's]"
        ),
    ] = None,
    max_norm_error: Annotated[
        float | None,
        typer.Option(
            "--max-norm-error",
            metavar="V",
            help="Exit 1 when a capture's corrected norm is further than V from the reference (output units).",
        ),
    ] = None,
    max_noise: Annotated[
        float,
        typer.Option(
            "--max-noise",
            metavar="FRACTION",
            help="Reject (exit 3) a capture whose corrected standard deviation is above FRACTION x reference: "
            "it is not static. 0 turns the check off.",
        ),
    ] = 0.02,
    columns: Columns = None,
    no_header: NoHeader = False,
    json_summary: Annotated[
        bool, typer.Option("--json", help="Print the per-capture and overall figures on stdout as JSON.")
    ] = False,
    quiet: Quiet = False,
) -> None:
    """Check a calibration on static captures it was not fitted on: the norm of each mean, before
    and after correction, against the reference (seed 001's test of a calibration model).

    \b
      tumblecal verify --cal cal.json check1.csv check2.csv check3.csv
      tumblecal verify --cal cal.json tilted/*.csv --max-norm-error 0.005 --json
    """
    from tumblecal_cli import calfile, captures, core, gate

    if sum(f == "-" for f in captures_) + (cal == "-") > 1:
        raise InputError("only one file can be read from stdin ('-')")
    c = calfile.load(cal)
    ref = c.reference if reference is None else reference
    if not math.isfinite(ref) or ref < 0:
        raise InputError(f"--reference must be a positive number, got {ref:g}")
    if max_norm_error is not None and not max_norm_error > 0:
        raise InputError(f"--max-norm-error must be positive, got {max_norm_error:g}")
    picked = columns.split(",") if columns else None
    # raw and corrected share units, so "before" means something: fixed gains, the same unit
    # labels, or gains within 20 % of 1 (data already in g, m/s^2 ...: counts are far from it)
    gains = [float(g) for g in c.doc.get("gain") or []]
    same_units = (
        c.doc.get("method") in gate.FIXED_GAINS
        or (c.doc.get("input_units") is not None and c.doc.get("input_units") == c.doc.get("units"))
        or (len(gains) == 3 and all(abs(g - 1.0) < 0.2 for g in gains))
    )
    fitted = {str(p.get("sha256")): str(p.get("file")) for p in c.doc.get("poses") or [] if p.get("sha256")}
    notes: list[str] = []
    rows: list[dict[str, Any]] = []
    rejected: list[str] = []
    failed: list[str] = []
    for path in captures_:
        s = captures.read_samples(path, sensor=c.sensor, columns=picked, prefer=c.columns, no_header=no_header)
        if s.sha256 in fitted:
            notes.append(
                f"{s.layout.name}: the calibration was fitted on this capture ({fitted[s.sha256]}): "
                "it reads the reference by construction, a self-check rather than a verification"
            )
        st = core.pose_stats(s.values)
        before = float((st.mean**2).sum() ** 0.5)
        fixed = gate.corrected(st.mean, st.std, None, c.offset, c.matrix, ref)  # the norm error, as solve's
        std = fixed.std
        row: dict[str, Any] = {
            "file": s.layout.name,
            "samples": st.samples,
            "norm_before": before,
            "error_before": before - ref if same_units else None,
            "norm_after": fixed.norm_error + ref,
            "error_after": fixed.norm_error,
            "std": [float(v) for v in std],
        }
        rows.append(row)
        if max_noise > 0 and ref > 0 and float(std.max()) > max_noise * ref:
            rejected.append(
                f"{s.layout.name}: standard deviation {float(std.max()):.3g} is above --max-noise "
                f"({max_noise * ref:.3g}): not a static capture"
            )
        elif max_norm_error is not None and not abs(row["error_after"]) <= max_norm_error:
            failed.append(row["file"])
    errors = [r["error_after"] for r in rows]
    overall = {
        "rms_error": float((sum(e * e for e in errors) / len(errors)) ** 0.5),
        "max_error": float(max(abs(e) for e in errors)),
    }
    if same_units:
        raw_errors = [r["error_before"] for r in rows]
        overall["rms_error_before"] = float((sum(e * e for e in raw_errors) / len(raw_errors)) ** 0.5)
        overall["max_error_before"] = float(max(abs(e) for e in raw_errors))
    status = 3 if rejected else (1 if failed else 0)
    if json_summary:
        _print_json(
            {
                "status": {0: "pass", 1: "fail", 3: "rejected"}[status],
                "exit_status": status,
                "cal": cal,
                "reference": ref,
                "max_norm_error": max_norm_error,
                "captures": rows,
                **overall,
                "rejections": rejected,
                "failed": failed,
                "notes": notes,
            }
        )
    if not quiet:
        _print_verify(c.doc, rows, overall, ref, max_norm_error, failed)
        for note in notes:
            _console().print(f"note: {note}", soft_wrap=True, markup=False)
    if rejected:
        raise CaptureRejected(rejected[0], more=tuple(rejected[1:]), hint="capture it again holding the unit still")
    if failed:
        raise typer.Exit(1)


SEGMENT_EXIT = """\
Exit status: 0 blocks found and written; 2 usage or input error (bad file or option, a time
column that goes backwards); 3 nothing to calibrate from (fewer than two still blocks kept).
Nothing is written on 2 or 3."""


@app.command(cls=Command, epilog=SEGMENT_EXIT)
def segment(
    log: Annotated[str, typer.Argument(metavar="LOG", help="The continuous log, one CSV ('-' reads stdin).")],
    out_dir: Annotated[
        str | None,
        typer.Option(
            "--out-dir",
            "-d",
            metavar="DIR",
            help="Write each kept block as a CSV of its own (the log's header and rows, unchanged): xp.csv xn.csv "
            "yp.csv yn.csv zp.csv zn.csv for the best block of each face, blockNN.csv for the others; and "
            "segments.csv, the index. DIR is created if needed. Without it the index goes to stdout.",
        ),
    ] = None,
    sensor: Sensor = SensorKind.accelerometer,
    columns: Columns = None,
    no_header: NoHeader = False,
    time_column: TimeColumn = None,
    time_unit: TimeUnitOption = TimeUnit.s,
    rate: Rate = None,
    window: Window = None,
    threshold: Threshold = None,
    min_duration: MinDuration = None,
    trim: Trim = None,
    pose_column: PoseColumn = None,
    pose_map: PoseMap = None,
    max_noise: Annotated[
        float,
        _log_option(
            "--max-noise",
            "FRACTION",
            "Drop a block whose standard deviation, or drift between its first and last third, is above "
            "FRACTION x its magnitude (as solve's moved check).",
        ),
    ] = 0.02,
    max_tilt: Annotated[
        float,
        _log_option("--max-tilt", "DEGREES", "Label a block with its nearest face only when within this angle."),
    ] = 25.0,
    nominal_offset: Annotated[
        str | None,
        _log_option(
            "--nominal-offset",
            "V|X,Y,Z",
            "The raw value at zero stimulus, removed before judging a block's direction. "
            "[default: the per-axis midpoint of the block means]",
        ),
    ] = None,
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="List the dropped blocks too.")] = False,
    quiet: Quiet = False,
) -> None:
    """Find the static poses in one continuous log and cut it into one CSV per pose.

    A sample is still when the rolling standard deviation around it is below the threshold;
    each still run is a block, labelled with the face it rests on. The blocks go to
    `solve --poses`, or let `solve --log` do all of it in one step.

    \b
      tumblecal segment session.csv --out-dir poses/
      tumblecal solve --poses poses/xp.csv poses/xn.csv poses/yp.csv poses/yn.csv poses/zp.csv poses/zn.csv
      tumblecal segment session.csv --rate 102.4 > segments.csv       # the index only
      tumblecal segment annotated.csv --pose-column part --pose-map x_p=+x,x_a=-x,y_p=+y,y_a=-y,z_p=+z,z_a=-z -d poses/
    """
    import csv
    import io

    from tumblecal_cli import captures
    from tumblecal_cli import segment as seg_core
    from tumblecal_cli.files import atomic_output

    for option, value in (("--max-noise", max_noise), ("--max-tilt", max_tilt)):
        if not value > 0:
            raise InputError(f"{option} must be positive, got {value:g}")
    if out_dir is not None and os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise InputError("is a file, not a folder: --out-dir takes a folder", file=out_dir)
    settings = seg_core.Settings(
        window=window,
        threshold=threshold,
        min_duration=min_duration,
        trim=trim,
        max_noise=max_noise,
        max_tilt_deg=max_tilt,
        nominal_offset=None if nominal_offset is None else _triplet_option(nominal_offset, "--nominal-offset"),
    )
    with _segmented(
        log,
        sensor=sensor.value,
        columns=columns,
        no_header=no_header,
        time_column=time_column,
        time_unit=time_unit.value,
        rate=rate,
        pose_column=pose_column,
        pose_map=pose_map,
        settings=settings,
        digest=False,  # the block files are copies; nothing records the log's hash
    ) as (path, data, seg):
        files = _block_files(seg)
        if not quiet:
            # "-> xp.csv" only where it is written; the index alone names the file each block would go to
            shown = {n: f"-> {f}" if out_dir is not None else f"kept ({f})" for n, f in files.items()}
            _print_blocks(data, seg, _console(), used=shown, everything=verbose)
        _enough_blocks(data, seg, 2)
        text = io.StringIO()
        writer = csv.writer(text, lineterminator="\n")
        writer.writerow(INDEX_COLUMNS)
        writer.writerows(_index_rows(data, seg, files))
        if out_dir is None:
            _print_text(text.getvalue())
            return
        if log != "-":
            for f in [*files.values(), "segments.csv"]:
                check_path = os.path.join(out_dir, f)
                if os.path.exists(check_path) and os.path.samefile(check_path, log):
                    raise InputError(f"--out-dir would overwrite the input with {f}", file=log)
        ours, listed = _earlier_run(out_dir)
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
            if log == "-" or not os.path.samefile(os.path.join(out_dir, name), log)  # never the log itself
        }
        os.makedirs(out_dir, exist_ok=True)
        kept = seg.kept
        spans = [(int(data.rows[b.first]), int(data.rows[b.last])) for b in kept]
        # the index first: a run stopped part-way leaves its blocks listed, so the next run
        # into this folder knows them for its own and replaces them
        with atomic_output(os.path.join(out_dir, "segments.csv")) as out:
            out.write(text.getvalue().encode())
        captures.copy_rows(path, data.layout, spans, [os.path.join(out_dir, files[b.number]) for b in kept])
        for name in sorted(earlier):  # a re-run replaces the earlier segmentation, never mixes with it
            with contextlib.suppress(FileNotFoundError):
                os.unlink(os.path.join(out_dir, name))
    if not quiet:
        gone = f"; removed {len(earlier)} block files of the earlier segmentation" if earlier else ""
        _console().print(f"wrote {len(kept)} block files and segments.csv to {out_dir}{gone}", soft_wrap=True)


def _earlier_run(out_dir: str) -> tuple[bool, set[str]]:
    """Whether ``out_dir`` holds an earlier ``segment``'s index (segments.csv with its header),
    and the block files it lists that are still there: only names this command gives (xp.csv
    ... block07.csv), never another file of the folder."""
    import csv

    index = os.path.join(out_dir, "segments.csv")
    try:
        with open(index, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            names = {row.get("file") or "" for row in reader}
            ours = reader.fieldnames == INDEX_COLUMNS
    except (OSError, UnicodeDecodeError, csv.Error):
        return False, set()
    if not ours:
        return False, set()
    pattern = r"(?:[xyz][pn]|block\d{2,})\.csv"
    return True, {n for n in names if re.fullmatch(pattern, n) and os.path.exists(os.path.join(out_dir, n))}


BATCH_PANEL = "Batch"
BATCH_EXIT = """\
Exit status, the first that any unit has: 2 an input or usage error; 3 a capture rejected;
1 a unit outside its limits; 0 every unit passed. A unit that fails never stops the batch:
its row in summary.csv says why. Nothing but the calibrations and summary.csv is written."""
#: solve's options that are each unit's own, not the batch's.
PER_UNIT = ("poses", "log", "output", "json_summary", "quiet", "serial", "plot")


def _batch_options(
    source: Annotated[
        str,
        typer.Argument(
            metavar="UNITS",
            help="A folder with one folder of pose files per unit, UNITS/<serial>/x.csv y.csv z.csv (files named "
            "x y z, xp xn yp yn zp zn or +x ... are labelled so; others are unlabelled, in name order); with --log, "
            "one log per unit, UNITS/<serial>.csv or UNITS/<serial>/<log>.csv. Or a manifest CSV: the header "
            "'serial,...', then a serial and its files per row (relative to the manifest; a column headed x, "
            "+x, xp ... labels its files; a cell may be LABEL=FILE).",
        ),
    ],
    out_dir: Annotated[
        str,
        typer.Option(
            "--out-dir",
            "-d",
            metavar="DIR",
            help="Where each unit's calibration goes, as <serial>_<UTC time>.json (never replacing a file: "
            "a unit's history stays), with summary.csv, one row per unit. Created if needed.",
            rich_help_panel=BATCH_PANEL,
        ),
    ],
    log: Annotated[
        bool,
        typer.Option(
            "--log",
            help="Each unit is one continuous log, cut into still blocks as 'solve --log' does.",
            rich_help_panel=BATCH_PANEL,
        ),
    ] = False,
    jobs: Annotated[
        int,
        typer.Option(
            "--jobs",
            "-j",
            metavar="N",
            min=1,
            help="Solve N units at a time, in N processes.",
            rich_help_panel=BATCH_PANEL,
        ),
    ] = 1,
    resume: Annotated[
        bool,
        typer.Option(
            "--resume",
            help="Continue a batch: skip the units already in DIR/summary.csv (whatever their status; delete a "
            "row to redo that unit). Without it an existing summary.csv is an error.",
            rich_help_panel=BATCH_PANEL,
        ),
    ] = False,
    dask_scheduler: Annotated[
        str | None,
        typer.Option(
            "--dask-scheduler",
            metavar="ADDRESS",
            help="Run the units on a Dask distributed cluster, tcp://host:8786 (README: Dask). Needs "
            "'tumblecal[dask]' here and on the workers, and UNITS and DIR at the same paths on every worker.",
            rich_help_panel=BATCH_PANEL,
        ),
    ] = None,
    json_summary: Annotated[
        bool,
        typer.Option(
            "--json",
            help="Print the summary on stdout as JSON: the batch's status, counts, and each unit's row.",
            rich_help_panel=BATCH_PANEL,
        ),
    ] = False,
    quiet: Annotated[
        bool,
        typer.Option(
            "--quiet", "-q", help="Print nothing on stderr unless there is an error.", rich_help_panel=BATCH_PANEL
        ),
    ] = False,
) -> None:
    """batch's own options; the rest are solve's (see _batch_signature)."""


def _batch_signature() -> Any:
    """batch takes its own options and every option of solve that is not a unit's own."""
    own = list(inspect.signature(_batch_options, eval_str=True).parameters.values())
    shared = [p for n, p in inspect.signature(solve, eval_str=True).parameters.items() if n not in PER_UNIT]
    return inspect.Signature(own + shared)


def batch(**given: Any) -> None:
    """Calibrate many units in one run: one calibration file per unit, and a summary.

    Each unit is solved as 'tumblecal solve' would (every solve option below applies to all of
    them), its calibration written to DIR/<serial>_<UTC time>.json, and its outcome added to
    DIR/summary.csv: serial, status, verdict, codes, file, method, offset, gain, their 1-sigma
    uncertainties, inputs, and the message of a unit that failed.

    \b
      tumblecal batch units/ --out-dir cals/ --limits limits.yaml --jobs 2
      tumblecal batch manifest.csv --out-dir cals/ --reference 9.81
      tumblecal batch logs/ --log --rate 100 --out-dir cals/ --resume
      tumblecal batch units/ --out-dir /shared/cals --dask-scheduler tcp://scheduler:8786
    """
    from tumblecal_cli import batch as batches
    from tumblecal_cli import calfile

    own = {name: given.pop(name) for name in list(given) if name in _BATCH_OWN}
    source, out_dir, log, quiet = own["source"], own["out_dir"], own["log"], own["quiet"]
    if out_dir == "-":
        raise InputError("--out-dir takes a folder: the calibrations are files, not a stream on stdout")
    _solve_settings(log_given=log, **{k: given[k] for k in _SETTINGS})  # a bad option: one error, not one per unit
    calfile.created()  # so is a bad SOURCE_DATE_EPOCH
    units, notes = batches.find_units(source, log=log, out_dir=out_dir)
    if own["dask_scheduler"] is not None:  # the workers do not share this working folder
        units = [batches.Unit(u.serial, tuple(batches.absolute(i) for i in u.inputs), u.problem) for u in units]
        out_dir = os.path.abspath(out_dir)
        if given["limits_file"]:
            given["limits_file"] = os.path.abspath(given["limits_file"])
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise InputError("is a file, not a folder: --out-dir takes a folder", file=out_dir)
    summary_path = os.path.join(out_dir, batches.SUMMARY)
    rows: list[dict[str, Any]] = []
    if os.path.exists(summary_path):
        if not own["resume"]:
            raise InputError(
                "a batch summary is already here",
                file=summary_path,
                hint="--resume continues it; or use another --out-dir",
            )
        rows = batches.read_summary(summary_path)
    done = {str(r["serial"]) for r in rows}
    todo = [u for u in units if u.serial not in done]
    console = _console()
    if not quiet:
        for note in notes:
            console.print(f"note: {note}", soft_wrap=True, markup=False)
        if done:
            console.print(f"resuming: {len(units) - len(todo)} of {len(units)} units already done", soft_wrap=True)
    run = batches.engine(own["jobs"], own["dask_scheduler"])  # connects to a cluster: before writing anything
    os.makedirs(out_dir, exist_ok=True)
    from concurrent.futures.process import BrokenProcessPool

    token = f"{os.getpid()}-{time.time_ns()}"  # names this batch's staging files
    summary = batches.Summary(out_dir, rows)
    try:
        with _batch_progress(console, len(todo), enabled=not quiet) as (show, tick):
            epoch = os.environ.get("SOURCE_DATE_EPOCH", "")  # the caller's, wherever the units run
            work = [(u, given, out_dir, log, token, epoch) for u in todo]
            for (unit, *_), outcome in run(batches.run_unit, work):
                if isinstance(outcome, BaseException):
                    row = batches.failed_row(unit, outcome)
                else:
                    row = batches.finish(outcome, out_dir)  # published as it is recorded
                summary.add(row)
                if row["status"] or not show:
                    _print_unit(row, out_dir, console, quiet=quiet)
                tick()
    except BrokenProcessPool:
        raise InputError(
            f"a worker process died (killed, or out of memory) after {len(summary.rows) - len(done)} of "
            f"{len(todo)} units",
            hint="the summary keeps the units done: run the same command with --resume",
        ) from None
    finally:
        summary.close()
        batches.clean_staging(out_dir, token)
    status = batches.status(summary.rows)
    counts = {v: sum(r["verdict"] == v for r in summary.rows) for v in batches.VERDICTS.values()}
    if not quiet:
        said = ", ".join(f"{n} {v}" for v, n in counts.items() if n)
        console.print(
            f"{len(summary.rows)} unit{'s' if len(summary.rows) != 1 else ''}: {said} -> {summary_path}",
            soft_wrap=True,
            markup=False,
            highlight=False,
        )
    if own["json_summary"]:
        table = [{c: r.get(c) for c in batches.SUMMARY_COLUMNS} for r in summary.rows]
        _print_json({"status": status, "counts": counts, "summary": summary_path, "units": table})
    if status:
        raise typer.Exit(status)


_BATCH_OWN = tuple(inspect.signature(_batch_options).parameters)  # the rest of batch's options are solve's
_SETTINGS = (
    "window",
    "threshold",
    "min_duration",
    "trim",
    "pose_column",
    "pose_map",
    "meta",
    "method",
    "tilt_compensate",
    "up",
    "sensor",
    "reference",
    "max_noise",
    "max_tilt",
    "full_scale",
    "nominal_offset",
    "limits_file",
    "max_offset",
    "max_gain_error",
    "nominal_gain",
)
batch.__signature__ = _batch_signature()  # type: ignore[attr-defined]
app.command(cls=Command, epilog=BATCH_EXIT)(batch)


@contextlib.contextmanager
def _term_as_interrupt() -> Iterator[None]:
    """SIGTERM (a scheduler's or a station's kill) stops a command as Ctrl-C does: partial
    outputs removed, a batch's summary written and its worker processes shut down; exit 130."""
    import signal

    def interrupt(signum: int, frame: Any) -> None:
        raise Interrupted("interrupted (SIGTERM)")

    try:
        previous = signal.signal(signal.SIGTERM, interrupt)
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def _batch_progress(console: Console, total: int, *, enabled: bool) -> Iterator[tuple[bool, Any]]:
    """A progress bar on stderr when it is a terminal: (shown, advance by one unit)."""
    if not (enabled and console.is_terminal and total):
        yield False, lambda: None
        return
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    columns = (TextColumn("batch"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
    with Progress(*columns, console=console, transient=True) as progress:
        task = progress.add_task("units", total=total)
        yield True, lambda: progress.advance(task)


def _print_unit(row: dict[str, Any], out_dir: str, console: Console, *, quiet: bool) -> None:
    """One line per unit: its verdict and file, or why it failed (``quiet``: only a unit with
    an error or a rejected capture, as ``solve -q`` still prints those)."""
    if quiet and row["status"] not in (2, 3):
        return
    codes = f" ({', '.join(row['codes'])})" if row.get("codes") else ""
    head = f"{row['serial']}: {row['verdict']}{codes}"
    if row.get("file"):
        head += f" -> {os.path.join(out_dir, row['file'])}"
    messages = row.get("messages") or [row.get("message") or ""]
    if len(messages) == 1 and not row.get("file"):
        head, messages = f"{head}: {messages[0]}", []
    for line in [head, *(f"  {m}" for m in messages if not row.get("file"))]:
        console.print(line, soft_wrap=True, markup=False, highlight=False)


def _print_verify(
    doc: dict[str, Any],
    rows: list[dict[str, Any]],
    overall: dict[str, float],
    ref: float,
    bound: float | None,
    failed: list[str],
) -> None:
    from rich import box
    from rich.table import Table

    console = _console()
    units = f" {doc['units']}" if doc.get("units") else ""
    table = Table(
        title=f"{doc['method']} calibration on {len(rows)} capture{'s' if len(rows) > 1 else ''}, "
        f"reference {ref:g}{units}",
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    for name in ("file", "n", "|mean| raw", "error", "|corrected|", "error", ""):
        table.add_column(name, justify="left" if name in ("file", "") else "right", no_wrap=name != "file")
    for r in rows:
        before = "" if r["error_before"] is None else f"{r['error_before']:+.4g}"
        mark = "FAIL" if r["file"] in failed else ""
        table.add_row(
            os.path.basename(r["file"]),
            str(r["samples"]),
            f"{r['norm_before']:.6g}",
            before,
            f"{r['norm_after']:.6g}",
            f"{r['error_after']:+.4g}",
            mark,
        )
    console.print(table)
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


# -- people's output, on stderr ----------------------------------------------------------


def _console(stderr: bool = True) -> Console:
    from rich.console import Console

    class Quiet(Console):
        def on_broken_pipe(self) -> None:  # Rich's own exits 1; a closed reader is exit 141 here (main)
            raise PipeClosed("output closed")

    return Quiet(stderr=stderr, highlight=False, markup=False)  # paths and column names are not markup


def _print_summary(
    doc: dict[str, Any], console: Console, warned: list[Finding], notes: list[str], *, judged: bool
) -> None:
    """The calibration for people: per axis offset and gain with their uncertainty and tilt
    sensitivity, per pose its statistics, then warnings, notes and the verdict."""
    from rich import box
    from rich.table import Table

    def g(v: float | None, digits: int = 6) -> str:
        return "" if v is None else f"{v:.{digits}g}"

    se = doc.get("uncertainty") or {}
    tilt = doc.get("tilt_sensitivity") or {}
    from tumblecal_cli.gate import FIXED_GAINS

    fixed = doc["method"] in FIXED_GAINS
    # numbers never wrap or shrink; a long column or file name is what gives way on a narrow terminal
    axes = Table(title=f"{doc['method']} calibration", title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False)
    for name in ("axis", "column", "offset", "± 1σ", "± tilt", "gain", "± 1σ", "± tilt"):
        text = name in ("axis", "column")
        axes.add_column(
            name,
            justify="left" if text else "right",
            no_wrap=not text,
            min_width=len(name) if text else None,  # the heading whole
            max_width=14 if text else None,  # ... and a long name folds within it, not widening the table
            overflow="fold",  # a long column name folds onto a second line rather than losing its end
        )
    for i, axis in enumerate("xyz"):
        cells = [axis, doc["columns"][i]]
        for name in ("offset", "gain"):
            if name == "gain" and fixed:
                cells += [g(doc["gain"][i]), "fixed", ""]
            else:
                cells += [g(doc[name][i]), g(_at(se, name, i), 2), g(_at(tilt, name, i), 2)]
        axes.add_row(*cells)
    poses = Table(title="poses", title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False)
    for name in ("pose", "file", "n", "angle", "", "x", "y", "z"):
        text = name == "file"
        poses.add_column(
            name,
            justify="left" if name in ("pose", "file", "") else "right",
            no_wrap=not text,
            min_width=6 if text else None,
            max_width=14 if text else None,  # a long file name folds, the numbers stay whole
            overflow="fold",
        )
    for p in doc.get("poses", []):
        angle = p.get("angle_deg")
        name = os.path.basename(str(p.get("file", ""))) + (f" #{p['block']}" if "block" in p else "")
        poses.add_row(
            p["pose"] or "?",
            name,
            str(p["samples"]),
            "" if angle is None else f"{angle:.1f}°",
            "mean",
            *map(g, p["mean"]),
        )
        if "std" in p:  # a field of every file tumblecal writes; other writers may leave it out
            poses.add_row("", "", "", "", "std", *(f"{v:.3g}" for v in p["std"]), end_section=True)
    _print_whole(console, axes)
    if doc.get("poses"):  # an imported calibration has none
        _print_whole(console, poses)
    matrix = doc["matrix"]
    if any(matrix[i][j] for i in range(3) for j in range(3) if i != j):
        import numpy as np

        a = np.linalg.inv(np.array(matrix, dtype=float))
        terms = ", ".join(
            f"{'xyz'[i]}{'xyz'[j]} {a[i, j] / a[i, i]:+.3%}" for i in range(3) for j in range(3) if i != j
        )
        console.print(f"cross-axis terms (A = M⁻¹, each over its row's gain): {terms}", soft_wrap=True)
    if doc.get("coverage") is not None:
        console.print(f"coverage: {doc['coverage']:.0%} of the sphere's directions", soft_wrap=True)
    if tilt.get("tolerance_deg") is not None:
        console.print(f"± tilt: worst-case shift if each pose is {tilt['tolerance_deg']:g}° off level", soft_wrap=True)
    for w in warned:
        console.print(f"warning: {w.render()} ({w.code})", style="yellow", soft_wrap=True)
    for note in notes:
        console.print(f"note: {note}", soft_wrap=True)
    verdict = doc.get("verdict")
    if judged and isinstance(verdict, dict):
        judged_by = ", ".join(k for k in verdict.get("limits") or {} if k not in ("nominal_gain", "nominal_offset"))
        limits = f"limits: {judged_by}" if judged_by else "no limits judged"
        if verdict["pass"]:
            console.print(f"verdict: PASS ({limits})", style="bold green", soft_wrap=True)
        else:
            console.print(f"verdict: FAIL ({limits})", style="bold red", soft_wrap=True)
            for f in verdict["failures"]:
                where = f"{f['file']}: " if f.get("file") else ""
                console.print(f"  {f['code']}: {where}{f.get('message', '')}", style="red", soft_wrap=True)


def _print_whole(console: Console, table: Any) -> None:
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


def _at(block: dict[str, Any], name: str, i: int) -> float | None:
    values = block.get(name)
    return float(values[i]) if isinstance(values, list) and len(values) == 3 else None


# -- the one error boundary --------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; return the exit status. Every error is reported here and only here."""
    try:
        with _term_as_interrupt():  # a station's or scheduler's kill: outputs cleaned up as for Ctrl-C
            result = app(args=argv, prog_name="tumblecal", standalone_mode=False)
        sys.stdout.flush()  # a reader that stopped early (`| head`) is found here, not at exit
    except (PipeClosed, BrokenPipeError):
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no flush error at exit
        return PipeClosed.exit_code
    except TumblecalError as err:
        if _state["debug"]:
            raise
        _report(str(err), err.hint, err.more)
        return err.exit_code
    except typer.Exit as err:
        return err.exit_code
    except typer.TyperException as err:  # the parser's usage errors: one line, like ours
        if type(err).__name__ == "NoArgsIsHelpError":  # bare `tumblecal`: the help, on stderr
            getattr(err, "show", print)()
            return 2
        ctx = getattr(err, "ctx", None)
        command = ctx.command_path if ctx is not None else "tumblecal"
        _report(err.format_message(), f"see '{command} --help'")
        return 2
    except (typer.Abort, KeyboardInterrupt):
        _report("interrupted", None)
        return 130
    except Interrupted as err:  # SIGTERM (_term_as_interrupt)
        _report(str(err), None)
        return Interrupted.exit_code
    except OSError as err:  # the system refused (a full disk, stdout on /dev/full): not a bug
        if _state["debug"]:
            raise
        _report(f"{err.filename}: {err.strerror or err}" if err.filename else f"{err.strerror or err}", None)
        return 2
    except Exception as err:  # a bug: one line unless --debug
        if _state["debug"]:
            raise
        _report(f"internal error: {type(err).__name__}: {err}", "run with --debug for the traceback")
        return 2
    finally:
        _state["debug"] = False
    return result if isinstance(result, int) else 0


def _report(message: str, hint: str | None, more: tuple[str, ...] = ()) -> None:
    for line in (message, *more):
        print(f"error: {line}", file=sys.stderr)
    if hint:
        print(f"hint: {hint}", file=sys.stderr)


def main_exit() -> None:
    """Console-script entry point: the status, without the interpreter's teardown.

    Every file is written (atomically) and every pool shut down before main() returns; what
    is left is the interpreter's teardown, where a native library's thread (pyarrow's, seen
    about once in 500 runs) could abort the process and turn a documented status into 134."""
    status = main()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # a closed pipe: main() has said so already
            stream.flush()
    os._exit(status)
