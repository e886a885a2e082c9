"""tumblecal batch: calibrate many units in one run, one calibration file each and a summary."""

from __future__ import annotations

import contextlib
import inspect
from typing import TYPE_CHECKING, Annotated, Any

import typer

from tumblecal_cli.cli import render
from tumblecal_cli.cli.app import Command, app
from tumblecal_cli.cli.flags import STATUS_WORDS, LotName, RecordDb
from tumblecal_cli.cli.solve import CLI_ONLY, solve

if TYPE_CHECKING:
    from collections.abc import Callable

    from rich.console import Console

    from tumblecal_cli.pipeline.batch import summary as summaries
    from tumblecal_cli.pipeline.batch import units as batches

BATCH_PANEL = "Batch"
BATCH_EXIT = """\
Exit status, the first that any unit has: 2 an input or usage error; 3 a capture rejected;
1 a unit outside its limits; 0 every unit passed. A unit that fails never stops the batch:
its row in summary.csv says why. Nothing but the calibrations and summary.csv is written."""


def _batch_options(
    source: Annotated[
        str,
        typer.Argument(
            metavar="UNITS",
            help="A folder with one folder of pose files per unit, UNITS/<serial>/x.csv y.csv z.csv (files named "
            "x y z, xp xn yp yn zp zn or +x ... are labelled so; others are unlabelled, in name order); with --log, "
            "one log per unit, UNITS/<serial>.csv or UNITS/<serial>/<log>.csv. Or a manifest CSV: the header "
            "'serial,...', then a serial and its files per row (relative to the manifest; a column headed x, "
            "+x, xp ... labels its files; a cell may be LABEL=FILE).",
        ),
    ],
    out_dir: Annotated[
        str,
        typer.Option(
            "--out-dir",
            "-d",
            metavar="DIR",
            help="Where each unit's calibration goes, as <serial>_<UTC time>.json (never replacing a file: "
            "a unit's history stays), with summary.csv, one row per unit. Created if needed.",
            rich_help_panel=BATCH_PANEL,
        ),
    ],
    log: Annotated[
        bool,
        typer.Option(
            "--log",
            help="Each unit is one continuous log, cut into still blocks as 'solve --log' does.",
            rich_help_panel=BATCH_PANEL,
        ),
    ] = False,
    jobs: Annotated[
        int,
        typer.Option(
            "--jobs",
            "-j",
            metavar="N",
            min=1,
            max=1024,
            help="Solve N units at a time, in N processes.",
            rich_help_panel=BATCH_PANEL,
        ),
    ] = 1,
    resume: Annotated[
        bool,
        typer.Option(
            "--resume",
            help="Continue a batch: skip the units already in DIR/summary.csv (whatever their status; delete a "
            "row to redo that unit). Without it an existing summary.csv is an error.",
            rich_help_panel=BATCH_PANEL,
        ),
    ] = False,
    dask_scheduler: Annotated[
        str | None,
        typer.Option(
            "--dask-scheduler",
            metavar="ADDRESS",
            help="Run the units on a Dask distributed cluster, tcp://host:8786 (docs/commands/batch.md). Needs "
            "'tumblecal[dask]' here and on the workers, and UNITS and DIR at the same paths on every worker.",
            rich_help_panel=BATCH_PANEL,
        ),
    ] = None,
    json_summary: Annotated[
        bool,
        typer.Option(
            "--json",
            help="Print the summary on stdout as JSON: the batch's status, counts, and each unit's row.",
            rich_help_panel=BATCH_PANEL,
        ),
    ] = False,
    record: RecordDb = None,
    lot: LotName = None,
    quiet: Annotated[
        bool,
        typer.Option(
            "--quiet", "-q", help="Print nothing on stderr unless there is an error.", rich_help_panel=BATCH_PANEL
        ),
    ] = False,
) -> None:
    """batch's own options; the rest are solve's (see _batch_signature)."""


def _batch_signature() -> inspect.Signature:
    """batch takes its own options and every one of solve's flat options (all but its CLI_ONLY),
    but a unit's serial."""
    own = list(inspect.signature(_batch_options, eval_str=True).parameters.values())
    solves = inspect.signature(solve, eval_str=True).parameters.items()
    return inspect.Signature(own + [p for n, p in solves if n not in CLI_ONLY and n != "serial"])


def batch(**given: Any) -> None:  # Typer passes each option by name, each of its own type
    """Calibrate many units in one run: one calibration file per unit, and a summary.

    \b
      tumblecal batch units/ --out-dir cals/ --limits limits.yaml --jobs 2
      tumblecal batch manifest.csv --out-dir cals/ --reference 9.81
      tumblecal batch logs/ --log --rate 100 --out-dir cals/ --resume
      tumblecal batch units/ -d /shared/cals --dask-scheduler tcp://sched:8786

    Each unit is solved as 'tumblecal solve' would (every solve option applies to all of them),
    its calibration written to DIR/<serial>_<UTC time>.json and its outcome added to
    DIR/summary.csv (README: batch), with a warning for serials that share a pose file.
    """

    from tumblecal_cli.pipeline.batch import units as batches

    own = {name: given.pop(name) for name in list(given) if name in _BATCH_OWN}
    quiet, console = own["quiet"], render.make_console()
    with contextlib.ExitStack() as stack:
        shown: list[tuple[bool, Callable[[], None]]] = [(False, lambda: None)]  # a bar, once the units are known

        def start(plan: batches.Plan) -> None:
            if not quiet:
                for note in plan.notes:
                    render.tell(console, f"note: {note}")
                if len(plan.todo) < len(plan.units):
                    done = len(plan.units) - len(plan.todo)
                    console.print(f"resuming: {done} of {len(plan.units)} units already done", soft_wrap=True)
            shown[0] = stack.enter_context(render.batch_progress(console, len(plan.todo), enabled=not quiet))

        def unit(row: summaries.Row) -> None:
            if row.status or not shown[0][0]:
                render.print_unit(row, out_dir, console, quiet=quiet)
            shown[0][1]()

        out_dir = own["out_dir"]
        result = batches.run_batch(
            own["source"],
            out_dir,
            given,  # solve's flat options: run_batch maps them (SolveOptions.of)
            log=own["log"],
            jobs=own["jobs"],
            resume=own["resume"],
            scheduler=own["dask_scheduler"],
            on_start=start,
            on_unit=unit,
            keep=keeper(own["record"], own["lot"], out_dir),
        )
    _show(result, console, quiet=quiet, json_summary=own["json_summary"])


def keeper(record: str | None, lot: str | None, out_dir: str) -> batches.Keeper | None:
    """--record: each unit's calibration recorded as it is published, its lot --lot or the
    output folder's name; the database checked first, before any unit runs."""
    if not record:
        return None
    import os

    from tumblecal_cli.pipeline.records import recording

    recording.check(record)
    return recording.keeper(record, lot or os.path.basename(os.path.abspath(out_dir)))


def _show(result: batches.Batched, console: Console, *, quiet: bool, json_summary: bool) -> None:
    """The batch's counts on stderr, the --json summary on stdout; its status."""
    from tumblecal_cli.pipeline.batch import summary as summaries

    if not quiet:
        for warning in result.warnings:
            render.tell(console, f"warning: {warning}", style="red")
        said = ", ".join(f"{n} {v}" for v, n in result.counts.items() if n)
        console.print(
            f"{len(result.rows)} unit{'s' if len(result.rows) != 1 else ''}: {said} -> {result.summary}",
            soft_wrap=True,
            markup=False,
            highlight=False,
        )
    if json_summary:  # each status a word, as every --json says it, its number beside it
        table = [_unit_json(r, summaries.SUMMARY_COLUMNS) for r in result.rows]
        head = {"status": STATUS_WORDS[result.status], "exit_status": result.status}
        render.print_json(
            head | {"counts": result.counts, "summary": result.summary, "warnings": result.warnings, "units": table}
        )
    if result.status:
        raise typer.Exit(result.status)


def _unit_json(row: summaries.Row, columns: list[str]) -> dict[str, object]:
    """A unit's row of summary.csv for --json: its status a word, the number as exit_status."""
    out: dict[str, object] = {}
    for c in columns:
        if c == "status":
            out |= {"status": STATUS_WORDS[row.status], "exit_status": row.status}
        else:
            out[c] = row.value(c)
    return out


_BATCH_OWN = tuple(inspect.signature(_batch_options).parameters)  # the rest of batch's options are solve's
batch.__signature__ = _batch_signature()  # type: ignore[attr-defined]
app.command(cls=Command, epilog=BATCH_EXIT)(batch)
