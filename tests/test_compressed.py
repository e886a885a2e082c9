"""Compressed captures (docs/reference/csv.md): gzip, bzip2, xz and zstd files read by every
command as the plain file is (known by their first bytes, whatever their names); ``apply -o``
writes compressed when the name ends so; a corrupt one is one error line naming the file."""

from __future__ import annotations

import bz2
import gzip
import hashlib
import lzma
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pytest

import tumblecal_cli as tumblecal
from tests.conftest import POSES_3, SAMPLE, assert_one_error, assert_untouched, feed_stdin, precious, run

DATA = Path(__file__).resolve().parent / "data"
STILL = DATA / "xsens_acc_still.txt"  # a real still capture: whitespace-separated, headerless
ANNOTATED = DATA / "logs" / "imucal_annotated_session.csv.gz"  # a real log, gzip-compressed


def _zstd(data: bytes) -> bytes:
    out = pa.BufferOutputStream()
    with pa.CompressedOutputStream(out, "zstd") as f:
        f.write(data)
    return bytes(out.getvalue().to_pybytes())


def _unzstd(data: bytes) -> bytes:
    return bytes(pa.CompressedInputStream(pa.BufferReader(data), "zstd").read())


#: Each format: its suffix, how to compress bytes, and how to decompress them.
FORMATS: dict[str, tuple[str, Callable[[bytes], bytes], Callable[[bytes], bytes]]] = {
    "gzip": (".gz", gzip.compress, gzip.decompress),
    "bzip2": (".bz2", bz2.compress, bz2.decompress),
    "xz": (".xz", lzma.compress, lzma.decompress),
    "zstd": (".zst", _zstd, _unzstd),
}


def packed(source: Path, folder: Path, kind: str, name: str | None = None) -> Path:
    """``source`` compressed by ``kind`` into ``folder``, named ``name`` (else its name and the suffix)."""
    suffix, pack, _ = FORMATS[kind]
    target = folder / (name or source.name + suffix)
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_bytes(pack(source.read_bytes()))
    return target


@pytest.fixture(scope="module")
def plain_cal(tmp_path_factory: pytest.TempPathFactory) -> Path:
    cal = tmp_path_factory.mktemp("cal") / "cal.json"
    solved = tumblecal.solve(POSES_3)
    assert solved.calibration is not None
    solved.calibration.save(cal)
    return cal


@pytest.mark.parametrize("kind", list(FORMATS))
def test_solve_reads_compressed_poses(
    kind: str, plain_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    files = [packed(Path(p), tmp_path, kind) for p in POSES_3]
    r = run(capsys, "solve", "--poses", *files, "-o", tmp_path / "cal.json")
    assert r.code == 0, r.err
    plain, back = tumblecal.load(plain_cal), tumblecal.load(tmp_path / "cal.json")
    np.testing.assert_array_equal(back.offset, plain.offset)
    np.testing.assert_array_equal(back.matrix, plain.matrix)
    assert [p.file for p in back.poses] == [str(f) for f in files]
    assert back.poses[0].sha256 == hashlib.sha256(files[0].read_bytes()).hexdigest()  # the file's bytes
    solved = tumblecal.solve([str(f) for f in files])
    assert solved.calibration is not None
    np.testing.assert_array_equal(solved.calibration.matrix, plain.matrix)


@pytest.mark.parametrize("kind", list(FORMATS))
def test_apply_reads_compressed_captures(
    kind: str, plain_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    capture = packed(SAMPLE / "capture.csv", tmp_path, kind)
    assert run(capsys, "apply", "--cal", plain_cal, SAMPLE / "capture.csv", "-o", tmp_path / "plain.csv").code == 0
    r = run(capsys, "apply", "--cal", plain_cal, capture, "-o", tmp_path / "out.csv")
    assert r.code == 0, r.err
    assert (tmp_path / "out.csv").read_bytes() == (tmp_path / "plain.csv").read_bytes()
    assert tumblecal.correct(capture, plain_cal, output=tmp_path / "api.csv").rows == 3000
    assert (tmp_path / "api.csv").read_bytes() == (tmp_path / "plain.csv").read_bytes()


@pytest.mark.slow
@pytest.mark.parametrize("kind", list(FORMATS))
def test_noise_reads_compressed_captures(kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plain = tumblecal.noise(STILL, no_header=True)
    capture = packed(STILL, tmp_path, kind)
    back = tumblecal.noise(capture, no_header=True)
    assert (back.rate, back.samples) == (plain.rate, plain.samples)
    np.testing.assert_array_equal(back.curve.adev, plain.curve.adev)
    r = run(capsys, "noise", capture, "--no-header")
    assert r.code == 0, r.err
    assert f"{capture.name}: 5000 samples at 100 Hz" in r.err


@pytest.mark.slow
def test_segment_and_solve_log_read_a_compressed_log(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """imucal's annotated session as it is stored here (gzip) and decompressed: the same blocks,
    the same block files, the same calibration."""
    plain = tmp_path / "session.csv"
    plain.write_bytes(gzip.decompress(ANNOTATED.read_bytes()))
    for source, out in ((ANNOTATED, "from_gz"), (plain, "from_csv")):
        r = run(capsys, "segment", source, "--rate", "204.8", "--out-dir", tmp_path / out)
        assert r.code == 0, r.err
    names = sorted(p.name for p in (tmp_path / "from_csv").iterdir())
    assert names == sorted(p.name for p in (tmp_path / "from_gz").iterdir())
    for name in names:
        assert (tmp_path / "from_gz" / name).read_bytes() == (tmp_path / "from_csv" / name).read_bytes()
    from_gz = tumblecal.solve_log(ANNOTATED, rate=204.8, reference=2048.0)
    from_csv = tumblecal.solve_log(plain, rate=204.8, reference=2048.0)
    assert from_gz.calibration is not None
    assert from_csv.calibration is not None
    np.testing.assert_array_equal(from_gz.calibration.matrix, from_csv.calibration.matrix)


@pytest.mark.parametrize("kind", list(FORMATS))
def test_apply_writes_compressed_when_the_name_ends_so(
    kind: str, plain_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    suffix, _, unpack = FORMATS[kind]
    out = tmp_path / f"corrected.csv{suffix}"
    assert run(capsys, "apply", "--cal", plain_cal, SAMPLE / "capture.csv", "-o", tmp_path / "plain.csv").code == 0
    r = run(capsys, "apply", "--cal", plain_cal, SAMPLE / "capture.csv", "-o", out)
    assert r.code == 0, r.err
    assert unpack(out.read_bytes()) == (tmp_path / "plain.csv").read_bytes()
    pd.testing.assert_frame_equal(tumblecal.read_capture(out), tumblecal.read_capture(tmp_path / "plain.csv"))
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temporary file left


def test_a_gzip_output_is_the_same_bytes_run_after_run(plain_cal: Path, tmp_path: Path) -> None:
    """No time stamp in it (a station compares outputs); the name inside is the output's."""
    a, b = tmp_path / "a" / "out.csv.gz", tmp_path / "b" / "out.csv.gz"
    for out in (a, b):
        out.parent.mkdir()
        tumblecal.correct(SAMPLE / "capture.csv", plain_cal, output=out)
    assert a.read_bytes() == b.read_bytes()
    with gzip.open(a) as f:
        assert f.read(10) == b"t,ax,ay,az"
    assert b"out.csv\x00" in a.read_bytes()[:40]  # gunzip -N restores it as out.csv


def test_a_compressed_capture_from_stdin(
    plain_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    assert run(capsys, "apply", "--cal", plain_cal, SAMPLE / "capture.csv", "-o", tmp_path / "plain.csv").code == 0
    data = (SAMPLE / "capture.csv").read_bytes()
    for kind in FORMATS:
        feed_stdin(monkeypatch, FORMATS[kind][1](data))
        r = run(capsys, "apply", "--cal", plain_cal, "-o", tmp_path / "out.csv")
        assert r.code == 0, r.err
        assert (tmp_path / "out.csv").read_bytes() == (tmp_path / "plain.csv").read_bytes()
    packed_bytes = gzip.compress((SAMPLE / "x.csv").read_bytes())
    feed_stdin(monkeypatch, packed_bytes)
    solved = tumblecal.solve(["-"], up="+x")
    assert solved.calibration is not None
    assert solved.calibration.poses[0].sha256 == hashlib.sha256(packed_bytes).hexdigest()


def test_the_first_bytes_say_what_a_file_is_not_its_name(
    plain_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """gzip data named .csv reads as the CSV inside; plain text named .csv.gz reads as text."""
    assert run(capsys, "apply", "--cal", plain_cal, SAMPLE / "capture.csv", "-o", tmp_path / "plain.csv").code == 0
    misnamed = packed(SAMPLE / "capture.csv", tmp_path, "gzip", name="capture.csv")
    text_gz = tmp_path / "text.csv.gz"
    shutil.copy(SAMPLE / "capture.csv", text_gz)
    for source in (misnamed, text_gz):
        r = run(capsys, "apply", "--cal", plain_cal, source, "-o", tmp_path / "out.csv")
        assert r.code == 0, r.err
        assert (tmp_path / "out.csv").read_bytes() == (tmp_path / "plain.csv").read_bytes()


def _truncated(data: bytes) -> bytes:
    return data[: len(data) // 2]


def _corrupt(data: bytes) -> bytes:
    return data[:200] + bytes(300) + data[500:]


@pytest.mark.parametrize(
    ("damage", "said"),
    [(_truncated, "the gzip data ends early (a file cut short?)"), (_corrupt, "not valid gzip data: ")],
    ids=["truncated", "corrupt"],
)
@pytest.mark.parametrize("command", ["solve", "apply", "noise"])
def test_a_damaged_gzip_is_one_error_naming_the_file(
    damage: Callable[[bytes], bytes],
    said: str,
    command: str,
    plain_cal: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    bad = tmp_path / "capture.csv.gz"
    bad.write_bytes(damage(gzip.compress((SAMPLE / "capture.csv").read_bytes())))
    out = precious(tmp_path / "out.json")
    commands: dict[str, list[str | Path]] = {
        "solve": ["solve", "--poses", bad, "-o", out],
        "apply": ["apply", "--cal", plain_cal, bad, "-o", out],
        "noise": ["noise", bad, "--rate", "100", "--kalibr", out, "--cal", plain_cal],
    }
    args = commands[command]
    r = run(capsys, *args)
    lines = [ln for ln in r.err.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1, r.err
    assert lines[0].startswith(f"error: {bad}: {said}")
    assert_one_error(r, lines[0].removeprefix("error: "), hint="gunzip -t")
    assert_untouched(out)


def test_a_bad_cell_in_a_compressed_file_names_its_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rows = (SAMPLE / "x.csv").read_text().splitlines(keepends=True)
    rows[700] = "7.990,1.0,oops,0.0\n"
    bad = tmp_path / "x.csv.xz"
    bad.write_bytes(lzma.compress("".join(rows).encode()))
    assert_one_error(run(capsys, "solve", "--poses", bad), f"{bad}: not a number: 'oops' (line 701, column ay)")


@pytest.mark.parametrize(
    ("name", "content", "hint"),
    [
        ("capture.csv.gz", b"\x00\x01binary\x00" * 10, "it is named like gzip data but does not start like it"),
        ("capture.zip", b"PK\x03\x04\x14\x00\x00\x00" + bytes(40), "it is a zip archive: extract the CSV first"),
        ("capture.bin", bytes(64), "gzip, bzip2, xz and zstd captures are read as they are"),
    ],
)
def test_binary_data_says_what_it_looks_like(
    name: str, content: bytes, hint: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / name
    path.write_bytes(content)
    assert_one_error(run(capsys, "solve", "--poses", path), f"{path}: binary data, not a CSV text file", hint=hint)
