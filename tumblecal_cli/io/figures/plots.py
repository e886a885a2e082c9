"""PNG figures for ``solve --plot`` of a rotation capture, ``report --plot``, ``thermal --plot``,
``noise --plot`` and ``records trend --plot`` (the optional extra ``tumblecal[plot]``).

matplotlib and numpy are imported inside the functions, so importing this module costs nothing.
Figures are drawn on a bare ``matplotlib.figure.Figure`` (no pyplot, no global backend state),
rendered to memory, and only then written with :func:`tumblecal_cli.io.outputs.atomic_output`: bad
input raises :class:`InputError` before any file is touched. The same call gives the same bytes.

Model (docs/reference/calibration-file.md): ``corrected = M·(raw − offset)``, ``A = M⁻¹``.
"""

from __future__ import annotations

import importlib.util
import io
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from tumblecal_cli.core.allan import BIAS_FACTOR
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.outputs import atomic_output

if TYPE_CHECKING:
    import numpy as np
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from tumblecal_cli.core.allan import Curve, Figures
    from tumblecal_cli.core.arrays import FloatArray
    from tumblecal_cli.io.figures.trendhtml import SeriesChart

#: Rotation captures are drawn from at most this many samples (evenly spaced, so deterministic).
MAX_POINTS = 5000
DPI = 100
#: The colours every figure (and io.figures.fitplots) draws in: raw readings, corrected ones, a fit.
BEFORE = "#9a9a9a"  # grey: raw, before calibration
_BEFORE_BAR = "#cfcfcf"  # light grey bars
AFTER = "tab:blue"
FIT = "tab:red"
_OUTLINE = "tab:orange"


def require() -> None:
    """Raise :class:`InputError` when matplotlib is not installed (without importing it)."""
    if importlib.util.find_spec("matplotlib") is None:
        raise InputError("--plot needs matplotlib, which is not installed", hint="pip install 'tumblecal[plot]'")


@dataclass(frozen=True)
class Mark:
    """A unit a lot figure names: ``kind`` "outside" (beyond a limit: fails), "outlier", or
    "both"."""

    name: str
    value: float
    kind: str


@dataclass(frozen=True)
class Histogram:
    """One parameter over a lot: its values, and the limits it is judged against (None: none);
    ``marks``: the units to name on it (failing ones and outliers)."""

    name: str
    values: FloatArray  # (n,)
    lower: float | None
    upper: float | None
    label: str = ""  # x-axis label, e.g. the units
    marks: tuple[Mark, ...] = ()


@dataclass(frozen=True)
class PlottedCorrection:
    """A calibration's correction as a figure shows it: ``corrected = matrix · (raw − offset)``
    against ``reference``, in ``units``."""

    offset: FloatArray
    matrix: FloatArray
    reference: float
    units: str | None = None


def rotation_figure(
    path: str,
    raw: FloatArray,
    fitted: PlottedCorrection,
    *,
    title: str = "",
    plane: str | None = None,
    limit: float | None = None,
) -> None:
    """A turning capture in the xy, xz and yz planes: the raw samples with the fitted ellipse
    (top), the corrected samples with the circle of radius ``reference`` (middle); and each
    sample's residual ``|corrected| − reference`` in % of the reference, in the order
    captured, with ±``limit`` (the residual limit, output units) dashed (bottom).

    ``plane`` ("xy" ...): a capture turned in that plane only (2-D min/max) is drawn in that
    plane alone, against the circle of its in-plane radius (the field's part in the plane: the
    median of the corrected samples' in-plane norms), not the whole field's.

    The ellipse in a plane is the image of that plane's great circle, ``offset + A·(reference·u)``,
    projected onto the plane: where a capture turned in that plane lies. A capture turned through
    all orientations fills the fitted ellipsoid's shadow instead, drawn dashed; the two coincide
    when ``A`` has no cross terms to the third axis.
    """
    from matplotlib.lines import Line2D

    samples = checked_array(raw, "raw samples", (-1, 3))
    count = samples.shape[0]
    b = checked_array(fitted.offset, "offset", (3,))
    m = checked_array(fitted.matrix, "matrix", (3, 3))
    ref = checked_number(fitted.reference, "reference")
    units = fitted.units
    if ref <= 0:
        raise InputError(f"reference must be positive for a rotation figure, not {fitted.reference}")
    if count == 0:
        raise InputError("no samples to plot")
    try:
        a = np.linalg.inv(m)
    except np.linalg.LinAlgError:
        raise InputError("the calibration matrix is singular") from None
    if count > MAX_POINTS:
        samples = samples[np.linspace(0, count - 1, MAX_POINTS).round().astype(np.intp)]
    corrected = (samples - b) @ m.T
    theta = np.linspace(0.0, 2.0 * math.pi, 361)
    suffix = f" ({units})" if units else ""

    pairs = [(0, 1), (0, 2), (1, 2)]
    if plane is not None:
        if plane not in ("xy", "xz", "yz"):
            raise InputError(f"plane must be xy, xz or yz, not {plane!r}")
        pairs = [("xyz".index(plane[0]), "xyz".index(plane[1]))]
        ref = float(np.median(np.linalg.norm(corrected[:, list(pairs[0])], axis=1)))
    fig = new_figure(width=9.0 if plane else 12.0, height=11.5 if plane else 10.5, title=title)
    grid = fig.add_gridspec(3, len(pairs), height_ratios=[1, 1, 0.55])
    for col, (i, j) in enumerate(pairs):
        name = "xyz"[i] + "xyz"[j]
        u = np.zeros((theta.size, 3))
        u[:, i] = np.cos(theta)
        u[:, j] = np.sin(theta)
        ellipse = b + (ref * u) @ a.T
        rows = a[[i, j]]  # the ellipsoid's shadow on the plane: b + reference·L·(cos θ, sin θ), L·Lᵀ = rows·rowsᵀ
        outline = (
            b[[i, j]] + ref * np.stack([np.cos(theta), np.sin(theta)], axis=1) @ np.linalg.cholesky(rows @ rows.T).T
        )

        ax = fig.add_subplot(grid[0, col])
        ax.plot(samples[:, i], samples[:, j], ".", color=BEFORE, markersize=2, alpha=0.5)
        ax.plot(outline[:, 0], outline[:, 1], color=_OUTLINE, linewidth=1.2, linestyle=(0, (4, 3)))
        ax.plot(ellipse[:, i], ellipse[:, j], color=FIT, linewidth=1.5)
        ax.plot(b[i], b[j], "+", color=FIT, markersize=10)
        _plane_axes(ax, f"raw, {name} plane", f"raw {'xyz'[i]}", f"raw {'xyz'[j]}")

        ax = fig.add_subplot(grid[1, col])
        ax.plot(corrected[:, i], corrected[:, j], ".", color=AFTER, markersize=2, alpha=0.5)
        ax.plot(ref * np.cos(theta), ref * np.sin(theta), color="black", linewidth=1.5)
        ax.plot(0.0, 0.0, "+", color="black", markersize=10)
        _plane_axes(ax, f"corrected, {name} plane", f"{'xyz'[i]}{suffix}", f"{'xyz'[j]}{suffix}")
    _turn_residuals(fig.add_subplot(grid[2, :]), corrected, ref, plane, limit)
    shown = f", {samples.shape[0]} of {count}" if samples.shape[0] < count else f", {count}"
    handles = [  # the legend fills columns first: raw and its curves on the first row
        Line2D([], [], linestyle="", marker=".", markersize=8, color=BEFORE, label=f"raw samples{shown}"),
        Line2D([], [], linestyle="", marker=".", markersize=8, color=AFTER, label="corrected M·(raw − offset)"),
        Line2D([], [], color=FIT, linewidth=1.5, label="fitted ellipse: offset + A·(reference·u), u in the plane"),
        Line2D(
            [],
            [],
            color="black",
            linewidth=1.5,
            label=f"circle of radius {ref:.4g}{_unit(units)}"
            + (f" (the field's part in the {plane} plane)" if plane else ""),
        ),
        Line2D(
            [],
            [],
            color=_OUTLINE,
            linewidth=1.2,
            linestyle=(0, (4, 3)),
            label="fitted ellipsoid's outline (under the ellipse when A has no cross terms)",
        ),
        Line2D([], [], linestyle="", marker="+", markersize=10, color=FIT, label="offset"),
    ]
    fig.legend(handles=handles, loc="outside lower center", ncols=2 if plane else 3, fontsize="small", frameon=False)
    write_png(fig, path)


def _turn_residuals(ax: Axes, corrected: FloatArray, ref: float, plane: str | None, limit: float | None) -> None:
    """Each sample's ``|corrected| − ref`` in % of ``ref`` (in the plane's part alone for a
    one-plane capture), with ±``limit`` dashed."""
    part = corrected if plane is None else corrected[:, ["xyz".index(plane[0]), "xyz".index(plane[1])]]
    residual = (np.linalg.norm(part, axis=1) - ref) / ref * 100.0
    ax.axhline(0.0, color="black", linewidth=0.8)
    ax.plot(residual, ".", color=AFTER, markersize=3, alpha=0.7)
    if limit is not None:
        v = limit / ref * 100.0
        ax.axhline(v, color=FIT, linestyle="--", linewidth=1.2, label=f"residual limit ±{v:.3g} %")
        ax.axhline(-v, color=FIT, linestyle="--", linewidth=1.2)
        ax.legend(fontsize="small", loc="upper right")
        low, high = ax.get_ylim()
        ax.set_ylim(min(low, -1.08 * v), max(high, 1.08 * v))
    rms, worst = float(np.sqrt(np.mean(residual**2))), float(np.max(np.abs(residual)))
    ax.set_title(
        f"after calibration: each sample's |corrected| − reference (RMS {rms:.3g} %, largest {worst:.3g} %)",
        fontsize="medium",
    )
    ax.set_ylabel("residual (% of reference)")
    ax.set_xlabel("sample (in the order captured)")
    ax.grid(axis="y", alpha=0.3)


def lot_figure(path: str, histograms: list[Histogram], *, title: str = "") -> None:
    """One histogram per parameter (≤ 4 columns): the mean as a solid line, the limits as red
    dashed lines, failing units (red) and outliers (orange) marked above the bars and named. The
    x range is the data's: a limit far beyond it (a cross-axis limit of 0.01 over terms of 1e-4)
    is an arrow at the edge with its value, so the bars do not collapse to a line."""
    from matplotlib.lines import Line2D

    checked = _checked(histograms)
    ncols = min(4, len(checked))
    nrows = math.ceil(len(checked) / ncols)
    fig = new_figure(width=3.4 * ncols + 0.6, height=2.6 * nrows + 0.8, title=title)
    grid = fig.add_gridspec(nrows, ncols)
    for k, (h, values, limits) in enumerate(checked):
        _draw_histogram(fig.add_subplot(grid[k // ncols, k % ncols]), h, values, limits)
    handles = [Line2D([], [], color="black", linewidth=1.5, label="mean")]
    if any(limits for _, _, limits in checked):  # no "limit" entry for a figure without any
        handles.append(Line2D([], [], color=FIT, linestyle="--", linewidth=1.5, label="limit"))
    for kind, (color, label) in _MARKS.items():
        if any(_colour(m.kind) == kind for h, _, _ in checked for m in h.marks):
            handles.append(Line2D([], [], color=color, marker="v", linestyle="", label=label))
    fig.legend(handles=handles, loc="outside lower center", ncols=len(handles), fontsize="small", frameon=False)
    write_png(fig, path)


def lot_panels_svg(histograms: list[Histogram]) -> list[str]:
    """Each histogram of :func:`lot_figure` as its own SVG document (text paths, no fonts, ids
    unique to each panel), to be inlined in an HTML page."""
    import matplotlib

    out = []
    for k, (h, values, limits) in enumerate(_checked(histograms)):
        fig = new_figure(width=4.2, height=3.0, title="")
        _draw_histogram(fig.add_subplot(), h, values, limits)
        buffer = io.StringIO()
        with matplotlib.rc_context({"svg.fonttype": "path", "svg.hashsalt": f"lot-panel-{k}"}):
            fig.savefig(buffer, format="svg", metadata={"Date": None, "Creator": None})
        text = buffer.getvalue()
        text = text[text.index("<svg") :]  # no XML declaration or DOCTYPE inside HTML
        # ids unique in the page: each panel's own (glyphs, clip paths, groups), and the references to them
        text = re.sub(r'(\sid="|href="#|url\(#)(?=[^"\)])', rf"\g<1>lot{k}-", text)
        out.append(text)
    return out


_MARKS = {"outside": (FIT, "outside a limit (fails)"), "outlier": (_OUTLINE, "outlier")}


def _checked(histograms: list[Histogram]) -> list[tuple[Histogram, FloatArray, list[float]]]:
    if not histograms:
        raise InputError("no parameters to plot")
    checked = []
    for h in histograms:
        values = checked_array(h.values, f"values of {h.name}", (-1,))
        if values.size == 0:
            raise InputError(f"no values of {h.name} to plot")
        limits = [checked_number(v, f"{h.name} limit") for v in (h.lower, h.upper) if v is not None]
        if h.lower is not None and h.upper is not None and h.lower > h.upper:
            raise InputError(f"{h.name}: lower limit {h.lower:g} is above upper limit {h.upper:g}")
        for m in h.marks:
            checked_number(m.value, f"{h.name} mark {m.name}")
        checked.append((h, values, limits))
    return checked


def _draw_histogram(ax: Axes, h: Histogram, values: FloatArray, limits: list[float]) -> None:
    from matplotlib.ticker import MaxNLocator

    lo, hi = float(values.min()), float(values.max())
    span = hi - lo or 0.1 * abs(lo) or 1.0
    # drawn in place when the data keep ≥ 1/3 of the axis (or all values are equal: no scale of their own)
    near = [v for v in limits if lo - span <= v <= hi + span or hi == lo]
    shown = [lo, hi, *near]
    edges = np.linspace(lo, hi, _bins(values) + 1)
    if hi == lo:  # all values equal: a thin bar in the middle of a span set by the limits or the value
        wide = (max(shown) - min(shown)) or span
        edges = np.array([lo - wide / 40, lo + wide / 40])
        if not near:
            shown += [lo - wide / 2, lo + wide / 2]
    counts, _, _ = ax.hist(values, bins=[float(e) for e in edges], color=AFTER, alpha=0.75)
    ax.axvline(float(values.mean()), color="black", linewidth=1.5)
    for limit in near:
        ax.axvline(limit, color=FIT, linestyle="--", linewidth=1.5)
    left, right = min([float(edges[0]), *shown]), max([float(edges[-1]), *shown])
    pad = 0.06 * (right - left)
    ax.set_xlim(left - pad, right + pad)
    top = max(float(np.max(counts)), 1.0)
    ax.set_ylim(0, top * (1.45 if h.marks else 1.3 if len(near) < len(limits) else 1.1))
    for limit in limits:
        if limit not in near:  # off scale: an arrow at the edge it lies beyond, with its value
            right_side = limit > hi
            value = f"{limit:.3g}".replace("-", "−")
            ax.annotate(
                f"limit {value} →" if right_side else f"← limit {value}",
                xy=(1.0 if right_side else 0.0, 0.92),
                xycoords="axes fraction",
                ha="right" if right_side else "left",
                fontsize="x-small",
                color=FIT,
            )
    _draw_marks(ax, h.marks, top)
    outside = int(np.sum(values < h.lower)) if h.lower is not None else 0
    outside += int(np.sum(values > h.upper)) if h.upper is not None else 0
    flagged = sum(1 for m in h.marks if m.kind in ("outlier", "both"))
    count = f"n={values.size}" + (f", {outside} outside" if outside else "")
    count += f", {flagged} outlier{'s' if flagged > 1 else ''}" if flagged else ""
    ax.set_title(f"{h.name} ({count})", fontsize="medium")
    if h.label:
        ax.set_xlabel(h.label)
    ax.xaxis.set_major_locator(MaxNLocator(nbins=4))
    ax.yaxis.set_major_locator(MaxNLocator(integer=True, nbins=4))
    ax.tick_params(labelsize="small")


def _colour(kind: str) -> str:
    """A failing unit is drawn as failing, whether or not it is also an outlier."""
    return "outlier" if kind == "outlier" else "outside"


def _draw_marks(ax: Axes, marks: tuple[Mark, ...], top: float, named: int = 6) -> None:
    """A triangle above the bars at each marked unit, the first ``named`` of them labelled."""
    for kind, (color, _) in _MARKS.items():
        xs = [m.value for m in marks if _colour(m.kind) == kind]
        if xs:
            ax.scatter(xs, [top * 1.12] * len(xs), marker="v", color=color, s=36, zorder=3, clip_on=False)
    left, right = ax.get_xlim()
    for k, m in enumerate(sorted(marks, key=lambda m: m.value)[:named]):
        where = (m.value - left) / (right - left)
        ax.annotate(
            shortened(m.name, 14),
            xy=(m.value, top * 1.16),
            xytext=(0, 2 + 7 * (k % 2)),  # alternate heights: neighbours do not overprint
            textcoords="offset points",
            ha="right" if where > 0.85 else "left" if where < 0.15 else "center",  # inside the axes
            fontsize="x-small",
            color=_MARKS[_colour(m.kind)][0],
        )
    if len(marks) > named:
        ax.annotate(
            f"+{len(marks) - named} more",
            xy=(0.99, 0.99),
            xycoords="axes fraction",
            ha="right",
            va="top",
            fontsize="x-small",
        )


def drift_figure(
    path: str,
    sweeps: list[tuple[str, FloatArray, FloatArray, FloatArray]],
    *,
    units: str | None = None,
    title: str = "",
) -> None:
    """``thermal --plot``: per axis, each sweep's observed drift against temperature (its cells,
    dots) with the fitted drift (line), and below it the residuals. ``sweeps`` are (label,
    temperature (m,), observed (m, 3), fitted (m, 3)), core.drift.observed."""

    if not sweeps:
        raise InputError("no sweeps to plot")
    fig = new_figure(width=12.0, height=6.4, title=title)
    grid = fig.add_gridspec(2, 3, height_ratios=[2, 1])
    colours = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink", "tab:olive"]
    for j, axis in enumerate("xyz"):
        top = fig.add_subplot(grid[0, j])
        bottom = fig.add_subplot(grid[1, j], sharex=top)
        for k, (label, temp, seen, fitted) in enumerate(sweeps):
            t = checked_array(temp, f"temperature of {label}", (-1,))
            o = checked_array(seen, f"drift of {label}", (t.size, 3))
            f = checked_array(fitted, f"fit of {label}", (t.size, 3))
            order = np.argsort(t)
            colour = colours[k % len(colours)]
            top.plot(t, o[:, j], ".", color=colour, markersize=3, alpha=0.6, label=shortened(label))
            top.plot(t[order], f[order, j], "-", color=colour, linewidth=1.2)
            bottom.plot(t, o[:, j] - f[:, j], ".", color=colour, markersize=3, alpha=0.6)
        top.set_title(f"{axis}: drift against temperature", fontsize="medium")
        top.set_ylabel(f"drift{_unit(units)}")
        top.grid(alpha=0.3)
        bottom.axhline(0.0, color="black", linewidth=0.8)
        bottom.set_xlabel("temperature (°C)")
        bottom.set_ylabel("residual")
        bottom.grid(alpha=0.3)
        top.tick_params(labelsize="small")
        bottom.tick_params(labelsize="small")
        if j == 0:
            top.legend(fontsize="x-small", loc="best")
    write_png(fig, path)


def _bins(values: FloatArray) -> int:
    """numpy's "auto" rule (the finer of Freedman–Diaconis and Sturges), at most 50 bins."""

    sturges = math.ceil(math.log2(values.size)) + 1
    q1, q3 = np.percentile(values, [25.0, 75.0])
    width = 2.0 * float(q3 - q1) / values.size ** (1 / 3)
    span = float(values.max() - values.min())
    fd = math.ceil(span / width) if width > 0 else 0
    return max(1, min(50, max(sturges, fd)))


def new_figure(*, width: float, height: float, title: str) -> Figure:
    """A figure of ``width`` x ``height`` inches at DPI, its layout constrained, titled."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    if title:
        fig.suptitle(title)
    return fig


def _plane_axes(ax: Axes, title: str, xlabel: str, ylabel: str) -> None:
    ax.set_title(title, fontsize="medium")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)


def write_png(fig: Figure, path: str) -> None:
    """Render to memory first, so a failure leaves ``path`` as it was; then write it atomically."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI, metadata={"Software": None})
    with atomic_output(path) as out:
        out.write(buffer.getvalue())


def checked_array(value: object, what: str, shape: tuple[int, ...]) -> FloatArray:
    """``value`` as a finite float array of ``shape`` (-1: any length); InputError otherwise."""

    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{what} is not an array of numbers") from None
    if array.ndim != len(shape) or any(want not in (-1, got) for want, got in zip(shape, array.shape, strict=True)):
        want = "×".join("n" if s == -1 else str(s) for s in shape)
        raise InputError(f"{what} has shape {'×'.join(map(str, array.shape)) or 'scalar'}, expected {want}")
    bad = int(np.count_nonzero(~np.isfinite(array)))
    if bad:
        raise InputError(f"{what} has {bad} of {array.size} values that are not finite (NaN or infinity)")
    return array


def checked_number(value: float, what: str) -> float:
    """``value`` as a finite float; InputError naming ``what`` otherwise."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{what} is not a number: {value!r}") from None
    if not math.isfinite(number):
        raise InputError(f"{what} is not finite: {value}")
    return number


def _unit(units: str | None) -> str:
    return f" {units}" if units else ""


def shortened(name: str, keep: int = 24) -> str:
    """A long tick label shortened in the middle, so the file name's end stays readable."""
    return name if len(name) <= keep else f"{name[: keep // 2 - 1]}…{name[-(keep // 2) :]}"


def noise_figure(path: str, curve: Curve, figures: list[Figures], units: str | None, *, title: str = "") -> None:
    """``noise --plot``: the Allan deviation of each axis on log-log axes with its 95 % band, the
    fitted -1/2 and +1/2 lines over the cluster times they were read from, and the read-off
    points (N at 1 s, the minimum 0.664 B, K at 3 s). ``curve`` a core.allan.Curve, ``figures``
    its core.allan.Figures per axis, both in the data's units."""

    tau = checked_array(curve.tau, "cluster times", (-1,))
    adev = checked_array(curve.adev, "Allan deviation", (-1, 3))
    low, high = curve.interval()
    fig = new_figure(width=11.0, height=4.2, title=title)
    axes = fig.subplots(1, 3, sharey=True)
    for j, (ax, figs) in enumerate(zip(axes, figures, strict=True)):
        top = np.where(np.isfinite(high[:, j]), high[:, j], np.nan)
        ax.fill_between(tau, low[:, j], top, color=AFTER, alpha=0.2, lw=0, label="95 % interval")
        ax.loglog(tau, adev[:, j], "o-", color=AFTER, ms=3, lw=1, label="overlapping ADEV")
        marks = []
        n, b, k = figs.noise_density, figs.bias_instability, figs.random_walk
        if n.value is not None and n.tau is not None:
            span = np.geomspace(min(n.tau[0], 1.0), max(n.tau[1], 1.0), 20)
            ax.loglog(span, n.value / np.sqrt(span), "--", color=FIT, lw=1, label="−½ slope (noise density)")
            marks.append((1.0, n.value, "N"))
        if k.value is not None and k.tau is not None:
            span = np.geomspace(min(k.tau[0], 3.0), max(k.tau[1], 3.0), 20)
            ax.loglog(span, k.value * np.sqrt(span / 3.0), ":", color=FIT, lw=1.2, label="+½ slope (random walk)")
            marks.append((3.0, k.value, "K"))
        if b.value is not None and b.tau is not None:
            ax.axhline(b.value * BIAS_FACTOR, color=_OUTLINE, lw=0.8, label="minimum (0.664 B)")
            marks.append((b.tau[0], b.value * BIAS_FACTOR, "B"))
        for x, y, name in marks:
            ax.plot([x], [y], "s", color=FIT, ms=6)
            ax.annotate(name, (x, y), textcoords="offset points", xytext=(5, 5), fontsize="small")
        _plane_axes(ax, "xyz"[j], "τ (s)", f"σ(τ){_unit(units)}" if j == 0 else "")
        ax.set_aspect("auto")
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize="x-small", loc="lower left")
    write_png(fig, path)


def trend_figure(path: str, charts: Sequence[SeriesChart], *, title: str = "") -> None:
    """``records trend --plot``: each alarmed series's control chart (≤ 2 columns, the first 12):
    its values in time order, the baseline shaded, the centre and rule 1's limits dashed, the
    units where a rule fired marked and named. No alarm: one panel that says so."""
    shown = list(charts[:12])
    ncols = 2 if len(shown) > 1 else 1
    nrows = max(1, math.ceil(len(shown) / ncols))
    fig = new_figure(width=6.0 * ncols + 0.4, height=2.6 * nrows + 0.6, title=title)
    if not shown:
        ax = fig.add_subplot(1, 1, 1)
        ax.text(0.5, 0.5, "no alarm", ha="center", va="center", transform=ax.transAxes)
        ax.set_axis_off()
    for k, chart in enumerate(shown):
        ax = fig.add_subplot(nrows, ncols, k + 1)
        values = np.asarray(chart.values, dtype=np.float64)
        ax.axvspan(0, max(chart.baseline - 1, 0), color="#eef3f8", label="baseline")
        ax.plot(np.arange(values.size), values, color=AFTER, linewidth=0.8)
        ax.axhline(chart.centre, color="black", linewidth=1.0)
        for level in (chart.centre - chart.limit, chart.centre + chart.limit):
            ax.axhline(level, color=FIT, linestyle="--", linewidth=1.0)
        for rule, at in chart.marks:
            ax.plot([at], [values[at]], marker="o", color=FIT)
            ax.annotate(rule, (at, values[at]), textcoords="offset points", xytext=(4, 4), fontsize="x-small")
        ax.set_title(shortened(chart.title, 60), fontsize="small")
        ax.set_xlabel("unit")
        ax.grid(alpha=0.3)
    write_png(fig, path)
