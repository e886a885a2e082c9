"""A ROS bag's and an MCAP file's bytes, read without trusting them (io.logs.ros reads its topics
through here): every chunk inflated streamed, up to its declared size (``inflate``: at most
``CHUNK_BYTES``), and one pass over a file up to ``--max-spool`` in all (``io.logs.inflating_at_most``); rosbags'
readers bound alike (``bound_chunks``, ``FileZstd``, ``Within``); and the walks of a recording cut
short, without its index (``Unindexed``, a ROS 1 bag) or its summary (``Unfinished``, MCAP), which
check every field they read and stop at one that lies. See io.logs.ros's docstring."""

from __future__ import annotations

import bz2
import contextlib
import functools
import io
import mmap
import os
import pathlib
import struct
import sys
from collections.abc import Callable, Collection, Iterator
from contextvars import ContextVar
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO, Protocol

import lz4.frame  # type: ignore[import-untyped]  # rosbags' own dependency (ROS 1 bags' lz4 chunks)
from rosbags.interfaces import (
    Connection,
    ConnectionExtRosbag1,
    ConnectionExtRosbag2,
    MessageDefinition,
    MessageDefinitionFormat,
)
from rosbags.rosbag1 import Reader as Reader1
from rosbags.rosbag2 import reader as rosbag2_reader
from rosbags.rosbag2.storage_mcap import DECOMPRESSORS

if sys.version_info >= (3, 14):
    from compression import zstd
else:  # rosbags' own dependency
    from backports import zstd

from tumblecal_cli.errors import InputError
from tumblecal_cli.io import logs
from tumblecal_cli.io.outputs import MAX_SPOOL

if TYPE_CHECKING:
    from _typeshed import WriteableBuffer

MCAP_MAGIC = b"\x89MCAP0\r\n"
#: The most one chunk may inflate to: a chunk holds whole messages (rosbag closes one past 768
#: KiB, an MCAP writer past 4 MiB or so), and roscpp refuses a message over a gigabyte. A chunk
#: that declares more is refused before it is inflated.
CHUNK_BYTES = 1 << 30
#: Bytes inflated at a time (a chunk's output is checked against its declared size as it grows).
STEP = 1 << 24


class Damaged(Exception):
    """A chunk or a record that cannot be read: ``why`` (naming the field that lies), after
    ``where`` it is (the chunk at byte N) in its text; exit 2 naming the file, or the note of a
    walk that stops there (which says where itself)."""

    def __init__(self, why: str, where: str = "") -> None:
        self.why = why
        super().__init__(f"{where}: {why}" if where else why)


class _Pass:
    """One pass over a bag's files (its opening, or the reading of its messages): what its chunks
    may still inflate to in all, and the files to find a chunk in by its bytes (rosbags' MCAP
    reader hands its decompressors a chunk's data, not where it is)."""

    def __init__(self, path: str | None) -> None:
        limit = logs.inflate_limit()
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
        for part in bag_files(self.path):
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
def passing(path: str) -> Iterator[None]:
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
    the size, or short of it, is a Damaged naming the chunk (``at``: its byte, None: found by
    its bytes) and the field. Streams one after another (bz2's, zstd's frames) are read as one."""
    passing = _PASS.get() or _Pass(None)

    def where() -> str:
        found = at if at is not None else passing.locate(data, how)
        return "a chunk" if found is None else f"the chunk at byte {found}"

    if size is None:
        raise Damaged(f"it has no '{field}' (its uncompressed size)", where())
    if size > CHUNK_BYTES:
        raise Damaged(
            f"its '{field}' is {size:,} bytes: more than a chunk holds (at most {_size(CHUNK_BYTES)})", where()
        )
    if how in ("none", ""):
        if len(data) != size:
            raise Damaged(f"it holds {len(data):,} bytes, not its '{field}' ({size:,})", where())
        return bytes(data)
    if how not in _STREAMS:
        raise Damaged(f"it is compressed by {how!r}: not a compression of bags (bz2, lz4, zstd)", where())
    passing.charge(size, where)
    pieces, got, rest = [], 0, data
    stream = _STREAMS[how]()
    while True:
        try:
            piece = stream.decompress(rest, min(size - got + 1, STEP))
        except Exception as err:  # bz2's OSError, lz4's RuntimeError, zstd's ZstdError: damaged data
            raise Damaged(str(err) or type(err).__name__, where()) from None  # (as the walk's note said it)
        rest, got = b"", got + len(piece)
        pieces.append(piece)
        if got > size:
            raise Damaged(f"it inflates to more than its '{field}' ({size:,} bytes)", where())
        if stream.eof:
            rest = stream.unused_data
            if not rest:
                break
            stream = _STREAMS[how]()
        elif stream.needs_input:
            raise Damaged(f"its {how} data ends before its stream does (cut short)", where())
    if got != size:
        raise Damaged(f"it inflates to {got:,} bytes, not its '{field}' ({size:,})", where())
    return b"".join(pieces)


def _mcap_inflate(how: str) -> Callable[[bytes, int], bytes]:
    """rosbags' MCAP decompressor of ``how`` (data, uncompressed_size), as ``inflate``."""
    return lambda data, size: inflate(data, how, size, None, "uncompressed_size")


DECOMPRESSORS.update({"lz4": _mcap_inflate("lz4"), "zstd": _mcap_inflate("zstd")})  # every MCAP read's


def bound_chunks(reader: Reader1, path: str) -> None:
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


class FileZstd:
    """rosbags' zstd as a ROS 2 bag folder compressed by file uses it (``zstd.open(file, 'rb')``,
    copied into $TMPDIR): what it inflates charged to the pass."""

    def open(self, file: io.BufferedReader, mode: str) -> io.BufferedReader:
        assert mode == "rb"
        return io.BufferedReader(_Charged(zstd.open(file, "rb"), os.path.basename(file.name)))


rosbag2_reader.zstd = FileZstd()  # type: ignore[attr-defined,assignment]  # every ROS 2 folder read


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


class Within(_Path):
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
            except Damaged as err:  # a chunk that does not inflate as it says, or a record of it that lies
                self.stop = f"up to the chunk at byte {at}, which cannot be read ({err.why})"
                return

    def _chunk(self, fields: dict[str, bytes], data: bytes, at: int) -> Iterator[tuple[dict[str, bytes], bytes]]:
        """The records of the chunk at byte ``at`` (``fields``: its header; ``data``: compressed)."""
        how = fields.get("compression", b"none").decode("ascii", "replace")
        size = struct.unpack("<I", fields["size"])[0] if len(fields.get("size", b"")) == 4 else None
        chunk = inflate(data, how, size, at, "size")
        for inner, body, where in _records(chunk, 0, len(chunk)):
            if inner is None:
                raise Damaged(f"its record at byte {where} of {len(chunk):,} runs past its end")
            if why := _lacking(inner):
                raise Damaged(f"its record at byte {where}: {why}")
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
            except Damaged as err:  # a chunk that does not inflate as it says, or a record of it that lies
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
                raise Damaged(f"its record at byte {where} of {len(chunk):,} runs past its end")
            if inner in (0, 6) or (why := _overrun(inner, content)):
                why = {0: "opcode 0, which no MCAP record has", 6: "a chunk in a chunk"}.get(inner, why)
                raise Damaged(f"its record at byte {where}: {why}")
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


def bag_files(path: str) -> list[Path]:
    """A bag's files, in order (what its sha256 is of)."""
    if not os.path.isdir(path):
        return [Path(path)]
    return sorted(p for p in Path(path).iterdir() if p.is_file() and p.suffix in (".yaml", ".db3", ".mcap"))
