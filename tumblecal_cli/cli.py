"""The command line: parse, call io and core, tell people on stderr, map errors to exit codes.

numpy, pyarrow and the io modules are imported inside the commands, so ``tumblecal --help``
and ``--version`` pay only for Typer. Errors become exit codes in exactly one place, ``main``.
"""

from __future__ import annotations

import os
import sys
from enum import StrEnum
from typing import TYPE_CHECKING, Annotated, Any

import typer
from typer.core import TyperCommand

from tumblecal_cli import __version__
from tumblecal_cli.errors import InputError, PipeClosed, TumblecalError

if TYPE_CHECKING:
    from rich.console import Console

    from tumblecal_cli.captures import Samples
    from tumblecal_cli.core import PoseStats, Solution

EXIT_CODES = """\
Exit status: 0 ok; 2 usage or input error (bad file, bad option, wrong number of files,
a units mistake); 3 capture rejected (a pose that cannot be right, e.g. upside down).
Nothing is written on 2 or 3."""

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


class ManyValuesCommand(TyperCommand):
    """Lets ``--poses a.csv b.csv c.csv`` take every file after one flag.

    Click options have a fixed arity, so before parsing, each value that follows ``--poses``
    (up to the next option) is given its own ``--poses``. ``-`` (stdin) is a value.
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
            elif flag and (arg == "-" or not arg.startswith("-")):
                if out[-1] != flag:
                    out.append(flag)
                out.append(arg)
                continue
            else:
                flag = None
            out.append(arg)
        return super().parse_args(ctx, out)


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
Quiet = Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing on stderr unless there is an error.")]


@app.command(cls=ManyValuesCommand, epilog=EXIT_CODES)
def solve(
    poses: Annotated[
        list[str],
        typer.Option(
            "--poses",
            "-p",
            metavar="FILE...",
            help="1 file: the 1-pose solver (offsets; the face up is --up). "
            "3 files: the 3-pose solver (offsets and gains), the +x, +y, +z poses in that order. "
            "All files follow one --poses; '-' reads stdin.",
        ),
    ],
    output: Annotated[
        str,
        typer.Option(
            "--output", "-o", metavar="FILE", help="Calibration file: .json, or .yaml/.yml for YAML; '-' is stdout."
        ),
    ] = "-",
    up: Annotated[
        str,
        typer.Option(
            "--up",
            metavar="FACE",
            help="1-pose: the sensor axis pointing up, which reads +reference: +x -x +y -y +z -z "
            "(or xp xn yp yn zp zn). A sensor that reads -1 g on the axis pointing up is the opposite face.",
        ),
    ] = "+z",
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
    sensor: Sensor = SensorKind.accelerometer,
    units: Annotated[
        str | None,
        typer.Option("--units", metavar="TEXT", help="Label of the corrected units (default 'g' for reference 1)."),
    ] = None,
    input_units: Annotated[
        str | None, typer.Option("--input-units", metavar="TEXT", help="Label of the raw units, e.g. counts.")
    ] = None,
    columns: Columns = None,
    no_header: NoHeader = False,
    time_column: Annotated[
        str | None,
        typer.Option(
            "--time-column", metavar="NAME", help="The time column (default: t, time, timestamp, time_s or ts)."
        ),
    ] = None,
    time_unit: Annotated[TimeUnit, typer.Option("--time-unit", help="Unit of the time column.")] = TimeUnit.s,
    rate: Annotated[
        float | None,
        typer.Option("--rate", metavar="HZ", help="Sample rate in Hz, for durations when there is no time column."),
    ] = None,
    quiet: Quiet = False,
) -> None:
    """Average each pose file and solve for the offsets (and gains); write a calibration file.

    \b
      tumblecal solve --poses x.csv y.csv z.csv -o cal.json     # 3-pose
      tumblecal solve --poses z.csv -o cal.yaml                 # 1-pose, +z up
      tumblecal solve --poses z.csv --up=-x --reference 16384   # counts, -x up
    """
    from tumblecal_cli import calfile, captures, core
    from tumblecal_cli.files import check_not_input

    if len(poses) not in (1, 3):
        raise InputError(f"--poses takes 1 file (1-pose) or 3 files (+x +y +z), got {len(poses)}")
    if sum(p == "-" for p in poses) > 1:
        raise InputError("only one pose can be read from stdin ('-')")
    try:
        face = core.parse_face(up)
    except ValueError as err:
        raise InputError(f"--up: {err}") from None
    check_not_input(output, poses)
    ref = reference if reference is not None else (0.0 if sensor is SensorKind.gyroscope else 1.0)
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
        for f in poses
    ]
    stats = [core.pose_stats(s.values) for s in samples]
    if len(poses) == 1:
        _check_units(samples[0].layout.name, stats[0], ref)
        solution, faces = core.solve_one_pose(stats[0], face, ref), [face]
    else:
        solution = core.solve_three_pose(stats, ref, names=[s.layout.name for s in samples])
        faces = ["+x", "+y", "+z"]
    doc = calfile.build(
        solution,
        sensor=sensor.value,
        reference=ref,
        units=units,
        input_units=input_units,
        columns=samples[0].layout.sensor_names,
        poses=[_pose_record(f, s, st) for f, s, st in zip(faces, samples, stats, strict=True)],
    )
    calfile.write(doc, output)
    if not quiet:
        _print_solution(solution, faces, samples, stats, output)


def _check_units(name: str, pose: PoseStats, reference: float) -> None:
    from tumblecal_cli import core

    suggested = core.units_mistake(pose.mean, reference)
    if suggested is None:
        return
    magnitude = float((pose.mean**2).sum() ** 0.5)
    units = {1.0: "g", 9.80665: "m/s^2", 1000.0: "mg"}.get(suggested, "raw counts")
    raise InputError(
        f"the pose reads {magnitude:.4g} in magnitude but --reference is {reference:g}: a units mistake?",
        file=name,
        hint=f"the data looks like {units}: run with --reference {suggested:g} "
        "(the 1-pose solver has no gains, so --reference must be in the file's units)",
    )


def _pose_record(face: str, s: Samples, st: PoseStats) -> dict[str, Any]:
    record: dict[str, Any] = {
        "pose": face,
        "file": s.layout.name,
        "sha256": s.sha256,
        "rows": list(s.rows),
        "samples": st.samples,
        "mean": [float(v) for v in st.mean],
        "std": [float(v) for v in st.std],
    }
    if s.duration is not None:
        record["duration_s"] = s.duration
    return record


@app.command(epilog=EXIT_CODES)
def apply(
    capture: Annotated[
        str, typer.Argument(metavar="CAPTURE", help="The capture to correct; '-' (the default) reads stdin.")
    ] = "-",
    cal: Annotated[
        str, typer.Option("--cal", "-c", metavar="FILE", help="Calibration file from 'tumblecal solve'.")
    ] = ...,  # type: ignore[assignment]
    output: Annotated[
        str, typer.Option("--output", "-o", metavar="FILE", help="Corrected capture; '-' (the default) is stdout.")
    ] = "-",
    columns: Columns = None,
    no_header: NoHeader = False,
    quiet: Quiet = False,
) -> None:
    """Correct a capture: each sensor reading becomes M (raw - offset).

    Everything else is copied as it was: the header, the rows and their order, the text of
    every other column and the line endings. The sensor columns are the calibration's own
    (else found by the same rules as solve), written with every digit needed to round-trip.

    \b
      tumblecal apply --cal cal.json capture.csv -o corrected.csv
      cat capture.csv | tumblecal apply --cal cal.json > corrected.csv
    """
    from tumblecal_cli import calfile, captures, core
    from tumblecal_cli.files import atomic_output, check_not_input

    if cal == "-" and capture == "-":
        raise InputError("--cal - and the capture cannot both be read from stdin", hint="give the capture as a file")
    check_not_input(output, [capture, cal])
    c = calfile.load(cal)
    picked = columns.split(",") if columns else None
    with captures.open_capture(capture, sensor=c.sensor, columns=picked, prefer=c.columns, no_header=no_header) as cap:
        used = cap.layout.sensor_names
        if not quiet and [u.lower() for u in used] != [x.lower() for x in c.columns]:
            _console().print(
                f"note: {cap.layout.name}: correcting columns {', '.join(used)} "
                f"(the calibration was made from {', '.join(c.columns)})",
                soft_wrap=True,
            )
        with atomic_output(output) as out:
            rows = captures.correct_stream(cap, out, lambda raw: core.apply(raw, c.offset, c.matrix))
    if not quiet:
        target = "stdout" if output == "-" else output
        _console().print(f"corrected {rows} rows of {cap.layout.name} ({', '.join(used)}) -> {target}", soft_wrap=True)


# -- people's output, on stderr ----------------------------------------------------------


def _console() -> Console:
    from rich.console import Console

    return Console(stderr=True, highlight=False, markup=False)  # paths and column names are not markup


def _print_solution(
    solution: Solution, faces: list[str], samples: list[Samples], stats: list[PoseStats], output: str
) -> None:
    from rich import box
    from rich.table import Table

    def g(v: float) -> str:
        return f"{v:.6g}"

    axes = Table(title=f"{solution.method} calibration", title_justify="left", box=box.SIMPLE_HEAD)
    for name in ("axis", "column", "offset", "± 1σ", "gain", "± 1σ"):
        axes.add_column(name, justify="left" if name in ("axis", "column") else "right")
    columns = samples[0].layout.sensor_names
    for i, axis in enumerate("xyz"):
        gain_se = solution.gain_se[i]
        fixed = "fixed" if not gain_se else g(gain_se)
        axes.add_row(axis, columns[i], g(solution.offset[i]), g(solution.offset_se[i]), g(solution.gain[i]), fixed)
    poses = Table(title="poses", title_justify="left", box=box.SIMPLE_HEAD)
    for name in ("pose", "file", "n", "", "x", "y", "z"):
        poses.add_column(name, justify="right" if name in ("n", "x", "y", "z") else "left", overflow="fold")
    for face, s, st in zip(faces, samples, stats, strict=True):
        poses.add_row(face, os.path.basename(s.layout.name), str(st.samples), "mean", *map(g, st.mean))
        poses.add_row("", "", "", "std", *(f"{v:.3g}" for v in st.std), end_section=True)
    console = _console()
    console.print(axes)
    console.print(poses)
    if output != "-":
        console.print(f"wrote {output}", soft_wrap=True)


# -- the one error boundary --------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; return the exit status. Every error is reported here and only here."""
    try:
        result = app(args=argv, prog_name="tumblecal", standalone_mode=False)
    except PipeClosed:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no flush error at exit
        return PipeClosed.exit_code
    except TumblecalError as err:
        if _state["debug"]:
            raise
        _report(str(err), err.hint)
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
    except Exception as err:  # a bug: one line unless --debug
        if _state["debug"]:
            raise
        _report(f"internal error: {type(err).__name__}: {err}", "run with --debug for the traceback")
        return 2
    finally:
        _state["debug"] = False
    return result if isinstance(result, int) else 0


def _report(message: str, hint: str | None) -> None:
    print(f"error: {message}", file=sys.stderr)
    if hint:
        print(f"hint: {hint}", file=sys.stderr)


def main_exit() -> None:
    """Console-script entry point."""
    sys.exit(main())
