"""solve --sensor magnetometer --log LOG: a magnetometer from a log with both sensors, and its
dip check (docs/real-world.md).

The log's still blocks are found by its accelerometer columns, as ``segment`` finds them (with
``--accel-cal``, about that calibration's offset); the magnetometer's columns of the same rows are
the samples of the ellipsoid fit: those of the still blocks, and the samples between them where
they widen the directions the fit sees (core.solvers.coverage). With an accelerometer
calibration each still block gives a dip angle, the angle between gravity and the field
(core.earth.dip), which the calibration file and the summary report and the ``dip_angle`` limit
judges against the World Magnetic Model's (``--location`` and ``--date``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from tumblecal_cli.core import blocks, earth, gate, solvers
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import sources
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.io.csv import readings
from tumblecal_cli.io.csv.readings import Samples
from tumblecal_cli.pipeline import align as alignment
from tumblecal_cli.pipeline import segment as segmenting
from tumblecal_cli.pipeline.solve.rotations import block_settings

if TYPE_CHECKING:
    from tumblecal_cli.core.arrays import FloatArray
    from tumblecal_cli.core.blocks import Block, Segmentation
    from tumblecal_cli.core.gate import Finding, Limits
    from tumblecal_cli.io.calfiles.calfile import Calibration
    from tumblecal_cli.io.csv.readings import Log
    from tumblecal_cli.pipeline.options import SolveOptions

#: The samples between the still blocks are taken when they reach this share more of the
#: 26 directions of core.solvers.coverage than the still blocks alone.
WIDER = 1 / 26
#: Fewest still blocks a dip angle is reported from.
DIP_MIN_BLOCKS = 2


@dataclass
class MagLog:
    """A magnetometer's samples from a log with both sensors: ``samples`` for the fit (each
    still block, and the samples between them when taken), the accelerometer's and the
    magnetometer's readings (``acc``, ``mag``), the kept ``blocks``, the segmentation and notes."""

    samples: list[Samples]
    acc: Log
    mag: Log
    blocks: list[Block]
    seg: Segmentation
    notes: list[str]
    accel: Calibration | None = None
    table: bool = False  # a table of orientations: each row a still block (no spread of its own)


def read(log: str, options: SolveOptions) -> MagLog:
    """Segment the log by its accelerometer and read its magnetometer on the same rows."""
    if options.read.stream is not None or (log != "-" and sources.reader_for(log) is not None):
        raise InputError(
            "a magnetometer's --log reads both sensors on each row of one table; this log keeps each "
            "sensor in a stream of its own, on its own clock",
            file=log,
            hint="solve the magnetometer's turning capture with --poses LOG --stream (tumblecal logs LOG lists them)",
        )
    accel = None
    if options.log.accel_cal is not None:
        accel = calfile.load(options.log.accel_cal)
        if accel.sensor != "accelerometer":
            raise InputError(
                f"--accel-cal takes an accelerometer's calibration, not a {accel.sensor}'s", file=accel.path
            )
    settings = replace(
        block_settings(options, np.zeros(3)),
        nominal_offset=None if accel is None else accel.offset,
        # --max-noise, a share of the reference, judges the accelerometer's blocks here (as align's)
        max_noise=options.checks.max_noise if options.checks.max_noise is not None else 0.02,
    )
    centre = np.zeros(3) if accel is None else accel.offset
    acc_spec = replace(options.read, sensor="accelerometer", columns=None)
    table = alignment.table_of(log, acc_spec, options.read, centre, options.rows_are_poses)
    if table is not None:
        acc, mag = table
        seg = blocks.table_rows(acc.values, centre)
    else:
        with segmenting.segmented(
            log,
            replace(options.read, sensor="accelerometer", columns=None),
            settings=settings,
            whole=True,  # the samples between the still blocks may widen the magnetometer's coverage
            max_spool=options.log.max_spool,
        ) as (path, acc, seg):
            mag = readings.read_log(path, options.read, use_time=options.read.rate is None, name=acc.layout.name)
    if acc.layout.sensor_names == mag.layout.sensor_names:
        raise InputError(
            f"the accelerometer and the magnetometer would both be read from columns "
            f"{', '.join(acc.layout.sensor_names)}: a magnetometer's --log needs a log with both sensors' columns",
            file=mag.layout.name,
            hint="log both sensors (ax ... mx ...), or solve the magnetometer's captures with --poses",
        )
    if not np.array_equal(acc.rows, mag.rows):
        raise InputError(
            "the accelerometer and the magnetometer are not read on the same rows (an interleaved log?)",
            file=mag.layout.name,
        )
    kept = sorted(seg.kept, key=lambda b: b.first)
    segmenting.enough_blocks(acc, seg, 1)
    samples = [mag.block(b.number, b.first, b.last) for b in kept]
    notes = [f"the magnetometer's samples of the {len(kept)} still blocks the accelerometer found"]
    if table is not None:
        notes = [f"{acc.layout.name}: a table of {len(kept)} orientations, one averaged reading a row: each row a "
                 "still block"]  # fmt: skip
        return MagLog(samples, acc, mag, kept, seg, notes, accel, table=True)
    between = _between(mag, kept)
    if between is not None:
        still, every = _coverage(np.concatenate([s.values for s in samples])), _coverage(mag.values)
        if every >= still + WIDER:
            samples.append(between)
            notes[0] += (
                f", and the {len(between.values)} samples between them, which widen its coverage from "
                f"{still:.0%} to {every:.0%}"
            )
    return MagLog(samples, acc, mag, kept, seg, notes, accel)


def _between(mag: Log, kept: list[Block]) -> Samples | None:
    """The magnetometer's samples outside the still blocks, as one capture (None: there are none)."""
    outside = np.ones(len(mag.values), dtype=bool)
    for b in kept:
        outside[b.first : b.last + 1] = False
    if not outside.any():
        return None
    where = np.flatnonzero(outside)
    return Samples(mag.layout, mag.values[where], (int(mag.rows[where[0]]), int(mag.rows[where[-1]])), mag.sha256, None)


def _coverage(values: FloatArray) -> float:
    """The share of directions the samples reach about the sphere nearest them (as the ellipsoid
    fit's coverage check measures it)."""
    d = values - solvers.sphere_centre(values)
    return solvers.coverage(d / np.maximum(np.linalg.norm(d, axis=1), 1e-300)[:, None])


def dip_check(found: MagLog, cal: Calibration, limits: Limits) -> tuple[dict[str, object], list[Finding]] | None:
    """The dip angle of each still block through both calibrations, against the model's (the
    calibration's ``earth_field``): the ``dip`` part of the file and the dip_angle limit's
    failures. None without an accelerometer calibration or with fewer than DIP_MIN_BLOCKS blocks."""
    accel = found.accel
    if accel is None or len(found.blocks) < DIP_MIN_BLOCKS:
        return None
    acc_means = np.array([found.acc.values[b.first : b.last + 1].mean(axis=0) for b in found.blocks])
    mag_means = np.array([found.mag.values[b.first : b.last + 1].mean(axis=0) for b in found.blocks])
    up = (acc_means - accel.offset) @ accel.matrix.T
    field = (mag_means - cal.offset) @ cal.matrix.T
    d = earth.dip(up, field)
    model_field = cal.fields.get("earth_field")
    inclination = model_field.get("inclination_deg") if isinstance(model_field, dict) else None
    model = 90.0 - float(inclination) if isinstance(inclination, int | float) else None
    part: dict[str, object] = {
        "blocks": len(d.angles),
        "mean_deg": round(d.mean, 4),
        "spread_deg": round(d.spread, 4),
        "uncertainty_deg": round(d.uncertainty, 4),
        "model_deg": None if model is None else round(model, 4),
        "model_uncertainty_deg": None if model is None else _inclination_error(model_field),
        "difference_deg": None if model is None else round(d.mean - model, 4),
        "angles_deg": [round(float(a), 3) for a in d.angles],
        "accelerometer": accel.path,
    }
    return part, gate.dip_failures(limits, d.angles, model)


def _inclination_error(part: object) -> float | None:
    """The inclination error (1 sigma, degrees) of the release that gave the calibration's
    ``earth_field`` (each release's own: 0.20° for WMM2025, 0.21° for WMM2020 ...; None unknown)."""
    release = earth.release_named(part.get("model")) if isinstance(part, dict) else None
    return None if release is None or release.error is None else release.error["inclination_deg"]
