"""Hostile inputs, round 3 (numbers at the edge, a file that shrinks while read, outputs that
would wait for ever, temporary files of writers gone): each test is named for the defect it
pins, and failed on the main branch before its fix."""

from __future__ import annotations

import json
from collections.abc import Generator, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.conftest import POSES_3, SAMPLE, assert_one_error, precious, run, run_exe, write

#: apply's blocks in these tests (conftest.small_blocks): a capture of a few KB is many of them.
BLOCK = 4096


@pytest.fixture
def calibration(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> dict[str, object]:
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", tmp_path / "cal.json", "-q").code == 0
    doc: dict[str, object] = json.loads((tmp_path / "cal.json").read_text())
    return doc


def _with_offset(tmp_path: Path, doc: dict[str, object], offset: float, name: str) -> Path:
    return write(tmp_path / name, {**doc, "offset": [offset, 0.0, 0.0]})


@pytest.mark.parametrize(
    "command",
    [
        ["noise", "--cal", "{cal}", str(SAMPLE / "x.csv")],
        ["export", "{cal}", "--format", "px4"],
        ["verify", "--cal", "{cal}", str(SAMPLE / "x.csv")],
        ["apply", "--cal", "{cal}", str(SAMPLE / "x.csv")],
    ],
    ids=["noise", "export", "verify", "apply"],
)
def test_non_finite_figure_from_an_offset_of_1e308_is_refused_where_the_calibration_is_read(
    command: list[str], calibration: dict[str, object], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """noise --cal wrote NaN into its figures with exit 0; export px4 and verify printed numpy's
    RuntimeWarning lines before their error: an offset is a reading, bounded as one (1e150)."""
    cal = _with_offset(tmp_path, calibration, 1e308, "big.json")
    r = run(capsys, *(a.replace("{cal}", str(cal)) for a in command))
    assert_one_error(
        r,
        f"{cal}: field 'offset' has an entry of 1e+308: beyond any reading tumblecal computes with "
        "(|reading| <= 1e+150)",
    )


@pytest.mark.slow
@pytest.mark.parametrize(
    "command",
    [
        ["export", "{cal}", "--format", "registers", "--lsb", "1e-200"],
        ["export", "{cal}", "--format", "px4"],
        ["verify", "--cal", "{cal}", str(SAMPLE / "x.csv")],
        ["noise", "--cal", "{cal}", str(SAMPLE / "x.csv")],
    ],
    ids=["registers", "px4", "verify", "noise"],
)
def test_numpy_warning_never_reaches_stderr_of_the_installed_script(
    command: list[str], calibration: dict[str, object], tmp_path: Path
) -> None:
    """An offset of 1e150 (within the bound) and extreme options: numpy's "RuntimeWarning:
    overflow encountered" lines came before the error, or before a NaN with exit 0. A figure
    that goes inf or NaN on the way is one error line (errors.numbers_checked), or the
    command's own (the verify capture's units)."""
    cal = _with_offset(tmp_path, calibration, 1e150, "large.json")
    done = run_exe([a.replace("{cal}", str(cal)) for a in command], text=True)
    assert "Warning" not in done.stderr, done.stderr
    assert "nan" not in done.stdout.lower(), done.stdout
    if done.returncode != 0:
        assert done.returncode == 2, done.stderr
        assert [ln for ln in done.stderr.splitlines() if not ln.startswith("hint: ")][-1].startswith("error: ")
        assert "internal error" not in done.stderr


@pytest.mark.usefixtures("calibration")
def test_floating_point_warning_inside_a_command_is_one_error_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Any numpy floating-point warning a command meets is an InputError at the boundary: exit 2,
    one line, not a RuntimeWarning on stderr and not an internal error."""
    from tumblecal_cli.pipeline import verify

    real = verify.verify

    def overflowing(*args: object, **kwargs: object) -> object:
        np.float64(1e300) * np.float64(1e300)  # numpy warns: overflow encountered
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(verify, "verify", overflowing)
    r = run(capsys, "verify", "--cal", tmp_path / "cal.json", SAMPLE / "x.csv")
    assert_one_error(
        r,
        "a figure came out non-finite (overflow encountered in scalar multiply): a number in the inputs or the "
        "options is too large or too small to compute with",
        hint="look for an extreme value in the calibration (tumblecal show CAL), the capture or the options",
    )


def test_verify_far_off_reference_says_times_not_150_digits_of_percent(
    calibration: dict[str, object], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cal = _with_offset(tmp_path, calibration, 1e150, "large.json")
    r = run(capsys, "verify", "--cal", cal, SAMPLE / "x.csv")
    assert r.code == 2
    assert "is 9.88e+149 times the reference 1: a units mistake" in r.err.splitlines()[0]


# -- a capture truncated while apply reads it ------------------------------------------------


def _truncating(monkeypatch: pytest.MonkeyPatch, victim: Path, keep: int) -> None:
    """apply's reader of a file's blocks, which cuts ``victim`` to ``keep`` bytes once it has
    given its first block (as another process truncating the file mid-read would)."""
    from tumblecal_cli.io.rewrite import writer

    blocks = writer._stream_blocks

    def cut(stream: Any) -> Iterator[tuple[bytes, bool]]:
        for k, item in enumerate(blocks(stream)):
            yield item
            if k == 0:
                with victim.open("r+b") as f:
                    f.truncate(keep)

    monkeypatch.setattr(writer, "_stream_blocks", cut)


@pytest.mark.usefixtures("small_blocks")
@pytest.mark.parametrize("to_stdout", [False, True], ids=["file", "stdout"])
def test_apply_of_a_capture_truncated_while_read_is_exit_2_not_a_short_output(
    to_stdout: bool,
    calibration: dict[str, object],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A capture truncated while apply read it: exit 0 with the rows read so far written, a silent
    partial output. The file as it stands at the end is compared with the file opened (inode,
    size, time): exit 2, the output left as it was (stdout: the rows out, then the incomplete
    marker, as for any error after the first row)."""
    capture = tmp_path / "capture.csv"
    rng = np.random.default_rng(3)
    write(
        capture,
        np.column_stack([np.arange(2000) / 100, 0.01 * rng.standard_normal((2000, 3)) + [0, 0, 1]]),
        header="t,ax,ay,az",
    )
    size = capture.stat().st_size
    keep = capture.read_bytes().index(b"\n", size // 3) + 1  # at a line's end: what is left reads well
    _truncating(monkeypatch, capture, keep)
    out = precious(tmp_path / "out.csv")
    args: list[str | Path] = ["apply", "--cal", tmp_path / "cal.json", capture]
    if not to_stdout:
        args += ["-o", out]
    r = run(capsys, *args)
    assert r.code == 2, r.err
    assert r.err.splitlines()[0] == (
        f"error: {capture}: the file changed while it was read ({size:,} bytes when opened, now {keep:,} "
        "bytes): what was read is not the file"
    )
    assert "Traceback" not in r.err
    if to_stdout:
        assert r.out.endswith("tumblecal: output incomplete: the run stopped on an error (exit 2, see stderr)\n")
    else:
        assert out.read_bytes() == precious(tmp_path / "again.csv").read_bytes()
        assert sorted(p.name for p in tmp_path.iterdir()) == ["again.csv", "cal.json", "capture.csv", "out.csv"]


@pytest.mark.usefixtures("calibration")
def test_apply_of_a_capture_that_grew_while_read_is_what_was_there(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A logger still appending: the rows there when read are corrected, exit 0 (as the log reader
    takes a growing log)."""
    from tumblecal_cli.io.rewrite import writer

    capture = write(
        tmp_path / "capture.csv",
        np.column_stack([np.arange(50) / 100, np.tile([0, 0, 1.0], (50, 1))]),
        header="t,ax,ay,az",
    )
    blocks = writer._stream_blocks

    def grow(stream: Any) -> Iterator[tuple[bytes, bool]]:
        yield from blocks(stream)
        with capture.open("ab") as f:
            f.write(b"0.5,0,0,1\n")

    monkeypatch.setattr(writer, "_stream_blocks", grow)
    r = run(capsys, "apply", "--cal", tmp_path / "cal.json", capture, "-o", tmp_path / "out.csv")
    assert r.code == 0, r.err
    assert len((tmp_path / "out.csv").read_text().splitlines()) == 51


# -- outputs that would wait for ever, temporary files whose writer is gone -------------------


def test_output_to_a_named_pipe_with_no_reader_is_exit_2_after_a_bounded_wait(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`solve -o FIFO` with no reader waited for ever (as `cat` would): a station script could not
    tell a hung run from a slow one. It waits outputs.FIFO_WAIT (30 s), then says why; the pipe
    stays a pipe."""
    import os
    import stat
    import time

    from tumblecal_cli.io import outputs

    monkeypatch.setattr(outputs, "FIFO_WAIT", 0.3)
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    began = time.monotonic()
    r = run(capsys, "solve", "-q", "--poses", SAMPLE / "z.csv", "-o", fifo)
    assert 0.3 <= time.monotonic() - began < 10
    assert_one_error(
        r,
        f"{fifo}: a named pipe with no reader after 0.3 s: nothing would take the output",
        hint="start its reader first (or write to a file)",
    )
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


def _sleeper() -> Generator[int]:
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        yield proc.pid
    finally:
        proc.kill()
        proc.wait()


def test_stale_temporary_file_of_a_writer_in_another_pid_namespace_is_swept_by_age(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A writer killed in another PID namespace (a container's) left `.cal.json.<pid>-….tmp`
    whose pid is a live process here: never swept, as the owner check saw a running process.
    Swept now when not written for a day (outputs.STALE_AGE), or when written before the
    process that now has its pid started; a live writer's (written since its process started,
    within the day) is left."""
    import os
    import time

    sleeper = _sleeper()
    newer = next(sleeper)  # a process started after the entries below were last written
    time.sleep(0.05)
    day_old = tmp_path / f".cal.json.{os.getppid()}-0123abcd.tmp"  # a live pid, written two days ago
    reused = tmp_path / f".cal.json.{newer}-0123abcd.tmp"  # its pid's process is younger than it
    live = tmp_path / f".cal.json.{os.getppid()}-4567cdef.tmp"  # the live parent's, written now
    for path in (day_old, reused, live):
        path.write_text("{")
    os.utime(day_old, (time.time() - 2 * 86400,) * 2)
    os.utime(reused, (time.time() - 3600,) * 2)
    try:
        r = run(capsys, "solve", "-q", "--poses", SAMPLE / "z.csv", "-o", tmp_path / "cal.json")
    finally:
        sleeper.close()
    assert r.code == 0, r.err
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([live.name, "cal.json"])


@pytest.mark.parametrize("kind", ["step", "drift", "moving"])
def test_a_move_over_readings_that_otherwise_never_change_is_said_not_divided_by_zero(kind: str) -> None:
    """noise of a mutated DataFlash log: "internal error: ZeroDivisionError" in the moved
    check's message, whose bound (the spread of the block means) was 0."""
    from tumblecal_cli.core.allan import Moved

    text = Moved("x", kind, 0.5, 0.0, 7).message()
    assert " is 0 (not a still capture)" in text
    assert "times" not in text
