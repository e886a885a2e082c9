"""PX4 ULog logs read where a capture is read (io.logs.ulog through io.sources): real PX4 logs listed
and read as PX4's own parser (pyulog) reads them, --stream and --allow-corrected, a synthetic
six-face session that solves as its CSV does, and the logs that are cut, corrupt or odd."""

from __future__ import annotations

import gzip
import json
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from pyulog import ULog

import tumblecal_cli as tumblecal
from tests import ulog_writer
from tests.conftest import ROOT, run_exe, write
from tests.conftest import tumblecal as cli
from tests.test_sources import tumble
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import sources
from tumblecal_cli.io.csv import readings
from tumblecal_cli.io.logs import ulog
from tumblecal_cli.io.readspec import ReadSpec

PX4 = ROOT / "tests" / "data" / "px4"
G = 9.80665
#: The header of a sensor_accel sample as the test writer writes it: 46 bytes, 'D', msg_id 10.
SAMPLE = b"\x2e\x00D\x0a\x00"


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The real logs of tests/data/px4, decompressed."""
    folder = tmp_path_factory.mktemp("px4")
    out = {}
    for name in ("robologs_fmu_v5", "auterion_esc_status", "pyulog_sample_log_small"):
        path = folder / f"{name}.ulg"
        path.write_bytes(gzip.decompress((PX4 / f"{name}.ulg.gz").read_bytes()))
        out[name] = path
    return out


def session(tmp_path: Path, rows: int = 30_000, **kwargs: int) -> tuple[Path, Path]:
    """A six-face tumble at 500 Hz as a ULog (sensor_accel in m/s^2, float32, µs stamps) and as a
    CSV of the very same numbers (timestamp in µs, 17 digits: the float32 values exactly)."""
    t, acc = tumble(rows)
    t_us = np.round(t * 1e6).astype(np.int64) + 5_000_000
    values = ulog_writer.float32(acc * G)
    temperature = ulog_writer.float32(30.0 + 0.001 * np.arange(rows) / rows)
    log = ulog_writer.write(tmp_path / "session.ulg", t_us, values, temperature, **kwargs)
    table = np.column_stack([t_us, values, temperature])
    fmt = ["%d", "%.17g", "%.17g", "%.17g", "%.17g"]
    csv = write(tmp_path / "session.csv", table, header="timestamp,acc_x,acc_y,acc_z,temperature", fmt=fmt)
    return log, csv


# -- real logs -----------------------------------------------------------------------------


def test_logs_lists_a_real_log_s_streams(logs: dict[str, Path]) -> None:
    code, out, err = cli("logs", logs["robologs_fmu_v5"])
    assert (code, err) == (0, "")
    lines = out.splitlines()
    assert lines[0].split() == ["stream", "sensor", "rows", "rate", "Hz", "units", "as", "logged"]
    assert lines[1].split() == ["sensor_accel:0", "accelerometer", "10", "1.124", "m/s^2", "raw"]
    assert lines[3].split() == ["sensor_combined:0", "accelerometer", "1737", "194.2", "m/s^2", "corrected"]
    assert lines[4].split() == ["sensor_combined:0", "gyroscope", "1737", "194.2", "rad/s", "corrected"]
    assert "sensor_mag:1       magnetometer   10" in out
    assert any(line.startswith("vehicle_imu: corrected:") and "VehicleIMU.cpp" in line for line in lines)
    assert any(line.startswith("sensor_accel, sensor_gyro, sensor_mag: raw:") for line in lines)


def test_logs_json_says_each_stream_s_units_and_whether_it_is_corrected(logs: dict[str, Path]) -> None:
    code, out, _ = cli("logs", logs["pyulog_sample_log_small"], "--json")
    assert code == 0
    doc = json.loads(out)
    found = {(s["stream"], s["sensor"]): s for s in doc["streams"]}
    assert found[("sensor_accel:2", "accelerometer")]["rows"] == 6
    assert found[("sensor_mag:2", "magnetometer")]["rows"] == 0  # subscribed, never logged
    assert found[("sensor_gyro:1", "gyroscope")] | {"how": ""} == {
        "stream": "sensor_gyro:1",
        "name": "sensor_gyro",
        "instance": 1,
        "sensor": "gyroscope",
        "rows": 6,
        "rate": found[("sensor_gyro:1", "gyroscope")]["rate"],
        "units": "rad/s",
        "corrected": False,
        "how": "",
    }
    assert {k[0] for k, s in found.items() if s["corrected"]} == {f"vehicle_imu:{i}" for i in range(3)} | {
        "sensor_combined:0"
    }
    assert found[("vehicle_imu:1", "accelerometer")]["units"] == "m/s^2"


@pytest.mark.parametrize(
    ("log", "stream", "sensor"),
    [
        ("robologs_fmu_v5", "sensor_accel:1", "accelerometer"),
        ("robologs_fmu_v5", "sensor_gyro:0", "gyroscope"),
        ("robologs_fmu_v5", "sensor_mag:1", "magnetometer"),
        ("robologs_fmu_v5", "sensor_combined:0", "accelerometer"),
        ("robologs_fmu_v5", "sensor_combined", "gyroscope"),
        ("pyulog_sample_log_small", "vehicle_imu:2", "accelerometer"),
        ("pyulog_sample_log_small", "vehicle_imu:0", "gyroscope"),
        ("auterion_esc_status", "sensor_combined:0", "accelerometer"),
    ],
)
def test_a_stream_reads_as_pyulog_reads_it(logs: dict[str, Path], log: str, stream: str, sensor: str) -> None:
    """Every value and time as PX4's own parser gives them (vehicle_imu: the delta over its dt)."""
    name, _, instance = stream.partition(":")
    data = ULog(str(logs[log]), message_name_filter_list=[name]).get_dataset(name, int(instance or 0)).data
    spec = ReadSpec(sensor=sensor, stream=stream, allow_corrected=True)
    table = sources.reader_for(str(logs[log])).read(str(logs[log]), spec, None)  # type: ignore[union-attr]
    fields = {
        ("sensor_combined", "accelerometer"): "accelerometer_m_s2",
        ("sensor_combined", "gyroscope"): "gyro_rad",
        ("vehicle_imu", "accelerometer"): "delta_velocity",
        ("vehicle_imu", "gyroscope"): "delta_angle",
    }.get((name, sensor))
    expected = np.column_stack([data[f"{fields}[{i}]"] if fields else data["xyz"[i]] for i in range(3)]).astype(float)
    clock = data["timestamp_sample" if "timestamp_sample" in data else "timestamp"].astype(float)
    if name == "vehicle_imu":
        dt = data["delta_velocity_dt" if sensor == "accelerometer" else "delta_angle_dt"].astype(float)
        expected = expected / (dt[:, None] * 1e-6)
    if name == "sensor_combined" and sensor == "accelerometer":
        clock = clock + data["accelerometer_timestamp_relative"]
    np.testing.assert_array_equal(table.values, expected)
    np.testing.assert_array_equal(table.clock, clock)
    if "temperature" in data:
        np.testing.assert_array_equal(table.temperature, data["temperature"].astype(float))
    assert table.time_unit == "us"
    assert table.corrected == (name in ("sensor_combined", "vehicle_imu"))


def test_several_instances_and_no_stream_is_exit_2_listing_them(logs: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "cal.json"
    code, stdout, err = cli("solve", "--log", logs["pyulog_sample_log_small"], "-o", out)
    assert (code, stdout) == (2, "")
    assert (
        "holds 3 raw accelerometer streams: sensor_accel:0, sensor_accel:1, sensor_accel:2; give one with --stream"
        in err
    )
    assert "hint: e.g. --stream sensor_accel:0" in err
    assert not out.exists()
    code, _, err = cli("noise", logs["robologs_fmu_v5"], "--sensor", "magnetometer")
    assert code == 2
    assert "2 raw magnetometer streams: sensor_mag:0, sensor_mag:1" in err


def test_a_corrected_stream_is_refused_unless_allowed(logs: dict[str, Path], tmp_path: Path) -> None:
    """The log's only accelerometer stream is PX4's sensor_combined: refused with the reason, read
    with --allow-corrected (this flight has no still block: exit 3, not 2)."""
    log = logs["auterion_esc_status"]
    code, _, err = cli("solve", "--log", log, "-o", tmp_path / "cal.json")
    assert code == 2
    line = err.splitlines()[0]
    assert line.startswith(f"error: {log}: sensor_combined:0 (accelerometer) is already corrected before it was logged")
    assert "msg/SensorCombined.msg" in line
    assert line.endswith("a fit of it calibrates the residual, not the sensor")
    assert "--allow-corrected" in err
    code, _, err = cli("solve", "--log", log, "-o", tmp_path / "cal.json", "--allow-corrected")
    assert code == 3  # read: this flight has no still block
    assert "nothing to calibrate from: 0 still blocks kept" in err
    commands: list[list[str | Path]] = [["noise", log], ["segment", log], ["noise", log, "--sensor", "gyroscope"]]
    for command in commands:
        code, _, err = cli(*command)
        assert code == 2, command
        assert "calibrates the residual, not the sensor" in err
    assert cli("noise", log, "--allow-corrected").code == 0


def test_stream_picks_the_instance_and_the_sensor(logs: dict[str, Path]) -> None:
    log = str(logs["robologs_fmu_v5"])
    one = readings.read_log(log, ReadSpec(stream="sensor_accel:1"))
    zero = readings.read_log(log, ReadSpec(stream="sensor_accel:0"))
    assert one.temperature is not None
    assert zero.temperature is not None
    assert (one.temperature[0], zero.temperature[0]) == (32.0, pytest.approx(39.3, abs=0.1))
    combined = readings.read_log(log, ReadSpec(sensor="gyroscope", stream="sensor_combined", allow_corrected=True))
    assert combined.layout.names[:3] == ["gyr_x", "gyr_y", "gyr_z"]
    assert len(combined.values) == 1737
    for stream, sensor, message in [
        ("sensor_gyro:0", "accelerometer", "sensor_gyro:0 carries gyroscope, not the accelerometer"),
        ("sensor_accel:7", "accelerometer", "the log has no stream sensor_accel:7"),
        ("vehicle_imu", "gyroscope", "vehicle_imu has 2 instances: vehicle_imu:0, vehicle_imu:1; name one"),
    ]:
        with pytest.raises(InputError, match=message) as err:
            readings.read_log(log, ReadSpec(sensor=sensor, stream=stream))
        assert err.value.file == log
    with pytest.raises(InputError, match="sensor_mag:2 has no samples in this log"):
        readings.read_log(str(logs["pyulog_sample_log_small"]), ReadSpec(sensor="magnetometer", stream="sensor_mag:2"))
    assert [s.key for s in tumblecal.streams(log) if s.sensor == "gyroscope"] == [
        "sensor_combined:0",
        "sensor_gyro:0",
        "sensor_gyro:1",
        "vehicle_imu:0",
        "vehicle_imu:1",
    ]


def test_stream_on_a_csv_and_logs_on_a_csv_are_exit_2(tmp_path: Path) -> None:
    csv = str(ROOT / "sample_data" / "x.csv")
    code, _, err = cli("solve", "--poses", csv, "--stream", "sensor_accel:0", "-o", tmp_path / "c.json")
    assert code == 2
    assert "--stream sensor_accel:0: this file is read as a CSV capture" in err
    code, _, err = cli("logs", csv)
    assert code == 2
    assert err.startswith(f"error: {csv}: not a log of a kind tumblecal reads by streams (PX4 ULog, ")


def test_a_log_whose_reader_needs_an_extra_not_installed_is_exit_2_naming_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A reader's module is imported when a file it claims is read; a package it needs that is
    missing is one line saying which pip install brings it."""
    (tmp_path / "fake_bag_reader.py").write_text("import rosbags_not_installed_here\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    entry = sources.Lazy(
        "ROS bag", "fake_bag_reader", magic=(b"#ROSBAG V2.0\n",), extra="ros", needs=("rosbags_not_installed_here",)
    )
    monkeypatch.setattr(sources, "READERS", [entry, *sources.READERS])
    bag = write(tmp_path / "test.bag", b"#ROSBAG V2.0\n" + bytes(100))
    commands: list[list[str | Path]] = [
        ["logs", bag],
        ["solve", "--log", bag, "-o", tmp_path / "c.json"],
        ["noise", bag],
    ]
    for command in commands:
        code, out, err = cli(*command)
        assert (code, out) == (2, ""), command
        assert err == (
            f"error: {bag}: reading a ROS bag needs the rosbags_not_installed_here package, which is not installed\n"
            "hint: pip install 'tumblecal[ros]'\n"
        )


# -- a synthetic session in the real format --------------------------------------------------


@pytest.mark.slow
def test_a_six_face_session_in_a_ulog_solves_as_its_csv_does(tmp_path: Path) -> None:
    log, csv = session(tmp_path)
    from_csv = tumblecal.solve_log(csv, time_unit="us", reference=G, units="m/s^2", input_units="m/s^2")
    from_log = tumblecal.solve_log(log)  # m/s^2: standard gravity and m/s^2 by default, with a note
    assert (from_csv.status, from_log.status) == (0, 0)
    a, b = from_csv.calibration, from_log.calibration
    assert a is not None
    assert b is not None
    assert b.method == a.method == "six-pose"
    np.testing.assert_allclose(b.offset, a.offset, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.matrix, a.matrix, rtol=0, atol=1e-12)
    assert (b.reference, b.units, b.input_units) == (a.reference, a.units, a.input_units) == (G, "m/s^2", "m/s^2")
    assert [p.temperature for p in b.poses] == [p.temperature for p in a.poses]
    assert {p.file for p in b.poses} == {str(log)}
    assert np.allclose(b.gain, [1.01, 0.99, 1.02], atol=2e-3)  # the tumble's own gains: m/s^2 in, m/s^2 out
    assert from_log.notes[0].startswith("sensor_accel:0 is in m/s^2: solved against standard gravity")
    # the command line: the same calibration, and --reference 1 for g
    out = tmp_path / "cli.json"
    code, _, err = cli("solve", "--log", log, "-o", out)
    assert code == 0, err
    assert "note: sensor_accel:0 is in m/s^2" in err
    assert tumblecal.load(str(out)).offset.tolist() == b.offset.tolist()
    in_g = tumblecal.solve_log(log, reference=1.0).calibration
    assert in_g is not None
    assert in_g.units == "g"
    assert np.allclose(in_g.gain, np.array([1.01, 0.99, 1.02]) * G, rtol=2e-3)


@pytest.mark.slow
def test_several_instances_in_a_session_pick_by_stream(tmp_path: Path) -> None:
    log, _ = session(tmp_path, instances=2)
    with pytest.raises(InputError, match="2 raw accelerometer streams: sensor_accel:0, sensor_accel:1"):
        tumblecal.solve_log(log)
    one = tumblecal.solve_log(log, stream="sensor_accel:1").calibration
    zero = tumblecal.solve_log(log, stream="sensor_accel:0").calibration
    assert one is not None
    assert zero is not None
    np.testing.assert_allclose(one.matrix, zero.matrix, rtol=0, atol=1e-12)  # the same readings, 7 µs apart
    done = tumblecal.segment(str(log), stream="sensor_accel:1")
    assert len(done.files) == 6


def test_pyulog_reads_the_test_writer_s_logs(tmp_path: Path) -> None:
    t = np.arange(200, dtype=np.int64) * 2000 + 1_000_000
    xyz = np.random.default_rng(0).normal(0, 1, (200, 3))
    log = ulog_writer.write(tmp_path / "w.ulg", t, xyz, instances=2, sync_every=50)
    parsed = ULog(str(log))
    assert not parsed.file_corruption
    data = parsed.get_dataset("sensor_accel", 1).data
    np.testing.assert_array_equal(data["timestamp_sample"], t + 7)
    np.testing.assert_array_equal(np.column_stack([data["x"], data["y"], data["z"]]), xyz.astype(np.float32))


# -- logs cut short, corrupt, odd ------------------------------------------------------------


def small(tmp_path: Path, rows: int = 2000, sync_every: int = 0) -> tuple[Path, bytes, np.ndarray]:
    """A still +z capture as a ULog: its path, bytes and clock (µs)."""
    t = np.arange(rows, dtype=np.int64) * 2000 + 1_000_000
    xyz = np.tile([0.01, -0.02, G], (rows, 1)) + np.random.default_rng(1).normal(0, 0.01, (rows, 3))
    path = ulog_writer.write(tmp_path / "still.ulg", t, xyz, sync_every=sync_every)
    return path, path.read_bytes(), t


def rewrite(path: Path, data: bytes) -> str:
    path.write_bytes(data)
    ulog.READER.forget()
    return str(path)


def test_a_log_cut_mid_message_is_read_up_to_there_with_a_note(tmp_path: Path) -> None:
    path, data, _ = small(tmp_path)
    cut = rewrite(path, data[:-20])
    log = readings.read_log(cut, ReadSpec())
    assert len(log.values) == 1999
    note = f"{cut}: the log ends mid-message (its last 29 bytes, from byte {len(data) - 49})"
    assert any(n.startswith(note) and "cut short" in n for n in log.layout.notes), log.layout.notes
    code, _, err = cli("noise", cut)
    assert code == 0
    assert "the log ends mid-message" in err
    assert "Traceback" not in err


def test_a_corrupt_stretch_is_skipped_to_the_next_sync_marker(tmp_path: Path) -> None:
    path, data, _ = small(tmp_path, sync_every=100)
    at = data.index(SAMPLE, len(data) // 2)  # a sample's header in the middle: its size and type zeroed
    broken = rewrite(path, data[:at] + bytes(3) + data[at + 3 :])
    log = readings.read_log(broken, ReadSpec())
    assert 1900 <= len(log.values) < 2000
    assert any("skipped a corrupt stretch of" in n and f"at byte {at}" in n for n in log.layout.notes)
    assert cli("noise", broken).code == 0


def test_a_corrupt_message_with_no_sync_marker_after_it_is_exit_2(tmp_path: Path) -> None:
    path, data, _ = small(tmp_path)
    at = data.index(SAMPLE, len(data) // 2)
    broken = rewrite(path, data[:at] + b"\xff\xff\x00" + data[at + 3 :])
    code, out, err = cli("solve", "--log", broken, "-o", tmp_path / "c.json")
    assert (code, out) == (2, "")
    assert err.splitlines()[0] == (
        f"error: {broken}: a corrupt message at byte {at} (type 0x00, 65535 bytes) and no sync marker after it "
        "to resume reading from"
    )
    assert f"head -c {at}" in err
    zeros = rewrite(path, data + bytes(4096))  # space a logger kept and never wrote: a note
    log = readings.read_log(zeros, ReadSpec())
    assert len(log.values) == 2000
    assert any("ends in 4096 bytes of zeros" in n for n in log.layout.notes)


def test_a_message_of_an_unknown_type_is_skipped_with_a_note(tmp_path: Path) -> None:
    path, data, _ = small(tmp_path)
    at = data.index(SAMPLE, len(data) // 2)
    odd = rewrite(path, data[:at] + ulog_writer.message("Z", b"a newer logger's message") + data[at:])
    log = readings.read_log(odd, ReadSpec())
    assert len(log.values) == 2000
    assert f"{odd}: skipped messages of a type this reader does not know ('Z' x1): a newer logger's?" in (
        log.layout.notes
    )
    assert not ULog(odd).file_corruption  # PX4's parser skips it too


def test_a_timestamp_that_jumps_back_once_is_skipped_and_twice_over_is_exit_2(tmp_path: Path) -> None:
    t = np.arange(2000, dtype=np.int64) * 2000 + 1_000_000
    xyz = np.tile([0.0, 0.0, G], (2000, 1))
    stray = t.copy()
    stray[700] = 5  # one corrupt sample
    path = ulog_writer.write(tmp_path / "stray.ulg", stray, xyz)
    log = readings.read_log(str(path), ReadSpec())
    assert len(log.values) == 1999
    assert log.clock is not None
    assert 5.0 not in log.clock
    assert any("1 samples whose timestamp went back skipped" in n and "sample 701" in n for n in log.layout.notes)
    twice = np.concatenate([t[:1000], t[:1000]])  # two sessions in one log
    path = ulog_writer.write(tmp_path / "twice.ulg", twice, xyz)
    code, _, err = cli("segment", path)
    assert code == 2
    assert err.splitlines()[0] == (
        f"error: {path}: sensor_accel:0: the timestamps go back at sample 1001 (1.000000 s after 2.998000 s), "
        "1 times in 2000 samples: not a stray corrupt sample"
    )
    assert "hint: give --rate HZ" in err
    assert cli("noise", path, "--rate", "500").code == 0  # by the rate, the clock is not read


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (b"ULog\x01\x12\x35\x01", "not a PX4 ULog: its first bytes are not ULog's header"),
        (
            ulog_writer.MAGIC + b"\x01" + bytes(8) + ulog_writer.message("B", bytes([0] * 8 + [2] + [0] * 31)),
            "the log sets a ULog flag this reader does not know",
        ),
    ],
)
def test_a_log_that_cannot_be_read_is_one_line(tmp_path: Path, data: bytes, message: str) -> None:
    path = rewrite(tmp_path / "bad.ulg", data)
    for command in (["logs", path], ["solve", "--log", path, "-o", str(tmp_path / "c.json")]):
        code, out, err = cli(*command)
        assert (code, out) == (2, "")
        assert err.startswith(f"error: {path}: {message}")
        assert "Traceback" not in err


# -- the installed command, end to end -------------------------------------------------------


@pytest.mark.slow
def test_the_installed_command_lists_solves_and_verifies_a_ulog(logs: dict[str, Path], tmp_path: Path) -> None:
    done = run_exe(["logs", logs["robologs_fmu_v5"], "--json"], text=True)
    assert done.returncode == 0, done.stderr
    assert len(json.loads(done.stdout)["streams"]) == 12
    log, _ = session(tmp_path)
    cal = tmp_path / "cal.json"
    done = run_exe(["solve", "--log", log, "-o", cal, "--stream", "sensor_accel:0"], text=True)
    assert done.returncode == 0, done.stderr
    assert json.loads(cal.read_text())["units"] == "m/s^2"
    still, _, _ = small(tmp_path)
    done = run_exe(["verify", "--cal", cal, still, "--stream", "sensor_accel:0", "--json"], text=True)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["captures"][0]["samples"] == 2000
    done = run_exe(["verify", "--cal", cal, logs["auterion_esc_status"]], text=True)
    assert done.returncode == 2
    assert "calibrates the residual, not the sensor" in done.stderr


def thermal_sweeps(tmp_path: Path, write: Callable[..., Path], suffix: str) -> list[str]:
    """+z and -z sweeps from 10 to 40 °C with an x offset drift of 0.002 m/s^2/°C, each written
    by ``write(path, t_us, xyz, temperature)`` as a log named ``z+SUFFIX``, ``z-SUFFIX``: the
    thermal command's FACE=FILE arguments."""
    n = 20_000
    t = np.arange(n, dtype=np.int64) * 2000 + 1_000_000
    temp = 10 + 30 * np.arange(n) / n
    rng = np.random.default_rng(2)
    sweeps = []
    for face, sign in (("+z", 1.0), ("-z", -1.0)):
        xyz = np.column_stack(
            [0.01 * G + 0.002 * (temp - 25), np.full(n, -0.02 * G), np.full(n, sign * 1.02 * G + 0.015 * G)]
        )
        xyz = xyz + rng.normal(0, 0.01, (n, 3))
        path = write(tmp_path / f"{face[1]}{face[0]}{suffix}", t, xyz, ulog_writer.float32(temp))
        sweeps.append(f"{face}={path}")
    return sweeps


@pytest.mark.slow
def test_thermal_fits_a_drift_from_ulog_sweeps_with_their_temperature_field(tmp_path: Path) -> None:
    """sensor_accel's temperature field is the temperature column: +z and -z sweeps from 10 to
    40 °C with an x offset drift of 0.002 m/s^2/°C give it back."""
    log, _ = session(tmp_path)
    base = tumblecal.solve_log(log).calibration
    assert base is not None
    done = tumblecal.thermal(thermal_sweeps(tmp_path, ulog_writer.write, ".ulg"), base)
    assert done.calibration.thermal is not None
    assert done.fit.drift.order == 1
    assert done.fit.drift.offset[0][0] == pytest.approx(0.002, abs=1e-4)
    assert done.calibration.thermal.column == "temperature"


def paired_log(tmp_path: Path, rate: float = 1000.0) -> tuple[Path, Path, Path]:
    """A hand-turns session (tests/test_rotations.py's) as CSV and as a ULog: sensor_gyro:0 at
    ``rate`` and sensor_accel:0 at the same rate stamped 0.3 ms later; and the accelerometer's
    calibration the turns take."""
    from tests.test_rotations import ACC_A, ACC_B, synthetic_log

    csv = tmp_path / "hand.csv"
    synthetic_log(csv, np.random.default_rng(5), rate=rate)
    table = np.loadtxt(csv, delimiter=",", skiprows=1)
    t = 1_000_000 + np.round(table[:, 0] * 1e6).astype(np.int64)
    log = ulog_writer.write_streams(
        tmp_path / "hand.ulg",
        [("sensor_gyro", 0, t, table[:, 4:7]), ("sensor_accel", 0, t + 300, table[:, 1:4])],
    )
    acc = tmp_path / "acc.json"
    columns = ["acc_x", "acc_y", "acc_z"]
    tumblecal.Calibration("accelerometer", "six-pose", 1.0, columns, ACC_B, np.linalg.inv(ACC_A), np.diag(ACC_A)).save(
        acc
    )
    return csv, log, acc


@pytest.mark.slow
def test_hand_turns_from_sensor_gyro_and_sensor_accel_solve_and_verify_as_their_csv_does(tmp_path: Path) -> None:
    """The gyroscope's stream and its instance's accelerometer, 0.3 ms apart, put on the same rows:
    the truth recovered as from the CSV (both sensors on one row), by the command and the API."""
    from tests.test_rotations import A, B

    csv, log, acc = paired_log(tmp_path)
    assert {d.name for d in ULog(str(log)).data_list} == {"sensor_gyro", "sensor_accel"}
    solved = {}
    for source in (csv, log):
        out = tmp_path / f"{source.suffix[1:]}.json"
        code, _, err = cli("solve", "--sensor", "gyroscope", "--log", source, "--accel-cal", acc, "-o", out)
        assert code == 0, err
        got = solved[source.suffix] = tumblecal.load(str(out))
        a = np.linalg.inv(got.matrix)  # counts per deg/s
        assert np.abs(a - A).max() < 0.02, source  # 0.1 % of the gain, as the CSV path's test
        assert np.all(np.abs(got.offset - B) < 5 * np.asarray(got.uncertainty["offset"])), source
        assert len(got.rotations or ()) == 16
    assert "the accelerometer is sensor_accel:0 (the instance of sensor_gyro:0), resampled onto its" in err
    assert "sensor_gyro:0: 1 samples outside sensor_accel:0's time span dropped" in err
    by_api = tumblecal.solve_log(log, sensor="gyroscope", accel_cal=acc).calibration
    assert by_api is not None
    np.testing.assert_allclose(by_api.matrix, solved[".ulg"].matrix, rtol=1e-12)
    cal = tmp_path / "ulg.json"
    code, text, err = cli("verify", "--cal", cal, "--log", log, "--accel-cal", acc, "--json")
    assert code == 0, err
    doc = json.loads(text)
    assert len(doc["rotations"]) == 16
    assert doc["rms_error_after_deg"] < 0.1 < doc["rms_error_before_deg"]
    done = tumblecal.verify_rotations(log, cal, accel_cal=acc)
    assert done.overall == {k: v for k, v in doc.items() if k.endswith("_deg")}


def pair(tmp_path: Path, acc_step_us: int = 1000, acc_share: float = 1.0, instance: int = 0) -> Path:
    """sensor_gyro:0 at 1 kHz for 2 s and sensor_accel:``instance`` every ``acc_step_us`` over
    the first ``acc_share`` of it."""
    rng = np.random.default_rng(3)
    t = 1_000_000 + np.arange(2000, dtype=np.int64) * 1000
    ta = 1_000_000 + np.arange(0, int(2_000_000 * acc_share), acc_step_us, dtype=np.int64) + 300
    streams = [("sensor_gyro", 0, t, rng.normal(0, 0.01, (len(t), 3)))]
    streams.append(("sensor_accel", instance, ta, rng.normal(0, 0.01, (len(ta), 3)) + np.array([0, 0, G])))
    return ulog_writer.write_streams(tmp_path / "pair.ulg", streams)


def test_a_paired_read_puts_the_accelerometer_on_the_gyroscope_s_samples(tmp_path: Path) -> None:
    log = pair(tmp_path)
    spec = ReadSpec(sensor="accelerometer", paired=True)
    acc, gyr = readings.read_log(str(log), spec), readings.read_log(str(log), replace(spec, sensor="gyroscope"))
    assert len(acc.values) == len(gyr.values) == 1999  # the first gyroscope sample is before the accelerometer's
    np.testing.assert_array_equal(acc.clock, gyr.clock)
    raw = readings.read_log(str(log), ReadSpec())  # not paired: the accelerometer's own samples
    assert raw.clock is not None
    assert acc.clock is not None
    np.testing.assert_allclose(acc.values[0], raw.values[0] * 0.3 + raw.values[1] * 0.7, rtol=1e-12)
    assert acc.clock[0] == raw.clock[0] + 700


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"acc_step_us": 10_000}, "sensor_accel:0 is logged at 100 Hz, under 25% of sensor_gyro:0's 1000 Hz"),
        ({"acc_share": 0.3}, "sensor_accel:0 and sensor_gyro:0 overlap on 30% of the gyroscope's samples"),
        ({"instance": 1}, "sensor_gyro:0 has no sensor_accel:0 beside it with samples"),
    ],
)
def test_a_pairing_that_cannot_carry_the_turns_is_exit_2(
    tmp_path: Path, kwargs: dict[str, float], message: str
) -> None:
    log = pair(tmp_path, **kwargs)  # type: ignore[arg-type]
    acc = tmp_path / "acc.json"
    tumblecal.Calibration(
        "accelerometer", "six-pose", G, ["acc_x", "acc_y", "acc_z"], np.zeros(3), np.eye(3), np.ones(3)
    ).save(acc)
    out_file = tmp_path / "g.json"
    code, out, err = cli("solve", "--sensor", "gyroscope", "--log", log, "--accel-cal", acc, "-o", out_file)
    assert (code, out) == (2, "")
    assert message in err
    assert "Traceback" not in err
    assert not out_file.exists()
