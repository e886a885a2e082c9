"""``report --html``: the lot report as one self-contained HTML page for a quality engineer.

One file, nothing fetched: the figures are inline SVG (matplotlib's, text drawn as paths, so no
font is needed), the style is inline, there is no script, and a Content-Security-Policy forbids
the page any network access. Each unit's line links to its calibration file by a path relative
to the page, so the page and the calibrations can be moved together. Written atomically.
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from dataclasses import dataclass

from tumblecal_cli.core import lot
from tumblecal_cli.io.outputs import atomic_output

#: No network, no script: only the inline style and inline images.
POLICY = "default-src 'none'; style-src 'unsafe-inline'; img-src data:"

STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; margin: 2em auto;
  max-width: 80em; padding: 0 1em; color: #222; line-height: 1.4; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; } h2 { font-size: 1.25em; margin-top: 2em;
  border-bottom: 1px solid #ccc; }
.sub { color: #666; margin-top: 0; }
.verdict { padding: 0.8em 1.2em; border-radius: 6px; margin: 1em 0; }
.verdict.bad { background: #fde8e8; border: 1px solid #d33; }
.verdict.good { background: #e6f6e9; border: 1px solid #2a2; }
.verdict strong { font-size: 1.3em; }
table { border-collapse: collapse; margin: 0.5em 0; font-size: 0.92em; }
th, td { padding: 0.25em 0.7em; border-bottom: 1px solid #e4e4e4; text-align: right; vertical-align: top; }
th { background: #f4f4f4; } td.l, th.l { text-align: left; }
tr.fail td { background: #fdf0f0; } tr.flag td { background: #fff6e5; }
.low { color: #c00; font-weight: bold; }
.figures { display: flex; flex-wrap: wrap; gap: 1em; }
figure { margin: 0; } figure svg { width: 22em; height: auto; display: block; }
figcaption { font-size: 0.85em; color: #555; text-align: center; }
.note { color: #555; font-size: 0.9em; }
"""


@dataclass(frozen=True)
class UnitLine:
    """One unit of the lot as the page lists it. ``link``: its calibration file relative to the
    page (None: read from stdin); ``failing``: why it fails; ``flagged``: why it needs a look."""

    name: str
    created: str
    sensor: str
    method: str
    station: str | None
    operator: str | None
    link: str | None
    failing: tuple[str, ...] = ()
    flagged: tuple[str, ...] = ()


@dataclass(frozen=True)
class Page:
    """What the page shows: the report, its units, and one SVG panel per figure (name, svg)."""

    report: lot.Report
    units: list[UnitLine]
    panels: list[tuple[str, str]]
    limits: str | None
    tool: str
    drift_given: bool = False


def write(path: str, page: Page) -> None:
    """Render ``page`` and write it to ``path`` atomically (an error leaves ``path`` as it was)."""
    text = render(page)
    with atomic_output(path) as out:
        out.write(text.encode("utf-8"))


def render(page: Page) -> str:
    """The whole HTML document."""
    r = page.report
    title = f"Lot report: {_count(r.units, 'unit')} ({_count(r.files, 'file')})"
    dates = sorted(u.created for u in page.units if u.created)
    span = f"calibrations from {dates[0]} to {dates[-1]}; " if dates else ""
    limits = f"limits from {page.limits}" if page.limits else "no limits given (--limits)"
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f'<meta http-equiv="Content-Security-Policy" content="{POLICY}">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{_e(title)}</title><style>{STYLE}</style></head><body>",
        f"<h1>{_e(title)}</h1>",
        f'<p class="sub">{_e(span + limits)}; written by {_e(page.tool)}</p>',
        _verdict(page),
        _figures_table(r),
        _distributions(page.panels),
        _attention(page.units),
        _people(page.units),
        _extras(r, page.drift_given),
        _units(page.units),
        f'<p class="note">{_e(r.outlier_text)}. Cpk uses the lot\'s overall standard deviation '
        "(Ppk in AIAG's terms); its 95 % interval is Bissell's approximation (Bissell 1990).</p>",
        "</body></html>",
    ]
    return "\n".join(p for p in parts if p) + "\n"


def _verdict(page: Page) -> str:
    r = page.report
    failing = [u for u in page.units if u.failing]
    good = len(page.units) - len(failing)
    share = f" ({good / len(page.units):.1%})" if page.units else ""
    reasons = []
    if failing:
        reasons.append(f"{_count(len(failing), 'unit')} failing (outside a limit, or failed at calibration)")
    outliers = sum(len(row.outliers) for row in r.rows)
    if outliers:
        reasons.append(f"{_count(outliers, 'outlier')} (far from the rest of the lot)")
    drifted = sum(1 for d in r.drift if d.flagged)
    if drifted:
        reasons.append(f"{_count(drifted, 'change')} beyond --max-drift since a previous calibration")
    if r.duplicates:
        reasons.append(f"{_count(len(r.duplicates), 'pose file')} recorded under two serials")
    low = [row.parameter for row in r.rows if r.min_cpk is not None and row.cpk is not None and row.cpk < r.min_cpk]
    if low:
        reasons.append(f"Cpk below {r.min_cpk:g}: {', '.join(low)}")
    if r.unreadable:
        reasons.append(f"{_count(len(r.unreadable), 'file')} could not be read")
    words = "Needs attention" if r.needs_attention or r.unreadable else "In order"
    kind = "bad" if r.needs_attention or r.unreadable else "good"
    items = "".join(f"<li>{_e(reason)}</li>" for reason in reasons)
    return (
        f'<div class="verdict {kind}" id="verdict"><strong>Lot: {words}</strong>'
        f"<p>Yield: {good} of {_count(len(page.units), 'unit')}{share} pass.</p>"
        + (f"<ul>{items}</ul>" if items else "")
        + "</div>"
    )


def _figures_table(r: lot.Report) -> str:
    several = len({row.sensor for row in r.rows}) > 1
    head = ["figure", "n", "mean", "std", "min", "max", "limits", "Cpk", "Cpk 95 % interval", "outside", "outliers"]
    lines = []
    for row in r.rows:
        low = r.min_cpk is not None and row.cpk is not None and row.cpk < r.min_cpk
        interval = "" if row.cpk_low is None else f"{_g(row.cpk_low, 3)} … {_g(row.cpk_high, 3)}"
        cells = [
            _e(f"{row.sensor} {row.parameter}" if several else row.parameter),
            str(row.count),
            _g(row.mean),
            _g(row.std, 2),
            _g(row.min),
            _g(row.max),
            _e(_span(row)),
            f'<span class="low">{_g(row.cpk, 3)}</span>' if low else _g(row.cpk, 3),
            interval,
            _e(", ".join(row.outside)),
            _e(", ".join(f"{u} (t {t:+.1f})" for u, _, t in row.outliers)),
        ]
        kind = ' class="fail"' if row.outside else ' class="flag"' if row.outliers else ""
        lines.append(f"<tr{kind}>" + "".join(_cell(c, k) for k, c in enumerate(cells)) + "</tr>")
    header = "".join(f'<th class="l">{h}</th>' if k in (0, 6, 9, 10) else f"<th>{h}</th>" for k, h in enumerate(head))
    return f'<h2>Figures</h2><table id="figures"><tr>{header}</tr>{"".join(lines)}</table>'


def _cell(content: str, k: int) -> str:
    return f'<td class="l">{content}</td>' if k in (0, 6, 9, 10) else f"<td>{content}</td>"


def _distributions(panels: Sequence[tuple[str, str]]) -> str:
    if not panels:
        return ""
    figures = "".join(f"<figure>{svg}<figcaption>{_e(name)}</figcaption></figure>" for name, svg in panels)
    legend = (
        "Bars: the lot's units; black line: mean; red dashed: limits (an arrow with its value when the limit "
        "lies far off the scale); red triangles: failing units; orange: outliers, named by serial."
    )
    return f'<h2>Distributions</h2><p class="note">{legend}</p><div class="figures" id="distributions">{figures}</div>'


def _attention(units: Sequence[UnitLine]) -> str:
    named = [u for u in units if u.failing or u.flagged]
    if not named:
        return "<h2>Units needing attention</h2><p>None.</p>"
    rows = "".join(
        f'<tr class="{"fail" if u.failing else "flag"}"><td class="l">{_unit(u)}</td>'
        f'<td class="l">{"fails" if u.failing else "look"}</td>'
        f'<td class="l">{"<br>".join(_e(why) for why in (*u.failing, *u.flagged))}</td>'
        f'<td class="l">{_e(u.station or "")}</td><td class="l">{_e(u.operator or "")}</td></tr>'
        for u in named
    )
    head = "<tr>" + "".join(f'<th class="l">{h}</th>' for h in ("unit", "", "why", "station", "operator")) + "</tr>"
    return f'<h2>Units needing attention</h2><table id="attention">{head}{rows}</table>'


def _people(units: Sequence[UnitLine]) -> str:
    tables = []
    for what in ("station", "operator"):
        groups: dict[str, list[UnitLine]] = {}
        for u in units:
            groups.setdefault((u.station if what == "station" else u.operator) or "(none)", []).append(u)
        rows = "".join(
            f'<tr><td class="l">{_e(name)}</td><td>{len(group)}</td>'
            f"<td>{sum(1 for u in group if u.failing)}</td><td>{sum(1 for u in group if u.flagged)}</td>"
            f"<td>{sum(1 for u in group if not u.failing) / len(group):.1%}</td></tr>"
            for name, group in sorted(groups.items())
        )
        head = f'<tr><th class="l">{what}</th><th>units</th><th>failing</th><th>to look at</th><th>yield</th></tr>'
        tables.append(f'<table id="{what}s">{head}{rows}</table>')
    return "<h2>Stations and operators</h2>" + "".join(tables)


def _extras(r: lot.Report, drift_given: bool) -> str:
    out = []
    changed = [d for d in r.drift if d.flagged] if drift_given else []
    if changed:
        rows = "".join(
            f'<tr><td class="l">{_e(d.serial)}</td><td class="l">{_e(d.parameter)}</td>'
            f'<td>{_g(d.change)}</td><td>{_g(d.limit)}</td><td class="l">{_e(d.previous_created)}</td></tr>'
            for d in changed
        )
        head = '<tr><th class="l">unit</th><th class="l">figure</th><th>change</th><th>limit</th>'
        head += '<th class="l">since</th></tr>'
        out.append(f"<h2>Drift beyond --max-drift</h2><table>{head}{rows}</table>")
    if r.duplicates:
        items = "".join(f"<li>{_e(line)}</li>" for line in lot.duplicate_warnings(r.duplicates))
        out.append(f"<h2>Pose files under two serials</h2><ul>{items}</ul>")
    if r.unreadable:
        items = "".join(f"<li>{_e(path)}: {_e(why)}</li>" for path, why in r.unreadable)
        out.append(f"<h2>Files that could not be read</h2><ul>{items}</ul>")
    return "".join(out)


def _units(units: Sequence[UnitLine]) -> str:
    rows = "".join(
        f'<tr class="{"fail" if u.failing else "flag" if u.flagged else ""}"><td class="l">{_unit(u)}</td>'
        f'<td class="l">{_e(u.created)}</td><td class="l">{_e(u.sensor)}</td><td class="l">{_e(u.method)}</td>'
        f'<td class="l">{_e(u.station or "")}</td><td class="l">{_e(u.operator or "")}</td>'
        f'<td class="l">{"fails" if u.failing else "look" if u.flagged else "pass"}</td></tr>'
        for u in units
    )
    head = "".join(
        f'<th class="l">{h}</th>' for h in ("unit", "created", "sensor", "method", "station", "operator", "")
    )
    return f'<h2>Units</h2><table id="units"><tr>{head}</tr>{rows}</table>'


def _unit(u: UnitLine) -> str:
    return f'<a href="{_e(u.link)}">{_e(u.name)}</a>' if u.link else _e(u.name)


def _span(row: lot.ParameterRow) -> str:
    if row.lower is None and row.upper is None:
        return ""
    if row.lower is not None and row.upper is not None and row.lower == -row.upper:
        return f"±{_g(row.upper)}"
    return f"{_g(row.lower)} … {_g(row.upper)}"


def _g(value: float | None, digits: int = 4) -> str:
    return "" if value is None else f"{value:.{digits}g}".replace("-", "−")


def _e(text: str | None) -> str:
    return html.escape(text or "", quote=True)


def _count(n: int, word: str) -> str:
    return f"{n} {word}{'' if n == 1 else 's'}"
