"""ArduPilot DataFlash logs (binary ``.bin``, and the text ``.log`` form): the IMU messages of an
ArduPilot log as io.sources streams.

The format is ArduPilot's own (libraries/AP_Logger/LogStructure.h; pymavlink's DFReader.py reads
it the same way): messages back to back, each the header bytes ``0xA3 0x95``, a message type
(one byte) and its fields, little-endian, packed as the format of that type says. ``FMT``
(type 0x80, 89 bytes) defines a type: its ``Type``, ``Length`` (the whole message's), ``Name``
(4 chars), ``Format`` (one character a field: ``b B h H i I q Q`` integers, ``f d g`` floats,
``c C e E`` integers in hundredths, ``L`` a latitude in 1e-7 degrees, ``n N Z`` text of 4, 16
and 64 bytes, ``M`` a flight mode byte, ``a`` 32 int16) and ``Columns``. The text form (``.log``,
as pymavlink's DFReader_text reads it) is one message a line: ``NAME, value, ...``, the
``FMT`` lines first; io.logs.dftext reads it into the same index.

Read here: ``IMU`` (accelerometer and gyroscope, with the IMU's temperature ``T``), ``ACC`` and
``GYR`` (every sample, where raw logging was on: ``SampleUS`` is the time), and ``MAG``
(milligauss), each instance a stream: the ``I`` field of recent logs, or the message's name in
older ones (``IMU2`` is ``IMU:1``, ``MAG3`` is ``MAG:2``, ``ACC1`` is ``ACC:0``). Whether
ArduPilot had corrected them is told by the calibration in force, from the log's ``PARM``
messages (``_state``).

The log is walked once (``index``): the header bytes are found a chunk at a time with numpy,
and the messages are followed from one to the next by their lengths (each message's successor
found with numpy; one Python step a run of messages that follow each other, a handful a log),
keeping the places of the wanted types only; a stream's fields are then gathered with numpy a
chunk at a time, so the whole log is never in memory. What ArduPilot's parsers recover from is
skipped with a note: a log cut short mid-message, bytes that are no message (a corrupt stretch,
a message of a type no ``FMT`` defines) up to the next header of a known type, as pymavlink's
DFReader does, garbage, zeros or erased flash at the end, a lone sample whose clock goes back.
What a length or count declares is bounded by its field (an FMT's Length is a byte, its format 16
characters of at most 64 bytes each), so nothing is allocated past what the file holds. A field
this reader takes as a whole number, an ``I`` (instance) or ``INS_RAW_LOG_OPT`` (a bit mask),
that is not one is an InputError naming the byte (the text form's: the line) and the field.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import logs, sources
from tumblecal_cli.io.logs.fields import CHUNK, NAMES, forward, gather
from tumblecal_cli.io.logs.reader import LogReader
from tumblecal_cli.io.readspec import ReadSpec
from tumblecal_cli.io.sources import Stream, Table

HEAD = b"\xa3\x95"
FMT_TYPE = 0x80
#: A binary DataFlash log starts with the FMT message that defines FMT.
MAGIC = HEAD + bytes([FMT_TYPE])
#: FMT's own layout (pymavlink DFReader.py: 89 bytes, "BBnNZ").
FMT_LENGTH = 89
#: Each format character's size in bytes (pymavlink DFReader.py, FORMAT_TO_STRUCT).
SIZES = {
    **dict.fromkeys("bBM", 1),
    **dict.fromkeys("hHcCg", 2),
    **dict.fromkeys("iIfeEL", 4),
    **dict.fromkeys("qQd", 8),
    "n": 4,
    "N": 16,
    "Z": 64,
    "a": 64,
}
#: The numeric characters' numpy types, and the scale of those logged in hundredths or 1e-7.
TYPES = {
    "b": "i1",
    "B": "u1",
    "M": "u1",
    "h": "<i2",
    "H": "<u2",
    "c": "<i2",
    "C": "<u2",
    "g": "<f2",
    "i": "<i4",
    "I": "<u4",
    "e": "<i4",
    "E": "<u4",
    "L": "<i4",
    "f": "<f4",
    "q": "<i8",
    "Q": "<u8",
    "d": "<f8",
}
SCALES = {"c": 0.01, "C": 0.01, "e": 0.01, "E": 0.01, "L": 1e-7}
_NAME = re.compile(r"[A-Za-z0-9_]{1,4}")
#: The most an instance (``I``) is: LogStructure.h logs it as a byte (``B``).
MOST_INSTANCE = 255
#: INS_RAW_LOG_OPT is a bit mask of a few bits (AP_InertialSensor's RAW_LOGGING_OPTION): a
#: whole number from 0, under this.
MOST_OPTION = 1 << 24


@dataclass(frozen=True)
class DataflashSensor:
    """One sensor a message carries: its three columns and their units."""

    sensor: str
    columns: tuple[str, str, str]
    units: str


#: The messages read, and the sensors each carries (units: LogStructure.h's "o" m/s/s, "E" rad/s,
#: and "G" gauss with multiplier "C" 1e-3 for MAG).
PARTS: dict[str, tuple[DataflashSensor, ...]] = {
    "IMU": (
        DataflashSensor("accelerometer", ("AccX", "AccY", "AccZ"), "m/s^2"),
        DataflashSensor("gyroscope", ("GyrX", "GyrY", "GyrZ"), "rad/s"),
    ),
    "ACC": (DataflashSensor("accelerometer", ("AccX", "AccY", "AccZ"), "m/s^2"),),
    "GYR": (DataflashSensor("gyroscope", ("GyrX", "GyrY", "GyrZ"), "rad/s"),),
    "MAG": (DataflashSensor("magnetometer", ("MagX", "MagY", "MagZ"), "mGauss"),),
}
#: Older logs' message names for an instance: IMU2 is IMU:1; ACC1 is ACC:0 (LOG_ACC1_MSG + instance).
_OLD = re.compile(r"(IMU|MAG)([23])|(ACC|GYR)([123])")


def named(message: str) -> tuple[str, int | None] | None:
    """The stream a logged message belongs to: its name, and its instance when the name tells it
    (None: from its ``I`` field, 0 without one); None for a message not read."""
    if message in PARTS:
        return message, None
    found = _OLD.fullmatch(message)
    if found is None:
        return None
    if found.group(1):
        return found.group(1), int(found.group(2)) - 1
    return found.group(3), int(found.group(4)) - 1


@dataclass(frozen=True)
class Format:
    """A message type as its FMT defines it: its id, name, length (the whole message's, header
    included), format characters and column names."""

    type: int
    name: str
    length: int
    chars: str
    columns: tuple[str, ...]

    def fields(self) -> dict[str, tuple[str, int]]:
        """Each numeric column's numpy type and offset from the message's first byte (header
        included); empty when a character is not one this reader knows, or the characters'
        sizes do not add up to the length (the type is then not read)."""
        if len(self.chars) != len(self.columns) or any(c not in SIZES for c in self.chars):
            return {}
        if 3 + sum(SIZES[c] for c in self.chars) != self.length:
            return {}
        out, offset = {}, 3
        for c, name in zip(self.chars, self.columns, strict=True):
            if c in TYPES:
                out[name] = (TYPES[c], offset)
            offset += SIZES[c]
        return out

    def scale(self, column: str) -> float | None:
        char = self.chars[self.columns.index(column)] if column in self.columns else ""
        return SCALES.get(char)


@dataclass
class DataflashStream:
    """The messages of one stream: its name and instance, the message logged (``IMU2``), its
    format, and where each message starts (a binary log's first header byte; a text log's line)."""

    name: str
    instance: int
    message: str
    fmt: Format
    places: NDArray[np.int64]


#: How a form of the log gathers columns of a stream's messages (a text log's lines that do not parse: NaN).
Gather = Callable[[str, DataflashStream, list[str]], dict[str, FloatArray]]


@dataclass
class DataflashIndex:
    """A log walked once: its streams' messages, the parameters logged (each one's first and last
    value), its sha256, the notes of what was skipped, how its columns are gathered (None: a
    binary log's, by ``binary_fields``; the text form's parses its lines), and where each
    parameter's last value is (a binary log's byte, a text log's line: what a message names)."""

    sources: list[DataflashStream]
    params: dict[str, tuple[float, float]]
    sha256: str
    notes: list[str]
    fields: Gather | None = None
    param_at: dict[str, int] = field(default_factory=dict)


@dataclass
class _BinaryWalk:
    """The state of one walk through a binary log: the formats seen, each type's message length,
    the places of the wanted types, what was skipped, and whether it is looking for the next
    message after bytes that are no message (``lost``: since which byte, and what they began with)."""

    name: str
    formats: dict[int, Format] = field(default_factory=dict)
    lengths: NDArray[np.int64] = field(default_factory=lambda: np.zeros(256, dtype=np.int64))
    wanted: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(256, dtype=bool))
    places: dict[int, list[NDArray[np.int64]]] = field(default_factory=dict)
    skipped: list[tuple[int, int, str]] = field(default_factory=list)
    redefined: set[str] = field(default_factory=set)
    lost: tuple[int, str] | None = None  # bytes that are no message since (byte, what): looking for a header
    zeros: bool = True  # the bytes since then are all zeros or all 0xff (space never written)
    notes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.define(Format(FMT_TYPE, "FMT", FMT_LENGTH, "BBnNZ", ("Type", "Length", "Name", "Format", "Columns")))

    def define(self, fmt: Format) -> None:
        known = self.formats.get(fmt.type)
        if known is not None:
            if known != fmt:
                self.redefined.add(known.name)  # a log defines each type once; the first kept
            return
        self.formats[fmt.type] = fmt
        self.lengths[fmt.type] = fmt.length
        self.wanted[fmt.type] = fmt.name == "PARM" or named(fmt.name) is not None

    def lose(self, at: int, what: str) -> None:
        if self.lost is None:
            self.lost, self.zeros = (at, what), True


def fmt_body(body: bytes) -> Format | None:
    """The format an FMT message's body (86 bytes) defines; None when it is not one (a header's
    bytes that happen to be inside another message)."""
    kind, length = body[0], body[1]
    try:
        name = body[2:6].split(b"\0", 1)[0].decode("ascii")
        chars = body[6:22].split(b"\0", 1)[0].decode("ascii")
        columns = body[22:86].split(b"\0", 1)[0].decode("ascii")
    except UnicodeDecodeError:
        return None
    if not _NAME.fullmatch(name) or length < 3 or not chars.isprintable() or not columns.isprintable():
        return None
    return Format(kind, name, length, chars, tuple(columns.split(",")) if columns else ())


class DataflashReader(LogReader[DataflashIndex]):
    """io.sources' Reader of ArduPilot DataFlash binary logs (io.logs.dftext's, a subclass, reads
    the text form: its own row and walk, the same streams and readings)."""

    row = logs.DATAFLASH
    called = "an ArduPilot DataFlash log"
    corrected_as = "corrected by ArduPilot"

    def walk(self, path: str) -> DataflashIndex:
        return _walk_file(path)

    def streams(self, path: str) -> list[Stream]:
        return streams_of(path, self.index(path))

    def table(self, path: str, spec: ReadSpec) -> Table:
        return read_stream(self, path, spec)


READER = DataflashReader()


def _walk_file(path: str) -> DataflashIndex:
    """Every message of the log stepped over once; the wanted types' messages placed."""
    digest = hashlib.sha256()
    walk = _BinaryWalk(path)
    base, carry = 0, b""
    with open(path, "rb") as f:
        while block := f.read(CHUNK):
            digest.update(block)
            buf = carry + block if carry else block
            pos = _step(walk, buf, base)
            carry, base = buf[pos:], base + pos
    _end(walk, carry, base)
    where: dict[str, int] = {}
    params = _params(path, walk, where)
    return DataflashIndex(_sources(path, walk), params, digest.hexdigest(), walk.notes, param_at=where)


def _step(walk: _BinaryWalk, buf: bytes, base: int) -> int:
    """Step over the whole messages of ``buf`` (its first byte at ``base`` in the file), keeping
    the places of the wanted ones; returns where the first message not wholly in ``buf`` (or the
    bytes where a header may start) begins."""
    data = np.frombuffer(buf, dtype=np.uint8)
    at = np.flatnonzero((data[:-2] == HEAD[0]) & (data[1:-1] == HEAD[1]))  # a type byte after each
    kinds = data[at + 2]
    for p in at[kinds == FMT_TYPE].tolist():
        if p + FMT_LENGTH <= len(buf) and (fmt := fmt_body(buf[p + 3 : p + FMT_LENGTH])) is not None:
            walk.define(fmt)
    known = walk.lengths[kinds] > 0
    at, kinds = at[known], kinds[known]
    ends = at + walk.lengths[kinds]
    n = len(at)
    j = np.searchsorted(at, ends)
    nxt = np.where((j < n) & (at[np.minimum(j, n - 1)] == ends) & (ends <= len(buf)), j, -1) if n else j
    runs, pos = _chain(walk, buf, base, at, ends, nxt)
    if runs:
        steps = np.concatenate([np.arange(a, b) for a, b in runs])
        places, types = at[steps] + base, kinds[steps]
        for kind in np.unique(types[walk.wanted[types]]).tolist():
            walk.places.setdefault(kind, []).append(places[types == kind])
    return pos


def _chain(
    walk: _BinaryWalk, buf: bytes, base: int, at: NDArray[np.int64], ends: NDArray[np.int64], nxt: NDArray[np.int64]
) -> tuple[list[tuple[int, int]], int]:
    """The messages of ``buf`` one after the other, from where the last buffer's left off, as runs
    of the known headers ``at`` (index ranges): each message's successor is the header where it
    ends (``nxt``), so a run goes on while that is the next header, and one Python step is taken
    a run, not a message (a run ends where a header's bytes turn up inside a message, or bytes
    that are no message, skipped to the next known header). Returns the runs and where the rest
    (carried to the next buffer) starts."""
    runs: list[tuple[int, int]] = []
    size, n = len(buf), len(at)
    breaks = np.flatnonzero(nxt != np.arange(1, n + 1))  # the last header is always one
    pos = 0
    i = int(np.searchsorted(at, pos))
    while True:
        if i < n and at[i] == pos:
            if walk.lost is not None:
                _found(walk, base + pos)
        else:  # no message here: bytes that are no message, up to the next known header
            if walk.lost is None:
                if pos + 3 > size:
                    return runs, pos  # too few bytes to tell: the next buffer tells
                walk.lose(base + pos, _what(buf[pos : pos + 3]))
            if i == n:
                stop = max(pos, size - 2)  # a header may straddle the next buffer
                _seen(walk, buf[pos:stop])
                return runs, stop
            _seen(walk, buf[pos : at[i]])
            pos = int(at[i])
            _found(walk, base + pos)
        last = int(breaks[np.searchsorted(breaks, i)])
        if ends[last] > size:  # the run's last message goes on past the buffer
            runs.append((i, last))
            return runs, int(at[last])
        runs.append((i, last + 1))
        pos = int(ends[last])
        follow = int(nxt[last])
        i = follow if follow >= 0 else int(np.searchsorted(at, pos))


def _what(head: bytes) -> str:
    """What the bytes where a message should start are."""
    if head[:2] == HEAD and len(head) == 3:
        return f"a message of type {head[2]:#04x}, which no FMT defines"
    return "bytes that are no message"


def _seen(walk: _BinaryWalk, stretch: bytes) -> None:
    if walk.zeros and stretch.strip(b"\0") and stretch.strip(b"\xff"):
        walk.zeros = False


def _found(walk: _BinaryWalk, at: int) -> None:
    """The next message after bytes that are no message: the stretch noted as skipped."""
    assert walk.lost is not None
    start, what = walk.lost
    walk.skipped.append((start, at - start, what))
    walk.lost = None


def _end(walk: _BinaryWalk, carry: bytes, base: int) -> None:
    """The log's last bytes (a message cut short, or bytes that are no message); then the notes."""
    if walk.lost is not None:
        _seen(walk, carry)
        start, what = walk.lost
        if walk.zeros:
            walk.notes.append(
                f"the log ends in {base + len(carry) - start} bytes that were never written, from byte {start}"
            )
        else:
            walk.notes.append(
                f"the log ends in {base + len(carry) - start} bytes that are no message, from byte {start} "
                f"({what}): skipped"
            )
    elif carry:
        walk.notes.append(
            f"the log ends mid-message (its last {len(carry)} bytes, from byte {base}): cut short, as a log is "
            "when power is lost; read up to there"
        )
    if walk.skipped:
        start, length, what = walk.skipped[0]
        more = f" (and {len(walk.skipped) - 1} more)" if len(walk.skipped) > 1 else ""
        walk.notes.insert(
            0, f"skipped {length} bytes at byte {start} ({what}){more}, resuming at the next message, as pymavlink does"
        )
    if walk.redefined:
        walk.notes.append(f"an FMT redefines {', '.join(sorted(walk.redefined))}: the first definition read")


def _sources(path: str, walk: _BinaryWalk) -> list[DataflashStream]:
    """The streams' messages: each wanted type's places, split by their ``I`` field where the
    format has one."""
    out = []
    for kind, parts in sorted(walk.places.items()):
        fmt = walk.formats[kind]
        stream = named(fmt.name)
        if stream is None:
            continue
        fields = fmt.fields()
        if not fields:
            walk.notes.append(f"{fmt.name}'s format {fmt.chars!r} does not fit its length {fmt.length}: not read")
            continue
        places = np.concatenate(parts)
        out += split(path, stream, fmt, places, fields)
    return sorted(out, key=lambda s: (s.name, s.instance))


def split(
    path: str,
    stream: tuple[str, int | None],
    fmt: Format,
    places: NDArray[np.int64],
    fields: dict[str, tuple[str, int]],
) -> list[DataflashStream]:
    """A type's messages as the streams they are: one per value of the ``I`` field (binary); an
    ``I`` that is no instance (a float's NaN, a fraction, past 255) is exit 2 naming its message."""
    name, instance = stream
    if instance is not None or "I" not in fields:
        return [DataflashStream(name, instance or 0, fmt.name, fmt, places)]
    got = gather(path, places, fields, ["I"])["I"]
    wrong = np.flatnonzero(~((got >= 0) & (got <= MOST_INSTANCE) & (got == np.round(got))))
    if wrong.size:
        raise InputError(
            f"{fmt.name}'s field 'I' (its instance) is {got[wrong[0]]:.6g} in the message at byte "
            f"{int(places[wrong[0]])}: not an instance (a whole number, 0 to {MOST_INSTANCE})",
            file=path,
        )
    which = got.astype(np.int64)
    return [DataflashStream(name, int(k), fmt.name, fmt, places[which == k]) for k in np.unique(which).tolist()]


def _params(path: str, walk: _BinaryWalk, where: dict[str, int]) -> dict[str, tuple[float, float]]:
    """Each parameter's first and last value in the log's PARM messages (``where``: the byte of
    each one's last)."""
    kinds = [k for k in walk.places if walk.formats[k].name == "PARM"]
    if not kinds:
        return {}
    fmt = walk.formats[kinds[0]]
    fields = fmt.fields()
    if "Name" not in fmt.columns or "Value" not in fields:
        return {}
    places = np.concatenate(walk.places[kinds[0]])
    offset = 3 + sum(SIZES[c] for c in fmt.chars[: fmt.columns.index("Name")])
    values = gather(path, places, fields, ["Value"])["Value"]
    out: dict[str, tuple[float, float]] = {}
    with open(path, "rb") as f:
        for place, value in zip(places.tolist(), values.tolist(), strict=True):
            f.seek(place + offset)
            key = f.read(16).split(b"\0", 1)[0].decode("ascii", "replace")
            out[key] = (out[key][0], value) if key in out else (value, value)
            where[key] = place
    return out


# -- streams: what each is, and whether ArduPilot had corrected it -----------------------------

_ACC_SOURCE = "libraries/AP_InertialSensor/AP_InertialSensor_Backend.cpp: _rotate_and_correct_accel, log_accel_raw"
_GYR_SOURCE = "libraries/AP_InertialSensor/AP_InertialSensor_Backend.cpp: _rotate_and_correct_gyro, log_gyro_raw"
_MAG_SOURCE = (
    "libraries/AP_Compass/AP_Compass_Backend.cpp: correct_field; AP_Logger/LogFile.cpp: Write_Compass_instance "
    "logs get_field"
)
_CORRECTED = {
    "accelerometer": "corrected: ArduPilot subtracts INS_ACC*OFFS and scales by INS_ACC*SCAL (and INS_TCAL* when "
    "enabled) before it logs IMU and ACC, whatever INS_RAW_LOG_OPT says: that picks the filtering",
    "gyroscope": "corrected: ArduPilot subtracts INS_GYR*OFFS (and INS_TCAL* when enabled) before it logs IMU and "
    "GYR, whatever INS_RAW_LOG_OPT says: that picks the filtering",
    "magnetometer": "corrected: MagX/Y/Z are the field after COMPASS_OFS* (added), COMPASS_DIA*/ODI*, COMPASS_SCALE* "
    "and motor compensation",
}
_RAW = {
    "accelerometer": "raw: the log's PARM holds INS_ACC*OFFS at 0 and INS_ACC*SCAL at 1 (INS_TCAL* off): no "
    "calibration in force, ArduPilot only rotated the readings to the board frame",
    "gyroscope": "raw: the log's PARM holds INS_GYR*OFFS at 0 (INS_TCAL* off): no calibration in force, ArduPilot "
    "only rotated the readings to the board frame",
    "magnetometer": "raw: the log's PARM holds COMPASS_OFS* at 0, COMPASS_DIA* at 1 and COMPASS_ODI* at 0, no motor "
    "compensation: no calibration in force, ArduPilot only rotated the readings to the board frame",
}
_SOURCE = {"accelerometer": _ACC_SOURCE, "gyroscope": _GYR_SOURCE, "magnetometer": _MAG_SOURCE}


def _vector(params: dict[str, tuple[float, float]], name: str) -> tuple[float, float, float] | None:
    """A parameter vector's last value (``NAME_X/_Y/_Z``); None when the log has not all three."""
    got = [params[f"{name}_{axis}"][1] for axis in "XYZ" if f"{name}_{axis}" in params]
    return (got[0], got[1], got[2]) if len(got) == 3 else None


def calibration(
    params: dict[str, tuple[float, float]], sensor: str, instance: int
) -> tuple[dict[str, object], bool | None]:
    """The calibration parameters of ``sensor`` ``instance`` in the log's PARM (each one's last
    value), and whether they leave the readings as they are (None: the log does not say)."""
    n = "" if instance == 0 else str(instance + 1)
    tcal = params.get(f"INS_TCAL{instance + 1}_ENABLE", (0.0, 0.0))[1] == 1
    if sensor == "magnetometer":
        names = {f"COMPASS_{p}{n}": _vector(params, f"COMPASS_{p}{n}") for p in ("OFS", "DIA", "ODI", "MOT")}
        scale = params.get(f"COMPASS_SCALE{n}")
        got: dict[str, object] = {k: v for k, v in names.items() if v is not None}
        if scale is not None:
            got[f"COMPASS_SCALE{n}"] = scale[1]
        ofs, dia, odi, mot = names.values()
        if ofs is None:
            return got, None
        motors = params.get("COMPASS_MOTCT", (0.0, 0.0))[1] != 0 and mot is not None and any(mot)
        plain = not any(ofs) and all(d in (0, 1) for d in dia or ()) and not any(odi or ()) and not motors
        return got, plain and (scale is None or scale[1] in (0, 1))
    kind = "ACC" if sensor == "accelerometer" else "GYR"
    offsets = f"INS_{kind}{n}OFFS"
    scales = f"INS_{kind}{n}SCAL" if kind == "ACC" else None
    vectors = {p: _vector(params, p) for p in (offsets, scales) if p is not None}
    got = {k: v for k, v in vectors.items() if v is not None}
    if tcal:
        got[f"INS_TCAL{instance + 1}_ENABLE"] = 1
    if any(v is None for v in vectors.values()):
        return got, None
    plain = not any(vectors[offsets] or ()) and all(s in (0, 1) for s in vectors.get(scales or "") or ())
    return got, plain and not tcal


def _base(path: str, found: DataflashIndex, src: DataflashStream) -> int:
    """The sensor an ACC or GYR instance is of: with INS_RAW_LOG_OPT bit 3 (pre and post filter)
    instances from the sensor count on are the post-filter copies (AP_InertialSensor_Backend.cpp,
    log_accel_raw: ``instance + _accel_count``)."""
    if src.name not in ("ACC", "GYR"):
        return src.instance
    value = found.params.get("INS_RAW_LOG_OPT", (0.0, 0.0))[1]
    if not (0 <= value < MOST_OPTION and value == int(value)):  # NaN fails the first
        at = found.param_at.get("INS_RAW_LOG_OPT")
        text = found.fields is not None  # the text form names a line, the binary a byte
        raise InputError(
            f"the PARM{'' if text or at is None else f' message at byte {at}'} gives INS_RAW_LOG_OPT as "
            f"{value:.6g}: not a bit mask (a whole number from 0), so which ACC and GYR instances are "
            "post-filter copies cannot be told",
            file=path,
            line=at if text else None,
        )
    if not int(value) & 8:
        return src.instance
    count = len([s for s in found.sources if s.name == src.name]) // 2
    return src.instance - count if count and src.instance >= count else src.instance


def _state(path: str, found: DataflashIndex, src: DataflashStream, sensor: str) -> tuple[bool, str]:
    """Whether ArduPilot had corrected ``sensor`` in ``src``, and how that is told."""
    base = _base(path, found, src)
    _, plain = calibration(found.params, sensor, base)
    if plain:
        how = _RAW[sensor]
    else:
        how = _CORRECTED[sensor] + ("" if plain is False else "; this log's PARM does not say otherwise")
    if base != src.instance:
        how = f"{how}; and filtered: the post-filter copy of {src.name}:{base} (INS_RAW_LOG_OPT bit 3)"
    return not plain, f"{how} ({_SOURCE[sensor]})"


def _clock(src: DataflashStream) -> tuple[str | None, float]:
    """The column of a message's time (the sample's own where ACC and GYR log it) and its ticks a second."""
    for name, per_second in (("SampleUS", 1e6), ("TimeUS", 1e6), ("TimeMS", 1e3)):
        if name in src.fmt.columns:
            return name, per_second
    return None, 1.0


def _temperature(src: DataflashStream) -> str | None:
    return next((c for c in ("T", "Temp") if c in src.fmt.columns), None)


def _fields(path: str, found: DataflashIndex, src: DataflashStream, names: list[str]) -> dict[str, FloatArray]:
    """The columns ``names`` of ``src``'s messages."""
    return (found.fields or binary_fields)(path, src, names)


def binary_fields(path: str, src: DataflashStream, names: list[str]) -> dict[str, FloatArray]:
    """The columns ``names`` of a binary log's messages, scaled where the format logs them in
    hundredths or 1e-7."""
    data = gather(path, src.places, src.fmt.fields(), names)
    for name in names:
        if (scale := src.fmt.scale(name)) is not None:
            data[name] = data[name] * scale
    return data


def streams_of(path: str, found: DataflashIndex) -> list[Stream]:
    """Each message instance's sensors: rows, mean rate (from its first and last time), units, and
    whether ArduPilot had corrected it."""
    out = []
    for src in found.sources:
        clock, per_second = _clock(src)
        rate = None
        if len(src.places) > 1 and clock is not None:
            ends = _fields(path, found, replace(src, places=src.places[[0, -1]]), [clock])
            span = float(ends[clock][1] - ends[clock][0]) / per_second
            rate = (len(src.places) - 1) / span if span > 0 else None
        for part in PARTS[src.name]:
            if all(c in src.fmt.columns for c in part.columns):
                corrected, how = _state(path, found, src, part.sensor)
                out.append(
                    Stream(src.name, src.instance, part.sensor, len(src.places), rate, part.units, corrected, how)
                )
    return out


def read_stream(reader: DataflashReader, path: str, spec: ReadSpec) -> Table:
    """The readings of the stream ``spec`` names (or the log's one stream of ``spec.sensor``), of
    the log ``reader`` walks (the binary or the text form)."""
    found = reader.index(path)
    chosen = sources.pick(path, streams_of(path, found), spec)
    src = next(s for s in found.sources if (s.name, s.instance) == (chosen.name, chosen.instance))
    part = next(p for p in PARTS[src.name] if p.sensor == chosen.sensor)
    clock_name, per_second = _clock(src)
    hot = _temperature(src)
    names = [*part.columns, *(n for n in (clock_name, hot) if n is not None)]
    data = _fields(path, found, src, names)
    notes = [f"{path}: {note}" for note in found.notes]
    keep: NDArray[np.bool_] = np.ones(len(src.places), dtype=bool)
    if found.fields is not None:  # the text form: a line that does not parse is NaN
        keep = np.asarray(np.isfinite(np.column_stack([data[n] for n in names])).all(axis=1))
        if not keep.all():
            notes.append(f"{path}: {chosen.key}: {int((~keep).sum())} lines that do not parse skipped")
    values = np.column_stack([data[c] for c in part.columns])
    clock = None if clock_name is None else data[clock_name]
    temperature = data[hot] if hot is not None else _borrowed(path, found, src, clock, notes)
    if clock is not None and spec.rate is None:
        keep &= forward(path, chosen.key, clock, keep, notes, per_second)
    if not keep.all():
        values, clock = values[keep], None if clock is None else clock[keep]
        temperature = None if temperature is None else temperature[keep]
    notes[:0] = [_read_note(reader, path, found, src, chosen, len(values))]
    unit = "ms" if clock_name == "TimeMS" else "us"
    return Table(
        NAMES[chosen.sensor],
        values,
        clock,
        unit,
        temperature,
        None,
        found.sha256,
        tuple(notes),
        chosen.corrected,
        chosen,
    )


def _read_note(
    reader: DataflashReader, path: str, found: DataflashIndex, src: DataflashStream, chosen: Stream, rows: int
) -> str:
    """Which stream was read, and the calibration in force (from PARM) as the log tells it."""
    logged = "" if src.message == src.name else f", logged as {src.message}"
    note = reader.read_note(path, chosen, rows, logged)
    got, _ = calibration(found.params, chosen.sensor, _base(path, found, src))
    if got:
        shown = ", ".join(f"{k} {_show(v)}" for k, v in got.items())
        note += f"; in force (PARM): {shown}"
    return note


def _show(value: object) -> str:
    if isinstance(value, tuple):
        return "(" + ", ".join(f"{v:.6g}" for v in value) + ")"
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def _borrowed(
    path: str, found: DataflashIndex, src: DataflashStream, clock: FloatArray | None, notes: list[str]
) -> FloatArray | None:
    """An ACC or GYR stream's temperature: its IMU's ``T``, interpolated to its times."""
    base = _base(path, found, src)
    imu = next((s for s in found.sources if (s.name, s.instance) == ("IMU", base)), None)
    if src.name not in ("ACC", "GYR") or clock is None or imu is None or len(imu.places) < 2:
        return None
    hot = _temperature(imu)
    if _clock(imu)[0] != "TimeUS" or hot is None:
        return None
    data = _fields(path, found, imu, ["TimeUS", hot])
    t, temp = data["TimeUS"], data[hot]
    good = np.isfinite(t) & np.isfinite(temp)
    t, temp = t[good], temp[good]
    if len(t) < 2 or (np.diff(t) <= 0).any():
        return None
    notes.append(f"{path}: {src.name}:{src.instance}: the temperature is IMU:{base}'s {hot}, interpolated to its times")
    return np.interp(clock, t, temp)
