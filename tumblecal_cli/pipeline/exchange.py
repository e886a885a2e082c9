"""Calibration files after solve: judged again (check), written for firmware or another tool
(export), and read from another tool (import)."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, TypedDict, Unpack

import numpy as np

from tumblecal_cli.core import gate, model, solvers
from tumblecal_cli.errors import InputError, control_character
from tumblecal_cli.io.calfiles import calfile, documents
from tumblecal_cli.io.export import formats, registry
from tumblecal_cli.io.export.contract import Exported, ExportOptions
from tumblecal_cli.pipeline.options import Triplet, keywords_known, path_of, unit_block
from tumblecal_cli.pipeline.options import limits as parse_limits

if TYPE_CHECKING:
    from tumblecal_cli.core.gate import Finding, Limits
    from tumblecal_cli.io.calfiles.calfile import Calibration
    from tumblecal_cli.io.export.contract import Importer, Peer
    from tumblecal_cli.io.export.registry import ExportFormat


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
        c.sensor_matrix,  # judged in the sensor's axes, as solve judged it (its poses are the sensor's)
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


def exported(cal: Calibration | str | os.PathLike[str], fmt: str, **options: Unpack[ExportKeywords]) -> Exported:
    """:func:`export`, with the notes the command prints on stderr: the format's row in
    io.export.registry says which options it takes and whether it holds a current block."""

    keywords_known(options, ExportKeywords, "export")
    given = ExportOptions(
        prefix=options.get("prefix"),
        lsb=options.get("lsb"),
        bits=options.get("bits", 16),
        register_sign=options.get("register_sign", "subtract"),
        gain_step=options.get("gain_step"),
        nominal_gain=options.get("nominal_gain"),
        instance=options.get("instance"),
    )
    row = registry.export_format(fmt)
    _export_options(row, given)
    c = calfile.resolve(cal)
    if c.failed and not options.get("force", False):
        calfile.refuse_failed(c, "export it", "export")
    notes: tuple[str, ...] = ()
    if c.current is not None and not row.current:  # docs/current.md: the firmware parameters hold it
        c = replace(c, current=None)
        notes = (f"warning: the current block (offset per ampere) is NOT written: --format {fmt} holds none",)
    done = row.exporter()(c, given)
    return Exported(done.text, (*notes, *done.notes))


def _export_options(row: ExportFormat, given: ExportOptions) -> None:
    """export's options that go together, checked before the calibration is read: each option a
    format does not take (its row) is named with the formats that do."""
    if given.register_sign not in ("subtract", "add"):
        raise InputError(f"--register-sign: {given.register_sign!r} is not one of subtract, add")
    for flag, number in (("--lsb", given.lsb), ("--gain-step", given.gain_step)):
        if number is not None and (isinstance(number, bool) or not isinstance(number, int | float)):
            raise InputError(f"{flag} takes a number, got {number!r}")
    foreign = [n for n in ("lsb", "gain_step", "nominal_gain") if getattr(given, n) is not None and n not in row.takes]
    if foreign:
        extra = ", ".join(_flag(n) for n in foreign)
        raise InputError(f"{extra} {'is' if len(foreign) == 1 else 'are'} for --format {registry.owners(foreign[0])}")
    if (given.bits != 16 or given.register_sign != "subtract") and not {"bits", "register_sign"} <= row.takes:
        raise InputError(f"--bits and --register-sign are for --format {registry.owners('bits')}")
    for name, why in row.needs:
        if getattr(given, name) is None:
            raise InputError(f"--format {row.name} needs {_flag(name)}, {why}")
    if given.prefix is not None and "prefix" not in row.takes:
        raise InputError(f"--prefix is for --format {registry.owners('prefix')}")
    if given.nominal_gain is not None and given.gain_step is None:
        raise InputError("--nominal-gain is the gain trim's aim: it needs --gain-step")
    if given.instance is not None and "instance" not in row.takes:
        raise InputError(f"--instance is for --format {registry.owners('instance')}")


def _flag(option: str) -> str:
    """An option of ExportOptions as the command line spells it."""
    return "--" + option.replace("_", "-")


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
    rows = registry.IMPORTS
    found = next((row.name for row in rows.values() if row.importer().claims(doc)), None)
    name = fmt if fmt is not None else found
    if name is None or (found is not None and found != name):
        what = "neither " + " nor ".join(row.described for row in rows.values())
        raise InputError(
            f"{what} file" if found is None else f"the file is {found}, not {name}",
            file=path,
            hint=f"tumblecal import reads --from {' or '.join(rows)}",
        )
    if name not in rows:
        raise InputError(f"--from: {name!r} is not one of {', '.join(rows)}")
    reader = rows[name].importer()
    peer = reader.read(doc, path, sensor)
    ref = reference if reference is not None else _peer_reference(peer, reader, path)
    if not (math.isfinite(ref) and (ref > 0 or (ref == 0 and peer.sensor == "gyroscope"))):
        raise InputError(f"--reference must be a positive number (0 for a gyroscope), got {ref}")
    if columns:
        picked = [c.strip() for c in (columns.split(",") if isinstance(columns, str) else map(str, columns))]
        if len(picked) != 3 or not all(picked) or len({c.lower() for c in picked}) != 3:
            raise InputError(f"--columns takes three different names X,Y,Z, got {columns!r}")
    else:
        picked = peer.columns or reader.columns(peer.sensor)
    if serial is None and peer.serial is not None and control_character(peer.serial):
        raise InputError(f"its serial holds a control character: {peer.serial!r}", file=path, hint="give --serial")
    who = unit_block(
        serial if serial is not None else peer.serial, peer.was.get("station"), peer.was.get("operator"), []
    )
    cal = formats.imported(peer, path=path, raw=raw, sensor=peer.sensor, reference=ref, columns=picked, unit=who)
    # what import writes, tumblecal must read back: validated as `load` validates a file
    calfile.validate(cal.to_dict(), path)
    return Imported(cal, name, list(peer.notes))


def _peer_reference(peer: Peer, reader: Importer, path: str) -> float:
    """The reference a peer file implies (docs/commands/export-import.md): what a tumblecal export
    recorded, 0 for a gyroscope, else what its format takes for its units."""
    if peer.reference is not None:
        return float(peer.reference)
    if peer.sensor == "gyroscope":
        return 0.0
    implied = reader.reference(peer)
    if implied is not None:
        return implied
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
