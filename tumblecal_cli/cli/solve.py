"""tumblecal solve: pose files (or one log) in, a calibration file out."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import typer

from tumblecal_cli.cli import render
from tumblecal_cli.cli.app import ManyValuesCommand, app
from tumblecal_cli.cli.flags import (
    CHECKS_PANEL,
    EXIT_CODES,
    SOLVER_PANEL,
    UNIT_PANEL,
    AccelCal,
    AlignTo,
    AllowCorrected,
    AxesOption,
    CheckName,
    Columns,
    Date,
    Decimal,
    DropIncomplete,
    End,
    FieldModel,
    Gravity,
    JsonSummary,
    LimitsFile,
    Location,
    LotName,
    MaxGainError,
    MaxOffset,
    MaxSpool,
    MethodName,
    MinDuration,
    NoHeader,
    NominalGain,
    PlaneName,
    PoseColumn,
    PoseMap,
    Quiet,
    Rate,
    RecordDb,
    RowsArePoses,
    Sensor,
    SensorKind,
    SkipRows,
    Start,
    StreamOption,
    Threshold,
    TimeColumn,
    TimeUnit,
    TimeUnitOption,
    Trim,
    TurnAngle,
    Turns,
    Verbose,
    Window,
    check_plot_target,
    method_help,
)
from tumblecal_cli.cli.records import Saver
from tumblecal_cli.errors import InputError

if TYPE_CHECKING:
    from tumblecal_cli.pipeline.solve.solving import Solved


@app.command(cls=ManyValuesCommand, epilog=EXIT_CODES)
def solve(
    poses: Annotated[
        list[str] | None,
        typer.Option(
            "--poses",
            "-p",
            metavar="FILE...",
            help="Pose files, all after one --poses; each FILE or LABEL=FILE, LABEL a face (+x -x +y -y +z -z, "
            "xp ... zn) or a direction X,Y,Z (0.707,0,0.707=a.csv). Unlabelled: files each named for a different "
            "face (xp.csv xn.csv ..., x_p, +x) take it, in any order; else 1 file is the --up face, "
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
            "Face solvers take the best block of each face (the least tilted of the longest); sphere takes "
            "every kept block. '-' reads stdin.",
        ),
    ] = None,
    window: Window = None,
    threshold: Threshold = None,
    min_duration: MinDuration = None,
    trim: Trim = None,
    pose_column: PoseColumn = None,
    pose_map: PoseMap = None,
    turns: Turns = None,
    turn_angle: TurnAngle = None,
    accel_cal: AccelCal = None,
    max_spool: MaxSpool = None,
    align_to: AlignTo = None,
    spin: Annotated[
        list[str] | None,
        typer.Option(
            "--spin",
            metavar="RATE=FILE",
            help="A gyroscope spun at a known rate, repeatable: 45rpm=a.csv, 270deg/s=b.csv, 0=rest.csv; "
            "+z@45rpm=FILE: that face up (docs/recipes/gyroscope.md).",
            rich_help_panel=SOLVER_PANEL,
        ),
    ] = None,
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
            "9.80665 (m/s^2), 16384 (LSB at +-2 g), a magnetometer's field (or --location). "
            "1-pose's is in the file's units. [default: 1; a gyroscope 0: its rates by --spin]",
        ),
    ] = None,
    method: Annotated[
        MethodName,
        typer.Option("--method", "-m", metavar="NAME", help=method_help()),
    ] = MethodName.auto,
    sensor: Sensor = SensorKind.accelerometer,
    stream: StreamOption = None,
    allow_corrected: AllowCorrected = False,
    tilt_compensate: Annotated[
        bool,
        typer.Option(
            "--tilt-compensate",
            help="1-pose: take the attitude from the readings, so fixture tilt leaves the up offset alone "
            "(method one-pose-tilt).",
            rich_help_panel=SOLVER_PANEL,
        ),
    ] = False,
    no_robust: Annotated[
        bool,
        typer.Option(
            "--no-robust",
            help="ellipsoid, minmax, least-squares, known-rates: fit everything by plain least squares (by "
            "default samples, poses or runs far off the fit are left out and named).",
            rich_help_panel=SOLVER_PANEL,
        ),
    ] = False,
    bias_spread: Annotated[
        float | None,
        typer.Option(
            "--bias-spread",
            metavar="V",
            help="one-pose-tilt: the spread (1σ) of the horizontal offsets, in the file's units; it bounds "
            "the up offset's error. [default: 0.01 x reference]",
            rich_help_panel=SOLVER_PANEL,
        ),
    ] = None,
    plane: Annotated[
        PlaneName | None,
        typer.Option(
            "--plane",
            help="minmax: the capture turned in one plane only (2-D); that plane's axes.",
            rich_help_panel=SOLVER_PANEL,
        ),
    ] = None,
    units: Annotated[
        str | None,
        typer.Option(
            "--units",
            metavar="TEXT",
            help="Label of the corrected units (default 'g' for reference 1).",
            rich_help_panel=SOLVER_PANEL,
        ),
    ] = None,
    input_units: Annotated[
        str | None,
        typer.Option(
            "--input-units", metavar="TEXT", help="Label of the raw units, e.g. counts.", rich_help_panel=SOLVER_PANEL
        ),
    ] = None,
    rows_are_poses: RowsArePoses = None,
    location: Location = None,
    gravity: Gravity = None,
    date: Date = None,
    field_model: FieldModel = None,
    columns: Columns = None,
    axes: AxesOption = None,
    no_header: NoHeader = False,
    time_column: TimeColumn = None,
    time_unit: TimeUnitOption = TimeUnit.auto,
    rate: Rate = None,
    skip_rows: SkipRows = None,
    decimal: Decimal = None,
    drop_incomplete: DropIncomplete = False,
    start: Start = None,
    end: End = None,
    json_summary: JsonSummary = False,
    quiet: Quiet = False,
    verbose: Verbose = False,
    plot: Annotated[
        str | None,
        typer.Option(
            "--plot",
            metavar="PNG",
            help="Also draw the fit: each pose's residual after calibration with the limits, and before "
            "(docs/plots.md; tumblecal[plot]).",
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
            "judged. ferraris-turns: deg/s of the calibrated gyroscope on a still face (default 1). "
            "[default: 0.02]",
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
    gain_tolerance: Annotated[
        float,
        typer.Option(
            "--gain-tolerance",
            metavar="FRACTION",
            min=0,
            help="one-pose, one-pose-tilt: the up axis's gain error (a fraction) its offset may hold: one pose "
            "cannot tell a gain error from an offset, so FRACTION x reference is added to that offset's "
            "tilt_sensitivity.",
            rich_help_panel=CHECKS_PANEL,
        ),
    ] = 0.02,
    no_checks: Annotated[
        bool, typer.Option("--no-checks", help="Turn every quality check off.", rich_help_panel=CHECKS_PANEL)
    ] = False,
    no_check: Annotated[
        list[CheckName] | None,
        typer.Option(
            "--no-check",
            metavar="CHECK",
            help="Turn one check off: moved, orientation, saturated, short, upside-down or coverage (repeatable).",
            rich_help_panel=CHECKS_PANEL,
        ),
    ] = None,
    no_trim: Annotated[
        bool,
        typer.Option(
            "--no-trim",
            help="Judge each pose file whole. Without it, a file rejected as moved (the unit placed or lifted "
            "while it logged) is solved from its one still run, with a note naming its rows; still runs in two "
            "orientations are exit 3.",
            rich_help_panel=CHECKS_PANEL,
        ),
    ] = False,
    # -- limits (exit 1) --
    limits: LimitsFile = None,
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
    lot: LotName = None,
    record: RecordDb = None,
) -> None:
    """Average each pose file, check it, solve for the offsets (and gains), judge the unit.

    \b
      tumblecal solve --poses x.csv y.csv z.csv -o cal.json   # 3-pose
      tumblecal solve --poses z.csv --up=-x --reference 16384 # 1-pose, counts
      tumblecal solve -p x.csv y.csv z.csv -o cal.json --limits limits.yaml
      tumblecal solve --log session.csv --reference 9.81 -o cal.json

    Writes the calibration on exit 0 (pass) and 1 (outside its limits), nothing on 2 or 3;
    prints it, the verdict, warnings and notes (-v: each pose and block too).
    """

    given = {name: value for name, value in locals().items() if name not in CLI_ONLY}  # (locals: the parameters)
    from tumblecal_cli.io.outputs import check_not_input, check_writable
    from tumblecal_cli.pipeline.options import SolveOptions
    from tumblecal_cli.pipeline.solve import solving as pipeline

    options = SolveOptions.of(given)

    inputs = _inputs(poses, [log, limits, accel_cal, align_to], spin)
    if json_summary and output == "-" and (poses or log or spin):
        raise InputError("--json prints the summary on stdout, so the calibration needs -o FILE")
    check_not_input(output, inputs)
    check_writable(output)
    if plot is not None:
        check_plot_target(plot, output, json_summary, inputs)
    save = Saver(record, lot, "solve")  # (--record: the database checked before any work)
    solved = pipeline.calibrate(options, poses=poses, log=log)
    shown = render.Shown(quiet=quiet, verbose=verbose)
    _show(
        solved, output=output, json_summary=json_summary, shown=shown, plot=plot, plane=plane and plane.value, save=save
    )


def _inputs(poses: list[str] | None, files: list[str | None], spin: list[str] | None) -> list[str]:
    """Every file solve reads, which -o must not name: the pose files (of ``LABEL=FILE`` too), the
    log, limits and calibrations given, and the --spin items' files."""
    given = [*(poses or []), *(p.partition("=")[2] for p in poses or [] if "=" in p)]
    return given + [f for f in files if f] + [item.partition("=")[2] for item in spin or []]


#: The parameters of solve that are the command line's own: what to read, where to write and what
#: to print. Every other parameter is one of solve's flat options (pipeline.options.FLAT, the
#: Python API's SolveKeywords), passed to SolveOptions.of by its name; batch takes them too.
CLI_ONLY = ("poses", "log", "output", "json_summary", "quiet", "verbose", "plot", "lot", "record")


def _show(
    solved: Solved,
    *,
    output: str,
    json_summary: bool,
    shown: render.Shown,
    plot: str | None,
    plane: str | None,
    save: Saver | None = None,
) -> None:
    """The blocks of a log (-v: their table), the calibration's summary, the --json summary;
    the calibration written (exit 0 and 1), or the rejection raised (exit 3): the rejection
    alone, with no results before it (-v: the draft's, for inspection)."""
    quiet, verbose = shown.quiet, shown.verbose
    console = None if quiet else render.make_console()  # (-q: Rich not imported)
    cal, draft = solved.calibration, solved.draft
    if solved.blocks is not None and console is not None:  # rejected: the log's warnings alone, unless -v
        blocks, table = solved.blocks, verbose or (False if cal is not None else None)
        render.print_blocks(blocks.log, blocks.seg, console, used=blocks.used, everything=False, table=table)
    if cal is None:
        assert solved.error is not None
        if draft is not None and verbose and console is not None:
            render.print_summary(draft, console, solved.warnings, solved.notes, judged=False)
        if json_summary:
            render.print_json(
                render.summary(draft, 3, None, solved.rejections, solved.warnings, solved.notes)
                if draft is not None
                else render.rejected_head(solved.error)
            )
        raise solved.error
    if plot is not None:  # drawn before the calibration is written: a failure leaves nothing behind
        from tumblecal_cli.pipeline import plotting

        plotting.solve_plot(plot, solved, plane)
    if save is None:
        cal.save(output)
    else:
        save(cal, output, solved.status)
    if console is not None:
        render.print_summary(cal, console, solved.warnings, solved.notes, judged=True, verbose=verbose)
        if output != "-":
            console.print(f"wrote {output}", soft_wrap=True)
    if json_summary:
        render.print_json(render.summary(cal, solved.status, output, [], solved.warnings, solved.notes))
    if solved.status:
        raise typer.Exit(solved.status)
