"""The records database: its schema (versioned), opened safely, written in transactions.

A database is a SQLite file (the standard library's ``sqlite3``: WAL, so readers never wait for
a writer, and a busy timeout, so several stations on one host write at once). Every statement
takes its values as parameters, never spliced into the SQL.

**Ours, and which schema.** The table ``tumblecal_meta`` holds ``application`` =
``tumblecal-records`` and ``schema`` (the version, ``SCHEMA`` the newest this tool knows); SQLite's
``application_id`` says the same to ``file(1)``. A database with tables but no such row is not
ours, a newer schema is refused (never written to), an older one is brought up to date by
``tumblecal records migrate`` (``MIGRATIONS``: each version's statements, in order).
"""

from __future__ import annotations

import contextlib
import os
import re
import sqlite3
import urllib.parse
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass

from tumblecal_cli.errors import InputError

AXES = "xyz"
OFFSETS = tuple(f"offset_{k}" for k in AXES)
GAINS = tuple(f"gain_{k}" for k in AXES)
CROSS = tuple(f"cross_{i}{j}" for i in AXES for j in AXES if i != j)
#: Every charted parameter, in the order of trend's and history's rows.
PARAMETERS = (*OFFSETS, *GAINS, *CROSS, "residual")
#: The stated 1σ columns, and the parameter each belongs to.
SIGMAS = {f"{name}_sd": name for name in (*OFFSETS, *GAINS)}
#: The text columns people filter on, in the table's order.
TEXT = ("kind", "serial", "station", "operator", "lot", "created", "recorded", "sensor", "method", "verdict")
#: What a record is of: a calibration (solve, batch, thermal, import) or a re-test (verify).
KINDS = ("calibration", "verification")


@dataclass(frozen=True)
class RecordRow:
    """One record: its ``key`` (the content's sha256), the text columns (``TEXT``), ``status``
    (the command's exit status, 0 or 1), the numbers (``PARAMETERS``, ``SIGMAS``, reference and
    coverage), where it came from (``command``, ``source``: an imported file), the inputs'
    (name, sha256) and the whole ``document`` (the calibration file's JSON)."""

    key: str
    text: Mapping[str, str | None]
    status: int | None
    numbers: Mapping[str, float | None]
    command: str
    source: str | None
    inputs: tuple[tuple[str, str], ...]
    document: str


#: The newest schema this tool reads and writes.
SCHEMA = 1
APPLICATION = "tumblecal-records"
#: SQLite's application_id of a records database ("TCAL").
APPLICATION_ID = 0x5443414C
#: How long a writer waits for another's transaction to end before it gives up (ms).
BUSY_MS = 30_000

_NUMBERS = (*PARAMETERS, *SIGMAS, "reference", "coverage")
#: The records table's columns after ``id``, in order.
COLUMNS = ("key", *TEXT, "status", *_NUMBERS, "command", "source", "tool", "document")

_CREATE = [
    "CREATE TABLE tumblecal_meta (name TEXT PRIMARY KEY, value TEXT NOT NULL)",
    "CREATE TABLE records (id INTEGER PRIMARY KEY, key TEXT NOT NULL UNIQUE, "
    + ", ".join(f"{c} TEXT" for c in TEXT)
    + ", status INTEGER, "
    + ", ".join(f"{c} REAL" for c in _NUMBERS)
    + ", command TEXT NOT NULL, source TEXT, tool TEXT NOT NULL, document TEXT NOT NULL)",
    "CREATE TABLE inputs (record INTEGER NOT NULL REFERENCES records(id), name TEXT NOT NULL, sha256 TEXT NOT NULL)",
    "CREATE INDEX records_serial ON records (serial, created)",
    "CREATE INDEX records_station ON records (station, sensor, created)",
    "CREATE INDEX records_lot ON records (lot)",
    "CREATE INDEX inputs_record ON inputs (record)",
]
#: Each schema version's statements, applied in order from the database's version to SCHEMA.
MIGRATIONS: dict[int, list[str]] = {1: _CREATE}


def shown(target: str) -> str:
    """The database as a message names it: a URL's password masked."""
    parts = urllib.parse.urlsplit(target)
    if parts.scheme and parts.password is not None:
        host = parts.netloc.rpartition("@")[2]
        netloc = f"{parts.username or ''}:***@{host}"
        return urllib.parse.urlunsplit(parts._replace(netloc=netloc))
    return target


def _refused(target: str, what: str, hint: str | None = None) -> InputError:
    return InputError(what, file=shown(target), hint=hint)


def _failed(target: str, doing: str, err: sqlite3.Error) -> InputError:
    text = str(err) or type(err).__name__
    if "not a database" in text:
        return _refused(target, "not a records database: not a SQLite file")
    return _refused(target, f"cannot {doing}: {text}")


@dataclass
class Store:
    """An open records database (``open_store``)."""

    target: str
    connection: sqlite3.Connection
    schema: int

    def close(self) -> None:
        self.connection.close()

    def execute(self, sql: str, values: Sequence[object] = ()) -> sqlite3.Cursor:
        """One statement with its values as parameters; a database error names the database."""
        try:
            return self.connection.execute(sql, values)
        except sqlite3.Error as err:
            raise _failed(self.target, "read or write it", err) from None

    def begin(self) -> None:
        """A write transaction, the database's write lock taken now (waits BUSY_MS for it)."""
        self.execute("BEGIN IMMEDIATE")

    def commit(self) -> None:
        self.execute("COMMIT")

    def rollback(self) -> None:
        with contextlib.suppress(sqlite3.Error):
            self.connection.execute("ROLLBACK")

    def insert(self, row: RecordRow, tool: str) -> bool:
        """``row`` added unless a record of its key is there (the same content recorded again):
        whether it was added. Inside a transaction (``begin``)."""
        values = [
            row.key,
            *(row.text[c] for c in TEXT),
            row.status,
            *(row.numbers.get(c) for c in _NUMBERS),
            row.command,
            row.source,
            tool,
            row.document,
        ]
        marks = ", ".join("?" for _ in COLUMNS)
        cursor = self.execute(
            f"INSERT INTO records ({', '.join(COLUMNS)}) VALUES ({marks}) ON CONFLICT (key) DO NOTHING", values
        )
        if cursor.rowcount != 1:
            return False
        record = cursor.lastrowid
        for name, sha in row.inputs:
            self.execute("INSERT INTO inputs (record, name, sha256) VALUES (?, ?, ?)", (record, name, sha))
        return True


def _connect(target: str, write: bool) -> sqlite3.Connection:
    path = os.path.abspath(target)
    if not write and not os.path.exists(path):
        raise _refused(target, "no such records database", "record into it first (--record DB, or records import)")
    if os.path.isdir(path):
        raise _refused(target, "is a folder: a records database is a file")
    if write and not os.path.isdir(os.path.dirname(path)):
        raise _refused(target, "the database's folder does not exist")
    if write and os.path.exists(path) and not os.access(path, os.W_OK):
        raise _refused(target, "cannot record: the database is read-only")
    uri = f"file:{urllib.parse.quote(path)}?mode={'rwc' if write else 'ro'}"
    try:
        connection = sqlite3.connect(uri, uri=True, timeout=BUSY_MS / 1000, isolation_level=None)
        connection.execute(f"PRAGMA busy_timeout = {BUSY_MS}")
    except sqlite3.Error as err:
        raise _failed(target, "open it", err) from None
    return connection


def _tables(store: Store) -> list[str]:
    return [r[0] for r in store.execute("SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")]


def _schema(store: Store) -> int | None:
    """The database's schema version; None for an empty database; an error for one not ours."""
    tables = _tables(store)
    if not tables:
        return None
    if "tumblecal_meta" not in tables:
        listed = ", ".join(tables[:5]) + (" ..." if len(tables) > 5 else "")
        raise _refused(store.target, f"not a tumblecal records database (its tables: {listed})")
    meta = dict(store.execute("SELECT name, value FROM tumblecal_meta").fetchall())
    version = str(meta.get("schema", ""))
    if meta.get("application") != APPLICATION or not re.fullmatch(r"[0-9]{1,6}", version):
        raise _refused(store.target, "not a tumblecal records database (its tumblecal_meta names another)")
    return int(version)


def _create(store: Store, upto: int = SCHEMA) -> None:
    """The schema made, in one transaction with the check that nobody made it first."""
    store.execute("PRAGMA journal_mode = WAL").fetchall()  # (persistent; not inside a transaction)
    store.begin()
    try:
        have = _schema(store)
        if have is None:
            _migrate(store, 0, upto)
        store.commit()
    except BaseException:
        store.rollback()
        raise


def _migrate(store: Store, have: int, upto: int) -> None:
    for version in range(have + 1, upto + 1):
        for statement in MIGRATIONS[version]:
            store.execute(statement)
    if have == 0:
        store.execute("INSERT INTO tumblecal_meta (name, value) VALUES ('application', ?)", (APPLICATION,))
        store.execute("INSERT INTO tumblecal_meta (name, value) VALUES ('schema', ?)", (str(upto),))
        store.execute(f"PRAGMA application_id = {APPLICATION_ID}")
    else:
        store.execute("UPDATE tumblecal_meta SET value = ? WHERE name = 'schema'", (str(upto),))
    store.schema = upto


def _newer(store: Store, version: int) -> InputError:
    return _refused(
        store.target,
        f"written by a newer tumblecal (records schema {version}; this one knows schema {SCHEMA} at most): "
        "never written to",
        "use the tumblecal that wrote it, or a newer one",
    )


def open_store(target: str, *, write: bool) -> Store:
    """The records database ``target`` (a SQLite file), made with the schema when it is new or
    empty and ``write``. Refused (exit 2, one line naming it): not a SQLite file, not ours, a
    newer schema, an older one to write (``records migrate`` first), read-only to write."""
    if re.match(r"[a-z][a-z0-9+.-]*://", target, flags=re.IGNORECASE):
        raise _refused(target, "only SQLite files are records databases in this version (give a file name)")
    store = Store(target, _connect(target, write), 0)
    try:
        version = _schema(store)
        if version is None:
            if not write:
                raise _refused(target, "an empty database: no records in it")
            _create(store)
            version = SCHEMA
        if version > SCHEMA:
            raise _newer(store, version)
        if version < SCHEMA and write:
            raise _refused(
                target, f"records schema {version} is older than {SCHEMA}", f"tumblecal records migrate --db {target}"
            )
        store.schema = version
    except BaseException:
        store.close()
        raise
    return store


@contextlib.contextmanager
def connected(path: str | os.PathLike[str]) -> Iterator[sqlite3.Connection]:
    """A plain ``sqlite3`` connection to a records file (for a look with SQL: tests, scripts),
    committed at the end of the block and closed (``with sqlite3.connect(...)`` leaves it open)."""
    connection = sqlite3.connect(path)
    try:
        with connection:
            yield connection
    finally:
        connection.close()


@contextlib.contextmanager
def opened(target: str, *, write: bool) -> Iterator[Store]:
    """``open_store`` as a block that closes it."""
    store = open_store(target, write=write)
    try:
        yield store
    finally:
        store.close()


def migrate(target: str) -> tuple[int, int]:
    """The database brought to SCHEMA (made if new): its version before and after."""
    store = Store(target, _connect(target, True), 0)
    try:
        if _schema(store) is None:
            store.execute("PRAGMA journal_mode = WAL").fetchall()
        store.begin()
        try:
            have = _schema(store)
            if have is not None and have > SCHEMA:
                raise _newer(store, have)
            if (have or 0) < SCHEMA:
                _migrate(store, have or 0, SCHEMA)
            store.commit()
        except BaseException:
            store.rollback()
            raise
    finally:
        store.close()
    return have or 0, SCHEMA
