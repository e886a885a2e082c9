"""Hostile inputs (issue: "nothing written on failure, no file trusted that should not be"): each
test is named for the defect it pins, and failed on the main branch before its fix."""

from __future__ import annotations

import csv
import gzip
import io
import json
import re
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import POSES_3, ROOT, SAMPLE, precious, run, snapshot, tumblecal_exe, unit

#: A tree of YAML aliases, 10 wide and 8 deep: 10^8 strings once expanded (GB of memory).
ALIAS_BOMB = "\n".join(
    [f"a: &a [{', '.join(['x'] * 10)}]"]
    + [f"{b}: &{b} [{', '.join(['*' + a] * 10)}]" for a, b in zip("abcdefg", "bcdefgh", strict=True)]
)


@pytest.mark.parametrize(
    "command",
    [
        ["show", "{file}"],
        ["check", str(SAMPLE / "cal_placeholder.json"), "--limits", "{file}"],
        ["import", "{file}", "--from", "ros-yaml"],
    ],
    ids=["show", "limits", "import"],
)
def test_yaml_alias_bomb_is_refused_at_once(
    command: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text(ALIAS_BOMB + "\n", encoding="utf-8")
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal).code == 0
    args = [a.replace("{file}", str(bomb)).replace(str(SAMPLE / "cal_placeholder.json"), str(cal)) for a in command]
    r = run(capsys, *args, "-o", tmp_path / "out.json") if command[0] == "import" else run(capsys, *args)
    assert r.code == 2
    assert r.err.splitlines()[0] == (
        f"error: {bomb}: not valid YAML: an alias (*name): tumblecal's files are read without them (line 2, column 8)"
    )
    assert not (tmp_path / "out.json").exists()


def test_a_calibration_file_too_large_is_refused_without_reading_it_all(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    big = tmp_path / "big.json"
    with open(big, "wb") as f:
        f.write(b"{" + b" " * (17 * 1024 * 1024) + b"}")
    r = run(capsys, "show", big)
    assert r.code == 2
    assert r.err.splitlines() == [
        f"error: {big}: holds more than 16 MB: too large for a calibration file (they are kilobytes)",
        "hint: is this the calibration file you meant?",
    ]
    r = run(capsys, "check", "/dev/zero", "--max-offset", "1")
    assert r.code == 2
    assert "/dev/zero: holds more than 16 MB" in r.err


def test_import_writes_nothing_that_tumblecal_would_reject(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A ROS file whose recorded columns name one column twice: exit 2, no file (before: written,
    then refused by every command that read it)."""
    ros = tmp_path / "imu_calib.yaml"
    ros.write_text('SM: [1,0,0,0,1,0,0,0,1]\nbias: [0,0,0]\ntumblecal: {"columns": ["ax", "ax", "az"]}\n')
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "import", ros, "-o", out)
    assert r.code == 2
    assert r.err.splitlines() == [f"error: {ros}: field 'columns' must name three different columns, got ax, ax, az"]
    assert out.read_bytes() == precious(tmp_path / "again.json").read_bytes()


@pytest.mark.parametrize("serial", ["=1+1", "+1+1", "-2+3", "@SUM(A1)"])
def test_a_serial_that_is_a_formula_is_text_in_summary_csv(
    serial: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """CSV injection: summary.csv and report's CSV show such a serial as text ('=...), and
    --resume reads it back as the serial it was."""
    src = tmp_path / "units"
    manifest = tmp_path / "lot.csv"
    unit(src, "good", "good")
    with open(manifest, "w", newline="", encoding="utf-8") as f:
        csv.writer(f).writerows([["serial", "x", "y", "z"], [serial, *(str(src / "good" / f"{a}.csv") for a in "xyz")]])
    out = tmp_path / "cals"
    assert run(capsys, "batch", manifest, "--out-dir", out).code == 0
    with open(out / "summary.csv", newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert rows[0]["serial"] == "'" + serial
    assert float(rows[0]["offset_y"]) < 0  # a negative number stays a number
    again = run(capsys, "batch", manifest, "--out-dir", out, "--resume")
    assert again.code == 0
    assert "resuming: 1 of 1 units already done" in again.err
    r = run(capsys, "report", out, "--max-drift", "offset=1e-9")
    assert r.code == 0, r.err
    cal = next(out.glob("*.json"))
    assert json.loads(cal.read_text())["unit"]["serial"] == serial  # the calibration keeps it as given


@pytest.mark.parametrize(("flag", "value"), [("--serial", "A1\nB2"), ("--station", "S\x00"), ("--meta", "k=v\r")])
def test_control_characters_in_identifiers_are_refused(
    flag: str, value: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "--poses", *POSES_3, flag, value, "-o", out)
    assert r.code == 2
    assert len(r.err.splitlines()) == 1
    assert "holds a control character" in r.err
    assert not out.exists()


def test_a_serial_that_is_a_formula_is_text_in_report_csv(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    cals = tmp_path / "cals"
    cals.mkdir()
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1000")
    assert run(capsys, "solve", "--poses", *POSES_3, "--serial", "=1+1", "-o", cals / "a.json").code == 0
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "2000")  # calibrated again, later, from its +z pose alone
    assert run(capsys, "solve", "--poses", POSES_3[2], "--serial", "=1+1", "-o", cals / "b.json").code == 0
    r = run(capsys, "report", cals, "--max-drift", "offset=1e-6")
    assert r.code == 1, r.err
    flagged = [row for row in csv.DictReader(r.out.splitlines()) if row["drift_flagged"]]
    assert flagged
    assert {row["drift_flagged"] for row in flagged} == {"'=1+1"}


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (None, "field 'reference' must be a finite number"),
        ('{"a": ' + "9" * 5000 + "}", "not valid JSON: Exceeds the limit (4300 digits)"),
        ("[" * 100_000 + "]" * 100_000, "nested too deeply"),
    ],
    ids=["integer-beyond-float", "integer-of-5000-digits", "nested-100000-deep"],
)
def test_numbers_and_nesting_beyond_python_are_named_input_errors(
    text: str | None, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "cal.json"
    if text is None:  # a whole calibration whose reference is 1 followed by 400 zeros
        assert run(capsys, "solve", "--poses", *POSES_3, "-o", path).code == 0
        text = path.read_text().replace('"reference": 1.0', '"reference": 1' + "0" * 400, 1)
    path.write_text(text, encoding="utf-8")
    r = run(capsys, "show", path)
    assert r.code == 2
    assert "internal error" not in r.err
    assert message in r.err
    assert len(r.err.splitlines()) == 1


@pytest.mark.parametrize("command", ["solve", "verify"])
def test_readings_beyond_float_range_are_an_input_error(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """1e200 in a capture: its square overflows (a 'math domain error', or verify's norm error
    of inf with exit 0, before)."""
    capture = tmp_path / "z.csv"
    capture.write_text("t,ax,ay,az\n0,0,0,1e200\n0.1,0,0,1e200\n", encoding="utf-8")
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal).code == 0
    if command == "solve":
        r = run(capsys, "solve", "--poses", capture, "--reference", "1e200", "-o", tmp_path / "o.json")
    else:
        r = run(capsys, "verify", "--cal", cal, capture)
    assert r.code == 2
    assert r.err.splitlines()[0] == (
        f"error: {capture}: a reading of 1e+200 is beyond what tumblecal computes with (|reading| <= 1e+150)"
    )


def test_a_calibration_of_the_time_column_is_refused_by_apply(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal).code == 0
    doc = json.loads(cal.read_text())
    doc["columns"] = ["t", "ay", "az"]
    cal.write_text(json.dumps(doc))
    out = precious(tmp_path / "out.csv")
    commands: list[list[str | Path]] = [
        ["apply", "--cal", cal, SAMPLE / "capture.csv", "-o", out],
        ["verify", "--cal", cal, POSES_3[0]],
    ]
    for command in commands:
        r = run(capsys, *command)
        assert r.code == 2
        name = command[3]
        assert r.err.splitlines() == [
            f"error: {name}: the calibration's columns include 't', the capture's time column",
            "hint: a calibration corrects three sensor columns: check its 'columns' field (columns: t, ax, ay, az)",
        ]
    assert out.read_bytes() == precious(tmp_path / "again.csv").read_bytes()


def test_a_ros_comment_with_no_number_for_the_reference_is_ignored(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ros = tmp_path / "imu_calib.yaml"
    ros.write_text("# raw units in, g out, reference -; columns ax, ay, az\nSM: [1,0,0,0,1,0,0,0,1]\nbias: [0,0,0]\n")
    out = tmp_path / "cal.json"
    r = run(capsys, "import", ros, "-o", out)
    assert r.code == 0, r.err
    assert json.loads(out.read_text())["reference"] == 9.80665  # imu_calib's default, not the comment's "-"


def _segment_log(tmp_path: Path) -> Path:
    from tests.test_segment import six_poses, synth_log, write_log

    return write_log(tmp_path / "session.csv", synth_log(six_poses(), seed=2))


def _listing(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_segment_that_fails_while_writing_leaves_the_folder_as_it_was(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A full disk after some block files: exit 2, and neither a new segments.csv nor any block
    file nor a staging folder (before: segments.csv and the first blocks stayed)."""
    import errno

    from tumblecal_cli.io.csv import capture

    log = _segment_log(tmp_path)
    out = tmp_path / "poses"
    assert run(capsys, "segment", log, "--out-dir", out).code == 0  # an earlier segmentation
    before = _listing(out)
    for copier in ("copy_rows", "copy_bytes"):  # a log read whole, or block by block (io.csv.logread)
        real = getattr(capture, copier)

        def disk_full_after_two(
            path: str, layout: object, spans: list[object], outputs: list[str], real: object = real
        ) -> None:
            real(path, layout, spans[:2], outputs[:2])  # type: ignore[operator]
            raise OSError(errno.ENOSPC, "No space left on device", outputs[2])

        monkeypatch.setattr(capture, copier, disk_full_after_two)
    r = run(capsys, "segment", log, "--out-dir", out, "--min-duration", "2")
    assert r.code == 2
    assert "No space left on device" in r.err
    assert _listing(out) == before
    fresh = tmp_path / "new"
    assert run(capsys, "segment", log, "--out-dir", fresh).code == 2
    assert not fresh.exists()  # a folder it created for nothing is gone too


def test_segment_removes_the_staging_folder_a_killed_run_left(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import os

    log = _segment_log(tmp_path)
    out = tmp_path / "poses"
    (out / ".tumblecal-segment-4194305-abc123").mkdir(parents=True)  # a pid above Linux's largest: gone
    (out / ".tumblecal-segment-4194305-abc123" / "xp.csv").write_text("half")
    (out / "notes.txt").write_text("mine")
    running = out / f".tumblecal-segment-{os.getppid()}-def456"  # another segment run, still writing
    running.mkdir()
    r = run(capsys, "segment", log, "--out-dir", out)
    assert r.code == 0, r.err
    assert "note: removed 1 staging folder(s) an earlier, interrupted segment run left" in r.err
    assert not (out / ".tumblecal-segment-4194305-abc123").exists()
    assert (out / "notes.txt").read_text() == "mine"
    assert running.is_dir()


def test_a_killed_runs_temporary_files_are_removed_by_the_next_write(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """kill -9 leaves ``.out.csv.PID-XXXXXXXX.tmp``; the next write into that folder removes the
    temporary files of that naming whose process is gone, and nothing else (a live process's,
    other names, other files)."""
    import os

    cal = tmp_path / "cal.json"
    dead = [tmp_path / f".{name}.4194305-abcd1234.tmp" for name in ("out.csv", "other.csv")]  # no such pid
    live = tmp_path / f".out.csv.{os.getppid()}-efgh5678.tmp"
    other = [tmp_path / ".out.csv.tmp", tmp_path / ".out.csv.4194305-abc.tmp", tmp_path / "out.csv.bak"]
    for path in [*dead, live, *other]:
        path.write_text("partial")
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal).code == 0  # a new process's first write here
    assert run(capsys, "apply", "--cal", cal, SAMPLE / "capture.csv", "-o", tmp_path / "out.csv").code == 0
    assert not any(p.exists() for p in dead)
    assert live.exists()
    assert all(p.exists() for p in other)


@pytest.mark.slow
@pytest.mark.parametrize("command", ["solve", "segment"])
def test_a_fifo_is_read_once_and_never_blocks(command: str, tmp_path: Path) -> None:
    """A named pipe given as a pose file or a log: read once, as stdin is (before: opened a
    second time, waiting for a writer for ever; process substitution failed with 'lseek failed')."""
    import os
    import subprocess

    from tests.conftest import run_exe

    source = SAMPLE / "z.csv" if command == "solve" else _segment_log(tmp_path)
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    writer = subprocess.Popen(["sh", "-c", f"cat '{source}' > '{fifo}'"])
    try:
        if command == "solve":
            done = run_exe(["solve", "--poses", fifo, "-o", tmp_path / "cal.json", "-q"])
        else:
            done = run_exe(["segment", fifo, "--out-dir", tmp_path / "poses", "-q"])
    finally:
        try:
            writer.wait(timeout=60)
        finally:  # a run that never opened the pipe leaves its writer blocked: not for ever
            if writer.poll() is None:
                writer.kill()
                writer.wait()
    assert done.returncode == 0, done.stderr
    if command == "solve":
        assert json.loads((tmp_path / "cal.json").read_text())["poses"][0]["file"] == str(fifo)
    else:
        assert (tmp_path / "poses" / "segments.csv").exists()


@pytest.mark.slow
def test_apply_to_stdout_that_fails_part_way_ends_its_output_as_incomplete(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Rows already streamed cannot be taken back: the output ends with a line no CSV reader of
    that header takes for a row, and the exit status is 2."""
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal).code == 0
    rows = [f"{k * 0.01:.2f},0.1,0.2,0.9" for k in range(200_000)]
    rows[150_000] = "1500.00,0.1,x,0.9"
    capture = tmp_path / "capture.csv"
    capture.write_text("t,ax,ay,az\n" + "\n".join(rows) + "\n")
    r = run(capsys, "apply", "--cal", cal, capture)
    assert r.code == 2
    assert r.err.splitlines() == [f"error: {capture}: not a number: 'x' (line 150002, column ay)"]
    lines = r.out.splitlines()
    assert lines[0] == "t,ax,ay,az"
    assert len(lines) > 1000
    assert lines[-1] == "tumblecal: output incomplete: the run stopped on an error (exit 2, see stderr)"
    out = precious(tmp_path / "out.csv")
    assert run(capsys, "apply", "--cal", cal, capture, "-o", out).code == 2
    assert out.read_bytes() == precious(tmp_path / "again.csv").read_bytes()  # with -o: nothing written


def test_batch_stops_on_a_full_disk_and_leaves_that_unit_to_resume(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A unit whose calibration cannot be written is not done: the batch stops (exit 2, naming
    the file), its row is not in summary.csv, and --resume does it (before: recorded as an error
    row, then skipped by --resume as done)."""
    from tumblecal_cli.errors import InputError
    from tumblecal_cli.io.calfiles import calfile

    src = tmp_path / "units"
    for serial in ("A", "B", "C"):
        unit(src, serial, "good")
    out = tmp_path / "cals"
    real = calfile.Calibration.save

    def full_disk_for_b(self: calfile.Calibration, path: str) -> None:
        if self.serial == "B":
            raise InputError("cannot write: No space left on device", file=str(path))
        real(self, path)

    monkeypatch.setattr(calfile.Calibration, "save", full_disk_for_b)
    r = run(capsys, "batch", src, "--out-dir", out)
    assert r.code == 2
    assert "B: " in r.err
    assert "No space left on device" in r.err
    assert "--resume" in r.err
    with open(out / "summary.csv", newline="", encoding="utf-8") as f:
        assert [row["serial"] for row in csv.DictReader(f)] == ["A"]
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no staging file left
    monkeypatch.setattr(calfile.Calibration, "save", real)
    r = run(capsys, "batch", src, "--out-dir", out, "--resume")
    assert r.code == 0, r.err
    with open(out / "summary.csv", newline="", encoding="utf-8") as f:
        assert [row["serial"] for row in csv.DictReader(f)] == ["A", "B", "C"]


def test_batch_removes_the_staging_files_a_killed_batch_left(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = tmp_path / "units"
    unit(src, "A", "good")
    out = tmp_path / "cals"
    out.mkdir()
    stale = out / ".A.4194305-1700000000000000000.partial.json"  # a pid above Linux's largest
    stale.write_text("{}")
    mine = out / ".notes.partial.json"  # not of a batch's naming
    mine.write_text("{}")
    r = run(capsys, "batch", src, "--out-dir", out)
    assert r.code == 0, r.err
    assert f"note: removed 1 staging file(s) a killed batch left in {out}" in r.err
    assert not stale.exists()
    assert mine.exists()


@pytest.mark.slow
def test_batch_workers_exit_when_the_batch_is_killed(tmp_path: Path) -> None:
    """kill -9 of `batch --jobs 2` cannot shut its pool down: its workers see it gone and exit
    (before: alive after 60 s, holding 260 MB)."""
    import os
    import signal
    import subprocess
    import time
    import uuid

    from tests.conftest import tumblecal_exe

    src = tmp_path / "units"
    for k in range(60):
        unit(src, f"U{k:03d}", "good")
    mark = uuid.uuid4().hex
    scratch = tmp_path / "tmp"  # the pool's own folder, which no one can remove after a kill -9: not /tmp's
    scratch.mkdir()
    env = {**os.environ, "TUMBLECAL_TEST_MARK": mark, "TMPDIR": str(scratch)}

    def ours() -> list[int]:
        found = []
        for pid in filter(str.isdigit, os.listdir("/proc")):
            try:
                environ = Path(f"/proc/{pid}/environ").read_bytes()
            except OSError:
                continue
            if f"TUMBLECAL_TEST_MARK={mark}".encode() in environ.split(b"\0"):
                found.append(int(pid))
        return found

    batch = subprocess.Popen(
        [tumblecal_exe(), "batch", str(src), "--out-dir", str(tmp_path / "cals"), "--jobs", "2", "-q"],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 30
    while len(ours()) < 3 and time.monotonic() < deadline:  # the batch and its workers
        time.sleep(0.05)
    assert len(ours()) >= 3
    os.kill(batch.pid, signal.SIGKILL)
    batch.wait(timeout=10)
    deadline = time.monotonic() + 10
    while ours() and time.monotonic() < deadline:
        time.sleep(0.2)
    assert ours() == []


def _marked(mark: str) -> dict[int, int]:
    """The processes whose environment holds TUMBLECAL_TEST_MARK=mark (this test's own), each
    with its parent's pid."""
    import os

    found = {}
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            environ = Path(f"/proc/{pid}/environ").read_bytes()
            stat = Path(f"/proc/{pid}/stat").read_text()
        except OSError:
            continue
        if f"TUMBLECAL_TEST_MARK={mark}".encode() in environ.split(b"\0"):
            found[int(pid)] = int(stat.rsplit(")", 1)[1].split()[1])  # after "pid (name) state"
    return found


@pytest.mark.slow
def test_a_killed_batch_does_not_hang_a_caller_reading_its_output(tmp_path: Path) -> None:
    """subprocess.run(capture_output=True) reads the output to its end before it reaps: a
    `batch --jobs 2` killed with -9 is a zombie until then, and its workers, fork server and
    resource tracker must see it gone all the same and let go of the caller's pipes (before: the
    caller still waited after 25 s in 11 of 14 tries). The pool's folder in $TMPDIR, which a
    kill -9 leaves, is removed by the next run."""
    import os
    import signal
    import threading
    import time
    import uuid

    src = tmp_path / "units"
    for k in range(60):
        unit(src, f"U{k:03d}", "good")
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    command = [tumblecal_exe(), "batch", str(src), "--jobs", "2", "-q", "--out-dir"]
    for attempt in range(3):
        mark = uuid.uuid4().hex
        killed: list[float] = []

        def kill_once_the_workers_run(mark: str = mark, killed: list[float] = killed) -> None:
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline:
                found = _marked(mark)
                batch = [pid for pid, parent in found.items() if parent == os.getpid()]
                if batch and len(found) >= 4:  # the batch, its resource tracker, fork server and a worker
                    os.kill(batch[0], signal.SIGKILL)
                    killed.append(time.monotonic())
                    return
                time.sleep(0.02)

        killer = threading.Thread(target=kill_once_the_workers_run, daemon=True)
        killer.start()
        env = {**os.environ, "TUMBLECAL_TEST_MARK": mark, "TMPDIR": str(scratch)}
        try:
            subprocess.run([*command, str(tmp_path / f"cals{attempt}")], env=env, capture_output=True, timeout=20)
            returned = time.monotonic()
        except subprocess.TimeoutExpired:
            returned = float("inf")
        finally:
            killer.join()
            for pid in _marked(mark):  # what this test started and is still there
                os.kill(pid, signal.SIGKILL)
        assert killed, "the batch's workers never ran"
        assert returned - killed[0] < 10, f"try {attempt + 1}: the caller still waits, 10 s after the kill"
    left = [p.name for p in scratch.iterdir() if p.name.startswith("pymp-")]
    assert left  # what the kills left
    done = subprocess.run([*command, str(tmp_path / "again")], env={**os.environ, "TMPDIR": str(scratch)}, timeout=60)
    assert done.returncode == 0
    assert [p.name for p in scratch.iterdir() if p.name.startswith("pymp-")] == []


def test_only_the_pool_folders_of_killed_batches_are_removed(tmp_path: Path) -> None:
    """A pool folder is removed when it is marked as a tumblecal pool's and its process is gone;
    never one of a running process, this one's, one without the mark, or a file."""
    import os

    from tumblecal_cli.pipeline.batch.cluster import remove_stale_pools

    marks = {
        "pymp-dead0000": 4194305,
        "pymp-live0000": os.getppid(),
        "pymp-mine0000": os.getpid(),
        "pymp-other000": None,
    }
    for name, pid in marks.items():
        (tmp_path / name).mkdir()
        (tmp_path / name / "listener-abc").write_text("")
        if pid is not None:
            (tmp_path / name / f"tumblecal-{pid}").write_text("")
    (tmp_path / "pymp-file").write_text("")
    assert remove_stale_pools(str(tmp_path)) == ["pymp-dead0000"]
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "pymp-file",
        "pymp-live0000",
        "pymp-mine0000",
        "pymp-other000",
    ]


#: Streams that never end, as a program's output: random bytes, and `yes` (one column of y).
ENDLESS = {
    "random": "import os, sys\nwhile True: sys.stdout.buffer.write(os.urandom(1 << 16))",
    "yes": "import sys\nwhile True: sys.stdout.buffer.write(b'y\\n' * (1 << 15))",
}


@pytest.mark.slow
@pytest.mark.parametrize(
    ("command", "stream", "first"),
    [
        (["segment", "/dev/urandom"], None, "error: /dev/urandom: binary data, not a CSV text file"),
        (
            ["solve", "--log", "/dev/urandom", "-o", "{out}"],
            None,
            "error: /dev/urandom: binary data, not a CSV text file",
        ),
        (["segment", "-"], "random", "error: <stdin>: binary data, not a CSV text file"),
        (["solve", "--log", "-", "-o", "{out}"], "yes", "error: <stdin>: only one column: no delimiter found"),
    ],
    ids=["segment-urandom", "solve-log-urandom", "segment-stdin-random", "solve-log-stdin-yes"],
)
def test_an_endless_stream_is_refused_at_once_not_spooled(
    command: list[str], stream: str | None, first: str, tmp_path: Path
) -> None:
    """A log from a pipe or a device is copied to $TMPDIR for a second read: the copy checks what
    it copies as the CSV reader does, and stops at the first block of what no reader takes
    (before: it filled $TMPDIR at ~100 MB/s, for ever)."""
    import os
    import sys
    import time

    scratch = tmp_path / "tmp"
    scratch.mkdir()
    out = tmp_path / "cal.json"
    feeder = subprocess.Popen([sys.executable, "-c", ENDLESS[stream]], stdout=subprocess.PIPE) if stream else None
    started = time.monotonic()
    try:
        r = subprocess.run(
            [tumblecal_exe(), *(a.replace("{out}", str(out)) for a in command)],
            stdin=feeder.stdout if feeder else subprocess.DEVNULL,
            capture_output=True,
            env={**os.environ, "TMPDIR": str(scratch)},
            timeout=10,
        )
    finally:
        if feeder:
            feeder.kill()
            feeder.wait()
            assert feeder.stdout is not None
            feeder.stdout.close()
    assert time.monotonic() - started < 5
    assert r.returncode == 2
    lines = r.stderr.decode().splitlines()
    assert lines[0] == first
    assert all(ln.startswith("hint: ") for ln in lines[1:]), lines
    assert r.stdout == b""
    assert list(scratch.iterdir()) == []
    assert not out.exists()


class _EndlessLog(io.RawIOBase):
    """A log on stdin that never ends: a header, then the same row."""

    def __init__(self) -> None:
        self.head = b"t,ax,ay,az\n"
        self.row = b"0.01,0.001,-0.002,1.003\n"

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        view = memoryview(buffer).cast("B")
        data = self.head + self.row * (len(view) // len(self.row) + 1)
        self.head = b""
        view[:] = data[: len(view)]
        return len(view)


@pytest.mark.parametrize(
    "command", [["segment", "-"], ["solve", "--log", "-", "-o", "{out}"]], ids=["segment", "solve"]
)
def test_a_log_on_stdin_longer_than_max_spool_is_exit_2(
    command: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import sys
    import tempfile

    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BufferedReader(_EndlessLog())))
    out = tmp_path / "cal.json"
    r = run(capsys, *(a.replace("{out}", str(out)) for a in command), "--max-spool", "2M")
    assert r.code == 2
    assert r.err.splitlines() == [
        "error: <stdin>: more than --max-spool 2M to keep for a second read: an endless stream?",
        f"hint: a log from stdin or a pipe is copied to $TMPDIR ({scratch}) to be read twice: "
        "save it to a file and give its name, or raise --max-spool",
    ]
    assert list(scratch.iterdir()) == []
    assert not out.exists()


def test_a_log_on_stdin_longer_than_the_room_in_tmpdir_is_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without --max-spool, the copy stops short of filling $TMPDIR: at its free space less a
    margin (a tenth of it here)."""
    import shutil
    import sys
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(shutil, "disk_usage", lambda path: shutil._ntuple_diskusage(100 << 20, 97 << 20, 3 << 20))
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BufferedReader(_EndlessLog())))
    r = run(capsys, "segment", "-")
    assert r.code == 2
    assert r.err.splitlines()[0] == (
        "error: <stdin>: more than 2.7M to keep for a second read "
        "(--max-spool's default: the free space in $TMPDIR less a margin): an endless stream?"
    )
    assert r.err.splitlines()[1].endswith(
        "save it to a file and give its name, or set TMPDIR to a folder with more room"
    )
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_the_copy_of_a_log_a_killed_run_left_is_removed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import os
    import tempfile

    from tests.conftest import feed_stdin

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    stale = tmp_path / "tumblecal-4194305-0123abcd.csv"  # a pid above Linux's largest
    live = tmp_path / f"tumblecal-{os.getppid()}-0123abcd.csv"
    other = tmp_path / "tumblecal-notes.csv"
    for path in (stale, live, other):
        path.write_text("t,x,y,z\n")
    feed_stdin(monkeypatch, (SAMPLE / "imucal" / "session_every4th.csv").read_bytes())
    r = run(capsys, "segment", "-", "--rate", "25.6")
    assert r.code == 0, r.err
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([live.name, other.name])


@pytest.mark.parametrize(
    ("given", "error"),
    [
        ("lots", "--max-spool takes a size: bytes, or with K, M, G or T (500M, 4G), got 'lots'"),
        ("0", "--max-spool must be more than 0 bytes, got 0"),
    ],
)
def test_max_spool_that_is_not_a_size_is_exit_2(given: str, error: str, capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "segment", str(SAMPLE / "x.csv"), "--max-spool", given)
    assert r.code == 2
    assert r.err.splitlines() == [f"error: {error}"]


def test_a_name_with_a_line_break_cannot_split_an_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal).code == 0
    doc = json.loads(cal.read_text())
    doc["columns"] = ["a\nb", "a\nb", "z\u2028"]
    cal.write_text(json.dumps(doc))
    r = run(capsys, "show", cal)
    assert r.code == 2
    assert r.err.splitlines() == [
        f"error: {cal}: field 'columns' must name three different columns, got a\\nb, a\\nb, z\\u2028"
    ]


# -- the corpus: every hostile file through every command that reads its kind ---------------------

HOSTILE = Path(__file__).resolve().parent / "data" / "hostile"
CALIBRATIONS = [
    "alias_bomb.yaml",
    "deep_nesting.json",
    "int_5000_digits.json",
    "int_beyond_float.json",
    "columns_with_line_breaks.json",
    "int_5000_digits.yaml",
    "yaml_binary_serial.yaml",
    "yaml_set_field.yaml",
    "yaml_timestamp_field.yaml",
    "yaml_omap_field.yaml",
    "yaml_duplicate_offset.yaml",
    "yaml_sexagesimal_reference.yaml",
    "json_lone_surrogates.json",
    "json_duplicate_offset.json",
]
CASES = [
    *(
        pytest.param(name, command, id=f"{name}-{command[0]}")
        for name in CALIBRATIONS
        for command in (
            ["show", "{f}"],
            ["show", "--json", "{f}"],
            ["check", "{f}", "--max-offset", "1"],
            ["export", "{f}", "--format", "c-header", "-o", "{out}"],
            ["apply", "--cal", "{f}", str(SAMPLE / "capture.csv"), "-o", "{out}"],
            ["verify", "--cal", "{f}", str(SAMPLE / "x.csv")],
        )
    ),
    pytest.param(
        "calibrates_the_time_column.json", ["apply", "--cal", "{f}", str(SAMPLE / "capture.csv"), "-o", "{out}"]
    ),
    pytest.param("ros_duplicate_columns.yaml", ["import", "{f}", "-o", "{out}"]),
    pytest.param("limits_alias.yaml", ["check", "{cal}", "--limits", "{f}"]),
    pytest.param("limits_alias.yaml", ["solve", "--poses", *POSES_3, "--limits", "{f}", "-o", "{out}"]),
    *(
        pytest.param(name, command, id=f"{name}-{command[0]}")
        for name in ("capture_1e200.csv", "capture_1e308_constant.csv")
        for command in (
            ["solve", "--poses", "{f}", "--reference", "1e308", "-o", "{out}"],
            ["verify", "--cal", "{cal}", "{f}"],
        )
    ),
    pytest.param("log_time_steps_1e-300.csv", ["segment", "{f}"]),
    pytest.param("log_time_steps_1e-300.csv", ["solve", "--log", "{f}", "-o", "{out}"]),
]


@pytest.mark.parametrize(("name", "command"), CASES)
def test_hostile_file(name: str, command: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """One error line (and a hint), exit 2, no traceback, an existing output left byte for byte,
    no temporary file, in bounded time."""
    import time

    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal).code == 0
    out = precious(tmp_path / "out.json")
    before = sorted(p.name for p in tmp_path.iterdir())
    args = [
        a.replace("{f}", str(HOSTILE / name)).replace("{out}", str(out)).replace("{cal}", str(cal)) for a in command
    ]
    started = time.monotonic()
    r = run(capsys, *args)
    assert time.monotonic() - started < 10
    assert r.code == 2, r.err
    lines = r.err.splitlines()
    assert [ln for ln in lines if not ln.startswith("hint:")] == [lines[0]], r.err
    assert lines[0].startswith("error: ")
    assert "internal error" not in r.err
    assert "Traceback" not in r.err
    assert out.read_bytes() == precious(tmp_path / "again.json").read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir() if p.name != "again.json") == before


def test_a_cr_only_capture_keeps_its_line_ends_in_apply(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Line ends of a lone CR (old Macs): the header's and the rows' the same (before: a CR after
    the header, LF after each row)."""
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal).code == 0
    capture = tmp_path / "cr.csv"
    capture.write_bytes(b"t,ax,ay,az\r0.00,0.1,0.2,0.9\r0.01,0.1,0.2,0.9\r")
    out = tmp_path / "out.csv"
    assert run(capsys, "apply", "--cal", cal, capture, "-o", out).code == 0
    data = out.read_bytes()
    assert b"\n" not in data
    assert data.count(b"\r") == 3


def test_a_first_line_over_a_megabyte_says_so(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capture = tmp_path / "wide.csv"
    capture.write_text("a," * 600_000 + "\n1,2,3\n")
    r = run(capsys, "solve", "--poses", capture, "-o", tmp_path / "cal.json")
    assert r.code == 2
    assert (
        r.err.splitlines()[0] == f"error: {capture}: the first line is longer than 1 MB: not a capture's header or data"
    )


def test_a_huge_cell_is_quoted_short(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capture = tmp_path / "long.csv"
    capture.write_text("t,ax,ay,az\n1,2,3," + "9" * 2_000_000 + "\n1,2,3,4\n")
    r = run(capsys, "solve", "--poses", capture, "-o", tmp_path / "cal.json")
    assert r.code == 2
    assert r.err.splitlines() == [
        f"error: {capture}: not a finite number: '{'9' * 40}'... (2,000,000 characters) (line 2, column az)"
    ]


def test_a_log_of_readings_beyond_float_range_is_an_input_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """(before: numpy's overflow warnings on stderr, then exit 3 'nothing to calibrate from')"""
    log = tmp_path / "log.csv"
    log.write_text("t,ax,ay,az\n" + "".join(f"{k / 100:.2f},{1e200 * (1 + k % 3 / 100):.4e},0,0\n" for k in range(600)))
    r = run(capsys, "segment", log)
    assert r.code == 2
    assert r.err.splitlines()[0] == (
        f"error: {log}: a reading of 1.02e+200 is beyond what tumblecal computes with (|reading| <= 1e+150)"
    )


def test_a_row_over_a_megabyte_says_so_and_where(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """(before: pyarrow's 'straddling object straddles two block boundaries')"""
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal).code == 0
    rows = [f"{k / 100:.2f},0.1,0.2,0.9" for k in range(100_000)]
    rows[50_000] = "500.00,0.1,0.2," + "9" * (3 << 20)
    capture = tmp_path / "capture.csv"
    capture.write_text("t,ax,ay,az\n" + "\n".join(rows) + "\n")
    r = run(capsys, "apply", "--cal", cal, capture, "-o", tmp_path / "out.csv")
    assert r.code == 2
    assert r.err.splitlines() == [f"error: {capture}: a row longer than 1 MB: not a capture's row (line 50002)"]


@pytest.mark.parametrize("fmt", ["ros-yaml", "imucal-json"])
def test_metadata_never_travels_in_comments_that_import_parses(
    fmt: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A serial written to look like the export's comment (`; reference 9.81; columns t, ay, az`)
    comes back as that serial, and the reference and columns stay the calibration's (before: the
    serial overrode them, and apply then rewrote the time column)."""
    cal = tmp_path / "cal.json"
    serial = "A1; reference 9.81; columns t, ay, az"
    assert run(capsys, "solve", "--poses", *POSES_3, "--serial", serial, "-o", cal).code == 0
    peer, back = tmp_path / "peer.txt", tmp_path / "back.json"
    assert run(capsys, "export", cal, "--format", fmt, "-o", peer).code == 0
    r = run(capsys, "import", peer, "--from", fmt, "-o", back)
    assert r.code == 0, r.err
    doc = json.loads(back.read_text())
    assert doc["unit"]["serial"] == serial
    assert (doc["reference"], doc["columns"]) == (1.0, ["ax", "ay", "az"])
    text = (
        peer.read_text()
        .replace('"reference": 1.0', '"reference": "9.81"')
        .replace('\\"reference\\": 1.0', '\\"reference\\": \\"9.81\\"')
    )
    peer.write_text(text)
    r = run(capsys, "import", peer, "--from", fmt, "-o", tmp_path / "bad.json")
    assert r.code == 2
    assert "reference' must be a" in r.err


# -- found by a stress run: values no sensor has, and output names that are none ------------------

THERMAL = SAMPLE / "thermal"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--reference-temperature", "nan"], "--reference-temperature must be in °C, from -273.15 to 1000, got nan"),
        (["--reference-temperature", "inf"], "--reference-temperature must be in °C, from -273.15 to 1000, got inf"),
        (["--reference-temperature", "25", "--min-swing", "nan"], "--min-swing must be a positive number of °C"),
    ],
)
def test_thermal_option_values_no_sweep_has(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    """LAPACK printed to stdout and 'internal error: LinAlgError' followed (or a ValueError)."""
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "-q", "-p", *POSES_3, "-o", cal).code == 0
    sweeps = [f"+z={THERMAL / 'sweep_up_zp.csv'}", f"-z={THERMAL / 'sweep_down_zn.csv'}"]
    r = run(capsys, "thermal", *sweeps, "--cal", cal, *args, "-o", tmp_path / "t.json")
    assert r.code == 2, r.err
    assert r.out == ""
    assert r.err.splitlines()[0].startswith(f"error: {message}")


def test_a_thermal_sweep_with_a_cell_of_1e308(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Overflow warnings, then 'internal error: StopIteration', the file unnamed."""
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "-q", "-p", *POSES_3, "-o", cal).code == 0
    lines = (THERMAL / "sweep_up_zp.csv").read_text().splitlines()
    lines[1000] = ",".join([*lines[1000].split(",")[:-1], "1e308"])
    broken = tmp_path / "sweep.csv"
    broken.write_text("\n".join(lines) + "\n")
    r = run(capsys, "thermal", f"+z={broken}", f"-z={THERMAL / 'sweep_down_zn.csv'}", "--cal", cal,
            "--reference-temperature", "25", "-o", tmp_path / "t.json")  # fmt: skip
    assert r.code == 2
    assert r.err.splitlines()[0].startswith(f"error: {broken}: a reading of 1e+308 is beyond")


@pytest.mark.parametrize("diagonal", [1e308, 1e-320])
def test_a_calibration_matrix_no_sensor_has(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], diagonal: float
) -> None:
    """export wrote NaN and inf with exit 0; noise divided by zero."""
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "-q", "-p", *POSES_3, "-o", cal).code == 0
    doc = json.loads(cal.read_text())
    doc["matrix"] = [[diagonal if i == j else 0.0 for j in range(3)] for i in range(3)]
    cal.write_text(json.dumps(doc))
    r = run(capsys, "export", cal, "-f", "imucal-json", "-o", tmp_path / "out.json")
    assert r.code == 2
    assert r.err.startswith(
        f"error: {cal}: field 'matrix' has entries of {diagonal:.3g}: no sensor's correction is that"
    )
    assert not (tmp_path / "out.json").exists()


@pytest.mark.parametrize("option", ["--window", "--min-duration", "--trim", "--rate", "--threshold"])
@pytest.mark.parametrize("value", ["inf", "1e308"])
def test_segment_option_values_that_overflow(capsys: pytest.CaptureFixture[str], option: str, value: str) -> None:
    """'internal error: OverflowError: cannot convert float infinity to integer'."""
    if option == "--threshold" and value == "1e308":
        return  # a threshold that keeps everything still is a threshold
    r = run(capsys, "segment", "-q", ROOT / "tests" / "data" / "logs" / "ckexplorer_acc_log.csv", option, value)
    assert r.code == 2
    assert r.err.startswith(f"error: {option} must be ")
    assert "internal error" not in r.err


@pytest.mark.parametrize(
    ("output", "message"),
    [
        ("", "error: -o names no file (an empty name)"),
        ("newdir/", "error: newdir/: names a folder (it ends with '/'): -o takes a file name"),
    ],
)
def test_an_output_name_that_is_no_file_name(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, output: str, message: str
) -> None:
    """The rename at the end failed naming the temporary file: '.../..23972-f_zt2vqi.tmp: No such file'."""
    monkeypatch.chdir(tmp_path)
    r = run(capsys, "solve", "-q", "-p", *POSES_3, "-o", output)
    assert r.code == 2
    assert r.err.splitlines()[0] == message
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
def test_show_onto_a_full_disk_names_stdout() -> None:
    """It said 'error: No space left on device', naming nothing."""
    with open("/dev/full", "wb") as full:
        done = subprocess.run(
            [tumblecal_exe(), "show", str(SAMPLE / "lot" / "SN0001_20261121T090000Z.json")],
            stdout=full,
            stderr=subprocess.PIPE,
            check=False,
        )
    assert done.returncode == 2
    assert done.stderr.decode().splitlines() == ["error: <stdout>: cannot write: No space left on device"]


def test_a_sweep_below_absolute_zero(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """400 °C taken off every temperature was fitted, exit 0."""
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "-q", "-p", *POSES_3, "-o", cal).code == 0
    rows = (THERMAL / "sweep_up_zp.csv").read_text().splitlines()
    cold = tmp_path / "cold.csv"
    cells = [r.split(",") for r in rows[1:]]
    cold.write_text("\n".join([rows[0], *(",".join([c[0], f"{float(c[1]) - 400:.2f}", *c[2:]]) for c in cells)]) + "\n")
    r = run(capsys, "thermal", f"+z={cold}", "--cal", cal, "--reference-temperature", "25", "-o", tmp_path / "t.json")
    assert r.code == 2
    assert r.err.splitlines()[0].startswith(f"error: {cold}: a temperature of -4")
    assert "°C is none a sensor is swept through (-273.15 to 1000)" in r.err


def test_a_pose_map_that_gives_a_label_two_faces(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The last one was kept, and the run went on to exit 3."""
    log = tmp_path / "session.csv"
    log.write_bytes(
        gzip.decompress((ROOT / "tests" / "data" / "logs" / "imucal_annotated_session.csv.gz").read_bytes())
    )
    r = run(capsys, "segment", log, "--pose-column", "part", "--pose-map", "x_p=+x,x_p=-x")
    assert (r.code, r.err.splitlines()[0]) == (2, "error: --pose-map gives label 'x_p' twice: +x and -x")


def test_a_calibration_whose_serial_holds_a_line_break(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """show and report printed it across lines, export wrote it out, import then named --serial."""
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "-q", "-p", *POSES_3, "-o", cal).code == 0
    doc = json.loads(cal.read_text())
    doc["unit"] = {"serial": "A1\r\nSM: [1]"}
    cal.write_text(json.dumps(doc))
    commands: list[list[str | Path]] = [
        ["show", cal],
        ["report", cal],
        ["export", cal, "-f", "ros-yaml", "-o", tmp_path / "r.yaml"],
    ]
    for command in commands:
        r = run(capsys, *command)
        assert r.code == 2
        assert f"error: {cal}: field 'unit.serial' holds a control character: 'A1\\r\\nSM: [1]'" in r.err.splitlines()


def test_a_still_capture_that_never_changes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """noise printed RuntimeWarnings (log of 0) and a bias instability of '0±nan'."""
    capture = tmp_path / "constant.csv"
    capture.write_text("x,y,z\n" + "1,2,3\n" * 5000)
    r = run(capsys, "noise", capture, "--rate", "100")
    assert r.code == 0, r.err
    assert "nan" not in r.err
    assert "bias instability: xyz not determined (the readings do not change: no noise to measure)" in r.err


def test_a_matrix_that_maps_one_axis_onto_another(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A with a 0 on its diagonal (x and y swapped): RuntimeWarnings in show, report and check,
    and check's cross-axis limit passed it (0 / 0 is NaN, and NaN is not over any limit)."""
    cal = tmp_path / "cal.json"
    faces = [SAMPLE / f"{n}.csv" for n in ("x", "xn", "y", "yn", "z", "zn")]
    assert run(capsys, "solve", "-q", "-p", *faces, "-m", "six-pose", "-o", cal).code == 0  # cross-axis terms
    doc = json.loads(cal.read_text())
    doc["matrix"] = [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    cal.write_text(json.dumps(doc))
    limits = tmp_path / "limits.yaml"
    limits.write_text("cross_axis: 0.01\n")
    assert run(capsys, "show", cal).code == 0
    assert run(capsys, "report", cal).code == 0
    r = run(capsys, "check", cal, "--limits", limits)
    assert r.code == 1
    assert "limit.cross.xy: cross-axis term xy is +inf%" in r.err


def test_an_output_that_is_a_symbolic_link_loop(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The link was replaced by a regular file (realpath of a loop is the link itself)."""
    (tmp_path / "a").symlink_to(tmp_path / "b")
    (tmp_path / "b").symlink_to(tmp_path / "a")
    r = run(capsys, "solve", "-q", "-p", *POSES_3, "-o", tmp_path / "a")
    assert r.code == 2
    assert r.err.startswith(f"error: {tmp_path / 'a'}: cannot write: Too many levels of symbolic links")
    assert (tmp_path / "a").is_symlink()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b"]


@pytest.mark.slow
def test_data_for_a_closed_stderr_is_an_error() -> None:
    """-o /dev/stderr with stderr closed (2>&-) dropped the calibration, exit 0."""
    done = subprocess.run(
        ["sh", "-c", f"'{tumblecal_exe()}' solve -q -p {' '.join(map(str, POSES_3))} -o /dev/stderr 2>&-"],
        capture_output=True,
        check=False,
    )
    assert (done.returncode, done.stdout) == (2, b"")


# -- what summary.csv and segments.csv say, and what --resume trusts -------------------------

#: What a spreadsheet takes for the start of a formula: = + - @, a tab or a carriage return, and
#: the full-width = + - @ (some input paths fold them to ASCII).
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r", "\uff1d", "\uff0b", "\uff0d", "\uff20")
PLAIN_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")


def formula_cells(path: Path) -> list[tuple[int, str, str]]:
    """(line, column, cell) of every cell of a CSV file that a spreadsheet would take for a
    formula and that came from an input's text (a plain number, -0.01, is a number; a face, +x,
    is tumblecal's own word, written as it is: issue 42)."""
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    return [
        (n, c, v)
        for n, row in enumerate(rows, 2)
        for c, v in row.items()
        if v.startswith(FORMULA_STARTS) and not PLAIN_NUMBER.fullmatch(v) and not re.fullmatch(r"[+-][xyz]", v)
    ]


def test_formulas_in_summary_csv_inputs_message_and_duplicate_of_are_text(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A manifest cell ``=cmd|calc!A0`` (a file by that name), a missing ``=HYPERLINK(...)``, a
    clean unit's labelled inputs (``+x=x.csv``) and a duplicate's serial: each text cell that a
    spreadsheet would take for a formula is written with a leading ' (before: only serial and
    file were), and --resume reads the summary back as it was written."""
    monkeypatch.chdir(tmp_path)
    shutil.copy(SAMPLE / "x.csv", tmp_path / "=cmd|calc!A0")
    for name in ("x.csv", "y.csv", "z.csv"):
        shutil.copy(SAMPLE / name, tmp_path / name)
    with open("lot.csv", "w", newline="", encoding="utf-8") as f:
        csv.writer(f).writerows(
            [
                ["serial", "first", "second", "third"],
                ["SN1", "=cmd|calc!A0", "y.csv", "z.csv"],
                ["SN2", '=HYPERLINK("http://x")', "y.csv", "z.csv"],
                ["-SN3", "+x=x.csv", "+y=y.csv", "+z=z.csv"],
            ]
        )
    r = run(capsys, "batch", "lot.csv", "--out-dir", "cals", "-q")
    assert r.code == 2, r.err
    summary = tmp_path / "cals" / "summary.csv"
    assert formula_cells(summary) == []
    with open(summary, newline="", encoding="utf-8") as f:
        rows = {row["serial"]: row for row in csv.DictReader(f)}
    assert rows["SN1"]["inputs"] == "'=cmd|calc!A0;y.csv;z.csv"
    assert rows["SN2"]["message"] == '\'=HYPERLINK("http://x"): no such file'
    assert rows["'-SN3"]["inputs"] == "'+x=x.csv;+y=y.csv;+z=z.csv"
    assert rows["SN1"]["duplicate_of"] == "'-SN3"
    assert float(rows["SN1"]["offset_y"]) < 0  # a negative number stays a number
    written = summary.read_bytes()
    r = run(capsys, "batch", "lot.csv", "--out-dir", "cals", "--resume")
    assert r.code == 2, r.err
    assert "resuming: 3 of 3 units already done" in r.err
    assert summary.read_bytes() == written  # read back as written, written again the same


def test_a_formula_in_a_logs_label_column_is_text_in_segments_csv(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """segments.csv (in --out-dir, or on stdout) wrote a label cell ``=1+1`` as it was: a formula
    to a spreadsheet. (The faces, ``+x``, are written as they are: tumblecal's own words.)"""
    from tests.test_segment import POSE_MAP, ROTATION, SIX, log_text, six_poses, synth_log

    src = tmp_path / "labelled.csv"
    src.write_text(log_text(synth_log(six_poses(), seed=5), with_labels=True).replace(f",{ROTATION}\n", ",=1+1\n"))
    out = tmp_path / "poses"
    r = run(capsys, "segment", src, "--pose-column", "part", "--pose-map", POSE_MAP, "-d", out)
    assert r.code == 0, r.err
    index = out / "segments.csv"
    assert formula_cells(index) == []
    with open(index, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert {row["label"] for row in rows if row["status"] == "dropped"} == {"'=1+1"}
    assert [row["face"] for row in rows if row["status"] == "kept"] == list(SIX)
    r = run(capsys, "segment", src, "--pose-column", "part", "--pose-map", POSE_MAP)
    assert r.code == 0, r.err
    assert r.out == index.read_text()


#: The time of the lot the tamperings start from (SOURCE_DATE_EPOCH), as a calibration's name has it.
EPOCH, STAMP = "1700000000", "20231114T221320Z"
#: The summary's columns by name (the rows below: header, A good, B good, C rejected).
COLUMN = {"serial": 0, "status": 1, "verdict": 2, "codes": 3, "file": 4, "method": 5, "offset_x": 6, "offset_y": 7}
COLUMN |= {"gain_z": 11, "gain_se_y": 16}


def cells(*edits: tuple[int, str, str]) -> Callable[[list[list[str]], Path], None]:
    """A tampering that sets cells: (row, column, text)."""

    def edit(rows: list[list[str]], out: Path) -> None:
        for row, column, text in edits:
            rows[row][COLUMN[column]] = text.format(stamp=STAMP)

    return edit


def a_file_linked_out(rows: list[list[str]], out: Path) -> None:
    (out / "A_20991231T000000Z.json").symlink_to("/etc/passwd")
    rows[1][COLUMN["file"]] = "A_20991231T000000Z.json"


def a_file_of_bs(rows: list[list[str]], out: Path) -> None:
    shutil.copy(out / rows[2][COLUMN["file"]], out / "A_20991231T000000Z.json")
    rows[1][COLUMN["file"]] = "A_20991231T000000Z.json"


def a_file_gone(rows: list[list[str]], out: Path) -> None:
    (out / rows[1][COLUMN["file"]]).unlink()


def a_file_not_a_calibration(rows: list[list[str]], out: Path) -> None:
    (out / rows[1][COLUMN["file"]]).write_text("[1, 2]\n")


def a_row_twice(rows: list[list[str]], out: Path) -> None:
    rows.append(list(rows[1]))


def a_code_not_a_code_and_a_row_cut_short(rows: list[list[str]], out: Path) -> None:
    rows[3][COLUMN["codes"]] = "=cmd|calc!A0"
    rows.append(["D", "0", "pa"])


#: Each tampering --resume refuses: (the edit, the error's text, its line and column).
TAMPERED: dict[str, tuple[Callable[[list[list[str]], Path], None], str, int, int]] = {
    "status-99": (cells((1, "status", "99")), "status '99' is not one tumblecal writes (0, 1, 2 or 3)", 2, 2),
    "verdict-banana": (cells((2, "verdict", "banana")), "verdict 'banana' is not status 0's (pass)", 3, 3),
    "verdict-of-another-status": (cells((3, "verdict", "pass")), "verdict 'pass' is not status 3's (rejected)", 4, 3),
    "code-not-a-code": (
        cells((3, "codes", "pose.orientation;rm -rf /")),
        "code 'rm -rf /' is not one tumblecal writes",
        4,
        4,
    ),
    "file-outside-the-folder": (
        cells((1, "file", "../../../../etc/passwd")),
        "file '../../../../etc/passwd' is not a calibration this batch wrote (A_<UTC time>.json in this folder)",
        2,
        5,
    ),
    "file-absolute": (
        cells((1, "file", "/etc/passwd")),
        "file '/etc/passwd' is not a calibration this batch wrote (A_<UTC time>.json in this folder)",
        2,
        5,
    ),
    "file-a-link-out": (
        a_file_linked_out,
        "file 'A_20991231T000000Z.json' is a symbolic link, not a calibration this batch wrote",
        2,
        5,
    ),
    "file-of-another-serial": (a_file_of_bs, "A_20991231T000000Z.json is the calibration of B, not of A", 2, 5),
    "file-gone": (a_file_gone, "file 'A_{stamp}.json' is not in the folder (the unit's calibration is gone)", 2, 5),
    "file-not-a-calibration": (
        a_file_not_a_calibration,
        "A_{stamp}.json: not a calibration file: expected a JSON/YAML object at the top",
        2,
        5,
    ),
    "pass-without-a-file": (
        cells((1, "file", "")),
        "status 0 (pass) names its calibration in 'file': this row names none",
        2,
        5,
    ),
    "rejected-with-a-file": (
        cells((3, "file", "A_{stamp}.json")),
        "status 3 (rejected) has no calibration: this row names A_{stamp}.json",
        4,
        5,
    ),
    "method-not-its-calibrations": (
        cells((1, "method", "six-pose")),
        "method 'six-pose' is not its calibration's (three-pose)",
        2,
        6,
    ),
    "status-not-its-calibrations": (
        cells((1, "status", "1"), (1, "verdict", "fail")),
        "status 1 (fail) is not its calibration's verdict (pass)",
        2,
        2,
    ),
    "code-not-a-code-then-a-row-cut-short": (
        a_code_not_a_code_and_a_row_cut_short,
        "code '=cmd|calc!A0' is not one tumblecal writes",
        4,
        4,
    ),
    "offset-nan": (cells((1, "offset_x", "nan")), "offset_x 'nan' is not a finite number, as a batch writes", 2, 7),
    "gain-inf": (cells((2, "gain_z", "inf")), "gain_z 'inf' is not a finite number, as a batch writes", 3, 12),
    "offset-text": (cells((1, "offset_y", "0x1p3")), "offset_y '0x1p3' is not a number", 2, 8),
    "gain-se-negative": (cells((2, "gain_se_y", "-0.001")), "gain_se_y '-0.001' is a negative 1-sigma", 3, 17),
    "serial-twice": (a_row_twice, "serial A is also on line 2", 5, 1),
    "serial-a-path": (cells((3, "serial", "../C")), "serial '../C' cannot name a unit", 4, 1),
}


@pytest.mark.parametrize("tampering", list(TAMPERED))
def test_batch_resume_refuses_a_summary_row_it_could_not_have_written(
    tampering: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A status 99, a verdict 'banana', a file ../../../../etc/passwd or /etc/passwd (opened),
    a calibration of another serial ...: --resume kept such a row as done and went on, its
    status counted as written. Now exit 2 naming the summary's line and cell, and nothing is
    touched (not even a last row cut short, which a trusted summary loses)."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", EPOCH)
    src = tmp_path / "units"
    for serial, kind in (("A", "good"), ("B", "good"), ("C", "rejected")):
        unit(src, serial, kind)
    out = tmp_path / "cals"
    assert run(capsys, "batch", src, "--out-dir", out, "-q").code == 3
    summary = out / "summary.csv"
    with open(summary, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    edit, message, line, column = TAMPERED[tampering]
    edit(rows, out)
    with open(summary, "w", newline="", encoding="utf-8") as f:
        csv.writer(f, lineterminator="\n").writerows(rows)
    before = snapshot(out)
    r = run(capsys, "batch", src, "--out-dir", out, "--resume")
    assert r.code == 2, r.err
    lines = r.err.splitlines()
    assert lines[0] == f"error: {summary}: {message.format(stamp=STAMP)} (line {line}, column {column})", r.err
    hint = (
        "hint: --resume trusts only what a batch wrote: check that row; delete it and --resume again to redo its unit"
    )
    assert lines[1:] == [hint]
    assert snapshot(out) == before
