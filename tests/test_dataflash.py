"""ArduPilot DataFlash logs read where a capture is read (io.logs.dataflash and io.logs.dftext through
io.sources): real ArduPilot logs listed and read as ArduPilot's own parser (pymavlink's DFReader)
reads them, in the binary and the text form; --stream and --allow-corrected; raw or corrected as
the log's PARM tells; a synthetic six-face session that solves as its CSV does; and the logs that
are cut, corrupt or odd."""

from __future__ import annotations

import contextlib
import gzip
import json
from pathlib import Path

import numpy as np
import pytest
from pymavlink import DFReader

import tumblecal_cli as tumblecal
from tests import dataflash_writer as writer
from tests.conftest import ROOT, run_exe, write
from tests.conftest import tumblecal as cli
from tests.test_sources import tumble
from tests.test_ulog import thermal_sweeps
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import sources
from tumblecal_cli.io.csv import readings
from tumblecal_cli.io.logs import dataflash, dftext
from tumblecal_cli.io.readspec import ReadSpec

DATA = ROOT / "tests" / "data" / "ardupilot"
G = 9.80665
IMU = writer.TYPES["IMU"][0]


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The real logs of tests/data/ardupilot, decompressed, and their text form."""
    folder = tmp_path_factory.mktemp("ardupilot")
    out = {}
    for name in ("spark404_copter.bin", "pymavlink_plane.BIN"):
        path = folder / name
        path.write_bytes(gzip.decompress((DATA / f"{name}.gz").read_bytes()))
        out[name.partition(".")[0]] = path
        out[name.partition(".")[0] + ".log"] = writer.text_of(path, folder / f"{path.stem}.log")
    return out


def read(path: Path | str, stream: str, sensor: str = "accelerometer", allow: bool = True) -> sources.Table:
    reader = sources.reader_for(str(path))
    assert reader is not None
    return reader.read(str(path), ReadSpec(sensor=sensor, stream=stream, allow_corrected=allow), None)


def rewrite(path: Path, data: bytes) -> str:
    path.write_bytes(data)
    dataflash.READER.forget()
    dftext.READER.forget()
    return str(path)


def still(tmp_path: Path, rows: int = 2000, **kwargs: object) -> tuple[Path, bytes, np.ndarray]:
    """A still +z capture as a DataFlash log (IMU:0, raw): its path, bytes and clock (µs)."""
    t = np.arange(rows, dtype=np.int64) * 2000 + 1_000_000
    acc = np.tile([0.01, -0.02, G], (rows, 1)) + np.random.default_rng(1).normal(0, 0.01, (rows, 3))
    path = writer.write(tmp_path / "still.bin", t, acc, **kwargs)  # type: ignore[arg-type]
    return path, path.read_bytes(), t


# -- real logs -----------------------------------------------------------------------------


def test_logs_lists_a_real_log_s_streams(logs: dict[str, Path]) -> None:
    code, out, err = cli("logs", logs["spark404_copter"])
    assert (code, err) == (0, "")
    lines = out.splitlines()
    assert lines[0].split() == ["stream", "sensor", "rows", "rate", "Hz", "units", "as", "logged"]
    assert lines[1].split() == ["IMU:0", "accelerometer", "1258", "24.72", "m/s^2", "corrected"]
    assert lines[4].split() == ["IMU:1", "gyroscope", "1258", "24.72", "rad/s", "corrected"]
    assert lines[6].split() == ["MAG:1", "magnetometer", "503", "9.886", "mGauss", "corrected"]
    hows = [line for line in lines[8:] if line]
    assert hows[0].startswith("IMU: corrected: ArduPilot subtracts INS_ACC*OFFS and scales by INS_ACC*SCAL")
    assert hows[0].endswith(
        "(libraries/AP_InertialSensor/AP_InertialSensor_Backend.cpp: _rotate_and_correct_accel, log_accel_raw)"
    )
    assert hows[1].startswith("IMU: corrected: ArduPilot subtracts INS_GYR*OFFS")
    assert hows[2].startswith("MAG: corrected: MagX/Y/Z are the field after COMPASS_OFS* (added)")
    assert "AP_Compass_Backend.cpp: correct_field" in hows[2]


def test_logs_json_says_each_stream_s_units_and_whether_it_is_corrected(logs: dict[str, Path]) -> None:
    code, out, _ = cli("logs", logs["pymavlink_plane"], "--json")
    assert code == 0
    doc = json.loads(out)
    found = {(s["stream"], s["sensor"]): s for s in doc["streams"]}
    assert sorted(found) == [
        ("IMU:0", "accelerometer"),
        ("IMU:0", "gyroscope"),
        ("IMU:1", "accelerometer"),
        ("IMU:1", "gyroscope"),
        ("MAG:0", "magnetometer"),
        ("MAG:1", "magnetometer"),
        ("MAG:2", "magnetometer"),
    ]
    mag = found[("MAG:2", "magnetometer")]
    assert mag | {"how": "", "rate": 0} == {
        "stream": "MAG:2",
        "name": "MAG",
        "instance": 2,
        "sensor": "magnetometer",
        "rows": 8,
        "rate": 0,
        "units": "mGauss",
        "corrected": True,
        "how": "",
    }
    assert mag["rate"] == pytest.approx(8.6, abs=0.05)
    assert found[("IMU:1", "accelerometer")]["rows"] == 45
    assert all(s["corrected"] for s in doc["streams"])


def pymavlink_rows(path: Path, message: str, columns: list[str]) -> np.ndarray:
    with DFReader.DFReader_binary(str(path)) as log:
        rows = []
        while (m := log.recv_match(type=message)) is not None:
            rows.append([getattr(m, c) for c in columns])
    return np.array(rows, dtype=float)


@pytest.mark.parametrize(
    ("log", "stream", "sensor", "message"),
    [
        ("spark404_copter", "IMU:0", "accelerometer", "IMU"),
        ("spark404_copter", "IMU:1", "gyroscope", "IMU2"),
        ("spark404_copter", "MAG:1", "magnetometer", "MAG2"),
        ("pymavlink_plane", "IMU:1", "accelerometer", "IMU2"),
        ("pymavlink_plane", "IMU:0", "gyroscope", "IMU"),
        ("pymavlink_plane", "MAG:2", "magnetometer", "MAG3"),
    ],
)
def test_a_stream_reads_as_pymavlink_reads_it(
    logs: dict[str, Path], log: str, stream: str, sensor: str, message: str
) -> None:
    """Every value, time and temperature as ArduPilot's own parser gives them, from the binary
    log and from its text form."""
    axes = {"accelerometer": "Acc", "gyroscope": "Gyr", "magnetometer": "Mag"}[sensor]
    columns = [f"{axes}{a}" for a in "XYZ"] + ["TimeUS"] + (["T"] if message.startswith("IMU") else [])
    expected = pymavlink_rows(logs[log], message, columns)
    for path in (logs[log], logs[log + ".log"]):
        table = read(path, stream, sensor)
        np.testing.assert_array_equal(table.values, expected[:, :3])
        np.testing.assert_array_equal(table.clock, expected[:, 3])
        if message.startswith("IMU"):
            np.testing.assert_array_equal(table.temperature, expected[:, 4])
        else:
            assert table.temperature is None
        assert (table.time_unit, table.corrected, table.names[0][:3]) == ("us", True, axes.lower()[:3])


def test_the_text_form_lists_the_same_streams(logs: dict[str, Path]) -> None:
    for name in ("spark404_copter", "pymavlink_plane"):
        binary, text = tumblecal.streams(str(logs[name])), tumblecal.streams(str(logs[name + ".log"]))
        assert [(s.key, s.sensor, s.rows, s.units, s.corrected, s.how) for s in text] == [
            (s.key, s.sensor, s.rows, s.units, s.corrected, s.how) for s in binary
        ]
        assert [s.rate for s in text] == pytest.approx([s.rate for s in binary])


def test_the_read_note_names_the_message_and_the_calibration_in_force(logs: dict[str, Path]) -> None:
    table = read(logs["spark404_copter"], "IMU:1")
    assert table.notes[0] == (
        f"{logs['spark404_copter']}: read IMU:1 (accelerometer, 1258 samples, m/s^2, corrected by ArduPilot, "
        "logged as IMU2); in force (PARM): INS_ACC2OFFS (0.00362926, 0.136469, 0.407869), "
        "INS_ACC2SCAL (1.05204, 1.00571, 1.0323)"
    )
    mag = read(logs["pymavlink_plane"], "MAG:0", "magnetometer")
    assert "in force (PARM): COMPASS_OFS (-58.5135, 57.0916, 90.3058)" in mag.notes[0]
    assert any("the log ends mid-message (its last 24 bytes, from byte 65512)" in n for n in mag.notes)


def test_several_instances_and_no_stream_is_exit_2_listing_them(logs: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "cal.json"
    code, stdout, err = cli("solve", "--log", logs["spark404_copter"], "-o", out, "--allow-corrected")
    assert (code, stdout) == (2, "")
    assert "the log holds 2 accelerometer streams: IMU:0, IMU:1; give one with --stream" in err
    assert "hint: e.g. --stream IMU:0" in err
    assert not out.exists()
    code, _, err = cli("noise", logs["pymavlink_plane"], "--sensor", "magnetometer", "--allow-corrected")
    assert code == 2
    assert "3 magnetometer streams: MAG:0, MAG:1, MAG:2" in err


def test_a_corrected_stream_is_refused_unless_allowed(logs: dict[str, Path], tmp_path: Path) -> None:
    log = logs["spark404_copter"]
    code, _, err = cli("solve", "--log", log, "--stream", "IMU:0", "-o", tmp_path / "cal.json")
    assert code == 2
    line = err.splitlines()[0]
    said = "IMU:0 (accelerometer) is already corrected before it was logged (corrected: "
    assert line.startswith(f"error: {log}: {said}")
    assert "_rotate_and_correct_accel" in line
    assert line.endswith("a fit of it calibrates the residual, not the sensor")
    assert "--allow-corrected" in err
    commands: list[list[str | Path]] = [
        ["noise", log, "--stream", "IMU:1"],
        ["segment", log, "--stream", "IMU:0"],
        ["noise", log, "--stream", "MAG:0", "--sensor", "magnetometer"],
    ]
    for command in commands:
        code, _, err = cli(*command)
        assert code == 2, command
        assert "calibrates the residual, not the sensor" in err
    code, _, err = cli("noise", log, "--stream", "IMU:1", "--allow-corrected")
    assert code == 0, err
    assert "read IMU:1 (accelerometer, 1258 samples, m/s^2, corrected by ArduPilot, logged as IMU2)" in err
    code, _, err = cli("solve", "--log", log, "--stream", "IMU:0", "--allow-corrected", "-o", tmp_path / "c.json")
    assert code == 3  # read: this flight has no still block
    assert "nothing to calibrate from" in err


def test_stream_picks_the_instance_and_the_sensor(logs: dict[str, Path]) -> None:
    log = str(logs["pymavlink_plane"])
    gyro = readings.read_log(log, ReadSpec(sensor="gyroscope", stream="IMU:1", allow_corrected=True))
    assert gyro.layout.names[:3] == ["gyr_x", "gyr_y", "gyr_z"]
    assert len(gyro.values) == 45
    for stream, sensor, message in [
        ("MAG:0", "accelerometer", "MAG:0 carries magnetometer, not the accelerometer"),
        ("IMU:7", "accelerometer", "the log has no stream IMU:7"),
        ("IMU2", "accelerometer", "the log has no stream IMU2"),  # older logs' IMU2 is listed and read as IMU:1
        ("IMU", "gyroscope", "IMU has 2 instances: IMU:0, IMU:1; name one"),
    ]:
        with pytest.raises(InputError, match=message) as err:
            readings.read_log(log, ReadSpec(sensor=sensor, stream=stream, allow_corrected=True))
        assert err.value.file == log


# -- raw or corrected, as the log's PARM tells -------------------------------------------------


@pytest.mark.parametrize(
    ("params", "corrected", "how"),
    [
        (writer.identity(1), False, "raw: the log's PARM holds INS_ACC*OFFS at 0 and INS_ACC*SCAL at 1"),
        (writer.identity(1) | {"INS_ACCOFFS_Y": 0.2}, True, "corrected: ArduPilot subtracts INS_ACC*OFFS"),
        (writer.identity(1) | {"INS_ACCSCAL_Z": 1.01}, True, "corrected: ArduPilot subtracts INS_ACC*OFFS"),
        (writer.identity(1) | {"INS_TCAL1_ENABLE": 1.0}, True, "corrected: ArduPilot subtracts INS_ACC*OFFS"),
        ({}, True, "corrected: ArduPilot subtracts"),
    ],
)
def test_an_imu_is_raw_where_the_log_s_parm_holds_no_calibration(
    tmp_path: Path, params: dict[str, float], corrected: bool, how: str
) -> None:
    path, _, _ = still(tmp_path, 200, params=params)
    dataflash.READER.forget()
    stream = next(s for s in tumblecal.streams(str(path)) if s.sensor == "accelerometer")
    assert (stream.key, stream.corrected) == ("IMU:0", corrected)
    assert stream.how.startswith(how)
    assert stream.how.endswith("_rotate_and_correct_accel, log_accel_raw)")
    assert ("this log's PARM does not say otherwise (libraries/" in stream.how) == (not params)


def test_acc_and_gyr_read_by_sample_time_with_the_imu_s_temperature(tmp_path: Path) -> None:
    """ACC and GYR (raw logging): one stream an instance, timed by SampleUS, the temperature
    their IMU's T interpolated; with INS_RAW_LOG_OPT bit 3 the upper instances are the
    post-filter copies, told so."""
    rows = 400
    t = np.arange(rows, dtype=np.int64) * 1000 + 5_000_000
    acc = np.tile([0.0, 0.0, -G], (rows, 1)) + np.random.default_rng(4).normal(0, 0.01, (rows, 3))
    temp = 30 + np.arange(rows, dtype=np.float64) * 0.01
    parts = [writer.imu(t, acc, temp, 0)]
    for k in range(2):
        xyz = {"AccX": acc[:, 0], "AccY": acc[:, 1], "AccZ": acc[:, 2]}
        parts.append(writer.records("ACC", rows, TimeUS=t + 400, I=k, SampleUS=t + 37, **xyz))
        parts.append(writer.records("GYR", rows, TimeUS=t + 400, I=k, SampleUS=t + 41, GyrX=0.01, GyrY=0.0, GyrZ=0.0))
    params = writer.identity(1) | {"INS_RAW_LOG_OPT": 8.0}
    path = tmp_path / "raw.bin"
    path.write_bytes(writer.header(params) + writer.frames(parts))
    found = {(s.key, s.sensor): s for s in tumblecal.streams(str(path))}
    assert sorted(found) == [
        ("ACC:0", "accelerometer"),
        ("ACC:1", "accelerometer"),
        ("GYR:0", "gyroscope"),
        ("GYR:1", "gyroscope"),
        ("IMU:0", "accelerometer"),
        ("IMU:0", "gyroscope"),
    ]
    assert not found[("ACC:0", "accelerometer")].corrected
    assert "post-filter copy of ACC:0 (INS_RAW_LOG_OPT bit 3)" in found[("ACC:1", "accelerometer")].how
    assert "post-filter copy" not in found[("ACC:0", "accelerometer")].how
    table = read(path, "ACC:0")
    np.testing.assert_array_equal(table.clock, t + 37)
    np.testing.assert_array_equal(table.values, writer.float32(acc))
    assert table.temperature is not None
    expected = np.interp((t + 37).astype(np.float64), t.astype(np.float64), writer.float32(temp))
    np.testing.assert_allclose(table.temperature, expected)
    assert any("ACC:0: the temperature is IMU:0's T, interpolated to its times" in n for n in table.notes)
    gyro = read(path, "GYR:1", "gyroscope")
    np.testing.assert_array_equal(gyro.clock, t + 41)
    assert gyro.values[0].tolist() == pytest.approx([0.01, 0.0, 0.0])
    code, _, err = cli("noise", path, "--stream", "ACC:0")  # raw: read without --allow-corrected
    assert code == 0, err


def test_the_test_writer_s_logs_read_in_pymavlink(tmp_path: Path) -> None:
    path, _, t = still(tmp_path, 300, instances=2)
    with DFReader.DFReader_binary(str(path)) as log:
        rows = []
        while (m := log.recv_match(type="IMU")) is not None:
            rows.append((m.I, m.TimeUS, m.AccZ))
        assert log.params["INS_ACC2SCAL_X"] == 1.0
    assert len(rows) == 600
    assert [r[1] for r in rows if r[0] == 1] == (t + 7).tolist()


# -- the text form -------------------------------------------------------------------------

TEXT = """FMT, 128, 89, FMT, BBnNZ, Type,Length,Name,Format,Columns
FMT, 129, 31, PARM, QNf, TimeUS,Name,Value
FMT, 130, 54, IMU, QBffffffIIfBBHH, TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH,GHz,AHz
PARM, 1000, INS_ACCOFFS_X, 0
PARM, 1000, INS_ACCOFFS_Y, 0
PARM, 1000, INS_ACCOFFS_Z, 0
PARM, 1000, INS_ACCSCAL_X, 1
PARM, 1000, INS_ACCSCAL_Y, 1
PARM, 1000, INS_ACCSCAL_Z, 1
IMU, 2000, 0, 0.001, -0.002, 0.003, 0.1, -0.2, -9.8, 0, 0, 31.5, 1, 1, 1000, 1000
XKF1, 2100, 0, 1, 2
IMU, 4000, 0, 0.001, -0.002, 0.003, 0.11, -0.21, -9.81, 0, 0, 31.5, 1, 1, 1000, 1000
IMU, 6000, 0, 0.001, -0.002, 0.003, oops, -0.21, -9.81, 0, 0, 31.5, 1, 1, 1000, 1000
IMU, 8000, 0, 0.001, -0.002, 0.003, 0.12, -0.22
IMU, 10000, 0, 0.001, -0.002, 0.003, 0.13, -0.23, -9.83, 0, 0, 31.6, 1, 1, 1000, 1000
IMU, 12000, 0, 0.001, -0.002, 0.003, 0.14, -0.2"""


@pytest.mark.parametrize("delimiter", [", ", ","])
def test_a_text_log_reads_its_lines_and_skips_what_does_not_parse(tmp_path: Path, delimiter: str) -> None:
    """Mission Planner's ", " and a plain ",": a line of a type no FMT line defines, lines whose
    fields do not parse, and a last line cut short, each skipped with a note."""
    body = TEXT.replace(", ", delimiter)
    path = write(tmp_path / "flight.log", body.encode())
    table = read(path, "IMU:0", allow=False)
    assert table.values.tolist() == [[0.1, -0.2, -9.8], [0.11, -0.21, -9.81], [0.13, -0.23, -9.83]]
    assert table.clock is not None
    assert table.clock.tolist() == [2000, 4000, 10000]
    assert table.temperature is not None
    assert table.temperature.tolist() == [31.5, 31.5, 31.6]
    assert not table.corrected
    notes = "\n".join(table.notes)
    last = body.rpartition("\n")[2]
    assert (
        f"the log ends mid-line (its last {len(last)} bytes, from byte {len(body) - len(last)}, with no line end)"
        in notes
    )
    assert "skipped lines of a message type no FMT line defines (XKF1 x1)" in notes
    assert "IMU:0: 2 lines that do not parse skipped" in notes


def test_a_text_line_longer_than_a_read_is_skipped_and_the_rest_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A "line" with no end for more than a read's bytes (binary garbage in a text log) is one
    line that does not parse, not the rest of the log held in memory."""
    monkeypatch.setattr(dftext, "CHUNK", 256)
    lines = TEXT.splitlines()
    body = "\n".join([*lines[:10], "IMU, " + "9" * 1000, *lines[10:12]]) + "\n"
    path = write(tmp_path / "long.log", body.encode())
    found = dftext.walk(str(path))
    assert [len(s.places) for s in found.sources] == [2]
    assert "skipped 1 lines whose fields do not parse" in found.notes


# -- a synthetic session in the real format --------------------------------------------------


def session(tmp_path: Path, rows: int = 30_000, **kwargs: object) -> tuple[Path, Path]:
    """A six-face tumble at 500 Hz as a DataFlash log (IMU in m/s^2, float32, µs stamps; INS_ACC*
    at their defaults, so raw) and as a CSV of the very same numbers."""
    t, acc = tumble(rows)
    t_us = np.round(t * 1e6).astype(np.int64) + 5_000_000
    values = writer.float32(acc * G)
    temperature = writer.float32(30.0 + 0.001 * np.arange(rows) / rows)
    log = writer.write(tmp_path / "session.bin", t_us, values, temperature, **kwargs)  # type: ignore[arg-type]
    table = np.column_stack([t_us, values, temperature])
    fmt = ["%d", "%.17g", "%.17g", "%.17g", "%.17g"]
    csv = write(tmp_path / "session.csv", table, header="timestamp,acc_x,acc_y,acc_z,temperature", fmt=fmt)
    return log, csv


@pytest.mark.slow
def test_a_six_face_session_in_a_dataflash_log_solves_as_its_csv_does(tmp_path: Path) -> None:
    log, csv = session(tmp_path)
    text = writer.text_of(log, tmp_path / "session.log")
    from_csv = tumblecal.solve_log(csv, time_unit="us", reference=G, units="m/s^2", input_units="m/s^2")
    assert from_csv.status == 0
    a = from_csv.calibration
    assert a is not None
    for path in (log, text):
        done = tumblecal.solve_log(path)
        assert done.status == 0
        b = done.calibration
        assert b is not None
        assert b.method == a.method == "six-pose"
        np.testing.assert_allclose(b.offset, a.offset, rtol=0, atol=1e-12)
        np.testing.assert_allclose(b.matrix, a.matrix, rtol=0, atol=1e-12)
        assert (b.reference, b.units, b.input_units) == (G, "m/s^2", "m/s^2")
        assert [p.temperature for p in b.poses] == [p.temperature for p in a.poses]
        assert done.notes[0].startswith("IMU:0 is in m/s^2: solved against standard gravity")
    assert np.allclose(a.gain, [1.01, 0.99, 1.02], atol=2e-3)
    out = tmp_path / "cli.json"
    code, _, err = cli("solve", "--log", log, "-o", out)
    assert code == 0, err
    assert "note: IMU:0 is in m/s^2" in err
    assert "read IMU:0 (accelerometer, 30000 samples, m/s^2, raw); in force (PARM): INS_ACCOFFS (0, 0, 0)" in err
    assert tumblecal.load(str(out)).offset.tolist() == a.offset.tolist()


@pytest.mark.slow
def test_several_instances_in_a_session_pick_by_stream(tmp_path: Path) -> None:
    log, _ = session(tmp_path, instances=2)
    with pytest.raises(InputError, match="2 raw accelerometer streams: IMU:0, IMU:1"):
        tumblecal.solve_log(log)
    one = tumblecal.solve_log(log, stream="IMU:1").calibration
    zero = tumblecal.solve_log(log, stream="IMU:0").calibration
    assert one is not None
    assert zero is not None
    np.testing.assert_allclose(one.matrix, zero.matrix, rtol=0, atol=1e-12)
    assert len(tumblecal.segment(str(log), stream="IMU:1").files) == 6


# -- logs cut short, corrupt, odd ------------------------------------------------------------


def imu_at(data: bytes, after: int) -> int:
    """Where the first IMU message after byte ``after`` starts."""
    return data.index(writer.HEAD + bytes([IMU]), after)


def pymavlink_count(path: str) -> int:
    """The IMU messages pymavlink reads message by message (its _parse_next: bad bytes skipped to
    the next header of a known type; its index by type stops at a type no FMT defines)."""
    with DFReader.DFReader_binary(path) as log:
        n = 0
        while (m := log.recv_msg()) is not None:
            n += m.get_type() == "IMU"
    return n


def test_a_log_cut_mid_message_is_read_up_to_there_with_a_note(tmp_path: Path) -> None:
    path, data, _ = still(tmp_path)
    cut = rewrite(path, data[:-20])
    log = readings.read_log(cut, ReadSpec())
    assert len(log.values) == 1999 == pymavlink_count(cut)
    note = f"{cut}: the log ends mid-message (its last 34 bytes, from byte {len(data) - 54})"
    assert any(n.startswith(note) and "cut short" in n for n in log.layout.notes), log.layout.notes
    code, _, err = cli("noise", cut)
    assert code == 0
    assert "the log ends mid-message" in err
    assert "Traceback" not in err


def test_a_corrupt_stretch_is_skipped_to_the_next_message_as_pymavlink_does(tmp_path: Path) -> None:
    path, data, _ = still(tmp_path)
    at = imu_at(data, len(data) // 2)
    broken = rewrite(path, data[:at] + b"\x13\x37" + data[at + 2 :])  # a message's header bytes hit
    log = readings.read_log(broken, ReadSpec())
    assert len(log.values) == 1999 == pymavlink_count(broken)
    assert any(f"skipped 54 bytes at byte {at} (bytes that are no message)" in n for n in log.layout.notes)
    inserted = rewrite(path, data[:at] + bytes(range(200)) + data[at:])  # bytes that are no message at all
    log = readings.read_log(inserted, ReadSpec())
    assert len(log.values) == 2000 == pymavlink_count(inserted)
    assert any(f"skipped 200 bytes at byte {at}" in n for n in log.layout.notes)
    assert cli("noise", inserted).code == 0


def test_a_message_of_a_type_no_fmt_defines_is_skipped_with_a_note(tmp_path: Path) -> None:
    path, data, _ = still(tmp_path)
    at = imu_at(data, len(data) // 2)
    odd = rewrite(path, data[:at] + writer.HEAD + b"\xf0" + bytes(30) + data[at:])
    log = readings.read_log(odd, ReadSpec())
    assert len(log.values) == 2000 == pymavlink_count(odd)
    assert (
        f"{odd}: skipped 33 bytes at byte {at} (a message of type 0xf0, which no FMT defines), resuming at the next "
        "message, as pymavlink does"
    ) in log.layout.notes


def test_zeros_or_erased_flash_at_the_end_are_space_never_written(tmp_path: Path) -> None:
    path, data, _ = still(tmp_path)
    for filler in (b"\0", b"\xff"):
        padded = rewrite(path, data + filler * 4096)
        log = readings.read_log(padded, ReadSpec())
        assert len(log.values) == 2000
        never = f"the log ends in 4096 bytes that were never written, from byte {len(data)}"
        assert any(never in n for n in log.layout.notes)
    junk = rewrite(path, data + bytes(range(256)) * 4)
    log = readings.read_log(junk, ReadSpec())
    assert any("the log ends in 1024 bytes that are no message" in n for n in log.layout.notes)


def test_a_timestamp_that_jumps_back_once_is_skipped_and_twice_over_is_exit_2(tmp_path: Path) -> None:
    t = np.arange(2000, dtype=np.int64) * 2000 + 1_000_000
    acc = np.tile([0.0, 0.0, G], (2000, 1))
    stray = t.copy()
    stray[700] = 5  # one corrupt sample
    path = writer.write(tmp_path / "stray.bin", stray, acc)
    log = readings.read_log(str(path), ReadSpec())
    assert len(log.values) == 1999
    assert log.clock is not None
    assert 5.0 not in log.clock
    assert any(
        "IMU:0: 1 samples whose timestamp went back skipped" in n and "sample 701" in n for n in log.layout.notes
    )
    twice = np.concatenate([t[:1000], t[:1000]])  # two sessions in one log
    path = writer.write(tmp_path / "twice.bin", twice, acc)
    code, _, err = cli("segment", path)
    assert code == 2
    assert err.splitlines()[0] == (
        f"error: {path}: IMU:0: the timestamps go back at sample 1001 (1.000000 s after 2.998000 s), "
        "1 times in 2000 samples: not a stray corrupt sample"
    )
    assert "hint: give --rate HZ" in err
    assert cli("noise", path, "--rate", "500").code == 0


def test_a_corrupt_float_is_one_line_not_a_warning(tmp_path: Path) -> None:
    """A sample whose AccX has a signalling NaN's bits (a corrupt message whose header survived)."""
    path, data, _ = still(tmp_path)
    start = imu_at(data, len(data) // 2)
    at, row = start + 3 + 8 + 1 + 12, data[:start].count(writer.HEAD + bytes([IMU])) + 1  # its AccX
    broken = rewrite(path, data[:at] + b"\x01\x00\x80\x7f" + data[at + 4 :])
    code, out, err = cli("solve", "--log", broken, "-o", tmp_path / "c.json")
    assert (code, out) == (2, "")
    assert err.splitlines()[0] == f"error: {broken}: reading {row} (acc_x...) is not a finite number"


@pytest.mark.parametrize("form", ["bin", "log"])
def test_mutated_logs_end_in_a_documented_way(tmp_path: Path, form: str) -> None:
    """Seeded mutations of a small log (bytes changed, inserted, cut, moved): each read lists
    its streams and reads them, or is an InputError; never another exception or a warning."""
    import random

    t = np.arange(300, dtype=np.int64) * 2000 + 1_000_000
    good = writer.write(tmp_path / "good.bin", t, np.tile([0.0, 0.0, G], (300, 1)), instances=2)
    base = (good if form == "bin" else writer.text_of(good, tmp_path / "good.log")).read_bytes()
    rng = random.Random(7)
    for _ in range(60):
        data = bytearray(base)
        for _ in range(rng.randint(1, 5)):
            i, n = rng.randrange(len(data)), rng.randint(1, 80)
            choice = rng.randrange(4)
            if choice == 0:
                data[i] = rng.randrange(256)
            elif choice == 1:
                data[i:i] = rng.randbytes(n)
            elif choice == 2:
                del data[i : i + n]
            else:
                data[i:i] = data[rng.randrange(len(data)) :][:n]
        path = rewrite(tmp_path / f"case.{form}", bytes(data))
        reader = sources.reader_for(path)
        if reader is None:
            continue  # the first line or bytes were hit: read as a CSV (its reader is fuzzed apart)
        try:
            for stream in reader.streams(path):
                with contextlib.suppress(InputError):
                    readings.read_log(path, ReadSpec(sensor=stream.sensor, stream=stream.key, allow_corrected=True))
        except InputError:
            pass


def test_a_log_with_no_sensor_stream(tmp_path: Path) -> None:
    bare = write(tmp_path / "bare.bin", writer.header(writer.identity(1)))
    code, out, _ = cli("logs", bare)
    assert (code, out) == (0, "no sensor streams in this log\n")
    code, _, err = cli("solve", "--log", bare, "-o", tmp_path / "c.json")
    assert code == 2
    assert "the log holds no accelerometer stream with samples" in err


# -- the installed command, end to end -------------------------------------------------------


@pytest.mark.slow
def test_the_installed_command_lists_solves_and_verifies_a_dataflash_log(logs: dict[str, Path], tmp_path: Path) -> None:
    done = run_exe(["logs", logs["spark404_copter.log"], "--json"], text=True)
    assert done.returncode == 0, done.stderr
    keys = [s["stream"] for s in json.loads(done.stdout)["streams"]]
    assert keys == ["IMU:0", "IMU:0", "IMU:1", "IMU:1", "MAG:0", "MAG:1"]
    log, _ = session(tmp_path)
    cal = tmp_path / "cal.json"
    done = run_exe(["solve", "--log", log, "-o", cal, "--stream", "IMU:0"], text=True)
    assert done.returncode == 0, done.stderr
    assert json.loads(cal.read_text())["units"] == "m/s^2"
    still_log, _, _ = still(tmp_path)
    done = run_exe(["verify", "--cal", cal, still_log, "--stream", "IMU:0", "--json"], text=True)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["captures"][0]["samples"] == 2000
    done = run_exe(["verify", "--cal", cal, logs["spark404_copter"], "--stream", "IMU:0"], text=True)
    assert done.returncode == 2
    assert "calibrates the residual, not the sensor" in done.stderr


@pytest.mark.slow
def test_thermal_fits_a_drift_from_dataflash_sweeps_with_the_imu_s_temperature(tmp_path: Path) -> None:
    """IMU's T is the temperature column: +z and -z sweeps from 10 to 40 °C with an x offset
    drift of 0.002 m/s^2/°C give it back."""
    log, _ = session(tmp_path)
    base = tumblecal.solve_log(log).calibration
    assert base is not None
    done = tumblecal.thermal(thermal_sweeps(tmp_path, writer.write, ".bin"), base)
    assert done.calibration.thermal is not None
    assert done.fit.drift.order == 1
    assert done.fit.drift.offset[0][0] == pytest.approx(0.002, abs=1e-4)
    assert done.calibration.thermal.column == "temperature"
