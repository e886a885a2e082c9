"""Capture reading (docs/reference/csv.md): layout sniffing, column detection, streaming.

Unit tests of ``capture.open_capture`` / ``readings.read_samples``; the CLI tests check the
same rules end to end.
"""

from __future__ import annotations

import hashlib
import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from tests.conftest import feed_stdin, write
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.csv import capture, sniff
from tumblecal_cli.io.csv.capture import open_capture
from tumblecal_cli.io.csv.readings import read_log, read_samples
from tumblecal_cli.io.readspec import ReadSpec
from tumblecal_cli.io.rewrite import writer as rewrite

FloatArray = NDArray[np.float64]

DATA = Path(__file__).resolve().parent / "data"
NCSU = DATA / "ncsu_xplus_head.csv"
XSENS = DATA / "xsens_acc_head.txt"


def one_row(header: str) -> str:
    """A header and one row of numbers, one per column."""
    n = len(header.split(","))
    return header + "\n" + ",".join(str(i + 1) for i in range(n)) + "\n"


def picked(path: str, **kwargs: object) -> tuple[list[str], str | None]:
    """(sensor column names, time column name) that open_capture decides."""
    with open_capture(path, ReadSpec(**kwargs)) as cap:  # type: ignore[arg-type]
        lay = cap.layout
        return lay.sensor_names, None if lay.time is None else lay.names[lay.time]


# -- column detection ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("header", "sensor", "expected", "time"),
    [
        ("x,y,z", "accelerometer", ["x", "y", "z"], None),
        ("t,x,y,z", "accelerometer", ["x", "y", "z"], "t"),
        ("t,ax,ay,az", "accelerometer", ["ax", "ay", "az"], "t"),
        ("Time,AX,AY,AZ", "accelerometer", ["AX", "AY", "AZ"], "Time"),
        ("time,acc_x,acc_y,acc_z", "accelerometer", ["acc_x", "acc_y", "acc_z"], "time"),
        ("timestamp,accX,accY,accZ", "accelerometer", ["accX", "accY", "accZ"], "timestamp"),
        (
            "ts,scaledAccelX,scaledAccelY,scaledAccelZ",
            "accelerometer",
            ["scaledAccelX", "scaledAccelY", "scaledAccelZ"],
            "ts",
        ),
        ("time_s,x_g,y_g,z_g", "accelerometer", ["x_g", "y_g", "z_g"], "time_s"),
        ("t,mag_x,mag_y,mag_z", "magnetometer", ["mag_x", "mag_y", "mag_z"], "t"),
        ("t,gyr_x,gyr_y,gyr_z", "gyroscope", ["gyr_x", "gyr_y", "gyr_z"], "t"),
        ("t,gyro_x,gyro_y,gyro_z", "gyroscope", ["gyro_x", "gyro_y", "gyro_z"], "t"),
        # the order of the columns in the file does not matter, x, y, z come out in order
        ("az,t,ay,ax", "accelerometer", ["ax", "ay", "az"], "t"),
    ],
)
def test_one_triplet(header: str, sensor: str, expected: list[str], time: str | None, tmp_path: Path) -> None:
    assert picked(str(write(tmp_path / "capture.csv", one_row(header))), sensor=sensor) == (expected, time)


NINE = "t,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z,mag_x,mag_y,mag_z,temp"


@pytest.mark.parametrize(
    ("header", "sensor", "expected"),
    [
        (NINE, "accelerometer", ["acc_x", "acc_y", "acc_z"]),
        (NINE, "gyroscope", ["gyr_x", "gyr_y", "gyr_z"]),
        (NINE, "magnetometer", ["mag_x", "mag_y", "mag_z"]),
        ("t,ax,ay,az,gx,gy,gz,mx,my,mz", "accelerometer", ["ax", "ay", "az"]),
        ("t,ax,ay,az,gx,gy,gz,mx,my,mz", "gyroscope", ["gx", "gy", "gz"]),
        ("t,ax,ay,az,gx,gy,gz,mx,my,mz", "magnetometer", ["mx", "my", "mz"]),
        # an unlabelled triplet is the one meant when the sensor's own family is not there
        ("t,x,y,z,gyr_x,gyr_y,gyr_z", "accelerometer", ["x", "y", "z"]),
        ("t,x,y,z,gyr_x,gyr_y,gyr_z", "gyroscope", ["gyr_x", "gyr_y", "gyr_z"]),
        # the real imucal header
        ("part,samples,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z", "accelerometer", ["acc_x", "acc_y", "acc_z"]),
        ("part,samples,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z", "gyroscope", ["gyr_x", "gyr_y", "gyr_z"]),
    ],
)
def test_sensor_picks_the_family(header: str, sensor: str, expected: list[str], tmp_path: Path) -> None:
    assert picked(str(write(tmp_path / "capture.csv", one_row(header))), sensor=sensor)[0] == expected


def test_ambiguous_triplets_list_the_headers(tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", one_row("t,x1,y1,z1,x2,y2,z2")))
    with pytest.raises(InputError) as err:
        picked(path)
    assert str(err.value) == f"{path}: several accelerometer triplets could be meant: x1,y1,z1; x2,y2,z2"
    assert err.value.hint is not None
    assert "--columns" in err.value.hint


def test_another_sensors_triplet_is_never_taken(tmp_path: Path) -> None:
    """A file with only gyroscope columns has no accelerometer columns (not: gyr_* as acc)."""
    path = str(write(tmp_path / "capture.csv", one_row("t,gyr_x,gyr_y,gyr_z")))
    with pytest.raises(InputError, match=r"no accelerometer x,y,z columns found \(columns: t, gyr_x, gyr_y, gyr_z\)"):
        picked(path)
    with pytest.raises(InputError, match="no magnetometer x,y,z columns"):
        picked(str(write(tmp_path / "acc.csv", one_row("t,ax,ay,az"))), sensor="magnetometer")


def test_no_triplet(tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", one_row("a,b,c,d")))
    with pytest.raises(InputError) as err:
        picked(path)
    assert str(err.value) == f"{path}: no accelerometer x,y,z columns found (columns: a, b, c, d)"


@pytest.mark.parametrize(
    ("columns", "expected"),
    [
        (["acc2_x", "acc2_y", "acc2_z"], ["acc2_x", "acc2_y", "acc2_z"]),
        (["ACC_Z", "acc_y", "acc_x"], ["acc_z", "acc_y", "acc_x"]),  # any order, any case
        (["4", "5", "6"], ["acc2_x", "acc2_y", "acc2_z"]),  # 0-based indices
        (["acc_y", "acc_x", "6"], ["acc_y", "acc_x", "acc2_z"]),  # mixed
    ],
)
def test_columns_override(columns: list[str], expected: list[str], tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", one_row("t,acc_x,acc_y,acc_z,acc2_x,acc2_y,acc2_z")))
    assert picked(path, columns=columns)[0] == expected


@pytest.mark.parametrize(
    ("columns", "message"),
    [
        (["acc_x", "acc_y"], "--columns needs three columns (x,y,z), got 2"),
        (["acc_x", "acc_y", "nope"], "column 'nope' not found (columns: t, acc_x, acc_y, acc_z)"),
        (["1", "2", "9"], "column '9' not found (columns: t, acc_x, acc_y, acc_z)"),
    ],
)
def test_columns_override_errors(columns: list[str], message: str, tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", one_row("t,acc_x,acc_y,acc_z")))
    with pytest.raises(InputError) as err:
        picked(path, columns=columns)
    assert message in str(err.value)


def test_prefer_is_used_when_all_present(tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", one_row("t,acc_x,acc_y,acc_z,acc2_x,acc2_y,acc2_z")))
    assert picked(path, prefer=["acc2_x", "acc2_y", "acc2_z"])[0] == ["acc2_x", "acc2_y", "acc2_z"]
    # a calibration's columns that are not all there: detection decides (here: ambiguous)
    with pytest.raises(InputError, match="several accelerometer triplets"):
        picked(path, prefer=["ax", "ay", "az"])
    # --columns beats the calibration's columns
    assert picked(path, columns=["1", "2", "3"], prefer=["acc2_x", "acc2_y", "acc2_z"])[0] == [
        "acc_x",
        "acc_y",
        "acc_z",
    ]


# -- headerless files and time columns -------------------------------------------------------


def test_headerless_three_columns(tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", "0.1,0.2,0.9\n0.1,0.2,0.9\n"))
    with open_capture(path) as cap:
        assert cap.layout.has_header is False
        assert cap.layout.names == ["x", "y", "z"]
        assert cap.layout.time is None
        assert cap.layout.head == b""
    s = read_samples(path)
    np.testing.assert_array_equal(s.values, [[0.1, 0.2, 0.9], [0.1, 0.2, 0.9]])


def test_headerless_four_columns_are_t_x_y_z(tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", "0.00,0.1,0.2,0.9\n0.01,0.1,0.2,0.9\n"))
    assert picked(path) == (["x", "y", "z"], "t")


def test_headerless_five_columns_need_columns(tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", "7,0.00,0.1,0.2,0.9\n7,0.01,0.1,0.2,0.9\n"))
    with pytest.raises(InputError, match=r"no accelerometer x,y,z columns found \(columns: 0, 1, 2, 3, 4\)"):
        picked(path)
    assert picked(path, columns=["2", "3", "4"], time_column="1") == (["2", "3", "4"], "1")


def test_no_header_option_reads_the_first_line_as_data(tmp_path: Path) -> None:
    # a first line of numbers is data anyway; --no-header says so explicitly
    path = str(write(tmp_path / "capture.csv", "1,2,3\n4,5,6\n"))
    assert read_samples(path, ReadSpec(no_header=True)).values.tolist() == [[1, 2, 3], [4, 5, 6]]
    assert read_samples(path).values.tolist() == [[1, 2, 3], [4, 5, 6]]


def test_time_column_and_duration(tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", "t,ax,ay,az\n" + "".join(f"{i * 10},0,0,1\n" for i in range(101))))
    assert read_samples(path, ReadSpec(time_unit="s")).duration == pytest.approx(1000.0)
    auto = read_samples(path)  # a step of 10 at a sensor's rate: milliseconds, said in a note
    assert auto.duration == pytest.approx(1.0)
    assert auto.layout.notes == [
        f"{path}: time column 't' read in milliseconds: it advances 10 per sample (100 Hz); "
        "if it is not, give --time-unit"
    ]
    assert read_samples(path, ReadSpec(time_unit="ms")).duration == pytest.approx(1.0)
    assert read_samples(path, ReadSpec(time_unit="us")).duration == pytest.approx(1e-3)


def test_time_column_option(tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", "clock,ax,ay,az\n" + "".join(f"{i},0,0,1\n" for i in range(11))))
    assert read_samples(path).duration is None
    assert read_samples(path, ReadSpec(time_column="clock", time_unit="s")).duration == pytest.approx(10.0)
    with pytest.raises(InputError, match="time column 'tick' not found"):
        read_samples(path, ReadSpec(time_column="tick"))


def test_rate_gives_the_duration_without_a_time_column(tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", "ax,ay,az\n" + "0,0,1\n" * 200))
    assert read_samples(path, ReadSpec(rate=100.0)).duration == pytest.approx(2.0)
    assert read_samples(path).duration is None


def test_a_time_cell_that_is_not_a_number_leaves_the_duration_unknown(tmp_path: Path) -> None:
    for cell in ("", "n/a"):
        path = str(write(tmp_path / "capture.csv", f"t,ax,ay,az\n0,1,2,3\n{cell},1,2,3\n2,1,2,3\n"))
        s = read_samples(path)
        assert s.duration is None
        assert s.values.shape == (3, 3)


# -- delimiters, comments, BOM, CRLF, numbers -----------------------------------------------

EXPECTED = [[0.5, -0.25, 1.0], [1.0, 2.0, 3.0]]


@pytest.mark.parametrize(
    ("text", "delimiter", "eol"),
    [
        pytest.param("t,ax,ay,az\n0,0.5,-0.25,1.0\n1,1,2,3\n", ",", "\n", id="comma"),
        pytest.param("t;ax;ay;az\n0;0.5;-0.25;1.0\n1;1;2;3\n", ";", "\n", id="semicolon"),
        pytest.param("t\tax\tay\taz\n0\t0.5\t-0.25\t1.0\n1\t1\t2\t3\n", "\t", "\n", id="tab"),
        pytest.param("  t   ax   ay   az\n  0  0.5  -0.25  1.0\n  1  1  2  3\n", None, "\n", id="spaces"),
        pytest.param("t,ax,ay,az\r\n0,0.5,-0.25,1.0\r\n1,1,2,3\r\n", ",", "\r\n", id="crlf"),
        pytest.param("\ufefft,ax,ay,az\n0,0.5,-0.25,1.0\n1,1,2,3\n", ",", "\n", id="bom"),
        pytest.param("t,ax,ay,az\n0,+5e-1,-2.5E-1,1\n1,1.,2.0,3\n", ",", "\n", id="number-forms"),
        pytest.param("t,ax,ay,az\n0, 0.5 , -0.25,1.0\n1,1,2,3", ",", "\n", id="padded-no-final-eol"),
        pytest.param(
            "t\tax\tay\taz\tnote\n0\t0.5\t-0.25\t1.0\ta, b, c\n1\t1\t2\t3\tok\n", "\t", "\n", id="tab-with-commas"
        ),
    ],
)
def test_delimiters_and_forms(text: str, delimiter: str | None, eol: str, tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", text))
    with open_capture(path) as cap:
        assert cap.layout.delimiter == delimiter
        assert cap.layout.eol == eol
        assert cap.layout.sensor_names == ["ax", "ay", "az"]
    np.testing.assert_array_equal(read_samples(path).values, EXPECTED)


def test_bom_is_kept_in_the_head(tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", "\ufeff# made by a station\nt,ax,ay,az\n0,0,0,1\n"))
    with open_capture(path) as cap:
        assert cap.layout.head == "\ufeff# made by a station\nt,ax,ay,az\n".encode()
        assert cap.layout.data_line == 3
        assert cap.layout.names == ["t", "ax", "ay", "az"]


def test_comment_lines_anywhere_are_skipped(tmp_path: Path) -> None:
    text = (
        "# preamble\n\n"
        "t,ax,ay,az\n"
        "0,1,2,3\n"
        "# a comment without the delimiter\n"
        "\n"
        "# a comment, with, three, delimiters\n"  # as many fields as the header: still a comment
        "   # an indented, comment, with, commas\n"
        "1,4,5,6\n"
        "2,7,8,9\n"
    )
    path = str(write(tmp_path / "capture.csv", text))
    s = read_samples(path)
    np.testing.assert_array_equal(s.values, [[1, 2, 3], [4, 5, 6], [7, 8, 9]])
    assert s.rows == (0, 2)


def test_error_line_numbers_count_comments_and_blanks(tmp_path: Path) -> None:
    text = "# pre\nt,ax,ay,az\n0,1,2,3\n# one, two, three, four\n\n1,4,x,6\n"
    path = str(write(tmp_path / "capture.csv", text))
    with pytest.raises(InputError) as err:
        read_samples(path)
    assert str(err.value) == f"{path}: not a number: 'x' (line 6, column ay)"


def test_interleaved_rows_with_empty_sensor_cells_are_skipped(tmp_path: Path) -> None:
    text = "t,ax,ay,az,lat\n0,,,,52.1\n1,1,2,3,\n2,,,,52.2\n3,4,5,6,\n4,,,,52.3\n"
    s = read_samples(str(write(tmp_path / "capture.csv", text)), ReadSpec(time_unit="s"))
    np.testing.assert_array_equal(s.values, [[1, 2, 3], [4, 5, 6]])
    assert s.rows == (1, 3)
    assert s.duration == pytest.approx(2.0)  # from the rows used


def test_only_empty_sensor_rows(tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", "t,ax,ay,az,lat\n0,,,,52.1\n1,,,,52.2\n"))
    with pytest.raises(InputError, match="no rows with sensor values"):
        read_samples(path)


@pytest.mark.parametrize(
    ("row", "message"),
    [
        ("1,2,,4", "empty sensor cell in a row whose other sensor cells are filled (line 3, column ay)"),
        ("1,,3,", "empty sensor cell in a row whose other sensor cells are filled (line 3, column ax)"),
        ("1,2,3,four", "not a number: 'four' (line 3, column az)"),
        ("1,0x10,3,4", "not a number: '0x10' (line 3, column ax)"),
        ("1,2,3", "row has 3 fields, the header has 4 (line 3)"),
        ("1,2,3,4,5", "row has 5 fields, the header has 4 (line 3)"),
    ],
)
def test_bad_rows_name_line_and_column(row: str, message: str, tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", f"t,ax,ay,az\n0,1,2,3\n{row}\n2,1,2,3\n"))
    with pytest.raises(InputError) as err:
        read_samples(path)
    assert str(err.value) == f"{path}: {message}"


@pytest.mark.slow
def test_bad_row_in_a_later_block_names_its_line(tmp_path: Path) -> None:
    """Rows are counted across pyarrow's blocks (this file is larger than one block)."""
    n = 200_000
    lines = [f"{i},{i % 7}.125,-{i % 5}.5,{i % 3}.75" for i in range(n)]
    bad = n - 10
    lines[bad] = f"{bad},1,oops,3"
    text = "# comment\nt,ax,ay,az\n" + "\n".join(lines) + "\n"
    assert len(text) > capture.BLOCK_BYTES
    path = str(write(tmp_path / "capture.csv", text))
    with pytest.raises(InputError) as err:
        read_samples(path)
    assert str(err.value) == f"{path}: not a number: 'oops' (line {bad + 3}, column ay)"


def test_integers_and_exponents(tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", "ax,ay,az\n16384,-12,0\n1e3,-1.5E+2,2.5e-3\n"))
    np.testing.assert_array_equal(read_samples(path).values, [[16384, -12, 0], [1000, -150, 0.0025]])


# -- real files ------------------------------------------------------------------------------


def _ncsu_column(name: str) -> list[str]:
    lines = NCSU.read_text().splitlines()
    index = lines[0].split(",").index(name)
    return [ln.split(",")[index] for ln in lines[1:]]


def test_ncsu_microstrain_picks_scaled_accel() -> None:
    """Interleaved raw/estimated packets: scaledAccel* is the accelerometer, not deltaVel*
    (a velocity increment) nor estCompensatedAccel*/estLinearAccel* (the filter's estimates)."""
    s = read_samples(str(NCSU))
    assert s.layout.sensor_names == ["scaledAccelX", "scaledAccelY", "scaledAccelZ"]
    assert s.layout.names[s.layout.time or 0] == "timestamp"
    x = [float(v) for v in _ncsu_column("scaledAccelX") if v]
    assert s.values.shape == (len(x), 3)
    assert len(x) == 132  # the estimated-packet rows leave these cells empty and are skipped
    np.testing.assert_array_equal(s.values[:, 0], x)
    assert 0.99 < s.values[:, 0].mean() < 1.0  # +x up, in g


def test_ncsu_microstrain_duration_in_ns() -> None:
    s = read_samples(str(NCSU), ReadSpec(time_unit="ns"))
    stamps = [int(t) for t, x in zip(_ncsu_column("timestamp"), _ncsu_column("scaledAccelX"), strict=True) if x]
    assert s.duration == pytest.approx((stamps[-1] - stamps[0]) * 1e-9, rel=1e-6)
    assert s.duration is not None
    assert 0.1 < s.duration < 0.2


def test_ncsu_microstrain_gyroscope() -> None:
    s = read_samples(str(NCSU), ReadSpec(sensor="gyroscope"))
    assert s.layout.sensor_names == ["scaledGyroX", "scaledGyroY", "scaledGyroZ"]
    assert s.values.shape == (132, 3)


def test_ncsu_microstrain_columns_can_still_pick_an_estimate() -> None:
    s = read_samples(str(NCSU), ReadSpec(columns=("estLinearAccelX", "estLinearAccelY", "estLinearAccelZ")))
    assert s.values.shape == (199 - 132, 3)


def test_xsens_whitespace_file() -> None:
    """imu_tk's format: whitespace-aligned, headerless, t x y z in raw counts."""
    with open_capture(str(XSENS)) as cap:
        lay = cap.layout
        assert lay.delimiter is None
        assert lay.has_header is False
        assert lay.names == ["t", "x", "y", "z"]
        assert lay.time == 0
    s = read_samples(str(XSENS))
    expected = np.loadtxt(XSENS)
    assert s.values.shape == (300, 3)
    np.testing.assert_array_equal(s.values, expected[:, 1:])
    assert np.all((s.values > 30000) & (s.values < 40000))
    assert s.duration == pytest.approx(expected[-1, 0] - expected[0, 0])


@pytest.mark.slow
def test_large_whitespace_file_streams_across_chunks(tmp_path: Path) -> None:
    """Longer than the sniffed first block: the squeezed stream must not break a line."""
    rng = np.random.default_rng(3)
    data = np.column_stack([np.arange(60_000) * 0.01, rng.integers(30000, 40000, (60_000, 3))])
    path = tmp_path / "big.txt"
    np.savetxt(path, data, fmt=["%16.7e", "%16.7e", "%16.7e", "%16.7e"])
    assert path.stat().st_size > sniff.HEAD_BYTES
    s = read_samples(str(path))
    np.testing.assert_array_equal(s.values, data[:, 1:])


# -- stdin ------------------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("rows", [10, 120_000], ids=["small", "larger-than-the-first-block"])
def test_stdin_reads_and_hashes_like_the_file(rows: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    text = "t,ax,ay,az\n" + "".join(f"{i * 0.01:.2f},{i % 10}.5,-0.25,1.0\n" for i in range(rows))
    data = text.encode()
    path = str(write(tmp_path / "capture.csv", data))
    from_file = read_samples(path)
    feed_stdin(monkeypatch, data)
    from_stdin = read_samples("-")
    assert from_stdin.layout.name == "<stdin>"
    assert from_stdin.sha256 == from_file.sha256 == hashlib.sha256(data).hexdigest()
    np.testing.assert_array_equal(from_stdin.values, from_file.values)
    assert from_stdin.values.shape == (rows, 3)


def test_stdin_whitespace_hash(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    data = XSENS.read_bytes()
    feed_stdin(monkeypatch, data)
    s = read_samples("-")
    assert s.sha256 == hashlib.sha256(data).hexdigest()
    np.testing.assert_array_equal(s.values, read_samples(str(XSENS)).values)


# -- whole-file errors -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"", "empty file"),
        (b"\n\n# only comments\n", "no data: the file holds only blank or # comment lines"),
        (b"t,ax,ay,az\n", "a header but no data rows"),
        (b"t,ax,ay,az\n# nothing logged\n\n", "a header but no data rows"),
        (b"PK\x03\x04\x00\x00binary", "binary data, not a CSV text file"),
        (b"t,ax,ay,az\n0,1,2,\xff\n", "not UTF-8 text (byte 17)"),
        (b"ax,ay\n1,2\n", "2 columns, a capture needs at least 3"),
        (b"just some text\nmore text here\n", "no accelerometer x,y,z columns found"),
    ],
)
def test_unreadable_files(content: bytes, message: str, tmp_path: Path) -> None:
    path = str(write(tmp_path / "capture.csv", content))
    with pytest.raises(InputError) as err:
        read_samples(path)
    assert str(err.value).startswith(f"{path}: {message}")


def test_missing_file_and_directory(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file"):
        read_samples(str(tmp_path / "nope.csv"))
    with pytest.raises(InputError, match="is a directory"):
        read_samples(str(tmp_path))


def _values(rows: Sequence[Sequence[float]]) -> FloatArray:
    return np.array(rows, dtype=np.float64)


def test_correct_stream_round_trips(tmp_path: Path) -> None:
    """correct_stream with the identity writes every number back as the same float64."""
    rng = np.random.default_rng(11)
    raw = _values(rng.normal(0, 1e3, (500, 3)).tolist())
    text = "t,ax,ay,az\n" + "".join(f"{i},{a!r},{b!r},{c!r}\n" for i, (a, b, c) in enumerate(raw.tolist()))
    path = str(write(tmp_path / "capture.csv", text))
    out = io.BytesIO()
    with open_capture(path) as cap:
        rows = rewrite.correct_stream(cap, out, lambda v: v)
    assert rows == 500
    back = np.loadtxt(io.BytesIO(out.getvalue()), delimiter=",", skiprows=1)[:, 1:]
    np.testing.assert_array_equal(back, raw)
    assert out.getvalue() == text.encode()  # repr is the shortest round-trip text: same bytes


def test_columns_naming_one_column_twice(tmp_path: Path) -> None:
    """--columns ax,ax,az is a usage error naming the file, not a crash in the CSV engine."""
    path = tmp_path / "p.csv"
    path.write_text("ax,ay,az\n1,2,3\n")
    with pytest.raises(InputError, match="--columns names the same column twice: ax,ax,az") as err:
        read_samples(str(path), ReadSpec(columns=("ax", "ax", "az")))
    assert err.value.exit_code == 2
    assert str(path) in str(err.value)


def test_columns_of_a_headerless_file_take_what_was_only_guessed_the_time(tmp_path: Path) -> None:
    """A headerless file's first column is taken for time; --columns 0,1,2 says it is a sensor's
    (x, y, z, temperature): it was refused as "--columns names 't', the time column"."""
    path = tmp_path / "xyzt.csv"
    path.write_text("".join(f"1.03{k % 7},0.02{k % 5},0.01{k % 3},25.0\n" for k in range(50)))
    log = read_log(str(path), ReadSpec(no_header=True, columns=("0", "1", "2")), use_time=False)
    assert log.layout.time is None
    assert log.values[0].tolist() == [1.03, 0.02, 0.01]
