"""PNG figures that judge a fit: ``solve --plot`` of static poses, ``verify --plot`` and
``segment --plot`` (the optional extra ``tumblecal[plot]``; drawn and written as in
:mod:`tumblecal_cli.io.figures.plots`, matplotlib imported inside the functions).

Each figure answers "is this calibration good?": the residuals after calibration on a scale
where they are visible (mg for a calibration in g, else % of the reference), with the limits
in force drawn; "before" on its own axes, never on one axis with the calibrated data.

Model (README "Calibration file"): ``corrected = M·(raw − offset)``; a pose's residual is
``|M·(mean − offset)| − reference`` (Sports Sensing 2023's test of a calibration).
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from tumblecal_cli.core.blocks import Block, Segmentation, rolling_std
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.figures.plots import (
    AFTER,
    BEFORE,
    FIT,
    PlottedCorrection,
    checked_array,
    checked_number,
    new_figure,
    shortened,
    write_png,
)

if TYPE_CHECKING:
    from matplotlib.artist import Artist
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from tumblecal_cli.core.arrays import FloatArray

#: Each pose's samples are drawn from at most this many (evenly spaced, so deterministic).
POSE_POINTS = 2000
#: A log is drawn from at most this many columns, each its lowest and highest reading.
LOG_COLUMNS = 4000
_LIMIT = "tab:red"
_FAIL = "tab:red"
_KEPT = "tab:green"
_DROPPED = "#bbbbbb"
_AXES = ("tab:blue", "tab:orange", "tab:green")
#: The log's axes are about this many pixels wide, and an x-small label's character this wide:
#: a block's file name is written in it where it fits.
_PLOT_PIXELS = 1250.0
_CHAR_PIXELS = 6.0


@dataclass(frozen=True)
class Scale:
    """How a residual in output units is shown: times ``factor``, in ``unit``."""

    factor: float
    unit: str

    @staticmethod
    def of(units: str | None, reference: float, sensor: str = "accelerometer") -> Scale:
        """mg for an accelerometer (its reference is 1 g, whatever its units), % of the
        reference otherwise (the output units where the reference is 0: a gyroscope at rest)."""
        if units == "g" or (sensor == "accelerometer" and reference > 0):
            return Scale(1000.0 / (1.0 if units == "g" else reference), "mg")
        if reference > 0:
            return Scale(100.0 / reference, "% of reference")
        return Scale(1.0, units or "output units")

    def coarser(self, values: FloatArray) -> Scale:
        """g instead of mg where the values reach 1 g (a raw "before" in counts)."""
        if self.unit == "mg" and values.size and float(np.max(np.abs(values))) >= 1000.0:
            return Scale(1.0, "g")
        return self


@dataclass(frozen=True)
class PoseData:
    """One static pose: its name, raw mean, raw samples (None: the mean alone is known), its
    face, and its angle from that face as read (the orientation check's)."""

    name: str
    mean: FloatArray
    samples: FloatArray | None = None
    face: str | None = None
    angle_deg: float | None = None


@dataclass(frozen=True)
class Before:
    """What "before calibration" means: ``|mean − centre| / gain``, and how to say it."""

    centre: FloatArray
    gain: float
    label: str


@dataclass(frozen=True)
class Bounds:
    """The limits in force, as a figure draws them: ``residual`` on a pose's
    ``|corrected| − reference`` (output units); ``tolerance_deg`` the fixture tolerance the tilt
    sensitivity is stated at; ``max_tilt_deg`` the orientation check's bound."""

    residual: float | None = None
    tolerance_deg: float | None = None
    max_tilt_deg: float | None = None


@dataclass
class _Residuals:
    """Each pose's residual after calibration (output units): the mean's, its 1σ from the
    samples' noise, and the samples' own (at most POSE_POINTS of them)."""

    mean: FloatArray
    sigma: FloatArray
    spread: list[FloatArray] = field(default_factory=list)


def poses_figure(
    path: str,
    poses: list[PoseData],
    fitted: PlottedCorrection,
    bounds: Bounds,
    before: Before,
    *,
    sensor: str = "accelerometer",
    title: str = "",
) -> None:
    """``solve --plot`` of static poses: the residual of each pose after calibration (its mean
    with 1σ, its samples' spread as a box, the residual limit), the residual before on its own
    axes, and the tilt of each pose from its face (face solvers) or the calibrated poses on the
    unit sphere coloured by residual (orientation-free solvers: sphere, least squares)."""
    if not poses:
        raise InputError("no poses to plot")
    b = checked_array(fitted.offset, "offset", (3,))
    m = checked_array(fitted.matrix, "matrix", (3, 3))
    ref = checked_number(fitted.reference, "reference")
    gain = checked_number(before.gain, "nominal gain")
    if gain <= 0:
        raise InputError(f"nominal gain must be positive, not {before.gain}")
    means = checked_array(np.array([p.mean for p in poses]), "pose means", (-1, 3))
    scale = Scale.of(fitted.units, ref, sensor)
    res = _residuals(poses, b, m, ref)
    raw = np.linalg.norm(means - checked_array(before.centre, "nominal offset", (3,)), axis=1) / gain - ref
    faced = any(p.face for p in poses) and any(p.angle_deg is not None for p in poses)
    n = len(poses)
    fig = new_figure(width=min(16.0, max(9.0, 4.0 + 0.25 * n)), height=8.0, title=title)
    grid = fig.add_gridspec(2, 2, height_ratios=[3, 2.4], width_ratios=[3, 2])
    ticks = [p.name for p in poses]
    exact = bool(np.all(np.abs(res.mean) <= 1e-7 * max(ref, 1.0)))  # as many parameters as readings
    _after_axes(fig.add_subplot(grid[0, :]), res, scale, bounds.residual, ticks, exact=exact, ref=ref)
    right = faced or ref > 0  # a gyroscope at rest: no direction to draw
    below = fig.add_subplot(grid[1, 0] if right else grid[1, :])
    _before_axes(below, raw, scale.coarser(raw * scale.factor), before.label, ticks)
    if faced:
        _tilt_axes(fig.add_subplot(grid[1, 1]), poses, bounds, ticks)
    elif right:
        corrected = (means - b) @ m.T
        _sphere_axes(fig, fig.add_subplot(grid[1, 1], projection="3d"), corrected, res.mean * scale.factor, scale)
    write_png(fig, path)


def _residuals(poses: list[PoseData], offset: FloatArray, matrix: FloatArray, ref: float) -> _Residuals:
    means = np.array([p.mean for p in poses], dtype=np.float64)
    out = _Residuals(np.linalg.norm((means - offset) @ matrix.T, axis=1) - ref, np.zeros(len(poses)))
    for k, p in enumerate(poses):
        if p.samples is None or len(p.samples) < 2:
            out.spread.append(out.mean[k : k + 1])
            continue
        samples = checked_array(p.samples, f"samples of {p.name}", (-1, 3))
        each = np.linalg.norm((samples - offset) @ matrix.T, axis=1) - ref
        out.sigma[k] = float(np.std(each, ddof=1)) / math.sqrt(each.size)
        if each.size > POSE_POINTS:
            each = each[np.linspace(0, each.size - 1, POSE_POINTS).round().astype(np.intp)]
        out.spread.append(each)
    return out


def _ticks(names: list[str]) -> tuple[list[str], str]:
    """Tick labels, and the axis label: a log's blocks and a table's rows by number alone
    ("block 3" → "3", "orient31.csv row 7" → "7"), files by their base name."""
    parts = [re.fullmatch(r"(?:(.*) )?(block|row) (\d+)", name) for name in names]
    if all(parts) and len({(p[1], p[2]) for p in parts if p}) == 1:
        head, word = parts[0][1], parts[0][2]  # type: ignore[index]
        return [p[3] for p in parts if p], f"{os.path.basename(head)} {word}" if head else word
    return [shortened(os.path.basename(name), 20) for name in names], ""


def _pose_ticks(ax: Axes, ticks: list[str]) -> None:
    ticks, name = _ticks(ticks)
    if name:
        ax.set_xlabel(name)
    n = len(ticks)
    ax.set_xlim(-0.6, n - 0.4)
    ax.set_xticks(np.arange(n, dtype=np.float64), ticks)
    longest = max(len(t) for t in ticks)
    if n > 30 and longest > 3:
        ax.tick_params(axis="x", labelrotation=90, labelsize=7)
    elif n > 30:
        ax.tick_params(axis="x", labelsize=7)
    elif (n > 8 and longest > 3) or longest > 5:
        for label in ax.get_xticklabels():
            label.set_rotation(45)
            label.set_horizontalalignment("right")
            label.set_rotation_mode("anchor")
            label.set_fontsize("small")


def _limit_lines(ax: Axes, limit: float | None, factor: float, unit: str, what: str = "limit") -> None:
    """±limit as red dashed lines (one legend entry), kept inside the axes' range."""
    if limit is None:
        return
    v = limit * factor
    ax.axhline(v, color=_LIMIT, linestyle="--", linewidth=1.2, label=f"{what} ±{v:.3g} {unit}")
    ax.axhline(-v, color=_LIMIT, linestyle="--", linewidth=1.2)
    low, high = ax.get_ylim()
    pad = 0.08 * v
    ax.set_ylim(min(low, -v - pad), max(high, v + pad))


def _after_axes(
    ax: Axes, res: _Residuals, scale: Scale, limit: float | None, ticks: list[str], *, exact: bool, ref: float
) -> None:
    x = np.arange(len(ticks), dtype=np.float64)
    f = scale.factor
    ax.axhline(0.0, color="black", linewidth=0.8)
    if any(s.size > 1 for s in res.spread):
        ax.boxplot(
            [s * f for s in res.spread],
            positions=x,
            widths=0.5,
            whis=(5.0, 95.0),
            showfliers=False,
            patch_artist=True,
            boxprops={"facecolor": "#cfe0f1", "edgecolor": "#7aa6d1"},
            medianprops={"color": "#7aa6d1"},
            whiskerprops={"color": "#7aa6d1"},
            capprops={"color": "#7aa6d1"},
        )
        ax.plot([], [], "s", color="#cfe0f1", markeredgecolor="#7aa6d1", label="samples: quartiles, 5–95 %")
    what = "pose mean ± 1σ (noise)" if np.any(res.sigma > 0) else "pose"
    ax.errorbar(x, res.mean * f, yerr=res.sigma * f, fmt="o", color=AFTER, ms=5, capsize=3, label=what)
    _limit_lines(ax, limit, f, scale.unit, "residual limit")
    rms = float(np.sqrt(np.mean(res.mean**2))) * f
    worst = float(np.max(np.abs(res.mean))) * f
    what = "|corrected| − reference" if ref > 0 else "|corrected|"
    if exact:  # a solver with as many parameters as readings: the spread is what is left to see
        figures = "0 by construction, an exact fit: check it with verify"
    else:
        figures = f"RMS {rms:.3g}, largest {worst:.3g} {scale.unit}"
    ax.set_title(f"after calibration: {what} per pose ({figures})", fontsize="medium")
    ax.set_ylabel(f"residual ({scale.unit})")
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize="small", loc="best")
    _pose_ticks(ax, ticks)


def _before_axes(ax: Axes, raw: FloatArray, scale: Scale, label: str, ticks: list[str]) -> None:
    x = np.arange(len(ticks), dtype=np.float64)
    ax.axhline(0.0, color="black", linewidth=0.8)
    ax.plot(x, raw * scale.factor, "o", color=BEFORE, ms=5)
    rms = float(np.sqrt(np.mean(raw**2))) * scale.factor
    ax.set_title(f"before calibration: |{label}| − reference (RMS {rms:.3g} {scale.unit})", fontsize="medium")
    ax.set_ylabel(f"residual ({scale.unit})")
    ax.grid(axis="y", alpha=0.3)
    _pose_ticks(ax, ticks)


def _tilt_axes(ax: Axes, poses: list[PoseData], bounds: Bounds, ticks: list[str]) -> None:
    x = np.arange(len(ticks), dtype=np.float64)
    angle = np.array([math.nan if p.angle_deg is None else p.angle_deg for p in poses])
    ax.bar(x, angle, width=0.5, color=AFTER, alpha=0.8)
    top = float(np.nanmax(angle)) if np.isfinite(angle).any() else 1.0
    if bounds.tolerance_deg is not None:
        t = bounds.tolerance_deg
        ax.axhline(
            t, color=FIT, linestyle="--", linewidth=1.2, label=f"fixture tolerance {t:g}° (of the tilt sensitivity)"
        )
        top = max(top, t)
    if bounds.max_tilt_deg is not None and bounds.max_tilt_deg <= 3.0 * top:  # else it flattens the bars
        t = bounds.max_tilt_deg
        ax.axhline(t, color=_LIMIT, linestyle="-", linewidth=1.2, label=f"rejected above {t:g}°")
        top = max(top, t)
    ax.set_ylim(0.0, 1.12 * top)
    where = f" (rejected above {bounds.max_tilt_deg:g}°)" if bounds.max_tilt_deg is not None else ""
    ax.set_title(f"each pose's tilt from its face, as read{where}", fontsize="medium")
    ax.set_ylabel("tilt (°)")
    ax.grid(axis="y", alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize="small", loc="upper left")
    _pose_ticks(ax, ticks)


def _sphere_axes(fig: Figure, ax: Axes, corrected: FloatArray, residual: FloatArray, scale: Scale) -> None:
    """The calibrated poses' directions on the unit sphere (a wire frame), coloured by residual."""
    u, v = np.meshgrid(np.linspace(0.0, 2.0 * math.pi, 25), np.linspace(0.0, math.pi, 13))
    sphere = (np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v))
    ax.plot_wireframe(*sphere, color="#dddddd", linewidth=0.5)  # type: ignore[attr-defined]
    unit = corrected / np.linalg.norm(corrected, axis=1, keepdims=True)
    span = float(np.max(np.abs(residual))) or 1.0
    points = ax.scatter(
        unit[:, 0],
        unit[:, 1],
        unit[:, 2],
        c=residual,
        cmap="coolwarm",
        vmin=-span,
        vmax=span,
        edgecolors="black",
        linewidths=0.4,
        depthshade=False,
    )
    points.set_sizes([36.0])
    fig.colorbar(points, ax=ax, shrink=0.7, label=f"residual ({scale.unit})")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")  # type: ignore[attr-defined]
    ax.set_box_aspect((1, 1, 1))  # type: ignore[arg-type]
    ax.set_title(f"calibrated poses on the unit sphere ({len(unit)})", fontsize="medium")


@dataclass(frozen=True)
class VerifiedCapture:
    """One capture (or row) of verify: its norm error after calibration (output units), its
    largest corrected standard deviation, its samples, its error before (None: the raw units
    are not the output's) and whether it failed --max-norm-error."""

    name: str
    error: float
    std: float
    samples: int
    before: float | None = None
    failed: bool = False


def verify_figure(
    path: str, rows: list[VerifiedCapture], limit: float | None, scale: Scale, *, title: str = ""
) -> None:
    """``verify --plot``: each capture's norm error after calibration with 1σ of its mean (dark)
    and ±1 standard deviation of its samples (light), the failing ones red, ±``limit`` dashed;
    below it, the error before on its own axes (where the raw units are the output's)."""
    if not rows:
        raise InputError("no captures to plot")
    after = checked_array(np.array([r.error for r in rows]), "norm errors", (-1,)) * scale.factor
    std = checked_array(np.array([r.std for r in rows]), "standard deviations", (-1,)) * scale.factor
    sigma = std / np.sqrt(np.maximum(1, np.array([r.samples for r in rows], dtype=np.float64)))
    failed = np.array([r.failed for r in rows])
    ticks = [r.name for r in rows]
    x = np.arange(len(rows), dtype=np.float64)
    has_before = all(r.before is not None for r in rows)
    fig = new_figure(width=min(16.0, max(8.0, 4.0 + 0.25 * len(rows))), height=7.0 if has_before else 4.8, title=title)
    grid = fig.add_gridspec(2 if has_before else 1, 1, height_ratios=[3, 2] if has_before else [1])
    ax = fig.add_subplot(grid[0])
    ax.axhline(0.0, color="black", linewidth=0.8)
    spread = std > 0
    if spread.any():
        ax.vlines(
            x[spread],
            (after - std)[spread],
            (after + std)[spread],
            color="#9ec5e8",
            linewidth=6,
            label="±1 std of the samples",
        )
    for mask, colour, what in ((~failed, AFTER, "capture mean ± 1σ"), (failed, _FAIL, "outside the limit")):
        if mask.any():
            ax.errorbar(x[mask], after[mask], yerr=sigma[mask], fmt="o", color=colour, ms=5, capsize=3, label=what)
    _limit_lines(ax, limit, scale.factor, scale.unit, "--max-norm-error")
    rms, worst = float(np.sqrt(np.mean(after**2))), float(np.max(np.abs(after)))
    ax.set_title(
        f"after calibration: |corrected mean| − reference (RMS {rms:.3g}, largest {worst:.3g} {scale.unit}"
        + (f", {int(failed.sum())} of {len(rows)} outside" if failed.any() else "")
        + ")",
        fontsize="medium",
    )
    ax.set_ylabel(f"norm error ({scale.unit})")
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize="small", loc="best")
    _pose_ticks(ax, ticks)
    if has_before:
        raw = np.array([r.before for r in rows], dtype=np.float64)
        _before_axes(fig.add_subplot(grid[1]), raw, scale.coarser(raw * scale.factor), "raw mean", ticks)
    write_png(fig, path)


def segment_figure(
    path: str,
    values: FloatArray,
    clock: FloatArray | None,
    seg: Segmentation,
    files: dict[int, str],
    *,
    title: str = "",
) -> None:
    """``segment --plot``: the log's three axes against time, each still block shaded and
    labelled with its face (kept: green, with the file it goes to; dropped: grey, with why),
    and below it the rolling standard deviation the blocks were found by, with the threshold."""
    data = checked_array(values, "log readings", (-1, 3))
    n = data.shape[0]
    if n == 0:
        raise InputError("no readings to plot")
    if clock is not None:
        t, xlabel = checked_array(clock, "log times", (n,)), "time (s)"
    elif seg.period is not None:
        t, xlabel = np.arange(n, dtype=np.float64) * seg.period, "time (s)"
    else:
        t, xlabel = np.arange(n, dtype=np.float64), "sample"
    fig = new_figure(width=14.0, height=7.0, title=title)
    grid = fig.add_gridspec(2, 1, height_ratios=[3, 1])
    top = fig.add_subplot(grid[0])
    bottom = fig.add_subplot(grid[1], sharex=top)
    for j in range(3):
        tx, ty = _envelope(t, data[:, j])
        top.plot(tx, ty, color=_AXES[j], linewidth=0.8)
    spread = rolling_std(data, max(2, seg.window)) if n > 1 else np.zeros(1)
    tx, ty = _envelope(t, spread)
    bottom.plot(tx, ty, color="black", linewidth=0.8, label="rolling standard deviation")
    if seg.threshold is not None:
        bottom.axhline(
            seg.threshold, color=_LIMIT, linestyle="--", linewidth=1.2, label=f"threshold {seg.threshold:.3g}"
        )
    top.set_xlim(float(t[0]), float(t[-1]) if n > 1 else float(t[0]) + 1.0)
    low, high = top.get_ylim()
    top.set_ylim(low, high + 0.14 * (high - low))  # room for the labels above the data
    half = float(np.median(np.diff(t))) / 2 if n > 1 else 0.5  # a reading stands for its sample period
    for block in seg.blocks:
        _shade((top, bottom), block, t, half, files.get(block.number))
    kept = len(seg.kept)
    top.set_title(
        f"{len(seg.blocks)} still blocks, {kept} kept"
        + (f" ({seg.dropped_counts()} dropped)" if kept < len(seg.blocks) else ""),
        fontsize="medium",
    )
    top.set_ylabel("raw reading")
    top.grid(alpha=0.3)
    top.tick_params(labelbottom=False)
    bottom.set_yscale("symlog" if float(np.min(spread)) <= 0 else "log")
    bottom.set_ylabel("rolling std")
    bottom.set_xlabel(xlabel)
    bottom.grid(alpha=0.3)
    _segment_legend(fig, seg)
    write_png(fig, path)


def _segment_legend(fig: Figure, seg: Segmentation) -> None:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles: list[Artist] = [
        Line2D([], [], color=c, linewidth=1.5, label=axis) for c, axis in zip(_AXES, "xyz", strict=True)
    ]
    handles.append(Patch(color=_KEPT, alpha=0.3, label="still block, kept (its face; the file it goes to)"))
    if len(seg.kept) < len(seg.blocks):
        handles.append(Patch(color=_DROPPED, alpha=0.6, label="still block, dropped"))
    handles.append(Line2D([], [], color="black", linewidth=1, label="rolling standard deviation"))
    if seg.threshold is not None:
        handles.append(Line2D([], [], color=_LIMIT, linestyle="--", label=f"threshold {seg.threshold:.3g}"))
    fig.legend(handles=handles, loc="outside lower center", ncols=len(handles), fontsize="small", frameon=False)


def _shade(axes: tuple[Axes, Axes], block: Block, t: FloatArray, half: float, file: str | None) -> None:
    """A block's span on both axes; a kept block labelled at the top with its face (? where it
    rests on none) and, where there is room, the file it goes to."""
    from matplotlib.transforms import blended_transform_factory

    top, bottom = axes
    first, last = float(t[block.first]) - half, float(t[min(block.last, t.size - 1)]) + half
    colour, alpha = (_KEPT, 0.18) if block.kept else (_DROPPED, 0.45)
    for ax in (top, bottom):
        ax.axvspan(first, last, color=colour, alpha=alpha, linewidth=0)
    if not block.kept:  # the title counts the dropped blocks and why
        return
    low, high = top.get_xlim()
    room = (last - first) / (high - low) * _PLOT_PIXELS  # the block's width in pixels, about
    where = blended_transform_factory(top.transData, top.transAxes)
    pad = 0.012 * (high - low)  # a label at the log's very edge stays whole
    middle = min(max((first + last) / 2, low + pad), high - pad)
    face = block.face or "?"
    top.text(middle, 0.985, face, transform=where, ha="center", va="top", fontsize="small", fontweight="bold")
    name = (file or "").removesuffix(".csv")
    if name and room > _CHAR_PIXELS * len(name):
        top.text(middle, 0.935, name, transform=where, ha="center", va="top", fontsize="x-small", color="#444444")


def _envelope(t: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
    """At most LOG_COLUMNS columns, each drawn from its lowest to its highest reading, so that a
    spike in a long log stays in the picture."""
    n = y.size
    if n <= 2 * LOG_COLUMNS:
        return t, y
    edges = np.linspace(0, n, LOG_COLUMNS + 1).round().astype(np.intp)
    low = np.minimum.reduceat(y, edges[:-1])
    high = np.maximum.reduceat(y, edges[:-1])
    tt = np.repeat(t[edges[:-1]], 2)
    yy = np.stack([low, high], axis=1).ravel()
    return tt, yy
