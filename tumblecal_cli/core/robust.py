"""Fits that outliers cannot bend: a trimmed refit around any fit of a magnitude model, and the
stretches it leaves out (numpy only).

A magnitude fit (sphere, ellipsoid, min/max over a turned capture; later a gyroscope's known
rates) minimises ``sum (|M (raw - b)| - reference)^2``: least squares, so two glitch rows at ten
times the field move the centre far enough that the directions about it miss a face (a false
coverage refusal), and still stretches in a disturbed field (a steel desk, 1.2-1.4 times the
field) bend a gain by several percent and PASS. The rule here (a trimmed refit, iterated):

1. **Screen**: the distance of every sample from the coordinate-wise median of the samples; a
   sample whose distance is more than ``SCREEN_FACTOR`` times the median distance, or less than
   its reciprocal, is not a reading of this field (a glitch, a dropped-out zero). Nothing else is
   judged before a fit.
2. **Fit** the samples kept; take every sample's residual ``|M (raw - b)| - reference``.
3. **Trim**: a sample whose |residual| is beyond ``max(K_SIGMA · s, FLOOR · reference)`` is left
   out, ``s`` the residuals' robust spread among those kept (the MAD × 1.4826). The floor keeps
   a clean capture whole: a model that does not fit exactly (an ellipsoid's small non-linearity,
   a capture's own noise at 1 % of the field) leaves no sample out, and the fit is then exactly
   the plain least squares one. Refit, and repeat until the samples kept do not change (at most
   ``ROUNDS``).

``TrimmedFit`` reports what was left out as stretches of consecutive samples (first, last, and the
worst |residual| there as a share of the reference); coverage is judged by the caller on the
samples kept, about the fitted centre. Measured in tests/test_robust.py: synthetic captures with
0-20 % outliers (glitches, disturbed stretches) stay within their stated uncertainty of the truth
while the plain fit does not; a clean capture's fit is the plain fit to the last digit.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np

from tumblecal_cli.core.arrays import BoolArray, FloatArray
from tumblecal_cli.core.outliers import MAD_NORMAL

#: A sample further than this many times the median distance from the samples' median (or nearer
#: than its reciprocal) is screened out before any fit: not a reading of this field.
SCREEN_FACTOR = 3.0
#: A sample whose |residual| is beyond this many robust sigmas ...
K_SIGMA = 6.0
#: ... and beyond this share of the reference is left out of the fit.
FLOOR = 0.05
#: Refits at most.
ROUNDS = 8

F = TypeVar("F")


@dataclass(frozen=True)
class LeftOutRun:
    """Consecutive samples left out: the first and last (0-based, among the samples given), and
    the largest |residual| among them as a share of the reference."""

    first: int
    last: int
    worst: float


@dataclass(frozen=True)
class TrimmedFit(Generic[F]):
    """A fit on the samples kept (``kept``), and what was left out: its stretches, the |residual|
    bound (``bound``, output units) and the robust spread it was made from (``scale``)."""

    fit: F
    kept: BoolArray
    stretches: tuple[LeftOutRun, ...]
    bound: float
    scale: float

    @property
    def left_out(self) -> int:
        return int((~self.kept).sum())


@dataclass(frozen=True)
class Outliers:
    """What a fit left out (core.solvers.Fit.outliers): ``count`` of its ``of`` samples, in
    ``stretches``, beyond ``bound`` (output units) made from the robust spread ``scale``."""

    count: int
    of: int
    stretches: tuple[LeftOutRun, ...]
    bound: float
    scale: float


def screen(points: FloatArray) -> BoolArray:
    """The samples whose distance from the samples' coordinate-wise median is within
    SCREEN_FACTOR of the median distance (rule 1); all of them when that leaves too few."""
    finite: BoolArray = np.asarray(np.isfinite(points).all(axis=1))
    if finite.sum() < 3:
        return finite
    centre = np.median(points[finite], axis=0)
    distance = np.linalg.norm(points - centre, axis=1)
    typical = float(np.median(distance[finite]))
    if not typical > 0:
        return finite
    with np.errstate(invalid="ignore"):
        ok: BoolArray = np.asarray(
            finite & (distance <= SCREEN_FACTOR * typical) & (distance >= typical / SCREEN_FACTOR)
        )
    return ok if ok.sum() >= 0.5 * finite.sum() else finite


def bounds(res: FloatArray, kept: BoolArray, reference: float) -> tuple[BoolArray, float, float]:
    """Rule 3 on residuals ``res``: the samples within the bound (its spread taken over ``kept``),
    the bound, and that spread."""
    inside = res[kept & np.isfinite(res)]
    scale = MAD_NORMAL * float(np.median(np.abs(inside - np.median(inside)))) if len(inside) else np.inf
    bound = max(K_SIGMA * scale, FLOOR * reference)
    with np.errstate(invalid="ignore"):
        within: BoolArray = np.asarray(np.isfinite(res) & (np.abs(res) <= bound))
    return within, float(bound), float(scale)


def trimmed(
    points: FloatArray,
    reference: float,
    fit: Callable[[FloatArray], F],
    residuals: Callable[[F, FloatArray], FloatArray],
    kept: BoolArray | None = None,
) -> TrimmedFit[F]:
    """``fit`` on the samples a trimmed refit keeps (module docstring): ``fit(kept_points)`` makes a
    fit, ``residuals(fit, points)`` every sample's |M (raw - b)| - reference under it; ``kept``
    the samples to start from (default: :func:`screen`'s)."""
    kept = screen(points) if kept is None else kept
    result = fit(points[kept])
    bound = scale = np.inf
    for _ in range(ROUNDS):
        now, bound, scale = bounds(residuals(result, points), kept, reference)
        if np.array_equal(now, kept):
            break
        kept = now
        result = fit(points[kept])
    res = residuals(result, points)
    return TrimmedFit(result, kept, _stretches(~kept, res, reference), float(bound), float(scale))


def _stretches(out: BoolArray, res: FloatArray, reference: float) -> tuple[LeftOutRun, ...]:
    """The runs of ``out``, each with its worst |residual| / reference (inf: not a finite reading)."""
    if not out.any():
        return ()
    edges = np.flatnonzero(np.diff(np.concatenate([[0], out.astype(np.int8), [0]])))
    worst = np.where(np.isfinite(res), np.abs(res), np.inf) / reference
    return tuple(
        LeftOutRun(int(a), int(b) - 1, float(worst[a:b].max())) for a, b in zip(edges[::2], edges[1::2], strict=True)
    )
