"""A log's clock: the seconds per sample its time column gives, its gaps, and whether it was
stamped on arrival, in bursts. numpy only.

Part of the core layer (docs/development.md). The rules (docs/reference/csv.md, *Sample rate*):

- **steps**: the differences of consecutive times, in seconds.
- **regular or bursty.** A logger that stamps samples as they reach the host (a sensor read over
  a serial link) stamps them in bursts: a few samples a millisecond apart, then a pause. Its
  median step is the spacing within a burst, not the sample period (seen: a median of 2 ms on a
  true 99.3 Hz, every duration 5x off). The clock's *local* mean step is the median, over windows
  of ``WINDOW`` steps, of each window's mean step: a window holds many bursts, so bursts average
  out, and a gap (the logger paused) moves only the one window it falls in. A clock whose median
  and local mean differ by more than ``DISAGREE`` is bursty; otherwise it is regular. A clock too
  short for ``MIN_WINDOWS`` windows of ``SHORT_WINDOW`` steps, or a coarse one (steps of 0, ``coarse``: a clock ticking
  slower than the samples, which callers name with its own warning) is taken as regular.
- **gaps.** A step over ``GAP_FACTOR`` median steps on a regular clock (segment's rule, kept:
  its blocks never span one); on a bursty clock a step over ``BURSTY_GAP_FACTOR`` times its
  typical pause (the median of the steps longer than the local mean): a host's pauses vary with
  its scheduler, and three of the median pause would take the long tail of ordinary pauses for
  gaps, where the samples are all there.
- **the period.** A regular clock's is its median step, as it always was, so that the windows,
  durations and calibrations of a regular log do not change by a digit; a bursty clock's is the
  mean of its steps that are not gaps: the span the samples cover, less the gaps, over the steps
  (``(n - 1 - gaps) / (span - gap time)`` samples a second). Gaps are left out so that a logger
  that paused (an hour's gap in ten minutes of data) does not lower the rate of the samples it
  did log; the local mean is not used as the period because it is a median of windows, which a
  clock that changes its bursts over the log would bias, where the mean of the steps is the
  samples' own count over their time.
- **jitter**: the standard deviation of the steps that are not gaps (seconds).

``judge`` takes the steps of a whole log (or its first block) and the caller's median step (each
caller keeps the median rule it always had: nearest rank, or numpy's); ``Clock.tally`` counts
further blocks of steps into it, for a capture streamed block by block.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from tumblecal_cli.core.arrays import FloatArray, IntArray
from tumblecal_cli.errors import said

#: Steps per window of the local mean step, and the fewest windows that judge a clock bursty.
WINDOW = 64
MIN_WINDOWS = 8
#: A log too short for MIN_WINDOWS windows of WINDOW steps (a capture of a few seconds, or the
#: part --start/--end pick) is judged on MIN_WINDOWS windows as long as it has steps for, each of
#: SHORT_WINDOW steps at least (a burst is a handful of samples), so that it is not taken as
#: regular for its length alone; fewer steps than one window of that: regular.
SHORT_WINDOW = 8
#: The median step and the local mean step differ by more than this (of the local mean): bursty.
DISAGREE = 0.10
#: A step this many median steps is a gap on a regular clock ...
GAP_FACTOR = 3.0
#: ... and this many typical pauses on a bursty one.
BURSTY_GAP_FACTOR = 5.0
#: Steps summed at a time (the temporaries stay small on a log of millions).
CHUNK = 1 << 20
#: More time steps of 0 than this share, and steps shorter on average than the median one by
#: more than SHORTFALL (a logger that stamps on arrival repeats a stamp now and then, and its
#: steps still average the median), and the clock is not the samples' (coarse).
ZERO_STEPS = 0.01
SHORTFALL = 0.05


@dataclass(frozen=True)
class Clock:
    """What a time column says of its samples (the module docstring), in seconds: the median
    step, the local mean step, whether bursty, the bound above which a step is a gap, and the
    steps counted so far (those that are not gaps: how many, their sum and sum of squares; the
    gaps: how many and the time in them)."""

    median: float
    local: float
    bursty: bool
    bound: float
    steps: int = 0
    seconds: float = 0.0
    squares: float = 0.0  # about the median: the digits of an epoch clock's steps are kept
    gaps: int = 0
    gap_seconds: float = 0.0

    @property
    def mean(self) -> float:
        """The mean of the steps that are not gaps (the median when none is counted)."""
        return self.seconds / self.steps if self.steps else self.median

    @property
    def jitter(self) -> float:
        """The standard deviation of the steps that are not gaps."""
        if not self.steps:
            return 0.0
        off = self.seconds / self.steps - self.median
        return math.sqrt(max(self.squares / self.steps - off * off, 0.0))

    @property
    def period(self) -> float:
        """Seconds per sample: the median step of a regular clock, the mean of a bursty one's."""
        return self.mean if self.bursty else self.median

    def tally(self, steps: FloatArray) -> tuple[Clock, IntArray]:
        """This clock with ``steps`` counted too, and the position among them of each gap."""
        at = np.flatnonzero(steps > self.bound).astype(np.int64)
        held = steps[at]
        total, squares = 0.0, 0.0
        for first in range(0, steps.size, CHUNK):  # a temporary of CHUNK steps, not of the log's
            centred = steps[first : first + CHUNK] - self.median
            total += float(centred.sum())
            squares += float(np.square(centred, out=centred).sum())
        off = held - self.median
        counted = replace(
            self,
            steps=self.steps + int(steps.size - at.size),
            seconds=self.seconds + total - float(off.sum()) + self.median * (steps.size - at.size),
            squares=self.squares + squares - float((off * off).sum()),
            gaps=self.gaps + int(at.size),
            gap_seconds=self.gap_seconds + float(held.sum()),
        )
        return counted, at


def local_step(spans: FloatArray) -> float | None:
    """The local mean step from the time each whole window of WINDOW steps spans (from the
    first step on): the median of those over WINDOW; None with fewer than MIN_WINDOWS."""
    if spans.size < MIN_WINDOWS:
        return None
    return float(np.median(spans)) / WINDOW


def window_spans(steps: FloatArray) -> FloatArray:
    """The time each whole window of WINDOW steps spans, the first from the first step."""
    k = steps.size // WINDOW
    spans: FloatArray = steps[: k * WINDOW].reshape(k, WINDOW).sum(axis=1)
    return spans


def coarse(zero_share: float, median: float, mean: float) -> bool:
    """Whether a clock does not advance with its samples: steps of 0 in more than ZERO_STEPS of
    them, and a median step of 0 or a mean step short of the median by more than SHORTFALL (a
    3 kHz log stamped in whole milliseconds; one that stops)."""
    return zero_share > ZERO_STEPS and (not median > 0 or mean < (1 - SHORTFALL) * median)


def classify(median: float, local: float | None, zero_share: float) -> bool:
    """Whether a clock is bursty: its median and local mean step differ by more than DISAGREE
    of the local mean (and it is long enough to tell, and not coarse)."""
    if local is None or not median > 0 or not local > 0:
        return False
    if coarse(zero_share, median, local):
        return False
    return abs(median - local) > DISAGREE * local


def bound_of(steps: FloatArray, median: float, local: float | None, bursty: bool) -> float:
    """The longest step that is not a gap (the module docstring)."""
    if not bursty or local is None:
        return GAP_FACTOR * median
    pauses = steps[steps > local]
    typical = float(np.median(pauses)) if pauses.size else local
    return BURSTY_GAP_FACTOR * max(typical, local)


def judge(steps: FloatArray, median: float) -> tuple[Clock, IntArray]:
    """The clock of ``steps`` (seconds, the whole log's or its first block's) whose median step is
    ``median`` (the caller's rule), with those steps counted, and the position of each gap
    among them."""
    local = local_step(window_spans(steps))
    if local is None and steps.size >= MIN_WINDOWS * SHORT_WINDOW:
        width = steps.size // MIN_WINDOWS
        local = float(np.median(steps[: MIN_WINDOWS * width].reshape(MIN_WINDOWS, width).sum(axis=1))) / width
    zero_share = float(np.count_nonzero(steps == 0)) / steps.size if steps.size else 0.0
    bursty = classify(median, local, zero_share)
    base = Clock(median, local if local is not None else median, bursty, bound_of(steps, median, local, bursty))
    return base.tally(steps)


def note(clock: Clock, name: str, rate: float | None) -> str | None:
    """The note a bursty clock gets: its median and mean step, the rate used, and --rate."""
    if not clock.bursty:
        return None
    used = f"{1.0 / clock.period:.6g} Hz" if rate is None else f"{rate:.6g} Hz"
    return (
        f"{name}: the time column's steps are bursty (samples stamped on arrival?): median "
        f"{clock.median * 1e3:.3g} ms ({1.0 / clock.median:.4g} Hz), mean {clock.mean * 1e3:.3g} ms; the rate used is "
        f"{used}, from the samples over the time they span{_gaps(clock)}; {said('clock.bursty')}"
    )


def _gaps(clock: Clock) -> str:
    if not clock.gaps:
        return ""
    return f" less {clock.gaps} gap{'s' if clock.gaps > 1 else ''} ({clock.gap_seconds:.3g} s)"


def rate_of(clock: Clock) -> float | None:
    """Samples a second by the clock's period, to 9 digits (the period's float noise, not the rate's)."""
    return float(f"{1.0 / clock.period:.9g}") if clock.period > 0 else None


def as_dict(clock: Clock) -> dict[str, object]:
    """The clock in a --json object: the rate it gives and how (from the median or the mean
    step), both steps, the jitter, the gaps."""
    return {
        "rate": rate_of(clock),
        "from": "mean step" if clock.bursty else "median step",
        "bursty": clock.bursty,
        "median_step_s": clock.median,
        "mean_step_s": clock.mean,
        "jitter_s": clock.jitter,
        "gaps": clock.gaps,
        "gap_s": clock.gap_seconds,
    }
