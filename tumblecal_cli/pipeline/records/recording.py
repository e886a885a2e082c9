"""A calibration recorded in the same run that writes its file (``--record DB``): both or neither.

The order (``recorded``): the record is inserted inside a write transaction; the file is then
published atomically (io.outputs); then the transaction commits. A record that cannot be
inserted leaves no file (the file is not written yet); a file that cannot be written rolls the
record back; a commit that fails puts the output back as it was (the file it replaced, kept by a
hard link until the commit, or no file). A kill at any point leaves the database whole (SQLite's
journal) and holds the record only once its commit is done. An output that is not a file
(stdout, a device) cannot be taken back, so there the record commits before it is written.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager as ContextManager
from datetime import UTC, datetime

from tumblecal_cli.errors import InputError
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.pipeline.records import columns
from tumblecal_cli.pipeline.records.store import Store, open_store, shown

#: The environment variable that gives ``--record`` its default (a station script's database).
RECORD_ENV = "TUMBLECAL_RECORD"


def now() -> str:
    """The time a record is written, UTC to the microsecond."""
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _is_file(output: str) -> bool:
    return output != "-" and (not os.path.exists(output) or os.path.isfile(output))


def _keep(output: str) -> str | None:
    """A hard link to the file ``output`` replaces, named as io.outputs names its temporary
    files (a killed run's is swept by the next), or None when there is none to keep."""
    if not os.path.isfile(output):
        return None
    target = os.path.realpath(output)
    folder, name = os.path.split(target)
    kept = os.path.join(folder, f".{name[:100]}.{os.getpid()}-{secrets.token_hex(4)}.tmp")
    try:
        os.link(target, kept)
    except OSError:  # no hard links here: a commit that fails then leaves the new file in its place
        return None
    return kept


def _undo(output: str, kept: str | None, existed: bool) -> None:
    """The output as it was before the block: the file kept put back, or the new one removed
    (never a file that was there and could not be kept: the new one stays in its place)."""
    target = os.path.realpath(output)
    with contextlib.suppress(OSError):
        if kept is not None:
            os.replace(kept, target)
        elif not existed:
            os.unlink(target)


@contextlib.contextmanager
def recorded(db: str, cal: calfile.Calibration, output: str, origin: columns.Origin) -> Iterator[None]:
    """The block publishes ``output``; ``cal`` is recorded in ``db`` with it, both or neither."""
    row = columns.row_of(cal, origin, now())
    store = open_store(db, write=True)
    try:
        store.begin()
        store.insert(row, columns.tool())
        if not _is_file(output):
            store.commit()
            yield
            return
        existed, kept = os.path.lexists(output), _keep(output)
        try:
            yield
        except BaseException:
            store.rollback()
            if kept is not None:
                with contextlib.suppress(OSError):
                    os.unlink(kept)
            raise
        _commit(store, output, kept, existed)
    except BaseException:
        store.rollback()
        raise
    finally:
        store.close()


def _commit(store: Store, output: str, kept: str | None, existed: bool) -> None:
    try:
        store.commit()
    except InputError:
        _undo(output, kept, existed)
        raise
    if kept is not None:
        with contextlib.suppress(OSError):
            os.unlink(kept)


@contextlib.contextmanager
def publishing(db: str, cal: calfile.Calibration, origin: columns.Origin) -> Iterator[list[str]]:
    """``cal`` recorded around a block that publishes new files (never replacing one: batch's),
    adding each to the list it is given: both or neither (a failed commit removes them)."""
    row = columns.row_of(cal, origin, now())
    store = open_store(db, write=True)
    published: list[str] = []
    try:
        store.begin()
        store.insert(row, columns.tool())
        yield published
        try:
            store.commit()
        except InputError:
            for path in published:
                with contextlib.suppress(OSError):
                    os.unlink(path)
            raise
    except BaseException:
        store.rollback()
        raise
    finally:
        store.close()


def keeper(db: str, lot: str | None, command: str = "batch") -> Callable[[str, int], ContextManager[list[str]]]:
    """batch's ``keep`` (pipeline.batch.units.Keeper): each staged calibration recorded as it is
    published."""

    def keep(staging: str, status: int) -> ContextManager[list[str]]:
        return publishing(db, calfile.load(staging), columns.Origin(lot=lot, command=command, status=status))

    return keep


def check(db: str) -> None:
    """Refuse, before any work, a database that cannot be recorded into: an existing one opened
    for writing (ours, its schema, writable), a new one's folder there. Nothing is made."""
    if os.path.exists(db) or "://" in db:
        open_store(db, write=True).close()
        return
    folder = os.path.dirname(os.path.abspath(db))
    if not os.path.isdir(folder) or not os.access(folder, os.W_OK):
        raise InputError("cannot record: the database's folder does not exist or is not writable", file=shown(db))


def record(db: str, cal: calfile.Calibration, origin: columns.Origin) -> bool:
    """``cal`` recorded on its own (no file with it): whether it was new."""
    row = columns.row_of(cal, origin, now())
    store = open_store(db, write=True)
    try:
        store.begin()
        added = store.insert(row, columns.tool())
        store.commit()
    except BaseException:
        store.rollback()
        raise
    finally:
        store.close()
    return added
