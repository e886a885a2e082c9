"""Control charts over a station's calibrations in time (``tumblecal records trend``).

numpy only: the pipeline (``pipeline.records.trend``) reads the records and orders each
station's values by time; this module judges each series and compares the stations.

**The chart.** Each series (one station, one sensor, one parameter: an offset, a gain, a
cross-axis term, the residual) is an individuals chart: its centre and σ come from a baseline
(the first N units, or the units of a period), σ from the average moving range, ``MR̄ / d2``
with d2 = 1.128 for ranges of two (Montgomery 2009, Introduction to Statistical Quality Control,
6th ed., §6.4, Eq. 6.33), and an EWMA of the same values (Montgomery §9.2, Eq. 9.22 and the
exact variance, Eq. 9.24). Units after the baseline are judged.

**The rules.** The Western Electric rules (Western Electric 1956, Statistical Quality Control
Handbook, §1.B; Montgomery §5.3.6): 1, a point beyond 3σ; 2, 2 of 3 in a row beyond 2σ on one
side; 3, 4 of 5 beyond 1σ on one side; 4, 8 in a row on one side; and an EWMA beyond its limit.
As printed, on one chart of 500 units they fire about 5 times when nothing is wrong (the
in-control run length of the four rules together is about 91 points, Champ and Woodall 1987),
and a line has dozens of stations and parameters. Here the rules keep their shape and their
limits widen with the number of points judged, so that a whole trend run over stable stations
raises an alarm with probability at most ``TREND_ALPHA``:

- the run is ``points`` judgements (every judged unit of every series) by each of the 6 rules,
  each at the level ``p = TREND_ALPHA / (6 · points)`` (Bonferroni);
- rule 1's limit ``L1``: ``P(|z| > L1) = p``; rule 2's ``L2``: 2 of 3 beyond it on one side at
  ``≈ 6 q²`` (``q`` the one-sided tail), ``6 q² = p``; rule 3's ``L3``: ``10 q⁴ = p``; rule 4's
  run: ``R`` in a row on one side, ``2 · s^R = p``, where ``s`` is the chance of one side with the
  baseline's centre 2 standard errors off (``Φ(2 / √N)``); the EWMA's: its points are correlated
  over ``(2 − λ) / λ`` units, so ``p`` times that;
- each z is against the baseline's estimates, ``(x − centre) / (σ̂ · √(1 + 1/N))``, and its
  quantiles are Student's t with the moving-range σ's degrees of freedom, ``0.62 (N − 1)``
  (Montgomery §6.4): a short baseline widens the limits rather than raising false alarms.

The widened limits are stated in the output (``ControlLimits``). What that costs is the time to see a
small shift: an honest chart of many series cannot tell a third of a σ from noise within a
hundred units (tests/test_control.py measures the delay).

- the drift rule (``drifting``): a slope since some earlier unit, judged at rule 1's limit.

**Stations compared.** For each sensor and parameter, each station's mean over its judged units
against the mean of the other stations': Welch's t, ``(m − m_rest) / √(s²/n + s_rest²/n_rest)``,
Šidák over every station and parameter compared at ``TREND_ALPHA``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from tumblecal_cli.core.arrays import BoolArray, FloatArray
from tumblecal_cli.core.outliers import t_quantile, t_tail

#: The chance that a trend run over stable stations (every series in control) raises any alarm.
TREND_ALPHA = 0.05
#: d2 for moving ranges of two: E|x₁ − x₂| = d2 σ for normal x (Montgomery Table VI).
D2 = 1.128
#: The EWMA's weight of each new unit (small: a slow drift, the fixture's, is what it is for).
EWMA_LAMBDA = 0.05
#: The EWMA is judged at ``p`` times this: its points are correlated (over about (2 − λ) / λ = 39
#: units), so fewer than every point are independent judgements; 4, not 39, so that the run's
#: false-alarm rate holds with the baseline's own errors (tests/test_control.py simulates it).
EWMA_SPAN = 4.0
#: The drift rule fits a slope starting at most this many starts per series (evenly spaced,
#: every DRIFT_STEP units at the least), each over at most DRIFT_SPAN units after it.
DRIFT_STARTS = 60
DRIFT_STEP = 10
DRIFT_SPAN = 400
#: A slope is judged over DRIFT_MIN units or more, each z clipped at ±DRIFT_CLIP: one unit far off
#: is rule 1's, not a drift.
DRIFT_MIN = 25
DRIFT_CLIP = 4.0
#: A baseline of fewer units gives no chart (its σ would have under 3 degrees of freedom).
MIN_BASELINE = 6
#: The baseline's size when none is given: the first this many units of each series.
BASELINE_UNITS = 100
#: The rules, in the order they are checked and named.
RULES = ("beyond-limit", "2-of-3", "4-of-5", "run", "ewma", "drift")
#: What each rule says of a series, for people.
RULE_WORDS = {
    "beyond-limit": "one point beyond {l1:.2f}σ",
    "2-of-3": "2 of 3 in a row beyond {l2:.2f}σ on one side",
    "4-of-5": "4 of 5 in a row beyond {l3:.2f}σ on one side",
    "run": "{run} in a row on one side of the centre",
    "ewma": "the EWMA (λ {lam:g}) beyond {le:.2f}σ of its own",
    "drift": "a slope since one unit, beyond {l1:.2f} of its standard errors",
    "station": "this station's mean differs from the other stations' by {z:.1f} of its standard errors",
}


@dataclass(frozen=True)
class ControlLimits:
    """The widened rule limits of one trend run (see the module docstring): ``l1`` ``l2`` ``l3``
    in σ of a unit, ``run`` units in a row, ``le`` in σ of the EWMA; ``p`` each judgement's level,
    ``points`` the judgements made, ``df`` the baseline's degrees of freedom."""

    l1: float
    l2: float
    l3: float
    run: int
    le: float
    p: float
    points: int
    df: float
    lam: float = EWMA_LAMBDA

    def as_dict(self) -> dict[str, object]:
        return {
            "alpha": TREND_ALPHA,
            "points": self.points,
            "p": self.p,
            "beyond_limit_sigma": self.l1,
            "two_of_three_sigma": self.l2,
            "four_of_five_sigma": self.l3,
            "run": self.run,
            "ewma_lambda": self.lam,
            "ewma_sigma": self.le,
            "baseline_df": self.df,
        }


def limits(points: int, baseline: int, alpha: float = TREND_ALPHA) -> ControlLimits:
    """The rule limits for ``points`` judgements against baselines of ``baseline`` units."""
    p = alpha / (len(RULES) * max(points, 1))
    df = max(0.62 * (baseline - 1), 2.0)
    l1 = t_quantile(p, df)
    off = 1.0 / math.sqrt(baseline)  # the baseline centre's standard error, in σ: a window rule's limit moves by it
    l2 = t_quantile(min(2.0 * math.sqrt(p / 6.0), 0.999), df) + off
    l3 = t_quantile(min(2.0 * (p / 10.0) ** 0.25, 0.999), df) + off
    side = _normal_cdf(2.0 / math.sqrt(baseline))
    run = max(8, math.ceil(math.log(p / 2.0) / math.log(side)))
    le = t_quantile(min(p * EWMA_SPAN, 0.999), df)
    return ControlLimits(l1=l1, l2=l2, l3=l3, run=run, le=le, p=p, points=points, df=df)


def _normal_cdf(x: float) -> float:
    return 0.5 * (1.0 + math.erf(x / math.sqrt(2.0)))


@dataclass(frozen=True)
class Chart:
    """One series' chart: ``centre`` and ``sigma`` (the baseline's, σ from the moving range),
    ``z`` each unit's standardised value, ``ewma`` its EWMA in σ of a unit, ``ewma_sigma`` the
    EWMA's own σ at each unit (exact, Eq. 9.24, with the baseline's centre error), ``judged``
    the units after the baseline."""

    centre: float
    sigma: float
    baseline: int
    z: FloatArray
    ewma: FloatArray
    ewma_sigma: FloatArray
    judged: BoolArray


def moving_range(values: FloatArray) -> FloatArray:
    """|x_i − x_{i−1}|, one fewer than the values."""
    return np.abs(np.diff(values))


def chart(values: FloatArray, baseline: BoolArray) -> Chart | None:
    """The chart of ``values`` (in time order) with its baseline the units ``baseline`` marks;
    judged: the units after the last baseline unit. None when the baseline is too short or has
    no scatter (a parameter a method fixes)."""
    return charts(values[None, :], baseline)[0]


def charts(values: FloatArray, baseline: BoolArray) -> list[Chart | None]:
    """``chart`` of each row of ``values`` (series of one station's units: the same times, the
    same baseline), computed together."""
    base = values[:, baseline]
    n = int(base.shape[1])
    if n < MIN_BASELINE:
        return [None] * values.shape[0]
    sigma = np.mean(moving_range(base), axis=1) / D2
    centre = np.mean(base, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):  # (a row without scatter: None below)
        z = (values - centre[:, None]) / (sigma[:, None] * math.sqrt(1.0 + 1.0 / n))
        raw = (values - centre[:, None]) / sigma[:, None]
    lam = EWMA_LAMBDA
    ewma = ewma_of(raw, lam)
    steps = np.arange(1, values.shape[1] + 1, dtype=np.float64)
    ewma_sigma = np.sqrt(lam / (2.0 - lam) * (1.0 - (1.0 - lam) ** (2.0 * steps)) + 1.0 / n)
    last = int(np.flatnonzero(baseline)[-1])
    judged = np.arange(values.shape[1]) > last
    out: list[Chart | None] = []
    for k in range(values.shape[0]):
        sd, mid = float(sigma[k]), float(centre[k])
        if not (sd > 1e-12 * max(abs(mid), 1e-300)) or not math.isfinite(sd):
            out.append(None)
        else:
            out.append(Chart(mid, sd, n, z[k], ewma[k], ewma_sigma, judged))
    return out


#: The EWMA is summed in chunks of this many units ((1 − λ)^−k stays well inside a float's range).
_CHUNK = 1000


def ewma_of(values: FloatArray, lam: float) -> FloatArray:
    """``e_t = λ x_t + (1 − λ) e_{t−1}``, ``e_0`` = 0 before the first unit (Eq. 9.22), as sums:
    ``e_t = (1 − λ)^t (e_start + λ Σ x_k (1 − λ)^−k)`` over each chunk, carried across chunks;
    along the last axis (each row of a 2-D ``values`` its own series)."""
    out = np.empty_like(values)
    level = np.zeros(values.shape[:-1])
    keep = 1.0 - lam
    size = values.shape[-1]
    for start in range(0, size, _CHUNK):
        x = values[..., start : start + _CHUNK]
        k = np.arange(1, x.shape[-1] + 1, dtype=np.float64)
        decay = keep**k
        out[..., start : start + x.shape[-1]] = decay * (level[..., None] + lam * np.cumsum(x / decay, axis=-1))
        level = out[..., start + x.shape[-1] - 1]
    return out


def _windows(hits: BoolArray, width: int) -> FloatArray:
    """How many of the last ``width`` units (this one included) are hits, at each unit (along
    the last axis)."""
    counts = np.cumsum(hits, axis=-1, dtype=np.int64)
    out = counts.copy()
    out[..., width:] -= counts[..., :-width]
    return out.astype(np.float64)


def _runs(side: FloatArray) -> FloatArray:
    """The length of the run of one sign ending at each unit (0 where the sign is 0), along the
    last axis."""
    size = side.shape[-1]
    if size == 0:
        return np.zeros(side.shape)
    starts = np.ones(side.shape, dtype=bool)
    starts[..., 1:] = side[..., 1:] != side[..., :-1]
    at = np.arange(size)
    first = np.maximum.accumulate(np.where(starts, at, 0), axis=-1)
    return np.where(side != 0, at - first + 1, 0).astype(np.float64)


def fired(c: Chart, lim: ControlLimits) -> dict[str, int]:
    """Each rule that fires on the chart's judged units, and the first unit (an index into the
    series) where it does."""
    return fired_together([c], lim)[0]


def fired_together(cs: Sequence[Chart], lim: ControlLimits) -> list[dict[str, int]]:
    """``fired`` of each chart of ``cs``: one station's series (the same units, the same baseline
    and judged units, so the same EWMA σ), judged together."""
    z = np.stack([c.z for c in cs])
    judged = cs[0].judged
    rules: dict[str, BoolArray] = {"beyond-limit": np.abs(z) > lim.l1}
    for name, limit, width, need in (("2-of-3", lim.l2, 3, 2), ("4-of-5", lim.l3, 5, 4)):
        up = _windows(z > limit, width) >= need
        down = _windows(z < -limit, width) >= need
        rules[name] = (up & (z > limit)) | (down & (z < -limit))  # the point that makes the count
    rules["run"] = _runs(np.sign(z)) >= lim.run
    rules["ewma"] = np.abs(np.stack([c.ewma for c in cs])) > lim.le * cs[0].ewma_sigma
    rules["drift"] = drifting(z * math.sqrt(1.0 + 1.0 / cs[0].baseline), judged, lim.l1)
    out: list[dict[str, int]] = [{} for _ in cs]
    for name in RULES:
        hits = rules[name] & judged
        first = np.argmax(hits, axis=-1)
        for k in np.flatnonzero(hits.any(axis=-1)):
            out[k][name] = int(first[k])
    return out


def drifting(z: FloatArray, judged: BoolArray, limit: float) -> BoolArray:
    """The units where a slope that starts at an earlier judged unit τ is beyond ``limit`` of its
    standard errors: the hinge regression ``z_t = a + b·max(0, t − τ)`` over every unit up to
    this one, ``a`` free (so the baseline's centre error does not count; the units before τ give
    the level), its t for ``b`` (Draper and Smith 1998, Applied Regression Analysis, §1.4)
    ``Σ (h − h̄) z / √Σ (h − h̄)²`` with z in σ. Each start τ on a grid of at most DRIFT_STARTS,
    each over DRIFT_SPAN units: a drift the EWMA would take too long to see, seen once the slope
    it has had is clear of the noise. Over DRIFT_MIN units at the least, z clipped at DRIFT_CLIP.
    Along the last axis: each row of a 2-D ``z`` its own series, ``judged`` theirs."""
    out = np.zeros(z.shape, dtype=bool)
    judged_at = np.flatnonzero(judged)
    if judged_at.size < 2:
        return out
    first, size = int(judged_at[0]), z.shape[-1]
    z = np.clip(z, -DRIFT_CLIP, DRIFT_CLIP)
    t = np.arange(size, dtype=np.float64)
    lead = np.zeros((*z.shape[:-1], 1))
    tz = np.concatenate([lead, np.cumsum(t * z, axis=-1)], axis=-1)  # tz[k], zs[k]: sums over the units before k
    zs = np.concatenate([lead, np.cumsum(z, axis=-1)], axis=-1)
    step = max(DRIFT_STEP, (size - first) // DRIFT_STARTS)
    starts = np.arange(first - 1, size - 1, step)
    m = np.arange(DRIFT_MIN, DRIFT_SPAN + 1, dtype=np.float64)[None, :]
    end = starts[:, None] + m.astype(np.int64)  # the last unit, inclusive
    inside = end < size
    end = np.minimum(end, size - 1)
    tau = starts[:, None]
    # Σ h z (h = t − τ after τ) less h̄ Σ z, over the units up to ``end``: tz[end+1] − tz[τ+1] −
    # τ (zs[end+1] − zs[τ+1]) − (Σh / count) zs[end+1]; its square against limit² Σ (h − h̄)²
    h1, h2, count = m * (m + 1) / 2, m * (m + 1) * (2 * m + 1) / 6, end + 1.0
    spread = h2 - h1 * h1 / count
    beyond = np.where(inside, limit * limit * spread, np.inf)  # (past the series' end: no slope)
    lead = tau * zs[..., tau + 1] - tz[..., tau + 1]
    slope = tz[..., end + 1] - (tau + h1 / count) * zs[..., end + 1] + lead
    where = np.nonzero(slope * slope > beyond)
    out[(*where[:-2], end[where[-2], where[-1]])] = True
    return out


@dataclass(frozen=True)
class Compared:
    """One station's mean against the other stations' on one parameter: Welch's ``t`` with ``df``
    degrees of freedom, judged at the two-sided level ``p``; whether it is ``beyond``, and the
    ``limit`` that is (its quantile, found only where asked: a bisection per station)."""

    station: str
    mean: float
    rest: float
    t: float
    df: float
    p: float

    @property
    def beyond(self) -> bool:
        return t_tail(abs(self.t), self.df) < self.p

    @property
    def limit(self) -> float:
        return t_quantile(self.p, self.df)


def compare(groups: dict[str, FloatArray], comparisons: int, alpha: float = TREND_ALPHA) -> list[Compared]:
    """Each station of ``groups`` (its judged values) against the rest, Šidák over
    ``comparisons`` (every station and parameter compared in the run)."""
    if len(groups) < 2:
        return []
    p = 1.0 - (1.0 - alpha) ** (1.0 / max(comparisons, 1))
    # each station's count and sums about the grand mean; the rest's are the totals less its own
    # (centred first, so the variances lose no digits to the values' size)
    grand = float(np.mean(np.concatenate(list(groups.values()))))
    n = np.array([v.size for v in groups.values()], dtype=np.float64)
    s1 = np.array([np.sum(v - grand) for v in groups.values()])
    s2 = np.array([np.sum((v - grand) ** 2) for v in groups.values()])
    k, r1, r2 = n.sum() - n, s1.sum() - s1, s2.sum() - s2
    out = []
    for i, station in enumerate(groups):
        if n[i] < MIN_BASELINE or k[i] < MIN_BASELINE:
            continue
        mine, rest = s1[i] / n[i], r1[i] / k[i]
        v1 = max(s2[i] - s1[i] * mine, 0.0) / (n[i] - 1) / n[i]
        v2 = max(r2[i] - r1[i] * rest, 0.0) / (k[i] - 1) / k[i]
        if not v1 + v2 > 0:
            continue
        t = float((mine - rest) / math.sqrt(v1 + v2))
        df = (v1 + v2) ** 2 / (v1 * v1 / (n[i] - 1) + v2 * v2 / (k[i] - 1))  # Welch–Satterthwaite
        out.append(Compared(station, grand + float(mine), grand + float(rest), t, max(float(df), 1.0), p))
    return out
