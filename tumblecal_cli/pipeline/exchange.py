"""Calibration files after solve: judged again (check), written for firmware or another tool
(export), and read from another tool (import)."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, TypedDict, Unpack

import numpy as np

from tumblecal_cli.core import catalog, gate, model, solvers
from tumblecal_cli.errors import InputError, control_character
from tumblecal_cli.io.calfiles import calfile, documents
from tumblecal_cli.io.export import formats, paramfile
from tumblecal_cli.pipeline.options import Triplet, keywords_known, path_of, triplet, unit_block
from tumblecal_cli.pipeline.options import limits as parse_limits

if TYPE_CHECKING:
    from tumblecal_cli.core.gate import Finding, Limits
    from tumblecal_cli.io.calfiles.calfile import Calibration
    from tumblecal_cli.io.export.formats import Peer


#: export's formats (docs/commands/export-import.md).
FORMATS = ("c-header", "registers", "imucal-json", "ros-yaml", "matlab", "ardupilot", "px4")


@dataclass
class Checked:
    """A calibration judged afresh: ``calibration`` carries the new verdict; status 0 or 1."""

    calibration: Calibration
    failures: list[Finding]
    notes: list[str] = field(default_factory=list)

    @property
    def status(self) -> int:
        return 1 if self.failures else 0


def check(
    cal: Calibration | str | os.PathLike[str],
    *,
    limits: str | None = None,
    max_offset: Triplet | None = None,
    max_gain_error: Triplet | None = None,
    nominal_gain: Triplet | None = None,
) -> Checked:
    """Judge an existing calibration file against limits again (the file is not changed), by
    the rules solve judged it by (core.gate.judge_again)."""

    given = parse_limits(limits, max_offset, max_gain_error, nominal_gain)
    if not given.judges():
        raise InputError("no limits to judge against", hint="give --limits FILE, --max-offset or --max-gain-error")
    c = calfile.resolve(cal)
    if c.verdict is not None and "nominal_offset" in c.verdict.limit_names and not any(given.nominal_offset):
        _recorded_centre(c)
        given = replace(given, nominal_offset=c.verdict.limits.nominal_offset)  # the centre solve judged it from
    notes = given.not_applying_notes(c.method)
    recorded = gate.Calibrated(
        c.method,
        c.reference,
        c.offset,
        c.matrix,
        c.gain,
        [gate.Recorded(p.name, p.face, p.mean, p.std) for p in c.poses] if c.poses else None,
        None if c.residuals is None else c.residuals.max,
        None if c.thermal is None else c.thermal.drift(),
    )
    try:
        failures = gate.judge_again(recorded, given, "; ".join(notes))
    except InputError as err:  # about this calibration: its file named
        raise InputError(err.message, file=c.path, hint=err.hint) from None
    failures += _dip_again(c, given)
    verdict = calfile.Verdict(not failures, tuple(failures), given.for_method(c.method))
    return Checked(c.with_verdict(verdict), failures, notes)


def _dip_again(c: Calibration, given: Limits) -> list[Finding]:
    """The dip_angle limit judged again on the still blocks' dip angles the file records (its
    ``dip`` part, pipeline.solve.maglog); a limit with no such part to judge is an input error."""
    if given.dip_angle is None:
        return []
    dip = c.fields.get("dip")
    angles = dip.get("angles_deg") if isinstance(dip, dict) else None
    if not (isinstance(angles, list) and angles and all(map(calfile.is_number, angles))):
        raise InputError(
            "has no dip angles to judge the dip_angle limit by",
            file=c.path,
            hint="a magnetometer solved from a --log with --accel-cal has them; judge it without dip_angle",
        )
    assert isinstance(dip, dict)
    model = dip.get("model_deg")
    centre = float(model) if calfile.is_number(model) else None
    return gate.dip_failures(given, np.array(angles, dtype=np.float64), centre)


def _recorded_centre(c: Calibration) -> None:
    """The nominal offset a verdict records is what check judges the offsets from again: one that
    is not three numbers (a hand edit) is an error, not a centre of zero."""
    assert c.verdict is not None
    written = c.verdict.as_dict()["limits"]
    centre = written.get("nominal_offset") if isinstance(written, dict) else None
    if not (isinstance(centre, list) and len(centre) == 3 and all(map(calfile.is_number, centre))):
        raise InputError(
            f"field 'verdict.limits.nominal_offset' must be 3 numbers (the centre the offsets were judged from), "
            f"got {centre!r}",
            file=c.path,
        )


class ExportKeywords(TypedDict, total=False):
    """export's options (docs/commands/export-import.md): the command line's long options in snake case."""

    prefix: str | None
    lsb: float | None
    bits: int
    register_sign: str
    gain_step: float | None
    nominal_gain: str | None
    force: bool
    instance: int | None


def export(cal: Calibration | str | os.PathLike[str], fmt: str, **options: Unpack[ExportKeywords]) -> str:
    """The text of a calibration in another format: c-header, registers, imucal-json, ros-yaml,
    matlab, or ardupilot or px4 parameters (its offsets and scales, or its thermal block)
    (docs/commands/export-import.md); ``instance`` is the firmware's number (ArduPilot from 1, PX4 from 0). What an
    autopilot cannot hold is said in the text's comments; :func:`exported` gives it apart too."""

    return exported(cal, fmt, **options).text


@dataclass(frozen=True)
class Exported:
    """An export's text, and its notes for people (a warning starts with ``warning: ``): what an
    autopilot's parameters cannot hold, a value outside the firmware's range."""

    text: str
    notes: tuple[str, ...] = ()


def exported(cal: Calibration | str | os.PathLike[str], fmt: str, **options: Unpack[ExportKeywords]) -> Exported:
    """:func:`export`, with the notes the command prints on stderr."""

    keywords_known(options, ExportKeywords, "export")
    prefix, lsb, bits = options.get("prefix"), options.get("lsb"), options.get("bits", 16)
    register_sign, gain_step = options.get("register_sign", "subtract"), options.get("gain_step")
    nominal_gain, force, instance = options.get("nominal_gain"), options.get("force", False), options.get("instance")
    _export_options(fmt, prefix, lsb, bits, register_sign, gain_step, nominal_gain)
    if instance is not None and fmt not in paramfile.FIRMWARES:
        raise InputError("--instance is for --format ardupilot and px4")
    c = calfile.resolve(cal)
    if c.failed and not force:
        calfile.refuse_failed(c, "export it", "export")
    if fmt in paramfile.FIRMWARES:
        written = paramfile.write(c, fmt, instance)
        return Exported(written.text, written.notes)
    if c.current is not None:  # docs/current.md: the firmware parameters hold it, these formats do not
        c = replace(c, current=None)
        note = f"warning: the current block (offset per ampere) is NOT written: --format {fmt} holds none"
        inner = exported(c, fmt, **options)
        return replace(inner, notes=(note, *inner.notes))
    if fmt == "registers":
        assert lsb is not None
        return Exported(_registers(c, lsb, bits, register_sign, gain_step, nominal_gain))
    writers = {
        "c-header": lambda: formats.c_header(c, prefix=prefix),
        "imucal-json": lambda: formats.imucal_json(c),
        "ros-yaml": lambda: formats.ros_yaml(c),
        "matlab": lambda: formats.matlab(c),
    }
    return Exported(writers[fmt]())


def _export_options(
    fmt: str,
    prefix: str | None,
    lsb: float | None,
    bits: int,
    register_sign: str,
    gain_step: float | None,
    nominal_gain: str | None,
) -> None:
    """export's options that go together, checked before the calibration is read."""
    if fmt not in FORMATS:
        raise InputError(f"--format: {fmt!r} is not one of {', '.join(FORMATS)}")
    if register_sign not in ("subtract", "add"):
        raise InputError(f"--register-sign: {register_sign!r} is not one of subtract, add")
    for flag, number in (("--lsb", lsb), ("--gain-step", gain_step)):
        if number is not None and (isinstance(number, bool) or not isinstance(number, int | float)):
            raise InputError(f"{flag} takes a number, got {number!r}")
    given = {"--lsb": lsb, "--gain-step": gain_step, "--nominal-gain": nominal_gain}
    if fmt != "registers":
        if extra := [flag for flag, value in given.items() if value is not None]:
            raise InputError(f"{', '.join(extra)} {'is' if len(extra) == 1 else 'are'} for --format registers")
        if bits != 16 or register_sign != "subtract":
            raise InputError("--bits and --register-sign are for --format registers")
    elif lsb is None:
        raise InputError("--format registers needs --lsb, the raw units of one register count")
    if fmt != "c-header" and prefix is not None:
        raise InputError("--prefix is for --format c-header")
    if nominal_gain is not None and gain_step is None:
        raise InputError("--nominal-gain is the gain trim's aim: it needs --gain-step")


def _registers(
    c: Calibration, lsb: float, bits: int, register_sign: str, gain_step: float | None, nominal_gain: str | None
) -> str:
    """export --format registers: offset (and gain trim) register counts, CSV."""

    if not (lsb is not None and math.isfinite(lsb) and lsb > 0):
        raise InputError(f"--lsb must be a positive number, got {lsb}")
    if gain_step is not None and not (math.isfinite(gain_step) and gain_step > 0):
        raise InputError(f"--gain-step must be a positive number, got {gain_step}")

    if gain_step is not None and catalog.fixes_gains(c.method):
        raise InputError(f"the {c.method} solver fixes the gains: there is no gain to trim", file=c.path)
    recorded = c.verdict.limits.nominal_gain if c.verdict and "nominal_gain" in c.verdict.limit_names else None
    nominal = triplet(nominal_gain or ",".join(map(str, [1, 1, 1] if recorded is None else recorded)), "--nominal-gain")
    if not (nominal > 0).all():
        raise InputError(f"--nominal-gain must be positive, got {nominal_gain}")
    rows = formats.registers(c, lsb=lsb, bits=bits, sign=register_sign, gain_step=gain_step, nominal_gain=nominal)
    return formats.registers_csv(rows)


@dataclass
class Imported:
    """Another tool's calibration read in: the Calibration, the format it was in, and notes."""

    calibration: Calibration
    format: str
    notes: list[str]


def import_peer(
    path: str | os.PathLike[str],
    *,
    fmt: str | None = None,
    sensor: str | None = None,
    reference: float | None = None,
    columns: str | Sequence[str] | None = None,
    serial: str | None = None,
) -> Imported:
    """An imucal JSON or ROS imu_calib YAML file as a tumblecal Calibration (docs/commands/export-import.md)."""

    path = path_of(path, "import_peer reads a file of another tool")
    raw = documents.read_bytes(path, "calibration file")
    as_yaml = not path.lower().endswith(".json") and raw.lstrip()[:1] != b"{"  # ROS files are YAML, any name
    doc = documents.parse_object(raw, path, "calibration file", as_yaml=as_yaml)
    found = formats.detect(doc)
    name = fmt if fmt is not None else found
    if name is None or (found is not None and found != name):
        what = "neither an imucal JSON (cal_type, K_a …) nor a ROS imu_calib YAML (SM, bias)"
        raise InputError(
            f"{what} file" if found is None else f"the file is {found}, not {name}",
            file=path,
            hint="tumblecal import reads --from imucal-json or ros-yaml",
        )
    peer = formats.read_peer(doc, name, path, sensor)
    ref = reference if reference is not None else _peer_reference(peer, path)
    if not (math.isfinite(ref) and (ref > 0 or (ref == 0 and peer.sensor == "gyroscope"))):
        raise InputError(f"--reference must be a positive number (0 for a gyroscope), got {ref}")
    if columns:
        picked = [c.strip() for c in (columns.split(",") if isinstance(columns, str) else map(str, columns))]
        if len(picked) != 3 or not all(picked) or len({c.lower() for c in picked}) != 3:
            raise InputError(f"--columns takes three different names X,Y,Z, got {columns!r}")
    elif peer.columns:
        picked = peer.columns
    elif name == "ros-yaml":
        picked = list("xyz")
    else:
        picked = [f"{'gyr' if peer.sensor == 'gyroscope' else 'acc'}_{a}" for a in "xyz"]
    if serial is None and peer.serial is not None and control_character(peer.serial):
        raise InputError(f"its serial holds a control character: {peer.serial!r}", file=path, hint="give --serial")
    who = unit_block(
        serial if serial is not None else peer.serial, peer.was.get("station"), peer.was.get("operator"), []
    )
    cal = formats.imported(peer, path=path, raw=raw, sensor=peer.sensor, reference=ref, columns=picked, unit=who)
    # what import writes, tumblecal must read back: validated as `load` validates a file
    calfile.validate(cal.to_dict(), path)
    return Imported(cal, name, list(peer.notes))


def _peer_reference(peer: Peer, path: str) -> float:
    """The reference a peer file implies (docs/commands/export-import.md)."""
    if peer.reference is not None:
        return float(peer.reference)
    if peer.sensor == "gyroscope":
        return 0.0
    if peer.format == "ros-yaml" and peer.sensor == "accelerometer":
        return 9.80665  # imu_calib's do_calib: reference_acceleration defaults to 9.80665
    by_units = {"g": 1.0, "m/s^2": 9.81, "m/s2": 9.81}  # imucal's Ferraris default expected gravity 9.81
    if peer.units in by_units:
        return by_units[peer.units]
    raise InputError(
        f"cannot tell the reference of output units {peer.units!r}",
        file=path,
        hint="give --reference, the stimulus magnitude in the output units",
    )


#: Tilt past this many times a parameter's noise (1σ) is worth a note even with no limit near.
TILT_OVER_NOISE = 10.0


def tilt_notes(cal: Calibration) -> list[str]:
    """A note when fixture tilt, not noise, bounds how well the parameters are known, said only
    where that changes a decision: a parameter that the tilt (over 3 times its noise) could move
    past one of its limits, or that it moves by more than 10 times its noise. A station's every
    run with a tilt a few times the noise and no limit near is no news."""
    tilt, se = cal.tilt_sensitivity, cal.uncertainty
    if tilt is None or not se:
        return []
    shifts = {"offset": tilt_only(cal), "gain": [float(v) for v in tilt.gain]}
    noise = {n: [float(v) for v in se[n]] if n in se else [0.0, 0.0, 0.0] for n in shifts}
    crossing = _limits_in_reach(cal, shifts)
    dominated = [
        n
        for n in ("offset", "gain")
        if any(
            t > 3 * u and (t > TILT_OVER_NOISE * u or (n, i) in crossing)
            for i, (t, u) in enumerate(zip(shifts[n], noise[n], strict=True))
        )
    ]
    if not dominated:
        return []
    worst = " and ".join(f"the {n}s by up to {max(shifts[n]):.2g} (noise: {max(noise[n]):.2g})" for n in dominated)
    past = {
        n: [("xyz"[i]) for i in range(3) if (n, i) in crossing and shifts[n][i] > 3 * noise[n][i]] for n in dominated
    }
    across = " and the ".join(f"{', '.join(a)} {n}{'s' if len(a) > 1 else ''}" for n, a in past.items() if a)
    limit = f", enough to cross the limits of the {across}" if across else ""
    advice = "level the fixture better and state how well with --fixture-tolerance"
    if cal.method in ("one-pose", "three-pose"):
        advice += ", or capture the six faces (six-pose takes offsets and gains from vertical readings only)"
    level = tilt.tolerance_deg  # a file from elsewhere may not say at what tilt
    off = f"{level:g}° off level" if level is not None else "the fixture's tilt"
    return [f"fixture tilt, not noise, limits this calibration: {off} moves {worst}{limit}; " + advice]


def _limits_in_reach(cal: Calibration, shifts: dict[str, list[float]]) -> set[tuple[str, int]]:
    """The (parameter, axis) whose limit lies within its tilt shift of its value: fixture tilt
    alone could take it across (inside or out), so the verdict rests on the fixture."""
    limits = cal.verdict.limits if cal.verdict is not None else None
    found: set[tuple[str, int]] = set()
    if limits is None:
        return found
    for i in range(3):
        if limits.offset is not None:
            distance = abs(float(cal.offset[i]) - float(limits.nominal_offset[i]))
            if abs(distance - float(limits.offset[i])) <= shifts["offset"][i]:
                found.add(("offset", i))
        if limits.gain_error is not None:
            nominal = float(limits.nominal_gain[i])
            error = abs(float(cal.gain[i]) / nominal - 1)
            if abs(error - float(limits.gain_error[i])) <= shifts["gain"][i] / abs(nominal):
                found.add(("gain", i))
    return found


def tilt_only(cal: Calibration) -> list[float]:
    """The tilt sensitivity of the offsets without the part a stated gain tolerance adds to a
    1-pose up axis (solvers.gain_error_bound): what fixture tilt alone moves them by."""

    tilt = cal.tilt_sensitivity
    if tilt is None:
        return []
    offset = [float(v) for v in tilt.offset]
    face = cal.poses[0].face if cal.poses else None
    if tilt.gain_tolerance is not None and face in model.FACES:
        part = solvers.gain_error_bound(cal.reference, tilt.gain_tolerance)
        offset = [v - abs(c) * part for v, c in zip(offset, model.FACES[face], strict=True)]
    return offset
