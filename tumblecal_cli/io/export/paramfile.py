"""Autopilot parameter files (``tumblecal export --format ardupilot | px4``): a calibration's
offsets and scales as ArduPilot's ``INS_``/``COMPASS_`` parameters in a ``.parm`` file, or PX4's
``CAL_`` parameters in a QGroundControl ``.params`` file; a ``thermal`` block as ``INS_TCAL``
or ``TC_A``/``TC_G`` parameters (docs/commands/export-import.md).

Each firmware's own correction, which the mapping from ``corrected = M (raw - b)`` follows (the
sources, file and commit, are in docs/sources.md):

- ArduPilot accelerometer (``_rotate_and_correct_accel``): ``(raw - INS_ACCOFFS) * INS_ACCSCAL``
  per axis; gyroscope (``_rotate_and_correct_gyro``): ``raw - INS_GYROFFS``; compass
  (``AP_Compass_Backend::correct_field``): ``DIA/ODI * (COMPASS_SCALE * (raw + COMPASS_OFS))``,
  the offset *added*, the matrix symmetric. m/s^2, rad/s, mGauss.
- PX4 (``src/lib/sensor_calibration``, ``Correct``): accelerometer ``(raw - OFF) .* SCALE``,
  gyroscope ``raw - OFF``, magnetometer ``S (raw - OFF)`` with S symmetric (``XSCALE`` … on the
  diagonal, ``XODIAG`` = S01, ``YODIAG`` = S02, ``ZODIAG`` = S12). m/s^2, rad/s, gauss.

What a firmware cannot hold (a rotation, cross-axis terms, a gyroscope's scale) is dropped
by the polar decomposition ``M = U P`` (U a rotation, P symmetric positive definite), and its
size said in a comment and a warning.

Both files are read by loaders that skip a line starting with ``#`` (docs/sources.md); every comment
line is ASCII and at most 97 characters, as ArduPilot's own defaults-file reader reads lines
of up to 98 (``AP_Param::read_param_defaults_file``: ``fgets(line, sizeof(line)-1)``).
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from tumblecal_cli.core import catalog
from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.axes import Axes
from tumblecal_cli.core.quantities import COMMON, QUANTITY, factor
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.calfiles.calfile import Calibration
from tumblecal_cli.io.export.contract import Exported, Exporter, ExportOptions
from tumblecal_cli.io.export.formats import FLOAT32_MAX, provenance, safe_comment
from tumblecal_cli.version import __version__

NAMES = {"ardupilot": "ArduPilot", "px4": "PX4"}
#: The units each firmware's parameters are in (INS_ACCOFFS "m/s/s", INS_GYROFFS "rad/s",
#: COMPASS_OFS "mGauss"; PX4's CAL_ACC/GYRO/MAG _XOFF "m/s^2", "rad/s", "gauss"), and the factor
#: from the base units of core.quantities (m/s^2, rad/s, gauss) to them.
FIRMWARE_UNITS = {
    ("ardupilot", "accelerometer"): ("m/s^2", 1.0),
    ("ardupilot", "gyroscope"): ("rad/s", 1.0),
    ("ardupilot", "magnetometer"): ("mGauss", 1000.0),
    ("px4", "accelerometer"): ("m/s^2", 1.0),
    ("px4", "gyroscope"): ("rad/s", 1.0),
    ("px4", "magnetometer"): ("gauss", 1.0),
}
#: --instance: the firmware's numbering (ArduPilot's IMU and compass 1-3, PX4's CAL_ slots 0-3
#: (MAX_SENSOR_COUNT 4), its TC_ slots 0-2).
INSTANCES = {("ardupilot", False): (1, 3), ("ardupilot", True): (1, 3), ("px4", False): (0, 3), ("px4", True): (0, 2)}
#: A loss below this (relative) is float rounding, not a term the firmware drops.
NEGLIGIBLE = 1e-6
#: ArduPilot's thermal reference temperature and parameter scale (AP_InertialSensor_tempcal.cpp:
#: TEMP_REFERENCE 35.0, SCALE_FACTOR 1.0e6).
ARDUPILOT_T_REF = 35.0
ARDUPILOT_SCALE = 1.0e6
#: ArduPilot's compass offset limit by default (COMPASS_OFFS_MAX, AP_COMPASS_OFFSETS_MAX_DEFAULT),
#: which its arming check holds the offsets' length to ("Compass offsets too high").
COMPASS_OFFS_MAX = 1800.0


def instance_range(fmt: str, cal: Calibration) -> tuple[int, int]:
    """The --instance numbers ``fmt`` has for this calibration (docs/commands/export-import.md)."""
    return INSTANCES[fmt, cal.thermal is not None]


def write(cal: Calibration, fmt: str, instance: int | None) -> Exported:
    """The parameter file of ``cal`` for ``fmt`` (ardupilot, px4): its thermal block's drift
    where it has one, else its offsets and scales; ``instance`` None is the firmware's first."""
    low, high = instance_range(fmt, cal)
    number = low if instance is None else instance
    if not low <= number <= high:
        what = "TC_A/TC_G" if fmt == "px4" and cal.thermal is not None else "the firmware's"
        raise InputError(f"--instance for {fmt} is {low} to {high} ({what} numbering), got {number}")
    if cal.thermal is not None:
        return _thermal(cal, fmt, number)
    return _ardupilot(cal, number) if fmt == "ardupilot" else _px4(cal, number)


# -- units and what the firmware holds ----------------------------------------------------------


@dataclass(frozen=True)
class Mapped:
    """A calibration in a firmware's units and terms: ``offset`` b and ``held`` the matrix the
    firmware applies (diagonal, symmetric, or the identity) in ``units``, ``reference`` the
    stimulus in them; ``lost`` what it cannot hold (a comment and a warning), ``notes`` how the
    raw units were taken (a comment and a note), ``conversion`` the factors (a comment)."""

    offset: FloatArray
    held: FloatArray
    units: str
    reference: float
    lost: str | None
    notes: tuple[str, ...]
    conversion: str


def mapped(cal: Calibration, fmt: str) -> Mapped:
    """``cal`` in ``fmt``'s units, with the part of M the firmware holds.

    With raw' = k_in raw and corrected' = k_out corrected in the firmware's units,
    corrected' = (k_out / k_in) M (raw' - k_in b). Of ``M' = U P`` (polar decomposition) an
    accelerometer keeps diag(P), a magnetometer P, a gyroscope nothing (H). What is lost, relative
    to the reading: the corrected vector's error, the largest singular value of ``H M'^-1 - I``;
    its length's, the largest ``|s - 1|`` of the singular values s of ``H M'^-1``; and U's angle.
    """
    k_in, k_out, notes = _factors(cal, fmt)
    units, _ = FIRMWARE_UNITS[fmt, cal.sensor]
    raw, out = (cal.input_units or cal.units or "").strip(), (cal.units or "").strip()
    offset, in_axes = _firmware_axes(cal, fmt)
    matrix = (k_out / k_in) * in_axes
    if not np.isfinite(matrix).all() or np.linalg.det(matrix) <= 0:
        raise InputError(
            "its matrix mirrors the axes (det M <= 0): no positive scale or symmetric matrix the firmware "
            "holds does that",
            file=cal.path,
            hint="check the order and signs of the calibration's columns",
        )
    rotation, symmetric = polar(matrix)
    held = {
        "accelerometer": np.diag(np.diag(symmetric)),
        "magnetometer": symmetric,
        "gyroscope": np.eye(3),
    }[cal.sensor]
    kept = held @ np.linalg.inv(matrix)
    total = float(np.linalg.norm(kept - np.eye(3), 2))
    length = float(np.abs(np.linalg.svd(kept, compute_uv=False) - 1).max())
    if k_in == k_out:
        conversion = f"units: {out} in and out" + (f", x {k_out:.9g} to {units}" if k_out != 1 else f", as {units}")
    else:
        conversion = f"units: raw {raw} x {k_in:.9g}, corrected {out} x {k_out:.9g}, to {units}"
    reference = float(cal.reference) * k_out
    sizes = Loss(total, length, angle(rotation))
    lost = _lost(cal.sensor, fmt, sizes, (units, reference)) if total > NEGLIGIBLE else None
    return Mapped(k_in * offset, held, units, reference, lost, tuple(notes), conversion)


#: The autopilots' sensor rotations (MAVLink's MAV_SENSOR_ORIENTATION, which ArduPilot's
#: COMPASS_ORIENT and PX4's CAL_*_ROT number alike) that turn by right angles: value, roll,
#: pitch, yaw (degrees); ``v_body = Rz(yaw) Ry(pitch) Rx(roll) v_sensor``.
ROTATIONS = (
    (0, 0, 0, 0), (2, 0, 0, 90), (4, 0, 0, 180), (6, 0, 0, 270), (8, 180, 0, 0), (10, 180, 0, 90),
    (12, 0, 180, 0), (14, 180, 0, 270), (16, 90, 0, 0), (18, 90, 0, 90), (20, 270, 0, 0), (22, 270, 0, 90),
    (24, 0, 90, 0), (25, 0, 270, 0), (26, 0, 180, 90), (27, 0, 180, 270), (28, 90, 90, 0), (29, 180, 90, 0),
    (30, 270, 90, 0), (31, 90, 180, 0), (32, 270, 180, 0), (33, 90, 270, 0), (34, 180, 270, 0),
    (35, 270, 270, 0), (36, 90, 180, 90), (37, 90, 0, 270),
)  # fmt: skip


def rotation_value(axes: Axes) -> int | None:
    """The MAV_SENSOR_ORIENTATION value that states ``axes`` (None: a mirror, which none does)."""
    for value, roll, pitch, yaw in ROTATIONS:
        r, p, y = (math.radians(a) for a in (roll, pitch, yaw))
        rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
        ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
        rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
        if np.allclose(rz @ ry @ rx, axes.matrix, atol=1e-9):
            return value
    return None


def _firmware_axes(cal: Calibration, fmt: str) -> tuple[FloatArray, FloatArray]:
    """The offset and M in the axes the firmware corrects in: PX4 corrects in the sensor's and
    rotates after (CAL_*_ROT); ArduPilot rotates a compass first (COMPASS_ORIENT) and corrects it
    in the body's, and corrects an IMU in its driver's axes before the board's rotation
    (AP_InertialSensor_Backend::_rotate_and_correct_accel): the sensor's."""
    if cal.axes is None:
        return cal.offset, cal.matrix
    if rotation_value(cal.axes) is None:
        raise InputError(
            f"its axes {cal.axes.text} mirror the sensor's (a left-handed sensor): no {fmt} rotation does that",
            file=cal.path,
            hint="check the signs of --axes, or export it as a matrix (c-header)",
        )
    if fmt == "px4" or cal.sensor != "magnetometer":
        return cal.offset, cal.sensor_matrix
    p = cal.axes.matrix
    return p @ cal.offset, cal.matrix @ p.T


def polar(matrix: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``matrix = U P``: U orthogonal, P symmetric positive semi-definite (from the SVD W S V^T:
    U = W V^T, P = V S V^T)."""
    w, s, vt = np.linalg.svd(matrix)
    symmetric = vt.T @ np.diag(s) @ vt
    return w @ vt, (symmetric + symmetric.T) / 2


def angle(rotation: FloatArray) -> float:
    """A rotation matrix's angle, degrees."""
    return math.degrees(math.acos(max(-1.0, min(1.0, (float(np.trace(rotation)) - 1) / 2))))


@dataclass(frozen=True)
class Loss:
    """What dropping part of M costs, relative to the reading: the corrected vector's error, its
    length's error, and the angle of the rotation dropped (degrees)."""

    total: float
    length: float
    degrees: float


#: Where each firmware levels the board instead (roll and pitch trims).
LEVEL = {"ardupilot": "AHRS_TRIM_X/Y", "px4": "SENS_BOARD_X_OFF/Y_OFF"}


def _lost(sensor: str, fmt: str, loss: Loss, at: tuple[str, float]) -> str:
    units, reference = at

    def size(share: float) -> str:
        return f"{share:.3%}" + (f" ({share * reference:.3g} {units} at {reference:.6g} {units})" if reference else "")

    if sensor == "magnetometer":
        what = "COMPASS_DIA/ODI hold" if fmt == "ardupilot" else "CAL_MAG SCALE/ODIAG hold"
        return (
            f"a {loss.degrees:.3g} deg rotation NOT written ({what} a symmetric matrix): the field's direction "
            f"is off by up to {loss.degrees:.3g} deg, {size(loss.total)} of it, its length not at all"
        )
    if sensor == "gyroscope":
        return (
            f"scale and cross-axis terms NOT written ({NAMES[fmt]} takes a gyroscope's offsets only): the rate is "
            f"off by up to {loss.total:.3%} of it"
        )
    parts = []
    if loss.length > NEGLIGIBLE:
        parts.append(f"cross-axis terms (the reading's length is off by up to {size(loss.length)})")
    if loss.degrees >= 1e-3:
        parts.append(f"a {loss.degrees:.3g} deg rotation to the poses' frame (level the board with {LEVEL[fmt]})")
    return f"{' and '.join(parts)} NOT written ({NAMES[fmt]} has one scale per axis)"


def _corrected_units(cal: Calibration, fmt: str, solve: str) -> float:
    """One of the calibration's corrected units in the base unit of what it measures (core.quantities:
    m/s^2, rad/s, gauss), else an InputError saying to ``solve`` (the calibration, or its base)
    with --units naming them."""
    found = factor(cal.sensor, (cal.units or "").strip())
    if found is None:
        raise InputError(
            f"--format {fmt} writes {FIRMWARE_UNITS[fmt, cal.sensor][0]}: the calibration's corrected units are "
            + ("not recorded" if cal.units is None else f"{cal.units!r}, not one of {_common(cal.sensor)}"),
            file=cal.path,
            hint=f"{solve} with --units naming them (and --reference in them)",
        )
    return found


def _common(sensor: str) -> str:
    """The unit names a message lists for ``sensor`` (core.quantities.COMMON; every other name is taken too)."""
    return ", ".join(COMMON[QUANTITY[sensor]])


def _factors(cal: Calibration, fmt: str) -> tuple[float, float, list[str]]:
    """k_in and k_out, the factors from the calibration's raw and corrected units to the
    firmware's; a note when the raw units are not recorded and taken as the corrected ones."""
    firmware, scale = FIRMWARE_UNITS[fmt, cal.sensor]
    out = _corrected_units(cal, fmt, "solve")
    named, raw = (cal.units or "").strip(), (cal.input_units or "").strip()
    if raw:
        k_raw = factor(cal.sensor, raw)
        if k_raw is None:
            raise InputError(
                f"--format {fmt}: {NAMES[fmt]} corrects readings in {firmware}, and the calibration's raw units "
                f"are {cal.input_units!r}, not one of {_common(cal.sensor)}",
                file=cal.path,
                hint="calibrate from readings in the firmware's units (its own log), or solve with --input-units "
                "naming them",
            )
        return k_raw * scale, out * scale, []
    gains = [float(g) for g in cal.gain]
    if catalog.fixes_gains(cal.method) or all(abs(g - 1.0) < 0.2 for g in gains):
        return (
            out * scale,
            out * scale,
            [f"raw units not recorded: taken as {named}, as the gains near 1 say"],
        )
    raise InputError(
        f"--format {fmt}: the calibration does not say its raw units, and its gains "
        f"({', '.join(f'{g:.4g}' for g in gains)}) say they are not its corrected {named}",
        file=cal.path,
        hint=f"{NAMES[fmt]} corrects readings in {firmware}: solve with --input-units naming the raw units",
    )


# -- ArduPilot ----------------------------------------------------------------------------------


def _ardupilot(cal: Calibration, n: int) -> Exported:
    """INS_ACC<n>OFFS/SCAL, INS_GYR<n>OFFS or COMPASS_OFS<n>/DIA<n>/ODI<n>/SCALE<n> as NAME,VALUE."""
    m = mapped(cal, "ardupilot")
    s = "" if n == 1 else str(n)
    notes = list(m.notes)
    if cal.sensor == "accelerometer":
        formula = f"corrected = (raw - INS_ACC{s}OFFS) * INS_ACC{s}SCAL per axis"
        params = _axes(f"INS_ACC{s}OFFS_", m.offset) + _axes(f"INS_ACC{s}SCAL_", np.diag(m.held))
        notes += _outside(params, {f"INS_ACC{s}OFFS_": (-3.5, 3.5), f"INS_ACC{s}SCAL_": (0.8, 1.2)}, "ArduPilot")
        if not m.offset.any():
            notes.append(
                "warning: ArduPilot reads offsets of exactly 0 as an accelerometer never calibrated "
                "('3D Accel calibration needed', accel_calibrated_ok_all)"
            )
        usage = [
            f"ArduPilot uses them only for the accelerometer whose id is saved in INS_ACC{s}_ID (by its own "
            f"calibration; on a board never calibrated, set INS_ACC{s}_ID to the value it shows)",
            f"with temperature calibration on (INS_TCAL{n}_ENABLE), set INS_ACC{n}_CALTEMP to the temperature "
            "of this calibration: ArduPilot takes the drift from there",
        ]
    elif cal.sensor == "gyroscope":
        formula = f"corrected = raw - INS_GYR{s}OFFS"
        params = _axes(f"INS_GYR{s}OFFS_", m.offset)
        notes.append(
            f"ArduPilot measures INS_GYR{s}OFFS again at each boot unless INS_GYR_CAL is 0 (Never): set it to "
            "keep these"
        )
        usage = [
            f"ArduPilot uses them only for the gyroscope whose id is saved in INS_GYR{s}_ID",
            f"with temperature calibration on (INS_TCAL{n}_ENABLE), set INS_GYR{n}_CALTEMP to the temperature "
            "of this calibration: ArduPilot takes the drift from there",
        ]
    else:
        formula = f"corrected = DIA{s}/ODI{s} * (COMPASS_SCALE{s} * (raw + COMPASS_OFS{s})): the offset is ADDED"
        held = m.held
        params = [
            *_axes(f"COMPASS_OFS{s}_", -m.offset),
            *_axes(f"COMPASS_DIA{s}_", np.diag(held)),
            *_axes(f"COMPASS_ODI{s}_", np.array([held[0, 1], held[0, 2], held[1, 2]])),
            (f"COMPASS_SCALE{s}", 1.0),
            *_motor(cal, m, f"COMPASS_MOT{s}_"),
        ]
        length = float(np.linalg.norm(m.offset))
        if length > COMPASS_OFFS_MAX:
            notes.append(
                f"warning: COMPASS_OFS{s} is {length:.0f} mGauss long, above COMPASS_OFFS_MAX's default "
                f"{COMPASS_OFFS_MAX:.0f}: ArduPilot's arming check refuses it unless COMPASS_OFFS_MAX is raised"
            )
        usage = [
            f"ArduPilot uses them for the compass whose id is COMPASS_DEV_ID{s}; COMPASS_SCALE{s} is 1, "
            "DIA/ODI hold the scales (older firmware has no COMPASS_SCALE: a loader may call it unknown)"
        ]
        if cal.current is not None:
            formula += f", plus COMPASS_MOT{s} * current (A) after DIA/ODI"
            usage.append(
                f"COMPASS_MOTCT 2: the motor offset COMPASS_MOT{s} (mGauss/A) times the battery monitor's current "
                "(AP_Compass_Backend::correct_field); COMPASS_MOTCT applies to every compass"
            )
    head = [
        f"ArduPilot {cal.sensor} calibration of {'compass' if cal.sensor == 'magnetometer' else 'IMU'} {n}, "
        f"written by tumblecal {__version__}{_source(cal)}",
        f"{formula}, in {m.units}",
        *provenance(cal),
        *_says(m),
        *usage,
        f"axes: the captures' {', '.join(cal.columns)} as ArduPilot's X, Y, Z, after its driver's rotation",
        *_ardupilot_axes(cal, s),
    ]
    lines = comments(head + [x.removeprefix("warning: ") for x in notes if x not in m.notes])
    lines += [f"{name},{_value(value, name, cal.path)}" for name, value in params]
    if cal.axes is not None and cal.sensor == "magnetometer":
        lines.append(f"COMPASS_ORIENT{s},{rotation_value(cal.axes)}")
    return Exported("\n".join(lines) + "\n", _with_loss(m, notes))


def _ardupilot_axes(cal: Calibration, s: str) -> list[str]:
    """What a calibration's --axes become in ArduPilot's file."""
    if cal.axes is None:
        return []
    if cal.sensor == "magnetometer":
        return [
            f"the calibration's axes {cal.axes.text} are COMPASS_ORIENT{s} {rotation_value(cal.axes)}, applied before "
            "the offsets: COMPASS_OFS and DIA/ODI are in the body's axes; ArduPilot applies COMPASS_ORIENT to an "
            "external compass (COMPASS_EXTERNAL 1), an internal one turns with AHRS_ORIENTATION"
        ]
    return [
        f"the calibration's axes {cal.axes.text}: ArduPilot corrects an IMU in its driver's axes, so the offsets and "
        "scales are the sensor's; its rotation into the body's is the board's (AHRS_ORIENTATION), not written"
    ]


# -- PX4 ----------------------------------------------------------------------------------------


def _px4(cal: Calibration, n: int) -> Exported:
    """CAL_ACC<n>_xOFF/xSCALE, CAL_GYRO<n>_xOFF or CAL_MAG<n>_xOFF/xSCALE/xODIAG in
    QGroundControl's parameter-file layout."""
    m = mapped(cal, "px4")
    kind = {"accelerometer": "ACC", "gyroscope": "GYRO", "magnetometer": "MAG"}[cal.sensor]
    head = f"CAL_{kind}{n}_"
    notes = list(m.notes)
    params = [(f"{head}{a}OFF", float(v)) for a, v in zip("XYZ", m.offset, strict=True)]
    rotated = None if cal.axes is None else rotation_value(cal.axes)
    if cal.sensor == "accelerometer":
        formula = f"corrected = (raw - {head}xOFF) * {head}xSCALE per axis"
        params += [(f"{head}{a}SCALE", float(v)) for a, v in zip("XYZ", np.diag(m.held), strict=True)]
    elif cal.sensor == "magnetometer":
        formula = f"corrected = S (raw - {head}xOFF), S symmetric: xSCALE diagonal, XODIAG S01, YODIAG S02, ZODIAG S12"
        held = m.held
        params += [(f"{head}{a}SCALE", float(v)) for a, v in zip("XYZ", np.diag(held), strict=True)]
        params += [
            (f"{head}{a}ODIAG", float(v)) for a, v in zip("XYZ", (held[0, 1], held[0, 2], held[1, 2]), strict=True)
        ]
        if cal.current is not None:
            formula = (
                f"corrected = S (raw + {head}xCOMP * current (kA) - {head}xOFF), S symmetric: xSCALE diagonal, "
                "XODIAG S01, YODIAG S02, ZODIAG S12"
            )
            params += [(f"{head}{a}COMP", v) for a, v in _motor(cal, m, "")]
            notes.append(
                "CAL_MAG_COMP_TYP 2: power compensation by battery_status instance 0's current_a / 1000 (kA) "
                "(VehicleMagnetometer.cpp); it applies to every magnetometer slot"
            )
    else:
        formula = f"corrected = raw - {head}xOFF"
        notes.append(
            "PX4 updates the gyroscope's offsets itself while the vehicle is still unless IMU_GYRO_CAL_EN is 0"
        )
    if cal.sensor != "gyroscope":
        notes += _outside(
            params, {f"{head}XSCALE": (0.1, 3.0), f"{head}YSCALE": (0.1, 3.0), f"{head}ZSCALE": (0.1, 3.0)}, "PX4"
        )
    text = [
        f"PX4 {cal.sensor} calibration of slot {n}, written by tumblecal {__version__}{_source(cal)}",
        f"{formula}, in {m.units}",
        *provenance(cal),
        *_says(m),
        f"PX4 applies slot {n} to the sensor whose device id {head}ID holds: tumblecal does not know it. If the "
        f"sensor was calibrated in slot {n} before, it is set; else set {head}ID to its device id (the device_id "
        "of its sensor_ topic in a log)",
        "reboot after loading: PX4 takes a changed vector only if it moves by more than 0.01",
        f"axes: the captures' {', '.join(cal.columns)} as PX4's X, Y, Z, before CAL_{kind}{n}_ROT/SENS_BOARD_ROT"
        + (
            ""
            if cal.axes is None
            else f"; CAL_{kind}{n}_ROT {rotated} is the calibration's axes {cal.axes.text} (PX4 "
            "applies it to an external sensor; an internal one's is -1, turned by SENS_BOARD_ROT)"
        ),
    ]
    lines = comments(text + [x.removeprefix("warning: ") for x in notes if x not in m.notes])
    lines.append("# Vehicle-Id\tComponent-Id\tName\tValue\tType")
    lines += [f"1\t1\t{name}\t{_value(value, name, cal.path)}\t9" for name, value in params]
    if cal.current is not None:  # int32 (type 6): 2, the current of battery instance 0
        lines.append("1\t1\tCAL_MAG_COMP_TYP\t2\t6")
    if rotated is not None:  # --axes: the sensor's rotation, int32
        lines.append(f"1\t1\t{head}ROT\t{rotated}\t6")
    return Exported("\n".join(lines) + "\n", _with_loss(m, notes))


# -- current compensation (docs/current.md) ---------------------------------------------------


def _motor(cal: Calibration, m: Mapped, prefix: str) -> list[tuple[str, float]]:
    """A current block's parameters: ArduPilot's ``COMPASS_MOT`` (``prefix`` COMPASS_MOT<n>_,
    mGauss/A), added to the corrected field (``mag = DIA/ODI (raw + OFS); mag += MOT * current``,
    AP_Compass_Backend::correct_field), so ``-P k`` with P the matrix it holds; PX4's
    ``CAL_MAG<n>_xCOMP`` (``prefix`` ""; gauss/kA) added to the raw reading before its offset
    (``Correct``: ``S ((raw + power * COMP) - OFF)``, power = current_a * 0.001), so ``-1000 k``.
    ArduPilot's ``COMPASS_MOTCT`` 2 (current) is one line of its own. Nothing without a block."""
    if cal.current is None:
        return []
    k_in, _, _ = _factors(cal, "ardupilot" if prefix else "px4")
    per_amp = k_in * np.asarray(cal.current.per_amp, dtype=np.float64)  # firmware raw units per ampere
    if prefix:
        return [("COMPASS_MOTCT", 2.0), *_axes(prefix, -(m.held @ per_amp))]
    return list(zip("XYZ", (float(v) for v in -1000.0 * per_amp), strict=True))


# -- shared -------------------------------------------------------------------------------------


def _source(cal: Calibration) -> str:
    return f" from {cal.path}" if cal.path else ""


def _axes(prefix: str, values: FloatArray) -> list[tuple[str, float]]:
    return [(f"{prefix}{a}", float(v)) for a, v in zip("XYZ", values, strict=True)]


def _says(m: Mapped) -> list[str]:
    return [m.conversion, *m.notes, *([m.lost] if m.lost else [])]


def _with_loss(m: Mapped, notes: list[str]) -> tuple[str, ...]:
    return tuple(([f"warning: {m.lost}"] if m.lost else []) + notes)


def _outside(params: list[tuple[str, float]], ranges: dict[str, tuple[float, float]], name: str) -> list[str]:
    """A warning for each value outside the range the firmware documents for its parameter."""
    out = []
    for param, value in params:
        for prefix, (low, high) in ranges.items():
            if param.startswith(prefix) and not low <= value <= high:
                out.append(f"warning: {param} = {value:.6g} is outside {name}'s range for it, {low:g} to {high:g}")
    return out


def comments(texts: Iterable[str]) -> list[str]:
    """``# `` lines every loader skips (docs/commands/export-import.md): ASCII only (another
    character written ``\\uXXXX``), no line breaks, at most 97 characters (a longer text wrapped)."""
    out: list[str] = []
    for text in texts:
        plain = "".join(
            c if " " <= c <= "~" else f"\\u{ord(c):04x}" if ord(c) < 0x10000 else f"\\U{ord(c):08x}"
            for c in safe_comment(text)
        )
        out += [f"# {part}" for part in textwrap.wrap(plain, 95, break_on_hyphens=False)] or ["#"]
    return out


def _value(value: float, name: str, path: str | None) -> str:
    if not math.isfinite(value) or abs(value) > FLOAT32_MAX:
        raise InputError(f"{name} = {value!r} does not fit a float parameter", file=path)
    return f"{value + 0.0:.9g}"  # + 0.0: a -0.0 (a zero offset negated) is written 0


# -- thermal drift ------------------------------------------------------------------------------


def firmware_drift(cal: Calibration, fmt: str) -> tuple[FloatArray, str]:
    """The offset drift coefficients (3, order) in the firmware's corrected units per °C^k:
    ``M @ c_k`` (corrected = M (raw - b - drift(T)) = M (raw - b) - M drift(T)) times the factor
    from the calibration's ``units``; and those units' name."""
    assert cal.thermal is not None
    if cal.sensor == "magnetometer":
        raise InputError(f"--format {fmt} takes an accelerometer's or a gyroscope's thermal block", file=cal.path)
    name, _ = FIRMWARE_UNITS[fmt, cal.sensor]
    k_out = _corrected_units(cal, fmt, "solve the base calibration")
    coeffs: FloatArray = k_out * (cal.matrix @ np.asarray(cal.thermal.offset, dtype=np.float64))
    return coeffs, name


def _shifted(coeffs: FloatArray, shift: float) -> FloatArray:
    """Coefficients (3, order) of sum_k a_k x^k (k >= 1) re-expanded in d = x - shift:
    b_m = sum_{k >= m} a_k C(k, m) shift^(k - m), for m >= 1 (the constant dropped)."""
    order = coeffs.shape[1]
    out = np.zeros_like(coeffs)
    for m in range(1, order + 1):
        for k in range(m, order + 1):
            out[:, m - 1] += coeffs[:, k - 1] * math.comb(k, m) * shift ** (k - m)
    return out


def _gain_note(cal: Calibration) -> list[str]:
    """What the firmware cannot hold: a temperature-dependent gain."""
    assert cal.thermal is not None
    thermal = cal.thermal
    d = np.array([thermal.range[0], thermal.range[1]]) - thermal.reference_temperature
    powers = np.column_stack([d ** (k + 1) for k in range(thermal.order)])
    worst = np.abs(powers @ np.asarray(thermal.gain, dtype=np.float64).T).max(axis=0)
    if not worst.any():
        return []
    figures = ", ".join(f"{a} {w:.3%}" for a, w in zip("xyz", worst, strict=True))
    return [f"gain drift NOT written (the firmware has no temperature-dependent scale): largest {figures}"]


def _thermal(cal: Calibration, fmt: str, n: int) -> Exported:
    lost = _gain_note(cal)
    text = _ardupilot_thermal(cal, n, lost) if fmt == "ardupilot" else _px4_thermal(cal, n, lost)
    return Exported(text, tuple(f"warning: {line}" for line in lost))


def _ardupilot_thermal(cal: Calibration, instance: int, lost: list[str]) -> str:
    """ArduPilot's INS_TCAL<n>_* parameters (AP_InertialSensor_tempcal.cpp), as NAME,VALUE lines.

    ArduPilot corrects ``v -= P(T - 35) - P(CALTEMP - 35)`` with ``P(d) = (c1 d + c2 d^2 + c3 d^3)
    1e-6`` (``polynomial_eval``), T and CALTEMP (INS_ACCn_CALTEMP / INS_GYRn_CALTEMP, set by its own
    calibration) clamped to [TMIN, TMAX], before its offsets and scales, in m/s^2 or rad/s. Our
    drift is zero at T_ref, so P is the drift re-expanded about 35 °C without its constant: then
    P(T - 35) - P(CALTEMP - 35) = drift(T) - drift(CALTEMP), right whatever CALTEMP is.
    """
    coeffs, units = firmware_drift(cal, "ardupilot")
    assert cal.thermal is not None
    thermal = cal.thermal
    shifted = _shifted(coeffs, ARDUPILOT_T_REF - thermal.reference_temperature) * ARDUPILOT_SCALE
    kind = "ACC" if cal.sensor == "accelerometer" else "GYR"
    head = f"INS_TCAL{instance}_"
    lines = [
        *comments(
            [
                f"ArduPilot temperature calibration of IMU {instance} ({cal.sensor}), "
                f"written by tumblecal {__version__}",
                f"from {cal.path or 'a calibration'}: offset drift in {units} per degC^k x 1e6, "
                "about 35 degC, subtracted",
                *lost,
            ]
        ),
        f"{head}ENABLE,1",
        f"{head}TMIN,{thermal.range[0]:.2f}",
        f"{head}TMAX,{thermal.range[1]:.2f}",
    ]
    for k in range(3):
        for j, axis in enumerate("XYZ"):
            value = shifted[j, k] if k < thermal.order else 0.0
            lines.append(f"{head}{kind}{k + 1}_{axis},{_value(value, 'a thermal coefficient', cal.path)}")
    return "\n".join(lines) + "\n"


def _px4_thermal(cal: Calibration, instance: int, lost: list[str]) -> str:
    """PX4's TC_A<n>_* or TC_G<n>_* parameters (temperature_compensation module), in
    QGroundControl's parameter-file layout (vehicle, component, name, value, type; 9 float, 6 int32).

    PX4 computes ``offset = X0 + X1 d + X2 d^2 + X3 d^3``, d = clamp(T, TMIN, TMAX) - TREF
    (``calc_thermal_offsets_3D``) and corrects ``data - thermal_offset - CAL offset`` before the
    rotation to the body frame; our drift is zero at T_ref, so X0 = 0 and TREF = T_ref: the
    calibration's own offsets stay in CAL_ACC/CAL_GYRO.
    """
    coeffs, units = firmware_drift(cal, "px4")
    assert cal.thermal is not None
    thermal = cal.thermal
    kind = "A" if cal.sensor == "accelerometer" else "G"
    head = f"TC_{kind}{instance}_"
    cal_name = "CAL_ACC" if kind == "A" else "CAL_GYRO"
    lines = [
        *comments(
            [
                f"PX4 thermal compensation of {cal.sensor} {instance}, written by tumblecal {__version__}",
                f"from {cal.path or 'a calibration'}: offset drift in {units} per degC^k, subtracted",
                f"set {head}ID to the sensor's device id ({cal_name}{instance}_ID): tumblecal does not know it",
                *lost,
            ]
        ),
        "# Vehicle-Id\tComponent-Id\tName\tValue\tType",
        f"1\t1\tTC_{kind}_ENABLE\t1\t6",
    ]
    rows = [("TREF", thermal.reference_temperature), ("TMIN", thermal.range[0]), ("TMAX", thermal.range[1])]
    for k in range(4):
        for j in range(3):
            value = 0.0 if k == 0 or k > thermal.order else coeffs[j, k - 1]
            rows.append((f"X{k}_{j}", value))
    lines += [f"1\t1\t{head}{name}\t{_value(value, 'a thermal coefficient', cal.path)}\t9" for name, value in rows]
    return "\n".join(lines) + "\n"


# -- the registry's rows (io.export.registry) ----------------------------------------------------


def export_ardupilot(cal: Calibration, options: ExportOptions) -> Exported:
    return write(cal, "ardupilot", options.instance)


def export_px4(cal: Calibration, options: ExportOptions) -> Exported:
    return write(cal, "px4", options.instance)


#: The export formats of this module, by their names in io.export.registry.EXPORTS.
EXPORTERS: dict[str, Exporter] = {"ardupilot": export_ardupilot, "px4": export_px4}
