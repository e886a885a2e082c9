"""apply's worker processes (io/rewrite/forked.py) write what this process's threads write.

Each case of ``test_splice.CASES`` is corrected twice with small blocks (so that a file is
dozens of them, spread over the workers): into a file, which forks the workers, and into a
``BytesIO``, which has no descriptor and keeps the work here. Same bytes, same error; the
workers are gone afterwards, whatever happened.
"""

from __future__ import annotations

import contextlib
import io
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.conftest import POSES_3, write
from tests.test_splice import CASES, _accel, lines, table
from tumblecal_cli.errors import InputError, TumblecalError
from tumblecal_cli.io.csv import splice
from tumblecal_cli.io.csv.capture import open_capture
from tumblecal_cli.io.rewrite import forked
from tumblecal_cli.io.rewrite import writer as rewrite

BLOCK = 2048


@pytest.fixture
def worker_counts(small_blocks: None, monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Blocks of 2 KiB, workers for any size of file, and a record of each forked run's workers."""
    monkeypatch.setattr(forked, "MIN_BYTES", 0)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1, 2})  # 3 workers, even on 2 cores
    monkeypatch.setattr(threading, "active_count", lambda: 1)  # whatever threads other tests left
    runs: list[int] = []
    pipeline = forked.pipeline

    def spy(*args: object, **kwargs: object) -> int:
        runs.append(int(args[5]))  # type: ignore[call-overload]
        return pipeline(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(forked, "pipeline", spy)
    return runs


def corrected(path: Path, out: io.BytesIO | None) -> tuple[bytes, str | None]:
    """``correct_stream`` of ``path`` into ``out``, or into a file when ``out`` is None."""
    error = None
    target = path.with_suffix(".out")
    with contextlib.ExitStack() as stack:
        sink = out if out is not None else stack.enter_context(open(target, "wb"))
        try:
            with open_capture(str(path)) as cap:
                rewrite.correct_stream(cap, sink, _accel)
        except TumblecalError as err:
            error = str(err)
    return (out.getvalue() if out is not None else target.read_bytes()), error


FORKED: list[int] = []  # the worker processes forked by this module's tests


@pytest.fixture(autouse=True)
def record_forks(monkeypatch: pytest.MonkeyPatch) -> None:
    fork = os.fork

    def recorded() -> int:
        pid = fork()
        if pid:
            FORKED.append(pid)
        return pid

    monkeypatch.setattr(os, "fork", recorded)


def no_children_left() -> bool:
    """Every worker forked so far has ended and been reaped (other tests' children aside)."""
    for pid in FORKED:
        try:
            os.waitpid(pid, os.WNOHANG)
        except ChildProcessError:
            continue
        return False
    return True


@pytest.mark.parametrize("case", list(CASES))
def test_workers_write_what_threads_write(case: str, tmp_path: Path, worker_counts: list[int]) -> None:
    path = write(tmp_path / "c.csv", CASES[case]())
    with contextlib.suppress(TumblecalError):  # refused when opened: neither runs
        with open_capture(str(path)):
            pass
        threads = corrected(path, io.BytesIO())
        workers = corrected(path, None)
        assert workers == threads
    assert no_children_left()


def test_a_plain_file_is_spread_over_the_workers(tmp_path: Path, worker_counts: list[int]) -> None:
    path = write(tmp_path / "c.csv", "t,ax,ay,az\n" + "\n".join(lines(table(3000))) + "\n")
    out, error = corrected(path, None)
    assert error is None
    assert worker_counts == [3]
    assert out == corrected(path, io.BytesIO())[0]
    assert len(splice.cuts(str(path), 11, BLOCK) or []) > 30


def test_an_error_in_a_late_block_names_its_line_after_the_blocks_before_it(
    tmp_path: Path, worker_counts: list[int]
) -> None:
    rows = lines(table(3000))
    rows[2500] = "2.5,0.5,oops,0.5"
    path = write(tmp_path / "c.csv", "t,ax,ay,az\n" + "\n".join(rows) + "\n")
    out, error = corrected(path, None)
    assert worker_counts == [3]
    assert error is not None
    assert "line 2502" in error
    assert "oops" in error
    assert (out, error) == corrected(path, io.BytesIO())
    assert out.endswith(rewrite.INCOMPLETE)
    assert out.count(b"\n") > 2000  # the blocks before the bad one are out, those after it are not
    assert b"2.999" not in out
    assert no_children_left()


def test_a_line_longer_than_the_window_keeps_the_work_here(tmp_path: Path, worker_counts: list[int]) -> None:
    text = "t,ax,ay,az,note\n" + "\n".join(f"{ln},{'n' * 3000}" for ln in lines(table(20))) + "\n"
    path = write(tmp_path / "c.csv", text)
    assert splice.cuts(str(path), 16, BLOCK) is None
    (to_file, error), (to_memory, same_error) = corrected(path, None), corrected(path, io.BytesIO())
    assert error == same_error
    assert error is not None
    assert "line 2" in error
    # how many rows are out before the reader stops depends on the threads' timing (the general path's way)
    for written in (to_file, to_memory):
        assert written == b"" or (written.startswith(b"t,ax,ay,az,note\n") and written.endswith(rewrite.INCOMPLETE))
    assert worker_counts == []


def test_the_cuts_are_a_readers_blocks(tmp_path: Path) -> None:
    """Block by block as a reader of ``block`` bytes cuts them: whole lines, the last part line
    carried into the next read, a last line without its line end a block of its own."""
    text = ("t,ax,ay,az\n" + "\n".join(lines(table(5000))) + "\n5.000,0.1,0.2,0.3").encode()
    path = write(tmp_path / "c.csv", text)
    expected, carry, at = [], b"", 11
    with open(path, "rb") as f:
        f.seek(at)
        while chunk := f.read(4096):
            cut = chunk.rfind(b"\n") + 1
            block, carry = carry + chunk[:cut], chunk[cut:]
            expected.append((at, len(block)))
            at += len(block)
    expected.append((at, len(carry)))
    assert splice.cuts(str(path), 11, 4096) == expected


def test_a_worker_that_dies_is_an_error_not_a_hang(tmp_path: Path, worker_counts: list[int]) -> None:
    path = write(tmp_path / "c.csv", "t,ax,ay,az\n" + "\n".join(lines(table(3000))) + "\n")

    def render(block: bytes, at: int) -> tuple[list[bytes], int]:
        if at > 20_000:
            os.kill(os.getpid(), signal.SIGKILL)
        return [block], block.count(b"\n")

    blocks = splice.cuts(str(path), 11, BLOCK)
    assert blocks is not None
    with open(tmp_path / "out", "wb") as out, pytest.raises(RuntimeError, match="ended without its block"):
        forked.pipeline(str(path), blocks, render, out, b"t,ax,ay,az\n", 2, written=lambda: None)
    assert no_children_left()


def test_a_workers_error_comes_back_as_it_was(tmp_path: Path, worker_counts: list[int]) -> None:
    path = write(tmp_path / "c.csv", "t,ax,ay,az\n" + "\n".join(lines(table(3000))) + "\n")

    def render(block: bytes, at: int) -> tuple[list[bytes], int]:
        if at > 20_000:
            raise InputError("bad cell", file="c.csv", line=7, hint="fix it")
        return [block], block.count(b"\n")

    blocks = splice.cuts(str(path), 11, BLOCK)
    assert blocks is not None
    with open(tmp_path / "out", "wb") as out, pytest.raises(InputError) as caught:
        forked.pipeline(str(path), blocks, render, out, b"t,ax,ay,az\n", 2, written=lambda: None)
    assert (str(caught.value), caught.value.hint, caught.value.line) == ("c.csv: bad cell (line 7)", "fix it", 7)
    written = (tmp_path / "out").read_bytes()
    failed_at = next(at for at, _ in blocks if at > 20_000)  # every block before the failed one, none after
    assert written.startswith(b"t,ax,ay,az\n0.000,")
    assert len(written) == failed_at
    assert no_children_left()


@pytest.mark.slow
def test_sigterm_leaves_no_worker_and_no_file(tmp_path: Path) -> None:
    """A station's kill in the middle of a big file: exit 130, the workers gone with it, no
    output and no temporary file."""
    cal = tmp_path / "cal.json"
    tumblecal = [sys.executable, "-m", "tumblecal_cli"]
    subprocess.run([*tumblecal, "solve", "-q", "--poses", *POSES_3, "-o", str(cal)], check=True)
    row = "0.001,0.012345,-0.023456,1.012345\n"
    big = tmp_path / "big.csv"
    big.write_text("t,ax,ay,az\n" + row * (2 * forked.MIN_BYTES // len(row)) * 4)
    argv = [*tumblecal, "apply", "-q", "--cal", str(cal), str(big), "-o", str(tmp_path / "o.csv")]
    with subprocess.Popen(argv, stderr=subprocess.PIPE) as proc:
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and len(_processes_with(str(big))) < 3:  # the command and its workers
            time.sleep(0.02)
        assert len(_processes_with(str(big))) >= 3
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(20) == 130
        assert b"Traceback" not in proc.communicate()[1]
    time.sleep(0.2)
    assert _processes_with(str(big)) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.csv", "cal.json"]


def _processes_with(word: str) -> list[int]:
    found = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            with contextlib.suppress(OSError), open(f"/proc/{entry}/cmdline", "rb") as f:
                if word.encode() in f.read():
                    found.append(int(entry))
    return found


def test_a_process_with_threads_of_its_own_does_not_fork(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A fork copies other threads' locks as they are (a Dask worker runs several): threads then."""
    monkeypatch.setattr(forked, "MIN_BYTES", 0)
    monkeypatch.setattr(threading, "active_count", lambda: 3)
    assert forked.workers_for(str(tmp_path / "c.csv"), 1 << 30) == 0
    monkeypatch.setattr(threading, "active_count", lambda: 1)
    assert forked.workers_for(str(tmp_path / "c.csv"), 1 << 30) == min(len(os.sched_getaffinity(0)), 8) or (
        len(os.sched_getaffinity(0)) == 1
    )
