"""ROS bags and MCAP files read where a capture is read (io.logs.ros through io.sources): real robot
bags listed and read as rosbags' own reader and deserializer read them, --stream and the
raw-or-corrected rule, a synthetic six-face session in each kind of bag that solves as its CSV
does, and the bags that are cut, damaged or odd."""

from __future__ import annotations

import json
import re
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2

import tumblecal_cli as tumblecal
from tests import ros_writer
from tests.conftest import ROOT, run_exe, write
from tests.conftest import tumblecal as cli
from tests.ros_writer import Messages
from tests.test_rotations import ACC_A, ACC_B, synthetic_log
from tests.test_sources import tumble
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import sources
from tumblecal_cli.io.calfiles.calfile import Calibration
from tumblecal_cli.io.csv import readings
from tumblecal_cli.io.logs import ros
from tumblecal_cli.io.readspec import ReadSpec

DATA = ROOT / "tests" / "data" / "ros"
TEST1 = DATA / "test1_cut.bag"
TEST2 = DATA / "test2_cut.bag"
MCAP_BAG = DATA / "test1_mcap_cut"
MCAP_FILE = MCAP_BAG / "test1_mcap_cut.mcap"
G = 9.80665
EPOCH = 1_700_000_000_000_000_000


@pytest.fixture(autouse=True)
def _fresh() -> None:
    ros.READER.forget()  # a bag rewritten in place within a test is read again


def bag(tmp_path: Path, kind: str, topics: dict[str, Messages], name: str = "b", **kwargs: bool) -> str:
    suffix = {"ros1": ".bag", "plain": ".mcap"}.get(kind, "")
    return str(ros_writer.write(tmp_path / f"{name}_{kind}{suffix}", kind, topics, **kwargs))


def still(rows: int = 1000, rate: float = 200.0, seed: int = 1) -> Messages:
    """A unit resting on +z: an Imu topic at ``rate`` from an epoch stamp."""
    rng = np.random.default_rng(seed)
    t = EPOCH + np.round(np.arange(rows) * 1e9 / rate).astype(np.int64)
    acc = np.array([0.1, -0.2, G]) + rng.normal(0, 0.01, (rows, 3))
    return Messages(t, acc, rng.normal(0, 0.001, (rows, 3)))


# -- real bags -------------------------------------------------------------------------------


def test_logs_lists_a_real_bag_s_topics() -> None:
    code, out, err = cli("logs", TEST1)
    assert (code, err) == (0, "")
    lines = out.splitlines()
    assert lines[0].split() == ["stream", "sensor", "rows", "rate", "Hz", "units", "as", "logged"]
    assert lines[1].split() == ["/imu/data", "accelerometer", "360", "30.01", "m/s^2", "corrected"]
    assert lines[2].split() == ["/imu/data", "gyroscope", "360", "30.01", "rad/s", "corrected"]
    assert lines[4].startswith("/imu/data: corrected: imu/data is what imu_tools' filters publish from imu/data_raw")
    assert "complementary_filter_ros.cpp" in lines[4]
    assert len(lines) == 5


@pytest.mark.parametrize("path", [TEST1, TEST2, MCAP_BAG, MCAP_FILE], ids=["ros1", "ros1-sim", "ros2", "mcap"])
def test_logs_json_gives_each_topic_s_sensors(path: Path) -> None:
    code, out, _ = cli("logs", path, "--json")
    assert code == 0
    doc = json.loads(out)
    assert doc["file"] == str(path)
    rows, rate = (300, 50.0) if path == TEST2 else (360, 30.014)
    assert [(s["stream"], s["sensor"], s["units"]) for s in doc["streams"]] == [
        ("/imu/data", "accelerometer", "m/s^2"),
        ("/imu/data", "gyroscope", "rad/s"),
    ]
    for s in doc["streams"]:
        assert (s["instance"], s["rows"], s["rate"], s["corrected"]) == (None, rows, rate, True)


@pytest.mark.parametrize("path", [TEST1, TEST2, MCAP_BAG, MCAP_FILE], ids=["ros1", "ros1-sim", "ros2", "mcap"])
@pytest.mark.parametrize("sensor", ["accelerometer", "gyroscope"])
def test_a_topic_reads_as_rosbags_reads_it(path: Path, sensor: str) -> None:
    """Every value and header stamp as rosbags' AnyReader and deserializer give them."""
    with AnyReader([path]) as reader:
        found = [c for c in reader.connections if c.topic == "/imu/data"]
        msgs = [reader.deserialize(data, c.msgtype) for c, _, data in reader.messages(connections=found)]
    field = "linear_acceleration" if sensor == "accelerometer" else "angular_velocity"
    expected = np.array([[getattr(getattr(m, field), a) for a in "xyz"] for m in msgs])
    stamps = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in msgs])  # type: ignore[attr-defined]
    spec = ReadSpec(sensor=sensor, stream="/imu/data", allow_corrected=True)
    table = sources.reader_for(str(path)).read(str(path), spec, None)  # type: ignore[union-attr]
    np.testing.assert_array_equal(table.values, expected)
    np.testing.assert_array_equal(table.clock, (stamps - stamps[0]) / 1e9)  # seconds from the first stamp
    assert table.time_unit == "s"
    assert table.names == ros.NAMES[sensor]
    assert table.corrected
    assert table.notes[0] == (
        f"{path}: read /imu/data ({sensor}, {len(msgs)} samples, {table.stream.units}, "  # type: ignore[union-attr]
        f"corrected, by its name; time in s from its first header stamp, {stamps[0] // 10**9}."
        f"{stamps[0] % 10**9:09d} s)"
    )


def test_the_ros2_copy_of_a_ros1_bag_reads_the_same() -> None:
    spec = ReadSpec(allow_corrected=True)
    one, two = readings.read_log(str(TEST1), spec), readings.read_log(str(MCAP_BAG), spec)
    np.testing.assert_array_equal(one.values, two.values)
    np.testing.assert_array_equal(one.clock, two.clock)
    assert one.scale == 1.0


def test_a_corrected_topic_is_refused_unless_allowed(tmp_path: Path) -> None:
    code, _, err = cli("solve", "--log", TEST1, "-o", tmp_path / "cal.json")
    assert code == 2
    line = err.splitlines()[0]
    assert line.startswith(f"error: {TEST1}: /imu/data (accelerometer) is already corrected")
    assert line.endswith("a fit of it calibrates the residual, not the sensor")
    assert "--allow-corrected" in err
    assert not (tmp_path / "cal.json").exists()
    code, _, err = cli("noise", TEST1, "--allow-corrected", "--sensor", "gyroscope")
    assert code == 0, err
    assert f"{TEST1}: 360 samples at 30.0117 Hz (12 s)" in err


def test_segment_finds_the_still_period_of_a_real_bag(tmp_path: Path) -> None:
    """test1's robot stands still from about 238.5 to 246 s (2.5 to 10 s into the copy, at 30 Hz):
    with a threshold below the driving's noise, segment finds it, facing +y (its gravity axis)."""
    out = tmp_path / "poses"
    code, _, err = cli("segment", TEST1, "--allow-corrected", "--threshold", "0.05", "-d", out, "-v")
    assert code == 0, err
    kept = [line.split() for line in err.splitlines() if "-> " in line]
    assert [k[-1] for k in kept] == ["block02.csv", "yp.csv"]
    for k in kept:
        first, last = (int(r) for r in k[1].split("-"))
        assert 2.5 * 30 <= first < last <= 10.5 * 30
        assert k[6] == "+y"  # block, rows, start, s, length, s, face
    assert int(kept[1][1].split("-")[1]) - int(kept[1][1].split("-")[0]) > 90  # the longer one: over 3 s
    assert sorted(p.name for p in out.iterdir()) == ["block02.csv", "segments.csv", "yp.csv"]


def test_a_topic_of_another_type_or_a_missing_one_is_exit_2_listing_the_topics(tmp_path: Path) -> None:
    odom = "/husky_velocity_controller/odom"
    code, out, err = cli("noise", TEST1, "--stream", odom)
    assert (code, out) == (2, "")
    assert err.splitlines() == [
        f"error: {TEST1}: {odom} is a nav_msgs/msg/Odometry topic: tumblecal reads sensor_msgs/msg/Imu and "
        "sensor_msgs/msg/MagneticField",
        f"hint: its IMU topics: /imu/data; its other topics: /fix (sensor_msgs/msg/NavSatFix), {odom} "
        "(nav_msgs/msg/Odometry)",
    ]
    code, _, err = cli("noise", TEST1, "--stream", "/imu/data_raw")
    assert code == 2
    assert err.startswith(f"error: {TEST1}: the log has no stream /imu/data_raw\nhint: its streams: /imu/data")
    code, _, err = cli("noise", TEST1, "--stream", "/imu/data", "--sensor", "magnetometer", "--allow-corrected")
    assert code == 2
    assert "/imu/data carries accelerometer, gyroscope, not the magnetometer" in err
    # the leading slash may be left out
    log = readings.read_log(str(TEST1), ReadSpec(stream="imu/data", allow_corrected=True))
    assert len(log.values) == 360


# -- raw or corrected ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("topic", "corrected", "how"),
    [
        ("/imu/data_raw", False, ros._RAW),
        ("/camera/imu_raw", False, ros._RAW),
        ("/imu_raw/data", False, ros._RAW),
        ("/imu/data", True, ros._DATA),
        ("/mavros/imu/data", True, ros._DATA),
        ("/vectornav/imu/data", True, ros._DATA),
        ("/imu/corrected", True, ros._NAMED),
        ("/imu_unbiased/data", True, ros._NAMED),
        ("/imu/mag_calibrated", True, ros._NAMED),
        ("/imu/mag", False, ros._UNTOLD),
        ("/camera/imu", False, ros._UNTOLD),
        ("/sensors/data", False, ros._UNTOLD),
        ("/imu/dataset", False, ros._UNTOLD),
    ],
)
def test_a_topic_s_name_tells_raw_or_corrected(topic: str, corrected: bool, how: str) -> None:
    assert ros.judged(topic) == (corrected, how)


def test_a_topic_whose_name_does_not_say_is_read_as_raw_with_a_note(tmp_path: Path) -> None:
    path = bag(tmp_path, "mcap", {"/camera/imu": still(200)})
    log = readings.read_log(path, ReadSpec())
    assert any("/camera/imu read as raw: its name does not say" in n for n in log.layout.notes)
    [stream] = [s for s in tumblecal.streams(path) if s.sensor == "gyroscope"]
    assert (stream.corrected, stream.how) == (False, ros._UNTOLD)


# -- a synthetic session in each kind of bag -------------------------------------------------


def session(tmp_path: Path, rows: int = 30_000) -> tuple[Messages, Path]:
    """A six-face tumble at 500 Hz in m/s^2 with epoch stamps (ns), and a CSV of the very same
    numbers (the time in s from the first stamp, as a bag is read, and the readings, to 17 digits:
    the float64 values exactly)."""
    t, acc = tumble(rows)
    stamps = EPOCH + np.round(t * 1e9).astype(np.int64)
    values = acc * G
    csv = write(
        tmp_path / "session.csv",
        np.column_stack([(stamps - stamps[0]) / 1e9, values]),
        header="t,acc_x,acc_y,acc_z",
        fmt="%.17g",
    )
    return Messages(stamps, values, np.zeros_like(values)), csv


@pytest.mark.slow
def test_a_six_face_session_in_each_kind_of_bag_solves_as_its_csv_does(tmp_path: Path) -> None:
    messages, csv = session(tmp_path)
    from_csv = tumblecal.solve_log(csv, time_unit="s", reference=G, units="m/s^2", input_units="m/s^2")
    a = from_csv.calibration
    assert from_csv.status == 0
    assert a is not None
    for kind in ros_writer.KINDS:
        path = bag(tmp_path, kind, {"/imu/data_raw": messages})
        from_bag = tumblecal.solve_log(path)  # m/s^2: standard gravity and m/s^2 by default, with a note
        b = from_bag.calibration
        assert from_bag.status == 0, kind
        assert b is not None
        assert b.method == a.method == "six-pose"
        np.testing.assert_allclose(b.offset, a.offset, rtol=0, atol=1e-12)
        np.testing.assert_allclose(b.matrix, a.matrix, rtol=0, atol=1e-12)
        assert (b.reference, b.units, b.input_units) == (G, "m/s^2", "m/s^2")
        assert b.columns == ["acc_x", "acc_y", "acc_z"]
        assert [p.times for p in b.poses] == [p.times for p in a.poses]
        assert from_bag.notes[0].startswith("/imu/data_raw is in m/s^2: solved against standard gravity")
    assert np.allclose(a.gain, [1.01, 0.99, 1.02], atol=2e-3)


@pytest.mark.slow
def test_hand_turns_in_a_bag_s_imu_topic_solve_as_their_csv_does(tmp_path: Path) -> None:
    """solve --sensor gyroscope --accel-cal reads both sensors of one Imu topic, on the same rows."""
    csv = tmp_path / "hand.csv"
    synthetic_log(csv, np.random.default_rng(5))
    table = np.loadtxt(csv, delimiter=",", skiprows=1)
    stamps = EPOCH + np.round(table[:, 0] * 1e9).astype(np.int64)
    path = bag(tmp_path, "ros1", {"/imu/data_raw": Messages(stamps, table[:, 1:4], table[:, 4:7])})
    acc = tmp_path / "acc.json"
    Calibration(
        "accelerometer", "six-pose", 1.0, ["acc_x", "acc_y", "acc_z"], ACC_B, np.linalg.inv(ACC_A), np.diag(ACC_A)
    ).save(acc)
    from_csv, from_bag = tmp_path / "csv.json", tmp_path / "bag.json"
    for log, out in ((csv, from_csv), (path, from_bag)):
        code, _, err = cli("solve", "--sensor", "gyroscope", "--log", log, "--accel-cal", acc, "-o", out)
        assert code == 0, err
    a, b = tumblecal.load(str(from_csv)), tumblecal.load(str(from_bag))
    assert b.method == a.method == "rotations"
    np.testing.assert_allclose(b.offset, a.offset, rtol=0, atol=1e-9)
    np.testing.assert_allclose(b.matrix, a.matrix, rtol=1e-9, atol=0)
    assert b.input_units == "rad/s"


@pytest.mark.slow
def test_several_topics_and_no_stream_is_exit_2_listing_them(tmp_path: Path) -> None:
    path = bag(tmp_path, "ros1", {"/imu/data_raw": still(), "/imu2/data_raw": still(seed=2), "/imu/data": still()})
    code, out, err = cli("solve", "--log", path, "-o", tmp_path / "c.json")
    assert (code, out) == (2, "")
    assert "holds 2 raw accelerometer streams: /imu/data_raw, /imu2/data_raw; give one with --stream" in err
    assert "hint: e.g. --stream /imu/data_raw" in err
    assert not (tmp_path / "c.json").exists()
    log = readings.read_log(path, ReadSpec(sensor="gyroscope", stream="/imu2/data_raw"))
    np.testing.assert_array_equal(log.values, still(seed=2).gyro)
    code, _, err = cli("noise", path, "--stream", "/imu2/data_raw", "--sensor", "gyroscope")
    assert code == 0
    assert f"{path}: 1000 samples at 200 Hz (5 s)" in err


def test_a_command_opens_the_bag_once_and_decodes_only_the_topic_it_reads(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = bag(tmp_path, "ros1", {"/imu/data_raw": still(), "/imu2/data_raw": still(seed=2)})
    opened: list[str] = []
    real = ros._sources

    def sources_of(path: str, kind: str, notes: list[str]) -> list[ros._Source]:
        opened.append(path)
        return real(path, kind, notes)

    monkeypatch.setattr(ros, "_sources", sources_of)
    code, _, err = cli("noise", path, "--stream", "/imu2/data_raw")  # picks the stream, then reads it
    assert code == 0, err
    assert opened == [path]
    found = ros.index(path)
    assert [(t.name, t.decoded) for t in found.topics] == [("/imu/data_raw", False), ("/imu2/data_raw", True)]
    listed = tumblecal.streams(path)  # the listing decodes the rest (for their rates), in one more pass
    assert opened == [path, path]
    assert [(s.key, s.rows, round(s.rate or 0)) for s in listed if s.sensor == "gyroscope"] == [
        ("/imu/data_raw", 1000, 200),
        ("/imu2/data_raw", 1000, 200),
    ]
    assert len(readings.read_log(path, ReadSpec(stream="/imu/data_raw")).values) == 1000
    assert len(opened) == 2


def test_a_topic_none_of_whose_messages_is_of_its_type_s_layout_is_exit_2(tmp_path: Path) -> None:
    path = tmp_path / "odd"
    with Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:  # MagneticField bytes typed Imu
        c = writer.add_connection("/imu/data_raw", ros_writer.IMU, typestore=ros_writer.ROS2)
        for k in range(10):
            writer.write(
                c, EPOCH + k, ros_writer.serialize(ros_writer.ROS2, ros_writer.MAG, EPOCH + k, "m", (1, 2, 3), ())
            )
    code, _, err = cli("noise", path)
    assert code == 2
    assert err.splitlines()[0] == (
        f"error: {path}: none of the 10 messages of /imu/data_raw could be read: none is of the layout of "
        "sensor_msgs/msg/Imu (a type of the same name defined otherwise?)"
    )


def test_a_magnetometer_topic_in_tesla(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    field = rng.normal(0, 3e-5, (400, 3))
    mag = Messages(EPOCH + np.arange(400, dtype=np.int64) * 10_000_000, field, msgtype=ros_writer.MAG)
    path = bag(tmp_path, "sqlite3", {"/imu/mag": mag, "/imu/data_raw": still()})
    streams = {(s.key, s.sensor): s for s in tumblecal.streams(path)}
    assert streams[("/imu/mag", "magnetometer")].units == "T"
    assert streams[("/imu/mag", "magnetometer")].rate == pytest.approx(100.0)
    log = readings.read_log(path, ReadSpec(sensor="magnetometer"))
    np.testing.assert_array_equal(log.values, field)
    assert log.layout.names[:3] == ["mag_x", "mag_y", "mag_z"]


def test_big_endian_cdr_messages_decode_as_rosbags_reads_them() -> None:
    store = ros_writer.ROS2
    msg = store.deserialize_cdr(
        ros_writer.serialize(store, ros_writer.IMU, 5 * 10**9 + 7, "imu", (1, 2, 3), (4, 5, 6)), ros_writer.IMU
    )
    big = bytes(store.serialize_cdr(msg, ros_writer.IMU, little_endian=False))
    little = ros_writer.serialize(store, ros_writer.IMU, 6 * 10**9, "a_longer_frame", (7, 8, 9), (1, 1, 1))
    sizes = np.array([len(big), len(little)], dtype=np.int64)
    stamps, values, ok = ros.decode(big + little, sizes, True, 296, (200, 104))
    assert ok.tolist() == [True, True]
    assert stamps.tolist() == [5 * 10**9 + 7, 6 * 10**9]
    assert values.tolist() == [[1, 2, 3, 4, 5, 6], [7, 8, 9, 1, 1, 1]]


# -- bags cut short, damaged, odd ------------------------------------------------------------


def test_a_ros1_bag_cut_short_is_read_up_to_the_cut_as_rosbag_reindex_would(tmp_path: Path) -> None:
    """A recording cut short has no index (rosbag writes it last): its records are read one after
    another, up to where the file ends."""
    whole = readings.read_log(str(TEST1), ReadSpec(allow_corrected=True))
    cut = write(tmp_path / "cut.bag", TEST1.read_bytes()[:30_000])
    log = readings.read_log(str(cut), ReadSpec(allow_corrected=True))
    assert len(log.values) == 195
    np.testing.assert_array_equal(log.values, whole.values[:195])
    np.testing.assert_array_equal(log.clock, whole.clock[:195])  # type: ignore[index]
    assert (
        f"{cut}: the ROS 1 bag has no index (a recording cut short?): its records read one after another, up to "
        "byte 29925, where it is cut short, as rosbag reindex would"
    ) in log.layout.notes
    code, out, _ = cli("logs", cut)
    assert code == 0
    assert out.splitlines()[1].split()[:3] == ["/imu/data", "accelerometer", "195"]
    data = TEST1.read_bytes()  # the index position left at zero, as rosbag record leaves it until it closes
    at = data.index(b"index_pos=") + len(b"index_pos=")
    unindexed = write(tmp_path / "unindexed.bag", data[:at] + bytes(8) + data[at + 8 :])
    log = readings.read_log(str(unindexed), ReadSpec(allow_corrected=True))
    np.testing.assert_array_equal(log.values, whole.values)
    assert log.layout.notes[-1].endswith("its records read one after another, as rosbag reindex would")
    first = data.index(b"BZh")  # and a damaged chunk in one: read up to it
    broken = write(
        tmp_path / "broken.bag", data[:at] + bytes(8) + data[at + 8 : first + 100] + bytes(40) + data[first + 140 :]
    )
    code, _, err = cli("noise", broken, "--allow-corrected")  # the first chunk: no connection before it
    assert code == 2
    found = re.fullmatch(
        rf"error: {re.escape(str(broken))}: the ROS 1 bag has no index, and no connection record up to the chunk at "
        r"byte (\d+), which cannot be read \(Invalid data stream\): nothing to read",
        err.splitlines()[0],
    )
    assert found is not None
    assert first - 100 < int(found[1]) < first  # the chunk record's header, just before its bz2 data
    code, _, err = cli("logs", write(tmp_path / "garbage.bag", b"#ROSBAG V2.0\n" + bytes(range(256)) * 4))
    assert code == 2
    assert "cannot read this ROS 1 bag: Header could not be read from file." in err


def test_a_ros1_bag_of_lz4_chunks_without_its_index_reads_as_with_it(tmp_path: Path) -> None:
    path = Path(bag(tmp_path, "ros1", {"/imu/data_raw": still(2000)}, compressed=True))
    indexed = readings.read_log(str(path), ReadSpec())
    data = path.read_bytes()
    at = data.index(b"index_pos=") + len(b"index_pos=")
    write(path, data[:at] + bytes(8) + data[at + 8 :])
    log = readings.read_log(str(path), ReadSpec())
    np.testing.assert_array_equal(log.values, indexed.values)
    np.testing.assert_array_equal(log.clock, indexed.clock)
    assert any("has no index" in n for n in log.layout.notes)


@pytest.mark.slow
def test_a_ros2_recording_cut_short_is_read_up_to_the_cut_as_mcap_recover_would(tmp_path: Path) -> None:
    """A ROS 2 recording stopped by a power loss: no metadata.yaml, and its MCAP file without the
    summary and footer written last: its whole chunks are read, with notes."""
    folder = Path(bag(tmp_path, "mcap", {"/imu/data_raw": still(8000)}, compressed=True))  # 4 zstd chunks
    whole = readings.read_log(str(folder), ReadSpec())
    (folder / "metadata.yaml").unlink()
    mcap = next(folder.glob("*.mcap"))
    data = mcap.read_bytes()
    write(mcap, data[: len(data) * 3 // 4])
    log = readings.read_log(str(folder), ReadSpec())
    assert 3000 < len(log.values) < 8000
    np.testing.assert_array_equal(log.values, whole.values[: len(log.values)])
    np.testing.assert_array_equal(log.clock, whole.clock[: len(log.values)])  # type: ignore[index]
    assert any("no metadata.yaml (a recording cut short?)" in n for n in log.layout.notes)
    note = f"{folder}: its {mcap.name} has no summary (a recording cut short?): its records read one after another, "
    assert any(
        n.startswith(note) and n.endswith("where it is cut short, as mcap recover would") for n in log.layout.notes
    )


def test_an_mcap_file_cut_in_its_first_chunk_is_exit_2(tmp_path: Path) -> None:
    cut = write(tmp_path / "cut.mcap", MCAP_FILE.read_bytes()[:100_000])  # one chunk of 240 kB: nothing whole
    code, out, err = cli("noise", cut)
    assert (code, out) == (2, "")
    assert err.splitlines() == [
        f"error: {cut}: the MCAP file has no summary, and no channel record up to byte 43, where it is cut short: "
        "nothing to read",
        "hint: check that the file is whole (its size, a copy that finished)",
    ]
    code, _, err = cli("logs", write(tmp_path / "tiny.mcap", MCAP_FILE.read_bytes()[:12]))
    assert code == 2
    assert err.splitlines()[1] == (
        "hint: the file was cut short: mcap recover FILE -o FIXED.mcap (the MCAP command line tool) rewrites it whole"
    )


def test_a_damaged_chunk_is_read_up_to_with_a_note_and_the_first_one_is_exit_2(tmp_path: Path) -> None:
    data = TEST1.read_bytes()
    later = data.index(b"BZh", len(data) // 2)  # a bz2 chunk half way through the bag
    broken = write(tmp_path / "broken.bag", data[: later + 100] + bytes(40) + data[later + 140 :])
    log = readings.read_log(str(broken), ReadSpec(allow_corrected=True))
    assert 0 < len(log.values) < 360
    note = f"{broken}: the ROS 1 bag cannot be read past its first {len(log.values)} messages of /imu/data"
    assert any(n.startswith(note) and n.endswith("read up to there") for n in log.layout.notes), log.layout.notes
    first = data.index(b"BZh")
    broken = write(tmp_path / "first.bag", data[: first + 100] + bytes(40) + data[first + 140 :])
    code, _, err = cli("noise", broken, "--allow-corrected")
    assert code == 2
    assert err.startswith(f"error: {broken}: cannot read this ROS 1 bag: ")
    assert "Traceback" not in err


def test_a_message_not_of_the_layout_is_skipped_with_a_note(tmp_path: Path) -> None:
    path = bag(tmp_path, "ros1", {"/imu/data_raw": still(300)})
    data = Path(path).read_bytes()
    one = ros_writer.serialize(ros_writer.ROS1, ros_writer.IMU, EPOCH + 150 * 5_000_000, "imu_link", *([0.0] * 3,) * 2)
    at = data.index(one[4:16])  # message 151 (its stamp and frame_id length): its frame_id's length made wrong
    write(Path(path), data[: at + 8] + b"\x09" + data[at + 9 :])
    log = readings.read_log(path, ReadSpec())
    assert len(log.values) == 299
    assert f"{path}: /imu/data_raw: 1 messages not of the layout of sensor_msgs/msg/Imu skipped (corrupt?)" in (
        log.layout.notes
    )


def test_a_topic_with_no_messages_is_exit_2_naming_it_and_listing_the_others(tmp_path: Path) -> None:
    empty = Messages(np.zeros(0, dtype=np.int64), np.zeros((0, 3)))
    path = bag(tmp_path, "mcap", {"/imu/data_raw": empty, "/imu2/data_raw": still()})
    code, _, err = cli("noise", path, "--stream", "/imu/data_raw")
    assert code == 2
    assert err.splitlines()[:2] == [
        f"error: {path}: /imu/data_raw has no samples in this log",
        "hint: its streams: /imu2/data_raw",
    ]
    assert len(readings.read_log(path, ReadSpec()).values) == 1000  # the one topic with messages
    only = bag(tmp_path, "ros1", {"/imu/data_raw": empty}, name="only")
    code, _, err = cli("noise", only)
    assert code == 2
    assert err.startswith(f"error: {only}: the log holds no accelerometer stream with samples\nhint: its streams: none")
    none = bag(tmp_path, "sqlite3", {}, name="none")
    code, _, err = cli("segment", none)
    assert code == 2
    assert err.splitlines() == [
        f"error: {none}: the ROS 2 bag has no sensor_msgs/msg/Imu or sensor_msgs/msg/MagneticField topic",
        "hint: its IMU topics: none; its other topics: /odom (nav_msgs/msg/Odometry)",
    ]


def test_a_stamp_that_jumps_back_once_is_skipped_and_a_clock_restarted_is_exit_2(tmp_path: Path) -> None:
    m = still(2000)
    m.received = m.stamps + 2_000_000  # recorded in order
    m.stamps[700] = EPOCH - 10**9  # one corrupt stamp
    path = bag(tmp_path, "mcap", {"/imu/data_raw": m})
    log = readings.read_log(path, ReadSpec())
    assert len(log.values) == 1999
    assert any(
        "1 messages whose header stamp went back skipped (a corrupt message; the first at message 701)" in n
        for n in log.layout.notes
    )
    twice = still(2000)
    twice.received = twice.stamps + 2_000_000
    twice.stamps[1000:] = twice.stamps[:1000]  # a simulation restarted: the clock again from the start
    path = bag(tmp_path, "ros1", {"/imu/data_raw": twice}, name="twice")
    code, _, err = cli("segment", path)
    assert code == 2
    assert err.splitlines()[0] == (
        f"error: {path}: /imu/data_raw: the header stamps go back at message 1001 (1700000000.000000 s after "
        "1700000004.995000 s), 1 times in 2000 messages: not a stray corrupt message"
    )
    assert "hint: give --rate HZ" in err
    assert cli("noise", path, "--rate", "200").code == 0


def test_zero_header_stamps_are_read_by_the_record_times(tmp_path: Path) -> None:
    m = still(500)
    received = m.stamps + 3_000_000
    unset = Messages(np.zeros(500, dtype=np.int64), m.xyz, m.gyro, received=received)
    path = bag(tmp_path, "ros1", {"/imu/data_raw": unset})
    log = readings.read_log(path, ReadSpec())
    np.testing.assert_array_equal(log.clock, (received - received[0]) / 1e9)
    assert f"{path}: /imu/data_raw: every header stamp is zero: read by the bag's record times instead" in (
        log.layout.notes
    )
    assert log.layout.notes[0].endswith("raw; time in s from its first record time, 1700000000.003000000 s)")
    assert tumblecal.streams(path)[0].rate == pytest.approx(200.0)
    some = Messages(m.stamps.copy(), m.xyz, m.gyro)
    some.stamps[:3] = 0  # a driver that stamps from its fourth message on
    path = bag(tmp_path, "mcap", {"/imu/data_raw": some}, name="some")
    log = readings.read_log(path, ReadSpec())
    assert len(log.values) == 497
    assert f"{path}: /imu/data_raw: 3 messages with a zero header stamp skipped" in log.layout.notes


def test_a_ros2_bag_folder_without_its_metadata_reads_its_storage_files(tmp_path: Path) -> None:
    folder = tmp_path / "recording"
    shutil.copytree(MCAP_BAG, folder)
    (folder / "metadata.yaml").unlink()
    log = readings.read_log(str(folder), ReadSpec(allow_corrected=True))
    assert len(log.values) == 360
    assert any(
        "no metadata.yaml (a recording cut short?): read its test1_mcap_cut.mcap directly" in n
        for n in log.layout.notes
    )
    (folder / "test1_mcap_cut.mcap").unlink()
    (folder / "notes.txt").write_text("not a bag")
    assert sources.reader_for(str(folder)) is None  # a folder of neither: read as a CSV, which says so


def test_a_sqlite3_file_of_a_bag_is_read_by_itself(tmp_path: Path) -> None:
    folder = Path(bag(tmp_path, "sqlite3", {"/imu/data_raw": still(300)}))
    db3 = next(folder.glob("*.db3"))
    log = readings.read_log(str(db3), ReadSpec())
    assert len(log.values) == 300
    other = write(tmp_path / "other.sqlite", db3.read_bytes())
    assert sources.reader_for(str(other)) is None  # an sqlite3 file not named .db3 is not claimed


def test_a_bag_without_rosbags_installed_is_exit_2_naming_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    """rosbags not importable (the [ros] extra not installed): one line saying which pip install
    brings it, whatever the command."""
    for name in [n for n in sys.modules if n.partition(".")[0] == "rosbags"] + ["rosbags"]:
        monkeypatch.setitem(sys.modules, name, None)  # import rosbags...: ModuleNotFoundError
    monkeypatch.delitem(sys.modules, "tumblecal_cli.io.logs.ros", raising=False)
    commands: list[list[str | Path]] = [["logs", TEST1], ["noise", MCAP_BAG], ["solve", "--log", TEST2, "-o", "c.json"]]
    for command in commands:
        code, out, err = cli(*command)
        assert (code, out) == (2, ""), command
        assert err.splitlines()[1:] == ["hint: pip install 'tumblecal[ros]'"]
        assert err.splitlines()[0].endswith(
            ": reading a ROS bag or MCAP file needs the rosbags package, which is not installed"
        )
    assert "tumblecal_cli.io.logs.ros" not in sys.modules


# -- the installed command, end to end -------------------------------------------------------


@pytest.mark.slow
def test_the_installed_command_lists_and_solves_a_bag(tmp_path: Path) -> None:
    done = run_exe(["logs", MCAP_BAG, "--json"], text=True)
    assert done.returncode == 0, done.stderr
    assert [s["stream"] for s in json.loads(done.stdout)["streams"]] == ["/imu/data", "/imu/data"]
    messages, _ = session(tmp_path)
    path = bag(tmp_path, "mcap", {"/imu/data_raw": messages, "/imu/data": messages})
    cal = tmp_path / "cal.json"
    done = run_exe(["solve", "--log", path, "-o", cal], text=True)
    assert done.returncode == 0, done.stderr
    assert "note: /imu/data_raw is in m/s^2" in done.stderr
    assert json.loads(cal.read_text())["input_units"] == "m/s^2"
    done = run_exe(["noise", TEST1, "--allow-corrected"], text=True)
    assert done.returncode == 3, done.stderr  # the robot drives off at the end of the copy
    assert "not a still capture" in done.stderr


def test_a_stream_that_is_no_stream_is_an_input_error() -> None:
    with pytest.raises(InputError, match="--stream takes NAME"):
        readings.read_log(str(TEST1), ReadSpec(stream=" "))
