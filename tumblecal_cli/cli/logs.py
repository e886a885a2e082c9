"""tumblecal logs: the streams an autopilot's or robot's log holds, and which --stream picks each."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import typer

from tumblecal_cli.cli import render
from tumblecal_cli.cli.app import Command, app

if TYPE_CHECKING:
    from tumblecal_cli.io.sources import Stream


@app.command(
    "logs",
    cls=Command,
    epilog="Exit status: 0 listed; 2 not a log of a kind tumblecal reads by streams, or one it cannot read.",
)
def logs(
    log: Annotated[
        str,
        typer.Argument(
            metavar="FILE",
            help="A log: a PX4 ULog (.ulg), an ArduPilot DataFlash log (.bin, or its text form .log), a ROS bag (.bag, "
            "a ROS 2 bag's folder) or an MCAP file.",
        ),
    ],
    json_summary: Annotated[bool, typer.Option("--json", help="Print the streams on stdout as JSON.")] = False,
) -> None:
    """List the streams of a log: each one's --stream, sensor, rows, rate, units, and whether the
    autopilot had already corrected it (and how that is told). A corrected stream is refused by
    solve, segment, noise, thermal and verify unless --allow-corrected.

    \b
      tumblecal logs flight.ulg
      tumblecal solve --log flight.ulg --stream sensor_accel:0 -o cal.json
      tumblecal noise 00000042.BIN --stream IMU:1
    """
    from tumblecal_cli.io import sources

    found = sources.streams(log)
    if json_summary:
        render.print_json({"file": log, "streams": [_doc(s) for s in found]})
        return
    render.print_text(table(found))


def _doc(s: Stream) -> dict[str, object]:
    return {
        "stream": s.key,
        "name": s.name,
        "instance": s.instance,
        "sensor": s.sensor,
        "rows": s.rows,
        "rate": None if s.rate is None else round(s.rate, 3),
        "units": s.units,
        "corrected": s.corrected,
        "how": s.how,
    }


def table(found: list[Stream]) -> str:
    """The streams as a plain table, each distinct "how" told once below it."""
    head = ("stream", "sensor", "rows", "rate Hz", "units", "as logged")
    rows = [
        (s.key, s.sensor, str(s.rows), "-" if s.rate is None else f"{s.rate:.4g}", s.units, _word(s)) for s in found
    ]
    widths = [max(len(r[k]) for r in [head, *rows]) for k in range(len(head))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in [head, *rows]]
    hows: dict[str, list[str]] = {}
    for s in found:
        names = hows.setdefault(s.how, [])
        if s.name not in names:
            names.append(s.name)
    lines += [""] + [f"{', '.join(names)}: {how}" for how, names in hows.items() if how]
    if not found:
        lines = ["no sensor streams in this log"]
    return "\n".join(lines) + "\n"


def _word(s: Stream) -> str:
    return "corrected" if s.corrected else "raw"
