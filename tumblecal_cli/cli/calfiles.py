"""Commands on calibration files: show, check, export and import."""

from __future__ import annotations

from enum import StrEnum
from typing import TYPE_CHECKING, Annotated

import typer

from tumblecal_cli.cli import render
from tumblecal_cli.cli.app import Command, app
from tumblecal_cli.cli.flags import (
    REGISTERS_PANEL,
    JsonSummary,
    LimitsFile,
    MaxGainError,
    MaxOffset,
    NominalGain,
    Quiet,
    RegisterSign,
    SensorKind,
    Verbose,
)
from tumblecal_cli.errors import one_line
from tumblecal_cli.io.export import registry

if TYPE_CHECKING:  # a name of the registry, to mypy; Typer offers the choices of the enum below
    ExportChoice = str
    ImportChoice = str
else:
    #: --format's and --from's choices: the registries' names (io.export.registry), read when this
    #: module is imported (a format registered later is not offered).
    ExportChoice = StrEnum("ExportChoice", {name: name for name in registry.EXPORTS})
    ImportChoice = StrEnum("ImportChoice", {name: name for name in registry.IMPORTS})


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

    import numpy as np

    from tumblecal_cli.io.calfiles import calfile
    from tumblecal_cli.pipeline.exchange import tilt_notes

    c = calfile.load(cal)
    if json_out:
        render.print_json(c.to_dict())
        return
    console = render.make_console(stderr=False)
    unit = c.unit or calfile.Unit()
    facts = [
        ("file", cal),
        ("sensor", f"{c.sensor}, {c.method}, reference {c.reference:g} {c.units or ''}".rstrip()),
        ("input units", c.input_units),
        ("axes", None if c.axes is None else f"{c.axes.text} (the body's x, y, z; corrected into them)"),
        ("unit", ", ".join(f"{k} {v}" for k, v in unit.as_dict().items() if k != "meta" and v)),
        ("meta", ", ".join(f"{k}={v}" for k, v in unit.meta.items())),
        ("created", f"{c.created or ''} by {c.tool or '?'}"),
    ]
    for key, value in facts:
        if value:
            console.print(f"{key + ':':<12} {one_line(value)}", soft_wrap=True)  # a field with an ESC: escaped
    if np.count_nonzero(c.matrix - np.diag(np.diag(c.matrix))):
        console.print("matrix M (corrected = M (raw - offset)):")
        for row in c.matrix:
            console.print("  " + "  ".join(f"{v:>14.6g}" for v in row))
    aligned = c.fields.get("alignment")
    if isinstance(aligned, dict):  # tumblecal align --aligned-mag
        console.print(f"{'aligned:':<12} {one_line(render.alignment_line(aligned))}", soft_wrap=True)
    notes = tilt_notes(c) if c.tilt_sensitivity and c.uncertainty else []
    render.print_summary(c, console, [], notes, judged=True)


@app.command(cls=Command, epilog="Exit status: 0 within the limits; 1 outside them; 2 usage or input error.")
def check(
    cal: Annotated[str, typer.Argument(metavar="CAL", help="Calibration file; '-' reads stdin.")],
    limits_file: LimitsFile = None,
    max_offset: MaxOffset = None,
    max_gain_error: MaxGainError = None,
    nominal_gain: NominalGain = None,
    json_summary: JsonSummary = False,
    quiet: Quiet = False,
    verbose: Verbose = False,
) -> None:
    """Judge an existing calibration against limits again (the file is not changed).

    \b
      tumblecal check cal.json --limits limits.yaml
      tumblecal check cal.json --max-offset 0.05 --max-gain-error 0.02 --json
    """

    from tumblecal_cli.pipeline import exchange

    checked = exchange.check(
        cal, limits=limits_file, max_offset=max_offset, max_gain_error=max_gain_error, nominal_gain=nominal_gain
    )
    if json_summary:  # the same summary as solve --json, judged afresh
        render.print_json(render.summary(checked.calibration, checked.status, cal, [], [], checked.notes))
    if not quiet:
        console = render.make_console()
        render.print_summary(checked.calibration, console, [], checked.notes, judged=True, verbose=verbose)
    if checked.status:
        raise typer.Exit(checked.status)


@app.command(cls=Command, epilog="Exit status: 0 written; 2 usage or input error (a value that does not fit is one).")
def export(
    cal: Annotated[str, typer.Argument(metavar="CAL", help="Calibration file; '-' reads stdin.")],
    fmt: Annotated[ExportChoice, typer.Option("--format", "-f", help=registry.export_help())],
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
    instance: Annotated[
        int | None,
        typer.Option(
            "--instance",
            metavar="N",
            help="ardupilot, px4: the sensor the parameters are for, in the firmware's numbering (ArduPilot 1-3: "
            "INS_ACC<N>, COMPASS_OFS<N>, INS_TCAL<N>; PX4 0-3: CAL_ACC<N>, CAL_MAG<N>; TC_A<N>/TC_G<N>, 0-2). "
            "[default: the first]",
        ),
    ] = None,
) -> None:
    """Write a calibration for firmware or for another tool.

    \b
      tumblecal export cal.json --format c-header -o imu_cal.h
      tumblecal export cal.json --format registers --lsb 0.98 --bits 16
      tumblecal export cal.json --format imucal-json -o imucal_cal.json
      tumblecal export cal.json --format ardupilot -o accel.parm
      tumblecal export mag.json --format px4 --instance 1 -o mag.params
      tumblecal export cal-thermal.json --format ardupilot -o tcal.parm
    """

    from tumblecal_cli.io.outputs import atomic_output, check_not_input, check_writable
    from tumblecal_cli.pipeline import exchange

    check_not_input(output, [cal])
    check_writable(output)
    done = exchange.exported(
        cal,
        str(fmt),
        prefix=prefix,
        lsb=lsb,
        bits=bits,
        register_sign=register_sign.value,
        gain_step=gain_step,
        nominal_gain=nominal_gain,
        force=force,
        instance=instance,
    )
    with atomic_output(output) as out:
        out.write(done.text.encode())
    for note in done.notes:
        render.say(render.note_line(note))


@app.command("import", cls=Command, epilog="Exit status: 0 written; 2 usage or input error.")
def import_(
    peer_file: Annotated[
        str, typer.Argument(metavar="FILE", help="An imucal JSON or ROS imu_calib YAML file; '-' reads stdin.")
    ],
    fmt: Annotated[
        ImportChoice | None,
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

    from tumblecal_cli.io.outputs import check_not_input, check_writable
    from tumblecal_cli.pipeline import exchange

    check_not_input(output, [peer_file])
    check_writable(output)
    got = exchange.import_peer(
        peer_file,
        fmt=str(fmt) if fmt is not None else None,
        sensor=sensor.value if sensor else None,
        reference=reference,
        columns=columns,
        serial=serial,
    )
    got.calibration.save(output)
    if not quiet:
        console = render.make_console()
        for note in got.notes:
            render.tell(console, f"note: {note}")
        console.print(
            f"imported {got.format} {got.calibration.sensor} calibration, reference {got.calibration.reference:g}"
            + (f": wrote {output}" if output != "-" else ""),
            soft_wrap=True,
        )
