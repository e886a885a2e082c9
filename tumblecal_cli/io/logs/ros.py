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
(``bounded``; ``MAX_SPOOL`` when not given) in all; beyond it is exit 2, refused before it is
inflated. rosbags' readers inflate through it too: each ROS 1 chunk's decompressor (``_bound``),
MCAP's (``DECOMPRESSORS``), a ROS 2 bag folder's files compressed whole (``_FileZstd``); and they
read the file through ``_Within``, so a length that runs past the file's end reads what the file
holds, not a buffer of the size it declares. A walk checks the fields it reads of each record
(a ROS 1 record's ``op``, ``conn``, ``time``; an MCAP record's lengths and strings): one that lies
ends the walk there, with the note.
"""

from __future__ import annotations

import array
import bz2
import contextlib
import functools
import hashlib
import io
import mmap
import os
import pathlib
import re
import struct
import sys
from collections.abc import Callable, Collection, Iterator
from contextvars import ContextVar
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO, Protocol

import lz4.frame  # type: ignore[import-untyped]  # rosbags' own dependency (ROS 1 bags' lz4 chunks)
import numpy as np
from numpy.typing import NDArray
from rosbags.interfaces import (
    Connection,
    ConnectionExtRosbag1,
    ConnectionExtRosbag2,
    MessageDefinition,
    MessageDefinitionFormat,
)
from rosbags.rosbag1 import Reader as Reader1
from rosbags.rosbag2 import Reader as Reader2
from rosbags.rosbag2 import reader as rosbag2_reader
from rosbags.rosbag2.storage_mcap import DECOMPRESSORS

if sys.version_info >= (3, 14):
    from compression import zstd
else:  # rosbags' own dependency
    from backports import zstd

from tumblecal_cli.core.arrays import BoolArray, FloatArray, IntArray
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import logs, sources
from tumblecal_cli.io.logs import fields as logfields
from tumblecal_cli.io.logs.reader import LogReader, file_key
from tumblecal_cli.io.outputs import MAX_SPOOL
from tumblecal_cli.io.readspec import ReadSpec
from tumblecal_cli.io.sources import Stream, Table

if TYPE_CHECKING:
    from _typeshed import WriteableBuffer

IMU = "sensor_msgs/msg/Imu"
MAG = "sensor_msgs/msg/MagneticField"
ROS1_MAGIC = b"#ROSBAG V"
MCAP_MAGIC = b"\x89MCAP0\r\n"
#: Bytes of messages gathered before a batch is decoded.
BATCH = 1 << 22
#: A clock that goes back this often is not a stray message but two sessions (exit 2).
BACK_SHARE = 0.01
#: The most one chunk may inflate to: a chunk holds whole messages (rosbag closes one past 768
#: KiB, an MCAP writer past 4 MiB or so), and roscpp refuses a message over a gigabyte. A chunk
#: that declares more is refused before it is inflated.
CHUNK_BYTES = 1 << 30
#: Bytes inflated at a time (a chunk's output is checked against its declared size as it grows).
STEP = 1 << 24


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


class _Damaged(Exception):
    """A chunk or a record that cannot be read: ``why`` (naming the field that lies), after
    ``where`` it is (the chunk at byte N) in its text; exit 2 naming the file, or the note of a
    walk that stops there (which says where itself)."""

    def __init__(self, why: str, where: str = "") -> None:
        self.why = why
        super().__init__(f"{where}: {why}" if where else why)


#: What ``bounded`` gives: the most one pass over a bag's file inflates (None: MAX_SPOOL).
_LIMIT: ContextVar[int | None] = ContextVar("tumblecal_ros_limit", default=None)


@contextlib.contextmanager
def bounded(limit: int | None) -> Iterator[None]:
    """Bags read inside inflate at most ``limit`` bytes a pass over a file (--max-spool, as
    read_twice is given it; None: MAX_SPOOL)."""
    token = _LIMIT.set(limit)
    try:
        yield
    finally:
        _LIMIT.reset(token)


class _Pass:
    """One pass over a bag's files (its opening, or the reading of its messages): what its chunks
    may still inflate to in all, and the files to find a chunk in by its bytes (rosbags' MCAP
    reader hands its decompressors a chunk's data, not where it is)."""

    def __init__(self, path: str | None) -> None:
        limit = _LIMIT.get()
        self.path, self.given = path, limit is not None
        self.bound = self.left = MAX_SPOOL if limit is None else limit

    def charge(self, size: int, where: Callable[[], str]) -> None:
        """``size`` more bytes to inflate: beyond the bound, exit 2 before they are."""
        if size <= self.left:
            self.left -= size
            return
        text = _size(self.bound)
        if self.given:
            what, hint = f"more than --max-spool {text}", "raise --max-spool if the bag is that large"
        else:
            what = f"more than {text}, the most one read of a log inflates (--max-spool's default)"
            hint = "give --max-spool (solve --log, segment) if the bag is that large"
        raise InputError(
            f"its chunks inflate to {what} in all: {where()} would pass it",
            file=self.path,
            hint=hint + "; a few megabytes that inflate to gigabytes are a decompression bomb",
        )

    def locate(self, data: bytes, how: str) -> int | None:
        """Where the MCAP chunk whose compressed bytes (by ``how``) are ``data`` starts in its
        file (the first that holds them), or None: a chunk record is its opcode (6) and length,
        three times and a crc (28 bytes), the compression's name, the data's length, the data."""
        if self.path is None or not data:
            return None
        key = struct.pack("<I", len(how)) + how.encode() + struct.pack("<Q", len(data)) + data[:256]
        for part in _files(self.path):
            with (
                contextlib.suppress(ValueError, OSError),
                open(part, "rb") as f,
                mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as mapped,
            ):
                found = mapped.find(key)
                while found >= 0:
                    if found >= 37 and mapped[found - 37] == 6:
                        return found - 37
                    found = mapped.find(key, found + 1)
        return None


_PASS: ContextVar[_Pass | None] = ContextVar("tumblecal_ros_pass", default=None)


@contextlib.contextmanager
def _passing(path: str) -> Iterator[None]:
    """A pass over the bag ``path``'s files: what it inflates is bounded afresh."""
    token = _PASS.set(_Pass(path))
    try:
        yield
    finally:
        _PASS.reset(token)


def _size(size: int) -> str:
    """A size as --max-spool takes it: 4G, 1.5G, 500M, 812 bytes."""
    for unit, scale in (("T", 1 << 40), ("G", 1 << 30), ("M", 1 << 20), ("K", 1 << 10)):
        if size >= scale:
            return f"{size / scale:.3g}{unit}" if size / scale < 100 else f"{size / scale:.0f}{unit}"
    return f"{size} bytes"


class _Stream(Protocol):
    """A streamed decompressor (bz2's, lz4.frame's, zstd's): output up to a length at a time."""

    @property
    def eof(self) -> bool: ...

    @property
    def needs_input(self) -> bool: ...

    @property
    def unused_data(self) -> bytes: ...

    def decompress(self, data: bytes, max_length: int = -1, /) -> bytes: ...


#: A streamed decompressor of each compression a chunk may have (bz2, lz4: ROS 1; lz4, zstd: MCAP).
_STREAMS: dict[str, Callable[[], _Stream]] = {
    "bz2": bz2.BZ2Decompressor,
    "lz4": lz4.frame.LZ4FrameDecompressor,
    "zstd": zstd.ZstdDecompressor,
}


def inflate(data: bytes, how: str, size: int | None, at: int | None, field: str) -> bytes:
    """A chunk's ``data`` inflated (``how``: none, bz2, lz4, zstd), streamed up to its declared
    ``size`` (its ``field``: None when the chunk has none) and never past it: a size over
    CHUNK_BYTES, or past what the pass may still inflate, is refused before any is; output past
    the size, or short of it, is a _Damaged naming the chunk (``at``: its byte, None: found by
    its bytes) and the field. Streams one after another (bz2's, zstd's frames) are read as one."""
    passing = _PASS.get() or _Pass(None)

    def where() -> str:
        found = at if at is not None else passing.locate(data, how)
        return "a chunk" if found is None else f"the chunk at byte {found}"

    if size is None:
        raise _Damaged(f"it has no '{field}' (its uncompressed size)", where())
    if size > CHUNK_BYTES:
        raise _Damaged(
            f"its '{field}' is {size:,} bytes: more than a chunk holds (at most {_size(CHUNK_BYTES)})", where()
        )
    if how in ("none", ""):
        if len(data) != size:
            raise _Damaged(f"it holds {len(data):,} bytes, not its '{field}' ({size:,})", where())
        return bytes(data)
    if how not in _STREAMS:
        raise _Damaged(f"it is compressed by {how!r}: not a compression of bags (bz2, lz4, zstd)", where())
    passing.charge(size, where)
    pieces, got, rest = [], 0, data
    stream = _STREAMS[how]()
    while True:
        try:
            piece = stream.decompress(rest, min(size - got + 1, STEP))
        except Exception as err:  # bz2's OSError, lz4's RuntimeError, zstd's ZstdError: damaged data
            raise _Damaged(str(err) or type(err).__name__, where()) from None  # (as the walk's note said it)
        rest, got = b"", got + len(piece)
        pieces.append(piece)
        if got > size:
            raise _Damaged(f"it inflates to more than its '{field}' ({size:,} bytes)", where())
        if stream.eof:
            rest = stream.unused_data
            if not rest:
                break
            stream = _STREAMS[how]()
        elif stream.needs_input:
            raise _Damaged(f"its {how} data ends before its stream does (cut short)", where())
    if got != size:
        raise _Damaged(f"it inflates to {got:,} bytes, not its '{field}' ({size:,})", where())
    return b"".join(pieces)


def _mcap_inflate(how: str) -> Callable[[bytes, int], bytes]:
    """rosbags' MCAP decompressor of ``how`` (data, uncompressed_size), as ``inflate``."""
    return lambda data, size: inflate(data, how, size, None, "uncompressed_size")


DECOMPRESSORS.update({"lz4": _mcap_inflate("lz4"), "zstd": _mcap_inflate("zstd")})  # every MCAP read's


def _bound(reader: Reader1, path: str) -> None:
    """An opened rosbags ROS 1 reader's chunks inflated by ``inflate``, each up to its own
    header's 'size' (rosbags reads the header but not the size, and inflates whatever the data
    gives): each Chunk's decompressor replaced."""
    with open(path, "rb") as f:
        for pos, chunk in reader.chunks.items():
            f.seek(pos)
            (length,) = struct.unpack("<I", f.read(4))  # (rosbags has read this header: it is whole)
            fields = dict(_fields(f.read(length), 0, length))
            how = fields.get("compression", b"none").decode("ascii", "replace")
            size = struct.unpack("<I", fields["size"])[0] if len(fields.get("size", b"")) == 4 else None
            reader.chunks[pos] = chunk._replace(
                decompressor=functools.partial(inflate, how=how, size=size, at=pos, field="size")
            )


class _Charged(io.RawIOBase):
    """A stream whose reads are charged to the pass (``_Pass.charge``): a ROS 2 bag's file
    compressed whole, which rosbags inflates into $TMPDIR."""

    def __init__(self, source: zstd.ZstdFile, name: str) -> None:
        self.source, self.name = source, name
        self.passing = _PASS.get() or _Pass(None)

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: WriteableBuffer, /) -> int:
        view = memoryview(buffer).cast("B")
        data = self.source.read(len(view))
        self.passing.charge(len(data), lambda: f"its file {self.name}")
        view[: len(data)] = data
        return len(data)

    def close(self) -> None:
        self.source.close()
        super().close()


class _FileZstd:
    """rosbags' zstd as a ROS 2 bag folder compressed by file uses it (``zstd.open(file, 'rb')``,
    copied into $TMPDIR): what it inflates charged to the pass."""

    def open(self, file: io.BufferedReader, mode: str) -> io.BufferedReader:
        assert mode == "rb"
        return io.BufferedReader(_Charged(zstd.open(file, "rb"), os.path.basename(file.name)))


rosbag2_reader.zstd = _FileZstd()  # type: ignore[attr-defined,assignment]  # every ROS 2 folder read


class _WithinFile(io.BufferedReader):
    """A bag's file as rosbags reads it: a read of more than the file holds from where it is
    reads what it holds (a length field of 4 GiB asks Python's read for a buffer of 4 GiB)."""

    def read(self, size: int | None = -1, /) -> bytes:
        if size is not None and size > STEP:
            size = max(0, min(size, os.fstat(self.fileno()).st_size - self.tell()))
        return super().read(size)


if sys.platform == "win32":
    _Path = pathlib.WindowsPath
else:
    _Path = pathlib.PosixPath


class _Within(_Path):
    """A bag's path as rosbags is given it: its files (``/`` gives one of the same kind) opened
    for reading as _WithinFile."""

    def open(self, *args: object, **kwargs: object) -> BinaryIO:  # type: ignore[override]
        if args == ("rb",) and not kwargs:
            return _WithinFile(io.FileIO(self, "rb"))
        return super().open(*args, **kwargs)  # type: ignore[call-overload,no-any-return]


class _Mapped:
    """A recording read record by record from the file mapped (not read whole): its path, the
    connections found, why the walk stopped early (``stop``, for the note), and the map."""

    def __init__(self, path: str) -> None:
        self.path = path
        self.connections: list[Connection] = []
        self.stop = ""
        self._map: mmap.mmap | None = None

    def _open_map(self) -> None:
        with open(self.path, "rb") as f:
            self._map = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)

    def close(self) -> None:
        if self._map is not None:
            self._map.close()
            self._map = None


class Unindexed(_Mapped):
    """A ROS 1 bag without its index (a recording cut short: rosbag writes the index last), read
    as rosbag reindex reads it: its records one after another (the file mapped, not read whole),
    each chunk inflated (``inflate``), the connections taken as they come; the walk stops where
    the file is cut, or at a chunk that does not inflate or a record whose fields lie (``stop``:
    why, for the note)."""

    def open(self) -> None:
        self._open_map()
        counts: dict[int, int] = {}
        found: dict[int, Connection] = {}
        for fields, data in self._walk():
            op = fields["op"][0]
            if op == 7:  # a connection
                conn = struct.unpack("<I", fields["conn"])[0]
                found.setdefault(conn, self._connection(conn, fields, data))
            elif op == 2:  # a message
                conn = struct.unpack("<I", fields["conn"])[0]
                counts[conn] = counts.get(conn, 0) + 1
        self.connections = [c._replace(msgcount=counts.get(k, 0)) for k, c in sorted(found.items())]

    def messages(self, connections: Collection[Connection], /) -> Iterator[tuple[Connection, int, bytes]]:
        wanted = {c.id: c for c in connections}
        for fields, data in self._walk():
            if fields["op"][0] == 2 and (c := wanted.get(struct.unpack("<I", fields["conn"])[0])):
                sec, nsec = struct.unpack("<II", fields["time"])
                yield c, sec * 1_000_000_000 + nsec, data

    def _connection(self, conn: int, fields: dict[str, bytes], data: bytes) -> Connection:
        header = dict(_fields(data, 0, len(data)))
        kind = header.get("type", b"").decode("utf-8", "replace")
        package, _, name = kind.partition("/")
        msgtype = f"{package}/msg/{name}" if "/msg/" not in kind and name else kind
        text = header.get("message_definition", b"").decode("utf-8", "replace")
        return Connection(
            conn,
            fields.get("topic", b"").decode("utf-8", "replace"),
            msgtype,
            MessageDefinition(MessageDefinitionFormat.MSG, text),
            header.get("md5sum", b"").decode("ascii", "replace"),
            0,
            ConnectionExtRosbag1(None, None),
            self,
        )

    def _walk(self) -> Iterator[tuple[dict[str, bytes], bytes]]:
        """The bag's records and those of its chunks (inflated), as (header fields, data), each
        with the fields open and messages read (``_lacking``)."""
        assert self._map is not None
        top, self.stop = self._map, ""
        for fields, data, at in _records(top, top.find(b"\n") + 1, len(top)):
            if fields is None:
                self.stop = f"up to byte {at}, where it is cut short"
                return
            if why := _lacking(fields):
                self.stop = f"up to the record at byte {at}, which cannot be read ({why})"
                return
            if fields["op"][0] != 5:
                yield fields, data
                continue
            try:
                yield from self._chunk(fields, data, at)
            except _Damaged as err:  # a chunk that does not inflate as it says, or a record of it that lies
                self.stop = f"up to the chunk at byte {at}, which cannot be read ({err.why})"
                return

    def _chunk(self, fields: dict[str, bytes], data: bytes, at: int) -> Iterator[tuple[dict[str, bytes], bytes]]:
        """The records of the chunk at byte ``at`` (``fields``: its header; ``data``: compressed)."""
        how = fields.get("compression", b"none").decode("ascii", "replace")
        size = struct.unpack("<I", fields["size"])[0] if len(fields.get("size", b"")) == 4 else None
        chunk = inflate(data, how, size, at, "size")
        for inner, body, where in _records(chunk, 0, len(chunk)):
            if inner is None:
                raise _Damaged(f"its record at byte {where} of {len(chunk):,} runs past its end")
            if why := _lacking(inner):
                raise _Damaged(f"its record at byte {where}: {why}")
            yield inner, body


#: The fields a walk reads of a ROS 1 record of each op, and their sizes.
_NEEDS = {2: (("conn", 4), ("time", 8)), 7: (("conn", 4),)}


def _lacking(fields: dict[str, bytes]) -> str:
    """What a ROS 1 record's header lacks of the fields a walk reads ('op'; a message's 'conn'
    and 'time', a connection's 'conn'), or ''."""
    op = fields.get("op")
    if op is None or len(op) != 1:
        return "its header has no 'op' field" if op is None else f"its 'op' field is {len(op)} bytes, not 1"
    for name, size in _NEEDS.get(op[0], ()):
        value = fields.get(name)
        if value is None:
            return f"its header has no '{name}' field"
        if len(value) != size:
            return f"its '{name}' field is {len(value)} bytes, not {size}"
    return ""


class Unfinished(_Mapped):
    """An MCAP file without its summary and footer (a ROS 2 recording cut short: they are written
    last), read as mcap recover reads it: its records one after another (the file mapped), each
    chunk inflated (``inflate``), schemas and channels taken as they come, up to where the file is
    cut, a chunk cannot be read or a record's lengths lie (``stop``: why, for the note). Channels
    of CDR messages only."""

    def open(self) -> None:
        self._open_map()
        schemas: dict[int, str] = {}
        found: dict[int, Connection] = {}
        counts: dict[int, int] = {}
        for op, body in self._walk():
            if op == 3:  # a schema: id, name
                schemas[struct.unpack_from("<H", body)[0]] = _string(body, 2)[0]
            elif op == 4:  # a channel: id, schema id, topic, message encoding
                key, schema = struct.unpack_from("<HH", body)
                topic, at = _string(body, 4)
                encoding = _string(body, at)[0]
                if encoding == "cdr" and key not in found:
                    found[key] = Connection(
                        key,
                        topic,
                        schemas.get(schema, ""),
                        MessageDefinition(MessageDefinitionFormat.NONE, ""),
                        "",
                        0,
                        ConnectionExtRosbag2("cdr", []),
                        self,
                    )
            elif op == 5:
                key = struct.unpack_from("<H", body)[0]
                counts[key] = counts.get(key, 0) + 1
        self.connections = [c._replace(msgcount=counts.get(k, 0)) for k, c in sorted(found.items())]

    def messages(self, connections: Collection[Connection], /) -> Iterator[tuple[Connection, int, bytes]]:
        wanted = {c.id: c for c in connections}
        for op, body in self._walk():
            if op == 5 and (c := wanted.get(struct.unpack_from("<H", body)[0])):
                yield c, struct.unpack_from("<Q", body, 6)[0], body[22:]

    def _walk(self) -> Iterator[tuple[int, bytes]]:
        """The file's records and those of its chunks (inflated), as (opcode, content), each with
        the lengths open and messages read within it (``_overrun``)."""
        assert self._map is not None
        top, self.stop = self._map, ""
        for op, body, at in _mcap_records(top, len(MCAP_MAGIC), len(top)):
            if op is None:
                self.stop = f"up to byte {at}, where it is cut short"
                return
            if op in (2, 15):  # the footer, the end of the data: the file is whole after all
                return
            if why := _overrun(op, body):
                self.stop = f"up to the record at byte {at}, which cannot be read ({why})"
                return
            if op != 6:
                yield op, body
                continue
            try:
                yield from self._chunk(body, at)
            except _Damaged as err:  # a chunk that does not inflate as it says, or a record of it that lies
                self.stop = f"up to the chunk at byte {at}, which cannot be read ({err.why})"
                return

    def _chunk(self, body: bytes, at: int) -> Iterator[tuple[int, bytes]]:
        """The records of the chunk at byte ``at`` (``body``: its content, its lengths checked)."""
        size = struct.unpack_from("<Q", body, 16)[0]
        how, after = _string(body, 28)
        length = struct.unpack_from("<Q", body, after)[0]
        chunk = inflate(body[after + 8 : after + 8 + length], how, size, at, "uncompressed_size")
        for inner, content, where in _mcap_records(chunk, 0, len(chunk)):
            if inner is None:
                raise _Damaged(f"its record at byte {where} of {len(chunk):,} runs past its end")
            if inner in (0, 6) or (why := _overrun(inner, content)):
                why = {0: "opcode 0, which no MCAP record has", 6: "a chunk in a chunk"}.get(inner, why)
                raise _Damaged(f"its record at byte {where}: {why}")
            yield inner, content


def _overrun(op: int, body: bytes) -> str:
    """What runs past the end of an MCAP record of the fields a walk reads of it (a schema's
    name, a channel's topic and encoding, a message's 22 bytes of header, a chunk's compression
    and records), or ''."""
    if op == 3:
        return _strings(body, 2, ("name",))
    if op == 4:
        return _strings(body, 4, ("topic", "message_encoding"))
    if op == 5 and len(body) < 22:
        return f"a message of {len(body)} bytes, less than its header's 22"
    if op == 6:
        if why := _strings(body, 28, ("compression",)):
            return why
        after = 28 + 4 + struct.unpack_from("<I", body, 28)[0]
        if after + 8 > len(body):
            return "its 'records' length runs past its end"
        (length,) = struct.unpack_from("<Q", body, after)
        if after + 8 + length > len(body):
            return f"its 'records' are {length:,} bytes long, past its end ({len(body) - after - 8:,} bytes on)"
    return ""


def _strings(body: bytes, at: int, names: tuple[str, ...]) -> str:
    """What runs past the end of ``body`` of the MCAP strings ``names`` from ``at`` (each a
    length, then its bytes), or ''."""
    for name in names:
        if at + 4 > len(body):
            return f"its '{name}' length runs past its end ({len(body)} bytes)"
        (size,) = struct.unpack_from("<I", body, at)
        if at + 4 + size > len(body):
            return f"its '{name}' is {size:,} bytes long: past its end ({len(body) - at - 4:,} bytes on)"
        at += 4 + size
    return ""


def _string(body: bytes, at: int) -> tuple[str, int]:
    """An MCAP string (a length, then UTF-8) at ``at``, and where it ends (its length checked by
    ``_overrun``)."""
    (size,) = struct.unpack_from("<I", body, at)
    return body[at + 4 : at + 4 + size].decode("utf-8", "replace"), at + 4 + size


def _mcap_records(buf: bytes | mmap.mmap, at: int, end: int) -> Iterator[tuple[int | None, bytes, int]]:
    """The MCAP records of ``buf`` from ``at`` (an opcode, a length, the content), each as
    (opcode, content, its byte); one cut short ends them as (None, b"", its byte)."""
    while at < end:
        size = struct.unpack_from("<Q", buf, at + 1)[0] if at + 9 <= end else end
        if at + 9 + size > end:
            yield None, b"", at
            return
        yield buf[at], buf[at + 9 : at + 9 + size], at
        at += 9 + size


def _fields(buf: bytes | mmap.mmap, at: int, end: int) -> Iterator[tuple[str, bytes]]:
    """A ROS 1 record header's fields (each a length, then name=value)."""
    while at + 4 <= end:
        (size,) = struct.unpack_from("<I", buf, at)
        name, _, value = buf[at + 4 : min(at + 4 + size, end)].partition(b"=")
        yield name.decode("ascii", "replace"), value
        at += 4 + size


def _records(buf: bytes | mmap.mmap, at: int, end: int) -> Iterator[tuple[dict[str, bytes] | None, bytes, int]]:
    """The ROS 1 records of ``buf`` from ``at`` (a header length and header, a data length and
    data), each as (header fields, data, its byte); one cut short ends them as (None, b"", its byte)."""
    while at < end:
        body = at + 4 + (struct.unpack_from("<I", buf, at)[0] if at + 4 <= end else end)
        size = struct.unpack_from("<I", buf, body)[0] if body + 4 <= end else end
        if body + 4 + size > end:
            yield None, b"", at
            return
        yield dict(_fields(buf, at + 4, body)), buf[body + 4 : body + 4 + size], at
        at = body + 4 + size


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
        with _passing(path):  # (an MCAP file without a summary is inflated to be opened)
            readers = [_opened(path, kind, reader, notes, stack) for reader in _sources(path, kind, notes)]
        found = found or _summary(kind, readers, notes)
        names = {n for n in choose(found) if not found.topic(n).decoded}
        for reader in readers:
            wanted = [c for c in reader.connections if c.topic in names and c.msgtype in TYPES]
            if wanted:
                with _passing(path):
                    _gather(path, kind, reader.messages(wanted), [found.topic(n) for n in sorted(names)], notes)
        for name in names:
            found.topic(name).decoded = True
    return found


def _opened(path: str, kind: str, reader: _Source, notes: list[str], stack: contextlib.ExitStack) -> _Source:
    """``reader`` opened (and closed by ``stack``), a ROS 1 bag's chunks bounded (``_bound``); a
    ROS 1 bag without its index (a recording cut short) walked instead, with a note. What cannot
    be opened: exit 2; what inflates past the pass's bound (an InputError) as it is."""
    try:
        reader.open()
        stack.callback(reader.close)
        if isinstance(reader, Reader1):
            _bound(reader, path)
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


def _files(path: str) -> list[Path]:
    """A bag's files, in order (what its sha256 is of)."""
    if not os.path.isdir(path):
        return [Path(path)]
    return sorted(p for p in Path(path).iterdir() if p.is_file() and p.suffix in (".yaml", ".db3", ".mcap"))


def _sources(path: str, kind: str, notes: list[str]) -> list[_Source]:
    """The rosbags readers of a bag: a ROS 1 bag's, a ROS 2 bag folder's (its storage files read
    directly when it has no metadata.yaml), an MCAP or sqlite3 file's (chosen by its bytes, not
    its name)."""
    plugins = Reader2.STORAGE_PLUGINS
    if kind == "ROS 1 bag":
        return [Reader1(_Within(path))]
    if kind == "MCAP file":
        return [plugins[".mcap"](_Within(path))]
    if not os.path.isdir(path):
        return [plugins[".db3"](_Within(path))]
    if os.path.exists(os.path.join(path, "metadata.yaml")):
        return [plugins["dir"](_Within(path))]
    stored = [p for p in _files(path) if p.suffix in (".db3", ".mcap")]
    if not stored:
        raise InputError("a folder with neither metadata.yaml nor .db3 or .mcap files: not a ROS 2 bag", file=path)
    notes.append(
        f"{path}: no metadata.yaml (a recording cut short?): read its {', '.join(p.name for p in stored)} directly, "
        "as ros2 bag reindex would"
    )
    return [plugins[p.suffix](_Within(p)) for p in stored]


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
    found.sha256 = found.sha256 or _sha256(_files(path))
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
