"""tumblecal thermal: temperature sweeps and a base calibration in, the calibration with its
temperature drift (a ``thermal`` block) out."""

from __future__ import annotations

from typing import Annotated

import typer

from tumblecal_cli.cli import render
from tumblecal_cli.cli.app import LabelledItemsCommand, app
from tumblecal_cli.cli.flags import (
    CHECKS_PANEL,
    AllowCorrected,
    Columns,
    JsonSummary,
    LotName,
    Quiet,
    RecordDb,
    SensorKind,
    StreamOption,
    check_plot_target,
    source,
)
from tumblecal_cli.cli.records import Saver


@app.command(
    cls=LabelledItemsCommand,
    epilog="Exit status: 0 written; 2 usage or input error (a sweep without the temperature column, a cell that "
    "is not a number, a base without a temperature and no --reference-temperature); 3 a temperature that cannot "
    "carry the fit (constant, noise without a trend, a swing too small for the order) or a sweep that moved "
    "once its drift is removed. Nothing is written on 2 or 3.",
)
def thermal(
    sweeps: Annotated[
        list[str],
        typer.Argument(
            metavar="SWEEP...",
            help="Still captures during which the temperature changes, each FILE or LABEL=FILE labelled as "
            "solve --poses takes them (+z=up.csv -z=down.csv); a gyroscope's in any pose, unlabelled.",
        ),
    ],
    cal: Annotated[
        str, typer.Option("--cal", "-c", metavar="FILE", help="The unit's calibration at one temperature (any solver).")
    ] = ...,  # type: ignore[assignment]
    output: Annotated[
        str, typer.Option("--output", "-o", metavar="FILE", help="The calibration with its thermal block; '-' stdout.")
    ] = "-",
    temperature_column: Annotated[
        str | None,
        typer.Option(
            "--temperature-column",
            metavar="NAME",
            help="The temperature column, in °C (default: temp, temperature, temp_c, die_temp ...).",
        ),
    ] = None,
    reference_temperature: Annotated[
        float | None,
        typer.Option(
            "--reference-temperature",
            metavar="DEGC",
            help="The temperature the base calibration was made at. [default: the mean its poses recorded]",
        ),
    ] = None,
    order: Annotated[
        str,
        typer.Option(
            "--order",
            metavar="1|2|3|auto",
            help="Polynomial order of the drift in (T - T_ref); auto chooses by cross-validation over temperature.",
        ),
    ] = "auto",
    min_swing: Annotated[
        float,
        typer.Option(
            "--min-swing",
            metavar="DEGC",
            min=0,
            help="Reject (exit 3) a swing below DEGC for order 1, DEGC + 5 °C per order above.",
            rich_help_panel=CHECKS_PANEL,
        ),
    ] = 10.0,
    max_noise: Annotated[
        float | None,
        typer.Option(
            "--max-noise",
            metavar="V",
            help="Reject (exit 3) a sweep whose standard deviation or drift, once the fitted drift is removed, "
            "is above V output units: it moved. [default: 0.02 x reference; off for a gyroscope]",
            rich_help_panel=CHECKS_PANEL,
        ),
    ] = None,
    columns: Columns = None,
    sensor: Annotated[
        SensorKind | None,
        typer.Option(
            "--sensor",
            help="The sensor the sweeps are of; it must be the base calibration's (a gyroscope fits its zero-rate "
            "bias from still captures in any pose). [default: the calibration's]",
        ),
    ] = None,
    stream: StreamOption = None,
    allow_corrected: AllowCorrected = False,
    plot: Annotated[
        str | None,
        typer.Option(
            "--plot",
            metavar="PNG",
            help="Draw each axis's drift against temperature, the fit and residuals; needs tumblecal[plot].",
        ),
    ] = None,
    json_summary: JsonSummary = False,
    quiet: Quiet = False,
    lot: LotName = None,
    record: RecordDb = None,
) -> None:
    """Fit each axis's offset and gain drift against temperature from still sweeps, and add it to a
    calibration: apply then corrects each row at its own temperature.

    \b
      tumblecal thermal +z=up.csv -z=down.csv --cal base.json -o base-thermal.json
      tumblecal thermal sweep.csv --cal g.json --temperature-column die -o gt.json
    """
    from tumblecal_cli.errors import InputError
    from tumblecal_cli.io.outputs import check_not_input, check_writable
    from tumblecal_cli.pipeline import thermal as pipeline

    if json_summary and output == "-":
        raise InputError("--json prints the summary on stdout, so the calibration needs -o FILE")
    inputs = [cal, *(s.partition("=")[2] or s for s in sweeps)]
    check_not_input(output, inputs)
    check_writable(output)
    if plot is not None:
        check_plot_target(plot, output, json_summary, inputs)
    save = Saver(record, lot, "thermal")
    done = pipeline.thermal(
        sweeps,
        cal,
        temperature_column=temperature_column,
        reference_temperature=reference_temperature,
        order=order,
        min_swing=min_swing,
        max_noise=max_noise,
        columns=columns.split(",") if columns else None,
        sensor=sensor and sensor.value,
        **source(stream, allow_corrected),
    )
    if plot is not None:  # drawn before the calibration is written: a failure leaves nothing behind
        pipeline.plot(done, plot)
    save(done.calibration, output, 0)
    if json_summary:
        render.print_json({"status": "pass", "exit_status": 0, **render.thermal_doc(done)})
    if not quiet:
        render.print_thermal(done, render.make_console())
