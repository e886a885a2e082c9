"""apply on stdin: blocks of plain lines spliced as a file's are, the same bytes and errors as
the general reader's, which takes over from the first block that is not plain."""

from __future__ import annotations

import io
import subprocess
import sys
import types
from pathlib import Path

import pytest

from tests.conftest import POSES_3, spliced_blocks
from tests.test_splice import CASES, _accel, lines, table
from tumblecal_cli.errors import TumblecalError
from tumblecal_cli.io.csv import capture
from tumblecal_cli.io.csv.capture import open_capture
from tumblecal_cli.io.readspec import Dialect, ReadSpec
from tumblecal_cli.io.rewrite import writer as rewrite

BLOCK = 4096


def piped(
    data: bytes, monkeypatch: pytest.MonkeyPatch, *, splice_on: bool, **options: object
) -> tuple[bytes, str | None, list[str]]:
    """What ``correct_stream`` writes for ``data`` read from stdin, its error, and its notes."""
    monkeypatch.setattr(sys, "stdin", types.SimpleNamespace(buffer=io.BytesIO(data)))
    out = io.BytesIO()
    notes: list[str] = []
    try:
        with open_capture("-", ReadSpec(**options)) as cap:  # type: ignore[arg-type]
            rewrite.correct_stream(cap, out, _accel, splice=splice_on)
            notes = list(cap.layout.notes)
    except TumblecalError as err:
        return out.getvalue(), str(err), notes
    return out.getvalue(), None, notes


@pytest.mark.parametrize("case", list(CASES))
def test_stdin_spliced_is_the_general_path(case: str, monkeypatch: pytest.MonkeyPatch, small_blocks: None) -> None:
    text = CASES[case]()
    data = text.encode() if isinstance(text, str) else text
    assert piped(data, monkeypatch, splice_on=True) == piped(data, monkeypatch, splice_on=False)


def test_stdin_takes_the_fast_path_then_the_general_one(monkeypatch: pytest.MonkeyPatch, small_blocks: None) -> None:
    """Plain blocks are spliced until one is not; the error after it counts data rows from the start."""
    body = lines(table(3000))
    taken = spliced_blocks(monkeypatch)
    data = ("t,ax,ay,az\n" + "\n".join(body) + "\n").encode()
    fast = piped(data, monkeypatch, splice_on=True)
    assert fast == piped(data, monkeypatch, splice_on=False)
    assert len(taken) > 10
    assert all(taken)
    body[2000] = "# paused"
    body[2500] = "2.5,0.5,oops,0.5"
    data = ("t,ax,ay,az\n" + "\n".join(body) + "\n").encode()
    taken.clear()
    fast = piped(data, monkeypatch, splice_on=True)
    assert fast == piped(data, monkeypatch, splice_on=False)
    assert fast[1] == "<stdin>: not a number: 'oops' in column 'ay' (data row 2500)"
    assert fast[0].endswith(rewrite.INCOMPLETE)
    assert taken.count(False) == 1  # the block with the comment; after it, the general reader


def test_a_cut_last_line_dropped_on_stdin(monkeypatch: pytest.MonkeyPatch, small_blocks: None) -> None:
    data = ("t,ax,ay,az\n" + "\n".join(lines(table(2000))) + "\n2.000,0.01").encode()
    fast = piped(data, monkeypatch, splice_on=True, dialect=Dialect(drop_incomplete=True))
    assert fast == piped(data, monkeypatch, splice_on=False, dialect=Dialect(drop_incomplete=True))
    assert any("dropped (--drop-incomplete)" in note for note in fast[2])


@pytest.mark.slow
def test_a_pipe_through_the_cli_writes_what_a_file_does(tmp_path: Path) -> None:
    cal = tmp_path / "cal.json"
    tumblecal = [sys.executable, "-m", "tumblecal_cli"]
    subprocess.run([*tumblecal, "solve", "-q", "--poses", *POSES_3, "-o", str(cal)], check=True)
    capture = tmp_path / "c.csv"
    capture.write_text("t,ax,ay,az\n" + "\n".join(lines(table(200_000))) + "\n")
    from_file = subprocess.run([*tumblecal, "apply", "-q", "--cal", str(cal), str(capture)], capture_output=True)
    with capture.open("rb") as stdin:
        from_pipe = subprocess.run([*tumblecal, "apply", "-q", "--cal", str(cal)], stdin=stdin, capture_output=True)
    assert from_pipe.returncode == from_file.returncode == 0
    assert from_pipe.stdout == from_file.stdout


def test_crlf_lines_across_the_general_readers_reads_are_all_written(monkeypatch: pytest.MonkeyPatch) -> None:
    """A block of BLOCK_BYTES + 1 bytes ending in CRLF once fed pyarrow a read of a lone line
    feed, which it took for the end of the data: 30 of 40 rows were dropped, exit 0 (found in
    review). Reads now fill the reader's buffer across blocks."""
    monkeypatch.setattr(capture, "BLOCK_BYTES", 64)
    import random

    pick = random.Random(3)  # these cells make a block of 65 bytes ending in CRLF
    body = ["# paused"] + [f"{i},{pick.choice(['1', '1.5', '1.25', '1.125'])},2,3" for i in range(40)]
    data = ("t,ax,ay,az\r\n" + "\r\n".join(body) + "\r\n").encode()
    fast = piped(data, monkeypatch, splice_on=True)
    assert fast == piped(data, monkeypatch, splice_on=False)
    assert fast[1] is None
    assert fast[0].count(b"\r\n") == 41
