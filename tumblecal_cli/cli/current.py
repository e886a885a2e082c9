"""tumblecal current: magnetometer logs with a motor-current column and the magnetometer's
calibration in, the calibration with its offset per ampere (a ``current`` block) out."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import typer

from tumblecal_cli.cli import render
from tumblecal_cli.cli.app import Command, app
from tumblecal_cli.cli.flags import AllowCorrected, Columns, JsonSummary, LimitsFile, Quiet, StreamOption, source

if TYPE_CHECKING:
    from rich.console import Console

    from tumblecal_cli.pipeline.current import CurrentResult


@app.command(
    cls=Command,
    epilog="Exit status: 0 written; 1 written, but the field's change at the largest current is above the limits "
    "file's current_interference; 2 usage or input error (not a magnetometer's calibration, no such current "
    "column, a current cell that is not a number); 3 a current that never changes within a log, or too few "
    "readings. Nothing is written on 2 or 3.",
)
def current(
    logs: Annotated[
        list[str],
        typer.Argument(
            metavar="LOG...",
            help="Magnetometer logs with a current column, each of the vehicle still (in one attitude) while its "
            "motors run up; each log may be in another attitude.",
        ),
    ],
    cal: Annotated[
        str, typer.Option("--cal", "-c", metavar="FILE", help="The magnetometer's calibration (any solver).")
    ] = ...,  # type: ignore[assignment]
    current_column: Annotated[
        str,
        typer.Option("--current-column", metavar="NAME", help="The column of the motor current, in amperes."),
    ] = ...,  # type: ignore[assignment]
    output: Annotated[
        str, typer.Option("--output", "-o", metavar="FILE", help="The calibration with its current block; '-' stdout.")
    ] = "-",
    limits: LimitsFile = None,
    columns: Columns = None,
    stream: StreamOption = None,
    allow_corrected: AllowCorrected = False,
    json_summary: JsonSummary = False,
    quiet: Quiet = False,
) -> None:
    """Fit a magnetometer's offset per ampere of motor current (per axis, with its uncertainty and the
    share of the field's variation it explains) and add it to the calibration: apply then corrects each
    row at its own current, and export writes it as COMPASS_MOT or CAL_MAGn_xCOMP (docs/current.md).

    \b
      tumblecal current runup.csv --cal mag.json --current-column curr_a -o mag-current.json
    """
    from tumblecal_cli.errors import InputError
    from tumblecal_cli.io.outputs import check_not_input, check_writable
    from tumblecal_cli.pipeline import current as pipeline

    if json_summary and output == "-":
        raise InputError("--json prints the summary on stdout, so the calibration needs -o FILE")
    check_not_input(output, [cal, *logs])
    check_writable(output)
    done = pipeline.current(
        logs,
        cal,
        current_column=current_column,
        columns=columns.split(",") if columns else None,
        limits=limits,
        **source(stream, allow_corrected),
    )
    done.calibration.save(output)
    if json_summary:
        render.print_json(
            {"status": "fail" if done.status else "pass", "exit_status": done.status, **current_doc(done)}
        )
    if not quiet:
        print_current(done, render.make_console())
    if done.status:
        raise typer.Exit(done.status)


def current_doc(done: CurrentResult) -> dict[str, object]:
    """The --json summary of ``tumblecal current``: the block, the field's change at the largest
    current as a share of the reference, warnings and notes."""
    block = done.calibration.current
    assert block is not None  # what current() made
    return {
        "current": block.as_dict(),
        "interference": done.interference[0],
        "interference_sigma": done.interference[1],
        "verdict": None
        if done.limit is None
        else {
            "pass": not done.failures,
            "failures": [f.as_dict() for f in done.failures],
            "limits": {"current_interference": done.limit},
        },
        "warnings": done.warnings,
        "notes": done.notes,
    }


def print_current(done: CurrentResult, console: Console) -> None:
    """``tumblecal current`` for people: the fit per axis, how much it explains, warnings, notes."""
    fit = done.fit
    cal = done.calibration
    console.print(
        f"current: {fit.samples} readings from {len(done.logs)} log{'s' if len(done.logs) != 1 else ''}, "
        f"{fit.span[0]:.3g} to {fit.span[1]:.3g} A",
        soft_wrap=True,
    )
    units = cal.input_units or "raw units"
    terms = ", ".join(f"{a} {k:+.4g} ± {se:.2g}" for a, k, se in zip("xyz", fit.per_amp, fit.per_amp_se, strict=True))
    console.print(f"offset per ampere ({units}/A): {terms}", soft_wrap=True)
    console.print(render.current_line(cal), soft_wrap=True)
    for line in done.warnings:
        console.print(line, style="yellow", soft_wrap=True)
    for note in done.notes:
        console.print(f"note: {note}", soft_wrap=True)
    if done.limit is not None:
        word = "FAIL" if done.failures else "PASS"
        said = "".join(f": {f.message}" for f in done.failures)
        console.print(f"verdict: {word} (limit: current_interference {done.limit:g}){said}", soft_wrap=True)
