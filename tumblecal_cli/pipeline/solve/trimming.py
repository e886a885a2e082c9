"""Pose files with motion: a file that logged the unit being placed or lifted as well as its
pose is solved from its still run.

A station's files often start or end with the hand on the unit (NCSU's MicroStrain files: rest,
then handling). Judged whole, such a file moved (pose.moved); its still run is found by the
detector that cuts a continuous log (core.blocks.detect) and taken as the pose, with a note
naming its rows. This is tried only when the poses judged whole are rejected (exit 3, or the
exit 2 of a check that reads their means: one-pose's units), so a file that passes is solved
as it always was; ``--no-trim`` keeps the rejection.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from tumblecal_cli.core import blocks, catalog, model, spin
from tumblecal_cli.core.running import Summary
from tumblecal_cli.errors import CaptureRejected
from tumblecal_cli.io.csv.readings import Log, Samples

if TYPE_CHECKING:
    from tumblecal_cli.core.arrays import FloatArray
    from tumblecal_cli.core.blocks import Block
    from tumblecal_cli.pipeline.options import Settings, SolveOptions

#: Two still runs of one file whose directions are further apart than this are two poses, not
#: one pose settled twice (a hand puts a unit back within a degree or two of where it was).
TURNED_DEG = 5.0


@dataclass
class Trimmed:
    """The poses with each moved file's still run in its place (``samples``), a note for each
    (``notes``); or the rejection of a file with no such run (``error``)."""

    samples: list[Samples]
    notes: list[str] = field(default_factory=list)
    error: CaptureRejected | None = None


def applies(method: str, options: SolveOptions, given: Settings) -> bool:
    """Whether a rejected solve may try the poses' still runs: not with --no-trim, nor where the
    moved check does not judge the poses (turned captures, a gyroscope at rest, the check off)."""
    checks = options.checks
    off = checks.no_checks or "moved" in checks.no_check
    return not (checks.no_trim or off or catalog.turned(method) or given.reference <= 0)


def still_runs(poses: list[Samples], options: SolveOptions, given: Settings) -> Trimmed | None:
    """Each pose that moved as a whole replaced by its still run (None: none moved). A pose
    moved when its spread or drift (first vs last third) is above --max-noise times its
    magnitude about the nominal offset, as the detector judges a block. Its run is the longest
    kept block the detector finds in it (at least --min-samples long); still runs in two
    orientations (more than TURNED_DEG apart) are a rejection (exit 3) naming both."""
    centre = given.centre if given.centre is not None else np.zeros(3)
    max_noise = options.checks.max_noise if options.checks.max_noise is not None else 0.02
    out = Trimmed(list(poses))
    for s in poses:
        model.in_range(s.readings, s.name)  # readings no statistic can take: the error _fit_poses gives
    for k, s in enumerate(poses):
        if not moved(s.readings, centre, max_noise):
            continue
        log = s.log if s.log is not None else Log(s.layout, s.values, np.arange(len(s.values)), None, None, s.sha256)
        run = _still_run(log, options, centre, max_noise)
        if isinstance(run, CaptureRejected):
            return Trimmed(out.samples, out.notes, run)
        if run is None:
            continue
        out.samples[k] = replace_run(s, log, run, options.read.rate)
        out.notes.append(_note(s, log, run, options.read.rate))
    return out if out.notes else None


#: Samples per window of the gyroscope's own still-run detector when a file has no clock.
GYRO_WINDOW = 25
#: Two steady runs of a gyroscope's file further apart than this many standard errors of a window's
#: mean read two rates: it turned steadily between them (a bias drifts by far less).
LEVELS_SIGMAS = 20.0


def gyro_rests(poses: list[Samples], options: SolveOptions) -> Trimmed | None:
    """gyro-bias: each file replaced by the gyroscope's still run, where the file holds more (the
    unit picked up, put down, turned): the longest stretch whose windows spread no more than
    the quietest ones do (core.spin.steady_runs, on the gyroscope's own readings), with a note
    naming its rows. A file still throughout is kept whole (None: none was cut)."""
    out = Trimmed(list(poses))
    rate = options.read.rate
    for k, s in enumerate(poses):
        if isinstance(s.readings, Summary) or len(s.values) < 4 * GYRO_WINDOW:
            continue  # a long file's running sums, or too short to cut
        log = s.log if s.log is not None else Log(s.layout, s.values, np.arange(len(s.values)), None, None, s.sha256)
        period = blocks.sample_period(None if rate else log.seconds(), rate)
        window = max(round(0.5 / period), 4) if period else GYRO_WINDOW
        runs = spin.steady_runs(log.values, window, max(2 * window, options.checks.min_samples))
        if not runs:
            continue
        run = max(runs, key=lambda r: (r.samples, -r.first))
        noise = run.stderr * math.sqrt(run.samples)  # one reading's spread, from the longest run
        apart = [
            r for r in runs if float(np.linalg.norm(r.mean - run.mean)) > LEVELS_SIGMAS * noise / math.sqrt(window)
        ]
        if apart:
            return Trimmed(out.samples, out.notes, _turning(s, log, [run, *apart], rate))
        if run.first < window and run.last >= len(log.values) - window:
            continue  # still throughout (the ends' part windows aside)
        cut = blocks.Block(0, run.first, run.last, run.mean, np.zeros(3), np.zeros(3), None, "+z", 0.0, None)
        out.samples[k] = replace_run(s, log, cut, rate)
        out.notes.append(
            f"{s.layout.name}: the gyroscope turned or was handled in it; its bias is its still run, "
            f"{_where(log, cut, rate)} ({run.samples:,} of {len(log.values):,} readings); --no-trim takes the whole "
            "file"
        )
    return out if out.notes else None


def _turning(s: Samples, log: Log, runs: list[spin.Run], rate: float | None) -> CaptureRejected:
    """A gyroscope's file with steady stretches at different rates: it turned steadily (a turntable,
    a placement on it), so no one of them is its bias."""
    shown = sorted(runs, key=lambda r: r.first)[:3]
    told = ", ".join(
        f"rows {int(log.rows[r.first])}-{int(log.rows[r.last])} at {float(np.linalg.norm(r.mean)):.4g}" for r in shown
    )
    return CaptureRejected(
        f"the gyroscope reads {len(runs)} different steady rates in it ({told}{' …' if len(runs) > 3 else ''}): "
        "it turned at a steady rate, not only rested",
        file=s.layout.name,
        hint="gyro-bias takes still captures: give the still rows (--start and --end); a turntable's files take "
        "--spin RATE=FILE",
        code="pose.turned",
    )


def moved(values: FloatArray | Summary, centre: FloatArray, max_noise: float) -> bool:
    """Whether readings vary (spread, or drift between their first and last third) by more than
    ``max_noise`` times their magnitude about ``centre`` (core.blocks's NOISY and DRIFTING);
    a long pose file's by its running sums."""
    st = model.pose_stats(values)
    magnitude = float(np.linalg.norm(st.mean - centre))
    if isinstance(values, Summary):
        drift = values.drift()
    else:
        third = values.shape[0] // 3
        drift = values[-third:].mean(axis=0) - values[:third].mean(axis=0) if third else np.zeros(3)
    return not (float(st.std.max()) <= max_noise * magnitude and float(np.abs(drift).max()) <= max_noise * magnitude)


def _still_run(log: Log, options: SolveOptions, centre: FloatArray, max_noise: float) -> Block | CaptureRejected | None:
    """The still run of a pose that moved: the longest block the detector keeps (None: no
    block), or the rejection of runs in two orientations."""
    rate = options.read.rate
    seconds = None if rate else log.seconds()
    period = blocks.sample_period(seconds, rate)
    least = options.checks.min_samples
    settings = blocks.DetectorSettings(
        min_duration=least * period if period else least,
        max_noise=max_noise,
        max_tilt_deg=options.checks.max_tilt,
        nominal_offset=centre,
    )
    kept = blocks.detect(log.values, seconds, rate, settings).kept
    if not kept or (len(kept) == 1 and kept[0].samples == len(log.values)):  # no run, or the whole file
        return None
    run = max(kept, key=lambda b: (b.samples, -b.first))  # the longest; of two as long, the first
    apart = [(b, _angle(b.mean - centre, run.mean - centre)) for b in kept if b is not run]
    turned = [(b, a) for b, a in apart if a > TURNED_DEG]
    if not turned:
        return run
    other, angle = max(turned, key=lambda p: p[1])
    first, second = sorted((run, other), key=lambda b: b.first)
    return CaptureRejected(
        f"two still runs in different orientations, {angle:.0f}° apart: {_where(log, first, rate)} "
        f"(near {first.nearest}) and {_where(log, second, rate)} (near {second.nearest}); "
        "a pose file holds one pose",
        file=log.layout.name,
        hint="give the rows of the pose with --start and --end (e.g. "
        f"--start {int(log.rows[run.first])}r --end {int(log.rows[run.last])}r), or capture each pose in a file; "
        "a log of several poses: solve --log FILE",
        code="pose.turned",
    )


def _angle(a: FloatArray, b: FloatArray) -> float:
    """Degrees between two directions (0 when either is zero)."""
    na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    if na == 0 or nb == 0:
        return 0.0
    return math.degrees(math.acos(max(-1.0, min(1.0, float(a @ b) / (na * nb)))))


def replace_run(s: Samples, log: Log, run: Block, rate: float | None) -> Samples:
    """The pose ``s`` as its still run: its readings, rows, clock and temperature there (its
    duration as read_samples gives a file's: by the time column, else by --rate)."""
    part = log.block(0, run.first, run.last)
    duration = part.duration
    if duration is None and rate:
        duration = (part.rows[1] - part.rows[0] + 1) / rate
    return Samples(s.layout, part.values, part.rows, s.sha256, duration, part.temperature, times=part.times, log=log)


def _seconds(log: Log, i: int, rate: float | None) -> float | None:
    """Seconds from the capture's first reading to reading ``i`` of ``log`` (None: no clock)."""
    if rate:
        return log.first_s + i / rate
    if log.clock is None:
        return None
    return log.first_s + float(log.clock[i] - log.clock[0]) * log.scale


def _where(log: Log, b: Block, rate: float | None) -> str:
    """A block as a person finds it: its data rows, and its seconds when known."""
    rows = f"rows {int(log.rows[b.first])}-{int(log.rows[b.last])}"
    t0, t1 = _seconds(log, b.first, rate), _seconds(log, b.last, rate)
    return rows if t0 is None or t1 is None else f"{rows} ({t0:.3f}-{t1:.3f} s)"


def _note(s: Samples, log: Log, run: Block, rate: float | None) -> str:
    """What was solved from a pose that moved."""
    of = f"{int(log.rows[0])}-{int(log.rows[-1])}"
    end = _seconds(log, len(log.values) - 1, rate)
    if end is not None:
        of += f" ({log.first_s:.3f}-{end:.3f} s)"
    return (
        f"{s.layout.name}: the unit moved while it logged; solved from its still run, {_where(log, run, rate)} "
        f"of {of}; --no-trim rejects the file instead"
    )
