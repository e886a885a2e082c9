"""What every log reader shares (io.sources' ``Reader`` contract, one base for all): the index of
the log it walked, kept while the file is the same one (a command lists a log's streams, then
reads one: one walk for both); the refusal of a label column (a log's still blocks are found by
the detector); and the note that says which stream was read.

A reader of a new kind of log subclasses :class:`LogReader` with its format's row
(io.logs.LogFormat: its kind and claim), how a log of it is called in a sentence, what its
corrected streams are said to be, and three methods: ``walk`` (the log into its index),
``streams`` and ``table`` (the readings of the stream a spec picks).
"""

from __future__ import annotations

import os
from abc import abstractmethod
from typing import ClassVar, Generic, TypeVar

from tumblecal_cli.errors import InputError
from tumblecal_cli.io.logs import LogFormat
from tumblecal_cli.io.readspec import ReadSpec
from tumblecal_cli.io.sources import Reader, Stream, Table

IndexT = TypeVar("IndexT")
#: What tells a file is the one walked: its real path, and its (or its folder's files') name,
#: size, time and inode.
Key = tuple[object, ...]


def file_key(path: str) -> Key:
    """What a log's index is kept by: the file's real path, size, time and inode (a folder's:
    each of its files' name, size, time and inode), so a log rewritten or grown is walked again."""
    names = sorted(os.listdir(path)) if os.path.isdir(path) else [""]
    stats = [os.stat(os.path.join(path, n)) if n else os.stat(path) for n in names]
    return (
        os.path.realpath(path),
        *((n, s.st_size, s.st_mtime_ns, s.st_ino) for n, s in zip(names, stats, strict=True)),
    )


class LogReader(Reader, Generic[IndexT]):
    """A reader of one kind of log: its ``row`` in io.logs.FORMATS (its kind and claim), how the
    messages call one such log (``called``: "a PX4 ULog"), how the read note says a stream the
    source had corrected (``corrected_as``: "corrected by PX4"), and the index of the log last
    walked, kept while the file is unchanged (``index``)."""

    row: ClassVar[LogFormat]
    called: ClassVar[str]
    corrected_as: ClassVar[str]

    def __init__(self) -> None:
        self._kept: tuple[Key, IndexT] | None = None

    @property
    def kind(self) -> str:
        return self.row.kind

    def claims(self, path: str, head: bytes) -> bool:
        return self.row.claims(path, head)

    @abstractmethod
    def walk(self, path: str) -> IndexT:
        """The log ``path`` walked once into its index (what its streams and readings are read from)."""

    @abstractmethod
    def table(self, path: str, spec: ReadSpec) -> Table:
        """The readings of the stream of ``path`` that ``spec`` picks."""

    def index(self, path: str) -> IndexT:
        """``path`` walked once (kept while the file's size, time and inode are the same)."""
        key = file_key(path)
        found = self.kept(key)
        if found is None:
            found = self.walk(path)
            self.keep(key, found)
        return found

    def kept(self, key: Key) -> IndexT | None:
        """The index kept for the file ``key`` tells, if it is the one kept."""
        return self._kept[1] if self._kept is not None and self._kept[0] == key else None

    def keep(self, key: Key, found: IndexT) -> None:
        """``found`` kept as the index of the file ``key`` tells (the one log kept)."""
        self._kept = (key, found)

    def forget(self) -> None:
        """The index kept let go (the next read walks the log again)."""
        self._kept = None

    def read(self, path: str, spec: ReadSpec, label_column: str | None) -> Table:
        if label_column is not None and not self.labels:
            raise InputError(
                f"{self.called} has no label column ({label_column!r}): its still blocks are found by the detector",
                file=path,
                hint="leave --pose-column out",
            )
        return self.table(path, spec)

    def read_note(self, path: str, chosen: Stream, rows: int, more: str = "") -> str:
        """The first note of a read: which stream, its sensor, samples, units, and whether the
        source had corrected it (``more``: what the format adds inside the brackets)."""
        how = self.corrected_as if chosen.corrected else "raw"
        return f"{path}: read {chosen.key} ({chosen.sensor}, {rows} samples, {chosen.units}, {how}{more})"
