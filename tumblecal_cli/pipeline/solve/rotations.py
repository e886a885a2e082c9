"""solve --sensor gyroscope --log LOG --accel-cal ACC: a gyroscope's scale and misalignment
from hand turns between still poses, no labels and no known angles (core.rotation_fit).

The log's still blocks are found by its accelerometer columns (as ``segment`` does) and cut to
where the gyroscope is still too (core.stillness: a hand's smooth start and stop turns the unit
too little for the accelerometer to see); the accelerometer calibration gives each block's
gravity direction; the gyroscope's columns of the same rows are integrated over each rotation
between consecutive kept blocks.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from tumblecal_cli.core import blocks, rotation_fit, stillness
from tumblecal_cli.core.gate import Finding
from tumblecal_cli.core.model import Solution
from tumblecal_cli.errors import CaptureRejected, InputError
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.io.csv import readings
from tumblecal_cli.pipeline import segment as segmenting
from tumblecal_cli.pipeline.solve.turns import GyroMade, Outcome, gyro_calibration, seconds_per_sample

if TYPE_CHECKING:
    from tumblecal_cli.core.arrays import FloatArray
    from tumblecal_cli.core.blocks import Block, Segmentation
    from tumblecal_cli.io.calfiles.calfile import Calibration, Pose
    from tumblecal_cli.io.csv.readings import Log
    from tumblecal_cli.pipeline.options import Settings, SolveOptions

HINTS = {
    "rotations.few": "turn the unit by hand between more still poses (2 s or more each), about all three axes",
    "rotations.axes": "turn the unit about each of its three axes between still poses",
    "rotations.residual": "hold the unit still in each pose; `tumblecal segment` lists the still blocks",
}


@dataclass
class HandTurns:
    """A log's kept still blocks (in time order, cut to where the gyroscope is still), the
    rotations between consecutive ones, the gyroscope's still samples, their mean (the bias) and
    its 1-sigma, how messages name each rotation, and notes on the blocks the gyroscope cut."""

    acc: Log
    gyr: Log
    kept: list[Block]
    rotations: list[rotation_fit.RotationReadings]
    still: FloatArray  # (n, 3) the gyroscope's samples in the still blocks
    bias: FloatArray  # (3,) their mean
    names: list[str]
    bias_se: FloatArray = field(default_factory=lambda: np.zeros(3))  # (3,) batch means (core.stillness.bias)
    notes: list[str] = field(default_factory=list)


def hand_turns(log: str, options: SolveOptions) -> HandTurns:
    """Segment the log by its accelerometer (``options.log.accel_cal`` gives the gravity directions)
    and read its gyroscope: the rotations between its still blocks."""

    assert options.log.accel_cal is not None
    accel = calfile.load(options.log.accel_cal)
    if accel.sensor != "accelerometer":
        raise InputError(f"--accel-cal takes an accelerometer's calibration, not a {accel.sensor}'s", file=accel.path)
    settings = block_settings(options, accel.offset)
    with segmenting.segmented(
        log,
        replace(options.read, sensor="accelerometer", columns=None, paired=True),
        settings=settings,
        whole=True,  # the turns between the still blocks are integrated
        max_spool=options.log.max_spool,
    ) as (path, acc, seg):
        spec = replace(options.read, sensor="gyroscope", paired=True)
        gyr = readings.read_log(path, spec, use_time=options.read.rate is None, name=acc.layout.name)
    if acc.layout.sensor_names == gyr.layout.sensor_names:  # a log of one sensor: both read the same columns
        raise InputError(
            f"the accelerometer and the gyroscope would both be read from columns "
            f"{', '.join(acc.layout.sensor_names)}: --accel-cal needs a log with both sensors' columns",
            file=gyr.layout.name,
            hint="log both sensors (acc_x ... gyr_x ...), or name the gyroscope's columns with --columns; "
            "a gyroscope alone is calibrated from known turns (--turns)",
        )
    if not np.array_equal(acc.rows, gyr.rows):
        raise InputError(
            "the accelerometer and the gyroscope are not read on the same rows (an interleaved log?)",
            file=gyr.layout.name,
        )
    kept, notes = gyro_still(seg, acc.values, gyr.values)
    _clock_integrates(seg, kept, gyr, options.read.rate)
    dt = seconds_per_sample(gyr, options.read.rate, seg.clock)
    still = np.concatenate([gyr.values[b.first : b.last + 1] for b in kept]) if kept else np.zeros((0, 3))
    bias, bias_se = stillness.bias(gyr.values, [(b.first, b.last) for b in kept], seg.window)
    directions = [_direction(accel, acc.values[b.first : b.last + 1].mean(axis=0)) for b in kept]
    rots = [
        rotation_fit.RotationReadings(
            gyr.values[a.last : b.first], dt[a.last : b.first], directions[k], directions[k + 1]
        )
        for k, (a, b) in enumerate(itertools.pairwise(kept))
    ]
    names = [f"block {a.number} to {b.number}" for a, b in itertools.pairwise(kept)]
    return HandTurns(acc, gyr, kept, rots, still, bias, names, bias_se, notes)


def block_settings(options: SolveOptions, nominal_offset: FloatArray) -> blocks.DetectorSettings:
    """How the accelerometer's still blocks are found: as ``segment`` finds them (its
    ``--window`` ...), in any orientation, about the accelerometer calibration's offset."""
    return blocks.DetectorSettings(
        window=options.log.window,
        threshold=options.log.threshold,
        min_duration=options.log.min_duration,
        trim=options.log.trim,
        max_noise=0.02,
        max_tilt_deg=180.0,  # any orientation is a pose here
        nominal_offset=nominal_offset,
    )


def gyro_still(seg: Segmentation, acc: FloatArray, gyr: FloatArray) -> tuple[list[Block], list[str]]:
    """The accelerometer's kept blocks, in time order, cut to where the gyroscope (``gyr``, the
    same rows as ``acc``) is still (core.stillness; the accelerometer's mean and spread over
    what is left), those it finds no still part in left out; and notes on what it cut."""
    blocks = sorted(seg.kept, key=lambda b: b.first)
    found = stillness.still(gyr, [(b.first, b.last) for b in blocks], seg.window, seg.min_samples)
    kept, notes = [], []
    for block, span, why in zip(blocks, found.spans, found.why, strict=True):
        if span is None:
            notes.append(f"still block {block.number} left out: {why} (the accelerometer saw it still)")
            continue
        first, last = span
        if (first, last) != (block.first, block.last):
            part = acc[first : last + 1]
            duration = None if seg.period is None else (last - first + 1) * seg.period
            mean, std = part.mean(axis=0), part.std(axis=0)
            block = replace(block, first=first, last=last, mean=mean, std=std, duration=duration)
        kept.append(block)
    trimmed = sum(head + tail for head, tail in found.cut)
    if trimmed:
        ends = sum(1 for head, tail in found.cut if head + tail)
        amount = f"{trimmed * seg.period:.3g} s" if seg.period else f"{trimmed} samples"
        notes.insert(
            0,
            f"the gyroscope was still turning at the ends of {ends} of {len(blocks)} still blocks "
            f"(too slowly for the accelerometer): {amount} cut in all",
        )
    return kept, notes


def _clock_integrates(seg: Segmentation, kept: list[Block], gyr: Log, rate: float | None) -> None:
    """The log's clock can carry the integration of its turns: one that does not advance with
    the samples (whole seconds at 100 Hz) gave gains 1000x off with a PASS; a gap in a turn
    leaves the turn's samples out (exit 2 and 3, for solve and verify alike)."""

    if rate is not None:
        return
    if segmenting.coarse_clock(seg):
        raise InputError(
            f"the time column does not advance with the samples ({seg.zero_steps:.0%} of its steps are 0): "
            "the turns cannot be integrated from it",
            file=gyr.layout.name,
            hint="give the sample rate: --rate HZ",
        )
    for a, b in itertools.pairwise(kept):
        inside = [g for g in seg.gaps if a.last < g <= b.first]
        if inside:
            raise CaptureRejected(
                f"the turn from block {a.number} to block {b.number} spans a gap in time (after data row "
                f"{int(gyr.rows[inside[0] - 1])}): its samples are not all there to integrate",
                file=gyr.layout.name,
                hint="log without gaps, or leave that turn out: cut the log at the gap",
                code="rotations.gap",
            )


def from_log(log: str, options: SolveOptions, given: Settings) -> Outcome:
    """The rotations of the log (:func:`hand_turns`), M fitted over them, the checks."""
    turns = hand_turns(log, options)
    acc, gyr, kept, rots, bias, names = (turns.acc, turns.gyr, turns.kept, turns.rotations, turns.bias, turns.names)
    name = gyr.layout.name
    if len(rots) < rotation_fit.MIN_ROTATIONS:
        finding = Finding(
            "rotations.few",
            f"{len(rots)} rotations between {len(kept)} still blocks; need {rotation_fit.MIN_ROTATIONS}",
            len(rots),
            rotation_fit.MIN_ROTATIONS,
        )
        return Outcome(3, None, rejections=[finding], error=_rejected([finding], name))
    fit = rotation_fit.fit(rots, bias)
    rank = int(np.linalg.matrix_rank(fit.axes * np.radians(fit.angle_deg)[:, None], tol=0.2))
    findings = []
    if rank < 3:
        findings.append(Finding("rotations.axes", f"rotations about {rank} independent axes; need 3", rank, 3))
    for label, res in zip(names, fit.residual_deg, strict=True):
        if res > rotation_fit.MAX_RESIDUAL_DEG:
            findings.append(
                Finding(
                    "rotations.residual",
                    f"rotation {label}: the gyroscope misses the gravity direction after it by {res:.1f}° "
                    f"(more than {rotation_fit.MAX_RESIDUAL_DEG:g}°): the unit moved in a still block, "
                    "or samples are missing",
                    float(res),
                    rotation_fit.MAX_RESIDUAL_DEG,
                )
            )
    solution, poses, made, cross_se = _parts(fit, bias, turns.bias_se, acc, gyr, kept, names)
    cal, failures = gyro_calibration(solution, gyr, poses, fit.residual_deg, cross_se, made, options, given)
    if findings:
        return Outcome(3, None, draft=cal, rejections=findings, error=_rejected(findings, name))
    notes = [
        *dict.fromkeys([*acc.layout.notes, *gyr.layout.notes]),  # how the log was read (a ULog's pairing)
        *turns.notes,
        f"{len(rots)} rotations between {len(kept)} still blocks: residual RMS "
        f"{float(np.sqrt(np.mean(fit.residual_deg**2))):.3g}°, largest {float(fit.residual_deg.max()):.3g}°",
    ]
    return Outcome(1 if failures else 0, cal, cal, notes=notes, failures=failures)


def _direction(accel: Calibration, mean: FloatArray) -> FloatArray:
    v = accel.matrix @ (mean - accel.offset)
    unit: FloatArray = v / np.linalg.norm(v)
    return unit


def _rejected(findings: list[Finding], name: str) -> CaptureRejected:
    first = findings[0]
    return CaptureRejected(
        first.message,
        file=name,
        hint=HINTS[first.code],
        more=tuple(f.render() for f in findings[1:]),
        code=first.code,
        codes=tuple(f.code for f in findings),
    )


def _parts(
    fit: rotation_fit.RotationsFit,
    bias: FloatArray,
    bias_se: FloatArray,
    acc: Log,
    gyr: Log,
    kept: list[Block],
    names: list[str],
) -> tuple[Solution, list[Pose], GyroMade, FloatArray | None]:
    """The solution (the bias of the still blocks, the fitted matrix), the calibration's poses
    (the still blocks), what it was made of (the hand rotations) and the cross terms' 1-sigma."""

    gain_se, cross_se = rotation_fit.gain_se(fit.matrix, fit.matrix_cov)
    solution = Solution("rotations", bias, fit.matrix, bias_se, gain_se)

    poses = [
        calfile.Pose(
            face=None,
            mean=gyr.values[b.first : b.last + 1].mean(axis=0),
            samples=b.samples,
            std=gyr.values[b.first : b.last + 1].std(axis=0),
            file=gyr.layout.name,
            sha256=acc.sha256,
            rows=(int(gyr.rows[b.first]), int(gyr.rows[b.last])),
            block=b.number,
            accelerometer_mean=b.mean,
        )
        for b in kept
    ]
    made = GyroMade(
        segmentation=calfile.SegmentationPart(gyr.layout.name, acc.sha256, "detector"),
        rotations=tuple(
            calfile.Rotation(name, float(angle), float(res))
            for name, angle, res in zip(names, fit.angle_deg, fit.residual_deg, strict=True)
        ),
    )
    return solution, poses, made, cross_se
