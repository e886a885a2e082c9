"""PX4 ULog (``.ulg``): the IMU topics of a PX4 log as io.sources streams.

The format is PX4's own ("ULog File Format", docs.px4.io/main/en/dev_log/ulog_file_format.html):
a 16-byte header (magic ``ULog\\x01\\x12\\x35``, version, start time), then messages, each a
3-byte header (``uint16 msg_size``, ``uint8 msg_type``) and its body, little-endian. ``F``
defines a topic's fields (``name:type field;...``), ``A`` subscribes a topic instance
(``multi_id``) under a ``msg_id``, and ``D`` carries one sample of it (``msg_id`` then the
fields, packed as declared). ``S`` is a sync marker a parser resumes at after a corrupt byte.

Read here (``TOPICS``): ``sensor_accel``, ``sensor_gyro``, ``sensor_mag`` (the drivers' output,
raw since PX4 1.11), ``sensor_combined`` (accelerometer and gyroscope, corrected) and
``vehicle_imu`` (delta angle and velocity over ``delta_*_dt``, corrected), each instance a
stream. Time is ``timestamp_sample`` where the topic has it, else ``timestamp`` (µs since boot;
``sensor_combined``'s accelerometer adds its ``accelerometer_timestamp_relative``).

The log is walked once (``index``: each wanted message's place, not its bytes: one Python step a
message), then a stream's fields are gathered a chunk at a time with numpy: the whole log is never
in memory. What PX4's parser (pyulog) recovers from is skipped with a note: a log cut short, a
message of a type it does not know, a corrupt stretch up to the next sync marker, a sample whose
size or clock is wrong, an appended-data offset past the log's end. What it cannot (a corrupt
header with no sync marker after it, a header that is not ULog's) is one InputError naming the
file and the byte; so is a wanted topic's format that cannot be what its samples hold (an array
count that is no number or more than a message can hold, two formats of the topic that differ,
two subscriptions of one instance or one msg_id), and a field this reader needs that the format
lacks (when that sensor is read). Nothing is allocated by a declared count before it is checked
against the 65535 bytes a message holds.
"""

from __future__ import annotations

import array
import hashlib
import os
import struct
from dataclasses import dataclass, field, replace
from typing import BinaryIO

import numpy as np

from tumblecal_cli.errors import InputError
from tumblecal_cli.io import logs, sources
from tumblecal_cli.io.logs.fields import NAMES, ascii_int, forward, gather, shown
from tumblecal_cli.io.logs.reader import LogReader
from tumblecal_cli.io.readspec import ReadSpec
from tumblecal_cli.io.sources import Stream, Table

MAGIC = logs.ULOG.magic[0]
SYNC = b"\x2f\x73\x13\x20\x25\x0c\xbb\x12"
#: The message types of the format; any other is skipped (a newer logger's) or corrupt.
KNOWN = frozenset(b"BFIMPQARDLCSO")
#: Bytes read at a time (each read's messages walked, then dropped).
CHUNK = 1 << 22
#: A header PX4's parser takes as corrupt: type 0, size 0, or a body over 10000 bytes (pyulog
#: core.py, _check_packet_corruption).
BIGGEST = 10_000
#: The most bytes a topic's fields can take: a message's size is a uint16, and a data message's
#: body starts with its two-byte msg_id. A format that lays out more cannot be logged.
MOST = 0xFFFF - 2
#: A gyroscope's turns read beside its instance's sensor_accel (ReadSpec.paired): the accelerometer's
#: rate at least this share of the gyroscope's, and the gyroscope's samples in its time span at least
#: this share (else exit 2).
PAIR_RATE = 0.25
PAIR_OVERLAP = 0.5

_TYPES = {
    "int8_t": "i1",
    "uint8_t": "u1",
    "int16_t": "<i2",
    "uint16_t": "<u2",
    "int32_t": "<i4",
    "uint32_t": "<u4",
    "int64_t": "<i8",
    "uint64_t": "<u8",
    "float": "<f4",
    "double": "<f8",
    "bool": "u1",
    "char": "u1",
}

#: sensor_combined: a relative timestamp that marks its sensor's values invalid (msg/SensorCombined.msg).
INVALID_RELATIVE = 0x7FFFFFFF

_RAW = (
    "raw: since PX4 1.11 drivers publish sensor_accel/gyro/mag uncalibrated, and the sensors module "
    "applies CAL_* to them (src/modules/sensors/vehicle_imu/VehicleIMU.cpp: UpdateAccel/UpdateGyro take "
    "x, y, z as the raw reading)"
)
_OLD = (
    "corrected: this topic has x_raw, the PX4 1.10 and earlier form, whose drivers applied the CAL_* "
    "offsets and scales to x, y, z before publishing (src/lib/drivers/accelerometer/PX4Accelerometer.cpp, v1.10)"
)
_COMBINED = (
    "corrected: 'scaled and offset-compensated where possible' (PX4 msg/SensorCombined.msg), published by the "
    "sensors module after CAL_* are applied"
)
_IMU = (
    "corrected: delta angle/velocity with 'offsets, scale, and board rotation' applied "
    "(src/modules/sensors/vehicle_imu/VehicleIMU.cpp, Publish)"
)


@dataclass(frozen=True)
class UlogSensor:
    """One sensor a topic carries: its three fields, its units, the field added to the time
    (a relative timestamp), the field its values are divided by (an integration time in µs)."""

    sensor: str
    fields: tuple[str, str, str]
    units: str
    relative: str | None = None
    per: str | None = None


def _fields(prefix: str) -> tuple[str, str, str]:
    return (f"{prefix}[0]", f"{prefix}[1]", f"{prefix}[2]")


#: The topics read, and the sensors each carries.
TOPICS: dict[str, tuple[UlogSensor, ...]] = {
    "sensor_accel": (UlogSensor("accelerometer", ("x", "y", "z"), "m/s^2"),),
    "sensor_gyro": (UlogSensor("gyroscope", ("x", "y", "z"), "rad/s"),),
    "sensor_mag": (UlogSensor("magnetometer", ("x", "y", "z"), "gauss"),),
    "sensor_combined": (
        UlogSensor(
            "accelerometer", _fields("accelerometer_m_s2"), "m/s^2", relative="accelerometer_timestamp_relative"
        ),
        UlogSensor("gyroscope", _fields("gyro_rad"), "rad/s"),
        UlogSensor("magnetometer", _fields("magnetometer_ga"), "gauss", relative="magnetometer_timestamp_relative"),
    ),
    "vehicle_imu": (
        UlogSensor("accelerometer", _fields("delta_velocity"), "m/s^2", per="delta_velocity_dt"),
        UlogSensor("gyroscope", _fields("delta_angle"), "rad/s", per="delta_angle_dt"),
    ),
}


@dataclass
class TopicFormat:
    """One 'F' message: its fields (type, array count: 0 for one value, name), the byte it is at,
    what is wrong with it (None: nothing), and where a second 'F' of its name that differs is."""

    fields: list[tuple[str, int, str]]
    at: int
    wrong: str | None = None
    again: int | None = None


@dataclass
class TopicLayout:
    """A topic's flattened fields: each field's (numpy type, byte offset), and the body's size."""

    fields: dict[str, tuple[str, int]]
    size: int


@dataclass
class Subscription:
    """One subscription of a wanted topic: its name, instance, layout, and where each of its
    samples' bodies (after the msg_id) starts in the file."""

    name: str
    instance: int
    layout: TopicLayout
    places: array.array[int] = field(default_factory=lambda: array.array("q"))
    at: int = 0  # the byte of the topic's format (its 'F' message)


@dataclass
class UlogIndex:
    """A log walked once: its wanted topics, its sha256, and the notes of what was skipped."""

    topics: list[Subscription]
    sha256: str
    notes: list[str]
    size: int


class _Walk:
    """The state of one walk through a log: the formats and subscriptions seen so far, the
    places of the wanted topics' samples, and what was skipped (for the notes)."""

    def __init__(self, name: str, size: int) -> None:
        self.name = name
        self.size = size  # the file's bytes (the appended-data offsets must be inside them)
        self.formats: dict[str, TopicFormat] = {}
        self.wanted: dict[int, tuple[array.array[int], int]] = {}
        self.topics: dict[int, Subscription] = {}
        self.ids: dict[int, tuple[int, str]] = {}  # each msg_id subscribed: (the byte of its 'A', its topic)
        self.cuts: list[int] | None = None  # where appended data starts (the flag bits message): None, not read yet
        self.unknown: dict[int, int] = {}
        self.short = 0
        self.skipped: list[tuple[int, int]] = []  # corrupt stretches: (first byte, bytes skipped)
        self.resync: tuple[int, int, int] | None = None  # a corrupt header: (byte, type, size)
        self.zeros = True  # the bytes skipped since then are all zeros
        self.notes: list[str] = []

    def other(self, kind: int, body: bytes, at: int) -> None:
        """A message that is not a sample: a format, a subscription or the flag bits taken in."""
        if kind == 70:  # F
            self.define(body, at)
        elif kind == 65:  # A
            self.subscribe(body, at)
        elif kind == 66:  # B
            self.flags(body, at)

    def flags(self, body: bytes, at: int) -> None:
        """The flag bits (the first message): a log with an incompatible flag this reader does
        not know is refused, as pyulog refuses it; appended data is read from its offsets, each
        checked to be in the file (after the flag bits; one past its end noted, as there is no
        data there, and the log read to its end as pyulog does)."""
        if self.cuts is not None:
            return
        self.cuts = []
        incompat = body[8:16]
        if len(body) < 40 or at != 16 or incompat[0] & ~1 or any(incompat[1:]):
            if at == 16 and len(body) >= 16 and (incompat[0] & ~1 or any(incompat[1:])):
                raise InputError(
                    "the log sets a ULog flag this reader does not know (an incompatible, newer format)",
                    file=self.name,
                    hint="convert it with a current pyulog (ulog2csv) and read the CSV",
                )
            return
        if not incompat[0] & 1:
            return
        start = at + 3 + len(body)  # where the messages after the flag bits start
        for k, offset in enumerate(struct.unpack_from("<3Q", body, 16)):
            where = f"the flag bits' appended-data offset {k + 1} (the field at byte {at + 3 + 16 + 8 * k})"
            if not offset:
                continue
            if offset < start:
                raise InputError(
                    f"{where} is {offset}, before the log's messages start (byte {start}): a corrupt flag bits message",
                    file=self.name,
                )
            if offset > self.size:
                self.notes.append(f"{where} is {offset}, past the log's end ({self.size} bytes): read to its end")
                continue
            self.cuts.append(offset)
        self.cuts.sort()

    def define(self, body: bytes, at: int) -> None:
        """A format taken in: its fields, with what is wrong with it kept (an array count that is
        no number, or more than a message holds) for when a wanted topic is laid out by it; a
        second format of a name kept as the byte that it is at, when it differs from the first."""
        text = body.decode("utf-8", "replace")
        name, _, rest = text.partition(":")
        fields = []
        wrong = None
        for item in rest.split(";"):
            kind, _, fname = item.strip().partition(" ")
            if not fname:
                continue
            count = 0
            if "[" in kind:
                kind, _, n = kind.partition("[")
                n = n.removesuffix("]")
                number = ascii_int(n)
                if number is None or number > MOST:
                    what = "not a number (ASCII digits)" if number is None else f"more than a message holds ({MOST})"
                    wrong = wrong or f"field {fname!r} has the array count {shown(n)}: {what}"
                    number = 0
                count = number
            fields.append((kind, count, fname))
        known = self.formats.get(name)
        if known is None:
            self.formats[name] = TopicFormat(fields, at, wrong)
        elif known.fields != fields and known.again is None:
            known.again = at

    def summarise(self) -> None:
        """The notes of what the walk skipped."""
        if self.unknown:
            kinds = ", ".join(f"{chr(k)!r} x{n}" if 32 < k < 127 else f"{k:#04x} x{n}" for k, n in self.unknown.items())
            self.notes.append(f"skipped messages of a type this reader does not know ({kinds}): a newer logger's?")
        if self.skipped:
            first, length = self.skipped[0]
            more = f" (and {len(self.skipped) - 1} more)" if len(self.skipped) > 1 else ""
            self.notes.append(
                f"skipped a corrupt stretch of {length} bytes at byte {first}{more}, resuming at the next sync marker"
            )
        if self.short:
            self.notes.append(f"skipped {self.short} samples shorter than their topic's format (corrupt)")

    def subscribe(self, body: bytes, at: int) -> None:
        """A subscription taken in: a wanted topic's laid out by its format. A msg_id subscribed
        twice, or a wanted topic's instance subscribed twice, is refused where a wanted topic
        is one of them (whose samples are whose cannot be told)."""
        if len(body) < 3:
            return
        instance, msg_id = struct.unpack_from("<BH", body)
        name = body[3:].decode("utf-8", "replace")
        first = self.ids.setdefault(msg_id, (at, name))
        if first[0] != at and (name in TOPICS or first[1] in TOPICS):
            raise InputError(
                f"msg_id {msg_id} is subscribed twice (the 'A' messages at bytes {first[0]} and {at}, "
                f"{first[1]!r} and {name!r}): whose samples are whose cannot be told",
                file=self.name,
            )
        if name not in TOPICS or name not in self.formats:
            return
        same = next((t for t in self.topics.values() if (t.name, t.instance) == (name, instance)), None)
        if same is not None:
            raise InputError(
                f"{name}:{instance} is subscribed twice (the 'A' message at byte {at}, msg_id {msg_id}, after "
                f"the one of msg_id {next(k for k, t in self.topics.items() if t is same)}): which is the stream "
                "cannot be told",
                file=self.name,
            )
        try:
            layout = _flatten(name, self.formats, self.name)
        except (KeyError, ValueError, RecursionError):
            return  # a topic whose format cannot be laid out is not read (as a topic not logged)
        topic = Subscription(name, instance, layout, at=self.formats[name].at)
        self.topics[msg_id] = topic
        self.wanted[msg_id] = (topic.places, layout.size + 2)

    def recheck(self) -> None:
        """The wanted topics laid out again once the whole log is walked: a format that a later
        'F' of its name contradicts is refused (a subscription laid out before it came)."""
        for topic in self.topics.values():
            _flatten(topic.name, self.formats, self.name)


def _flatten(
    name: str,
    formats: dict[str, TopicFormat],
    path: str,
    depth: int = 0,
    done: dict[str, TopicLayout] | None = None,
) -> TopicLayout:
    """A topic's fields by their flattened names (``gyro_rad[0]``, ``nested.x``), as pyulog
    names them, each with its numpy type and offset; nested types laid out in place, each type
    once (``done``). Each field's bytes are added up before its names are made, so a count
    that would lay out more than a message holds is refused, not allocated (as is a format
    whose count is no number, or that a second 'F' of its name contradicts): an InputError
    naming the 'F' message. A type no format defines is a KeyError, nested too deep a
    ValueError (the topic is then not read)."""
    fmt = formats[name]
    where = f"the format of {name} (the 'F' message at byte {fmt.at})"
    if fmt.wrong is not None:
        raise InputError(f"{where}: {fmt.wrong}", file=path)
    if fmt.again is not None:
        raise InputError(
            f"{where} and a second one of {name}, at byte {fmt.again}, differ: which one its samples follow "
            "cannot be told",
            file=path,
        )
    done = {} if done is None else done
    out: dict[str, tuple[str, int]] = {}
    offset = 0
    for kind, count, fname in fmt.fields:
        inner = None
        if kind in _TYPES:
            width = np.dtype(_TYPES[kind]).itemsize
        else:
            if depth > 8:
                raise ValueError(f"{name}: types nested too deep")
            if kind not in done:
                done[kind] = _flatten(kind, formats, path, depth + 1, done)
            inner = done[kind]
            width = inner.size
        if offset + max(count, 1) * width > MOST:
            raise InputError(
                f"{where}: field {fname!r} ({kind}{f'[{count}]' if count else ''}) ends at byte "
                f"{offset + max(count, 1) * width} of a sample, more than a message holds ({MOST} after its "
                "msg_id): no sample of it can be logged",
                file=path,
            )
        if inner is not None and not inner.fields:  # a type of no fields (only padding): its bytes only
            offset += max(count, 1) * width
            continue
        names = [f"{fname}[{i}]" for i in range(count)] if count else [fname]
        for each in names:
            if inner is None:
                out[each] = (_TYPES[kind], offset)
            else:
                out.update({f"{each}.{k}": (t, offset + o) for k, (t, o) in inner.fields.items()})
            offset += width
    while out and next(reversed(out)).startswith("_padding"):  # trailing padding is not always logged
        last = next(reversed(out))
        kind, start = out.pop(last)
        offset = start
    return TopicLayout(out, offset)


_HEAD = struct.Struct("<HBH")  # a message's size and type, and a data message's msg_id
_DATA = ord("D")


class UlogReader(LogReader[UlogIndex]):
    """io.sources' Reader of PX4 ULog files."""

    row = logs.ULOG
    called = "a PX4 ULog"
    corrected_as = "corrected by PX4"

    def walk(self, path: str) -> UlogIndex:
        return _walk_file(path)

    def streams(self, path: str) -> list[Stream]:
        return streams_of(path, self.index(path))

    def table(self, path: str, spec: ReadSpec) -> Table:
        return read_stream(path, spec)


READER = UlogReader()


def _walk_file(path: str) -> UlogIndex:
    """Every message of the log stepped over once; the wanted topics' samples placed."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        walk = _Walk(path, os.fstat(f.fileno()).st_size)
        head = f.read(16)
        digest.update(head)
        if len(head) < 16 or not head.startswith(MAGIC):
            raise InputError("not a PX4 ULog: its first bytes are not ULog's header", file=path)
        if head[7] > 1:
            walk.notes.append(f"ULog version {head[7]} (this reader knows version 1): read as version 1")
        first = f.read(3)  # the flag bits, when there: where appended data starts bounds the reads
        if len(first) == 3 and first[2] == ord("B"):
            first += f.read(struct.unpack_from("<H", first)[0])
            if len(first) >= 43:
                walk.flags(first[3:], 16)
        f.seek(16)
        base = 16
        for cut in [*(walk.cuts or []), None]:
            base = _walk_part(walk, f, digest, base, cut)
            if cut is not None:
                f.seek(cut)
                base = cut
    walk.recheck()
    walk.summarise()
    topics = sorted(walk.topics.values(), key=lambda t: (t.name, t.instance))
    return UlogIndex(topics, digest.hexdigest(), walk.notes, base)


def _walk_part(walk: _Walk, f: BinaryIO, digest: hashlib._Hash, base: int, cut: int | None) -> int:
    """Walk the log from ``base`` to ``cut`` (None: its end); returns where that is."""
    carry = b""
    while True:
        want = CHUNK if cut is None else min(CHUNK, cut - base - len(carry))
        block = f.read(want) if want > 0 else b""
        digest.update(block)
        if not block:
            break
        buf = carry + block if carry else block
        pos = _step(walk, buf, base)
        carry, base = buf[pos:], base + pos
    pos = _step(walk, carry, base)
    if len(carry) - pos >= 3 and walk.resync is None:  # a last message of fewer body bytes than a msg_id
        size = struct.unpack_from("<H", carry, pos)[0]
        pos += 3 + size if pos + 3 + size == len(carry) else 0
    end = base + len(carry)
    if walk.resync is not None:
        if carry[pos:].strip(b"\0"):
            walk.zeros = False
        if cut is None:
            _no_sync(walk, end)
        walk.resync = None
    elif len(carry) > pos:
        what = "the log ends" if cut is None else f"the data before the appended data at byte {cut} ends"
        walk.notes.append(
            f"{what} mid-message (its last {len(carry) - pos} bytes, from byte {base + pos}): cut short, as a "
            "log is when power is lost; read up to there"
        )
    return end


def _step(walk: _Walk, buf: bytes, base: int) -> int:
    """Step over the whole messages of ``buf`` (its first byte at ``base`` in the file): a
    wanted sample's place kept, a definition or subscription taken in, the rest skipped.
    Returns where the first message not wholly in ``buf`` starts."""
    unpack, wanted, end = _HEAD.unpack_from, walk.wanted, len(buf)
    pos = 0
    if walk.resync is not None:
        pos = _resync(walk, buf, 0, base)
        if walk.resync is not None:
            return pos
    while pos + 5 <= end:
        size, kind, mid = unpack(buf, pos)
        after = pos + 3 + size
        if kind not in KNOWN and (kind == 0 or size == 0 or size > BIGGEST):  # corrupt: on at the next sync marker
            walk.resync, walk.zeros = (base + pos, kind, size), True
            pos = _resync(walk, buf, pos + 1, base)
            if walk.resync is not None:
                return pos
            continue
        if after > end:
            break
        if kind == _DATA:
            got = wanted.get(mid)
            if got is not None:
                if size >= got[1]:
                    got[0].append(base + pos + 5)
                else:
                    walk.short += 1
        elif kind in KNOWN:
            walk.other(kind, buf[pos + 3 : after], base + pos)
        else:
            walk.unknown[kind] = walk.unknown.get(kind, 0) + 1
        pos = after
    return pos


def _resync(walk: _Walk, buf: bytes, pos: int, base: int) -> int:
    """Past the next sync marker in ``buf`` (from ``pos``), the stretch before it noted as skipped;
    without one, all but the marker's length less one (it may straddle the next read)."""
    assert walk.resync is not None
    found = buf.find(SYNC, pos)
    stop = found if found >= 0 else max(pos, len(buf) - len(SYNC) + 1)
    if buf[pos:stop].strip(b"\0"):
        walk.zeros = False
    if found < 0:
        return stop
    start = walk.resync[0]
    walk.skipped.append((start, base + found + len(SYNC) - start))
    walk.resync = None
    return found + len(SYNC)


def _no_sync(walk: _Walk, size: int) -> None:
    """A corrupt message with no sync marker after it: the rest of the log is zeros (space a
    logger kept and never wrote: a note), or it cannot be read (exit 2)."""
    assert walk.resync is not None
    at, kind, length = walk.resync
    if walk.zeros:
        walk.notes.append(f"the log ends in {size - at} bytes of zeros (from byte {at}): space never written")
        return
    raise InputError(
        f"a corrupt message at byte {at} (type {kind:#04x}, {length} bytes) and no sync marker after it to "
        "resume reading from",
        file=walk.name,
        hint=f"keep the log up to there (head -c {at}), which reads as a log cut short",
    )


def _parts(topic: Subscription) -> list[UlogSensor]:
    """The sensors ``topic`` carries in this log (sensor_combined's magnetometer only in old logs)."""
    return [p for p in TOPICS[topic.name] if all(f in topic.layout.fields for f in p.fields)]


def _clock(topic: Subscription) -> str:
    return "timestamp_sample" if "timestamp_sample" in topic.layout.fields else "timestamp"


#: What each field read beside a sensor's three is, for the message of a format that lacks it.
_NEEDED = {
    "timestamp": "the samples' time (the format has neither timestamp_sample nor timestamp)",
    "accelerometer_timestamp_relative": "the accelerometer's time after timestamp",
    "magnetometer_timestamp_relative": "the magnetometer's time after timestamp",
    "delta_velocity_dt": "the time the delta velocity is over",
    "delta_angle_dt": "the time the delta angle is over",
}


def _needed(path: str, topic: Subscription, part: UlogSensor) -> list[str]:
    """The fields read for ``part`` of ``topic`` beside its three (its clock, a relative
    timestamp, an integration time); one its format lacks is exit 2 naming it and the format."""
    names = [_clock(topic), *(f for f in (part.relative, part.per) if f)]
    for name in names:
        if name not in topic.layout.fields:
            raise InputError(
                f"{topic.name}:{topic.instance}: the format of {topic.name} (the 'F' message at byte {topic.at}) "
                f"has no field {name!r}, {_NEEDED[name]}: its {part.sensor} cannot be read",
                file=path,
            )
    return names


def _corrected(topic: Subscription) -> tuple[bool, str]:
    """Whether PX4 had corrected the topic's readings, and how that is told (with the source)."""
    if topic.name in ("sensor_combined", "vehicle_imu"):
        return True, _COMBINED if topic.name == "sensor_combined" else _IMU
    if "x_raw" in topic.layout.fields:
        return True, _OLD
    return False, _RAW


def streams_of(path: str, found: UlogIndex) -> list[Stream]:
    """Each topic instance's sensors: rows, mean rate (from its first and last time), units, and
    whether PX4 had corrected it."""
    out = []
    for topic in found.topics:
        places = np.frombuffer(topic.places, dtype=np.int64)
        rate = None
        if len(places) > 1 and _clock(topic) in topic.layout.fields:
            ends = gather(path, places[[0, -1]], topic.layout.fields, [_clock(topic)])[_clock(topic)]
            span = float(ends[1] - ends[0]) * 1e-6
            rate = (len(places) - 1) / span if span > 0 else None
        corrected, how = _corrected(topic)
        for part in _parts(topic):
            out.append(Stream(topic.name, topic.instance, part.sensor, len(places), rate, part.units, corrected, how))
    return out


def read_stream(path: str, spec: ReadSpec) -> Table:
    """The readings of the stream ``spec`` names (or the log's one stream of ``spec.sensor``);
    with ``spec.paired`` and a ``sensor_gyro`` stream for the gyroscope, either sensor on the
    gyroscope's samples (:func:`paired`)."""
    found = READER.index(path)
    listed = streams_of(path, found)
    if spec.paired:
        gyro = sources.pick(path, listed, replace(spec, sensor="gyroscope"))
        if gyro.name == "sensor_gyro":
            return paired(path, found, listed, spec, gyro)
    return _table(path, found, sources.pick(path, listed, spec), spec.rate is None)


def paired(path: str, found: UlogIndex, listed: list[Stream], spec: ReadSpec, gyro: Stream) -> Table:
    """``spec.sensor`` of the turns pipelines' one log of both sensors: ``gyro``'s samples, and
    ``sensor_accel`` of the same instance resampled onto their timestamps by linear
    interpolation. Gyroscope samples outside the accelerometer's time span are dropped (a note);
    an accelerometer under ``PAIR_RATE`` of the gyroscope's rate, or streams that overlap on under
    ``PAIR_OVERLAP`` of the gyroscope's samples, is exit 2."""
    key = f"sensor_accel:{gyro.instance}"
    acc = next((s for s in listed if s.key == key and s.rows > 1), None)
    if acc is None:
        raise InputError(
            f"{gyro.key} has no {key} beside it with samples: the turns take the accelerometer of the "
            "gyroscope's instance",
            file=path,
            hint="--stream sensor_gyro:N picks a gyroscope whose instance has both (tumblecal logs FILE lists them)",
        )
    g, a = _table(path, found, gyro, True), _table(path, found, acc, True)
    assert g.clock is not None
    assert a.clock is not None
    if not (acc.rate and gyro.rate and acc.rate >= PAIR_RATE * gyro.rate):
        raise InputError(
            f"{acc.key} is logged at {acc.rate or 0:.4g} Hz, under {PAIR_RATE:.0%} of {gyro.key}'s "
            f"{gyro.rate or 0:.4g} Hz: too slow to put on the gyroscope's samples",
            file=path,
            hint="log sensor_accel at the gyroscope's rate (the logger's high-rate IMU profile)",
        )
    inside = (g.clock >= a.clock[0]) & (g.clock <= a.clock[-1])
    if inside.mean() < PAIR_OVERLAP:
        raise InputError(
            f"{acc.key} and {gyro.key} overlap on {inside.mean():.0%} of the gyroscope's samples "
            f"(under {PAIR_OVERLAP:.0%}): they are not one session",
            file=path,
            hint="give --stream sensor_gyro:N of an instance whose accelerometer was logged over the same time",
        )
    clock = g.clock[inside]
    notes = [*g.notes, *(n for n in a.notes if n not in g.notes)]
    if not inside.all():
        notes.append(f"{path}: {gyro.key}: {int((~inside).sum())} samples outside {acc.key}'s time span dropped")
    notes.append(
        f"{path}: the accelerometer is {acc.key} (the instance of {gyro.key}), resampled onto its "
        f"{len(clock)} timestamps by linear interpolation"
    )
    if spec.sensor == "gyroscope":
        hot = None if g.temperature is None else g.temperature[inside]
        return replace(g, values=g.values[inside], clock=clock, temperature=hot, notes=tuple(notes))
    values = np.column_stack([np.interp(clock, a.clock, a.values[:, k]) for k in range(3)])
    hot = None if a.temperature is None else np.interp(clock, a.clock, a.temperature)
    return replace(a, values=values, clock=clock, temperature=hot, notes=tuple(notes))


def _table(path: str, found: UlogIndex, chosen: Stream, check_clock: bool) -> Table:
    """The readings of the stream ``chosen``; ``check_clock``: samples whose clock goes back dropped."""
    topic = next(t for t in found.topics if (t.name, t.instance) == (chosen.name, chosen.instance))
    part = next(p for p in _parts(topic) if p.sensor == chosen.sensor)
    names = [*part.fields, *_needed(path, topic, part)]
    if "temperature" in topic.layout.fields:
        names.append("temperature")
    data = gather(path, np.frombuffer(topic.places, dtype=np.int64), topic.layout.fields, names)
    values = np.column_stack([data[f] for f in part.fields])
    clock = data[_clock(topic)]
    temperature = data.get("temperature")
    notes = [f"{path}: {note}" for note in found.notes]
    keep = np.ones(len(values), dtype=bool)
    if part.relative is not None:  # a sensor's own time: sensor_combined's relative timestamp
        relative = data[part.relative]
        keep &= relative != INVALID_RELATIVE
        clock = clock + np.where(keep, relative, 0)
    if part.per is not None:  # vehicle_imu: the delta over its integration time (µs) is the mean reading
        dt = data[part.per]
        keep &= dt > 0
        values = values / np.where(keep, dt * 1e-6, 1.0)[:, None]
    if not keep.all():
        what = "an invalid relative timestamp" if part.relative else "no integration time"
        notes.append(f"{path}: {chosen.key}: {int((~keep).sum())} samples with {what} skipped")
    if check_clock:
        keep &= forward(path, chosen.key, clock, keep, notes)
    if not keep.all():
        values, clock = values[keep], clock[keep]
        temperature = None if temperature is None else temperature[keep]
    notes.insert(0, READER.read_note(path, chosen, len(values)))
    return Table(
        NAMES[chosen.sensor],
        values,
        clock,
        "us",
        temperature,
        None,
        found.sha256,
        tuple(notes),
        corrected=chosen.corrected,
        stream=chosen,
    )
