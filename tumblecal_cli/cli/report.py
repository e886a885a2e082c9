"""tumblecal report: statistics of a production lot of calibration files."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import typer

from tumblecal_cli.cli import render
from tumblecal_cli.cli.app import Command, app
from tumblecal_cli.cli.flags import STATUS_WORDS, Quiet, check_plot_target
from tumblecal_cli.errors import InputError

if TYPE_CHECKING:
    from tumblecal_cli.pipeline.report import Judged, Reported

REPORT_EXIT = """\
Exit status: 0 the lot is in order; 1 it needs attention (a unit outside --limits, an
outlier, a drift beyond --max-drift, or a Cpk below --min-cpk); 2 usage or input error (an unreadable file among
the rest: the report is still printed)."""


@app.command(cls=Command, epilog=REPORT_EXIT)
def report(
    paths: Annotated[
        list[str] | None,
        typer.Argument(
            metavar="CALS...",
            help="Calibration files, or folders searched for *.json and *.yaml (hidden ones skipped).",
        ),
    ] = None,
    limits_file: Annotated[
        str | None,
        typer.Option(
            "--limits",
            metavar="FILE",
            help="Limits file (as for solve): offset, gain_error with nominal_gain, and cross_axis give the "
            "specification limits Cpk is computed against.",
        ),
    ] = None,
    max_drift: Annotated[
        str | None,
        typer.Option(
            "--max-drift",
            metavar="KEY=V,...",
            help="Flag a unit whose latest calibration moved further than this from its previous one: "
            "offset=V (raw units), gain=F (fraction of the previous gain), cross=F (e.g. offset=0.01,gain=0.002).",
        ),
    ] = None,
    min_cpk: Annotated[
        float | None,
        typer.Option("--min-cpk", metavar="C", help="Flag a parameter whose Cpk is below C (1.33 is usual)."),
    ] = None,
    outlier_alpha: Annotated[
        float,
        typer.Option(
            "--outlier-alpha",
            metavar="P",
            help="Lot-wide false-alarm rate of the outlier flags: the chance that a lot of good units gets any "
            "flag (between 0 and 1). Smaller lots than the rule can judge get none (docs/lot-report.md).",
        ),
    ] = 0.005,  # core.outliers.OUTLIER_ALPHA (not imported here: --help loads no numpy)
    json_out: Annotated[
        bool, typer.Option("--json", help="Print the whole report as JSON on stdout instead of the CSV table.")
    ] = False,
    plot: Annotated[
        str | None,
        typer.Option(
            "--plot", metavar="PNG", help="Also draw a histogram per parameter, with its limits (needs [plot])."
        ),
    ] = None,
    html: Annotated[
        str | None,
        typer.Option(
            "--html",
            metavar="FILE.html",
            help="Also write the report as one self-contained web page: verdict, yield, Cpk with its interval, "
            "the distributions, the units to look at and why, stations and operators, a link to each "
            "calibration (needs [plot]).",
        ),
    ] = None,
    quiet: Quiet = False,
    db: Annotated[
        str | None,
        typer.Option("--db", metavar="DB", help="Judge a lot from a records database instead (with --lot)."),
    ] = None,
    lot_name: Annotated[str | None, typer.Option("--lot", metavar="L", help="The lot, with --db.")] = None,
) -> None:
    """Statistics of a production lot: per parameter count, mean, std, min/max, Cpk, outliers, drift.

    The lot is the latest calibration of each serial (unit.serial; files without one count
    once each); a serial calibrated more than once also gets the change since its previous
    calibration (by created). Outliers: a unit far from the others for a lot-wide false-alarm
    rate of --outlier-alpha (the report says the rule it used).
    CSV (or --json) on stdout, tables on stderr.

    \b
      tumblecal report cals/ --limits limits.yaml
      tumblecal report lot1/ lot2/ --max-drift offset=0.01,gain=0.002 --json
      tumblecal report cals/ --limits limits.yaml --plot lot.png
      tumblecal report cals/ --limits limits.yaml --html lot.html
      tumblecal report --db records.db --lot L7 --limits limits.yaml
    """

    from tumblecal_cli.pipeline import report as pipeline

    _early_checks(plot, html)
    judged = pipeline.Judged(limits_file, max_drift, min_cpk, outlier_alpha)
    reported = _reported(paths or [], db, lot_name, judged, html)
    result = reported.result
    _late_checks(plot, html, [*reported.files, *([limits_file] if limits_file else [])])
    if json_out:
        render.print_json({"status": STATUS_WORDS[reported.status], "exit_status": reported.status} | result.as_dict())
    else:
        render.print_csv(result.csv_rows())
    if plot is not None and not result.unreadable:  # exit 2 writes no file
        _plot_lot(plot, reported)
    if html is not None and not result.unreadable:
        pipeline.write_html(reported, html, limits=limits_file, drift_given=bool(max_drift))
    if not quiet:
        written = ", ".join(p for p in (plot, html) if p is not None) or None
        render.print_lot(result, render.make_console(), written, drift_given=bool(max_drift))
    if result.unreadable:  # an error line per file, after the report of the rest
        (first, why), rest = result.unreadable[0], result.unreadable[1:]
        raise InputError(
            why,
            file=first,
            more=tuple(f"{path}: {message}" for path, message in rest),
            hint=f"the report leaves out the {len(result.unreadable)} of {result.files} files that could not be read",
        )
    if result.needs_attention:
        raise typer.Exit(1)


def _reported(paths: list[str], db: str | None, lot: str | None, judged: Judged, html: str | None) -> Reported:
    """The files' report, or (--db, --lot) the records'."""
    from tumblecal_cli.pipeline import report as pipeline

    if db is None and lot is None:
        if not paths:
            raise InputError("report takes calibration files or folders (CALS...), or --db DB --lot L")
        j = judged
        return pipeline.report(
            paths, limits=j.limits, max_drift=j.max_drift, min_cpk=j.min_cpk, outlier_alpha=j.outlier_alpha
        )
    if db is None or lot is None or paths:
        raise InputError("--db DB and --lot L go together, in place of CALS...")
    if html is not None:
        raise InputError("--html links each unit's calibration file: give the files, not --db")
    from tumblecal_cli.pipeline.records.importing import report_lot

    return report_lot(db, lot, judged)


def _early_checks(plot: str | None, html: str | None) -> None:
    """Before any work: matplotlib for --plot and --html, and an --html that can be written."""
    if plot is None and html is None:
        return
    from tumblecal_cli.io.figures import plots

    plots.require()
    if html is None:
        return
    import os
    import tempfile

    from tumblecal_cli.io.outputs import check_writable

    check_writable(html, "--html")
    if not html.lower().endswith((".html", ".htm")):
        raise InputError("--html writes a web page: give a file name ending in .html", file=html)
    folder = os.path.dirname(os.path.abspath(html))
    try:  # a folder that cannot be written into (read-only, /proc): found now, not after the report
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as err:
        raise InputError(f"cannot write into {folder}: {err.strerror}", file=html) from None


def _late_checks(plot: str | None, html: str | None, inputs: list[str]) -> None:
    """Once the inputs are known: no output onto an input, and not both onto one file."""
    from tumblecal_cli.io.outputs import check_not_input

    if plot is not None:
        check_plot_target(plot, "-", False, inputs)
    if html is not None:
        check_not_input(html, inputs, "--html")
        if plot is not None and plot == html:
            raise InputError("--plot and --html name the same file", file=html)


def _plot_lot(plot: str, reported: Reported) -> None:
    """report --plot: a histogram per parameter of the lot, with its limits and marked units."""
    from tumblecal_cli.io.figures import plots
    from tumblecal_cli.pipeline import report as pipeline

    plots.lot_figure(
        plot, pipeline.histograms(reported), title=f"{reported.result.units} units, {reported.result.files} files"
    )
