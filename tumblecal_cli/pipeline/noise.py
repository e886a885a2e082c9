"""noise: the Allan deviation of a still capture and the noise figures read off it (IEEE Std
952-1997 Annex C), in the units datasheets use, judged against limits, and written as the
noise model Kalibr and VINS read.

The capture is streamed block by block (``core.allan.AllanStream``, ``core.allan.StepWatch``):
memory does not grow with its length, so a day at 200 Hz (17M rows) runs in a few tens of MB.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import os
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Unpack

import numpy as np
from numpy.typing import NDArray

from tumblecal_cli.core import allan, arrays, clock, gate
from tumblecal_cli.core import quantities as unit_names
from tumblecal_cli.core.clock import Clock
from tumblecal_cli.core.model import apply
from tumblecal_cli.errors import CaptureRejected, InputError
from tumblecal_cli.io import sources
from tumblecal_cli.io.calfiles import calfile, documents, limitfile
from tumblecal_cli.io.csv import capture, readings, sniff
from tumblecal_cli.io.csv.ahead import ahead
from tumblecal_cli.io.csv.splice import Splicer, cuts, reader_for
from tumblecal_cli.io.outputs import atomic_output
from tumblecal_cli.io.readspec import ReadKeywords, read_spec
from tumblecal_cli.pipeline.frames import in_memory
from tumblecal_cli.pipeline.options import axes_given, in_axes, keywords_known

if TYPE_CHECKING:
    from tumblecal_cli.core.arrays import FloatArray
    from tumblecal_cli.core.axes import Axes
    from tumblecal_cli.io.calfiles.calfile import Calibration
    from tumblecal_cli.io.readspec import ReadSpec
    from tumblecal_cli.pipeline.frames import DataFrame, JSONObject

#: The sensors noise has figures for in datasheet and SI units (core.quantities converts them).
FIGURED = ("accelerometer", "gyroscope")
#: The units each choice of --units reports the three figures in (noise density, bias
#: instability, random walk); "{u}" is the data's own unit.
UNIT_NAMES = {
    "native": ("{u}/√Hz", "{u}", "{u}/s/√Hz"),
    ("datasheet", "accelerometer"): ("µg/√Hz", "µg", "µg/s/√Hz"),
    ("datasheet", "gyroscope"): ("°/√h", "°/h", "°/h/√h"),
    ("si", "accelerometer"): ("m/s²/√Hz", "m/s²", "m/s³/√Hz"),
    ("si", "gyroscope"): ("rad/s/√Hz", "rad/s", "rad/s²/√Hz"),
}
UNIT_CHOICES = ("native", "datasheet", "si")
#: Kalibr's imu.yaml keys for each sensor (noise density, random walk), in SI.
KALIBR_KEYS = {
    "accelerometer": ("accelerometer_noise_density", "accelerometer_random_walk"),
    "gyroscope": ("gyroscope_noise_density", "gyroscope_random_walk"),
}


def unit_key(units: str | None) -> str:
    return "" if units is None else units.strip().lower().replace(" ", "")


def to_si(sensor: str, units: str | None) -> float | None:
    """What one of a calibration's ``units`` is in SI (m/s^2, rad/s), matched without regard to
    case or spaces; None: units noise does not know, or a sensor it has no figures for."""
    return unit_names.factor(sensor, unit_key(units)) if sensor in FIGURED else None


def factors(sensor: str, units: str | None, choice: str) -> tuple[float, float, float]:
    """What the figures in the data's units are multiplied by to read in ``choice``'s units."""
    if choice == "native":
        return (1.0, 1.0, 1.0)
    si = to_si(sensor, units)
    if si is None:
        raise InputError(
            f"--units {choice} needs a calibration in known {sensor} units, "
            f"not {units!r}" + ("" if sensor in FIGURED else f" (a {sensor} has none)"),
            hint=f"calibrations in {', '.join(unit_names.names(sensor) if sensor in FIGURED else ['m/s^2'])}; "
            "or --units native",
        )
    if choice == "si":
        return (si, si, si)
    if sensor == "accelerometer":  # µg: per g, a millionth
        f = si / unit_names.STANDARD_GRAVITY * 1e6
        return (f, f, f)
    deg = si * 180.0 / math.pi  # °/s; sqrt(h) = 60 sqrt(s): °/s/√Hz = °/√s = 60 °/√h
    return (deg * 60.0, deg * 3600.0, deg * 3600.0 * 60.0)


@dataclass
class Noise:
    """noise's result: the curve (``curve``, in the data's units), the figures of each axis in
    ``figure_units``, and the outcome (``status`` 0 pass, 1 outside its limits, 3 the capture
    moved: ``rejected`` says how)."""

    status: int
    file: str
    sensor: str
    rate: float
    samples: int
    units: str | None  # the data's units (the calibration's), None: raw
    choice: str  # native | datasheet | si
    figure_units: tuple[str, str, str]
    curve: allan.Curve  # in the data's units
    axes: list[allan.Figures]  # per axis, in figure_units
    limits: dict[str, FloatArray] = field(default_factory=dict)
    failures: list[gate.Finding] = field(default_factory=list)
    not_judged: list[str] = field(default_factory=list)
    rejected: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    short: CaptureRejected | None = None  # --kalibr asked for a figure the capture does not show
    clock: Clock | None = None  # the time column's (core.clock); None: --rate

    @property
    def error(self) -> CaptureRejected | None:
        """The rejection as the command line reports it (None: none): a move first."""
        if not self.rejected:
            return self.short
        return CaptureRejected(
            self.rejected[0],
            more=tuple(self.rejected[1:]),
            code="capture.moved",
            hint="capture it again with the unit resting still (and its temperature settled)",
        )

    def verdict(self) -> JSONObject | None:
        if not self.limits:
            return None
        bounds = {k: [float(x) for x in v] for k, v in self.limits.items()}
        return {
            "pass": not self.failures,
            "failures": [f.as_dict() for f in self.failures],
            "limits": bounds,
            "not_judged": self.not_judged,
        }

    def to_dict(self) -> JSONObject:
        """The --json object (docs/commands/noise.md)."""
        low, high = self.curve.interval()
        curve = {"tau": [float(t) for t in self.curve.tau], "terms": [int(t) for t in self.curve.terms]}
        for j, axis in enumerate("xyz"):
            curve[axis] = [float(v) for v in self.curve.adev[:, j]]
            curve[f"{axis}_interval"] = [
                [_finite(lo), _finite(hi)] for lo, hi in zip(low[:, j], high[:, j], strict=True)
            ]
        axes = {}
        for axis, figs in zip("xyz", self.axes, strict=True):
            axes[axis] = {
                name: {
                    "value": f.value,
                    "uncertainty": f.uncertainty,
                    "units": unit,
                    "tau": list(f.tau) if f.tau else None,
                    **({"why": f.why} if f.value is None else {}),
                }
                for name, f, unit in zip(
                    ("noise_density", "bias_instability", "random_walk"),
                    (figs.noise_density, figs.bias_instability, figs.random_walk),
                    self.figure_units,
                    strict=True,
                )
            }
        return {
            "status": {0: "pass", 1: "fail", 3: "rejected"}[self.status],
            "exit_status": self.status,
            "file": self.file,
            "sensor": self.sensor,
            "rate": self.rate,
            "samples": self.samples,
            "units": self.units,
            "clock": None if self.clock is None else clock.as_dict(self.clock),
            "adev": curve,
            "axes": axes,
            "verdict": self.verdict(),
            "rejections": self.rejected or ([self.short.message] if self.short else []),
            "notes": self.notes,
        }

    def kalibr(self) -> dict[str, float]:
        """The Kalibr/VINS noise model of this sensor in SI: the largest of the three axes."""
        if self.sensor not in KALIBR_KEYS:
            raise InputError(f"Kalibr's noise model has no {self.sensor}: only an accelerometer or a gyroscope")
        to_si = factors(self.sensor, self.units, "si")
        back = factors(self.sensor, self.units, self.choice)
        out: dict[str, float] = {}
        for key, name, k in zip(KALIBR_KEYS[self.sensor], ("noise_density", "random_walk"), (0, 2), strict=True):
            values = [getattr(a, name).value for a in self.axes]
            if any(v is None for v in values):
                raise CaptureRejected(
                    f"{self.file}: {name.replace('_', ' ')} is not determined on every axis, and Kalibr needs it",
                    code="capture.short",
                    hint="a longer still capture shows the random walk (hours, for a good IMU)",
                )
            out[key] = max(float(v) for v in values if v is not None) / back[k] * to_si[k]
        out["update_rate"] = self.rate
        return out


def _finite(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


class NoiseKeywords(ReadKeywords, total=False):
    """noise's options beside how the capture is read (docs/commands/noise.md)."""

    cal: Calibration | str | os.PathLike[str] | None
    limits: str | os.PathLike[str] | Mapping[str, object] | None
    units: str | None
    per_octave: int
    progress: Callable[[int], None] | None
    kalibr: bool
    axes: str | None  # --axes: the figures in the body's axes (core.axes)


def noise(
    capture: str | os.PathLike[str] | DataFrame,
    **options: Unpack[NoiseKeywords],
) -> Noise:
    """The Allan deviation of a still capture and its noise figures (docs/commands/noise.md).
    ``capture`` may be its data in memory: a DataFrame (its time column gives the rate), or an
    (n, 3) array with ``rate=`` ((n, 4): t, x, y, z), read as its file would be."""

    keywords_known(options, NoiseKeywords, "noise")
    with in_memory(capture, "noise reads a still capture: a file, a DataFrame or an (n, 3) array") as path:
        return _noise(path, options)


def _noise(path: str, options: NoiseKeywords) -> Noise:
    """noise on a capture's path (or the name its data in memory is held under)."""
    rate, cal, units, kalibr = (
        options.get("rate"),
        options.get("cal"),
        options.get("units"),
        options.get("kalibr", False),
    )
    per_octave = options.get("per_octave", 1)
    if rate is not None and not (math.isfinite(rate) and rate > 0):
        raise InputError(f"--rate must be a positive number of Hz, got {rate:g}")
    if not 1 <= per_octave <= 64:
        raise InputError(f"--taus must be 1 to 64 points per octave, got {per_octave}")
    given = axes_given(options.get("axes"))
    c = in_axes(calfile.resolve(cal), options.get("axes")) if cal is not None else None
    kind = c.sensor if c is not None else options.get("sensor", "accelerometer")
    data_units = c.units if c is not None else _stream_units(path, replace(read_spec(options), sensor=kind))
    if units is not None and units not in UNIT_CHOICES:
        raise InputError(f"--units must be one of {', '.join(UNIT_CHOICES)}, got {units!r}")
    if units in ("datasheet", "si") and c is None:
        raise InputError(f"--units {units} needs --cal: raw readings have no known units")
    known = to_si(kind, data_units) is not None
    choice = units or ("datasheet" if known else "native")
    scale = factors(kind, data_units, choice)
    if kalibr:  # refused before the capture is read
        _kalibr_units(kind, c, data_units)
    bounds = _limits(options.get("limits"))
    spec = replace(read_spec(options, prefer=None if c is None else c.columns), sensor=kind)
    turn = given if c is None else None  # (a calibration's correction turns them itself)
    loaded = _stream(path, _Feed(c, allan.AllanStream(per_octave), options.get("progress"), turn), spec)
    curve, watch, name, notes, hz = loaded.curve, loaded.watch, loaded.name, loaded.notes, loaded.hz
    if given is not None:
        notes.append(f"--axes {given.text}: x, y and z are the body's axes")
    if curve.samples < 2:
        raise InputError(f"{curve.samples} sample: an Allan deviation needs many", file=name)
    names = UNIT_NAMES.get(choice) or UNIT_NAMES[(choice, kind)]
    figure_units = tuple(n.format(u=data_units or "raw") for n in names)
    axes = [
        allan.Figures(*(getattr(f, n).scaled(s) for n, s in zip(allan.NAMES, scale, strict=True)))
        for f in allan.figures(curve)
    ]
    _all_finite(name, curve, axes)
    result = Noise(0, name, kind, hz, curve.samples, data_units, choice, figure_units, curve, axes, bounds)  # type: ignore[arg-type]
    result.notes, result.clock = notes, loaded.clock
    result.rejected = [f"{name}: {m.message()}" for m in watch.verdict()]
    if not result.rejected:
        result.failures, result.not_judged = judge(axes, bounds, figure_units)
    if kalibr and not result.rejected:  # judged now: a rejected run writes no --plot either
        try:
            result.kalibr()
        except CaptureRejected as err:
            result.short = err
    result.status = 3 if result.error else 1 if result.failures else 0
    return result


def _all_finite(name: str, curve: allan.Curve, axes: list[allan.Figures]) -> None:
    """Every figure a number: readings near the bound tumblecal computes with (a calibration's
    offset of 1e150) make sums of squares overflow, and inf or NaN would leave with exit 0."""
    for axis, figs in zip("xyz", axes, strict=True):
        for what, f in zip(allan.NAMES, (figs.noise_density, figs.bias_instability, figs.random_walk), strict=True):
            if any(v is not None and not math.isfinite(v) for v in (f.value, f.uncertainty)):
                raise InputError(
                    f"the {what.replace('_', ' ')} of {axis} came out {f.value}: the readings are too large to "
                    "compute an Allan deviation with",
                    file=name,
                    hint="check --cal is this sensor's, and the capture's units",
                )
    if not np.isfinite(curve.adev).all():
        raise InputError("the Allan deviation came out non-finite: the readings are too large", file=name)


def _stream_units(path: str, spec: ReadSpec) -> str | None:
    """The units of a log's stream (a PX4 ULog's m/s^2 or rad/s: io.sources), None for a CSV."""
    stream = sources.stream_of(path, spec)
    return None if stream is None else stream.units


def _kalibr_units(sensor: str, cal: Calibration | None, units: str | None) -> None:
    """Kalibr's figures are in SI: refuse a sensor it has no keys for, or units not known."""
    if sensor not in KALIBR_KEYS:
        raise InputError(f"Kalibr's noise model has no {sensor}: only an accelerometer or a gyroscope")
    if cal is None:
        raise InputError(
            "--kalibr needs --cal: Kalibr's figures are in SI, and raw readings have no known units",
            hint="give the calibration of this sensor (its units: g, m/s^2, deg/s or rad/s)",
        )
    factors(sensor, units, "si")


def _limits(limits: str | os.PathLike[str] | Mapping[str, object] | None) -> dict[str, FloatArray]:
    """The noise limits of a limits file (or a mapping of them), each (3,)."""

    if limits is None:
        return {}
    given = limitfile.load_limits(os.fspath(limits)) if isinstance(limits, str | os.PathLike) else dict(limits)
    out: dict[str, FloatArray] = {}
    for key in limitfile.NOISE_LIMITS:
        value = given.get(key)
        if value is not None:
            listed = list(value) if isinstance(value, list | tuple | np.ndarray) else value  # [x, y, z], or one
            out[key] = np.asarray(limitfile.limit_value(listed, key, None, per_axis=True), dtype=np.float64)
    return out


def judge(
    axes: list[allan.Figures], bounds: Mapping[str, FloatArray], figure_units: tuple[str, ...]
) -> tuple[list[gate.Finding], list[str]]:
    """Each figure above its limit (a failure, code ``limit.<figure>.<axis>``), and those not
    determined where a limit asks for them (not judged: said, not failed)."""

    failures, not_judged = [], []
    for name, unit in zip(allan.NAMES, figure_units, strict=True):
        if name not in bounds:
            continue
        for j, axis in enumerate("xyz"):
            f = getattr(axes[j], name)
            bound = float(bounds[name][j])
            if f.value is None:
                not_judged.append(f"{name}.{axis}")
                continue
            if not f.value <= bound:
                failures.append(
                    gate.Finding(
                        f"limit.{name}.{axis}",
                        f"{name.replace('_', ' ')} {f.value:.3g} {unit} on {axis} is above {bound:g}",
                        float(f.value),
                        bound,
                    )
                )
    return failures, not_judged


def _stream(path: str, feed: _Feed, spec: ReadSpec) -> _Streamed:
    """Read the capture block by block into ``feed`` (the Allan stream and the step watch), its
    clock judged as it goes (``_Timer``; a source beside CSV, io.sources: read whole, then fed
    the same way). A regular file of plain lines is parsed where its cells lie (``_spliced``)."""
    rate = spec.rate
    stream = feed.stream
    if sources.reader_for(path) is not None or spec.span() != (None, None):  # (--start/--end: readings.in_span)
        log = readings.read_log(path, spec, use_time=rate is None)
        lay = log.layout
        if rate is None and log.clock is None:
            raise InputError("the sample rate is unknown: the log has no clock", file=lay.name, hint="give --rate HZ")
        timer = None if rate is not None or log.clock is None else _Timer(lay.name, log.scale)
        gaps = np.zeros(0, dtype=np.int64)
        if timer is not None and log.clock is not None:  # judged whole: its median step, as a CSV's first block's
            gaps = timer.add(log.clock, log.rows)
        for first in range(0, len(log.values), 1 << 16):
            block = log.values[first : first + (1 << 16)]
            inside = gaps[(gaps >= first) & (gaps < first + len(block))] - first
            feed.add(block, rate or (timer.hz if timer else None), inside)
        return _streamed(stream, feed, lay, rate, timer)
    with capture.open_capture(path, spec) as cap:
        lay = cap.layout
        if rate is None and lay.time is None:
            raise InputError(
                "the sample rate is unknown: the capture has no time column", file=lay.name, hint="give --rate HZ"
            )
        plain = _spliced(path, cap, rate is None)
        if plain is not None:
            said = list(lay.notes)
            with contextlib.suppress(_NotPlain):
                return _fed(cap, plain, feed, spec)
            feed = feed.again()  # (what the splice path fed is dropped: the general rules read it all,
            lay.notes[:] = said  # and say again what they find of the time column)
        return _fed(cap, _parsed(cap, rate is None), feed, spec)


def _fed(cap: capture.Capture, blocks: Iterator[_Parsed], feed: _Feed, spec: ReadSpec) -> _Streamed:
    """The blocks of a CSV capture into ``feed``, each parsed on a thread of its own while the
    last one is summed (io.csv.ahead), the time column judged by a ``_Timer`` without --rate."""
    rate, lay = spec.rate, cap.layout
    timer = None if rate is not None else _Timer(lay.name, time_unit=spec.time_unit, cap=cap)
    for first_row, values, empty, times in ahead(blocks):
        found: NDArray[np.int64] | None = None
        if timer is not None and times is not None and values.shape[0]:
            rows = first_row + (np.flatnonzero(~empty) if empty.any() else np.arange(values.shape[0]))
            found = timer.add(times, rows)
        feed.add(values, rate or (timer.hz if timer else None), found)
    return _streamed(feed.stream, feed, lay, rate, timer)


#: One block of a capture as numbers: its first data row, the readings of its rows that have
#: them, which rows have none, and the time of those that do (None: not read).
_Parsed = tuple[int, "FloatArray", NDArray[np.bool_], "FloatArray | None"]


class _NotPlain(Exception):
    """A block the splice path does not take: the capture is read again by the general rules,
    which name what is wrong with it, if anything."""


def _spliced(path: str, cap: capture.Capture, timed: bool) -> Iterator[_Parsed] | None:
    """The blocks of a regular file of plain lines (io.csv.splice's rules), each one's cells
    parsed where they lie: what ``_parsed`` gives, in half its time (4M rows: 0.34 s of CPU
    against 0.68 s). None when its lines cannot be spliced, or may not be cut into the general
    reader's blocks (CR LF line ends: pyarrow's reader ends a line at a CR; no line end after
    the last line: it keeps that line in the last block); a block that is not plain, or holds a
    reading or a time that is not a finite number, raises _NotPlain as it is reached."""
    lay = cap.layout
    extra = [lay.time] if timed and lay.time is not None else []
    splicer = reader_for(cap, also=extra)  # (a regular file's)
    if splicer is None or lay.eol != "\n" or not _ends_a_line(path):
        return None
    blocks = cuts(path, len(lay.head), capture.BLOCK_BYTES)  # (the general reader's)
    if blocks is None:
        return None
    where = [splicer.parsed.index(i) for i in (*lay.sensor, *extra)]
    return _plain_blocks(path, splicer, where, blocks)


def _plain_blocks(path: str, splicer: Splicer, where: list[int], blocks: list[tuple[int, int]]) -> Iterator[_Parsed]:
    row = 0
    with open(path, "rb") as f:
        for at, length in blocks:
            text = os.pread(f.fileno(), length, at)
            found = splicer.read(text) if len(text) == length else None  # (a file cut short meanwhile)
            if found is None:
                raise _NotPlain
            parsed, empty, _ = found
            kept = parsed[~empty] if empty.any() else parsed
            # a time cell is a number on every row, one without readings too (as _parsed reads it)
            if not np.isfinite(kept).all() or (len(where) > 3 and not np.isfinite(parsed[:, where[3]]).all()):
                raise _NotPlain
            values = np.ascontiguousarray(kept[:, where[:3]])  # (row by row, as _parsed's: the same sums)
            yield row, values, empty, kept[:, where[3]] if len(where) > 3 else None
            row += len(empty)


def _ends_a_line(path: str) -> bool:
    """Whether the file's last byte ends a line."""
    with open(path, "rb") as f:
        size = os.fstat(f.fileno()).st_size
        return size > 0 and os.pread(f.fileno(), 1, size - 1) == b"\n"


def _parsed(
    cap: capture.Capture, timed: bool
) -> Iterator[tuple[int, FloatArray, NDArray[np.bool_], FloatArray | None]]:
    """Each block of a capture as numbers: its first data row, the readings of its rows that
    have them, which rows have none, and (``timed``) the time of those that do."""
    for first_row, cols in cap.batches(only_sensor=True):
        values, empty = cap.finite_values(cols, first_row)
        if empty.any():
            values = values[~empty]
        times = readings.block_times(cap, first_row, cols[3], empty) if timed and values.shape[0] else None
        yield first_row, values, empty, times


@dataclass
class _Streamed:
    """What reading a capture gave: the curve, the step watch, the file's name and notes, the
    rate and the clock it came from (None: --rate)."""

    curve: allan.Curve
    watch: allan.StepWatch
    name: str
    notes: list[str]
    hz: float
    clock: Clock | None


def _streamed(
    stream: allan.AllanStream, feed: _Feed, lay: sniff.Layout, rate: float | None, timer: _Timer | None
) -> _Streamed:
    """The curve at the rate (--rate, else the clock's), and the notes on how the capture was read."""
    notes = list(lay.notes)
    hz = rate
    if timer is not None:
        hz = timer.rate()
        notes += timer.notes()
    if hz is None:
        raise InputError("the sample rate is unknown", file=lay.name, hint="give --rate HZ")
    clocked = None if timer is None else timer.clock
    return _Streamed(stream.result(hz), feed.watch or allan.StepWatch(1), lay.name, notes, hz, clocked)


@dataclass
class _Timer:
    """A capture's clock, block by block (core.clock): judged by the first steps, its unit
    (``readings.time_scale``) by the first block; the gaps in each block found, and counted."""

    name: str
    scale: float | None = None
    time_unit: str = "auto"
    cap: capture.Capture | None = None
    clock: Clock | None = None
    hz: float | None = None  # the first steps' rate: the watch's block length, and a regular clock's rate
    last: float | None = None  # the last time seen, in the clock's own unit
    last_row: int = -1  # ... and its data row
    first_gap: int | None = None  # the data row before the first gap

    def add(self, t: FloatArray, rows: NDArray[np.int64]) -> NDArray[np.int64]:
        """The position among ``t`` of each sample after a gap (``rows``: their data rows)."""
        if t.size == 0:
            return np.zeros(0, dtype=np.int64)
        joined = t if self.last is None else np.concatenate([[self.last], t])
        shift = 1 if self.last is None else 0  # steps[k] ends at t[k + shift]
        before = self.last_row
        self.last, self.last_row = float(t[-1]), int(rows[t.size - 1])
        if joined.size < 2:
            return np.zeros(0, dtype=np.int64)
        raw = np.diff(joined)
        if self.clock is None:
            if self.scale is None:  # the unit, by the first block's steps (a note when it is not named)
                assert self.cap is not None
                self.scale = readings.time_scale(self.cap.layout, joined, self.time_unit)
            median = float(arrays.median(raw)) * self.scale  # the median step, as the rate always was
            if not median > 0:
                raise InputError("the time column does not advance", file=self.name, hint="give --rate HZ")
            self.clock, at = clock.judge(raw * self.scale, median)
            self.hz = clock.rate_of(self.clock)
        else:
            self.clock, at = self.clock.tally(raw * self.scale)
        at = at + shift
        if at.size and self.first_gap is None:
            self.first_gap = int(rows[at[0] - 1]) if at[0] > 0 else before
        return at

    def rate(self) -> float | None:
        """A regular clock's rate is its first steps' median (as it always was); a bursty one's,
        the mean of all its steps that are not gaps (core.clock)."""
        if self.clock is None or not self.clock.bursty:
            return self.hz
        return clock.rate_of(self.clock)

    def notes(self) -> list[str]:
        """How the clock was read: bursty (both steps, the rate used), and its gaps."""
        out = []
        if self.clock is not None:
            said = clock.note(self.clock, self.name, None)
            out += [said] if said else []
        if self.clock is not None and self.clock.gaps:
            after = f" (the first after data row {self.first_gap})" if self.first_gap is not None else ""
            k = self.clock.gaps
            out.append(
                f"{self.name}: {k} gap{'s' if k > 1 else ''} in time{after}, {self.clock.gap_seconds:.3g} s in all "
                f"(a step over {self.clock.bound:.3g} s): no cluster of the deviation spans one"
            )
        return out


@dataclass
class _Feed:
    """Readings into the Allan stream and the step watch (made once the rate is known: about a
    second of samples a step), corrected by ``cal`` first when one is given, or turned into the
    body's axes by ``turn`` (--axes without a calibration); a gap in time starts a new run of
    the stream (no cluster spans it)."""

    cal: Calibration | None
    stream: allan.AllanStream
    progress: Callable[[int], None] | None
    turn: Axes | None = None
    watch: allan.StepWatch | None = None

    def again(self) -> _Feed:
        """This feed as it was before anything was added."""
        return _Feed(self.cal, self.stream.fresh(), self.progress, self.turn)

    def add(self, values: FloatArray, hz: float | None, gaps: NDArray[np.int64] | None = None) -> None:
        if self.cal is not None:
            values = apply(values, self.cal.offset, self.cal.matrix)
        elif self.turn is not None:
            values = self.turn.body(values)
        if self.watch is None and hz is not None:
            self.watch = allan.StepWatch(max(16, 2 ** round(math.log2(max(hz, 1.0)))))  # about a second
        cuts = [0, *(int(g) for g in gaps), values.shape[0]] if gaps is not None and gaps.size else None
        if cuts is None:
            self.stream.add(values)
        else:
            for k, (a, b) in enumerate(itertools.pairwise(cuts)):
                if k:
                    self.stream.restart()
                self.stream.add(values[a:b])
        if self.watch is not None:
            self.watch.add(values)
        if self.progress is not None:
            self.progress(self.stream.n)


def write_kalibr(path: str, result: Noise) -> dict[str, float]:
    """Write (atomically) the noise model Kalibr's imu.yaml and VINS read, in SI. An existing
    file's other keys (the other sensor's figures, rostopic ...) are kept: run it once for the
    accelerometer and once for the gyroscope into one file."""

    model = result.kalibr()
    doc: dict[str, object] = {}
    if os.path.isfile(path):  # a file's keys are kept; a device or a pipe (/dev/null, -) is written into
        doc = documents.parse_object(
            documents.read_bytes(path, "Kalibr imu.yaml"), path, "Kalibr imu.yaml", as_yaml=True
        )
    old_rate = doc.get("update_rate")
    if isinstance(old_rate, int | float) and abs(float(old_rate) - result.rate) > 1e-6 * result.rate:
        raise InputError(
            f"holds update_rate {old_rate:g}, this capture's rate is {result.rate:g} Hz",
            file=path,
            hint="one imu.yaml describes one IMU at one rate: write another file",
        )
    doc.update(model)
    head = (
        "# IMU noise model (Kalibr / VINS): continuous-time densities in SI, the largest axis's,\n"
        f"# from the Allan deviation of {os.path.basename(result.file)} "
        f"({result.samples} samples at {result.rate:g} Hz)\n"
        "# accelerometer: m/s^2/sqrt(Hz) and m/s^3/sqrt(Hz); gyroscope: rad/s/sqrt(Hz) and rad/s^2/sqrt(Hz)\n"
    )
    import yaml  # (--kalibr alone)

    with atomic_output(path) as out:
        out.write((head + yaml.safe_dump(doc, sort_keys=False)).encode())
    return model
