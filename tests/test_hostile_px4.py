"""Hostile autopilot logs (issue "Hostile input, round 3"): PX4 ULog and ArduPilot DataFlash
files whose declared counts, lengths, offsets, numbers and definitions are crafted. Each is one
error line naming the file, the byte (a text log's line) and the field, exit 2, or where the
log's own parser recovers, read with a note. Each test is named for the defect it pins, and
failed before its fix."""

from __future__ import annotations

import struct
import sys
from pathlib import Path

import numpy as np
import pytest

from tests import dataflash_writer, ulog_writer
from tests.conftest import assert_one_error, limited
from tests.conftest import tumblecal as cli

G = 9.80665
ACCEL = ulog_writer.FORMATS["sensor_accel"]
#: The byte the first 'F' message is at in :func:`ulog`'s logs (header 16, flag bits 43).
FIRST_FORMAT = 59


def ulog(
    path: Path,
    accel: str = ACCEL,
    *,
    topic: str = "sensor_accel",
    flags: bytes = bytes(40),
    before: bytes = b"",
    after: bytes = b"",
    subscriptions: bytes | None = None,
) -> Path:
    """A ULog of 400 still sensor_accel samples whose format is ``accel`` (logged as ``topic``),
    with these flag bits, messages ``before`` the format and ``after`` it (before the subscription)."""
    t = np.arange(400, dtype=np.int64) * 2000 + 1_000_000
    xyz = np.tile([0.0, 0.0, G], (400, 1))
    head = ulog_writer.MAGIC + b"\x01" + bytes(8) + ulog_writer.message("B", flags)
    formats = before + ulog_writer.message("F", f"{topic}:{accel}".encode()) + after
    subscribed = ulog_writer.subscribe(10, topic) if subscriptions is None else subscriptions
    body = ulog_writer.samples(10, "sensor_accel", t, xyz, np.full(len(t), 25.0))
    path.write_bytes(head + formats + subscribed + b"".join(body))
    return path


# -- PX4 ULog: declared counts ------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.skipif(sys.platform != "linux", reason="RLIMIT_AS bounds the address space on Linux")
@pytest.mark.parametrize("command", ["logs", "solve", "segment", "noise"])
def test_a_ulog_array_count_of_2_to_the_40_is_refused_before_it_is_allocated(tmp_path: Path, command: str) -> None:
    """Before: the layout of sensor_accel was a list of 2**40 field names; each command grew to
    the limit and died ('internal error: MemoryError', killed without one)."""
    path = ulog(tmp_path / "huge.ulg", "uint64_t timestamp;float[1099511627776] x;float y;float z;")
    args: dict[str, list[str | Path]] = {
        "logs": ["logs", path],
        "solve": ["solve", "--log", path, "-o", tmp_path / "c.json"],
    }
    r = limited(*args.get(command, [command, path]))
    assert "internal error" not in r.err
    assert_one_error(
        r,
        f"{path}: the format of sensor_accel (the 'F' message at byte {FIRST_FORMAT}): field 'x' has the array "
        "count '1099511627776': more than a message holds (65533)",
    )
    assert not (tmp_path / "c.json").exists()


def test_a_topic_that_lays_out_more_than_a_message_holds_is_refused(tmp_path: Path) -> None:
    """Before: a count under 65536 passed, and a layout past 65535 bytes (which no message can
    hold) read every sample as short: a stream of 0 samples."""
    path = ulog(tmp_path / "wide.ulg", "uint64_t timestamp;float x;float y;float z;double[8191] more;")
    assert_one_error(
        cli("logs", path),
        f"{path}: the format of sensor_accel (the 'F' message at byte {FIRST_FORMAT}): field 'more' (double[8191]) "
        "ends at byte 65548 of a sample, more than a message holds (65533 after its msg_id): no sample of it can "
        "be logged",
    )


@pytest.mark.slow
def test_nested_arrays_of_an_empty_type_are_not_walked_element_by_element(tmp_path: Path) -> None:
    """Before: 65533 elements of a type of 65533 elements of a type of no fields was 4.3e9 Python
    steps: the command ran for hours. Now a type is laid out once, and one of no fields adds none."""
    nested = ulog_writer.message("F", b"empty:") + ulog_writer.message("F", b"wide:empty[65533] a;")
    path = ulog(tmp_path / "nested.ulg", ACCEL + "wide[65533] b;", before=nested)
    r = limited("noise", path, timeout=30)
    assert r.code == 0, r.err
    assert "read sensor_accel:0 (accelerometer, 400 samples" in r.err


@pytest.mark.parametrize(
    ("count", "what"),
    [
        ("²", "not a number (ASCII digits)"),
        ("٣", "not a number (ASCII digits)"),
        ("3_0", "not a number (ASCII digits)"),
        ("-1", "not a number (ASCII digits)"),
        ("9" * 5000, "more than a message holds (65533)"),
    ],
    ids=["superscript", "arabic-indic", "underscore", "negative", "5000-digits"],
)
def test_an_array_count_that_is_no_ascii_number_is_refused_naming_the_field(
    tmp_path: Path, count: str, what: str
) -> None:
    """Before: '²' passed str.isdigit and int('²') raised ('internal error: ValueError'); 5000
    nines were 'internal error: ValueError: Exceeds the limit (4300 digits)'; '٣' read as 3 and
    '3_0' as 30; '-1' read as no array at all, the fields after it at the wrong offsets."""
    path = ulog(tmp_path / "count.ulg", ACCEL.replace("uint8_t[3] clip_counter", f"uint8_t[{count}] clip_counter"))
    shown = repr(count) if len(count) < 24 else "'999999999999'... (5000 characters)"
    assert_one_error(
        cli("noise", path),
        f"{path}: the format of sensor_accel (the 'F' message at byte {FIRST_FORMAT}): field 'clip_counter' has the "
        f"array count {shown}: {what}",
    )


def test_a_bad_count_in_a_topic_not_read_is_left_alone(tmp_path: Path) -> None:
    other = ulog_writer.message("F", b"battery_status:uint64_t timestamp;float[\xc2\xb2] voltage_cell_v;")
    r = cli("noise", ulog(tmp_path / "other.ulg", before=other))
    assert r.code == 0, r.err


# -- PX4 ULog: offsets -------------------------------------------------------------------------


def _appended(*offsets: int) -> bytes:
    """Flag bits that say the log has appended data at ``offsets``."""
    return bytes(8) + bytes([1]) + bytes(7) + struct.pack("<3Q", *offsets, *[0] * (3 - len(offsets)))


@pytest.mark.parametrize("offset", [2**63, 2**64 - 1, 10**9])
def test_an_appended_data_offset_past_the_end_is_a_note_not_an_internal_error(tmp_path: Path, offset: int) -> None:
    """Before: past 2**63 f.seek raised ('internal error: ValueError: cannot fit 'int' into an
    offset-sized integer'); below it, seeking past the end was silent. pyulog reads the log to
    its end (and marks 2**63 corrupt): read to the end with a note naming the field."""
    path = ulog(tmp_path / "appended.ulg", flags=_appended(offset))
    r = cli("noise", path)
    assert r.code == 0, r.err
    size = path.stat().st_size
    assert (
        f"note: {path}: the flag bits' appended-data offset 1 (the field at byte 35) is {offset}, past the log's "
        f"end ({size} bytes): read to its end"
    ) in r.err.splitlines()
    assert "read sensor_accel:0 (accelerometer, 400 samples" in r.err


def test_an_appended_data_offset_before_the_messages_is_refused(tmp_path: Path) -> None:
    """Before: an offset inside the header walked the log again from there, its samples twice
    (or its bytes as messages)."""
    path = ulog(tmp_path / "back.ulg", flags=_appended(5000, 20))
    assert_one_error(
        cli("noise", path),
        f"{path}: the flag bits' appended-data offset 2 (the field at byte 43) is 20, before the log's messages "
        "start (byte 59): a corrupt flag bits message",
    )


# -- PX4 ULog: fields looked up by name, definitions given twice -----------------------------------

COMBINED = (
    "uint64_t timestamp;float[3] gyro_rad;uint32_t gyro_integral_dt;float[3] accelerometer_m_s2;"
    "uint32_t accelerometer_integral_dt;"
)


def test_sensor_combined_without_its_accelerometer_relative_timestamp_is_one_error(tmp_path: Path) -> None:
    """Before: 'internal error: KeyError: 'accelerometer_timestamp_relative''."""
    path = ulog(tmp_path / "combined.ulg", COMBINED, topic="sensor_combined")
    expected = (
        f"{path}: sensor_combined:0: the format of sensor_combined (the 'F' message at byte {FIRST_FORMAT}) has no "
        "field 'accelerometer_timestamp_relative', the accelerometer's time after timestamp: its accelerometer "
        "cannot be read"
    )
    assert_one_error(cli("noise", path, "--stream", "sensor_combined:0", "--allow-corrected"), expected)
    gyro = cli("noise", path, "--stream", "sensor_combined:0", "--sensor", "gyroscope", "--allow-corrected")
    assert gyro.code == 0, gyro.err  # its gyroscope needs no relative timestamp


def test_a_format_with_no_timestamp_is_one_error_naming_it(tmp_path: Path) -> None:
    """Before: 'internal error: KeyError: 'timestamp'' from logs and from every read."""
    path = ulog(tmp_path / "stampless.ulg", ACCEL.replace("timestamp", "stamp"))
    r = cli("logs", path)
    assert r.code == 0, r.err
    assert "sensor_accel:0" in r.out
    assert_one_error(
        cli("noise", path),
        f"{path}: sensor_accel:0: the format of sensor_accel (the 'F' message at byte {FIRST_FORMAT}) has no field "
        "'timestamp', the samples' time (the format has neither timestamp_sample nor timestamp): its accelerometer "
        "cannot be read",
    )


@pytest.mark.parametrize("where", ["before", "after"])
def test_two_formats_of_a_topic_that_differ_are_refused(tmp_path: Path, where: str) -> None:
    """Before: the second replaced the first ('internal error: KeyError: 'timestamp'' when it
    came before the subscription; after it, silently ignored)."""
    second = ulog_writer.message("F", b"sensor_accel:uint32_t stamp;float x;float y;float z;")
    path = ulog(tmp_path / "twice.ulg", after=second if where == "before" else b"")
    if where == "after":  # the second format after the subscription
        data = path.read_bytes()
        at = data.index(ulog_writer.subscribe(10, "sensor_accel")) + len(ulog_writer.subscribe(10, "sensor_accel"))
        path.write_bytes(data[:at] + second + data[at:])
    formats = [i for i in range(len(path.read_bytes())) if path.read_bytes().startswith(b"sensor_accel:", i)]
    assert_one_error(
        cli("noise", path),
        f"{path}: the format of sensor_accel (the 'F' message at byte {FIRST_FORMAT}) and a second one of "
        f"sensor_accel, at byte {formats[1] - 3}, differ: which one its samples follow cannot be told",
    )


def test_the_same_format_given_twice_reads(tmp_path: Path) -> None:
    again = ulog_writer.message("F", f"sensor_accel:{ACCEL}".encode())
    r = cli("noise", ulog(tmp_path / "again.ulg", after=again))
    assert r.code == 0, r.err


def test_a_topic_instance_subscribed_twice_is_refused(tmp_path: Path) -> None:
    """Before: two streams both called sensor_accel:0, which --stream could not tell apart."""
    twice = ulog_writer.subscribe(10, "sensor_accel") + ulog_writer.subscribe(11, "sensor_accel")
    path = ulog(tmp_path / "twice.ulg", subscriptions=twice)
    at = path.read_bytes().index(ulog_writer.subscribe(11, "sensor_accel"))
    assert_one_error(
        cli("logs", path),
        f"{path}: sensor_accel:0 is subscribed twice (the 'A' message at byte {at}, msg_id 11, after the one of "
        "msg_id 10): which is the stream cannot be told",
    )


def test_a_msg_id_subscribed_twice_is_refused(tmp_path: Path) -> None:
    """Before: the second subscription took the msg_id over, the samples before it dropped unsaid."""
    twice = ulog_writer.subscribe(10, "sensor_accel") + ulog_writer.subscribe(10, "sensor_gyro")
    gyro = ulog_writer.message("F", f"sensor_gyro:{ulog_writer.FORMATS['sensor_gyro']}".encode())
    path = ulog(tmp_path / "reused.ulg", after=gyro, subscriptions=twice)
    data = path.read_bytes()
    first, second = (data.index(ulog_writer.subscribe(10, name)) for name in ("sensor_accel", "sensor_gyro"))
    assert_one_error(
        cli("logs", path),
        f"{path}: msg_id 10 is subscribed twice (the 'A' messages at bytes {first} and {second}, 'sensor_accel' "
        "and 'sensor_gyro'): whose samples are whose cannot be told",
    )


# -- ArduPilot DataFlash ------------------------------------------------------------------------


def _still(rows: int = 400) -> tuple[np.ndarray, np.ndarray]:
    return np.arange(rows, dtype=np.int64) * 2000 + 1_000_000, np.tile([0.0, 0.0, G], (rows, 1))


def dataflash(path: Path, **params: float) -> Path:
    """A binary log of 400 still IMU and ACC messages, after the default calibration and ``params``."""
    t, acc = _still()
    imu = dataflash_writer.imu(t, acc, np.full(len(t), 25.0))
    raw = dataflash_writer.records("ACC", len(t), TimeUS=t, SampleUS=t, AccX=acc[:, 0], AccY=acc[:, 1], AccZ=acc[:, 2])
    given = {**dataflash_writer.identity(1), **params}
    path.write_bytes(dataflash_writer.header(given, int(t[0]) - 1000) + dataflash_writer.frames([imu, raw]))
    return path


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines()


@pytest.mark.parametrize(("column", "k"), [("Type", 1), ("Length", 2)])
def test_a_text_fmt_number_of_5000_digits_is_one_error_naming_the_line(tmp_path: Path, column: str, k: int) -> None:
    """Before: 'internal error: ValueError: Exceeds the limit (4300 digits) for integer string
    conversion' from logs and every read."""
    text = dataflash_writer.text_of(dataflash(tmp_path / "log.bin"), tmp_path / "log.log")
    lines = _lines(text)
    n = next(i for i, ln in enumerate(lines) if ln.startswith("FMT, 130, "))
    parts = lines[n].split(", ")
    parts[k] = "9" * 5000
    lines[n] = ", ".join(parts)
    text.write_text("\n".join(lines) + "\n")
    least = 0 if column == "Type" else 3
    expected = (
        f"{text}: the FMT line of 'IMU' gives its {column} as '999999999999'... (5000 characters): not a DataFlash "
        f"message's (a byte, {least} to 255) (line {n + 1})"
    )
    assert_one_error(cli("logs", text), expected)
    assert_one_error(cli("noise", text), expected)


def test_a_text_fmt_number_out_of_a_byte_is_one_error(tmp_path: Path) -> None:
    text = dataflash_writer.text_of(dataflash(tmp_path / "log.bin"), tmp_path / "log.log")
    lines = [ln.replace("FMT, 130, 54, IMU,", "FMT, 130, 2, IMU,") for ln in _lines(text)]
    text.write_text("\n".join(lines) + "\n")
    n = next(i for i, ln in enumerate(lines) if ln.startswith("FMT, 130, 2, IMU,")) + 1
    assert_one_error(
        cli("noise", text),
        f"{text}: the FMT line of 'IMU' gives its Length as '2': not a DataFlash message's (a byte, 3 to 255) "
        f"(line {n})",
    )


@pytest.mark.parametrize("value", [float("nan"), float("inf"), 2.5, -8.0])
def test_an_ins_raw_log_opt_that_is_no_bit_mask_is_one_error(tmp_path: Path, value: float) -> None:
    """Before: int() of the parameter: 'internal error: ValueError: cannot convert float NaN to
    integer' (OverflowError for inf) from every command that read the log; 2.5 read as 2 and -8
    as the post-filter bit set."""
    path = dataflash(tmp_path / "opt.bin", INS_RAW_LOG_OPT=value)
    data = path.read_bytes()
    at = data.index(b"INS_RAW_LOG_OPT") - 3 - 8  # the PARM's header and TimeUS before its Name
    expected = (
        f"{path}: the PARM message at byte {at} gives INS_RAW_LOG_OPT as {value:.6g}: not a bit mask (a whole "
        "number from 0), so which ACC and GYR instances are post-filter copies cannot be told"
    )
    assert_one_error(cli("noise", path, "--stream", "ACC:0"), expected)
    assert_one_error(cli("logs", path), expected)  # the listing says which ACC is which filter's


def test_an_ins_raw_log_opt_of_nan_in_a_text_log_names_its_line(tmp_path: Path) -> None:
    text = dataflash_writer.text_of(dataflash(tmp_path / "opt.bin", INS_RAW_LOG_OPT=float("nan")), tmp_path / "o.log")
    n = next(i for i, ln in enumerate(_lines(text)) if "INS_RAW_LOG_OPT" in ln) + 1
    assert_one_error(
        cli("noise", text, "--stream", "ACC:0"),
        f"{text}: the PARM gives INS_RAW_LOG_OPT as nan: not a bit mask (a whole number from 0), so which ACC and "
        f"GYR instances are post-filter copies cannot be told (line {n})",
    )


IMU_FLOAT_I = "QfffffffIIfBBHH"  # IMU with its instance logged as a float


@pytest.mark.parametrize("instance", [float("nan"), 1e30, 0.5, -1.0, 256.0])
def test_an_instance_field_that_is_no_instance_is_one_error(tmp_path: Path, instance: float) -> None:
    """Before: NaN and 1e30 were 'a figure came out non-finite (invalid value encountered in
    cast)', naming no file; 0.5 read as IMU:0, -1 as IMU:-1 and 256 as IMU:256."""
    t, acc = _still(50)
    columns = dataflash_writer.TYPES["IMU"][2]
    length = 3 + struct.calcsize("<" + IMU_FLOAT_I)
    fmt = dataflash_writer.message("FMT", 130, length, b"IMU", IMU_FLOAT_I.encode(), columns.encode())
    head = dataflash_writer.fmt("FMT") + fmt
    rows = [
        dataflash_writer.HEAD
        + bytes([130])
        + struct.pack("<" + IMU_FLOAT_I, int(ts), 0.0 if k else instance, 0, 0, 0, *a, 0, 0, 25.0, 1, 1, 1000, 1000)
        for k, (ts, a) in enumerate(zip(t, acc, strict=True))
    ]
    path = tmp_path / "instance.bin"
    path.write_bytes(head + b"".join(rows))
    assert_one_error(
        cli("logs", path),
        f"{path}: IMU's field 'I' (its instance) is {instance:.6g} in the message at byte {len(head)}: not an "
        "instance (a whole number, 0 to 255)",
    )


@pytest.mark.parametrize("instance", ["1_0", "-1", "+1"])
def test_a_text_instance_not_in_ascii_digits_is_a_line_that_does_not_parse(tmp_path: Path, instance: str) -> None:
    """Before: int() read '1_0' as instance 10, '+1' as 1 and '-1' as -1: streams the log does
    not hold."""
    text = dataflash_writer.text_of(dataflash(tmp_path / "log.bin"), tmp_path / "log.log")
    lines = _lines(text)
    first = next(i for i, ln in enumerate(lines) if ln.startswith("IMU, "))
    parts = lines[first].split(", ")
    parts[2] = instance  # IMU, TimeUS, I, ...
    lines[first] = ", ".join(parts)
    text.write_text("\n".join(lines) + "\n", encoding="utf-8")
    r = cli("logs", "--json", text)
    assert r.code == 0, r.err
    assert '"IMU:0"' in r.out
    assert [k for k in ("IMU:10", "IMU:1", "IMU:-1") if f'"{k}"' in r.out] == []
    noise = cli("noise", text, "--stream", "IMU:0")
    assert "skipped 1 lines whose fields do not parse" in noise.err
