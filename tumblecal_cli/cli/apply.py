"""tumblecal apply: correct captures with a calibration, streamed file to file."""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import Annotated

import typer

from tumblecal_cli.cli import render
from tumblecal_cli.cli.app import Command, app, report
from tumblecal_cli.cli.flags import AxesOption, Columns, Decimal, DropIncomplete, NoHeader, Quiet, SkipRows, file_shape
from tumblecal_cli.errors import InputError


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
        str,
        typer.Option(
            "--output",
            "-o",
            metavar="FILE",
            help="Corrected capture; '-' (the default) is stdout. A name ending .gz, .bz2, .xz or .zst is "
            "written compressed.",
        ),
    ] = "-",
    columns: Columns = None,
    axes: AxesOption = None,
    no_header: NoHeader = False,
    skip_rows: SkipRows = None,
    decimal: Decimal = None,
    drop_incomplete: DropIncomplete = False,
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
            "(docs/commands/batch.md). The captures, --cal and DIR must be at the same paths on every worker.",
        ),
    ] = None,
    quiet: Quiet = False,
) -> None:
    """Correct a capture: each sensor reading becomes M (raw - offset).

    Everything else is copied as it was: the header, the rows and their order, the text of
    every other column and the line endings. The sensor columns are the calibration's own
    (a capture without them is refused unless --columns names them), written with every
    digit needed to round-trip. A calibration whose unit failed its limits is refused
    unless --force. One with a thermal block (tumblecal thermal) corrects each row at its own
    temperature, read from the column the block names; rows outside its range are clamped to it.

    With -o nothing is written unless the whole capture is corrected. To stdout the rows are
    streamed as they are corrected, and a stream cannot be taken back: a bad row far into the
    capture ends it with the line "tumblecal: output incomplete: ..." and exit 2.

    \b
      tumblecal apply --cal cal.json capture.csv -o corrected.csv
      cat capture.csv | tumblecal apply --cal cal.json > corrected.csv
      tumblecal apply --cal cal.json 'logs/*.csv' --out-dir corrected/
    """

    from tumblecal_cli.pipeline import apply as pipeline

    inputs = pipeline.expand(capture or ["-"])
    shape = file_shape(skip_rows, decimal, drop_incomplete)
    if out_dir is not None or dask_scheduler is not None or len(inputs) > 1:
        if output != "-" and out_dir is not None:
            raise InputError("-o names one output; with --out-dir each capture is written into DIR under its own name")
        if out_dir is None:
            raise InputError(
                f"{len(inputs)} captures need --out-dir DIR (each is corrected into DIR under its own name)"
                if len(inputs) > 1
                else "--dask-scheduler corrects captures into --out-dir DIR"
            )
        done = pipeline.correct_many(
            inputs,
            cal,
            out_dir,
            columns=columns,
            no_header=no_header,
            force=force,
            scheduler=dask_scheduler,
            **shape,
            axes=axes,
        )
        _show_many(done, len(set(inputs)), out_dir, quiet=quiet)
        return
    applied = pipeline.correct(
        inputs[0],
        cal,
        output=output,
        columns=columns,
        no_header=no_header,
        force=force,
        **shape,
        axes=axes,
        on_note=None if quiet else lambda note: render.say(render.note_line(note)),
    )
    if not quiet:
        target = "stdout" if output == "-" else output
        render.say(f"corrected {applied.rows} rows of {applied.capture} ({', '.join(applied.columns)}) -> {target}")


def _show_many(done: Iterator[tuple[str, int, str]], total: int, out_dir: str, *, quiet: bool) -> None:
    """A line per capture as it is corrected (an error line for one that failed), then the count."""
    console = render.make_console()
    failed = 0
    for name, status, message in done:
        if status:
            failed += 1
            report(message, None)
        elif not quiet:
            console.print(
                f"corrected {name} -> {os.path.join(out_dir, os.path.basename(name))}",
                soft_wrap=True,
                markup=False,
                highlight=False,
            )
    if failed:
        rest = f"; the others are in {out_dir}" if failed < total else ""
        raise InputError(f"{failed} of {total} capture{'s' if total != 1 else ''} failed (above){rest}")
    if not quiet:
        many = "s" if total != 1 else ""
        console.print(f"corrected {total} capture{many} into {out_dir}", soft_wrap=True, markup=False)
