"""ROS bags and MCAP: the ``sensor_msgs/Imu`` and ``sensor_msgs/MagneticField`` topics of a ROS 1
bag (``.bag``), a ROS 2 bag (a folder of ``metadata.yaml`` and sqlite3 ``.db3`` or ``.mcap``
files) or a plain MCAP file (ROS 2 messages), as io.sources streams.

The bag is opened with rosbags (the ``[ros]`` extra, Apache-2.0, no ROS install), which hands over
each message of the topics read as its serialized bytes; the messages are then decoded here with
numpy a batch at a time (``decode``), not one by one with rosbags' deserializer: an Imu message
is a header (stamp, then the frame_id string) and a fixed block of float64s after it, so one
record view over a batch's bytes reads every message's stamp, string length and values at once.
ROS 1 messages are packed little-endian; ROS 2 messages are CDR (a 4-byte encapsulation header,
little- or big-endian, each float64 aligned to 8 bytes from after that header). Only the decoded
numbers are kept: the bag is never in memory whole. A command picks its topic by the bag's own
message counts and decodes that topic alone, in the same pass; a listing decodes them all.

Time is the header stamp (``sec`` + ``nanosec``), in seconds from the topic's first stamp (epoch
nanoseconds as float64 would lose 256 ns); a topic whose stamps are all zero (a driver that never
set them) is read by the bag's record time, with a note. Raw or corrected: ROS messages carry no
flag, so the topic's name tells (``judged``, with the conventions it follows).
A recording cut short has no index (ROS 1: rosbag writes it last) or no summary (MCAP): its
records are walked one after another (``Unindexed``, ``Unfinished``), as rosbag reindex and mcap
recover do, up to the cut, with a note. What rosbags cannot read otherwise (a damaged chunk) is
one InputError naming the file, or, when some messages were read before it, a note saying where
the reading stopped.

What a chunk inflates to is bounded (``inflate``), whoever reads it: it is streamed, up to its
declared uncompressed size (a ROS 1 chunk's ``size``, an MCAP chunk's ``uncompressed_size``), which
may not pass ``CHUNK_BYTES``, and one pass over a bag's file inflates at most ``--max-spool``
(``io.logs.inflating_at_most``; ``MAX_SPOOL`` when not given) in all; beyond it is exit 2, refused before it is
inflated. rosbags' readers inflate through it too: each ROS 1 chunk's decompressor (``bound_chunks``),
MCAP's (``DECOMPRESSORS``), a ROS 2 bag folder's files compressed whole (``FileZstd``); and they
read the file through ``Within``, so a length that runs past the file's end reads what the file
holds, not a buffer of the size it declares. A walk checks the fields it reads of each record
(a ROS 1 record's ``op``, ``conn``, ``time``; an MCAP record's lengths and strings): one that lies
ends the walk there, with the note.
"""

from __future__ import annotations

import array
import contextlib
import hashlib
import os
import re
import sys
from collections.abc import Callable, Collection, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray
from rosbags.interfaces import (
    Connection,
)
from rosbags.rosbag1 import Reader as Reader1
from rosbags.rosbag2 import Reader as Reader2

if sys.version_info >= (3, 14):
    pass
else:  # rosbags' own dependency
    pass

from tumblecal_cli.core.arrays import BoolArray, FloatArray, IntArray
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import logs, sources
from tumblecal_cli.io.logs import fields as logfields
from tumblecal_cli.io.logs.bagfile import (
    MCAP_MAGIC,
    Unfinished,
    Unindexed,
    Within,
    bag_files,
    bound_chunks,
    passing,
)
from tumblecal_cli.io.logs.reader import LogReader, file_key
from tumblecal_cli.io.readspec import ReadSpec
from tumblecal_cli.io.sources import Stream, Table

if TYPE_CHECKING:
    pass

IMU = "sensor_msgs/msg/Imu"
MAG = "sensor_msgs/msg/MagneticField"
ROS1_MAGIC = b"#ROSBAG V"
#: Bytes of messages gathered before a batch is decoded.
BATCH = 1 << 22
#: A clock that goes back this often is not a stray message but two sessions (exit 2).
BACK_SHARE = 0.01


@dataclass(frozen=True)
class BagSensor:
    """One sensor a message type carries: the offset of its three float64s after the header."""

    sensor: str
    offset: int
    units: str


#: The message types read, the sensors each carries, and the bytes after the header (the
#: fixed block: Imu's orientation, angular velocity and linear acceleration with their
#: covariances; MagneticField's field and its covariance).
TYPES: dict[str, tuple[tuple[BagSensor, ...], int]] = {
    IMU: ((BagSensor("accelerometer", 200, "m/s^2"), BagSensor("gyroscope", 104, "rad/s")), 296),
    MAG: ((BagSensor("magnetometer", 0, "T"),), 96),
}
#: The columns a calibration records for each sensor.
NAMES = {
    "accelerometer": ("acc_x", "acc_y", "acc_z"),
    "gyroscope": ("gyr_x", "gyr_y", "gyr_z"),
    "magnetometer": ("mag_x", "mag_y", "mag_z"),
}

_RAW = "raw: named so (imu/data_raw: what imu_tools' filters read; REP-145's imu_raw namespace)"
_DATA = (
    "corrected: imu/data is what imu_tools' filters publish from imu/data_raw, the gyroscope less their bias "
    "estimate by default (imu_complementary_filter, complementary_filter_ros.cpp: publish)"
)
_NAMED = (
    "corrected: named so (imu_calib's apply_calib publishes 'corrected'; REP-145's imu_unbiased, imu_compensated "
    "namespaces)"
)
_UNTOLD = (
    "raw: its name does not say (no 'raw', not imu/data); REP-145 asks drivers to publish readings as the device "
    "reports them"
)
_CORRECTED_WORDS = frozenset({"corrected", "calibrated", "calib", "filtered", "unbiased", "compensated"})


def judged(topic: str) -> tuple[bool, str]:
    """Whether a topic's readings were already corrected, told by its name (ROS has no flag),
    and how that is told: a name with the word ``raw`` is raw; ``imu/data`` (any namespace
    ending in ``imu``) or a name saying corrected, calibrated, filtered, unbiased or compensated
    is corrected; any other name is read as raw (with a note when read)."""
    words = set(re.split(r"[/_\-.]+", topic.lower()))
    parts = [p for p in topic.lower().split("/") if p]
    if "raw" in words:
        return False, _RAW
    if words & _CORRECTED_WORDS:
        return True, _NAMED
    if len(parts) >= 2 and parts[-1] == "data" and parts[-2].endswith("imu"):
        return True, _DATA
    return False, _UNTOLD


class _Source(Protocol):
    """What this reader uses of a rosbags reader (rosbag1.Reader and rosbag2's storage readers)."""

    @property
    def connections(self) -> list[Connection]: ...

    def open(self) -> None: ...

    def close(self) -> None: ...

    def messages(self, connections: Collection[Connection], /) -> Iterator[tuple[Connection, int, bytes]]: ...


@dataclass
class Topic:
    """One topic of a type read: its name and type, the messages the bag says it holds, and
    those decoded: header stamps and record times (ns), the values (``(n, 3)`` per sensor)."""

    name: str
    msgtype: str
    count: int
    stamps: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    received: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    values: dict[str, FloatArray] = field(default_factory=dict)
    odd: int = 0  # messages not of the type's layout (skipped)
    decoded: bool = False


@dataclass
class BagIndex:
    """A bag opened: its kind, the topics of the types read (those decoded so far), the others
    (name, type), the notes of what could not be read, and its sha256 once asked for."""

    kind: str
    topics: list[Topic]
    others: list[tuple[str, str]]
    notes: list[str]
    sha256: str = ""

    def topic(self, name: str) -> Topic:
        return next(t for t in self.topics if t.name == name)


class RosReader(LogReader[BagIndex]):
    """io.sources' Reader of ROS 1 and ROS 2 bags and MCAP files: the bag opened once for the
    topics a command reads (``index``), decoded only as far as they are asked for."""

    row = logs.ROS
    called = "a ROS bag"
    corrected_as = "corrected, by its name"

    def walk(self, path: str) -> BagIndex:
        return _open_bag(path, None, lambda found: ())

    def streams(self, path: str) -> list[Stream]:
        return streams_of(self.index(path, lambda found: [t.name for t in found.topics]))

    def table(self, path: str, spec: ReadSpec) -> Table:
        return read_stream(path, spec)

    def pick(self, path: str, spec: ReadSpec) -> Stream:
        """The stream ``spec`` reads (io.sources.stream_of), saying what a --stream that names no
        IMU topic names; its topic decoded now, in the same pass (it is read next)."""
        chosen: list[Stream] = []

        def choose(found: BagIndex) -> list[str]:
            chosen.append(sources.pick(path, streams_of(found, decoded=False), _asked(path, found, spec)))
            return [chosen[-1].name]

        self.index(path, choose)
        return chosen[-1]

    def index(self, path: str, choose: Callable[[BagIndex], Collection[str]] = lambda found: ()) -> BagIndex:
        """``path`` opened, with the topics ``choose`` names (of its topics) decoded, in one pass
        over the bag; kept while its files' sizes and times are the same, and opened again only
        for topics not decoded yet."""
        key = file_key(path)
        found = self.kept(key)
        if found is None or not all(found.topic(n).decoded for n in choose(found)):
            found = _open_bag(path, found, choose)
            self.keep(key, found)
        return found


READER = RosReader()


def index(path: str, choose: Callable[[BagIndex], Collection[str]] = lambda found: ()) -> BagIndex:
    """``path`` opened by the reader (:meth:`RosReader.index`), its topics ``choose`` names decoded."""
    return READER.index(path, choose)


def _open_bag(path: str, found: BagIndex | None, choose: Callable[[BagIndex], Collection[str]]) -> BagIndex:
    """The bag ``path`` opened (``found``: what an earlier pass read of it), and the topics ``choose``
    names that are not decoded yet decoded, in one pass."""
    kind = _kind(path)
    notes = [] if found is None else found.notes
    with contextlib.ExitStack() as stack:
        with passing(path):  # (an MCAP file without a summary is inflated to be opened)
            readers = [_opened(path, kind, reader, notes, stack) for reader in _sources(path, kind, notes)]
        found = found or _summary(kind, readers, notes)
        names = {n for n in choose(found) if not found.topic(n).decoded}
        for reader in readers:
            wanted = [c for c in reader.connections if c.topic in names and c.msgtype in TYPES]
            if wanted:
                with passing(path):
                    _gather(path, kind, reader.messages(wanted), [found.topic(n) for n in sorted(names)], notes)
        for name in names:
            found.topic(name).decoded = True
    return found


def _opened(path: str, kind: str, reader: _Source, notes: list[str], stack: contextlib.ExitStack) -> _Source:
    """``reader`` opened (and closed by ``stack``), a ROS 1 bag's chunks bounded (``bound_chunks``); a
    ROS 1 bag without its index (a recording cut short) walked instead, with a note. What cannot
    be opened: exit 2; what inflates past the pass's bound (an InputError) as it is."""
    try:
        reader.open()
        stack.callback(reader.close)
        if isinstance(reader, Reader1):
            bound_chunks(reader, path)
        return reader
    except InputError:
        raise
    except Exception as err:  # rosbags' own errors, and what its decompressors raise
        mcap = isinstance(reader, Reader2.STORAGE_PLUGINS[".mcap"])
        if kind == "ROS 1 bag" and re.search("not indexed|index looks damaged", str(err)):
            walked: Unindexed | Unfinished = Unindexed(path)
            what, record, tool = "the ROS 1 bag has no index", "connection", "rosbag reindex"
        elif mcap and re.search("end magic|footer|summary", str(err)):
            walked = Unfinished(str(getattr(reader, "path", path)))
            file = "the MCAP file" if kind == "MCAP file" else f"its {Path(walked.path).name}"
            what, record, tool = f"{file} has no summary", "channel", "mcap recover"
        else:
            raise _damaged(path, kind, err) from None
    stack.callback(walked.close)
    walked.open()
    if not walked.connections:
        walked.close()
        raise InputError(
            f"{what}, and no {record} record {walked.stop or 'before its end'}: nothing to read",
            file=path,
            hint="check that the file is whole (its size, a copy that finished)",
        )
    notes.append(
        f"{path}: {what} (a recording cut short?): its records read one after another"
        + (f", {walked.stop}" if walked.stop else "")
        + f", as {tool} would"
    )
    return walked


def _summary(kind: str, readers: list[_Source], notes: list[str]) -> BagIndex:
    """The topics of an opened bag, and the messages each holds (as the bag says)."""
    topics: dict[str, Topic] = {}
    others: dict[str, str] = {}
    for reader in readers:
        for c in reader.connections:
            if c.msgtype in TYPES:
                topic = topics.setdefault(c.topic, Topic(c.topic, c.msgtype, 0))
                topic.count += c.msgcount
            else:
                others.setdefault(c.topic, c.msgtype)
    return BagIndex(kind, sorted(topics.values(), key=lambda t: t.name), sorted(others.items()), notes)


def _kind(path: str) -> str:
    if os.path.isdir(path):
        return "ROS 2 bag"
    with open(path, "rb") as f:
        head = f.read(16)
    return "ROS 1 bag" if head.startswith(ROS1_MAGIC) else "MCAP file" if head.startswith(MCAP_MAGIC) else "ROS 2 bag"


def _sources(path: str, kind: str, notes: list[str]) -> list[_Source]:
    """The rosbags readers of a bag: a ROS 1 bag's, a ROS 2 bag folder's (its storage files read
    directly when it has no metadata.yaml), an MCAP or sqlite3 file's (chosen by its bytes, not
    its name)."""
    plugins = Reader2.STORAGE_PLUGINS
    if kind == "ROS 1 bag":
        return [Reader1(Within(path))]
    if kind == "MCAP file":
        return [plugins[".mcap"](Within(path))]
    if not os.path.isdir(path):
        return [plugins[".db3"](Within(path))]
    if os.path.exists(os.path.join(path, "metadata.yaml")):
        return [plugins["dir"](Within(path))]
    stored = [p for p in bag_files(path) if p.suffix in (".db3", ".mcap")]
    if not stored:
        raise InputError("a folder with neither metadata.yaml nor .db3 or .mcap files: not a ROS 2 bag", file=path)
    notes.append(
        f"{path}: no metadata.yaml (a recording cut short?): read its {', '.join(p.name for p in stored)} directly, "
        "as ros2 bag reindex would"
    )
    return [plugins[p.suffix](Within(p)) for p in stored]


def _damaged(path: str, kind: str, err: BaseException) -> InputError:
    """rosbags' error (or a decompressor's, or a failed assertion in its reader) as one line."""
    text = re.sub(r"\('(.*)',\)", r"\1", str(err).strip()) or type(err).__name__  # rosbags quotes its args
    hint = "check that the file is whole (its size, a copy that finished)"
    if "end magic" in text or "Truncated" in text:
        hint = "the file was cut short: mcap recover FILE -o FIXED.mcap (the MCAP command line tool) rewrites it whole"
    elif "Profile is not ros2" in text:
        hint = "an MCAP file of ROS 1 messages: convert it to a ROS 2 bag (rosbags-convert) or to a ROS 1 bag"
    return InputError(f"cannot read this {kind}: {text}", file=path, hint=hint)


def _sha256(files: list[Path]) -> str:
    """The sha256 of the bag's bytes: its file's, or its folder's files' one after another."""
    digest = hashlib.sha256()
    for part in files:
        with open(part, "rb") as f:
            while block := f.read(1 << 20):
                digest.update(block)
    return digest.hexdigest()


class _Batch:
    """The messages of one topic gathered since its last decode: their bytes, sizes and record
    times, and what has been decoded so far."""

    def __init__(self, topic: Topic, cdr: bool) -> None:
        self.topic, self.cdr = topic, cdr
        self.buf = bytearray()
        self.sizes: array.array[int] = array.array("q")
        self.times: array.array[int] = array.array("q")
        self.done: list[tuple[IntArray, IntArray, FloatArray, BoolArray]] = []

    def flush(self) -> None:
        if not self.sizes:
            return
        parts, tail = TYPES[self.topic.msgtype]
        sizes = np.frombuffer(self.sizes, dtype=np.int64)
        stamps, values, ok = decode(bytes(self.buf), sizes, self.cdr, tail, tuple(p.offset for p in parts))
        self.done.append((stamps, np.frombuffer(self.times, dtype=np.int64).copy(), values, ok))
        self.buf, self.sizes, self.times = bytearray(), array.array("q"), array.array("q")

    def finish(self) -> None:
        """The decoded messages into the topic (those not of the layout counted and left out)."""
        self.flush()
        topic, parts = self.topic, TYPES[self.topic.msgtype][0]
        if not self.done:
            return
        ok = np.concatenate([d[3] for d in self.done])
        topic.odd += int((~ok).sum())
        topic.stamps = np.concatenate([d[0] for d in self.done])[ok]
        topic.received = np.concatenate([d[1] for d in self.done])[ok]
        values = np.concatenate([d[2] for d in self.done])[ok]
        topic.values = {p.sensor: values[:, 3 * k : 3 * k + 3] for k, p in enumerate(parts)}
        self.done = []


def _gather(
    path: str, kind: str, messages: Iterator[tuple[Connection, int, bytes]], topics: list[Topic], notes: list[str]
) -> None:
    """The messages rosbags yields, gathered per topic and decoded a batch at a time. An error
    of rosbags' part way through keeps what was read before it, with a note; before any, exit 2."""
    cdr = kind != "ROS 1 bag"
    batches = {topic.name: _Batch(topic, cdr) for topic in topics}
    read = 0
    while True:
        try:
            conn, t, data = next(messages)
        except StopIteration:
            break
        except InputError:  # more inflated than the pass may: exit 2, not a note
            raise
        except Exception as err:  # rosbags' own errors, and what its decompressors raise (not this loop's)
            if read == 0:
                raise _damaged(path, kind, err) from None
            text = str(err).strip() or type(err).__name__
            notes.append(
                f"{path}: the {kind} cannot be read past its first {read} messages of {', '.join(batches)} ({text}): "
                "read up to there"
            )
            break
        batch = batches[conn.topic]
        batch.buf += data
        batch.sizes.append(len(data))
        batch.times.append(t)
        read += 1
        if len(batch.buf) >= BATCH:
            batch.flush()
    for batch in batches.values():
        batch.finish()


def _view(padded: bytes, dtype: np.dtype[np.void] | np.dtype[np.uint16]) -> NDArray[np.void]:
    """A record of ``dtype`` at every byte of ``padded`` (indexed by where the messages start)."""
    return np.ndarray((len(padded) - dtype.itemsize + 1,), dtype=dtype, buffer=padded, strides=(1,))


def decode(
    buf: bytes, sizes: IntArray, cdr: bool, tail: int, offsets: tuple[int, ...]
) -> tuple[IntArray, FloatArray, BoolArray]:
    """The header stamps (ns), the float64 triplets at ``offsets`` after the header (``(n,
    3 * len(offsets))``) and whether each message is of the layout, of the messages packed in
    ``buf`` (``sizes`` bytes each): ROS 1 (``seq``, ``sec``, ``nsec``, the frame_id's length and
    bytes, then the block) or CDR (the encapsulation, ``sec``, ``nanosec``, the frame_id's length
    and bytes with its NUL, then the block from the next multiple of 8 after the encapsulation:
    0x0001 little-endian, 0x0000 big-endian). A message is of the layout when its size is its
    header's and the ``tail`` bytes of the block."""
    n = len(sizes)
    starts = np.zeros(n, dtype=np.int64)
    np.cumsum(sizes[:-1], out=starts[1:])
    padded = bytes(buf) + bytes(max(offsets) + 40)  # a record view reaches past the last message
    stamps = np.zeros(n, dtype=np.int64)
    values = np.full((n, 3 * len(offsets)), np.nan)
    ok = np.zeros(n, dtype=bool)
    whole = sizes >= 16
    groups = [("<", whole)]
    if cdr:
        encapsulation = _view(padded, np.dtype(">u2"))[starts]
        groups = [("<", whole & (encapsulation == 1)), (">", whole & (encapsulation == 0))]
    for order, rows in groups:
        if rows.any():
            where = np.flatnonzero(rows)
            good, stamp, found = _decode(padded, starts[where], sizes[where], (order, cdr, tail), offsets)
            stamps[where[good]], values[where[good]], ok[where[good]] = stamp, found, True
    return stamps, values, ok


def _decode(
    padded: bytes, starts: IntArray, sizes: IntArray, how: tuple[str, bool, int], offsets: tuple[int, ...]
) -> tuple[BoolArray, IntArray, FloatArray]:
    """decode's messages of one byte order: which are of the layout, their stamps and values."""
    order, cdr, tail = how
    head = np.dtype(
        {
            "names": ["sec", "nsec", "length"],
            "formats": [order + ("i4" if cdr else "u4"), order + "u4", order + "u4"],
            "offsets": [4, 8, 12],
            "itemsize": 16,
        }
    )
    h = _view(padded, head)[starts]
    length = h["length"].astype(np.int64)
    at = starts + (4 + ((12 + length + 7) & ~7) if cdr else 16 + length)
    good = (length < sizes) & (at - starts + tail == sizes)
    names = [f"v{k}" for k in range(len(offsets))]
    block = np.dtype(
        {
            "names": names,
            "formats": [(order + "f8", (3,))] * len(offsets),
            "offsets": list(offsets),
            "itemsize": max(offsets) + 24,
        }
    )
    v = _view(padded, block)[at[good]]
    stamps = h["sec"][good].astype(np.int64) * 1_000_000_000 + h["nsec"][good].astype(np.int64)
    return good, stamps, np.column_stack([v[name] for name in names]).astype(np.float64)


def _clock(topic: Topic) -> IntArray:
    """A topic's time: its header stamps, or its record times when the stamps are all zero."""
    return topic.received if len(topic.stamps) and not topic.stamps.any() else topic.stamps


def streams_of(found: BagIndex, decoded: bool = True) -> list[Stream]:
    """Each topic's sensors: rows (those decoded, or with ``decoded`` off as the bag counts them:
    what a stream is picked by, whatever has been decoded so far), mean rate (from its first and
    last time; None for a topic not decoded), units, and whether it was corrected (told by its
    name)."""
    out = []
    for topic in found.topics:
        clock, rate = _clock(topic), None
        if len(clock) > 1 and clock[-1] > clock[0]:
            rate = (len(clock) - 1) / (float(clock[-1] - clock[0]) * 1e-9)
        rows = len(clock) if topic.decoded and decoded else topic.count
        corrected, how = judged(topic.name)
        for part in TYPES[topic.msgtype][0]:
            out.append(Stream(topic.name, None, part.sensor, rows, rate, part.units, corrected, how))
    return out


def _listing(found: BagIndex) -> str:
    """The bag's topics: those read, and the others with their types."""
    read = [t.name for t in found.topics if (len(t.stamps) if t.decoded else t.count)]
    others = [f"{name} ({kind})" for name, kind in found.others]
    return (
        "its IMU topics: "
        + (", ".join(read) or "none")
        + ("; its other topics: " + ", ".join(others) if others else "")
    )


def _asked(path: str, found: BagIndex, spec: ReadSpec) -> ReadSpec:
    """``spec`` with ``--stream`` as the bag names the topic (a leading / added where it has
    none); a topic of another type, or a bag without IMU topics: an InputError naming them."""
    names = {t.name: t for t in found.topics}
    if spec.stream is not None:
        name = spec.stream.strip()
        if name not in names and name not in dict(found.others) and "/" + name in {*names, *dict(found.others)}:
            name = "/" + name
            spec = replace(spec, stream=name)
        if name in dict(found.others):
            raise InputError(
                f"{name} is a {dict(found.others)[name]} topic: tumblecal reads {IMU} and {MAG}",
                file=path,
                hint=_listing(found),
            )
    if not found.topics:
        raise InputError(f"the {found.kind} has no {IMU} or {MAG} topic", file=path, hint=_listing(found))
    return spec


def read_stream(path: str, spec: ReadSpec) -> Table:
    """The readings of the topic ``spec`` names (or the bag's one topic of ``spec.sensor``)."""
    chosen = READER.pick(path, spec)
    found = READER.index(path)
    topic = found.topic(chosen.name)
    if not len(topic.stamps):
        why = f"of the layout of {topic.msgtype} (a type of the same name defined otherwise?)" if topic.odd else ""
        raise InputError(
            f"none of the {topic.count} messages of {topic.name} could be read" + (f": none is {why}" if why else ""),
            file=path,
            hint=" ".join(found.notes) or None,
        )
    found.sha256 = found.sha256 or _sha256(bag_files(path))
    values, clock = topic.values[chosen.sensor], _clock(topic)
    notes = list(found.notes)
    if topic.odd:
        notes.append(
            f"{path}: {topic.name}: {topic.odd} messages not of the layout of {topic.msgtype} skipped (corrupt?)"
        )
    keep = np.ones(len(clock), dtype=bool)
    by_record = clock is topic.received
    if by_record:
        notes.append(f"{path}: {topic.name}: every header stamp is zero: read by the bag's record times instead")
    elif not (clock > 0).all():
        keep &= clock > 0
        notes.append(f"{path}: {topic.name}: {int((~keep).sum())} messages with a zero header stamp skipped")
    if spec.rate is None:
        keep &= logfields.forward(path, topic.name, clock, keep, notes, 1e9, ("message", "header stamp"))
    if not keep.all():
        values, clock = values[keep], clock[keep]
    if chosen.how == _UNTOLD:
        notes.append(
            f"{path}: {topic.name} read as raw: its name does not say whether a filter or a calibration had "
            "corrected it (imu/data_raw is raw, imu/data corrected); if one had, --stream a raw topic"
        )
    stamps = "record times" if by_record else "header stamps"
    first = int(clock[0]) if len(clock) else 0
    since = f"; time in s from its first {stamps[:-1]}, {first // 1_000_000_000}.{first % 1_000_000_000:09d} s"
    notes.insert(0, READER.read_note(path, chosen, len(values), since))
    return Table(
        NAMES[chosen.sensor],
        np.ascontiguousarray(values),
        (clock - first).astype(np.float64) / 1e9,  # exact to the ns for 104 days; an epoch in ns is not
        "s",
        None,
        None,
        found.sha256,
        tuple(notes),
        corrected=chosen.corrected,
        stream=chosen,
    )
