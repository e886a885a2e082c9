"""Compressed captures: gzip, bzip2, xz and Zstandard, read as they are, and written when an
output's name ends so (docs/reference/csv.md).

A capture is known compressed by its first bytes (its format's magic number), whatever its
name: ``capture.csv.gz`` holding plain text reads as text, a gzip named ``capture.csv`` as the
CSV inside it. gzip, bzip2 and xz are Python's own modules; Zstandard, which Python's standard
library lacks before 3.14, is pyarrow's codec (pyarrow has no xz: one mechanism cannot do all
four). Each is a binary stream to the readers, whose decompression errors are InputErrors
naming the file; an output's compressor is chosen by its name's suffix.
"""

from __future__ import annotations

import bz2
import contextlib
import gzip
import io
import lzma
import os
import re
import typing
import zlib
from collections.abc import Callable, Iterator
from typing import IO, TYPE_CHECKING

import pyarrow as pa

from tumblecal_cli.errors import InputError
from tumblecal_cli.io import sources

if TYPE_CHECKING:
    from _typeshed import ReadableBuffer, WriteableBuffer

#: Each format: what its files start with, and the suffix its files are named with.
MAGIC = {
    "gzip": re.compile(rb"\x1f\x8b"),
    "bzip2": re.compile(rb"BZh[1-9](?:\x31\x41\x59\x26\x53\x59|\x17\x72\x45\x38\x50\x90)"),  # a block, or none
    "xz": re.compile(rb"\xfd7zXZ\x00"),
    "zstd": re.compile(rb"\x28\xb5\x2f\xfd"),
}
SUFFIXES = {".gz": "gzip", ".bz2": "bzip2", ".xz": "xz", ".zst": "zstd"}
#: The command that decompresses each (in hints).
TOOLS = {"gzip": "gunzip", "bzip2": "bunzip2", "xz": "unxz", "zstd": "unzstd"}
#: The level gzip and xz write at (``gzip -1``, ``xz -1``): a corrected 1M-row capture (70 MB)
#: takes 1.6 s of gzip at level 1, 10 s at its default 6, for 9 % more bytes; xz's default is
#: 15 times slower still. bzip2 has about one speed, and zstd's default is fast.
FAST = 1
#: What a decompressor raises on data that is not its format, corrupt or cut short.
ERRORS = (EOFError, OSError, zlib.error, lzma.LZMAError, pa.ArrowInvalid)
#: Other archives and compressors, known by their first bytes: named in the error, not read.
OTHERS = {
    b"PK\x03\x04": ("a zip archive", "extract the CSV first (unzip FILE)"),
    b"7z\xbc\xaf\x27\x1c": ("a 7-Zip archive", "extract the CSV first (7z x FILE)"),
    b"\x04\x22\x4d\x18": ("LZ4-compressed", "decompress it first (unlz4 FILE)"),
    b"Rar!\x1a\x07": ("a RAR archive", "extract the CSV first (unrar x FILE)"),
}


def kind_of(head: bytes) -> str | None:
    """The compression of data that starts with ``head`` (its first 10 bytes are enough), or None."""
    return next((kind for kind, magic in MAGIC.items() if magic.match(head)), None)


def named(path: str) -> str | None:
    """The compression a file's name asks for (``.gz``, ``.bz2``, ``.xz``, ``.zst``), or None."""
    return SUFFIXES.get(os.path.splitext(path)[1].lower())


def binary_hint(name: str, head: bytes) -> str:
    """What to do about a file of binary data that is not a capture: the archive or compressor
    its first bytes name, or the name's suffix that its bytes belie."""
    for magic, (what, todo) in OTHERS.items():
        if head.startswith(magic):
            return f"it is {what}: {todo.replace('FILE', name)}"
    said = named(name)
    log = next((r.kind for r in sources.READERS if isinstance(r, sources.Lazy) and r.claims(name, head)), None)
    if log is not None and said is not None:  # what a compressed file holds: logs are read whole, uncompressed
        return f"it is a {said}-compressed {log}: decompress it first, and give the log itself"
    if log is not None:
        return f"it is a {log}: solve --log, segment, noise, thermal and verify read it; this command reads CSV"
    if said is not None:
        return f"it is named like {said} data but does not start like it: is the file whole?"
    return "is this a CSV capture? (gzip, bzip2, xz and zstd captures are read as they are)"


class _Decompressing(io.RawIOBase):
    """A decompressor's ``read`` as a raw stream: its errors InputErrors naming the file."""

    def __init__(self, read: Callable[[int], bytes], kind: str, name: str, closing: list[IO[bytes] | pa.NativeFile]):
        self._read = read
        self._kind = kind
        self._name = name
        self._closing = closing  # the decompressor and the file under it, closed with this

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: WriteableBuffer) -> int:
        view = memoryview(buffer).cast("B")
        try:
            data = self._read(len(view))
        except ERRORS as err:
            raise _corrupt(self._kind, self._name, err) from None
        view[: len(data)] = data
        return len(data)

    def close(self) -> None:
        for f in self._closing:
            with contextlib.suppress(*ERRORS):
                f.close()
        super().close()


def _corrupt(kind: str, name: str, err: BaseException) -> InputError:
    if isinstance(err, EOFError) or "runcated" in str(err):
        what = f"the {kind} data ends early (a file cut short?)"
    else:
        what = f"not valid {kind} data: {str(err) or type(err).__name__}"
    return InputError(what, file=name, hint=f"check the file with {TOOLS[kind]} -t (or copy it again)")


def reader(kind: str, raw: IO[bytes], name: str) -> IO[bytes]:
    """The data ``raw`` (a file at its start, or a stream) holds compressed by ``kind``, as a
    binary stream (closing it closes ``raw`` too); ``name`` is how errors name the file."""
    source: IO[bytes] | pa.NativeFile
    if kind == "gzip":
        source = gzip.GzipFile(fileobj=raw, mode="rb")
    elif kind == "bzip2":
        source = bz2.BZ2File(raw, "rb")
    elif kind == "xz":
        source = lzma.LZMAFile(raw, "rb")  # noqa: SIM115 (closed with what is returned)
    else:
        if not pa.Codec.is_available("zstd"):
            raise InputError(
                "zstd-compressed, and this pyarrow has no zstd codec",
                file=name,
                hint=f"decompress it first: unzstd {name}",
            )
        source = pa.CompressedInputStream(pa.PythonFile(raw, mode="r"), "zstd")
    return io.BufferedReader(_Decompressing(source.read, kind, name, [source, raw]), buffer_size=1 << 20)


def open_data(path: str, name: str | None = None) -> IO[bytes]:
    """A file's data: its bytes, decompressed when it is compressed (a second pass over a capture)."""
    f = open(path, "rb")  # noqa: SIM115 (returned open)
    kind = kind_of(f.read(16))
    f.seek(0)
    return f if kind is None else reader(kind, f, name or path)


def read_all(path: str) -> bytes:
    """A whole file's data (decompressed when it is compressed)."""
    with open_data(path) as f:
        return f.read()


class Replay(io.RawIOBase):
    """A stream's first bytes, already read (and hashed), then the rest of it, hashed as read:
    what a decompressor reads from stdin once its first block has been looked at."""

    def __init__(self, first: bytes, rest: IO[bytes], update: Callable[[bytes], None]) -> None:
        self._first = memoryview(first)
        self._rest = rest
        self._update = update

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: WriteableBuffer) -> int:
        view = memoryview(buffer).cast("B")
        if len(self._first):
            n = min(len(view), len(self._first))
            view[:n] = self._first[:n]
            self._first = self._first[n:]
            return n
        data = self._rest.read(len(view))
        self._update(data)
        view[: len(data)] = data
        return len(data)


class _Compressing(io.RawIOBase):
    """A compressor's ``write`` as a raw stream, with no file descriptor of its own (apply's
    worker processes write to an output's descriptor directly: never past the compressor)."""

    def __init__(self, write: Callable[[ReadableBuffer], object]) -> None:
        self._write = write

    def writable(self) -> bool:
        return True

    def write(self, data: ReadableBuffer) -> int:
        self._write(data)
        return memoryview(data).nbytes


class _Unclosed(io.RawIOBase):
    """``out`` for pyarrow's compressor, which closes what it writes to when it is closed."""

    def __init__(self, out: IO[bytes]) -> None:
        self._out = out

    def writable(self) -> bool:
        return True

    def write(self, data: ReadableBuffer) -> int:
        return self._out.write(data)


@contextlib.contextmanager
def writing(path: str, out: IO[bytes]) -> Iterator[IO[bytes]]:
    """``out`` (the output ``path`` is written through), compressed as ``path``'s suffix asks
    (``.gz``, ``.bz2``, ``.xz``, ``.zst``; gzip and xz at their fastest level, FAST); the
    compressed data is finished as the block ends without an error."""
    kind = named(path)
    if kind is None:
        yield out
        return
    sink: IO[bytes] | pa.NativeFile
    if kind == "gzip":  # the name inside is the output's (gunzip -N); no time, so that a run repeats byte for byte
        sink = gzip.GzipFile(filename=os.path.basename(path), mode="wb", fileobj=out, compresslevel=FAST, mtime=0)
    elif kind == "bzip2":
        sink = bz2.BZ2File(out, "wb")
    elif kind == "xz":
        sink = lzma.LZMAFile(out, "wb", preset=FAST)  # noqa: SIM115 (closed below)
    else:
        if not pa.Codec.is_available("zstd"):
            raise InputError("this pyarrow has no zstd codec to write it with", file=path, hint="name it .gz instead")
        sink = pa.CompressedOutputStream(pa.PythonFile(_Unclosed(out), mode="w"), "zstd")
    try:
        yield typing.cast("IO[bytes]", _Compressing(sink.write))
    except BaseException:
        with contextlib.suppress(Exception):  # the output is thrown away whole: only the error matters
            sink.close()
        raise
    sink.close()
