"""Records on a real PostgreSQL server that the tests start themselves: Debian's ``postgresql``
package (``make test`` installs it where it can), ``initdb`` into a temporary folder, listening
on a Unix socket only (no TCP), torn down at the end. Skipped, with the reason, where the server
or psycopg (``tumblecal[postgres]``) is not installed."""

from __future__ import annotations

import glob
import itertools
import json
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.conftest import POSES_3, ROOT, assert_one_error, run
from tests.test_records import WRITER, _template

pytestmark = pytest.mark.slow

SOLVE = ["solve", "-q", "--poses", *POSES_3]
_names = itertools.count()


def _initdb() -> str | None:
    found = shutil.which("initdb")
    return found or next(iter(sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"), reverse=True)), None)


@pytest.fixture(scope="module")
def server() -> Iterator[str]:
    """A PostgreSQL server of its own, on a socket in a temporary folder: its URL without a database."""
    initdb = _initdb()
    if initdb is None:
        pytest.skip("PostgreSQL is not installed (make test installs Debian's postgresql package where it can)")
    pytest.importorskip("psycopg", reason="psycopg is not installed: pip install 'tumblecal[postgres]'")
    bin_dir = os.path.dirname(os.path.realpath(initdb))
    folder = tempfile.mkdtemp(prefix="tcpg")  # short: a socket's path has at most 107 bytes
    as_user: list[str] = []
    if os.geteuid() == 0:  # initdb refuses root: the server runs as the package's postgres user
        shutil.chown(folder, "postgres")
        as_user = ["runuser", "-u", "postgres", "--"]
    data = os.path.join(folder, "data")
    subprocess.run([*as_user, initdb, "-D", data, "-A", "trust", "-U", "tumblecal", "-E", "UTF8", "--no-sync"],
                   check=True, capture_output=True)  # fmt: skip
    options = f"-c listen_addresses='' -k {folder} -c fsync=off"
    start = [*as_user, f"{bin_dir}/pg_ctl", "-D", data, "-o", options, "-l", f"{folder}/log", "-w", "start"]
    subprocess.run(start, check=True, capture_output=True)
    try:
        yield f"postgresql://tumblecal@/{{}}?host={folder}"
    finally:
        subprocess.run([*as_user, f"{bin_dir}/pg_ctl", "-D", data, "-m", "immediate", "stop"], capture_output=True)
        shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture
def db(server: str) -> str:
    """A new database on the server, for one test: its URL."""
    import psycopg

    name = f"records_{os.getpid()}_{next(_names)}"
    with psycopg.connect(server.format("postgres"), autocommit=True) as con:
        con.execute(f"CREATE DATABASE {name}")
    return server.format(name)


def _sql(db: str, sql: str) -> list[tuple[object, ...]]:
    import psycopg

    with psycopg.connect(db, autocommit=True) as con:
        cursor = con.execute(sql)
        return cursor.fetchall() if cursor.description else []


def test_solve_records_on_the_server_once(capsys: pytest.CaptureFixture[str], db: str, tmp_path: Path) -> None:
    args = [*SOLVE, "--serial", "PG1", "--station", "S1", "-o", str(tmp_path / "a.json"), "--record", db]
    assert run(capsys, *args).code == 0
    assert run(capsys, *args).code == 0  # a retry
    rows = _sql(db, "SELECT serial, station, verdict, offset_x, document FROM records")
    assert len(rows) == 1
    assert rows[0][:3] == ("PG1", "S1", "pass")
    recorded, written = json.loads(str(rows[0][4])), json.loads((tmp_path / "a.json").read_text())
    assert recorded.pop("created") <= written.pop("created")  # the retry's file is a second later, or not
    assert recorded == written  # a record is keyed by its content but for when it was made
    history = json.loads(run(capsys, "records", "history", "PG1", "--db", db, "--json").out)
    assert [r["serial"] for r in history] == ["PG1"]
    assert run(capsys, "records", "trend", "--db", db).code == 0
    assert run(capsys, "records", "migrate", "--db", db).err.endswith(": schema 1, up to date\n")


def test_an_injection_like_serial_is_text_on_the_server(
    capsys: pytest.CaptureFixture[str], db: str, tmp_path: Path
) -> None:
    serial = "x'); DROP TABLE records;--"
    assert run(capsys, *SOLVE, "--serial", serial, "-o", str(tmp_path / "a.json"), "--record", db).code == 0
    assert _sql(db, "SELECT serial FROM records") == [(serial,)]


def test_the_servers_refusals_mask_the_password(capsys: pytest.CaptureFixture[str], db: str, tmp_path: Path) -> None:
    out = tmp_path / "a.json"
    secret = db.replace("tumblecal@", "tumblecal:hunter2@")
    missing = secret.replace("/records_", "/nosuch_")
    result = run(capsys, *SOLVE, "-o", out, "--record", missing)
    assert result.code == 2
    assert "hunter2" not in result.err
    assert result.err.startswith(f"error: {missing.replace('hunter2', '***')}: cannot connect: ")
    assert not out.exists()
    _sql(db, "CREATE TABLE t (x int)")
    masked = secret.replace("hunter2", "***")
    result = run(capsys, *SOLVE, "-o", out, "--record", secret)
    assert_one_error(result, f"{masked}: not a tumblecal records database (its tables: t)")
    assert not out.exists()


def test_a_newer_schema_on_the_server_is_never_written(
    capsys: pytest.CaptureFixture[str], db: str, tmp_path: Path
) -> None:
    assert run(capsys, *SOLVE, "-o", tmp_path / "a.json", "--record", db).code == 0
    _sql(db, "UPDATE tumblecal_meta SET value = '5' WHERE name = 'schema'")
    result = run(capsys, *SOLVE, "--serial", "N", "-o", tmp_path / "b.json", "--record", db)
    assert result.code == 2
    assert "written by a newer tumblecal (records schema 5" in result.err
    assert _sql(db, "SELECT count(*) FROM records") == [(1,)]


def test_eight_processes_record_into_the_server_each_once(db: str, tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    template = _template(tmp_path)
    writers = [
        subprocess.Popen(
            [sys.executable, "-c", WRITER, db, out, f"Q{k}", "125", template], stdout=subprocess.PIPE, cwd=ROOT
        )
        for k in range(8)
    ]  # (the schema made by whichever comes first: the others wait on its lock)
    printed = [w.communicate(timeout=300)[0].decode().split() for w in writers]
    assert [w.returncode for w in writers] == [0] * 8
    serials = [str(r[0]) for r in _sql(db, "SELECT serial FROM records")]
    assert len(serials) == 1000
    assert set(serials) == {s for p in printed for s in p}
    assert len(list(out.iterdir())) == 1000
