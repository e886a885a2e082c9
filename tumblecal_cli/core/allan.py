"""Allan deviation of a still capture, and the noise figures read off it. numpy only.

Part of the core layer (docs/development.md): pure numbers, no files, no terminal. Sources:
IEEE Std 952-1997 (Annex C, "Allan variance method of data reduction", cited as IEEE 952 C),
and Riley 2008, "Handbook of Frequency Stability Analysis", NIST SP 1065 (cited as SP 1065).
Every work cited here is listed in docs/sources.md.

**The deviation.** A sensor's rate-like output ``y`` (one sample every ``tau0``) is integrated
to ``S_k = sum_{j<k} y_j`` (``S_0 = 0``, N = n + 1 points: the "phase" of SP 1065), and the
overlapping Allan variance at ``tau = m tau0`` is (SP 1065 eq. 11, the phase form divided by
``tau0``)::

    sigma^2(m tau0) = sum_{i=0}^{N-2m-1} (S_{i+2m} - 2 S_{i+m} + S_i)^2 / (2 m^2 (N - 2m))

``AllanStream`` computes it block by block in memory that does not grow with the capture:

- every ``m <= EXACT_MAX`` uses every overlapping term, from one shared history of the last
  ``2 * EXACT_MAX`` values of S (a few MB): equal to the textbook estimator (and to
  allantools' ``oadev``, which tests pin to 1e-9 relative);
- a larger ``m`` (a cluster time past 2**18 samples: 44 minutes at 100 Hz) keeps S only every
  ``d = m / WINDOW`` samples (``m`` is rounded to a multiple of ``d``), ``2 * WINDOW + 1`` values
  each, and sums the terms that start on that grid: ``WINDOW`` start points per cluster instead
  of ``m``. Terms that start within ``m / 1024`` of each other are nearly the same term, so the
  estimate's spread is the overlapping one's to well under a percent; its value is no longer
  the textbook sum, and tests check it against it to a few percent.

**Gaps.** A capture whose clock has a gap (``core.clock``: the logger paused) is fed as runs
of samples (``restart`` between): each cluster's terms lie within one run, the sum above taken
over each run and the runs' terms pooled, so that no term spans time the samples do not cover.
A point's EDF is then that of ``terms + 2m`` phase points (one run's count, the pooled terms
as if from one run: fewer terms, a wider interval).

The data's first-block mean is removed before the sum (the variance does not change: a
constant adds a straight line to S, which the second difference cancels) so that S stays small
and the differences keep their digits on a day-long capture.

**Confidence.** Each point's equivalent degrees of freedom (EDF) is SP 1065's simple
approximation for the overlapping Allan variance (SP 1065 section 5.3.3, after Howe, Allan and
Barnes 1981), for the power-law noise the curve's local slope shows: white FM (slope -1/2,
the sensor's white noise), flicker FM (0, the bias-instability floor) or random-walk FM (+1/2).
The interval is the chi-squared one, ``sigma^2 * edf / chi2_{p}(edf)`` (SP 1065 eq. 39), with
the chi-squared quantiles from the Wilson-Hilferty approximation (Abramowitz and Stegun 1964,
26.4.17; within 1 % of the exact quantile for edf >= 3), at ``LEVEL`` (95 %).

**Figures** (IEEE 952 C, table C.1 and figure C.2):

- noise density N (angle or velocity random walk): the -1/2 slope, ``sigma(tau) = N / sqrt(tau)``,
  read at tau = 1 s: the log-mean of ``sigma_k sqrt(tau_k)`` over the run of points on that
  slope, each weighted by its EDF;
- bias instability B: the flat minimum, ``B = sigma_min / 0.664`` (0.664 = sqrt(2 ln 2 / pi),
  IEEE 952 C.3); determined only when the curve at its longest usable tau lies significantly
  above the white-noise line (the floor is shown) and the minimum is not the last point;
- random walk K (rate or acceleration random walk): the +1/2 slope, ``sigma(tau) = K sqrt(tau / 3)``,
  read at tau = 3 s, over a run of points on that slope that rises significantly (the top of
  the run above the bottom's confidence interval).

A figure the curve does not show is None ("not determined"), never the last point's value.
Each figure's uncertainty is the half-width of the 95 % interval of the point it is read from
(for a run: the best point's, combined with the run's own spread).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from tumblecal_cli.core.arrays import FloatArray, IntArray, median

#: Cluster sizes up to this use every overlapping term (equal to the textbook estimator).
EXACT_MAX = 2**18
#: Above EXACT_MAX: this many start points per cluster length.
WINDOW = 1024
#: Rows handled at once (larger blocks are split): bounds the temporary arrays.
CHUNK = 2**16
#: The confidence level of the intervals and of the figures' uncertainty.
LEVEL = 0.95
#: IEEE 952 C.3: a flicker floor sits at sqrt(2 ln 2 / pi) = 0.664 times the bias instability.
BIAS_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)
#: How far a segment's slope may be from -1/2 or +1/2 and still count as on it.
SLOPE_TOLERANCE = 0.15
#: Points with fewer EDF than this are drawn but not read from (their slope is noise).
MIN_EDF = 1.0
AXES = "xyz"


def cluster_sizes(
    per_octave: int = 1, largest: int = 2**40, exact_max: int = EXACT_MAX, window: int = WINDOW
) -> list[int]:
    """The averaging factors m (tau = m tau0): ``per_octave`` a power of two apart
    (1: 1, 2, 4, 8 ...), each above ``exact_max`` rounded to a multiple of its stride."""
    if per_octave < 1:
        raise ValueError("per_octave must be at least 1")
    out: set[int] = set()
    k = 0
    while True:
        m = round(2.0 ** (k / per_octave))
        if m > largest:
            break
        if m > exact_max:
            d = stride(m, exact_max, window)
            m = max(d, round(m / d) * d)
        out.add(m)
        k += 1
    return sorted(out)


def stride(m: int, exact_max: int = EXACT_MAX, window: int = WINDOW) -> int:
    """The spacing of the start points used for cluster size m (1: every one)."""
    if m <= exact_max:
        return 1
    return 1 << max(0, math.floor(math.log2(m / window)))


@dataclass
class _Strided:
    """One large cluster size: S every ``d`` samples, the last 2 * (m / d) of them."""

    m: int
    d: int
    tail: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))


class AllanStream:
    """The overlapping Allan variance of (n, 3) samples fed block by block (``add``), in memory
    that does not grow with n (module docstring). ``result(rate)`` gives the curve so far."""

    def __init__(
        self, per_octave: int = 1, *, exact_max: int = EXACT_MAX, window: int = WINDOW, largest: int = 2**40
    ) -> None:
        self.made = (per_octave, exact_max, window, largest)  # (``fresh``)
        self.sizes = cluster_sizes(per_octave, largest, exact_max, window)
        self.strides = np.array([stride(m, exact_max, window) for m in self.sizes], dtype=np.int64)
        self.runs = 1  # runs of samples between gaps in time (restart)
        self.exact = [m for m in self.sizes if stride(m, exact_max, window) == 1]
        self.strided = [_Strided(m, stride(m, exact_max, window)) for m in self.sizes if m not in self.exact]
        self.keep = 2 * max(self.exact)  # history values of S the exact sizes need
        # S, axis by axis (each axis's values contiguous), with room for as many more as it keeps: the
        # history is moved back to the start once that room is used, not once a chunk
        self.buffer = np.zeros((3, self.keep + max(CHUNK, self.keep) + 1))
        self.scratch = np.empty((3, CHUNK))  # one size's second differences of a chunk
        self.filled = 1  # buffer[0] is S_0 = 0
        self.start = 0  # global index of buffer[0]
        self.n = 0  # samples so far
        self.offset: FloatArray | None = None
        self.sums = np.zeros((len(self.sizes), 3))
        self.terms = np.zeros(len(self.sizes), dtype=np.int64)
        for s in self.strided:
            s.tail = np.zeros((1, 3))  # S_0, on every grid

    def fresh(self) -> AllanStream:
        """A stream of the same cluster sizes with nothing fed yet."""
        per_octave, exact_max, window, largest = self.made
        return AllanStream(per_octave, exact_max=exact_max, window=window, largest=largest)

    def add(self, samples: FloatArray) -> None:
        """Feed the next samples, (b, 3), in order."""
        for first in range(0, samples.shape[0], CHUNK):
            self._add(np.asarray(samples[first : first + CHUNK], dtype=np.float64))

    def restart(self) -> None:
        """The samples fed next follow a gap in time: no cluster spans it (module docstring)."""
        self.buffer[:, 0] = 0.0  # S starts again (a constant added to S changes no term)
        self.filled = 1
        self.start = 0
        for s in self.strided:
            s.tail = np.zeros((1, 3))
        self.runs += 1

    def _add(self, y: FloatArray) -> None:
        c = y.shape[0]
        if c == 0:
            return
        if self.offset is None:
            self.offset = y.mean(axis=0)
        if self.filled + c > self.buffer.shape[1]:  # keep the last `keep` values of S
            drop = self.filled - self.keep
            self.buffer[:, : self.keep] = self.buffer[:, drop : self.filled]
            self.start += drop
            self.filled = self.keep
        b, p0 = self.buffer, self.filled
        new = b[:, p0 : p0 + c]
        np.cumsum((y - self.offset).T, axis=1, out=new)
        new += b[:, p0 - 1 : p0]  # S_{j} = S_{p0-1} + the running sum since
        self.filled += c
        end = p0 + c
        for k, m in enumerate(self.exact):
            lo = max(p0, 2 * m)  # S_{j-2m} is held: from global 0, or the `keep` values kept
            if lo >= end:
                continue
            d = self.scratch[:, : end - lo]  # S_{j} - 2 S_{j-m} + S_{j-2m}, SP 1065 eq. 11
            np.multiply(b[:, lo - m : end - m], 2.0, out=d)
            np.subtract(b[:, lo:end], d, out=d)
            d += b[:, lo - 2 * m : end - 2 * m]
            self.sums[k] += np.square(d, out=d).sum(axis=1)  # along each axis's contiguous values
            self.terms[k] += end - lo
        g0 = self.start + p0  # global index of the first new S value
        offset = len(self.exact)
        for j, s in enumerate(self.strided):
            first = -(-g0 // s.d) * s.d  # the first grid index at or after g0
            if first > self.start + end - 1:
                continue
            grid = b[:, first - self.start : end : s.d].T
            t = np.concatenate([s.tail, grid])
            w = s.m // s.d
            if t.shape[0] > 2 * w:
                d = t[2 * w :] - 2.0 * t[w:-w] + t[: -2 * w]
                self.sums[offset + j] += (d * d).sum(axis=0)
                self.terms[offset + j] += d.shape[0]
            s.tail = t[-2 * w :].copy()
        self.n += c

    def result(self, rate: float) -> Curve:
        """The curve so far: sizes with at least one term."""
        used = self.terms > 0
        m = np.array(self.sizes, dtype=np.int64)[used]
        var = self.sums[used] / (2.0 * (m.astype(np.float64) ** 2)[:, None] * self.terms[used][:, None])
        points = None
        if self.runs > 1:  # the phase points each size's pooled terms stand for (one run: n + 1)
            points = self.terms[used] * self.strides[used] + 2 * m
        return Curve(rate=rate, samples=self.n, m=m, adev=np.sqrt(var), terms=self.terms[used].copy(), points=points)


def oadev(samples: FloatArray, m: Sequence[int]) -> FloatArray:
    """The textbook overlapping Allan deviation of (n, 3) samples at cluster sizes ``m``, all in
    memory (SP 1065 eq. 11): the reference the stream is tested against."""
    y = np.asarray(samples, dtype=np.float64)
    s = np.concatenate([np.zeros((1, 3)), np.cumsum(y - y.mean(axis=0), axis=0)])
    out = np.empty((len(m), 3))
    for k, mk in enumerate(m):
        d = s[2 * mk :] - 2.0 * s[mk:-mk] + s[: -2 * mk]
        out[k] = np.sqrt((d * d).sum(axis=0) / (2.0 * mk * mk * d.shape[0]))
    return out


# -- confidence ------------------------------------------------------------------------------


def edf(n_phase: int, m: int, slope: float) -> float:
    """Equivalent degrees of freedom of an overlapping Allan variance point (SP 1065 section
    5.3.3, simple approximations): ``n_phase`` phase points N = n + 1, cluster size m, and the
    curve's local log-log slope choosing the noise type (nearest of -1/2, 0, +1/2)."""
    n, m_ = float(n_phase), float(m)
    if n - 2 * m_ < 1:
        return 0.0
    if slope < -0.25:  # white FM
        value = (3.0 * (n - 1) / (2.0 * m_) - 2.0 * (n - 2) / n) * 4.0 * m_ * m_ / (4.0 * m_ * m_ + 5.0)
    elif slope < 0.25:  # flicker FM
        value = 2.0 * (n - 2) / (2.3 * n - 4.9) if m == 1 else 5.0 * n * n / (4.0 * m_ * (n + 3.0 * m_))
    else:  # random-walk FM
        value = (n - 2) / m_ * ((n - 1) ** 2 - 3.0 * m_ * (n - 1) + 4.0 * m_ * m_) / ((n - 3) ** 2)
    return max(float(value), 0.0)


def chi2_quantile(p: float, dof: float) -> float:
    """The p-quantile of chi-squared with ``dof`` degrees of freedom, Wilson-Hilferty
    (Abramowitz and Stegun 1964, 26.4.17)."""
    z = _normal_quantile(p)
    h = 2.0 / (9.0 * dof)
    return dof * max(1.0 - h + z * math.sqrt(h), 1e-6) ** 3


def _normal_quantile(p: float) -> float:
    """The standard normal quantile (Acklam's rational approximation, relative error < 1.2e-9)."""
    a = (-3.969683028665376e01, 2.209460984245205e02, -2.759285104469687e02, 1.383577518672690e02,
         -3.066479806614716e01, 2.506628277459239e00)  # fmt: skip
    b = (-5.447609879822406e01, 1.615858368580409e02, -1.556989798598866e02, 6.680131188771972e01,
         -1.328068155288572e01)  # fmt: skip
    c = (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e00, -2.549732539343734e00,
         4.374664141464968e00, 2.938163982698783e00)  # fmt: skip
    d = (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e00, 3.754408661907416e00)
    if p < 0.02425:
        q = math.sqrt(-2.0 * math.log(p))
        return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) / (
            (((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0
        )
    if p > 1.0 - 0.02425:
        return -_normal_quantile(1.0 - p)
    q = p - 0.5
    r = q * q
    return (
        (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5])
        * q
        / (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0)
    )


@dataclass(frozen=True)
class Curve:
    """An Allan deviation curve: cluster sizes ``m`` (k,), deviations ``adev`` (k, 3) in the
    samples' units, the terms each was averaged over, and the capture's rate and length."""

    rate: float
    samples: int
    m: IntArray
    adev: FloatArray
    terms: IntArray
    points: IntArray | None = None  # phase points per size, for its EDF (None: samples + 1; gaps: module docstring)

    @property
    def tau(self) -> FloatArray:
        result: FloatArray = self.m / self.rate
        return result

    def slopes(self) -> FloatArray:
        """(k, 3) local log-log slope at each point (central where it can be)."""
        k = len(self.m)
        if k < 2:
            return np.full((k, 3), -0.5)
        lt = np.log(self.tau)[:, None]
        la = np.log(np.maximum(self.adev, 1e-300))
        result: FloatArray = np.gradient(la, lt[:, 0], axis=0)
        return result

    def edf(self) -> FloatArray:
        """(k, 3) equivalent degrees of freedom of each point."""
        slopes = self.slopes()
        points = [self.samples + 1] * len(self.m) if self.points is None else [int(p) for p in self.points]
        return np.array(
            [[edf(points[k], int(m), float(slopes[k, j])) for j in range(3)] for k, m in enumerate(self.m)]
        ).reshape(len(self.m), 3)

    def interval(self, level: float = LEVEL) -> tuple[FloatArray, FloatArray]:
        """(low, high), each (k, 3): the chi-squared confidence interval of each deviation
        (SP 1065 eq. 39); infinite above where a point has no EDF to speak of."""
        dof = self.edf()
        low = np.empty_like(self.adev)
        high = np.empty_like(self.adev)
        for idx, v in np.ndenumerate(dof):
            if v <= 0.0:
                low[idx], high[idx] = 0.0, math.inf
                continue
            low[idx] = self.adev[idx] * math.sqrt(v / chi2_quantile(0.5 + level / 2.0, v))
            high[idx] = self.adev[idx] * math.sqrt(v / chi2_quantile(0.5 - level / 2.0, v))
        return low, high


# -- the figures -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Figure:
    """One noise figure of one axis; ``value`` None when the curve does not show it."""

    value: float | None
    uncertainty: float | None
    tau: tuple[float, float] | None  # the cluster times (s) it was read from
    why: str = ""  # why it is not determined

    def scaled(self, factor: float) -> Figure:
        if self.value is None or self.uncertainty is None:
            return self
        return Figure(self.value * factor, self.uncertainty * factor, self.tau, self.why)


@dataclass(frozen=True)
class Figures:
    """The three figures of one axis (IEEE 952 C): noise density at 1 s, bias instability,
    random walk at 3 s, in the samples' units (per sqrt(Hz), as is, per s per sqrt(Hz))."""

    noise_density: Figure
    bias_instability: Figure
    random_walk: Figure


NAMES = ("noise_density", "bias_instability", "random_walk")


def figures(curve: Curve) -> list[Figures]:
    """The figures of each axis (module docstring)."""
    dof = curve.edf()
    low, high = curve.interval()
    out = []
    for j in range(3):
        usable = np.flatnonzero(dof[:, j] >= MIN_EDF)
        tau = curve.tau[usable]
        a = curve.adev[usable, j]
        ax = _Axis(tau, a, dof[usable, j], low[usable, j], high[usable, j])
        white = ax.slope_run(-0.5, tau_at=1.0)
        out.append(Figures(white, ax.floor(white), ax.slope_run(0.5, tau_at=3.0)))
    return out


@dataclass(frozen=True)
class _Axis:
    tau: FloatArray
    adev: FloatArray
    dof: FloatArray
    low: FloatArray
    high: FloatArray

    def runs(self, slope: float) -> list[tuple[int, int]]:
        """Runs (first, last point, inclusive) of consecutive segments within SLOPE_TOLERANCE of ``slope``."""
        if self.tau.size < 2 or not (self.adev > 0).all():  # readings that do not change: no slope to read
            return []
        span = np.diff(np.log(self.tau))
        seg = np.diff(np.log(self.adev)) / span
        # a segment is on the slope within SLOPE_TOLERANCE, or within its ends' own scatter
        # (1 sigma of log sigma is about 1 / sqrt(2 edf), SP 1065 section 5.3) where that is wider
        scatter = np.sqrt(0.5 / self.dof[:-1] + 0.5 / self.dof[1:]) / span
        on = np.abs(seg - slope) <= np.maximum(SLOPE_TOLERANCE, scatter)
        runs, k = [], 0
        while k < on.size:
            if not on[k]:
                k += 1
                continue
            first = k
            while k < on.size and on[k]:
                k += 1
            runs.append((first, k))
        return runs

    def slope_run(self, slope: float, tau_at: float) -> Figure:
        """The figure of a +-1/2 slope: the coefficient of ``sigma = C (tau / tau_at)^slope`` fitted
        on the longest run of points on that slope (IEEE 952 C, table C.1)."""
        name = "white-noise (-1/2)" if slope < 0 else "random-walk (+1/2)"
        runs = self.runs(slope)
        if slope > 0:  # it must rise by more than the points' own scatter: the parts of each run that do
            runs = [
                (i, j) for a, b in runs for i in range(a, b) for j in range(i + 1, b + 1) if self.low[j] > self.high[i]
            ]
        if not runs:
            return Figure(None, None, None, f"the curve shows no {name} slope")
        first, last = max(runs, key=lambda r: (self.tau[r[1]] / self.tau[r[0]], -r[0]))
        idx = np.arange(first, last + 1)
        per_point = np.log(self.adev[idx]) - slope * np.log(self.tau[idx] / tau_at)  # log C at each point
        w = self.dof[idx]
        centre = float((w * per_point).sum() / w.sum())
        spread = float(np.sqrt((w * (per_point - centre) ** 2).sum() / w.sum()))
        best = int(idx[np.argmax(w)])
        rel = max(self.high[best] / self.adev[best] - 1.0, 1.0 - self.low[best] / self.adev[best])
        value = math.exp(centre)
        return Figure(value, value * math.hypot(rel, 2.0 * spread), (float(self.tau[first]), float(self.tau[last])))

    def floor(self, white: Figure) -> Figure:
        """The bias instability: the curve's minimum over 0.664 (IEEE 952 C.3), when it is shown."""
        if self.tau.size < 3:
            return Figure(None, None, None, "too few points")
        k = int(np.argmin(self.adev))
        if not self.adev[k] > 0:
            return Figure(None, None, None, "the readings do not change: no noise to measure")
        last = self.tau.size - 1
        if k == last:
            return Figure(None, None, None, "the curve is still falling at its longest cluster time")
        if white.value is not None:
            line = white.value / np.sqrt(self.tau[last])  # where white noise alone would be
            if not self.low[last] > line:
                return Figure(None, None, None, "the curve has not left the white-noise line")
        value = float(self.adev[k]) / BIAS_FACTOR
        rel = max(self.high[k] / self.adev[k] - 1.0, 1.0 - self.low[k] / self.adev[k])
        return Figure(value, value * rel, (float(self.tau[k]), float(self.tau[k])))


# -- a capture that moved --------------------------------------------------------------------

#: A step between consecutive block means this many times their spread (without the largest)
#: is a move: a Gaussian difference that large has odds below 1e-20.
STEP_FACTOR = 10.0
#: A change from the first block to the last this many times what a random walk with the
#: blocks' own increments would reach in as many steps is a drift, not noise.
DRIFT_FACTOR = 5.0
#: Block means that jump from one block to the next (rms) by this many times the noise within a
#: block (the median block's standard deviation) are a capture that moves throughout: still, they
#: jump by about sqrt(2 / samples per block) of it (0.1-0.2 on real still captures). Noise filtered
#: far below a block's length changes smoothly, and a smooth change jumps by up to sqrt(12) of the
#: spread it makes within a block: 3.0-3.4 for two poles at 0.2 Hz or 0.15 Hz, 4-5 at 0.05 Hz. Real
#: logs tumbled by hand gave 15-330 (one of slow continuous motion, CK-Explorer's, 5-6: not caught).
#: Noise filtered harder still (two poles at 0.05 Hz) reaches 17, so motion is also asked to come
#: in bursts: the rms jump over TAIL_FACTOR times the median one (1.4-1.8 for filtered noise, whose
#: jumps are alike; 3-1900 on the hand-tumbled logs, whose turns stand out of the still blocks).
MOTION_FACTOR = 8.0
TAIL_FACTOR = 2.5
#: Fewer blocks than this judge nothing (the spread of a handful of differences is no yardstick).
MIN_BLOCKS = 8


@dataclass(frozen=True)
class Moved:
    """Why a capture is not still: the axis, what was measured and its bound, and a sentence."""

    axis: str
    kind: str  # "step", "drift" or "moving"
    value: float
    bound: float
    at_sample: int | None  # a step: the first sample of the block after it

    def message(self) -> str:
        if self.kind == "step":
            return (
                f"block means jump by {self.value:.3g} on {self.axis} near sample {self.at_sample}, "
                f"{self._times(STEP_FACTOR, 'the spread of its block means')} (not a still capture)"
            )
        if self.kind == "moving":
            return (
                f"block means jump by {self.value:.3g} (rms) on {self.axis} from one block to the next, "
                f"{self._times(MOTION_FACTOR, 'the noise within a block', '.1f')} (not a still capture)"
            )
        return (
            f"drifts {self.value:.3g} on {self.axis} from start to end, "
            f"{self._times(DRIFT_FACTOR, 'what its own random walk reaches')} (not a still capture)"
        )

    def _times(self, factor: float, measure: str, digits: str = ".0f") -> str:
        """How many times ``measure`` the value is; over a measure of 0 (readings that otherwise
        never change: a quantised or stuck sensor's), that the measure is 0."""
        if self.bound == 0:
            return f"where {measure} is 0"
        return f"{self.value / self.bound * factor:{digits}} times {measure}"


class StepWatch:
    """Means of consecutive blocks of ``block`` samples, streamed: a capture moved when one
    difference between neighbours stands far out of the others (a step), or when the first and
    last blocks differ far more than a random walk with those increments would (a drift), or
    when the block means jump far more than the noise within a block allows, throughout (moving).

    With the differences d_k of M + 1 block means (d_k = ybar_{k+1} - ybar_k): a random walk's
    net change after M steps has a standard deviation std(d) sqrt(M), white noise's far less, so
    ``|ybar_M - ybar_0| > DRIFT_FACTOR std(d) sqrt(M)`` is a trend no noise of the capture
    explains; the spread used for steps leaves the largest difference out, so the step does not
    hide itself. Memory: three running sums per axis, and each block's standard deviation and
    difference from the one before."""

    def __init__(self, block: int) -> None:
        self.block = max(1, int(block))
        self.partial = np.zeros(3)
        self.count = 0  # samples in the partial block
        self.seen = 0
        self.first: FloatArray | None = None
        self.last: FloatArray | None = None
        self.blocks = 0
        self.sum = np.zeros(3)
        self.sum2 = np.zeros(3)
        self.largest = np.zeros(3)
        self.largest_at = np.zeros(3, dtype=np.int64)
        self.origin = np.zeros(3)  # the block's first sample: its spread is summed about it
        self.about = np.zeros(3)
        self.squares = np.zeros(3)
        self.within: list[FloatArray] = []  # each block's standard deviation per axis
        self.jumps: list[FloatArray] = []  # the differences between neighbouring block means, (k, 3) each
        self.begun = 0  # the sample the block under way starts at

    def add(self, samples: FloatArray) -> None:
        y = np.asarray(samples, dtype=np.float64)
        k = 0
        if self.count:  # the block begun in the last call
            k = min(self.block - self.count, y.shape[0])
            self._piece(y[:k], self.begun)
        whole = (y.shape[0] - k) // self.block
        if whole:  # whole blocks at once, summed along one axis of a (whole, block, 3) view (einsum: 3x
            # faster than sum() over a middle axis); each block's spread about its first sample
            blocks = y[k : k + whole * self.block].reshape(whole, self.block, 3)
            about = blocks - blocks[:, :1, :]
            mean = np.einsum("kbj->kj", about) / self.block
            squares = np.einsum("kbj,kbj->kj", about, about) / self.block
            self.within += list(np.sqrt(np.maximum(squares - mean * mean, 0.0)))
            starts = self.seen + k + self.block * np.arange(whole)
            self._close(blocks[:, 0, :] + mean, starts)
            k += whole * self.block
        if k < y.shape[0]:
            self._piece(y[k:], self.seen + k)
        self.seen += y.shape[0]

    def _piece(self, piece: FloatArray, begun: int) -> None:
        """Samples of the block under way (no more than it lacks; ``begun``: the sample it starts
        at): summed in, and the block closed when whole."""
        self.partial += piece.sum(axis=0)
        if self.count == 0:
            self.origin, self.begun = piece[0].copy(), begun
        about = piece - self.origin
        self.about += about.sum(axis=0)
        self.squares += np.square(about, out=about).sum(axis=0)
        self.count += piece.shape[0]
        if self.count == self.block:
            mean = self.about / self.block
            self.within.append(np.sqrt(np.maximum(self.squares / self.block - mean * mean, 0.0)))
            self._close((self.partial / self.block)[None], np.array([self.begun]))
            self.partial, self.about, self.squares = np.zeros(3), np.zeros(3), np.zeros(3)
            self.count = 0

    def _close(self, means: FloatArray, starts: IntArray) -> None:
        """Blocks closed, in order: their means (k, 3), and the sample each starts at."""
        self.blocks += means.shape[0]
        if self.last is None:
            self.first = means[0].copy()
        else:
            means = np.concatenate([self.last[None], means])
            starts = np.concatenate([[0], starts])
        if means.shape[0] > 1:
            d = np.diff(means, axis=0)
            self.jumps.append(d)
            self.sum += d.sum(axis=0)
            self.sum2 += np.square(d).sum(axis=0)
            size = np.abs(d)
            top = np.argmax(size, axis=0)  # the first of the largest, as one by one
            peak = size[top, np.arange(3)]
            bigger = peak > self.largest
            self.largest = np.where(bigger, peak, self.largest)
            self.largest_at = np.where(bigger, starts[1:][top], self.largest_at)
        self.last = means[-1].copy()

    def verdict(self) -> list[Moved]:
        """What moved (empty: still, or too few blocks to tell)."""
        m = self.blocks - 1  # differences
        if m < MIN_BLOCKS or self.first is None or self.last is None:
            return []
        out = []
        rest = np.maximum(self.sum2 - self.largest**2, 0.0) / (m - 1)  # without the largest
        mean = self.sum / m
        centred = np.maximum(self.sum2 / m - mean * mean, 0.0)
        jumps = np.sqrt(self.sum2 / m)
        noise = median(np.array(self.within), axis=0)  # a quantised quiet axis: 0, not judged so
        typical = median(np.abs(np.concatenate(self.jumps)), axis=0)
        for j, axis in enumerate(AXES):  # a step says where; a drift, how far; else moving throughout
            bound = STEP_FACTOR * math.sqrt(rest[j])
            if self.largest[j] > bound:
                out.append(Moved(axis, "step", float(self.largest[j]), bound, int(self.largest_at[j])))
                continue
            net = abs(float(self.last[j] - self.first[j]))
            bound = DRIFT_FACTOR * math.sqrt(centred[j] * m)
            if net > bound:
                out.append(Moved(axis, "drift", net, bound, None))
                continue
            moving = noise[j] > 0 and jumps[j] > MOTION_FACTOR * noise[j]
            if moving and jumps[j] > TAIL_FACTOR * typical[j]:
                out.append(Moved(axis, "moving", float(jumps[j]), MOTION_FACTOR * float(noise[j]), None))
        return out
