"""Numbers in double quotes (``"1.033358"``, as some loggers and spreadsheet exports write every
cell) read as numbers (docs/reference/csv.md): in pose files, logs and apply's input, from the
command line and from Python, with and without a header, through every reader of a capture
(the general one, apply's splicing one, the streaming log reader, stdin)."""

from __future__ import annotations

import io
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import tumblecal_cli as tumblecal
from tests.conftest import IMUCAL, POSES_3, SAMPLE, feed_stdin, run
from tumblecal_cli.io.csv.capture import open_capture
from tumblecal_cli.io.csv.readings import read_log
from tumblecal_cli.io.csv.splice import Splicer
from tumblecal_cli.io.readspec import ReadSpec
from tumblecal_cli.io.rewrite import writer as rewrite

#: The fields of a calibration that depend on the file, not on its numbers.
FILE_FIELDS = ("file", "sha256", "created")


def quote(text: str, columns: set[int] | None = None, *, header: bool = True) -> str:
    """``text`` (a comma-separated capture) with every cell, or those of ``columns``, in double quotes."""
    lines = []
    for k, line in enumerate(text.splitlines(keepends=True)):
        body = line.rstrip("\r\n")
        cells = body.split(",")
        if header or k > 0:
            cells = [f'"{c}"' if columns is None or j in columns else c for j, c in enumerate(cells)]
        lines.append(",".join(cells) + line[len(body) :])
    return "".join(lines)


def quoted_copy(source: Path, target: Path, columns: set[int] | None = None) -> Path:
    """``source`` with every cell in quotes, or the data cells of ``columns`` (the header as it was)."""
    target.write_text(quote(source.read_text(), columns, header=columns is None), encoding="utf-8")
    return target


def numbers_of(cal: tumblecal.Calibration) -> dict[str, object]:
    """A calibration's document without what names its files."""
    doc = json.loads(json.dumps(cal.to_dict()))
    doc.pop("created", None)
    for pose in doc.get("poses", []):
        for key in FILE_FIELDS:
            pose.pop(key, None)
    seg = doc.get("segmentation") or {}
    for key in ("log", "file", "sha256"):
        seg.pop(key, None)
    return dict(doc)


@pytest.mark.slow
def test_quoted_pose_files_solve_as_the_plain_ones(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    quoted = [quoted_copy(Path(p), tmp_path / Path(p).name) for p in POSES_3]
    assert quoted[0].read_text().splitlines()[1] == '"0.000","1.033358","-0.032690","0.047851"'
    plain_out, quoted_out = tmp_path / "plain.json", tmp_path / "quoted.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", plain_out).code == 0
    r = run(capsys, "solve", "--poses", *quoted, "-o", quoted_out)
    assert r.code == 0, r.err
    assert "not a number" not in r.err
    plain, back = tumblecal.load(plain_out), tumblecal.load(quoted_out)
    assert numbers_of(back) == numbers_of(plain)
    solved = tumblecal.solve([str(p) for p in quoted])  # and from Python
    assert solved.calibration is not None
    assert numbers_of(solved.calibration) == numbers_of(plain)


def test_a_headerless_file_of_quoted_cells(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """No header to tell the numbers from names: a row of quoted numbers is still data."""
    files = []
    for p in POSES_3:
        rows = Path(p).read_text().splitlines()[1:]
        text = "".join(",".join(f'"{c}"' for c in row.split(",")[1:]) + "\n" for row in rows)
        files.append(tmp_path / Path(p).name)
        files[-1].write_text(text)
    with open_capture(str(files[0])) as cap:
        assert not cap.layout.has_header
        assert cap.layout.names == ["x", "y", "z"]
    assert run(capsys, "solve", "--poses", *files, "-o", tmp_path / "q.json").code == 0
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", tmp_path / "p.json").code == 0
    back, plain = tumblecal.load(tmp_path / "q.json"), tumblecal.load(tmp_path / "p.json")
    np.testing.assert_array_equal(back.offset, plain.offset)
    np.testing.assert_array_equal(back.matrix, plain.matrix)


@pytest.mark.slow
def test_a_quoted_log_solves_and_segments_as_the_plain_one(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """imucal's Ferraris session (real, m/s^2), every cell quoted: the same blocks, the same calibration."""
    plain = IMUCAL / "session_every4th.csv"
    quoted = quoted_copy(plain, tmp_path / "session.csv")
    args = ["--rate", "25.6", "--reference", "9.81"]
    assert run(capsys, "solve", "--log", plain, *args, "-o", tmp_path / "p.json").code == 0
    r = run(capsys, "solve", "--log", quoted, *args, "-o", tmp_path / "q.json")
    assert r.code == 0, r.err
    assert numbers_of(tumblecal.load(tmp_path / "q.json")) == numbers_of(tumblecal.load(tmp_path / "p.json"))
    by_api = tumblecal.solve_log(quoted, rate=25.6, reference=9.81)
    assert by_api.calibration is not None
    assert numbers_of(by_api.calibration) == numbers_of(tumblecal.load(tmp_path / "p.json"))
    plain_index = tumblecal.segment(str(plain), rate=25.6).table()
    quoted_index = tumblecal.segment(str(quoted), rate=25.6).table()
    pd.testing.assert_frame_equal(quoted_index, plain_index)


def test_a_quoted_label_column_reads_its_labels(tmp_path: Path) -> None:
    text = "label,ax,ay,az\n" + "".join(f"x_p,1.0{k % 3},0.0{k % 5},0.0{k % 7}\n" for k in range(20))
    path = tmp_path / "labelled.csv"
    path.write_text(quote(text))
    log = read_log(str(path), ReadSpec(), label_column="label", use_time=False)
    assert set(log.labels or []) == {"x_p"}
    assert log.values[0].tolist() == [1.0, 0.0, 0.0]


@pytest.mark.parametrize("which", ["sensor cells", "every cell"])
def test_apply_corrects_quoted_numbers(which: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Sensor cells in quotes: the output is the plain file's, byte for byte. Every cell in
    quotes: the same corrected numbers; the other cells (and the header) keep their quotes, as
    apply copies every byte but the sensor cells' (docs/commands/apply.md)."""
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal).code == 0
    source = SAMPLE / "capture.csv"
    quoted = quoted_copy(source, tmp_path / "capture.csv", {1, 2, 3} if which == "sensor cells" else None)
    assert run(capsys, "apply", "--cal", cal, source, "-o", tmp_path / "plain.csv").code == 0
    r = run(capsys, "apply", "--cal", cal, quoted, "-o", tmp_path / "quoted.csv")
    assert r.code == 0, r.err
    plain_out, quoted_out = (tmp_path / "plain.csv").read_bytes(), (tmp_path / "quoted.csv").read_bytes()
    if which == "sensor cells":
        assert quoted_out == plain_out
    else:
        plain_rows = [ln.split(",") for ln in plain_out.decode().splitlines()]
        quoted_rows = [ln.split(",") for ln in quoted_out.decode().splitlines()]
        assert [r[1:] for r in quoted_rows[1:]] == [r[1:] for r in plain_rows[1:]]
        assert [r[0] for r in quoted_rows] == [f'"{r[0]}"' for r in plain_rows]
    by_api = tumblecal.correct(quoted, cal, output=tmp_path / "api.csv")
    assert by_api.rows == 3000
    assert (tmp_path / "api.csv").read_bytes() == quoted_out


def test_apply_from_stdin_corrects_quoted_numbers(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal).code == 0
    quoted = quoted_copy(SAMPLE / "capture.csv", tmp_path / "capture.csv")
    assert run(capsys, "apply", "--cal", cal, quoted, "-o", tmp_path / "file.csv").code == 0
    feed_stdin(monkeypatch, quoted.read_bytes())
    r = run(capsys, "apply", "--cal", cal, "-o", tmp_path / "stdin.csv")
    assert r.code == 0, r.err
    assert (tmp_path / "stdin.csv").read_bytes() == (tmp_path / "file.csv").read_bytes()


#: Blocks of 16 KiB (the ``small_blocks`` fixture): a small file is many blocks.
BLOCK = 1 << 14


@pytest.mark.parametrize("spliced", [True, False], ids=["spliced", "general"])
@pytest.mark.usefixtures("small_blocks")
def test_both_of_apply_s_paths_write_the_same_bytes(spliced: bool, tmp_path: Path) -> None:
    """A file of several blocks, every cell quoted, a quoted empty row among them: the splicing
    path (io.csv.splice) and the general one (pyarrow's reader and writer) agree byte for byte."""
    rng = np.random.default_rng(5)
    rows = [
        f'"{k * 0.005:.3f}","{a:.6f}","{b:.6f}","{c:.6f}"\n' for k, (a, b, c) in enumerate(rng.normal(0, 1, (6000, 3)))
    ]
    rows[1000] = '"5.000","","",""\n'
    path = tmp_path / "capture.csv"
    path.write_text('"t","ax","ay","az"\n' + "".join(rows))
    out = io.BytesIO()
    with open_capture(str(path)) as cap:
        assert rewrite.correct_stream(cap, out, lambda v: 2.0 * v, splice=spliced) == 6000
    lines = out.getvalue().decode().splitlines()
    assert lines[0] == '"t","ax","ay","az"'
    assert lines[1001] == '"5.000",,,'
    first = lines[1].split(",")
    assert first[0] == '"0.000"'
    assert float(first[1]) == pytest.approx(2 * float(rows[0].split(",")[1].strip('"')), rel=1e-15)
    other = io.BytesIO()
    with open_capture(str(path)) as cap:
        rewrite.correct_stream(cap, other, lambda v: 2.0 * v, splice=not spliced)
    assert other.getvalue() == out.getvalue()


def test_the_splicing_path_takes_quoted_numbers() -> None:
    """apply's fast path corrects a block of quoted numbers itself (the general path is 10x slower)."""
    splicer = Splicer(4, ",", "\n", ".", [((1, 2, 3), lambda v: 2.0 * v)])
    done = splicer.block(b'"0.0","1.5","2","-3e-1"\n"0.1",1,2,3\n')
    assert done is not None
    assert bytes(done[0]) == b'"0.0",3,4,-0.6\n"0.1",2,4,6\n'


@pytest.mark.parametrize(
    ("cell", "said"),
    [('"abc"', "not a number: '\"abc\"'"), ('"1.5', "not a number: '\"1.5'")],
    ids=["quoted-text", "unbalanced"],
)
def test_a_quoted_cell_that_is_not_a_number_is_named(
    cell: str, said: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "pose.csv"
    path.write_text(f'ax,ay,az\n"1.0","0.0","0.0"\n"1.0",{cell},"0.0"\n')
    r = run(capsys, "solve", "--poses", path)
    assert r.code == 2
    assert re.search(rf"{re.escape(str(path))}: {re.escape(said)} \(line 3, column ay\)", r.err), r.err
