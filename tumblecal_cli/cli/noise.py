"""tumblecal noise: Allan deviation of a still capture, its noise figures, judged against limits."""

from __future__ import annotations

from enum import StrEnum
from typing import Annotated

import typer

from tumblecal_cli.cli import render
from tumblecal_cli.cli.app import Command, app
from tumblecal_cli.cli.flags import (
    AllowCorrected,
    AxesOption,
    Columns,
    Decimal,
    DropIncomplete,
    End,
    NoHeader,
    Quiet,
    Rate,
    Sensor,
    SensorKind,
    SkipRows,
    Start,
    StreamOption,
    TimeColumn,
    TimeUnit,
    TimeUnitOption,
    file_shape,
    limit_option,
    source,
)
from tumblecal_cli.errors import InputError


class UnitChoice(StrEnum):
    native = "native"
    datasheet = "datasheet"
    si = "si"


@app.command(
    cls=Command,
    epilog="Exit status: 0 within the limits (or none given); 1 a figure above its limit; 2 usage or input "
    "error (no rate, unknown units for --kalibr); 3 the capture moved (a step, or a drift far above its "
    "random walk), or --kalibr needs a figure the capture is too short to show.",
)
def noise(
    capture: Annotated[str, typer.Argument(metavar="CAPTURE", help="A capture of one still pose; '-' reads stdin.")],
    rate: Rate = None,
    sensor: Sensor = SensorKind.accelerometer,
    stream: StreamOption = None,
    allow_corrected: AllowCorrected = False,
    cal: Annotated[
        str | None,
        typer.Option("--cal", "-c", metavar="FILE", help="Correct with this calibration: figures in its units."),
    ] = None,
    units: Annotated[
        UnitChoice | None,
        typer.Option(
            "--units",
            help="native: the data's units per √Hz; datasheet: µg/√Hz, µg (accelerometer), °/√h, °/h (gyroscope); "
            "si: m/s², rad/s. [default: datasheet with a --cal in known units, else native]",
        ),
    ] = None,
    taus: Annotated[
        int, typer.Option("--taus", metavar="N", help="Cluster times per octave (1: τ0, 2τ0, 4τ0 ...).")
    ] = 1,
    limits: Annotated[
        str | None,
        limit_option("--limits", "FILE", "Limits file: noise_density, bias_instability, random_walk (reported units)."),
    ] = None,
    json_summary: Annotated[
        bool, typer.Option("--json", help="Print the curve and figures on stdout as JSON.")
    ] = False,
    plot: Annotated[
        str | None, typer.Option("--plot", metavar="PNG", help="Draw the curve, its band and the read-offs.")
    ] = None,
    kalibr: Annotated[
        str | None,
        typer.Option("--kalibr", metavar="YAML", help="Write (or update) Kalibr's imu.yaml noise model, in SI."),
    ] = None,
    columns: Columns = None,
    axes: AxesOption = None,
    no_header: NoHeader = False,
    time_column: TimeColumn = None,
    time_unit: TimeUnitOption = TimeUnit.auto,
    skip_rows: SkipRows = None,
    decimal: Decimal = None,
    drop_incomplete: DropIncomplete = False,
    start: Start = None,
    end: End = None,
    quiet: Quiet = False,
    verbose: Annotated[
        bool, typer.Option("--verbose", "-v", help="Also print the cluster times each figure was read at.")
    ] = False,
) -> None:
    """Allan deviation of a still capture (overlapping, octave cluster times, with its confidence
    band) and the noise figures read off it (IEEE Std 952): noise density at τ = 1 s, bias
    instability (the flat minimum / 0.664), random walk at τ = 3 s. A figure the capture is too
    short to show is "not determined". Streams: a day at 200 Hz runs in bounded memory.

    \b
      tumblecal noise still.csv --rate 100
      tumblecal noise gyro.csv --sensor gyroscope --cal gyro.json --limits l.yaml
      tumblecal noise acc.csv --cal acc.json --kalibr imu.yaml --plot adev.png
    """

    from tumblecal_cli.pipeline import noise as pipeline

    _targets(plot, kalibr, json_summary, [capture, *(p for p in (cal, limits) if p)])
    with render.samples_progress(enabled=not quiet) as progress:
        done = pipeline.noise(
            capture,
            rate=rate,
            sensor=sensor.value,
            cal=cal,
            limits=limits,
            units=units and units.value,
            per_octave=taus,
            columns=columns,
            axes=axes,
            no_header=no_header,
            time_column=time_column,
            time_unit=time_unit.value,
            **file_shape(skip_rows, decimal, drop_incomplete),
            **source(stream, allow_corrected),
            start=start,
            end=end,
            progress=progress,
            kalibr=kalibr is not None,
        )
    render.show_noise(done, json_summary=json_summary, shown=render.Shown(quiet, verbose), plot=plot)
    if done.error is not None:
        raise done.error
    if kalibr is not None:
        pipeline.write_kalibr(kalibr, done)
    if done.status:
        raise typer.Exit(done.status)


def _targets(plot: str | None, kalibr: str | None, json_summary: bool, inputs: list[str]) -> None:
    """Refuse a --plot or --kalibr path that names an input or cannot be written, before any work."""
    from tumblecal_cli.cli.flags import check_plot_target
    from tumblecal_cli.io.outputs import check_not_input, check_writable

    if plot is not None:
        check_plot_target(plot, "-", json_summary, inputs)
    if kalibr is not None:
        if kalibr == "-":
            raise InputError("--kalibr writes a file: give a path (imu.yaml)")
        check_not_input(kalibr, inputs, "--kalibr")
        check_writable(kalibr, "--kalibr")
