"""``records trend --html``: the stations' trend as one self-contained page, each alarmed series
an inline SVG control chart (no script, no request: everything is in the page, as the lot
report's). Plain data in (what the pipeline computed), text out; every text is escaped."""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from dataclasses import dataclass

from tumblecal_cli.io.figures.lothtml import POLICY

#: A chart's size in the page (CSS pixels) and its margins.
WIDTH, HEIGHT, LEFT, RIGHT, TOP, BOTTOM = 760, 220, 64, 12, 14, 26


@dataclass(frozen=True)
class SeriesChart:
    """One series to draw: its ``title``, the ``values`` in time order, the baseline's ``centre``
    and the rule-1 ``limit`` either side of it (in the values' units), how many units the
    ``baseline`` was, and each alarm's (rule, index) ``marks``."""

    title: str
    values: Sequence[float]
    centre: float
    limit: float
    baseline: int
    marks: Sequence[tuple[str, int]]


def _svg(chart: SeriesChart) -> str:
    values = [v for v in chart.values if math.isfinite(v)]
    low = min([*values, chart.centre - chart.limit])
    high = max([*values, chart.centre + chart.limit])
    span = (high - low) or 1.0
    count = max(len(chart.values) - 1, 1)

    def x(i: int) -> float:
        return LEFT + (WIDTH - LEFT - RIGHT) * i / count

    def y(v: float) -> float:
        return TOP + (HEIGHT - TOP - BOTTOM) * (high - v) / span

    points = " ".join(f"{x(i):.1f},{y(v):.1f}" for i, v in enumerate(chart.values) if math.isfinite(v))
    lines = [
        f'<rect x="{LEFT}" y="{TOP}" width="{x(chart.baseline) - LEFT:.1f}" height="{HEIGHT - TOP - BOTTOM}" '
        'fill="#eef3f8"/>',
        f'<polyline points="{points}" fill="none" stroke="#33669a" stroke-width="1"/>',
    ]
    for level, colour in (
        (chart.centre, "#555"),
        (chart.centre + chart.limit, "#c0392b"),
        (chart.centre - chart.limit, "#c0392b"),
    ):
        lines.append(
            f'<line x1="{LEFT}" x2="{WIDTH - RIGHT}" y1="{y(level):.1f}" y2="{y(level):.1f}" stroke="{colour}" '
            'stroke-dasharray="4 3"/>'
        )
    for rule, at in chart.marks:
        value = chart.values[at]
        lines.append(
            f'<circle cx="{x(at):.1f}" cy="{y(value):.1f}" r="4" fill="#c0392b">'
            f"<title>{html.escape(rule)}</title></circle>"
        )
    for level in (high, low):
        lines.append(f'<text x="{LEFT - 4}" y="{y(level) + 4:.1f}" text-anchor="end" font-size="11">{level:.4g}</text>')
    lines.append(
        f'<text x="{WIDTH - RIGHT}" y="{HEIGHT - 6}" text-anchor="end" font-size="11">{len(chart.values)} units</text>'
    )
    body = "".join(lines)
    return (
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" viewBox="0 0 {WIDTH} {HEIGHT}" '
        f'role="img" aria-label="{html.escape(chart.title)}">{body}</svg>'
    )


def page(title: str, stated: Sequence[str], alarms: Sequence[Sequence[str]], charts: Sequence[SeriesChart]) -> str:
    """The page: the ``stated`` lines (baseline, limits, counts), the ``alarms`` table (station,
    parameter, rule, first serial, first time, meaning) and each chart."""
    head = ("station", "parameter", "rule", "first serial", "first time", "what it usually means")
    rows = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in alarms)
    table = (
        "<table><tr>" + "".join(f"<th>{h}</th>" for h in head) + f"</tr>{rows}</table>"
        if alarms
        else "<p>No alarm.</p>"
    )
    figures = "".join(f"<figure><figcaption>{html.escape(c.title)}</figcaption>{_svg(c)}</figure>" for c in charts)
    return "".join(
        [
            '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">',
            f'<meta http-equiv="Content-Security-Policy" content="{POLICY}">',
            '<meta name="viewport" content="width=device-width, initial-scale=1">',
            f"<title>{html.escape(title)}</title>",
            "<style>body{font-family:sans-serif;margin:2em;color:#222}table{border-collapse:collapse}"
            "td,th{border:1px solid #ccc;padding:3px 8px;text-align:left;font-size:13px}"
            "figure{margin:1.5em 0}figcaption{font-weight:bold;margin-bottom:4px}</style>",
            f"</head><body><h1>{html.escape(title)}</h1>",
            "".join(f"<p>{html.escape(line)}</p>" for line in stated),
            f'<h2>Alarms</h2><section id="alarms">{table}</section>',
            f'<h2>Charts</h2><section id="charts">{figures}</section>',
            "</body></html>\n",
        ]
    )
