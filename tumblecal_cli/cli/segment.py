"""tumblecal segment: find the still poses of one continuous log, and cut it into a CSV per pose."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import typer

from tumblecal_cli.cli import render
from tumblecal_cli.cli.app import Command, app
from tumblecal_cli.cli.flags import (
    LOG_PANEL,
    AllowCorrected,
    AxesOption,
    Columns,
    Decimal,
    DropIncomplete,
    End,
    MaxSpool,
    MinDuration,
    NoHeader,
    PoseColumn,
    PoseMap,
    Quiet,
    Rate,
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
    Window,
    check_plot_target,
    file_shape,
    log_option,
    source,
)

if TYPE_CHECKING:
    from collections.abc import Callable

    from tumblecal_cli.pipeline.segment import Blocks, Segmented

SEGMENT_EXIT = """\
Exit status: 0 blocks found and written (whatever faces they show: solve judges whether they are
enough); 2 usage or input error (bad file or option, a time column that goes backwards); 3 no
still block kept. Nothing is written on 2 or 3."""


class SegmentCommand(Command):
    """segment's help describes how blocks are found: its job."""

    first_panels = (*Command.first_panels, LOG_PANEL)


@app.command(cls=SegmentCommand, epilog=SEGMENT_EXIT)
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
    stream: StreamOption = None,
    allow_corrected: AllowCorrected = False,
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
    window: Window = None,
    threshold: Threshold = None,
    min_duration: MinDuration = None,
    trim: Trim = None,
    pose_column: PoseColumn = None,
    pose_map: PoseMap = None,
    max_spool: MaxSpool = None,
    max_noise: Annotated[
        float,
        log_option(
            "--max-noise",
            "FRACTION",
            "Drop a block whose standard deviation, or drift between its first and last third, is above "
            "FRACTION x its magnitude (as solve's moved check).",
        ),
    ] = 0.02,
    max_tilt: Annotated[
        float,
        log_option("--max-tilt", "DEGREES", "Label a block with its nearest face only when within this angle."),
    ] = 25.0,
    nominal_offset: Annotated[
        str | None,
        log_option(
            "--nominal-offset",
            "V|X,Y,Z",
            "The raw value at zero stimulus, removed before judging a block's direction. "
            "[default: the per-axis midpoint of the block means]",
        ),
    ] = None,
    plot: Annotated[
        str | None,
        typer.Option(
            "--plot",
            metavar="PNG",
            help="Draw the log with its still blocks shaded and labelled by face, and the rolling standard "
            "deviation with the threshold (reads the whole log into memory); needs tumblecal[plot].",
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
      tumblecal solve --poses poses/[xyz][pn].csv -o cal.json
      tumblecal segment session.csv --rate 102.4 > segments.csv   # the index only
      tumblecal segment session.csv --plot blocks.png -d poses/    # and a picture
    """

    from tumblecal_cli.pipeline import segment as segmenting

    if plot is not None:
        check_plot_target(plot, out_dir or "-", False, [log])
    done = segmenting.segment(
        log,
        out_dir=out_dir,
        on_blocks=None if quiet else _shower(out_dir is not None, verbose),
        plot=plot,
        sensor=sensor.value,
        columns=columns,
        axes=axes,
        no_header=no_header,
        time_column=time_column,
        time_unit=time_unit.value,
        rate=rate,
        **file_shape(skip_rows, decimal, drop_incomplete),
        **source(stream, allow_corrected),
        start=start,
        end=end,
        window=window,
        threshold=threshold,
        min_duration=min_duration,
        trim=trim,
        pose_column=pose_column,
        pose_map=pose_map,
        max_noise=max_noise,
        max_tilt=max_tilt,
        nominal_offset=nominal_offset,
        max_spool=max_spool,
    )
    if out_dir is None:
        render.print_text(done.index)
    elif not quiet:
        _written(done, out_dir)


def _shower(writes: bool, verbose: bool) -> Callable[[Blocks, dict[int, str]], None]:
    """The blocks as they are found: "-> xp.csv" only where it is written; the index alone
    names the file each would go to."""

    def show(found: Blocks, files: dict[int, str]) -> None:
        shown = {n: f"-> {f}" if writes else f"kept ({f})" for n, f in files.items()}
        render.print_blocks(found.log, found.seg, render.make_console(), used=shown, everything=verbose, notes=True)

    return show


def _written(done: Segmented, out_dir: str) -> None:
    """What segment --out-dir wrote, and removed."""
    console = render.make_console()
    if done.stale:
        render.tell(
            console,
            f"note: removed {done.stale} staging folder(s) an earlier, interrupted segment run left in {out_dir}",
        )
    gone = f"; removed {done.removed} block files of the earlier segmentation" if done.removed else ""
    kept = len(done.blocks.seg.kept)
    console.print(f"wrote {render.count(kept, 'block file')} and segments.csv to {out_dir}{gone}", soft_wrap=True)
