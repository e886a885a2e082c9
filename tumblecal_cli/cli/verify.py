"""tumblecal verify: a calibration checked on static captures it was not fitted on."""

from __future__ import annotations

from typing import Annotated

import typer

from tumblecal_cli.cli import render
from tumblecal_cli.cli.app import Command, app
from tumblecal_cli.cli.options import Columns, Decimal, DropIncomplete, NoHeader, Quiet, SkipRows


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
    skip_rows: SkipRows = None,
    decimal: Decimal = None,
    drop_incomplete: DropIncomplete = False,
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

    from tumblecal_cli.pipeline import verify as pipeline

    done = pipeline.verify(
        captures_,
        cal,
        reference=reference,
        max_norm_error=max_norm_error,
        max_noise=max_noise,
        columns=columns,
        no_header=no_header,
        skip_rows=skip_rows,
        decimal=decimal and decimal.value,
        drop_incomplete=drop_incomplete,
    )
    if json_summary:
        render.print_json(
            {
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
        )
    if not quiet:
        render.print_verify(done.cal, done.rows, done.overall, done.reference, max_norm_error, done.failed)
        for note in done.notes:
            render.make_console().print(f"note: {note}", soft_wrap=True, markup=False)
    if done.error is not None:
        raise done.error
    if done.status:
        raise typer.Exit(done.status)
