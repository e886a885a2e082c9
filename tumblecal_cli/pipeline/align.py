"""tumblecal align: the rotation between two sensors' axes from a log's still blocks
(core.alignment).

- ``mag_to_accel``: a log with an accelerometer and a magnetometer, each with its calibration:
  the rotation of the magnetometer's axes onto the accelerometer's, the dip, and the heading
  error the rotation removes.
- ``imus``: a log with two or three accelerometers (a PX4 ULog's ``sensor_accel`` instances,
  or logs on one clock): the rotation of each onto the first, and how far their corrected
  readings differ, judged by the limits file's ``imu_consistency``.
- ``gyros``: the same for two or three gyroscopes, from their rates while the unit turns
  (matched in time), judged by ``gyro_consistency``.

Still blocks are found on the (first) accelerometer by the segment detector, in any
orientation; each block's mean of every sensor is taken over the same rows (or, for streams of
their own, over the same span of time).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from tumblecal_cli.core import alignment, blocks, methods, model
from tumblecal_cli.core import axes as sensor_axes
from tumblecal_cli.core.gate import Finding
from tumblecal_cli.core.quantities import DIP_SAID
from tumblecal_cli.errors import CaptureRejected, InputError
from tumblecal_cli.io import outputs, sources
from tumblecal_cli.io.calfiles import calfile, limitfile
from tumblecal_cli.io.csv import readings
from tumblecal_cli.pipeline import segment as segmenting

if TYPE_CHECKING:
    from tumblecal_cli.core.arrays import FloatArray
    from tumblecal_cli.core.blocks import Block
    from tumblecal_cli.io.calfiles.calfile import Calibration
    from tumblecal_cli.io.csv.readings import Log
    from tumblecal_cli.io.readspec import ReadSpec

#: Two still blocks whose gravity directions are closer than this are one orientation.
SAME_ORIENTATION_DEG = 10.0


@dataclass(frozen=True)
class Means:
    """Block means of one sensor, calibrated, and each mean's per-component noise as a
    direction (radians: the samples' spread over the magnitude over √samples)."""

    values: FloatArray  # (k, 3)
    direction_sigma: FloatArray  # (k,)
    noise: FloatArray  # (k,) per-component 1-sigma of each mean, in the calibration's units


@dataclass
class MagAligned:
    """The magnetometer-to-accelerometer alignment of a log, and what to tell people."""

    log: str
    sha256: str
    fit: alignment.MagAlignment
    blocks: int
    orientations: int
    notes: list[str] = field(default_factory=list)
    mag: Calibration | None = None  # the magnetometer's calibration, as given
    accel_cal: str | None = None  # the accelerometer calibration's file

    def as_dict(self) -> dict[str, object]:
        r, fit = self.fit.rotation, self.fit
        return {
            "kind": "magnetometer-to-accelerometer",
            "log": self.log,
            "sha256": self.sha256,
            "blocks": self.blocks,
            "orientations": self.orientations,
            "rotation": [[float(v) for v in row] for row in r.matrix],
            "rotation_vector_deg": [float(v) for v in r.vector_deg],
            "rotation_sigma_deg": [float(v) for v in r.sigma_deg],
            **({} if r.axes is None else {"axes": r.axes.text, "mag_axes": self.mag and _mag_axes(r, self.mag)}),
            "angle_deg": r.angle_deg,
            "angle_sigma_deg": r.angle_sigma_deg,
            "chi2": r.chi2,
            "dip_deg": fit.dip_deg,
            "dip_sigma_deg": fit.dip_sigma_deg,
            "dip_spread_deg": {"before": float(np.std(fit.dip_before)), "after": float(np.std(fit.dip_after))},
            "heading_error_deg": {
                "rms": float(np.sqrt(np.mean(fit.heading_error**2))),
                "max": float(np.abs(fit.heading_error).max()),
            },
        }


@dataclass
class ImuPair:
    """One IMU against the first: its stream, the rotation, and the consistency: the RMS of the
    difference of their corrected block means as they are (what an autopilot compares, and the
    limit judges), and after the rotation (what is left once it is applied)."""

    stream: str
    fit: alignment.Fitted | None  # None: one orientation, the rotation is not determined
    consistency: alignment.Consistency
    consistency_aligned: alignment.Consistency | None


@dataclass
class ImusAligned:
    """Several IMUs of one log against the first, the verdict, and notes."""

    reference: str
    pairs: list[ImuPair]
    blocks: int
    orientations: int
    units: str | None
    limit: float | None
    failures: list[Finding] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    #: Gyroscopes: the reference's turning samples compared (``blocks`` and ``orientations``
    #: are then 0) and about how many axes they turned.
    turning: Turning | None = None

    @property
    def limit_key(self) -> str:
        return "imu_consistency" if self.turning is None else "gyro_consistency"

    def as_dict(self) -> dict[str, object]:
        seen: dict[str, object] = {"blocks": self.blocks, "orientations": self.orientations}
        if self.turning is not None:
            seen = {"sensor": "gyroscope", "turning_samples": self.turning.samples, "turn_axes": self.turning.axes,
                    "turn_threshold": self.turning.threshold}  # fmt: skip
        return {
            "kind": "imus",
            "reference": self.reference,
            **seen,
            "units": self.units,
            "imus": [_pair_dict(p) for p in self.pairs],
            "verdict": {
                "pass": not self.failures,
                "limit": {self.limit_key: self.limit} if self.limit is not None else {},
                "failures": [f.as_dict() for f in self.failures],
            },
        }


@dataclass(frozen=True)
class Turning:
    """What a gyroscopes' alignment compared: the reference's samples above ``threshold`` (its
    units: TURN_SIGMAS × its noise at rest) matched in every other, and the axes they turned about."""

    samples: int
    axes: int
    threshold: float


def _pair_dict(p: ImuPair) -> dict[str, object]:
    out: dict[str, object] = {
        "stream": p.stream,
        "consistency": p.consistency.rms,
        "consistency_sigma": p.consistency.sigma,
        "consistency_unbiased": p.consistency.unbiased,
        "consistency_noise": p.consistency.noise,
        "consistency_aligned": None if p.consistency_aligned is None else p.consistency_aligned.rms,
        "consistency_aligned_sigma": None if p.consistency_aligned is None else p.consistency_aligned.sigma,
        "consistency_aligned_unbiased": None if p.consistency_aligned is None else p.consistency_aligned.unbiased,
    }
    if p.fit is not None:
        out |= {
            "rotation": [[float(v) for v in row] for row in p.fit.matrix],
            "rotation_vector_deg": [float(v) for v in p.fit.vector_deg],
            "rotation_sigma_deg": [float(v) for v in p.fit.sigma_deg],
            **({} if p.fit.axes is None else {"axes": p.fit.axes.text}),
            "angle_deg": p.fit.angle_deg,
            "angle_sigma_deg": p.fit.angle_sigma_deg,
            "chi2": p.fit.chi2,
        }
    return out


def block_means(values: FloatArray, spans: list[tuple[int, int]], cal: Calibration | None) -> Means:
    """Each span's (first, last, inclusive) mean of ``values`` corrected by ``cal`` (as read
    without one), and its noise."""
    out, sigma, noise = [], [], []
    for first, last in spans:
        part = values[first : last + 1]
        if cal is not None:
            part = (part - cal.offset) @ cal.matrix.T
        n = max(len(part), 1)
        mean = part.mean(axis=0)
        se = float(np.sqrt(np.mean(part.var(axis=0)) / n)) if len(part) > 1 else 0.0
        out.append(mean)
        noise.append(se)
        sigma.append(se / max(float(np.linalg.norm(mean)), 1e-300))
    return Means(np.array(out).reshape(-1, 3), np.array(sigma), np.array(noise))


def orientations(directions: FloatArray) -> int:
    """How many distinct orientations (gravity directions SAME_ORIENTATION_DEG apart) the blocks hold."""
    seen: list[FloatArray] = []
    for d in alignment.unit(directions):
        if all(float(d @ s) < np.cos(np.radians(SAME_ORIENTATION_DEG)) for s in seen):
            seen.append(d)
    return len(seen)


def _settings(settings: blocks.DetectorSettings, offset: FloatArray | None) -> blocks.DetectorSettings:
    return replace(settings, max_tilt_deg=180.0, nominal_offset=offset)  # any orientation is a still block


def _calibration(path: str, sensor: str, flag: str) -> Calibration:
    cal = calfile.load(path)
    if cal.sensor != sensor:
        raise InputError(f"{flag} takes the {sensor}'s calibration, not the {cal.sensor}'s", file=cal.path)
    return cal


def mag_to_accel(
    log: str,
    accel_cal: str,
    mag_cal: str | Calibration,
    spec: ReadSpec,
    settings: blocks.DetectorSettings,
    max_spool: int | str | None = None,
    accel_flag: str = "--accel-cal",
) -> MagAligned:
    """The rotation of the magnetometer's axes onto the accelerometer's from ``log`` (both
    sensors' columns on the same rows), each corrected by its calibration (the magnetometer's
    a file, or one just solved); ``accel_flag`` names the option that gave the accelerometer's."""
    accel = _calibration(accel_cal, "accelerometer", accel_flag)
    mag = _calibration(mag_cal, "magnetometer", "--mag-cal") if isinstance(mag_cal, str) else mag_cal
    acc_spec = replace(spec, sensor="accelerometer", columns=None, prefer=tuple(accel.columns))
    mag_spec = replace(spec, sensor="magnetometer", columns=None, prefer=tuple(mag.columns))
    table = table_of(log, acc_spec, mag_spec, accel.offset)
    if table is not None:
        return _table_aligned(table, accel, mag, accel_cal)
    with segmenting.segmented(
        log, acc_spec, settings=_settings(settings, accel.offset), whole=True, max_spool=max_spool,
    ) as (path, acc, seg):  # fmt: skip
        mlog = readings.read_log(path, mag_spec, use_time=spec.rate is None, name=acc.layout.name)
    name = acc.layout.name
    if acc.layout.sensor_names == mlog.layout.sensor_names or not np.array_equal(acc.rows, mlog.rows):
        raise InputError(
            "the accelerometer and the magnetometer are not read from their own columns of the same rows",
            file=name,
            hint="log both sensors on each row (ax,ay,az,mx,my,mz), or name the columns in the calibrations",
        )
    kept = sorted(seg.kept, key=lambda b: b.first)
    spans = [(b.first, b.last) for b in kept]
    g, m = block_means(acc.values, spans, accel), block_means(mlog.values, spans, mag)
    seen = orientations(g.values) if kept else 0
    if len(kept) < alignment.MIN_BLOCKS or seen < 3:
        raise CaptureRejected(
            f"{len(kept)} still blocks in {seen} orientations; the alignment needs {alignment.MIN_BLOCKS} or more "
            "in 3 or more orientations",
            file=name,
            hint="hold the unit still (1 s or more) in 8 or more orientations; `tumblecal segment` lists the "
            "still blocks, --min-duration and --max-noise loosen them",
            code="alignment.few",
        )
    fit = alignment.mag_to_accel(g.values, m.values, g.direction_sigma, m.direction_sigma)
    _observable(fit.rotation, name, "blocks")
    notes = [f"still blocks dropped: {seg.dropped_counts()}"] if seg.dropped_counts() else []
    return MagAligned(name, acc.sha256, fit, len(kept), seen, [*_axes_notes(fit.rotation, mag), *notes], mag, accel_cal)


#: A direction's noise for the rows of a table (one averaged reading each, their own noise not
#: known): small, so that the fit's chi2 scales its covariance to the rows' scatter about it.
TABLE_SIGMA = 1e-6


def table_of(
    log: str, acc_spec: ReadSpec, mag_spec: ReadSpec, centre: FloatArray, rows_are_poses: bool | None = None
) -> tuple[Log, Log] | None:
    """Both sensors' readings of ``log`` when it is a table of orientations (no time column, its
    rows pointing different ways about ``centre``, as solve recognises one:
    methods.orientation_table; ``rows_are_poses`` True or False: --rows-are-poses said so), else
    None. A pipe is not looked into (it is read once, as a log). align and the dip check
    (pipeline.solve.maglog) take a table so."""
    if log == "-" or not os.path.isfile(log) or rows_are_poses is False:
        return None
    acc = readings.read_log(log, acc_spec, use_time=False)
    if rows_are_poses is not True and (
        acc.layout.time is not None or methods.orientation_table(acc.values, centre) is None
    ):
        return None
    return acc, readings.read_log(log, mag_spec, use_time=False, name=acc.layout.name)


def _table_aligned(table: tuple[Log, Log], accel: Calibration, mag: Calibration, accel_cal: str) -> MagAligned:
    """The rotation from a table of orientations: each row a still block, its direction's noise
    unknown (TABLE_SIGMA: the uncertainties come from the rows' scatter about the fit)."""
    acc, mlog = table
    name = acc.layout.name
    if acc.layout.sensor_names == mlog.layout.sensor_names:
        raise InputError(
            "the accelerometer and the magnetometer are not read from their own columns of the same rows",
            file=name,
            hint="name each sensor's columns in its calibration (columns), or give --columns",
        )
    spans = [(k, k) for k in range(len(acc.values))]
    g, m = block_means(acc.values, spans, accel), block_means(mlog.values, spans, mag)
    seen = orientations(g.values)
    if len(spans) < alignment.MIN_BLOCKS or seen < 3:
        raise CaptureRejected(
            f"{len(spans)} rows in {seen} orientations; the alignment needs {alignment.MIN_BLOCKS} or more in 3 or "
            "more orientations",
            file=name,
            hint="add shots turned about each of the unit's axes",
            code="alignment.few",
        )
    sigma = np.full(len(spans), TABLE_SIGMA)
    fit = alignment.mag_to_accel(g.values, m.values, sigma, sigma)
    sigma *= np.sqrt(max(fit.rotation.chi2, 1e-30))  # the rows' scatter: the noise that makes chi2 1
    fit = alignment.mag_to_accel(g.values, m.values, sigma, sigma)
    _observable(fit.rotation, name, "rows")
    notes = [
        *_axes_notes(fit.rotation, mag),
        f"{name}: a table of {len(spans)} orientations, one averaged reading a row: each row a still block, the "
        "uncertainties from the rows' scatter about the fit",
    ]
    return MagAligned(name, acc.sha256, fit, len(spans), seen, notes, mag, accel_cal)


def source_of(sensor: str, given: object) -> str:
    """The one capture ``solve --align-to`` aligns on: the log, or the one pose file (a
    magnetometer turned through many orientations, the accelerometer's columns beside its own)."""
    if sensor != "magnetometer":
        raise InputError(f"--align-to aligns a magnetometer's axes to an accelerometer's, not the {sensor}'s")
    items = [given] if isinstance(given, str | os.PathLike) else given
    if not isinstance(items, list | tuple) or len(items) != 1 or not isinstance(items[0], str | os.PathLike):
        raise InputError(
            "--align-to takes one capture with both sensors' columns (--log LOG, or --poses FILE)",
            hint="or align a calibration afterwards: tumblecal align --accel-cal ACC --mag-cal MAG LOG",
        )
    return os.fspath(items[0])


def solved_note(done: MagAligned) -> str:
    """What solve --align-to tells people."""
    r, fit = done.fit.rotation, done.fit
    turned = "" if r.axes is None else f"axes {r.axes.text} and "
    return (
        f"aligned to {done.accel_cal} from {done.blocks} still blocks: {turned}rotated {r.angle_deg:.3f}° ± "
        f"{r.angle_sigma_deg:.3f}°, dip {fit.dip_deg:.2f}° ± {fit.dip_sigma_deg:.2f}° ({DIP_SAID}), heading error "
        "removed up to "
        f"{float(np.abs(fit.heading_error).max()):.2f}°"
    )


def aligned(done: MagAligned) -> Calibration:
    """The magnetometer's calibration with the rotation in its matrix (``M' = R M``: corrected
    readings in the accelerometer's axes) and an ``alignment`` field saying so."""
    mag = done.mag
    assert mag is not None
    r = done.fit.rotation
    matrix = r.matrix @ mag.matrix
    told = _mag_axes(r, mag)
    axes = mag.axes if r.axes is None else None if told is None else sensor_axes.parse(told)
    record = {
        "to": done.accel_cal,
        "log": done.log,
        "sha256": done.sha256,
        "rotation": [[float(v) for v in row] for row in r.matrix],
        **({} if r.axes is None else {"axes": r.axes.text}),
        "angle_deg": r.angle_deg,
        "angle_sigma_deg": r.angle_sigma_deg,
        "dip_deg": done.fit.dip_deg,
        "dip_sigma_deg": done.fit.dip_sigma_deg,
        "heading_error_deg": float(np.abs(done.fit.heading_error).max()),
    }
    order = mag.order if "alignment" in mag.order else (*mag.order, "alignment")
    sensor = matrix if axes is None else axes.matrix.T @ matrix
    return replace(
        mag,
        matrix=matrix,
        axes=axes,
        gain=np.diag(np.linalg.inv(sensor)).copy(),
        fields={**mag.fields, "alignment": record},
        order=order,
    )


def _mag_axes(r: alignment.Fitted, mag: Calibration) -> str | None:
    """The --axes that would state the magnetometer's axes in the accelerometer's, solved again:
    the signed permutation nearest ``R P`` (P its own --axes), when the rotation is near one."""
    if r.axes is None:
        return None
    before = np.eye(3) if mag.axes is None else mag.axes.matrix
    found, _ = sensor_axes.nearest(r.matrix @ before)
    return None if found.identity else found.text


def _axes_notes(r: alignment.Fitted, mag: Calibration) -> list[str]:
    """What a rotation near a signed permutation means: the axes differ, and the --axes that says so."""
    if r.axes is None:
        return []
    turned = sensor_axes.angle_between(np.eye(3), r.axes.matrix)
    told = _mag_axes(r, mag)
    fix = f"solve the magnetometer with --axes {told}, or " if told else ""
    return [
        f"the accelerometer's x, y, z are the magnetometer's {r.axes.text} (a turn of {turned:.0f}°) and a rotation "
        f"of {r.angle_deg:.3f}° more: {fix}write it aligned with --aligned-mag"
    ]


def _observable(fit: alignment.Fitted, name: str, what: str) -> None:
    """A rotation that the blocks (or a table's rows) do not determine is refused, naming the axis
    it is loosest about, in the accelerometer's axes."""
    if not fit.observable():
        axis, worst = fit.loosest()
        said = model.parse_label(",".join(f"{v:.3f}" for v in axis))
        near = next((f for f in model.FACES if model.angle_deg(axis, f) < 20 or model.angle_deg(-axis, f) < 20), None)
        about = f"{near.lstrip('+-')}" if near else said
        raise CaptureRejected(
            f"the rotation about the accelerometer's {about} axis is not determined by these {what} (1-sigma "
            f"{worst:.3g}°): the unit never turned that axis away from the plane of gravity and the field",
            file=name,
            hint=f"hold the unit still in more orientations, its {about} axis tilted towards east or west",
            code="alignment.unobservable",
        )


def imu_streams(logs_given: list[str], spec: ReadSpec, streams: list[str]) -> list[tuple[str, ReadSpec]]:
    """The (log, spec) of each IMU: ``streams`` named (of the one log, or one per log), else every
    raw stream of ``spec.sensor`` with samples in the one log, or each log's one stream."""
    if streams:
        if len(logs_given) == 1:
            twice = next((s for i, s in enumerate(streams) if s in streams[:i]), None)
            if twice is not None:
                raise InputError(f"--stream {twice} is given twice: an IMU compared with itself", file=logs_given[0])
            return [(logs_given[0], replace(spec, stream=s)) for s in streams]
        if len(streams) != len(logs_given):
            raise InputError(f"{len(logs_given)} logs and {len(streams)} --stream: give one --stream per log")
        return [(lg, replace(spec, stream=s)) for lg, s in zip(logs_given, streams, strict=True)]
    if len(logs_given) > 1:
        return [(lg, spec) for lg in logs_given]
    log = logs_given[0]
    if sources.reader_for(log) is None:
        raise InputError(
            f"one IMU: a CSV log holds one {spec.sensor}, and align compares two or three",
            file=log,
            hint="give the other IMU's log too (on the same clock), or a log that holds several (tumblecal logs FILE)",
        )
    found = [s for s in sources.streams(log) if s.sensor == spec.sensor and s.rows > 0]
    raw = [s for s in found if not s.corrected] or found
    if len(raw) < 2:
        raise InputError(
            f"one IMU: the log holds {len(raw)} {spec.sensor} stream{'s' if len(raw) != 1 else ''} with samples "
            f"({', '.join(s.key for s in raw) or 'none'}); align compares two or three",
            file=log,
            hint="tumblecal logs FILE lists its streams; --stream NAME:INSTANCE names each IMU",
        )
    return [(log, replace(spec, stream=s.key)) for s in raw[:3]]


def imus(
    logs_given: list[str],
    spec: ReadSpec,
    streams: list[str],
    cals: list[str],
    settings: blocks.DetectorSettings,
    limits: str | None = None,
) -> ImusAligned:
    """Two or three IMUs (``imu_streams``), each corrected by its calibration in ``cals`` (in
    order; none: as read): the rotation of each onto the first from simultaneous still blocks,
    their consistency, and the verdict against ``imu_consistency``."""
    if spec.sensor not in ("accelerometer", "gyroscope"):
        raise InputError(
            f"align compares accelerometers (still blocks) or gyroscopes (turns), not {spec.sensor}s",
            hint="give --sensor accelerometer or gyroscope; a magnetometer is aligned to its accelerometer with "
            "--accel-cal ACC --mag-cal MAG",
        )
    chosen = imu_streams(logs_given, spec, streams)
    if len(chosen) > 3:
        raise InputError(f"{len(chosen)} IMUs: align compares two or three")
    if cals and len(cals) != len(chosen):
        raise InputError(f"{len(cals)} --cal for {len(chosen)} IMUs: give one per IMU, in their order, or none")
    calibrations: list[Calibration | None] = [_calibration(c, spec.sensor, "--cal") for c in cals]
    calibrations = calibrations or [None] * len(chosen)
    if spec.sensor == "gyroscope":
        return gyros(chosen, calibrations, limits)
    read = [readings.read_log(lg, s, use_time=True, name=_name(lg, s)) for lg, s in chosen]
    first = read[0]
    seg = segmenting.find_blocks(first, spec.rate, None, _settings(settings, None))
    kept = sorted(seg.kept, key=lambda b: b.first)
    spans = _time_spans(first, kept)
    if not kept:
        raise CaptureRejected(
            "no still block in the first IMU's readings",
            file=first.layout.name,
            hint="`tumblecal segment --stream ...` lists its blocks; --window and --min-duration shorten them",
            code="alignment.few",
        )
    means = [block_means(lg.values, _rows_in(lg, spans), cal) for lg, cal in zip(read, calibrations, strict=True)]
    seen = orientations(means[0].values)
    pairs = [_pair(means[0], m, _name(*chosen[i]), seen) for i, m in enumerate(means[1:], start=1)]
    bound = _consistency_limit(limits, "imu_consistency")
    units = calibrations[0].units if calibrations[0] is not None else _units(*chosen[0])
    notes = []
    if seen < 2:
        notes.append("one orientation: the rotation about gravity is not determined; consistency is judged as read")
    failures = _failures(pairs, _name(*chosen[0]), bound, "imu_consistency")
    return ImusAligned(_name(*chosen[0]), pairs, len(kept), seen, units, bound, failures, notes)


def _failures(pairs: list[ImuPair], reference: str, bound: float | None, key: str) -> list[Finding]:
    return [
        Finding(
            f"limit.{key}.{i}",
            f"{p.stream} differs from {reference} by {p.consistency.rms:.4g} RMS, above {bound:g}",
            p.consistency.rms,
            bound,
        )
        for i, p in enumerate(pairs, start=1)
        if bound is not None and not p.consistency.rms <= bound
    ]


def gyros(
    chosen: list[tuple[str, ReadSpec]], calibrations: list[Calibration | None], limits: str | None
) -> ImusAligned:
    """Two or three gyroscopes: each corrected by its calibration (else its level at rest
    subtracted: its bias), matched to the first's samples in time, compared where the first
    turns faster than TURN_SIGMAS × its noise at rest; the rotation of each onto the first by
    Wahba's problem over those rate vectors, their consistency (RMS difference of the rates),
    and the verdict against ``gyro_consistency``."""
    read = [readings.read_log(lg, s, use_time=True, name=_name(lg, s)) for lg, s in chosen]
    rates, noise = [], []
    for lg, cal in zip(read, calibrations, strict=True):
        values = lg.values if cal is None else (lg.values - cal.offset) @ cal.matrix.T
        still = alignment.rest(values)
        if still is None:
            raise CaptureRejected(
                "the gyroscope never rests: its noise (and, without --cal, its bias) is not known",
                file=lg.layout.name,
                hint="log a few seconds at rest before or after the turns",
                code="alignment.few",
            )
        rates.append(values if cal is not None else values - still.level)
        noise.append(still.noise)
    threshold = alignment.TURN_SIGMAS * noise[0]
    turning = np.linalg.norm(rates[0], axis=1) > threshold
    pairs, count, axes = [], 0, 0
    for i in range(1, len(read)):
        other = _on_clock_of(read[0], read[i], rates[i])
        keep = turning & np.isfinite(other).all(axis=1)
        ref_v, other_v = rates[0][keep], other[keep]
        count, axes = int(keep.sum()), alignment.turn_axes(ref_v, noise[0])
        _turned(count, axes, read[0].layout.name, threshold)
        sigma = np.full(count, float(np.hypot(noise[0], noise[i])))
        fit = alignment.wahba(ref_v, other_v, sigma)
        _observable(fit, read[i].layout.name, "the turns were about one axis")
        pairs.append(ImuPair(_name(*chosen[i]), fit, alignment.consistency(ref_v, other_v, None, sigma),
                             alignment.consistency(ref_v, other_v, fit.matrix, sigma)))  # fmt: skip
    bound = _consistency_limit(limits, "gyro_consistency")
    units = calibrations[0].units if calibrations[0] is not None else _units(*chosen[0])
    failures = _failures(pairs, _name(*chosen[0]), bound, "gyro_consistency")
    return ImusAligned(_name(*chosen[0]), pairs, 0, 0, units, bound, failures, turning=Turning(count, axes, threshold))


def _turned(count: int, axes: int, name: str, threshold: float) -> None:
    """Exit 3 unless the gyroscopes turned, about two axes or more."""
    if count < alignment.MIN_BLOCKS:
        raise CaptureRejected(
            f"{count} samples turning faster than {threshold:.3g} ({alignment.TURN_SIGMAS:g} x the noise at rest): "
            "the gyroscopes' rotation needs turns",
            file=name,
            hint="turn the unit about two or more of its axes while logging",
            code="alignment.few",
        )
    if axes < 2:
        raise CaptureRejected(
            "the rotation is not determined by these turns: they were about one axis",
            file=name,
            hint="turn the unit about two or more of its axes while logging",
            code="alignment.unobservable",
        )


def _on_clock_of(ref: Log, other: Log, rates: FloatArray) -> FloatArray:
    """``rates`` (``other``'s) at each of ``ref``'s readings: interpolated in time on their
    clocks (NaN outside ``other``'s span or across its gaps), or row by row without clocks."""
    out = np.full((len(ref.values), 3), np.nan)
    if ref.clock is None or other.clock is None:
        n = min(len(out), len(rates))
        out[:n] = rates[:n]
        return out
    t, to = ref.clock * ref.scale, other.clock * other.scale
    if len(to) < 2:
        return out
    for axis in range(3):
        out[:, axis] = np.interp(t, to, rates[:, axis], left=np.nan, right=np.nan)
    at = np.clip(np.searchsorted(to, t), 1, len(to) - 1)
    gap = to[at] - to[at - 1]
    out[gap > 1.5 * float(np.median(np.diff(to)))] = np.nan
    return out


def _name(log: str, spec: ReadSpec) -> str:
    """How messages name an IMU: its stream, or its log."""
    return spec.stream or log


def _units(log: str, spec: ReadSpec) -> str | None:
    stream = sources.stream_of(log, spec)
    return None if stream is None else stream.units


def _time_spans(log: Log, kept: list[Block]) -> list[tuple[float, float]]:
    """Each block's first and last time (seconds of the log's own clock), or its rows when the log has no clock."""
    if log.clock is None:
        return [(float(b.first), float(b.last)) for b in kept]
    t = log.clock * log.scale
    return [(float(t[b.first]), float(t[b.last])) for b in kept]


def _rows_in(log: Log, spans: list[tuple[float, float]]) -> list[tuple[int, int]]:
    """The readings of ``log`` within each time span (first, last inclusive)."""
    if log.clock is None:
        return [(int(a), int(b)) for a, b in spans]
    t = log.clock * log.scale
    out = []
    for a, b in spans:
        first, last = int(np.searchsorted(t, a, "left")), int(np.searchsorted(t, b, "right")) - 1
        if last < first:
            raise InputError(
                f"no reading between {a:.6g} s and {b:.6g} s, a still block of the first IMU: "
                "the logs are not on one clock",
                file=log.layout.name,
            )
        out.append((first, last))
    return out


def _pair(ref: Means, other: Means, stream: str, seen: int) -> ImuPair:
    fit = None
    noise = np.sqrt(ref.noise**2 + other.noise**2)
    if seen >= 2 and len(ref.values) >= 2:
        sigma = np.maximum(noise, 1e-9 * np.linalg.norm(ref.values, axis=1).mean())
        fit = alignment.wahba(ref.values, other.values, sigma)
        fit = fit if fit.observable() else None
    aligned = None if fit is None else alignment.consistency(ref.values, other.values, fit.matrix, noise)
    return ImuPair(stream, fit, alignment.consistency(ref.values, other.values, None, noise), aligned)


def _consistency_limit(path: str | None, key: str) -> float | None:
    if path is None:
        return None
    value = limitfile.load_limits(path).get(key)
    return None if value is None else float(np.asarray(value).ravel()[0])


#: The alignment document's format and version (written by ``tumblecal align -o``).
FORMAT, VERSION = "tumblecal-alignment", 1


@dataclass(frozen=True)
class AlignRequest:
    """What ``tumblecal align`` was asked: the logs; the accelerometer and magnetometer
    calibrations (the magnetometer's alignment) or the IMUs' streams and calibrations; how to
    read and segment; the limits file; and where to write the document."""

    logs: list[str]
    spec: ReadSpec
    settings: blocks.DetectorSettings
    accel_cal: str | None = None
    mag_cal: str | None = None
    streams: list[str] = field(default_factory=list)
    cals: list[str] = field(default_factory=list)
    limits: str | None = None


def check_outputs(request: AlignRequest, output: str | None, aligned_mag: str | None) -> None:
    """Before any work: no output names an input (a log, a calibration, the limits file), the two
    outputs are not one file, and each can be written."""
    inputs = [*request.logs, *request.cals, *(p for p in (request.accel_cal, request.mag_cal, request.limits) if p)]
    for path, flag in ((output, "-o"), (aligned_mag, "--aligned-mag")):
        if path is not None:
            outputs.check_writable(path, flag)
            outputs.check_not_input(path, inputs, flag)
    same = output == aligned_mag or (output is None and aligned_mag == "-")
    if aligned_mag is not None and same:
        raise InputError(
            "-o and --aligned-mag would write one file (or both onto stdout)",
            file=aligned_mag,
            hint="give each its own file: the alignment with -o, the magnetometer's calibration with --aligned-mag",
        )
    if output is None or aligned_mag is None or output == "-" or not os.path.exists(output):
        return
    if os.path.exists(aligned_mag) and os.path.samefile(output, aligned_mag):  # one file, two spellings
        raise InputError("-o and --aligned-mag name one file", file=aligned_mag, hint="give each its own file")


def run(request: AlignRequest) -> MagAligned | ImusAligned:
    """The magnetometer's alignment when both calibrations are given, else the IMUs'."""
    if (request.accel_cal is None) != (request.mag_cal is None):
        raise InputError(
            "the magnetometer's alignment takes both --accel-cal and --mag-cal",
            hint="several IMUs of one kind are aligned without them (--cal gives each IMU's calibration)",
        )
    if request.accel_cal is not None and request.mag_cal is not None:
        if len(request.logs) != 1 or request.streams or request.cals:
            raise InputError("the magnetometer's alignment reads one log with both sensors (no --stream, no --cal)")
        return mag_to_accel(request.logs[0], request.accel_cal, request.mag_cal, request.spec, request.settings)
    return imus(request.logs, request.spec, request.streams, request.cals, request.settings, request.limits)


def document(done: MagAligned | ImusAligned) -> dict[str, object]:
    """The alignment as the file ``align -o`` writes (and ``--json`` prints, with the status)."""
    return {"format": FORMAT, "version": VERSION, **done.as_dict(), "notes": list(done.notes)}


def write_aligned(done: MagAligned | ImusAligned, path: str) -> None:
    """The magnetometer's aligned calibration (:func:`aligned`) into ``path``."""
    if not isinstance(done, MagAligned):
        raise InputError("--aligned-mag writes a magnetometer's calibration: give --accel-cal and --mag-cal")
    calfile.write(aligned(done), path)


def write(done: MagAligned | ImusAligned, path: str) -> None:
    """The document into ``path`` (atomically; '-': stdout)."""
    with outputs.atomic_output(path) as out:
        out.write((json.dumps(document(done), indent=2, ensure_ascii=False) + "\n").encode())
