"""tumblecal records: the records database (import, history, trend, migrate), and ``--record``'s
saving of a command's calibration with its record."""

from __future__ import annotations

import json
import sys
from typing import TYPE_CHECKING, Annotated

import typer

from tumblecal_cli.cli.app import Command, app
from tumblecal_cli.cli.flags import LotName, Quiet
from tumblecal_cli.errors import InputError, one_line

if TYPE_CHECKING:
    from tumblecal_cli.io.calfiles.calfile import Calibration
    from tumblecal_cli.pipeline.records.history import UnitRecord
    from tumblecal_cli.pipeline.records.trend import Trended


class Saver:
    """How a command writes its calibration: as it is, or with its record (``--record DB``). The
    database is checked when this is made, before any work: a usage error comes first."""

    def __init__(self, record: str | None, lot: str | None, command: str) -> None:
        self.record = record or None  # (TUMBLECAL_RECORD= set empty: no record)
        self.lot, self.command = lot, command
        if self.record is not None:
            from tumblecal_cli.pipeline.records import recording

            recording.check(self.record)

    def __call__(self, cal: Calibration, output: str, status: int) -> None:
        if self.record is None:
            cal.save(output)
            return
        from tumblecal_cli.pipeline.records import columns, recording

        origin = columns.Origin(lot=self.lot, command=self.command, status=status)
        with recording.recorded(self.record, cal, output, origin):
            cal.save(output)

    def retest(self, cal: Calibration, status: int, figures: dict[str, object]) -> None:
        """A re-test (verify) recorded: the calibration judged, its ``figures`` and outcome."""
        if self.record is None:
            return
        from tumblecal_cli.io.calfiles.calfile import created
        from tumblecal_cli.pipeline.records import columns, recording

        when = created()  # (as a calibration's created is written: records sort by it)
        origin = columns.Origin(
            kind="verification", lot=self.lot, command=self.command, status=status, created=when, verification=figures
        )
        recording.record(self.record, cal, origin)


RECORDS_EXIT = "Exit status: 0 done; 2 usage or input error (the database missing, not ours, newer, read-only)."
TREND_EXIT = (
    "Exit status: 0 no alarm; 1 an alarm (a station needs attention); 2 usage or input error "
    "(the database missing, not ours or newer)."
)

records_app = typer.Typer(
    name="records",
    help="The records database: calibrations kept for as long as the units live, stations watched over time.",
    no_args_is_help=True,
    rich_markup_mode=None,
    context_settings={"help_option_names": ["-h", "--help"]},
)
app.add_typer(records_app, name="records")

Db = Annotated[
    str,
    typer.Option(
        "--db",
        metavar="DB",
        envvar="TUMBLECAL_RECORD",
        show_envvar=False,
        help="The records database: a SQLite file, or a postgresql:// URL. [env: TUMBLECAL_RECORD]",
    ),
]
JsonOut = Annotated[bool, typer.Option("--json", help="Print JSON on stdout instead of text.")]


@records_app.command("import", cls=Command, epilog=RECORDS_EXIT)
def import_(
    paths: Annotated[
        list[str], typer.Argument(metavar="DIR|FILE...", help="Calibration files, or folders searched for them.")
    ],
    db: Db,
    lot: LotName = None,
    quiet: Quiet = False,
) -> None:
    """Take existing calibration files and batch folders into the database (twice adds nothing).

    \b
      tumblecal records import lots/ --db records.db
      tumblecal records import lots/L7 --db records.db --lot L7

    A batch folder (one holding summary.csv) gives its files its name as their lot.
    """
    from tumblecal_cli.pipeline.records.importing import import_files
    from tumblecal_cli.pipeline.records.store import shown

    done = import_files(db, paths, lot)
    for path, why in done.unreadable:
        print(f"warning: {one_line(path)}: skipped: {one_line(why)}", file=sys.stderr)
    if not quiet:
        print(f"{done.added} records added, {done.known} there already ({one_line(shown(db))})", file=sys.stderr)
    if done.unreadable:
        raise typer.Exit(2)


@records_app.command("history", cls=Command, epilog=RECORDS_EXIT)
def history(
    serial: Annotated[str, typer.Argument(metavar="SERIAL", help="The unit's serial number.")],
    db: Db,
    json_out: JsonOut = False,
) -> None:
    """Every calibration and re-test of one unit, newest first, with what changed between them.

    \b
      tumblecal records history SN0042 --db records.db
      tumblecal records history SN0042 --db records.db --json | jq '.[0].changes'

    Each change is the new value less the one before, in the parameter's units and in the stated σ
    of the two (√(σ_new² + σ_old²)).
    """
    from tumblecal_cli.pipeline.records.history import history as unit_history

    found = unit_history(db, serial)
    if json_out:
        print(json.dumps([r.as_dict() for r in found], indent=2))
    elif not found:
        raise InputError(f"no records of serial {serial!r}", file=db)
    else:
        print_history(serial, found)


def print_history(serial: str, found: list[UnitRecord]) -> None:
    print(f"{one_line(serial)}: {len(found)} records, newest first")
    for r in found:
        f = r.facts
        who = ", ".join(f"{k} {one_line(str(f[k]))}" for k in ("station", "operator", "lot") if f[k] is not None)
        verdict = f["verdict"] or "no verdict"
        print(f"{f['created']}  {f['kind']} ({f['sensor']}, {f['method']}), {verdict}; {who or 'no station'}")
        for c in r.changes:
            sigmas = f" ({c.sigmas:+.1f}σ)" if c.sigmas is not None else ""
            print(f"    {c.parameter:<10} {r.numbers[c.parameter]:>+12.6g}  changed {c.delta:+.4g}{sigmas}")


@records_app.command("trend", cls=Command, epilog=TREND_EXIT)
def trend(
    db: Db,
    station: Annotated[str | None, typer.Option("--station", metavar="S", help="One station only.")] = None,
    since: Annotated[
        str | None, typer.Option("--since", metavar="DATE", help="Only records created on or after DATE.")
    ] = None,
    baseline: Annotated[
        str | None,
        typer.Option(
            "--baseline",
            metavar="N|FIRST..LAST",
            help="The units the control limits come from: each station's first N, or those created "
            "FIRST..LAST (dates). [default: 100]",
        ),
    ] = None,
    json_out: JsonOut = False,
    html: Annotated[
        str | None,
        typer.Option(
            "--html",
            metavar="FILE.html",
            help="Also write one self-contained page: the alarms and a control chart (SVG) of each series with one.",
        ),
    ] = None,
    plot: Annotated[
        str | None,
        typer.Option(
            "--plot", metavar="PNG", help="Also draw the control chart of each series with an alarm (needs [plot])."
        ),
    ] = None,
) -> None:
    """Watch each station over time: control charts of every offset, gain, cross-axis term and the
    residual, the Western Electric rules and an EWMA, and the stations compared.

    \b
      tumblecal records trend --db records.db
      tumblecal records trend --db records.db --station S3 --since 2026-11-01 --json

    The rules' limits widen with the units judged, so that stable stations raise an alarm in at
    most 5 % of runs; the limits used are printed.
    """
    from tumblecal_cli.pipeline.records import trend as watching

    _outputs_checked(html, plot)
    trended = watching.trend(db, station, since, watching.parse_baseline(baseline))
    if html is not None:
        watching.write_html(trended, html, trend_lines(trended, alarms=False))
    if plot is not None:
        from tumblecal_cli.io.figures import plots

        count = len(trended.alarms)
        plots.trend_figure(plot, trended.charts, title=f"{count} alarm{'s' if count != 1 else ''}: {trended.baseline}")
    if json_out:
        print(json.dumps(trended.as_dict(), indent=2))
    else:
        print("\n".join(trend_lines(trended)))
    if trended.alarms:
        raise typer.Exit(1)


def _outputs_checked(html: str | None, plot: str | None) -> None:
    """--html and --plot: each a file that can be written, matplotlib there for --plot, before any work."""
    from tumblecal_cli.io.outputs import check_writable

    if html is not None:
        check_writable(html, "--html")
    if plot is not None:
        from tumblecal_cli.io.figures import plots

        plots.require()
        check_writable(plot, "--plot")
        if plot == html:
            raise InputError("--plot and --html name the same file", file=plot)


def trend_lines(t: Trended, alarms: bool = True) -> list[str]:
    """What trend prints: the baseline, the limits, the counts, each alarm (``alarms``)."""
    lim = t.limits
    lines = [f"baseline: {t.baseline}"]
    if lim is not None:
        lines.append(
            f"limits: one beyond {lim.l1:.2f}σ, 2 of 3 beyond {lim.l2:.2f}σ, 4 of 5 beyond {lim.l3:.2f}σ, "
            f"{lim.run} in a row, EWMA (λ {lim.lam:g}) beyond {lim.le:.2f}σ of its own: {lim.points} units "
            f"judged, each rule at {lim.p:.2g} (a run of stable stations alarms at most 5 % of the time)"
        )
    count = f"{len(t.alarms)} alarm{'s' if len(t.alarms) != 1 else ''}"
    stations = f"{len(t.stations)} station{'s' if len(t.stations) != 1 else ''}"
    lines.append(f"{stations}, {t.series} series, {t.units} units: {count}")
    for a in t.alarms if alarms else []:
        lines.append(
            f"alarm: station {one_line(a.station)}, {a.sensor} {a.parameter}, rule {a.rule} ({a.words}): "
            f"first at serial {one_line(str(a.serial))} ({a.created}): {a.meaning}"
        )
    return lines


@records_app.command("migrate", cls=Command, epilog=RECORDS_EXIT)
def migrate(db: Db) -> None:
    """Bring a records database to this tool's schema (a new file is made with it).

    \b
      tumblecal records migrate --db records.db
    """
    from tumblecal_cli.pipeline.records import store

    before, after = store.migrate(db)
    words = f"schema {after}, up to date" if before == after else f"schema {before} -> {after}"
    print(f"{one_line(store.shown(db))}: {words}", file=sys.stderr)
