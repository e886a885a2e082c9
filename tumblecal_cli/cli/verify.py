"""tumblecal verify: a calibration checked on static captures it was not fitted on."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import typer

from tumblecal_cli.cli import render
from tumblecal_cli.cli.app import Command, app
from tumblecal_cli.cli.flags import (
    AllowCorrected,
    Columns,
    Date,
    Decimal,
    DropIncomplete,
    End,
    Gravity,
    Location,
    LotName,
    NoHeader,
    Quiet,
    RecordDb,
    RowsArePoses,
    SkipRows,
    Start,
    StreamArguments,
    StreamOption,
    check_plot_target,
    file_shape,
    source,
)
from tumblecal_cli.cli.records import Saver
from tumblecal_cli.errors import InputError

if TYPE_CHECKING:
    from tumblecal_cli.pipeline.frames import JSONObject
    from tumblecal_cli.pipeline.verify import Verified


@app.command(
    cls=Command,
    epilog="Exit status: 0 every capture within --max-norm-error (or none given); 1 some capture outside it; "
    "2 usage or input error; 3 a capture that is not static (above --max-noise).",
)
def verify(
    captures_: Annotated[
        list[str] | None,
        typer.Argument(
            metavar="CAPTURE", help="Static captures the calibration was not fitted on, one or more; '-' reads stdin."
        ),
    ] = None,
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
    log: Annotated[
        str | None,
        typer.Option(
            "--log",
            metavar="FILE",
            help="Instead of captures: a gyroscope calibration judged on a log of hand turns between still poses "
            "(with --accel-cal): each rotation's gravity error before and after it.",
        ),
    ] = None,
    accel_cal: Annotated[
        str | None,
        typer.Option("--accel-cal", metavar="FILE", help="With --log: the accelerometer calibration (gravity)."),
    ] = None,
    spin: Annotated[
        list[str] | None,
        typer.Option(
            "--spin",
            metavar="RATE=FILE",
            help="Instead of captures: a gyroscope calibration judged on files spun at known rates (45rpm=a.csv, "
            "repeatable, as solve takes them): |corrected| - rate over each file's steady runs (RMS, largest), "
            "exit 1 over --max-norm-error.",
        ),
    ] = None,
    rate: Annotated[
        float | None,
        typer.Option(
            "--rate",
            metavar="HZ",
            help="The sample rate, for a log (--log) or captures without a time column (--start/--end in seconds).",
        ),
    ] = None,
    columns: Columns = None,
    stream: StreamOption = None,
    allow_corrected: AllowCorrected = False,
    no_header: NoHeader = False,
    skip_rows: SkipRows = None,
    decimal: Decimal = None,
    drop_incomplete: DropIncomplete = False,
    start: Start = None,
    end: End = None,
    rows_are_poses: RowsArePoses = None,
    location: Location = None,
    gravity: Gravity = None,
    date: Date = None,
    json_summary: Annotated[
        bool, typer.Option("--json", help="Print the per-capture and overall figures on stdout as JSON.")
    ] = False,
    plot: Annotated[
        str | None,
        typer.Option(
            "--plot",
            metavar="PNG",
            help="Draw each capture's norm error after calibration with --max-norm-error, and before it; "
            "needs tumblecal[plot].",
        ),
    ] = None,
    quiet: Quiet = False,
    lot: LotName = None,
    record: RecordDb = None,
) -> None:
    """Check a calibration on static captures it was not fitted on: the norm of each mean, before
    and after correction, against the reference (the test of a calibration model in Sports
    Sensing 2023). A magnetometer's turning capture is judged sample by sample: the RMS and
    largest |corrected| - reference, and the directions it reaches.

    \b
      tumblecal verify --cal cal.json check1.csv check2.csv check3.csv
      tumblecal verify --cal cal.json tilted/*.csv --max-norm-error 0.005 --json
      tumblecal verify --cal cal.json tilted/*.csv --max-norm-error 0.005 --plot verify.png
    """

    from tumblecal_cli.pipeline import verify as pipeline

    found = source(stream, allow_corrected)
    _check_plot(plot, log is not None or accel_cal is not None, json_summary, [*(captures_ or []), cal])
    if log is not None or accel_cal is not None:
        where = (log, accel_cal, rate, columns, captures_, found, (start, end))
        return _rotations(cal, *where, json_summary=json_summary, quiet=quiet)
    save = Saver(record, lot, "verify")  # (--record: a re-test of the unit, checked before any work)
    done = pipeline.verify(
        captures_ or [],
        cal,
        reference=reference,
        location=location,
        gravity=gravity,
        date=date,
        max_norm_error=max_norm_error,
        max_noise=max_noise,
        columns=columns,
        no_header=no_header,
        **file_shape(skip_rows, decimal, drop_incomplete),
        **found,
        start=start,
        end=end,
        rate=rate,
        rows_are_poses=rows_are_poses,
        spin=spin,
    )
    _recorded(done, _summary(done, cal, max_norm_error), save, json_summary=json_summary)
    if not quiet and done.error is None:  # a capture that is not static: its rejection alone
        render.print_verify(done.cal, done.rows, done.overall, done.reference, max_norm_error, done.failed)
        for note in done.notes:
            render.tell(render.make_console(), f"note: {note}")
    if done.error is not None:
        raise done.error
    if plot is not None:  # exit 0 and 1: the errors are what the figure shows
        _plot_verify(plot, done, quiet=quiet)
    if done.status:
        raise typer.Exit(done.status)


def _check_plot(plot: str | None, turns: bool, json_summary: bool, inputs: list[str]) -> None:
    """--plot's target judged before any work (a --log of hand turns has no norm errors to draw)."""
    if plot is not None:
        if turns:
            raise InputError("--plot draws the errors of static captures, not of a --log of hand turns")
        check_plot_target(plot, "-", json_summary, inputs)


def _recorded(done: Verified, summary: JSONObject, save: Saver, *, json_summary: bool) -> None:
    """--record: the re-test recorded before anything is printed (a failed record is the one
    error); --json: the summary."""
    if done.error is None:
        save.retest(done.cal, done.status, dict(summary))
    if json_summary:
        render.print_json(summary)


def _plot_verify(plot: str, done: Verified, *, quiet: bool) -> None:
    from tumblecal_cli.pipeline import plotting

    plotting.verify_plot(plot, done)
    if plot != "-" and not quiet:
        render.make_console().print(f"wrote {plot}", soft_wrap=True, markup=False)


def _summary(done: Verified, cal: str, max_norm_error: float | None) -> JSONObject:
    """verify --json: the per-capture and overall figures."""
    return {
        "status": render.status_word(done.status),
        "exit_status": done.status,
        "cal": cal,
        "reference": done.reference,
        "max_norm_error": max_norm_error,
        "captures": done.rows,
        **done.overall,
        "rejections": done.rejected,
        "failed": done.failed,
        "notes": done.notes,
    }


def _rotations(
    cal: str,
    log: str | None,
    accel_cal: str | None,
    rate: float | None,
    columns: str | None,
    captures_: list[str] | None,
    given: StreamArguments,
    part: tuple[str | None, str | None],
    *,
    json_summary: bool,
    quiet: bool,
) -> None:
    """verify --log LOG --accel-cal ACC: a gyroscope calibration on held-out hand turns."""
    if part != (None, None):
        raise InputError("--start/--end pick a part of static captures, not of a --log of hand turns")
    from tumblecal_cli.pipeline import verify as pipeline

    if log is None or accel_cal is None or captures_:
        raise InputError("a gyroscope is verified on one --log of hand turns with --accel-cal (and no captures)")
    done = pipeline.verify_rotations(log, cal, accel_cal=accel_cal, rate=rate, columns=columns, **given)
    if json_summary:
        render.print_json({"status": "pass", "exit_status": 0, "cal": cal, "rotations": done.rows, **done.overall})
    if not quiet:
        console = render.make_console()
        console.print("rotation          angle  error before  error after", soft_wrap=True, markup=False)
        for r in done.rows:
            console.print(
                f"{r['rotation']:<16} {r['angle_deg']:6.1f}°  {r['error_before_deg']:11.2f}°  "
                f"{r['error_after_deg']:10.2f}°",
                soft_wrap=True,
                markup=False,
            )
        o = done.overall
        console.print(
            f"RMS error {o['rms_error_before_deg']:.3g}° before, {o['rms_error_after_deg']:.3g}° after "
            f"(largest {o['max_error_before_deg']:.3g}°, {o['max_error_after_deg']:.3g}°) "
            f"over {len(done.rows)} rotations",
            soft_wrap=True,
            markup=False,
        )
