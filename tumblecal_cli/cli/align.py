"""tumblecal align: the rotation between a magnetometer's axes and an accelerometer's, or
between two or three IMUs of one board, from a log's still blocks (pipeline.align)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import typer

from tumblecal_cli.cli import render
from tumblecal_cli.cli.app import Command, app
from tumblecal_cli.cli.flags import (
    AllowCorrected,
    JsonSummary,
    LimitsFile,
    MinDuration,
    Quiet,
    Rate,
    Sensor,
    SensorKind,
    Threshold,
    Trim,
    Window,
    log_option,
)
from tumblecal_cli.core.quantities import DIP_SAID

if TYPE_CHECKING:
    from tumblecal_cli.core.alignment import Consistency, Fitted
    from tumblecal_cli.pipeline.align import ImusAligned, MagAligned

ALIGN_EXIT = """\
Exit status: 0 aligned (and within the limits); 1 an IMU differs from the first by more than
the limits file's imu_consistency (gyro_consistency for gyroscopes); 2 usage or input error
(one IMU, a calibration of the wrong sensor); 3 too few still blocks or turns, or orientations
(turns) that do not determine the rotation. Nothing is written on 2 or 3."""


@app.command(cls=Command, epilog=ALIGN_EXIT)
def align(
    logs: Annotated[
        list[str],
        typer.Argument(
            metavar="LOG...",
            help="One log with both sensors (--accel-cal, --mag-cal), or one log with several IMUs (a PX4 ULog's "
            "sensor_accel instances), or two or three logs on one clock, one IMU each.",
        ),
    ],
    accel_cal: Annotated[
        str | None,
        typer.Option("--accel-cal", metavar="FILE", help="The accelerometer's calibration (with --mag-cal)."),
    ] = None,
    mag_cal: Annotated[
        str | None,
        typer.Option(
            "--mag-cal",
            metavar="FILE",
            help="The magnetometer's calibration: align its axes to the accelerometer's (--accel-cal).",
        ),
    ] = None,
    stream: Annotated[
        list[str] | None,
        typer.Option(
            "--stream",
            metavar="NAME[:INSTANCE]",
            help="An IMU's stream, once per IMU, the first the reference (e.g. --stream sensor_accel:0 --stream "
            "sensor_accel:1). [default: every raw stream of --sensor in the log]",
        ),
    ] = None,
    cal: Annotated[
        list[str] | None,
        typer.Option("--cal", "-c", metavar="FILE", help="An IMU's calibration, once per IMU in their order."),
    ] = None,
    sensor: Sensor = SensorKind.accelerometer,
    allow_corrected: AllowCorrected = False,
    rate: Rate = None,
    window: Window = None,
    threshold: Threshold = None,
    min_duration: MinDuration = None,
    trim: Trim = None,
    max_noise: Annotated[
        float,
        log_option("--max-noise", "FRACTION", "Drop a still block whose spread is above FRACTION x its magnitude."),
    ] = 0.02,
    limits_file: LimitsFile = None,
    output: Annotated[
        str | None,
        typer.Option("--output", "-o", metavar="FILE", help="Write the alignment (JSON) here. [default: stdout]"),
    ] = None,
    aligned_mag: Annotated[
        str | None,
        typer.Option(
            "--aligned-mag",
            metavar="FILE",
            help="Write the magnetometer's calibration with the rotation in its matrix (corrected readings in the "
            "accelerometer's axes) here.",
        ),
    ] = None,
    json_summary: JsonSummary = False,
    quiet: Quiet = False,
) -> None:
    """The rotation between two sensors' axes from the still blocks of a log, with its uncertainty.

    With --accel-cal and --mag-cal: the magnetometer's axes onto the accelerometer's, from the
    angle between gravity and the field (the same in every orientation), the dip angle, and the
    heading error the rotation removes. Otherwise: each IMU's accelerometer onto the first's,
    and how far their corrected readings differ (limits file: imu_consistency); with --sensor
    gyroscope the same for gyroscopes, from their rates while the unit turns (gyro_consistency).

    \b
      tumblecal align --accel-cal acc.json --mag-cal mag.json session.csv -o align.json --aligned-mag mag-aligned.json
      tumblecal align flight.ulg --limits limits.yaml
      tumblecal align flight.ulg --stream sensor_accel:0 --stream sensor_accel:2 --cal a0.json --cal a2.json
    """
    from tumblecal_cli.core.blocks import DetectorSettings
    from tumblecal_cli.io.readspec import ReadSpec
    from tumblecal_cli.pipeline import align as alignment

    settings = DetectorSettings(window, threshold, min_duration, trim, max_noise)
    spec = ReadSpec(sensor=sensor.value, rate=rate, allow_corrected=allow_corrected)
    request = alignment.AlignRequest(logs, spec, settings, accel_cal, mag_cal, stream or [], cal or [], limits_file)
    alignment.check_outputs(request, output, aligned_mag)
    done = alignment.run(request)
    status = 1 if isinstance(done, alignment.ImusAligned) and done.failures else 0
    if aligned_mag is not None:
        alignment.write_aligned(done, aligned_mag)
    if output is not None or not json_summary:
        alignment.write(done, output or "-")
    if json_summary:
        render.print_json({"status": render.status_word(status), "exit_status": status, **alignment.document(done)})
    if not quiet:
        _tell(done)
    if status:
        raise typer.Exit(status)


def _tell(done: MagAligned | ImusAligned) -> None:
    """What people read on stderr."""
    from tumblecal_cli.pipeline.align import MagAligned

    lines = _mag_lines(done) if isinstance(done, MagAligned) else _imu_lines(done)
    for line in [*lines, *(render.note_line(n) for n in done.notes)]:
        render.say(line)


def _mag_lines(done: MagAligned) -> list[str]:
    import numpy as np

    r, fit = done.fit.rotation, done.fit
    vec = ", ".join(f"{v:+.3f} ± {s:.3f}" for v, s in zip(r.vector_deg, r.sigma_deg, strict=True))
    rms = float(np.sqrt(np.mean(fit.heading_error**2)))
    return [
        f"{done.log}: magnetometer to accelerometer, {done.blocks} still blocks in {done.orientations} orientations",
        f"{_axes_said(r)}rotation {r.angle_deg:.3f}° ± {r.angle_sigma_deg:.3f}° (rotation vector [{vec}]°; chi2 "
        f"{r.chi2:.3g})",
        f"dip {fit.dip_deg:.3f}° ± {fit.dip_sigma_deg:.3f}° ({DIP_SAID}); spread over the blocks "
        f"{np.std(fit.dip_before):.3f}° before, {np.std(fit.dip_after):.3f}° after",
        f"heading error removed: RMS {rms:.3f}°, largest {np.abs(fit.heading_error).max():.3f}°",
    ]


def _axes_said(r: Fitted) -> str:
    """A rotation near a signed permutation, as people read it: ``axes -y,-x,-z, then``."""
    return "" if r.axes is None else f"axes {r.axes.text} (the first's x, y, z as the other's), then a "


def _imu_lines(done: ImusAligned) -> list[str]:
    unit = f" {done.units}" if done.units else " (readings' units)"
    seen = f"{render.count(done.blocks, 'still block')} in {render.count(done.orientations, 'orientation')}"
    if done.turning is not None:
        t = done.turning
        seen = f"{render.count(t.samples, 'turning sample')} (faster than {t.threshold:.3g}{unit}) about {t.axes} axes"
    lines = [f"{done.reference}: the reference, {seen}"]
    for p in done.pairs:
        turned = (
            "rotation not determined"
            if p.fit is None or p.consistency_aligned is None
            else f"{_axes_said(p.fit)}rotation {p.fit.angle_deg:.3f}° ± {p.fit.angle_sigma_deg:.3f}°, once rotated "
            f"{_rms(p.consistency_aligned, unit)}"
        )
        lines.append(f"{p.stream}: consistency {_rms(p.consistency, unit)}; {turned}")
    if done.limit is not None:
        word = "FAIL" if done.failures else "PASS"
        lines.append(
            f"{word}: {done.limit_key} {done.limit:g}{unit}" + "".join(f"\n  {f.message}" for f in done.failures)
        )
    return lines


def _rms(c: Consistency, unit: str) -> str:
    """A consistency as people read it: ``0.3606 ± 0.0012 m/s^2 RMS``."""
    told = f"{c.rms:.4g} ± {c.sigma:.2g}{unit} RMS"
    if c.rms - c.unbiased <= c.sigma:
        return told
    return f"{told} ({c.unbiased:.2g} without the noise's {c.noise:.2g})" if c.unbiased else f"{told} (the noise's)"
